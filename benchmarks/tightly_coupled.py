"""Tightly coupled INS/GNSS speed: the filter on 1 h of 200 Hz IMU with 1 Hz raw
observations of 10–20 satellites, against the loosely coupled filter on the same IMU with
1 Hz fixes (the reference, same run); and the walk log end to end through the command.

Run: ``.venv/bin/python benchmarks/tightly_coupled.py [--quick] [--walk DATA_DIR] [--out FILE]``

1. benchmarks/estimation.py's aircraft scenario (tactical IMU, 200 Hz) with GPS + Galileo
   Walker constellations (24 + 24 satellites, 55°/56°) seen from the true track: the
   tightly coupled filter (21 INS states with scale factors + clock bias, drift and one
   inter-system bias; pseudorange and Doppler of every satellite above 10°, kf_dt 0.1 s)
   against the loosely coupled one (21 states, 1 Hz position fixes). Best of 3
   interleaved, CPU and wall time; horizontal RMS error of both after the first 300 s.
2. ``--walk DATA_DIR``: ``sinslab navigate --gnss-raw`` on the rtklib-walk log as a
   subprocess (the command of docs/raw-gnss.md), CPU time of the child, second of two
   runs (the first may compile).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402

from sinslab.core import units as u  # noqa: E402
from sinslab.core.earth import radii  # noqa: E402
from sinslab.fusion import loosely_coupled as lc  # noqa: E402
from sinslab.fusion.spec import FilterGrid, FixSpec  # noqa: E402
from sinslab.fusion.gnss import SatelliteObservations  # noqa: E402
from sinslab.fusion.tightly_coupled import RawGnss, tc_model, tightly_coupled  # noqa: E402
from sinslab.sim import gnss as SG  # noqa: E402


def filter_speed(duration):
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from estimation import LC_ACCEL_VRW, LC_GYRO_ARW, lc_scenario
    meas, init, ft, fix, sig, P0, kw, truth = lc_scenario(duration)
    k = np.rint((ft - truth.t[0]) / meas.dt).astype(int)
    orbits = [SG.Walker(system="G"), SG.Walker(system="E", inclination=math.radians(56.0), planes=3,
                                                per_plane=8, raan0=0.4, u0=1.1)]
    sim = SG.simulate_observations(ft, truth.lat[k], truth.lon[k], truth.h[k], truth.vel[k], orbits,
                                   SG.GnssErrors(isb={"E": 12.0}), seed=3)
    sv = SatelliteObservations(**sim.fields)
    n_sat = np.bincount(sv.epoch)
    b, d = sim.clock[0]
    raw_kw = dict(nominal=(b - d * (ft[0] - meas.t0), d, meas.t0, {"E": 12.0}), gate=None)
    model = tc_model(LC_GYRO_ARW, LC_ACCEL_VRW, systems=sv.systems, scale_factors=True)
    lc_model = lc.lc_model(LC_GYRO_ARW, LC_ACCEL_VRW, scale_factors=True)
    n_lc = lc_model.n
    P = np.zeros((model.n, model.n))
    P[:15, :15] = P0
    P[15:21, 15:21] = np.eye(6) * 1e-8
    Plc = P[:n_lc, :n_lc]
    cpu = {"tc": math.inf, "lc": math.inf}
    wall = dict(cpu)
    out = {}
    for _ in range(3):
        for key in ("tc", "lc"):
            c0, w0 = time.process_time(), time.perf_counter()
            if key == "tc":
                r = tightly_coupled(meas, init, RawGnss(sv, **raw_kw), P, model, grid=FilterGrid(0.1))
            else:
                r = lc.loosely_coupled(meas, init, FixSpec(ft, fix, sig), Plc, lc_model, grid=FilterGrid(0.1))
            cpu[key] = min(cpu[key], time.process_time() - c0)
            wall[key] = min(wall[key], time.perf_counter() - w0)
            kk = np.rint((r.t - truth.t[0]) / meas.dt).astype(int)
            rm, rn = radii(truth.lat[kk], truth.h[kk])
            hz = np.hypot((r.nav[:, 7] - truth.lat[kk]) * rm,
                          (r.nav[:, 8] - truth.lon[kk]) * rn * np.cos(truth.lat[kk]))
            late = r.t > r.t[0] + min(300.0, duration / 3)
            out[f"{key}_hz_err_rms_m"] = float(np.sqrt(np.mean(hz[late] ** 2)))
    out.update(duration_s=duration, imu_samples=len(meas), imu_rate_hz=1 / meas.dt,
               gnss_epochs=int(ft.size), satellites_min=int(n_sat.min()), satellites_max=int(n_sat.max()),
               tc_states=model.n, lc_states=n_lc, tc_cpu_s=cpu["tc"], tc_wall_s=wall["tc"],
               lc_cpu_s=cpu["lc"], lc_wall_s=wall["lc"], tc_over_lc_cpu=cpu["tc"] / cpu["lc"])
    return out


def walk(data):
    cmd = [sys.executable, "-m", "sinslab.cli", "navigate", "--imu", f"{data}/imu_1730.csv",
           "--format", "rtklib-imu", "--mount", "rpy:180,0,-90", "--frame", "frd",
           "--gnss-raw", f"{data}/gnss_1730.ubx", "--init", "course_speed=1 m/s,course_spread=10 deg"]
    res = {}
    for k in range(2):
        with tempfile.TemporaryDirectory() as tmp:
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            w0 = time.perf_counter()
            subprocess.run(cmd + ["--out", f"{tmp}/run"], check=True, capture_output=True)
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            res = {"walk_end_to_end_wall_s": time.perf_counter() - w0,
                   "walk_end_to_end_cpu_s": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)}
    return res


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="2 min instead of 1 h (smoke test)")
    p.add_argument("--walk", default=None, help="the rtklib-walk data folder")
    p.add_argument("--out", default=None, help="write the figures as JSON")
    a = p.parse_args(argv)
    out = filter_speed(120.0 if a.quick else 3600.0)
    if a.walk:
        out.update(walk(a.walk))
    print(json.dumps(out, indent=1))
    if a.out:
        with open(a.out, "w") as fh:
            json.dump(out, fh, indent=1)
    return out


if __name__ == "__main__":
    main()
