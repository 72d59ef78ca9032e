"""Raw time-stamped IMU samples -> a uniform :class:`~sinslab.core.records.ImuRecord`:
the shared container of every IMU reader (:class:`ImuData`), time-stamp checks with
file/line positions, rates -> increments, and gap/jitter handling on a uniform grid."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core.records import ImuRecord, all_finite

__all__ = ["ImuData", "uniform_increments", "rates_to_increments", "check_stamps", "where"]


def where(path, line=None):
    """``path:line`` (or ``path``) for error messages."""
    return f"{path}:{line}" if line is not None else f"{path}"


@dataclass(frozen=True)
class ImuData:
    """An IMU recording read by :func:`~sinslab.data.load.load_imu` (any format).

    Attributes
    ----------
    imu : ImuRecord
        Increments on a uniform grid, RFU vehicle body axes (mount applied).
    gaps : ndarray, shape (k, 2)
        ``[start, length]`` [s] of the gaps found in the raw time stamps (intervals longer
        than 1.5 nominal intervals); they are bridged with the mean rate across the gap.
    path : str
    format : str
    n_raw : int
        Samples in the file.
    jitter : float
        RMS deviation of the raw sampling interval from the nominal one [s].
    meta : dict
        Format-specific extras (PSINS header, RTKLIB tag times ...).
    """

    imu: ImuRecord
    gaps: np.ndarray
    path: str
    format: str
    n_raw: int
    jitter: float = 0.0
    meta: dict = None


def check_stamps(t, path, lines):
    """Raise ValueError naming the file line of the first non-finite, duplicated or
    decreasing stamp of ``t`` (``lines[i]`` is the line of sample i)."""
    _steps(t, path, lines)


def _steps(t, path, lines):
    """:func:`check_stamps`, returning the intervals ``np.diff(t)``. Each test screens by
    reductions (no array of the record's size made) and looks for the first offender only
    when the screen fails."""
    if not all_finite(t):
        bad = ~np.isfinite(t)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(f"{where(path, lines[i])}: time stamp is not a finite number")
    d = np.diff(t)
    if d.size and not d.min() > 0:
        if (d == 0).any():
            i = int(np.argmax(d == 0)) + 1
            raise ValueError(f"{where(path, lines[i])}: duplicated time stamp {float(t[i])!r}")
        if (d < 0).any():
            i = int(np.argmax(d < 0)) + 1
            order = "decrease throughout: the record is in reverse order" if d.size > 1 and (d < 0).all() else "not sorted"
            raise ValueError(f"{where(path, lines[i])}: time stamps {order} ({float(t[i])!r} follows {float(t[i - 1])!r})")
    return d


def uniform_increments(t, dth, dv, *, path="", lines=None, dt=None, max_gap=1.0, allow_gaps=False):
    """Increments at (possibly jittery or gappy) end times -> a uniform :class:`ImuRecord`.

    The cumulative angle and velocity (sums of increments at the raw end times) are
    interpolated linearly onto a uniform grid and differenced: jitter is absorbed, a gap
    is bridged with the mean rate across it. Gaps longer than ``max_gap`` [s] raise
    ValueError unless ``allow_gaps``. Returns ``(ImuRecord, gaps (k, 2), jitter_rms)``.
    """
    t = np.asarray(t, dtype=float)
    n = t.size
    lines = list(range(1, n + 1)) if lines is None else lines
    if n < 2:
        raise ValueError(f"{where(path)}: needs at least 2 samples, got {n}")
    d = _steps(t, path, lines)
    dt_nom = float(np.median(d)) if dt is None else float(dt)
    gap_i = np.flatnonzero(d > 1.5 * dt_nom) if d.max() > 1.5 * dt_nom else np.zeros(0, dtype=np.intp)
    gaps = np.stack([t[gap_i], d[gap_i]], -1) if gap_i.size else np.zeros((0, 2))
    if gap_i.size and not allow_gaps:
        long_ = gap_i[d[gap_i] > max_gap]
        if long_.size:
            i = int(long_[0])
            raise ValueError(f"{where(path, lines[i + 1])}: gap of {d[i]:.3f} s in the IMU record "
                             f"after t = {t[i]:.3f} s (longer than max_gap = {max_gap:g} s); "
                             "allow it explicitly to navigate across")
    if gap_i.size == 0:
        # every interval counts (d[ok] is d); the deviations r squared in place, the bound
        # on |r| tested on its extremes: the values of the expressions below in the
        # other branch, without their arrays of the record's size
        r = d - dt_nom
        uniform = r.max() <= 1e-4 * dt_nom and -r.min() <= 1e-4 * dt_nom
        jitter = float(np.sqrt(np.mean(np.square(r, out=r))))
    else:
        ok = d <= 1.5 * dt_nom
        jitter = float(np.sqrt(np.mean((d[ok] - dt_nom) ** 2))) if ok.any() else 0.0
        uniform = False
    if uniform and abs(t[-1] - t[0] - (n - 1) * dt_nom) <= 1e-9 * max(1.0, abs(t[-1])):
        return ImuRecord(t, dth, dv, dt_nom), gaps, jitter
    tc = np.concatenate([[t[0] - dt_nom], t])
    m = int(math.floor((tc[-1] - tc[0]) / dt_nom + 1e-9))
    grid = tc[0] + dt_nom * np.arange(m + 1)
    out = []
    for a in (dth, dv):
        c = np.vstack([np.zeros((1, 3)), np.cumsum(a, 0)])
        ci = np.stack([np.interp(grid, tc, c[:, k]) for k in range(3)], -1)
        out.append(np.diff(ci, axis=0))
    return ImuRecord(grid[1:], out[0], out[1], dt_nom), gaps, jitter


def rates_to_increments(t, w, f, dt_nom):
    """Rectangular rule with the actual intervals; across a gap the mean of the rates at
    its two ends is held."""
    d = np.diff(t, prepend=t[0] - dt_nom)
    big = d > 1.5 * dt_nom
    w = np.array(w, dtype=float)
    f = np.array(f, dtype=float)
    if big.any():
        i = np.flatnonzero(big)
        i = i[i > 0]
        w[i] = 0.5 * (w[i] + w[i - 1])
        f[i] = 0.5 * (f[i] + f[i - 1])
    return w * d[:, None], f * d[:, None]
