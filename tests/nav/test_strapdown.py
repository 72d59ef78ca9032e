"""Tests of sinslab.nav.strapdown against exact (closed-form) motions."""
from fractions import Fraction

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from sinslab.core import attitude, earth
from support import static_imu
from sinslab.core.records import ImuRecord, NavState
from sinslab.nav import strapdown as sd

ARCSEC = np.pi / 180 / 3600
LAT = np.radians(34.246)
GL_X, GL_W = np.polynomial.legendre.leggauss(5)


def increments(rate, t0, dt, n):
    """Exact increments ∫rate dt over n samples by 5-point Gauss-Legendre per sample.

    ``rate(t)`` maps times (m,) to (m, 3). Returns end times and (n, 3) increments."""
    starts = t0 + dt * np.arange(n)
    tt = (starts[:, None] + 0.5 * dt * (GL_X + 1.0)[None, :]).ravel()
    r = rate(tt).reshape(n, GL_X.size, 3)
    return starts + dt, 0.5 * dt * np.einsum("j,njk->nk", GL_W, r)


def att_err(att_true, att_nav):
    """Misalignment angle magnitude(s) [rad] between two Euler attitudes."""
    phi = attitude.misalignment(attitude.euler_to_dcm(att_true), attitude.euler_to_dcm(att_nav))
    return np.linalg.norm(phi, axis=-1)


# --- coefficients -------------------------------------------------------------------------
def _sin_series(k, x_pow):
    """Fraction coefficient of x^x_pow in sin(k x)."""
    if x_pow % 2 == 0:
        return Fraction(0)
    m = (x_pow - 1) // 2
    f = Fraction(1)
    for i in range(1, x_pow + 1):
        f /= i
    return (-1) ** m * Fraction(k) ** x_pow * f


