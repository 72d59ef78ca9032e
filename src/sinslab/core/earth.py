"""The Earth model: WGS-84 ellipsoid, normal gravity, Earth and transport rates.

One model for the whole package: the trajectory generator, the mechanization and the
error-state models all call these functions, so that error-free navigation of
synthesised data reproduces the truth.

Frames: navigation frame n = ENU (east, north, up). Latitude ``lat`` and longitude
``lon`` in rad, ellipsoidal height ``h`` in m, velocity ``v = [vE, vN, vU]`` in m/s.

The ``*_s`` functions are numba-compiled scalar versions for hot loops; the others
accept numpy arrays and broadcast.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from sinslab.core.errors import InputError
from sinslab.core.jitnotice import install as _compile_notice

_compile_notice()   # a status line while the kernels below compile (first run)

__all__ = [
    "A", "F", "E2", "B", "WIE", "GM", "GEO_RADIUS", "radii", "gravity", "gravity_vector", "wie_n",
    "wen_n", "win_n", "schuler_frequency", "schuler_period", "foucault_frequency",
    "check_latitude", "radii_s", "gravity_s", "radii_sin_s", "gravity_sin_s", "metres_per_rad", "geodetic_to_ecef",
    "ecef_to_geodetic", "enu_to_ecef_matrix", "ecef_to_enu", "elevation_azimuth",
]

A = 6378137.0                     #: WGS-84 semi-major axis [m]
F = 1.0 / 298.257223563           #: WGS-84 flattening [-]
E2 = F * (2.0 - F)                #: first eccentricity squared [-] (0.00669437999014)
B = A * (1.0 - F)                 #: semi-minor axis [m]
WIE = 7.2921151467e-5             #: Earth rotation rate [rad/s]
GM = 3.986004418e14               #: gravitational constant [m^3/s^2]
#: Geocentric radius of the geostationary orbit [m], the nominal value (two-GEO RDSS);
#: (GM / WIE²)^(1/3) gives 2.8 m more.
GEO_RADIUS = 42164.1696e3

# Normal gravity, Somigliana's closed form with a linear free-air height term.
G_EQ = 9.7803267714               #: normal gravity at the equator [m/s^2]
K_SOM = 0.00193185138639          #: Somigliana constant [-]
DGDH = 3.086e-6                   #: free-air gradient [1/s^2]


@njit(cache=True, inline="always")
def radii_s(lat: float, h: float) -> tuple[float, float]:
    """Meridian and prime-vertical radii plus height, ``(R_M + h, R_N + h)`` [m]."""
    return radii_sin_s(math.sin(lat), h)


@njit(cache=True, inline="always")
def radii_sin_s(sl: float, h: float) -> tuple[float, float]:
    """:func:`radii_s` from the sine of the latitude ``sl``."""
    sq2 = 1.0 - E2 * sl * sl
    sq = math.sqrt(sq2)
    return A * (1.0 - E2) / (sq2 * sq) + h, A / sq + h


@njit(cache=True, inline="always")
def gravity_s(lat: float, h: float) -> float:
    """Normal gravity magnitude [m/s^2] at latitude ``lat`` [rad] and height ``h`` [m]."""
    return gravity_sin_s(math.sin(lat), h)


@njit(cache=True, inline="always")
def gravity_sin_s(sl: float, h: float) -> float:
    """:func:`gravity_s` from the sine of the latitude ``sl``."""
    return G_EQ * (1.0 + K_SOM * sl * sl) / math.sqrt(1.0 - E2 * sl * sl) - DGDH * h


def check_latitude(lat: ArrayLike) -> None:
    """Raise :class:`~sinslab.core.errors.InputError` (a ValueError) if any latitude [rad]
    is beyond ±90° or not finite: a bad input, or errors that carried a solution over a pole."""
    if isinstance(lat, (float, np.floating)):        # the per-call check of compiled loops
        if not math.isfinite(lat):
            raise InputError("latitude is not finite")
        if abs(float(lat)) > math.pi / 2:
            raise InputError(f"latitude {math.degrees(lat):.6g} deg is beyond ±90 deg")
        return
    lat = np.asarray(lat, dtype=float)
    if not np.all(np.isfinite(lat)):
        raise InputError("latitude is not finite")
    if np.any(np.abs(lat) > math.pi / 2):
        bad = float(np.degrees(lat.flat[np.argmax(np.abs(lat))]))
        raise InputError(f"latitude {bad:.6g} deg is beyond ±90 deg")


def radii(lat: ArrayLike, h: ArrayLike = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Meridian radius R_M and prime-vertical radius R_N, each plus height.

    Parameters
    ----------
    lat : float or array_like
        Geodetic latitude [rad].
    h : float or array_like
        Ellipsoidal height [m].

    Returns
    -------
    rm_h, rn_h : ndarray
        ``R_M + h`` and ``R_N + h`` [m].
    """
    lat = np.asarray(lat, dtype=float)
    sl2 = np.sin(lat) ** 2
    sq2 = 1.0 - E2 * sl2
    return A * (1.0 - E2) / sq2 ** 1.5 + h, A / np.sqrt(sq2) + h


