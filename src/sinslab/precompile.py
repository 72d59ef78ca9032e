"""Compile sinslab's numba kernels ahead of the first run (``sinslab compile``).

A kernel compiles on its first call, for the argument types of that call, and numba keeps
it on disk (:mod:`sinslab.core.jitcache`). So that the first ``navigate`` or ``run`` after
an install starts warm, this module makes those first calls at install: the clone's
``make`` runs ``sinslab compile`` after ``pip install``, and a wheel is built with the
kernels inside (its build runs this module on the built package).

The calls are the commands themselves, on small inputs simulated here: ``navigate`` on a
three-minute car drive (loosely coupled; smoothed; with vehicle constraints, scale factors
and time synchronisation), ``align`` and ``allan`` on a rest record (as whitespace-delimited
text), and every experiment's ``--quick`` run with the variants ``sinslab demo`` adds
(campaigns in the process). Going through the commands, rather than
calling kernels with types written down here, compiles each kernel for the argument types
the commands give it (an array read from a memory-mapped file is read-only, for
instance, and that is another signature). Kernels that only other calls reach (a
tightly coupled navigation, a non-default option) still compile on their first use.

The work is split between ``jobs`` processes; :mod:`sinslab.core.jitlock` lets each kernel
compile in one of them while the others wait for it.

A compile for this machine leaves a stamp (:func:`fingerprint`: the package's sources, the
numba and Python versions, the CPU; and the kernel cache files it left). ``sinslab
compile`` run again with nothing changed finds the stamp true and says so instead of
running the commands a second time (a minute of CPU on a small machine); ``--force``
compiles anyway. A compile for any CPU (``--portable``, a wheel's build) leaves no stamp.
"""
from __future__ import annotations

import datetime
import hashlib
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

__all__ = ["precompile", "JOBS", "fingerprint"]

#: the commands, in two groups of about equal compile work (one per process of a 2-core
#: machine); each entry is the argument list of one ``sinslab`` command (``{d}``: the
#: folder of the simulated inputs, ``{o}``: a folder for the run)
DRIVE = ["--imu", "{d}/drive.csv", "--fixes", "{d}/fixes.csv"]
JOBS = (
    [["navigate", *DRIVE],
     ["navigate", *DRIVE, "--smooth", "--time-sync", "auto"],
     ["navigate", *DRIVE, "--aid", "nhc,zupt", "--scale-factors"],
     ["align", "--imu", "{d}/rest.txt", "--lat", "34 deg"],
     ["allan", "{d}/rest.txt"]],
    "experiments",
)


def _drive(folder: Path, minutes: float = 3.0, rate: float = 200.0) -> None:
    """A car drive (30 s at rest, then turns, straights and speed changes) with
    consumer-grade IMU errors and 1 Hz fixes, as ``drive.csv`` and ``fixes.csv``; and a
    rest record ``rest.csv`` (2 min), and as ``rest.txt`` for ``align`` and ``allan``."""
    import numpy as np

    from sinslab.core import units as u
    from sinslab.core.records import Fixes, ImuRecord
    from sinslab.data import write_fixes, write_imu
    from sinslab.sim import imu as IM
    from sinslab.sim import trajectory as tr

    pattern = [tr.Accelerate(duration=5.0, accel=2.0), tr.Level(duration=20.0),
               tr.Turn(duration=10.0, rate=9 * u.deg, coordinated=False), tr.Level(duration=20.0),
               tr.Turn(duration=20.0, rate=-9 * u.deg, coordinated=False),
               tr.Accelerate(duration=5.0, accel=-2.0), tr.Level(duration=10.0)]
    segs, tot = [tr.Static(duration=30.0)], 30.0
    while tot < 60.0 * minutes:
        for p in pattern:
            segs.append(p)
            tot += p.duration
    g = tr.generate(segs, tr.Start(lat=math.radians(40.1), lon=math.radians(-105.1), h=1600.0,
                                   heading=math.radians(30)), 1.0 / rate, duration=60.0 * minutes)
    err = IM.ImuErrors.from_datasheet(gyro_bias="0.05 deg/s", accel_bias="0.03 m/s^2",
                                      gyro_arw="0.0038 deg/sqrt(s)", accel_vrw="70 ug/sqrt(Hz)")
    write_imu(folder / "drive.csv", IM.apply(g.imu, err, 1))
    tru = g.truth
    rng = np.random.default_rng(2)
    k = np.arange(0, len(tru.t), int(round(rate)))[1:]
    write_fixes(folder / "fixes.csv", Fixes(tru.t[k], tru.lat[k] + rng.normal(0, 1.0, k.size) / 6.37e6,
                                           tru.lon[k], tru.h[k], np.full((k.size, 3), 1.0),
                                           tru.vel[k] + rng.normal(0, 0.05, (k.size, 3)),
                                           np.full((k.size, 3), 0.05), np.ones(k.size, int)))
    n, dt = int(120 * 100), 0.01
    lat = math.radians(34.0)
    wie = 7.292115e-5
    w = np.array([0.0, wie * math.cos(lat), wie * math.sin(lat)])
    rng = np.random.default_rng(3)
    rest = ImuRecord(dt * np.arange(1, n + 1), w * dt + rng.normal(0, 2e-7, (n, 3)),
                     np.array([0.0, 0.0, 9.7966]) * dt + rng.normal(0, 2e-5, (n, 3)), dt)
    write_imu(folder / "rest.csv", rest)
    # the rest record as whitespace-delimited text (KF-GINS', PSINS' layout), whose
    # compiled reader the commands on it compile
    text = (folder / "rest.csv").read_text(encoding="utf-8")
    (folder / "rest.txt").write_text(text.replace(",", " "), encoding="utf-8")