def _derive_coeffs(n):
    """Coning coefficients of (Σ_{i<N} c_i θ_i) × θ_N for classic coning, exact fractions.

    For coning ω = aΩ[cos Ωt, sin Ωt, 0], sub-interval h, x = Ωh, one finds
    (θ_i × θ_N)_z = a² · 2(1 − cos x) · sin((N − i) x), and the exact coning term over
    T = N h is a²/2 · (N x − sin N x). Matching the series in x through x^(2N−1+2)
    determines the N − 1 coefficients (a linear system solved with fractions)."""
    def two_one_minus_cos_times_sin(k, p):       # coeff of x^p in 2(1-cos x) sin(kx)
        tot = Fraction(0)
        for a in range(2, p + 1, 2):             # 2(1-cos x) = Σ_{a even>=2} 2(-1)^(a/2+1) x^a/a!
            ca = Fraction(2 * (-1) ** (a // 2 + 1))
            for i in range(1, a + 1):
                ca /= i
            tot += ca * _sin_series(k, p - a)
        return tot

    rhs_c = lambda p: -Fraction(1, 2) * _sin_series(n, p) + (Fraction(n, 2) if p == 1 else 0)
    m = n - 1
    pows = [3 + 2 * j for j in range(m)]
    A = [[two_one_minus_cos_times_sin(n - i, p) for i in range(1, n)] for p in pows]
    b = [rhs_c(p) for p in pows]
    # Gaussian elimination in fractions
    for col in range(m):
        piv = next(r for r in range(col, m) if A[r][col] != 0)
        A[col], A[piv] = A[piv], A[col]
        b[col], b[piv] = b[piv], b[col]
        for r in range(m):
            if r != col and A[r][col] != 0:
                f = A[r][col] / A[col][col]
                A[r] = [x - f * y for x, y in zip(A[r], A[col])]
                b[r] -= f * b[col]
    return [b[i] / A[i][i] for i in range(m)]


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_coning_coefficients_derived(n):
    c = _derive_coeffs(n)
    assert np.allclose(sd.CONING_COEFFS[n - 1, :n - 1], [float(x) for x in c], rtol=1e-14, atol=0)


def _quadratic_rate_mismatch(n):
    """For ω(t) = ω0 + αt + βt², the second-order rotation-vector term ½∫θ×ω over T = n·h
    is ω0×α T³/12 + ω0×β T⁴/12 + α×β T⁵/60. With θ_i = ω0 h + α h² a_i + β h³ b_i,
    a_i = (2i−1)/2, b_i = (3i²−3i+1)/3, the algorithm's Σ c_i θ_i×θ_N gives
    ω0×α h³ Σc_i(a_N−a_i) + ω0×β h⁴ Σc_i(b_N−b_i) + ...; returns the two coefficient
    mismatches (algorithm − exact), exact fractions."""
    c = _derive_coeffs(n)
    a = [Fraction(2 * i - 1, 2) for i in range(1, n + 1)]
    b = [Fraction(3 * i * i - 3 * i + 1, 3) for i in range(1, n + 1)]
    lin = sum(ci * (a[-1] - ai) for ci, ai in zip(c, a)) - Fraction(n ** 3, 12)
    quad = sum(ci * (b[-1] - bi) for ci, bi in zip(c, b)) - Fraction(n ** 4, 12)
    return lin, quad


def test_coning_coefficients_under_angular_acceleration():
    """The coning-optimised coefficients are exact for a linearly varying rate at every N,
    and for a quadratically varying one only at N = 2: N = 3, 4, 5 leave ω0×β h⁴ times
    27/20, 204/35, 2075/126 — why nsub ≥ 3 is less accurate than nsub = 2 through
    manoeuvre onsets (test_manoeuvre_error_ratio_follows_quadratic_rate_term)."""
    got = {n: _quadratic_rate_mismatch(n) for n in (2, 3, 4, 5)}
    assert all(lin == 0 for lin, _ in got.values())
    assert [q for _, q in got.values()] == [0, Fraction(27, 20), Fraction(204, 35),
                                             Fraction(2075, 126)]


def test_manoeuvre_error_ratio_follows_quadratic_rate_term():
    """Roll-in of a coordinated turn (quintic rate profile): the attitude error made with
    nsub = 4 and 5 relative to nsub = 3 is the ratio of the quadratic-rate mismatches per
    unit time, (m_N/N)/(m_3/3) = 3.24 and 7.32 (the error per update ∝ m_N h⁴, updates per
    second ∝ 1/(N h)); nsub = 2, which has no such term, is ≥ 10× better than nsub = 3."""
    from sinslab.sim import trajectory as tr
    st = tr.Start(lat=np.radians(32.0), lon=np.radians(118.0), h=1000.0, speed=300.0,
                  heading=0.0)
    g = tr.generate([tr.Turn(12.0, np.radians(1.5), ramp=5.0)], st, 0.01, duration=3.5)
    k = int(np.searchsorted(g.truth.t, 3.0))            # mid roll-in
    err = {}
    for nsub in (2, 3, 4, 5):
        nav = sd.navigate(g.imu, NavState.from_series(g.truth, 0), nsub=nsub, vertical="hold",
                          height=g.truth.h, progress=False)
        j = int(np.searchsorted(nav.t, g.truth.t[k]))
        err[nsub] = np.linalg.norm(attitude.misalignment(attitude.euler_to_dcm(g.truth.att[k]),
                                                         attitude.euler_to_dcm(nav.att[j])))
    per_time = {n: float(_quadratic_rate_mismatch(n)[1]) / n for n in (3, 4, 5)}
    assert err[4] / err[3] == pytest.approx(per_time[4] / per_time[3], rel=0.1)
    assert err[5] / err[3] == pytest.approx(per_time[5] / per_time[3], rel=0.1)
    assert err[2] < 0.1 * err[3]


def test_one_plus_previous_coefficient():
    # (θ_{k-1} × θ_k)_z = a² 2(1-cos x) sin x ≈ a² x³ ; exact a²/2 (x - sin x) ≈ a² x³/12
    assert sd.CONING_COEFFS[0, 0] == pytest.approx(1 / 12)


# --- static, constant velocity ----------------------------------------------------------
@pytest.mark.parametrize("nsub", [1, 2, 3, 4, 5])
def test_static_error_free_stays_put(nsub):
    att = np.radians([1.0, -2.0, 123.0])
    imu = static_imu(LAT, att, 0.01, 360_000)
    nav = sd.navigate(imu, NavState(LAT, 1.9, 50.0, np.zeros(3), att), nsub=nsub,
                      vertical="hold", height=50.0, out_every=100, progress=False)
    assert nav.t[-1] == pytest.approx(3600.0)
    assert np.abs(nav.vel).max() < 1e-6
    assert att_err(att, nav.att[-1]) < 1e-3 * ARCSEC
    assert abs(nav.lat[-1] - LAT) * 6.4e6 < 1e-3 and abs(nav.lon[-1] - 1.9) * 5e6 < 1e-3


def test_static_free_vertical_short():
    imu = static_imu(LAT, np.zeros(3), 0.01, 60_000)
    nav = sd.navigate(imu, NavState(LAT, 0.0, 0.0, np.zeros(3), np.zeros(3)), progress=False)
    assert abs(nav.h[-1]) < 1e-4 and abs(nav.vel[-1, 2]) < 1e-6


def test_constant_velocity_along_meridian():
    """Level, heading north, vN constant, constant height: exact increments from the ODE."""
    vN, h, dt, dur = 250.0, 3000.0, 0.01, 1200.0
    sol = solve_ivp(lambda t, y: [vN / earth.radii(y[0], h)[0]], (0, dur + 1), [LAT],
                    method="DOP853", rtol=1e-13, atol=1e-16, dense_output=True)
    lat_t = lambda t: sol.sol(t)[0]

    def gyro(t):
        lat = lat_t(t)
        rm, _ = earth.radii(lat, h)
        return np.stack([-vN / rm, earth.WIE * np.cos(lat), earth.WIE * np.sin(lat)], -1)

    def accel(t):
        lat = lat_t(t)
        rm, _ = earth.radii(lat, h)
        return np.stack([-2 * earth.WIE * np.sin(lat) * vN, 0 * lat,
                         earth.gravity(lat, h) - vN ** 2 / rm], -1)

    n = int(round(dur / dt))
    t, dth = increments(gyro, 0.0, dt, n)
    _, dvl = increments(accel, 0.0, dt, n)
    imu = ImuRecord(t, dth, dvl, dt)
    init = NavState(LAT, 0.5, h, [0.0, vN, 0.0], np.zeros(3))
    for nsub in (1, 2, 5):
        nav = sd.navigate(imu, init, nsub=nsub, vertical="free", out_every=50, progress=False)
        rm, _ = earth.radii(lat_t(nav.t[-1]), h)
        assert abs(nav.lat[-1] - lat_t(nav.t[-1])) * rm < 2e-3, nsub
        assert abs(nav.lon[-1] - 0.5) * 5e6 < 2e-3
        assert abs(nav.h[-1] - h) < 2e-3
        assert np.abs(nav.vel[-1] - [0, vN, 0]).max() < 2e-5
        assert att_err(np.zeros(3), nav.att[-1]) < 0.01 * ARCSEC


# --- coning -----------------------------------------------------------------------------
def _cone_q(t, a, Om):
    s = np.sin(a / 2)
    return np.stack([np.full_like(t, np.cos(a / 2)), s * np.cos(Om * t), s * np.sin(Om * t),
                     np.zeros_like(t)], -1)


def coning_imu(a, Om, dt, n, C0, lat=LAT):
    """IMU at rest on Earth undergoing classic coning: C_b^n(t) = C0 · C(q_c(t)),
    q_c = [cos(a/2), sin(a/2) cos Ωt, sin(a/2) sin Ωt, 0] (closed form)."""
    s = np.sin(a / 2)
    g = float(earth.gravity(lat, 0.0))

    def cbn(t):
        return C0 @ attitude.quat_to_dcm(_cone_q(t, a, Om))

    def gyro(t):
        q = _cone_q(t, a, Om)
        qd = np.stack([0 * t, -s * Om * np.sin(Om * t), s * Om * np.cos(Om * t), 0 * t], -1)
        w_nb = 2 * attitude.quat_mul(attitude.quat_conj(q), qd)[:, 1:]
        return w_nb + np.einsum("nji,j->ni", cbn(t), earth.wie_n(lat))

    def accel(t):
        return np.einsum("nji,j->ni", cbn(t), np.array([0.0, 0.0, g]))

    tt, dth = increments(gyro, 0.0, dt, n)
    _, dvl = increments(accel, 0.0, dt, n)
    return ImuRecord(tt, dth, dvl, dt), cbn


def coning_residual(n, x):
    """Coning-algorithm error per update divided by a² for classic coning, x = Ω·dt.

    Exact coning term ½(N x − sin N x) minus the algorithm's Σ c_i 2(1 − cos x) sin((N − i)x)
    (the N = 1 algorithm uses the previous sample: c·2(1 − cos x) sin x)."""
    c = sd.CONING_COEFFS[n - 1]
    if n == 1:
        alg = c[0] * 2 * (1 - np.cos(x)) * np.sin(x)
    else:
        alg = sum(c[i - 1] * 2 * (1 - np.cos(x)) * np.sin((n - i) * x) for i in range(1, n))
    return 0.5 * (n * x - np.sin(n * x)) - alg


@pytest.mark.parametrize("a_deg,f_hz,dt,dur", [(1.0, 2.0, 0.01, 60.0), (2.0, 5.0, 0.004, 60.0)])
def test_coning_closed_form_all_nsub(a_deg, f_hz, dt, dur):
    """Attitude after classic coning vs its closed form; the residual drift equals the
    algorithm's known truncation error (uncompensated it would be ~ Ω(1 − cos a)·t)."""
    a, Om = np.radians(a_deg), 2 * np.pi * f_hz
    n = int(round(dur / dt))
    C0 = attitude.euler_to_dcm(np.radians([3.0, -4.0, 40.0]))
    imu, cbn = coning_imu(a, Om, dt, n, C0)
    att0 = attitude.dcm_to_euler(cbn(np.array([0.0]))[0])
    init = NavState(LAT, 0.0, 0.0, np.zeros(3), att0)
    errs, preds = [], []
    for nsub in (1, 2, 3, 4, 5):
        nav = sd.navigate(imu, init, nsub=nsub, vertical="hold", height=0.0, out_every=60,
                          progress=False)
        phi = attitude.misalignment(cbn(nav.t[-1:])[0], attitude.euler_to_dcm(nav.att[-1]))
        pred = np.sin(a) ** 2 * abs(coning_residual(nsub, Om * dt)) * (nav.t[-1] / (nsub * dt))
        err = np.linalg.norm(phi)
        errs.append(err)
        preds.append(pred)
        if pred > 1e-8:       # the algorithm's own truncation error dominates
            assert abs(err - pred) < 0.06 * pred, (nsub, err, pred)
        else:                 # higher-order (non-Bortz-2nd-order) floor, < 0.04 arcsec
            assert err < 2e-7, (nsub, err, pred)
        # the residual is a drift about the cone axis (C0 z)
        if pred > 1e-7:
            assert abs(phi @ C0[:, 2]) > 0.99 * err
        assert np.abs(nav.vel).max() < 2e-3 * (f_hz / 2) ** 2, nsub         # sculling
    assert errs[4] < 0.02 * errs[1]
    if f_hz == 2.0:
        assert max(errs) < 0.25 * ARCSEC


# --- mount --------------------------------------------------------------------------------
def test_mount_round_trip():
    """Carrier at rest; IMU rotating about its z axis at 6 deg/s on a turntable."""
    att_c = np.radians([2.0, 1.0, -30.0])
    Cc = attitude.euler_to_dcm(att_c)
    Om, dt, n = np.radians(6.0), 0.01, 60_000
    g = float(earth.gravity(LAT, 0.0))

    def cbn(t):
        return Cc @ attitude.euler_to_dcm(np.stack([0 * t, 0 * t, Om * t], -1))

    gyro = lambda t: np.einsum("nji,j->ni", cbn(t), earth.wie_n(LAT)) + np.array([0, 0, Om])
    accel = lambda t: np.einsum("nji,j->ni", cbn(t), np.array([0.0, 0.0, g]))
    tt, dth = increments(gyro, 0.0, dt, n)
    _, dvl = increments(accel, 0.0, dt, n)
    imu = ImuRecord(tt, dth, dvl, dt)
    t_ep = np.concatenate([[0.0], tt])
    mount = np.stack([0 * t_ep, 0 * t_ep, Om * t_ep], -1)
    init = NavState(LAT, 0.0, 0.0, np.zeros(3), attitude.dcm_to_euler(cbn(np.array([0.0]))[0]))
    nav = sd.navigate(imu, init, nsub=2, vertical="hold", height=0.0, mount=mount,
                      out_every=100, progress=False)
    assert nav.att_imu is not None
    assert att_err(att_c, nav.att).max() < 0.01 * ARCSEC
    assert att_err(attitude.dcm_to_euler(cbn(nav.t)), nav.att_imu).max() < 0.01 * ARCSEC
    assert np.abs(nav.vel).max() < 1e-6
    nav0 = sd.navigate(imu, init, nsub=2, vertical="hold", height=0.0, out_every=100, progress=False)
    assert nav0.att_imu is None
    assert np.allclose(nav0.att, nav.att_imu, atol=1e-12)


# --- steppable API -------------------------------------------------------------------------
def test_correct_round_trip():
    init = NavState(LAT, 2.0, 100.0, [10.0, -5.0, 1.0], np.radians([5.0, -3.0, 70.0]))
    s = sd.initial_state_array(init)
    phi = np.radians([0.2, -0.3, 1.5])
    dvel = np.array([0.5, -0.2, 0.1])
    dpos = np.array([1e-6, -2e-6, 15.0])
    # perturbed (computed) state: C' = exp(-φ×) C, v' = v + δv, pos' = pos + δpos
    sp = s.copy()
    sp[:10] = sd.with_errors(s[:10], phi, dvel, dpos)
    C = attitude.quat_to_dcm(s[:4])
    assert np.allclose(attitude.misalignment(C, attitude.quat_to_dcm(sp[:4])), phi, atol=1e-14)
    assert np.allclose(sp[:4], attitude.dcm_to_quat(attitude.apply_misalignment(C, phi)), atol=1e-15)
    assert np.array_equal(sp[4:10], s[4:10] + np.r_[dvel, dpos])
    np.testing.assert_allclose(sd.correct_rows(sp[:10], phi, dvel, dpos), s[:10], rtol=0, atol=1e-12)
    sd.correct(sp, phi, dvel, dpos)
    q = sp[:4] * np.sign(sp[0])
    assert np.allclose(q, s[:4], atol=1e-14)
    assert np.allclose(sp[4:10], s[4:10], rtol=0, atol=1e-12)
    nav = sd.state_to_navstate(sp, 3.0)
    assert np.allclose(nav.att, init.att, atol=1e-13) and nav.t == 3.0


def test_correct_is_the_compiled_correct_rows():
    """The in-place feedback correction of one state and the row form agree to rounding,
    on rows and on a horizontal (2-component) velocity and position error."""
    rng = np.random.default_rng(3)
    rows = np.empty((5, 10))
    rows[:, :4] = attitude.euler_to_quat(rng.uniform(-1, 1, (5, 3)))
    rows[:, 4:7] = rng.normal(0, 10, (5, 3))
    rows[:, 7:10] = np.c_[rng.uniform(-1, 1, 5), rng.uniform(-3, 3, 5), rng.normal(0, 100, 5)]
    phi, dv, dp = rng.normal(0, 1e-3, (5, 3)), rng.normal(0, 1e-1, (5, 2)), rng.normal(0, 1e-6, (5, 2))
    got = sd.correct_rows(rows, phi, dv, dp)
    assert np.array_equal(got[:, [6, 9]], rows[:, [6, 9]])          # the vertical left alone
    for i in range(5):
        st = rows[i].copy()
        sd.correct(st, phi[i], dv[i], dp[i])
        np.testing.assert_allclose(got[i], st, rtol=0, atol=1e-14)
    np.testing.assert_allclose(sd.with_errors(got, phi, dv, dp), rows, rtol=0, atol=1e-12)


def test_step_chunks_equal_navigate():
    a, Om, dt, n = np.radians(1.0), 2 * np.pi, 0.01, 3000
    C0 = attitude.euler_to_dcm(np.radians([3.0, -4.0, 40.0]))
    imu, cbn = coning_imu(a, Om, dt, n, C0)
    init = NavState(LAT, 0.3, 20.0, [3.0, 4.0, 0.0], attitude.dcm_to_euler(C0))
    for nsub in (1, 3):
        nav = sd.navigate(imu, init, nsub=nsub, progress=False)
        s = sd.initial_state_array(init)
        outs, lo = [], 0
        while lo < n:
            m = 7 * nsub * 30 + 1                    # ragged chunks; leftovers carried over
            dth, dvl = imu.dtheta[lo:lo + m], imu.dv[lo:lo + m]
            out = np.empty((dth.shape[0] // nsub, sd.NAV))
            k = sd.step(s, dth, dvl, dt, nsub, out=out)
            outs.append(out[:k])
            lo += k * nsub
            if k == 0:
                break
        rows = np.concatenate(outs)
        assert rows.shape[0] == len(nav) - 1
        assert np.array_equal(rows[:, 4:7], nav.vel[1:])
        assert np.array_equal(rows[:, 7], nav.lat[1:])
    # a length-10 state works too and zero correction changes nothing
    s10 = sd.initial_state_array(init)[:sd.NAV].copy()
    sd.step(s10, imu.dtheta[:100], imu.dv[:100], dt, 2)
    s_full = sd.initial_state_array(init)
    sd.step(s_full, imu.dtheta[:100], imu.dv[:100], dt, 2)
    assert np.allclose(s10, s_full[:sd.NAV], rtol=0, atol=1e-12)
    before = s_full.copy()
    sd.correct(s_full, np.zeros(3), np.zeros(3), np.zeros(3))
    assert np.allclose(before[:sd.NAV], s_full[:sd.NAV], atol=1e-15)


def test_bias_compensation_cancels_bias():
    att = np.radians([1.0, 2.0, 30.0])
    imu = static_imu(LAT, att, 0.05, 20_000)
    gb, ab = np.radians([0.01, -0.02, 0.03]) / 3600, np.array([1e-3, -2e-3, 5e-4])
    biased = ImuRecord(imu.t, imu.dtheta + gb * imu.dt, imu.dv + ab * imu.dt, imu.dt)
    init = NavState(LAT, 0.0, 0.0, np.zeros(3), att)
    nav = sd.navigate(biased, init, vertical="hold", height=0.0, gyro_bias=gb, accel_bias=ab,
                      out_every=100, progress=False)
    assert np.abs(nav.vel).max() < 1e-6
    raw = sd.navigate(biased, init, vertical="hold", height=0.0, out_every=100, progress=False)
    assert np.abs(raw.vel).max() > 0.1


def test_vertical_damped_and_hold():
    att = np.zeros(3)
    imu = static_imu(LAT, att, 0.05, 72_000, h=100.0)          # 1 h at 100 m
    bad = ImuRecord(imu.t, imu.dtheta, imu.dv + np.array([0, 0, 1e-3]) * imu.dt, imu.dt)
    init = NavState(LAT, 0.0, 100.0, np.zeros(3), att)
    free = sd.navigate(bad, init, out_every=200, progress=False)
    assert abs(free.h[-1] - 100.0) > 1000.0                    # unstable free channel
    for damping in (None, {"order": 2, "tau": 50.0}, sd.VerticalDamping(k=(0.03, 3e-4, 1e-6))):
        d = sd.navigate(bad, init, vertical="damped", height=100.0, damping=damping,
                        out_every=200, progress=False)
        assert np.abs(d.h - 100.0).max() < 5.0, damping
        # steady state: second order keeps δh = b/(k2 − 2ω_s²) and v_U = k1·δh
        k1, k2, k3 = sd.VerticalDamping.coerce(damping).gains(LAT, 100.0)
        if k3 == 0:
            dh = 1e-3 / (k2 - 2 * earth.schuler_frequency(LAT, 100.0) ** 2)
            assert d.h[-1] - 100.0 == pytest.approx(dh, rel=0.02)
            assert d.vel[-1, 2] == pytest.approx(k1 * dh, rel=0.02)
        else:
            assert abs(d.vel[-1, 2]) < 0.01
    # third order removes the steady-state offset of a vertical accel bias
    d3 = sd.navigate(bad, init, vertical="damped", height=100.0, out_every=200, progress=False)
    assert abs(d3.h[-1] - 100.0) < 0.01
    hh = 100.0 + 2.0 * np.sin(np.arange(len(bad) + 1) * 0.05 / 60)
    hold = sd.navigate(bad, init, vertical="hold", height=hh, out_every=200, progress=False)
    assert np.allclose(hold.h, hh[::400], atol=1e-12)
    assert np.allclose(hold.vel[1:, 2], (2.0 / 60 * np.cos(hold.t / 60))[1:], atol=1e-6)


def test_held_vertical_rate_given_once_or_computed_per_slice():
    """A held channel given its vertical rate (``vup``) navigates to the bytes of one that
    differentiates the height itself; a shared :class:`HeldHeight` returns for each slice
    exactly ``held_vup`` of that slice (cos-shaped height: 2nd-order differences ≈ the
    derivative), computed once; a rate for a channel that is not held is refused."""
    att = np.zeros(3)
    imu = static_imu(LAT, att, 0.05, 6000, h=100.0)
    init = NavState(LAT, 0.0, 100.0, np.zeros(3), att)
    hh = 100.0 + 2.0 * np.sin(np.arange(len(imu) + 1) * 0.05 / 60)
    a = sd.navigate(imu, init, vertical="hold", height=hh, out_every=20, progress=False)
    b = sd.navigate(imu, init, vertical="hold", height=hh, vup=sd.held_vup(hh, imu.dt), out_every=20,
                    progress=False)
    assert np.array_equal(a.h, b.h) and np.array_equal(a.vel, b.vel) and np.array_equal(a.lat, b.lat)
    held = sd.HeldHeight(hh, 0.05)
    h1, v1 = held.slice(100, 400)
    assert np.array_equal(h1, hh[100:401]) and np.array_equal(v1, sd.held_vup(hh[100:401], 0.05))
    assert held.slice(100, 400)[1] is v1                          # computed once
    t = np.arange(100, 401) * 0.05
    assert np.allclose(v1, 2.0 / 60 * np.cos(t / 60), atol=1e-8)
    with pytest.raises(ValueError, match="only used with vertical='hold'"):
        sd.navigate(imu, init, vertical="damped", height=hh, vup=b.vel[:, 2], progress=False)
    with pytest.raises(ValueError, match="NaN"):
        sd.HeldHeight(np.r_[hh[:-1], np.nan], 0.05)


def test_gains():
    k1, k2, k3 = sd.VerticalDamping(order=3, tau=100.0).gains(LAT)
    ws2 = earth.schuler_frequency(LAT) ** 2
    roots = np.roots([1, k1, k2 - 2 * ws2, k3])
    assert np.allclose(roots, -0.01, atol=1e-4)


# --- bad input ----------------------------------------------------------------------------
def test_bad_input():
    imu = static_imu(LAT, np.zeros(3), 0.1, 10)
    init = NavState(LAT, 0.0, 0.0, np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="nsub"):
        sd.navigate(imu, init, nsub=6)
    with pytest.raises(ValueError, match="nsub"):
        sd.navigate(imu, init, nsub=0)
    with pytest.raises(ValueError, match="fewer than nsub"):
        sd.navigate(ImuRecord(imu.t[:2], imu.dtheta[:2], imu.dv[:2]), init, nsub=3)
    with pytest.raises(ValueError, match="height series must have 11 epochs"):
        sd.navigate(imu, init, vertical="hold", height=np.zeros(10))
    with pytest.raises(ValueError, match="needs a height"):
        sd.navigate(imu, init, vertical="damped")
    with pytest.raises(ValueError, match="vertical must be"):
        sd.navigate(imu, init, vertical="baro")
    with pytest.raises(ValueError, match="mount"):
        sd.navigate(imu, init, mount=np.zeros((10, 3)))
    with pytest.raises(ValueError, match="latitude"):
        s = sd.initial_state_array(init)
        s[7] = 2.0
        sd.step(s, imu.dtheta, imu.dv, 0.1)
    with pytest.raises(ValueError, match="latitude"):
        NavState(np.radians(91.0), 0.0, 0.0, np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="pole"):
        sd.navigate(imu, NavState(np.pi / 2, 0.0, 0.0, np.zeros(3), np.zeros(3)))
    with pytest.raises(ValueError, match="non-finite"):
        huge = ImuRecord(imu.t, imu.dtheta, imu.dv + 1e307, imu.dt)
        sd.navigate(huge, init, progress=False)
    with pytest.raises(ValueError, match="shape"):
        sd.step(sd.initial_state_array(init), imu.dtheta[:, :2], imu.dv, 0.1)
    with pytest.raises(ValueError, match="gyro_bias"):
        sd.navigate(imu, init, gyro_bias=[1.0, 2.0])
    with pytest.raises(ValueError, match="damping order"):
        sd.navigate(imu, init, vertical="damped", height=0.0, damping={"order": 4})
    with pytest.raises(ValueError, match="NaN"):
        ImuRecord(imu.t, np.where(np.arange(10)[:, None] == 3, np.nan, imu.dtheta), imu.dv)


def test_truncates_trailing_samples_and_out_grid():
    imu = static_imu(LAT, np.zeros(3), 0.1, 23)
    init = NavState(LAT, 0.0, 0.0, np.zeros(3), np.zeros(3), t=0.0)
    nav = sd.navigate(imu, init, nsub=3, out_every=2, progress=False, chunk=6)
    # 7 updates of 3 samples; outputs after updates 2, 4, 6 -> epochs t0, 0.6, 1.2, 1.8
    assert np.allclose(nav.t, [0.0, 0.6, 1.2, 1.8])
    calls = []
    sd.navigate(imu, init, nsub=3, progress=lambda d, t: calls.append((d, t)), chunk=6)
    assert calls[-1] == (21, 21)


def test_sine_and_cosine_near_a_known_angle_agree_with_libm():
    """The mid-interval Earth model takes sin, cos of the latitude from those of the
    update's start (a Taylor series to d³ for |d| < 1e-5 rad): equal to math.sin/cos to
    rounding on both sides of the switch, and math.sin/cos themselves beyond it."""
    import math

    rng = np.random.default_rng(11)
    for a in rng.uniform(-1.5, 1.5, 40):
        for d in (*rng.uniform(-1e-5, 1e-5, 5), 2e-5, -3e-3):
            s, c = sd._sincos_near(a + d, a, math.sin(a), math.cos(a))
            assert abs(s - math.sin(a + d)) <= 3e-16 and abs(c - math.cos(a + d)) <= 3e-16
