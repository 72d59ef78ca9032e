"""Paper 000 (stationary alignment): derivations, limits vs filter, coarse alignment."""
import math
import warnings

import numpy as np
import support
import pytest

from sinslab.methods import alignment as al
from sinslab.nav import errstate as es
from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.estimation import kalman, linear
from sinslab.core import units as u
from sinslab.sim.imu import ImuErrors, apply
from sinslab.core.records import ImuRecord

LATS = [34.246, -45.0, 0.0, 60.0, -88.5, 5.0]


def static_imu(lat, att, duration, dt=0.01, h=0.0):
    """Exact increments of an IMU at rest for ``duration`` [s], and its C_b^n."""
    return support.static_imu(lat, att, dt, int(round(duration / dt)), h), A.euler_to_dcm(att)


def att_of(pitch, roll, heading):
    return np.array([math.radians(pitch), math.radians(roll),
                     float(A.heading_to_yaw(math.radians(heading)))])


# ------------------------------------------------------------------ model derivations
@pytest.mark.parametrize("lat_deg", LATS)
def test_reduction_intertwines_models(lat_deg):
    """Eqs 21-24: T F = F' T and H = H' T, so X' = T X is a closed observable system."""
    lat = math.radians(lat_deg)
    g = float(E.gravity(lat))
    F, G, H = al.full_model(lat, g)
    Fr, Gr, Hr = al.reduced_model(lat, g)
    T = al.reduction_matrix(lat, g)
    assert np.allclose(T @ F, Fr @ T, atol=1e-14, rtol=0)
    assert np.allclose(H, Hr @ T, atol=1e-12)
    assert np.allclose(T @ G, Gr)
    # observability: full rank 5 of 8, reduced 5 of 5; null(O_full) == null(T)
    O = np.vstack([H @ np.linalg.matrix_power(F, k) for k in range(8)])
    Or = np.vstack([Hr @ np.linalg.matrix_power(Fr, k) for k in range(5)])
    scale = np.r_[[1.0] * 3, [1 / E.WIE] * 3, [1 / g] * 2]      # make columns comparable
    assert np.linalg.matrix_rank(O * scale, tol=1e-10 * np.abs(O * scale).max()) == 5
    assert np.linalg.matrix_rank(Or) == 5
    from scipy.linalg import null_space
    N = null_space(T)
    assert N.shape[1] == 3
    assert np.abs(O @ N).max() <= 1e-12 * np.abs(O).max()
    # the unobservable directions (one per pair of the paper): T n = 0 and F n = 0, so
    # the limits are constant in time
    wN, wU = E.WIE * math.cos(lat), E.WIE * math.sin(lat)
    n_nabN = np.array([-1 / g, 0, 0, 0, wU / g, -wN / g, 0, 1])
    n_nabE = np.array([0, 1 / g, math.tan(lat) / g, 0, 0, 0, 1, 0])
    n_epsE = np.array([0, 0, -1 / wN, 1, 0, 0, 0, 0])
    for nv in (n_nabN, n_nabE, n_epsE):
        assert np.abs(T @ nv).max() < 1e-12 * np.abs(nv).max()
        assert np.abs(F @ nv).max() < 1e-15
        assert np.abs(H @ nv).max() < 1e-15


def test_full_model_matches_nonlinear_attitude_error():
    """F's φ rows: finite difference of the exact misalignment of a propagated attitude."""
    lat = math.radians(-30.0)
    att = att_of(3.0, -4.0, 100.0)
    imu0, C = static_imu(lat, att, 1200.0, dt=0.1)
    eps_b = np.array([0.3, -0.2, 0.5]) * u.dph
    imu = ImuRecord(imu0.t, imu0.dtheta + eps_b * imu0.dt, imu0.dv, imu0.dt)
    phi0 = np.array([2.0, -3.0, 5.0]) * u.arcmin
    q = A.euler_to_quat(A.dcm_to_euler(A.apply_misalignment(C, phi0)))
    qo = np.empty((2, 4))
    fo = np.empty((2, 3))
    al._propagate(q.copy(), imu.dtheta, imu.dv, imu.dt, E.wie_n(lat), 0, 6000, 2, qo, fo)
    phis = A.misalignment(C, A.quat_to_dcm(qo))
    g = float(E.gravity(lat))
    F, _, H = al.full_model(lat, g)
    x0 = np.r_[phi0, C @ eps_b, 0.0, 0.0]
    from scipy.linalg import expm
    for k, tk in enumerate((600.0, 1200.0)):
        pred = expm(F * tk) @ x0
        # Earth-rate coupling moves φ by ~5 % of its size here; sign errors would show
        assert np.allclose(phis[k], pred[:3], atol=3e-3 * np.abs(pred[:3]).max()), (phis[k], pred)
        wrong = expm(F.T * tk) @ x0                     # e.g. ω×φ instead of φ×ω
        assert not np.allclose(phis[k], wrong[:3], atol=3e-3 * np.abs(pred[:3]).max())
    # measurement: mean specific force in the computed frame = H x (first order)
    nab_b = np.array([50.0, -80.0, 30.0]) * u.ug
    x = np.r_[phi0, 0, 0, 0, (C @ nab_b)[:2]]
    fn = A.apply_misalignment(C, phi0) @ (C.T @ np.array([0, 0, g]) + nab_b)
    assert np.allclose(fn[:2], H @ x, atol=1e-3 * g * np.abs(phi0).max())


