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

LAT = math.radians(28.222)


def _stops(m1, mk, t_end, dt=0.5):
    """Stops where both mounts are still, in time order: (C_b1^c, C_bk^c, durations)."""
    t = np.arange(0.0, t_end, dt)
    a1, r1 = ix.mount_angles(m1, t)
    ak, rk = ix.mount_angles(mk, t)
    still = np.all(r1 == 0, -1) & np.all(rk == 0, -1)
    key = np.round(np.hstack([a1, ak]), 9)
    segs = []
    for i in np.flatnonzero(still):
        if segs and segs[-1][2] == i - 1 and np.array_equal(segs[-1][0], key[i]):
            segs[-1][1] += dt
            segs[-1][2] = i
        else:
            segs.append([key[i], dt, i])
    ang = np.array([s[0] for s in segs])
    return euler_to_dcm(ang[:, :3]), euler_to_dcm(ang[:, 3:]), np.array([s[1] for s in segs])


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
    C1, Ck, T = _stops(ix.single_axis_4pos(), ix.dual_axis_16(), CYCLE)
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


def test_one_stop_alone_rank_5(model):
    for att1, attk in (([0, 0, 0], [0, 0, 0]), ([0, 0, math.pi / 2], [0, math.pi, math.pi])):
        r = rotins.schedule_observability(model, euler_to_dcm(np.array([att1], float)),
                                          euler_to_dcm(np.array([attk], float)), LAT)
        assert r.rank_static == 5 and r.ranks == [5]


def test_ins_k_flipping_about_azimuth_only_leaves_rank_12(model):
    """Both azimuth gyros stay on the up axis: ε_z1 = ε_zk is the unobservable direction."""
    mk = ix.RotateStop((("yaw", math.pi), ("yaw", -math.pi)))
    C1, Ck, T = _stops(ix.single_axis_4pos(), mk, CYCLE)
    r = rotins.schedule_observability(model, C1, Ck, LAT)
    assert r.ranks[-1] == 12 and set(r.segment_ranks) == {5}
    N = r.result.null_space[:, 0]
    N = N / N[r.labels.index("eps_z_1")]
    e = np.zeros(13)
    e[[r.labels.index("eps_z_1"), r.labels.index("eps_z_k")]] = 1.0
    np.testing.assert_allclose(N, e, atol=1e-6)
    assert r.degree[r.labels.index("eps_z_1")] == 0.0


def test_ins_k_flipping_about_roll_only_leaves_rank_12(model):
    """Relative attitude changes about azimuth (INS 1 indexes) and a horizontal axis (INS k
    rolls), both attitudes change — the paper's conditions (2)–(3) hold — yet the stacked
    rank is 12: one direction mixing φE, ε_z1, ε_yk, ∇_yk stays unobservable (INS k's roll
    axis stays north)."""
    mk = ix.RotateStop((("roll", math.pi), ("roll", -math.pi)))
    C1, Ck, T = _stops(ix.single_axis_4pos(), mk, CYCLE)
    r = rotins.schedule_observability(model, C1, Ck, LAT, durations=T, method="tom")
    assert r.ranks[-1] == 12
    zero = {l for l, d in zip(r.labels, r.degree) if d == 0.0}
    assert zero == {"phiE_1k", "eps_z_1", "eps_y_k", "nabla_y_k"}


def test_schedule_observability_bad_input(model):
    C = np.eye(3)[None]
    with pytest.raises(ValueError, match="shape"):
        rotins.schedule_observability(model, C, np.eye(3), LAT)
    with pytest.raises(ValueError, match="needs the stop durations"):
        rotins.schedule_observability(model, C, C, LAT, method="tom")
    with pytest.raises(ValueError, match="positive"):
        rotins.schedule_observability(model, C, C, LAT, durations=[0.0])
