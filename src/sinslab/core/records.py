"""Plain containers for time series: IMU increments, truth, navigation solutions, fixes.

They hold numpy arrays, validate them once on construction, and do nothing else; the
functions of the other modules work on their arrays.

Time convention: an IMU record of N samples covers ``[t0, t0 + N·dt]``; sample k is the
increment over ``(t[k] − dt, t[k]]`` (``t`` holds interval end times). A truth or
navigation series sampled on the same grid has N + 1 epochs ``t0, t[0], ..., t[N−1]``.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field, fields

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from sinslab.core.errors import InputError

if TYPE_CHECKING:                       # to_pandas imports pandas when it is called
    import pandas

__all__ = ["Fixes", "ImuRecord", "NavSeries", "NavState", "all_finite", "check_times"]


def all_finite(a: np.ndarray) -> bool:
    """Whether every value of ``a`` is finite, by two reductions and no array of ``a``'s
    size: a NaN or an infinity shows in the minimum or the maximum."""
    return a.size == 0 or bool(np.isfinite(a.min()) and np.isfinite(a.max()))


def check_times(t: ArrayLike, name: str = "time", rel_tol: float = 1e-3, uniform: bool = True) -> float:
    """Check a time column: finite, strictly increasing, (optionally) uniform.

    Returns the mean sampling interval [s]. Raises ValueError naming the first problem:
    non-finite values, duplicated or decreasing stamps (with the index), or an interval
    that departs from the mean by more than ``rel_tol`` (relative).
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise ValueError(f"{name} must be one-dimensional, got shape {t.shape}")
    if t.size == 0:
        raise ValueError(f"{name} is empty")
    # each test screens by reductions (no array of the record's size made) and looks for
    # the first offender only when the screen fails; |d − dt| exceeds a bound somewhere
    # iff d.max() − dt or dt − d.min() does (rounding is monotonic and symmetric)
    if not all_finite(t):
        bad = ~np.isfinite(t)
        if bad.any():
            raise ValueError(f"{name} has a non-finite value at index {int(np.argmax(bad))}")
    if t.size < 2:
        return float("nan")
    d = np.diff(t)
    dmin, dmax = d.min(), d.max()
    if not dmin > 0:
        if (d == 0).any():
            i = int(np.argmax(d == 0))
            raise ValueError(f"{name} has a duplicated stamp {float(t[i])!r} at index {i + 1}")
        if (d < 0).any():
            i = int(np.argmax(d < 0))
            raise ValueError(f"{name} is not sorted: {float(t[i + 1])!r} follows {float(t[i])!r} at index {i + 1}")
    dt = (t[-1] - t[0]) / (t.size - 1)
    if uniform and (dmax - dt > rel_tol * dt or dt - dmin > rel_tol * dt):
        dev = np.abs(d - dt) > rel_tol * dt
        if dev.any():
            i = int(np.argmax(dev))
            raise ValueError(f"{name} is not uniformly sampled: interval {float(d[i])!r} s at index "
                             f"{i + 1} vs mean {float(dt)!r} s (tolerance {rel_tol:g} relative)")
    return float(dt)


def _finite(a, name):
    if all_finite(a):
        return
    bad = ~np.isfinite(a)
    if bad.any():
        idx = np.argwhere(bad)[0]
        raise ValueError(f"{name} has a NaN/inf value at sample {int(idx[0])}")


