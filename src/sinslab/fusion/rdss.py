"""Two-GEO radio determination (RDSS, the "double-star" system of paper 003) as a
measurement of the fusion driver: the two measured signal paths themselves instead of the
position fix computed from them.

A user interrogated through geostationary satellite 1 measures the round trip
``ρa = 2 r1`` and the path through both satellites ``ρb = r1 + r2`` (``r_i`` the
user–satellite distances). :class:`TwoGeoRanges` compares them with the INS antenna:
``z = [2 r̂1 − ρa, r̂1 + r̂2 − ρb]`` [m], linearised in the horizontal position error
``δp = [δL, δλ]`` with the unit lines of sight (``∂r_i/∂L = −e_i·(R_M+h) n̂``,
``∂r_i/∂λ = −e_i·(R_N+h) cos L ê``). The height is not measured: the INS holds the
external height (barometer, map), whose error ``ΔH`` moves both paths along
``g = [2 ∂r1/∂h, ∂r1/∂h + ∂r2/∂h]``; it enters the noise as ``ΔH² g gᵀ`` (correlated
between the two rows), beside the ranging error ``m0`` and the ephemeris error ``m1`` of each
path (``σ² = m0² + m1²``), the error model of paper 003's eqs 11–15 before the fix is solved.
"""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import earth as E
from sinslab.fusion.measurements import Epoch, arrival_epochs

__all__ = ["TwoGeoRanges", "geo_paths"]


def geo_paths(lat, lon, h, sat_lon1, sat_lon2, sat_radius=E.GEO_RADIUS):
    """``[ρa, ρb] = [2 r1, r1 + r2]`` [m] of a user at ``lat, lon, h`` (shape S + (2,)),
    with the lines of sight (S + (2, 3)) to the two satellites on the equator."""
    r = E.geodetic_to_ecef(lat, lon, h)
    s = np.array([[sat_radius * math.cos(a), sat_radius * math.sin(a), 0.0] for a in (sat_lon1, sat_lon2)])
    d = s - np.asarray(r)[..., None, :]
    rr = np.linalg.norm(d, axis=-1)
    return np.stack([2 * rr[..., 0], rr[..., 0] + rr[..., 1]], -1), d / rr[..., None]


class TwoGeoRanges:
    """The two RDSS paths of each request against one INS stream (see the module notes).

    Parameters
    ----------
    t_valid : array_like (J,)
        Times the paths were measured [s] (filter epochs for the lag policies that need them).
    paths : array_like (J, 2)
        ``[ρa, ρb]`` [m].
    sat_lon1, sat_lon2 : float
        Longitudes of the inquiry satellite (round trip) and of the second one [rad].
    range_sigma : float
        σ of each path [m] (``√(m0² + m1²)``).
    height_sigma : float
        σ of the held height [m] (ΔH).
    t_arrive : array_like (J,), optional
        Arrival times [s] (default: the validity times).
    windows : sequence of (start, end) [s], optional
        Requests processed outside are dropped.
    sat_radius : float
    stream : int
    """

    def __init__(self, t_valid, paths, sat_lon1, sat_lon2, range_sigma, height_sigma, *, t_arrive=None,
                 windows=None, sat_radius=E.GEO_RADIUS, stream=0):
        self.t_valid = np.atleast_1d(np.asarray(t_valid, dtype=float))
        self.t_arrive = self.t_valid.copy() if t_arrive is None else np.asarray(t_arrive, dtype=float)
        self.paths = np.asarray(paths, dtype=float).reshape(self.t_valid.size, 2)
        if self.t_arrive.shape != self.t_valid.shape or not np.all(self.t_arrive >= self.t_valid):
            raise ValueError("one arrival time per request, none before its validity time")
        if not (range_sigma > 0 and height_sigma >= 0):
            raise ValueError(f"range_sigma must be > 0 and height_sigma >= 0, got {range_sigma}, {height_sigma}")
        self.sats = (float(sat_lon1), float(sat_lon2), float(sat_radius))
        self.range_sigma = float(range_sigma)
        self.height_sigma = float(height_sigma)
        self.windows = windows
        self.stream = int(stream)

    def epochs(self, grid):
        return arrival_epochs(self.t_valid, self.t_arrive, grid, windows=self.windows)

    def times(self, item):
        return float(self.t_valid[item]), float(self.t_arrive[item])

    def matrices(self, ep: Epoch):
        nr = ep.streams[self.stream]
        lat, lon, h = float(nr.lat), float(nr.lon), float(nr.h)
        rho, e = geo_paths(lat, lon, h, *self.sats)
        Cne = E.enu_to_ecef_matrix(lat, lon)
        rm, rn = E.radii_s(lat, h)
        dr = -e @ Cne                                    # ∂r_i/∂(east, north, up) [m/m] (2, 3)
        A = np.array([[2.0, 0.0], [1.0, 1.0]])          # paths from the two distances
        lay = ep.layout
        sp = lay.slice("dp")
        H = np.zeros((2, ep.n))
        H[:, sp.start] = A @ dr[:, 1] * rm
        H[:, sp.start + 1] = A @ dr[:, 0] * rn * math.cos(lat)
        g = A @ dr[:, 2]
        R = self.range_sigma ** 2 * np.eye(2) + self.height_sigma ** 2 * np.outer(g, g)
        # an item applied after its validity time by a policy that keeps the current rows
        # is compared as if valid now (the driver's on-arrival rule)
        return rho - self.paths[ep.item], H, R
