"""free-inertial: oracles of its analysis, an end-to-end quick run, and claims that can fail."""
import json

import numpy as np
import pytest
from typer.testing import CliRunner

import sinslab.experiments as E
from sinslab.core import earth, units
from sinslab.cli import app
from sinslab.app.config import ConfigError, resolve
from sinslab.experiments import free_inertial as fi
from sinslab.methods import free_inertial as fim

CONTRACT = ["max_horiz_pos_err_m", "final_horiz_pos_err_m", "max_horiz_vel_err_mps",
            "final_att_err_arcsec", "schuler_period_min", "samples", "runtime_s"]


def _run(tmp_path, sets, quick=True, name="r"):
    exp = E.get("free-inertial")
    cfg = resolve(exp.config, quick=exp.quick if quick else None, sets=sets)
    return E.execute(exp, cfg, tmp_path / name, quick=quick), tmp_path / name


def test_quick_run_end_to_end(tmp_path):
    s, d = _run(tmp_path, [])
    m = s["metrics"]
    for k in CONTRACT:
        assert k in m
    assert m["schuler_period_min"] is None                  # 10 min < one Schuler period
    assert len(m["final_att_err_arcsec"]) == 3
    assert m["samples"] == 30000
    assert 0 < m["max_horiz_pos_err_m"] < 200
    ids = {c["id"]: c["passed"] for c in s["claims"]}
    assert "schuler_period" not in ids
    assert all(ids.values()), s["claims"]
    for f in ("pos_err", "vel_err", "att_err", "track"):
        assert (d / f"{f}.png").is_file() and (d / f"{f}.svg").is_file()
    assert (d / "errors.csv").is_file() and (d / "truth.csv").is_file()
    written = json.loads((d / "summary.json").read_text())
    assert written["metrics"]["schuler_period_min"] is None


def test_schuler_period_over_one_period(tmp_path):
    s, _ = _run(tmp_path, ["scenario.duration=90 min", "scenario.sample_interval=0.05 s",
                           "nav.output_interval=2 s"])
    m = s["metrics"]
    c = {c["id"]: c for c in s["claims"]}
    assert c["schuler_period"]["passed"], c["schuler_period"]
    assert m["schuler_period_min"] == pytest.approx(m["schuler_period_theory_min"], rel=0.01)
    assert all(x["passed"] for x in s["claims"]), s["claims"]


def test_static_run_direct_fit_is_schuler(tmp_path):
    """At rest (no heading modulation) the plain fit of the error itself finds the Schuler period."""
    s, _ = _run(tmp_path, ["scenario.motion=static", "scenario.duration=90 min",
                           "scenario.sample_interval=0.1 s", "nav.output_interval=2 s",
                           "imu.gyro_arw=0 deg/sqrt(h)", "imu.accel_vrw=0 ug/sqrt(Hz)",
                           "imu.accel_bias=[100, -80, 0] ug", "imu.gyro_bias=0 deg/h"])
    m = s["metrics"]
    assert m["schuler_period_direct_min"] == pytest.approx(m["schuler_period_theory_min"], rel=0.01)
    # static bias-driven error: position error stays near the closed-form 2∇/ω_s² scale
    ws2 = earth.gravity(32 * units.deg, 1000.0) / 6.37e6
    assert m["max_horiz_pos_err_m"] < 2 * np.hypot(100, 80) * units.ug / ws2 * 1.5


def test_claims_fail_when_navigation_is_wrong(tmp_path, monkeypatch):
    """A navigation solution with an extra 0.05 m/s north drift must fail the model claims."""
    from sinslab.nav import strapdown
    from sinslab.core.records import NavSeries

    real = strapdown.navigate

    def drifting(*a, **kw):
        nav = real(*a, **kw)
        dt = nav.t - nav.t[0]
        rm, _ = earth.radii(nav.lat, nav.h)
        vel = nav.vel.copy()
        vel[:, 1] += 0.05
        return NavSeries(nav.t, nav.lat + 0.05 * dt / rm, nav.lon, nav.h, vel, nav.att, nav.att_imu)

    monkeypatch.setattr(strapdown, "navigate", drifting)
    s, _ = _run(tmp_path, [])
    c = {c["id"]: c["passed"] for c in s["claims"]}
    assert not c["pos_linear_model"] and not c["vel_linear_model"]


