"""Raw GNSS observations of a simulated trajectory: pseudoranges and range rates per
satellite with a receiver clock, ionosphere/troposphere residuals, C/N0-dependent noise,
multipath-like outliers and masking (elevation mask, urban-canyon windows with at most k
satellites).

Satellites fly a Walker constellation (circular orbits, :class:`Walker`) or the orbits
of real broadcast ephemerides (:class:`sinslab.core.gnss.Ephemerides`, evaluated by
:func:`sinslab.core.gnss.kepler_states`). Each observation is formed at the true
transmission time (the light-time equation iterated), with the Sagnac term, so that the
model of :mod:`sinslab.fusion.gnss` is exact up to the errors drawn here:

``P = ρ + b + b_sys − c δt_s + I (1 + ε_I) + T (1 + ε_T) + e_orb + n + outlier``,
``ρ̇_obs = ρ̇ + d − c δṫ_s + ṅ``,

with ``I`` Klobuchar (default coefficients) and ``T`` Saastamoinen at the true receiver,
per-satellite relative residuals ``ε_I``, ``ε_T`` and orbit/clock errors ``e_orb`` held
over the run, the clock ``b, d`` the two-state clock model (white frequency and random-walk
frequency noise, drawn with the exact discrete covariance) and white noise of σ ``σ₀ √(10^{max(0, C/N0_ref − C/N0)/10}) / sin el``
(the filter's weighting); C/N0 ``= c0 + c1 sin el`` plus Gaussian noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import earth as E
from sinslab.core import gnss as G

__all__ = ["Walker", "GnssErrors", "simulate_observations", "SimulatedGnss"]


@dataclass(frozen=True)
class Walker:
    """A Walker delta constellation ``i: T/P/F`` on circular orbits.

    Attributes
    ----------
    planes, per_plane : int
        P orbital planes of S satellites each (T = P·S).
    phasing : int
        F: satellites of adjacent planes are offset by 2π F / T in argument of latitude.
    inclination : float
        [rad].
    radius : float
        Orbit radius [m] (26 560 km: GPS).
    system : str
        Letter of the satellites ("G").
    raan0, u0 : float
        Right ascension of the first plane and argument of latitude of its first
        satellite at t = 0 [rad].
    """

    planes: int = 6
    per_plane: int = 4
    phasing: int = 1
    inclination: float = math.radians(55.0)
    radius: float = 26_560e3
    system: str = "G"
    raan0: float = 0.0
    u0: float = 0.0

    @property
    def sats(self):
        return np.array([f"{self.system}{k + 1:02d}" for k in range(self.planes * self.per_plane)])

    def positions(self, t):
        """ECEF positions (S, 3) [m] of every satellite at time ``t`` [s] (a float, or one
        time per satellite (S,)); the Earth-fixed frame coincides with the inertial one at
        t = 0."""
        t = np.asarray(t, dtype=float)
        n = math.sqrt(E.GM / self.radius ** 3)
        T = self.planes * self.per_plane
        j = np.repeat(np.arange(self.planes), self.per_plane)
        k = np.tile(np.arange(self.per_plane), self.planes)
        raan = self.raan0 + 2 * math.pi * j / self.planes
        u = self.u0 + 2 * math.pi * k / self.per_plane + 2 * math.pi * self.phasing * j / T + n * t
        ci, si = math.cos(self.inclination), math.sin(self.inclination)
        x, y = self.radius * np.cos(u), self.radius * np.sin(u)
        xi = x * np.cos(raan) - y * ci * np.sin(raan)
        yi = x * np.sin(raan) + y * ci * np.cos(raan)
        zi = y * si
        a = E.WIE * t
        ca, sa = np.cos(a), np.sin(a)
        return np.stack([ca * xi + sa * yi, -sa * xi + ca * yi, zi + 0 * a], -1)


@dataclass(frozen=True)
class GnssErrors:
    """Error budget of :func:`simulate_observations` (SI).

    Attributes
    ----------
    pseudorange_sigma, doppler_sigma : float
        σ₀ of the white noise [m], [m/s] at zenith and C/N0 >= ``cn0_ref``.
    cn0_ref : float
    cn0 : (c0, c1, σ)
        C/N0 = c0 + c1 sin el + N(0, σ²) [dB-Hz].
    clock_bias, clock_drift : float
        Initial receiver clock [m], [m/s].
    clock_noise : (bias [m/√s], drift [m/s/√s])
    isb : dict
        Inter-system biases [m] by system letter (the first system: 0).
    iono_residual, tropo_residual : float
        σ of the per-satellite relative model errors ε_I, ε_T [-].
    orbit_clock : float
        σ of the per-satellite orbit + clock error along the line of sight [m].
    outlier_rate : float
        Probability of a multipath outlier per pseudorange.
    outlier_size : (lo, hi)
        Uniform outlier size [m] (added: a reflected path is longer).
    mask : float
        Elevation mask [rad].
    canyon : sequence of (k, start, duration)
        At most k satellites visible (highest first) in ``[start, start + duration)`` [s].
    """

    pseudorange_sigma: float = 1.0
    doppler_sigma: float = 0.05
    cn0_ref: float = 45.0
    cn0: tuple = (35.0, 15.0, 1.0)
    clock_bias: float = 3.0e4
    clock_drift: float = -50.0
    clock_noise: tuple = (0.5, 0.5)
    isb: dict = None
    iono_residual: float = 0.0
    tropo_residual: float = 0.0
    orbit_clock: float = 0.0
    outlier_rate: float = 0.0
    outlier_size: tuple = (20.0, 100.0)
    mask: float = math.radians(10.0)
    canyon: tuple = ()


@dataclass(frozen=True)
class SimulatedGnss:
    """Simulated observations and their truth.

    ``fields`` holds the arrays of :class:`sinslab.fusion.gnss.SatelliteObservations`
    (build it with ``SatelliteObservations(**sim.fields)``); ``clock`` (E, 2) the true
    receiver clock bias [m] and drift [m/s] at the epochs; ``outlier`` (M,) bool.
    """

    fields: dict
    clock: np.ndarray
    outlier: np.ndarray


def _sats(orbits):
    if isinstance(orbits, (list, tuple)):
        return np.concatenate([_sats(o) for o in orbits])
    return orbits.sats if isinstance(orbits, Walker) else np.unique(orbits.sat)


def _states(orbits, sats, t):
    """Positions and velocities (M, 3) of ``sats`` at times ``t`` (M,)."""
    if isinstance(orbits, (list, tuple)):      # several constellations, in order
        out, i = [], 0
        for o in orbits:
            n = _sats(o).size
            out.append(_states(o, sats[i:i + n], t[i:i + n]))
            i += n
        return np.concatenate([a for a, _ in out]), np.concatenate([b for _, b in out])
    if isinstance(orbits, Walker):         # every satellite, in the constellation's order
        h = 1e-3
        return orbits.positions(t), (orbits.positions(t + h) - orbits.positions(t - h)) / (2 * h)
    rows = np.array([int(np.flatnonzero(orbits.sat == s)[np.argmin(np.abs(orbits.toe[orbits.sat == s] - tt))])
                     for s, tt in zip(sats, t)], dtype=np.int64)
    p, v, _, _ = G.kepler_states(orbits, rows, t)
    return p, v


def simulate_observations(t, lat, lon, h, vel, orbits, errors: GnssErrors = GnssErrors(), *, seed=0,
                          t_orbit=0.0) -> SimulatedGnss:
    """Pseudoranges and range rates of the antenna track at the epochs ``t``.

    Parameters
    ----------
    t : array (E,)
        Reception epochs [s] (the trajectory's time axis).
    lat, lon, h : array (E,)
        True antenna position [rad, rad, m].
    vel : array (E, 3)
        True antenna velocity ENU [m/s].
    orbits : Walker, sinslab.core.gnss.Ephemerides, or a list of them
        Walker constellations (their time is ``t``) or real ephemerides (their time is
        ``t − t[0] + t_orbit``, GPS seconds relative to ``orbits.t_ref``); a list for
        several systems seen by one receiver (one clock).
    errors : GnssErrors
    seed : int or numpy.random.Generator
    t_orbit : float
        Orbit time of the first epoch for real ephemerides.

    Returns
    -------
    SimulatedGnss
    """
    rng = np.random.default_rng(seed)
    t = np.asarray(t, float)
    n_ep = t.size
    walker = all(isinstance(o, Walker) for o in (orbits if isinstance(orbits, (list, tuple)) else [orbits]))
    sats = _sats(orbits)
    systems = np.array([s[0] for s in sats])
    ns = sats.size
    r_rx = E.geodetic_to_ecef(lat, lon, h)
    v_rx = np.einsum("eij,ej->ei", E.enu_to_ecef_matrix(lat, lon), np.asarray(vel, float))
    # clock: bias integrates drift, both driven by white noise
    qb, qd = errors.clock_noise
    b = np.empty(n_ep)
    d = np.empty(n_ep)
    b[0], d[0] = errors.clock_bias, errors.clock_drift
    for k in range(1, n_ep):
        dt = t[k] - t[k - 1]
        # the exact discrete covariance of (ḃ = d + w_b, ḋ = w_d) over dt
        Q = np.array([[qb ** 2 * dt + qd ** 2 * dt ** 3 / 3, qd ** 2 * dt ** 2 / 2],
                      [qd ** 2 * dt ** 2 / 2, qd ** 2 * dt]])
        l11 = math.sqrt(Q[0, 0])
        l21 = Q[1, 0] / l11 if l11 > 0 else 0.0
        n1, n2 = rng.normal(size=2)
        wb, wd = l11 * n1, l21 * n1 + math.sqrt(max(Q[1, 1] - l21 * l21, 0.0)) * n2
        b[k] = b[k - 1] + d[k - 1] * dt + wb
        d[k] = d[k - 1] + wd
    isb = errors.isb or {}
    eps_i = rng.normal(0.0, errors.iono_residual, ns)
    eps_t = rng.normal(0.0, errors.tropo_residual, ns)
    e_orb = rng.normal(0.0, errors.orbit_clock, ns)
    sat_clk = rng.normal(0.0, 3e4, ns)            # broadcast satellite clocks [m], known
    sat_dft = rng.normal(0.0, 0.3, ns)
    t_orb = (t if walker else t - t[0] + t_orbit)
    out = {k: [] for k in ("epoch", "sat", "system", "pseudorange", "range_rate", "cn0", "sat_pos",
                           "sat_vel", "sat_clock", "sat_drift")}
    outl = []
    for e in range(n_ep):
        # light time: two passes from the position at reception
        p, _ = _states(orbits, sats, np.full(ns, t_orb[e]))
        tau = np.linalg.norm(p - r_rx[e], axis=1) / G.C_LIGHT
        for _ in range(2):
            p, v = _states(orbits, sats, t_orb[e] - tau)
            rho, u = G.sagnac_range(p, r_rx[e])
            tau = rho / G.C_LIGHT
        el, az = E.elevation_azimuth(p, lat[e], lon[e], h[e])
        vis = el >= errors.mask
        for k, s0, dur in errors.canyon:
            if s0 <= t[e] < s0 + dur and vis.sum() > k:
                idx = np.flatnonzero(vis)
                vis[idx[np.argsort(-el[idx], kind="stable")[k:]]] = False
        i = np.flatnonzero(vis)
        if not i.size:
            continue
        c0, c1, cs = errors.cn0
        cn0 = c0 + c1 * np.sin(el[i]) + rng.normal(0.0, cs, i.size)
        scale = np.sqrt(10.0 ** (np.maximum(errors.cn0_ref - cn0, 0.0) / 10.0)) / np.maximum(np.sin(el[i]), 0.05)
        iono = G.klobuchar(t[e], lat[e], lon[e], az[i], el[i]) * (1 + eps_i[i])
        trop = G.saastamoinen(lat[e], h[e], el[i]) * (1 + eps_t[i])
        bias = np.array([isb.get(sy, 0.0) for sy in systems[i]])
        P = (rho[i] + b[e] + bias - sat_clk[i] + iono + trop + e_orb[i]
             + rng.normal(0.0, errors.pseudorange_sigma, i.size) * scale)
        is_out = rng.random(i.size) < errors.outlier_rate
        P = P + is_out * rng.uniform(*errors.outlier_size, i.size)
        w = E.WIE / G.C_LIGHT
        rs, vs, rr, vr = p[i], v[i], r_rx[e], v_rx[e]
        rate = (np.sum((vs - vr) * u[i], 1)
                + w * (vs[:, 1] * rr[0] + rs[:, 1] * vr[0] - vs[:, 0] * rr[1] - rs[:, 0] * vr[1]))
        rr_obs = rate + d[e] - sat_dft[i] + rng.normal(0.0, errors.doppler_sigma, i.size) * scale
        out["epoch"].append(np.full(i.size, e))
        out["sat"].append(sats[i])
        out["system"].append(systems[i])
        out["pseudorange"].append(P)
        out["range_rate"].append(rr_obs)
        out["cn0"].append(cn0)
        out["sat_pos"].append(rs)
        out["sat_vel"].append(vs)
        out["sat_clock"].append(sat_clk[i])
        out["sat_drift"].append(sat_dft[i])
        outl.append(is_out)
    cat = {k: np.concatenate(v) for k, v in out.items()}
    M = cat["sat"].size
    fields = dict(t_ref=0, t_epoch=t.copy(), epoch=cat["epoch"].astype(np.int64), sat=cat["sat"],
                  system=cat["system"], pseudorange=cat["pseudorange"], range_rate=cat["range_rate"],
                  freq=np.full(M, 1575.42e6), cn0=cat["cn0"], sat_pos=cat["sat_pos"], sat_vel=cat["sat_vel"],
                  sat_clock=cat["sat_clock"], sat_drift=cat["sat_drift"], iono=np.zeros(8),
                  usable=np.ones(M, bool))
    return SimulatedGnss(fields, np.stack([b, d], -1), np.concatenate(outl))
