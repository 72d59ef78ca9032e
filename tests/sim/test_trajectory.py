"""Oracles for sinslab.sim.trajectory: closed forms, consistency, round trip through the
strapdown mechanization, config/TOML handling and bad input."""
import math
from pathlib import Path

import numpy as np
import pytest

from sinslab.core import attitude as at
from sinslab.core import earth
from sinslab.sim import indexing, presets
from sinslab.sim import _synth
from sinslab.sim import trajectory as tr
from sinslab.core import units as u
from sinslab.core.records import NavState

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
START_003 = tr.Start(lat=32 * u.deg, lon=118 * u.deg, h=1000.0, speed=300.0, heading=0.0)


# --- static -----------------------------------------------------------------------------------
@pytest.mark.parametrize("lat_deg,heading_deg,pitch_deg,roll_deg",
                         [(34.246, 235.0, -5.0, 2.0), (-60.0, 10.0, 20.0, -40.0), (0.0, 90.0, 0.0, 0.0)])
def test_static_increments_are_earth_rate_and_gravity(lat_deg, heading_deg, pitch_deg, roll_deg):
    st = tr.Start(lat=lat_deg * u.deg, lon=1.0, h=400.0, heading=heading_deg * u.deg,
                  pitch=pitch_deg * u.deg, roll=roll_deg * u.deg)
    dt = 0.01
    g = tr.generate(presets.static(20.0), st, dt)
    att = g.truth.att
    np.testing.assert_allclose(att, np.tile([pitch_deg * u.deg, roll_deg * u.deg,
                                             at.heading_to_yaw(heading_deg * u.deg)], (len(att), 1)),
                               atol=1e-15)
    assert at.yaw_to_heading(att[0, 2]) == pytest.approx(heading_deg * u.deg, abs=1e-14)
    Cnb = at.euler_to_dcm(att[0]).T
    w = Cnb @ earth.wie_n(st.lat) * dt
    f = Cnb @ np.array([0.0, 0.0, float(earth.gravity(st.lat, st.h))]) * dt
    assert np.abs(g.imu.dtheta - w).max() <= 1e-15 * WIE_DT(dt)
    assert np.abs(g.imu.dv - f).max() <= 1e-15
    assert np.all(g.truth.lat == st.lat) and np.all(g.truth.h == st.h) and np.all(g.truth.vel == 0)
    assert g.mount is None and g.truth.att_imu is None
    assert len(g.imu) == 2000 and len(g.truth) == 2001
    np.testing.assert_allclose(g.imu.t, dt * np.arange(1, 2001))
    np.testing.assert_allclose(g.truth.t, dt * np.arange(2001))


def WIE_DT(dt):
    return earth.WIE * dt * 10        # a few ulps of the increment


# --- constant-rate turn ----------------------------------------------------------------------
def _earth_terms_np(truth, att):
    """ω_in^b and the Earth part of f^b [(2ω_ie+ω_en)×v + (0,0,g)] in body axes, numpy."""
    lat, h, v = truth.lat, truth.h, truth.vel
    win = earth.wie_n(lat) + earth.wen_n(lat, h, v)
    cor = np.cross(2 * earth.wie_n(lat) + earth.wen_n(lat, h, v), v)
    cor[:, 2] += earth.gravity(lat, h)
    Cnb = np.swapaxes(at.euler_to_dcm(att), -1, -2)
    return np.einsum("kij,kj->ki", Cnb, win), np.einsum("kij,kj->ki", Cnb, cor)


