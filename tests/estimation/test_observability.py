"""Observability: ranks, unobservable subspaces, piecewise-constant systems, degrees."""
from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.linalg

from sinslab.methods.alignment import full_model
from sinslab.methods.rotins import joint_rotation_model
from sinslab.nav import errstate as es
from sinslab.estimation import observability as ob
from sinslab.core.earth import WIE, gravity
from sinslab.core.units import dph, ug

d = np.radians
LATS = [-60.0, -5.0, 0.0, 20.0, 34.246, 60.0, 85.0]
#: typical magnitudes of the paper-000 states (φ 3.4', ε 0.02 °/h, ∇ 100 µg): a unit-free frame
P000_SCALE = np.array([1e-3] * 3 + [0.02 * dph] * 3 + [100 * ug] * 2)


def _expected_null_000(lat):
    """Null directions of paper 000's 8-state model, derived: a constant misalignment that
    the measured specific force cannot see needs the bias that cancels its tilt signal and
    the drift that keeps it from moving (φ̇ = −ω_ie×φ − ε = 0)."""
    g = float(gravity(lat))
    wN, wU = WIE * np.cos(lat), WIE * np.sin(lat)
    n1 = np.zeros(8); n1[[1, 6, 3]] = [1.0, g, wU]                  # (φN, ∇E): ∇E = g φN
    n2 = np.zeros(8); n2[[0, 7, 4, 5]] = [1.0, -g, -wU, wN]         # (φE, ∇N): ∇N = −g φE
    n3 = np.zeros(8); n3[[2, 3]] = [1.0, -wN]                       # (φU, εE): εE = −ω_N φU
    return np.stack([n1, n2, n3], 1)


@pytest.mark.parametrize("lat_deg", LATS)
@pytest.mark.parametrize("scaled", [False, True])
def test_static_alignment_rank_5_and_null_space_is_the_three_pairs(lat_deg, scaled):
    """Paper 000: rank 5 of 8; the unobservable subspace is spanned by exactly the
    (φN, ∇E), (φE, ∇N), (φU, εE) combinations (computed, at several latitudes)."""
    lat = d(lat_deg)
    F, G, H = full_model(lat)
    r = ob.analyze(F, H, scale=P000_SCALE if scaled else None)
    assert r.rank == 5
    assert r.null_space.shape == (8, 3)
    O = ob.observability_matrix(F, H)
    E = _expected_null_000(lat)
    # the derived vectors are unobservable (O v = 0 relative to ‖O‖‖v‖) ...
    for v in E.T:
        assert np.linalg.norm(O @ v) <= 1e-12 * np.linalg.norm(O) * np.linalg.norm(v)
    # ... and span the computed null space (compare in unit-free coordinates)
    Ns = r.null_space / P000_SCALE[:, None]
    Es = E / P000_SCALE[:, None]
    Qn, _ = np.linalg.qr(Ns)
    Qe, _ = np.linalg.qr(Es)
    angles = scipy.linalg.subspace_angles(Qn, Qe)
    assert np.max(angles) < 1e-6
    # SVD gap: 5 clearly non-zero singular values, 3 at round-off
    assert r.singular_values[4] > 1e-3 and r.singular_values[5] < 1e-12


def test_static_alignment_observable_fraction_splits_each_pair():
    """With automatic scaling each pair member is half observable (fraction 1/√2) while εN
    and εU are fully observable directions at mid-latitude; strict degrees are 0 there
    because every state touches one of the null vectors (εN → ∇N ω sinL / g, paper 000)."""
    F, G, H = full_model(d(34.246))
    r = ob.analyze(F, H)
    np.testing.assert_allclose(r.observable_fraction[[0, 1, 2, 3, 6, 7]], np.sqrt(0.5), atol=1e-6)
    np.testing.assert_allclose(r.observable_fraction[[4, 5]], 1.0, atol=1e-6)
    assert np.all(r.degree == 0.0)
    # at the equator ω_U = 0: εN no longer mixes with the (φE, ∇N) null vector
    r0 = ob.analyze(*full_model(0.0)[::2])
    assert r0.degree[4] > 0.1 and np.sum(r0.degree > 0) == 1


