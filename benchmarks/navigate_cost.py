"""Fixed cost and peak memory of one ``sinslab navigate`` process, by stage.

Run: ``.venv/bin/python benchmarks/navigate_cost.py [--minutes 10 60] [--format csv]
[--smooth] [--json FILE] [--reference PYTHON | --reference-src SRC]``

``--reference PYTHON``: the interpreter of another sinslab install (another clone's
``.venv/bin/python``, the code before a change) runs ``navigate`` on the same logs, its
processes alternated with this install's, and each figure is printed beside its
reference (the machine's load moves both alike). The load average is printed with them.
``--reference-src SRC``: the same with the ``src`` folder of another checkout run by this
interpreter. For memory this is the fairer reference: part of the resident memory is the
installed libraries' files mapped from the page cache (llvmlite's alone is 180 MB), and
a freshly installed environment, whose files are all cached, maps far more of them
(+77 MB measured for the same code) than one whose pages have aged out of the cache.

A simulated car drive (30 s at rest, then turns, straights, accelerations; 200 Hz IMU with
consumer-MEMS errors, 1 Hz position fixes) of each length is written as an IMU table
(``imu.csv`` or ``imu.parquet``) and ``fixes.csv``; then ``sinslab navigate`` runs on it
in a fresh process (the way a user runs it) that records, by CPU time:

* start-up: interpreter, imports and command-line parsing up to the command's body;
* reading: the IMU table and the fixes (:func:`sinslab.data.load_imu`,
  :func:`sinslab.data.read_fixes`);
* compute: :func:`sinslab.fusion.recorded.navigate_recorded` (the filter, and the
  smoother with ``--smooth``);
* the rest: metrics, tables, figures, report and writing the run folder;

and its peak resident memory (``VmHWM``; ``ru_maxrss`` where there is none). The fixed
cost is everything but compute (target < 2 s of CPU on a 10 min log); the peak memory of
the 1 h log is the second target (< 300 MB); ``benchmarks/navigate_memory.py`` shows
what the part of the memory that does not depend on the log is made of.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

_CHILD = r"""
import json, os, resource, sys, time
from sinslab.cli import app
import sinslab.data as D
import sinslab.fusion.recorded as R
t_cli = time.process_time()
st = {}
def timed(mod, name):
    f = getattr(mod, name)
    def g(*a, **k):
        c = time.process_time()
        try:
            return f(*a, **k)
        finally:
            st[name] = st.get(name, 0.0) + time.process_time() - c
    setattr(mod, name, g)
import sinslab.app.commands.navigate as N
for mod, name in ((D, "load_imu"), (D, "read_fixes"), (R, "navigate_recorded"), (N, "_read_imu")):
    if hasattr(mod, name):              # an install that reads the IMU log in blocks
        timed(mod, name)
try:
    app(sys.argv[1:], standalone_mode=False)
finally:
    tot = time.process_time()
    # VmHWM where there is one: ru_maxrss of a spawned process starts at the RSS its parent
    # had (the high-water mark of the image exec replaced), here the simulating parent's
    try:
        with open("/proc/self/status") as fh:
            hwm = next(int(ln.split()[1]) for ln in fh if ln.startswith("VmHWM:"))
    except (OSError, StopIteration):
        hwm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print("STAGES " + json.dumps({"startup": t_cli, "total": tot, "maxrss_mb": hwm / 1024, **st}))
