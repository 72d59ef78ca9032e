"""``sinslab navigate`` with carrier phase: GNSS alone without ``--imu`` (RTK against a
base on the real static pair, the single-point solution), RTK/INS from the command line
(the real pair with a synthesised IMU at rest) and through the recorded front end (the RTK
source, on a simulated drive), time-differenced phase on the real walk, and the bad inputs
of a base as one line and exit status 2 with nothing written."""
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from sinslab.cli import app

ROOT = Path(__file__).resolve().parents[2]
STATIC = ROOT.parent / "shared" / "data" / "cssrlib-static-rtk"
WALK = ROOT.parent / "shared" / "data" / "rtklib-walk"
needs_static = pytest.mark.skipif(not (STATIC / "SEPT078M1.21O").exists(), reason="cssrlib-static-rtk not available")
runner = CliRunner()
BASE_XYZ = "-3959400.631,3385704.533,3667523.111 m"
ROVER = ["navigate", "--gnss-raw", str(STATIC / "SEPT078M1.21O"), "--gnss-nav", str(STATIC / "SEPT078M.21P")]


BASE_XYZ_M = np.array([-3959400.631, 3385704.533, 3667523.111])
#: the rover's reference coordinates (the set's README)
ROVER_XYZ = np.array([-3962108.673, 3381309.574, 3668678.638])


def reference_baseline():
    """Rover minus base, east/north/up at the base [m]."""
    from sinslab.core import earth as E
    lat, lon, _ = E.ecef_to_geodetic(BASE_XYZ_M)
    return (ROVER_XYZ - BASE_XYZ_M) @ E.enu_to_ecef_matrix(lat, lon)


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@needs_static
def test_gnss_alone_rtk_on_the_static_pair(tmp_path):
    """No --imu, a base (the static model, 10 s of outage; the default command runs in the
    docs test): RTK alone, fixed from the first epoch at every epoch used, fixed again at the
    first epoch after the outage (this pair: three carriers of two systems fix in one epoch),
    the epochs inside left out (status 0, no position), within 2 cm horizontally and 10 cm
    vertically of the reference; the run folder with the per-epoch table (status, ratio,
    integers, position ± σ, baseline) and figures."""
    out = tmp_path / "rtk"
    r = invoke(*ROVER, "--gnss-base", STATIC / "3034078M1.21O", "--base-position", BASE_XYZ, "--outages", "20:10",
               "--set", "gnss.raw.dynamics=static", "--out", out)
    assert r.exit_code == 0, r.output
    m = json.loads((out / "summary.json").read_text())["metrics"]
    assert m["rtk_first_fix_epochs"] == 1 and m["restarts_base_lli"] > 50
    assert m["rtk_epochs_solved"] == 50 and m["rtk_epochs_fixed"] == 50
    assert m["rtk_ratio_min"] >= 3.0 and m["rtk_integers_fixed_median"] >= 40
    assert abs(m["rtk_baseline_m"] - np.linalg.norm(ROVER_XYZ - BASE_XYZ_M)) < 0.005
    sol = pd.read_csv(out / "solution.csv")
    gap = (sol.t_s >= 20) & (sol.t_s < 30)
    assert len(sol) == 60 and gap.sum() == 10 and (sol.status[gap] == 0).all() and sol.lat_deg[gap].isna().all()
    assert (sol.status[~gap] == 2).all() and (sol.sigma_u_m[~gap] < 0.05).all()
    assert abs(sol.lat_deg.iloc[-1] - 35.3393258) < 1e-6
    err = sol[["baseline_e_m", "baseline_n_m", "baseline_u_m"]].to_numpy()[~gap] - reference_baseline()
    assert np.all(np.hypot(err[:, 0], err[:, 1]) < 0.02) and np.all(np.abs(err[:, 2]) < 0.10)
    assert (out / "rtk.png").is_file() and (out / "track.png").is_file()


@needs_static
def test_gnss_alone_single_point(tmp_path):
    """No --imu, no base: the single-point solution, the epochs of an outage left out."""
    r = invoke(*ROVER, "--outages", "20:10", "--out", tmp_path / "spp")
    assert r.exit_code == 0, r.output
    m = json.loads((tmp_path / "spp" / "summary.json").read_text())["metrics"]
    assert m["gnss_epochs"] == 60 and m["gnss_epochs_solved"] == 50 and m["satellites_used_median"] > 15
    sp = pd.read_csv(tmp_path / "spp" / "solution.csv")
    gap = (sp.t_s >= 20) & (sp.t_s < 30)
    assert (sp.status[gap] == 0).all() and (sp.status[~gap] == 1).all() and sp.h_m[gap].isna().all()


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


