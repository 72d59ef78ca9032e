"""The filter's error model from a TOML file or a grade (sinslab.app.error_model): every
term reaches the NavOptions field it names, in SI, and bad files are one clear line."""
import numpy as np
import pytest

from sinslab.app import error_model as M
from sinslab.core import units as u
from sinslab.fusion.recorded import NavOptions, recorded_model


@pytest.mark.parametrize("grade", ["consumer", "industrial", "tactical", "navigation"])
def test_grades_reach_the_options(grade):
    err, extras, resolved = M.load_error_model(grade)
    opt = M.apply_error_model(NavOptions(), err, extras)
    g = M.GRADES[grade]
    assert opt.errors.gyro_arw == pytest.approx(u.parse(g["gyro_arw"], "angle_random_walk"))
    assert opt.errors.accel_vrw == pytest.approx(u.parse(g["accel_vrw"], "velocity_random_walk"))
    assert opt.errors.gyro_bias_sigma == pytest.approx(u.parse(g["gyro_bias"], "angular_rate"))
    assert opt.errors.rest_noise is False and opt.errors.scale_factors
    assert resolved["grade"] == grade


def test_bias_models_and_overrides(tmp_path):
    p = tmp_path / "e.toml"
    p.write_text('grade = "tactical"\n[imu]\ngyro_bias_instability = "0.5 deg/h"\ngyro_corr_time = "300 s"\n'
                 'accel_rrw = "10 ug/sqrt(h)"\n[scale]\ngyro_corr_time = "3600 s"\naccel_rw = "10 ppm/sqrt(h)"\n'
                 '[initial]\nattitude = ["0.5 deg", "0.5 deg", "3 deg"]\n'
                 '[fixes]\nposition_sigma = "[0.5, 0.5, 1.0] m"\nvelocity_floor = "0.02 m/s"\n'
                 '[aiding]\nzupt_sigma = "0.01 m/s"\nlever_sigma = "0.5 m"\n')
    err, extras, resolved = M.load_error_model(p)
    opt = M.apply_error_model(NavOptions(), err, extras)
    sig, tau = opt.errors.gyro_markov
    assert tau == 300.0 and sig == pytest.approx(0.5 * u.dph)
    assert opt.errors.accel_rrw == pytest.approx(10 * u.ug / 60)
    assert opt.errors.scale_tau == (3600.0, None) and opt.errors.scale_rw[1] == pytest.approx(1e-5 / 60)
    assert opt.start.att_sigma == pytest.approx((0.5 * u.deg, 0.5 * u.deg, 3 * u.deg))
    assert opt.fix.fix_sigma == pytest.approx((0.5, 0.5, 1.0)) and opt.fix.vel_sigma_floor == 0.02
    # the [aiding] table goes to the aids that are enabled
    assert M.aid_settings("zupt", extras) == {"sigma": 0.01} and M.aid_settings("lever", extras) == {"sigma": 0.5}
    assert M.aid_settings("nhc", extras) == {}
    # the model carries the blocks with their dynamics: Gauss-Markov gyro bias, GM gyro
    # scale (F = -1/tau on the diagonal), accel scale random walk (noise q = rw^2)
    m = recorded_model(opt, opt.errors.gyro_arw, opt.errors.accel_vrw)
    lay = m.layout
    assert {"eps", "nabla", "eps_m", "kg", "ka"} <= set(lay.names)
    blocks = {s.name: s for s in m._ins[0]["sensors"]}
    assert blocks["kg"].dynamics() == pytest.approx(np.full(3, -1 / 3600.0))
    assert blocks["ka"].q == pytest.approx(np.full(3, (1e-5 / 60) ** 2))
    assert blocks["eps_m"].q == pytest.approx(2 * (0.5 * u.dph) ** 2 / 300.0)
    assert resolved["scale.gyro_corr_time"] == "3600 s"


@pytest.mark.parametrize("text, msg", [
    ('grade = "supreme"\n', "unknown grade"),
    ('[imu]\ngyro_arw = "0.1 deg/h"\n', "gyro_arw"),
    ('[imu]\ngyro_arww = "0.1 deg/sqrt(h)"\n', "gyro_arww"),
    ('[sensors]\nx = 1\n', "unknown key"),
    ('grade = "tactical"\n[fixes]\nposition = "1 m"\n', r"\[fixes\] unknown key"),
    ('grade = "tactical"\n[scale]\ngyro_rw = "1 ppm/sqrt(h)"\ngyro_corr_time = "10 s"\n', "not both"),
    ('grade = "tactical"\n[initial]\nattitude = "5"\n', "attitude"),
    ("grade = \n", "not valid TOML"),
])
def test_bad_files(tmp_path, text, msg):
    p = tmp_path / "e.toml"
    p.write_text(text)
    with pytest.raises(ValueError, match=msg) as e:
        M.load_error_model(p)
    assert "\n" not in str(e.value)


def test_not_a_file_nor_a_grade():
    with pytest.raises(ValueError, match="neither a file nor a grade"):
        M.load_error_model("/nonexistent/model.toml")
