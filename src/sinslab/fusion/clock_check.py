"""Are the IMU and the GNSS on one clock? A whole-second check before any filtering.

An IMU logged in UTC beside a receiver in GPS time is 18 s off (the leap seconds of 2017),
one logged with a truncated or rounded second is 1 s off; a filter fed such a pair still
converges to something — on a drive of NaveGo's kind a heading off by 240° and a gyro bias of
10⁵ °/h — and every claim of the run can pass. The turns tell: the vertical gyro rate and
the course rate of the GNSS velocity (Doppler, or the fixes' position differences) are the
same signal, and their cross-correlation over lags of whole seconds peaks where the clocks
agree. :func:`clock_check` searches ±``search`` s in steps of a tenth of a second and
reports the lag of the peak, its correlation and how it stands against the correlation at
lag zero.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core.records import Fixes, ImuRecord

__all__ = ["ClockCheck", "clock_check", "LEAP_SECONDS"]

#: GPST − UTC since 2017-01-01 [s]: the usual whole-second offset of a UTC-stamped log
LEAP_SECONDS = 18


@dataclass(frozen=True)
class ClockCheck:
    """Result of :func:`clock_check`."""

    lag: float             #: [s] the IMU stamps are this much late against the GNSS (peak)
    correlation: float     #: at the peak
    at_zero: float         #: correlation at lag 0 (within ±0.5 s)
    whole_seconds: int     #: the lag rounded to whole seconds
    turning: float         #: [s] of the overlap with a clear turn (course rate above 2 °/s)
    #: vertical gyro rate over course rate in the turns, at the lag within ±0.5 s of the
    #: strongest correlation of either sign (least squares; 1 for a level IMU read in its
    #: own units, 180/π for degrees read as radians, −1 for a z axis pointing down)
    rate_ratio: float = math.nan
    rate_correlation: float = math.nan   #: the correlation at that lag
    #: [s] the median interval of the fixes: the course rate is known at that spacing only
    fix_interval: float = 1.0

    @property
    def resolution(self) -> float:
        """[s] the smallest lag the check can tell from zero: half a second, or half the fix
        interval where the fixes are sparser than 1 Hz (the course rate between two fixes
        is interpolated, so where in that interval a turn starts is not known)."""
        return max(0.5, 0.5 * self.fix_interval)

    @property
    def off(self) -> bool:
        """The clocks differ by a second or more: a clear peak (correlation at least 0.6)
        at least :attr:`resolution` from zero and above the correlation of the stamps as
        given (the fine estimator of :func:`sinslab.fusion.recorded.estimate_time_offset`
        searches ±1 s and would lock on a wrong turn beyond it)."""
        return (abs(self.lag) >= self.resolution and self.correlation >= 0.6
                and self.correlation - self.at_zero >= 0.01)

    def describe(self) -> str:
        leap = " (GPST − UTC: an IMU stamped in UTC?)" if abs(self.whole_seconds) == LEAP_SECONDS else ""
        return (f"the IMU turn rates match the GNSS course rates {self.lag:+.1f} s later "
                f"(correlation {self.correlation:.2f}; {self.at_zero:.2f} at the stamps as given){leap}")


def _course_rate(t, vel, min_speed):
    crs = np.unwrap(np.arctan2(vel[:, 0], vel[:, 1]))
    rate = -np.gradient(crs, t)                      # counter-clockwise, as the gyro's z
    rate[np.hypot(vel[:, 0], vel[:, 1]) < min_speed] = 0.0
    return rate


def clock_check(imu: ImuRecord, fixes: Fixes, *, search=30.0, step=0.1, min_speed=2.0, gyro_bias_z=0.0,
                span=900.0):
    """Cross-correlate the vertical gyro rate with the course rate of the fixes' velocity
    (ENU; the position differences when the fixes have none) over lags ``±search`` [s], on
    at most ``span`` s of the overlap (its start: the check costs the same on any record).
    Returns a :class:`ClockCheck`, or None when the overlap holds no turn."""
    if fixes.vel is not None:
        vel = fixes.vel
    else:
        from sinslab.core.earth import radii
        rm, rn = radii(fixes.lat, fixes.h)
        vel = np.column_stack([np.gradient(fixes.lon, fixes.t) * rn * np.cos(fixes.lat),
                               np.gradient(fixes.lat, fixes.t) * rm, np.zeros(len(fixes))])
    cr = _course_rate(fixes.t, vel, min_speed)
    lo = max(float(fixes.t[0]), float(imu.t[0])) + search
    hi = min(float(fixes.t[-1]), float(imu.t[-1])) - search
    if hi - lo < 30.0:
        lo, hi = max(float(fixes.t[0]), float(imu.t[0])), min(float(fixes.t[-1]), float(imu.t[-1]))
        search = min(search, 0.25 * (hi - lo))
        lo, hi = lo + search, hi - search
        if hi - lo < 10.0:
            return None
    grid = np.arange(lo, min(hi, lo + span), 0.1)
    ref = np.interp(grid, fixes.t, cr)
    turning = float(np.sum(np.abs(ref) > math.radians(2.0)) * 0.1)
    if turning < 5.0 or np.std(ref) < 1e-3:
        return None
    tw = imu.t - 0.5 * imu.dt
    wz = imu.dtheta[:, 2] / imu.dt - gyro_bias_z
    # the gyro averaged over 0.1 s bins (the grid), then shifted
    lags = np.arange(-search, search + step / 2, step)
    c = np.array([np.corrcoef(np.interp(grid + o, tw, wz), ref)[0, 1] for o in lags])
    c = np.nan_to_num(c, nan=-1.0)
    i = int(np.argmax(c))
    near0 = np.abs(lags) <= 0.5
    k0 = int(np.flatnonzero(near0)[np.argmax(np.abs(c[near0]))])
    turn = np.abs(ref) > math.radians(2.0)
    gz = np.interp(grid + lags[k0], tw, wz)[turn]
    ratio = float(np.dot(gz, ref[turn]) / np.dot(ref[turn], ref[turn]))
    return ClockCheck(float(lags[i]), float(c[i]), float(np.max(c[near0])), int(round(float(lags[i]))), turning,
                      ratio, float(c[k0]), float(np.median(np.diff(fixes.t))))
