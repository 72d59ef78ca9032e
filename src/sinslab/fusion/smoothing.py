"""Fixed-interval (Rauch–Tung–Striebel) smoothing of a fusion-driver run.

The forward pass (:func:`sinslab.fusion.driver.run` with ``history=History(...)``)
records what the backward pass needs; :func:`smooth` runs the backward pass
(:func:`sinslab.estimation.smoother.rts_smooth`, closed-loop form) and corrects the
recorded navigation solution with the smoothed error states.

What is stored
--------------
The driver's filter steps every ``T = kf_dt`` seconds, k = 0..K. The history keeps a
subset of those epochs, the *stored epochs* ``s_0 = 0 < s_1 < ... < s_R = K``: every
epoch at which a measurement arrives or is valid (where the filter updates or feeds
back), and one epoch every ``every`` seconds between them. Between two stored epochs
the filter only predicts, so the stored epochs form a Gauss–Markov chain of their own
with the composed transition ``Φ_{s_r→s_{r+1}} = Φ_{s_{r+1}−1} ··· Φ_{s_r}`` and the
predicted covariance the filter reached at ``s_{r+1}``; the RTS smoother on that chain
gives the exact smoothed marginals at the stored epochs (the marginal chain of a linear
Gauss–Markov model is again one, and no measurement lies between its epochs).

Per stored epoch r (n states): the updated state before the feedback of that epoch
``x_{r|r}`` (n), the fed-back amount ``d_r`` (n), the prediction ``x_{r|r−1}`` (n),
``P_{r|r−1}`` (n²), ``Φ_{r−1→r}`` (n²), and ``P_{r|r}`` (n²) only at the epochs where a
measurement was applied (elsewhere it equals ``P_{r|r−1}``). For 1 h of 200 Hz IMU with
the covariance stored at 10 Hz (36 001 epochs), 15 states and 1 Hz fixes:
36 001 × (2·225 + 3·15) × 8 B + 3 601 × 225 × 8 B = 149 MB (21 states: 285 MB); see
:meth:`History.nbytes`. ``spill=DIR`` keeps the arrays in memory-mapped ``.npy`` files
in ``DIR`` instead of memory (the backward pass reads them in chunks).

Lagged measurements re-processed exactly (:class:`sinslab.fusion.lag.ExactReprocessing`)
change the stored epochs back to their validity epoch; the recorder copies the
re-processed values from the filter's own history after each such update, so the stored
forward pass is the one a filter that received the item on time would have run.

Smoothed solution
-----------------
At stored epoch r the smoothed error of the recorded (post-feedback) solution is
``x⁺_{r|R} = x_{r|R} − d_r`` (eq. 10 of :mod:`sinslab.estimation.smoother`). Between
``s_r`` and ``s_{r+1}`` the free-running solution carries an error that starts as
``x⁺_{r|R}`` and ends as ``x_{r+1|R}`` (before the feedback at ``s_{r+1}``); the
correction at the filter epochs in between, and at any time (IMU rate), is interpolated
linearly between those two, never across a feedback jump; the forward solution between
filter epochs is interpolated linearly (quaternions: normalised linear interpolation).
The smoothed solution is the forward one corrected like a feedback
(:func:`sinslab.nav.strapdown.correct_rows`): ``q ← q(φ) ⊗ q``,
``v ← v − δv``, ``p ← p − δp``, sensor compensation ``+ δε``, ``+ δ∇``.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from numba import njit

from sinslab.core.blocks import release_pages
from sinslab.estimation.kernels import copy2, predict_step, row_nonzeros
from sinslab.estimation.smoother import rts_smooth
from sinslab.nav import strapdown as sd

__all__ = ["History", "SmoothedRun", "smooth", "interpolate_rows"]


@njit(cache=True)
def _compose(acc, nacc, Phi, W):
    """acc <- Phi acc (acc <- Phi for the first step since a stored epoch)."""
    if nacc == 0:
        copy2(acc, Phi)
    else:
        np.dot(Phi, acc, W)
        copy2(acc, W)


@njit(cache=True)
def _predict_record(x, c, P, Phis, Qs, nzc, nnz, T1, T2, tmp, sig_out, x_out, stop, acc, nacc, W,
                    Phi_o, Pp_o, xp_o):
    """The filter's compiled prediction (:func:`sinslab.estimation.kernels.predict_step`,
    the arithmetic of ``KalmanFilter.predict_many``) with the recording of the
    stored epochs: after step i with ``stop[i]``, the composed transition, P and x go to
    the next row of ``Phi_o``, ``Pp_o``, ``xp_o``. Returns (rows written, steps composed
    since the last stored epoch)."""
    m = Phis.shape[0]
    n = x.shape[0]
    j = 0
    for i in range(m):
        predict_step(x, c, P, Phis[i], Qs[i], n, nzc[i], nnz[i], T1, T2, tmp, sig_out[i], x_out[i])
        _compose(acc, nacc, Phis[i], W)
        nacc += 1
        if stop[i]:
            Phi_o[j] = acc
            Pp_o[j] = P
            xp_o[j] = x
            j += 1
            nacc = 0
    return j, nacc


class _PostView:
    """``P_{r|r}`` of every stored epoch, read from ``P_{r|r−1}`` where nothing was applied
    (an array-like for :func:`rts_smooth`: ``shape``, integer and slice indexing)."""

    def __init__(self, h):
        self._h = h
        R1 = h.epochs.size
        self.shape = (R1, h.n, h.n)

    def release_pages(self):
        release_pages(self._h.P_upd, self._h.P_prior)

    def __getitem__(self, key):
        h = self._h
        if isinstance(key, (int, np.integer)):
            r = int(key) % self.shape[0]
            s = h._slot[r]
            return np.asarray(h.P_upd[s] if s >= 0 else h.P_prior[r - 1], dtype=float)
        a, b, st = key.indices(self.shape[0])
        if st != 1:
            raise IndexError("only contiguous slices")
        out = np.empty((b - a, h.n, h.n))
        for i, r in enumerate(range(a, b)):
            s = h._slot[r]
            out[i] = h.P_upd[s] if s >= 0 else h.P_prior[r - 1]
        return out


#: Rows a spilled history writes between two releases of its pages.
SPILL_ROWS = 2048


class History:
    """Recorder of the forward pass for :func:`smooth` (give it to
    :func:`sinslab.fusion.driver.run` as ``history=``). One recorder per run.

    Parameters
    ----------
    every : float
        Longest interval [s] between stored epochs (rounded to whole filter steps, at
        least one); the covariance is stored at this rate and at every epoch with a
        measurement.
    dtype : numpy dtype
        Storage type (float64 default; float32 halves the memory, see the notes of
        :mod:`sinslab.estimation.smoother` for its effect).
    spill : str or path-like, optional
        Directory for memory-mapped ``.npy`` arrays instead of memory: the recorded rows
        go to the files as the forward pass runs (the process lets their pages go every
        ``SPILL_ROWS`` rows, :func:`sinslab.core.blocks.release_pages`), and the
        backward pass reads them back a chunk at a time, so the memory a spilled history
        holds does not grow with the length of the run.

    Attributes (after the run)
    --------------------------
    epochs : int ndarray (R+1,)
        Stored filter epochs.
    x_post, feedback : ndarray (R+1, n)
        ``x_{r|r}`` before the feedback of epoch r, and that feedback ``d_r``.
    x_prior : ndarray (R, n)
        Row r−1: ``x_{r|r−1}``.
    P_prior, Phi : ndarray (R, n, n)
        Row r−1: ``P_{r|r−1}`` and the transition from stored epoch r−1 to r.
    P_upd : ndarray (U, n, n)
        ``P_{r|r}`` at the U epochs that can receive a measurement (and epoch 0).
    """

    def __init__(self, every=0.1, *, dtype=np.float64, spill=None):
        if not (every > 0 and math.isfinite(every)):
            raise ValueError(f"history interval must be > 0 s, got {every}")
        self.every = float(every)
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.dtype(np.float64), np.dtype(np.float32)):
            raise ValueError(f"history dtype must be float64 or float32, got {self.dtype}")
        self.spill = spill
        self.epochs = None
        self.n = None

    # ------------------------------------------------------------------ driver hooks --
    def begin(self, filt, n_ep, T, special):
        """Allocate for ``n_ep`` filter steps of ``T`` s; ``special`` = epochs at which
        measurements arrive or are valid (stored with their own ``P_{r|r}``)."""
        if self.epochs is not None:
            raise ValueError("a History records one run; make a new one for each run")
        n = filt.n
        stride = max(1, int(round(self.every / T)))
        special = sorted({int(e) for e in special if 0 <= e <= n_ep} | {0})
        ep = np.union1d(np.arange(0, n_ep + 1, stride), np.r_[special, n_ep]).astype(np.int64)
        R1 = ep.size
        self.n, self.T, self.stride = n, float(T), stride
        self.epochs = ep
        self._slot = np.full(R1, -1, dtype=np.int64)
        self._slot[np.searchsorted(ep, special)] = np.arange(len(special))
        alloc = self._alloc
        self.x_post = alloc("x_post", (R1, n))
        self.feedback = alloc("feedback", (R1, n), zero=True)
        self.x_prior = alloc("x_prior", (R1 - 1, n))
        self.P_prior = alloc("P_prior", (R1 - 1, n, n))
        self.Phi = alloc("Phi", (R1 - 1, n, n))
        self.P_upd = alloc("P_upd", (len(special), n, n))
        self.x_post[0] = filt.x
        self.P_upd[0] = filt.P
        self._direct = self.spill is None and self.dtype == np.float64
        self._next = 1                 # row of the next stored epoch to reach
        self._released = 0             # row up to which a spilled record's pages were let go
        self._acc = np.eye(n)          # transition composed since the last stored epoch
        self._nacc = 0                 # steps composed in it
        self._W = np.empty((n, n))

    def _alloc(self, name, shape, zero=False):
        if self.spill is None:
            return (np.zeros if zero else np.empty)(shape, dtype=self.dtype)
        os.makedirs(self.spill, exist_ok=True)
        return np.lib.format.open_memmap(os.path.join(os.fspath(self.spill), name + ".npy"),
                                         mode="w+", dtype=self.dtype, shape=shape)

    def predict(self, filt, Phis, Qs, T, e0, sigma_out, x_out):
        """The driver's prediction ``e0 -> e0 + m``, recording the stored epochs reached.

        A filter without a history of its own and without checks (the driver's) is
        stepped by one compiled loop with the arithmetic of its ``predict_many``; else
        by ``predict_many`` in pieces that end at the stored epochs. Either way the
        numbers are those of one ``predict_many`` call."""
        Phis = np.ascontiguousarray(Phis, dtype=float)
        Qs = np.ascontiguousarray(Qs, dtype=float)
        m = Phis.shape[0]
        ep = self.epochs
        r0 = self._next
        r1 = int(np.searchsorted(ep, e0 + m, side="right"))     # rows r0..r1-1 reached
        stop = np.zeros(m, dtype=np.bool_)
        stop[ep[r0:r1] - e0 - 1] = True
        k = r1 - r0
        direct = self._direct
        if direct:                     # in-memory float64: the kernel writes the rows in place
            Phi_o, Pp_o, xp_o = self.Phi[r0 - 1:r1 - 1], self.P_prior[r0 - 1:r1 - 1], self.x_prior[r0 - 1:r1 - 1]
        else:
            Phi_o = np.empty((k, self.n, self.n))
            Pp_o = np.empty((k, self.n, self.n))
            xp_o = np.empty((k, self.n))
        if filt.fast:
            nzc = np.zeros((m, self.n, max(self.n, 1)), dtype=np.int64)
            nnz = np.zeros((m, self.n), dtype=np.int64)
            row_nonzeros(Phis, nzc, nnz)

            def step(x, c, P, T1, T2, tmp):
                return _predict_record(x, c, P, Phis, Qs, nzc, nnz, T1, T2, tmp, sigma_out, x_out, stop,
                                       self._acc, self._nacc, self._W, Phi_o, Pp_o, xp_o)

            _, self._nacc = filt.propagate(step, m, T)
        else:
            i = 0
            for jj, b in enumerate(list(np.flatnonzero(stop) + 1) + ([m] if not stop[-1] else [])):
                filt.predict_many(Phis[i:b], Qs[i:b], T, sigma_out=sigma_out[i:b], x_out=x_out[i:b])
                for q in range(i, b):
                    _compose(self._acc, self._nacc, Phis[q], self._W)
                    self._nacc += 1
                if jj < k:
                    Phi_o[jj] = self._acc
                    Pp_o[jj] = filt.P
                    xp_o[jj] = filt.x
                    self._nacc = 0
                i = b
        if k:
            if not direct:
                self.Phi[r0 - 1:r1 - 1] = Phi_o
                self.P_prior[r0 - 1:r1 - 1] = Pp_o
                self.x_prior[r0 - 1:r1 - 1] = xp_o
            self.x_post[r0:r1] = xp_o
            sl = self._slot[r0:r1]
            has = sl >= 0
            if has.any():
                self.P_upd[sl[has]] = Pp_o[has]
            self._next = r1
            if self.spill is not None and r1 - self._released >= SPILL_ROWS:
                self.release_pages()
                self._released = r1

    def release_pages(self):
        """Let the resident pages of a spilled record go (they stay in its files)."""
        release_pages(self.x_post, self.feedback, self.x_prior, self.P_prior, self.Phi, self.P_upd)

    def _row(self, e):
        r = int(np.searchsorted(self.epochs, e))
        if r >= self.epochs.size or self.epochs[r] != e:
            raise RuntimeError(f"epoch {e} is not a stored epoch of the history")
        return r

    def updated(self, e, filt, lagged_from=None):
        """After the measurements of epoch ``e``, before its feedback. ``lagged_from``:
        the earliest validity epoch of an item re-processed exactly at ``e``."""
        if lagged_from is not None and lagged_from < e:
            self._refresh(filt, int(lagged_from), e)
        r = self._row(e)
        self.x_post[r] = filt.x
        self.P_upd[self._slot[r]] = filt.P

    def fed_back(self, e, d):
        """Add the amount ``d`` (n,) fed back at epoch ``e``."""
        self.feedback[self._row(e)] += d

    def _refresh(self, filt, ev, e):
        """Copy the re-processed epochs ``ev..e`` from the filter's ring buffer."""
        T = self.T
        n_buf = len(filt.epochs())
        for j in range(n_buf):
            st = filt.stored_epoch(j)
            k = int(round(st.t / T))
            if k < ev or k > e:
                continue
            r = int(np.searchsorted(self.epochs, k))
            if r >= self.epochs.size or self.epochs[r] != k:
                continue
            if k > ev:
                self.x_prior[r - 1] = st.x_prior
                self.P_prior[r - 1] = st.P_prior
            if k < e:
                # x_post in the buffer is after that epoch's feedback
                self.x_post[r] = st.x_post + (st.c_post - st.c_prior)
                if self._slot[r] >= 0:
                    self.P_upd[self._slot[r]] = st.P_post

    # --------------------------------------------------------------------- queries --
    def nbytes(self):
        """Bytes held by the stored arrays."""
        return int(sum(a.nbytes for a in (self.x_post, self.feedback, self.x_prior, self.P_prior,
                                          self.Phi, self.P_upd)))

    @staticmethod
    def estimate_bytes(n_states, duration, every, n_updates, itemsize=8):
        """Storage [B] of a run of ``duration`` s stored every ``every`` s with
        ``n_updates`` epochs that receive measurements (see the module notes)."""
        R1 = int(round(duration / every)) + 1
        n = int(n_states)
        return int((R1 * (2 * n * n + 3 * n) + (n_updates + 1) * n * n) * itemsize)


@dataclass(frozen=True)
class SmoothedRun:
    """Output of :func:`smooth` at the filter epochs (M rows, those of the run).

    Attributes
    ----------
    t : ndarray (M,)
        Epoch times [s].
    x : ndarray (M, n)
        Smoothed error of the recorded (post-feedback) solution, computed − true, in the
        units of the error model (interpolated between stored epochs).
    sigma : ndarray (M, n)
        Smoothed σ (interpolated between stored epochs).
    nav : ndarray (M, 10) or None
        Smoothed ``[q0..q3, vE, vN, vU, lat, lon, h]`` of the stream (None when the
        model has no φ/δv/δp blocks to route, or the run has several streams).
    gyro_bias, accel_bias : ndarray (M, 3) or None
        Smoothed sensor compensation [rad/s], [m/s²] of a live stream.
    forward_nav : ndarray (M, 10)
        The recorded forward solution (corrected by the filter's remaining estimate of
        a feed-forward run).
    stored : int ndarray (R+1,)
        The stored epochs (indices into ``t``).
    x_stored, sigma_stored : ndarray (R+1, n)
        Smoothed error after the feedback and σ at the stored epochs (not interpolated).
    x_before : ndarray (R+1, n)
        Smoothed error before the feedback of each stored epoch.
    dropped : int ndarray (R,)
        Directions of ``P_{r+1|r}`` treated as singular (see :func:`rts_smooth`).
    """

    t: np.ndarray
    x: np.ndarray
    sigma: np.ndarray
    nav: np.ndarray | None
    gyro_bias: np.ndarray | None
    accel_bias: np.ndarray | None
    forward_nav: np.ndarray
    stored: np.ndarray
    x_stored: np.ndarray
    sigma_stored: np.ndarray
    x_before: np.ndarray
    dropped: np.ndarray
    _route: object = None

    def at(self, t):
        """Smoothed ``[q, v, lat, lon, h]`` rows (len(t), 10) at times ``t`` [s] inside
        the run (e.g. the IMU sample times): forward solution interpolated between the
        filter epochs, corrected by the interpolated smoothed error (module notes)."""
        if self._route is None:
            raise ValueError("the error model has no φ/δv/δp blocks: no navigation solution to correct")
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if t.size and (t.min() < self.t[0] - 1e-9 or t.max() > self.t[-1] + 1e-9):
            raise ValueError(f"times {t.min():.3f}..{t.max():.3f} s outside the run "
                             f"{self.t[0]:.3f}..{self.t[-1]:.3f} s")
        rows = interpolate_rows(self.t, self.forward_nav, t)
        x = _interp_between(self.t, self.stored, self.x_stored, self.x_before, t)
        return sd.correct_rows(rows, *self._route.nav_errors(x))


def interpolate_rows(t_ep, rows, t):
    """Navigation rows ``[q0..q3, v(3), lat, lon, h]`` (M, 10) at epochs ``t_ep`` (M,)
    interpolated to ``t``: linear in v and position, normalised linear in q."""
    t_ep = np.asarray(t_ep, dtype=float)
    t = np.asarray(t, dtype=float)
    i = np.clip(np.searchsorted(t_ep, t, side="right") - 1, 0, t_ep.size - 2)
    w = ((t - t_ep[i]) / (t_ep[i + 1] - t_ep[i]))[:, None]
    a, b = rows[i], rows[i + 1]
    qb = np.where((np.sum(a[:, :4] * b[:, :4], 1) < 0)[:, None], -b[:, :4], b[:, :4])
    out = a + w * (b - a)
    q = a[:, :4] + w * (qb - a[:, :4])
    out[:, :4] = q / np.linalg.norm(q, axis=1, keepdims=True)
    return out


def _interp_between(t_ep, stored, after, before, t):
    """Interpolate the error between stored epochs: from ``after[r]`` (post-feedback at
    stored epoch r) to ``before[r+1]`` (pre-feedback at r+1); at a stored epoch itself
    the post-feedback value."""
    ts = t_ep[stored]
    r = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, ts.size - 1)
    out = after[r].copy()
    inner = r < ts.size - 1
    ri = r[inner]
    w = ((t[inner] - ts[ri]) / (ts[ri + 1] - ts[ri]))[:, None]
    out[inner] = after[ri] + w * (before[ri + 1] - after[ri])
    return out


