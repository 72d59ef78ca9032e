"""Speed of the shared-noise kernel of :func:`sinslab.sim.imu.apply_arrays_shared` (the
noise of rotation-evaluation's INS #2 at every β drawn once for all of them) against its
previous form, written out here as the reference: the same draws and arithmetic with a
loop over the six channels around the loop over the models. Both run on the same inputs
and generator state in one process; their outputs are checked byte for byte.

Per number of models V (1, 2 and 7: rotation-evaluation's largest group) the CPU time per
sample of each (best of ``--repeat``, the two alternated) and their ratio, with the load
average.

Run: ``.venv/bin/python benchmarks/noise_shared.py [--samples N] [--repeat 5] [--out FILE]``;
results printed and written to ``benchmarks/results/noise_shared.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from numba import njit  # noqa: E402

from sinslab.sim import imu  # noqa: E402
from sinslab.sim._rng import _normal  # noqa: E402

HERE = Path(__file__).resolve().parent


@njit(cache=False, nogil=True)
def reference(dth, dv, state, bias_dt, wsig, out_dth, out_dv):
    """The kernel before its draws were unrolled (same bytes)."""
    n = dth.shape[0]
    V = bias_dt.shape[0]
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    for k in range(n):
        for c in range(6):
            z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
            if c < 3:
                x = dth[k, c]
                for j in range(V):
                    out_dth[j, k, c] = x + (bias_dt[j, c] + wsig[j, c] * z)
            else:
                x = dv[k, c - 3]
                for j in range(V):
                    out_dv[j, k, c - 3] = x + (bias_dt[j, c] + wsig[j, c] * z)


def case(V, n, repeat):
    rng = np.random.default_rng(V)
    dth, dv = rng.standard_normal((n, 3)) * 1e-5, rng.standard_normal((n, 3)) * 1e-3
    state = rng.integers(0, 2**64, size=4, dtype=np.uint64)
    bias_dt, wsig = rng.random((V, 6)) * 1e-7, rng.random((V, 6)) * 1e-6
    outs = {k: (np.empty((V, n, 3)), np.empty((V, n, 3))) for k in ("reference", "kernel")}
    fns = {"reference": reference, "kernel": imu._kernel_white_all_shared}
    best = {k: float("inf") for k in fns}
    for _ in range(max(1, repeat)):
        for k, fn in fns.items():
            c0 = time.process_time()
            fn(dth, dv, state.copy(), bias_dt, wsig, *outs[k])
            best[k] = min(best[k], time.process_time() - c0)
    same = all(a.tobytes() == b.tobytes() for a, b in zip(outs["reference"], outs["kernel"]))
    if not same:
        raise SystemExit(f"noise_shared: V={V}: the kernel's bytes differ from the reference's")
    return {"models": V, "reference_ns_per_sample": best["reference"] / n * 1e9,
            "kernel_ns_per_sample": best["kernel"] / n * 1e9, "ratio": best["reference"] / best["kernel"],
            "identical": same}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=360_000, help="samples per call (an hour at 100 Hz)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", default=str(HERE / "results" / "noise_shared.json"))
    a = ap.parse_args(argv)
    # compiled before timing
    for fn in (reference, imu._kernel_white_all_shared):
        o = (np.empty((1, 4, 3)), np.empty((1, 4, 3)))
        fn(np.zeros((4, 3)), np.zeros((4, 3)), np.ones(4, dtype=np.uint64), np.zeros((1, 6)), np.zeros((1, 6)), *o)
    res = {"samples": a.samples, "load_average": list(os.getloadavg()),
           "cases": [case(V, a.samples, a.repeat) for V in (1, 2, 7)]}
    for c in res["cases"]:
        print(f"V={c['models']}: reference {c['reference_ns_per_sample']:.1f} ns/sample, kernel "
              f"{c['kernel_ns_per_sample']:.1f} ns/sample: {c['ratio']:.2f}x (bytes identical)")
    print(f"load average {res['load_average'][0]:.2f}")
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=1))
    return res


if __name__ == "__main__":
    main()