@pytest.mark.parametrize("rate_deg", [3.0, -2.0])
def test_flat_turn_matches_closed_form(rate_deg):
    V, dt = 20.0, 0.01
    st = tr.Start(lat=45 * u.deg, lon=0.0, h=10.0, speed=V, heading=30 * u.deg)
    turn = tr.Turn(60.0, rate_deg * u.deg, ramp=2.0, coordinated=False)
    g = tr.generate([tr.Level(5.0), turn, tr.Level(5.0)], st, dt)
    T = g.truth
    # heading change = rate (duration - ramp), clockwise positive
    dpsi = at.wrap_pi(T.att[-1, 2] - T.att[0, 2])
    assert -dpsi == pytest.approx(turn.angle, abs=1e-12)
    assert turn.angle == pytest.approx(rate_deg * u.deg * 58.0)
    # flat part of the turn: 5+2 .. 65-2 s; Earth terms by Simpson's rule on a half-step truth
    k = np.arange(int(7.5 / dt), int(62.5 / dt))
    psid = -rate_deg * u.deg
    half = tr.generate([tr.Level(5.0), turn, tr.Level(5.0)], st, dt / 2).truth
    win_b, cor_b = _earth_terms_np(half, half.att)
    w_mid = (win_b[2 * k] + 4 * win_b[2 * k + 1] + win_b[2 * k + 2]) / 6
    c_mid = (cor_b[2 * k] + 4 * cor_b[2 * k + 1] + cor_b[2 * k + 2]) / 6
    w_exp = np.array([0.0, 0.0, psid]) + w_mid
    f_exp = np.array([-V * psid, 0.0, 0.0]) + c_mid
    np.testing.assert_allclose(g.imu.dtheta[k] / dt, w_exp, rtol=0, atol=1e-15)
    np.testing.assert_allclose(g.imu.dv[k] / dt, f_exp, rtol=0, atol=1e-12)
    assert np.all(T.att[:, :2] == 0.0)
    np.testing.assert_allclose(np.hypot(T.vel[:, 0], T.vel[:, 1]), V, rtol=1e-14)


def test_coordinated_turn_banks_right_wing_down_for_right_turn():
    st = tr.Start(lat=30 * u.deg, lon=0.0, h=1000.0, speed=200.0, heading=0.0)
    rate = 2.0 * u.deg
    g = tr.generate([tr.Turn(40.0, rate, ramp=4.0)], st, 0.01)
    mid = len(g.truth) // 2
    bank = math.atan(200.0 * rate / u.g0)
    assert g.truth.att[mid, 1] == pytest.approx(bank, abs=1e-12)
    assert g.truth.att[0, 1] == 0.0 and abs(g.truth.att[-1, 1]) < 1e-15
    # in the steady coordinated turn the lateral specific force nearly vanishes: what is
    # left is V·ω·cos φ·(1 − g/g0) and the Coriolis force, ~0.01 m/s² (V·ω = 7 m/s²)
    assert abs(g.imu.dv[mid, 0] / 0.01) < 0.03


# --- numerical consistency --------------------------------------------------------------------
def test_quadrature_orders_converge_and_agree():
    segs = presets.aircraft_mixed(200.0)
    mount = indexing.dual_axis_16(dwell=10.0)
    ref = tr.generate(segs, START_003, 0.01, mount=mount, quadrature="gauss", nodes=6)
    errs = {}
    for q, n in (("gauss", 1), ("gauss", 2), ("gauss", 3), ("lobatto", 3), ("stencil", 4),
                 ("stencil", 6), ("stencil", 8)):
        g = tr.generate(segs, START_003, 0.01, mount=mount, quadrature=q, nodes=n)
        errs[q, n] = max(np.abs(g.imu.dtheta - ref.imu.dtheta).max(),
                         np.abs(g.imu.dv - ref.imu.dv).max())
        np.testing.assert_array_equal(g.truth.att_imu, ref.truth.att_imu)
    assert errs["gauss", 1] > 100 * errs["gauss", 2] > 100 * errs["gauss", 3]
    assert errs["stencil", 4] > 100 * errs["stencil", 6]
    assert errs["stencil", 8] < 1e-13 and errs["stencil", 6] < 1e-12
    assert errs["gauss", 3] < 1e-14


@pytest.mark.parametrize("dt", [0.005, 0.02, 0.1])
def test_stencil_agrees_with_gauss_at_other_rates(dt):
    """The stencil path evaluates the Earth terms at positions predicted over a block of 64
    intervals (0.3–6.4 s here), the Gauss path at positions from the exact one of each
    interval: both must give the same increments and positions. Bars: the 8-point stencil's
    own truncation error (~2e-9 m/s at 10 Hz) and a few ulps elsewhere; leaving out the
    latitude term of R_M in the prediction gave 3.4e-14 m/s at 50 Hz."""
    segs = presets.aircraft_mixed(700.0)
    ref = tr.generate(segs, START_003, dt, quadrature="gauss", nodes=6)
    g = tr.generate(segs, START_003, dt)
    err = max(np.abs(g.imu.dtheta - ref.imu.dtheta).max(), np.abs(g.imu.dv - ref.imu.dv).max())
    assert err < (1e-8 if dt >= 0.1 else 5e-15)
    rm, _ = earth.radii(ref.truth.lat, ref.truth.h)
    assert np.abs((g.truth.lat - ref.truth.lat) * rm).max() < (1e-6 if dt >= 0.1 else 1e-9)
    assert np.abs(g.truth.h - ref.truth.h).max() < 1e-9


