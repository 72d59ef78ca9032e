"""Plain containers for time series: IMU increments, truth, navigation solutions.

They hold numpy arrays, validate them once on construction, and do nothing else; the
functions of the other modules work on their arrays.

Time convention: an IMU record of N samples covers ``[t0, t0 + N·dt]``; sample k is the
increment over ``(t[k] − dt, t[k]]`` (``t`` holds interval end times). A truth or
navigation series sampled on the same grid has N + 1 epochs ``t0, t[0], ..., t[N−1]``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

__all__ = ["ImuRecord", "NavSeries", "NavState", "check_times"]


def check_times(t, name="time", rel_tol=1e-3, uniform=True) -> float:
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
    bad = ~np.isfinite(t)
    if bad.any():
        raise ValueError(f"{name} has a non-finite value at index {int(np.argmax(bad))}")
    if t.size < 2:
        return float("nan")
    d = np.diff(t)
    if (d == 0).any():
        i = int(np.argmax(d == 0))
        raise ValueError(f"{name} has a duplicated stamp {float(t[i])!r} at index {i + 1}")
    if (d < 0).any():
        i = int(np.argmax(d < 0))
        raise ValueError(f"{name} is not sorted: {float(t[i + 1])!r} follows {float(t[i])!r} at index {i + 1}")
    dt = (t[-1] - t[0]) / (t.size - 1)
    if uniform:
        dev = np.abs(d - dt) > rel_tol * dt
        if dev.any():
            i = int(np.argmax(dev))
            raise ValueError(f"{name} is not uniformly sampled: interval {float(d[i])!r} s at index "
                             f"{i + 1} vs mean {dt!r} s (tolerance {rel_tol:g} relative)")
    return float(dt)


def _finite(a, name):
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

    @property
    def t0(self) -> float:
        """Start time of the first interval [s]."""
        return float(self.t[0] - self.dt)

    def __len__(self):
        return self.t.size

    @classmethod
    def from_rates(cls, t, gyro, accel, dt=None):
        """Build from rates ω [rad/s] and specific force f [m/s^2] sampled at ``t``.

        The increments are rate × dt (rectangular rule): exact for constant rates over a
        sample, the usual assumption for rate-output IMUs.
        """
        t = np.asarray(t, dtype=float)
        d = check_times(t, "IMU time") if dt is None else float(dt)
        return cls(t, np.asarray(gyro, float) * d, np.asarray(accel, float) * d, d)

    def slice(self, start=None, stop=None):
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
    def pos(self):
        """``(M, 3)`` array of ``[lat, lon, h]`` [rad, rad, m]."""
        return np.stack([self.lat, self.lon, self.h], -1)

    def at(self, idx):
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
                raise ValueError(f"initial {name} is not finite")
            object.__setattr__(self, name, v)
        if abs(self.lat) > np.pi / 2:
            raise ValueError(f"latitude {np.degrees(self.lat):.6g} deg is beyond ±90 deg")
        for name in ("vel", "att"):
            a = np.array(getattr(self, name), dtype=float).reshape(-1)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise ValueError(f"initial {name} must be 3 finite numbers, got {getattr(self, name)!r}")
            object.__setattr__(self, name, a)

    @classmethod
    def from_series(cls, s: "NavSeries", k: int = 0, imu_frame: bool = True):
        """Epoch ``k`` of a series; with ``imu_frame`` the IMU attitude is taken when present."""
        att = s.att_imu[k] if (imu_frame and s.att_imu is not None) else s.att[k]
        return cls(s.lat[k], s.lon[k], s.h[k], s.vel[k], att, s.t[k])
