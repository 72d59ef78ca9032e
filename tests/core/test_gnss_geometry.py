"""Satellite geometry (sinslab.core.gnss) against RTKLIB's own functions, and the ECEF
helpers of sinslab.core.earth as round trips.

RTKLIB (demo5, the pyrtklib5 binding) is an independent implementation of the same
interface documents: satellite positions and clocks at transmission (IS-GPS-200
§20.3.3.4.3, Galileo OS SIS ICD §5.1.1, BDS SIS ICD §5.2.4, GLONASS ICD A.3.1.2), Klobuchar
(IS-GPS-200 §20.3.3.5.2.5) and Saastamoinen.
"""
import math
from pathlib import Path

import numpy as np
import pytest

from sinslab.core import earth as E
from sinslab.core import gnss as G

WALK = Path(__file__).resolve().parents[3] / "shared" / "data" / "rtklib-walk" / "gnss_1730.ubx"
needs_walk = pytest.mark.skipif(not WALK.exists(), reason="rtklib-walk not available")


def test_geodetic_ecef_round_trip():
    rng = np.random.default_rng(1)
    lat = rng.uniform(-1.5, 1.5, 200)
    lon = rng.uniform(-math.pi, math.pi, 200)
    h = rng.uniform(-500.0, 2.5e7, 200)
    r = E.geodetic_to_ecef(lat, lon, h)
    la, lo, hh = E.ecef_to_geodetic(r)
    assert np.max(np.abs(la - lat)) < 1e-12 and np.max(np.abs(hh - h)) < 1e-4
    assert np.max(np.abs(np.angle(np.exp(1j * (lo - lon))))) < 1e-12
    # C_n^e: orthonormal, and its north column is d r / d lat scaled by R_M + h
    C = E.enu_to_ecef_matrix(0.6, 2.1)
    assert np.allclose(C.T @ C, np.eye(3), atol=1e-15)
    rm, rn = E.radii(0.6, 100.0)
    dn = (E.geodetic_to_ecef(0.6 + 1e-7, 2.1, 100.0) - E.geodetic_to_ecef(0.6 - 1e-7, 2.1, 100.0)) / 2e-7
    assert np.allclose(dn, C[:, 1] * rm, rtol=1e-7)


@pytest.fixture(scope="module")
def walk():
    rtk = pytest.importorskip("pyrtklib5")
    if not WALK.exists():
        pytest.skip("rtklib-walk not available")
    from sinslab.data.gnss import read_gnss_raw
    g = read_gnss_raw(WALK)
    raw = rtk.raw_t()
    rtk.init_raw(raw, rtk.STRFMT_UBX)
    fw = rtk.FileWrapper(str(WALK), "rb")
    last = None
    while True:
        r = rtk.input_ubxf(raw, fw)
        if r == -2:
            break
        if r == 1:
            last = raw.obs.n
    return rtk, raw, last, g


@needs_walk
def test_satellite_positions_match_rtklib(walk):
    """At the last epoch of the walk log: every satellite with an ephemeris, position at
    transmission to 1 mm, velocity to 1 mm/s, clock (relativistic term included) to 1 mm
    of range — against RTKLIB's satposs on the same observations and ephemerides."""
    rtk, raw, n, g = walk
    nav = raw.nav
    obs = raw.obs
    for s in range(rtk.MAXSAT):        # Galileo: the I/NAV ephemerides (set 0), as the reader keeps
        nav.eph[s + rtk.MAXSAT].sat = 0
    rs, dts, var, svh = (rtk.Arr1Ddouble(6 * n), rtk.Arr1Ddouble(2 * n), rtk.Arr1Ddouble(n),
                         rtk.Arr1Dint(n))
    rtk.satposs(obs.data[0].time, obs.data.ptr, n, nav, 0, rs, dts, var, svh)
    from sinslab.data.gnss import _satid
    e = g.epoch_t.size - 1
    m = g.epoch == e
    sats, P = g.sat[m], g.pseudorange[m]
    # the ephemerides RTKLIB holds at the end of the log (set 0), found in the reader's table
    rows = []
    for s in range(rtk.MAXSAT):
        ee = nav.eph[s]
        if ee.sat <= 0 or ee.A <= 0:
            continue
        toe = (ee.toe.time - g.t_ref) + ee.toe.sec
        k = np.flatnonzero((g.eph.sat == _satid(rtk, ee.sat)) & (np.abs(g.eph.toe - toe) < 1e-6)
                           & (np.abs(g.eph.f0 - ee.f0) < 1e-15))
        rows += k[:1].tolist()
    eph = g.eph.take(np.array(rows))
    pos, vel, clk, drift, row = G.transmit_states(eph, None, sats, np.full(sats.size, g.epoch_t[e]), P)
    checked = 0
    for i in range(n):
        sid = _satid(rtk, obs.data[i].sat)
        k = np.flatnonzero(sats == sid)
        ref = np.array([rs[6 * i + j] for j in range(6)])
        if not k.size or not np.any(ref[:3]) or row[k[0]] < 0:
            continue
        k = k[0]
        assert np.max(np.abs(pos[k] - ref[:3])) < 1e-3, sid
        assert np.max(np.abs(vel[k] - ref[3:])) < 2e-3, sid       # RTKLIB: 1 ms forward difference
        assert abs(clk[k] - dts[2 * i]) * G.C_LIGHT < 1e-3, sid
        assert abs(drift[k] - dts[2 * i + 1]) * G.C_LIGHT < 1e-3, sid
        checked += 1
    assert checked >= 15          # GPS, Galileo and BeiDou (MEO, IGSO and GEO) satellites


