"""The graph's world frame: the east-north-up tangent frame at a fixed origin, and the
conversions between it and sinslab's navigation state (WGS-84 geodetic position, ENU
velocity and attitude of the local level frame at the vehicle).

GTSAM integrates the IMU in one fixed frame with constant gravity and a Coriolis term
(:mod:`sinslab.fusion.graph.translate`); sinslab's navigation frame moves with the vehicle
(transport rate) and gravity follows it (normal gravity at the vehicle). Every quantity
crosses between the two here and only here, exactly (through ECEF), so the one
approximation of the graph is the physics of the fixed frame, not the conversion.

Notation: w the tangent frame at the origin, n the local level (ENU) frame at the
vehicle, e ECEF, b the IMU body frame (RFU, sinslab's). ``R_wn = C_e^w C_n^e``.
"""
from __future__ import annotations

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E

__all__ = ["LocalFrame"]


class LocalFrame:
    """The ENU tangent frame w at ``origin = (lat, lon, h)`` [rad, rad, m].

    Attributes
    ----------
    origin : tuple of float
    C_ew : ndarray (3, 3)
        ``C_w^e``: the columns are w's east, north and up axes in ECEF.
    r0 : ndarray (3,)
        The origin in ECEF [m].
    """

    def __init__(self, lat, lon, h):
        self.origin = (float(lat), float(lon), float(h))
        self.C_ew = E.enu_to_ecef_matrix(lat, lon)
        self.r0 = E.geodetic_to_ecef(lat, lon, h)

    # ------------------------------------------------------------------ positions
    def to_w(self, lat, lon, h):
        """Points ``(lat, lon, h)`` (arrays broadcast) as w coordinates (..., 3) [m]."""
        return (E.geodetic_to_ecef(lat, lon, h) - self.r0) @ self.C_ew

    def to_geodetic(self, p):
        """w coordinates (..., 3) [m] as ``(lat, lon, h)``."""
        return E.ecef_to_geodetic(self.r0 + np.asarray(p, dtype=float) @ self.C_ew.T)

    def R_wn(self, lat, lon):
        """``C_n^w`` (..., 3, 3) of the local level frames at ``lat``, ``lon``."""
        return self.C_ew.T @ E.enu_to_ecef_matrix(lat, lon)

    # ------------------------------------------------------------------ navigation rows
    def rows_to_w(self, rows):
        """sinslab rows ``[q0..q3, vE, vN, vU, lat, lon, h]`` (M, 10) as
        ``(R_wb (M, 3, 3), v_w (M, 3), p_w (M, 3))``."""
        rows = np.atleast_2d(np.asarray(rows, dtype=float))
        R = self.R_wn(rows[:, 7], rows[:, 8])
        Rwb = R @ A.quat_to_dcm(rows[:, :4])
        v = np.einsum("kij,kj->ki", R, rows[:, 4:7])
        return Rwb, v, self.to_w(rows[:, 7], rows[:, 8], rows[:, 9])

    def rows_from_w(self, Rwb, v, p):
        """The inverse of :meth:`rows_to_w`: rows (M, 10)."""
        Rwb = np.asarray(Rwb, dtype=float).reshape(-1, 3, 3)
        lat, lon, h = self.to_geodetic(np.asarray(p, dtype=float).reshape(-1, 3))
        R = self.R_wn(lat, lon)
        Rnw = np.swapaxes(R, -1, -2)
        q = A.dcm_to_quat(Rnw @ Rwb)
        vn = np.einsum("kij,kj->ki", Rnw, np.asarray(v, dtype=float).reshape(-1, 3))
        return np.column_stack([q, vn, lat, lon, h])

    def gravity_w(self, p=None):
        """Normal gravity as a w vector [m/s²] at the w point ``p`` (3,) (None: at the
        origin, down its normal)."""
        if p is None:
            lat, _, h = self.origin
            return np.array([0.0, 0.0, -float(E.gravity(lat, h))])
        lat, lon, h = (float(v) for v in self.to_geodetic(p))
        return self.R_wn(lat, lon) @ np.array([0.0, 0.0, -float(E.gravity(lat, h))])

    def earth_rate_w(self):
        """The Earth's rotation rate in w [rad/s]."""
        return self.C_ew.T @ np.array([0.0, 0.0, E.WIE])
