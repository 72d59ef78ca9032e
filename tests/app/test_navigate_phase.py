"""``sinslab navigate`` with carrier phase: GNSS alone without ``--imu`` (RTK against a
base on the real static pair, the single-point solution), RTK/INS through the recorded
front end (the RTK source, on a simulated drive), and the bad inputs of a base as one
line and exit status 2 with nothing written."""
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from sinslab.cli import app

STATIC = Path(__file__).resolve().parents[3] / "shared" / "data" / "cssrlib-static-rtk"
needs_static = pytest.mark.skipif(not (STATIC / "SEPT078M1.21O").exists(), reason="cssrlib-static-rtk not available")
runner = CliRunner()
BASE_XYZ = "-3959400.631,3385704.533,3667523.111 m"
ROVER = ["navigate", "--gnss-raw", str(STATIC / "SEPT078M1.21O"), "--gnss-nav", str(STATIC / "SEPT078M.21P")]


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@needs_static
def test_gnss_alone_rtk_on_the_static_pair(tmp_path):
    """No --imu, a base: RTK alone, fixed from the first epoch at every epoch, the run
    folder with the per-epoch table (status, ratio, integers, position ± σ) and figures."""
    out = tmp_path / "rtk"
    r = invoke(*ROVER, "--gnss-base", STATIC / "3034078M1.21O", "--base-position", BASE_XYZ, "--out", out)
    assert r.exit_code == 0, r.output
    m = json.loads((out / "summary.json").read_text())["metrics"]
    assert m["rtk_first_fix_epochs"] == 1 and m["rtk_fixed_fraction"] == 1.0 and m["restarts_base_lli"] > 50
    sol = pd.read_csv(out / "solution.csv")
    assert (sol.status == 2).all() and (sol.sigma_u_m < 0.05).all() and len(sol) == 60
    assert abs(sol.lat_deg.iloc[-1] - 35.3393258) < 1e-6
    assert (out / "rtk.png").is_file() and (out / "track.png").is_file()


@needs_static
def test_gnss_alone_single_point(tmp_path):
    r = invoke(*ROVER, "--out", tmp_path / "spp")
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "spp" / "summary.json").read_text())["metrics"]
    assert m["gnss_epochs_solved"] == m["gnss_epochs"] == 60 and m["satellites_used_median"] > 15


@needs_static
@pytest.mark.parametrize("args, msg", [
    (["--gnss-base", STATIC / "3034078M1.21O"], "--gnss-base needs --base-position"),
    (["--base-position", BASE_XYZ], "--base-position needs --gnss-base"),
    (["--gnss-base", STATIC / "3034078M1.21O", "--base-position", "-3959400.631,3385704.533,3667523.111"],
     "--base-position"),
    (["--gnss-base", STATIC / "3034078M1.21O", "--base-position", "-3962400.631,3385704.533,3667523.111 m"],
     "3034078M1.21O: the base position given is 3 km from the base observations' own single-point solution"),
    (["--phase", "tdcp"], "--phase tdcp compares each phase change with the INS's position change"),
    (["--gnss-base", STATIC / "3034078M1.21O", "--base-position", BASE_XYZ, "--phase", "tdcp"],
     "--phase tdcp is the carrier phase without a base"),
])
def test_bad_base_input(tmp_path, args, msg):
    out = tmp_path / "bad"
    r = invoke(*ROVER, *args, "--out", out)
    assert r.exit_code == 2, r.output
    line = r.output.strip().splitlines()[-1]
    assert line.startswith("sinslab: error:") and msg in line, line
    assert not out.exists()


def test_rtk_source_in_the_recorded_front_end():
    """RTK/INS through navigate_recorded (the recorded front end: start in motion, the RTK
    source's ambiguity states and double differences) on a simulated drive with a 10 s
    outage: fixed at ≥ 95 % of the epochs with satellites, the IMU point within 3 cm RMS
    horizontally of the truth after the first 30 s, the report's table per epoch."""
    from support import phase_drive

    from sinslab.core import earth as E
    from sinslab.fusion.recorded import NavOptions, navigate_recorded
    from sinslab.fusion.rtk import RtkOptions
    from sinslab.fusion.rtk_source import RtkSource
    from sinslab.fusion.tightly_coupled import RawGnss
    d = phase_drive(1, canyon=((0, 80.0, 10.0),), duration=120.0)
    src = RtkSource(RawGnss(d["rover"], pseudorange_sigma=0.3), d["base"],
                    RtkOptions(mask=math.radians(10), ar_mask=math.radians(10), iono="broadcast"))
    res = navigate_recorded(d["imu"], src, NavOptions.of(move_speed=1.0))
    m = res.source.metrics
    assert m["rtk_fixed_fraction"] >= 0.95 and m["restarts_rover_lli"] >= 16
    tru = d["truth"]
    k = np.searchsorted(tru.t, res.t - 1e-9)
    rm, rn = E.radii(tru.lat[0], tru.h[0])
    e = np.stack([(res.nav[:, 8] - tru.lon[k]) * rn * math.cos(tru.lat[0]), (res.nav[:, 7] - tru.lat[k]) * rm], -1)
    late = res.t > res.t[0] + 30
    assert np.sqrt(np.mean(np.sum(e[late] ** 2, 1))) < 0.03
    tab = next(t for t in res.source.tables if t.name == "rtk_epochs").columns
    assert np.sum(tab["status"] == 2) == m["rtk_epochs_fixed"]
