"""The `sinslab` CLI and the run contract (DESIGN §4), on a small test experiment."""
import json
import os
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import sinslab.experiments as E
from sinslab import __version__
from sinslab.cli import app
from sinslab.experiments.base import Claim, ExperimentConfig, Field, Figure, Metric, Q, QV, Result, Section, Table

HERE = Path(__file__).resolve().parent


# ------------------------------------------------------------------ test experiment -----
class _Scenario(Section):
    duration: Q("time", gt="0 s", le="1 d") = "100 s"
    latitude: Q("angle", ge="-90 deg", le="90 deg") = "34 deg"
    rows: int = Field(50, ge=2)
    sleep_s: float = Field(0.0, ge=0)


class _Imu(Section):
    gyro_bias: QV("angular_rate") = "0.01 deg/h"


class _Config(ExperimentConfig):
    scenario: _Scenario = _Scenario()
    imu: _Imu = _Imu()


def _run(cfg, ctx):
    from sinslab.app import plotting as P

    t = np.linspace(0.0, float(cfg.scenario.duration), cfg.scenario.rows)
    with ctx.progress("waiting", total=1) as bar:
        time.sleep(cfg.scenario.sleep_s)
        bar.advance(1)
    x = np.sin(t / 10) + ctx.rng(1).normal(size=t.size) * 1e-3
    figs = [Figure("wave", P.error_figure(t, [("x [m]", np.c_[x, -x], ["x", "-x"])]), "a wave"),
            Figure("bias", P.error_figure(t, [("b", np.c_[t * 0 + float(cfg.imu.gyro_bias[0])], ["b"])]),
                   "bias")]
    return Result(
        metrics={"final_x_m": float(x[-1]), "bias_dph": np.asarray(cfg.imu.gyro_bias) / (np.pi / 180 / 3600),
                 "nothing": None},
        claims=[Claim.within("lat", "latitude is 34 deg", float(cfg.scenario.latitude) * 180 / np.pi, 34.0,
                             abs=1e-9, unit="deg", origin="paper"),
                Claim.at_most("small", "|x| stays below 2 m", float(np.abs(x).max()), 2.0, "m", origin="check")],
        series={"wave": {"t_s": t, "x_m": x}},
        figures=figs,
        tables=[Table("stats", {"stat": ["mean", "max"], "value": [float(x.mean()), float(x.max())]}, "stats")],
        notes=["a note"])


class Dummy:
    """A registrable experiment (module-like)."""

    NAME = "dummy"
    PURPOSE = "test experiment for the CLI"
    Config = _Config
    QUICK = {"scenario": {"duration": "10 s", "rows": 20}}
    METRICS = {"final_x_m": Metric("m", "last x"), "bias_dph": Metric("deg/h", "bias"),
               "nothing": Metric("-", "always null")}
    DEMO_VARIANTS = {"north": ["scenario.latitude=60 deg"]}
    run = staticmethod(_run)


@pytest.fixture(autouse=True, scope="module")
def _registered():
    E.register(Dummy)
    yield


runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def tree(d):
    return sorted(p.relative_to(d).as_posix() for p in Path(d).rglob("*"))


# ------------------------------------------------------------------ happy path ----------
def test_list_shows_experiments():
    r = invoke("list")
    assert r.exit_code == 0
    assert "dummy" in r.stdout and "test experiment for the CLI" in r.stdout
    assert "free-inertial" in r.stdout


def test_run_writes_the_contract(tmp_path):
    out = tmp_path / "r"
    r = invoke("run", "dummy", "--out", out, "--seed", 3, "--set", "imu.gyro_bias=0.02 deg/h")
    assert r.exit_code == 0, r.output
    names = tree(out)
    for f in ("config.toml", "summary.json", "report.html", "wave.csv", "wave.png", "wave.svg",
              "bias.png", "bias.svg", "table_stats.csv", ".sinslab-run"):
        assert f in names
    assert not [n for n in names if ".tmp-" in n]
    s = json.loads((out / "summary.json").read_text())
    assert s["experiment"] == "dummy" and s["sinslab_version"] == __version__
    assert set(s["claims"][0]) == {"id", "statement", "measured", "expected", "passed", "origin"}
    assert [c["origin"] for c in s["claims"]] == ["paper", "check"]
    assert [c["passed"] for c in s["claims"]] == [True, True]
    assert s["metrics"]["bias_dph"] == pytest.approx([0.02] * 3)
    assert s["metrics"]["nothing"] is None and s["metrics"]["runtime_s"] > 0
    assert s["config"]["seed"] == 3 and s["config"]["imu"]["gyro_bias"] == "0.02 deg/h"
    cfg = tomllib.loads((out / "config.toml").read_text())
    assert cfg["seed"] == 3 and cfg["imu"]["gyro_bias"] == "0.02 deg/h"
    assert json.loads((out / ".sinslab-run").read_text())["status"] == "complete"
    assert "2/2 claims passed (paper: 1 of 1 reproduced · checks: 1 of 1)" in r.stdout
    assert "[pass] lat (paper):" in r.stdout
    html = (out / "report.html").read_text()
    assert "paper: 1 of 1 reproduced · checks: 1 of 1" in html