@dataclass(frozen=True)
class ImuRecord:
    """IMU output as body-frame increments.

    Attributes
    ----------
    t : ndarray, shape (N,)
        End time of each increment interval [s], strictly increasing and uniform.
    dtheta : ndarray, shape (N, 3)
        Angle increments ∫ω_ib^b dt over each interval [rad], body frame RFU.
    dv : ndarray, shape (N, 3)
        Velocity increments ∫f^b dt over each interval [m/s], body frame RFU.
    dt : float
        Sampling interval [s] (derived from ``t`` when not given).
    """

    t: np.ndarray
    dtheta: np.ndarray
    dv: np.ndarray
    dt: float = field(default=float("nan"))
    rel_tol: float = field(default=1e-3, repr=False)

    def __post_init__(self):
        t = np.ascontiguousarray(self.t, dtype=float)
        dth = np.ascontiguousarray(self.dtheta, dtype=float)
        dv = np.ascontiguousarray(self.dv, dtype=float)
        if t.ndim != 1 or t.size == 0:
            raise ValueError("IMU record is empty" if t.size == 0 else
                             f"IMU time must be 1-D, got shape {t.shape}")
        for name, a in (("dtheta", dth), ("dv", dv)):
            if a.shape != (t.size, 3):
                raise ValueError(f"IMU {name} must have shape ({t.size}, 3), got {a.shape}")
            _finite(a, f"IMU {name}")
        dt = check_times(t, "IMU time", self.rel_tol)
        if t.size == 1:
            dt = self.dt
            if not np.isfinite(dt) or dt <= 0:
                raise ValueError("a one-sample IMU record needs an explicit dt > 0")
        elif np.isfinite(self.dt) and abs(self.dt - dt) > self.rel_tol * dt:
            raise ValueError(f"given dt {self.dt} s disagrees with the time column ({dt} s)")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "dtheta", dth)
        object.__setattr__(self, "dv", dv)
        object.__setattr__(self, "dt", float(dt))

    @classmethod
    def checked(cls, t: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, dt: float) -> ImuRecord:
        """A record of arrays checked already (finite, increasing, uniform: a reader that
        checked them a block at a time), taken as they are — memory-mapped arrays stay
        mapped, nothing is copied or scanned again. ``dt`` the mean interval [s]."""
        self = object.__new__(cls)
        for k, v in (("t", t), ("dtheta", dtheta), ("dv", dv), ("dt", float(dt)), ("rel_tol", 1e-3)):
            object.__setattr__(self, k, v)
        return self

    @property
    def t0(self) -> float:
        """Start time of the first interval [s]."""
        return float(self.t[0] - self.dt)

    def __len__(self):
        return self.t.size

    @classmethod
    def from_rates(cls, t: ArrayLike, gyro: ArrayLike, accel: ArrayLike, dt: float | None = None) -> ImuRecord:
        """Build from rates ω [rad/s] and specific force f [m/s^2] sampled at ``t``.

        The increments are rate × dt (rectangular rule): exact for constant rates over a
        sample, the usual assumption for rate-output IMUs.
        """
        t = np.asarray(t, dtype=float)
        d = check_times(t, "IMU time") if dt is None else float(dt)
        return cls(t, np.asarray(gyro, float) * d, np.asarray(accel, float) * d, d)

    def to_pandas(self) -> "pandas.DataFrame":
        """The record as a table, one row per sample, units in the column names:
        ``t_s`` (interval end time), ``dtheta_x_rad`` .. ``dtheta_z_rad`` (angle increments)
        and ``dv_x_mps`` .. ``dv_z_mps`` (velocity increments), body axes x right, y
        forward, z up. ``ImuRecord(df.t_s, df[dtheta cols], df[dv cols])`` gives the record
        back."""
        import pandas as pd

        cols = {"t_s": self.t}
        for i, ax in enumerate("xyz"):
            cols[f"dtheta_{ax}_rad"] = self.dtheta[:, i]
        for i, ax in enumerate("xyz"):
            cols[f"dv_{ax}_mps"] = self.dv[:, i]
        return pd.DataFrame(cols)

    def slice(self, start: float | None = None, stop: float | None = None) -> ImuRecord:
        """Samples whose end times lie in ``(start, stop]`` [s]."""
        lo = 0 if start is None else int(np.searchsorted(self.t, start, side="right"))
        hi = self.t.size if stop is None else int(np.searchsorted(self.t, stop, side="right"))
        if hi <= lo:
            raise ValueError(f"no IMU samples in ({start}, {stop}] s "
                             f"(record spans {self.t0:.3f}..{self.t[-1]:.3f} s)")
        return ImuRecord(self.t[lo:hi], self.dtheta[lo:hi], self.dv[lo:hi], self.dt)