@needs_static
def test_rtk_ins_from_the_command_line(tmp_path):
    """RTK/INS on the real pair: the same command line with ``--imu`` (the consumer MEMS at
    rest of examples/rtk_static_pair.py, its first 20 s written as a CSV of increments on
    GPS time, the heading given 5° off): fixed within 10 epochs (the issue's target) and at
    every epoch after, the fixed antenna within 2 cm horizontally and 10 cm vertically of
    the rover's reference, the per-epoch table and figure in the run folder."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("rtk_static_pair", ROOT / "examples" / "rtk_static_pair.py")
    ex = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(ex)
    rover, _ = ex.read(STATIC)
    imu = ex.consumer_imu_at_rest(rover)[0]
    n = int(np.searchsorted(imu.t, rover.t_epoch[0] + 20.0))
    cols = {"t": imu.t[:n], **{f"dtheta_{c}": imu.dtheta[:n, k] for k, c in enumerate("xyz")},
            **{f"dv_{c}": imu.dv[:n, k] for k, c in enumerate("xyz")}}
    pd.DataFrame(cols).to_csv(tmp_path / "imu.csv", index=False, float_format="%.17g")
    out = tmp_path / "rtk-ins"
    r = invoke(*ROVER, "--gnss-base", STATIC / "3034078M1.21O", "--base-position", BASE_XYZ,
               "--imu", tmp_path / "imu.csv", "--init", "heading=45 deg", "--out", out)
    assert r.exit_code == 0, r.output
    m = json.loads((out / "summary.json").read_text())["metrics"]
    assert m["rtk_first_fix_epochs"] <= 10 and m["rtk_epochs_solved"] >= 19
    tab = pd.read_csv(out / "rtk_epochs.csv")
    first = int(np.flatnonzero(tab.status == 2)[0])
    assert (tab.status[first:] == 2).all() and np.sum(tab.status == 2) == m["rtk_epochs_fixed"]
    fx = tab[tab.status == 2]
    err = fx[["baseline_e_m", "baseline_n_m", "baseline_u_m"]].to_numpy() - reference_baseline()
    assert np.all(np.hypot(err[:, 0], err[:, 1]) < 0.02) and np.all(np.abs(err[:, 2]) < 0.10)
    assert (out / "rtk.png").is_file() and "RTK against" in r.output


@pytest.mark.skipif(not (WALK / "gnss_1730.ubx").exists(), reason="rtklib-walk not available")
def test_time_differenced_phase_on_the_walk(tmp_path):
    """``--phase tdcp`` on the real walk with at most 3 satellites from 60 to 80 s: the
    phase-change rows per epoch in the run folder, at most 3 satellites' worth (≤ 3
    carriers each) inside the window like the pseudoranges and more outside it, none
    rejected, the restarts counted by cause."""
    out = tmp_path / "tdcp"
    r = invoke("navigate", "--imu", WALK / "imu_1730.csv", "--format", "rtklib-imu", "--mount", "rpy:180,0,-90",
               "--frame", "frd", "--init", "course_speed=1 m/s,course_spread=10 deg", "--gnss-raw",
               WALK / "gnss_1730.ubx", "--phase", "tdcp", "--max-satellites", "3@60:20", "--out", out)
    assert r.exit_code == 0, r.output
    m = json.loads((out / "summary.json").read_text())["metrics"]
    assert m["tdcp_rows_used"] > 5000 and m["tdcp_rows_rejected"] == 0 and m["tdcp_restarts_lli"] > 0
    tab = pd.read_csv(out / "tdcp_epochs.csv")
    sats = pd.read_csv(out / "gnss_satellites.csv")
    n_pr = sats.groupby(sats.t_s.round(2)).pr_used.sum()             # the window: 3 pseudoranges an epoch
    win = tab.t_s.round(2).map(n_pr).le(3).to_numpy()
    assert win.sum() >= 15 and tab.rows_used[win].max() <= 9 and tab.rows_used[~win].median() > 9
    assert "time-differenced phase:" in r.output
