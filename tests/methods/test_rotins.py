"""Oracles for sinslab.methods.rotins (Wang, Wu et al. 2018: joint rotation-modulated INS,
online evaluation).

- windowed_std (eq 21): against a direct per-window numpy evaluation, and against the
  closed form of a linear ramp (N samples spaced dt: slope·dt·sqrt((N²−1)/12), → the
  continuous slope·window/√12);
- schedule observability: the stops of the sim.indexing schedules (single-axis 4-position
  for INS 1, dual-axis 16-step for INS k) found by sampling both mounts; rank 5 per stop
  (paper eq 14), 13 stacked in time order (eq 15), SOM = TOM (Goshen-Meskin), and the
  one-axis flip schedules of INS k with their unobservable direction.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from sinslab.core import units as u
from sinslab.core.attitude import euler_to_dcm
from sinslab.methods import rotins
from sinslab.sim import indexing as ix
from support import assert_doc_quotes

LAT = math.radians(28.222)


#: one cycle of the dual-axis schedule (16 × (300 s dwell + 21 s move))
CYCLE = 16 * (300.0 + 21.0)


def test_windowed_std_matches_direct_evaluation():
    rng = np.random.default_rng(7)
    t = 10.0 + 0.5 * np.arange(2001)                      # 10 … 1010 s
    x = np.cumsum(rng.standard_normal((t.size, 2)), axis=0)
    start, window = 100.0, 150.0
    te, s = rotins.windowed_std(t, x, start, window)
    J = int((t[-1] - start) // window)
    assert te.size == J == 6
    for j in range(J):
        a, b = start + j * window, start + (j + 1) * window
        seg = x[(t >= a) & (t < b)]
        np.testing.assert_allclose(s[j], np.std(seg, axis=0), rtol=1e-13)
        assert te[j] == b
    _, s1 = rotins.windowed_std(t, x[:, 0], start, window)
    np.testing.assert_allclose(s1, s[:, 0], rtol=1e-13)


def test_windowed_std_start_before_the_record_skips_the_partial_window():
    t = np.arange(101.0)
    te, s = rotins.windowed_std(t, t, -50.0, 60.0)
    assert te.tolist() == [70.0]                           # [10, 70): 60 samples of a unit ramp
    np.testing.assert_allclose(s, np.sqrt((60 ** 2 - 1) / 12), rtol=1e-12)


def test_windowed_std_linear_ramp_closed_form():
    """Ramp x = a t: std over N samples spaced dt is a·dt·sqrt((N²−1)/12) → a·window/√12."""
    dt, a = 1.0, 3e-9
    t = np.arange(0.0, 144 * 3600.0 + dt, dt)
    start, window = 16 * 3600.0, 4 * 3600.0
    te, s = rotins.windowed_std(t, a * t, start, window)
    N = window / dt
    assert te.size == 32
    np.testing.assert_allclose(s, a * dt * np.sqrt((N ** 2 - 1) / 12), rtol=1e-9)
    np.testing.assert_allclose(s, a * window / np.sqrt(12), rtol=1e-7)


@pytest.mark.parametrize("start, window, msg", [
    (0.0, 0.0, "window must be > 0"), (0.0, -1.0, "window must be > 0"),
    (100.0, 10.0, "start 100.0 s is not before"), (120.0, 10.0, "not before"),
    (50.0, 60.0, "longer than the 50.0 s"), (-100.0, 101.0, "longer than"),
    (-50.0, 90.0, "no full 90.0 s window"),
])
def test_windowed_std_bad_input(start, window, msg):
    t = np.arange(101.0)
    with pytest.raises(ValueError, match=msg):
        rotins.windowed_std(t, t, start, window)


@pytest.fixture(scope="module")
def model():
    return rotins.joint_rotation_model()


def test_paper_schedules_rank_5_per_stop_13_stacked(model):
    C1, Ck, T = ix.common_stops(ix.single_axis_4pos(), ix.dual_axis_16(), CYCLE)
    assert C1.shape[0] >= 16
    res = {m: rotins.schedule_observability(model, C1, Ck, LAT, durations=T, method=m) for m in ("som", "tom")}
    r = res["som"]
    assert r.n == 13 and r.labels[5] == "eps_z_1"
    assert r.rank_static == 5 and set(r.segment_ranks) == {5}
    assert r.ranks[-1] == 13 and r.observable
    assert all(b >= a for a, b in zip(r.ranks, r.ranks[1:]))
    assert r.ranks[:6] == [5, 8, 11, 11, 11, 13]            # computed: full rank at the 6th stop
    assert res["tom"].ranks == r.ranks
    assert np.all(r.degree > 0)
    # the index state with physical scales (1', 0.001 °/h, 20 µg) is observable too
    sc = np.r_[[u.arcmin] * 3, [0.001 * u.dph] * 6, [20 * u.ug] * 4]
    rs = rotins.schedule_observability(model, C1, Ck, LAT, scale=sc)
    assert rs.ranks[-1] == 13 and rs.degree[5] > 0
    # docs/methods/001.md's table of the schedules and its row of degrees with physical scales
    doc = "docs/methods/001.md"
    assert_doc_quotes(doc, "| `dual_axis_16` (paper) | 5 (all 27) | 5, 8, 11, 11, 11, 13 | **13** | — |",
                      [16, r.rank_static, len(r.segment_ranks), *r.ranks[:6], r.ranks[-1]])
    assert_doc_quotes(doc, "one 5136 s dual-axis cycle has 27 common stops", [CYCLE, C1.shape[0]])
    assert_doc_quotes(doc, "Computed (one dual-axis cycle, 27 stops;", [C1.shape[0]])
    assert_doc_quotes(doc, "Rank 5 per static stop (eq 14) and 13 for the schedule reproduce",
                      [r.rank_static, 14, r.ranks[-1]])
    assert_doc_quotes(doc, "full rank is reached at the 6th common stop (ranks 5, 8, 11, 11, 11, 13)",
                      [r.ranks.index(13) + 1, *r.ranks[:6]])
    assert_doc_quotes(doc, "| physical | 0.37 | 0.29 | 0.45 | 0.18 | 0.19 | 0.070 | 0.21 | 0.15 | 0.18 | 0.020 | 0.020 | "
                      "0.020 | 0.020 |", rs.degree)


def test_one_stop_alone_rank_5(model):
    for att1, attk in (([0, 0, 0], [0, 0, 0]), ([0, 0, math.pi / 2], [0, math.pi, math.pi])):
        r = rotins.schedule_observability(model, euler_to_dcm(np.array([att1], float)),
                                          euler_to_dcm(np.array([attk], float)), LAT)
        assert r.rank_static == 5 and r.ranks == [5]


def test_ins_k_flipping_about_azimuth_only_leaves_rank_12(model):
    """Both azimuth gyros stay on the up axis: ε_z1 = ε_zk is the unobservable direction."""
    mk = ix.RotateStop((("yaw", math.pi), ("yaw", -math.pi)))
    C1, Ck, T = ix.common_stops(ix.single_axis_4pos(), mk, CYCLE)
    r = rotins.schedule_observability(model, C1, Ck, LAT)
    assert r.ranks[-1] == 12 and set(r.segment_ranks) == {5}
    N = r.result.null_space[:, 0]
    N = N / N[r.labels.index("eps_z_1")]
    e = np.zeros(13)
    e[[r.labels.index("eps_z_1"), r.labels.index("eps_z_k")]] = 1.0
    np.testing.assert_allclose(N, e, atol=1e-6)
    assert r.degree[r.labels.index("eps_z_1")] == 0.0
    assert_doc_quotes("docs/methods/001.md", "| azimuth flip 0°/180° only | 5 | 5, 8, 12, 12, … | 12 |",
                      [0, 180, r.rank_static, *r.ranks[:4], r.ranks[-1]])


def test_ins_k_flipping_about_roll_only_leaves_rank_12(model):
    """Relative attitude changes about azimuth (INS 1 indexes) and a horizontal axis (INS k
    rolls), both attitudes change — the paper's conditions (2)–(3) hold — yet the stacked
    rank is 12: one direction mixing φE, ε_z1, ε_yk, ∇_yk stays unobservable (INS k's roll
    axis stays north)."""
    mk = ix.RotateStop((("roll", math.pi), ("roll", -math.pi)))
    C1, Ck, T = ix.common_stops(ix.single_axis_4pos(), mk, CYCLE)
    r = rotins.schedule_observability(model, C1, Ck, LAT, durations=T, method="tom")
    assert r.ranks[-1] == 12
    zero = {l for l, d in zip(r.labels, r.degree) if d == 0.0}
    assert zero == {"phiE_1k", "eps_z_1", "eps_y_k", "nabla_y_k"}
    assert_doc_quotes("docs/methods/001.md", "| roll flip 0°/180° only | 5 | 5, 10, 12, 12, … | 12 |",
                      [0, 180, r.rank_static, *r.ranks[:4], r.ranks[-1]])
    assert_doc_quotes("docs/methods/001.md", "with INS 1 indexing in azimuth, meets both and the rank stays 12",
                      [1, r.ranks[-1]])


def test_schedule_observability_bad_input(model):
    C = np.eye(3)[None]
    with pytest.raises(ValueError, match="shape"):
        rotins.schedule_observability(model, C, np.eye(3), LAT)
    with pytest.raises(ValueError, match="needs the stop durations"):
        rotins.schedule_observability(model, C, C, LAT, method="tom")
    with pytest.raises(ValueError, match="positive"):
        rotins.schedule_observability(model, C, C, LAT, durations=[0.0])


# ----------------------------------------------------------------------- the joint filter
def _static_streams(T=60.0, hours=144.0):
    """Error-free outputs of INS 1 (single-axis) and INS k (dual-axis) on a moored ship at
    the filter epochs: IMU attitude from the schedules, carrier axes = ENU."""
    from sinslab.core import attitude as A
    from sinslab.core import earth

    m1, mk = ix.single_axis_4pos(), ix.dual_axis_16()
    t = T * np.arange(int(hours * 3600 / T) + 1)
    g = float(earth.gravity(LAT, 0.0))
    wie = np.array([0.0, math.cos(LAT), math.sin(LAT)]) * 7.2921151467e-5
    out = []
    for m in (m1, mk):
        ang, _ = ix.mount_angles(m, t)
        C = euler_to_dcm(ang)                                  # C_b^n
        rows = np.zeros((t.size, 10))
        rows[:, :4] = A.euler_to_quat(ang)
        rows[:, 7] = LAT
        rows[:, 8] = 2.0
        w = np.einsum("kji,j->ki", C, wie)[:-1]
        f = np.einsum("kji,j->ki", C, np.array([0.0, 0.0, g]))[:-1]
        out.append((rows, w, f))
    return t, out


def _joint_setup(drift_rw1=0.0):
    model = rotins.joint_rotation_model(0.001 * u.deg / 60, 0.001 * u.deg / 60, 1e-4, 1e-4, drift_rw1=drift_rw1)
    P0 = rotins.joint_P0(model, LAT, att=np.array([5, 5, 30]) * u.arcsec * math.sqrt(2),
                         gyro1=0.01 * u.dph, gyrok=0.01 * u.dph, accel1=20 * u.ug, accelk=20 * u.ug)
    return model, P0


def test_joint_filter_covariance_stays_symmetric_pd_over_144h():
    """R ≈ 0 (floor of 1 mm / 1e-5 m/s, sequential scalar Joseph updates): over 144 h of
    filter epochs P stays symmetric and positive definite (its correlation matrix has a
    Cholesky factor at every epoch), and the fusion driver's σ equals that of the same
    filter run step by step here (two implementations of one filter)."""
    from sinslab.estimation.filter import KalmanFilter
    from sinslab.fusion.driver import PrecomputedStream

    T = 60.0
    t, ((r1, w1, f1), (rk, wk, fk)) = _static_streams(T)
    model, P0 = _joint_setup()
    sig = rotins.difference_sigma(LAT)
    Phi, Q = rotins.joint_transitions(model, T, r1[:-1], rk[:-1], (w1, f1), (wk, fk))
    kf = KalmanFilter(np.zeros(model.n), P0, check=False)
    H = np.zeros((4, model.n))
    H[[0, 1, 2, 3], [0, 1, 2, 3]] = 1.0
    sig_loop = np.empty((t.size - 1, model.n))
    worst = np.inf
    for k in range(t.size - 1):
        kf.predict(Phi[k], Q["all"][k], T)
        kf.update(np.zeros(4), H, sig ** 2)
        P = kf.P
        assert np.array_equal(P, P.T)
        d = np.sqrt(np.diag(P))
        assert np.all(d > 0)
        Cn = P / d[:, None] / d[None, :]
        np.linalg.cholesky(Cn)
        if k % 240 == 0:
            worst = min(worst, np.linalg.eigvalsh(Cn)[0])
        sig_loop[k] = d
    assert worst > 0
    res = rotins.joint_filter(PrecomputedStream(t, r1, w1, f1), PrecomputedStream(t, rk, wk, fk), model, P0,
                              kf_dt=T, sigma=sig)
    np.testing.assert_allclose(res.sigma[1:, 4:], sig_loop[:, 4:], rtol=1e-6)
    iz = model.layout.index(["eps_z_1"])[0]
    assert res.sigma[-1, iz] < 0.1 * res.sigma[0, iz]          # ε_z1 observable along the schedule


def test_noise_share_equals_suboptimal_filter_covariance():
    """Paper eqs 16–20: with the nominal gains fixed, scaling one noise source by 1 + α
    adds α times its share to the error variance. Checked against a direct propagation of
    the actual error covariance of the mis-tuned filter, P⁺ = (I−KH)(ΦPΦᵀ + Q̃)(I−KH)ᵀ +
    K R Kᵀ (K from the nominal filter)."""
    T = 60.0
    t, ((r1, w1, f1), (rk, wk, fk)) = _static_streams(T, hours=6.0)
    model, P0 = _joint_setup()
    sig = rotins.difference_sigma(LAT)
    groups = {"ins1": range(0, 5), "gyro_k": range(5, 8), "accel_k": range(8, 10)}
    Phi, Q = rotins.joint_transitions(model, T, r1[:-1], rk[:-1], (w1, f1), (wk, fk), noise_groups=groups)
    bud = rotins.noise_share(model, P0, Phi, Q, sig)
    alpha = 1.1 ** 2 - 1
    H = np.zeros((4, model.n))
    H[[0, 1, 2, 3], [0, 1, 2, 3]] = 1.0
    R = np.diag(sig ** 2)
    P = P0.copy()
    Pa = P0.copy()
    for k in range(t.size - 1):
        Qn = Q["ins1"][k] + Q["gyro_k"][k] + Q["accel_k"][k]
        P = Phi[k] @ P @ Phi[k].T + Qn
        Pa = Phi[k] @ Pa @ Phi[k].T + Qn + alpha * Q["gyro_k"][k]
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        I_KH = np.eye(model.n) - K @ H
        P = I_KH @ P @ I_KH.T + K @ R @ K.T
        Pa = I_KH @ Pa @ I_KH.T + K @ R @ K.T
    j = bud.names.index("gyro_k")
    rest = slice(4, None)                                      # positions are rescaled inside
    np.testing.assert_allclose(bud.total[rest], np.diag(P)[rest], rtol=1e-5)
    np.testing.assert_allclose(bud.total[rest] + alpha * bud.variance[j, rest], np.diag(Pa)[rest], rtol=1e-5)
    # eq 20 taken literally (ΔP = αP) would need every source scaled; INS k's gyros are only a share
    iz = model.layout.index(["eps_z_1"])[0]
    assert 0 < bud.variance[j, iz] < bud.total[iz]


def test_difference_sigma_and_settle_times():
    s = rotins.difference_sigma(LAT, 1e-3, 1e-5)
    assert s.shape == (4,) and s[2] == 1e-5 and 1e-10 < s[0] < 2e-10
    with pytest.raises(ValueError, match="floors"):
        rotins.difference_sigma(LAT, 0.0, 1e-5)
    t = np.arange(10.0)
    x = np.array([5, 4, 3, 2, 1.5, 1.2, 1.05, 1.0, 1.02, 1.0])
    # the σ reading: first sample at or below the level
    assert rotins.sigma_settle_time(t, x, 1.5) == 4.0 and math.isnan(rotins.sigma_settle_time(t, x, 0.5))
    # the band reading: first sample of the final stay within ± band of the truth
    assert rotins.band_settle_time(t, x, 1.0, 0.1) == 6.0
    assert rotins.band_settle_time(t, x, 1.0, 10.0) == 0.0
    assert math.isnan(rotins.band_settle_time(t, x, 2.0, 0.1))
    # a longer record that stays inside does not move it (a band around the final value would)
    x2 = np.r_[x, np.full(10, 1.01)]
    assert rotins.band_settle_time(np.arange(20.0), x2, 1.0, 0.1) == 6.0


#: a drift random walk of the size used against a 0.0005 °/h, 48 h trend (A·sqrt(2π/P))
RW = 0.0005 * u.dph * math.sqrt(2 * math.pi / (48 * 3600.0))


@pytest.mark.parametrize("drift_rw1", [0.0, RW], ids=["constant_drifts", "drift_random_walk"])
def test_driver_and_compiled_joint_filters_agree(drift_rw1):
    """Two implementations of one joint filter: the fusion driver on the two outputs every
    1 s with a measurement every 10 s, and the compiled loop on the transitions chained from
    the same 1 s steps (:func:`rotins.joint_transitions` with sub-steps) — same estimate
    and σ on synthetic INS differences; with the paper's random-constant drifts and with a
    random walk on INS 1's drifts."""
    from sinslab.fusion.driver import PrecomputedStream

    Ts, m = 1.0, 10
    t, ((r1, w1, f1), (rk, wk, fk)) = _static_streams(Ts, hours=2.0)
    rng = np.random.default_rng(0)
    rk = rk.copy()
    rk[:, 4:6] += np.cumsum(rng.standard_normal((t.size, 2)) * 1e-4, 0)
    rk[:, 7] += np.cumsum(rng.standard_normal(t.size) * 1e-10)
    rk[:, 8] += np.cumsum(rng.standard_normal(t.size) * 1e-10)
    model, P0 = _joint_setup(drift_rw1)
    sig = rotins.difference_sigma(LAT)
    res = rotins.joint_filter(PrecomputedStream(t, r1, w1, f1), PrecomputedStream(t, rk, wk, fk), model, P0,
                              kf_dt=Ts, meas_every=m, sigma=sig)
    Phi, Q = rotins.joint_transitions(model, Ts, r1[:-1], rk[:-1], (w1, f1), (wk, fk), substeps=m)
    z = rotins.difference_measurements(r1[m::m], rk[m::m])
    x, s = rotins.joint_filter_linear(z, Phi, Q["all"], model, P0, sigma=sig)
    xd, sd_ = res.x[::m], res.sigma[::m]
    np.testing.assert_allclose(s[:, 4:], sd_[:, 4:], rtol=1e-9)
    assert np.max(np.abs(x - xd) / sd_) < 1e-8


