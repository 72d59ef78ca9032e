"""Raw GNSS in the factor graph beside the tightly coupled filter, on the walk.

Run: ``.venv/bin/python benchmarks/graph_raw.py [--out FILE]``;
``.venv/bin/python benchmarks/record.py graph_raw`` stores its figures in
docs/benchmarks.json, the record docs/methods/graph.md quotes them from. Needs
``sinslab[graph]`` (gtsam) and the shared rtklib-walk data.

rtklib-walk (134 s, GPS + Galileo + BeiDou): the tightly coupled filter and its RTS
smoother (``sinslab navigate --gnss-raw --smooth``) and, on the same inputs, the raw GNSS
graph (batch and a 5 s fixed-lag window), in one process: horizontal distance from the RTK
solution (its fixed and float points, less the RTK solution's constant offset from the
absolute single-point positions: its base is not surveyed), the graph against the smoother
(position in σ, attitude, clock), the post-fit residuals, CPU time of each estimator, peak
memory of the process.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / ".." / "shared" / "data"


def _att_rms(t, nav, t_ref, nav_ref):
    """benchmarks/graph.py's attitude RMS against a reference solution [deg]."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("bench_graph", HERE / "graph.py")
    G = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(G)
    return G._att_rms(t, nav, t_ref, nav_ref)


WALK = ["--imu", "{W}/imu_1730.csv", "--format", "rtklib-imu", "--mount", "rpy:180,0,-90", "--frame", "frd",
        "--gnss-raw", "{W}/gnss_1730.ubx", "--init", "course_speed=1 m/s,course_spread=10 deg"]


def _ne_against(t, lat_s, lon_s, ref, q):
    """North, east [m] of a solution (antenna = IMU point: no lever arm on the walk) minus
    the reference fixes of quality ``q`` inside its span."""
    m = (ref.quality == q) & (ref.t >= t[0]) & (ref.t <= t[-1])
    lat = np.interp(ref.t[m], t, lat_s)
    lon = np.interp(ref.t[m], t, lon_s)
    return np.column_stack([(lat - ref.lat[m]) * 6378137.0, (lon - ref.lon[m]) * 6378137.0 * np.cos(lat)])


def _rtk_offset(raw, ref):
    """The RTK solution's constant offset [m] (north, east) from absolute positions: its
    base station's coordinates are not surveyed, so the single-point solution (absolute,
    independent of every estimator compared) sits metres from it everywhere alike; the mean
    of single point − RTK over the fixed points."""
    sp = raw.single_point()
    ok = np.isfinite(sp.lat)
    return np.mean(_ne_against(sp.t[ok], sp.lat[ok], sp.lon[ok], ref, 1), 0)


def walk(out_json):
    """Child process: the walk's raw observations through ``sinslab navigate --gnss-raw
    --smooth`` (the tightly coupled filter and its RTS smoother) and, on the same inputs,
    the raw GNSS graph (batch and a 5 s fixed-lag window): horizontal distance from the
    RTK solution (fixed, float), the graph against the smoother in units of its σ, the
    clock against the smoother's, the post-fit residuals, CPU time of each estimator."""
    import tempfile

    from sinslab import cli
    from sinslab.data import load_fixes
    from sinslab.fusion.estimators import KalmanEstimator
    from sinslab.fusion.graph import GraphSpec
    from sinslab.fusion.graph.raw import graph_navigate_raw
    got = {}
    orig = KalmanEstimator.estimate

    def estimate(self, e):
        c = time.process_time()
        out = orig(self, e)
        got.update(cpu=time.process_time() - c, e=e, out=out)
        return out
    KalmanEstimator.estimate = estimate
    W = str((DATA / "rtklib-walk").resolve())
    with tempfile.TemporaryDirectory() as tmp:
        try:
            cli.app(["-q", "navigate", *[a.replace("{W}", W) for a in WALK], "--smooth", "--out", str(Path(tmp) / "run")],
                    prog_name="sinslab", standalone_mode=False)
        except SystemExit:
            pass
    e, (r, smoothed, _) = got["e"], got["out"]
    plan = e.plans[0]
    raw, lay = plan.facts["raw"], e.model.layout
    ref = load_fixes(str(DATA / "rtklib-walk" / "gnss_1730_sf.pos"))[0]
    sl = lay.find("receiver_clock")
    res = {"systems": "".join(raw.systems), "filter_cpu_s": got["cpu"]}
    clock_s = raw.clock_estimate(smoothed.t, smoothed.x, lay, plan.facts["nominal"])
    sols = {"filter": r.nav[0], "rts": smoothed.nav}
    for name, spec in (("graph_fixed_lag", GraphSpec("fixed-lag", 5.0)), ("graph_batch", GraphSpec("batch"))):
        c = time.process_time()
        g = graph_navigate_raw(e.imu, e.start.nav_state, raw, [m for _, m in plan.measurements], e.P0, e.model,
                               ins=e.ins, grid=e.grid, spec=spec)
        row = {"cpu_s": time.process_time() - c, "keyframes": int(g.key_t.size), "iterations": g.iterations}
        for kind, (_, _, v, sd) in g.raw["residuals"].items():
            row[f"{kind}_rows"] = int(v.size)
            row[f"{kind}_postfit_rms"] = float(np.sqrt(np.mean(v ** 2)))
            row[f"{kind}_postfit_chi2_per_row"] = float(np.mean((v / sd) ** 2))
        dn = (g.nav[:, 7] - smoothed.nav[:, 7]) / smoothed.sigma[:, lay.slice("dp")][:, 0]
        de = (g.nav[:, 8] - smoothed.nav[:, 8]) / smoothed.sigma[:, lay.slice("dp")][:, 1]
        row["vs_rts_max_sigma"] = float(np.max(np.hypot(dn, de)))
        phi = _att_rms(g.t, g.nav, smoothed.t, smoothed.nav)
        row["att_vs_rts_rms_deg"] = phi
        dc = g.raw["clock"] - clock_s
        row["clock_vs_rts_rms"] = np.sqrt(np.mean(dc ** 2, 0)).tolist()      # bias, drift, ISBs
        row["clock_sigma_median"] = np.median(g.raw["clock_sigma"], 0).tolist()
        res[name] = row
        sols[name] = g.nav
    off = _rtk_offset(raw, ref)
    res["rtk_offset_ne_m"] = off.tolist()
    for name, nav in sols.items():
        res.setdefault(name, {})
        for q, what in ((1, "fixed"), (2, "float")):
            d = _ne_against(r.t, nav[:, 7], nav[:, 8], ref, q) - off
            res[name][f"hz_vs_rtk_{what}_rms_m"] = float(np.sqrt(np.mean(np.sum(d ** 2, 1))))
            res[name][f"rtk_{what}_points"] = int(d.shape[0])
    res["rts"]["cpu_s"] = None
    res["filter_and_rts_cpu_s"] = got["cpu"]
    res["rts_clock_sigma_median"] = np.median(smoothed.sigma[:, sl], 0).tolist()
    res["peak_rss_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    Path(out_json).write_text(json.dumps(res))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    import tempfile
    with tempfile.TemporaryDirectory() as tmp:
        f = Path(tmp) / "walk.json"
        walk(f)
        res = {"walk": json.loads(f.read_text())}
    text = json.dumps(res, indent=1)
    if a.out:
        Path(a.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
