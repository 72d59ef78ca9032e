"""Speed of the IMU table readers: CSV text against Parquet, same samples.

Run: ``.venv/bin/python benchmarks/readers.py [--rows N] [--repeat K] [--out FILE.json]``

A 100 Hz record of ``--rows`` samples (default 720 000: two hours) of rates in datasheet
units (``t[s], gx..gz[deg/s], ax..az[g]``) plus two extra columns a real log carries (a
temperature and an integer status word) is written once as CSV and once as Parquet; each
file is read ``--repeat`` times with :func:`sinslab.data.load_imu` (the whole path: header,
units, checks, mount, increments) and the best time is kept. The figure of merit is the
ratio CSV time / Parquet time measured in the same process (target: ≤ ~2).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from sinslab.data import load_imu  # noqa: E402

COLUMNS = ["t[s]", "gx[deg/s]", "gy[deg/s]", "gz[deg/s]", "ax[g]", "ay[g]", "az[g]",
           "temp[degC]", "status"]


def write_record(folder: Path, rows: int, seed: int = 0):
    """Write the same record as ``imu.csv`` and ``imu.parquet``; returns both paths."""
    import pandas as pd
    rng = np.random.default_rng(seed)
    t = 100.0 + 0.01 * np.arange(1, rows + 1)
    g = 0.2 * rng.standard_normal((rows, 3))
    a = np.array([0.0, 0.0, 1.0]) + 0.01 * rng.standard_normal((rows, 3))
    df = pd.DataFrame(np.column_stack([t, g, a, 25 + 0.1 * rng.standard_normal(rows)]),
                      columns=COLUMNS[:-1])
    df["status"] = rng.integers(0, 4, rows)
    csv, pq = folder / "imu.csv", folder / "imu.parquet"
    df.to_csv(csv, index=False, float_format="%.9g")
    df.to_parquet(pq, index=False)
    return csv, pq


def _best(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=720_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out", type=Path, default=None, help="write the figures as JSON")
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as d:
        csv, pq = write_record(Path(d), a.rows)
        r_csv = load_imu(csv)
        r_pq = load_imu(pq)
        same = bool(np.allclose(r_csv.imu.dtheta, r_pq.imu.dtheta, rtol=1e-7, atol=1e-15)
                    and np.allclose(r_csv.imu.dv, r_pq.imu.dv, rtol=1e-7, atol=1e-15))
        t_csv = _best(lambda: load_imu(csv), a.repeat)
        t_pq = _best(lambda: load_imu(pq), a.repeat)
        mb = csv.stat().st_size / 1e6
    res = {"rows": a.rows, "csv_mb": mb, "csv_s": t_csv, "parquet_s": t_pq,
           "csv_over_parquet": t_csv / t_pq, "same_samples": same}
    print(f"{a.rows} rows ({mb:.0f} MB of CSV): CSV {t_csv:.3f} s, Parquet {t_pq:.3f} s, "
          f"ratio {t_csv / t_pq:.2f}; same samples (to the CSV's 9 digits): {same}")
    if a.out:
        a.out.write_text(json.dumps(res, indent=1))
    return res


if __name__ == "__main__":
    main(sys.argv[1:])
