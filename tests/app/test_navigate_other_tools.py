"""`sinslab navigate` on a simulated car drive written as other tools ship their files:
NaveGo's IMU and GNSS structs, KF-GINS's IMU text and GNSS position file, a ROS 2 bag —
given by file name only (plus the lever arm where the tool keeps it in its own config).

Oracle: the truth of the simulation (antenna fixes 1.2 m ahead and 1.0 m above the IMU,
0.3 m to the right): with the lever arm the file states, the solution follows the IMU
point to the fixes' noise; the terminal says where the lever arm, the fix σ and the noise
model came from."""
import json

import numpy as np
import pytest
import scipy.io
from typer.testing import CliRunner

import foreign_unit as fu
from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.sim import trajectory as tr
from support import simulated_car_drive

LEVER = np.array([0.3, 1.2, 1.0])                       # IMU -> antenna, RFU [m]
FRD = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("tools")
    segs = [tr.Static(duration=30.0), tr.Accelerate(duration=5.0, accel=2.0), tr.Level(duration=15.0),
            tr.Turn(duration=10.0, rate=9 * u.deg, coordinated=False), tr.Level(duration=20.0)]
    imu, _, tru, _, rng = simulated_car_drive(segs)
    t = np.arange(0.2, tru.t[-1] - 0.1, 0.2)
    fx = fu.fixes_at(tru, t, rng, pos_sigma=0.05, vel_sigma=0.03, lever=LEVER, imu=imu)
    t0 = 138000.0                                                     # seconds of week
    # NaveGo: rates in FRD, noise of the unit, GNSS struct with its σ and FRD lever arm
    scipy.io.savemat(d / "imu.mat", {"imu": {
        "t": imu.t[:, None] + t0, "fb": imu.dv @ FRD.T / imu.dt, "wb": imu.dtheta @ FRD.T / imu.dt,
        "arw": np.full((1, 3), np.radians(0.0038)), "vrw": np.full((1, 3), 70e-6 * 9.80665),
        "gb_dyn": np.full((1, 3), np.radians(0.15)), "ab_dyn": np.full((1, 3), 0.1),
        "gb_corr": np.full((1, 3), 3600.0), "ab_corr": np.full((1, 3), 3600.0), "freq": 100.0}})
    scipy.io.savemat(d / "gnss.mat", {"gnss": {
        "t": fx.t[:, None] + t0, "lat": fx.lat[:, None], "lon": fx.lon[:, None], "h": fx.h[:, None],
        "vel": A.vec_enu_to_ned(fx.vel), "stdm": np.array([[0.05, 0.05, 0.05]]),
        "stdv": np.array([[0.03, 0.03, 0.03]]), "larm": (FRD @ LEVER)[:, None], "freq": 5.0}})
    # KF-GINS: IMU increments text, 7-column GNSS position file (no velocity)
    np.savetxt(d / "imu.txt", np.column_stack([imu.t + t0, imu.dtheta @ FRD.T, imu.dv @ FRD.T]),
               fmt="%.6f" + " %.17g" * 6)
    np.savetxt(d / "GNSS_RTK.pos", np.column_stack([fx.t + t0, np.degrees(fx.lat), np.degrees(fx.lon),
                                                     fx.h, fx.sigma]), fmt="%.3f %.10f %.10f %.3f %.3f %.3f %.3f")
    return d, tru


def _run(args, out):
    from sinslab.cli import app
    res = CliRunner().invoke(app, ["navigate", *args, "--out", str(out)])
    assert res.exit_code == 0, res.output
    return res.output, json.loads((out / "summary.json").read_text())


def test_navego_files_as_shipped(drive, tmp_path):
    d, _ = drive
    out, s = _run(["--imu", str(d / "imu.mat"), "--gnss", str(d / "gnss.mat")], tmp_path / "navego")
    assert "lever arm (IMU -> antenna, right-forward-up) [0.3, 1.2, 1] m from gnss.larm" in out, out
    assert "fix σ from gnss.stdm" in out
    assert "IMU error model from imu (arw, vrw, gb_dyn, ab_dyn, gb_corr, ab_corr)" in out
    m = s["metrics"]
    assert m["hz_err_with_fixes_median_m"] < 0.1, m
    assert s["config"]["imu_errors"]["source"].startswith("imu (")


def test_kfgins_files_as_shipped(drive, tmp_path):
    d, _ = drive
    out, s = _run(["--imu", str(d / "imu.txt"), "--gnss", str(d / "GNSS_RTK.pos"),
                   "--lever-arm", "[0.3, 1.2, 1.0] m"], tmp_path / "kfgins")
    assert "fix σ from GNSS_RTK.pos (per line)" in out, out
    assert s["metrics"]["hz_err_with_fixes_median_m"] < 0.1, s["metrics"]


def test_ros2_bag_as_shipped(drive, tmp_path):
    pytest.importorskip("rosbags")
    from rosbag_files import write_bag
    d, tru = drive
    from sinslab import data
    imu = data.load_imu(d / "imu.txt").imu
    fx, _ = data.load_fixes(d / "gnss.mat")
    write_bag(tmp_path / "bag", imu, fx)
    out, s = _run(["--imu", str(tmp_path / "bag"), "--gnss", str(tmp_path / "bag"),
                   "--lever-arm", "[0.3, 1.2, 1.0] m"], tmp_path / "ros")
    assert "fix σ from /gnss/fix position_covariance" in out, out
    assert s["metrics"]["hz_err_with_fixes_median_m"] < 0.1, s["metrics"]
