"""The first run after an install against the second: CPU and peak memory of ``navigate``
(10 min and 1 h logs) and of a ``--quick`` experiment, on a fresh install whose only numba
cache is what the install compiled.

Run: ``.venv/bin/python benchmarks/cold_start.py [--only clone|wheel|none ...] [--minutes 10 60]
[--experiment NAME] [--out FILE]`` (minutes: each install is a new virtual environment).

Installs (each a new virtual environment of this interpreter's Python, packages from pip's
cache or the index; the user's cache folder a new empty one, ``HOME`` and
``XDG_CACHE_HOME`` pointing there, so nothing compiled earlier is found):

* ``clone``: the committed tree (``HEAD``) cloned and installed as CI and the README do,
  ``make .venv/.installed`` (``pip install -e .[dev]``, then ``sinslab compile``);
* ``wheel``: a wheel built from the clone (``pip wheel``: the build compiles the kernels for
  any CPU of the architecture into it), installed into the environment, whose
  ``site-packages`` is then made read-only (new kernels go to the user cache folder);
* ``none``: the clone's install without ``sinslab compile`` — what a first run paid before
  the kernels were compiled at install (the reference of the choice).

Per install and command: the first run (``cold``) and the second (``warm``) — CPU of the
process (user + system), its peak resident memory (``VmHWM``) and the kernels it compiled
(numba's compile events) — and their difference. Targets: the first run within 3 s of CPU
of the second, and its peak under 300 MB (the warm 1 h ``navigate``). The install's own
time is reported (pip, and the kernel compilation apart), with the load average.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import stat
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

#: the command's process: the run, then its CPU, peak memory and the kernels it compiled
_CHILD = r"""
import json, sys, time
from sinslab.core import jitnotice
jitnotice.install()
from sinslab.cli import app
code = 0
try:
    code = app(sys.argv[1:], standalone_mode=False)
except SystemExit as e:
    code = e.code
with open("/proc/self/status") as fh:
    hwm = next(int(ln.split()[1]) for ln in fh if ln.startswith("VmHWM:"))
log = jitnotice.compile_log()
import resource
r = resource.getrusage(resource.RUSAGE_SELF)
print("COLD " + json.dumps({"code": code, "cpu_s": r.ru_utime + r.ru_stime, "peak_mb": hwm / 1024,
                            "kernels": len(log), "compile_cpu_s": sum(x for _, x in log),
                            "compiled": [k for k, _ in log]}))
