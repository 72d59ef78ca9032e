"""A run checks its estimated sensor errors against the IMU's grade before it reports
them (:func:`sinslab.app.plausibility.declared_findings`, ``bias_findings``): an estimate
beyond 5σ of the declared error model's prior (probability 6e-7 per axis for a Gaussian
prior) that the data determine (beyond 3 of its own final σ) is a warning line, listed in
the report; without a declared model the class of the noise measured at rest bounds it."""
import json
from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from sinslab.app.plausibility import DECLARED_FACTOR, declared_findings
from sinslab.core import units as u
from support import simulated_car_drive, turning_drive_segments


def _gyro(est_dph, sig_dph, dec_dph):
    return [("gyro bias", np.array(est_dph) * u.dph, np.array(sig_dph) * u.dph, dec_dph * u.dph, "°/h", 1 / u.dph)]


def test_declared_prior_rule():
    assert declared_findings(_gyro([0, 0, 4.9], [0.1] * 3, 1.0), "run", "--imu-errors x") == []
    (f,) = declared_findings(_gyro([0, -6.0, 1.0], [0.1] * 3, 1.0), "run", "--imu-errors x")
    assert not f.refuse and "gyro bias y 6 °/h is 6 × the 1 °/h (1σ)" in f.text and "--imu-errors x" in f.text
    # not determined by the data (6 < 3 × 2.5): no finding, whatever the prior says
    assert declared_findings(_gyro([0, -6.0, 0], [2.5] * 3, 1.0), "run", "--imu-errors x") == []
    # a scale factor without its own σ: the prior alone
    sf = [("gyro scale factor", np.array([0.0, 0.0, 2e-3]), np.zeros(3), 300e-6, "ppm", 1e6)]
    assert "2000 ppm is 6.67 × the 300 ppm" in declared_findings(sf, "run", "g")[0].text
    assert DECLARED_FACTOR == 5.0


def test_without_a_declared_model_the_rest_noise_sets_the_class():
    """No --imu-errors: ``bias_findings`` with the gyro noise the run measured at rest."""
    from sinslab.app.commands.navigate import _estimate_findings
    arw = 0.005 * u.deg / 60                     # 0.005 °/√h: a navigation-grade gyro (up to 0.1 °/h)
    res = SimpleNamespace(start=SimpleNamespace(gyro_noise=np.full(3, arw)), scale=None)
    p = SimpleNamespace(errors=None, cfg=SimpleNamespace(imu=SimpleNamespace(file=["imu.csv"])))
    m = {"gyro_bias_final_dph": [0.0, 0.0, 5.0], "accel_bias_final_ug": [0.0, 0.0, 10.0]}
    (f,) = _estimate_findings(res, p, m)
    assert "imu.csv (the run's estimates): estimated gyro bias 5 °/h is beyond a navigation-grade IMU" in f.text
    m["gyro_bias_final_dph"] = [0.0, 0.0, 0.05]
    assert _estimate_findings(res, p, m) == []


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    from sinslab.data import write_fixes, write_imu
    imu, fx, _, err, _ = simulated_car_drive(turning_drive_segments())
    d = tmp_path_factory.mktemp("drive")
    write_imu(d / "imu.csv", imu)
    write_fixes(d / "fixes.csv", fx)
    return d, err


def test_consumer_imu_declared_navigation_grade_is_flagged(drive, tmp_path):
    """The simulated consumer MEMS (gyro bias z 0.15 °/s = 540 °/h) run as navigation grade
    (0.01 °/h): the filter finds the bias (within 5 % of the simulated one) and the run says
    the estimate is beyond the declared grade — a warning line and the report's flag."""
    from sinslab.cli import app
    d, err = drive
    out = tmp_path / "run"
    r = CliRunner().invoke(app, ["-q", "navigate", "--imu", str(d / "imu.csv"), "--fixes", str(d / "fixes.csv"),
                                 "--imu-errors", "navigation", "--out", str(out)])
    assert r.exit_code == 0, r.output
    s = json.loads((out / "summary.json").read_text())
    gz = s["metrics"]["gyro_bias_final_dph"][2]
    assert gz == pytest.approx(float(np.ravel(err.gyro_bias)[2]) / u.dph, rel=0.05)          # 540 °/h
    line = [w for w in s["warnings"] if "estimated gyro bias z" in w]
    assert line and "of the declared error model (--imu-errors navigation" in line[0], s["warnings"]
    assert "warning: " + line[0][:60] in r.output
    assert "estimated gyro bias z" in (out / "report.html").read_text()
