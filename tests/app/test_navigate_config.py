"""``sinslab navigate``'s one configuration (sinslab.app.commands.navigate_config): the
defaults ``sinslab config navigate`` prints resolve back; every option is the short form of
a key; a bad key (unknown, without its unit, of an aid that is not enabled, of the GNSS
source not chosen) is one line naming it and where it came from, exit 2, nothing written;
and the run folder's ``config.toml`` re-runs the navigation: the same metrics and the same
table bytes."""
import json
import tomllib
from pathlib import Path

import pytest
from typer.testing import CliRunner

from sinslab.app.commands import navigate_config as NC
from sinslab.app.config import ConfigError
from sinslab.cli import app
from sinslab.sim import trajectory as tr
from support import simulated_car_drive


def _cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def test_config_navigate_prints_the_defaults_and_they_resolve_back(tmp_path):
    r = _cli("config", "navigate")
    assert r.exit_code == 0, r.output
    p = tmp_path / "nav.toml"
    p.write_text(r.output)
    cfg = NC.resolve_navigate(p)
    assert cfg.aid == [] and cfg.gnss.source == "fixes" and cfg.output.csv_rate == 1.0
    for name in ("zupt", "lever", "nhc", "odometer"):                  # every aid, commented out
        assert f"# [{name}]" in r.output
    r = _cli("config", "navigate", "--set", "aid=[\"nhc\", \"zaru\"]", "--set", "gnss.source=raw")
    assert r.exit_code == 0, r.output
    data = tomllib.loads(r.output)
    assert data["aid"] == ["zupt", "nhc"] and data["zupt"]["zaru"] is True and "raw" in data["gnss"]
    assert data["nhc"]["sigma"] == "[0.1, 0.1] m/s" and "fixes" not in data["gnss"]


def test_every_option_is_a_key():
    cfg = NC.resolve_navigate(given={"--aid": "zupt,lever,nhc,odometer", "--odometer": "odo.csv"})
    raw = NC.resolve_navigate(given={"--gnss-raw": "x.ubx"})
    for opt, (key, _) in NC.FLAGS.items():
        node = raw if key.startswith("gnss.raw.") else cfg
        for part in key.split("."):
            node = getattr(node, part)                                  # AttributeError: no such key
    for opt, (name, key, _) in NC._aid_flags().items():
        assert hasattr(getattr(cfg, name), key), opt


@pytest.mark.parametrize("toml, sets, msg", [
    ('[gnss.fixes]\nfromat = "csv"\n', (), "unknown config key gnss.fixes.fromat (config file {f}); did you "
                                          "mean gnss.fixes.format?"),
    ('[gnss]\nlever_arm = "[0.1, 0, 0]"\n', (), "config key gnss.lever_arm (config file {f}): '0.1' "
                                                "has no unit"),
    ('[nhc]\nsigma = "[0.2, 0.1] m/s"\n', (), "config key nhc.sigma (config file {f}): the nhc aid is not "
                                              "enabled: add --aid nhc"),
    ('aid = ["nhc"]\n[nhc]\nsigma = "0.2"\n', (), "config key nhc.sigma (config file {f}): '0.2' has no unit"),
    ('[gnss.raw]\nfile = "x.ubx"\n', (), "config key gnss.raw.file (config file {f}): the GNSS source is fixes"),
    ('aid = ["nhc", "wings"]\n', (), "config key aid (config file {f}): unknown wings"),
    ('[start]\nheading = "400 deg"\n', (), "config key start.heading (config file {f}): '400 deg' is out of range"),
    ("", ["odometer.sigma=1 m/s"], "config key odometer.sigma (--set odometer.sigma=1 m/s): the odometer aid is "
                                   "not enabled"),
])
def test_bad_keys_are_one_line_exit_2_nothing_written(tmp_path, monkeypatch, toml, sets, msg):
    # a relative path: the error line shortens a long word (a deep temporary folder) in its middle
    monkeypatch.chdir(tmp_path)
    f = Path("nav.toml")
    f.write_text(toml + '[output]\nstrict = false\n')
    out = tmp_path / "run"
    args = ["navigate", "--config", f, "--imu", "imu.csv", "--fixes", "fix.pos", "--out", out]
    for s in sets:
        args += ["--set", s]
    r = _cli(*args)
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("sinslab: error: "), r.output
    assert msg.format(f=f) in lines[0], lines[0]
    assert not out.exists()


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    from sinslab.data import write_fixes, write_imu
    d = tmp_path_factory.mktemp("log")
    segs = [tr.Static(duration=20.0), tr.Accelerate(duration=5.0, accel=2.0), tr.Level(duration=20.0),
            tr.Turn(duration=10.0, rate=9 * 3.1416 / 180, coordinated=False), tr.Level(duration=15.0),
            tr.Accelerate(duration=5.0, accel=-2.0), tr.Static(duration=10.0)]
    imu, fx, _, _, _ = simulated_car_drive(segs)
    write_imu(d / "imu.csv", imu, "csv")
    write_fixes(d / "fixes.csv", fx)
    return d


