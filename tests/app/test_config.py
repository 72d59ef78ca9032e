"""Config models: unit strings, ranges, unknown keys, TOML files, --set, resolution order."""
import math
import tomllib

import numpy as np
import pytest

from sinslab.core import units
from sinslab.app.config import (ConfigError, ExperimentConfig, Field, ImuSection, Q, QV, Quantity, Section,
                                config_to_toml, describe, dump_toml, imu_section, load_toml, parse_set, resolve)


class Scen(Section):
    latitude: Q("angle", ge="-90 deg", le="90 deg") = "34.246 deg"
    duration: Q("time", gt="0 s") = "20 min"
    steps: int = Field(3, ge=1)


class Imu(Section):
    gyro_bias: QV("angular_rate") = "0.01 deg/h"
    accel_noise: Q("velocity_random_walk", ge="0 ug/sqrt(Hz)") = "10 ug/sqrt(Hz)"


class Cfg(ExperimentConfig):
    scenario: Scen = Scen()
    imu: Imu = Imu()


def test_quantities_are_si_and_keep_their_text():
    c = Cfg()
    assert isinstance(c.scenario.latitude, Quantity)
    assert c.scenario.latitude == pytest.approx(34.246 * units.deg)
    assert c.scenario.latitude.text == "34.246 deg"
    assert c.scenario.duration == 1200.0
    assert np.allclose(c.imu.gyro_bias, [0.01 * units.dph] * 3)
    dumped = c.model_dump(mode="json")
    assert dumped["scenario"]["duration"] == "20 min"
    assert dumped["imu"]["gyro_bias"] == "0.01 deg/h"


def test_vector_forms():
    for v in ("[1, 2, 3] deg/h", ["1 deg/h", "2 deg/h", "3 deg/h"]):
        c = resolve(Cfg, overrides={"imu": {"gyro_bias": v}})
        assert np.allclose(c.imu.gyro_bias, np.array([1, 2, 3]) * units.dph)
        assert c.model_dump(mode="json")["imu"]["gyro_bias"] == v


@pytest.mark.parametrize("sets, words", [
    (["scenario.latitude=95 deg"], ["scenario.latitude", "out of range", "90 deg"]),
    (["scenario.latitude=12"], ["scenario.latitude", "no unit", "12 deg"]),
    (["scenario.latitude=10 m"], ["scenario.latitude", "length", "angle"]),
    (["scenario.duration=-1 s"], ["scenario.duration", "out of range"]),
    (["scenario.steps=0"], ["scenario.steps", "greater than or equal to 1"]),
    (["scenario.steps=abc"], ["scenario.steps", "integer"]),
    (["imu.gyro_bias=[1, 2] deg/h"], ["imu.gyro_bias", "3 values"]),
    (["imu.gyro_bias=0.01"], ["imu.gyro_bias", "no unit"]),
    (["imu.gyro_bais=0.01 deg/h"], ["unknown config key imu.gyro_bais", "did you mean imu.gyro_bias"]),
    (["imu.xyz=1"], ["unknown config key imu.xyz", "known keys in imu"]),
    (["nosuch.key=1"], ["unknown config key nosuch"]),
    (["imu.accel_noise=-1 ug/sqrt(Hz)"], ["imu.accel_noise", "out of range"]),
    (["seed=-3"], ["seed"]),
])
def test_bad_values_name_the_key_in_one_line(sets, words):
    with pytest.raises(ConfigError) as e:
        resolve(Cfg, sets=sets)
    msg = str(e.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)
    assert "--set" in msg


@pytest.mark.parametrize("item", ["novalue", "=3", "a..b=1", "a.b=", "1abc=2"])
def test_set_syntax_errors(item):
    with pytest.raises(ConfigError, match="--set"):
        parse_set([item])


def test_set_values_are_toml_or_plain_strings():
    d, origin = parse_set(["a.b=3", "a.c=true", "a.d=2 h", 'a.e="4 deg"', "a.f=[1, 2]", "x=1.5"])
    assert d == {"a": {"b": 3, "c": True, "d": "2 h", "e": "4 deg", "f": [1, 2]}, "x": 1.5}
    assert origin["a.d"] == "a.d=2 h"