def _sum3_rows(x, s):
    """Compensation change (M, 3) of a feedback-layout entry for every row of ``x``
    (as :func:`sinslab.fusion.feedback._sum3` for one row)."""
    if s is None:
        return 0.0
    if isinstance(s, np.ndarray) and s.ndim == 2:
        xp = np.concatenate([x, np.zeros((x.shape[0], 1))], 1)
        return xp[:, s].sum(1)
    return x[:, s]


def _route(layout):
    from sinslab.fusion.feedback import FeedbackLayout
    names = list(layout.names)
    if not all(b in names for b in ("phi", "dv", "dp")):
        return None
    return FeedbackLayout.from_model(layout)


def smooth(run, *, stream=0, check=True, chunk=4096) -> SmoothedRun:
    """Smooth a driver run that stored its history (:func:`sinslab.fusion.driver.run` with
    ``history=History(...)``, or a :func:`sinslab.fusion.loosely_coupled.loosely_coupled`
    result made with ``history=``).

    Parameters
    ----------
    run : DriverResult or LooselyCoupled
        With ``history``, ``t``, ``nav``, ``x``, ``sigma``, ``gyro_bias``, ``accel_bias``,
        ``layout``.
    stream : int
        The navigation stream whose solution is corrected.
    check, chunk
        As in :func:`sinslab.estimation.smoother.rts_smooth`.

    Returns
    -------
    SmoothedRun

    Raises
    ------
    ValueError
        The run has no stored history.
    """
    h = getattr(run, "history", None)
    if h is None or h.epochs is None:
        raise ValueError("the run stored no history: run the filter with history=History() "
                         "to smooth it")
    # float32 storage rounds Φ and x: the stored prediction no longer passes the 1e-6 σ
    # consistency check of eq. (3), so it is recomputed from the stored x and Φ
    x_prior = h.x_prior if h.dtype == np.float64 else None
    s = rts_smooth(h.x_post, _PostView(h), x_prior, h.P_prior, h.Phi, feedback=h.feedback,
                   covariance="diag", check=check, chunk=chunk)
    t = np.asarray(run.t, dtype=float)
    stored = h.epochs
    k = np.arange(t.size)
    # interpolation on the epoch index (exact at the stored epochs)
    x = _interp_between(k.astype(float), stored, s.x_corrected, s.x, k.astype(float))
    sig = _interp_between(k.astype(float), stored, s.sigma, s.sigma, k.astype(float))
    nav_all = run.nav
    rows = np.asarray(nav_all[stream] if isinstance(nav_all, tuple) else nav_all, dtype=float)
    # with several streams the core blocks are differences of two INS (DifferenceModel):
    # x and σ are smoothed, no single solution is corrected
    route = _route(run.layout) if not (isinstance(nav_all, tuple) and len(nav_all) > 1) else None
    fwd = rows
    if route is not None and not np.any(h.feedback):
        # feed-forward run: the forward solution is the free INS minus the filter estimate
        fwd = sd.correct_rows(rows, *route.nav_errors(np.asarray(run.x, dtype=float)))
    nav = sd.correct_rows(rows, *route.nav_errors(x)) if route is not None else None
    gb = ab = None
    g_all, a_all = run.gyro_bias, run.accel_bias
    g = g_all[stream] if isinstance(g_all, tuple) else g_all
    a = a_all[stream] if isinstance(a_all, tuple) else a_all
    if route is not None and g is not None:
        gb = np.asarray(g, dtype=float) + _sum3_rows(x, route.gyro)
        ab = np.asarray(a, dtype=float) + _sum3_rows(x, route.accel)
    return SmoothedRun(t, x, sig, nav, gb, ab, fwd, stored, s.x_corrected, s.sigma, s.x,
                       s.dropped, route)
