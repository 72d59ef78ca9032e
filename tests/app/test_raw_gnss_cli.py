"""``sinslab navigate --gnss-raw`` on the rtklib-walk log: the run folder (solution columns
as the loosely coupled run's, satellite tables, figures), ``--max-satellites``, and every
bad input as one line and exit status 2 with the previous run left unchanged."""
import json
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from sinslab.cli import app

WALK = Path(__file__).resolve().parents[3] / "shared" / "data" / "rtklib-walk"
pytestmark = pytest.mark.skipif(not (WALK / "gnss_1730.ubx").exists(), reason="rtklib-walk not available")
runner = CliRunner()
BASE = ["navigate", "--imu", str(WALK / "imu_1730.csv"), "--format", "rtklib-imu", "--mount", "rpy:180,0,-90",
        "--frame", "frd", "--init", "course_speed=1 m/s,course_spread=10 deg"]


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def tc_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("tc") / "run"
    r = invoke(*BASE, "--gnss-raw", WALK / "gnss_1730.ubx", "--max-satellites", "3@60:20", "--out", out)
    assert r.exit_code == 0, r.output
    return out


def test_run_folder(tc_run):
    m = json.loads((tc_run / "summary.json").read_text())["metrics"]
    assert m["gnss_systems"] == "GEC" and m["satellites_used_min"] == 3 and m["satellites_over_limit"] > 0
    assert m["pseudoranges_used"] > 5000 and m["gnss_epochs_used"] == m["gnss_epochs"]
    sol = pd.read_parquet(tc_run / "solution.parquet")
    for c in ("t_s", "t_abs_s", "lat_deg", "lon_deg", "h_m", "vE_mps", "heading_deg", "gyro_bias_x_dph"):
        assert c in sol.columns
    sats = pd.read_csv(tc_run / "gnss_satellites.csv")
    win = (sats.t_s >= 60 - 18.8) & (sats.pr_used == 1)
    assert sats.groupby("t_s").pr_used.sum().min() >= 3
    for f in ("skyplot.png", "satellites.png", "clock.png", "gnss_clock.csv"):
        assert (tc_run / f).is_file()
    assert win.any()


@pytest.mark.parametrize("args, msg", [
    (["--gnss-raw", "EMPTY"], "empty.ubx: empty file"),
    (["--gnss-raw", "JUNK"], "junk.ubx: no raw measurements"),
    (["--gnss-raw", "RNX4"], "RINEX version 4"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--imu-delay", "3000"], "lie outside the IMU record"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--max-satellites", "three@60:20"], "--max-satellites"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--gnss", WALK / "gnss_1730_sf.pos"], "not both"),
])
def test_bad_input(tc_run, tmp_path, args, msg):
    empty = tmp_path / "empty.ubx"
    empty.write_bytes(b"")
    junk = tmp_path / "junk.ubx"
    junk.write_bytes(bytes(range(256)) * 40)
    rnx = tmp_path / "v4.obs"
    rnx.write_text("     4.01           OBSERVATION DATA    M                   RINEX VERSION / TYPE\n")
    sub = {"EMPTY": empty, "JUNK": junk, "RNX4": rnx}
    before = {p.name: p.read_bytes() for p in tc_run.iterdir() if p.is_file()}
    r = invoke(*BASE, *[sub.get(str(a), a) for a in args], "--out", tc_run, "--force")
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if "error" in ln]
    assert len(lines) == 1 and lines[0].startswith("sinslab: error:") and msg in lines[0], r.output
    assert {p.name: p.read_bytes() for p in tc_run.iterdir() if p.is_file()} == before


def test_satellites_below_the_mask_only(monkeypatch):
    """Every satellite below the elevation mask (here an 89.9° mask) is one line naming the
    file, not a filter without measurements."""
    import functools
    import math

    from sinslab.app.commands.raw_gnss import load_raw
    from sinslab.core.errors import InputError
    from sinslab.data import load_imu
    from sinslab.fusion import tightly_coupled as T
    monkeypatch.setattr(T, "RawGnss", functools.partial(T.RawGnss, mask=math.radians(89.9)))
    imu = load_imu(WALK / "imu_1730.csv", "rtklib-imu").imu
    with pytest.raises(InputError, match="gnss_1730.ubx: every satellite is below the 89.9 deg"):
        load_raw(WALK / "gnss_1730.ubx", None, None, imu, echo=lambda *a: None)
