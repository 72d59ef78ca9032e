"""Allan deviation: recovery of known noise terms and the laser-gyro record."""
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sinslab.sim import allan as AL
from sinslab.sim import imu as IM

from sinslab.core import units as u
from sinslab.core.records import ImuRecord
from support import assert_doc_quotes

LASER = Path(__file__).resolve().parents[3] / "shared" / "data" / "psins-lasergyro" / "lasergyro.imu"


def test_fit_recovers_synthesised_noise():
    # 2 h at 100 Hz: ARW 0.003 deg/sqrt(h), GM bias 0.05 deg/h (tau 1000 s); VRW 20 ug/sqrt(Hz),
    # GM 30 ug (tau 1000 s). The long correlation time puts a single clear minimum (white
    # falling, GM rising) at 20-300 s where the overlapping estimate has many clusters; a
    # short one makes the GM tail fall like white noise and the minimum land at the last tau.
    e = IM.ImuErrors.from_datasheet(gyro_arw="0.003 deg/sqrt(h)", gyro_bias_instability="0.05 deg/h",
                                    gyro_corr_time="1000 s", accel_vrw="20 ug/sqrt(Hz)",
                                    accel_bias_instability="30 ug", accel_corr_time="1000 s")
    n = int(2 * 3600 / 0.01)
    dth, dv = IM.noise_increments(n, 0.01, e, np.random.default_rng(7))
    r = AL.allan(ImuRecord(0.01 * np.arange(1, n + 1), dth, dv, 0.01))
    for fits, n0, s0 in ((r.gyro, 0.003 * u.dpsh, 0.05 * u.dph), (r.accel, 20 * u.ugpsHz, 30 * u.ug)):
        ratios = []
        for f in fits:
            assert f.n_white == pytest.approx(n0, rel=0.05)                 # ARW/VRW within 5 %
            assert not f.n_is_bound
            theory = np.min(np.sqrt(IM.gm_allan_deviation(f.tau, s0, 1000.0) ** 2 + n0 ** 2 / f.tau))
            ratios.append(f.floor / theory)
        # Allan floor (-> bias instability): each axis within 25 %, their median within 15 %
        assert np.all(np.abs(np.array(ratios) - 1) < 0.25) and abs(np.median(ratios) - 1) < 0.15
    errs = AL.imu_errors_from_allan(r)
    back = IM.ImuErrors.from_toml(errs.to_toml("imu"))
    assert back.gyro_arw == pytest.approx(errs.gyro_arw, rel=1e-9)
    # a GM block whose Allan peak is the measured floor
    assert errs.gyro_bias_instability * IM.GM_ALLAN_PEAK == pytest.approx([f.floor for f in r.gyro], rel=1e-9)


def test_rate_random_walk_recovered():
    e = IM.ImuErrors.from_datasheet(gyro_arw="0.01 deg/sqrt(h)", gyro_rrw="2 deg/h/sqrt(h)")
    n = int(3600 / 0.01)
    dth, dv = IM.noise_increments(n, 0.01, e, np.random.default_rng(3))
    r = AL.allan(ImuRecord(0.01 * np.arange(1, n + 1), dth, dv + 1e-9, 0.01))
    k = np.array([f.rrw for f in r.gyro]) / u.dphpsh
    assert k == pytest.approx(2.0, rel=0.35)


@pytest.mark.skipif(not LASER.exists(), reason="lasergyro.imu not available")
def test_lasergyro_and_cli(tmp_path):
    from sinslab.cli import app
    out = tmp_path / "al"
    res = CliRunner().invoke(app, ["-q", "allan", str(LASER), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "[imu]" in res.output and "gyro_arw" in res.output
    m = json.loads((out / "summary.json").read_text())["metrics"]
    # the vehicle sways ("some disturbance"): the horizontal gyros show the base motion; the
    # azimuth gyro gives the bound ARW <= 0.03 deg/sqrt(h), floor 0.17 deg/h at the longest
    # cluster time (205 s of a 1847 s record) -- docs/recorded-data.md
    assert m["gyro_z_arw_dpsh"] == pytest.approx(0.028, rel=0.1)
    assert m["gyro_z_bias_instability_dph"] == pytest.approx(0.174, rel=0.1)
    assert m["gyro_x_bias_instability_dph"] > 5 * m["gyro_z_bias_instability_dph"]
    doc = "docs/recorded-data.md"
    for row, ax in (("| gyro x | 0.33 °/√h (base sway plateau) | 1.67 °/h (205 s) |", "x"),
                    ("| gyro y | ≤ 0.32 °/√h | 2.05 °/h (205 s) |", "y"),
                    ("| gyro z (azimuth) | **≤ 0.028 °/√h** | **0.17 °/h** (205 s) |", "z")):
        assert_doc_quotes(doc, row, [m[f"gyro_{ax}_arw_dpsh"], m[f"gyro_{ax}_bias_instability_dph"],
                                     m[f"gyro_{ax}_tau_floor_s"]])
    assert_doc_quotes(doc, "| accel x, y, z | 750, 551, ≤ 55 µg/√Hz | 385 µg (1.8 s), 216 µg (2.6 s), 12.7 µg (105 s) |",
                      [*(m[f"accel_{a}_vrw_ugpsHz"] for a in "xyz"),
                       *(m[f"accel_{a}_{k}"] for a in "xyz" for k in ("bias_instability_ug", "tau_floor_s"))])
    assert (out / "imu_errors.toml").is_file() and (out / "allan.png").is_file()
    IM.ImuErrors.from_toml((out / "imu_errors.toml").read_text())
    res = CliRunner().invoke(app, ["allan", str(tmp_path / "missing.csv"), "--out", str(tmp_path / "x")])
    assert res.exit_code == 2 and "no such file" in res.output