def test_sincos_rotation_stays_within_a_few_ulps():
    """The kinematics follow sin/cos of slowly changing angles by small rotations with
    series for sin d, cos d, restarting from exact values every _ROT_RUN steps: over
    100 000 random steps (up to ±0.03 rad, some beyond _ROT_MAX, some zero) they stay within
    2e-15 of math.sin/math.cos of the angle (measured: 5.6e-16)."""
    rng = np.random.default_rng(7)
    steps = np.concatenate([rng.uniform(-0.03, 0.03, 50_000),       # some beyond _ROT_MAX
                            rng.uniform(-0.015, 0.015, 50_000)])    # runs of _ROT_RUN
    steps[rng.random(steps.size) < 0.05] = 0.0
    x = 1.0
    a, s, c, n = x, math.sin(x), math.cos(x), 0
    worst, rotated, runs = 0.0, 0, []
    for d in steps:
        x += d
        a, s, c, n2 = _synth._sincos_step(x, a, s, c, n)
        assert a == x and n2 <= _synth._ROT_RUN
        rotated += n2 == n + 1
        if n2 < n:
            runs.append(n)
        n = n2
        worst = max(worst, abs(s - math.sin(x)), abs(c - math.cos(x)))
    assert worst < 2e-15
    assert rotated > 0.75 * steps.size and max(runs) == _synth._ROT_RUN


@pytest.mark.parametrize("with_sines", [True, False])
def test_channel_rows_equal_the_array_evaluation(with_sines):
    """The kinematics evaluate the channel terms row by row over runs of epochs
    (_channel_rows); the fallback path's _channels sums them epoch by epoch into arrays
    indexed by channel. On random tables (all term types, every channel, several terms per
    channel) both must give the same numbers bit for bit: same terms, same order of the
    additions. With sine terms the runs are single epochs with a fresh per-term cache (its
    sines are then exact, as _channels takes them); without, runs of up to 60 epochs. One
    buffer throughout, pieces alternating: the rows of a channel without terms keep their
    constant from an earlier run only while it is the piece's value (rowb)."""
    rng = np.random.default_rng(11)
    nt = 40
    ttype = rng.integers(0, 3 if with_sines else 2, nt)
    tch = np.concatenate([np.arange(_synth.NCH), rng.integers(0, _synth.NCH, nt - _synth.NCH)])
    tta = rng.uniform(0.0, 5.0, nt)
    T = rng.uniform(0.5, 8.0, nt)
    tpar = np.zeros((nt, 6))
    tpar[:, 0] = rng.normal(0.0, 2.0, nt)
    tpar[:, 1] = np.where(ttype == _synth.T_SINE, rng.uniform(0.1, 5.0, nt), T)
    tpar[:, 2] = np.where(ttype == _synth.T_TRAP, T * rng.uniform(0.0, 0.5, nt), rng.uniform(-3, 3, nt))
    tpar[:, 3] = T
    tpar[:, 4] = T * rng.uniform(0.0, 0.5, nt) * (rng.random(nt) < 0.7)
    tpar[:, 5] = T * rng.uniform(0.0, 0.5, nt) * (rng.random(nt) < 0.7)
    base = rng.normal(0.0, 1.0, (3, _synth.NCH))
    base[2] = base[0]
    base[2, 3] = -0.0                                   # a zero of the other sign than piece 3's
    base = np.vstack([base, base[2:3]])
    base[3, 3] = 0.0
    plo = np.array([0, 3, 3, 3], dtype=np.int64)
    phi = np.array([3, nt, 3, 3], dtype=np.int64)
    act = rng.permutation(nt).astype(np.int64)
    val, d1, d2 = np.empty(_synth.NCH), np.empty(_synth.NCH), np.empty(_synth.NCH)
    NB, dt = _synth._NB, 0.01
    Z = np.zeros(_synth._NROW * NB)
    rowb = np.full(_synth.NCH, np.nan)
    rows = Z.reshape(_synth._NROW, NB)[44:44 + 3 * _synth.NCH].reshape(_synth.NCH, 3, NB)
    for _ in range(300):
        j = int(rng.integers(0, 4))
        nr = 1 if with_sines else int(rng.integers(1, 61))
        e = int(rng.integers(0, 1400))
        ui = int(rng.integers(0, NB - nr + 1))
        tc = np.zeros((nt, 4))
        tc[:, 0] = np.nan
        _synth._channel_rows(e, nr, np.uint64(ui), dt, j, base, plo, phi, act, ttype, tch, tta,
                             tpar, tc, rowb, Z)
        for k in range(nr):
            _synth._channels((e + k) * dt, j, base, plo, phi, act, ttype, tch, tta, tpar, val, d1, d2)
            got = rows[:, :, ui + k]
            want = np.stack([val, d1, d2], axis=1)
            assert np.array_equal(got.view(np.int64), want.view(np.int64))


