"""Transfer-alignment measurements: every H against central finite differences of its z
("Attitude matching method of transfer alignment based on the measured misalignment
angle", eqs 6–23), the
paper's printed Euler H against the derived one, the C22 = 0 loss of the DCM form, and
the 21-state model layout."""
import numpy as np
import pytest

from sinslab.core.attitude import euler_to_dcm, rotvec_to_dcm
from sinslab.methods import transfer as tr

DEG = np.pi / 180


def _fd(match, Cm, a0, h=1e-6):
    J = np.zeros((3, 6))
    for i in range(6):
        d = np.zeros(6)
        d[i] = h
        zp = match.predict(Cm, d[:3], a0 + d[3:])
        zm = match.predict(Cm, -d[:3], a0 - d[3:])
        J[:, i] = (zp - zm) / (2 * h)
    return J


def _rand_att(rng):
    return np.array([rng.uniform(-60, 60), rng.uniform(-170, 170), rng.uniform(-179, 179)]) * DEG


@pytest.mark.parametrize("kind", tr.KINDS)
@pytest.mark.parametrize("comp", [False, True])
@pytest.mark.parametrize("ekf", [False, True])
def test_H_matches_central_differences(kind, comp, ekf):
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(20):
        Cm = euler_to_dcm(_rand_att(rng))
        Cc = euler_to_dcm(_rand_att(rng)) if comp else None
        m = tr.AttitudeMatch(kind, Cc)
        a0 = rng.normal(0, 0.5, 3) if ekf else np.zeros(3)
        H = m.H(Cm, a0=a0)
        J = _fd(m, Cm, a0)
        worst = max(worst, np.max(np.abs(H - J)) / np.max(np.abs(J)))
    assert worst < 1e-6


@pytest.mark.parametrize("kind", tr.KINDS)
@pytest.mark.parametrize("comp", [False, True])
def test_innovation_many_equals_one_run_at_a_time(kind, comp):
    """The stacked EKF innovation (z − h(x̂) + H x̂ and H at â) of many runs is the
    per-run one; rows with â = 0 and â below the small-angle switch included."""
    rng = np.random.default_rng(3)
    Cm = euler_to_dcm(_rand_att(rng))
    m = tr.AttitudeMatch(kind, euler_to_dcm(_rand_att(rng)) if comp else None)
    R = 12
    phi = rng.normal(0, 0.02, (R, 3))
    a = rng.normal(0, 0.4, (R, 3))
    a[0] = 0.0
    a[1] = 1e-8
    C_hat = rotvec_to_dcm(-rng.normal(0, 0.02, (R, 3))) @ m.reference(Cm) @ rotvec_to_dcm(rng.normal(0, 0.4, (R, 3)))
    z, H = m.innovation_many(Cm, C_hat, phi, a)
    for j in range(R):
        z1, H1 = m.innovation_z(Cm, C_hat[j], phi[j], a[j], relinearise=True)
        np.testing.assert_allclose(z[j], z1, rtol=0, atol=1e-13)
        np.testing.assert_allclose(H[j], H1, rtol=0, atol=1e-13)


def test_z_exact_and_first_order():
    """z of the model point equals predict; kain's z = a − C_rᵀφ to first order (eq 16)."""
    rng = np.random.default_rng(1)
    Cm = euler_to_dcm(_rand_att(rng))
    phi, lam = rng.normal(0, 1e-4, 3), rng.normal(0, 1e-4, 3)
    Chat = rotvec_to_dcm(-phi) @ Cm @ rotvec_to_dcm(lam)
    m = tr.AttitudeMatch("kain")
    assert np.allclose(m.z(Cm, Chat), lam - Cm.T @ phi, atol=1e-7)
    assert np.allclose(m.z(Cm, Chat), m.predict(Cm, phi, lam), atol=1e-15)
    # the optimal form with the exact compensation sees only φ_α (eq 23)
    Cc = euler_to_dcm(np.array([10, 60, 8]) * DEG)
    pa = np.array([40, 30, 20]) / 60 * DEG
    Chat = rotvec_to_dcm(-phi) @ Cm @ Cc @ rotvec_to_dcm(pa)
    z = tr.AttitudeMatch("optimal", Cc).z(Cm, Chat)
    assert np.allclose(z, pa - (Cm @ Cc).T @ phi, atol=2e-6)


