"""``make demo`` on a fresh clone: wall and CPU time of every experiment at full scale.

What a user pays the first time: the committed tree (``HEAD``) is cloned into a temporary
folder, its ``.venv`` installed (``make .venv/.installed``: ``pip install``, then ``sinslab
compile``, which compiles the kernels into the clone's numba cache) and ``make demo`` timed
there. ``NUMBA_CACHE_DIR`` is removed from the environment, so the kernels are cached in
the clone, where they are counted before and after the demo (a kernel the demo compiles
itself shows as one more). The figure is the kernel compilation of the install plus the
demo (the packages' own installation is timed apart, not part of it): what a fresh clone
pays beyond pip. The CPU time is that of the whole process tree (the command, its Dask
workers; user + system). Per run: its ``runtime_s`` (the experiment's own compute time, from
its ``summary.json``), and when it started and ended (its timeline). ``--warm``: ``make
demo`` once more on the same cache.

Run: ``.venv/bin/python benchmarks/demo.py [--warm] [--keep DIR] [--out FILE]`` (minutes;
``DIR`` receives the runs for comparing them with another demo). Best on a quiet machine:
the figure is a wall time on its two CPUs (``benchmarks/record.py demo`` records the load).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _timed(cmd: list[str], cwd: Path, env: dict, log: Path) -> dict:
    """Run ``cmd`` to completion: wall [s], CPU of its process tree [s]; its output in ``log``."""
    c0, w0 = _cpu_children(), time.perf_counter()
    with open(log, "w") as fh:
        r = subprocess.run(cmd, cwd=cwd, env=env, stdout=fh, stderr=subprocess.STDOUT)
    wall, cpu = time.perf_counter() - w0, _cpu_children() - c0
    if r.returncode != 0:
        sys.exit(f"demo: error: {' '.join(cmd)} failed (exit {r.returncode}); its output:\n"
                 f"{log.read_text(errors='replace')[-3000:]}")
    return {"wall_s": round(wall, 2), "cpu_s": round(cpu, 2)}


def _compile_step(log: Path) -> dict | None:
    """What ``sinslab compile`` said it did in the install's log: kernels, CPU and wall."""
    import re

    m = re.search(r"compiled (\d+) kernels \((\d+) s of CPU; (\d+) s in all", log.read_text(errors="replace"))
    return None if m is None else {"kernels": int(m.group(1)), "compile_cpu_s": float(m.group(2)),
                                   "wall_s": float(m.group(3))}


def _cached_kernels(tree: Path) -> int:
    return sum(1 for _ in (tree / "src").rglob("*.nbi"))


def _runs(folder: Path) -> tuple[dict, dict]:
    """Of every run of a demo folder: its ``runtime_s`` (the experiment's computation) and
    the wall time of its robustness re-runs (0 without any)."""
    out, robust = {}, {}
    for s in sorted(folder.glob("*/summary.json")):
        summary = json.loads(s.read_text())
        out[s.parent.name] = round(float(summary["metrics"].get("runtime_s", float("nan"))), 2)
        robust[s.parent.name] = round(float((summary.get("robustness") or {}).get("wall_s") or 0.0), 2)
    return out, robust


def _timeline(folder: Path, t0: float) -> dict:
    """When each run of a demo folder started and ended [s after ``t0``, a Unix time]: its
    ``started`` stamp (whole seconds) and that plus its stages (``timing``: compute,
    series, figures, report, robustness re-runs). The run that ends last and the ones that
    started late show where the wall time goes."""
    import datetime as dt

    out = {}
    for s in sorted(folder.glob("*/summary.json")):
        summary = json.loads(s.read_text())
        start = dt.datetime.fromisoformat(summary["started"]).timestamp() - t0
        out[s.parent.name] = [round(start, 1), round(start + sum((summary.get("timing") or {}).values()), 1)]
    return dict(sorted(out.items(), key=lambda kv: kv[1][0]))