@pytest.mark.parametrize("has_mount", [False, True])
def test_state_rows_equal_the_scalar_state(has_mount):
    """_state_rows evaluates _kin over a run of columns in one vectorised loop, reading its
    inputs from rows it then overwrites (0..20). Every column must hold the bits of _kin
    called on that column's inputs alone: no reassociation or fused multiply-add in the
    SIMD code, each input read before its column is written."""
    rng = np.random.default_rng(5)
    NB, R = _synth._NB, lambda r: r * _synth._NB
    for _ in range(20):
        Z = rng.normal(0.0, 1.0, _synth._NROW * NB) * 10.0 ** rng.integers(-3, 3, _synth._NROW * NB)
        nr = int(rng.integers(1, NB + 1))
        ui = int(rng.integers(0, NB - nr + 1))
        before = Z.copy()
        _synth._state_rows(np.uint64(ui), nr, has_mount, Z)
        for c in range(ui, ui + nr):
            z = lambda r: before[R(r) + c]
            want = _synth._kin(z(44), z(45), z(51), z(6), z(7), z(8), z(9), z(48), z(63), z(64),
                               z(18), z(51) + z(57), z(10), z(11), z(20), z(48) + z(60), z(12),
                               z(13), z(19), z(16), z(14), z(15), has_mount,
                               (z(65), z(68), z(71), z(66), z(69), z(72), z(0), z(1), z(2),
                                z(3), z(4), z(5)))
            got = Z[[R(q) + c for q in range(24)]]
            assert np.array_equal(got.view(np.int64), np.array(want).view(np.int64))
        outside = np.ones(_synth._NROW * NB, bool)
        for q in range(24):
            outside[R(q) + ui:R(q) + ui + nr] = False
        assert np.array_equal(Z[outside], before[outside])


@pytest.mark.parametrize("zero", [0.0, -0.0])
def test_zero_body_offset_takes_the_path_angles_sines(zero):
    """With a body pitch (or yaw) offset of 0 over a run, the kinematics copy the path
    angle's sines and cache (_add_copy_rows) instead of stepping the body angle
    (_offset_sines_run): x + 0 == x, so the loop takes the path angle's values at every
    epoch, and the copy must give the same bits, the angle's row and the cache after the
    run included. _rows_same, which decides when a steady turn's bank angle is taken once,
    must tell the zeros apart."""
    rng = np.random.default_rng(3)
    NB, R = _synth._NB, lambda r: np.uint64(r * _synth._NB)
    nr, ui = 60, np.uint64(5)
    Z = rng.normal(0.0, 1.0, _synth._NROW * NB)
    row = Z[int(R(50)) + 5:int(R(50)) + 5 + nr]
    row[:] = np.cumsum(rng.normal(0.0, 3e-3, nr)) + 0.4
    row[10:14] = row[9]                                   # an angle that stops for a while
    Z[int(R(56)):int(R(57))] = zero
    th = _synth._sines_run(Z, R(50), R(6), R(22), ui, nr, np.nan, 0.0, 0.0, 0)
    A, B = Z.copy(), Z.copy()
    got = _synth._offset_sines_run(A, R(50), R(56), R(6), R(22), R(10), R(18), ui, nr,
                                   np.nan, 0.0, 0.0, 0)
    _synth._add_copy_rows(B, R(50), R(56), R(18), R(6), R(10), ui, nr)
    assert np.array_equal(A.view(np.int64), B.view(np.int64))
    assert np.array_equal(np.array(got).view(np.int64), np.array(th).view(np.int64))
    Zi = Z.view(np.int64)
    Z[int(R(48)):int(R(50))] = 0.0
    assert _synth._rows_same(Zi, R(48), np.uint64(2), ui, nr)
    Z[int(R(49)) + 30] = -0.0
    assert not _synth._rows_same(Zi, R(48), np.uint64(2), ui, nr)


