"""Time stamps of recorded streams: their nominal interval and jitter, and samples that a
logger held and repeated between a slower sensor's epochs.

A recorded stream's stamps are never exactly its nominal interval apart: a 1 Hz receiver
logged against another clock stamps its fixes 1.000019 s apart, a USB logger's ms ticks
jitter by a millisecond. Every time comparison on such stamps takes its tolerance from
the stamps themselves (:func:`stamp_step`), never from a fixed 1 ns; a window of "1 s" of a
stream is a whole number of its intervals (:func:`whole_intervals`).

A unit that logs a 1 Hz receiver's solution in every row of a 50 Hz record repeats each
fix until the next one: the repeats are not independent measurements (50 updates with
one error would weigh it 50 times) and their stamps are not the fix's validity time.
:func:`held_runs` finds such a stream and the first row of each receiver epoch.

A sensor logged on another clock than the IMU's (seconds of GPS week against seconds since
power-on, milliseconds, UTC against GPST) barely overlaps the IMU record, if at all:
:func:`check_time_base` refuses it.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["stamp_step", "whole_intervals", "held_runs", "check_time_base"]

#: robust jitter multiples a stamp interval may deviate by and still be "one interval"
JITTER_SIGMAS = 6.0


def stamp_step(t: ArrayLike) -> tuple[float, float]:
    """Nominal interval and the tolerance of one interval of strictly increasing stamps.

    ``dt`` is the median interval; the tolerance is ``JITTER_SIGMAS`` × the robust scatter
    of the intervals (1.4826 × their median absolute deviation), at least 1e-6 ``dt``
    (stamps printed to a few digits) and at most ``dt / 4`` (a quarter interval off is a
    different epoch, whatever the jitter).

    Parameters
    ----------
    t : array_like (N,), N >= 2
        Stamps [s].

    Returns
    -------
    (dt, tol) : float, float
        [s].
    """
    t = np.asarray(t, dtype=float).ravel()
    if t.size < 2:
        raise ValueError("the interval of a stream needs at least 2 stamps")
    d = np.diff(t)
    dt = float(np.median(d))
    if not dt > 0:
        raise ValueError(f"stamps do not increase (median interval {dt} s)")
    jit = 1.4826 * float(np.median(np.abs(d - dt)))
    return dt, float(min(max(JITTER_SIGMAS * jit, 1e-6 * dt), 0.25 * dt))


def whole_intervals(t: ArrayLike, length: float) -> tuple[int, float, float]:
    """``length`` [s] as a whole number of the stream's intervals.

    Returns ``(n, dt, tol)``: ``n >= 1`` intervals nearest to ``length``, and
    :func:`stamp_step`'s ``dt`` and ``tol``; a stretch ``t[j] .. t[j + n]`` is gap-free when
    ``|t[j + n] − t[j] − n dt| <= n tol``.
    """
    dt, tol = stamp_step(t)
    n = max(1, int(round(float(length) / dt)))
    return n, dt, tol


def held_runs(values: ArrayLike, *, min_fraction: float = 0.5) -> np.ndarray | None:
    """First rows of the runs of a held (sample-and-hold) stream, or None.

    A row is a repeat when every one of its values equals the row before bit for bit. The
    stream is taken as held when at least ``min_fraction`` of its rows are repeats (a
    receiver logged at a faster rate: 1 Hz fixes in 50 Hz rows are 98 % repeats; an
    honest stream repeats a row only by chance, a parked car's rounded position); then
    the index of the first row of every run is returned, else None.

    Parameters
    ----------
    values : array_like (N, k)
        The columns that change at every new epoch (position, velocity, σ), NaN allowed
        (equal NaNs count as equal).

    Returns
    -------
    ndarray of int (M,) or None
    """
    v = np.asarray(values, dtype=float)
    v = v.reshape(v.shape[0], -1)
    if v.shape[0] < 3:
        return None
    same = np.all((v[1:] == v[:-1]) | (np.isnan(v[1:]) & np.isnan(v[:-1])), axis=1)
    if not math.isfinite(min_fraction) or same.mean() < min_fraction:
        return None
    return np.flatnonzero(np.r_[True, ~same])


def check_time_base(t: np.ndarray, t_lo: float, t_hi: float, source: str, *, least: float = 0.5) -> None:
    """Refuse stamps ``t`` (increasing) that overlap the IMU record ``t_lo..t_hi`` [s] over
    less than ``least`` of the shorter of the two spans: another clock. Raises ValueError
    naming ``source`` (a file) and both spans."""
    a, b = float(t[0]), float(t[-1])
    over = min(b, t_hi) - max(a, t_lo)
    span = min(b - a, t_hi - t_lo)
    if span <= 0 or over < least * span:
        raise ValueError(f"{source}: its times {a:.3f}..{b:.3f} s do not overlap the IMU record "
                         f"{t_lo:.3f}..{t_hi:.3f} s (covered {max(over, 0.0) / max(span, 1e-300):.0%}): "
                         "a different time base? (seconds of week vs seconds since start, ms vs s, "
                         "UTC vs GPST)")
