"""Paper 003 beyond the paper: the SINS / two-GEO integration fed with the two measured
signal paths (and the height source) instead of the two-GEO position fix.

:func:`integrate_ranges` is :func:`sinslab.methods.doublestar.integrate` with the
measurement :class:`sinslab.fusion.rdss.TwoGeoRanges` in place of the 2-component fix: the
same 16-state horizontal model, the same held vertical channel, the same modes and lag
policies (the paths measured at t arrive at t + ΔT), the same feedback. The fix of the
paper is a nonlinear function of the same two paths and of the height; the filter here
takes them with their own noise (``m0``, ``m1`` per path, ``ΔH`` through the held height),
so the geometry's correlation of the north and east fix errors is kept, not lost.

:func:`plan_paths` draws both measurements from one error draw (:class:`PathPlan`): the
measured paths for :func:`integrate_ranges` and the fix solved from them at the erroneous
height for :func:`sinslab.methods.doublestar.integrate`, so the two filters can be compared
on the same draws.
"""
from __future__ import annotations

import numpy as np

from dataclasses import dataclass

from sinslab.core.earth import GEO_RADIUS
from sinslab.core.records import Fixes
from sinslab.methods.doublestar import (Integration, StoredStateUpdate, check_integration, check_windows,
                                        mode_policy)

__all__ = ["integrate_ranges", "PathPlan", "plan_paths"]


@dataclass(frozen=True)
class PathPlan:
    """A request schedule with what every draw on it shares (:func:`plan_paths`).

    Attributes
    ----------
    t, t_arrive : (J,) request (validity) and arrival times [s]
    lat, lon, h : (J,) true position at the requests [rad, rad, m]
    clean : (J, 2) error-free paths ``[ρa, ρb]`` [m]
    up : (J, 2) ∂[ρa, ρb]/∂h [m/m] along the local vertical
    solve : (J, 2, 2) first-order fix solution: (north, east) error [m] per path error [m]
    sigma : (J, 2) σ north, east [m] the fix filter is given (paper eqs 11–15)
    range_sigma, height_sigma : σ of each path (√(m0² + m1²)) and of the height source (ΔH) [m]
    """

    t: np.ndarray
    t_arrive: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    clean: np.ndarray
    up: np.ndarray
    solve: np.ndarray
    sigma: np.ndarray
    range_sigma: float
    height_sigma: float

    def draw(self, rng):
        """One error draw from ``rng`` (J×2 path errors, then J height errors, normal).

        Returns
        -------
        paths : (J, 2)
            The paths as the filter holding the true height sees them [m]: the measured
            paths ``clean + e`` moved by ``−up·ΔH`` (to first order, a fix solved at
            ``h + ΔH`` from ``clean + e`` has the paths ``clean + e − up·ΔH`` at ``h``).
        fixes : sinslab.core.records.Fixes
            The fix solved from the measured paths at the height ``h + ΔH`` (first order;
            it lies millimetres from the Newton solution for errors of hundreds of metres),
            with the plan's σ and NaN height (a horizontal fix), the drawn north/east
            errors in ``err``.
        """
        from sinslab.core.earth import radii

        J = self.t.size
        e = rng.standard_normal((J, 2)) * self.range_sigma
        dh = rng.standard_normal(J) * self.height_sigma
        res = e - self.up * dh[:, None]
        dne = np.einsum("jab,jb->ja", self.solve, res)
        rm, rn = radii(self.lat, self.h)
        nan = np.full(J, np.nan)
        fixes = Fixes(self.t, self.lat + dne[:, 0] / rm, self.lon + dne[:, 1] / (rn * np.cos(self.lat)), nan,
                      np.stack([self.sigma[:, 0], self.sigma[:, 1], nan], -1), t_arrive=self.t_arrive,
                      err=np.stack([dne[:, 0], dne[:, 1], nan], -1))
        return self.clean + res, fixes