def _commands(group, folder: Path) -> list:
    if group == "experiments":
        from sinslab.app.config import resolve
        from sinslab.app.validate import starts_campaign
        from sinslab.experiments import get, names

        cmds = []
        for n in names():
            exp = get(n)
            # the default scenario and the variants ``sinslab demo`` runs: a variant may take
            # another path (a turntable mount, another mode) to kernels of its own
            for sets in [()] + list(exp.variants.values()):
                opts = [a for kv in sets for a in ("--set", kv)]
                campaign = starts_campaign(exp, resolve(exp.config, quick=exp.quick, sets=list(sets)))
                cmds.append(["run", n, "--quick", *opts] + (["--workers", "0"] if campaign else []))
        return cmds
    return [[a.format(d=folder) for a in c] for c in group]


def _child(index: int, folder: str) -> dict:
    """Run group ``index`` of :data:`JOBS` in this process; what it compiled, and its CPU."""
    from sinslab.core import jitnotice

    jitnotice.install()
    from sinslab.cli import app

    out = Path(folder)
    c0 = time.process_time()
    done = []
    for k, args in enumerate(_commands(JOBS[index], out)):
        run = out / f"run{index}-{k}"
        try:
            code = app(["-q", *args, "--out", str(run), "--force"], standalone_mode=False)
        except SystemExit as e:
            code = e.code
        if code not in (0, 1, None):            # 1: a claim failed, the run went through
            raise RuntimeError(f"sinslab {' '.join(args)} failed (exit {code})")
        done.append(args[:2])
    log = jitnotice.compile_log()
    return {"commands": done, "kernels": len(log), "compile_cpu_s": sum(x for _, x in log),
            "cpu_s": time.process_time() - c0}


