"""Experiment schuler-suppression on --quick runs: the metric contract, claims computed from
the run (and able to fail), the injected ship scenario's suppression, config errors."""

import pytest

from sinslab.app.config import ConfigError, resolve
from sinslab.experiments import execute, get

CH = ("vE", "vN", "phiE", "phiN", "lat", "lon")


def _run(tmp_path, name, sets):
    exp = get("schuler-suppression")
    cfg = resolve(exp.config, quick=exp.quick, sets=sets)
    return execute(exp, cfg, tmp_path / name, quick=True)


@pytest.fixture(scope="module")
def ship_injected(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("ss"), "ship_inj", ["init.mode=injected"])


@pytest.fixture(scope="module")
def turntable_aligned(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("ss"), "tt", ["scenario.kind=turntable",
                                                       "turntable.duration=4 h"])


def _check_contract(s):
    m = s["metrics"]
    for x in CH:
        for k in (f"schuler_amp_{x}_single", f"schuler_amp_{x}_mean", f"suppression_{x}",
                  f"earth_amp_{x}_single", f"earth_amp_{x}_mean"):
            assert k in m, k
        assert m[f"suppression_{x}"] == pytest.approx(
            m[f"schuler_amp_{x}_single"] / m[f"schuler_amp_{x}_mean"])
    for k in ("schuler_period_min", "t1_s", "t2_s", "runtime_s"):
        assert k in m
    assert m["schuler_period_min"] == pytest.approx(84.4, abs=0.2)
    assert m["t2_s"] - m["t1_s"] == pytest.approx(m["schuler_period_min"] * 30, abs=1.0)
    info = s["metric_info"]
    assert "m/s" in info["schuler_amp_vE_single"]["unit"]
    assert "arcmin" in info["schuler_amp_phiN_mean"]["unit"]
    assert "arcsec" in info["earth_amp_lat_single"]["unit"]


def test_ship_injected_quick(ship_injected, tmp_path):
    s = ship_injected
    _check_contract(s)
    m = s["metrics"]
    claims = {c["id"]: c for c in s["claims"]}
    # injected initial errors start a large Schuler oscillation: the mean cancels it
    assert claims["suppression_velocity"]["passed"], claims["suppression_velocity"]
    assert claims["suppression_level_attitude"]["passed"]
    assert min(m["suppression_vE"], m["suppression_vN"]) >= 2
    assert "real_alignments" not in claims                       # injected mode
    # verdicts follow the measurements (claims can fail)
    for c in s["claims"]:
        if c["id"].startswith("suppression"):
            assert c["passed"] == all(v >= 2 for v in c["measured"]["value"])
    for f in ("attitude_errors", "velocity_errors", "position_errors", "spectrum"):
        assert any(f in x for x in map(str, s["figures"])), f
    # the run folder holds the contract files
    out = tmp_path.parent
    assert m["t1_s"] == pytest.approx(3600.0)


def test_turntable_aligned_quick(turntable_aligned):
    s = turntable_aligned
    _check_contract(s)
    claims = {c["id"]: c for c in s["claims"]}
    assert claims["real_alignments"]["passed"]
    ends = claims["real_alignments"]["measured"]["value"]["align_end_s"]
    assert ends[0] == pytest.approx(s["metrics"]["t1_s"]) and ends[1] == pytest.approx(s["metrics"]["t2_s"])
    # a 4 h record cannot resolve the 24 h line: that claim fails, saying why
    assert not claims["earth_period_kept"]["passed"]
    for c in s["claims"]:
        if c["id"].startswith("suppression"):
            assert c["passed"] == all(v >= 2 for v in c["measured"]["value"])
            if not c["passed"]:
                assert "noise" in c["statement"]
    assert s["config"]["scenario"]["kind"] == "turntable"
    assert s["config"]["turntable"]["imu"]["gyro_arw"] == "0.005 deg/sqrt(h)"


def test_config_errors():
    exp = get("schuler-suppression")
    with pytest.raises(ConfigError, match="scenario.kind"):
        resolve(exp.config, sets=["scenario.kind=boat"])
    with pytest.raises(ConfigError, match="ship.imu.gyro_bias"):
        resolve(exp.config, sets=["ship.imu.gyro_bias=0.01 m"])
    with pytest.raises(ConfigError, match="init.mode"):
        resolve(exp.config, sets=["init.mode=guess"])
    with pytest.raises(ConfigError, match="scenario.t1"):
        resolve(exp.config, sets=["scenario.t1=5"])
    cfg = resolve(exp.config)
    assert cfg.scenario.kind == "ship" and cfg.init.mode == "aligned"
    assert float(cfg.ship.duration) == 48 * 3600 and float(cfg.turntable.duration) == 24 * 3600


def test_bad_delay_is_a_clear_error(tmp_path):
    exp = get("schuler-suppression")
    cfg = resolve(exp.config, quick=exp.quick, sets=["scenario.delay=-5 min"])
    with pytest.raises(ValueError, match="positive duration"):
        exp.run(cfg, type("C", (), {"log": staticmethod(lambda m: None), "seed": 0,
                                    "rng": lambda self, *a: None})())