def test_rank_insensitive_to_state_scaling():
    """Rescaling states by factors 1e-8..1e8 (unit changes) leaves rank and null space."""
    rng = np.random.default_rng(3)
    F, G, H = full_model(d(34.246))
    for _ in range(5):
        s = 10.0 ** rng.uniform(-8, 8, 8)
        Fs = F * s[None, :] / s[:, None]           # x = S x'
        Hs = H * s[None, :]
        r = ob.analyze(Fs, Hs)
        assert r.rank == 5
        ang = scipy.linalg.subspace_angles((s[:, None] * r.null_space) / P000_SCALE[:, None],
                                           ob.analyze(F, H).null_space / P000_SCALE[:, None])
        assert np.max(ang) < 1e-3          # ~1.6e-4 rad at worst over 16 decades of scaling


def test_textbook_switching_sensor_gains_rank():
    """1-D [p, v], ṗ = v: velocity sensor only → rank 1 (position unobservable); a second
    segment with a position sensor → rank 2."""
    F = np.array([[0.0, 1.0], [0.0, 0.0]])
    segs = [(F, [[0.0, 1.0]], 10.0), (F, [[1.0, 0.0]], 10.0)]
    for m in ("som", "tom"):
        assert ob.piecewise(segs, m).ranks == [1, 2]
    np.testing.assert_allclose(np.abs(ob.analyze(F, [[0.0, 1.0]]).null_space[:, 0]), [1.0, 0.0], atol=1e-12)


def test_tom_accounts_for_motion_between_segments_and_som_does_not():
    """Segment 1 sees nothing while p drifts with v; segment 2 sees p: the TOM's
    unobservable direction is p0 + v0·T1 = 0 (the exact one), the SOM's is v alone."""
    F1 = np.array([[0.0, 1.0], [0.0, 0.0]])
    T1 = 7.0
    segs = [(F1, [[0.0, 0.0]], T1), (np.zeros((2, 2)), [[1.0, 0.0]], 5.0)]
    tom = ob.piecewise(segs, "tom", scale=[1.0, 1.0])
    som = ob.piecewise(segs, "som", scale=[1.0, 1.0])
    assert tom.ranks == [0, 1] and som.ranks == [0, 1]
    nt = tom.result.null_space[:, 0]
    ns = som.result.null_space[:, 0]
    assert abs(nt @ np.array([1.0, T1])) / np.hypot(1, T1) < 1e-12    # p0 + T1 v0 = 0
    np.testing.assert_allclose(np.abs(ns), [0.0, 1.0], atol=1e-12)


def test_goshen_meskin_stationary_alignment_with_heading_changes():
    """Stationary alignment, velocity measured, 10 states [φ, δvE, δvN, ∇x, ∇y, εx, εy, εz]
    (body biases): rank 7 in one position (Goshen-Meskin & Bar-Itzhack 1992); a 90° azimuth
    change makes it fully observable (10); a tilt alone only adds one (8)."""
    m = es.ErrorModel("attvel-horizontal", [es.accel_bias("xy"), es.gyro_bias()])
    H = m.layout.selector(["dvE", "dvN"])
    seg = lambda att: (m.F(es.NavPoint.static(d(45.0), att)), H, 300.0)
    for meth in ("som", "tom"):
        assert ob.piecewise([seg([0, 0, 0]), seg([0, 0, d(90)])], meth).ranks == [7, 10]
        assert ob.piecewise([seg([0, 0, 0]), seg([d(40), 0, 0]), seg([0, d(40), d(90)])], meth).ranks == [7, 8, 10]


# ------------------------------------------------------------------- paper 001 (13 states)
def _joint_segment(model, az1, att2, lat=d(28.222), T=1800.0):
    """Paper 001 §4: x1 is measured directly, so (F, H) ≡ (A, C) = (F22, F12) for x2 (13)."""
    lay = model.layout
    x2 = np.arange(lay.slice("phi").start, 17)
    dv = np.arange(lay.slice("dv").start, lay.slice("dv").stop)
    n1 = es.NavPoint.static(lat, [0.0, 0.0, az1])
    nk = es.NavPoint.static(lat, att2)
    F = model.F(n1, nk)
    return F[np.ix_(x2, x2)], F[np.ix_(dv, x2)], T


DUAL = {"0": [0, 0, 0], "az180": [0, 0, d(180)], "roll180": [0, d(180), 0],
        "both": [0, d(180), d(180)]}


