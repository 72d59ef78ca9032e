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
    st = res.start
    assert res.platform[0] == "aircraft"
    assert st.heading_source.startswith("in-motion alignment over 10.0 s"), st.heading_source
    assert st.t < 20.0, st.t                                  # the first window that shows the heading
    k = int(np.searchsorted(tru.t, st.t - 1e-9))
    C_est = A.euler_to_dcm(np.array([st.pitch, st.roll, A.heading_to_yaw(st.heading)]))
    phi = A.misalignment(A.euler_to_dcm(tru.att[k]), C_est)
    sig = np.asarray(st.motion_fit.sigma)
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


def test_a_start_given_whole_holds_where_and_as_given(turning_flight):
    """The start a user gives (NaveGo's ini_align, KF-GINS's init file): attitude, the IMU
    point's position and velocity at the time given, and their σ, are where and what the
    filter starts from — the truth of the flight 30 s in, in the middle of a turn, where
    nothing could be found; the sources say "given". Pitch and roll given alone keep the
    heading search, and keep their values through it."""
    from sinslab.fusion.recorded_spec import ErrorSpec, StartSpec
    from sinslab.fusion.recorded_start import solve_start
    imu, fx, tru = turning_flight
    k = int(np.argmin(np.abs(tru.t - 30.0)))
    t0 = float(tru.t[k])
    hd = float(A.yaw_to_heading(tru.att[k, 2]))
    given = dict(pitch=float(tru.att[k, 0]), roll=float(tru.att[k, 1]), heading=hd, init_time=t0,
                 init_position=(float(tru.lat[k]), float(tru.lon[k]), float(tru.h[k])),
                 init_velocity=tuple(tru.vel[k].tolist()), att_sigma=(0.001, 0.001, 0.002),
                 init_position_sigma=(0.3, 0.4, 0.5), init_velocity_sigma=(0.03, 0.04, 0.05))
    res = navigate_recorded(imu, fx, NavOptions.of(**given))
    st = res.start
    assert st.t == pytest.approx(t0, abs=1e-9)
    assert np.allclose(st.att, tru.att[k], atol=1e-12) and st.position == given["init_position"]
    assert np.array_equal(st.velocity, tru.vel[k])
    assert all(st.sources[f].startswith("given") for f in ("attitude", "attitude_sigma", "position", "velocity",
                                                             "position_sigma", "velocity_sigma")), st.sources
    lab = list(res.labels)
    sig0 = res.sigma[0]                                       # after one 0.02 s step: the prior, barely grown
    assert sig0[[lab.index(f"dv{a}") for a in "ENU"]] == pytest.approx([0.03, 0.04, 0.05], rel=0.05)
    assert sig0[:3] == pytest.approx([0.001, 0.001, 0.002], rel=0.05)
    _, err, _ = fix_errors(res, fx)
    assert float(np.median(np.hypot(err[:, 0], err[:, 1]))) < 1.5
    tilt = StartSpec(pitch=0.1, roll=-0.05)
    part = solve_start(imu, fx, tilt, ErrorSpec(), np.zeros(3), 2, ("aircraft", ""))
    assert (part.pitch, part.roll) == (0.1, -0.05) and part.sources["attitude"].startswith("pitch and roll given")
    assert part.heading_source != "given" and part.heading_sigma is not None, part.heading_source
    with pytest.raises(ValueError, match="start time needs the whole attitude"):
        StartSpec(heading=1.0, init_time=5.0)