def test_config_toml_reproduces_the_run(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert invoke("run", "dummy", "--quick", "--out", a, "--seed", 7).exit_code == 0
    r = invoke("run", "dummy", "--config", a / "config.toml", "--out", b)
    assert r.exit_code == 0, r.output
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert sa["config"] == sb["config"]
    assert sa["metrics"]["final_x_m"] == sb["metrics"]["final_x_m"]
    assert (a / "wave.csv").read_bytes() == (b / "wave.csv").read_bytes()


def test_default_out_dir(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = invoke("run", "dummy", "--quick")
    assert r.exit_code == 0, r.output
    (d,) = list((tmp_path / "runs").iterdir())
    assert d.name.startswith("dummy-") and (d / "summary.json").is_file()


def test_rerun_into_previous_run_folder(tmp_path):
    out = tmp_path / "r"
    assert invoke("run", "dummy", "--quick", "--out", out).exit_code == 0
    r = invoke("run", "dummy", "--quick", "--out", out, "--set", "scenario.rows=30")
    assert r.exit_code == 0, r.output
    assert len((out / "wave.csv").read_text().splitlines()) == 31
    assert not [p for p in tmp_path.iterdir() if p.name != "r"]      # no staging left
    # a file the user put there is never deleted silently: refused, unless --force
    (out / "mine.txt").write_text("user file")
    before = tree(out)
    r = invoke("run", "dummy", "--quick", "--out", out)
    assert r.exit_code == 2 and "mine.txt" in r.output and "--force" in r.output
    assert tree(out) == before
    r = invoke("run", "dummy", "--quick", "--out", out, "--force")
    assert r.exit_code == 0, r.output
    assert "mine.txt" not in tree(out) and "summary.json" in tree(out)


def test_report_rebuilds(tmp_path):
    out = tmp_path / "r"
    assert invoke("run", "dummy", "--quick", "--out", out).exit_code == 0
    (out / "report.html").unlink()
    r = invoke("report", out)
    assert r.exit_code == 0, r.output
    html = (out / "report.html").read_text()
    assert "id='claims'" in html and "data:image/png;base64," in html


def test_config_command_prints_toml():
    r = invoke("config", "dummy", "--quick", "--set", "seed=4")
    assert r.exit_code == 0
    d = tomllib.loads(r.stdout)
    assert d["seed"] == 4 and d["scenario"]["duration"] == "10 s"


def test_demo_writes_index(tmp_path):
    out = tmp_path / "runs"
    r = invoke("demo", "--out", out, "--quick", "--only", "dummy")
    assert r.exit_code == 0, r.output
    idx = (out / "index.html").read_text()
    assert "dummy/report.html" in idx and (out / "dummy" / "summary.json").is_file()
    # the declared variant runs too, with its settings, under NAME-suffix
    assert "dummy-north/report.html" in idx
    v = json.loads((out / "dummy-north" / "summary.json").read_text())
    assert v["config"]["scenario"]["latitude"] == "60 deg"


def test_strict_exit_status(tmp_path):
    r = invoke("run", "dummy", "--quick", "--out", tmp_path / "r", "--strict",
               "--set", "scenario.latitude=35 deg")
    assert r.exit_code == 1
    assert "1/2 claims passed" in r.stdout


# ------------------------------------------------------------------ bad input -----------
BAD = [
    (["--set", "imu.gyro_bais=0.02 deg/h"], "unknown config key imu.gyro_bais"),
    (["--set", "scenario.latitude=45"], "scenario.latitude"),                 # no unit
    (["--set", "scenario.latitude=95 deg"], "out of range"),
    (["--set", "scenario.duration=10 m"], "scenario.duration"),               # wrong kind
    (["--set", "scenario.rows=1"], "scenario.rows"),                          # below minimum
    (["--set", "no_equals_sign"], "--set 'no_equals_sign'"),
    (["--set", "=3"], "--set '=3'"),
    (["--config", "{missing}"], "not found"),
    (["--config", "{empty}"], "is empty"),
    (["--config", "{badtoml}"], "not valid TOML"),
    (["--config", "{unknownkey}"], "unknown config key scenario.lattitude"),
    (["--config", "{bare}"], "scenario.duration (config file"),
    (["--out", "{foreign}"], "not a previous sinslab run"),
    (["--out", "{afile}"], "is a file"),
]


@pytest.mark.parametrize("args, needle", BAD)
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, args, needle):
    files = {"missing": tmp_path / "missing.toml", "empty": tmp_path / "empty.toml",
             "badtoml": tmp_path / "bad.toml", "unknownkey": tmp_path / "unknown.toml",
             "bare": tmp_path / "bare.toml", "foreign": tmp_path / "foreign",
             "afile": tmp_path / "afile"}
    files["empty"].write_text("")
    files["badtoml"].write_text("[scenario\n")
    files["unknownkey"].write_text('[scenario]\nlattitude = "3 deg"\n')
    files["bare"].write_text("[scenario]\nduration = 100\n")
    files["foreign"].mkdir()
    (files["foreign"] / "data.txt").write_text("precious")
    files["afile"].write_text("")
    args = [a.format(**files) for a in args]
    before = tree(tmp_path)
    out = ["--out", tmp_path / "out"] if "--out" not in args else []
    r = invoke("run", "dummy", *args, *out)
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("sinslab: error: ") and needle in lines[0], lines[0]
    assert tree(tmp_path) == before                     # nothing written anywhere
    assert (files["foreign"] / "data.txt").read_text() == "precious"


def test_unknown_experiment_and_report_of_non_run(tmp_path):
    r = invoke("run", "dumy")
    assert r.exit_code == 2 and "did you mean 'dummy'" in r.stderr
    r = invoke("report", tmp_path)
    assert r.exit_code == 2 and "summary.json" in r.stderr


def test_bad_option_value_exits_2():
    assert invoke("run", "dummy", "--seed", "abc").exit_code == 2
    assert invoke("run", "dummy", "--runs", "0").exit_code == 2