def test_reduced_filter_equals_projected_full_filter():
    """Reduced filter (P0' = T P0 Tᵀ) on the same data == T × full filter, every step."""
    lat = math.radians(-23.0)
    g = float(E.gravity(lat))
    F, G, H = al.full_model(lat, g)
    Fr, Gr, Hr = al.reduced_model(lat, g)
    T = al.reduction_matrix(lat, g)
    Qc = np.diag([1e-12, 2e-12, 3e-12])
    Phi, Qk = kalman.discretize(F, Qc, 1.0, G=G)
    Phir, Qkr = kalman.discretize(Fr, Qc, 1.0, G=Gr)
    assert np.allclose(T @ Phi, Phir @ T, atol=1e-15)
    assert np.allclose(T @ Qk @ T.T, Qkr, rtol=1e-9, atol=1e-30)
    sig = np.r_[[1e-2] * 3, [5e-8] * 3, [1e-3] * 2]
    P0 = np.diag(sig ** 2)
    rng = np.random.default_rng(3)
    z = rng.standard_normal((300, 2)) * 1e-4 + np.array([0.01, -0.02])
    R = np.diag([1e-8, 2e-8])
    rf = linear.run_linear(np.zeros(8), P0, Phi, Qk, H, R, z, save_at=[-1])
    rr = linear.run_linear(np.zeros(5), T @ P0 @ T.T, Phir, Qkr, Hr, R, z, save_at=[-1])
    scale = np.r_[[1.0] * 3, [1e-6] * 2]
    assert np.allclose((rf.x @ T.T) / scale, rr.x / scale, atol=1e-9)
    assert np.allclose(T @ rf.P_saved[-1] @ T.T, rr.P_saved[-1], rtol=1e-6, atol=1e-24)


# ----------------------------------------------------------------- limit formulas
def test_limit_signs_match_coarse_alignment_errors():
    """Sign convention: the analytic coarse alignment with biases errs by exactly the
    limits (φ of sinslab.core.attitude.misalignment, i.e. C' = (I − φ×) C, the paper's eq 3)."""
    for lat_deg, head in [(34.246, 235.0), (-40.0, 10.0), (70.0, 300.0), (-5.0, 90.0)]:
        lat = math.radians(lat_deg)
        att = att_of(-5.0, 2.0, head)
        imu0, C = static_imu(lat, att, 10.0)
        eb = np.array([0.02, -0.01, 0.015]) * u.dph
        ab = np.array([100.0, -60.0, 40.0]) * u.ug
        imu = ImuRecord(imu0.t, imu0.dtheta + eb * imu0.dt, imu0.dv + ab * imu0.dt, imu0.dt)
        co = al.coarse_align(imu, lat, gyro_bias=eb, accel_bias=ab)
        phi = A.misalignment(C, co.C_bn)
        lim = al.limit_accuracy(lat, att, eb, ab)
        assert np.allclose(phi, lim[:3], rtol=5e-3, atol=1e-3 * u.arcmin), (lat_deg, head)
        assert np.allclose(co.phi_bias, lim[:3], rtol=5e-3, atol=1e-3 * u.arcmin)


