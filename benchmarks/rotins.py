"""Speed of paper 001's pipeline (rotation-evaluation).

Run: ``.venv/bin/python benchmarks/rotins.py [--quick] [--runs N] [--filter-hours H] [--json FILE]``

1. Stage times of one run of the experiment (full default: 144 h, eleven INS at 100 Hz,
   ten joint filters; ``--quick``: the experiment's --quick), from its ``stage_s`` metric:
   synthesis + navigation, joint filters, eq-20 covariance, Monte Carlo. Targets: full
   default < 60 s, --quick < 60 s on a quiet 2-core machine.
2. One joint filter over ``--filter-hours`` hours (1 s model steps, a measurement every
   10 s) two ways in the same run: the fusion driver on the two outputs and the compiled
   loop on the schedule's transition table (:func:`sinslab.methods.rotins.joint_filter_linear`);
   their ratio.
3. With ``--runs N`` (> 1): the linear-domain seed campaign of analysis one (Dask, local
   cluster) on the configuration of part 1. Target: 20 seeds at full scale < 10 min.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402


def stage_times(quick, runs=1, scheduler=None):
    from pathlib import Path

    from sinslab.app.config import resolve
    from sinslab.experiments import get
    from sinslab.experiments.base import RunContext

    exp = get("rotation-evaluation")
    cfg = resolve(exp.config, quick=exp.quick if quick else None, sets=[f"runs={runs}"])
    ctx = RunContext("bench", Path("."), seed=0, runs=runs, quick=quick, scheduler=scheduler)
    t0 = time.perf_counter()
    res = exp.run(cfg, ctx)
    wall = time.perf_counter() - t0
    st = res.metrics["stage_s"]
    return dict(wall_s=wall, navigation_s=st[0], filters_s=st[1], covariance_s=st[2], montecarlo_s=st[3],
                navigations=res.metrics["navigations"], imu_samples_per_ins=res.metrics["imu_samples_per_ins"])


def filter_ratio(hours):
    from sinslab.core import units as u
    from sinslab.experiments import rotation_evaluation as R
    from sinslab.app.config import resolve
    from sinslab.experiments import get
    from sinslab.fusion.driver import PrecomputedStream
    from sinslab.methods import rotins

    cfg = resolve(get("rotation-evaluation").config, sets=[])
    lat, lon = float(cfg.scenario.latitude), float(cfg.scenario.longitude)
    m1, mk = R.mounts(cfg)
    md, me = 1.0, 10
    K = int(hours * 3600 / (md * me))
    ts = md * np.arange(K * me + 1)
    (r1, w1, f1), (rk, wk, fk) = (R._truth_rows(m, ts, lat, lon) for m in (m1, mk))
    rng = np.random.default_rng(0)
    rk = rk.copy()
    rk[:, 4:6] += np.cumsum(rng.standard_normal((ts.size, 2)) * 1e-4, 0)
    model = rotins.joint_rotation_model(0.001 * u.deg / 60, 0.001 * u.deg / 60, 1e-4, 1e-4)
    P0 = rotins.joint_P0(model, lat, att=np.array([5, 5, 30]) * u.arcsec, gyro1=0.01 * u.dph, gyrok=0.01 * u.dph,
                         accel1=20 * u.ug, accelk=20 * u.ug)
    sig = rotins.difference_sigma(lat)
    t0 = time.perf_counter()
    rotins.joint_filter(PrecomputedStream(ts, r1, w1, f1), PrecomputedStream(ts, rk, wk, fk), model, P0,
                        kf_dt=md, meas_every=me, sigma=sig)
    t_drv = time.perf_counter() - t0
    t0 = time.perf_counter()
    Phi, Q, idx = R.schedule_transitions(m1, mk, lat, lon, model, md, me, K, {"all": range(10)})
    t_tab = time.perf_counter() - t0
    t0 = time.perf_counter()
    z = rotins.difference_measurements(r1[me::me], rk[me::me])
    rotins.joint_filter_linear(z, Phi, Q["all"], model, P0, sigma=sig, index=idx)
    t_lin = time.perf_counter() - t0
    return dict(hours=hours, driver_s=t_drv, table_s=t_tab, distinct_steps=int(Phi.shape[0]), steps=K,
                compiled_s=t_lin, ratio_driver_over_compiled=t_drv / t_lin)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--filter-hours", type=float, default=24.0)
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    out = {"filter": filter_ratio(a.filter_hours)}
    print("joint filter:", json.dumps(out["filter"], indent=1))
    out["run"] = stage_times(a.quick)
    print("experiment run:", json.dumps(out["run"], indent=1))
    if a.runs > 1:
        t0 = time.perf_counter()
        st = stage_times(a.quick, runs=a.runs)
        out["campaign"] = dict(runs=a.runs, montecarlo_s=st["montecarlo_s"], wall_s=time.perf_counter() - t0)
        print("campaign:", json.dumps(out["campaign"], indent=1))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