def test_drift_random_walk_enters_only_as_q_times_t_on_the_drift_block():
    """Random-walk drifts (ε̇_1 = w, density q): the drift rows of F are zero, so over a step
    T the discrete process noise of the ε_1 block grows by exactly q·T·I against the paper's
    random-constant model, and F, the noise of every other block's own diagonal at the
    first order, and the default model (no extra noise columns) are unchanged."""
    from sinslab.nav.errstate import NavPoint

    C1, Ck = euler_to_dcm(np.radians([0.0, 0.0, 90.0])), euler_to_dcm(np.radians([180.0, 0.0, 0.0]))
    m0 = rotins.joint_rotation_model(1e-6, 1e-6, 1e-4, 1e-4)
    m1 = rotins.joint_rotation_model(1e-6, 1e-6, 1e-4, 1e-4, drift_rw1=RW)
    assert m0.q.size == 10 and m1.q.size == 13
    p1, pk = NavPoint.static(LAT, C1), NavPoint.static(LAT, Ck)
    np.testing.assert_array_equal(m0.F(p1, pk), m1.F(p1, pk))
    T = 10.0
    rows = np.zeros((1, 10))
    rows[0, :4] = [1.0, 0.0, 0.0, 0.0]
    rows[0, 7] = LAT
    w = np.zeros((1, 3))
    f = np.array([[0.0, 0.0, 9.79]])
    Q0 = rotins.joint_transitions(m0, T, rows, rows, (w, f), (w, f))[1]["all"][0]
    Q1 = rotins.joint_transitions(m1, T, rows, rows, (w, f), (w, f))[1]["all"][0]
    e1 = m1.layout.slice("eps_1")
    np.testing.assert_allclose((Q1 - Q0)[e1, e1], RW ** 2 * T * np.eye(3), rtol=1e-12, atol=0)
    ek = m1.layout.slice("eps_k")
    np.testing.assert_array_equal((Q1 - Q0)[ek, ek], 0.0)
    with pytest.raises(ValueError, match="drift_rw1"):
        rotins.joint_rotation_model(drift_rw1=-1.0)