@pytest.mark.parametrize("m", [2, 4, 6, 8, 10])
def test_stencil_block_sums_in_the_order_of_the_pairwise_loop(m):
    """_stencil_block writes each stencil sum as one expression; it must give the bits of
    adding the symmetric pairs one after another to a zero (here in plain Python floats:
    the same IEEE operations), also where every pair is −0 (the sum is then +0), and touch
    no row but its outputs. m = 2 and 10 take its general loop."""
    rng = np.random.default_rng(5)
    mh, NB = m // 2, _synth._NB
    Z = rng.normal(0.0, 1.0, (_synth._NROW, NB)) * 10.0 ** rng.integers(-12, 3, (_synth._NROW, NB))
    Z[24:33, ::7] = -0.0
    Z[24:33, 20:40] = -0.0
    swd = rng.normal(0.0, 1.0, mh)
    off = 1
    nk = min(_synth._BLOCK, NB - off - m + 1)
    before = Z.copy()
    _synth._stencil_block(nk, off, swd, Z.reshape(-1))
    want = before.copy()
    for q in range(9):
        for k in range(nk):
            acc = 0.0
            for j in range(mh):
                acc += float(swd[j]) * (float(Z[24 + q, off + k + j]) + float(Z[24 + q, off + k + m - 1 - j]))
            want[35 + q, k] = acc
    assert np.array_equal(Z.view(np.int64), want.view(np.int64))


@pytest.mark.parametrize("n", [1, 2, 7, 63, 64, 65, 71, 72, 128, 130])
def test_run_length_does_not_change_the_samples(n):
    """Runs are synthesised in blocks of 64 intervals with a halo of look-ahead epochs: a
    run of n samples must give exactly the first n samples of a longer run, whatever the
    position of n relative to the blocks (segment breakpoints at 0.3 s and 0.64 s)."""
    segs = [tr.Accelerate(0.3, 2.0, ramp=0.1), tr.Turn(0.34, 3.0 * u.deg, ramp=0.1),
            tr.WingRock(5.0, 10 * u.deg, 1.0, ramp=0.2)]
    dt = 0.01
    long = tr.generate(segs, START_003, dt, duration=300 * dt, mount=indexing.Swing())
    g = tr.generate(segs, START_003, dt, duration=n * dt, mount=indexing.Swing())
    assert len(g.imu) == n
    np.testing.assert_array_equal(g.imu.dtheta, long.imu.dtheta[:n])
    np.testing.assert_array_equal(g.imu.dv, long.imu.dv[:n])
    np.testing.assert_array_equal(g.mount, long.mount[:n + 1])
    for name in ("lat", "lon", "h", "vel", "att", "att_imu"):
        np.testing.assert_array_equal(getattr(g.truth, name), getattr(long.truth, name)[:n + 1])


def test_truth_velocity_is_derivative_of_truth_position():
    g = tr.generate(presets.aircraft_mixed(700.0), START_003, 0.01)
    T = g.truth
    rm, rn = earth.radii(T.lat, T.h)
    dt2 = 2 * 0.01
    vn = (T.lat[2:] - T.lat[:-2]) / dt2 * rm[1:-1]
    ve = (T.lon[2:] - T.lon[:-2]) / dt2 * rn[1:-1] * np.cos(T.lat[1:-1])
    vu = (T.h[2:] - T.h[:-2]) / dt2
    err = np.abs(np.stack([ve, vn, vu], -1) - T.vel[1:-1]).max()
    assert err < 1e-4          # central differences: dt²/6·|v̈| with |v̈| < ~20 m/s³


def test_attitude_increments_match_truth_attitude():
    """Δθ minus the navigation-frame rate rotates C_b^n(k) into C_b^n(k+1) (to O(dt³))."""
    g = tr.generate(presets.aircraft_mixed(700.0), START_003, 0.01, mount=indexing.dual_axis_16(dwell=5.0))
    T = g.truth
    C = at.euler_to_dcm(T.att_imu)
    win_b, _ = _earth_terms_np(T, T.att_imu)
    rel = at.dcm_to_rotvec(np.swapaxes(C[:-1], -1, -2) @ C[1:])
    approx = g.imu.dtheta - 0.5 * (win_b[:-1] + win_b[1:]) * 0.01
    assert np.abs(rel - approx).max() < 1e-8