def test_paper001_static_segment_rank_5_and_three_segments_rank_13():
    """Per static segment rank 5 (paper eq 14); relative attitude changed about azimuth
    (INS k azimuth flip) and about a horizontal axis (INS 1 indexed 90°, INS k roll flip):
    ranks 5 → 9 → 13 (paper: m ≥ 3 segments)."""
    model = joint_rotation_model()
    for az1, key in itertools.product([0, 90, 180, 270], DUAL):
        A, C, _ = _joint_segment(model, d(az1), DUAL[key])
        assert ob.rank(A, C) == 5
    segs = [_joint_segment(model, 0.0, DUAL["0"]), _joint_segment(model, 0.0, DUAL["az180"]),
            _joint_segment(model, d(90), DUAL["roll180"])]
    for meth in ("som", "tom"):
        assert ob.piecewise(segs, meth).ranks == [5, 9, 13]


def test_paper001_azimuth_only_relative_motion_is_not_enough():
    """Condition (3) of paper 001: without a relative change about a horizontal axis the
    joint state stays unobservable, whatever the azimuth schedule."""
    model = joint_rotation_model()
    segs = [_joint_segment(model, d(a1), DUAL[k]) for a1 in (0, 90, 180, 270) for k in ("0", "az180")]
    assert ob.piecewise(segs, "som").ranks[-1] < 13


def test_paper001_full_schedule_reaches_13():
    """The 4-position single-axis × 16-step dual-axis stops (azimuth/roll 0°/180°) make the
    13-state subsystem fully observable (rank after each of 16 stops reported)."""
    model = joint_rotation_model()
    segs = [_joint_segment(model, d(a1), DUAL[k]) for a1, k in itertools.product((0, 90, 180, 270), DUAL)]
    for meth in ("som", "tom"):
        ranks = ob.piecewise(segs, meth).ranks
        assert ranks[0] == 5 and ranks[-1] == 13
        assert all(b >= a for a, b in zip(ranks, ranks[1:]))


# ------------------------------------------------------------------------ degrees, misc
def test_degree_is_cramer_rao_like_for_a_full_rank_system():
    """For a full-rank system degree_j = 1/sqrt([(OᵀO)⁻¹]_jj)/σ_max of the scaled matrix."""
    F = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    H = np.array([[1.0, 0.0, 0.0]])
    r = ob.analyze(F, H, scale=[1.0, 1.0, 1.0])
    assert r.rank == 3 and np.all(r.degree > 0) and np.allclose(r.observable_fraction, 1.0)
    # scaled O = rows H, HF/s, HF²/s² = the identity (s = ‖F‖₂ = 1): every degree is 1
    np.testing.assert_allclose(r.degree, 1.0, rtol=1e-12)


def test_covariance_degrees():
    P0 = np.diag([4.0, 9.0, 1.0])
    P = np.stack([P0, np.diag([1.0, 9.0, 0.25]), np.diag([0.04, 1.0, 0.01])])
    np.testing.assert_allclose(ob.covariance_degree(P0, P)[-1], [10.0, 3.0, 10.0])
    np.testing.assert_allclose(ob.covariance_degree(np.diag(P0), np.diagonal(P, axis1=1, axis2=2))[1], [2, 1, 2])
    w, V = ob.covariance_eigen_degree(P0, P[-1])
    np.testing.assert_allclose(np.sort(w), [0.01, 0.01, 1.0 / 9.0])
    with pytest.raises(ValueError):
        ob.covariance_degree(P0, np.diag([1.0, 0.0, 1.0]))


def test_bad_inputs():
    with pytest.raises(ValueError, match="square"):
        ob.analyze(np.zeros((2, 3)), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="columns"):
        ob.analyze(np.zeros((3, 3)), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="finite"):
        ob.analyze(np.full((2, 2), np.nan), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="durations"):
        ob.piecewise([(np.zeros((2, 2)), np.eye(2))], "tom")
    with pytest.raises(ValueError, match="method"):
        ob.piecewise([(np.zeros((2, 2)), np.eye(2))], "xyz")
    with pytest.raises(ValueError, match="scale"):
        ob.analyze(np.zeros((2, 2)), np.eye(2), scale=[1.0, 0.0])
    assert ob.analyze(np.zeros((2, 2)), np.zeros((1, 2))).rank == 0