def precompile(jobs: int = 2, env: dict | None = None, echo=print) -> dict:
    """Run the commands of :data:`JOBS` in ``jobs`` processes (1 or 2) on simulated inputs;
    their kernels end up in numba's cache (where :mod:`sinslab.core.jitcache` finds them).
    ``env``: extra environment of the processes (:data:`sinslab.core.jitcache.PORTABLE_ENV`
    to compile for any CPU of the architecture). Returns the kernels compiled, CPU and
    wall time."""
    w0 = time.perf_counter()
    full_env = dict(os.environ, SINSLAB_QUIET="1", MPLBACKEND="Agg", **(env or {}))
    with tempfile.TemporaryDirectory(prefix="sinslab-compile-") as d:
        sub = dict(full_env)
        subprocess.run([sys.executable, "-c", "import sys; from pathlib import Path; "
                        "from sinslab.precompile import _drive; _drive(Path(sys.argv[1]))", d],
                       check=True, env=sub)
        groups = list(range(len(JOBS)))
        procs, results = [], []
        batches = [groups] if jobs <= 1 else [[g] for g in groups]
        for batch in batches:
            procs.append(subprocess.Popen(
                [sys.executable, "-c", "import json, sys; from sinslab.precompile import _child; "
                 "print(json.dumps([_child(int(i), sys.argv[1]) for i in sys.argv[2:]]))", d,
                 *map(str, batch)], env=full_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
        for p in procs:
            out, err = p.communicate()
            if p.returncode != 0:
                raise RuntimeError(f"compiling the kernels failed:\n{err.strip()[-3000:]}")
            results += json.loads(out.strip().splitlines()[-1])
    res = {"kernels": sum(r["kernels"] for r in results), "cpu_s": sum(r["cpu_s"] for r in results),
           "compile_cpu_s": sum(r["compile_cpu_s"] for r in results), "wall_s": time.perf_counter() - w0,
           "commands": [c for r in results for c in r["commands"]]}
    echo(f"compiled {res['kernels']} kernels ({res['compile_cpu_s']:.0f} s of CPU; "
         f"{res['wall_s']:.0f} s in all, {len(res['commands'])} commands on simulated inputs)")
    return res


def _package() -> Path:
    return Path(__file__).resolve().parent


def _kernel_files(pkg: Path) -> list[Path]:
    """numba's cache files (index and data) of sinslab's kernels: beside the modules, under
    ``NUMBA_CACHE_DIR``, and in numba's per-user folder (where a read-only install's
    kernels go), one folder per source folder in the last two."""
    from numba.core import caching
    from numba.misc.appdirs import AppDirs

    folders = {p.parent / "__pycache__" for p in pkg.rglob("*.py")}
    roots = [Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)]
    if os.environ.get("NUMBA_CACHE_DIR"):
        roots.append(Path(os.environ["NUMBA_CACHE_DIR"]))
    for src in {p.parent for p in pkg.rglob("*.py")}:
        sub = caching._CacheLocator.get_suitable_cache_subpath(str(src / "x.py"))
        folders.update(r / sub for r in roots)
    return sorted(p for f in folders if f.is_dir() for p in f.iterdir() if p.suffix in (".nbi", ".nbc"))


def fingerprint() -> dict:
    """What this machine's compiled kernels depend on: the package's source files (their
    content), numba, Python and the CPU."""
    import llvmlite.binding as llvm
    import numba

    pkg = _package()
    src = hashlib.sha256()
    for p in sorted(pkg.rglob("*.py")):
        src.update(str(p.relative_to(pkg)).encode() + b"\0" + p.read_bytes())
    return {"sources": src.hexdigest(), "numba": numba.__version__, "python": sys.version,
            "cpu": os.environ.get("NUMBA_CPU_NAME") or llvm.get_host_cpu_name()}


def _stamp_path() -> Path:
    """Where the stamp of the last compile is kept: the package's ``__pycache__`` folder
    when it is writable, else the user's cache folder (one file per installed package)."""
    folder = _package() / "__pycache__"
    if os.access(folder if folder.is_dir() else _package(), os.W_OK):
        return folder / "sinslab-compiled.json"
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    tag = hashlib.sha256(str(_package()).encode()).hexdigest()[:12]
    return base / "sinslab" / f"compiled-{tag}.json"


def up_to_date() -> dict | None:
    """The stamp of the last compile for this machine when nothing it depends on has
    changed since and every cache file it left is still there (else None). Kernels compiled
    since (another signature, another command) add files and change nothing."""
    try:
        stamp = json.loads(_stamp_path().read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    now = fingerprint()
    if {k: stamp.get(k) for k in now} != now or not stamp.get("files"):
        return None
    return stamp if all(Path(f).is_file() for f in stamp["files"]) else None


def _write_stamp(res: dict) -> None:
    path = _stamp_path()
    stamp = dict(fingerprint(), kernels=res["kernels"], commands=len(res["commands"]),
                 compiled_at=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                 files=[str(p) for p in _kernel_files(_package())])
    try:
        from sinslab.core.atomic import atomic_write

        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, json.dumps(stamp, indent=1))
    except OSError:
        pass                                            # no stamp: the next compile runs again


def main(argv=None) -> int:
    """``python -m sinslab.precompile [--jobs N] [--portable] [--force]`` (what ``sinslab
    compile`` runs)."""
    import argparse

    ap = argparse.ArgumentParser(prog="sinslab compile", description=__doc__.splitlines()[0])
    ap.add_argument("--jobs", type=int, default=2, help="processes (1 or 2)")
    ap.add_argument("--portable", action="store_true", help="compile for any CPU of the architecture (wheels)")
    ap.add_argument("--force", action="store_true", help="compile even when the last compile is up to date")
    a = ap.parse_args(argv)
    from sinslab.core.jitcache import PORTABLE_ENV

    if not (a.portable or a.force):
        stamp = up_to_date()
        if stamp is not None:
            print(f"kernels up to date: compiled {stamp.get('compiled_at', '?')} for these sources, numba "
                  f"{stamp['numba']} and this CPU ({stamp['cpu']}); nothing changed since (--force compiles again)")
            return 0
    try:
        res = precompile(a.jobs, PORTABLE_ENV if a.portable else None)
    except RuntimeError as e:
        print(f"sinslab: error: {e}", file=sys.stderr)
        return 2
    if not a.portable:
        _write_stamp(res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
