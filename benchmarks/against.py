"""The default loosely coupled filter of this tree against another commit, in one run.

Two versions of a package cannot live in one process, so each is timed in fresh
subprocesses, alternated (this tree, the other, this tree, ...) so that load changes on a
shared machine hit both alike; each subprocess reports its best CPU time of ``--repeat``
calls after a warm-up call. The other commit is checked out into a temporary git worktree
(numba caches its kernels next to those sources, so its first subprocess compiles them;
that call is the warm-up).

Workloads (the simulated aircraft of ``benchmarks/estimation.py``, 200 Hz IMU with
tactical-grade errors, 1 Hz position fixes, filter step 0.1 s, nsub = 2):

* ``15``: the default 15-state model (φ, δv, δp, gyro and accelerometer bias);
* ``21``: plus gyro and accelerometer scale factors (21 states).

The final navigation rows of the two trees are compared too (attitude [rad], velocity
[m/s], position [m]; they should agree to rounding). Run::

    .venv/bin/python benchmarks/against.py [--rev a22fd11] [--duration 1800] [--rounds 3]

Results are printed and written to ``benchmarks/results/against.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

# What a subprocess runs: argv = [benchmarks dir, duration, states, repeat]; the package
# comes from PYTHONPATH.
_CHILD = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
import estimation as B
from sinslab.fusion import loosely_coupled as integ
from sinslab.fusion.spec import FilterGrid, FixSpec

dur, states, repeat = float(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
meas, init, ft, fix, sig, P, extra, truth = B.lc_states(dur, states)
go = lambda: integ.loosely_coupled(meas, init, FixSpec(ft, fix, sig), P, grid=FilterGrid(0.1), progress=False, **extra)
go()
best = float("inf")
for _ in range(repeat):
    c = time.process_time()
    r = go()
    best = min(best, time.process_time() - c)
print(json.dumps({"cpu_s": best, "epochs": int(r.t.size - 1), "last_row": np.asarray(r.nav[-1]).tolist()}))
"""


def _child(src: Path, duration: float, states: int, repeat: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(src), SINSLAB_QUIET="1",
               OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1", MKL_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    r = subprocess.run([sys.executable, "-c", _CHILD, str(HERE), str(duration), str(states), str(repeat)],
                       env=env, capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"benchmark subprocess failed for {src}:\n{r.stderr.strip()[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rev", default="a22fd11", help="the other commit (default: a22fd11)")
    ap.add_argument("--duration", type=float, default=1800.0, help="simulated drive [s]")
    ap.add_argument("--rounds", type=int, default=3, help="alternated subprocess pairs per workload")
    ap.add_argument("--repeat", type=int, default=3, help="timed calls per subprocess (best kept)")
    ap.add_argument("--states", default="15,21", help="workloads, comma separated: 15, 21")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "against.json")
    a = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="sinslab-against-"))
    other = tmp / "tree"
    try:
        r = subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(other), a.rev],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise SystemExit(f"cannot check out {a.rev!r}: {r.stderr.strip()}")
        trees = {"this": ROOT / "src", a.rev: other / "src"}
        out = {"rev": a.rev, "duration_s": a.duration, "rounds": a.rounds}
        for states in (int(s) for s in a.states.split(",")):
            best = {}
            rows = {}
            for _ in range(a.rounds):
                for name, src in trees.items():
                    res = _child(src, a.duration, states, a.repeat)
                    best[name] = min(best.get(name, float("inf")), res["cpu_s"])
                    rows[name] = res["last_row"]
            x, y = rows["this"], rows[a.rev]          # [q0..q3, vE, vN, vU, lat, lon, h]
            diff = {"attitude_rad": 2.0 * max(abs(x[i] - y[i]) for i in range(4)),
                    "velocity_mps": max(abs(x[i] - y[i]) for i in range(4, 7)),
                    "position_m": max(6.4e6 * abs(x[7] - y[7]), 6.4e6 * abs(x[8] - y[8]), abs(x[9] - y[9]))}
            out[f"states{states}"] = {"cpu_this_s": best["this"], f"cpu_{a.rev}_s": best[a.rev],
                                      "speedup": best[a.rev] / best["this"], "last_row_diff": diff,
                                      "epochs": res["epochs"]}
            print(f"{states} states, P at 10 Hz, {a.duration:g} s: this tree {best['this']:.3f} s CPU, "
                  f"{a.rev} {best[a.rev]:.3f} s -> {best[a.rev] / best['this']:.2f}x; "
                  f"final rows differ by {diff['attitude_rad']:.1e} rad, {diff['velocity_mps']:.1e} m/s, "
                  f"{diff['position_m']:.1e} m")
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(other)],
                       capture_output=True)
        shutil.rmtree(tmp, ignore_errors=True)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
