"""What a fresh clone pays for compiling the numba kernels, per experiment and per kernel.

The kernels are cached on disk (``cache=True``): a fresh clone, or an upgrade that changes
a kernel's file, compiles them on its first run; later runs load them. This script runs
every experiment's ``--quick`` configuration in one fresh interpreter whose numba cache
(``NUMBA_CACHE_DIR``) starts empty, then the same runs again in a second interpreter on the
cache the first one filled. Campaigns run in the interpreter itself (scheduler ``"sync"``),
so every kernel compiles exactly once and its cost is counted here (a Dask worker would
compile or load it again in its own process). The quick runs make the compile cost the
larger part of the first round, and the two rounds take turns on the same machine, so the
difference (fresh − warm CPU) is the compile share with the load falling on both alike.

Per experiment: CPU [s] fresh and warm (this process, all threads), their difference, and
the CPU the compilations of sinslab's kernels took (numba's compile events,
:func:`sinslab.core.jitnotice.compile_log`); then the kernels by compile CPU, and any kernel
compiled for more than one signature (each signature is a compilation of its own).

Run: ``.venv/bin/python benchmarks/compile_cost.py [--only NAME ...] [--out FILE]``;
printed and written to ``benchmarks/results/compile_cost.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"


def _child(names: list[str], out_dir: str) -> dict:
    """Quick runs of ``names`` in this interpreter: per-experiment CPU, wall and compile CPU."""
    from sinslab.core import jitnotice

    jitnotice.install()
    from numba.core.registry import CPUDispatcher

    from sinslab.app.config import resolve
    from sinslab.experiments import execute, get, registry

    names = names or list(registry())
    rows = {}
    for n in names:
        exp = get(n)
        cfg = resolve(exp.config, quick=exp.quick, sets=[])
        before = len(jitnotice.compile_log())
        c, w = time.process_time(), time.perf_counter()
        execute(exp, cfg, Path(out_dir) / n, quick=True, log=lambda *a, **k: None, scheduler="sync")
        log = jitnotice.compile_log()[before:]
        rows[n] = {"cpu_s": time.process_time() - c, "wall_s": time.perf_counter() - w,
                   "compile_cpu_s": sum(x for _, x in log), "compiled": [[k, x] for k, x in log]}
    multi = {}
    for mod_name, mod in list(sys.modules.items()):
        if mod_name.startswith("sinslab"):
            for k, v in list(vars(mod).items()):
                if isinstance(v, CPUDispatcher) and len(v.signatures) > 1:
                    multi[f"{mod_name}.{k}"] = [str(s) for s in v.signatures]
    return {"experiments": rows, "multi_signature": multi}


def _round(names: list[str], cache: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache, SINSLAB_QUIET="1", SINSLAB_JITCACHE="0",
               PYTHONPATH=os.pathsep.join(p for p in (str(SRC), os.environ.get("PYTHONPATH")) if p))
    with tempfile.TemporaryDirectory(prefix="sinslab-compile-runs-") as runs:
        r = subprocess.run([sys.executable, __file__, "--child", runs, *[a for n in names for a in ("--only", n)]],
                           capture_output=True, text=True, env=env)
    if r.returncode != 0:
        raise RuntimeError(f"quick runs failed:\n{r.stderr.strip()}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def measure(names: list[str]) -> dict:
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="sinslab-numba-cache-") as cache:
        fresh = _round(names, cache)
        warm = _round(names, cache)
    rows = {}
    for n, f in fresh["experiments"].items():
        w = warm["experiments"][n]
        rows[n] = {"cpu_fresh_s": f["cpu_s"], "cpu_warm_s": w["cpu_s"], "cpu_difference_s": f["cpu_s"] - w["cpu_s"],
                   "compile_cpu_s": f["compile_cpu_s"], "kernels_compiled": len(f["compiled"]),
                   "kernels_compiled_warm": len(w["compiled"])}
    kernels = {}
    for f in fresh["experiments"].values():
        for k, x in f["compiled"]:
            kernels[k] = kernels.get(k, 0.0) + x
    return {"experiments": rows, "kernels": dict(sorted(kernels.items(), key=lambda kv: -kv[1])),
            "multi_signature": fresh["multi_signature"],
            "machine": {"python": platform.python_version(), "cpu_count": os.cpu_count(),
                        "load_avg_before": load0, "load_avg_after": os.getloadavg()}}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", action="append", default=[], help="experiment to run (repeatable; default all)")
    ap.add_argument("--out", default=str(HERE / "results" / "compile_cost.json"))
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.child:
        print(json.dumps(_child(a.only, a.child)))
        return {}
    res = measure(a.only)
    print(f"{'experiment':<22s} {'CPU fresh':>10s} {'CPU warm':>9s} {'difference':>11s} {'compile':>8s} {'kernels':>8s}")
    tot = [0.0, 0.0, 0.0]
    for n, r in res["experiments"].items():
        print(f"{n:<22s} {r['cpu_fresh_s']:10.2f} {r['cpu_warm_s']:9.2f} {r['cpu_difference_s']:11.2f} "
              f"{r['compile_cpu_s']:8.2f} {r['kernels_compiled']:8d}")
        tot = [tot[0] + r["cpu_fresh_s"], tot[1] + r["cpu_warm_s"], tot[2] + r["compile_cpu_s"]]
    print(f"{'total':<22s} {tot[0]:10.2f} {tot[1]:9.2f} {tot[0] - tot[1]:11.2f} {tot[2]:8.2f}")
    print("kernels by compile CPU [s]:")
    for k, x in list(res["kernels"].items())[:15]:
        print(f"  {x:6.2f}  {k}")
    for k, sigs in res["multi_signature"].items():
        print(f"compiled {len(sigs)} times: {k}")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=2) + "\n")
    load = res["machine"]
    print(f"load average before {load['load_avg_before'][0]:.1f}, after {load['load_avg_after'][0]:.1f} -> {out}")
    return res


if __name__ == "__main__":
    main()
