"""Raw GNSS observations of a simulated trajectory: pseudoranges and range rates per
satellite with a receiver clock, ionosphere/troposphere residuals, C/N0-dependent noise,
multipath-like outliers and masking (elevation mask, urban-canyon windows with at most k
satellites); with :class:`PhaseErrors`, every signal of several carriers (pseudorange,
carrier phase with integer ambiguities, cycle slips and loss of lock, Doppler), and with
a :class:`BaseStation`, the same satellites seen from a static reference receiver.

Satellites fly a Walker constellation (circular orbits, :class:`Walker`) or the orbits
of real broadcast ephemerides (:class:`sinslab.core.gnss.Ephemerides`, evaluated by
:func:`sinslab.core.gnss.kepler_states`). Each observation is formed at the true
transmission time (the light-time equation iterated), with the Sagnac term, so that the
model of :mod:`sinslab.fusion.gnss` is exact up to the errors drawn here:

``P = ρ + b + b_sys − c δt_s + I (1 + ε_I) + T (1 + ε_T) + e_orb + n + outlier``,
``ρ̇_obs = ρ̇ + d − c δṫ_s + ṅ``,

and for each carrier ``f`` of :class:`PhaseErrors` (``λ = c/f``, ``γ = (f_L1/f)²``)

``λ φ = ρ + b + b_sys − c δt_s − γ I (1 + ε_I) + T (1 + ε_T) + e_orb + λ (N + β_r + β_s) + m_φ + n_φ``

with ``N`` an integer drawn when the signal is acquired (again after a loss of lock or a
cycle slip), fractional phase biases ``β_r`` of the receiver (per carrier) and ``β_s`` of
the satellite (per carrier, shared by every receiver) that cancel in double differences,
multipath ``m`` a first-order Gauss–Markov process per satellite and signal scaled by
``1/sin el``, and white noise ``n`` by C/N0 and elevation as for the pseudorange;
with ``I`` Klobuchar (default coefficients) and ``T`` Saastamoinen at the true receiver,
per-satellite relative residuals ``ε_I``, ``ε_T`` and orbit/clock errors ``e_orb`` held
over the run, the clock ``b, d`` the two-state clock model (white frequency and random-walk
frequency noise, drawn with the exact discrete covariance) and white noise of σ ``σ₀ √(10^{max(0, C/N0_ref − C/N0)/10}) / sin el``
(the filter's weighting); C/N0 ``= c0 + c1 sin el`` plus Gaussian noise.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import earth as E
from sinslab.core import gnss as G

__all__ = ["Walker", "GnssErrors", "PhaseErrors", "BaseStation", "simulate_observations", "SimulatedGnss",
           "CARRIERS"]

#: Carriers by system letter: (RINEX code, frequency [Hz], RTKLIB frequency slot).
CARRIERS = {"G": (("1C", 1575.42e6, 0), ("2W", 1227.60e6, 1), ("5Q", 1176.45e6, 2)),
            "J": (("1C", 1575.42e6, 0), ("2L", 1227.60e6, 1), ("5Q", 1176.45e6, 2)),
            "E": (("1C", 1575.42e6, 0), ("7Q", 1207.14e6, 1), ("5Q", 1176.45e6, 2)),
            "C": (("2I", 1561.098e6, 0), ("7I", 1207.14e6, 1), ("6I", 1268.52e6, 2))}


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
        n, u_at_0, cr, sr, ci, si = _walker_terms(self)
        u = u_at_0 + n * t
        x, y = self.radius * np.cos(u), self.radius * np.sin(u)
        xi = x * cr - y * ci * sr
        yi = x * sr + y * ci * cr
        zi = y * si
        a = E.WIE * t
        ca, sa = np.cos(a), np.sin(a)
        return np.stack([ca * xi + sa * yi, -sa * xi + ca * yi, zi + 0 * a], -1)


@functools.lru_cache(maxsize=16)
def _walker_terms(w: Walker):
    """The parts of :meth:`Walker.positions` that do not depend on time, in the order of
    its sums (the same bits): mean motion n [rad/s], argument of latitude at t = 0 and
    cos, sin of the right ascension per satellite (S,), cos, sin of the inclination. A
    simulation asks for the positions three times per epoch."""
    n = math.sqrt(E.GM / w.radius ** 3)
    T = w.planes * w.per_plane
    j = np.repeat(np.arange(w.planes), w.per_plane)
    k = np.tile(np.arange(w.per_plane), w.planes)
    raan = w.raan0 + 2 * math.pi * j / w.planes
    u_at_0 = w.u0 + 2 * math.pi * k / w.per_plane + 2 * math.pi * w.phasing * j / T
    cr, sr = np.cos(raan), np.sin(raan)
    for a in (u_at_0, cr, sr):             # shared by every call: read only
        a.flags.writeable = False
    return n, u_at_0, cr, sr, math.cos(w.inclination), math.sin(w.inclination)


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
class PhaseErrors:
    """The signals of :func:`simulate_observations` beyond the one pseudorange (SI).

    Attributes
    ----------
    carriers : int
        Carriers per satellite, the first ``carriers`` of :data:`CARRIERS` for its system
        (1: L1/E1 only; 2: L1 + L2 / E1 + E5b; 3 adds L5 / E5a).
    phase_sigma : float
        σ₀ of the carrier-phase white noise [m] at zenith and C/N0 >= ``cn0_ref`` of
        :class:`GnssErrors` (scaled like the pseudorange's).
    multipath : (code σ [m], phase σ [m], τ [s])
        Gauss–Markov multipath of every signal at zenith (divided by sin el), correlation
        time τ.
    slip_rate : float
        Cycle slips per signal per second.
    slip_cycles : int
        Largest slip magnitude [cycles] (uniform over ±1..±slip_cycles).
    slip_flagged : float
        Share of the slips the receiver flags (loss-of-lock bit); a loss of lock (the
        satellite hidden, then seen again) is always flagged.
    half_cycle : float
        Share of the slips that are half a cycle (flagged as unresolved half cycle until
        the next slip).
    """

    carriers: int = 2
    phase_sigma: float = 0.003
    multipath: tuple = (0.0, 0.0, 30.0)
    slip_rate: float = 0.0
    slip_cycles: int = 5
    slip_flagged: float = 1.0
    half_cycle: float = 0.0


@dataclass(frozen=True)
class BaseStation:
    """A static reference receiver seeing the same satellites (for RTK).

    Attributes
    ----------
    position : array_like (3,)
        ECEF [m] (known: the truth and what a user gives as the base position).
    clock_bias, clock_drift : float
        Initial receiver clock [m], [m/s].
    clock_noise : (bias [m/√s], drift [m/s/√s])
    iono_gradient : float
        σ of the difference of the zenith L1 ionospheric delay between rover and base per
        km of baseline [m/km], held per satellite over the run (the residual double
        differences keep).
    cn0 : tuple or None
        ``(c0, c1, σ)`` of the base (default the rover's).
    """

    position: tuple
    clock_bias: float = -1.2e4
    clock_drift: float = 20.0
    clock_noise: tuple = (0.05, 0.01)
    iono_gradient: float = 0.0
    cn0: tuple = None


@dataclass(frozen=True)
class SimulatedGnss:
    """Simulated observations and their truth.

    ``fields`` holds the arrays of :class:`sinslab.fusion.gnss.SatelliteObservations`
    (build it with ``SatelliteObservations(**sim.fields)``; with :class:`PhaseErrors`
    its ``signals``, a :class:`sinslab.core.gnss.Signals`); ``clock`` (E, 2) the true
    receiver clock bias [m] and drift [m/s] at the epochs; ``outlier`` (M,) bool;
    ``ambiguity`` (M, F) the integer part of each phase [cycles] and ``slip`` (M, F) the
    signals whose ambiguity changed since the previous epoch (a slip or a new lock,
    flagged or not); ``position`` (E, 3) the receiver's true ECEF position [m]; ``base``
    the base station's :class:`SimulatedGnss` (with a :class:`BaseStation`).
    """

    fields: dict
    clock: np.ndarray
    outlier: np.ndarray
    ambiguity: np.ndarray = None
    slip: np.ndarray = None
    position: np.ndarray = None
    base: "SimulatedGnss" = None


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


def _clock_series(t, b0, d0, noise, rng):
    """Receiver clock bias [m] and drift [m/s] at ``t``: the bias integrates the drift, both
    driven by white noise, drawn with the exact discrete covariance of (ḃ = d + w_b, ḋ = w_d)."""
    qb, qd = noise
    n_ep = t.size
    b = np.empty(n_ep)
    d = np.empty(n_ep)
    b[0], d[0] = b0, d0
    for k in range(1, n_ep):
        dt = t[k] - t[k - 1]
        Q = np.array([[qb ** 2 * dt + qd ** 2 * dt ** 3 / 3, qd ** 2 * dt ** 2 / 2],
                      [qd ** 2 * dt ** 2 / 2, qd ** 2 * dt]])
        l11 = math.sqrt(Q[0, 0])
        l21 = Q[1, 0] / l11 if l11 > 0 else 0.0
        n1, n2 = rng.normal(size=2)
        wb, wd = l11 * n1, l21 * n1 + math.sqrt(max(Q[1, 1] - l21 * l21, 0.0)) * n2
        b[k] = b[k - 1] + d[k - 1] * dt + wb
        d[k] = d[k - 1] + wd
    return b, d


def _geometry(orbits, sats, t_orb, r_rx, lat, lon, h):
    """Satellite states at the true transmission time (light time iterated from the
    position at reception), the range with the Sagnac term, line of sight, elevation and
    azimuth from the receiver at ``r_rx``."""
    ns = sats.size
    p, _ = _states(orbits, sats, np.full(ns, t_orb))
    tau = np.linalg.norm(p - r_rx, axis=1) / G.C_LIGHT
    for _ in range(2):
        p, v = _states(orbits, sats, t_orb - tau)
        rho, u = G.sagnac_range(p, r_rx)
        tau = rho / G.C_LIGHT
    el, az = E.elevation_azimuth(p, lat, lon, h)
    return p, v, rho, u, el, az


def _visible(el, t, errors):
    vis = el >= errors.mask
    for k, s0, dur in errors.canyon:
        if s0 <= t < s0 + dur and vis.sum() > k:
            idx = np.flatnonzero(vis)
            vis[idx[np.argsort(-el[idx], kind="stable")[k:]]] = False
    return vis


def _range_rate(p, v, u, r, vr):
    w = E.WIE / G.C_LIGHT
    return (np.sum((v - vr) * u, 1)
            + w * (v[:, 1] * r[0] + p[:, 1] * vr[0] - v[:, 0] * r[1] - p[:, 0] * vr[1]))


class _Tracking:
    """Carrier tracking of one receiver: integer ambiguity, multipath states, slips and
    flags of each (satellite, carrier), advanced epoch by epoch (its own random stream)."""

    def __init__(self, ns, nf, spec: PhaseErrors, rng):
        self.spec, self.rng = spec, rng
        self.N = np.zeros((ns, nf), np.int64)
        self.half = np.zeros((ns, nf), bool)
        self.seen = np.zeros(ns, bool)
        self.last = np.full(ns, -1)
        self.mp = rng.normal(size=(ns, nf, 2))
        self.beta = rng.random(nf)                     # the receiver's fractional phase bias

    def step(self, e, i, dt):
        """Rows ``i`` (visible satellites) at epoch ``e``: (N, half-cycle flag, changed, LLI)."""
        sp, rng = self.spec, self.rng
        nf = self.N.shape[1]
        new = self.last[i] != e - 1
        fresh = rng.integers(-10 ** 6, 10 ** 6, (i.size, nf))
        self.N[i[new]] = fresh[new]
        self.half[i[new]] = False
        slip = rng.random((i.size, nf)) < sp.slip_rate * dt
        slip &= ~new[:, None]
        size = rng.integers(1, sp.slip_cycles + 1, (i.size, nf)) * rng.choice([-1, 1], (i.size, nf))
        flagged = rng.random((i.size, nf)) < sp.slip_flagged
        half = slip & (rng.random((i.size, nf)) < sp.half_cycle)
        Ni = self.N[i] + np.where(slip & ~half, size, 0)
        hi = np.where(slip, half, self.half[i])
        self.N[i], self.half[i] = Ni, hi
        lli = ((new & self.seen[i])[:, None] | (slip & flagged)).astype(np.uint8) | (hi.astype(np.uint8) << 1)
        self.seen[i] = True
        self.last[i] = e
        a = math.exp(-dt / sp.multipath[2]) if sp.multipath[2] > 0 else 0.0
        self.mp[i] = a * self.mp[i] + math.sqrt(1 - a * a) * rng.normal(size=(i.size, nf, 2))
        return Ni, hi, new[:, None] | slip, lli


def _signals(sats, i, e, ctx, track, geo, P1, rr1, cn0, scale, iono, trop, clk_rx, rng):
    """Every carrier of the visible satellites ``i`` of one epoch: (code, P, φ, D, C/N0,
    f, LLI) arrays (n, F), the integer ambiguities and the changed flags. The first carrier
    keeps the pseudorange ``P1`` and range rate ``rr1`` drawn for the primary record."""
    spec, err = ctx["phase"], ctx["errors"]
    nf = spec.carriers
    n = i.size
    code = np.full((n, 3), "", dtype="<U3")
    f = np.full((n, 3), np.nan)
    for j, s in enumerate(sats[i]):
        for c, fr, slot in CARRIERS[s[0]][:nf]:
            code[j, slot], f[j, slot] = c, fr
    N, half, changed, lli = track.step(e, i, ctx["dt"][e])
    out = [np.full((n, 3), np.nan) for _ in range(3)]
    lli3 = np.zeros((n, 3), np.uint8)
    amb = np.zeros((n, 3), np.int64)
    chg = np.zeros((n, 3), bool)
    rho, rate, sat_clk, e_orb = geo
    mp_c, mp_p, _ = spec.multipath
    sin_el = ctx["sin_el"]
    for q in range(nf):
        sl = q                                  # the q-th carrier of every system is in slot q
        fq = f[:, sl]
        lam = G.C_LIGHT / fq
        gam = (1575.42e6 / fq) ** 2
        geom = rho + clk_rx[0] + ctx["bias"] - sat_clk + trop + e_orb
        mpc = mp_c * track.mp[i, q, 0] / sin_el
        mpp = mp_p * track.mp[i, q, 1] / sin_el
        if q == 0:                              # the primary record's draws, at this carrier
            P = P1 + (gam - 1.0) * iono + mpc
            rr = rr1
        else:
            P = geom + gam * iono + mpc + rng.normal(0.0, err.pseudorange_sigma, n) * scale
            rr = rate + clk_rx[1] - ctx["sat_drift"] + rng.normal(0.0, err.doppler_sigma, n) * scale
        phase = ((geom - gam * iono + mpp + rng.normal(0.0, spec.phase_sigma, n) * scale) / lam
                 + N[:, q] + 0.5 * half[:, q] + track.beta[q] + ctx["beta_s"][i, q])
        out[0][:, sl], out[1][:, sl], out[2][:, sl] = P, phase, -rr / lam
        lli3[:, sl], amb[:, sl], chg[:, sl] = lli[:, q], N[:, q], changed[:, q]
    cn0_3 = np.where(np.isfinite(f), cn0[:, None], np.nan)
    return (code, out[0], out[1], out[2], cn0_3, f, lli3), amb, chg


def simulate_observations(t, lat, lon, h, vel, orbits, errors: GnssErrors = GnssErrors(), *, seed=0,
                          t_orbit=0.0, phase: PhaseErrors | None = None,
                          base: BaseStation | None = None) -> SimulatedGnss:
    """Pseudoranges and range rates of the antenna track at the epochs ``t`` (with
    ``phase``, every signal of its carriers; with ``base``, the base station's too).

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
    phase : PhaseErrors, optional
        Carriers, phase noise, multipath and slips (``fields["signals"]``, ``ambiguity``,
        ``slip``). The draws of the primary pseudorange and range rate are those of a run
        without it (phase and base draw from streams of their own).
    base : BaseStation, optional
        A static reference receiver (needs ``phase``): ``SimulatedGnss.base``.

    Returns
    -------
    SimulatedGnss
    """
    rng = np.random.default_rng(seed)
    t = np.asarray(t, float)
    lat, lon, h = (np.asarray(v, float) for v in (lat, lon, h))
    if base is not None and phase is None:
        raise ValueError("a base station needs the carrier phase: give phase=PhaseErrors(...)")
    rng_phase, rng_base = rng.spawn(2)
    walker = all(isinstance(o, Walker) for o in (orbits if isinstance(orbits, (list, tuple)) else [orbits]))
    sats = _sats(orbits)
    ns = sats.size
    b, d = _clock_series(t, errors.clock_bias, errors.clock_drift, errors.clock_noise, rng)
    sat_err = dict(eps_i=rng.normal(0.0, errors.iono_residual, ns), eps_t=rng.normal(0.0, errors.tropo_residual, ns),
                   e_orb=rng.normal(0.0, errors.orbit_clock, ns), sat_clk=rng.normal(0.0, 3e4, ns),
                   sat_dft=rng.normal(0.0, 0.3, ns))
    t_orb = (t if walker else t - t[0] + t_orbit)
    rx = dict(lat=lat, lon=lon, h=h, r=E.geodetic_to_ecef(lat, lon, h),
              v=np.einsum("eij,ej->ei", E.enu_to_ecef_matrix(lat, lon), np.asarray(vel, float)),
              clock=(b, d), errors=errors)
    common = dict(sats=sats, orbits=orbits, t=t, t_orb=t_orb, sat_err=sat_err, phase=phase,
                  beta_s=rng_phase.random((ns, 3)) if phase is not None else None,
                  dI=np.zeros(ns))
    rover = _receiver(rx, common, rng, rng_phase)
    if base is None:
        return rover
    r_b = np.asarray(base.position, float).reshape(3)
    lb, ob, hb = (float(x) for x in E.ecef_to_geodetic(r_b))
    n_ep = t.size
    bb, bd = _clock_series(t, base.clock_bias, base.clock_drift, base.clock_noise, rng_base)
    base_err = GnssErrors(**{**errors.__dict__, "cn0": base.cn0 or errors.cn0, "outlier_rate": 0.0,
                             "canyon": ()})
    km = float(np.linalg.norm(r_b - rx["r"][0])) / 1e3
    common_b = {**common, "dI": rng_base.normal(0.0, base.iono_gradient * km, ns)}
    brx = dict(lat=np.full(n_ep, lb), lon=np.full(n_ep, ob), h=np.full(n_ep, hb), r=np.tile(r_b, (n_ep, 1)),
               v=np.zeros((n_ep, 3)), clock=(bb, bd), errors=base_err)
    b_sim = _receiver(brx, common_b, rng_base, rng_base.spawn(1)[0])
    return SimulatedGnss(rover.fields, rover.clock, rover.outlier, rover.ambiguity, rover.slip, rover.position,
                         b_sim)


def _receiver(rx, common, rng, rng_phase) -> SimulatedGnss:
    """The observations of one receiver (its track, clock and error budget in ``rx``;
    the satellites and their errors in ``common``); ``rng`` draws the primary records
    in the order of the single-receiver simulator, ``rng_phase`` the other signals."""
    sats, t, errors, spec = common["sats"], common["t"], rx["errors"], common["phase"]
    systems = np.array([s[0] for s in sats])
    se = common["sat_err"]
    b, d = rx["clock"]
    isb = errors.isb or {}
    track = _Tracking(sats.size, spec.carriers, spec, rng_phase) if spec is not None else None
    dt = np.r_[1.0, np.diff(t)]
    keys = ("epoch", "sat", "system", "pseudorange", "range_rate", "cn0", "sat_pos", "sat_vel",
            "sat_clock", "sat_drift", "outlier")
    out = {k: [] for k in keys}
    sig = [[] for _ in range(9)]
    for e in range(t.size):
        p, v, rho, u, el, az = _geometry(common["orbits"], sats, common["t_orb"][e], rx["r"][e], rx["lat"][e],
                                         rx["lon"][e], rx["h"][e])
        i = np.flatnonzero(_visible(el, t[e], errors))
        if not i.size:
            continue
        lat, lon, h = rx["lat"][e], rx["lon"][e], rx["h"][e]
        c0, c1, cs = errors.cn0
        cn0 = c0 + c1 * np.sin(el[i]) + rng.normal(0.0, cs, i.size)
        scale = np.sqrt(10.0 ** (np.maximum(errors.cn0_ref - cn0, 0.0) / 10.0)) / np.maximum(np.sin(el[i]), 0.05)
        iono = G.klobuchar(t[e], lat, lon, az[i], el[i]) * (1 + se["eps_i"][i])
        iono = iono + common["dI"][i] * (1.0 + 16.0 * (0.53 - el[i] / math.pi) ** 3)
        trop = G.saastamoinen(lat, h, el[i]) * (1 + se["eps_t"][i])
        bias = np.array([isb.get(sy, 0.0) for sy in systems[i]])
        sclk = se["sat_clk"][i] + se["sat_dft"][i] * t[e]       # the satellite clock runs at its drift
        P = (rho[i] + b[e] + bias - sclk + iono + trop + se["e_orb"][i]
             + rng.normal(0.0, errors.pseudorange_sigma, i.size) * scale)
        is_out = rng.random(i.size) < errors.outlier_rate
        P = P + is_out * rng.uniform(*errors.outlier_size, i.size)
        rate = _range_rate(p[i], v[i], u[i], rx["r"][e], rx["v"][e])
        rr_obs = rate + d[e] - se["sat_dft"][i] + rng.normal(0.0, errors.doppler_sigma, i.size) * scale
        for k, val in zip(keys, (np.full(i.size, e), sats[i], systems[i], P, rr_obs, cn0, p[i], v[i],
                                 sclk, se["sat_dft"][i], is_out)):
            out[k].append(val)
        if track is not None:
            ctx = dict(phase=spec, errors=errors, dt=dt, bias=bias, sat_drift=se["sat_dft"][i],
                       sin_el=np.maximum(np.sin(el[i]), 0.05), beta_s=common["beta_s"])
            cols, amb, chg = _signals(sats, i, e, ctx, track, (rho[i], rate, sclk, se["e_orb"][i]),
                                      P, rr_obs, cn0, scale, iono, trop, (b[e], d[e]), rng_phase)
            out["pseudorange"][-1] = cols[1][:, 0]          # with multipath, at the first carrier
            for lst, val in zip(sig, (*cols, amb, chg)):
                lst.append(val)
    return _assemble(out, sig, t, b, d, rx["r"], track is not None)


def _assemble(out, sig, t, b, d, r, with_phase):
    cat = {k: np.concatenate(v) for k, v in out.items()}
    M = cat["sat"].size
    fields = dict(t_ref=0, t_epoch=t.copy(), epoch=cat["epoch"].astype(np.int64), sat=cat["sat"],
                  system=cat["system"], pseudorange=cat["pseudorange"], range_rate=cat["range_rate"],
                  freq=np.full(M, 1575.42e6), cn0=cat["cn0"], sat_pos=cat["sat_pos"], sat_vel=cat["sat_vel"],
                  sat_clock=cat["sat_clock"], sat_drift=cat["sat_drift"], iono=np.zeros(8),
                  usable=np.ones(M, bool))
    if not with_phase:
        return SimulatedGnss(fields, np.stack([b, d], -1), cat["outlier"], position=r)
    cols = [np.concatenate(x) for x in sig]
    fields["signals"] = G.Signals(*cols[:7])
    fields["freq"] = cols[5][:, 0]
    return SimulatedGnss(fields, np.stack([b, d], -1), cat["outlier"], cols[7], cols[8], r)
