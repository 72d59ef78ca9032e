"""An error-free IMU for a given trajectory: a reference solution sampled at a low rate
(another tool's truth, a post-processed drive) interpolated smoothly and differentiated
into body-frame increments — the IMU that would have flown it, to which
:func:`sinslab.sim.imu.apply` adds a unit's errors.

The attitude ``C_b^n`` is a cubic rotation spline through the reference attitudes (its
rate is ``ω_nb^b``); the position cubic splines of latitude, longitude and height through
the reference positions, and the velocity their derivative (``[λ̇ (R_N+h) cos L, L̇ (R_M+h),
ḣ]``), so that position and velocity are one motion that passes through every reference
position. (A reference's own velocities are not used: sampled at 1 Hz they are not the
derivative of its positions — integrated, NaveGo's Turin reference velocities leave its
positions by 9 m in 20 minutes.) With ``ω_ib^b = ω_nb^b + C_n^b (ω_ie^n + ω_en^n)`` and
``f^n = v̇ + (2ω_ie^n + ω_en^n) × v − g^n`` the increments of each sample are the
integrals of ``ω_ib^b`` and ``C_n^b f^n`` over it (Simpson's rule on three points).
"""
from __future__ import annotations

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.core.records import ImuRecord, NavSeries

__all__ = ["imu_from_reference"]


def _rates(t, rs, v, vdot, lat, h):
    """ω_ib^b and f^b [SI] at times ``t`` of the rotation spline ``rs``, the velocity ``v``
    and its rate ``vdot`` (ENU)."""
    C = rs(t).as_matrix()                                       # C_b^n
    w_nb = rs(t, 1)
    w_ie = E.wie_n(lat)
    w_en = E.win_n(lat, h, v) - w_ie
    w_ib = w_nb + np.einsum("kji,kj->ki", C, w_ie + w_en)
    fn = vdot + np.cross(2 * w_ie + w_en, v) - E.gravity_vector(lat, h)
    return w_ib, np.einsum("kji,kj->ki", C, fn)


def imu_from_reference(ref: NavSeries, dt: float, *, t0=None, t1=None):
    """``(ImuRecord, NavSeries truth)`` at the interval ``dt`` [s] over ``[t0, t1]`` (default:
    the reference's span) from a reference trajectory sampled at any rate (its attitude
    ``att`` the IMU body's). See the module notes."""
    from scipy.interpolate import CubicSpline
    from scipy.spatial.transform import Rotation, RotationSpline
    t0 = float(ref.t[0]) if t0 is None else float(t0)
    t1 = float(ref.t[-1]) if t1 is None else float(t1)
    q = A.euler_to_quat(ref.att)                                  # scalar first
    rs = RotationSpline(ref.t, Rotation.from_quat(np.column_stack([q[:, 1:], q[:, :1]])))
    ps = CubicSpline(ref.t, np.column_stack([ref.lat, np.unwrap(ref.lon), ref.h]), axis=0)
    n = int(np.floor((t1 - t0) / dt + 1e-9))
    tg = t0 + dt * np.arange(n + 1)
    th = t0 + 0.5 * dt * np.arange(2 * n + 1)                    # sample ends and middles
    pos, rate = ps(th), ps(th, 1)
    lat, lon, h = pos[:, 0], pos[:, 1], pos[:, 2]
    rm, rn = E.radii(lat, h)
    v = np.column_stack([rate[:, 1] * rn * np.cos(lat), rate[:, 0] * rm, rate[:, 2]])
    vdot = np.gradient(v, th, axis=0)
    w_ib, f_b = _rates(th, rs, v, vdot, lat, h)
    # Simpson over each sample: start (2k), middle (2k+1), end (2k+2)
    dth = dt / 6.0 * (w_ib[0:-1:2] + 4 * w_ib[1::2] + w_ib[2::2])
    dv = dt / 6.0 * (f_b[0:-1:2] + 4 * f_b[1::2] + f_b[2::2])
    imu = ImuRecord(tg[1:], dth, dv, dt)
    qs = rs(tg).as_quat()
    att = A.quat_to_euler(np.column_stack([qs[:, 3:], qs[:, :3]]))
    truth = NavSeries(tg, lat[::2], A.wrap_pi(lon[::2]), h[::2], v[::2], att)
    return imu, truth