def measure(warm: bool, keep: str | None, py: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT")}
    head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                          text=True).stdout.strip()
    make = ["make"] + ([f"PY={py}"] if py else [])
    with tempfile.TemporaryDirectory(prefix="sinslab-demo-bench-") as tmp:
        tree = Path(tmp) / "sinslab"
        subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(ROOT), str(tree)], check=True)
        subprocess.run(["git", "checkout", "--quiet", head], cwd=tree, check=True)
        if _cached_kernels(tree):
            sys.exit("demo: error: the fresh clone holds cached kernels before its install")
        load0 = os.getloadavg()
        install = _timed(make + [".venv/.installed"], tree, env, Path(tmp) / "install.log")
        compiled = _compile_step(Path(tmp) / "install.log")
        before = _cached_kernels(tree)
        t0 = time.time()
        fresh = _timed(make + ["demo"], tree, env, Path(tmp) / "demo.log")
        fresh["load_avg_before"] = [round(x, 2) for x in load0]
        fresh["load_avg_after"] = [round(x, 2) for x in os.getloadavg()]
        fresh["kernels_cached_before"] = before
        fresh["kernels_cached_after"] = _cached_kernels(tree)
        fresh["runs"], fresh["robustness_s"] = _runs(tree / "runs")
        fresh["timeline_s"] = _timeline(tree / "runs", t0)
        res = {"commit": head, "install": install, "compile": compiled, "fresh": fresh,
               "compile_and_demo_wall_s": round(fresh["wall_s"] + (compiled or {}).get("wall_s", 0.0), 2),
               # what `make demo` on the fresh clone takes in all: pip, the kernels, the demo
               "install_and_demo_wall_s": round(fresh["wall_s"] + install["wall_s"], 2),
               "install_and_demo_cpu_s": round(fresh["cpu_s"] + install["cpu_s"], 2)}
        if keep:
            dest = Path(keep)
            if dest.exists():
                shutil.rmtree(dest)
            shutil.copytree(tree / "runs", dest)
        if warm:
            shutil.rmtree(tree / "runs")
            load0 = os.getloadavg()
            w = _timed(make + ["demo"], tree, env, Path(tmp) / "demo-warm.log")
            w["load_avg_before"] = [round(x, 2) for x in load0]
            w["load_avg_after"] = [round(x, 2) for x in os.getloadavg()]
            w["runs"], w["robustness_s"] = _runs(tree / "runs")
            res["warm"] = w
    res["machine"] = {"python": platform.python_version(), "cpu_count": os.cpu_count()}
    return res


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--warm", action="store_true", help="time make demo again on the filled numba cache")
    ap.add_argument("--keep", help="copy the fresh run's demo folder here")
    ap.add_argument("--py", help="python for make's PY (default: the Makefile's)")
    ap.add_argument("--out", default=str(HERE / "results" / "demo.json"))
    a = ap.parse_args(argv)
    res = measure(a.warm, a.keep, a.py)
    f, c = res["fresh"], res["compile"] or {}
    print(f"install: {res['install']['wall_s']:.1f} s wall, of it sinslab compile {c.get('wall_s', 0):.0f} s "
          f"({c.get('kernels', 0)} kernels)")
    print(f"make demo, fresh clone: {f['wall_s']:.1f} s wall, {f['cpu_s']:.1f} s CPU "
          f"(load {f['load_avg_before'][0]:.2f} before, {f['load_avg_after'][0]:.2f} after; kernels cached "
          f"{f['kernels_cached_before']} before, {f['kernels_cached_after']} after); with the install's "
          f"compilation {res['compile_and_demo_wall_s']:.1f} s wall; with the whole install "
          f"{res['install_and_demo_wall_s']:.1f} s wall, {res['install_and_demo_cpu_s']:.1f} s CPU")
    for name, s in f["runs"].items():
        print(f"  {name:<32s} {s:7.2f} s, robustness re-runs {f['robustness_s'][name]:6.2f} s")
    print("timeline of the runs (s after make demo started):")
    for name, (start, end) in f["timeline_s"].items():
        print(f"  {name:<32s} {start:6.1f} .. {end:6.1f}")
    if "warm" in res:
        w = res["warm"]
        print(f"make demo, warm cache: {w['wall_s']:.1f} s wall, {w['cpu_s']:.1f} s CPU")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1) + "\n")
    return res


if __name__ == "__main__":
    main()