def test_limit_formula_values():
    lat = math.radians(30.0)
    g = 9.8
    eps = np.array([0.01, 0.02, 0.03]) * u.dph
    nab = np.array([100.0, 200.0, 0.0]) * u.ug
    L = al.limit_accuracy(lat, None, eps, nab, g=g, frame="nav")
    wN, wU = E.WIE * math.cos(lat), E.WIE * math.sin(lat)
    exp = [-nab[1] / g, nab[0] / g, -eps[0] / wN + math.tan(lat) * nab[0] / g,
           nab[1] * wU / g, -nab[1] * wN / g]
    assert np.allclose(L, exp, rtol=1e-12)
    # residual = X_sub − T X for any X: the limits are exactly what T leaves unobservable
    T = al.reduction_matrix(lat, g)
    X = np.r_[[1e-3, 2e-3, 3e-3], eps, nab[:2]]
    assert np.allclose(X[al._FULL_SUB] - T @ X, L, rtol=1e-12, atol=1e-20)


def test_pole_and_bad_latitude():
    with pytest.raises(ValueError, match="pole"):
        al.limit_accuracy(math.radians(89.5), np.zeros(3), 0.0, 0.0)
    with pytest.raises(ValueError, match="pole"):
        al.check_alignment_latitude(math.radians(-89.2))
    imu, _ = static_imu(math.radians(60), att_of(0, 0, 0), 5.0)
    for fn in (al.coarse_align, al.coarse_align_inertial):
        with pytest.raises(ValueError, match="pole"):
            fn(imu, math.radians(89.01))
    with pytest.raises(ValueError, match="pole"):
        al.fine_align(imu, math.radians(-89.9), np.zeros(3))
    al.check_alignment_latitude(math.radians(88.9))        # 1.1 deg from the pole: fine


CASES = [  # lat, pitch, roll, heading, gyro bias (deg/h), accel bias (ug)
    (34.246, -5.0, 2.0, 235.0, [0.01, 0.01, 0.01], [100, 100, 100]),
    (-33.9, 1.0, -3.0, 20.0, [0.02, -0.01, 0.005], [-150, 50, 80]),
    (60.0, 4.0, 1.0, 300.0, [-0.01, 0.02, 0.0], [60, -120, 0]),
    (-65.0, -2.0, 6.0, 135.0, [0.005, 0.005, -0.02], [0, 200, -50]),
    (3.0, 0.0, 0.0, 90.0, [0.03, 0.0, 0.01], [-80, -80, 100]),
]


@pytest.mark.parametrize("lat_deg,pitch,roll,head,eb,ab", CASES)
def test_filters_reach_limit_noise_free(lat_deg, pitch, roll, head, eb, ab):
    """Both filters, on exact IMU data with biases only (nonlinear attitude propagation,
    feedback), end at the limits: φE, φN within 0.003′, every state within 2σ of the
    filter (+ a small floor) — φU, εN, εU converge slowly."""
    lat = math.radians(lat_deg)
    att = att_of(pitch, roll, head)
    imu0, C = static_imu(lat, att, 900.0, dt=0.1)
    eb = np.array(eb) * u.dph
    ab = np.array(ab) * u.ug
    imu = ImuRecord(imu0.t, imu0.dtheta + eb * imu0.dt, imu0.dv + ab * imu0.dt, imu0.dt)
    att0 = A.dcm_to_euler(A.apply_misalignment(C, np.array([10.0, -10.0, 60.0]) * u.arcmin))
    lim = al.limit_accuracy(lat, att, eb, ab)
    sc = np.r_[[u.arcmin] * 3, [u.dph] * 2]
    for model in ("reduced", "full"):
        fa = al.fine_align(imu, lat, att0, model=model, gyro_arw=1e-4 * u.dpsh,
                           accel_vrw=1.0 * u.ugpsHz, feedback=True, p0_gyro_bias=0.05 * u.dph,
                           p0_accel_bias=1.0 * u.ug if model == "full" else 100 * u.ug)
        d = (al.residuals(fa, C, C @ eb)[-1] - lim) / sc
        sig = (fa.sigma[-1][al._FULL_SUB] if model == "full" else fa.sigma[-1]) / sc
        assert abs(d[0]) < 0.003 and abs(d[1]) < 0.003, (model, d)
        assert np.all(np.abs(d) <= 2 * sig + [0.003, 0.003, 0.01, 1e-4, 1e-4]), (model, d, sig)