@dataclass(frozen=True)
class NavSeries:
    """Navigation state at epochs: truth or a navigation solution.

    Attributes
    ----------
    t : ndarray, shape (M,)
        Epochs [s].
    lat, lon : ndarray, shape (M,)
        Geodetic latitude and longitude [rad].
    h : ndarray, shape (M,)
        Ellipsoidal height [m].
    vel : ndarray, shape (M, 3)
        Velocity in ENU [m/s].
    att : ndarray, shape (M, 3)
        Attitude ``[pitch, roll, yaw]`` of the carrier [rad] (C_c^n).
    att_imu : ndarray, shape (M, 3) or None
        Attitude of the IMU body frame [rad] when it differs from the carrier's (rotating
        or swinging mount); ``None`` means the IMU is fixed to the carrier.
    """

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    vel: np.ndarray
    att: np.ndarray
    att_imu: np.ndarray | None = None

    def __post_init__(self):
        m = np.asarray(self.t).shape[0]
        for f in fields(self):
            a = getattr(self, f.name)
            if a is None:
                continue
            a = np.ascontiguousarray(a, dtype=float)
            want = (m,) if f.name in ("t", "lat", "lon", "h") else (m, 3)
            if a.shape != want:
                raise ValueError(f"{f.name} must have shape {want}, got {a.shape}")
            object.__setattr__(self, f.name, a)

    def __len__(self):
        return self.t.size

    @property
    def pos(self) -> np.ndarray:
        """``(M, 3)`` array of ``[lat, lon, h]`` [rad, rad, m]."""
        return np.stack([self.lat, self.lon, self.h], -1)

    def to_pandas(self) -> "pandas.DataFrame":
        """The series as a table, one row per epoch, units in the column names (the columns
        of a ``navigate`` run's ``solution.csv``): ``t_s``, ``lat_deg``, ``lon_deg``, ``h_m``
        (ellipsoidal), ``vE_mps``, ``vN_mps``, ``vU_mps``, ``pitch_deg``, ``roll_deg`` and
        ``heading_deg`` (clockwise from north, 0–360: ``−yaw``); with ``att_imu``, the IMU
        frame's ``imu_pitch_deg``, ``imu_roll_deg``, ``imu_heading_deg`` too."""
        import pandas as pd

        from sinslab.core.attitude import yaw_to_heading

        def heading(yaw: np.ndarray) -> np.ndarray:
            return np.degrees(yaw_to_heading(yaw))

        cols = {"t_s": self.t, "lat_deg": np.degrees(self.lat), "lon_deg": np.degrees(self.lon), "h_m": self.h,
                "vE_mps": self.vel[:, 0], "vN_mps": self.vel[:, 1], "vU_mps": self.vel[:, 2],
                "pitch_deg": np.degrees(self.att[:, 0]), "roll_deg": np.degrees(self.att[:, 1]),
                "heading_deg": heading(self.att[:, 2])}
        if self.att_imu is not None:
            cols.update({"imu_pitch_deg": np.degrees(self.att_imu[:, 0]),
                         "imu_roll_deg": np.degrees(self.att_imu[:, 1]),
                         "imu_heading_deg": heading(self.att_imu[:, 2])})
        return pd.DataFrame(cols)

    def at(self, idx: slice | int | np.ndarray) -> NavSeries:
        """A new series with the epochs selected by ``idx`` (slice, mask or indices)."""
        return NavSeries(self.t[idx], self.lat[idx], self.lon[idx], self.h[idx],
                         self.vel[idx], self.att[idx],
                         None if self.att_imu is None else self.att_imu[idx])