def gravity(lat: ArrayLike, h: ArrayLike = 0.0) -> float | np.ndarray:
    """Normal gravity magnitude [m/s^2] (Somigliana + free-air), positive number."""
    lat = np.asarray(lat, dtype=float)
    sl2 = np.sin(lat) ** 2
    return G_EQ * (1.0 + K_SOM * sl2) / np.sqrt(1.0 - E2 * sl2) - DGDH * np.asarray(h)


def gravity_vector(lat: ArrayLike, h: ArrayLike = 0.0) -> np.ndarray:
    """Normal gravity in ENU, ``[0, 0, -g]`` [m/s^2], shape ``(..., 3)``."""
    g = np.asarray(gravity(lat, h))
    out = np.zeros(g.shape + (3,))
    out[..., 2] = -g
    return out


def wie_n(lat: ArrayLike) -> np.ndarray:
    """Earth rate in ENU, ``[0, ω cos L, ω sin L]`` [rad/s], shape ``(..., 3)``."""
    lat = np.asarray(lat, dtype=float)
    out = np.zeros(lat.shape + (3,))
    out[..., 1] = WIE * np.cos(lat)
    out[..., 2] = WIE * np.sin(lat)
    return out


def wen_n(lat: ArrayLike, h: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Transport rate in ENU, ``[-vN/(R_M+h), vE/(R_N+h), vE tan L/(R_N+h)]`` [rad/s]."""
    lat = np.asarray(lat, dtype=float)
    v = np.asarray(v, dtype=float)
    rm, rn = radii(lat, h)
    out = np.empty(np.broadcast_shapes(lat.shape, v.shape[:-1]) + (3,))
    out[..., 0] = -v[..., 1] / rm
    out[..., 1] = v[..., 0] / rn
    out[..., 2] = v[..., 0] * np.tan(lat) / rn
    return out


def win_n(lat: ArrayLike, h: ArrayLike, v: ArrayLike) -> np.ndarray:
    """Rate of the navigation frame w.r.t. inertial space, ω_ie + ω_en [rad/s]."""
    return wie_n(lat) + wen_n(lat, h, v)


def metres_per_rad(lat: ArrayLike, h: ArrayLike = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Metres per radian of latitude and of longitude: ``(R_M + h, (R_N + h) cos L)``."""
    rm, rn = radii(lat, h)
    return rm, rn * np.cos(lat)


def schuler_frequency(lat: ArrayLike = 0.0, h: ArrayLike = 0.0) -> float | np.ndarray:
    """Schuler angular frequency ω_s = sqrt(g / R) [rad/s], R = sqrt(R_M R_N) + h."""
    rm, rn = radii(lat, 0.0)
    return np.sqrt(gravity(lat, h) / (np.sqrt(rm * rn) + h))


def schuler_period(lat: ArrayLike = 0.0, h: ArrayLike = 0.0) -> float | np.ndarray:
    """Schuler period 2π sqrt(R/g) [s] (≈ 84.4 min), R = sqrt(R_M R_N) + h."""
    return 2.0 * np.pi / schuler_frequency(lat, h)


def foucault_frequency(lat: ArrayLike) -> float | np.ndarray:
    """Foucault frequency ω_ie sin L [rad/s] (sign follows the hemisphere)."""
    return WIE * np.sin(np.asarray(lat, dtype=float))


# ------------------------------------------------------------------ ECEF <-> geodetic
def geodetic_to_ecef(lat: ArrayLike, lon: ArrayLike, h: ArrayLike) -> np.ndarray:
    """Earth-centred Earth-fixed coordinates [m] of geodetic ``lat``, ``lon`` [rad] and
    ellipsoidal height ``h`` [m] on WGS-84; arrays broadcast, result shape ``S + (3,)``."""
    lat, lon, h = (np.asarray(v, dtype=float) for v in (lat, lon, h))
    one = lat.ndim == lon.ndim == h.ndim == 0
    if not one:
        lat, lon, h = np.broadcast_arrays(lat, lon, h)
    sl, cl = np.sin(lat), np.cos(lat)
    rn = A / np.sqrt(1.0 - E2 * sl * sl)
    xyz = [(rn + h) * cl * np.cos(lon), (rn + h) * cl * np.sin(lon), (rn * (1.0 - E2) + h) * sl]
    # one point (a receiver epoch by epoch): the same numbers without stack's overhead
    return np.array(xyz) if one else np.stack(xyz, axis=-1)


def ecef_to_geodetic(r: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geodetic ``(lat, lon, h)`` [rad, rad, m] of ECEF points ``r`` (..., 3) [m] on WGS-84.

    Fixed-point iteration on the latitude (the prime-vertical radius from the latest
    estimate) until it moves less than 1e-14 rad: millimetre-exact anywhere near the
    Earth's surface and up to GNSS orbits."""
    r = np.asarray(r, dtype=float)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    p = np.hypot(x, y)
    lat = np.arctan2(z, p * (1.0 - E2))
    for _ in range(20):
        sl = np.sin(lat)
        rn = A / np.sqrt(1.0 - E2 * sl * sl)
        new = np.arctan2(z + rn * E2 * sl, p)
        done = np.all(np.abs(new - lat) < 1e-14)
        lat = new
        if done:
            break
    sl, cl = np.sin(lat), np.cos(lat)
    rn = A / np.sqrt(1.0 - E2 * sl * sl)
    # height along the normal, well conditioned at every latitude
    h = p * cl + z * sl - rn * (1.0 - E2 * sl * sl)
    return lat, np.arctan2(y, x), h


def enu_to_ecef_matrix(lat: ArrayLike, lon: ArrayLike) -> np.ndarray:
    """``C_n^e`` (..., 3, 3): columns are the east, north and up unit vectors in ECEF."""
    lat, lon = np.asarray(lat, dtype=float), np.asarray(lon, dtype=float)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    if lat.ndim == lon.ndim == 0:
        # one point (a receiver epoch by epoch): the entries below without four stacks
        # (``+ 0.0`` as there: a −0 entry becomes +0)
        return np.array([[-so + 0.0, -sl * co, cl * co], [co + 0.0, -sl * so, cl * so], [0.0, cl + 0.0, sl + 0.0]])
    z = np.zeros_like(sl * so)
    e = np.stack([-so + z, co + z, z], -1)
    n = np.stack([-sl * co, -sl * so, cl + z], -1)
    u = np.stack([cl * co, cl * so, sl + z], -1)
    return np.stack([e, n, u], axis=-1)


def ecef_to_enu(d: ArrayLike, lat: ArrayLike, lon: ArrayLike) -> np.ndarray:
    """ECEF vectors ``d`` (..., 3) in the local east-north-up axes at ``lat``, ``lon`` [rad]."""
    C = enu_to_ecef_matrix(lat, lon)
    return np.einsum("...ji,...j->...i", C, np.asarray(d, dtype=float))


def elevation_azimuth(r_sat: ArrayLike, lat: ArrayLike, lon: ArrayLike, h: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Elevation and azimuth [rad] of ECEF points ``r_sat`` (..., 3) [m] seen from the
    geodetic point ``lat``, ``lon``, ``h``: elevation above the ellipsoid's tangent plane,
    azimuth clockwise from north in [0, 2π)."""
    d = np.asarray(r_sat, dtype=float) - geodetic_to_ecef(lat, lon, h)
    u = ecef_to_enu(d / np.linalg.norm(d, axis=-1, keepdims=True), lat, lon)
    el = np.arcsin(np.clip(u[..., 2], -1.0, 1.0))
    az = np.mod(np.arctan2(u[..., 0], u[..., 1]), 2.0 * np.pi)
    return el, az
