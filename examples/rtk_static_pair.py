"""RTK on the real static rover + base pair (cssrlib-static-rtk), GNSS alone and with a
synthesised consumer IMU at rest on the rover's antenna, against the reference coordinates.

    python examples/rtk_static_pair.py DATA_DIR

DATA_DIR holds SEPT078M1.21O (rover), 3034078M1.21O (base) and SEPT078M.21P (navigation).
Prints the table of docs/raw-gnss.md: time to first fix, share of epochs fixed and the
error of the fixed antenna positions (east/north/up against the rover's reference
coordinates). The observations are real; the IMU is simulated (a consumer MEMS at rest at
the antenna, 100 Hz: gyro bias 0.1 °/s and ARW 0.6 °/√h, accelerometer bias 40 mg and VRW
150 µg/√Hz, drawn with seed 1; the filter starts 3 m off in position, 3° off in tilt and
10° in heading, each within its σ).
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from sinslab.core import earth as E

BASE = np.array([-3959400.631, 3385704.533, 3667523.111])        # GSI 3034 (the set's README)
ROVER = np.array([-3962108.673, 3381309.574, 3668678.638])


def read(data):
    from sinslab.data.gnss import read_gnss_raw
    from sinslab.fusion.gnss import prepare
    from sinslab.fusion.rtk import RtkBase
    nav = data / "SEPT078M.21P"
    rover = prepare(read_gnss_raw(data / "SEPT078M1.21O", nav))
    base = prepare(read_gnss_raw(data / "3034078M1.21O", nav))
    return rover, RtkBase(base, BASE, "3034078M1.21O")


def consumer_imu_at_rest(rover, seed=1):
    """100 Hz increments of a consumer MEMS standing still at the rover's reference
    coordinates, on the observations' time axis (from 1 s before the first epoch), the
    truth's start state and the σ of the errors drawn."""
    from sinslab.core import units as u
    from sinslab.core.records import ImuRecord
    from sinslab.sim import imu as IM
    from sinslab.sim import trajectory as tr
    lat, lon, h = (float(v) for v in E.ecef_to_geodetic(ROVER))
    dur = float(rover.t_epoch[-1] - rover.t_epoch[0]) + 2.0
    g = tr.generate([tr.Static(duration=dur)], tr.Start(lat=lat, lon=lon, h=h, heading=math.radians(40.0)), 0.01)
    rng = np.random.default_rng(seed)
    err = IM.ImuErrors.from_datasheet(gyro_bias=[f"{v} deg/s" for v in rng.normal(0, 0.1, 3)],
                                      accel_bias=[f"{v} ug" for v in rng.normal(0, 40000, 3)],
                                      gyro_arw="0.6 deg/sqrt(h)", accel_vrw="150 ug/sqrt(Hz)")
    imu = IM.apply(g.imu, err, rng)
    t0 = float(rover.t_epoch[0]) - 1.0
    imu = ImuRecord(imu.t + t0, imu.dtheta, imu.dv, imu.dt)
    sig = dict(gyro_bias=0.1 * u.deg, accel_bias=0.04 * 9.80665, arw=0.6 * u.deg / 60.0, vrw=150e-6 * 9.80665)
    return imu, g.truth, sig, rng


def rtk_ins_at_rest(rover, base):
    from sinslab.core import attitude as A
    from sinslab.core.records import NavState
    from sinslab.fusion.carrier import max_signals, slot_count
    from sinslab.fusion.rtk_ins import rtk_ins, rtk_model
    from sinslab.fusion.spec import FilterGrid
    imu, tru, sig, rng = consumer_imu_at_rest(rover)
    rm, rn = E.radii(tru.lat[0], tru.h[0])
    s_att = np.radians([3.0, 3.0, 10.0])
    dp = np.array([2.0, -2.0, 1.0])                       # a single-point start, metres off
    phi = np.radians([2.0, -1.5, 8.0])
    C = A.apply_misalignment(A.euler_to_dcm(tru.att[0]), phi)
    init = NavState(tru.lat[0] + dp[1] / rm, tru.lon[0] + dp[0] / (rn * math.cos(tru.lat[0])), tru.h[0] + dp[2],
                    np.zeros(3), A.dcm_to_euler(C))
    model = rtk_model(sig["arw"], sig["vrw"], slots=slot_count(max_signals(rover)))
    sd = np.r_[s_att, np.full(3, 0.1), 3.0 / rm, 3.0 / (rn * math.cos(tru.lat[0])), 3.0,
               np.full(3, sig["gyro_bias"]), np.full(3, sig["accel_bias"])]
    P0 = np.zeros((model.n, model.n))
    P0[:15, :15] = np.diag(sd ** 2)
    r = rtk_ins(imu, init, rover, base, P0, model, grid=FilterGrid(0.1))
    a = r.rtk.arrays()
    return a["t"], a["status"], a["fixed_pos"]


def rows(rover, base):
    from sinslab.fusion.gnss_alone import rtk_solve
    out = []
    for label, dyn in (("GNSS only, static", "static"), ("GNSS only, kinematic (constant velocity)", "kinematic")):
        s = rtk_solve(rover, base, dynamics=dyn)
        out.append((label, s.t, s.status, s.fixed_pos))
    out.append(("RTK/INS, consumer IMU at rest (simulated)", *rtk_ins_at_rest(rover, base)))
    return out


def main(data):
    data = Path(data)
    rover, base = read(data)
    lat, lon, _ = E.ecef_to_geodetic(ROVER)
    C = E.enu_to_ecef_matrix(lat, lon)
    print(f"baseline {np.linalg.norm(ROVER - BASE) / 1e3:.2f} km, {rover.t_epoch.size} epochs at 1 Hz\n")
    print("| solution | first fix [epoch] | epochs fixed | horizontal RMS / max [cm] | vertical RMS / max [cm] |")
    print("| --- | --- | --- | --- | --- |")
    for label, t, status, pos in rows(rover, base):
        fx = status == 2
        e = (pos[fx] - ROVER) @ C
        hz = np.hypot(e[:, 0], e[:, 1])
        first = int(np.flatnonzero(fx)[0]) + 1 if fx.any() else None
        print(f"| {label} | {first} | {int(fx.sum())} of {fx.size} | {100 * np.sqrt(np.mean(hz ** 2)):.1f} / "
              f"{100 * hz.max():.1f} | {100 * np.sqrt(np.mean(e[:, 2] ** 2)):.1f} / {100 * np.abs(e[:, 2]).max():.1f} |")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python examples/rtk_static_pair.py DATA_DIR")
    main(sys.argv[1])