def test_paper_euler_H_rows():
    """Pitch row and the DCM form agree with the paper; the printed roll/yaw rows do not."""
    rng = np.random.default_rng(3)
    Cm = euler_to_dcm(_rand_att(rng))
    H = tr.AttitudeMatch("euler").H(Cm)
    Hp = tr.paper_euler_H(Cm)
    assert np.allclose(H[0], Hp[0], atol=1e-12)
    same = np.isclose(H, Hp, atol=1e-9)
    # roll row: all but the λy coefficient agree
    assert same[1].tolist() == [True, True, True, True, False, True]
    # yaw row: only φE agrees (φN, φU, λx, λz sign; φU factor)
    assert same[2].tolist() == [True, False, False, False, True, False]
    # eq 11 of the DCM form in closed form
    C = Cm
    Hd = tr.AttitudeMatch("dcm").H(Cm)
    ref = np.array([[0, -C[2, 1], C[1, 1], C[0, 2], 0, -C[0, 0]],
                    [-C[1, 0], C[0, 0], 0, 0, -C[2, 2], C[2, 1]],
                    [-C[1, 1], C[0, 1], 0, C[2, 2], 0, -C[2, 0]]])
    assert np.allclose(Hd, ref, atol=1e-12)


@pytest.mark.parametrize("heading", [90.0, 270.0])
def test_dcm_phiU_lost_when_C22_zero(heading):
    Cm = euler_to_dcm(np.array([0.0, 5.0, -heading]) * DEG)
    H = tr.AttitudeMatch("dcm").H(Cm)
    assert abs(Cm[1, 1]) < 1e-12
    assert np.linalg.norm(H[:, 2]) < 1e-12
    keep = [0, 1, 3, 4, 5]
    assert np.linalg.matrix_rank(H, tol=1e-9) == np.linalg.matrix_rank(H[:, keep], tol=1e-9)
    assert np.linalg.norm(tr.AttitudeMatch("kain").H(Cm)[:, 2]) > 0.9


def test_model_layout_and_velocity():
    model = tr.transfer_model()
    assert model.n == 21
    assert model.layout.names == ("phi", "dv", "lam", "eps", "kg", "nabla", "ka")
    vm = tr.VelocityMatch()
    assert np.allclose(vm.H[:, 3:6], np.eye(3)) and vm.H.sum() == 3


def test_bad_kind():
    with pytest.raises(ValueError, match="unknown attitude-matching kind"):
        tr.AttitudeMatch("quat")


def test_driver_plugins_match_the_library():
    """The measurement plug-ins (``matrices(ep)``) give the library's z and H placed in the
    21-state layout, with the master interpolated at the epoch time."""
    from types import SimpleNamespace

    rng = np.random.default_rng(5)
    att = np.array([[0.01, 0.2, 0.3], [0.02, 0.25, 0.31]])
    vel = np.array([[1.0, 2.0, 0.0], [1.2, 2.2, 0.1]])
    master = tr.MasterRecord([0.0, 0.1], att, vel)
    C_mid, v_mid = master.at(0.05)
    assert np.allclose(v_mid, vel.mean(0))
    Cc = euler_to_dcm(np.array([10, 60, 8]) * DEG)
    Chat = rotvec_to_dcm(rng.normal(0, 1e-3, 3)) @ C_mid @ Cc
    nav = SimpleNamespace(C_bn=Chat, vel=v_mid + 0.05)
    ep = SimpleNamespace(t=0.05, k=0, streams=(nav,), n=21)
    m = tr.AttitudeMatch("optimal", Cc)
    z, H, R = tr.AttitudeMeasurement(m, master, 1e-3).matrices(ep)
    assert np.allclose(z, m.z(C_mid, Chat)) and np.allclose(H[:, 0:3], m.H(C_mid)[:, :3])
    assert np.allclose(H[:, 6:9], np.eye(3)) and H.shape == (3, 21) and np.allclose(R, 1e-6)
    zv, Hv, _ = tr.VelocityMeasurement(master, 0.01).matrices(ep)
    assert np.allclose(zv, 0.05) and np.allclose(Hv[:, 3:6], np.eye(3))
    with pytest.raises(ValueError, match="outside the master record"):
        master.at(0.2)


def _stationary(lam, att_m, lat=0.6, h=50.0, dt=0.01, n=3001):
    """Error-free slave increments of a parked carrier (stationary in ENU) mounted with
    ``C_s^m = exp(λ×)``, and the master's record (attitude, zero velocity, position)."""
    from sinslab.core import earth
    from sinslab.core.records import ImuRecord
    Cmn = euler_to_dcm(att_m)
    Csn = Cmn @ rotvec_to_dcm(lam)
    w = Csn.T @ earth.wie_n(lat)
    f = Csn.T @ -earth.gravity_vector(lat, h)
    t = dt * np.arange(n)
    imu = ImuRecord(t, np.tile(w * dt, (n, 1)), np.tile(f * dt, (n, 1)), dt)
    tm = np.arange(0.0, t[-1] + 1e-9, 0.1)
    master = tr.MasterRecord(tm, np.tile(att_m, (tm.size, 1)), np.zeros((tm.size, 3)))
    return imu, master, np.tile([lat, 0.2, h], (tm.size, 1))