def test_full_filter_limit_depends_on_prior():
    """Noise-free linear system: the full filter converges to full_filter_limit (prior
    split of the unobservable part), the reduced one to the paper's limits."""
    lat = math.radians(45.0)
    g = 9.806
    F, G, H = al.full_model(lat, g)
    Fr, Gr, Hr = al.reduced_model(lat, g)
    x0 = np.r_[np.array([10.0, 10.0, 60.0]) * u.arcmin, np.array([0.01, -0.008, 0.005]) * u.dph,
               np.array([100.0, -60.0]) * u.ug]
    Phi = kalman.discretize(F, np.zeros((8, 8)), 1.0)[0]
    Phir = kalman.discretize(Fr, np.zeros((5, 5)), 1.0)[0]
    K = 3000
    xs = np.empty((K + 1, 8))
    xs[0] = x0
    for k in range(K):
        xs[k + 1] = Phi @ xs[k]
    z = xs[1:] @ H.T
    R = np.eye(2) * (0.1 * u.ug) ** 2
    for s_nab in (100 * u.ug, 1000 * u.ug):
        sig = np.r_[np.array([100.0, 100.0, 600.0]) * u.arcmin, [0.01 * u.dph] * 3, [s_nab] * 2]
        P0 = np.diag(sig ** 2)
        run = linear.run_linear(np.zeros(8), P0, Phi, np.zeros((8, 8)), H, R, z)
        resid = xs[-1] - run.x[-1]
        expect = al.full_filter_limit(lat, g, x0, P0)
        sc = np.r_[[u.arcmin] * 3, [u.dph] * 3, [u.ug] * 2]
        assert np.allclose(resid / sc, expect / sc, atol=[0.01] * 3 + [1e-4] * 3 + [2.0] * 2)
    sigr = np.r_[np.array([100.0, 100.0, 600.0]) * u.arcmin, [0.01 * u.dph] * 2]
    run = linear.run_linear(np.zeros(5), np.diag(sigr ** 2), Phir, np.zeros((5, 5)), Hr, R, z)
    resid = xs[-1][al._FULL_SUB] - run.x[-1]
    lim = al.limit_accuracy(lat, None, x0[3:6], np.r_[x0[6:8], 0.0], g=g, frame="nav")
    sc = np.r_[[u.arcmin] * 3, [u.dph] * 2]
    assert np.allclose(resid / sc, lim / sc, atol=[0.002, 0.002, 0.01, 1e-5, 5e-4])


# ------------------------------------------------------------------ coarse alignment
def test_coarse_exact_on_error_free_data_and_noise_sigma():
    for lat_deg, head in [(34.246, 235.0), (-50.0, 359.0), (0.5, 45.0)]:
        lat = math.radians(lat_deg)
        att = att_of(-5.0, 2.0, head)
        imu, C = static_imu(lat, att, 60.0)
        co = al.coarse_align(imu, lat)
        assert np.abs(A.misalignment(C, co.C_bn)).max() < 1e-9
        assert abs(co.heading - math.radians(head)) < 1e-8
    # noise: the predicted σ matches the scatter over seeds
    lat = math.radians(34.246)
    att = att_of(-5.0, 2.0, 235.0)
    imu, C = static_imu(lat, att, 100.0, dt=0.02)
    err = ImuErrors.from_datasheet(gyro_arw="0.05 deg/sqrt(h)", accel_vrw="50 ug/sqrt(Hz)")
    phis, sig = [], None
    for s in range(40):
        co = al.coarse_align(apply(imu, err, seed=s), lat, gyro_arw=err.gyro_arw,
                             accel_vrw=err.accel_vrw)
        phis.append(A.misalignment(C, co.C_bn))
        sig = co.phi_sigma
    ratio = np.std(phis, axis=0) / sig
    assert np.all((ratio > 0.6) & (ratio < 1.5)), ratio