@pytest.mark.parametrize("mount", [indexing.Swing(), None])
def test_out_every_decimates_truth_only(mount):
    """Without a mount, full-rate truth takes the kernel's three-pass path for blocks away
    from breakpoints, decimated truth its general per-interval loop: the same bits."""
    full = tr.generate(presets.aircraft_mixed(100.0), START_003, 0.01, mount=mount)
    dec = tr.generate(presets.aircraft_mixed(100.0), START_003, 0.01, mount=mount, out_every=7)
    np.testing.assert_array_equal(dec.imu.dtheta, full.imu.dtheta)
    np.testing.assert_array_equal(dec.imu.dv, full.imu.dv)
    np.testing.assert_array_equal(dec.mount, full.mount)
    sel = np.arange(0, len(full.truth), 7)
    np.testing.assert_allclose(dec.truth.t, full.truth.t[sel])
    for name in ("lat", "lon", "h", "vel", "att") + (("att_imu",) if mount else ()):
        np.testing.assert_array_equal(getattr(dec.truth, name), getattr(full.truth, name)[sel])


def test_duration_longer_than_segments_holds_last_state():
    g = tr.generate([tr.Accelerate(10.0, 1.0, ramp=1.0)], tr.Start(lat=0.3, lon=0.1), 0.01,
                    duration=20.0)
    assert len(g.imu) == 2000
    np.testing.assert_allclose(g.truth.vel[-1, 1], 9.0, atol=1e-12)
    np.testing.assert_allclose(g.truth.vel[1000:, 1], 9.0, atol=1e-12)


# --- round trip through the mechanization --------------------------------------------------
def _roundtrip_errors(g):
    from sinslab.nav import strapdown as sd
    nav = sd.navigate(g.imu, NavState.from_series(g.truth, 0), nsub=2, vertical="hold",
                      height=g.truth.h, mount=g.mount, out_every=10, progress=False)
    T = g.truth
    idx = np.searchsorted(T.t, nav.t)
    np.testing.assert_allclose(T.t[idx], nav.t)
    rm, rn = earth.radii(T.lat[idx], T.h[idx])
    pos = np.hypot((nav.lat - T.lat[idx]) * rm, (nav.lon - T.lon[idx]) * rn * np.cos(T.lat[idx]))
    vel = np.abs(nav.vel[:, :2] - T.vel[idx, :2])
    phi = at.misalignment(at.euler_to_dcm(T.att[idx]), at.euler_to_dcm(nav.att))
    return pos.max(), vel.max(), np.abs(phi).max() / u.arcsec


@pytest.mark.slow
@pytest.mark.parametrize("mount", [None, "dual_axis_16"])
def test_error_free_navigation_reproduces_truth_1h(mount):
    """The exactness bar: 1 h mixed aircraft trajectory at 100 Hz, vertical held."""
    pytest.importorskip("sinslab.nav.strapdown")
    m = indexing.dual_axis_16(rate=9 * u.deg, dwell=60.0) if mount else None
    g = tr.generate(presets.aircraft_mixed(3600.0), START_003, 0.01, mount=m)
    kinds = {s.kind for s in g.segments}
    assert {"turn", "climb", "accelerate", "wing_rock", "level"} <= kinds
    pos, vel, att = _roundtrip_errors(g)
    print(f"round trip 1 h, mount={mount}: pos {pos:.3g} m, vel {vel:.3g} m/s, att {att:.3g} arcsec")
    assert pos < 0.5 and vel < 5e-3 and att < 1.0


@pytest.mark.slow
def test_error_free_navigation_ship_and_swing_table():
    pytest.importorskip("sinslab.nav.strapdown")
    st = tr.Start(lat=30 * u.deg, lon=120 * u.deg, h=0.0, heading=30 * u.deg)
    g = tr.generate(presets.ship_manoeuvring(1800.0, static_time=60.0), st, 0.02)
    hd = at.yaw_to_heading(g.truth.att[:, 2])
    assert np.all((hd > -1e-9) & (hd < 61 * u.deg) | (hd > 359 * u.deg))
    speed = np.linalg.norm(g.truth.vel[:, :2], axis=1)
    assert speed.max() > 25.0 and speed.min() >= 0.0
    pos, vel, att = _roundtrip_errors(g)
    assert pos < 0.05 and vel < 5e-4 and att < 0.1
    g = tr.generate(presets.static(1800.0), st, 0.02, mount=indexing.Swing(amplitude=5 * u.deg, period=40.0))
    assert np.abs(g.mount[:, 0]).max() == pytest.approx(5 * u.deg, rel=1e-6)
    pos, vel, att = _roundtrip_errors(g)
    assert pos < 0.05 and vel < 5e-4 and att < 0.1


