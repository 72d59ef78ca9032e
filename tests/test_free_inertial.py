"""free-inertial: oracles of its analysis, an end-to-end quick run, and claims that can fail."""
import json

import numpy as np
import pytest
import scipy.linalg
from typer.testing import CliRunner

import sinslab.experiments as E
from sinslab import earth, units
from sinslab.cli import app
from sinslab.config import ConfigError, resolve
from sinslab.experiments import free_inertial as fi

CONTRACT = ["max_horiz_pos_err_m", "final_horiz_pos_err_m", "max_horiz_vel_err_mps",
            "final_att_err_arcsec", "schuler_period_min", "samples", "runtime_s"]


def test_fit_schuler_period_recovers_a_foucault_split_oscillation():
    lat = 40 * units.deg
    ws = 2 * np.pi / earth.schuler_period(lat)
    wf = earth.WIE * np.sin(lat)
    t = np.arange(0.0, 2 * 3600.0, 1.0)
    z = np.exp(-1j * wf * t) * (0.3 * np.exp(1j * ws * t) + 0.2j * np.exp(-1j * ws * t)) + 0.05 + 1e-6 * t
    v = np.column_stack([z.real, z.imag]) + np.random.default_rng(0).normal(0, 1e-3, (t.size, 2))
    p = fi.fit_schuler_period(t, v)
    assert p == pytest.approx(2 * np.pi / ws, rel=1e-3)


def test_expm_batch_matches_scipy():
    A = np.random.default_rng(1).normal(size=(4, 9, 9)) * np.array([0.01, 1, 10, 30])[:, None, None]
    ref = np.stack([scipy.linalg.expm(a) for a in A])
    got = fi._expm_batch(A)
    assert np.allclose(got, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())


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
    from sinslab import strapdown
    from sinslab.records import NavSeries

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
    (["runs=3"], "runs"),
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
