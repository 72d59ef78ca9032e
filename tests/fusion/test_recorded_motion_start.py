"""A start in any motion: a simulated small aircraft whose log begins in flight, climbing
and in continuous coordinated turns (course changing 6–25° per second, 18 m/s, 1 Hz fixes
of 1 m / 0.1 m/s), has no straight second for a heading from the course; the in-motion
alignment (Wu & Pan 2013 velocity integration, Davenport's q-method) sees the heading
through the turns' accelerations. Oracle: the simulation's truth at the start, within the
3σ the fit states. A record whose motion shows no heading is refused with the figures of
what it lacks."""
import math
import re

import numpy as np
import pytest

import foreign_unit as fu
from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.fusion.recorded import NavOptions, fix_errors, navigate_recorded
from sinslab.sim import imu as IM
from sinslab.sim import trajectory as tr

RATES = [-18, 10, -25, 15, -8, 20, -12, 6, -15, 22, -10, 14]        # deg/s, one turn after another


def _flight(segs, start, seed=1):
    g = tr.generate(segs, start, 0.02)
    err = IM.ImuErrors.from_datasheet(gyro_bias=["0.05 deg/s", "-0.03 deg/s", "0.04 deg/s"],
                                      accel_bias=["0.03 m/s^2", "-0.02 m/s^2", "0.05 m/s^2"],
                                      gyro_arw="0.01 deg/sqrt(s)", accel_vrw="300 ug/sqrt(Hz)")
    imu = IM.apply(g.imu, err, seed)
    rng = np.random.default_rng(seed)
    fx = fu.fixes_at(g.truth, np.arange(1.0, g.truth.t[-1] - 0.5, 1.0), rng, pos_sigma=1.0, vel_sigma=0.1)
    return imu, fx, g.truth


@pytest.fixture(scope="module")
def turning_flight():
    segs = [tr.Turn(duration=10.0 + 3 * (k % 3), rate=r * u.deg, ramp=0.5) for k, r in enumerate(RATES)]
    start = tr.Start(lat=math.radians(45.2), lon=math.radians(-93.1), h=300.0, heading=math.radians(74),
                     speed=18.0, pitch=math.radians(12))
    return _flight(segs, start)


def test_aircraft_in_continuous_turns_starts_from_the_alignment(turning_flight):
    """Before: "no 1 s of motion faster than 10.0 m/s with a consistent course"."""
    imu, fx, tru = turning_flight
    res = navigate_recorded(imu, fx, NavOptions())
    i = res.init
    assert i["platform"][0] == "aircraft"
    assert i["heading_source"].startswith("in-motion alignment over 10.0 s"), i["heading_source"]
    assert i["t_start"] < 20.0, i["t_start"]                 # the first window that shows the heading
    k = int(np.searchsorted(tru.t, i["t_start"] - 1e-9))
    C_est = A.euler_to_dcm(np.array([i["pitch"], i["roll"], A.heading_to_yaw(i["heading"])]))
    phi = A.misalignment(A.euler_to_dcm(tru.att[k]), C_est)
    sig = np.asarray(i["motion_alignment"]["sigma"])
    assert np.all(np.abs(phi) < 3 * sig + math.radians(0.05)), (np.degrees(phi), np.degrees(sig))
    assert math.degrees(sig[2]) < 2.0
    # and it navigates: the solution stays on the fixes (1 m noise) to the end
    _, err, _ = fix_errors(res, fx)
    hz = np.hypot(err[:, 0], err[:, 1])
    assert float(np.median(hz)) < 1.5 and res.t[-1] > tru.t[-1] - 2.0, float(np.median(hz))


def test_a_record_without_a_visible_heading_is_refused_with_its_figures():
    """A slow straight climb at constant speed: no course above the aircraft's 10 m/s, no
    acceleration to see a heading through."""
    start = tr.Start(lat=math.radians(45.2), lon=math.radians(-93.1), h=300.0, heading=math.radians(74),
                     speed=8.0, pitch=math.radians(25))
    imu, fx, _ = _flight([tr.Climb(duration=40.0, angle=math.radians(25))], start)
    with pytest.raises(ValueError) as e:
        navigate_recorded(imu, fx, NavOptions())
    msg = str(e.value)
    assert "no 1 s of motion faster than 10 m/s with a consistent course" in msg, msg
    assert "whose accelerations show the heading to 5.0 deg (the best of" in msg, msg
    assert re.search(r"fastest fix 7\.\d m/s, largest horizontal acceleration 0\.\d+ m/s²\); give the initial "
                     r"heading", msg), msg
