"""Cost of writing a run folder against the computation (target: at most 1 s + 20 % of it).

Run: ``.venv/bin/python benchmarks/run_folder.py [NAME ...] [--full] [--json FILE]``

For each experiment (``--quick`` scale unless ``--full``) the computation runs once; its
figures are then written twice in the same process, from identical copies:

* reference — the previous writer: ``savefig(..., bbox_inches="tight")`` for PNG and for
  SVG, full-rate lines (every format lays the figure out and draws it twice);
* current — :func:`sinslab.app.publish.write_figures`: lines thinned to the pixel columns
  (min/max), the axes laid out from one measurement, one draw (the SVG written from the
  PNG draw's primitives), the figures drawn by forked workers.

Printed per experiment: computation, series, figures (reference and current, ratio),
report, and whether writing stays within the budget of 1 s + 20 % of the computation.
"""
from __future__ import annotations

import argparse
import io
import json
import os
import pickle
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("SINSLAB_QUIET", "1")
os.environ.setdefault("MPLBACKEND", "Agg")


def _reference(figures) -> None:
    for f in figures:
        for fmt in ("png", "svg"):
            f.fig.savefig(io.BytesIO(), format=fmt, dpi=110, bbox_inches="tight")


def measure(name: str, quick: bool = True) -> dict:
    import sinslab.experiments as E
    from sinslab.app.config import resolve
    from sinslab.app.outputs import RunDir
    from sinslab.app.publish import complete_timed, write_figures
    from sinslab.experiments.base import RunContext

    exp = E.get(name)
    cfg = resolve(exp.config, quick=exp.quick if quick else None)
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        res = exp.run(cfg, RunContext(name=name, out=Path(d), seed=cfg.seed, runs=cfg.runs,
                                      quick=quick, scheduler="sync"))
        compute = time.perf_counter() - t0
        copies = pickle.loads(pickle.dumps(res.figures))
        rd = RunDir(Path(d) / "run", name).prepare()
        t0 = time.perf_counter()
        for k, table in res.series.items():
            rd.write_table(k, table)
        for t in res.tables:
            rd.write_table(f"table_{t.name}", t.data, t.caption)
        series = time.perf_counter() - t0
        t0 = time.perf_counter()
        _reference(copies)
        ref = time.perf_counter() - t0
        t0 = time.perf_counter()
        write_figures(rd, res.figures)
        cur = time.perf_counter() - t0
        summary = {"experiment": name, "metrics": res.metrics, "claims": [c.as_dict() for c in res.claims],
                   "figures": rd.figure_files, "series": rd.series_info, "tables": [],
                   "notes": res.notes, "timing": {}}
        complete_timed(rd, summary)
        report = summary["timing"]["report_s"]
    out = {"experiment": name, "figures": len(res.figures), "compute_s": compute, "series_s": series,
           "figures_reference_s": ref, "figures_s": cur, "report_s": report,
           "figure_speedup": ref / cur if cur > 0 else float("nan")}
    out["writing_s"] = series + cur + report
    out["budget_s"] = 1.0 + 0.2 * compute
    out["within_budget"] = out["writing_s"] <= out["budget_s"]
    return out


def main(argv=None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help="experiments (default: all)")
    ap.add_argument("--full", action="store_true", help="full-scale runs instead of --quick")
    ap.add_argument("--json", help="write the results here")
    a = ap.parse_args(argv)
    import sinslab.experiments as E

    rows = [measure(n, quick=not a.full) for n in (a.names or list(E.registry()))]
    print(f"{'experiment':<22s} {'figs':>4s} {'compute':>8s} {'series':>7s} {'fig ref':>8s} "
          f"{'fig now':>8s} {'ratio':>6s} {'report':>7s} {'write':>6s} {'budget':>6s}")
    for r in rows:
        print(f"{r['experiment']:<22s} {r['figures']:4d} {r['compute_s']:8.2f} {r['series_s']:7.2f} "
              f"{r['figures_reference_s']:8.2f} {r['figures_s']:8.2f} {r['figure_speedup']:6.2f} "
              f"{r['report_s']:7.3f} {r['writing_s']:6.2f} {r['budget_s']:6.2f}"
              f"{'' if r['within_budget'] else '  over'}")
    if a.json:
        Path(a.json).write_text(json.dumps(rows, indent=2))
    return rows


if __name__ == "__main__":
    main()
    sys.exit(0)
