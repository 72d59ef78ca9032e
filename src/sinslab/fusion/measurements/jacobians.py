"""Jacobian helpers shared by the measurement families: the IMU-body-to-vehicle
rotation of a mount and the lever-arm rate term placed on every block that feeds the gyro
(:func:`add_rate_H`)."""
from __future__ import annotations

import numpy as np

from sinslab.core import attitude as A

__all__ = ["vehicle_from_body", "add_rate_H"]


def vehicle_from_body(mount):
    """The vehicle-from-body mount ``C_b^v`` (3, 3): IMU body axes -> vehicle axes (both
    RFU: x right, y forward, z up) of the wheel constraints (the sensor-to-body mount of
    recorded data is :func:`sinslab.data.frames.sensor_to_body`).

    ``mount`` is None (aligned), a (3, 3) rotation matrix ``C_b^v`` or Euler angles
    ``[pitch, roll, yaw]`` [rad] of the IMU body frame in the vehicle frame (the
    :func:`sinslab.core.attitude.euler_to_dcm` convention with v in place of n).
    """
    if mount is None:
        return np.eye(3)
    m = np.asarray(mount, dtype=float)
    if m.shape == (3,):
        return A.euler_to_dcm(m)
    if m.shape == (3, 3):
        if not np.allclose(m @ m.T, np.eye(3), atol=1e-9) or np.linalg.det(m) < 0:
            raise ValueError("mount matrix C_b^v must be a proper rotation")
        return m
    raise ValueError(f"mount must be 3 Euler angles or a 3x3 matrix, got shape {m.shape}")


def add_rate_H(H, lay, M, omega_b, suffix=""):
    """Add ``M ∂δω_ib^b/∂x`` to ``H`` for every block that feeds the gyro compensation
    (:attr:`sinslab.nav.errstate.Block.feeds`): a bias or Gauss–Markov block enters the
    compensated rate as ``δω = x``, a scale block as ``δω = diag(ω) x``. ``suffix`` keeps
    the blocks whose names end with it (one INS's blocks in a two-INS layout)."""
    for b in lay.blocks:
        feeds = getattr(b, "feeds", None)
        if feeds not in ("gyro_bias", "gyro_scale") or not b.name.endswith(suffix):
            continue
        sl = lay.slice(b.name)
        for i, a in enumerate(b.axes):
            ax = "xyz".index(a)
            H[:, sl.start + i] += M[:, ax] * (omega_b[ax] if feeds == "gyro_scale" else 1.0)
