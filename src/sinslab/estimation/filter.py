"""The stepped Kalman filter that runs beside a nonlinear INS: predict, update, feedback
and lagged measurements from a history ring buffer.

:class:`KalmanFilter` works on an error state of any layout; it knows nothing about
navigation. What the fed-back states mean to an INS (attitude, velocity, position, sensor
compensation) is :class:`sinslab.fusion.feedback.FeedbackLayout`; the loop that runs the
filter beside the mechanization is :mod:`sinslab.fusion.driver`.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from sinslab.estimation.kalman import (UpdateResult, _as_square, _is_diag, check_covariance,
                                       update)
from sinslab.estimation.kernels import (cov_predict, predict_steps, predict_steps_dense, row_nonzeros,
                                         sequential_update)

__all__ = ["KalmanFilter", "StoredEpoch", "compiled_update"]


def compiled_update(x, P, z, H, R, tmp=None, B=None):
    """The Kalman update of :func:`sinslab.estimation.kalman.update` as sequential scalar
    Joseph updates in compiled code, in place on ``x`` (n,) and ``P`` (n, n) (both float64,
    C-contiguous).

    Applies when R is diagonal (a matrix, a vector of variances or a scalar) and every
    component of ``z`` is finite with ``r > 0``; the numbers equal the numpy sequential
    update to rounding. Returns the :class:`~sinslab.estimation.kalman.UpdateResult` (with
    copies of the new ``x``, ``P``), or None when it does not apply — then ``x`` and ``P``
    are unchanged and the caller takes :func:`~sinslab.estimation.kalman.update`.
    ``tmp`` (n,), ``B`` (n, n): optional work arrays.
    """
    if not (type(z) is np.ndarray and z.ndim == 1 and z.dtype == np.float64):
        z = np.atleast_1d(np.asarray(z, dtype=float))
    if not (type(H) is np.ndarray and H.ndim == 2 and H.dtype == np.float64 and H.flags.c_contiguous):
        H = np.ascontiguousarray(np.atleast_2d(H), dtype=float)
    R = np.asarray(R, dtype=float)
    m, n = z.size, x.shape[0]
    if R.ndim == 2:
        if R.shape != (m, m) or not _is_diag(R):
            return None
        r = np.diag(R).copy()
    elif R.shape == (m,):
        r = R
    else:
        r = np.broadcast_to(R, (m,)).astype(float)
    if H.shape != (m, n):
        return None
    S = H @ P @ H.T
    S.reshape(-1)[::m + 1] += r                 # the diagonal (S is a new C-contiguous array)
    # the innovation reported is the prior z − H x of all components, as the vector update
    # gives; the kernel's are those of each scalar step, after the earlier components
    innov = z - H @ x
    seq = np.empty(m)
    sdiag = np.empty(m)
    nis = sequential_update(x, P, z, H, np.ascontiguousarray(r, dtype=float), seq, sdiag,
                      np.empty(n) if tmp is None else tmp, np.empty((n, n)) if B is None else B)
    if nis < 0.0:                   # a non-finite z or an r <= 0: nothing was changed
        return None
    return UpdateResult(x.copy(), P.copy(), innov, S, float(nis), np.ones(m, dtype=bool))


def _readonly(a):
    v = a.view()
    v.flags.writeable = False
    return v


# ----------------------------------------------------------------------------------------
# stateful filter: feedback / feed-forward, lagged measurements
# ----------------------------------------------------------------------------------------
@dataclass
class StoredEpoch:
    """One epoch of the filter history (feedback coordinates; ``c`` = cumulative feedback)."""

    t: float
    x_prior: np.ndarray          # feedback coordinates, before updates at this epoch
    P_prior: np.ndarray
    c_prior: np.ndarray          # cumulative feedback at the prior
    updates: list = field(default_factory=list)   # (z_ff, H, R, mask, sequential)
    aux: object = None
    Phi: np.ndarray | None = None  # to the next epoch (set by the next predict)
    Q: np.ndarray | None = None
    x_post: np.ndarray | None = None
    P_post: np.ndarray | None = None
    c_post: np.ndarray | None = None


class KalmanFilter:
    """A Kalman filter stepped by the caller, for use beside a nonlinear INS.

    The filter works on an error state ``x`` (n,) with covariance ``P`` (n, n) at time
    ``t``. The caller predicts with the Φ and Q_k of each step (e.g. from
    :mod:`sinslab.nav.errstate`) and applies measurements as they arrive.

    Feedback and feed-forward
    -------------------------
    Feed-forward (open loop): never call :meth:`feedback`; ``x`` estimates the errors of
    the free-running INS and the user subtracts it from the output. Feedback (closed
    loop): after an update, ``d = kf.feedback(indices)`` returns the estimate of those
    states and zeroes them in ``x``; the caller corrects the navigation state (e.g.
    ``strapdown.correct``) and the sensor compensation by ``d``. The filter keeps the
    cumulative correction ``c`` propagated by Φ, so that ``x + c`` (:attr:`x_total`)
    is the feed-forward-equivalent estimate and lagged measurements stay exact.

    Lagged measurements
    -------------------
    With ``history > 0`` the filter keeps a ring buffer of the last ``history`` epochs:
    prior state and covariance, the transition to the next epoch, applied measurements,
    the cumulative feedback, and an optional ``aux`` payload (e.g. a copy of the
    navigation state, to form the lagged measurement from the INS output of that time).
    :meth:`update_lagged` applies a measurement valid at an earlier epoch:

    it inserts the measurement at its epoch and re-processes the stored steps and
    measurements up to now. For a linear system the result equals that of a filter that
    received it on time (to rounding), in feedback or feed-forward mode. Other ways of
    treating a lagged measurement (e.g. a one-step prediction from a stored state) are
    written against the public history accessors :meth:`find_epoch`,
    :meth:`stored_epoch`, :meth:`posterior_at` and :meth:`restart_history`.

    Parameters
    ----------
    x0 : array_like, shape (n,)
        Initial error-state estimate.
    P0 : array_like, shape (n, n)
        Initial covariance, symmetric positive semi-definite.
    t0 : float
        Initial time [s].
    history : int
        Number of epochs kept for lagged measurements (0: none).
    check : bool
        Validate Q and R at every call (cheap for small n; turn off in hot loops once the
        model is trusted).
    """

    def __init__(self, x0, P0, *, t0=0.0, history=0, check=True):
        P0 = np.asarray(P0, dtype=float)
        n = P0.shape[0] if P0.ndim == 2 else -1
        self._P = check_covariance(_as_square(P0, n, "P0"), "P0").copy()
        self.n = n
        x0 = np.zeros(n) if x0 is None else np.asarray(x0, dtype=float).copy()
        if x0.shape != (n,):
            raise ValueError(f"x0 must have shape ({n},) to match P0, got {x0.shape}")
        self._x = x0
        self._t = float(t0)
        self._c = np.zeros(n)
        self.check = bool(check)
        self.history = int(history)
        self._buf = deque(maxlen=self.history) if self.history > 0 else None
        self._new_epoch()
        # numba work arrays for the fast path
        self._T1 = np.empty((n, n))
        self._T2 = np.empty((n, n))
        self._tmp = np.empty(n)

    # -- history -----------------------------------------------------------------------
    def _new_epoch(self, aux=None):
        if self._buf is not None:
            self._buf.append(StoredEpoch(self._t, self._x.copy(), self._P.copy(), self._c.copy(), aux=aux))

    def _close_epoch(self, Phi, Q):
        if self._buf is not None and self._buf:
            e = self._buf[-1]
            e.Phi, e.Q = Phi.copy(), Q.copy()
            e.x_post, e.P_post, e.c_post = self._x.copy(), self._P.copy(), self._c.copy()

    def set_aux(self, aux):
        """Attach a payload (e.g. a copy of the navigation state) to the current epoch."""
        if self._buf is not None:
            self._buf[-1].aux = aux

    def epochs(self):
        """Times [s] of the stored epochs, oldest first (shape (≤history,))."""
        return np.array([e.t for e in self._buf]) if self._buf is not None else np.empty(0)

    def aux_at(self, t_m, tol=1e-9):
        """The payload stored at the epoch ``t_m`` (within ``tol`` s)."""
        return self._buf[self._find(t_m, tol, exact=True)].aux

    def _find(self, t_m, tol, exact):
        if self._buf is None:
            raise ValueError("no history kept: create the filter with history > 0 for lagged measurements")
        ts = self.epochs()
        if t_m > self._t + tol:
            raise ValueError(f"measurement time {t_m} s is in the future (filter time {self._t} s)")
        if t_m < ts[0] - tol:
            raise ValueError(f"lagged measurement at {t_m} s is older than the stored history "
                             f"({ts[0]} .. {ts[-1]} s, {len(ts)} epochs); increase history")
        j = int(np.searchsorted(ts, t_m + tol, side="right")) - 1
        if exact and abs(ts[j] - t_m) > tol:
            raise ValueError(f"measurement time {t_m} s is not a stored epoch (nearest "
                             f"{ts[j]} s); predict to the measurement epoch")
        return j

    # -- state (read-only views: the filter's own methods change it) --------------------
    @property
    def x(self):
        """Error-state estimate (n,), read-only (feedback coordinates)."""
        return _readonly(self._x)

    @property
    def P(self):
        """Covariance (n, n), read-only."""
        return _readonly(self._P)

    @property
    def c(self):
        """Cumulative feedback (n,) propagated by Φ, read-only."""
        return _readonly(self._c)

    @property
    def t(self):
        """Filter time [s]."""
        return self._t

    # -- basic steps -------------------------------------------------------------------
    @property
    def x_total(self):
        """Feed-forward-equivalent estimate ``x + c`` (n,): estimate of the errors of the
        INS as if no feedback had been applied."""
        return self._x + self._c

    @property
    def sigma(self):
        """Standard deviations sqrt(diag P), shape (n,)."""
        return np.sqrt(np.maximum(self._P.diagonal(), 0.0))

    def predict(self, Phi, Q, dt, *, aux=None):
        """Advance by ``dt`` [s]: ``x <- Phi x``, ``P <- Phi P Phi^T + Q``.

        Parameters
        ----------
        Phi : array_like, shape (n, n)
        Q : array_like, shape (n, n)
        dt : float
            Step length [s] (> 0); the filter time advances by it.
        aux : object, optional
            Payload for the new epoch (see :meth:`set_aux`).
        """
        n = self.n
        Phi = np.ascontiguousarray(Phi, dtype=float)
        Q = np.ascontiguousarray(Q, dtype=float)
        if Phi.shape != (n, n) or Q.shape != (n, n):
            raise ValueError(f"Phi and Q must have shape ({n}, {n}), got {Phi.shape} and {Q.shape}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        if self.check:
            check_covariance(Q, "Q")
            if not np.all(np.isfinite(Phi)):
                raise ValueError("Phi has NaN/inf elements")
        self._close_epoch(Phi, Q)
        cov_predict(self._P, Phi, Q, n, self._T1, self._T2)
        self._x = Phi @ self._x
        self._c = Phi @ self._c
        self._t += float(dt)
        self._new_epoch(aux)

    def predict_many(self, Phis, Qs, dt, *, aux=None, sigma_out=None, x_out=None):
        """Several :meth:`predict` steps in one compiled loop.

        Parameters
        ----------
        Phis, Qs : ndarray, shape (m, n, n)
            Transition and process-noise matrices of the m steps.
        dt : float
            Step length [s].
        aux : sequence of length m, optional
            Payloads of the new epochs (history only).
        sigma_out, x_out : ndarray, shape (m, n), optional
            Receive σ and x after each step.
        """
        Phis = np.ascontiguousarray(Phis, dtype=float)
        Qs = np.ascontiguousarray(Qs, dtype=float)
        m = Phis.shape[0]
        if self._buf is not None or self.check:
            i0 = 0
            if self._buf is not None and not self.check and aux is None and m >= self.history:
                # of the epochs reached by the first m − history + 1 steps only the last
                # stays in the history once the call returns: step them with predict's
                # arithmetic and store just that one
                n = self.n
                if Phis.shape != (m, n, n) or Qs.shape != (m, n, n):
                    raise ValueError(f"Phis and Qs must have shape (m, {n}, {n}), got {Phis.shape}, {Qs.shape}")
                if not dt > 0:
                    raise ValueError(f"dt must be > 0, got {dt}")
                i0 = m - self.history + 1
                so = np.empty((i0, n)) if sigma_out is None else sigma_out
                xo = np.empty((i0, n)) if x_out is None else x_out
                # stepped in place: new arrays first, as predict makes, since the old
                # ones may still be referenced (posterior_at returns them)
                self._x, self._c = self._x.copy(), self._c.copy()
                predict_steps_dense(self._x, self._c, self._P, Phis, Qs, i0, self._T1, self._T2, so, xo)
                for _ in range(i0):             # the clock as predict advances it
                    self._t += float(dt)
                self._buf.clear()
                self._new_epoch()
            for i in range(i0, m):
                self.predict(Phis[i], Qs[i], dt, aux=None if aux is None else aux[i])
                if sigma_out is not None:
                    sigma_out[i] = self.sigma
                if x_out is not None:
                    x_out[i] = self._x
            return
        n = self.n
        if Phis.shape != (m, n, n) or Qs.shape != (m, n, n):
            raise ValueError(f"Phis and Qs must have shape (m, {n}, {n}), got {Phis.shape}, {Qs.shape}")
        nzc = np.zeros((m, n, max(n, 1)), dtype=np.int64)
        nnz = np.zeros((m, n), dtype=np.int64)
        row_nonzeros(Phis, nzc, nnz)
        so = np.empty((m, n)) if sigma_out is None else sigma_out
        xo = np.empty((m, n)) if x_out is None else x_out
        predict_steps(self._x, self._c, self._P, Phis, Qs, nzc, nnz, self._T1, self._T2, self._tmp,
                      so, xo)
        self._t += m * float(dt)

    def update(self, z, H, R, *, mask=None, sequential=None):
        """Apply a measurement valid now (see :func:`update`). Returns :class:`UpdateResult`."""
        if not self.check and self._buf is None and mask is None and sequential is not False:
            fast = self._fast_update(z, H, R)
            if fast is not None:
                return fast
        res = update(self._x, self._P, z, H, R, mask=mask, sequential=sequential)
        if self._buf is not None:
            z = np.atleast_1d(np.asarray(z, dtype=float))
            Hm = np.atleast_2d(np.asarray(H, dtype=float))
            self._buf[-1].updates.append((z + Hm @ self._c, Hm, R, res.used.copy(), sequential))
        # own copies: predict() and feedback() work in place
        self._x, self._P = res.x.copy(), res.P.copy()
        return res

    def _fast_update(self, z, H, R):
        """Sequential scalar Joseph updates in compiled code (diagonal R, finite z)."""
        return compiled_update(self._x, self._P, z, H, R, self._tmp, self._T1)

    def transform(self, A, Q=None):
        """A jump of the state at the present time: ``x <- A x``, ``c <- A c``,
        ``P <- A P Aᵀ + Q`` (no time passes).

        For states a measurement re-initialises or copies (a carrier-phase ambiguity
        after a cycle slip: its row of ``A`` zero and its variance in ``Q``; the copy of
        the antenna position that time-differenced phase compares with: rows of ``A``
        forming it from the other states). Not re-processed by lagged updates, so a
        filter keeping a history refuses it.

        Parameters
        ----------
        A : array_like, shape (n, n)
        Q : array_like, shape (n, n), optional
        """
        if self._buf is not None:
            raise ValueError("a state transform cannot be re-processed by lagged updates: use a filter "
                             "without history")
        n = self.n
        A = np.asarray(A, dtype=float)
        if A.shape != (n, n):
            raise ValueError(f"A must have shape ({n}, {n}), got {A.shape}")
        P = A @ self._P @ A.T
        if Q is not None:
            Q = np.asarray(Q, dtype=float)
            if self.check:
                check_covariance(Q, "Q")
            P = P + Q
        self._P = np.ascontiguousarray(0.5 * (P + P.T))
        self._x = A @ self._x
        self._c = A @ self._c

    def feedback(self, indices=None):
        """Return the estimate of the given states and zero them (closed-loop correction).

        Parameters
        ----------
        indices : array_like of int or slice, optional
            States to feed back (default all), e.g. ``FeedbackLayout.indices(n)``.

        Returns
        -------
        ndarray, shape (n,)
            The fed-back amounts (zero outside ``indices``); the caller subtracts them
            from the navigation state / adds them to the sensor compensation.
        """
        if indices is None:
            # every state: the amounts are the estimate as it stands (the values the
            # indexed copy below gives)
            d = self._x.copy()
            self._x[:] = 0.0
            self._c += d
            return d
        d = np.zeros(self.n)
        if type(indices) is np.ndarray and indices.dtype == np.int64:
            idx = indices                   # what np.arange(n)[indices] would return
        else:
            idx = np.arange(self.n)[indices]
        d[idx] = self._x[idx]
        self._x[idx] = 0.0
        self._c += d
        return d

    # -- history access for lag policies ------------------------------------------------
    def find_epoch(self, t_m, tol=1e-9, *, exact=True):
        """Index in the history of the stored epoch at ``t_m`` (``exact``) or of the last
        stored epoch at or before it.

        Raises
        ------
        ValueError
            No history kept, ``t_m`` in the future or older than the history, or (exact)
            not a stored epoch.
        """
        return self._find(t_m, tol, exact)

    def stored_epoch(self, j):
        """The :class:`StoredEpoch` record ``j`` of the history (oldest = 0, newest = -1)."""
        if self._buf is None:
            raise ValueError("no history kept: create the filter with history > 0")
        return self._buf[j]

    def posterior_at(self, j):
        """``(x, P, c)`` after the updates and feedback of stored epoch ``j``; for the
        newest epoch that is the current state of the filter."""
        if j == len(self._buf) - 1 or j == -1:
            return self.x, self.P, self.c
        e = self._buf[j]
        return e.x_post, e.P_post, e.c_post

    def restart_history(self, x, P):
        """Set the current estimate (feedback coordinates) and restart the history from
        now: the stored epochs no longer describe the path to this estimate (used by lag
        policies that replace re-processing with a one-step form)."""
        self._x = np.array(x, dtype=float, copy=True)
        self._P = np.array(P, dtype=float, order="C", copy=True)
        buf = self._buf
        cur = buf[-1]
        buf.clear()
        cur.x_prior, cur.P_prior, cur.c_prior = self._x.copy(), self._P.copy(), self._c.copy()
        cur.updates = []
        buf.append(cur)

    # -- lagged measurements -----------------------------------------------------------
    def update_lagged(self, z, H, R, t_m, *, mask=None, sequential=None, tol=1e-9):
        """Apply a measurement valid at the stored epoch ``t_m`` <= now, arriving now, by
        exact re-processing of the stored steps and measurements.

        Parameters
        ----------
        z, H, R, mask, sequential
            As in :func:`sinslab.estimation.kalman.update`; ``z`` must be formed from the
            navigation state of ``t_m`` as it was then (:meth:`aux_at` returns what was
            stored): with feedback, the INS output at epoch ``t_m`` *before* any feedback
            applied at that epoch (the payload given to :meth:`predict`).
        t_m : float
            Validity time of the measurement [s], a stored epoch.
        tol : float
            Time tolerance [s] for matching ``t_m`` to a stored epoch.

        Returns
        -------
        UpdateResult
            Of the update at ``t_m`` (innovation, S, NIS there); the filter's ``x``, ``P``
            are then those of the current time.

        Raises
        ------
        ValueError
            ``t_m`` older than the stored history, in the future, or not a stored epoch.
        """
        return self._lagged_exact(z, H, R, t_m, mask, sequential, tol)

    def _lagged_exact(self, z, H, R, t_m, mask, sequential, tol):
        j = self._find(t_m, tol, exact=True)
        buf = self._buf
        z = np.atleast_1d(np.asarray(z, dtype=float))
        Hm = np.atleast_2d(np.asarray(H, dtype=float))
        e = buf[j]
        z_ff = z + Hm @ e.c_prior
        # re-run in feed-forward coordinates from the prior at epoch j
        xff = e.x_prior + e.c_prior
        P = e.P_prior.copy()
        first = None
        last = len(buf) - 1
        for i in range(j, last + 1):
            ei = buf[i]
            if i > j:
                prev = buf[i - 1]
                # the arithmetic of predict(): x by Φ x, P by the kernel (on a copy: the
                # update results handed out keep theirs)
                xff = prev.Phi @ xff
                P = np.array(P, dtype=float, order="C", copy=True)
                cov_predict(P, prev.Phi, prev.Q, self.n, self._T1, self._T2)
                ei.x_prior = xff - ei.c_prior
                ei.P_prior = P.copy()
            ups = ei.updates
            if i == j:
                res = update(xff, P, z_ff, Hm, R, mask=mask, sequential=sequential)
                first = res
                xff, P = res.x, res.P
            for (zf, Hs, Rs, ms, sq) in ups:
                r2 = update(xff, P, zf, Hs, Rs, mask=ms, sequential=sq)
                xff, P = r2.x, r2.P
            if i < last:
                ei.x_post = xff - ei.c_post
                ei.P_post = P.copy()
        buf[j].updates.insert(0, (z_ff, Hm, R, first.used.copy(), sequential))
        self._x = xff - self._c
        self._P = np.array(P, dtype=float, order="C", copy=True)
        return UpdateResult(first.x - e.c_prior, first.P, first.innovation, first.S, first.nis, first.used)

    # -- propagation by a caller's compiled kernel ---------------------------------------
    @property
    def fast(self):
        """True when the filter keeps no history and checks nothing: then its steps may be
        taken by a caller's compiled propagation (:meth:`propagate`, :meth:`propagate_lanes`)."""
        return self._buf is None and not self.check

    def propagate(self, step, m, dt):
        """Advance by ``m`` steps of ``dt`` [s] with a caller's compiled propagation.

        ``step(x, c, P, T1, T2, tmp)`` steps the estimate ``x`` (n,), the cumulative
        feedback ``c`` (n,) and ``P`` (n, n) in place with the arithmetic of
        :meth:`predict_many` (e.g. a fused model, Φ, Q_k and prediction that also records
        what a smoother needs); ``T1``, ``T2`` (n, n) and ``tmp`` (n,) are work arrays.
        Returns what ``step`` returns. Only for a :attr:`fast` filter: a history could not
        record the steps.
        """
        if not self.fast:
            raise ValueError("a compiled propagation steps only a filter without history and checks")
        out = step(self._x, self._c, self._P, self._T1, self._T2, self._tmp)
        self._t += m * float(dt)
        return out

    @staticmethod
    def propagate_lanes(filts, step, m, dt):
        """Advance the :attr:`fast` filters of several lanes (the runs of a Monte
        Carlo task) by ``m`` steps of ``dt`` [s] with one compiled call.

        ``step(x, c, P)`` steps ``x``, ``c`` (L, n) and ``P`` (L, n, n) of the L filters in
        place; one filter is stepped where it is (views), several are stacked and written back.
        Returns what ``step`` returns.
        """
        if not all(k.fast for k in filts):
            raise ValueError("a compiled propagation steps only filters without history and checks")
        if len(filts) == 1:
            f0 = filts[0]
            out = step(f0._x[None], f0._c[None], f0._P[None])
        else:
            x = np.stack([k._x for k in filts])
            c = np.stack([k._c for k in filts])
            P = np.stack([k._P for k in filts])
            out = step(x, c, P)
            for ln, k in enumerate(filts):
                k._x[:], k._c[:], k._P[:] = x[ln], c[ln], P[ln]
        for k in filts:
            k._t += m * float(dt)
        return out