def _same_run(a: Path, b: Path):
    sa, sb = (json.loads((p / "summary.json").read_text()) for p in (a, b))
    ma = {k: v for k, v in sa["metrics"].items() if "time" not in k}
    mb = {k: v for k, v in sb["metrics"].items() if "time" not in k}
    assert ma == mb
    assert sa["config"] == sb["config"]
    for f in sorted(a.glob("*.csv")):
        assert f.read_bytes() == (b / f.name).read_bytes(), f.name


def test_config_toml_reruns_the_navigation(log, tmp_path, monkeypatch):
    """A run with options, an alias and ``--set`` items; ``--config run/config.toml`` from
    another folder gives the same metrics and the same CSV bytes."""
    first = tmp_path / "first"
    r = _cli("-q", "navigate", "--imu", log / "imu.csv", "--fixes", log / "fixes.csv", "--aid", "zaru,nhc",
             "--outages", "50:15", "--lever-arm", "[0, 0, 0.2] m", "--set", "nhc.sigma=[0.2, 0.1] m/s",
             "--set", "start.course_speed=3 m/s", "--out", first)
    assert r.exit_code == 0, r.output
    cfg = tomllib.loads((first / "config.toml").read_text())
    assert cfg["aid"] == ["zupt", "nhc"] and cfg["zupt"]["zaru"] and cfg["nhc"]["sigma"] == "[0.2, 0.1] m/s"
    assert Path(cfg["imu"]["file"]).is_absolute()
    monkeypatch.chdir(tmp_path)
    again = tmp_path / "again"
    r = _cli("-q", "navigate", "--config", first / "config.toml", "--out", again)
    assert r.exit_code == 0, r.output
    _same_run(first, again)
    s = json.loads((again / "summary.json").read_text())
    assert s["metrics"]["zaru_updates_applied"] > 0 and "vehicle_mount_estimate_deg" in s["metrics"]


def test_options_override_the_file_and_set_overrides_both(tmp_path):
    f = tmp_path / "nav.toml"
    f.write_text('aid = ["nhc"]\n[gnss]\noutages = "10:5"\n[nhc]\ninterval = "0.2 s"\n')
    cfg = NC.resolve_navigate(f, ["nhc.interval=0.5 s"], {"--outages": "20:5", "--odometer": "odo.csv"})
    assert cfg.gnss.outages == "20:5" and cfg.nhc.interval == pytest.approx(0.5)
    assert cfg.aid == ["nhc", "odometer"] and cfg.odometer.file == "odo.csv"      # --odometer FILE enables it
    with pytest.raises(ConfigError, match="give either --gnss"):
        NC.resolve_navigate(given={"--fixes": ["a.pos"], "--gnss-raw": "b.ubx"})