@pytest.mark.parametrize("sets, needle", [
    (["scenario.motion_file=/nonexistent/motion.toml"], "scenario.motion_file"),
    (["scenario.duration=1 s"], "shorter than two output intervals"),
    (["imu.gyro_bias=0.01"], "imu.gyro_bias"),
    (["scenario.latitude=91 deg"], "scenario.latitude"),
    (["runs=0"], "runs"),
    (["runs=20", "montecarlo.transient=2 h"], "montecarlo.transient"),
    (["runs=20", "montecarlo.output_interval=20 min", "scenario.duration=30 min"],
     "shorter than two Monte Carlo output intervals"),
    (["nav.vertical=sideways"], "nav.vertical"),
])
def test_bad_config(sets, needle):
    exp = E.get("free-inertial")
    with pytest.raises(ConfigError, match=needle.replace(".", r"\.")):
        resolve(exp.config, sets=sets)


def test_cli_quick_run(tmp_path):
    r = CliRunner().invoke(app, ["run", "free-inertial", "--quick", "--out", str(tmp_path / "q"),
                                 "--set", "scenario.duration=5 min"])
    assert r.exit_code == 0, r.output
    s = json.loads((tmp_path / "q" / "summary.json").read_text())
    assert s["config"]["scenario"]["duration"] == "5 min"
    assert s["metrics"]["samples"] == 15000


# ---------------------------------------------------------------- Monte Carlo (--runs N)

MC_KEYS = ["pos_e", "pos_n", "vel_e", "vel_n", "phi_e", "phi_n", "phi_u"]


def test_mc_ratio_bounds_follow_the_chi_square_sampling_interval():
    from scipy import stats
    assert fi.mc_ratio_bounds(200) == (0.8, 1.2)           # chi-square 0.84-1.17 is inside
    lo, hi = fi.mc_ratio_bounds(20)
    assert lo == pytest.approx(np.sqrt(stats.chi2.ppf(0.0005, 20) / 20)) and lo == pytest.approx(0.52, abs=0.01)
    assert hi == pytest.approx(np.sqrt(stats.chi2.ppf(0.9995, 20) / 20)) and hi == pytest.approx(1.54, abs=0.01)


@pytest.fixture(scope="module")
def clusters():
    """A 1-worker and a 2-worker local Dask cluster, used through their addresses (--scheduler)."""
    import logging
    from distributed import LocalCluster
    cs = [LocalCluster(n_workers=k, threads_per_worker=1, processes=True, dashboard_address=":0",
                       silence_logs=logging.ERROR) for k in (1, 2)]
    yield [c.scheduler_address for c in cs]
    for c in cs:
        c.close()


def _mc(tmp_path, name, scheduler, sets=(), runs=20):
    exp = E.get("free-inertial")
    cfg = resolve(exp.config, quick=exp.quick, sets=[f"runs={runs}", *sets])
    return E.execute(exp, cfg, tmp_path / name, quick=True, scheduler=scheduler), tmp_path / name


def test_quick_monte_carlo_matches_covariance_and_is_worker_independent(tmp_path, clusters):
    """20 runs of 10 min: every MC RMS / σ ratio inside the chi-square interval for 20 runs;
    the same seed gives identical Monte Carlo aggregates on a 1-worker and a 2-worker cluster."""
    s1, d1 = _mc(tmp_path, "w1", clusters[0])
    s2, d2 = _mc(tmp_path, "w2", clusters[1])
    m = s1["metrics"]
    assert m["mc_runs"] == 20
    assert m["mc_ratio_bounds"] == pytest.approx(list(fi.mc_ratio_bounds(20)))
    c = {c["id"]: c for c in s1["claims"]}
    for k in MC_KEYS:
        assert c[f"mc_rms_over_sigma_{k}"]["passed"], c[f"mc_rms_over_sigma_{k}"]
        lo, hi = m[f"mc_rms_over_sigma_{k}"]
        assert 0.52 <= lo <= hi <= 1.54
    assert all(x["passed"] for x in s1["claims"]), s1["claims"]
    for f in ("mc_rms_sigma", "mc_ratio"):
        assert (d1 / f"{f}.png").is_file()
    assert (d1 / "table_mc_vs_covariance.csv").is_file()
    # identical aggregates whatever the number of workers
    assert (d1 / "montecarlo.csv").read_bytes() == (d2 / "montecarlo.csv").read_bytes()
    assert (d1 / "table_mc_vs_covariance.csv").read_bytes() == (d2 / "table_mc_vs_covariance.csv").read_bytes()
    for k in MC_KEYS:
        assert s1["metrics"][f"mc_rms_over_sigma_{k}"] == s2["metrics"][f"mc_rms_over_sigma_{k}"]


