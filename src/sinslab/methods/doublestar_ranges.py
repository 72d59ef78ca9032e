"""Paper 003 beyond the paper: the SINS / two-GEO integration fed with the two measured
signal paths (and the height source) instead of the two-GEO position fix.

:func:`integrate_ranges` is :func:`sinslab.methods.doublestar.integrate` with the
measurement :class:`sinslab.fusion.rdss.TwoGeoRanges` in place of the 2-component fix: the
same 16-state horizontal model, the same held vertical channel, the same modes and lag
policies (the paths measured at t arrive at t + ΔT), the same feedback. The fix of the
paper is a nonlinear function of the same two paths and of the height; the filter here
takes them with their own noise (``m0``, ``m1`` per path, ``ΔH`` through the held height),
so the geometry's correlation of the north and east fix errors is kept, not lost.
"""
from __future__ import annotations

import numpy as np

from sinslab.methods.doublestar import Integration, StoredStateUpdate, check_integration, check_windows

__all__ = ["integrate_ranges"]


def integrate_ranges(imu, init, t, paths, model, P0, *, sat_lon1, sat_lon2, range_sigma, height_sigma,
                     t_arrive=None, mode="lag-aware", lag_method="paper003", height, windows=None,
                     kf_dt=1.0, nsub=2, max_block=60.0, discretization="series") -> Integration:
    """SINS / two-GEO integration on the measured paths (see the module notes).

    Parameters
    ----------
    imu, init, model, P0, mode, lag_method, height, windows, kf_dt, nsub, max_block, discretization
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
    from sinslab.fusion.lag import ExactReprocessing, OnArrival
    from sinslab.fusion.rdss import TwoGeoRanges

    lay = check_integration(mode, lag_method, model, "integrate_ranges")
    t = np.asarray(t, dtype=float)
    arrive = t if (t_arrive is None or mode == "zero-lag") else np.asarray(t_arrive, dtype=float)
    meas = TwoGeoRanges(t, paths, sat_lon1, sat_lon2, range_sigma, height_sigma, t_arrive=arrive,
                        windows=None if windows is None else check_windows(windows))
    if mode == "lag-ignore":
        policy = OnArrival()
    else:
        policy = StoredStateUpdate() if lag_method == "paper003" else ExactReprocessing()
    ins = LiveStream(imu, init, nsub=nsub, vertical="hold", height=height)
    r = driver.run([ins], model, P0, [meas], kf_dt=kf_dt,
                   feedback=[(0, FeedbackLayout.from_model(lay, gyro="eps_b", accel=None))], lag=policy,
                   max_block=max_block, model_every=0.0, discretization=discretization)
    ap = r.applied
    inn = np.array(ap.innovation, dtype=float).reshape(-1, 2)
    return Integration(r.t, r.nav[0], r.x, r.sigma, r.gyro_bias[0], t[ap.item], ap.t_applied, inn, mode,
                       lag_method)
