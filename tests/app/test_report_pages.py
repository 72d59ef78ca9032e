"""Report pages as a reader sees them (headless Chromium) and command reports that are true.

Checked on every report of a quick demo subset (an experiment and its named variant) and
of the three recorded-data commands: every figure decodes, the page does not overflow
sideways at 1280 px, claim cells hold labelled values (no raw ``[`` / ``{`` structures),
every metric whose name carries a unit shows it, every link opens a file of the run
folder, no claims section when nothing was checked. The re-run line of a report is run.
"""
import json
import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

from browser import CHROMIUM, problems

from sinslab.cli import app

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
LASER = DATA / "psins-lasergyro" / "lasergyro.imu"
DRIVE = DATA / "rtklib-drive"
TRANSFER = DATA / "psins-transfer" / "transfer_align_fog_mems.mat"

needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed")
needs_data = pytest.mark.skipif(not (LASER.exists() and DRIVE.exists() and TRANSFER.exists()),
                                reason="shared data missing")


def _invoke(args):
    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exit_code == 0, r.output
    return r


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    _invoke(["-q", "demo", "--quick", "--only", "static-alignment", "--out", out])
    return out


@pytest.fixture(scope="module")
def commands(tmp_path_factory):
    from sinslab.data import rtklib

    d = tmp_path_factory.mktemp("cmd")
    mount = "rpy:%g,%g,%g" % rtklib.RTKLIB_DRIVE["mount_rpy_frd_deg"]
    _invoke(["-q", "allan", LASER, "--window", "0:600", "--out", d / "allan"])
    _invoke(["-q", "align", "--imu", LASER, "--window", "600:900", "--out", d / "align"])
    _invoke(["-q", "navigate", "--imu", DRIVE / "imu_1934.csv", "--fixes", DRIVE / "gnss_1934_sf.pos",
             "--mount", mount, "--frame", "frd", "--lever-arm", "[-0.05, 0, 0] m",
             "--outages", "15/60@40", "--velocity-lag", "0.125", "--out", d / "navigate"])
    _invoke(["-q", "transfer-align", "--slave", TRANSFER, "--master", TRANSFER, "--out", d / "transfer-align"])
    return d


def test_demo_variant_is_named(demo):
    s = json.loads((demo / "static-alignment-60min" / "summary.json").read_text())
    html = (demo / "static-alignment-60min" / "report.html").read_text()
    assert s["name"] == "static-alignment-60min" and s["variant"]["sets"] == ["scenario.duration=60 min"]
    assert "<title>sinslab — static-alignment-60min</title>" in html
    assert "--set scenario.duration=60 min" in html
    index = (demo / "index.html").read_text()
    assert "static-alignment with scenario.duration=60 min" in index
    base = (demo / "static-alignment" / "report.html").read_text()
    # the latitude said once in the notes, once as a metric, once as the site assumption
    assert "Variant of" not in base and base.count("34.246") <= 3


def test_summary_claims_are_structured(demo):
    s = json.loads((demo / "static-alignment" / "summary.json").read_text())
    c = {c["id"]: c for c in s["claims"]}["full_vs_reduced"]
    assert c["measured"]["names"] == ["φE", "φN", "φU", "εN", "εU"]
    assert c["measured"]["unit"] == ["′", "′", "′", "°/h", "°/h"]
    assert len(c["measured"]["value"]) == 5 and c["expected"]["relation"] == "<="
    assert set(s["timing"]) == {"compute_s", "series_s", "figures_s", "report_s", "robustness_s"}


@needs_data
def test_command_reports_are_true(commands):
    for name in ("allan", "align", "navigate", "transfer-align"):
        s = json.loads((commands / name / "summary.json").read_text())
        html = (commands / name / "report.html").read_text()
        assert "full scale" not in html
        assert set(s["timing"]) == {"compute_s", "series_s", "figures_s", "report_s"}, name
        assert s["rerun"].startswith(f"sinslab {name} ")
        described = [m for m, i in s["metric_info"].items() if i["description"]]
        assert set(described) >= set(s["metrics"]) - {"runtime_s"}, name
        if not s["claims"]:
            assert "claims passed" not in html and "id='claims'" not in html
    s = json.loads((commands / "navigate" / "summary.json").read_text())
    ids = {c["id"] for c in s["claims"]}
    assert ids == {"nis_not_overconfident", "fix_residual", "fix_residual_p99"}
    assert s["metrics"]["nis_dof"] in (3, 6)


@needs_data
def test_rerun_lines_run(commands):
    for name in ("allan", "align", "transfer-align"):
        s = json.loads((commands / name / "summary.json").read_text())
        words = shlex.split(s["rerun"])
        assert words[0] == "sinslab"
        _invoke(["-q", *words[1:]])
        again = json.loads((commands / name / "summary.json").read_text())
        assert again["config"] == s["config"] and again["rerun"] == s["rerun"]
        same = {k: v for k, v in s["metrics"].items() if k != "runtime_s"}
        assert {k: again["metrics"][k] for k in same} == same      # same input, same numbers


@needs_chromium
def test_demo_reports_in_a_browser(demo, tmp_path):
    for d in ("static-alignment", "static-alignment-60min"):
        assert problems(demo / d, tmp_path) == [], d


@needs_chromium
@needs_data
def test_command_reports_in_a_browser(commands, tmp_path):
    for d in ("allan", "align", "navigate", "transfer-align"):
        assert problems(commands / d, tmp_path) == [], d
