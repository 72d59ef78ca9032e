"""Shared test inputs (importable from every test module: pytest puts this folder on
``sys.path`` because it holds the root ``conftest.py``)."""
import numpy as np

from sinslab.core import attitude, earth
from sinslab.core.records import ImuRecord


def static_imu(lat, att, dt, n, h=0.0, gyro_err=(0.0, 0.0, 0.0), accel_err=(0.0, 0.0, 0.0)):
    """Exact output of an IMU at rest, ``n`` samples at ``dt`` [s]: Δθ = (C_n^b ω_ie^n + ε) dt,
    Δv = (C_n^b [0, 0, g] + ∇) dt with constant body-frame errors ε [rad/s], ∇ [m/s²]
    (zero by default), attitude ``att`` = [pitch, roll, yaw] [rad], latitude [rad]."""
    C = attitude.euler_to_dcm(att)
    wb = C.T @ earth.wie_n(lat) + np.asarray(gyro_err, float)
    fb = C.T @ np.array([0.0, 0.0, float(earth.gravity(lat, h))]) + np.asarray(accel_err, float)
    t = dt * np.arange(1, n + 1)
    return ImuRecord(t, np.tile(wb * dt, (n, 1)), np.tile(fb * dt, (n, 1)), dt)
