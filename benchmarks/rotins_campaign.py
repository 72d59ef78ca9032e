"""What a worker of rotation-evaluation's linear campaign no longer does (paper 001).

Run: ``.venv/bin/python benchmarks/rotins_campaign.py [--hours H] [--seeds B]``

The campaign's fixed part — the schedule's transition table with the noise split by source
and INS #1's input matrices (:func:`schedule_transitions`), the noise square roots and the
nominal filter's gains (:func:`sinslab.methods.rotins.campaign_setup`) — is made once in the main process, which
has the table anyway for the joint filters, and sent to every worker once. Before, every
worker rebuilt the table and the gains from the scenario. In one process, the same run:

- ``rebuild_s``: the table and the setup as a worker built them (what each worker saves);
- ``ship_s``: pickling and unpickling the setup, the part of sending it that costs the
  main process and a worker CPU (the transfer itself is a local copy);
- ``batch_s``: one task's step recursion over ``--seeds`` seeds, for scale;
- the ratio rebuild / ship.
"""
from __future__ import annotations

import argparse
import json
import os
import pickle
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402


def measure(hours=144.0, seeds=10):
    from sinslab.app.config import resolve
    from sinslab.experiments import get
    from sinslab.experiments import rotation_evaluation as R
    from sinslab.methods import rotins

    sets = [f"scenario.duration={hours} h"]
    if hours < 24:
        sets += [f"evaluation.start={hours / 4} h", f"evaluation.window={hours / 4} h"]
    cfg = resolve(get("rotation-evaluation").config, sets=sets)
    lat, lon = float(cfg.scenario.latitude), float(cfg.scenario.longitude)
    model, P0, sig = R.joint_filter_setup(cfg)
    m1, mk = R.mounts(cfg)
    _, _, me, n_kf, _ = R._grid(cfg)
    t0 = time.perf_counter()
    tables = R.schedule_transitions(m1, mk, lat, lon, model, float(cfg.filter.model_dt), me, n_kf,
                                    rotins.NOISE_GROUPS, inputs=True)
    spec = R.campaign_spec(cfg, model, P0, sig, tables)
    setup = rotins.campaign_setup(spec)
    rebuild = time.perf_counter() - t0
    t0 = time.perf_counter()
    blob = pickle.dumps(setup, protocol=pickle.HIGHEST_PROTOCOL)
    pickle.loads(blob)
    ship = time.perf_counter() - t0
    spec = {k: v for k, v in spec.items() if k not in ("Phi", "Q", "Gam", "P0")}
    t0 = time.perf_counter()
    rotins.campaign_batch(list(np.random.SeedSequence(0).spawn(seeds)), spec, setup)
    batch = time.perf_counter() - t0
    return dict(hours=hours, seeds=seeds, table_entries=int(tables[0].shape[0]), setup_mb=len(blob) / 1e6,
                rebuild_s=rebuild, ship_s=ship, batch_s=batch, rebuild_over_ship=rebuild / ship,
                load_avg=os.getloadavg())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=144.0)
    ap.add_argument("--seeds", type=int, default=10)
    a = ap.parse_args(argv)
    print(json.dumps(measure(a.hours, a.seeds), indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
