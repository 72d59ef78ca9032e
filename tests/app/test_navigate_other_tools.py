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
    assert any(n.startswith("Error model: source = imu (") for n in s["notes"]), s["notes"]


def test_kfgins_files_as_shipped(drive, tmp_path):
    d, _ = drive
    out, s = _run(["--imu", str(d / "imu.txt"), "--gnss", str(d / "GNSS_RTK.pos"),
                   "--lever-arm", "[0.3, 1.2, 1.0] m"], tmp_path / "kfgins")
    assert "fix σ from GNSS_RTK.pos (per line)" in out, out
    assert s["metrics"]["hz_err_with_fixes_median_m"] < 0.1, s["metrics"]
    assert "built-in default" not in out                           # a rest: the noise measured there
    assert s["metrics"]["start_source_white_noise"].startswith("measured at the initial rest (")


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


T_WEEK = 138000.0                       # the files' first stamp, seconds of the GPS week


def _truth_at(tru, t):
    i = int(np.argmin(np.abs(tru.t - t)))
    return float(tru.lat[i]), float(tru.lon[i]), float(tru.h[i]), tru.vel[i].tolist(), tru.att[i].tolist()


def test_init_gives_the_whole_start_and_outages_count_on_the_log_clock(drive, tmp_path):
    """NaveGo hands its filter the reference's attitude, KF-GINS its init file's position,
    velocity, attitude and their σ at a start time: `--init` takes all of them (units
    carried) and the filter starts there, at that time, with those σ; `--outages` at the
    log's own stamps, at GPS seconds of week and at a GPS calendar time name the same
    outage as seconds from the first fix."""
    d, tru = drive
    lat, lon, h, vel, att = _truth_at(tru, 40.0)                  # moving at 10 m/s, no rest to level on
    hd = float(np.degrees(np.mod(A.yaw_to_heading(att[2]), 2 * np.pi)))
    init = (f"pitch={float(np.degrees(att[0]))!r} deg, roll={float(np.degrees(att[1]))!r} deg, heading={hd!r} deg, "
            f"attitude_sigma=[0.05, 0.05, 0.1] deg, time={T_WEEK + 40.0!r} s, latitude={float(np.degrees(lat))!r} deg, "
            f"longitude={float(np.degrees(lon))!r} deg, height={h!r} m, velocity=[{vel[0]!r}, {vel[1]!r}, {vel[2]!r}] m/s, "
            "position_sigma=[0.1, 0.1, 0.2] m, velocity_sigma=[0.05, 0.05, 0.05] m/s")
    base = ["--imu", str(d / "imu.mat"), "--gnss", str(d / "gnss.mat"), "--init", init]
    out, s = _run([*base, "--outage-clock", "log", "--outages", f"{T_WEEK + 55.0!r}:10"], tmp_path / "log")
    m = s["metrics"]
    assert "start 39.80 s after the first fix" in out, out            # first fix at 0.2 s
    assert m["initial_heading_deg"] == pytest.approx(hd, abs=1e-6)
    assert m["initial_attitude_sigma_deg"] == pytest.approx([0.05, 0.05, 0.1], rel=0.05)
    for k in ("attitude", "position", "velocity", "position_sigma", "velocity_sigma"):
        assert m[f"start_source_{k}"].startswith("given"), (k, m[f"start_source_{k}"])
    assert m["start_source_attitude_sigma"] == "given"
    assert m["n_outages"] == 1 and m["hz_err_with_fixes_median_m"] < 0.1, m
    _, s2 = _run([*base, "--outages", "54.8:10"], tmp_path / "first")
    assert s2["metrics"]["outage_end_hz_err_m"] == m["outage_end_hz_err_m"]
    assert s["config"]["gnss"]["outage_clock"] == "log"


