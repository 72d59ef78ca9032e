"""Start-up time of the command line: ``sinslab list``, ``--help`` and ``config NAME``.

Target: each of them at most 0.5 s wall on the 2-core development machine — they import
no numerical or plotting package (``tests/app/test_startup.py`` checks the modules they
load; this script measures what that buys).

Every command is a fresh interpreter (``python -m sinslab.cli ...``, output discarded),
run ``--repeat`` times; the commands take turns (one run of each, then the next round) so
that a change of the machine's load falls on all of them alike. The reference measured in
the same run is ``python -c pass`` (the interpreter's own start): per command the median
wall time, its ratio to the reference's median and the difference (sinslab's own share).
``import sinslab.cli`` alone is measured too (the floor of every command).

Run: ``.venv/bin/python benchmarks/startup.py [--repeat 9] [--out FILE]``. Results are
printed and written to ``benchmarks/results/startup.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"
TARGET_S = 0.5


def _env() -> dict:
    # the sinslab of this repository, whatever the interpreter has installed
    return dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (str(SRC), os.environ.get("PYTHONPATH")) if p))


def commands() -> dict[str, list[str]]:
    """``{label: argv after the interpreter}``: the reference, the import, and the commands
    (``config NAME`` for every experiment that ``sinslab list`` prints)."""
    cli = ["-m", "sinslab.cli"]
    listed = subprocess.run([sys.executable, *cli, "list"], capture_output=True, text=True, env=_env(),
                            timeout=120, check=True).stdout
    cmds = {"python -c pass": ["-c", "pass"], "import sinslab.cli": ["-c", "import sinslab.cli"],
            "list": cli + ["list"], "--help": cli + ["--help"]}
    cmds.update({f"config {ln.split()[0]}": cli + ["config", ln.split()[0]] for ln in listed.splitlines() if ln.strip()})
    return cmds


def _wall(argv: list[str], env: dict) -> float:
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, *argv], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       env=env, timeout=120)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(argv)} failed: {r.stderr.decode(errors='replace').strip()}")
    return dt


def measure(repeat: int = 9) -> dict:
    cmds = commands()
    env = _env()
    for argv in cmds.values():              # warm-up: byte-compile, fill the file cache
        _wall(argv, env)
    times = {k: [] for k in cmds}
    for _ in range(repeat):
        for k, argv in cmds.items():
            times[k].append(_wall(argv, env))
    ref = statistics.median(times["python -c pass"])
    rows = {}
    for k, ts in times.items():
        med = statistics.median(ts)
        rows[k] = {"median_s": med, "min_s": min(ts), "max_s": max(ts),
                   "ratio_to_reference": med / ref, "above_reference_s": med - ref}
        if k not in ("python -c pass", "import sinslab.cli"):
            rows[k]["within_target"] = med <= TARGET_S
    return {"repeat": repeat, "reference": "python -c pass", "reference_median_s": ref,
            "target_s": TARGET_S, "commands": rows,
            "machine": {"python": platform.python_version(), "cpu": platform.processor() or platform.machine(),
                        "cpu_count": os.cpu_count(), "load_avg": os.getloadavg()}}


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=9, help="runs of each command (median taken)")
    ap.add_argument("--out", default=str(HERE / "results" / "startup.json"))
    a = ap.parse_args(argv)
    res = measure(a.repeat)
    print(f"{'command':<32s} {'median':>8s} {'min':>7s} {'max':>7s} {'x ref':>6s} {'- ref':>7s}")
    for k, r in res["commands"].items():
        mark = {True: "", False: f"  over {TARGET_S:g} s", None: ""}[r.get("within_target")]
        print(f"{k:<32s} {r['median_s']:8.3f} {r['min_s']:7.3f} {r['max_s']:7.3f} "
              f"{r['ratio_to_reference']:6.1f} {r['above_reference_s']:7.3f}{mark}")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=2) + "\n")
    return res


if __name__ == "__main__":
    main()
