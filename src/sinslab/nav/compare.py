"""Comparing a navigation solution with the truth: errors as computed − true.

One definition for every experiment and test: velocity errors in ENU [m/s], the
misalignment φ of the computed attitude (``C_b^{n'} = exp(−φ×) C_b^n``) [rad], Euler-angle
differences [rad], latitude/longitude errors [rad] and their north/east lengths [m].
"""
from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike

from sinslab.core import attitude as att_
from sinslab.core import earth
from sinslab.core.records import NavSeries

__all__ = ["nav_errors", "nav_errors_many", "row_errors", "match_epochs"]


def match_epochs(truth: NavSeries, t: ArrayLike, tol: float = 1e-6) -> np.ndarray:
    """Indices of the truth epochs equal (within ``tol`` s) to the times ``t``.

    Raises ValueError when the truth lacks any of them (the truth may be denser).
    """
    t = np.asarray(t, dtype=float)
    idx = np.searchsorted(truth.t, t - tol)
    if idx.size and (idx.max() >= len(truth.t) or np.max(np.abs(truth.t[idx] - t)) > tol):
        raise ValueError("the truth does not contain every epoch of the solution")
    return idx


def nav_errors(nav: NavSeries, truth: NavSeries, imu_frame: bool = False) -> dict[str, np.ndarray]:
    """Errors (computed − true) of a solution against a truth series on the same epochs
    (truth epochs are matched by time; the truth may be denser).

    Returns ``{"t", "vE", "vN", "vU" [m/s], "phiE", "phiN", "phiU" [rad] (misalignment φ of
    the computed attitude), "pitch", "roll", "yaw" [rad] (Euler differences), "lat",
    "lon" [rad], "north", "east", "up" [m]}``. ``imu_frame`` compares the IMU attitudes.
    """
    return row_errors(nav, truth.at(match_epochs(truth, nav.t)), imu_frame)


def row_errors(nav: NavSeries, truth: NavSeries, imu_frame: bool = False) -> dict[str, np.ndarray]:
    """:func:`nav_errors` against truth rows given row for row (no matching by time).

    ``nav`` may hold several runs stacked along the rows, each on the epochs of ``truth``
    (``len(nav)`` a multiple of ``len(truth)``): the truth's attitude matrices and radii
    are computed once and repeated, in one pass over all runs."""
    return _errors(nav, _truth_terms(truth, imu_frame), imu_frame)


def nav_errors_many(navs: Iterable[NavSeries], truth: NavSeries, imu_frame: bool = False) -> list[dict[str, np.ndarray]]:
    """:func:`nav_errors` of several solutions on the same epochs against one truth: the
    epochs are matched and the truth's attitude matrices and radii computed once (the same
    numbers as one call per solution). Solutions on different epochs are compared one by one."""
    navs = list(navs)
    if not navs or any(len(n.t) != len(navs[0].t) or not np.array_equal(n.t, navs[0].t) for n in navs[1:]):
        return [nav_errors(n, truth, imu_frame) for n in navs]
    terms = _truth_terms(truth.at(match_epochs(truth, navs[0].t)), imu_frame)
    return [_errors(n, terms, imu_frame) for n in navs]


def _truth_terms(truth: NavSeries, imu_frame):
    """What the errors need of the truth rows: the rows, their attitude (Euler and DCM) and
    the radii of curvature."""
    a_tr = truth.att_imu if (imu_frame and truth.att_imu is not None) else truth.att
    rm, rn = earth.radii(truth.lat, truth.h)
    return truth, a_tr, att_.euler_to_dcm(a_tr), rm, rn


def _errors(nav: NavSeries, terms, imu_frame) -> dict:
    truth, a_tr, C_tr, rm, rn = terms
    m = len(truth)
    if m == 0 or len(nav) % m:
        raise ValueError(f"{len(nav)} solution rows are not whole runs of the {m} truth rows")
    reps = len(nav) // m

    def rep(a):
        return a if reps == 1 else np.tile(a, (reps,) + (1,) * (a.ndim - 1))

    a_nav = nav.att_imu if (imu_frame and nav.att_imu is not None) else nav.att
    phi = att_.misalignment(rep(C_tr), att_.euler_to_dcm(a_nav))
    d_att = att_.wrap_pi(a_nav - rep(a_tr))
    lat = rep(truth.lat)
    dlat = nav.lat - lat
    dlon = att_.wrap_pi(nav.lon - rep(truth.lon))
    dv = nav.vel - rep(truth.vel)
    return {"t": nav.t, "vE": dv[:, 0], "vN": dv[:, 1], "vU": dv[:, 2],
            "phiE": phi[:, 0], "phiN": phi[:, 1], "phiU": phi[:, 2],
            "pitch": d_att[:, 0], "roll": d_att[:, 1], "yaw": d_att[:, 2],
            "lat": dlat, "lon": dlon, "north": dlat * rep(rm), "east": dlon * rep(rn) * np.cos(lat),
            "up": nav.h - rep(truth.h)}
