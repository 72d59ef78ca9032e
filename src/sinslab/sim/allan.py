"""Allan deviation of recorded IMU data (``sinslab allan FILE``).

For each gyro and accelerometer axis the overlapping Allan deviation (``allantools.oadev``)
of the rate (increment / dt) is computed on octave-spaced cluster times, and the IEEE-952
noise terms are read off it:

- **angle / velocity random walk N** — the −½ slope line: the median of σ(τ)·√τ over
  τ in [10 τ0, min(1 s, τ_min/10)] (above the quantization knee, below the floor), i.e.
  σ(1 s) of that line; a least-squares fit of ``σ²(τ) = N²/τ + B_f² + K² τ/3`` (relative
  residuals, non-negative coefficients) is drawn. When the curve has no clean −½ slope
  there (base motion of a "static" vehicle, quantization), N is reported as the upper
  bound min σ(τ)·√τ over τ up to the minimum, flagged ``n_is_bound``;
- **bias instability B** — the curve's minimum divided by 0.664 (IEEE; the flicker floor
  is 0.664·B), with the cluster time of the minimum;
- **rate random walk K** — from that fit (the +½ slope line, σ(3 s) = K); reported as 0
  when the curve does not rise after its minimum (record too short to show it).

The :class:`sinslab.sim.imu.ImuErrors` block converts them for simulation: ARW/VRW = N,
bias instability as a first-order Gauss–Markov process whose Allan peak equals the
measured floor (σ = floor/0.6174, correlation time = τ_min/1.893), RRW = K. The data must
be recorded at rest; the mean (bias and the Earth rate/gravity) does not affect the
Allan deviation but the 1-σ of a moving record would be dominated by the motion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from sinslab.core import units
from sinslab.core.records import ImuRecord

__all__ = ["AxisFit", "AllanResult", "allan", "fit_axis", "imu_errors_from_allan", "register"]

_FLICKER = 0.664


@dataclass
class AxisFit:
    """Noise terms of one axis (SI: gyro rad/s family, accel m/s² family)."""

    name: str
    tau: np.ndarray
    adev: np.ndarray
    n_white: float          #: ARW [rad/√s] or VRW [m/s/√s]
    bias_instability: float  #: B (IEEE) [rad/s] or [m/s²]
    floor: float            #: minimum of the Allan deviation
    tau_floor: float        #: its cluster time [s]
    rrw: float              #: K [rad/s/√s] or [m/s²/√s]
    fit: np.ndarray = field(default=None)   #: fitted curve on ``tau``
    n_is_bound: bool = False  #: no clean −½ slope: ``n_white`` is an upper bound


@dataclass
class AllanResult:
    gyro: list
    accel: list
    dt: float
    duration: float


def fit_axis(tau, adev, name=""):
    """Fit N, B, K to one Allan-deviation curve (see module notes)."""
    tau = np.asarray(tau, dtype=float)
    adev = np.asarray(adev, dtype=float)
    ok = np.isfinite(adev) & (adev > 0)
    tau, adev = tau[ok], adev[ok]
    if tau.size < 3:
        raise ValueError(f"{name}: too few cluster times for an Allan fit")
    i_min = int(np.argmin(adev))
    floor, tau_floor = float(adev[i_min]), float(tau[i_min])
    from scipy.optimize import nnls
    A = np.stack([1.0 / tau, np.ones_like(tau), tau / 3.0], -1)
    y = adev ** 2
    w = 1.0 / y                                           # relative residuals
    coef, _ = nnls(A * w[:, None], y * w)
    n2, b2, k2 = coef
    fit = np.sqrt(A @ coef)
    # white noise from the -1/2 line: short cluster times, where it dominates
    # (quantization bends the first decade; slow terms the long end): τ in [10 τ0, min(1 s, τ_min/10)]
    short = (tau >= 10 * tau[0] - 1e-12) & (tau <= min(1.0, tau_floor / 10))
    line = adev * np.sqrt(tau)
    bound = False
    if short.sum() >= 3 and line[short].max() / line[short].min() < 1.5:
        n_white = float(np.median(line[short]))
    else:
        # no clean -1/2 slope (base motion, quantization): sigma(tau) >= N/sqrt(tau) everywhere,
        # so the smallest sigma*sqrt(tau) up to the floor is an upper bound on N
        upto = (tau >= 10 * tau[0] - 1e-12) & (tau <= tau_floor)
        n_white = float(line[upto].min()) if upto.any() else float(line.min())
        bound = True
    k = math.sqrt(k2) if (k2 > 0 and tau_floor < tau[-1] / 2) else 0.0
    return AxisFit(name, tau, adev, n_white, floor / _FLICKER, floor, tau_floor, k, fit, bound)


def allan(imu: ImuRecord, *, max_clusters=None, progress=False) -> AllanResult:
    """Overlapping Allan deviation and noise terms of every axis of ``imu``."""
    import allantools

    n = len(imu)
    if n < 100:
        raise ValueError(f"the IMU record has {n} samples; the Allan deviation needs at least 100")
    rate = 1.0 / imu.dt
    m_max = n // 9 if max_clusters is None else int(max_clusters)
    ms = np.unique(np.round(np.logspace(0, math.log10(max(m_max, 2)), 60)).astype(int))
    taus = ms * imu.dt
    out = {"gyro": [], "accel": []}
    for sensor, arr in (("gyro", imu.dtheta), ("accel", imu.dv)):
        for k, ax in enumerate("xyz"):
            y = arr[:, k] / imu.dt
            t2, ad, _, _ = allantools.oadev(y, rate=rate, data_type="freq", taus=taus)
            out[sensor].append(fit_axis(t2, ad, f"{sensor} {ax}"))
    return AllanResult(out["gyro"], out["accel"], imu.dt, n * imu.dt)


def imu_errors_from_allan(res: AllanResult):
    """An :class:`sinslab.sim.imu.ImuErrors` with the measured noise terms (see module notes)."""
    from sinslab.sim.imu import GM_ALLAN_PEAK, GM_ALLAN_PEAK_TAU, ImuErrors

    def vec(fits, attr):
        return np.array([getattr(f, attr) for f in fits])

    g, a = res.gyro, res.accel
    return ImuErrors(
        gyro_arw=vec(g, "n_white"), gyro_bias_instability=vec(g, "floor") / GM_ALLAN_PEAK,
        gyro_corr_time=vec(g, "tau_floor") / GM_ALLAN_PEAK_TAU, gyro_rrw=vec(g, "rrw"),
        accel_vrw=vec(a, "n_white"), accel_bias_instability=vec(a, "floor") / GM_ALLAN_PEAK,
        accel_corr_time=vec(a, "tau_floor") / GM_ALLAN_PEAK_TAU, accel_rrw=vec(a, "rrw"))
