"""Carrier phase and a base station in the GNSS simulator (sinslab.sim.gnss): the
primary records do not move when phase is asked for; double differences of phase minus
code recover the known integer ambiguities exactly without noise; the phase noise has
the σ of its C/N0 and elevation model; multipath is a Gauss–Markov process of the given
correlation time; slips and losses of lock change the integers where the simulator says,
flagged as asked."""
import math

import numpy as np
import pytest

from sinslab.core import earth as E
from sinslab.core import gnss as G
from sinslab.sim import gnss as SG

T = np.arange(0.0, 120.0)
LAT, LON, H = math.radians(35.3), math.radians(139.5), 60.0
WALKERS = [SG.Walker(), SG.Walker(planes=3, per_plane=8, system="E", raan0=0.4, radius=29_600e3)]


def _sim(err=SG.GnssErrors(), phase=SG.PhaseErrors(), base_offset=(3000.0, -2000.0, 500.0), seed=5, t=T,
         **kw):
    n = t.size
    r0 = E.geodetic_to_ecef(LAT, LON, H)
    base = None if base_offset is None else SG.BaseStation(position=tuple(r0 + np.asarray(base_offset)), **kw)
    return SG.simulate_observations(t, np.full(n, LAT), np.full(n, LON), np.full(n, H), np.zeros((n, 3)),
                                    WALKERS, err, seed=seed, phase=phase, base=base)


def _code_minus_phase(sim, lat, lon, h):
    """(λφ − P + 2γ I)/λ [cycles] per row and carrier (I the Klobuchar delay at L1 the
    simulator adds): integer + fractional biases + noise."""
    f = sim.fields
    S = f["signals"]
    el, az = E.elevation_azimuth(f["sat_pos"], lat, lon, h)
    iono = G.klobuchar(f["t_epoch"][f["epoch"]], lat, lon, az, el)
    lam = G.C_LIGHT / S.freq
    gam = (1575.42e6 / S.freq) ** 2
    return (lam * S.phase - S.pseudorange + 2 * gam * iono[:, None]) / lam


def _dd(sim, x):
    """Double differences rover − base, satellite − the first common satellite of each
    epoch, of per-row values ``x`` (M, F) of the rover and the base: dict (epoch, sat) -> (F,)."""
    xr, xb = x
    fr, fb = sim.fields, sim.base.fields
    out = {}
    for e in range(T.size):
        ir = np.flatnonzero(fr["epoch"] == e)
        ib = np.flatnonzero(fb["epoch"] == e)
        common = sorted(set(fr["sat"][ir]) & set(fb["sat"][ib]))
        sr = {s: xr[i] for s, i in zip(fr["sat"][ir], ir)}
        sb = {s: xb[i] for s, i in zip(fb["sat"][ib], ib)}
        ref = common[0]
        for s in common[1:]:
            out[e, s] = (sr[s] - sb[s]) - (sr[ref] - sb[ref])
    return out


def test_primary_records_unchanged_by_phase():
    """The pseudorange, range rate and C/N0 of every row are those of a run without phase
    (phase and base draw from streams of their own): old scenarios keep their numbers."""
    err = SG.GnssErrors(outlier_rate=0.02)
    a = _sim(err, phase=None, base_offset=None)
    b = _sim(err)
    for k in ("pseudorange", "range_rate", "cn0", "sat"):
        assert np.array_equal(a.fields[k], b.fields[k]), k
    assert np.array_equal(a.clock, b.clock)
    assert np.array_equal(b.fields["signals"].pseudorange[:, 0], b.fields["pseudorange"])


def test_double_differences_are_the_known_integers():
    """Without noise, the double difference of (λφ − P + 2γI)/λ equals the double difference
    of the simulator's integers to 1e-6 cycles on both carriers (the receiver and satellite
    fractional biases cancel; single differences do not), base 3.6 km away and 500 m higher."""
    err = SG.GnssErrors(pseudorange_sigma=0.0, doppler_sigma=0.0, cn0=(35.0, 15.0, 0.0))
    sim = _sim(err, SG.PhaseErrors(phase_sigma=0.0))
    lb, ob, hb = E.ecef_to_geodetic(np.asarray(sim.base.position[0]))
    x = _code_minus_phase(sim, LAT, LON, H), _code_minus_phase(sim.base, float(lb), float(ob), float(hb))
    dd = _dd(sim, x)
    ddn = _dd(sim, (sim.ambiguity.astype(float), sim.base.ambiguity.astype(float)))
    assert len(dd) > 1000
    err_c = np.array([dd[k][:2] - ddn[k][:2] for k in dd])
    assert np.max(np.abs(err_c)) < 1e-6
    sd = x[0][:, 0] - sim.ambiguity[:, 0]            # undifferenced: a fractional bias remains
    assert np.ptp(np.mod(sd, 1.0)) > 0.1


