"""Speed benchmark of the transfer-alignment Monte Carlo (paper 002).

Target: a 1000-run campaign of one method (60 s of wing rock, 100 Hz slave IMU, 10 Hz
filter, 21 states) in under 60 s on the 2-core development machine. The campaign runs
vectorised across the runs of each Dask task (:func:`sinslab.methods.transfer.batch_filter`)
on a local Dask cluster; the reference, measured in the same process, is the same code run
one run at a time (a batch of one run, serially) — the ratio shows what the vectorisation
and distribution buy. The EKF form (per-run covariance and H) is measured the same way: the
runs of one task stacked against one run at a time, serially, with the largest difference
of their estimation errors.

Run: ``.venv/bin/python benchmarks/transfer.py [--runs 1000] [--quick] [--out FILE]``;
results printed and written to ``benchmarks/results/transfer.json``.
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
TARGET_S = 60.0


def main(argv=None) -> dict:
    from sinslab.app.config import resolve
    from sinslab.estimation import montecarlo as mc
    from sinslab.experiments import transfer_alignment as ta

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--method", default="optimal", choices=ta._M)
    ap.add_argument("--single", type=int, default=10, help="runs of the one-at-a-time reference")
    ap.add_argument("--quick", action="store_true", help="100 runs, 3 reference runs")
    ap.add_argument("--scheduler", default=None, help="Dask scheduler address (default: local cluster)")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "transfer.json")
    a = ap.parse_args(argv)
    runs, single = (100, 3) if a.quick else (a.runs, a.single)
    cfg = resolve(ta.Config)
    t0 = time.perf_counter()
    case = ta._case(cfg, cfg.installation.large, cfg.scenario.heading)
    setup_s = time.perf_counter() - t0
    var = [(f"{a.method}_large", "large", a.method, a.method == "optimal", False)]
    kw = dict(p=ta._params(cfg), cases={"large": case}, record_every=5, ekf_runs=0, variants=var)
    ta._batch(list(np.random.SeedSequence(1).spawn(2)), **kw)            # warm-up
    seeds = np.random.SeedSequence(2).spawn(single)
    t0 = time.perf_counter()
    for s in seeds:
        ta._batch([s], **kw)
    single_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = mc.run_campaign(ta._batch, runs, 0, batch=max(1, runs // 8), scheduler=a.scheduler, kwargs=kw,
                          progress=False)
    campaign_s = time.perf_counter() - t0
    err = res[f"err_{a.method}_large"]
    # EKF form (per-run covariance, H re-linearised at each run's installation estimate): the
    # runs of one task stacked vs the same filter one run at a time
    ekf_runs = 10 if a.quick else 50
    kind = "kain" if a.method == "optimal" else a.method
    kw_e = dict(kw, ekf_runs=ekf_runs, variants=[(f"{kind}_large_ekf", "large", kind, False, True)])
    seeds = np.random.SeedSequence(3).spawn(ekf_runs)
    t0 = time.perf_counter()
    stacked = ta._batch(seeds, **kw_e)[f"err_{kind}_large_ekf"]
    ekf_stacked_s = time.perf_counter() - t0
    n_one = min(ekf_runs, 3 if a.quick else 10)
    t0 = time.perf_counter()
    one = [ta._batch([s], **kw_e)[f"err_{kind}_large_ekf"] for s in seeds[:n_one]]
    ekf_one_s = time.perf_counter() - t0
    ekf_same = float(np.max(np.abs(np.concatenate(one) - stacked[:n_one])))
    out = dict(method=a.method, runs=runs, steps=int(case["Phi"].shape[0]), setup_s=setup_s,
               campaign_s=campaign_s, campaign_runs_per_s=runs / campaign_s,
               single_runs_per_s=single / single_s, speedup=(runs / campaign_s) / (single / single_s),
               target_s=TARGET_S, meets_target=campaign_s < TARGET_S,
               ekf_kind=kind, ekf_runs=ekf_runs, ekf_stacked_runs_per_s=ekf_runs / ekf_stacked_s,
               ekf_one_at_a_time_runs_per_s=n_one / ekf_one_s,
               ekf_speedup=(ekf_runs / ekf_stacked_s) / (n_one / ekf_one_s),
               ekf_max_abs_diff_rad=ekf_same,
               rms_end_arcmin=(np.sqrt(np.mean(err[:, -1] ** 2, 0)) / (np.pi / 180 / 60)).tolist(),
               machine=platform.platform(), python=platform.python_version())
    for k, v in out.items():
        print(f"{k:>22s}: {v}")
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
