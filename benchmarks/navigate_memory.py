"""The fixed memory of one ``sinslab navigate`` process, stage by stage.

Run: ``.venv/bin/python benchmarks/navigate_memory.py [--minutes 1] [--reference SRC]
[--json FILE]``

A short simulated drive (the log of ``benchmarks/navigate_cost.py``, 1 min at 200 Hz by
default, so that the part of the memory that grows with the log is negligible) goes
through ``sinslab navigate`` in a fresh process that records its resident memory (RSS,
and its anonymous and file-backed parts: the file-backed part is mostly the shared
libraries' mapped code, llvmlite's 180 MB library above all) at the end of each stage:

* ``interpreter``: Python started, nothing imported;
* ``numpy``: ``import numpy``;
* ``cli``: ``import sinslab.cli`` (typer; the commands' modules are imported when the
  command line is parsed);
* ``parse``: the command line parsed, up to the command's first file read (the command
  module and what its compute path imports at the top);
* ``reading``: the IMU table and the fixes read;
* ``filter``: the filter run (:func:`sinslab.fusion.recorded.navigate_recorded`); the
  memory taken while numba loads compiled kernels from its cache is counted apart
  (``kernels``, with the number of kernels loaded);
* ``after filter``: metrics, plausibility checks and the figures built (matplotlib);
* ``tables``: the solution and fix-error tables written;
* ``figures``: the figures drawn and written (PNG + SVG) and closed;
* ``report``: ``summary.json`` and ``report.html``.

For every stage: RSS at its end, its growth, the peak so far (``VmHWM``) and the
packages imported for the first time during it, with the memory each import took
(a package's figure includes what it imports in turn; scipy's, pyarrow's and
matplotlib's subpackages are listed apart). The peak of the process is the
figure the target applies to (a 1 h, 200 Hz navigate under 300 MB); this script shows
what the part that does not depend on the log is made of.

``--reference SRC``: the ``src`` folder of another checkout (the code before a change)
runs on the same log with this interpreter (the same installed packages), the two
alternated ``--rounds`` times; the table then shows both and the difference.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SRC = HERE.parent / "src"

_CHILD = r"""
import builtins, json, os, sys
def mem():
    d = {}
    with open("/proc/self/status") as fh:
        for ln in fh:
            k, _, v = ln.partition(":")
            if k in ("VmRSS", "VmHWM", "RssAnon", "RssFile"):
                d[k] = int(v.split()[0]) / 1024
    return d
def peak():
    # VmHWM, not ru_maxrss: the latter starts from the RSS of the process that spawned
    # this one (the high-water mark of the memory image replaced by exec is kept)
    return mem()["VmHWM"]
stages, imports, cur = [], {}, [None]
def mark(name):
    m = mem()
    stages.append({"stage": name, "rss": m["VmRSS"], "anon": m.get("RssAnon", 0.0),
                   "file": m.get("RssFile", 0.0), "peak": m["VmHWM"]})
    cur[0] = name
mark("interpreter")
kern = {"n": 0, "mb": 0.0}
_imp = builtins.__import__
def _patch_numba():
    cache = getattr(sys.modules.get("numba.core.caching"), "Cache", None)
    if cache is None or getattr(cache.load_overload, "_measured", False):
        return
    f = cache.load_overload
    def load_overload(self, *a, **k):
        r0 = mem()["VmRSS"]
        try:
            return f(self, *a, **k)
        finally:
            kern["n"] += 1
            kern["mb"] += mem()["VmRSS"] - r0
    load_overload._measured = True
    cache.load_overload = load_overload
SUB = ("scipy", "pyarrow", "matplotlib")      # their subpackages are counted apart
outer = []
def imp(name, globals=None, locals=None, fromlist=(), level=0):
    key = None
    if level == 0:
        parts = name.split(".")
        key = ".".join(parts[:2]) if parts[0] in SUB and len(parts) > 1 else parts[0]
        if key in SUB and fromlist:              # from scipy import stats
            key = next((f"{key}.{f}" for f in fromlist if f"{key}.{f}" not in sys.modules), key)
        if key in sys.modules or key in imports:
            key = None
    if key is not None:
        r0 = mem()["VmRSS"]
        imports[key] = None
        outer.append(key)
    try:
        return _imp(name, globals, locals, fromlist, level)
    finally:
        if key is not None:
            outer.pop()
            imports[key] = {"mb": mem()["VmRSS"] - r0, "stage": len(stages),
                            "within": outer[-1] if outer else None}
        if "numba.core.caching" in sys.modules:
            _patch_numba()
builtins.__import__ = imp
import numpy
mark("numpy")
from sinslab.cli import app
mark("cli")
import sinslab.data as D
import sinslab.data.spool as SP
import sinslab.fusion.recorded as R
import sinslab.app.commands.runner as RU
import sinslab.app.outputs as O
def staged(owner, name, before=None, after=None):
    f = getattr(owner, name)
    def g(*a, **k):
        if before and cur[0] != before:
            mark(before)
        try:
            return f(*a, **k)
        finally:
            if after:
                mark(after)
    setattr(owner, name, g)