@pytest.mark.parametrize("kind", tr.KINDS)
def test_align_recorded_on_a_parked_carrier(kind):
    """Error-free slave IMU on a parked carrier, installation λ = (20′, −15′, 30′), sensor
    errors known to be small (tight priors). Velocity matching pins the level φ, so
    Kain's φ_m = λ − C_rᵀφ (eq 16) gives λ except along u = C_rᵀ e_U (the rotation
    about the vertical, unobservable while parked, together with φU): the components
    of λ̂ − λ across u are < 0.2′, the σ of the one along u stays near its prior, every
    axis is within 3σ; the window restricts the filter epochs."""
    lam = np.array([20.0, -15.0, 30.0]) * DEG / 60
    att_m = np.array([1.0, -2.0, 30.0]) * DEG
    imu, master, pos = _stationary(lam, att_m)
    kw = dict(att_sigma=DEG / 60, gyro_arw=1e-6, accel_vrw=1e-4, accel_bias_sigma0=1e-4,
              gyro_bias_sigma0=1e-7, gyro_scale_sigma0=1e-6, accel_scale_sigma0=1e-6)
    u = euler_to_dcm(att_m).T @ np.array([0.0, 0.0, 1.0])
    arcmin = DEG / 60
    for t0, t1, m in ((None, None, 301), (10.0, 20.0, 101)):
        r = tr.align_recorded(imu, master, pos, kind, t_start=t0, t_end=t1, **kw)
        assert r.t.size == m and r.t[0] == pytest.approx(t0 or 0.0) and r.t[-1] == pytest.approx(t1 or 30.0)
        e = r.mounting - lam
        assert np.linalg.norm(e - (e @ u) * u) < 0.2 * arcmin
        assert np.all(np.abs(e) <= 3 * r.mounting_sigma)
        assert r.mounting_sigma[2] > 0.5 * 1e-2 * abs(u[2])
    with pytest.raises(ValueError, match="fewer than 3 master epochs"):
        tr.align_recorded(imu, master, pos, kind, t_start=10.0, t_end=10.15)


def test_each_form_measures_its_parameterisation_exactly_at_a_level_north_master():
    """Level master heading north (C_m^n = I), slave exact (φ = 0): the Euler form's z is
    the installation's Euler triple and Kain's z its rotation vector, to rounding — what
    PARAMETERISATION states and installation_parameters converts to (the two differ at
    second order, ≈ 1′ at a 1° installation)."""
    C = euler_to_dcm(np.array([1.0, 1.0, 1.0]) * DEG)
    for kind in tr.KINDS:
        z = tr.AttitudeMatch(kind).z(np.eye(3), C)
        if kind == "dcm":
            continue                           # elements, not angles: scored as Euler angles too
        np.testing.assert_allclose(z, tr.installation_parameters(C, tr.PARAMETERISATION[kind]), rtol=0, atol=1e-15)
    d = tr.installation_parameters(C, "euler") - tr.installation_parameters(C, "rotvec")
    assert 0.5 < np.max(np.abs(d)) / (DEG / 60) < 2.0
    with pytest.raises(ValueError, match="parameterisation"):
        tr.installation_parameters(C, "quaternion")


@pytest.mark.parametrize("kind", tr.KINDS)
def test_z_many_with_one_master_per_run(kind):
    rng = np.random.default_rng(5)
    m = tr.AttitudeMatch(kind, euler_to_dcm(_rand_att(rng)) if kind == "optimal" else None)
    Cm = euler_to_dcm(np.stack([_rand_att(rng) for _ in range(6)]))
    Cs = rotvec_to_dcm(rng.normal(0, 0.01, (6, 3))) @ Cm @ m.compensation
    z = m.z_many(Cm, Cs)
    for j in range(6):
        np.testing.assert_allclose(z[j], m.z(Cm[j], Cs[j]), rtol=0, atol=1e-15)