def test_phase_noise_follows_cn0_and_elevation():
    """Phase noise alone (code exact): the epoch-to-epoch change of λφ − ρ-terms over its
    model σ √2 σ₀ √(10^{(45 − C/N0)/10}) / sin el has a standard deviation of 1 (±5 %)."""
    err = SG.GnssErrors(pseudorange_sigma=0.0, doppler_sigma=0.0)
    sig = 0.004
    sim = _sim(err, SG.PhaseErrors(phase_sigma=sig), base_offset=None)
    x = _code_minus_phase(sim, LAT, LON, H)
    f = sim.fields
    lam = G.C_LIGHT / f["signals"].freq
    el, _ = E.elevation_azimuth(f["sat_pos"], LAT, LON, H)
    s = sig * np.sqrt(10 ** (np.maximum(45.0 - f["cn0"], 0) / 10)) / np.maximum(np.sin(el), 0.05)
    z = []
    for sat in np.unique(f["sat"]):
        m = np.flatnonzero(f["sat"] == sat)
        ok = np.diff(f["epoch"][m]) == 1
        d = np.diff((x[m, :2] - sim.ambiguity[m, :2]) * lam[m, :2], axis=0)[ok]
        z.append(d / np.sqrt(s[m][1:][ok] ** 2 + s[m][:-1][ok] ** 2)[:, None])
    z = np.concatenate(z).ravel()
    assert z.size > 2500 and abs(np.std(z) - 1.0) < 0.05


def test_multipath_is_gauss_markov():
    """Phase multipath only (τ = 20 s): its lag-1 s autocorrelation is exp(−1/20) ± 0.03 and
    its σ at zenith-scaled units 1 ± 10 %."""
    err = SG.GnssErrors(pseudorange_sigma=0.0, doppler_sigma=0.0)
    t = np.arange(0.0, 600.0)
    sim = _sim(err, SG.PhaseErrors(phase_sigma=0.0, multipath=(0.0, 0.01, 20.0)), base_offset=None, t=t)
    f = sim.fields
    el, _ = E.elevation_azimuth(f["sat_pos"], LAT, LON, H)
    lam = G.C_LIGHT / f["signals"].freq[:, 0]
    x = (_code_minus_phase(sim, LAT, LON, H)[:, 0] - sim.ambiguity[:, 0]) * lam * np.maximum(np.sin(el), 0.05) / 0.01
    r, v = [], []
    for sat in np.unique(f["sat"]):
        m = np.flatnonzero(f["sat"] == sat)
        if m.size < 300 or np.any(np.diff(f["epoch"][m]) != 1):
            continue
        y = x[m] - x[m].mean()          # the fractional biases are constants
        r.append(np.sum(y[1:] * y[:-1]) / np.sum(y * y))
        v.append(np.var(y))
    assert len(r) >= 5
    assert abs(np.mean(r) - math.exp(-1 / 20)) < 0.03 and abs(np.sqrt(np.mean(v)) - 1) < 0.1


def test_slips_and_losses_of_lock():
    """Slips at 1 per 100 s per signal, half flagged: the integer changes exactly where the
    simulator marks a slip; the LLI slip bit is on for some slips and off for others and
    never without one; an outage of every satellite (10 s) gives each a new integer and a
    flag when it returns."""
    err = SG.GnssErrors(canyon=((0, 60.0, 10.0),))
    sim = _sim(err, SG.PhaseErrors(slip_rate=0.01, slip_flagged=0.5), base_offset=None)
    f = sim.fields
    S = f["signals"]
    changed_seen = np.zeros_like(sim.slip)
    for sat in np.unique(f["sat"]):
        m = np.flatnonzero(f["sat"] == sat)
        changed_seen[m[1:]] = (np.diff(sim.ambiguity[m], axis=0) != 0) | (np.diff(f["epoch"][m]) != 1)[:, None]
    has = S.code != ""
    later = has.copy()
    later[_firsts(f)] = False                  # a satellite's first row is a new lock
    assert np.array_equal(changed_seen[later], sim.slip[later])
    flagged = S.slip & sim.slip
    assert flagged.sum() > 10 and (sim.slip & ~S.slip & has).sum() > 10
    assert not np.any(S.slip & ~sim.slip)
    back = f["epoch"] == 70
    assert back.sum() >= 6 and np.all(S.slip[back][:, :2]) and not np.any(f["epoch"] == 65)


def _firsts(f):
    return [int(np.flatnonzero(f["sat"] == s)[0]) for s in np.unique(f["sat"])]


def test_base_needs_phase():
    with pytest.raises(ValueError, match="base station needs the carrier phase"):
        _sim(phase=None)


def test_walker_positions_keep_the_bytes_of_the_full_formula():
    """Walker.positions with its time-independent terms computed once per constellation
    gives the bytes of the formula evaluated whole at every call (circular orbits, planes
    at equal right ascensions, Earth rotation), for one time and for one time per
    satellite."""
    for w in WALKERS:
        for t in (0.0, 1234.5678, np.linspace(10.0, 90_000.0, w.planes * w.per_plane)):
            t = np.asarray(t, dtype=float)
            n = math.sqrt(E.GM / w.radius ** 3)
            S = w.planes * w.per_plane
            j = np.repeat(np.arange(w.planes), w.per_plane)
            k = np.tile(np.arange(w.per_plane), w.planes)
            raan = w.raan0 + 2 * math.pi * j / w.planes
            u = w.u0 + 2 * math.pi * k / w.per_plane + 2 * math.pi * w.phasing * j / S + n * t
            ci, si = math.cos(w.inclination), math.sin(w.inclination)
            x, y = w.radius * np.cos(u), w.radius * np.sin(u)
            xi = x * np.cos(raan) - y * ci * np.sin(raan)
            yi = x * np.sin(raan) + y * ci * np.cos(raan)
            a = E.WIE * t
            want = np.stack([np.cos(a) * xi + np.sin(a) * yi, -np.sin(a) * xi + np.cos(a) * yi, y * si + 0 * a], -1)
            assert w.positions(t).tobytes() == want.tobytes()
