"""A large double-star campaign on an external Dask scheduler: the client's memory.

A ``dask scheduler`` and ``dask worker`` processes are started on this machine as
subprocesses (as a user would start them on a cluster) and the campaign is sent to the
scheduler's address, its statistics summed on the workers (``run_campaign(reduce=...)``).

Two measurements in one run:

1. ``--runs`` real runs of paper 003's campaign (three filters per run on 1200 s of
   100 Hz IMU): wall time, runs per second, the client's peak resident memory (ru_maxrss)
   and what gathering the same runs would have held (the bytes of one run's outputs times
   the runs).
2. The same campaign machinery at ``--scale`` runs (default 100 000) with a stand-in task
   function that returns arrays of exactly the real task's shapes from the runs' own
   generators, at no navigation cost: the client then holds everything that grows with the
   number of runs (the runs' seed sequences, the tasks and their futures, the tree nodes
   of the sums) as in the real campaign, so its peak memory at that scale is measured, not
   extrapolated. The real campaign at that scale would take (scale / runs) times the wall
   time of measurement 1; the task's outputs stay on the workers either way.

Run: ``.venv/bin/python benchmarks/campaign_scale.py [--runs 400] [--scale 100000] [--workers 2]``;
results printed and written to ``benchmarks/results/campaign_scale.json``.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent


def _rss_peak_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _rss_now_mb():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


class Cluster:
    """``dask scheduler`` and ``dask worker`` as subprocesses of this one (1 thread per
    worker process, the workers' allocator settings of the local cluster)."""

    def __init__(self, workers):
        from sinslab.estimation import montecarlo as mc

        self.dir = tempfile.mkdtemp(prefix="sinslab-dask-")
        self.file = os.path.join(self.dir, "scheduler.json")
        dask = str(Path(sys.executable).with_name("dask"))
        env = {**os.environ, **{k: str(v) for k, v in mc.WORKER_ENVIRON.items()}}
        log = open(os.path.join(self.dir, "dask.log"), "w")
        self.procs = [subprocess.Popen([dask, "scheduler", "--scheduler-file", self.file, "--port", "0",
                                        "--dashboard-address", "127.0.0.1:0", "--host", "127.0.0.1"],
                                       stdout=log, stderr=log, env=env)]
        t0 = time.time()
        while not os.path.exists(self.file):
            if time.time() - t0 > 60:
                raise RuntimeError("the Dask scheduler did not start")
            time.sleep(0.2)
        time.sleep(0.5)
        with open(self.file) as fh:
            self.address = json.load(fh)["address"]
        self.procs.append(subprocess.Popen([dask, "worker", "--scheduler-file", self.file, "--nworkers", str(workers),
                                            "--nthreads", "1", "--memory-limit", "0", "--no-dashboard"],
                                           stdout=log, stderr=log, env=env))
        from distributed import Client
        with Client(self.address, timeout="30s") as c:
            c.wait_for_workers(workers, timeout=120)

    def close(self):
        for p in reversed(self.procs):
            p.terminate()
        for p in reversed(self.procs):
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


def stand_in(seeds, shapes):
    """The real task's output shapes, drawn from the runs' own generators (no navigation)."""
    out = {}
    for b, s in enumerate(seeds):
        rng = np.random.default_rng(s)
        for k, shp in shapes.items():
            out.setdefault(k, np.empty((len(seeds),) + shp))[b] = rng.standard_normal(shp)
    return out


def main(argv=None):
    from sinslab.app.config import resolve
    from sinslab.estimation import montecarlo as mc
    from sinslab.experiments import double_star as dsx

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=400, help="real double-star runs")
    ap.add_argument("--scale", type=int, default=100_000, help="runs of the stand-in campaign")
    ap.add_argument("--workers", type=int, default=2, help="worker processes")
    ap.add_argument("--out", default=str(HERE / "results" / "campaign_scale.json"))
    a = ap.parse_args(argv)

    S = dsx._setup(resolve(dsx.Config))
    one = dsx._batch(mc.spawn_seeds(1, 1), S)
    run_bytes = sum(v.nbytes for v in one.values())
    shapes = {k: v.shape[1:] for k, v in one.items()}
    rss0 = _rss_now_mb()
    res = {"workers": a.workers, "cpus": os.cpu_count(), "load_1min": os.getloadavg()[0],
           "client_rss_before_mb": rss0, "one_run_output_bytes": run_bytes}
    cl = Cluster(a.workers)
    try:
        t0 = time.perf_counter()
        sums = mc.run_campaign(dsx._batch, a.runs, 0, scheduler=cl.address, kwargs=dict(S=S), reduce=dsx._squares,
                               progress=False)
        wall = time.perf_counter() - t0
        res.update(real_runs=a.runs, real_wall_s=wall, real_runs_per_s=a.runs / wall,
                   real_client_peak_rss_mb=_rss_peak_mb(), real_gather_would_hold_mb=a.runs * run_bytes / 2 ** 20,
                   real_sums_bytes=sum(v.nbytes for v in sums.values()),
                   real_fixes_per_run=float(sums["nfix"] / a.runs))
        t0 = time.perf_counter()
        mc.run_campaign(stand_in, a.scale, 0, scheduler=cl.address, kwargs=dict(shapes=shapes), reduce=dsx._squares,
                        progress=False)
        res.update(scale_runs=a.scale, scale_wall_s=time.perf_counter() - t0,
                   scale_client_peak_rss_mb=_rss_peak_mb(),
                   scale_gather_would_hold_mb=a.scale * run_bytes / 2 ** 20,
                   scale_real_wall_estimate_h=a.scale / res["real_runs_per_s"] / 3600)
    finally:
        cl.close()
    print(f"external scheduler, {a.workers} workers (load {res['load_1min']:.1f} on {res['cpus']} CPUs):")
    print(f"  {a.runs} real double-star runs: {res['real_wall_s']:.1f} s ({res['real_runs_per_s']:.2f} runs/s), "
          f"client peak RSS {res['real_client_peak_rss_mb']:.0f} MB (before the campaign {rss0:.0f} MB); "
          f"gathering them would hold {res['real_gather_would_hold_mb']:.0f} MB")
    print(f"  {a.scale} runs, stand-in task of the same output shapes: {res['scale_wall_s']:.1f} s, client peak RSS "
          f"{res['scale_client_peak_rss_mb']:.0f} MB; gathering would hold {res['scale_gather_would_hold_mb'] / 1024:.1f} GB; "
          f"the real runs would take ~{res['scale_real_wall_estimate_h']:.1f} h here")
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    with open(a.out, "w") as fh:
        json.dump(res, fh, indent=2)
    return res


if __name__ == "__main__":
    sys.exit(0 if main()["scale_client_peak_rss_mb"] < 1024 else 1)
