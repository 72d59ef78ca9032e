"""RTK/INS speed: the filter on 1 h of 200 Hz IMU with 1 Hz observations of about 15
satellites on two carriers from a rover and a base, against the tightly coupled filter
(pseudorange + Doppler) on the same IMU and rover observations (the reference, same run).

Run: ``.venv/bin/python benchmarks/rtk_ins.py [--quick] [--out FILE]``

A car at 15 m/s driving 600 m squares (40 s straight, 90° turns in 10 s) near 35.3° N with
an automotive MEMS IMU (gyro bias σ 10 °/h, ARW 0.2 °/√h, accelerometer bias σ 1 mg, VRW
50 µg/√Hz) at 200 Hz; Walker GPS + Galileo (24 + 30 satellites: 13–17 in view, 15 on average)
on L1/L2 and E1/E5b seen above 10° by the rover and by a base 5 km from the start (sinslab.sim.gnss, code σ₀
0.3 m, phase σ₀ 3 mm). RTK/INS (sinslab.fusion.rtk_ins.rtk_ins: 15 INS states + the
ambiguity states, double-differenced code and phase, LAMBDA with fix and hold, kf_dt
0.1 s) and the tightly coupled filter (15 INS states + clock, kf_dt 0.1 s); best of 2
interleaved, CPU and wall time of the filter calls (the simulation not counted), and the
share of epochs fixed and the horizontal RMS of the fixed antenna position.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402

from sinslab.core import earth as E  # noqa: E402
from sinslab.core import units as u  # noqa: E402
from sinslab.experiments.rtk_outages import simulate_drive  # noqa: E402
from sinslab.fusion.carrier import max_signals, slot_count  # noqa: E402
from sinslab.fusion.rtk import RtkOptions  # noqa: E402
from sinslab.fusion.rtk_ins import rtk_ins, rtk_model  # noqa: E402
from sinslab.fusion.spec import FilterGrid  # noqa: E402
from sinslab.fusion.tightly_coupled import RawGnss, tightly_coupled  # noqa: E402
from sinslab.nav import errstate as es  # noqa: E402
from sinslab.sim import gnss as SG  # noqa: E402
from sinslab.sim import trajectory as tr  # noqa: E402


def scenario(duration):
    segs = [tr.Accelerate(duration=10.0, accel=1.5)]
    while sum(s.duration for s in segs) < duration:
        segs += [tr.Level(duration=40.0), tr.Turn(duration=10.0, rate=9 * u.deg)]
    orbits = [SG.Walker(), SG.Walker(planes=3, per_plane=10, system="E", raan0=0.4, radius=29_600e3)]
    return simulate_drive(1, duration=duration, systems="GE", dt=0.005, segments=segs,
                          base_offset=(3000.0, 4000.0, 10.0), orbits=orbits)


def _fixed_stats(d, log):
    a = log.arrays()
    fx = a["status"] == 2
    tru = d["truth"]
    k = np.searchsorted(tru.t, a["t"][fx] - 1e-9)
    e = (a["fixed_pos"][fx] - E.geodetic_to_ecef(tru.lat[k], tru.lon[k], tru.h[k])) \
        @ E.enu_to_ecef_matrix(tru.lat[0], tru.lon[0])
    return float(fx.mean()), float(np.sqrt(np.mean(np.sum(e[:, :2] ** 2, 1))))


def filter_speed(duration):
    d = scenario(duration)
    rover = d["rover"]
    n_sat = np.bincount(rover.epoch)
    model = rtk_model(d["arw"], d["vrw"], slots=slot_count(max_signals(rover)))
    P = np.zeros((model.n, model.n))
    P[:15, :15] = np.diag(d["sigma0"] ** 2)
    opt = RtkOptions(mask=math.radians(10.0), ar_mask=math.radians(10.0), iono="broadcast")
    raw = RawGnss(rover, pseudorange_sigma=0.3, mask=math.radians(10.0))
    tc_model = es.ErrorModel("full", [es.gyro_bias(), es.accel_bias(), raw.clock_block()], gyro_arw=d["arw"],
                             accel_vrw=d["vrw"])
    Ptc = np.zeros((tc_model.n, tc_model.n))
    Ptc[:15, :15] = P[:15, :15]
    cpu = {"rtk": math.inf, "tc": math.inf}
    wall = dict(cpu)
    out = {}
    for _ in range(2):
        for key in ("rtk", "tc"):
            c0, w0 = time.process_time(), time.perf_counter()
            if key == "rtk":
                r = rtk_ins(d["imu"], d["init"], rover, d["base"], P, model, opt, grid=FilterGrid(0.1))
            else:
                r = tightly_coupled(d["imu"], d["init"], RawGnss(rover, pseudorange_sigma=0.3,
                                                                 mask=math.radians(10.0)), Ptc, tc_model,
                                    grid=FilterGrid(0.1))
            cpu[key] = min(cpu[key], time.process_time() - c0)
            wall[key] = min(wall[key], time.perf_counter() - w0)
            if key == "rtk":
                out["rtk_fixed_fraction"], out["rtk_fixed_hz_rms_m"] = _fixed_stats(d, r.rtk)
    out.update(duration_s=duration, imu_samples=len(d["imu"]), imu_rate_hz=1 / d["imu"].dt,
               gnss_epochs=int(rover.t_epoch.size), satellites_min=int(n_sat.min()),
               satellites_mean=float(n_sat.mean()), satellites_max=int(n_sat.max()),
               signals_max=max_signals(rover), rtk_states=model.n, tc_states=tc_model.n,
               rtk_cpu_s=cpu["rtk"], rtk_wall_s=wall["rtk"], tc_cpu_s=cpu["tc"], tc_wall_s=wall["tc"],
               rtk_over_tc_cpu=cpu["rtk"] / cpu["tc"])
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="2 min instead of 1 h (smoke test)")
    p.add_argument("--out", default=None, help="write the figures as JSON")
    a = p.parse_args(argv)
    out = filter_speed(120.0 if a.quick else 3600.0)
    print(json.dumps(out, indent=1))
    if a.out:
        with open(a.out, "w") as fh:
            json.dump(out, fh, indent=1)
    return out


if __name__ == "__main__":
    main(sys.argv[1:])