# --- configs and TOML ------------------------------------------------------------------------------
def test_from_dict_parses_units_and_aliases():
    s = tr.segment_from_dict({"kind": "turn", "duration": "60 s", "rate": "3 deg/s"}, 0)
    assert s == tr.Turn(60.0, 3 * u.deg)
    s = tr.segment_from_dict({"kind": "turn", "duration": "1 min", "angle": "90 deg", "ramp": "2 s"})
    assert s.angle == pytest.approx(90 * u.deg)
    s = tr.segment_from_dict({"kind": "decelerate", "duration": "20 s", "accel": "0.5 m/s^2"})
    assert isinstance(s, tr.Accelerate) and s.accel == -0.5
    s = tr.segment_from_dict({"kind": "descend", "duration": "20 s", "angle": "3 deg"})
    assert isinstance(s, tr.Climb) and s.angle == pytest.approx(-3 * u.deg)
    s = tr.segment_from_dict({"kind": "ship", "duration": "2 h", "roll_amplitude": "10 deg",
                              "heave_amplitude": "1 m", "speed_amplitude": "15 kn"})
    assert s.duration == 7200.0 and s.speed_amplitude == pytest.approx(15 * u.nm / 3600)
    st = tr.Start.from_dict({"lat": "32 deg", "lon": "118 deg", "h": "1 km", "speed": "300 m/s"})
    assert st.h == 1000.0 and st.lat == pytest.approx(32 * u.deg)


@pytest.mark.parametrize("d,words", [
    ({"kind": "turn", "duration": "60 s", "rate": "3 deg/s", "bank": "30 deg"}, ["segment 2", "'bank'"]),
    ({"kind": "turn", "duration": "60 s", "rate": 3.0}, ["segment 2", "'rate'", "no unit"]),
    ({"kind": "turn", "duration": "60 s", "rate": "3 m/s"}, ["segment 2", "'rate'", "angular rate"]),
    ({"kind": "static", "duration": "0 s"}, ["segment 2", "'duration'", "> 0"]),
    ({"kind": "static", "duration": "-5 s"}, ["segment 2", "'duration'"]),
    ({"kind": "accelerate", "duration": "10 s"}, ["segment 2", "missing", "'accel'"]),
    ({"kind": "accelerate", "duration": "10 s", "accel": "1 m/s^2", "ramp": "6 s"}, ["segment 2", "'ramp'"]),
    ({"kind": "turn", "duration": "60 s", "rate": "3 deg/s", "angle": "9 deg"}, ["segment 2", "'rate'", "'angle'"]),
    ({"kind": "hover", "duration": "60 s"}, ["segment 2", "'kind'", "hover"]),
    ({"kind": "wing_rock", "duration": "60 s", "amplitude": "10 deg", "period": "0 s"}, ["segment 2", "'period'"]),
    ({"kind": "turn", "duration": "60 s", "rate": "3 deg/s", "coordinated": "yes"}, ["segment 2", "'coordinated'"]),
])
def test_bad_segment_tables_name_key_and_index(d, words):
    with pytest.raises(ValueError) as ei:
        tr.segments_from_list([{"kind": "static", "duration": "1 s"}, {"kind": "level", "duration": "1 s"}, d])
    msg = str(ei.value)
    for w in words:
        assert w in msg, msg


def test_motion_consistency_errors():
    with pytest.raises(ValueError, match=r"segment 0 \(static\).*speed"):
        tr.generate([tr.Static(10.0)], START_003, 0.01)
    with pytest.raises(ValueError, match=r"segment 1 \(accelerate\).*'accel'"):
        tr.generate([tr.Static(1.0), tr.Accelerate(10.0, -1.0)], tr.Start(lat=0.1, lon=0.0), 0.01)
    with pytest.raises(ValueError, match="speed_amplitude"):
        tr.generate([tr.Ship(100.0, speed_amplitude=5.0)], tr.Start(lat=0.1, lon=0.0, speed=2.0), 0.01)
    with pytest.raises(ValueError, match="dt"):
        tr.generate(presets.static(1.0), tr.Start(lat=0.1, lon=0.0), 0.0)
    with pytest.raises(ValueError, match="latitude"):
        tr.Start(lat=2.0, lon=0.0)
    with pytest.raises(ValueError, match="'lat'"):
        tr.Start.from_dict({"lat": "32", "lon": "1 deg"})
    with pytest.raises(ValueError, match="missing key 'lon'"):
        tr.Start.from_dict({"lat": "32 deg"})
    with pytest.raises(ValueError, match="no segments"):
        tr.generate([], tr.Start(lat=0.1, lon=0.0), 0.01)
    with pytest.raises(ValueError, match="quadrature"):
        tr.generate(presets.static(1.0), tr.Start(lat=0.1, lon=0.0), 0.01, quadrature="simpson")


