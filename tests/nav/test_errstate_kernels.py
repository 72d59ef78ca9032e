"""Cross-checks of the compiled model evaluation against the numpy reference.

- F and G of sinslab.nav.errstate_kernels equal ErrorModel/DifferenceModel.matrices (the
  readable numpy assembly of Savage's φ-angle error equations, errstate module notes)
  entry by entry, for every core, each sensor kind (bias, Gauss–Markov, scale factor,
  installation, axis subsets, n-frame biases), radius derivatives on and off and the
  two-INS difference model, at random navigation points;
- the compiled series discretisation equals kalman.discretize(method="series")
  (Φ = I + FT + (FT)²/2, Q_k = T (Q̄ + Φ Q̄ Φᵀ)/2);
- whole filter runs of the fusion driver agree with model_eval="numpy" to 1e-9 relative:
  21 states with P propagated at every IMU epoch (one compiled loop per block) and a
  lagged-fix run (history kept: the unfused compiled path).
"""

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.estimation.kalman import discretize
from sinslab.estimation.linear import discretize_series_many
from sinslab.nav import errstate as es
from sinslab.nav import errstate_kernels as ek

MODELS = {
    "full-21": lambda: es.ErrorModel(
        "full", [es.gyro_bias(), es.accel_bias(), es.gyro_scale(), es.accel_scale()],
        gyro_arw=1e-4, accel_vrw=1e-3),
    "horizontal-markov-subsets": lambda: es.ErrorModel(
        "horizontal", [es.gyro_markov(100.0, 1e-5, axes="xz"), es.accel_bias(axes="xy", arw=1e-4),
                       es.installation()],
        gyro_arw=1e-4, accel_vrw=1e-3, accel_vrw_axes="xy", radius_derivatives=False),
    "attvel-nav-frame": lambda: es.ErrorModel(
        "attvel", [es.gyro_bias(frame="nav", rrw=1e-6), es.accel_bias(frame="nav")],
        gyro_arw=1e-4, accel_vrw=1e-3),
    "attvel-horizontal-scale": lambda: es.ErrorModel(
        "attvel-horizontal", [es.gyro_scale(axes="z"), es.accel_scale(), es.accel_markov(30.0, 1e-4)],
        gyro_arw=1e-4, accel_vrw=1e-3),
    "scale-markov-lever": lambda: es.ErrorModel(
        "full", [es.gyro_bias(), es.gyro_scale(tau=300.0, sigma=1e-4), es.accel_scale(rw=1e-6),
                 es.lever_arm()], gyro_arw=1e-4, accel_vrw=1e-3),
    "gnss-clock": lambda: es.ErrorModel(
        "full", [es.gyro_bias(), es.accel_bias(), es.receiver_clock(("G", "E", "C"))],
        gyro_arw=1e-4, accel_vrw=1e-3),
    "attitude": lambda: es.ErrorModel("attitude", [es.gyro_bias(), es.accel_bias()], gyro_arw=1e-4),
    "ordered": lambda: es.ErrorModel("full", [es.gyro_bias(), es.accel_bias()], gyro_arw=1e-4,
                                     order=["eps", "dv", "phi", "nabla", "dp"]),
    "difference": lambda: es.DifferenceModel(
        "horizontal", [es.gyro_bias(), es.accel_bias(), es.gyro_scale()],
        [es.gyro_bias(), es.accel_markov(50.0, 1e-4)], gyro_arw1=1e-4, gyro_arwk=2e-4,
        accel_vrw1=1e-3),
}


def _points(rng, k, S):
    """k navigation points at S epochs: rows (k, S, 10) with unnormalised quaternions,
    rates (k, S, 3)."""
    rows = np.zeros((k, S, 10))
    rows[..., :4] = 1.3 * rng.normal(size=(k, S, 4))
    rows[..., 4:7] = rng.normal(scale=100.0, size=(k, S, 3))
    rows[..., 7] = rng.uniform(-1.45, 1.45, size=(k, S))
    rows[..., 8] = rng.uniform(-3, 3, size=(k, S))
    rows[..., 9] = rng.uniform(-200.0, 9000.0, size=(k, S))
    return rows, rng.normal(scale=0.3, size=(k, S, 3)), rng.normal(scale=8.0, size=(k, S, 3))


def _numpy_FG(model, rows, w, f):
    navs = [es.NavPoint(r[:, 7], r[:, 9], r[:, 4:7], A.quat_to_dcm(r[:, :4]), ff, ww)
            for r, ww, ff in zip(rows, w, f)]
    return model.matrices(*navs)


@pytest.mark.parametrize("name", sorted(MODELS))
def test_compiled_F_G_and_series_equal_numpy(name):
    model = MODELS[name]()
    prog = ek.program(model)
    assert prog is not None
    rng = np.random.default_rng(7)
    rows, w, f = _points(rng, prog.n_ins, 40)
    F, G = _numpy_FG(model, rows, w, f)
    Fc, Gc = ek.matrices_rows(prog, rows, w, f)
    # relative to the largest magnitude of each entry over the epochs (a few entries are
    # sums of terms of different size: elementwise relative error is not meaningful)
    sF = np.maximum(np.abs(F).max(0), 1e-300)
    assert np.max(np.abs(Fc - F) / sF) < 1e-12
    assert np.max(np.abs(Gc - G)) < 1e-14
    assert np.array_equal(Fc == 0, F == 0) and np.array_equal(Gc == 0, G == 0)
    fnz, gnz = ek.pattern(prog)
    assert not np.any((F != 0) & ~fnz) and not np.any((G != 0) & ~gnz)
    T = 0.01
    Phi, Q = discretize(F, model.q, T, G=G, method="series")
    Phic, Qc = discretize_series_many(F, G, model.q, T)
    assert np.max(np.abs(Phic - Phi)) < 1e-14
    sQ = max(np.abs(Q).max(), 1e-300)
    assert np.max(np.abs(Qc - Q)) / sQ < 1e-12
    assert np.array_equal(Qc, np.swapaxes(Qc, -1, -2))