def test_outage_clocks_name_the_same_times():
    """GPS seconds of week and a GPS calendar time (no leap seconds) land on the log's
    stamps whether the log counts seconds of week (NaveGo, KF-GINS) or GPS seconds since
    1970 (RTKLIB .pos as read); a periodic FIRST on an absolute clock likewise."""
    from sinslab.app.commands.navigate import _outages
    from sinslab.core.gnss import GPS_EPOCH_UNIX
    week = T_WEEK, T_WEEK + 80.0
    assert _outages("138055:10", "log", *week) == ((138055.0, 10.0),)
    assert _outages("138055:10", "gps", *week) == ((138055.0, 10.0),)
    assert _outages("2026-12-07T14:20:55:10", "gps", *week) == ((138055.0, 10.0),)
    assert _outages("54.8:10", "first-fix", *week) == ((T_WEEK + 54.8, 10.0),)
    t70 = GPS_EPOCH_UNIX + 2448 * 604800.0 + T_WEEK                   # GPS week 2448, 138000 s
    since_1970 = t70, t70 + 80.0
    assert _outages("138055:10", "gps", *since_1970) == ((t70 + 55.0, 10.0),)
    assert _outages("2026-12-07T14:20:55:10", "gps", *since_1970) == ((t70 + 55.0, 10.0),)
    assert _outages("10/30@138010", "log", *week) == (("periodic", 10.0, 30.0, 10.0),)


def test_outages_off_the_record_and_a_start_half_given_are_one_line(drive, tmp_path):
    from sinslab.cli import app
    d, _ = drive
    for args, words in ((["--outage-clock", "log", "--outages", "55:10"],
                         "is outside the record (138000.200..138079.800 s"),
                        (["--outage-clock", "gps", "--outages", "2026-12-07T18:00:00:10"],
                         "is outside the record (GPS 138000.2 s"),
                        (["--outage-clock", "gps", "--outages", "700000:10"], "is not a second of the GPS week"),
                        (["--init", "latitude=45 deg"], "needs latitude, longitude and height; longitude, height "
                                                        "missing"),
                        (["--init", "heading=30 deg, time=138010 s"], "the start time needs the whole attitude"),
                        (["--init", "velocity=[1, 2] m/s"], "velocity"),
                        (["--init", "time=139000 s, pitch=1 deg, roll=0 deg, heading=3 deg"],
                         "the start time 139000.000 s is outside the IMU record")):
        res = CliRunner().invoke(app, ["navigate", "--imu", str(d / "imu.mat"), "--gnss", str(d / "gnss.mat"),
                                       *args, "--out", str(tmp_path / "x")])
        assert res.exit_code == 2 and words in res.output, (args, res.output)
        assert len([ln for ln in res.output.splitlines() if "sinslab: error" in ln]) == 1, res.output
        assert not (tmp_path / "x" / "summary.json").exists()


def test_a_start_in_motion_says_its_noise_is_a_default(drive, tmp_path):
    """No rest at the start and no error model given: the white noise is the built-in
    default, said once on the terminal with the option that sets it and in the summary
    (not "measured at the initial rest"); with a rest it is the rest's (the KF-GINS test above)."""
    d, _ = drive
    rows = np.loadtxt(d / "imu.txt")
    rows = rows[rows[:, 0] >= T_WEEK + 40.0]
    rng = np.random.default_rng(5)                  # a vibrating unit: 50x the default white noise
    rows[:, 1:4] += rng.normal(0, 50 * 0.0038 * u.deg * 0.1, (len(rows), 3))
    rows[:, 4:7] += rng.normal(0, 50 * 70 * u.ug * 0.1, (len(rows), 3))
    np.savetxt(tmp_path / "moving.txt", rows, fmt="%.6f" + " %.17g" * 6)
    out, s = _run(["--imu", str(tmp_path / "moving.txt"), "--gnss", str(d / "gnss.mat")], tmp_path / "moving")
    m = s["metrics"]
    assert out.count("white noise: the built-in default") == 1 and "--imu-errors" in out, out
    assert m["nis_verdict"] == "overconfident noise model", m["nis_mean"]
    assert "overconfident noise model; the white noise is the built-in default, not measured" in out, out
    assert m["start_source_white_noise"] == "the error model's: no rest at the start to measure it"
    assert m["start_source_gyro_bias"].startswith("zero with the error model's σ: no rest"), m
    assert not any("measured at the initial rest" in n for n in s["notes"]), s["notes"]
    assert any(n.startswith("Error model: white noise: the built-in default") for n in s["notes"]), s["notes"]


