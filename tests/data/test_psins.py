"""PSINS .imu reader, and alignment of the real laser-gyro record (paper 000 on real data)."""
import math
from pathlib import Path

import numpy as np
import pytest

from sinslab.core import earth as E
from sinslab import data
from sinslab.data import psins
from sinslab.core import units as u
from sinslab.methods import alignment as sa

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "psins-lasergyro" / "lasergyro.imu"
needs_data = pytest.mark.skipif(not DATA.exists(), reason="PSINS lasergyro.imu not available")

HEADER = """% PSINS-format SIMU log file.
0.0 0.0 -90.6 0 0 0
34.246048 108.909664 380 0 10 9.780327
0.1 0.1 0.1 125 125 125
"""


@pytest.fixture(scope="module")
def rec():
    return psins.read_psins_imu(DATA)


@needs_data
def test_read_lasergyro(rec):
    imu = rec.imu
    assert len(imu) == 184718 and imu.dt == pytest.approx(0.01)
    assert imu.t[0] == pytest.approx(0.01) and imu.t[-1] == pytest.approx(1847.18)
    assert math.degrees(rec.lat) == pytest.approx(34.246048) and rec.h == 380.0
    assert rec.g == 9.780327
    assert rec.gyro_scale[0] == pytest.approx(0.1 * u.arcsec)
    assert rec.accel_scale[0] == pytest.approx(125e-6 * 9.780327)
    assert math.degrees(rec.att0[2]) == pytest.approx(-90.6)
    # the header g is the accelerometer scale's g: |f| then equals local normal gravity
    T = len(imu) * imu.dt
    fn = np.linalg.norm(imu.dv.sum(0) / T)
    assert fn == pytest.approx(float(E.gravity(rec.lat, rec.h)), abs=2e-4)
    wn = np.linalg.norm(imu.dtheta.sum(0) / T)
    assert 0.95 < wn / E.WIE < 1.02


def _write(tmp_path, text, name="x.imu"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_reader_small_and_bad_files(tmp_path):
    p = _write(tmp_path, HEADER + "1 2 3 4 5 80\n-1 0 0 0 0 80\n")
    r = psins.read_psins_imu(p)
    assert len(r.imu) == 2
    assert r.imu.dtheta[0, 1] == pytest.approx(0.2 * u.arcsec)
    assert r.imu.dv[1, 2] == pytest.approx(80 * 125e-6 * 9.780327)
    with pytest.raises(ValueError, match="no samples"):
        psins.read_psins_imu(_write(tmp_path, HEADER))
    with pytest.raises(ValueError, match="3 header lines"):
        psins.read_psins_imu(_write(tmp_path, "% only a comment\n1 2 3 4 5 6\n"))
    with pytest.raises(ValueError, match="6 columns"):
        psins.read_psins_imu(_write(tmp_path, HEADER + "1 2 3 4 5\n"))
    with pytest.raises(ValueError):
        psins.read_psins_imu(_write(tmp_path, HEADER + "1 2 3 a 5 6\n"))
    with pytest.raises(ValueError, match="non-finite"):
        psins.read_psins_imu(_write(tmp_path, HEADER + "1 2 3 nan 5 6\n"))
    with pytest.raises(ValueError, match="header"):
        psins.read_psins_imu(_write(tmp_path, HEADER.replace("0 10 9.780327", "0 10")))
    with pytest.raises(FileNotFoundError):
        data.read_imu(tmp_path / "missing.imu")
    with pytest.raises(ValueError, match="unknown IMU format"):
        data.read_imu(p, "xyz")
    # CSV of increments
    c = _write(tmp_path, "t,dtheta_x,dtheta_y,dtheta_z,dv_x,dv_y,dv_z\n0.1,0,0,1e-6,0,0,0.98\n"
                         "0.2,0,0,1e-6,0,0,0.98\n", "x.csv")
    imu, ps = data.read_imu(c)
    assert ps is None and len(imu) == 2 and imu.dt == pytest.approx(0.1)
    with pytest.raises(ValueError, match="y.csv:1: no time column"):
        data.read_imu(_write(tmp_path, "a,b\n1,2\n", "y.csv"))


@needs_data
def test_lasergyro_alignment_consistent_over_windows(rec):
    """Fine and inertial-frame alignment agree over independent 10-min windows and with
    the header yaw (−90.6°, i.e. heading 90.6°); the analytic coarse alignment does not
    (the vehicle's slow tilt drift reads as Earth rate)."""
    imu = rec.imu
    full = sa.align_record(imu, rec.lat, rec.h)
    fa = full["fine"]
    assert math.degrees(fa.heading) == pytest.approx(90.606, abs=0.02)
    assert math.degrees(fa.att[0]) == pytest.approx(1.0025, abs=0.01)
    assert math.degrees(fa.att[1]) == pytest.approx(0.387, abs=0.01)
    assert fa.att_sigma[2] < 10 * u.arcmin and fa.att_sigma[0] < 0.5 * u.arcmin
    assert abs(math.degrees(fa.heading) - 90.6) < 0.05          # header yaw, PSINS convention
    assert fa.rest.at_rest                                       # disturbed, but no linear motion
    fine_h, iner_h, ana_h = [], [], []
    for lo, hi in ((0, 600), (600, 1200), (1200, 1800)):
        r = sa.align_record(imu.slice(lo, hi), rec.lat, rec.h)
        fine_h.append(math.degrees(r["fine"].heading))
        iner_h.append(math.degrees(r["inertial"].heading))
        ana_h.append(math.degrees(r["coarse"].heading))
        # each window's fine σ covers its distance to the whole-record heading (3σ)
        assert abs(fine_h[-1] - math.degrees(fa.heading)) < 3 * math.degrees(r["fine"].att_sigma[2])
    assert np.ptp(fine_h) < 0.05 and np.ptp(iner_h) < 0.05
    assert np.ptp(ana_h) > 0.5                                   # analytic coarse: fooled by motion
    # the limit accuracy the assumed biases allow (0.01 °/h, 100 µg, 1σ each axis)
    la = full["limit_att"] / u.arcmin
    assert la[2] == pytest.approx(2.77, abs=0.05) and la[0] == pytest.approx(0.344, abs=0.01)


@needs_data
def test_align_cli(tmp_path):
    from typer.testing import CliRunner

    from sinslab.cli import app

    res = CliRunner().invoke(app, ["align", "--imu", str(DATA), "--window", "600:900",
                                   "--out", str(tmp_path / "a")])
    assert res.exit_code == 0, res.output
    assert "fine (reduced, closed loop)" in res.output and "heading" in res.output
    for f in ("config.toml", "summary.json", "alignment.csv", "alignment.png", "report.html"):
        assert (tmp_path / "a" / f).exists()
    res = CliRunner().invoke(app, ["align", "--imu", str(DATA), "--lat", "89.6 deg",
                                   "--out", str(tmp_path / "b")])
    assert res.exit_code == 2 and not (tmp_path / "b").exists()
