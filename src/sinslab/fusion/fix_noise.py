"""How the position fixes of a record really err, from the record itself.

A receiver's position error is not white: multipath and the atmosphere move it by metres
over tens of seconds while its Doppler velocity stays good to centimetres per second. A
filter that takes 5 fixes a second with a white σ of 1 m believes their average to 0.1 m
within 2 s, follows the error's drift and carries its rate (0.1–0.5 m/s) in its velocity
into the next outage.

The error's time structure is measured against the fixes' own velocities: over a lag Δ
the position change minus the integrated velocity (trapezoid rule) is the change of the
position error plus the velocity noise integrated, so per axis its mean square (the
structure function)::

    D(Δ) = 2σ_w² + 2σ_c² (1 − e^(−Δ/τ)) + q_v Δ

with σ_w the white part, σ_c and τ a first-order Gauss–Markov part and q_v the random
walk of the integrated velocity error (a Doppler velocity's errors last seconds: their
integral grows like a random walk, whatever the σ the receiver states). σ_w², σ_c² and
q_v are fitted by non-negative least squares (relative residuals) for each τ of a
logarithmic grid up to half the longest lag, the τ of the smallest residual kept. The filter then carries the Gauss–Markov part as states
(:func:`sinslab.nav.errstate.fix_position_error`) and the white part as the fixes' σ.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import earth as E
from sinslab.core.records import Fixes

__all__ = ["FixErrorModel", "fix_error_model"]


@dataclass(frozen=True)
class FixErrorModel:
    """The fixes' position error: white σ and Gauss–Markov σ, τ per axis (east, north, up)."""

    white: np.ndarray        #: (3,) [m]
    correlated: np.ndarray   #: (3,) steady-state σ of the Gauss–Markov part [m]
    tau: float               #: [s] (one for the three axes)
    lags: np.ndarray         #: (k,) [s] the lags of the structure function
    structure: np.ndarray    #: (k, 3) its measured values [m²]
    velocity_walk: np.ndarray = None  #: (3,) [m/√s] the integrated velocity error's random walk

    def describe(self):
        return (f"white {', '.join(f'{x:.2f}' for x in self.white)} m, correlated "
                f"{', '.join(f'{x:.2f}' for x in self.correlated)} m over {self.tau:.0f} s (east, north, up)")


def _enu_positions(fixes):
    rm, rn = E.radii(fixes.lat, fixes.h)
    lat0 = float(fixes.lat[0])
    return np.stack([(fixes.lon - fixes.lon[0]) * rn * math.cos(lat0), (fixes.lat - fixes.lat[0]) * rm,
                     fixes.h - fixes.h[0]], -1)


def fix_error_model(fixes: Fixes, *, max_lag=120.0, n_lags=24, gap=None):
    """The :class:`FixErrorModel` of ``fixes`` (see the module notes), or None when they
    have no velocities or span less than four lags. Gaps longer than ``gap`` [s]
    (default 3 fix intervals) break the integration: pairs across them are not used."""
    if fixes.vel is None or len(fixes) < 20:
        return None
    t = fixes.t
    h = float(np.median(np.diff(t)))
    gap = 3.0 * h if gap is None else float(gap)
    p = _enu_positions(fixes)
    v = fixes.vel
    seg = np.concatenate([[0], np.cumsum(np.diff(t) > gap)])       # integration segments
    iv = np.vstack([np.zeros((1, 3)), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None], 0)])
    span = float(t[-1] - t[0])
    max_lag = min(max_lag, span / 4)
    if max_lag < 4 * h:
        return None
    lags = np.unique(np.round(np.geomspace(h, max_lag, n_lags) / h).astype(int))
    D, used = [], []
    for m in lags:
        ok = seg[m:] == seg[:-m]
        if ok.sum() < 10:
            continue
        d = (p[m:] - p[:-m]) - (iv[m:] - iv[:-m])
        D.append(np.mean(d[ok] ** 2, 0))
        used.append(m * h)
    if len(used) < 4:
        return None
    D, lags = np.array(D), np.array(used)
    return _fit(D, lags, h)


def _fit(D, lags, h):
    from scipy.optimize import nnls
    best = None
    for tau in np.geomspace(max(2 * h, 0.5), 0.5 * float(lags[-1]), 40):
        A = np.column_stack([np.full(lags.size, 2.0), 2.0 * (1.0 - np.exp(-lags / tau)), lags])
        cost, coef = 0.0, []
        for k in range(3):
            w = 1.0 / np.maximum(D[:, k], 1e-8)
            c, r = nnls(A * w[:, None], D[:, k] * w)
            cost += r * r
            coef.append(c)
        if best is None or cost < best[0]:
            best = (cost, tau, np.array(coef))
    _, tau, coef = best
    return FixErrorModel(np.sqrt(coef[:, 0]), np.sqrt(coef[:, 1]), float(tau), lags, D,
                         np.sqrt(coef[:, 2]))