def test_coarse_inertial_static_and_sway():
    lat = math.radians(-34.0)
    att = att_of(1.0, -2.0, 160.0)
    imu, C = static_imu(lat, att, 120.0)
    ci = al.coarse_align_inertial(imu, lat)
    assert np.abs(A.misalignment(C, ci.C_bn)).max() < 1e-7
    # swaying base: exact increments of a body rotating about a fixed point
    dt, N = 0.01, 30000
    t = dt * np.arange(N + 1)
    amp = np.radians([3.0, 5.0, 2.0])
    per = np.array([7.0, 9.0, 11.0])
    att_t = att[None, :] + amp * np.sin(2 * np.pi * t[:, None] / per)
    Cbn = A.euler_to_dcm(att_t)
    u_ax = np.array([0.0, math.cos(lat), math.sin(lat)])
    Cni = A.rotvec_to_dcm(E.WIE * t[:, None] * u_ax)          # C_n^{i0}(t)
    Cbi = Cni @ Cbn
    dth = A.dcm_to_rotvec(np.swapaxes(Cbi[:-1], 1, 2) @ Cbi[1:])
    g = float(E.gravity(lat))
    # f^b = C_n^b [0,0,g] (rotation about a point at the IMU: no lever arm), midpoint rule
    fb = np.einsum("kji,j->ki", Cbn, np.array([0.0, 0.0, g]))
    dv = 0.5 * (fb[:-1] + fb[1:]) * dt
    rec = ImuRecord(t[1:], dth, dv, dt)
    ci = al.coarse_align_inertial(rec, lat)
    err = A.misalignment(Cbn[-1], ci.C_bn)
    assert np.abs(err[:2]).max() < 0.5 * u.arcmin and abs(err[2]) < 5 * u.arcmin, err / u.arcmin
    # the analytic method fails on the same record (sway averages to the mean attitude)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        co = al.coarse_align(rec, lat)
    assert np.abs(A.misalignment(Cbn[-1], co.C_bn)).max() > 30 * u.arcmin
    assert not co.rest.at_rest and co.warnings


def test_not_at_rest_warning_in_fine_alignment():
    lat = math.radians(34.0)
    imu, C = static_imu(lat, att_of(0, 0, 30), 60.0)
    rng = np.random.default_rng(0)
    dv = imu.dv + np.repeat(rng.standard_normal((60, 3)) * 0.2, 100, axis=0) * imu.dt
    bad = ImuRecord(imu.t, imu.dtheta, dv, imu.dt)
    with pytest.warns(al.NotAtRestWarning, match="not at rest"):
        fa = al.fine_align(bad, lat, A.dcm_to_euler(C), gyro_arw=1e-4 * u.dpsh,
                           accel_vrw=10 * u.ugpsHz)
    assert fa.warnings and "not at rest" in fa.warnings[0]
    fa = al.fine_align(imu, lat, A.dcm_to_euler(C), gyro_arw=1e-4 * u.dpsh,
                       accel_vrw=10 * u.ugpsHz)
    assert fa.rest.at_rest and not fa.warnings


@pytest.mark.parametrize("lat_deg", [-60.0, 0.0, 34.246, 80.0])
def test_full_model_is_the_general_error_model_at_rest(lat_deg):
    """Paper 000: φ̇ = φ×ω_ie − ε (ε, ∇ in n), f_E = −gφN + ∇E, f_N = gφE + ∇N.

    F is the general model's φ/bias rows at rest with n-frame bias blocks; H is the
    finite-difference derivative of the horizontal specific force in the computed frame."""
    lat = np.radians(lat_deg)
    F8, G8, H8 = al.full_model(lat)
    nav = es.NavPoint.static(lat, [-5 * np.pi / 180, 2 * np.pi / 180, -235 * np.pi / 180])
    gen = es.ErrorModel("attvel", [es.gyro_bias(frame="nav"), es.accel_bias("xy", frame="nav")],
                        gyro_arw=1.0)
    F = gen.F(nav)
    idx = gen.layout.index(["phiE", "phiN", "phiU", "eps_E", "eps_N", "eps_U", "nabla_E", "nabla_N"])
    np.testing.assert_allclose(F8, F[np.ix_(idx, idx)], atol=1e-20)
    # velocity rows of the general model: δv̇ = f^n×φ + ∇ -> the measurement of paper 000
    vel = gen.layout.index(["dvE", "dvN"])
    np.testing.assert_allclose(H8, F[np.ix_(vel, idx)], rtol=1e-12, atol=1e-15)
    # H by finite differences of the computed-frame specific force
    g = float(E.gravity(lat))
    fn = np.array([0.0, 0.0, g])
    def z(x):
        Cc = A.rotvec_to_dcm(-x[:3])            # C_n^{n'} = exp(-φ×)
        return (Cc @ fn)[:2] + x[6:8]
    J = np.array([(z(e) - z(-e)) / 2e-6 for e in np.eye(8) * 1e-6]).T
    np.testing.assert_allclose(H8, J, rtol=1e-8, atol=1e-9)
    assert np.allclose(G8[:3], -np.eye(3)) and np.all(G8[3:] == 0)