staged(D, "load_imu", before="parse")
staged(SP, "spool_table_imu", before="parse")     # a CSV or Parquet log is read in blocks
staged(D, "read_fixes", after="reading")
staged(D, "load_fixes", after="reading")
def filt(*a, **k):
    k0 = dict(kern)
    try:
        return _nav(*a, **k)
    finally:
        mark("filter")
        stages[-1]["kernels"] = kern["n"] - k0["n"]
        stages[-1]["kernels_mb"] = kern["mb"] - k0["mb"]
_nav = R.navigate_recorded
R.navigate_recorded = filt
_wt = O.RunDir.write_table
def write_table(self, *a, **k):
    if cur[0] == "filter":
        mark("after filter")
    return _wt(self, *a, **k)
O.RunDir.write_table = write_table
_wf = RU.write_figures
def write_figures(*a, **k):
    mark("tables")
    try:
        return _wf(*a, **k)
    finally:
        mark("figures")
RU.write_figures = write_figures
staged(RU, "complete_timed", after="report")
try:
    app(sys.argv[1:], standalone_mode=False)
finally:
    print("MEMORY " + json.dumps({"stages": stages, "imports": {k: v for k, v in imports.items() if v},
                                  "peak": peak(), "modules": sorted(sys.modules)}))
"""


def run_child(ip, fp, out, src=SRC, extra=()):
    """One navigate process on the log ``ip``/``fp`` with the sinslab of ``src``; returns
    its stage records."""
    env = dict(os.environ, SINSLAB_QUIET="1", MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join(p for p in (str(src), os.environ.get("PYTHONPATH")) if p))
    p = subprocess.run([sys.executable, "-c", _CHILD, "-q", "navigate", "--imu", ip, "--fixes", fp,
                        "--out", out, "--force", *extra], capture_output=True, text=True, env=env)
    line = [ln for ln in p.stdout.splitlines() if ln.startswith("MEMORY ")]
    if p.returncode != 0 or not line:
        raise RuntimeError(f"navigate failed ({p.returncode}): {p.stderr[-2000:]}")
    return json.loads(line[-1][7:])


def _best(runs):
    """The run with the lowest peak (the least disturbed by the machine)."""
    return min(runs, key=lambda r: r["peak"])


def table(res, label):
    """Printable lines of one run's stages."""
    lines = [f"{label}: peak RSS {res['peak']:.0f} MB",
             f"  {'stage':<13s} {'RSS':>6s} {'+':>6s} {'anon':>6s} {'file':>6s} {'peak':>6s}  imported here (MB)"]
    by_stage = {}
    for name, v in res["imports"].items():    # v["stage"]: the stage in progress, by index
        if v["within"] is None:                  # an import inside another is part of it
            by_stage.setdefault(v["stage"], []).append((v["mb"], name))
    prev = 0.0
    for i, s in enumerate(res["stages"]):
        imp = sorted(by_stage.get(i, []), reverse=True)
        imp_txt = ", ".join(f"{n} {mb:.0f}" for mb, n in imp if mb >= 1.0)
        if "kernels" in s:
            imp_txt = (f"{s['kernels']} kernels loaded: {s['kernels_mb']:.0f}"
                       + (f"; {imp_txt}" if imp_txt else ""))
        lines.append(f"  {s['stage']:<13s} {s['rss']:6.0f} {s['rss'] - prev:+6.0f} {s['anon']:6.0f} "
                     f"{s['file']:6.0f} {s['peak']:6.0f}  {imp_txt}")
        prev = s["rss"]
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=1.0, help="length of the simulated log")
    ap.add_argument("--reference", help="the src folder of another checkout, run alternately on the same log")
    ap.add_argument("--rounds", type=int, default=2, help="processes of each (the lowest peak shown)")
    ap.add_argument("--smooth", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    sys.path.insert(0, str(HERE))
    from navigate_cost import make_log

    who = [("this", SRC)] + ([("reference", Path(a.reference).resolve())] if a.reference else [])
    runs = {w: [] for w, _ in who}
    with tempfile.TemporaryDirectory() as d:
        ip, fp, n = make_log(d, a.minutes)
        extra = ["--smooth"] if a.smooth else []
        for w, src in who:                       # warm-up: numba's cache of each tree filled
            run_child(ip, fp, os.path.join(d, "run"), src, extra)
        for _ in range(a.rounds):
            for w, src in who:
                runs[w].append(run_child(ip, fp, os.path.join(d, "run"), src, extra))
    print(f"navigate on {a.minutes:g} min at 200 Hz ({n:,} samples{', --smooth' if a.smooth else ''}), "
          f"load {os.getloadavg()[0]:.2f}; MB (2^20 bytes)")
    best = {w: _best(r) for w, r in runs.items()}
    for w, _ in who:
        print("\n".join(table(best[w], w)))
    if a.reference:
        t, r = best["this"], best["reference"]
        print(f"this - reference: peak {t['peak'] - r['peak']:+.0f} MB "
              f"({t['peak']:.0f} vs {r['peak']:.0f})")
    if a.json:
        Path(a.json).write_text(json.dumps({w: {k: v for k, v in b.items() if k != "modules"}
                                            for w, b in best.items()}, indent=2) + "\n")
    return best


if __name__ == "__main__":
    main()