@needs_walk
def test_orbit_at_many_times_and_beidou_geo(walk):
    """eph2pos over ±2 h around each ephemeris' reference time (every system, BeiDou GEO
    C01–C05 absent here, IGSO/MEO present) to 1 mm and 1e-12 s."""
    rtk, raw, n, g = walk
    checked = 0
    for s in range(rtk.MAXSAT * 2):
        ee = raw.nav.eph[s]
        if ee.sat <= 0 or ee.A <= 0:
            continue
        from sinslab.data.gnss import _satid
        sid = _satid(rtk, ee.sat)
        k = np.flatnonzero((g.eph.sat == sid) & (np.abs(g.eph.toe - ((ee.toe.time - g.t_ref) + ee.toe.sec)) < 1e-6))
        if not k.size:
            continue
        for dt in (-7000.0, -10.0, 0.0, 3333.3):
            t = rtk.gtime_t()
            t.time, t.sec = ee.toe.time + int(dt), dt - int(dt)
            rs, dts, var = rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(1), rtk.Arr1Ddouble(1)
            rtk.eph2pos(t, ee, rs, dts, var)
            p, v, c, d = G.kepler_states(g.eph, k[:1], np.array([g.eph.toe[k[0]] + dt]))
            assert np.max(np.abs(p[0] - [rs[0], rs[1], rs[2]])) < 1e-3, (sid, dt)
            assert abs(c[0] - dts[0]) < 1e-12, (sid, dt)
        checked += 1
    assert checked >= 15


def test_glonass_orbit_matches_rtklib():
    """A GLONASS state vector integrated 15 min either way: RTKLIB's geph2pos to 1 mm."""
    rtk = pytest.importorskip("pyrtklib5")
    ge = rtk.geph_t()
    ge.sat = rtk.satno(rtk.SYS_GLO, 3)
    ge.toe.time, ge.toe.sec = 1756402200, 0.0
    pos0, vel0, acc0 = (1.1e7, -1.3e7, 1.8e7), (1200.0, 2400.0, 1000.0), (1e-6, -2e-6, 3e-6)
    for j in range(3):
        ge.pos[j], ge.vel[j], ge.acc[j] = pos0[j], vel0[j], acc0[j]
    ge.taun, ge.gamn = 1.2e-5, 1.8e-12
    geph = G.GlonassEphemerides(1756402200, np.array(["R03"]), np.zeros(1, np.int64), np.zeros(1),
                                np.array([pos0]), np.array([vel0]), np.array([acc0]), np.array([1.2e-5]),
                                np.array([1.8e-12]), np.zeros(1, np.int64), np.zeros(1, np.int64))
    for dt in (-900.0, -45.5, 0.0, 130.0, 900.0):
        t = rtk.gtime_t()
        t.time, t.sec = 1756402200 + int(math.floor(dt)), dt - math.floor(dt)
        rs, dts, var = rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(1), rtk.Arr1Ddouble(1)
        rtk.geph2pos(t, ge, rs, dts, var)
        p, v, c, d = G.glonass_states(geph, np.array([0]), np.array([dt]))
        assert np.max(np.abs(p[0] - [rs[0], rs[1], rs[2]])) < 1e-3, dt
        assert abs(c[0] - dts[0]) < 1e-15


def test_klobuchar_and_saastamoinen_match_rtklib():
    rtk = pytest.importorskip("pyrtklib5")
    ion = (2.0e-08, 1.5e-08, -1.2e-07, -5.9e-08, 1.3e+05, 0.0, -2.6e+05, 1.9e+05)
    rng = np.random.default_rng(3)
    for _ in range(40):
        lat, lon, h = rng.uniform(-1.2, 1.2), rng.uniform(-3, 3), rng.uniform(-50, 3000)
        az, el = rng.uniform(0, 2 * math.pi), rng.uniform(0.05, 1.5)
        tow = rng.uniform(0, 604800)
        t = rtk.gtime_t()
        t.time, t.sec = G.GPS_EPOCH_UNIX + 2380 * 604800 + int(tow), tow - int(tow)
        pos = rtk.Arr1Ddouble(3)
        azel = rtk.Arr1Ddouble(2)
        pos[0], pos[1], pos[2] = lat, lon, h
        azel[0], azel[1] = az, el
        for coeffs in (ion, None):
            a = rtk.Arr1Ddouble(8)
            for j in range(8):
                a[j] = 0.0 if coeffs is None else coeffs[j]
            ref = rtk.ionmodel(t, a, pos, azel)
            assert abs(G.klobuchar(tow, lat, lon, az, el, coeffs) - ref) < 1e-6
        assert abs(G.saastamoinen(lat, h, el) - rtk.tropmodel(t, pos, azel, 0.7)) < 1e-6


