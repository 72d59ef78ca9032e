"""NaveGo's Turin drive as a user of NaveGo would run it, against a filter tuned on the truth.

    python tools/navego_drive.py REF.mat GNSS.mat [--grade ekinox|mpu ...]

REF.mat and GNSS.mat are NaveGo's ``examples/real-data/ref.mat`` (the reference solution,
1 Hz) and ``ekinox_gnss.mat`` (the receiver's real 5 Hz solution, its σ and lever arm),
read by sinslab's NaveGo reader. The IMU is made from the reference
(:func:`sinslab.sim.from_reference.imu_from_reference`) with a unit's errors: ``ekinox``
(a tactical MEMS: gyro bias 0.2 °/h, ARW 0.15 °/√h, accelerometer bias 50 µg) or ``mpu``
(a consumer MEMS: 300 °/h, 0.6 °/√h, 8 mg). Seven 40 s outages every 150 s from 100 s
after the first fix.

Printed per grade, against the truth: horizontal and vertical RMS, the horizontal error at
each outage end and the velocity error when each outage starts, for

- ``default``: the fixes as the file states them (σ 1 m, 0.05 m/s: white);
- ``fix errors measured``: ``fix_error="auto"`` (sinslab.fusion.fix_noise: the fixes'
  correlation measured from the record and taken into account);
- ``fix σ from innovations``: ``fix_noise="innovations"`` (the fixes' σ floored at the
  long-run variance of the filter's own innovations, the run repeated until they agree);
- ``start given``: the default with the reference's attitude at the first fix handed to
  the filter as NaveGo hands its ``ini_align`` (``--init pitch=,roll=,heading=,time=``):
  the run starts at the first fix instead of where the course first shows the heading;
- ``reference``: the same filter with the fix σ chosen on the truth (the pair of position
  and velocity σ of a small grid with the smallest mean outage-end error): a well-tuned
  filter no user can have, the bar to compare with.

Beside each run's velocity error at the outage starts, the ``receiver`` row gives the
receiver's own (its velocity fixes against the reference, mean over the 2 s before each
outage): a filter that follows its fixes enters an outage that far off.
"""
from __future__ import annotations

import argparse
import itertools
import sys
import time

import numpy as np

GRADES = {
    "ekinox": (dict(gyro_bias="[0.2, -0.15, 0.25] deg/h", gyro_arw="0.15 deg/sqrt(h)",
                    accel_bias="[50, -40, 30] ug", accel_vrw="40 ug/sqrt(Hz)",
                    gyro_bias_instability="0.05 deg/h", gyro_corr_time="300 s"),
               dict(gyro="0.15 deg/sqrt(h)", accel="40 ug", gb="1 deg/h", ab="200 ug")),
    "mpu": (dict(gyro_bias="[300, -200, 250] deg/h", gyro_arw="0.6 deg/sqrt(h)",
                 accel_bias="[8000, -6000, 5000] ug", accel_vrw="150 ug/sqrt(Hz)"),
            dict(gyro="0.6 deg/sqrt(h)", accel="150 ug", gb="400 deg/h", ab="10000 ug")),
}


def _drive(ref_path, gnss_path, grade, seed=1):
    from sinslab import data
    from sinslab.sim import imu as IM
    from sinslab.sim.from_reference import imu_from_reference
    ref = data.read_truth(ref_path)
    fx, meta = data.load_fixes(gnss_path)
    imu0, tru = imu_from_reference(ref, 0.01)
    return IM.apply(imu0, IM.ImuErrors.from_datasheet(**GRADES[grade][0]), seed), fx, tru, meta


def _errors(res, tru):
    from sinslab.core.earth import radii
    k = np.clip(np.rint((res.t - tru.t[0]) / 0.01).astype(int), 0, tru.t.size - 1)
    rm, rn = radii(tru.lat[k], tru.h[k])
    nav = res.nav
    e = np.stack([(nav[:, 8] - tru.lon[k]) * rn * np.cos(tru.lat[k]), (nav[:, 7] - tru.lat[k]) * rm,
                  nav[:, 9] - tru.h[k]], -1)
    return e, nav[:, 4:7] - tru.vel[k]


def _outages(fx):
    return tuple((float(fx.t[0]) + s, 40.0) for s in range(100, 1001, 150))