@dataclass(frozen=True)
class NavState:
    """One navigation state: the initial condition of a mechanization.

    Attributes
    ----------
    lat, lon : float
        Geodetic latitude and longitude [rad].
    h : float
        Ellipsoidal height [m].
    vel : ndarray, shape (3,)
        Velocity in ENU [m/s].
    att : ndarray, shape (3,)
        ``[pitch, roll, yaw]`` of the IMU body frame [rad] (``C_b^n``).
    t : float
        Epoch [s].
    """

    lat: float
    lon: float
    h: float
    vel: np.ndarray
    att: np.ndarray
    t: float = 0.0

    def __post_init__(self):
        for name in ("lat", "lon", "h", "t"):
            v = float(getattr(self, name))
            if not np.isfinite(v):
                raise InputError(f"initial {name} is not finite")
            object.__setattr__(self, name, v)
        if abs(self.lat) > np.pi / 2:           # an input (or initial errors) over a pole
            raise InputError(f"latitude {np.degrees(self.lat):.6g} deg is beyond ±90 deg")
        for name in ("vel", "att"):
            a = np.array(getattr(self, name), dtype=float).reshape(-1)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise ValueError(f"initial {name} must be 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, a)

    @classmethod
    def from_series(cls, s: NavSeries, k: int = 0, imu_frame: bool = True) -> NavState:
        """Epoch ``k`` of a series; with ``imu_frame`` the IMU attitude is taken when present."""
        att = s.att_imu[k] if (imu_frame and s.att_imu is not None) else s.att[k]
        return cls(s.lat[k], s.lon[k], s.h[k], s.vel[k], att, s.t[k])


def _column(v, J, name, shape=None, fill=None):
    if v is None:
        return None if fill is None else np.full((J,) + (shape or ()), fill, dtype=float)
    a = np.array(v, dtype=float)
    want = (J,) + (shape or ())
    if a.shape != want:
        a = a.reshape(-1) if shape is None and a.size == J else a
    if a.shape != want:
        raise ValueError(f"Fixes.{name} must have shape {want}, got {np.shape(v)}")
    return a


@dataclass(frozen=True)
class Fixes:
    """Position (and velocity) fixes: GNSS solutions, two-GEO fixes, any position aid.

    Attributes
    ----------
    t : ndarray (J,)
        Validity times [s] (the IMU's time base), strictly increasing.
    lat, lon : ndarray (J,)
        Geodetic latitude and longitude [rad].
    h : ndarray (J,)
        Ellipsoidal height [m]; NaN for a horizontal (2-D) fix whose height comes from
        elsewhere (map, barometer).
    sigma : ndarray (J, 3)
        Position standard deviations north, east, up [m]; the up column is NaN for a 2-D
        fix.
    vel : ndarray (J, 3) or None
        Velocity ENU [m/s].
    sigma_vel : ndarray (J, 3) or None
        Velocity standard deviations east, north, up [m/s].
    quality : ndarray (J,) of int
        Solution quality flag (RTKLIB Q: 1 fix, 2 float, 5 single; 0 unknown).
    path : str
        File the fixes were read from ("" when made in memory).
    t_arrive : ndarray (J,)
        Time each fix becomes available to the navigator [s] (``>= t``); defaults to
        ``t`` (no latency).
    err : ndarray (J, 3) or None
        The drawn position errors north, east, up [m] of simulated fixes (NaN where not
        drawn); ``None`` for recorded data.
    """

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    sigma: np.ndarray
    vel: np.ndarray | None = None
    sigma_vel: np.ndarray | None = None
    quality: np.ndarray | None = None
    path: str = ""
    t_arrive: np.ndarray | None = None
    err: np.ndarray | None = None

    def __post_init__(self):
        t = np.array(self.t, dtype=float).reshape(-1)
        J = t.size
        cols = {"t": t}
        for name in ("lat", "lon", "h"):
            cols[name] = _column(getattr(self, name), J, name)
        cols["sigma"] = _column(self.sigma, J, "sigma", (3,))
        for name in ("vel", "sigma_vel", "err"):
            cols[name] = _column(getattr(self, name), J, name, (3,))
        cols["t_arrive"] = t.copy() if self.t_arrive is None else _column(self.t_arrive, J, "t_arrive")
        q = np.zeros(J, dtype=int) if self.quality is None else np.asarray(self.quality).reshape(-1)
        if q.size != J:
            raise ValueError(f"Fixes.quality has {q.size} values for {J} fixes")
        for name in ("t", "t_arrive", "lat", "lon"):
            if not np.all(np.isfinite(cols[name])):
                raise ValueError(f"Fixes.{name} has NaN/inf values")
        if np.any(cols["t_arrive"] < t - 1e-9):
            raise ValueError("a fix arrives before the time it is valid for")
        if np.any(np.diff(t) <= 0):
            raise ValueError("fix validity times must be strictly increasing")
        if np.any(~(cols["sigma"][:, :2] > 0)):
            raise ValueError("fix sigmas must be > 0")
        for name, a in cols.items():
            object.__setattr__(self, name, a)
        object.__setattr__(self, "quality", q)
        object.__setattr__(self, "path", str(self.path))

    def __len__(self):
        return self.t.size

    def with_velocity_lag(self, lag: float) -> Fixes:
        """The same fixes with velocities that describe the motion ``lag`` [s] *before* their
        stamps re-timed to the stamps: ``vel(t) := vel_recorded(t + lag)`` by linear
        interpolation over the record (receivers that report a Doppler velocity averaged
        over the last epoch do this). ``lag = 0`` returns the fixes unchanged.

        Raises ValueError for a negative or non-finite lag, a lag not shorter than the
        record, or a lag on fixes without velocities.
        """
        lag = float(lag)
        if not math.isfinite(lag) or lag < 0:
            raise ValueError(f"velocity lag must be a finite number of seconds >= 0, got {lag:g}")
        if lag == 0:
            return self
        if self.vel is None:
            raise ValueError(f"{self.path or 'the fixes'}: a velocity lag was given but the fixes have no velocities")
        span = float(self.t[-1] - self.t[0]) if len(self) else 0.0
        if not lag < span:
            raise ValueError(f"velocity lag {lag:g} s is not shorter than the fix record ({span:g} s)")
        vel = np.stack([np.interp(self.t + lag, self.t, self.vel[:, i]) for i in range(3)], -1)
        return dataclasses.replace(self, vel=vel)

    def select(self, mask: slice | np.ndarray) -> Fixes:
        """The fixes selected by ``mask`` (boolean mask, slice or indices)."""
        m = np.asarray(mask) if not isinstance(mask, slice) else mask
        opt = lambda a: None if a is None else a[m]      # noqa: E731
        return Fixes(self.t[m], self.lat[m], self.lon[m], self.h[m], self.sigma[m], opt(self.vel),
                     opt(self.sigma_vel), opt(self.quality), self.path, opt(self.t_arrive), opt(self.err))
