"""Rotate-stop schedules and swinging table: stops, timing, continuity, config parsing, and
agreement between indexing.mount_angles (numpy) and the trajectory kernel."""
import math

import numpy as np
import pytest

from sinslab.core import attitude as at
from sinslab.sim import indexing as ix
from sinslab.sim import trajectory as tr
from sinslab.core import units as u


def _stops(m, which):
    """Mount angles in the middle of every dwell of the first cycle."""
    t, out = 0.0, []
    for _, x in m.moves:
        out.append(t + m.dwell / 2)
        t += m.dwell + m.move_time(x)
    out.append(t + m.dwell / 2)
    ang, rate = ix.mount_angles(m, np.array(out))
    assert np.all(rate == 0.0)
    return np.degrees(ang[:, which])


def test_single_axis_four_positions():
    m = ix.single_axis_4pos(rate=10 * u.deg, dwell=60.0, ramp=1.0)
    yaw = _stops(m, 2)
    np.testing.assert_allclose(yaw, [0, 180, 270, 90, 0], atol=1e-9)
    assert sorted(np.mod(np.round(yaw[:4]), 360)) == [0, 90, 180, 270]
    assert m.cycle_time == pytest.approx(4 * 60 + (180 + 90 + 180 + 90) / 10 + 4 * 1.0)


def test_dual_axis_sixteen_steps_stop_at_0_and_180():
    m = ix.dual_axis_16(dwell=30.0)
    assert len(m.moves) == 16
    ang = _stops(m, [1, 2])
    assert np.all(np.isclose(np.mod(ang, 180.0), 0.0, atol=1e-9) | np.isclose(np.mod(ang, 180.0), 180.0, atol=1e-9))
    np.testing.assert_allclose(ang[-1], [0, 0], atol=1e-9)      # a cycle comes back
    # both axes are used equally, every move is cancelled within the cycle
    for axis in ("yaw", "roll"):
        mv = [x for a, x in m.moves if a == axis]
        assert len(mv) == 8 and sum(mv) == pytest.approx(0.0)
    # the 8 stops of the sequence visit all four (roll, yaw) combinations of 0/180
    combos = {tuple(np.mod(np.round(a), 360).astype(int)) for a in ang}
    assert combos == {(0, 0), (0, 180), (180, 0), (180, 180)}


@pytest.mark.parametrize("mount", [ix.dual_axis_16(dwell=5.0, ramp=0.5),
                                   ix.single_axis_4pos(dwell=3.0, rate=20 * u.deg, ramp=2.0),
                                   ix.Swing(axis="roll", amplitude=5 * u.deg, period=40.0, ramp=10.0)])
def test_rates_are_the_derivative_of_angles_and_continuous(mount):
    t = np.linspace(0.0, 300.0, 300001)
    ang, rate = ix.mount_angles(mount, t)
    num = np.gradient(ang, t, axis=0)
    assert np.abs(num - rate)[2:-2].max() < 1e-6
    assert np.abs(np.diff(rate, axis=0)).max() < 1e-3          # no jumps (rates ~0.1-0.35 rad/s)


def test_rotation_profile_reaches_rate_and_takes_the_stated_time():
    m = ix.RotateStop((("yaw", math.radians(90.0)),), rate=10 * u.deg, ramp=2.0, dwell=10.0, repeat=False)
    assert m.move_time(math.radians(90.0)) == pytest.approx(11.0)
    t = np.array([10.0, 12.0, 15.0, 21.0, 22.0, 100.0])
    ang, rate = ix.mount_angles(m, t)
    np.testing.assert_allclose(rate[:, 2], [0, 10 * u.deg, 10 * u.deg, 0, 0, 0], atol=1e-15)
    np.testing.assert_allclose(np.degrees(ang[[0, -2, -1], 2]), [0, 90, 90], atol=1e-12)


