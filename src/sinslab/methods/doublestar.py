"""Beidou-1 ("double-star", two-GEO) positioning and its lag-aware fusion with a SINS.

Paper 003 (Liu, Lin, Lai, Sun 2004). Three parts, usable with any parameters and data:

1. **Fix error model** (paper eqs 11–15). A two-GEO RDSS fix measures two ranges through
   two geostationary satellites and takes the height from a map or a barometer. With
   satellite longitudes λ1, λ2 and the user at (λ, L, h), ranging error m0 (after
   differential correction), equivalent ephemeris range error m1 and height error ΔH::

       s_ns0 = m0 / (2 sinL sin(λ2−λ1)) · sqrt(sin²(λ2−λ) + 5 sin²(λ1−λ) + 2 sin(λ2−λ) sin(λ1−λ))
       s_ew0 = m0 / (2 sin(λ2−λ1))      · sqrt(cos²(λ2−λ) + 5 cos²(λ1−λ) + 2 cos(λ2−λ) cos(λ1−λ))
       s_ns1, s_ew1: the same with m1
       s_nsH = | cotL·ΔH − k ΔH (sin(λ2−λ) − sin(λ1−λ)) / (sinL sin(λ2−λ1)) |
       s_ewH = k ΔH | (cos(λ2−λ) − cos(λ1−λ)) / sin(λ1−λ2) |
       s_ns = sqrt(s_ns0² + s_ns1² + s_nsH²),  s_ew likewise

   :func:`fix_error` evaluates them (vectorised over any grid). The paper prints
   ``k = R_N / (R_N + h)`` with h the *user* height (``height_factor="paper"``, the
   default, reproduces that). Derivation (module tests, :func:`fix_error_linearised`):
   the two measured quantities are the round trip through satellite 1,
   ``ρa = 2 r1``, and the path through both satellites, ``ρb = r1 + r2``, each with
   error σ = m0 — the 5 and 2 of eqs 11–12 are exactly the variances of
   ``r1 = ρa/2``, ``r2 = ρb − ρa/2``; eqs 11–12 are then the first-order solution with
   ``r_i ≈ r_s`` (user–satellite range ≈ orbit radius). The same first-order solution
   gives the height terms with ``k = (R_N + h)/r_s`` ≈ 0.15 (Earth radius over the GEO
   orbit radius), i.e. the paper's "h" must be read as the satellite's altitude, not the
   user's (``height_factor="geometric"``). With the paper's literal k ≈ 1 the height
   term is larger (ns 106 m instead of 84 m at 32° N, 118° E for the paper's
   parameters). Satellite 1 is the one that carries the round trip (the inquiry
   satellite).

2. **Fix simulator** (:func:`request_schedule`, :func:`simulate_fixes`): inside covert
   windows the receiver requests a fix at t, receives the position *of time t* at
   t + ΔT and immediately requests the next one (paper §2); ΔT constant or random.

3. **Integration filter** (:func:`horizontal_model`, :func:`integrate`): the 16-state
   horizontal error model (φ 3, δvE, δvN, δL, δλ, gyro constant drift 3, gyro first-order
   Markov drift 3, accelerometer first-order Markov bias 3) from
   :mod:`sinslab.nav.errstate`, the strapdown mechanization of :mod:`sinslab.nav.strapdown`
   (vertical channel held to an external height) and one
   :class:`sinslab.estimation.filter.KalmanFilter`, run by the fusion driver through
   :func:`sinslab.fusion.loosely_coupled.loosely_coupled` (2-component fixes, fixes only
   inside the windows), in three modes:

   * ``"lag-aware"``: the fix valid at t arrives at t + ΔT and is applied at t with a lag
     policy of :mod:`sinslab.fusion.lag` (:class:`StoredStateUpdate`, the paper's eqs 4–10: update at t from the state
     stored at the last step, then one prediction ``expm(A ΔT)`` with the integrated Q; or
     :class:`sinslab.fusion.lag.ExactReprocessing`: re-process the stored steps), then the
     correction is fed back to the INS;
   * ``"lag-ignore"``: the fix is applied at its arrival as if it were current;
   * ``"zero-lag"``: an ideal receiver whose fix of time t is available at t.

   Feedback: φ, δv, δp and the gyro constant drift are fed back (navigation state and
   gyro compensation); the Gauss–Markov states stay in the filter (feed-forward) because
   a constant compensation of a decaying process would not follow the model.

Conventions: ENU, errors computed − true (:mod:`sinslab.nav.errstate`); the position
measurement is ``z = [(L_ins − L_fix)(R_M+h), (λ_ins − λ_fix)(R_N+h) cosL]`` (north, east,
metres) with ``H = [0₂ₓ₅, diag(R_M+h, (R_N+h)cosL), 0₂ₓ₉]`` (paper eq 2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core.records import Fixes
from sinslab.fusion import lag as _lag

__all__ = [
    "FixError", "fix_error", "fix_error_linearised", "fix_covariance",
    "measure_ranges", "solve_fix", "request_schedule", "FixPlan", "plan_fixes",
    "simulate_fixes",
    "horizontal_model", "initial_covariance", "FEEDBACK", "Integration", "integrate", "integrate_many",
    "StoredStateUpdate", "lag_policy", "mode_policy",
    "MODES", "horizontal_errors", "check_windows", "check_geometry", "check_integration",
]

_SMALL = 1e-9
MODES = ("lag-aware", "lag-ignore", "zero-lag")


# ======================================================================== error model
@dataclass(frozen=True)
class FixError:
    """Standard deviations of a two-GEO fix [m], each of shape S (the broadcast grid).

    ``ns``/``ew``: north–south and east–west totals (eq 15); ``*_range`` from the ranging
    error m0 (eqs 11, 12), ``*_ephem`` from the equivalent ephemeris error m1,
    ``*_height`` from the height error ΔH (eqs 13, 14).
    """

    ns: np.ndarray
    ew: np.ndarray
    ns_range: np.ndarray
    ew_range: np.ndarray
    ns_ephem: np.ndarray
    ew_ephem: np.ndarray
    ns_height: np.ndarray
    ew_height: np.ndarray


def check_geometry(lat, sat_lon1, sat_lon2):
    """The geometry checks of :func:`fix_error`: user latitude and satellite longitudes
    [rad] as float arrays, or ValueError where the two-GEO fix has no solution (non-finite
    values, satellites at equal or opposite longitudes, a latitude beyond ±90 deg, the equator)."""
    lat = np.asarray(lat, dtype=float)
    l1 = np.asarray(sat_lon1, dtype=float)
    l2 = np.asarray(sat_lon2, dtype=float)
    if not (np.all(np.isfinite(lat)) and np.all(np.isfinite(l1)) and np.all(np.isfinite(l2))):
        raise ValueError("latitude and satellite longitudes must be finite")
    if np.any(np.abs(np.sin(l2 - l1)) < _SMALL):
        raise ValueError("satellite longitudes are equal (or 180 deg apart): the two-GEO geometry "
                         "is singular (sin(lon2 - lon1) = 0)")
    if np.any(np.abs(lat) >= math.pi / 2):
        raise ValueError("latitude must be inside (-90, 90) deg")
    if np.any(np.abs(np.sin(lat)) < _SMALL):
        raise ValueError("user on the equator (sin L = 0): the two-GEO fix has no north-south "
                         "solution there (the two range spheres meet the Earth symmetrically)")
    return lat, l1, l2


def _height_k(lat, h, height_factor, sat_radius):
    sat_radius = _geo_radius(sat_radius)
    from sinslab.core.earth import radii

    _, rn = radii(lat, 0.0)
    if height_factor == "paper":
        return rn / (rn + h)
    if height_factor == "geometric":
        return (rn + h) / sat_radius
    raise ValueError(f"height_factor must be 'paper' or 'geometric', got {height_factor!r}")


def _coefficients(lat, lon, h, sat_lon1, sat_lon2, height_factor, sat_radius):
    """First-order maps (closed form, r_i ≈ r_s) from [e_a, e_b, ΔH] to [dN, dE].

    e_a: error of the round trip through satellite 1 (ρa = 2 r1), e_b: of the path through
    both (ρb = r1 + r2), ΔH: height error. Returns cN (S+(3,)), cE (S+(3,)).
    """
    lat, l1, l2 = check_geometry(lat, sat_lon1, sat_lon2)
    lon = np.asarray(lon, dtype=float)
    h = np.asarray(h, dtype=float)
    a1 = lon - l1
    a2 = lon - l2
    sL = np.sin(lat)
    d = np.sin(a2 - a1)                         # = sin(λ1 − λ2)
    D = sL * d
    k = _height_k(lat, h, height_factor, sat_radius)
    s1, s2, c1, c2 = np.sin(a1), np.sin(a2), np.cos(a1), np.cos(a2)
    cN = np.stack(np.broadcast_arrays((s1 + s2) / 2 / D, -s1 / D,
                                      np.cos(lat) / sL - k * (s2 - s1) / D), -1)
    cE = np.stack(np.broadcast_arrays(-(c1 + c2) / 2 / d, c1 / d, k * (c2 - c1) / d), -1)
    return cN, cE


def fix_error(lat, lon, sat_lon1, sat_lon2, m0, m1, dH, h=0.0, *, height_factor="paper",
              sat_radius=None) -> FixError:
    """Two-GEO fix standard deviations, paper eqs 11–15 (vectorised).

    Parameters
    ----------
    lat, lon : array_like
        User latitude and longitude [rad] (any broadcastable shapes, e.g. a meshgrid).
    sat_lon1, sat_lon2 : float or array_like
        Longitudes [rad] of satellite 1 (round trip, inquiry) and satellite 2.
    m0 : float
        Ranging error (after differential correction) [m], σ of each measured path.
    m1 : float
        Equivalent ranging error of the ephemeris after differential correction [m].
    dH : float
        Height (elevation) error σ [m].
    h : float or array_like
        User height [m].
    height_factor : {"paper", "geometric"}
        ``k`` of the height terms: ``R_N/(R_N+h)`` as printed, or ``(R_N+h)/r_s`` from the
        derivation (see the module notes).
    sat_radius : float
        Geocentric orbit radius [m] (``"geometric"`` only).

    Returns
    -------
    FixError

    Raises
    ------
    ValueError
        Equal satellite longitudes (singular geometry), a user on the equator, negative σ.
    """
    for name, v in (("m0", m0), ("m1", m1), ("dH", dH)):
        if not (np.all(np.isfinite(v)) and np.all(np.asarray(v) >= 0)):
            raise ValueError(f"{name} must be a finite standard deviation >= 0, got {v!r}")
    cN, cE = _coefficients(lat, lon, h, sat_lon1, sat_lon2, height_factor, sat_radius)
    # e_a and e_b each have σ = m; the two parts of one error source are independent
    gN = np.sqrt(cN[..., 0] ** 2 + cN[..., 1] ** 2)
    gE = np.sqrt(cE[..., 0] ** 2 + cE[..., 1] ** 2)
    ns0, ew0 = m0 * gN, m0 * gE
    ns1, ew1 = m1 * gN, m1 * gE
    nsH, ewH = np.abs(cN[..., 2]) * dH, np.abs(cE[..., 2]) * dH
    return FixError(np.sqrt(ns0 ** 2 + ns1 ** 2 + nsH ** 2), np.sqrt(ew0 ** 2 + ew1 ** 2 + ewH ** 2),
                    ns0, ew0, ns1, ew1, nsH, ewH)


def fix_covariance(lat, lon, sat_lon1, sat_lon2, m0, m1, dH, h=0.0, *, height_factor="paper",
                   sat_radius=None):
    """Full 2×2 covariance [m²] of the (north, east) fix error, shape S + (2, 2).

    Its diagonal is ``fix_error(...).ns**2`` and ``.ew**2``; the off-diagonal is the
    correlation the paper neglects (north and east errors come from the same two range
    errors and the same height error).
    """
    cN, cE = _coefficients(lat, lon, h, sat_lon1, sat_lon2, height_factor, sat_radius)
    w = np.array([m0 ** 2 + m1 ** 2, m0 ** 2 + m1 ** 2, dH ** 2], dtype=float)
    P = np.empty(cN.shape[:-1] + (2, 2))
    P[..., 0, 0] = (cN * cN * w).sum(-1)
    P[..., 1, 1] = (cE * cE * w).sum(-1)
    P[..., 0, 1] = P[..., 1, 0] = (cN * cE * w).sum(-1)
    return P


# ------------------------------------------------------------------ exact geometry
def _geo_radius(sat_radius):
    """``sat_radius`` [m], None for the geostationary radius of :mod:`sinslab.core.earth`
    (imported here, not with the module: a config validator imports this module and must
    not load the compiled Earth kernels)."""
    if sat_radius is None:
        from sinslab.core.earth import GEO_RADIUS
        return GEO_RADIUS
    return sat_radius


def _sat(lon_s, sat_radius):
    sat_radius = _geo_radius(sat_radius)
    lon_s = np.asarray(lon_s, dtype=float)
    return np.stack(np.broadcast_arrays(sat_radius * np.cos(lon_s), sat_radius * np.sin(lon_s),
                                        0.0 * lon_s), -1)


def measure_ranges(lat, lon, h, sat_lon1, sat_lon2, sat_radius=None):
    """The two measured paths ``ρa = 2 r1`` and ``ρb = r1 + r2`` [m] (shape S + (2,))."""
    from sinslab.core.earth import geodetic_to_ecef
    u = geodetic_to_ecef(lat, lon, h)
    r1 = np.linalg.norm(u - _sat(sat_lon1, sat_radius), axis=-1)
    r2 = np.linalg.norm(u - _sat(sat_lon2, sat_radius), axis=-1)
    return np.stack([2.0 * r1, r1 + r2], -1)


def solve_fix(rho, h, sat_lon1, sat_lon2, guess, *, sat_radius=None, tol=1e-7, max_iter=20):
    """Position (lat, lon) [rad] from the two measured paths and the height (Newton).

    Parameters
    ----------
    rho : array_like (2,)
        ``[ρa, ρb]`` [m] (see :func:`measure_ranges`).
    h : float
        Assumed height [m] (map / barometer).
    guess : (lat, lon) [rad]
        Start of the iteration, on the right side of the equator (two-GEO fixes have a
        mirror solution in the other hemisphere).

    Returns
    -------
    ndarray (2,)
    """
    x = np.array(guess, dtype=float)
    rho = np.asarray(rho, dtype=float)
    for _ in range(max_iter):
        f = measure_ranges(x[0], x[1], h, sat_lon1, sat_lon2, sat_radius) - rho
        J = np.empty((2, 2))
        for i, d in enumerate((1e-7, 1e-7)):
            xp = x.copy()
            xp[i] += d
            xm = x.copy()
            xm[i] -= d
            J[:, i] = (measure_ranges(xp[0], xp[1], h, sat_lon1, sat_lon2, sat_radius)
                       - measure_ranges(xm[0], xm[1], h, sat_lon1, sat_lon2, sat_radius)) / (2 * d)
        dx = np.linalg.solve(J, -f)
        x += dx
        if np.max(np.abs(dx)) < tol * 1e-7:
            break
    return x


def fix_error_linearised(lat, lon, sat_lon1, sat_lon2, m0, m1, dH, h=0.0, *,
                         sat_radius=None) -> FixError:
    """Exact first-order fix σ on the WGS-84 ellipsoid (no r_i ≈ r_s approximation).

    Same measurements and error sources as :func:`fix_error` (ρa = 2 r1, ρb = r1 + r2,
    σ = m0 and m1 each, height error ΔH), linearised exactly in ECEF: the reference the
    closed form is compared with.
    """
    lat, l1, l2 = check_geometry(lat, sat_lon1, sat_lon2)
    lat, lon, h = np.broadcast_arrays(lat, np.asarray(lon, float), np.asarray(h, float))
    from sinslab.core.earth import geodetic_to_ecef
    u = geodetic_to_ecef(lat, lon, h)
    sL, cL, sl, cl = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    eN = np.stack([-sL * cl, -sL * sl, cL], -1)
    eE = np.stack([-sl, cl, 0.0 * sl], -1)
    eU = np.stack([cL * cl, cL * sl, sL], -1)
    g = []
    for ls in (l1, l2):
        d = u - _sat(ls, sat_radius)
        g.append(d / np.linalg.norm(d, axis=-1, keepdims=True))        # ∂r/∂u
    # ∂[ρa, ρb]/∂[N, E] and ∂/∂U
    M = np.empty(lat.shape + (2, 2))
    b = np.empty(lat.shape + (2,))
    for j, e in enumerate((eN, eE)):
        dr1 = (g[0] * e).sum(-1)
        dr2 = (g[1] * e).sum(-1)
        M[..., 0, j] = 2 * dr1
        M[..., 1, j] = dr1 + dr2
    dr1u, dr2u = (g[0] * eU).sum(-1), (g[1] * eU).sum(-1)
    b[..., 0] = 2 * dr1u
    b[..., 1] = dr1u + dr2u
    Minv = np.linalg.inv(M)
    # position error = Minv (e − b ΔH); e = [e_a, e_b]
    cR = Minv                                          # S + (2 [N,E], 2 [e_a, e_b])
    cH = -np.einsum("...ij,...j->...i", Minv, b)       # S + (2,)
    gN = np.sqrt((cR[..., 0, :] ** 2).sum(-1))
    gE = np.sqrt((cR[..., 1, :] ** 2).sum(-1))
    ns0, ew0, ns1, ew1 = m0 * gN, m0 * gE, m1 * gN, m1 * gE
    nsH, ewH = np.abs(cH[..., 0]) * dH, np.abs(cH[..., 1]) * dH
    return FixError(np.sqrt(ns0 ** 2 + ns1 ** 2 + nsH ** 2), np.sqrt(ew0 ** 2 + ew1 ** 2 + ewH ** 2),
                    ns0, ew0, ns1, ew1, nsH, ewH)


# ======================================================================== fix simulator
def check_windows(windows, t_start=None, t_end=None):
    """Windows as a float array (W, 2), sorted, non-overlapping, inside [t_start, t_end]."""
    w = np.asarray(windows, dtype=float).reshape(-1, 2) if len(windows) else np.zeros((0, 2))
    if not np.all(np.isfinite(w)):
        raise ValueError("fix windows must be finite times")
    for a, b in w:
        if not b > a:
            raise ValueError(f"fix window ({a:g}, {b:g}) s ends before it starts")
    if np.any(w[1:, 0] < w[:-1, 1]):
        raise ValueError("fix windows must be sorted and must not overlap")
    if t_start is not None and w.size and (w[0, 0] < t_start - 1e-9 or w[-1, 1] > t_end + 1e-9):
        raise ValueError(f"fix windows {w[0, 0]:g}..{w[-1, 1]:g} s lie outside the IMU record "
                         f"{t_start:g}..{t_end:g} s")
    return w


def request_schedule(windows, latency, *, jitter=0.0, grid=1.0, t0=0.0, rng=None):
    """Fix requests and arrivals inside covert windows (paper §2, Fig. 1).

    In each window ``[a, b]`` the first request is at ``a``; each fix arrives ``ΔT`` after
    its request, and the next request is made at the first grid time at or after that
    arrival. Requests whose fix would arrive after ``b`` are not made.

    Parameters
    ----------
    windows : sequence of (start, end) [s]
    latency : float
        Mean delay ΔT [s] (≥ 0).
    jitter : float
        ΔT is uniform in ``[latency − jitter, latency + jitter]`` (needs ``rng``).
    grid : float
        Request times are multiples of ``grid`` after ``t0`` (the filter step, so the
        validity times are filter epochs).

    Returns
    -------
    t_request, t_arrive : ndarray (J,)

    Raises
    ------
    ValueError
        Negative latency, latency ≥ a window's length (no fix could arrive inside it), jitter
        larger than the latency.
    """
    w = check_windows(windows)
    latency, jitter = float(latency), float(jitter)
    if not (math.isfinite(latency) and latency >= 0):
        raise ValueError(f"latency must be >= 0 s, got {latency!r}")
    if not (math.isfinite(jitter) and 0 <= jitter <= latency):
        raise ValueError(f"latency jitter must be within 0..latency ({latency:g} s), got {jitter!r}")
    if jitter > 0 and rng is None:
        raise ValueError("a random latency (jitter > 0) needs rng")
    if not grid > 0:
        raise ValueError(f"grid must be > 0 s, got {grid!r}")
    req, arr = [], []
    for a, b in w:
        if latency + jitter >= b - a:
            raise ValueError(f"latency {latency + jitter:g} s >= the length of the fix window "
                             f"({a:g}, {b:g}) s: no fix requested in it could arrive inside it")
        t = t0 + math.ceil((a - t0) / grid - 1e-9) * grid
        while True:
            dT = latency if jitter == 0 else latency + jitter * (2.0 * rng.random() - 1.0)
            if t + dT > b + 1e-9:
                break
            req.append(t)
            arr.append(t + dT)
            nxt = t0 + math.ceil((t + dT - t0) / grid - 1e-9) * grid
            t = nxt if nxt > t + 1e-9 else t + grid
    return np.array(req), np.array(arr)


def _interp_truth(truth, t):
    tt = truth.t
    if np.any(t < tt[0] - 1e-9) or np.any(t > tt[-1] + 1e-9):
        raise ValueError(f"fix times {t.min():g}..{t.max():g} s lie outside the truth record "
                         f"{tt[0]:g}..{tt[-1]:g} s")
    lon = np.unwrap(truth.lon)
    return np.interp(t, tt, truth.lat), np.interp(t, tt, lon), np.interp(t, tt, truth.h)


@dataclass(frozen=True)
class FixPlan:
    """A fix schedule and what every draw on it shares: the true positions at the request
    times and the model σ there (:func:`plan_fixes`; :meth:`draw` adds the errors).

    Attributes
    ----------
    t, t_arrive : (J,) request (validity) and arrival times [s]
    lat, lon, h : (J,) true position at the requests [rad, rad, m]
    sigma : (J, 2) model σ north, east [m] (:func:`fix_error`)
    chol : (J, 2, 2) or None
        Cholesky factors of the full north/east covariance (``correlated=True``).
    """

    t: np.ndarray
    t_arrive: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    sigma: np.ndarray
    chol: np.ndarray | None = None

    def draw(self, rng) -> Fixes:
        """Fixes with errors drawn from ``rng`` (normal, the plan's σ or full covariance)."""
        from sinslab.core.earth import radii

        J = self.t.size
        if self.chol is not None:
            e = np.einsum("jab,jb->ja", self.chol, rng.standard_normal((J, 2)))
        else:
            e = rng.standard_normal((J, 2)) * self.sigma
        rm, rn = radii(self.lat, self.h)
        # horizontal fixes: the height is an external input (map/barometer), so h and its σ
        # are not part of the fix (NaN)
        nan = np.full(J, np.nan)
        return Fixes(self.t, self.lat + e[:, 0] / rm, self.lon + e[:, 1] / (rn * np.cos(self.lat)), nan,
                     np.stack([self.sigma[:, 0], self.sigma[:, 1], nan], -1), t_arrive=self.t_arrive,
                     err=np.stack([e[:, 0], e[:, 1], nan], -1))


def plan_fixes(truth, windows, *, sat_lon1, sat_lon2, m0, m1, dH, latency, rng=None,
               latency_jitter=0.0, grid=1.0, correlated=False, height_factor="paper",
               sat_radius=None) -> FixPlan:
    """The schedule of :func:`simulate_fixes` and the truth and σ at its requests.

    A constant latency (``latency_jitter = 0``) gives the same plan for every draw, so Monte
    Carlo runs make it once; a random latency draws the schedule from ``rng``. Parameters
    as :func:`simulate_fixes`.
    """
    check_windows(windows, truth.t[0], truth.t[-1])
    t_req, t_arr = request_schedule(windows, latency, jitter=latency_jitter, grid=grid,
                                    t0=float(truth.t[0]), rng=rng)
    if t_arr.size and t_arr.max() > truth.t[-1] + 1e-9:
        raise ValueError(f"a fix arrives at {t_arr.max():g} s, after the end of the record")
    lat, lon, h = _interp_truth(truth, t_req)
    fe = fix_error(lat, lon, sat_lon1, sat_lon2, m0, m1, dH, h, height_factor=height_factor,
                   sat_radius=sat_radius)
    chol = None
    if correlated:
        P = fix_covariance(lat, lon, sat_lon1, sat_lon2, m0, m1, dH, h,
                           height_factor=height_factor, sat_radius=sat_radius)
        chol = np.linalg.cholesky(P + 1e-12 * np.eye(2))
    return FixPlan(t_req, t_arr, lat, lon, h, np.stack([fe.ns, fe.ew], -1), chol)


def simulate_fixes(truth, windows, *, sat_lon1, sat_lon2, m0, m1, dH, latency, rng,
                   latency_jitter=0.0, grid=1.0, correlated=False, height_factor="paper",
                   sat_radius=None) -> Fixes:
    """Draw two-GEO fixes along a true trajectory inside covert windows.

    Returns :class:`sinslab.core.records.Fixes` with the request times as validity
    times ``t``, the arrivals in ``t_arrive``, σ north/east in ``sigma[:, :2]`` (the model σ
    the filter uses, R = diag(σ_ns², σ_ew²)), the drawn north/east errors in ``err`` and
    NaN height (a horizontal fix).

    Request/arrival times from :func:`request_schedule` (``grid`` from ``truth.t[0]``);
    the error of each fix is normal with the σ of :func:`fix_error` at the true position
    (independent north and east errors as the paper's filter assumes, or with
    ``correlated=True`` the full covariance of :func:`fix_covariance`). The same as
    ``plan_fixes(...).draw(rng)`` with one generator.

    Parameters
    ----------
    truth : sinslab.core.records.NavSeries
    windows : sequence of (start, end) [s], inside the truth record
    rng : numpy.random.Generator or int
    """
    rng = np.random.default_rng(rng)
    return plan_fixes(truth, windows, sat_lon1=sat_lon1, sat_lon2=sat_lon2, m0=m0, m1=m1, dH=dH,
                      latency=latency, rng=rng, latency_jitter=latency_jitter, grid=grid,
                      correlated=correlated, height_factor=height_factor,
                      sat_radius=sat_radius).draw(rng)


# ======================================================================== the filter
def horizontal_model(gyro_arw, gyro_markov_sigma, gyro_markov_tau, accel_markov_sigma,
                     accel_markov_tau, *, radius_derivatives=True) -> es.ErrorModel:
    """The paper's 16-state horizontal error model (eq 1) from :mod:`sinslab.nav.errstate`.

    States ``[φE φN φU, δvE δvN, δL δλ, ε_b (3, body), ε_r (3, body, Markov), ∇ (3, body,
    Markov)]``; noise ``[w_g (3), w_r (3), w_a (3)]``.

    Parameters
    ----------
    gyro_arw : float or (3,)
        Gyro white noise (angle random walk) [rad/√s].
    gyro_markov_sigma, gyro_markov_tau : steady-state σ [rad/s], correlation time [s]
    accel_markov_sigma, accel_markov_tau : steady-state σ [m/s²], correlation time [s]
    """
    from sinslab.nav import errstate as es

    return es.ErrorModel("horizontal",
                         [es.gyro_bias(name="eps_b"),
                          es.gyro_markov(gyro_markov_tau, gyro_markov_sigma, name="eps_r"),
                          es.accel_markov(accel_markov_tau, accel_markov_sigma, name="nabla")],
                         gyro_arw=gyro_arw, accel_vrw=0.0, accel_vrw_axes="xyz",
                         radius_derivatives=radius_derivatives)


def initial_covariance(model, lat, h, att, vel, pos, gyro_bias, gyro_markov, accel_markov):
    """Diagonal P0 of :func:`horizontal_model`.

    ``att`` (3,) [rad], ``vel`` (2,) or scalar [m/s], ``pos`` (2,) or scalar [m] (north,
    east), sensor σ per axis (SI).
    """
    from sinslab.core.earth import radii

    rm, rn = radii(lat, h)
    pos = np.broadcast_to(np.asarray(pos, float), (2,))
    d = np.concatenate([np.broadcast_to(att, (3,)), np.broadcast_to(vel, (2,)),
                        [pos[0] / float(rm), pos[1] / (float(rn) * math.cos(lat))],
                        np.broadcast_to(gyro_bias, (3,)), np.broadcast_to(gyro_markov, (3,)),
                        np.broadcast_to(accel_markov, (3,))]).astype(float)
    if d.size != model.n:
        raise ValueError(f"P0 has {d.size} states, the model {model.n}")
    return np.diag(d ** 2)


#: States fed back to the INS: φ (3), δv (2), δp (2), gyro constant drift (3).
FEEDBACK = np.arange(10)


@dataclass(frozen=True, eq=False)
class Integration:
    """Output of :func:`integrate`, at the filter epochs (every ``kf_dt``): a view of the
    composition's result (``run``, a :class:`sinslab.fusion.loosely_coupled.LooselyCoupled`)
    with the mode and lag policy it ran with.

    Attributes
    ----------
    t : (K+1,) s
    nav : (K+1, 10) navigation state ``[q0..q3, vE, vN, vU, lat, lon, h]`` after any
        feedback at that epoch
    x : (K+1, 16) the filter estimate after the epoch's updates and feedback (Markov states)
    sigma : (K+1, 16) filter σ
    gyro_comp : (K+1, 3) gyro compensation in use after the epoch [rad/s]
    applied : (J',) validity times of the fixes used; ``t_applied`` their processing times
    innovation : (J', 2) north/east [m]
    mode : str
    lag : lag policy of the lag-aware and zero-lag modes
    """

    run: object
    mode: str
    lag: object

    t = property(lambda self: self.run.t)
    nav = property(lambda self: self.run.nav)
    x = property(lambda self: self.run.x)
    sigma = property(lambda self: self.run.sigma)
    gyro_comp = property(lambda self: self.run.gyro_bias)
    applied = property(lambda self: self.run.fix_t)
    t_applied = property(lambda self: self.run.t_applied)
    innovation = property(lambda self: self.run.innovation)


@dataclass(frozen=True)
class StoredStateUpdate:
    """Paper 003's lagged update (eqs 4–10) as a lag policy of the fusion driver.

    A fix valid at ``t_m`` that arrives at ``t``: from the stored posterior at the last
    filter epoch ``t_j <= t_m`` predict to ``t_m`` with ``Φ = expm(F τ)`` and the
    integrated Q (τ = t_m − t_j, Van Loan), update there, then predict to the current time
    in one step with ``expm(F ΔT)`` and the integrated Q (ΔT = t − t_m; F, Qc of the
    validity epoch held constant, measurements in between ignored). The measurement is
    formed from the navigation output of the validity epoch *after* its feedback, as in the
    paper; the filter works in feed-forward coordinates ``x + c`` (c: cumulative feedback),
    and its history restarts from now because the stored steps no longer describe the path
    to the new estimate.
    """

    name = "paper003"
    on_arrival = False
    corrected_nav = True
    needs_model = True

    def update(self, filt, z, H, R, t_m, *, F, Qc, tol=1e-6, mask=None, sequential=None):
        """Apply the lagged fix to ``filt`` (a :class:`sinslab.estimation.filter.KalmanFilter`
        with history); ``F``, ``Qc`` (n, n): continuous model at ``t_m``. Returns the
        :class:`~sinslab.estimation.kalman.UpdateResult` of the update at ``t_m``."""
        from sinslab.estimation.filter import compiled_update
        from sinslab.estimation.kalman import update, van_loan
        from sinslab.estimation.kernels import cov_predict

        if F is None or Qc is None:
            raise ValueError("the stored-state update needs F and Qc (continuous model at t_m)")
        F = np.asarray(F, dtype=float)
        Qc = np.asarray(Qc, dtype=float)
        # the driver's own model: symmetrised as discretize would, without its validation
        Qc = 0.5 * (Qc + Qc.T)
        j = filt.find_epoch(t_m, tol, exact=False)
        e = filt.stored_epoch(j)
        x_post, P_post, c_post = filt.posterior_at(j)
        z = np.atleast_1d(np.asarray(z, dtype=float))
        Hm = np.atleast_2d(np.asarray(H, dtype=float))
        n = F.shape[0]
        T1, W = np.empty((n, n)), np.empty((n, n))
        xff = x_post + c_post
        tau = max(t_m - e.t, 0.0)
        # the predictions are those of KalmanFilter.predict: P by estimation's kernel
        # (exactly symmetric), x by Φ x
        P = np.array(P_post, dtype=float, order="C", copy=True)
        if tau > 0:
            Phi1, Q1 = van_loan(F, Qc, tau)
            xff = Phi1 @ xff
            cov_predict(P, np.ascontiguousarray(Phi1), np.ascontiguousarray(Q1), n, T1, W)
        else:
            P = 0.5 * (P + P.T)
        # the measurement was formed from the navigation state at t_m, which carried the
        # cumulative feedback of epoch j propagated to t_m
        c_m = (van_loan(F, np.zeros_like(F), tau)[0] @ c_post) if tau > 0 else c_post
        zc = z + Hm @ c_m
        res = (compiled_update(xff, P, zc, Hm, R) if mask is None and sequential is not False
               else None)
        if res is None:
            res = update(xff, P, zc, Hm, R, mask=mask, sequential=sequential)
        dT = filt.t - t_m
        P = np.array(res.P, dtype=float, order="C", copy=True)
        xff = res.x
        if dT > 0:
            Phi2, Q2 = van_loan(F, Qc, dT)
            xff = Phi2 @ xff
            cov_predict(P, np.ascontiguousarray(Phi2), np.ascontiguousarray(Q2), n, T1, W)
        filt.restart_history(xff - filt.c, 0.5 * (P + P.T))
        return res


def _epoch_of(t, t0, T, what):
    e = (np.asarray(t) - t0) / T
    r = np.round(e)
    if np.any(np.abs(e - r) > 1e-6):
        i = int(np.argmax(np.abs(e - r) > 1e-6))
        raise ValueError(f"{what} {float(np.asarray(t)[i]):.9g} s is not on the filter grid "
                         f"(t0 + k·{T:g} s)")
    return r.astype(np.int64)


def integrate(imu, init, fixes: Fixes, model: es.ErrorModel, P0, *, mode="lag-aware",
              lag=StoredStateUpdate(), height, windows=None, kf_dt=1.0, nsub=2, max_block=60.0,
              discretization="series") -> Integration:
    """SINS / two-GEO integration with feedback, fixes only inside windows.

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
        Measured increments (with errors).
    init : sinslab.core.records.NavState
        Initial navigation state (IMU attitude) at ``imu.t0``.
    fixes : sinslab.core.records.Fixes
        Horizontal fixes (``lat``, ``lon``, σ north/east in ``sigma[:, :2]``). Validity times
        ``t`` must be filter epochs (``imu.t0 + k·kf_dt``); arrivals are processed at the
        first epoch at or after ``t_arrive``.
    model : errstate.ErrorModel
        :func:`horizontal_model` (blocks phi, dv, dp, eps_b, eps_r, nabla).
    P0 : (16, 16)
    mode : {"lag-aware", "lag-ignore", "zero-lag"}
        The paper's three filters: the fixes applied at their validity epochs with ``lag``,
        on arrival as if current (:class:`sinslab.fusion.lag.OnArrival`), or by an ideal
        receiver whose fix of time t arrives at t.
    lag : lag policy
        The lagged update of the lag-aware mode (:mod:`sinslab.fusion.lag`):
        :class:`StoredStateUpdate` (paper 003) or
        :class:`sinslab.fusion.lag.ExactReprocessing`; :func:`lag_policy` makes one of
        their names.
    height : array_like (N+1,), float or sinslab.nav.strapdown.HeldHeight
        External height [m] at the IMU epochs (barometer / map); the vertical channel is
        held to it (the model has no vertical channel). A ``HeldHeight`` shared by the
        runs of a campaign computes its vertical rate per block once for all of them.
    windows : sequence of (start, end) [s], optional
        Fixes processed outside these windows are dropped (receiver silent); the
        covariance is propagated throughout, the INS runs free between updates.
    kf_dt : float
        Filter step [s], a multiple of ``nsub * imu.dt``.
    max_block : float
        Longest stretch [s] the INS runs in one compiled call.
    discretization : {"vanloan", "series"}
        Φ, Q_k of each step from F, G frozen at the epoch.

    Returns
    -------
    Integration
    """
    return integrate_many([(imu, init, fixes)], model, P0, mode=mode, lag=lag,
                          height=height, windows=windows, kf_dt=kf_dt, nsub=nsub, max_block=max_block,
                          discretization=discretization)[0]


def lag_policy(name):
    """The lag policy of a name: ``"paper003"`` (:class:`StoredStateUpdate`) or one of
    :data:`sinslab.fusion.lag.POLICIES`."""
    return _lag.lag_policy(name, extra=(StoredStateUpdate,))


def mode_policy(mode, lag):
    """The lag policy a mode of :data:`MODES` runs with: ``lag`` but for ``"lag-ignore"``
    (:class:`sinslab.fusion.lag.OnArrival`)."""
    return _lag.OnArrival() if mode == "lag-ignore" else lag


def check_integration(mode, model, what):
    """The arguments an integration shares: returns the model's layout, or ValueError
    naming the bad one."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    lay = model.layout
    if lay.n != 16 or lay.names[:3] != ("phi", "dv", "dp"):
        raise ValueError(f"{what} needs the 16-state horizontal model, got {lay!r}")
    return lay


def integrate_many(runs, model: es.ErrorModel, P0, *, mode="lag-aware", lag=StoredStateUpdate(),
                   height, windows=None, kf_dt=1.0, nsub=2, max_block=60.0,
                   discretization="series") -> list:
    """:func:`integrate` for the runs of a Monte Carlo campaign, in lockstep on the run axis
    of the fusion driver (:func:`sinslab.fusion.loosely_coupled.loosely_coupled_many`).

    Parameters
    ----------
    runs : sequence of (ImuRecord, NavState, Fixes)
        Each run's measured increments, initial state and fixes. The runs share the IMU
        grid and the fix schedule (the request plan of a constant latency,
        :func:`plan_fixes`); their errors and fix values are their own.
    model, P0, mode, lag, height, windows, kf_dt, nsub, max_block, discretization
        As in :func:`integrate`, shared by the runs.

    Returns
    -------
    list of Integration
        One per run, each equal to :func:`integrate` on that run alone.
    """
    from sinslab.fusion.feedback import FeedbackLayout
    from sinslab.fusion.loosely_coupled import loosely_coupled_many
    from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec

    lay = check_integration(mode, model, "integrate")
    w = None if windows is None else check_windows(windows)
    lanes = []
    for imu, init, fixes in runs:
        dt = imu.dt
        k_kf = int(round(kf_dt / dt))
        if k_kf < 1 or abs(k_kf * dt - kf_dt) > 1e-6 * kf_dt or k_kf % nsub:
            raise ValueError(f"kf_dt={kf_dt} s must be a multiple of nsub*dt = {nsub * dt} s")
        T = k_kf * dt
        K = len(imu) // k_kf
        if K < 1:
            raise ValueError("the IMU record is shorter than one filter step")
        t0 = imu.t0
        t_end = t0 + T * K
        J = len(fixes)
        if J and (fixes.t[0] < t0 - 1e-9 or fixes.t_arrive[-1] > t_end + 1e-9
                  or fixes.t[-1] > t_end + 1e-9):
            raise ValueError(f"fix times {fixes.t[0]:g}..{fixes.t_arrive.max():g} s lie outside "
                             f"the IMU record {t0:g}..{t_end:g} s")
        if J:
            _epoch_of(fixes.t, t0, T, "fix validity time")
        # 2-component (north, east) fixes against the horizontal model
        lanes.append((imu, init, FixSpec(fixes.t, np.stack([fixes.lat, fixes.lon], -1),
                                         np.stack([fixes.sigma[:, 0], fixes.sigma[:, 1]], -1),
                                         arrive=fixes.t if mode == "zero-lag" else fixes.t_arrive,
                                         windows=w)))
    # the one INS + fix driver: vertical channel held; φ, δv, δp and the gyro constant drift
    # fed back (FEEDBACK)
    rs = loosely_coupled_many(
        lanes, P0, model, ins=InsSpec(nsub=nsub, vertical="hold", height=height),
        grid=FilterGrid(kf_dt, max_block=max_block, model_every=0.0, discretization=discretization),
        lag=mode_policy(mode, lag), feedback=FeedbackLayout.from_model(lay, gyro="eps_b", accel=None),
        progress=False)
    return [Integration(r, mode, lag) for r in rs]


def horizontal_errors(nav, truth):
    """Horizontal errors of state rows against the truth at the same epochs, from the one
    error definition :func:`sinslab.nav.compare.nav_errors`.

    Parameters
    ----------
    nav : (..., M, 10) state rows ``[q, vel, lat, lon, h]`` (e.g. :attr:`Integration.nav`),
        or several runs' rows stacked in front
    truth : NavSeries with M epochs (IMU attitude in ``att_imu`` if present)

    Returns
    -------
    phi : (..., M, 3) misalignment [rad] (ENU)
    dvel : (..., M, 2) east, north [m/s]
    dpos : (..., M, 2) north, east [m]
    """
    from sinslab.nav import compare
    from sinslab.nav import strapdown as sd

    nav = np.asarray(nav, dtype=float)
    M = truth.t.size
    if nav.ndim < 2 or nav.shape[-2] != M:
        raise ValueError(f"nav rows {nav.shape} do not match the {M} truth epochs")
    lead = nav.shape[:-2]
    rows = nav.reshape(-1, nav.shape[-1])
    t = np.tile(truth.t, rows.shape[0] // M)            # the runs share the truth's epochs
    e = compare.row_errors(sd.rows_to_series(t, rows), truth, imu_frame=True)
    shape = lead + (M,)
    return (np.stack([e["phiE"], e["phiN"], e["phiU"]], -1).reshape(shape + (3,)),
            np.stack([e["vE"], e["vN"]], -1).reshape(shape + (2,)),
            np.stack([e["north"], e["east"]], -1).reshape(shape + (2,)))