"""

TARGET_CPU_S, TARGET_PEAK_MB = 3.0, 300.0


def _run(cmd, cwd, env, log):
    c0 = os.times()
    w0 = time.perf_counter()
    with open(log, "a") as fh:
        r = subprocess.run(cmd, cwd=cwd, env=env, stdout=fh, stderr=subprocess.STDOUT)
    c1 = os.times()
    if r.returncode:
        text = Path(log).read_text(errors="replace")
        said = [ln for ln in text.splitlines() if "sinslab: error" in ln or "Error:" in ln]
        sys.exit(f"cold_start: error: {' '.join(map(str, cmd))} failed (exit {r.returncode}):\n"
                 + "\n".join(said[:20]) + "\n" + text[-2000:])
    return {"wall_s": round(time.perf_counter() - w0, 2),
            "cpu_s": round((c1.children_user - c0.children_user) + (c1.children_system - c0.children_system), 2)}


def _env(home: Path) -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "NUMBA_DISABLE_JIT", "PYTHONPATH", "SINSLAB_JITCACHE", "VIRTUAL_ENV")}
    home.mkdir(parents=True, exist_ok=True)
    # pip keeps its own cache (the packages are not downloaded again); numba and matplotlib start empty
    env.setdefault("PIP_CACHE_DIR", os.path.join(os.path.expanduser("~"), ".cache", "pip"))
    env.update(HOME=str(home), XDG_CACHE_HOME=str(home / ".cache"), SINSLAB_QUIET="1", MPLBACKEND="Agg",
               MPLCONFIGDIR=str(home / "mpl"))
    return env


def _clone(tmp: Path) -> Path:
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
    tree = tmp / "sinslab"
    subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(ROOT), str(tree)], check=True)
    subprocess.run(["git", "checkout", "--quiet", head], cwd=tree, check=True)
    return tree


def install(kind: str, tmp: Path, env: dict) -> dict:
    """A fresh install of ``kind``; returns its python, and the install's times."""
    tree = _clone(tmp)
    log = tmp / "install.log"
    info = {"kind": kind}
    if kind in ("clone", "none"):
        py = tree / ".venv" / "bin" / "python"
        info["venv"] = _run([sys.executable, "-m", "venv", str(tree / ".venv")], tree, env, log)
        info["pip"] = _run([str(py), "-m", "pip", "install", "-q", "-e", ".[dev]"], tree, env, log)
        if kind == "clone":
            info["compile"] = _run([str(tree / ".venv" / "bin" / "sinslab"), "compile"], tree, env, log)
        return {**info, "python": str(py)}
    venv = tmp / "venv"
    py = venv / "bin" / "python"
    info["venv"] = _run([sys.executable, "-m", "venv", str(venv)], tmp, env, log)
    wheels = tmp / "dist"
    info["wheel"] = _run([str(py), "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(wheels), str(tree)],
                         tmp, env, log)
    whl = next(wheels.glob("sinslab-*.whl"))
    info["pip"] = _run([str(py), "-m", "pip", "install", "-q", str(whl)], tmp, env, log)
    site = Path(subprocess.run([str(py), "-c", "import sinslab, os; print(os.path.dirname(sinslab.__file__))"],
                               capture_output=True, text=True, env=env, cwd=tmp).stdout.strip())
    for p in [site, *site.rglob("*")]:           # read-only, as a system-wide install
        p.chmod(p.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    info["shipped_kernels"] = sum(1 for _ in site.rglob("*.nbi"))
    return {**info, "python": str(py), "site": str(site)}


def _read_only(folder: Path) -> list | None:
    """A command prefix that runs its command with ``folder`` mounted read-only in a mount
    namespace of its own (``unshare``: permission bits alone do not stop root, and the
    interpreter may live where another user cannot go); None where that cannot be done."""
    prefix = ["unshare", "--mount", "--propagation", "private", "sh", "-c",
              f'mount --bind "{folder}" "{folder}" && mount -o remount,bind,ro "{folder}" && exec "$@"', "sh"]
    probe = subprocess.run(prefix + ["sh", "-c", f'! touch "{folder}/.w" 2>/dev/null'], capture_output=True)
    return prefix if probe.returncode == 0 else None


def _command(py, args, cwd, env, prefix=None) -> dict:
    p = subprocess.run([*(prefix or []), py, "-c", _CHILD, "-q", *args, "--force"], cwd=cwd, env=env,
                       capture_output=True, text=True)
    line = [ln for ln in p.stdout.splitlines() if ln.startswith("COLD ")]
    if not line:
        sys.exit(f"cold_start: error: sinslab {' '.join(args)} failed:\n{p.stderr[-3000:]}")
    r = json.loads(line[-1][5:])
    if r["code"] not in (0, 1, None):
        sys.exit(f"cold_start: error: sinslab {' '.join(args)} exited {r['code']}:\n{p.stderr[-3000:]}")
    return r


def measure(kinds, minutes, experiment) -> dict:
    import navigate_cost

    res = {"installs": {}, "machine": {"python": platform.python_version(), "cpu_count": os.cpu_count()}}
    with tempfile.TemporaryDirectory(prefix="sinslab-cold-") as d:
        d = Path(d)
        logs = {}
        for m in minutes:
            folder = d / f"log{m:g}"
            folder.mkdir()
            ip, fp, n = navigate_cost.make_log(str(folder), m)
            logs[f"navigate {m:g} min"] = ["navigate", "--imu", ip, "--fixes", fp]
        logs[f"run {experiment} --quick"] = ["run", experiment, "--quick"]
        for kind in kinds:
            tmp = d / kind
            tmp.mkdir()
            env = _env(tmp / "home")
            load0 = os.getloadavg()[0]
            inst = install(kind, tmp, env)
            prefix = None
            if kind == "wheel":
                prefix = _read_only(Path(inst["site"]))
                inst["read_only"] = "mount" if prefix else ("permission bits" if os.geteuid() else "no (root)")
            work = tmp / "work"
            work.mkdir()
            rows = {}
            for name, args in logs.items():
                out = ["--out", str(work / "run")]
                cold = _command(inst["python"], args + out, work, env, prefix)
                warm = _command(inst["python"], args + out, work, env, prefix)
                rows[name] = {"cold": cold, "warm": warm, "cpu_difference_s": cold["cpu_s"] - warm["cpu_s"]}
            user_cache = sum(1 for _ in (tmp / "home" / ".cache").rglob("*.nbi")) if (tmp / "home" / ".cache").exists() else 0
            res["installs"][kind] = {**{k: v for k, v in inst.items() if k not in ("python",)},
                                     "commands": rows, "kernels_in_user_cache_after": user_cache,
                                     "load_before": round(load0, 2), "load_after": round(os.getloadavg()[0], 2)}
            shutil.rmtree(tmp, ignore_errors=True)
    return res


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", action="append", choices=("clone", "wheel", "none"),
                    help="installs to measure (repeatable; default clone and wheel)")
    ap.add_argument("--minutes", type=float, nargs="+", default=[10.0, 60.0])
    ap.add_argument("--experiment", default="static-alignment", help="the --quick experiment run")
    ap.add_argument("--out", default=str(HERE / "results" / "cold_start.json"))
    a = ap.parse_args(argv)
    res = measure(a.only or ["clone", "wheel"], a.minutes, a.experiment)
    for kind, r in res["installs"].items():
        t = " + ".join(f"{k} {r[k]['wall_s']:.0f} s" for k in ("venv", "wheel", "pip", "compile") if k in r)
        print(f"{kind}: install {t} (wall) at load {r['load_before']:.2f}-{r['load_after']:.2f}"
              + (f"; {r['shipped_kernels']} kernels in the wheel, site-packages read-only: {r['read_only']}"
                 if "shipped_kernels" in r else ""))
        for name, c in r["commands"].items():
            cold, warm = c["cold"], c["warm"]
            ok = c["cpu_difference_s"] <= TARGET_CPU_S and cold["peak_mb"] < TARGET_PEAK_MB
            print(f"  {name:<28s} first {cold['cpu_s']:6.2f} s CPU, {cold['peak_mb']:4.0f} MB, "
                  f"{cold['kernels']} kernels compiled ({cold['compile_cpu_s']:.1f} s); second {warm['cpu_s']:6.2f} s, "
                  f"{warm['peak_mb']:4.0f} MB -> +{c['cpu_difference_s']:.2f} s "
                  f"({'within' if ok else 'outside'} the targets: +{TARGET_CPU_S:g} s, < {TARGET_PEAK_MB:g} MB)")
        print(f"  kernels cached in the user cache folder afterwards: {r['kernels_in_user_cache_after']}")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1) + "\n")
    return res


if __name__ == "__main__":
    main()
