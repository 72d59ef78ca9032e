"""Simulated cars for the consistency of the NHC vehicle states: an IMU mounted off the
rear axle (a lever arm and a small pitch/yaw mount in the car), the car's rear-axle centre
moving without lateral or vertical velocity (the non-holonomic constraint holds exactly
there), a GNSS antenna elsewhere on the roof."""
import math

import numpy as np

import foreign_unit as fu
from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.core.records import ImuRecord
from sinslab.fusion import recorded as R
from sinslab.sim import imu as IM
from sinslab.sim import trajectory as tr


def drive_segments(rng, loops=6):
    """About 40 s a loop (6: 4 min) after a rest: turns left and right at 5–15 °/s, speed changes and a
    hill (the pitch rate lets the vertical constraint see the forward lever)."""
    segs = [tr.Static(duration=20.0), tr.Accelerate(duration=6.0, accel=2.0)]
    for k in range(loops):
        segs += [tr.Level(duration=float(rng.uniform(5, 12))),
                 tr.Turn(duration=float(rng.uniform(6, 12)), rate=float(rng.choice([-1, 1]) * rng.uniform(5, 15)) * u.deg,
                         coordinated=False),
                 tr.Climb(duration=8.0, angle=float(rng.uniform(-4, 4)) * u.deg, transition=4.0),
                 tr.Accelerate(duration=4.0, accel=1.0 if k % 2 else -1.0),
                 tr.Level(duration=6.0, transition=4.0)]
    return segs


def imu_off_the_axle(axle: ImuRecord, Cvb, r_v):
    """The increments of an IMU at ``r_v`` (vehicle axes, from the reference point whose
    increments ``axle`` holds in vehicle axes [m]) mounted with ``C_b^v`` = ``Cvb``: the
    same rotation, the specific force plus ``ω̇ × r + ω × (ω × r)`` (ω̇ by central
    differences of the rate), both turned into the IMU's axes."""
    dt = axle.dt
    w = axle.dtheta / dt
    wd = np.gradient(w, dt, axis=0)
    extra = np.cross(wd, r_v) + np.cross(w, np.cross(w, r_v))
    return ImuRecord(axle.t, axle.dtheta @ Cvb, (axle.dv + extra * dt) @ Cvb, dt)


def simulated_car(seed, nhc_sigma=(0.1, 0.1), loops=6):
    """One car: ``(imu, fixes, truth, opt)`` — the IMU at a random lever from the axle
    (0.3 m across, 0.5–2 m forward, 0.3–1 m up) with a random pitch/yaw mount (σ 1°), an
    industrial IMU, 5 Hz fixes of 2 cm / 2 cm/s at an antenna on the roof; ``truth`` holds
    the mount [pitch, roll, yaw] [rad] and the NHC lever (IMU -> axle, vehicle axes) [m];
    ``opt`` the filter options estimating them from zero."""
    rng = np.random.default_rng(seed)
    g = tr.generate(drive_segments(rng, loops), tr.Start(lat=math.radians(45.0), lon=math.radians(7.6), h=250.0,
                                                 heading=float(rng.uniform(0, 2 * math.pi))), 0.01)
    mount = np.radians([rng.normal(0, 1.0), 0.0, rng.normal(0, 1.0)])
    Cvb = A.euler_to_dcm(mount)
    r_v = np.array([rng.uniform(-0.3, 0.3), rng.uniform(0.5, 2.0), rng.uniform(0.3, 1.0)])
    err = IM.ImuErrors.from_datasheet(gyro_bias="10 deg/h", gyro_arw="0.2 deg/sqrt(h)",
                                      accel_bias="1000 ug", accel_vrw="100 ug/sqrt(Hz)")
    imu = IM.apply(imu_off_the_axle(g.imu, Cvb, r_v), err, int(seed) + 1000)
    r_ant = np.array([0.0, 1.2, 1.5])
    fx = fu.fixes_at(g.truth, np.arange(0.2, g.truth.t[-1] - 0.1, 0.2), rng, pos_sigma=0.02, vel_sigma=0.02,
                     lever=r_ant, imu=g.imu)
    opt = R.NavOptions.of(lever_arm=tuple(Cvb.T @ (r_ant - r_v)), rest_noise=False, gyro_arw=0.2 * u.deg / 60,
                          accel_vrw=100 * u.ug, gyro_bias_sigma=10 * u.dph, accel_bias_sigma=1e-2,
                          nhc_sigma=nhc_sigma, estimate_vehicle=True)
    return imu, fx, {"mount": mount, "nhc_lever": -r_v}, opt


def normalised_errors(res, truth):
    """(estimate − truth) / σ of the mount pitch, yaw and the NHC lever x, y, z."""
    i = res.init
    m, sm = np.asarray(i["vehicle_mount_estimate"]), i["vehicle_mount_sigma"]
    lv, sl = np.asarray(i["nhc_lever_estimate"]), np.asarray(i["nhc_lever_sigma"])
    e = [(m[0] - truth["mount"][0]) / sm[0], A.wrap_pi(m[2] - truth["mount"][2]) / sm[2]]
    return np.r_[e, (lv - truth["nhc_lever"]) / sl], np.r_[sm[0], sm[2], sl]


def run_car(seed, **kw):
    imu, fx, truth, opt = simulated_car(seed, **kw)
    res = R.navigate_recorded(imu, fx, opt)
    return normalised_errors(res, truth), res
