"""Speed of paper 001's pipeline (rotation-evaluation).

Run: ``.venv/bin/python benchmarks/rotins.py [--quick] [--runs N] [--filter-hours H]
[--nav-hours H] [--nav-ins N] [--grouping-hours H] [--only-navigation] [--compare-serial]
[--json FILE]``

1. Stage times of one run of the experiment (full default: 144 h, eleven INS at 100 Hz,
   ten joint filters; ``--quick``: the experiment's --quick), from its ``stage_s`` metric
   (wall) and ``stage_cpu_s`` (CPU of the process, all threads): synthesis + navigation,
   joint filters, eq-20 covariance, Monte Carlo; with ``--compare-serial`` also with the
   INS navigated one after another. Targets: full default < 60 s, --quick < 60 s on a
   quiet 2-core machine.
2. One joint filter over ``--filter-hours`` hours (1 s model steps, a measurement every
   10 s) two ways in the same run: the fusion driver on the two outputs and the compiled
   loop on the schedule's transition table (:func:`sinslab.methods.rotins.joint_filter_linear`);
   their ratio.
3. Navigation of ``--nav-ins`` independent INS over ``--nav-hours`` hours at 100 Hz three
   ways in the same run (``compute.navigation``): one after another, Dask threads (the
   compiled kernels release the GIL), a Dask local cluster of two processes; wall and CPU
   times, the ratios to serial, and a check that the outputs are identical.
4. The experiment's eleven INS over ``--grouping-hours`` hours (its own configuration,
   one thread): grouped as the experiment navigates them — INS on one random stream (INS #2
   at every β, INS #1 with and without its trend) share the tiled cycle and the noise
   draws — against one INS at a time; CPU seconds of each (best of two, alternated), the
   ratio, and a check that every output is identical.
5. With ``--runs N`` (> 1): the linear-domain seed campaign of analysis one (Dask, local
   cluster) on the configuration of part 1. Target: 20 seeds at full scale < 10 min.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402


def stage_times(quick, runs=1, scheduler=None, sets=()):
    from pathlib import Path

    from sinslab.app.config import resolve
    from sinslab.experiments import get
    from sinslab.experiments.base import RunContext

    exp = get("rotation-evaluation")
    cfg = resolve(exp.config, quick=exp.quick if quick else None, sets=[f"runs={runs}", *sets])
    ctx = RunContext("bench", Path("."), seed=0, runs=runs, quick=quick, scheduler=scheduler)
    t0 = time.perf_counter()
    res = exp.run(cfg, ctx)
    wall = time.perf_counter() - t0
    st = res.metrics["stage_s"]
    return dict(wall_s=wall, navigation_s=st[0], filters_s=st[1], covariance_s=st[2], montecarlo_s=st[3],
                stage_cpu_s=res.metrics["stage_cpu_s"], load_avg=os.getloadavg(),
                navigations=res.metrics["navigations"], imu_samples_per_ins=res.metrics["imu_samples_per_ins"])


def navigation_modes(hours, n_ins, workers=2):
    from sinslab.app.config import resolve
    from sinslab.core import units as u
    from sinslab.experiments import get
    from sinslab.experiments import rotation_evaluation as R
    from sinslab.sim import moored

    cfg = resolve(get("rotation-evaluation").config, sets=[])
    lat, lon, dt = float(cfg.scenario.latitude), float(cfg.scenario.longitude), float(cfg.scenario.sample_interval)
    m1, mk = R.mounts(cfg)
    cyc = [moored.one_cycle(m1, lat, lon, dt), moored.one_cycle(mk, lat, lon, dt)]
    specs = {f"ins{i}": R.InsSpec(f"INS {i}", cyc[i % 2], R._errors(cfg.imuk, gyro_scale=1.0 + 0.1 * i), (i,))
             for i in range(n_ins)}
    k_out = 1000
    n_out = int(hours * 3600 / (k_out * dt))
    kw = dict(seed=0, lat=lat, lon=lon, dt=dt, n_steps=n_out, k_kf=k_out, nsub=2,
              att_sigma=np.array([5, 5, 30]) * u.arcsec, chunk_steps=360, rates=False)
    R.navigate_many({"warm": specs["ins0"]}, dict(kw, n_steps=2), "serial")      # compile / load caches
    out, ref = {}, None
    for mode in ("serial", "threads", "processes"):
        c0, t0 = time.process_time(), time.perf_counter()
        res = R.navigate_many(specs, kw, mode, workers)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        rows = np.stack([res[k].rows for k in specs])
        same = True if ref is None else bool(np.array_equal(rows, ref))
        ref = rows if ref is None else ref
        out[mode] = dict(wall_s=wall, cpu_main_s=cpu, identical_to_serial=same)
    for mode in ("threads", "processes"):
        out[mode]["speedup_vs_serial"] = out["serial"]["wall_s"] / out[mode]["wall_s"]
    out.update(hours=hours, n_ins=n_ins, workers=workers, load_avg=os.getloadavg())
    return out


def grouping(hours, repeats=2):
    from sinslab.app.config import resolve
    from sinslab.experiments import get
    from sinslab.experiments import rotation_evaluation as R

    # the run's length only (the std windows moved inside it; they are not computed here)
    cfg = resolve(get("rotation-evaluation").config, sets=[f"scenario.duration={hours} h", "evaluation.start=0 h",
                                                           f"evaluation.window={hours / 2} h"])
    specs, kw, _, _ = R.ins_plan(cfg)
    # compile / load caches on a few steps: a whole number of INS #1's de-meaning noise blocks
    warm = math.lcm(kw["k_kf"], *(s.demean for s in specs.values() if s.demean)) // kw["k_kf"]
    R.navigate_many(specs, dict(kw, n_steps=max(2, warm)), "serial")
    best = {"grouped": np.inf, "one_at_a_time": np.inf}
    outs = {}
    for _ in range(repeats):
        for way in best:
            c0 = time.process_time()
            if way == "grouped":
                res = R.navigate_many(specs, kw, "serial")
            else:
                res = {k: R.navigate_chunked(sp, **kw) for k, sp in specs.items()}
            best[way] = min(best[way], time.process_time() - c0)
            outs[way] = res
    same = all(outs["grouped"][k].rows.tobytes() == outs["one_at_a_time"][k].rows.tobytes() for k in specs)
    return dict(hours=hours, n_ins=len(specs), groups=[len(g) for g in R._groups(specs)],
                grouped_cpu_s=best["grouped"], one_at_a_time_cpu_s=best["one_at_a_time"],
                ratio=best["one_at_a_time"] / best["grouped"], identical=same, load_avg=os.getloadavg())


def filter_ratio(hours):
    from sinslab.core import units as u
    from sinslab.experiments import rotation_evaluation as R
    from sinslab.app.config import resolve
    from sinslab.experiments import get
    from sinslab.fusion.driver import PrecomputedStream
    from sinslab.methods import rotins
    from sinslab.sim import moored

    cfg = resolve(get("rotation-evaluation").config, sets=[])
    lat, lon = float(cfg.scenario.latitude), float(cfg.scenario.longitude)
    m1, mk = R.mounts(cfg)
    md, me = 1.0, 10
    K = int(hours * 3600 / (md * me))
    ts = md * np.arange(K * me + 1)
    (r1, w1, f1), (rk, wk, fk) = (moored.truth_rows(m, ts, lat, lon) for m in (m1, mk))
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
    ap.add_argument("--nav-hours", type=float, default=6.0)
    ap.add_argument("--nav-ins", type=int, default=4)
    ap.add_argument("--grouping-hours", type=float, default=24.0)
    ap.add_argument("--only-navigation", action="store_true", help="parts 3 and 4 only")
    ap.add_argument("--compare-serial", action="store_true",
                    help="part 1 also with compute.navigation=serial (the INS one after another)")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    out = {"navigation": navigation_modes(a.nav_hours, a.nav_ins)}
    print("navigation modes:", json.dumps(out["navigation"], indent=1))
    out["grouping"] = grouping(a.grouping_hours)
    print("INS grouped by random stream:", json.dumps(out["grouping"], indent=1))
    if a.only_navigation:
        return 0
    out["filter"] = filter_ratio(a.filter_hours)
    print("joint filter:", json.dumps(out["filter"], indent=1))
    out["run"] = stage_times(a.quick)
    print("experiment run:", json.dumps(out["run"], indent=1))
    if a.compare_serial:
        out["run_serial"] = stage_times(a.quick, sets=["compute.navigation=serial"])
        print("experiment run, INS navigated one after another:", json.dumps(out["run_serial"], indent=1))
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
