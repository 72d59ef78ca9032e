"""Oracles of the factor-graph estimator (sinslab.fusion.graph).

* Cross-check of two independent implementations: on a simulated 201 s car drive with small
  errors (a 60 s GNSS outage inside), the RTS-smoothed filter (sinslab's error-state
  filter and backward pass) and the batch graph (GTSAM's preintegration, Levenberg–Marquardt
  and marginals) agree within 0.1 σ in position and attitude at every filter epoch, and
  their σ within 2 %: the same model translated once (noise, bias walks, P0, fixes) gives
  the same MAP estimate — a wrong sign, axis order, unit or frame in either breaks it.
* Power of that check: the same graph with GTSAM's usual constant gravity of the origin
  (the vehicle 4 km away at the end) disagrees by more than 0.3 σ in tilt.
* The fixed-lag smoother sees less data than the batch: its σ is never below the batch σ,
  and equal to it at the last keyframe (both have seen everything there).
(The robust weights and the frame conversions, which need no GTSAM, are in
test_robust_weighting.py.)
"""
import sys

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core.errors import InputError
from sinslab.fusion.spec import FilterGrid, FixSpec

gtsam = pytest.importorskip("gtsam", reason="gtsam (sinslab[graph]) is not installable here")


# ------------------------------------------------------------------ the cross-check


@pytest.fixture(scope="module")
def drive():
    """The smoother benchmark's car drive (201 s, 1 Hz fixes, outage 100–160 s) with small
    initial errors and bias random walks (both estimators take the same model)."""
    import importlib.util
    from pathlib import Path

    from sinslab.fusion.loosely_coupled import loosely_coupled
    from sinslab.fusion.smoothing import History, smooth
    from sinslab.nav import errstate as es
    spec = importlib.util.spec_from_file_location(
        "bench_smoother", Path(__file__).resolve().parents[2] / "benchmarks" / "smoother.py")
    B = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(B)
    d = B.drive_inputs(7)
    pf, vf = d["measurements"][0].parts
    fx = FixSpec(pf.t_valid, pf.pos, [1.0, 1.0, 2.0], vel=vf.vel, vel_sigma=0.05)
    m = es.ErrorModel("full", [es.gyro_bias(rrw=1e-6), es.accel_bias(arw=1e-5)],
                      gyro_arw=B.GYRO_ARW, accel_vrw=B.ACCEL_VRW)
    P0 = np.diag(d["sd"] ** 2)
    grid = FilterGrid(0.02)
    r = loosely_coupled(d["imu"], d["init"], fx, P0, m, grid=grid, history=History(0.1), progress=False)
    return dict(d=d, fx=fx, m=m, P0=P0, grid=grid, rts=smooth(r))


def _disagreement(a_nav, b_nav, sig, lay):
    """|a − b| / σ (M, 6): attitude (φ of b against a), position north, east, up."""
    phi = A.misalignment(A.quat_to_dcm(a_nav[:, :4]), A.quat_to_dcm(b_nav[:, :4]))
    dp = b_nav[:, 7:10] - a_nav[:, 7:10]
    return np.abs(np.column_stack([phi / sig[:, lay.slice("phi")], dp / sig[:, lay.slice("dp")]]))


def _graph(drive, spec):
    from sinslab.fusion.graph import graph_navigate
    return graph_navigate(drive["d"]["imu"], drive["d"]["init"], drive["fx"], drive["P0"], drive["m"],
                          grid=drive["grid"], spec=spec)


def test_rts_smoother_and_batch_graph_agree_within_a_tenth_of_sigma(drive):
    from sinslab.fusion.graph import GraphSpec
    s = drive["rts"]
    g = _graph(drive, GraphSpec("batch"))
    lay = drive["m"].layout
    assert np.array_equal(g.t, s.t)
    z = _disagreement(s.nav, g.nav, s.sigma, lay)
    assert z.max() < 0.1, z.max(0)                                   # measured 0.038
    keys = np.searchsorted(s.t, g.key_t - 1e-9)
    cols = np.r_[lay.slice("phi"), lay.slice("dv"), lay.slice("dp"), lay.slice("eps"), lay.slice("nabla")]
    ratio = g.sigma[keys][:, cols] / s.sigma[keys][:, cols]
    assert np.all(np.abs(ratio - 1) < 0.02), np.abs(ratio - 1).max(0)     # measured 0.010
    # post-fit residuals of the fixes, smaller than the fixes' σ on average (positions
    # 1, 1, 2 m; velocities 0.05 m/s), as a least-squares fit leaves them
    assert g.residual.shape == (g.fix_t.size, 6)
    chi = np.mean((g.residual / [1.0, 1.0, 2.0, 0.05, 0.05, 0.05]) ** 2, 0)
    assert np.all(chi < 1.0) and np.all(chi > 0.1), chi
    # the same solution as the driver's result of one stream (what the front end reads)
    dr = g.as_driver_result()
    assert np.array_equal(dr.nav[0], g.nav) and np.array_equal(dr.gyro_bias[0], g.gyro_bias)
    assert dr.applied.nis.shape == g.fix_t.shape and not np.any(dr.x)
    # power: GTSAM's constant gravity of the origin leaves a tilt the cross-check sees
    o = _graph(drive, GraphSpec("batch", gravity="origin"))
    assert _disagreement(s.nav, o.nav, s.sigma, lay)[:, :2].max() > 0.3


