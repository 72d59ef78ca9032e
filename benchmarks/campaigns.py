"""Monte Carlo tasks: runs stacked against one run at a time, and where the time goes.

A Dask task of a campaign computes a batch of runs. Its task function stacks them: what
the runs share is made once (double-star: error model, fix plan, held height with its
vertical rate per block; free-inertial: the held vertical rate) and the errors of all runs
are formed in one pass over (runs × epochs). This script times, in the same process and
alternated, a task of ``--runs`` runs against the same runs made one at a time by the
per-run definition the task must equal (double-star ``_one``, free-inertial ``mc_run``),
and splits the stacked task's time into the compiled kernels' own time (taken from a
profiled call) and the rest (interpreter and numpy calls: the unprofiled time minus that),
which bounds what any further stacking of the runs could remove.

Campaigns: ``double-star`` (three filters per run on 1200 s of 100 Hz IMU) and
``free-inertial`` (7200 s of 100 Hz IMU navigated per run). For double-star it also times
the task with its filters stepped over several runs at once on the fusion driver's run
axis against the same task with one run per driver call. (The transfer-alignment
campaign stacks its runs in arrays throughout: ``benchmarks/transfer.py``.)

Run: ``.venv/bin/python benchmarks/campaigns.py [--runs 8]``; results printed and written
to ``benchmarks/results/campaigns.json``.
"""
from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import time
from pathlib import Path

os.environ.setdefault("SINSLAB_QUIET", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent


def _double_star():
    from sinslab.app.config import resolve
    from sinslab.experiments import double_star as dsx

    S = dsx._setup(resolve(dsx.Config))
    return (lambda seeds: dsx._batch(seeds, S),
            lambda seed: dsx._one(np.random.default_rng(seed), S))


def _free_inertial():
    from sinslab.app.config import resolve
    from sinslab.experiments import free_inertial as fi
    from sinslab.sim import trajectory

    cfg = resolve(fi.Config)
    segments, start, mount = fi._motion(cfg)
    spec = fi._mc_spec(cfg, segments, start, mount)
    fi._mc_setup(spec, trajectory.generate(segments, start, float(cfg.scenario.sample_interval),
                                           duration=float(cfg.scenario.duration), mount=mount))
    return lambda seeds: fi.mc_batch(seeds, spec), lambda seed: fi.mc_run(seed, spec)


CAMPAIGNS = {"double-star": _double_star, "free-inertial": _free_inertial}


def _compiled_seconds(stats: pstats.Stats) -> float:
    """Own time [s] of numba-compiled functions (their frames show the Python source file
    of the kernel but no Python-level callees).

    The profiler charges every Python call, which inflates the interpreter's share of a
    profiled run; a compiled kernel is a few long calls, timed nearly as without it. So
    its seconds are taken from the profile and compared with the task timed unprofiled."""
    from numba.core.registry import CPUDispatcher  # noqa: F401  (numba must be importable)

    compiled = 0.0
    kernels = _kernel_sites()
    for (fname, line, func), (_, _, tt, _, _) in stats.stats.items():
        if (fname, line) in kernels:
            compiled += tt
    return compiled


def _kernel_sites():
    """(file, first line) of every numba dispatcher loaded from sinslab."""
    import sys

    from numba.core.dispatcher import Dispatcher

    sites = set()
    for name, mod in list(sys.modules.items()):
        if not name.startswith("sinslab") or mod is None:
            continue
        for obj in vars(mod).values():
            if isinstance(obj, Dispatcher):
                code = obj.py_func.__code__
                sites.add((code.co_filename, code.co_firstlineno))
    return sites


def _cpu(f):
    c0 = time.process_time()
    f()
    return time.process_time() - c0


def measure(name: str, runs: int, rounds: int = 3) -> dict:
    stacked, one = CAMPAIGNS[name]()
    seeds = np.random.SeedSequence(7).spawn(runs + 1)
    stacked(seeds[:1])                                     # compile / warm caches
    one(seeds[0])
    t_stacked, t_one = [], []
    for _ in range(rounds):                                # alternated, best of each
        t_stacked.append(_cpu(lambda: stacked(seeds[1:])))
        t_one.append(_cpu(lambda: [one(s) for s in seeds[1:]]))
    cpu, cpu_one = min(t_stacked), min(t_one)
    prof = cProfile.Profile()
    prof.enable()
    stacked(seeds[1:])
    prof.disable()
    compiled = _compiled_seconds(pstats.Stats(prof))
    # a task that is nearly all kernels can time its kernels above its best unprofiled
    # round (timing noise): then nothing is left to the interpreter
    other = max(cpu - compiled, 0.0)
    return {"runs": runs, "cpu_per_run_s": cpu / runs, "cpu_per_run_one_at_a_time_s": cpu_one / runs,
            "speedup": cpu_one / cpu, "runs_per_cpu_s": runs / cpu,
            "compiled_per_run_s": compiled / runs, "other_per_run_s": other / runs,
            "compiled_share": compiled / (compiled + other)}


def lockstep(runs: int, rounds: int = 3) -> dict:
    """Double-star's task with its filters stepped over up to ``LANES`` runs at once on the
    fusion driver's run axis, against the same task with one run per driver call
    (``LANES = 1``): alternated, best of each."""
    from sinslab.app.config import resolve
    from sinslab.experiments import double_star as dsx

    S = dsx._setup(resolve(dsx.Config))
    seeds = np.random.SeedSequence(7).spawn(runs + 1)
    lanes = dsx.LANES
    times = {lanes: [], 1: []}
    try:
        for width in (lanes, 1):                               # compile / warm caches
            dsx.LANES = width
            dsx._batch(seeds[:2], S)
        for _ in range(rounds):
            for width in (lanes, 1):
                dsx.LANES = width
                times[width].append(_cpu(lambda: dsx._batch(seeds[1:], S)))
    finally:
        dsx.LANES = lanes
    a, b = min(times[lanes]), min(times[1])
    return {"runs": runs, "lanes": lanes, "cpu_per_run_lockstep_s": a / runs,
            "cpu_per_run_one_per_call_s": b / runs, "speedup": b / a}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--only", default=",".join(CAMPAIGNS), help="comma-separated campaigns")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "campaigns.json")
    a = ap.parse_args(argv)
    out = {}
    for name in a.only.split(","):
        r = measure(name, a.runs)
        out[name] = r
        print(f"{name:>14s}: stacked task {r['cpu_per_run_s'] * 1e3:6.1f} ms CPU per run, one run at a "
              f"time {r['cpu_per_run_one_at_a_time_s'] * 1e3:6.1f} ms -> {r['speedup']:.2f}x; compiled "
              f"kernels {r['compiled_share'] * 100:4.1f} % of the stacked task, the rest (interpreter "
              f"and numpy) {r['other_per_run_s'] * 1e3:.1f} ms per run")
    if "double-star" in a.only.split(","):
        r = out["double-star lockstep"] = lockstep(a.runs)
        print(f"{'double-star':>14s}: filters over {r['lanes']} runs in lockstep "
              f"{r['cpu_per_run_lockstep_s'] * 1e3:6.1f} ms CPU per run, one run per driver call "
              f"{r['cpu_per_run_one_per_call_s'] * 1e3:6.1f} ms -> {r['speedup']:.2f}x")
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
