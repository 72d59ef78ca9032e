"""Ready-made motions (SI arguments): a carrier at rest, mixed aircraft manoeuvres and a
continuously manoeuvring ship, as segment lists of :mod:`sinslab.sim.trajectory` for its
:func:`~sinslab.sim.trajectory.generate`."""
from __future__ import annotations

import math

from sinslab.core import units
from sinslab.sim.trajectory import Accelerate, Climb, Level, Segment, Ship, Static, Turn, WingRock

__all__ = ["static", "aircraft_mixed", "ship_manoeuvring"]


def static(duration: float = 3600.0) -> list[Segment]:
    """A carrier at rest for ``duration`` seconds."""
    return [Static(float(duration))]


def _fill(cycle, duration):
    out, t = [], 0.0
    while True:
        added = False
        for s in cycle:
            if t + s.duration > duration + 1e-9:
                rest = duration - t
                if rest > 1e-9:
                    out.append(Level(rest, transition=min(5.0, rest)))
                return out
            out.append(s)
            t += s.duration
            added = True
        if not added:
            return out


def aircraft_mixed(duration: float = 3600.0, *, turn_rate: float = 1.5 * units.deg,
                   climb_angle: float = 5.0 * units.deg, accel: float = 2.0,
                   wing_rock_amplitude: float = 10.0 * units.deg,
                   wing_rock_period: float = 4.0) -> list[Segment]:
    """Aircraft manoeuvres repeated to fill ``duration`` [s]: level flight, coordinated
    turns (right and left), climb and descent, acceleration and deceleration, wing rock
    (SI arguments).

    One cycle lasts 700 s and returns to the same speed and height; its net heading change
    is +90° (turns of 90°, −180°, +180° at ``turn_rate``, rolled in and out over 5 s). At
    the paper-003 start (32° N, 118° E, 1000 m, heading 0°, 300 m/s) the default turns
    bank by about 39°. A last incomplete cycle is cut and ends with level flight.
    """
    tr = turn_rate
    t90 = (math.pi / 2) / tr + 5.0
    t180 = math.pi / tr + 5.0
    cycle = [
        Level(40.0),
        Accelerate(25.0, accel, ramp=3.0),
        Turn(t90, tr, ramp=5.0),                         # +90° (right)
        Climb(60.0, climb_angle, transition=10.0),
        Level(40.0, transition=10.0),
        WingRock(40.0, wing_rock_amplitude, wing_rock_period, ramp=wing_rock_period),
        Turn(t180, -tr, ramp=5.0),                       # 180° left
        Climb(60.0, -climb_angle, transition=10.0),      # descend
        Level(40.0, transition=10.0),
        Accelerate(25.0, -accel, ramp=3.0),
        Turn(t180, tr, ramp=5.0),                        # 180° right
    ]
    used = sum(s.duration for s in cycle)
    if used < 700.0:
        cycle.append(Level(700.0 - used))
    return _fill(cycle, float(duration))


def ship_manoeuvring(duration: float = 48 * 3600.0, *, static_time: float = 0.0,
                     mean_speed: float = 15.0, speed_amplitude: float = 15.0,
                     speed_period: float = 1200.0, course_amplitude: float = 30.0 * units.deg,
                     course_period: float = 1800.0, roll_amplitude: float = 5.0 * units.deg,
                     roll_period: float = 12.0, pitch_amplitude: float = 2.0 * units.deg,
                     pitch_period: float = 8.0, yaw_amplitude: float = 1.0 * units.deg,
                     yaw_period: float = 15.0, heave_amplitude: float = 0.5,
                     heave_period: float = 10.0, accel: float = 0.1) -> list[Segment]:
    """Continuously manoeuvring ship (paper 004 default): optional rest, acceleration to
    ``mean_speed``, then sinusoidal speed (amplitude 15 m/s: 0–30 m/s), sinusoidal course
    (±30°: with a start heading of 30° the heading stays within 0–60°), roll/pitch/yaw
    sway and heave, for the rest of ``duration`` [s] (SI arguments)."""
    segs: list[Segment] = []
    if static_time > 0:
        segs.append(Static(static_time))
    ta = mean_speed / accel + 10.0
    segs.append(Accelerate(ta, accel, ramp=10.0))
    rest = duration - static_time - ta
    if rest <= 20.0:
        raise ValueError(f"duration {duration} s is too short for the ship manoeuvres")
    segs.append(Ship(rest, pitch_amplitude, pitch_period, roll_amplitude, roll_period,
                     yaw_amplitude, yaw_period, heave_amplitude, heave_period,
                     speed_amplitude, speed_period, course_amplitude, course_period,
                     ramp=min(60.0, rest / 2)))
    return segs