def test_fixed_lag_sigma_bounds_the_batch(drive):
    from sinslab.fusion.graph import GraphSpec
    b = _graph(drive, GraphSpec("batch"))
    f = _graph(drive, GraphSpec("fixed-lag", lag=3.0))
    lay = drive["m"].layout
    pos = lay.slice("dp")
    assert np.all(f.key_sigma[:, pos] >= b.key_sigma[:, pos] * (1 - 1e-3))
    assert np.allclose(f.key_sigma[-1, pos], b.key_sigma[-1, pos], rtol=1e-3)
    # mid-outage the fixed-lag window (3 s) has no fix: there it is the forward solution
    mid = np.searchsorted(b.key_t, 130.0)
    assert f.key_sigma[mid, pos.start] > 2 * b.key_sigma[mid, pos.start]


# ------------------------------------------------------------------ bad input
def test_estimator_names_windows_and_models_refused(drive, monkeypatch):
    from sinslab.fusion.estimators import KalmanEstimator, canonical_estimator, estimator_of
    from sinslab.fusion.graph import GraphSpec, graph_navigate
    from sinslab.nav import errstate as es
    assert estimator_of("filter") == KalmanEstimator()
    assert estimator_of("fixed-lag:10").spec == GraphSpec("fixed-lag", 10.0)
    assert estimator_of("fixed-lag:1 min").spec == GraphSpec("fixed-lag", 60.0)
    assert estimator_of("graph").spec == GraphSpec("batch") and canonical_estimator("fixed-lag:10") == "fixed-lag:10 s"
    for bad in ("kalmann", "fixed-lag:", "fixed-lag:-3", "fixed-lag:3 m"):
        with pytest.raises(InputError):
            estimator_of(bad)
    with pytest.raises(InputError, match="shorter than the fix interval"):
        _graph(drive, GraphSpec("fixed-lag", lag=0.5))
    m = es.ErrorModel("full", [es.gyro_bias(), es.accel_bias(), es.gyro_scale()], gyro_arw=1e-4, accel_vrw=1e-3)
    with pytest.raises(InputError, match="nothing else"):
        graph_navigate(drive["d"]["imu"], drive["d"]["init"], drive["fx"], np.eye(m.n), m)
    monkeypatch.setitem(sys.modules, "gtsam", None)
    with pytest.raises(InputError, match=r"sinslab\[graph\]"):
        graph_navigate(drive["d"]["imu"], drive["d"]["init"], drive["fx"], drive["P0"], drive["m"])


def test_lever_arm_velocity_factor_jacobian():
    """The velocity fix with a lever arm (``v + R (ω × l)`` against the fix) has the
    Jacobian of its own error: central differences on the pose's and velocity's tangent
    spaces (GTSAM's retract) against its linearisation."""
    from sinslab.fusion.graph.build import _velocity_factor
    rng = np.random.default_rng(4)
    X, V = gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.V
    wl = np.cross([0.1, -0.3, 0.5], [0.4, 1.2, -0.8])
    f = _velocity_factor(gtsam, X(0), V(0), rng.normal(size=3), wl, gtsam.noiseModel.Unit.Create(3))
    pose = gtsam.Pose3(gtsam.Rot3.Expmap(rng.normal(size=3)), rng.normal(size=3))
    vel = rng.normal(size=3)

    def err(dx, dv):
        v = gtsam.Values()
        v.insert(X(0), pose.retract(dx))
        v.insert(V(0), vel + dv)
        return f.unwhitenedError(v)

    v0 = gtsam.Values()
    v0.insert(X(0), pose)
    v0.insert(V(0), vel)
    A = f.linearize(v0).jacobian()[0]
    h = 1e-6
    num = np.column_stack([(err(h * e, np.zeros(3)) - err(-h * e, np.zeros(3))) / (2 * h) for e in np.eye(6)]
                          + [(err(np.zeros(6), h * e) - err(np.zeros(6), -h * e)) / (2 * h) for e in np.eye(3)])
    assert np.allclose(A, num, atol=1e-7), np.abs(A - num).max()