def _parked_lanes(kind, lam, att_m, lanes=3, lat=0.6, h=50.0):
    """align_lanes on the parked carrier of _stationary: error-free slaves started from the
    master's attitude, transition from the 21-state model at the parked point."""
    from scipy.linalg import expm
    from sinslab.core import earth
    from sinslab.core.records import NavState
    from sinslab.nav import strapdown as sd
    from sinslab.nav.errstate import NavPoint
    from sinslab.nav.lanes import LaneBank

    imu, master, pos = _stationary(lam, att_m, lat=lat, h=h)
    Cmn = euler_to_dcm(att_m)
    Csn = Cmn @ rotvec_to_dcm(lam)
    model = tr.transfer_model()
    F = model.F(NavPoint(lat, h, np.zeros(3), Csn, Csn.T @ -earth.gravity_vector(lat, h), Csn.T @ earth.wie_n(lat)))
    K = 300
    Phi = np.broadcast_to(expm(F * 0.1), (K, 21, 21))
    s0 = sd.initial_state_array(NavState(lat, 0.2, h, np.zeros(3), att_m, 0.0))
    bank = LaneBank(np.tile(s0, (lanes, 1)), imu.dtheta[None, :K * 10], imu.dv[None, :K * 10], np.zeros(lanes, int), 0.01)
    sig0 = np.array([DEG / 60] * 3 + [0.1] * 3 + [1e-2] * 3 + [1e-7] * 3 + [1e-6] * 3 + [1e-4] * 3 + [1e-6] * 3)
    mC = np.broadcast_to(Cmn, (1, K + 1, 3, 3))
    mv = np.zeros((1, K + 1, 3))
    return tr.align_lanes(bank, 10, Phi, tr.AttitudeMatch(kind), np.diag(sig0 ** 2), np.full(3, 0.01 ** 2),
                          np.full(3, (DEG / 60) ** 2), mC, mv, np.zeros(lanes, int), C_lin=mC[0],
                          Qk=np.diag([1e-12] * 3 + [1e-8] * 3 + [0.0] * 15), record_every=10), Cmn


@pytest.mark.parametrize("kind", ["kain", "euler"])
def test_align_lanes_on_a_parked_carrier(kind):
    """The closed loop of align_lanes on the parked carrier of test_align_recorded_on_a_
    parked_carrier: the installation across the unobservable direction u = C_rᵀ e_U is
    found to < 0.3′ (the rotation about the vertical is not seen while parked), the lanes
    on the same data give the same numbers, and no lane diverges."""
    lam = np.array([20.0, -15.0, 30.0]) * DEG / 60
    att_m = np.array([1.0, -2.0, 30.0]) * DEG
    r, Cmn = _parked_lanes(kind, lam, att_m)
    u = Cmn.T @ np.array([0.0, 0.0, 1.0])
    e = r.a[0, -1] - tr.installation_parameters(rotvec_to_dcm(lam), tr.PARAMETERISATION[kind])
    assert np.linalg.norm(e - (e @ u) * u) < 0.3 * DEG / 60
    assert not r.diverged.any() and r.sigma.ndim == 2 and r.epochs[-1] == 300
    np.testing.assert_array_equal(r.a[0], r.a[2])


def _vector_joseph_gains(Phi, Hs, P0, Rd, Q=None):
    """The paper form's covariance recursion written out with numpy: the update at epoch 0,
    then per step the prediction and the update, each a vector Joseph update of the six
    rows (the textbook recursion, and this module's own before it stepped with
    estimation's kernels): gains (K+1, n, 6) and σ (K+1, n)."""
    n = P0.shape[0]
    R = np.diag(Rd)
    P, Ks, sig = P0.copy(), [], []
    for k in range(Hs.shape[0]):
        if k:
            P = Phi[k - 1] @ P @ Phi[k - 1].T + (0.0 if Q is None else Q)
        H = Hs[k]
        K = np.linalg.solve(H @ P @ H.T + R, H @ P).T
        A = np.eye(n) - K @ H
        P = A @ P @ A.T + K @ R @ K.T
        Ks.append(K)
        sig.append(np.sqrt(np.diag(P)))
    return np.array(Ks), np.array(sig)