def test_sagnac_and_elevation():
    """Sagnac term: the range to the satellite's position expressed in the Earth-fixed
    axes of the reception time (rotated by ω_e τ) equals the ECEF range plus the first-order
    term (to 0.1 mm)."""
    rr = E.geodetic_to_ecef(0.7, 0.3, 100.0)
    rs = E.geodetic_to_ecef(0.9, 0.8, 2.02e7)
    rho, u = G.sagnac_range(rs, rr)
    tau = np.linalg.norm(rs - rr) / G.C_LIGHT
    for _ in range(3):
        a = E.WIE * tau
        # the satellite's coordinates in the Earth-fixed axes of the reception time
        rsi = np.array([math.cos(a) * rs[0] + math.sin(a) * rs[1], -math.sin(a) * rs[0] + math.cos(a) * rs[1], rs[2]])
        tau = np.linalg.norm(rsi - rr) / G.C_LIGHT
    assert abs(rho - np.linalg.norm(rsi - rr)) < 1e-4
    el, az = E.elevation_azimuth(E.geodetic_to_ecef(0.7, 0.3, 2e7), 0.7, 0.3, 100.0)
    assert abs(el - math.pi / 2) < 1e-6


def test_elevation_azimuth_and_geodetic_match_rtklib():
    """Elevation/azimuth (satazel) and ECEF -> geodetic (ecef2pos) against RTKLIB."""
    rtk = pytest.importorskip("pyrtklib5")
    rng = np.random.default_rng(5)
    for _ in range(30):
        lat, lon, h = rng.uniform(-1.4, 1.4), rng.uniform(-3.1, 3.1), rng.uniform(-100, 5000)
        rs = E.geodetic_to_ecef(rng.uniform(-1.2, 1.2), rng.uniform(-3.1, 3.1), 2.0e7)
        pos, e, azel = rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(2)
        pos[0], pos[1], pos[2] = lat, lon, h
        rr = E.geodetic_to_ecef(lat, lon, h)
        d = (rs - rr) / np.linalg.norm(rs - rr)
        for j in range(3):
            e[j] = d[j]
        rtk.satazel(pos, e, azel)
        el, az = E.elevation_azimuth(rs, lat, lon, h)
        assert abs(el - azel[1]) < 1e-12
        if el > 0:
            assert abs(np.angle(np.exp(1j * (az - azel[0])))) < 1e-12
        r3, p3 = rtk.Arr1Ddouble(3), rtk.Arr1Ddouble(3)
        for j in range(3):
            r3[j] = rr[j]
        rtk.ecef2pos(r3, p3)
        la, lo, hh = E.ecef_to_geodetic(rr)
        assert abs(la - p3[0]) < 1e-12 and abs(lo - p3[1]) < 1e-12 and abs(hh - p3[2]) < 1e-4


def test_geodetic_to_ecef_broadcasts_mixed_shapes():
    """A scalar latitude against an array of longitudes (and the reverse): the same as the
    point-by-point conversion."""
    lon = np.linspace(-3.0, 3.0, 7)
    grid = E.geodetic_to_ecef(0.5, lon, 1000.0)
    assert grid.shape == (7, 3)
    for i, lo in enumerate(lon):
        assert np.array_equal(grid[i], E.geodetic_to_ecef(0.5, lo, 1000.0))
    assert E.geodetic_to_ecef(lon[:, None] / 3, 0.2, np.array([0.0, 10.0])).shape == (7, 2, 3)


def test_one_point_paths_are_the_array_paths_bit_for_bit():
    """enu_to_ecef_matrix and geodetic_to_ecef of one point (their shortcut without stacks)
    give the bytes of the same point taken from an array, signed zeros included (the
    poles, the equator and the prime meridian put zeros in the matrix)."""
    lats = np.array([0.0, -0.0, 0.6, -1.1, math.pi / 2, -math.pi / 2])
    lons = np.array([0.0, -0.0, 2.1, -3.0, math.pi, -math.pi / 2])
    C = E.enu_to_ecef_matrix(lats[:, None], lons[None, :])
    r = E.geodetic_to_ecef(lats[:, None], lons[None, :], 120.0)
    for i, la in enumerate(lats):
        for j, lo in enumerate(lons):
            for a, b in ((la, lo), (float(la), float(lo)), (np.array(la), np.array(lo))):
                assert E.enu_to_ecef_matrix(a, b).tobytes() == C[i, j].tobytes()
                assert E.geodetic_to_ecef(a, b, 120.0).tobytes() == r[i, j].tobytes()