def plan_paths(truth, windows, *, sat_lon1, sat_lon2, m0, m1, dH, latency, rng=None, latency_jitter=0.0,
               grid=1.0, height_factor="paper", sat_radius=GEO_RADIUS) -> PathPlan:
    """The request schedule of :func:`sinslab.methods.doublestar.plan_fixes` with the true
    paths, their height sensitivity and the first-order fix solution at each request.

    Parameters as :func:`sinslab.methods.doublestar.simulate_fixes` (``height_factor`` only
    sets the σ the fix filter is given; the drawn errors come from the paths).
    """
    from sinslab.core import earth as E
    from sinslab.fusion.rdss import geo_paths
    from sinslab.methods import doublestar as ds

    fp = ds.plan_fixes(truth, windows, sat_lon1=sat_lon1, sat_lon2=sat_lon2, m0=m0, m1=m1, dH=dH,
                       latency=latency, rng=rng, latency_jitter=latency_jitter, grid=grid,
                       height_factor=height_factor, sat_radius=sat_radius)
    clean, los = geo_paths(fp.lat, fp.lon, fp.h, sat_lon1, sat_lon2, sat_radius)
    # ∂r_i/∂(east, north, up), then the paths ρa = 2 r1, ρb = r1 + r2
    dr = -np.einsum("jsi,jik->jsk", los, E.enu_to_ecef_matrix(fp.lat, fp.lon))
    dp = np.einsum("ps,jsk->jpk", np.array([[2.0, 0.0], [1.0, 1.0]]), dr)
    solve = np.linalg.inv(dp[:, :, [1, 0]])              # (north, east) from path errors
    return PathPlan(fp.t, fp.t_arrive, fp.lat, fp.lon, fp.h, clean, dp[:, :, 2], solve, fp.sigma,
                    float(np.hypot(m0, m1)), float(dH))


def integrate_ranges(imu, init, t, paths, model, P0, *, sat_lon1, sat_lon2, range_sigma, height_sigma,
                     t_arrive=None, mode="lag-aware", lag=StoredStateUpdate(), height, windows=None,
                     kf_dt=1.0, nsub=2, max_block=60.0, discretization="series") -> Integration:
    """SINS / two-GEO integration on the measured paths (see the module notes).

    Parameters
    ----------
    imu, init, model, P0, mode, lag, height, windows, kf_dt, nsub, max_block, discretization
        As in :func:`sinslab.methods.doublestar.integrate`.
    t : array_like (J,)
        Measurement times [s], filter epochs.
    paths : array_like (J, 2)
        ``[ρa, ρb]`` [m] (:func:`sinslab.fusion.rdss.geo_paths` of the true position plus
        errors).
    sat_lon1, sat_lon2 : float
        Inquiry and second satellite longitudes [rad].
    range_sigma, height_sigma : float
        σ of each path (√(m0² + m1²)) and of the held height (ΔH) [m].
    t_arrive : array_like (J,), optional
        Arrival times [s] (``t + ΔT``); default ``t``.

    Returns
    -------
    Integration
        ``fix_t`` the measurement times applied, ``innovation`` (J, 2) of the paths [m].
    """
    from sinslab.fusion import driver
    from sinslab.fusion.driver import LiveStream
    from sinslab.fusion.feedback import FeedbackLayout
    from sinslab.fusion.loosely_coupled import LooselyCoupled
    from sinslab.fusion.rdss import TwoGeoRanges
    from sinslab.fusion.spec import FilterGrid

    lay = check_integration(mode, model, "integrate_ranges")
    t = np.asarray(t, dtype=float)
    arrive = t if (t_arrive is None or mode == "zero-lag") else np.asarray(t_arrive, dtype=float)
    meas = TwoGeoRanges(t, paths, sat_lon1, sat_lon2, range_sigma, height_sigma, t_arrive=arrive,
                        windows=None if windows is None else check_windows(windows))
    policy = mode_policy(mode, lag)
    ins = LiveStream(imu, init, nsub=nsub, vertical="hold", height=height)
    grid = FilterGrid(kf_dt, max_block=max_block, model_every=0.0, discretization=discretization)
    r = driver.run([ins], model, P0, [meas], grid=grid,
                   feedback=[(0, FeedbackLayout.from_model(lay, gyro="eps_b", accel=None))], lag=policy)
    ap = r.applied
    inn = np.array(ap.innovation, dtype=float).reshape(-1, 2)
    return Integration(LooselyCoupled(r.t, r.nav[0], r.x, r.sigma, r.gyro_bias[0], r.accel_bias[0],
                                      None if r.scale is None else r.scale[0], t[ap.item], ap.t_applied,
                                      ap.item, inn, ap.nis, r.layout), mode, lag)
