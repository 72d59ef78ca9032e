"""An IMU made from a reference trajectory sampled at 1 Hz (:mod:`sinslab.sim.from_reference`).
Oracle: the strapdown mechanization of the increments it returns follows the truth it
returns (free inertial, no errors) — one motion; and that truth passes through every
reference position."""
import math

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.core.earth import radii
from sinslab.core.records import NavState
from sinslab.nav import strapdown as sd
from sinslab.sim import trajectory as tr
from sinslab.sim.from_reference import imu_from_reference


def test_rebuilt_imu_mechanises_back_to_its_truth():
    segs = [tr.Accelerate(duration=5.0, accel=2.0), tr.Turn(duration=10.0, rate=10 * u.deg, coordinated=False),
            tr.Climb(duration=10.0, angle=3 * u.deg), tr.Level(duration=10.0),
            tr.Turn(duration=15.0, rate=-8 * u.deg, coordinated=False), tr.Level(duration=20.0)]
    g = tr.generate(segs, tr.Start(lat=math.radians(45), lon=math.radians(7), h=300.0, heading=0.4, speed=5.0), 0.01)
    ref = g.truth.at(slice(0, None, 100))                                   # a 1 Hz reference
    imu, tru = imu_from_reference(ref, 0.01)
    k = np.searchsorted(tru.t, ref.t)
    rm, rn = radii(ref.lat, ref.h)
    assert np.max(np.abs(tru.lat[k] - ref.lat) * rm) < 1e-6 and np.max(np.abs(tru.h[k] - ref.h)) < 1e-6
    nav = sd.navigate(imu, NavState.from_series(tru, 0), nsub=2)
    j = np.clip(np.searchsorted(nav.t, tru.t), 0, nav.t.size - 1)
    rm, rn = radii(tru.lat, tru.h)
    hz = np.hypot((nav.lat[j] - tru.lat) * rm, (nav.lon[j] - tru.lon) * rn * np.cos(tru.lat))
    assert np.max(hz) < 0.2, np.max(hz)                                      # 70 s free inertial
    assert np.max(np.abs(nav.vel[j] - tru.vel)) < 0.03
    phi = A.misalignment(A.euler_to_dcm(tru.att[-1]), A.euler_to_dcm(nav.att[j[-1]]))
    assert np.degrees(np.max(np.abs(phi))) < 0.01