def test_mc_batch_draws_and_navigates_like_the_covariance_model():
    """Direct library check on a short static run (sync): the biases are drawn from their 1σ
    (``imu.*_sigma``), so the run-to-run spread of the east velocity error after 5 min
    matches the model's σ, and the
    covariance analysis reproduces the closed-form static tilt from an accelerometer bias."""
    from sinslab.estimation import montecarlo as mc
    from sinslab.sim import trajectory as tr

    cfg = resolve(fi.Config, sets=["scenario.motion=static", "scenario.duration=5 min",
                                   "scenario.sample_interval=0.1 s", "imu.gyro_bias_sigma=0 deg/h",
                                   "imu.gyro_arw=0 deg/sqrt(h)", "imu.accel_vrw=0 ug/sqrt(Hz)",
                                   "imu.accel_bias_sigma=100 ug", "runs=2"])
    segs, start, mount = fi._motion(cfg)
    gen = tr.generate(segs, start, 0.1, duration=300.0, mount=mount)
    spec = fi._mc_spec(cfg, segs, start, mount)
    cov_every, _ = fi._mc_strides(cfg)
    t, sigma, model = fim.covariance_analysis(gen.truth, gen.imu, spec, cov_every)
    assert model.core == "horizontal"                      # vertical held by default
    # static, accel bias only: δv_N σ = ∇ sin(ω_s t)/ω_s (Schuler loop; Earth rate negligible over 5 min)
    ws = 2 * np.pi / earth.schuler_period(start.lat, start.h)
    ref = 100 * units.ug * np.sin(ws * (t - t[0])) / ws
    assert np.allclose(sigma[:, 4], ref, rtol=0.02, atol=1e-6)
    out = mc.run_campaign(fi.mc_batch, 400, 3, batch=100, scheduler="sync", progress=False,
                          kwargs=dict(spec=spec))
    rms = np.sqrt(np.mean(out["err"][:, -1, 4] ** 2))
    assert rms / sigma[-1, 4] == pytest.approx(1.0, abs=0.12)   # 400 runs: ~3.5 % sampling σ


@pytest.mark.parametrize("vertical", ["hold", "free", "damped"])
def test_mc_batch_stacked_runs_equal_one_run_at_a_time(vertical):
    """A stacked batch (held vertical rate shared, errors of all runs in one pass) returns,
    run for run, the bytes of :func:`mc_run`, a run made alone with the public functions
    (``imu.apply``, ``strapdown.navigate`` differentiating the held height itself,
    ``attitude.misalignment``); its errors are those of the documented draws (initial
    position error of the run = its first normal draws times σ)."""
    from sinslab.sim import trajectory as tr

    cfg = resolve(fi.Config, sets=["scenario.duration=4 min", "scenario.sample_interval=0.05 s",
                                   f"nav.vertical={vertical}", "init.att_err=[20, 20, 60] arcsec",
                                   "init.pos_err=[3, 3, 1] m", "runs=3"])
    segs, start, mount = fi._motion(cfg)
    spec = fi._mc_spec(cfg, segs, start, mount)
    fi._mc_setup(spec, tr.generate(segs, start, 0.05, duration=240.0, mount=mount))
    seeds = np.random.SeedSequence(11).spawn(3)
    stacked = fi.mc_batch(seeds, spec)["err"]
    for b, seed in enumerate(seeds):
        assert np.array_equal(fi.mc_run(seed, spec), stacked[b])
        z = np.random.default_rng(seed).standard_normal(9)
        assert stacked[b, 0, :2] == pytest.approx(z[6:8] * 3.0, rel=1e-6)


def test_mc_claims_fail_on_a_units_slip(tmp_path, monkeypatch):
    """A covariance σ three times too large (e.g. a units slip) must fail the MC claims."""
    real = fim.covariance_analysis

    def wrong(*a, **kw):
        t, s, m = real(*a, **kw)
        return t, 3.0 * s, m

    monkeypatch.setattr(fim, "covariance_analysis", wrong)
    s, _ = _mc(tmp_path, "bad", "sync", sets=["scenario.duration=5 min"], runs=10)
    c = {c["id"]: c["passed"] for c in s["claims"]}
    assert not any(c[f"mc_rms_over_sigma_{k}"] for k in MC_KEYS)
    assert c["pos_linear_model"]                          # the single-run claims are untouched


def test_monte_carlo_free_vertical_channel_matches_full_covariance_model(tmp_path):
    """Free vertical channel: the full 15-state φ-angle model (δh, δv_U included, whose
    vertical instability grows ~exp(√2 ω_s t)) still predicts the Monte Carlo RMS of every
    error within the chi-square interval for 100 runs of 10 min."""
    s, _ = _mc(tmp_path, "free", "sync", sets=["nav.vertical=free"], runs=100)
    lo_b, hi_b = fi.mc_ratio_bounds(100)
    for k in MC_KEYS:
        lo, hi = s["metrics"][f"mc_rms_over_sigma_{k}"]
        assert lo_b <= lo <= hi <= hi_b, (k, lo, hi)
