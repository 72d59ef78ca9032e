"""Speed of the linear-system Monte Carlo task :func:`sinslab.estimation.montecarlo.linear_batch`
against the textbook numpy form of the same task, in the same process.

``linear_batch`` steps the one Kalman core: the covariance and gains once for the batch
(:func:`sinslab.estimation.linear.propagate_covariance` with ``keep_gain``: compiled,
sequential scalar Joseph updates), every run filtered with those gains in one compiled loop
(:func:`sinslab.estimation.linear.fixed_gain_runs`). The reference, written out here, is
the recursion in numpy: covariance, gain and S by matrix products per step (vector Joseph
update), the runs' estimates stacked (``x @ Φᵀ``, ``ν @ Gᵀ``). Both draw the same numbers
and return the same outputs (error, σ, NEES, NIS); the largest difference of each, relative
to its largest value, is reported (the NEES moves most: the pseudo-inverse of a nearly
singular P).

Cases: ``small`` (2 states, a position measurement every third step, 60 steps, 400 runs:
the estimation tests' campaign) and ``ins`` (21 states, six rows every step, 600 steps,
64 runs: the size of a transfer-alignment filter). Per case the CPU seconds of each
(best of ``--repeat``, the two alternated) and their ratio, with the load average.

Run: ``.venv/bin/python benchmarks/linear_batch.py [--repeat 5] [--out FILE]``; results
printed and written to ``benchmarks/results/linear_batch.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent


def numpy_batch(seeds, Phi, Q, H, R, P0, n_steps, mask=None):
    """The task written with numpy (the reference): same draws, same outputs."""
    n, m, K, B = Phi.shape[0], H.shape[0], int(n_steps), len(seeds)
    mask = np.ones(K, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    P = P0.copy()
    Ps = np.empty((K + 1, n, n))
    Ps[0] = P
    gains = np.zeros((K, n, m))
    Sinv = np.zeros((K, m, m))
    for k in range(K):
        P = Phi @ P @ Phi.T + Q
        if mask[k]:
            Si = np.linalg.inv(H @ P @ H.T + R)
            G = P @ H.T @ Si
            A = np.eye(n) - G @ H
            P = A @ P @ A.T + G @ R @ G.T
            gains[k], Sinv[k] = G, Si
        P = 0.5 * (P + P.T)
        Ps[k + 1] = P
    Lp = np.linalg.cholesky(P0)
    x0, W, V = np.empty((B, n)), np.empty((B, K, n)), np.empty((B, K, m))
    for b, s in enumerate(seeds):
        rng = np.random.default_rng(s)
        x0[b] = Lp @ rng.standard_normal(n)
        W[b] = rng.multivariate_normal(np.zeros(n), Q, size=K, method="eigh")
        V[b] = rng.multivariate_normal(np.zeros(m), R, size=K)
    xt, xe = x0, np.zeros((B, n))
    err, nis = np.empty((B, K + 1, n)), np.zeros((B, K))
    err[:, 0] = xe - xt
    for k in range(K):
        xt = xt @ Phi.T + W[:, k]
        xe = xe @ Phi.T
        if mask[k]:
            nu = xt @ H.T + V[:, k] - xe @ H.T
            xe = xe + nu @ gains[k].T
            nis[:, k] = np.einsum("bi,ij,bj->b", nu, Sinv[k], nu)
        err[:, k + 1] = xe - xt
    nees = np.einsum("bti,tij,btj->bt", err, np.linalg.pinv(Ps, hermitian=True), err)
    sigma = np.broadcast_to(np.sqrt(np.diagonal(Ps, axis1=1, axis2=2)), (B, K + 1, n)).copy()
    return {"err": err, "sigma": sigma, "nees": nees, "nis": nis}


def _cases():
    from sinslab.estimation import kalman as kf

    F = np.array([[0.0, 1.0], [0.0, -0.05]])
    Phi2, Q2 = kf.discretize(F, np.diag([0.0, 0.02]), 1.0)
    small = dict(Phi=Phi2, Q=Q2, H=np.array([[1.0, 0.0]]), R=np.array([[0.5]]), P0=np.diag([4.0, 1.0]),
                 n_steps=60, mask=np.arange(60) % 3 == 0, runs=400)
    # 21 states: attitude, velocity (coupled through a specific force and the Earth rate),
    # installation and sensor states as random constants; six rows (velocity, attitude)
    rng = np.random.default_rng(3)
    n, T = 21, 0.1
    Fi = np.zeros((n, n))
    Fi[0:3, 0:3] = -np.array([[0, -7e-5, 4e-5], [7e-5, 0, -1e-5], [-4e-5, 1e-5, 0]])
    Fi[3:6, 0:3] = np.array([[0, -9.8, 0.3], [9.8, 0, -0.2], [-0.3, 0.2, 0]])
    Fi[0:3, 9:12] = -np.eye(3)
    Fi[3:6, 15:18] = np.eye(3)
    Fi[0:3, 12:15] = np.diag(rng.normal(0, 0.05, 3))
    Fi[3:6, 18:21] = np.diag(rng.normal(0, 5.0, 3))
    Phi21, Q21 = kf.discretize(Fi, np.diag(np.r_[[1e-12] * 3, [1e-8] * 3, [0.0] * 15]), T)
    H = np.zeros((6, n))
    H[0:3, 3:6] = np.eye(3)
    H[3:6, 0:3] = -np.eye(3)
    H[3:6, 6:9] = np.eye(3)
    sig0 = np.r_[[1e-2] * 3, [0.1] * 3, [1e-2] * 3, [1e-5] * 3, [1e-4] * 3, [1e-3] * 3, [1e-4] * 3]
    ins = dict(Phi=Phi21, Q=Q21, H=H, R=np.diag(np.r_[[1e-4] * 3, [1e-7] * 3]), P0=np.diag(sig0 ** 2),
               n_steps=600, mask=None, runs=64)
    return {"small": small, "ins": ins}


def _cpu(fn):
    c0 = time.process_time()
    out = fn()
    return out, time.process_time() - c0


def measure(repeat=5):
    from sinslab.estimation import montecarlo as mc

    out = {"load_1min_before": os.getloadavg()[0]}
    for name, c in _cases().items():
        kw = {k: c[k] for k in ("Phi", "Q", "H", "R", "P0", "n_steps", "mask")}
        seeds = list(np.random.SeedSequence(1).spawn(c["runs"]))
        mc.linear_batch(seeds[:2], **kw)                   # compile / load the kernels
        best = {"task": np.inf, "numpy": np.inf}
        for _ in range(repeat):                            # alternated, the best of each kept
            a, t = _cpu(lambda: mc.linear_batch(seeds, **kw))
            best["task"] = min(best["task"], t)
            b, t = _cpu(lambda: numpy_batch(seeds, **kw))
            best["numpy"] = min(best["numpy"], t)
        diff = {k: float(np.max(np.abs(a[k] - b[k])) / np.max(np.abs(b[k]))) for k in a}
        out[name] = dict(states=int(c["Phi"].shape[0]), rows=int(c["H"].shape[0]), steps=c["n_steps"],
                         runs=c["runs"], task_cpu_s=best["task"], numpy_cpu_s=best["numpy"],
                         numpy_over_task=best["numpy"] / best["task"], max_rel_diff=diff)
    out["load_1min_after"] = os.getloadavg()[0]
    return out


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--out", type=Path, default=HERE / "results" / "linear_batch.json")
    a = ap.parse_args(argv)
    out = measure(a.repeat)
    for k, v in out.items():
        print(f"{k:>18s}: {v}")
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