def test_toml_round_trip(tmp_path):
    segs = (presets.aircraft_mixed(700.0) + [tr.Ship(300.0, roll_amplitude=5 * u.deg, heave_amplitude=1.0,
                                                speed_amplitude=10.0, course_amplitude=20 * u.deg),
                                        tr.Turn(30.0, -1 * u.deg, coordinated=False)])
    mount = indexing.dual_axis_16(rate=6 * u.deg, dwell=120.0, ramp=2.0)
    p = tmp_path / "motion.toml"
    tr.dump_segments(segs, p, start=START_003, mount=mount)
    m = tr.load_motion(p)
    assert len(m.segments) == len(segs)
    for a, b in zip(segs, m.segments):
        assert type(a) is type(b)
        assert a == b           # short decimals that parse back to the same floats
    assert m.start.lat == pytest.approx(START_003.lat, rel=1e-15)
    assert m.mount.name == "dual_axis_16" and m.mount.rate == pytest.approx(6 * u.deg)
    assert tr.load_segments(p) == m.segments
    swing = indexing.Swing(axis="roll", amplitude=3 * u.deg, period=20.0, ramp=5.0)
    tr.dump_segments(presets.static(10.0), p, mount=swing)
    back = tr.load_motion(p).mount
    assert back.axis == "roll" and back.amplitude == pytest.approx(swing.amplitude)
    assert sorted(x.name for x in tmp_path.iterdir()) == ["motion.toml"]   # atomic: no temporaries left


def test_toml_dump_failure_keeps_the_old_file(tmp_path):
    """The segment dump goes through the atomic writer: a segment that cannot be written
    leaves the previous file untouched and no temporary behind."""
    p = tmp_path / "motion.toml"
    tr.dump_segments(presets.static(10.0), p)
    before = p.read_bytes()

    class Bad(tr.Static):
        def to_dict(self):
            return {"kind": "static", "duration": object()}

    with pytest.raises(TypeError):
        tr.dump_segments([Bad(5.0)], p)
    assert p.read_bytes() == before and sorted(x.name for x in tmp_path.iterdir()) == ["motion.toml"]


def test_bad_toml_files(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text("[[segment]]\nkind = 'static'\nduration = '10 s'\n[[segment]]\nkind='turn'\nduration='5 s'\n")
    with pytest.raises(ValueError, match=r"segment 1 \(turn\).*'rate'"):
        tr.load_segments(p)
    p.write_text("[start]\nlat = '1 deg'\nlon = '2 deg'\n")
    with pytest.raises(ValueError, match="no \\[\\[segment\\]\\]"):
        tr.load_segments(p)
    p.write_text("[[segment]]\nkind = 'static'\nduration = '10 s'\n[extra]\na=1\n")
    with pytest.raises(ValueError, match="unknown table 'extra'"):
        tr.load_segments(p)
    p.write_text("[[segment]\n")
    with pytest.raises(ValueError, match="not valid TOML"):
        tr.load_segments(p)


@pytest.mark.parametrize("name", sorted(p.name for p in EXAMPLES.glob("*.toml")))
def test_example_files_load_and_generate(name):
    m = tr.load_motion(EXAMPLES / name)
    assert m.start is not None
    g = tr.generate(m.segments, m.start, 0.05, duration=min(120.0, tr.total_duration(m.segments)),
                    mount=m.mount)
    assert np.all(np.isfinite(g.imu.dv))


def test_presets():
    assert tr.total_duration(presets.aircraft_mixed(3600.0)) == pytest.approx(3600.0)
    assert tr.total_duration(presets.aircraft_mixed(1200.0)) == pytest.approx(1200.0)
    assert tr.total_duration(presets.ship_manoeuvring(48 * 3600.0)) == pytest.approx(48 * 3600.0)
    assert presets.static(5.0) == [tr.Static(5.0)]
    g = tr.generate(presets.aircraft_mixed(700.0), START_003, 0.02)
    assert abs(g.truth.h[-1] - 1000.0) < 1e-6 and abs(g.truth.vel[-1, 2]) < 1e-9
    assert np.linalg.norm(g.truth.vel[-1]) == pytest.approx(300.0, rel=1e-12)
    assert at.yaw_to_heading(g.truth.att[-1, 2]) == pytest.approx(90 * u.deg, abs=1e-9)