def receiver_dv(fx, tru):
    """|δv| horizontal [m/s] of the receiver's velocity fixes against the reference, mean
    over the 2 s before each outage start."""
    k = np.clip(np.rint((fx.t - tru.t[0]) / 0.01).astype(int), 0, tru.t.size - 1)
    dv = np.hypot(*(fx.vel[:, :2] - tru.vel[k, :2]).T)
    return np.array([float(np.mean(dv[(fx.t >= s - 2.0) & (fx.t < s)])) for s, _ in _outages(fx)])


def given_start(fx, tru):
    """The reference's attitude at the first fix as the start options (NaveGo's ini_align)."""
    from sinslab.core import attitude as A
    t0 = float(fx.t[0])
    k = int(np.searchsorted(tru.t, t0 - 1e-9))                # the first reference sample from the first fix
    return dict(pitch=float(tru.att[k, 0]), roll=float(tru.att[k, 1]), init_time=float(tru.t[k]),
                heading=float(np.mod(A.yaw_to_heading(tru.att[k, 2]), 2 * np.pi)))


def run(imu, fx, tru, meta, grade, **kw):
    """One filter run: ``(hz RMS, vertical RMS, outage ends (7,), |δv| at outage starts (7,),
    NIS, start [s after the first fix], the RecordedNav)``."""
    from sinslab.core import units as U
    from sinslab.fusion import recorded as R
    f = GRADES[grade][1]
    outs = _outages(fx)
    opt = R.NavOptions.of(lever_arm=tuple(meta["lever_arm"]), rest_noise=False, outages=outs,
                          gyro_arw=U.parse(f["gyro"], "angle_random_walk"),
                          accel_vrw=U.parse(f["accel"] + "/sqrt(Hz)", "velocity_random_walk"),
                          gyro_bias_sigma=U.parse(f["gb"], "angular_rate"),
                          accel_bias_sigma=U.parse(f["ab"], "acceleration"), **kw)
    res = R.navigate_recorded(imu, fx, opt)
    e, dv = _errors(res, tru)
    hz = np.hypot(e[:, 0], e[:, 1])
    ends, dv0 = [], []
    for s, ln in outs:
        j0, j1 = int(np.searchsorted(res.t, s)), int(np.searchsorted(res.t, s + ln)) - 1
        ends.append(float(hz[j1]))
        dv0.append(float(np.hypot(*dv[j0, :2])))
    return (float(np.sqrt(np.mean(hz ** 2))), float(np.sqrt(np.mean(e[:, 2] ** 2))), np.array(ends),
            np.array(dv0), float(np.mean(res.nis)), float(res.start.t - fx.t[0]), res)


def _row(name, r):
    return (f"{name:<22} {r[0]:6.2f} {r[1]:6.2f}  {np.median(r[2]):6.2f}  "
            + " ".join(f"{x:5.1f}" for x in r[2]) + "   " + " ".join(f"{x:4.2f}" for x in r[3])
            + f"   {r[5]:5.1f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("ref")
    ap.add_argument("gnss")
    ap.add_argument("--grade", nargs="*", default=["ekinox", "mpu"], choices=sorted(GRADES))
    a = ap.parse_args(argv)
    import os
    print(f"load {os.getloadavg()[0]:.2f}")
    for grade in a.grade:
        t0 = time.time()
        d = _drive(a.ref, a.gnss, grade)
        print(f"\n{grade}: {'run':<22} {'hz RMS':>6} {'vert':>6}  {'median':>6}  outage ends [m]"
              f"{'':20}|δv| at outage starts [m/s]   start [s after the first fix]")
        print(_row("default", run(*d, grade)))
        print(_row("start given", run(*d, grade, **given_start(d[1], d[2]))))
        print(_row("fix errors measured", run(*d, grade, fix_error="auto")))
        print(_row("fix σ from innovations", run(*d, grade, fix_noise="innovations")))
        best = None
        for ps, vs in itertools.product((1.0, 2.5), (0.05, 0.15, 0.3, 0.5)):
            r = run(*d, grade, fix_sigma=(ps, ps, 2 * ps), fix_vel_sigma=(vs, vs, vs))
            if best is None or np.mean(r[2]) < np.mean(best[1][2]):
                best = ((ps, vs), r)
        print(_row(f"reference {best[0][0]:g} m {best[0][1]:g} m/s", best[1]))
        print(f"{'receiver':<22} {'':6} {'':6}  {'':6}  {'':41}   "
              + " ".join(f"{x:4.2f}" for x in receiver_dv(d[1], d[2])))
        print(f"({time.time() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
