"""When a measurement's items are processed: the arrival epochs of timed items
(:func:`arrival_epochs`, :class:`Timed`), measurements held on filter epochs inside
intervals (``_OnEpochs``) and the innovation gate that may refuse an update
(:class:`InnovationGate`), the robust weighting that may soften one
(:class:`RobustWeighting`), and the gate of single rows (:class:`RowGate`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["arrival_epochs", "Timed", "InnovationGate", "RobustWeighting", "robust_weighting", "robust_R", "RowGate"]


def arrival_epochs(t_valid, t_arrive, grid, *, outages=(), windows=None):
    """Arrival epochs of time-stamped records: the first filter epoch at or after each
    arrival; records arriving after the run, valid inside an outage ``(start, length)``
    [s], or processed outside every window ``(start, end)`` [s] are dropped.

    Returns
    -------
    dict
        ``{epoch index: [record indices]}``.
    """
    t_valid = np.asarray(t_valid, dtype=float)
    n_ep = grid.n
    t_ep = grid.t
    e_arr = grid.epoch_at_or_after(t_arrive)
    keep = e_arr <= n_ep
    for s, ln in outages:
        keep &= ~((t_valid >= s) & (t_valid < s + ln))
    if windows is not None:
        w = np.asarray(windows, dtype=float).reshape(-1, 2)
        te = t_ep[np.minimum(e_arr, n_ep)]
        keep &= ((te[:, None] >= w[:, 0] - 1e-9) & (te[:, None] <= w[:, 1] + 1e-9)).any(1)
    out = {}
    for j in np.flatnonzero(keep):
        out.setdefault(int(e_arr[j]), []).append(int(j))
    return out


class Timed:
    """Time stamps and schedule shared by the fix measurements (``t_valid``, ``t_arrive``,
    outages and windows: :func:`arrival_epochs`); a measurement of time-stamped records
    subclasses it and calls ``_init_times``. No gate by default (the
    :class:`~sinslab.fusion.measurements.Measurement` protocol's ``gate`` and ``row_gate``)."""

    gate = None
    row_gate = None

    def _init_times(self, t_valid, t_arrive, outages, windows):
        self.t_valid = np.atleast_1d(np.asarray(t_valid, dtype=float))
        self.t_arrive = (self.t_valid.copy() if t_arrive is None
                         else np.atleast_1d(np.asarray(t_arrive, dtype=float)))
        if self.t_arrive.shape != self.t_valid.shape:
            raise ValueError(f"{len(self.t_arrive)} arrival times for {len(self.t_valid)} fixes")
        self.outages = tuple(outages)
        self.windows = windows

    def __len__(self):
        return self.t_valid.size

    def epochs(self, grid):
        return arrival_epochs(self.t_valid, self.t_arrive, grid, outages=self.outages,
                              windows=self.windows)

    def times(self, item):
        return float(self.t_valid[item]), float(self.t_arrive[item])


def _intervals(intervals):
    if intervals is None:
        return None
    w = np.asarray(intervals, dtype=float).reshape(-1, 2)
    if not np.all(np.isfinite(w)) or np.any(w[:, 1] < w[:, 0]):
        raise ValueError("intervals must be finite (start, end) pairs [s] with end >= start")
    return w


def robust_R(ep, z, H, R, p):
    """``R`` inflated for a measurement its prior cannot explain (Chang 2014, "Robust
    Kalman filtering based on Mahalanobis distance as outlier judging criterion", J.
    Geodesy 88): with ``d = νᵀ S⁻¹ ν`` (``ν = z − H x``, ``S = H P Hᵀ + R``) above the
    ``1 − p`` quantile χ² of its dimension, ``R`` is multiplied by ``d / χ²`` — a biased
    stretch of fixes (multipath that makes a receiver's velocity 0.3 m/s wrong for seconds
    under a stated 0.05 m/s) pulls the filter as little as its consistency allows instead
    of setting its velocity and tilt. Returns ``(R, factor)`` (factor 1: untouched; no
    prior, for a lagged item: untouched)."""
    if p is None or ep.prior is None:
        return R, 1.0
    x, P = ep.prior
    z = np.atleast_1d(np.asarray(z, dtype=float))
    R = np.broadcast_to(np.asarray(R, dtype=float), z.shape).copy()
    nu = z - H @ x
    S = H @ P @ H.T + np.diag(R)
    try:
        d = float(nu @ np.linalg.solve(S, nu))
    except np.linalg.LinAlgError:
        return R, 1.0
    lim = _chi2_limit(z.size, p)
    if not d > lim:
        return R, 1.0
    return R * (d / lim), d / lim


#: the weight below which a row counts as rejected (IGG-III past k1): its R is divided by it
MIN_WEIGHT = 1e-10


@dataclass(frozen=True)
class RobustWeighting:
    """How a measurement its prior cannot explain is softened before the update.

    Kinds
    -----
    ``"chang"``
        The whole measurement (Chang 2014, :func:`robust_R`): ``R · d/χ²`` where the
        Mahalanobis distance ``d`` passes the ``1 − p`` quantile.
    ``"huber"``
        Row by row (an M-estimate in one step, the Huber weight of each standardised
        innovation ``ṽ_i = ν_i / √S_ii``, ``S = H P Hᵀ + R``): ``w = 1`` for ``|ṽ| <= k0``,
        else ``k0/|ṽ|``; ``R_ii ← R_ii / w``.
    ``"igg3"``
        Row by row with Yang's IGG-III weights (Yang, Song & Xu 2002, "Robust estimator for
        correlated observations based on bifactor equivalent weights", J. Geodesy 76):
        ``w = 1`` for ``|ṽ| <= k0``, ``(k0/|ṽ|)((k1 − |ṽ|)/(k1 − k0))²`` up to ``k1``,
        and the row rejected beyond (``w =`` :data:`MIN_WEIGHT`).

    The existing innovation gate (:class:`InnovationGate`) refuses an update whole; a
    robust weighting keeps the consistent rows of a fix and lets an outlying one pull
    as little as its residual allows. A lagged item (no prior at hand) is used as stated.

    Attributes
    ----------
    kind : {"chang", "huber", "igg3"}
    p : float
        ``chang``: probability that a consistent measurement is touched.
    k0, k1 : float
        ``huber``: k0 [σ]; ``igg3``: k0 < k1 [σ].
    """

    kind: str = "huber"
    p: float = 0.01
    k0: float = 1.5
    k1: float = 3.0

    def __post_init__(self):
        if self.kind not in ("chang", "huber", "igg3"):
            raise ValueError(f"robust weighting must be chang, huber or igg3, got {self.kind!r}")
        if not 0 < self.p < 1:
            raise ValueError(f"robust probability must be in (0, 1), got {self.p}")
        if not (0 < self.k0 < self.k1 and math.isfinite(self.k1)):
            raise ValueError(f"robust thresholds need 0 < k0 < k1, got {self.k0}, {self.k1}")

    def limit(self, m):
        """``chang``: the χ² quantile of ``m`` rows."""
        return _chi2_limit(m, self.p)

    def row_weights(self, v):
        """Weights (m,) of standardised innovations ``v`` (m,)."""
        a = np.abs(np.asarray(v, dtype=float))
        w = np.ones_like(a)
        big = a > self.k0
        if self.kind == "huber":
            w[big] = self.k0 / a[big]
        elif self.kind == "igg3":
            mid = big & (a <= self.k1)
            w[mid] = self.k0 / a[mid] * ((self.k1 - a[mid]) / (self.k1 - self.k0)) ** 2
            w[a > self.k1] = MIN_WEIGHT
            w = np.maximum(w, MIN_WEIGHT)
        return w

    def weigh(self, ep, z, H, R):
        """``(R, factor)``: ``R`` (m,) with its rows inflated, the largest inflation (1:
        untouched)."""
        if self.kind == "chang":
            return robust_R(ep, z, H, R, self.p)
        if ep.prior is None:
            return np.asarray(R, dtype=float), 1.0
        x, P = ep.prior
        z = np.atleast_1d(np.asarray(z, dtype=float))
        R = np.broadcast_to(np.asarray(R, dtype=float), z.shape).copy()
        nu = z - H @ x
        s = np.sqrt(np.einsum("ij,jk,ik->i", H, P, H) + R)
        w = self.row_weights(nu / s)
        if np.all(w == 1.0):
            return R, 1.0
        return R / w, float(1.0 / w.min())


def robust_weighting(spec):
    """A :class:`RobustWeighting` from ``spec``: None (none), a probability (Chang's rule,
    as ``FixSpec.robust`` always took it), a weighting, or text ``"huber[:k0]"``,
    ``"igg3[:k0:k1]"``, ``"chang[:p]"``."""
    if spec is None or isinstance(spec, RobustWeighting):
        return spec
    if isinstance(spec, str):
        kind, *args = spec.strip().lower().split(":")
        try:
            vals = [float(a) for a in args]
        except ValueError:
            raise ValueError(f"robust weighting {spec!r}: the numbers after the kind must be numbers") from None
        if kind == "chang" and len(vals) <= 1:
            return RobustWeighting("chang", *vals)
        if kind in ("huber", "igg3") and len(vals) <= (1 if kind == "huber" else 2):
            return RobustWeighting(kind, 0.01, *vals)
        raise ValueError(f"robust weighting {spec!r}: give huber[:k0], igg3[:k0:k1] or chang[:p]")
    return RobustWeighting("chang", float(spec))


def _chi2_limit(m, p, limits={}):
    if (m, p) not in limits:
        from scipy.special import chdtri       # χ² quantile, without scipy.stats' import
        limits[(m, p)] = float(chdtri(m, p))
    return limits[(m, p)]


class InnovationGate:
    """Reject an update whose innovation the filter's own covariance cannot explain.

    An aiding measurement is an assumption (the vehicle is at rest, does not slide
    sideways); where it is false its innovation ``ν = z − H x`` is far outside
    ``S = H P Hᵀ + R``. The update is applied only when ``νᵀ S⁻¹ ν`` is at most the
    ``1 − p`` quantile of χ² with ``m`` degrees of freedom (``m`` = rows of ``z``);
    a consistent measurement is rejected with probability ``p``.

    A measurement declares its gate as its ``gate`` attribute (the
    :class:`~sinslab.fusion.measurements.Measurement` protocol); the driver applies it
    before each update made on arrival and records each decision (the gate keeps no
    record: :attr:`sinslab.fusion.driver.DriverResult.decisions`).

    Attributes
    ----------
    p : float
        False-rejection probability per update.
    """

    def __init__(self, p=1e-6):
        if not (0 < p < 1):
            raise ValueError(f"gate probability must be in (0, 1), got {p}")
        self.p = float(p)
        self._limit = {}

    def limit(self, m):
        """χ² threshold for ``m`` rows."""
        if m not in self._limit:
            from scipy.special import chdtri       # χ² quantile, without scipy.stats' import
            self._limit[m] = float(chdtri(m, self.p))
        return self._limit[m]

    def test(self, x, P, z, H, R):
        """``(passed, nis)`` of the update ``(z, H, R)`` against the prior ``x, P``:
        inside the gate when ``νᵀ S⁻¹ ν`` is at most :meth:`limit` of its rows."""
        z = np.atleast_1d(np.asarray(z, dtype=float))
        H = np.atleast_2d(H)
        R = np.asarray(R, dtype=float)
        nu = z - H @ x
        S = H @ P @ H.T + (np.diag(np.broadcast_to(R, z.shape)) if R.ndim < 2 else R)
        try:
            nis = float(nu @ np.linalg.solve(S, nu))
        except np.linalg.LinAlgError:
            nis = math.inf
        return nis <= self.limit(z.size), nis


class RowGate:
    """Reject single rows of an update: row ``i`` is refused when
    ``ν_i² / (H_i P H_iᵀ + R_i) > sigmas²`` against the filter's prior (a satellite whose
    range the filter's own covariance cannot explain, RTKLIB's innovation test).

    After ``reset`` consecutive epochs whose every row was refused the gate lets one
    epoch through whole (then the filter, not every satellite, is wrong). That count is
    the caller's (the driver keeps it per measurement), so the gate holds no run state.

    Attributes
    ----------
    sigmas : float or None
        The gate in σ of ``H P Hᵀ + R`` (None: every row used; ν and the NIS still formed).
    reset : int
    """

    def __init__(self, sigmas=5.0, reset=10):
        if sigmas is not None and not (sigmas > 0 and math.isfinite(sigmas)):
            raise ValueError(f"row gate must be a number of σ > 0, got {sigmas!r}")
        self.sigmas = None if sigmas is None else float(sigmas)
        self.reset = int(reset)

    def decide(self, rows, prior, streak=0):
        """The decisions on ``rows`` (:class:`~sinslab.fusion.measurements.Rows`) against
        ``prior = (x, P)`` (None: a lagged update, nothing gated and ν not formed).

        Returns ``(rejected (m,) bool, ν (m,), ν²/S (m,), streak)`` over the rows of ``z``
        and the new count of consecutive all-refused epochs."""
        z, H, R = rows.z, rows.H, rows.R
        if prior is None or z.size == 0:
            return np.zeros(z.size, bool), np.full(z.size, np.nan), np.full(z.size, np.nan), streak
        x, P = prior
        nu = z - H @ x
        S = np.einsum("ij,jk,ik->i", H, P, H) + R
        nis = nu * nu / S
        if self.sigmas is None:
            return np.zeros(z.size, bool), nu, nis, streak
        rej = nis > self.sigmas ** 2
        if np.all(rej):
            streak += 1
            if streak > self.reset:
                streak = 0
                rej[:] = False
        else:
            streak = 0
        return rej, nu, nis, streak


class _OnEpochs:
    """Items are filter epochs (the item is the epoch index), optionally restricted to
    time intervals and thinned to every ``every``-th epoch; available at once. ``gate``:
    an :class:`InnovationGate` (or its false-rejection probability) the driver applies
    before each update (None: every update applied)."""

    row_gate = None

    def _init_sched(self, intervals, every, stream, gate=None):
        self.intervals = _intervals(intervals)
        self.every = int(every)
        if self.every < 1:
            raise ValueError(f"every must be >= 1, got {every}")
        self.stream = int(stream)
        self._t = None
        self.gate = gate if (gate is None or isinstance(gate, InnovationGate)) else InnovationGate(gate)

    def _keep(self, t):
        keep = np.ones(t.size, dtype=bool)
        keep[0] = False                                   # no step rate before epoch 0
        if self.intervals is not None:
            w = self.intervals
            keep &= ((t[:, None] >= w[:, 0] - 1e-9) & (t[:, None] <= w[:, 1] + 1e-9)).any(1)
        return keep

    def epochs(self, grid):
        t = grid.t
        self._t = t
        idx = np.flatnonzero(self._keep(t))[::self.every]
        return {int(k): [int(k)] for k in idx}

    def times(self, item):
        t = float(self._t[item])
        return t, t


def _sigma(sigma, m, what):
    s = np.broadcast_to(np.asarray(sigma, dtype=float), (m,)).copy()
    if not np.all(s > 0) or not np.all(np.isfinite(s)):
        raise ValueError(f"{what} sigma must be finite and > 0, got {sigma}")
    return s
