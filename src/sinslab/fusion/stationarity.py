"""Stationarity detection for zero-velocity / zero-rate updates.

:func:`detect` tests windows of IMU samples for rest: the mean specific-force magnitude
close to local gravity, a small specific-force standard deviation (no vibration of a
running engine in motion, no acceleration) and a small mean angular-rate magnitude. The
thresholds are in physical units. :func:`from_flags` turns a boolean column of a log (a
unit's own "stationary" flag) into the same intervals. Both return ``(start, end)`` time
intervals [s] for :class:`sinslab.fusion.measurements.ZeroVelocity` and
:class:`~sinslab.fusion.measurements.ZeroRate`.
"""
from __future__ import annotations

import numpy as np

from sinslab.core.blocks import BLOCK_ROWS, block_ranges, release_pages
from sinslab.core.earth import gravity

__all__ = ["detect", "from_flags", "intervals_from_mask"]


def intervals_from_mask(t_start, t_end, mask, min_duration=0.0):
    """Merge consecutive true samples into intervals.

    Parameters
    ----------
    t_start, t_end : array_like (N,)
        Start and end time [s] of each sample / window.
    mask : array_like of bool (N,)
    min_duration : float
        Intervals shorter than this [s] are dropped.

    Returns
    -------
    ndarray, shape (K, 2)
        ``(start, end)`` [s].
    """
    m = np.asarray(mask, dtype=bool).ravel()
    t_start = np.asarray(t_start, dtype=float).ravel()
    t_end = np.asarray(t_end, dtype=float).ravel()
    if not (m.size == t_start.size == t_end.size):
        raise ValueError(f"mask of {m.size} for {t_start.size} start and {t_end.size} end times")
    d = np.diff(np.r_[0, m.astype(np.int8), 0])
    a, b = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    out = np.stack([t_start[a], t_end[b]], -1) if a.size else np.zeros((0, 2))
    return out[(out[:, 1] - out[:, 0]) >= min_duration] if out.size else out


def from_flags(t, flags, min_duration=0.0):
    """Stationary intervals from a boolean column (true = at rest) sampled at ``t`` [s].

    Each true sample covers from its own time to the next sample's time (the last one to
    itself plus the median spacing).
    """
    t = np.asarray(t, dtype=float).ravel()
    f = np.asarray(flags)
    if f.dtype != bool:
        if not np.all(np.isin(f, (0, 1))):
            raise ValueError("stationarity flags must be boolean (or 0/1)")
        f = f.astype(bool)
    if f.shape != t.shape:
        raise ValueError(f"{f.size} flags for {t.size} times")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValueError("flag times must be strictly increasing")
    step = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    return intervals_from_mask(t, np.r_[t[1:], t[-1:] + step], f, min_duration)


def detect(imu, lat, *, h=0.0, window=1.0, f_tol=0.05, f_std=0.05, w_max=0.005,
           min_duration=2.0, w_std=None, gyro_bias=None):
    """Stationary intervals of an IMU record.

    A window of ``window`` seconds (non-overlapping) is at rest when all hold:
    ``| |f̄| − g(L, h) | < f_tol`` [m/s²], the per-axis standard deviation of the
    specific force has norm ``< f_std`` [m/s²], and ``|ω̄| < w_max`` [rad/s] (Earth rate is
    7.3e-5 rad/s, so MEMS biases set the floor of ``w_max``); with ``w_std`` [rad/s] also
    the norm of the per-axis standard deviation of the rate (road vibration turns the
    body even when its mean rate is zero). The windows are tested a block of them at a
    time (each window on its own samples: the same answer for any block), so a record
    mapped from files is read a block at a time.

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
        Increments (``dtheta``, ``dv``, sample ``dt``, end times ``t``).
    lat : float
        Latitude [rad] for gravity.
    h : float
        Height [m].
    window, f_tol, f_std, w_max, min_duration, w_std
        See above; ``min_duration`` [s] drops shorter intervals.
    gyro_bias : array_like (3,), optional
        Removed from the gyro increments first [rad/s].

    Returns
    -------
    ndarray, shape (K, 2)
        ``(start, end)`` [s] of the stationary intervals.
    """
    if not (window > 0 and f_tol > 0 and f_std > 0 and w_max > 0 and (w_std is None or w_std > 0)):
        raise ValueError("window, f_tol, f_std, w_max and w_std must be > 0")
    dt = float(imu.dt)
    k = max(1, int(round(window / dt)))
    N = (len(imu) // k) * k
    if N == 0:
        raise ValueError(f"the IMU record is shorter than one {window} s window")
    g = float(gravity(lat, h))
    gb = None if gyro_bias is None else np.asarray(gyro_bias, dtype=float) * imu.dt
    rest, starts, ends = [], [], []
    for a, b in block_ranges(N, BLOCK_ROWS, k):
        f = (imu.dv[a:b] / dt).reshape(-1, k, 3)
        dth = imu.dtheta[a:b] if gb is None else imu.dtheta[a:b] - gb
        w = (dth / dt).reshape(-1, k, 3)
        fm = f.mean(1)
        r = np.abs(np.linalg.norm(fm, axis=1) - g) < f_tol
        r &= np.linalg.norm(f.std(1), axis=1) < f_std
        r &= np.linalg.norm(w.mean(1), axis=1) < w_max
        if w_std is not None:
            r &= np.linalg.norm(w.std(1), axis=1) < w_std
        t = np.asarray(imu.t[a:b], dtype=float).reshape(-1, k)
        rest.append(r)
        starts.append(t[:, 0] - dt)
        ends.append(t[:, -1])
        release_pages(imu.t, imu.dtheta, imu.dv)
    return intervals_from_mask(np.concatenate(starts), np.concatenate(ends), np.concatenate(rest), min_duration)