"""


def make_log(folder, minutes, fmt="csv", rate=200.0, seed=1):
    """Write the drive of ``minutes`` minutes into ``folder``; returns (imu path, fix path)."""
    from sinslab.core.records import Fixes
    from sinslab.core import units as u
    from sinslab.data import write_fixes, write_imu
    from sinslab.sim import imu as IM
    from sinslab.sim import trajectory as tr

    dur = 60.0 * minutes
    pattern = [tr.Accelerate(duration=5.0, accel=2.0), tr.Level(duration=60.0),
               tr.Turn(duration=10.0, rate=9 * u.deg, coordinated=False), tr.Level(duration=40.0),
               tr.Turn(duration=20.0, rate=-9 * u.deg, coordinated=False),
               tr.Accelerate(duration=5.0, accel=-2.0), tr.Level(duration=30.0)]
    segs, tot = [tr.Static(duration=30.0)], 30.0
    while tot < dur:
        for p in pattern:
            segs.append(p)
            tot += p.duration
    g = tr.generate(segs, tr.Start(lat=math.radians(40.1), lon=math.radians(-105.1), h=1600.0,
                                   heading=math.radians(30)), 1.0 / rate, duration=dur)
    err = IM.ImuErrors.from_datasheet(gyro_bias="0.05 deg/s", accel_bias="0.03 m/s^2",
                                      gyro_arw="0.0038 deg/sqrt(s)", accel_vrw="70 ug/sqrt(Hz)")
    imu = IM.apply(g.imu, err, seed)
    tru = g.truth
    rng = np.random.default_rng(seed + 1)
    k = np.arange(0, len(tru.t), int(round(rate)))[1:]
    fx = Fixes(tru.t[k], tru.lat[k] + rng.normal(0, 1.0, k.size) / 6.37e6, tru.lon[k], tru.h[k],
               np.full((k.size, 3), 1.0), None, None, np.ones(k.size, int))
    ip = os.path.join(folder, f"imu.{fmt}")
    fp = os.path.join(folder, "fixes.csv")
    write_imu(ip, imu, fmt)
    write_fixes(fp, fx)
    return ip, fp, len(imu)


def run_navigate(ip, fp, out, extra=(), python=None, src=None):
    """One navigate process (of ``python``, default this interpreter, with the sinslab of
    ``src`` when given); returns its stage times [s CPU] and peak RSS [MB]."""
    env = dict(os.environ, SINSLAB_QUIET="1", MPLBACKEND="Agg", OMP_NUM_THREADS="1",
               OPENBLAS_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(src), os.environ.get("PYTHONPATH")) if p)
    p = subprocess.run([python or sys.executable, "-c", _CHILD, "-q", "navigate", "--imu", ip, "--fixes", fp,
                        "--out", out, "--force", *extra], capture_output=True, text=True, env=env)
    line = [ln for ln in p.stdout.splitlines() if ln.startswith("STAGES ")]
    if p.returncode != 0 or not line:
        raise RuntimeError(f"navigate failed ({p.returncode}): {p.stderr[-2000:]}")
    s = json.loads(line[-1][7:])
    load = s.pop("load_imu", 0.0)
    imu_read = s.pop("_read_imu", None)        # navigate's reader (load_imu inside it when it reads whole)
    s["reading"] = (load if imu_read is None else imu_read) + s.pop("read_fixes", 0.0)
    s["compute"] = s.pop("navigate_recorded", 0.0)
    s["rest"] = s["total"] - s["startup"] - s["reading"] - s["compute"]
    s["fixed"] = s["total"] - s["compute"]
    return s


def _line(best, n):
    return (f"total {best['total']:.2f} s CPU = start-up {best['startup']:.2f} + reading "
            f"{best['reading']:.2f} + compute {best['compute']:.2f} + rest (metrics, figures, "
            f"writing) {best['rest']:.2f}; fixed (all but compute) {best['fixed']:.2f} s; "
            f"peak RSS {best['maxrss_mb']:.0f} MB ({1e6 * best['maxrss_mb'] / n:.0f} B per sample)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[10.0, 60.0])
    ap.add_argument("--format", default="csv", choices=("csv", "parquet"))
    ap.add_argument("--smooth", action="store_true")
    ap.add_argument("--rounds", type=int, default=2, help="processes per log (best CPU of each stage)")
    ap.add_argument("--reference", help="interpreter of another sinslab install, run alternately on the same logs")
    ap.add_argument("--reference-src", help="the src folder of another checkout, run by this interpreter (the "
                    "same installed packages) alternately on the same logs")
    ap.add_argument("--json")
    a = ap.parse_args(argv)
    out = {}
    if a.reference and a.reference_src:
        ap.error("--reference and --reference-src exclude each other")
    who = ([("this", None, None)] + ([("reference", a.reference, None)] if a.reference else [])
           + ([("reference", None, a.reference_src)] if a.reference_src else []))
    print(f"load average at the start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    with tempfile.TemporaryDirectory() as d:
        for mins in a.minutes:
            ip, fp, n = make_log(d, mins, a.format)
            extra = ["--smooth"] if a.smooth else []
            runs = {w: [] for w, _, _ in who}
            for _ in range(a.rounds):
                for w, py, src in who:
                    runs[w].append(run_navigate(ip, fp, os.path.join(d, "run"), extra, python=py, src=src))
            print(f"{mins:g} min, {n:,} samples ({a.format}{', --smooth' if a.smooth else ''}), "
                  f"load {os.getloadavg()[0]:.2f} (targets: fixed < 2 s on 10 min, peak < 300 MB on 60 min):")
            for w, _, _ in who:
                best = {k: min(r[k] for r in runs[w]) for k in runs[w][0]}
                out.setdefault(w, {})[f"{mins:g}min"] = dict(best, samples=n)
                print(f"  {w:>9}: {_line(best, n)}")
            if len(who) > 1:
                t, r = out["this"][f"{mins:g}min"], out["reference"][f"{mins:g}min"]
                print(f"  this / reference: fixed {t['fixed'] / r['fixed']:.2f}, compute "
                      f"{t['compute'] / r['compute']:.2f}, peak RSS {t['maxrss_mb'] / r['maxrss_mb']:.2f}")
            os.remove(ip)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=2)
    return out


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
