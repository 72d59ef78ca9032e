"""The whole-second IMU–GNSS clock check (:mod:`sinslab.fusion.clock_check`). Oracle: a
simulated drive on one clock is found on it; its IMU stamps moved by the 18 leap seconds
(an IMU logged in UTC beside a receiver in GPS time) or by one second are found off by
that many seconds; a drive without turns gives no verdict."""
import numpy as np
import pytest

from sinslab.fusion import recorded as R
from sinslab.fusion.clock_check import clock_check
from sinslab.sim import trajectory as tr
from support import simulated_car_drive, turning_drive_segments


@pytest.fixture(scope="module")
def drive():
    imu, fx, _, _, _ = simulated_car_drive(turning_drive_segments())
    return imu, fx


@pytest.mark.parametrize("shift", [0.0, 18.0, -1.0])
def test_clock_check_finds_whole_seconds(drive, shift):
    imu, fx = drive
    c = clock_check(R.shift_imu_time(imu, -shift), fx)
    assert c.whole_seconds == int(shift) and abs(c.lag - shift) < 0.15, c
    assert c.off == (shift != 0.0), c
    if shift == 18.0:
        assert "GPST − UTC" in c.describe()


@pytest.mark.parametrize("shift", [0.0, 18.0])
def test_sparse_fixes_judge_the_lag_at_their_own_resolution(drive, shift):
    """Fixes every 5 s: the course rate between them is interpolated, so the peak may sit a
    second or two from the true lag. Before: one-clock data with 5 s fixes was refused as
    "the clocks differ by +1.4 s"; the 18 leap seconds are still found."""
    imu, fx = drive
    sparse = fx.select(slice(0, None, int(round(5.0 / np.median(np.diff(fx.t))))))
    c = clock_check(R.shift_imu_time(imu, -shift), sparse)
    assert c.resolution == pytest.approx(2.5) and abs(c.lag - shift) < c.resolution, c
    assert c.off == (shift != 0.0), c


def test_no_turn_no_verdict():
    imu, fx, _, _, _ = simulated_car_drive([tr.Static(duration=10.0), tr.Accelerate(duration=5.0, accel=2.0),
                                            tr.Level(duration=80.0)])
    assert clock_check(imu, fx) is None


def test_navigate_refuses_an_imu_18_s_off(drive, tmp_path):
    """Before: the run converged to a wrong heading and passed its claims."""
    from typer.testing import CliRunner

    from sinslab.cli import app
    from sinslab.data import write_fixes, write_imu
    imu, fx = drive
    write_imu(tmp_path / "imu.csv", R.shift_imu_time(imu, -18.0))
    write_fixes(tmp_path / "fixes.csv", fx)
    r = CliRunner().invoke(app, ["navigate", "--imu", str(tmp_path / "imu.csv"), "--fixes", str(tmp_path / "fixes.csv"),
                                 "--out", str(tmp_path / "run")])
    assert r.exit_code == 2, r.output
    assert "the clocks differ by +18.0 s" in r.output and "GPST − UTC" in r.output, r.output
    assert not (tmp_path / "run").exists()


def test_turn_rate_ratio_shows_the_gyro_unit_and_the_vertical_axis(drive):
    """The vertical gyro rate over the course rate in the turns (least squares): 1 for the
    simulated drive (the gyro z is the course rate, ψ̇ of a level car), 180/π for its
    increments written in degrees, −1 for a body z axis pointing down (x and z flipped:
    a rotation of 180° about y)."""
    from sinslab.core.records import ImuRecord
    imu, fx = drive
    assert clock_check(imu, fx).rate_ratio == pytest.approx(1.0, abs=0.01)
    deg = ImuRecord(imu.t, np.degrees(imu.dtheta), imu.dv)
    assert clock_check(deg, fx).rate_ratio == pytest.approx(np.degrees(1.0), rel=0.01)
    flip = np.array([-1.0, 1.0, -1.0])
    down = clock_check(ImuRecord(imu.t, imu.dtheta * flip, imu.dv * flip), fx)
    assert down.rate_ratio == pytest.approx(-1.0, abs=0.01) and down.rate_correlation < -0.9


def test_navigate_refuses_gyro_degrees_declared_radians(drive, tmp_path):
    """Before: 'no 1 s of motion faster than 2 m/s ...' (the start failed on the rotated
    course); now the unit slip is named from the turns, before any filtering."""
    from typer.testing import CliRunner

    from sinslab.app.commands.navigate import _turn_rate_findings
    from sinslab.cli import app
    from sinslab.core.records import ImuRecord
    from sinslab.data import write_fixes, write_imu
    imu, fx = drive
    write_imu(tmp_path / "imu.csv", ImuRecord(imu.t, np.degrees(imu.dtheta), imu.dv))   # header: [rad]
    write_fixes(tmp_path / "fixes.csv", fx)
    r = CliRunner().invoke(app, ["navigate", "--imu", str(tmp_path / "imu.csv"), "--fixes", str(tmp_path / "fixes.csv"),
                                 "--out", str(tmp_path / "run")])
    assert r.exit_code == 2, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("sinslab: error:")]
    assert len(err) == 1 and "imu.csv: in 24 s of turns the vertical gyro rate is 57.3 × the course rate" in err[0] \
        and "degrees read as radians" in err[0], r.output
    assert not (tmp_path / "run").exists()
    flip = np.array([-1.0, 1.0, -1.0])
    down = clock_check(ImuRecord(imu.t, imu.dtheta * flip, imu.dv * flip), fx)
    (w,) = _turn_rate_findings(down, "fixes.csv", "imu.csv")
    assert not w.refuse and "vertical axis points down" in w.text
    assert _turn_rate_findings(clock_check(imu, fx), "fixes.csv", "imu.csv") == []