def test_files(tmp_path):
    p = tmp_path / "c.toml"
    with pytest.raises(ConfigError, match="not found"):
        load_toml(p)
    p.write_text("")
    with pytest.raises(ConfigError, match="c.toml: is empty"):
        load_toml(p)
    p.write_text("   \n# only a comment\n")
    with pytest.raises(ConfigError, match="empty|no settings"):
        load_toml(p)
    p.write_text("[scenario\nlatitude = 1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_toml(p)
    p.write_bytes(b"\xff\xfe\x00bad")
    with pytest.raises(ConfigError, match="UTF-8"):
        load_toml(p)
    with pytest.raises(ConfigError, match="folder"):
        load_toml(tmp_path)
    p.write_text('[scenario]\nlatitude = 45\n')
    with pytest.raises(ConfigError, match=r"scenario.latitude \(config file .*c.toml\): 45 has no unit"):
        resolve(Cfg, file=p)


def test_resolution_order(tmp_path):
    p = tmp_path / "c.toml"
    p.write_text('[scenario]\nlatitude = "10 deg"\nduration = "5 min"\n')
    quick = {"scenario": {"duration": "1 min", "steps": 7}}
    c = resolve(Cfg, quick=quick, file=p, sets=["scenario.duration=2 min"], overrides={"seed": 5})
    assert c.scenario.latitude.text == "10 deg"       # file over default
    assert c.scenario.duration.text == "2 min"        # --set over file over quick
    assert c.scenario.steps == 7                      # quick over default
    assert c.seed == 5


def test_resolved_toml_round_trip(tmp_path):
    c = resolve(Cfg, sets=["imu.gyro_bias=[0.003, -0.002, 0.0005] deg/h", "seed=9"])
    text = config_to_toml(c, "header line\nsecond")
    assert text.startswith("# header line\n# second\n")
    p = tmp_path / "r.toml"
    p.write_text(text)
    c2 = resolve(Cfg, file=p)
    assert c2.model_dump(mode="json") == c.model_dump(mode="json")
    assert np.allclose(c2.imu.gyro_bias, c.imu.gyro_bias)


def test_dump_toml_values():
    d = {"a": 1, "b": 2.5, "c": "x \"q\" é", "d": [1, 2], "e": True, "n": None,
         "f": float("inf"), "t": {"u": {"v": 1}, "w": "z"}, "key with space": 3}
    back = tomllib.loads(dump_toml(d))
    assert back["c"] == d["c"] and back["t"] == {"w": "z", "u": {"v": 1}}
    assert "n" not in back and math.isinf(back["f"]) and back["key with space"] == 3


def test_describe_lists_dotted_keys():
    keys = {k: v for k, v, _ in describe(Cfg)}
    assert keys["scenario.latitude"] == "34.246 deg"
    assert keys["seed"] == 0 and "imu.gyro_bias" in keys


SharedImu = imu_section("SharedImu", {
    "gyro_bias": "[0.003, -0.002, 0.0005] deg/h", "gyro_arw": "0.001 deg/sqrt(h)",
    "gyro_bias_instability": "0.02 deg/h", "gyro_corr_time": "300 s",
    "accel_bias": "50 ug", "accel_vrw": "10 ug/sqrt(Hz)", "accel_scale_factor": "-120 ppm",
    "accel_bias_sigma": "100 ug",
}, scalar=("gyro_arw",), renamed={"gyro_noise": "gyro_arw"})


class ImuCfg(ExperimentConfig):
    imu: SharedImu = SharedImu()


def test_imu_section_errors_equal_the_datasheet_parse():
    """The shared IMU section parses once; its ImuErrors equal those the simulator's own
    datasheet parser (an independent path, sim.imu.ImuErrors.from_datasheet) builds from the
    same text, and the 1σ term stays out of the errors."""
    from sinslab.sim.imu import ImuErrors

    c = resolve(ImuCfg, sets=["imu.accel_vrw=[5, 6, 7] ug/sqrt(Hz)"])
    assert isinstance(c.imu, ImuSection)
    texts = {k: v for k, v in c.imu.model_dump(mode="json").items() if not k.endswith("_sigma")}
    ref = ImuErrors.from_datasheet(**texts)
    got = c.imu.errors()
    for k in texts:
        assert np.array_equal(getattr(got, k), getattr(ref, k)), k
    assert np.array_equal(got.accel_bias, np.full(3, 50 * units.ug))         # not the 1σ (100 ug)
    assert np.array_equal(c.imu.sigma("accel_bias"), np.full(3, 100 * units.ug))
    assert not got.gyro_scale_factor.any()                                   # a term it lacks is zero


@pytest.mark.parametrize("item, words", [
    ("imu.gyro_noise=1 deg/sqrt(h)", ["config key imu.gyro_noise", "renamed: use imu.gyro_arw"]),
    ("imu.gyro_nois=1 deg/sqrt(h)", ["unknown config key imu.gyro_nois", "did you mean imu.gyro_arw"]),
    ("imu.gyro_arw=[1, 2, 3] deg/sqrt(h)", ["imu.gyro_arw"]),               # a scalar term
    ("imu.accel_bias_sigma=-1 ug", ["imu.accel_bias_sigma", "out of range"]),
])
def test_imu_section_errors_name_the_key(item, words):
    with pytest.raises(ConfigError) as e:
        resolve(ImuCfg, sets=[item])
    assert all(w in str(e.value) for w in words), str(e.value)


def test_imu_section_refuses_unknown_terms():
    with pytest.raises(ValueError, match="gyro_drift"):
        imu_section("Bad", {"gyro_drift": "1 deg/h"})