def test_navego_ini_align_starts_the_run_at_the_first_sample(drive, tmp_path):
    """A NaveGo IMU struct with `ini_align` (roll, pitch, yaw of NED, the reference's at
    imu.t(1)) and `ini_align_err`: the run starts there, at the first sample, with that
    attitude and σ, as NaveGo's filter does — not 30 s later after the rest and the first
    straight stretch — and says where the attitude came from."""
    d, tru = drive
    m = scipy.io.loadmat(d / "imu.mat", squeeze_me=True, struct_as_record=False)["imu"]
    k = int(np.argmin(np.abs(tru.t - m.t[0] + T_WEEK)))
    pitch, roll, yaw = tru.att[k]
    hd = float(np.mod(A.yaw_to_heading(yaw), 2 * np.pi))
    fields = {f: getattr(m, f) for f in m._fieldnames}
    fields.update(ini_align=np.array([roll, pitch, hd]), ini_align_err=np.radians([0.2, 0.3, 0.5]))
    scipy.io.savemat(tmp_path / "imu.mat", {"imu": fields})
    out, s = _run(["--imu", str(tmp_path / "imu.mat"), "--gnss", str(d / "gnss.mat")], tmp_path / "run")
    assert f"heading {np.degrees(hd):.3f} deg at the first IMU sample from imu.ini_align (σ from ini_align_err)" \
        in out, out
    assert "start -0.19 s after the first fix" in out, out             # the first sample, 0.01 s
    mt = s["metrics"]
    assert mt["initial_heading_deg"] == pytest.approx(np.degrees(hd), abs=1e-6)
    assert mt["initial_attitude_sigma_deg"] == pytest.approx([0.3, 0.2, 0.5], rel=0.05)
    assert mt["start_source_attitude"].startswith("given") and mt["hz_err_with_fixes_median_m"] < 0.1, mt


def test_kfgins_init_file_as_shipped(drive, tmp_path):
    """A KF-GINS configuration's initial state (YAML as its dataset ships it: starttime,
    initpos deg/deg/m, initvel NED, initatt roll/pitch/yaw deg, their std) given whole by
    `--init kf-gins.yaml`: the run starts at starttime with the truth 40 s into the drive,
    where nothing could be found; a file without an initial state is one line."""
    d, tru = drive
    lat, lon, h, vel, att = _truth_at(tru, 40.0)
    rpy = np.degrees(A.euler_to_ned(np.array(att))).tolist()
    (tmp_path / "kf-gins.yaml").write_text(
        "# KF-GINS configuration file\nimupath: \"./imu.txt\"\nstarttime: 138040\nendtime: -1\n"
        f"initpos: [ {float(np.degrees(lat))!r}, {float(np.degrees(lon))!r}, {h!r} ]\n"
        f"initvel: [ {vel[1]!r}, {vel[0]!r}, {-vel[2]!r} ]  # north east down\n"
        f"initatt: [ {rpy[0]!r}, {rpy[1]!r}, {rpy[2]!r} ]\n"
        "initposstd: [ 0.1, 0.1, 0.2 ]\ninitvelstd: [ 0.05, 0.05, 0.05 ]\ninitattstd: [ 0.05, 0.05, 0.1 ]\n"
        "imunoise:\n  arw: [0.003, 0.003, 0.003]\nantlever:  [ 1.2, 0.3, -1.0 ]\n")
    out, s = _run(["--imu", str(d / "imu.txt"), "--gnss", str(d / "GNSS_RTK.pos"), "--lever-arm", "[0.3, 1.2, 1.0] m",
                   "--init", str(tmp_path / "kf-gins.yaml")], tmp_path / "kf")
    m = s["metrics"]
    assert "start 39.80 s after the first fix" in out, out
    assert m["initial_heading_deg"] == pytest.approx(float(np.mod(rpy[2], 360)), abs=1e-6)
    assert m["initial_attitude_sigma_deg"] == pytest.approx([0.05, 0.05, 0.1], rel=0.05)
    assert all(m[f"start_source_{k}"] == "given" for k in ("attitude_sigma", "position", "velocity_sigma")), m
    assert m["hz_err_with_fixes_median_m"] < 0.1, m
    (tmp_path / "other.yaml").write_text("imupath: x\n")
    from sinslab.cli import app
    res = CliRunner().invoke(app, ["navigate", "--imu", str(d / "imu.txt"), "--gnss", str(d / "GNSS_RTK.pos"),
                                   "--init", str(tmp_path / "other.yaml"), "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "other.yaml: no initial state (initpos, initvel, initatt" in res.output, res.output