def test_models_without_a_compiled_form_keep_numpy():
    class Custom(es.ErrorModel):
        def matrices(self, nav):
            return super().matrices(nav)

    assert ek.program(Custom("full", [es.gyro_bias()])) is None


def test_invalid_navigation_point_is_refused():
    model = MODELS["full-21"]()
    prog = ek.program(model)
    rows, w, f = _points(np.random.default_rng(1), 1, 5)
    rows[0, 3, 5] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        ek.matrices_rows(prog, rows, w, f)
    rows[0, 3, 5] = 0.0
    rows[0, 2, 7] = 1.6
    with pytest.raises(ValueError, match="latitude"):
        ek.matrices_rows(prog, rows, w, f)


def _scenario(duration=120.0, rate=100.0, seed=3):
    from sinslab.core.earth import radii
    from sinslab.core.records import NavState
    from sinslab.sim import imu as imu_mod
    from sinslab.sim import trajectory as tr
    segs = [tr.Level(duration=30.0), tr.Turn(duration=40.0, rate=2 * u.deg),
            tr.Accelerate(duration=20.0, accel=1.0), tr.Climb(duration=30.0, angle=3 * u.deg)]
    start = tr.Start(lat=32 * u.deg, lon=118 * u.deg, h=1000.0, speed=60.0, heading=0.3)
    gen = tr.generate(segs, start, 1.0 / rate, duration=duration)
    err = imu_mod.ImuErrors.from_datasheet(gyro_bias="0.5 deg/h", gyro_arw="0.05 deg/sqrt(h)",
                                           accel_bias="200 ug", accel_vrw="50 ug/sqrt(Hz)")
    meas = imu_mod.apply(gen.imu, err, seed)
    tru = gen.truth
    att0 = tru.att_imu[0] if tru.att_imu is not None else tru.att[0]
    idx = np.arange(int(rate), tru.t.size, int(rate))
    rm, rn = radii(tru.lat[idx], tru.h[idx])
    e = np.random.default_rng(seed).normal(size=(idx.size, 3)) * [3.0, 3.0, 5.0]
    fix = np.stack([tru.lat[idx] + e[:, 0] / rm, tru.lon[idx] + e[:, 1] / (rn * np.cos(tru.lat[idx])),
                    tru.h[idx] + e[:, 2]], -1)
    init = NavState(tru.lat[0], tru.lon[0], tru.h[0], tru.vel[0] + [0.1, -0.1, 0.05],
                    att0 + np.array([1, 1, 5]) * u.arcmin, tru.t[0])
    return meas, init, tru.t[idx], fix


def _rel(a, b):
    return float(np.max(np.abs(a - b) / np.maximum(np.abs(b).max(0), 1e-300)))


@pytest.mark.parametrize("case", ["full-rate-21", "lagged-fixes"])
def test_driver_run_compiled_equals_numpy(case):
    from sinslab.fusion import loosely_coupled as LC
    meas, init, ft, fix = _scenario()
    model = MODELS["full-21"]() if case == "full-rate-21" else LC.lc_model(0.05 * u.dpsh, 50 * u.ugpsHz)
    n = model.n
    P0 = np.diag(np.r_[[(2 * u.arcmin) ** 2] * 2, (10 * u.arcmin) ** 2, [0.2 ** 2] * 3,
                       (5 / 6.4e6) ** 2, (5 / 5.4e6) ** 2, 25.0, [(1 * u.dph) ** 2] * 3,
                       [(500 * u.ug) ** 2] * 3, [(100 * u.ppm) ** 2] * (n - 15)])
    from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec
    full = case == "full-rate-21"
    fixes = FixSpec(ft, fix, [3.0, 3.0, 5.0], latency=0.0 if full else 0.25)
    out = {}
    for mode in ("compiled", "numpy"):
        grid = FilterGrid(meas.dt if full else 0.1, model_eval=mode)
        out[mode] = LC.loosely_coupled(meas, init, fixes, P0, model, ins=InsSpec(nsub=1 if full else 2),
                                       grid=grid, progress=False)
    a, b = out["compiled"], out["numpy"]
    assert a.t.size == b.t.size > 1000 if case == "full-rate-21" else a.t.size == b.t.size
    assert _rel(a.nav, b.nav) < 1e-9
    assert _rel(a.sigma, b.sigma) < 1e-9
    assert np.max(np.abs(a.x - b.x) / np.maximum(b.sigma, 1e-300)) < 1e-9
    assert np.array_equal(a.nis == 0, b.nis == 0)
    assert np.max(np.abs(a.nis - b.nis)) < 1e-9 * max(1.0, np.abs(b.nis).max())