@pytest.mark.parametrize("kind", ["kain", "euler", "dcm"])
def test_common_gains_are_the_textbook_recursion(kind):
    """The paper form's covariance recursion made once (lane_gains for the closed loop,
    batch_gains for the open loop) is one recursion, stepped with estimation's kernels
    (sequential scalar Joseph updates, gains composed): the two give the same bits; gains
    and σ equal the textbook vector Joseph recursion to rounding, and its σ that of the
    standard form P⁺ = (I − KH)P within rounding too."""
    from scipy.linalg import expm

    rng = np.random.default_rng(2)
    n, K = 21, 40
    F = rng.normal(0, 0.02, (n, n))
    Phi = np.broadcast_to(expm(F * 0.1), (K, n, n))
    Cm = euler_to_dcm(np.stack([_rand_att(rng) for _ in range(K + 1)]))
    m = tr.AttitudeMatch(kind)
    sig0 = np.array([DEG / 60] * 3 + [0.1] * 3 + [1e-2] * 3 + [1e-7] * 3 + [1e-6] * 3 + [1e-4] * 3 + [1e-6] * 3)
    P0, Rv, Ra = np.diag(sig0 ** 2), np.full(3, 0.01 ** 2), np.full(3, (DEG / 60) ** 2)
    Q = np.diag(np.r_[[1e-12] * 3, [1e-8] * 3, [0.0] * 15])
    a = tr.lane_gains(Phi, m, P0, Rv, Ra, Cm, Qk=Q, record_every=4)
    b = tr.batch_gains(Phi, Cm, m, P0, Rv, Ra, Qk=Q, record_every=4)
    for u, v in zip(a, b):
        np.testing.assert_array_equal(u, v)
    Ko, so = _vector_joseph_gains(Phi, a.H, P0, np.r_[Rv, Ra], Q)
    np.testing.assert_allclose(a.K, Ko, rtol=1e-8, atol=1e-12 * np.abs(Ko).max())
    np.testing.assert_allclose(a.sigma, so[::4], rtol=1e-8)
    # standard-form recursion, written out here
    P = P0.copy()
    for k in range(K + 1):
        if k:
            P = Phi[k - 1] @ P @ Phi[k - 1].T + Q
        H = a.H[k]
        G = P @ H.T @ np.linalg.inv(H @ P @ H.T + np.diag(np.r_[Rv, Ra]))
        P = (np.eye(n) - G @ H) @ P
        if k % 4 == 0:
            np.testing.assert_allclose(a.sigma[k // 4], np.sqrt(np.diag(P)), rtol=1e-6)


def _fed_back(one, x, phi_bound):
    """The reference loops' guard and feedback of one lane: False (the lane stops) when x
    is not finite or asks for |φ̂| > ``phi_bound``; else its INS ``one`` corrected by φ̂, δv̂,
    its sensor compensation increased and those states of ``x`` zeroed."""
    sl = tr.transfer_model().layout.slice
    if not (np.all(np.isfinite(x)) and np.linalg.norm(x[sl("phi")]) <= phi_bound):
        return False
    one.correct(x[None, sl("phi")], x[None, sl("dv")])
    one.compensate(x[None, sl("eps")], x[None, sl("nabla")], x[None, sl("kg")], x[None, sl("ka")])
    x[np.r_[np.arange(21)[sl("phi")], np.arange(21)[sl("dv")], np.arange(9, 21)]] = 0.0
    return True


def _one_lane_at_a_time(bank, k_kf, Phi, match, G, mC, mv, noise, phi_bound, record_every):
    """The paper-form closed loop of align_lanes written out lane by lane with numpy and
    the library's one-run measurement (AttitudeMatch.z, scipy rotations): the reference
    the compiled lane step must reproduce."""
    from sinslab.nav.lanes import LaneBank

    lay = tr.transfer_model().layout
    sl = lay.slice
    K = Phi.shape[0]
    a = np.full((bank.lanes, K // record_every + 1, 3), np.nan)
    for l in range(bank.lanes):
        one = LaneBank(bank.state[l:l + 1], bank.dtheta, bank.dv, bank.source[l:l + 1], bank.dt, bank.nsub)
        x = np.zeros(21)
        for k in range(K + 1):
            if k:
                one.advance(k_kf)
                x = Phi[k - 1] @ x
            z = np.r_[one.velocity()[0] - mv[l, k], match.z(mC[l, k], one.attitude()[0])] + noise[l, k]
            nu = z - G.H[k] @ x
            if match.kind == "euler":
                nu[3:] = tr.wrap_pi(nu[3:])
            x = x + G.K[k] @ nu
            if not _fed_back(one, x, phi_bound):
                break
            if k % record_every == 0:
                a[l, k // record_every] = x[sl("lam")]
    return a


def _lanes_case(kind, K=60, L=4):
    """Lanes on the parked carrier of _stationary: every lane its own sensor errors, master
    and noise; the last starts 20° off in pitch, so its first update asks for a correction
    beyond the bound and stops it. Returns the case as a dict (``bank(rows)`` makes a
    fresh bank of those lanes)."""
    from scipy.linalg import expm
    from sinslab.core import earth
    from sinslab.core.records import NavState
    from sinslab.nav import strapdown as sd
    from sinslab.nav.errstate import NavPoint
    from sinslab.nav.lanes import LaneBank

    rng = np.random.default_rng(11)
    lam = np.array([20.0, -15.0, 30.0]) * DEG / 60
    att_m = np.array([1.0, -2.0, 30.0]) * DEG
    lat, h = 0.6, 50.0
    imu, _, _ = _stationary(lam, att_m, lat=lat, h=h, n=K * 10 + 1)
    Cmn = euler_to_dcm(att_m)
    Csn = Cmn @ rotvec_to_dcm(lam)
    F = tr.transfer_model().F(NavPoint(lat, h, np.zeros(3), Csn, Csn.T @ -earth.gravity_vector(lat, h),
                                       Csn.T @ earth.wie_n(lat)))
    dth = imu.dtheta[None, :K * 10] + rng.normal(0, 1e-5, (L, 1, 3)) * 0.01
    dv = imu.dv[None, :K * 10] + rng.normal(0, 1e-3, (L, 1, 3)) * 0.01
    s0 = np.stack([sd.initial_state_array(NavState(lat, 0.2, h, np.zeros(3), att_m + [20 * DEG * (l == L - 1), 0, 0],
                                                   0.0)) for l in range(L)])
    sig0 = np.array([DEG / 60] * 3 + [0.1] * 3 + [1e-2] * 3 + [1e-5] * 3 + [1e-4] * 3 + [1e-3] * 3 + [1e-4] * 3)
    return dict(
        Phi=np.ascontiguousarray(np.broadcast_to(expm(F * 0.1), (K, 21, 21))),
        mC=rotvec_to_dcm(rng.normal(0, 3e-4, (L, 1, 3))) @ np.broadcast_to(Cmn, (L, K + 1, 3, 3)),
        mv=np.broadcast_to(rng.normal(0, 0.01, (L, 1, 3)), (L, K + 1, 3)).copy(),
        noise=rng.normal(0, 1.0, (L, K + 1, 6)) * np.r_[[0.01] * 3, [DEG / 60] * 3],
        match=tr.AttitudeMatch(kind, euler_to_dcm(att_m * 0.5) if kind == "optimal" else None),
        P0=np.diag(sig0 ** 2), Rv=np.full(3, 0.01 ** 2), Ra=np.full(3, (DEG / 60) ** 2), bound=0.2 * DEG,
        bank=lambda rows: LaneBank(s0[rows], dth[rows], dv[rows], np.arange(len(rows)), 0.01), L=L)


@pytest.mark.parametrize("kind", tr.KINDS)
def test_compiled_lane_step_equals_one_lane_at_a_time(kind):
    """The compiled closed loop of align_lanes (all lanes stepped together per epoch) gives
    each lane the installation estimates of the same filter run on that lane alone with
    numpy and scipy (to 1e-9 of their size: the compiled step forms the attitude
    measurement and the products in another order), the same lanes stop at the same epochs,
    and a lane's numbers do not depend on the lanes beside it (bit for bit)."""
    c = _lanes_case(kind)
    Phi, match, mC, mv, noise, bound, L = c["Phi"], c["match"], c["mC"], c["mv"], c["noise"], c["bound"], c["L"]
    G = tr.lane_gains(Phi, match, c["P0"], c["Rv"], c["Ra"], mC[0])

    def lanes(rows):
        return tr.align_lanes(c["bank"](rows), 10, Phi, match, c["P0"], c["Rv"], c["Ra"], mC[rows], mv[rows],
                              np.arange(len(rows)), meas_noise=noise[rows], phi_bound=bound, record_every=5, gains=G)

    rows = np.arange(L)
    r = lanes(rows)
    ref = _one_lane_at_a_time(c["bank"](rows), 10, Phi, match, G, mC, mv, noise, bound, 5)
    assert r.diverged.tolist() == [False, False, False, True]
    np.testing.assert_array_equal(np.isnan(r.a), np.isnan(ref))
    ok = ~np.isnan(ref)
    np.testing.assert_allclose(r.a[ok], ref[ok], rtol=0, atol=1e-9 * np.abs(ref[ok]).max())
    for l in range(L):
        one = lanes(rows[l:l + 1])
        np.testing.assert_array_equal(one.a[0], r.a[l])
        np.testing.assert_array_equal(one.attitude[0], r.attitude[l])


def _ekf_one_lane_at_a_time(c, record_every):
    """The EKF form of align_lanes written out lane by lane with the textbook numpy core
    (kalman.predict, kalman.update) and the one-run measurement (innovation_z): installation
    estimates and σ (L, M, 3), NaN once a lane stopped."""
    from sinslab.estimation import kalman as kf
    from sinslab.nav.lanes import LaneBank

    lay = tr.transfer_model().layout
    sl = lay.slice
    Phi, match, L = c["Phi"], c["match"], c["L"]
    K = Phi.shape[0]
    a = np.full((L, K // record_every + 1, 3), np.nan)
    sa = np.full(a.shape, np.nan)
    bank = c["bank"](np.arange(L))
    for l in range(L):
        one = LaneBank(bank.state[l:l + 1], bank.dtheta[l:l + 1], bank.dv[l:l + 1], np.zeros(1, int), bank.dt)
        x, P = np.zeros(21), c["P0"].copy()
        for k in range(K + 1):
            if k:
                one.advance(10)
                x, P = kf.predict(x, P, Phi[k - 1], np.zeros((21, 21)))
            za, h6 = match.innovation_z(c["mC"][l, k], one.attitude()[0], x[sl("phi")], x[sl("lam")],
                                        relinearise=True)
            z = np.r_[one.velocity()[0] - c["mv"][l, k], za] + c["noise"][l, k]
            H = np.zeros((6, 21))
            H[np.arange(3), np.arange(21)[sl("dv")]] = 1.0
            H[3:, sl("phi")], H[3:, sl("lam")] = h6[:, :3], h6[:, 3:]
            res = kf.update(x, P, z, H, np.diag(np.r_[c["Rv"], c["Ra"]]))
            x, P = res.x.copy(), res.P
            if not _fed_back(one, x, c["bound"]):
                break
            if k % record_every == 0:
                a[l, k // record_every] = x[sl("lam")]
                sa[l, k // record_every] = np.sqrt(np.diag(P))[sl("lam")]
    return a, sa


@pytest.mark.parametrize("kind", ["euler", "kain"])
def test_ekf_lanes_equal_the_textbook_filter_one_lane_at_a_time(kind):
    """The EKF form of align_lanes (a covariance per lane, stepped with estimation's lane
    kernels) gives each lane the installation estimates and σ of the textbook EKF (numpy
    kalman.predict/update, one-run measurement) run on that lane alone, to 1e-9 of their
    size; the same lanes stop, a stopped lane's σ turns NaN from the next epoch, and a
    lane's numbers do not depend on the lanes beside it (bit for bit)."""
    c = _lanes_case(kind, K=30)
    L = c["L"]

    def lanes(rows):
        return tr.align_lanes(c["bank"](rows), 10, c["Phi"], c["match"], c["P0"], c["Rv"], c["Ra"], c["mC"][rows],
                              c["mv"][rows], np.arange(len(rows)), meas_noise=c["noise"][rows], phi_bound=c["bound"],
                              record_every=5, relinearise=True)

    r = lanes(np.arange(L))
    a, sa = _ekf_one_lane_at_a_time(c, 5)
    assert r.diverged.tolist() == [False, False, False, True] and r.sigma.shape == (L, 7, 21)
    np.testing.assert_array_equal(np.isnan(r.a), np.isnan(a))
    ok = ~np.isnan(a)
    np.testing.assert_allclose(r.a[ok], a[ok], rtol=0, atol=1e-9 * np.abs(a[ok]).max())
    np.testing.assert_allclose(r.sigma[:3, :, 6:9], sa[:3], rtol=1e-9)
    d = r.diverged_at[3]
    assert np.isfinite(r.sigma[3, r.epochs <= d]).all() and np.isnan(r.sigma[3, r.epochs > d]).all()
    for l in range(L):
        one = lanes(np.array([l]))
        np.testing.assert_array_equal(one.a[0], r.a[l])
        np.testing.assert_array_equal(one.sigma[0], r.sigma[l])


@pytest.mark.parametrize("kind", ["euler", "kain"])
def test_compiled_open_loop_equals_the_numpy_recursion(kind):
    """The paper-form batch_filter (compiled, run by run) against the recursion written
    with numpy over the stacked runs: the same estimates to 1e-12 of their size, and a
    run's numbers independent of the runs stacked with it (bit for bit)."""
    from scipy.linalg import expm

    rng = np.random.default_rng(4)
    n, K, R = 21, 50, 5
    Phi = np.ascontiguousarray(np.broadcast_to(expm(rng.normal(0, 0.02, (n, n)) * 0.1), (K, n, n)))
    Cm = euler_to_dcm(np.stack([_rand_att(rng) for _ in range(K + 1)]))
    m = tr.AttitudeMatch(kind)
    Cs = rotvec_to_dcm(rng.normal(0, 0.01, (R, K + 1, 3))) @ Cm[None]
    zv = rng.normal(0, 0.05, (R, K + 1, 3))
    sig0 = np.array([DEG / 60] * 3 + [0.1] * 3 + [1e-2] * 3 + [1e-7] * 3 + [1e-6] * 3 + [1e-4] * 3 + [1e-6] * 3)
    args = (np.zeros(n), np.diag(sig0 ** 2), np.full(3, 0.01 ** 2), np.full(3, (DEG / 60) ** 2))
    xs, _ = tr.batch_filter(Phi, Cm, zv, Cs, m, *args, record_every=3)
    G = tr.batch_gains(Phi, Cm, m, args[1], args[2], args[3])
    zz = np.concatenate([zv, m.z_many(Cm, Cs)], axis=2)
    x = np.zeros((R, n))
    for k in range(K + 1):
        nu = zz[:, k] - x @ G.H[k].T
        if kind == "euler":
            nu[:, 3:] = tr.wrap_pi(nu[:, 3:])
        x = x + nu @ G.K[k].T
        if k % 3 == 0:
            np.testing.assert_allclose(xs[:, k // 3], x, rtol=0, atol=1e-12 * np.abs(x).max())
        if k < K:
            x = x @ Phi[k].T
    for r in range(R):
        one, _ = tr.batch_filter(Phi, Cm, zv[r:r + 1], Cs[r:r + 1], m, *args, record_every=3)
        np.testing.assert_array_equal(one[0], xs[r])


@pytest.mark.parametrize("kind", ["dcm", "optimal"])
def test_ekf_open_loop_equals_the_textbook_filter_run_by_run(kind):
    """The EKF form of batch_filter (a covariance per run, stepped with estimation's lane
    kernels) against the textbook EKF (numpy kalman.predict/update, the one-run
    innovation_z) run by run: estimates and σ to 1e-9 of their size; a run's numbers do not
    depend on the runs stacked with it (bit for bit)."""
    from scipy.linalg import expm
    from sinslab.estimation import kalman as kf

    rng = np.random.default_rng(6)
    n, K, R = 21, 30, 3
    Phi = np.ascontiguousarray(np.broadcast_to(expm(rng.normal(0, 0.02, (n, n)) * 0.1), (K, n, n)))
    Cm = euler_to_dcm(np.stack([_rand_att(rng) for _ in range(K + 1)]))
    m = tr.AttitudeMatch(kind, euler_to_dcm(_rand_att(rng) * 0.1) if kind == "optimal" else None)
    Cs = rotvec_to_dcm(rng.normal(0, 0.01, (R, K + 1, 3))) @ Cm[None] @ m.compensation
    zv = rng.normal(0, 0.05, (R, K + 1, 3))
    sig0 = np.array([DEG / 60] * 3 + [0.1] * 3 + [1e-2] * 3 + [1e-7] * 3 + [1e-6] * 3 + [1e-4] * 3 + [1e-6] * 3)
    Q = np.diag(np.r_[[1e-12] * 3, [1e-8] * 3, [0.0] * 15])
    args = (np.zeros(n), np.diag(sig0 ** 2), np.full(3, 0.01 ** 2), np.full(3, (DEG / 60) ** 2))
    xs, sig = tr.batch_filter(Phi, Cm, zv, Cs, m, *args, Qk=Q, relinearise=True, record_every=3)
    Rm = np.diag(np.r_[args[2], args[3]])
    for r in range(R):
        x, P = np.zeros(n), args[1].copy()
        for k in range(K + 1):
            za, h6 = m.innovation_z(Cm[k], Cs[r, k], x[:3], x[6:9], relinearise=True)
            H = np.zeros((6, n))
            H[np.arange(3), np.arange(3, 6)] = 1.0
            H[3:, :3], H[3:, 6:9] = h6[:, :3], h6[:, 3:]
            res = kf.update(x, P, np.r_[zv[r, k], za], H, Rm)
            x, P = res.x, res.P
            if k % 3 == 0:
                np.testing.assert_allclose(xs[r, k // 3], x, rtol=0, atol=1e-9 * np.abs(x).max())
                np.testing.assert_allclose(sig[r, k // 3], np.sqrt(np.diag(P)), rtol=1e-9)
            if k < K:
                x, P = kf.predict(x, P, Phi[k], Q)
        one, s1 = tr.batch_filter(Phi, Cm, zv[r:r + 1], Cs[r:r + 1], m, *args, Qk=Q, relinearise=True, record_every=3)
        np.testing.assert_array_equal(one[0], xs[r])
        np.testing.assert_array_equal(s1[0], sig[r])


@pytest.mark.parametrize("kind", tr.KINDS)
def test_H_many_is_H_of_each_attitude(kind):
    """The paper-form H of stacked master attitudes equals H of each one (the same formulas;
    numpy's scalar square may round an Euler-form denominator one ulp apart)."""
    rng = np.random.default_rng(8)
    C = euler_to_dcm(np.stack([_rand_att(rng) for _ in range(50)]))
    m = tr.AttitudeMatch(kind, euler_to_dcm(_rand_att(rng)) if kind == "optimal" else None)
    np.testing.assert_allclose(m.H_many(C), np.stack([m.H(c) for c in C]), rtol=4e-16, atol=1e-15)