def test_swing_amplitude_period():
    s = ix.Swing(axis="pitch", amplitude=5 * u.deg, period=40.0)
    t = np.arange(0, 80.0, 0.01)
    ang, rate = ix.mount_angles(s, t)
    assert np.abs(ang[:, 0]).max() == pytest.approx(5 * u.deg, rel=1e-6)
    np.testing.assert_allclose(ang[:, 0], 5 * u.deg * np.sin(2 * np.pi * t / 40.0), atol=1e-15)
    assert np.all(ang[:, 1:] == 0)


@pytest.mark.parametrize("mount", [ix.dual_axis_16(dwell=7.0, rate=12 * u.deg, ramp=0.7),
                                   ix.single_axis_4pos(dwell=4.0),
                                   ix.Swing(axis="yaw", amplitude=30 * u.deg, period=25.0, ramp=6.0,
                                            initial=(0.0, 0.1, 0.2))])
def test_trajectory_kernel_agrees_with_mount_angles(mount):
    st = tr.Start(lat=0.5, lon=0.1, speed=10.0, heading=1.0)
    g = tr.generate([tr.Turn(200.0, 1 * u.deg, ramp=5.0, coordinated=False)], st, 0.01, mount=mount)
    ang, _ = ix.mount_angles(mount, g.truth.t)
    np.testing.assert_allclose(g.mount, at.wrap_pi(ang), atol=1e-12)
    # IMU attitude = carrier attitude composed with the mount
    C = at.euler_to_dcm(g.truth.att) @ at.euler_to_dcm(g.mount)
    phi = at.misalignment(C, at.euler_to_dcm(g.truth.att_imu))
    assert np.abs(phi).max() < 1e-13


def test_mount_from_dict_and_back():
    m = ix.mount_from_dict({"kind": "rotate_stop", "scheme": "dual_axis_16", "rate": "9 deg/s",
                            "dwell": "5 min", "ramp": "1 s"})
    assert m == ix.dual_axis_16(rate=9 * u.deg, dwell=300.0, ramp=1.0)
    assert ix.mount_from_dict(m.to_dict()) == m
    c = ix.mount_from_dict({"kind": "rotate_stop", "moves": [["yaw", "90 deg"], ["roll", "-180 deg"]],
                            "rate": "6 deg/s", "repeat": False})
    assert c.moves == (("yaw", math.radians(90)), ("roll", -math.pi)) and not c.repeat
    assert ix.mount_from_dict(c.to_dict()) == c
    s = ix.mount_from_dict({"kind": "swing", "axis": "roll", "amplitude": "5 deg", "period": "40 s"})
    assert s == ix.Swing(axis="roll", amplitude=5 * u.deg, period=40.0)
    assert ix.mount_from_dict(s.to_dict()) == s


@pytest.mark.parametrize("d,words", [
    ({"kind": "spin"}, ["'kind'"]),
    ({"kind": "swing", "amplitude": "5 m"}, ["'amplitude'", "angle"]),
    ({"kind": "swing", "period": "40"}, ["'period'", "no unit"]),
    ({"kind": "swing", "axis": "heave"}, ["heave"]),
    ({"kind": "swing", "speed": "1 m/s"}, ["unknown key 'speed'"]),
    ({"kind": "rotate_stop"}, ["'scheme'", "'moves'"]),
    ({"kind": "rotate_stop", "scheme": "triple"}, ["'scheme'", "triple"]),
    ({"kind": "rotate_stop", "scheme": "dual_axis_16", "rate": "0 deg/s"}, ["rate"]),
    ({"kind": "rotate_stop", "scheme": "dual_axis_16", "rate": "9 deg/s", "ramp": "30 s"}, ["too small"]),
    ({"kind": "rotate_stop", "moves": [["yaw"]]}, ["'moves'"]),
])
def test_bad_mount_tables(d, words):
    with pytest.raises(ValueError) as ei:
        ix.mount_from_dict(d)
    for w in words:
        assert w in str(ei.value), str(ei.value)
