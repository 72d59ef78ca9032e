"""The factor-graph estimator beside the filter: the frame difference, robust weighting on
an urban drive, and the real drives (outage ends, attitude, CPU time, peak memory).

Run: ``.venv/bin/python benchmarks/graph.py [--quick] [--out FILE]``;
``.venv/bin/python benchmarks/record.py graph`` stores its figures in docs/benchmarks.json,
the record docs/methods/graph.md quotes them from. Needs ``sinslab[graph]`` (gtsam).

1. Frame (error-free IMU of the smoother benchmark's 201 s car drive): free-inertial
   position error after 10/60/200 s of sinslab's strapdown and of GTSAM's preintegration
   with the frame's origin 0, 1, 10, 100 km away, as usually set up (constant gravity of
   the origin, rates = increments / dt) and with the estimator's compensations added one by
   one (the rotation term of the increments, normal gravity per 1 s interval, GTSAM's
   centrifugal term removed), all started from the truth; then exact fixes (1 Hz, 60 s
   outage) through the filter, the RTS smoother and the batch graph (with its compensations,
   and with GTSAM's constant gravity): largest position and attitude error.
2. Urban drive (the same car, 1 Hz fixes of σ 1 m, seeds 1..N): 10 % of the fixes
   with a multipath jump of 10–40 m horizontal, and two 15 s stretches biased by 8 m
   north; the filter (no weighting, Chang, Huber, IGG-III) and the batch graph (no
   weighting, Huber, Tukey for IGG-III): horizontal RMS and largest error, 3-D position
   NEES mean against the truth over the whole record.
3. Real drives (rtklib-drive, 15 s outages every 60 s from 40 s; onavdata n380, 30 s every
   120 s from 60 s; fixes only, the navigate defaults): forward filter, RTS smoother,
   fixed-lag graph (5 s, and a window longer than the outages: 20 s, 40 s) and batch graph
   on the inputs the filter takes, each in its own
   process: horizontal error at each outage end against the withheld fix, attitude against
   the RTS smoother (RMS, degrees), CPU time of the estimator and peak resident memory of
   the process (reading and start included, the same for all four).
Raw GNSS in the graph on the walk: ``benchmarks/graph_raw.py``.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / ".." / "shared" / "data"


def _bench_smoother():
    import importlib.util
    spec = importlib.util.spec_from_file_location("bench_smoother", HERE / "smoother.py")
    B = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(B)
    return B


# ---------------------------------------------------------------------- 1. frame
#: GTSAM's integration as usually set up, then with each of the estimator's three
#: compensations added: (gravity, centrifugal term removed, rotation term)
VARIANTS = {"stock": ("origin", False, False), "rotation": ("origin", False, True),
            "gravity": ("local", False, True), "sinslab": ("local", True, True)}


def _free_graph(gtsam, g, frame, t_end, variant, step=1.0):
    """GTSAM's free integration of the error-free IMU from the truth to ``t_end``."""
    from sinslab.core.records import NavState
    from sinslab.fusion.graph.build import Segments, integrate
    from sinslab.fusion.graph.translate import GraphImuModel
    from sinslab.nav import errstate as es
    from sinslab.nav import strapdown as sd
    gravity, centrifugal, rot = VARIANTS[variant]
    tru = g.truth
    m = GraphImuModel.from_error_model(es.ErrorModel("full", [es.gyro_bias(), es.accel_bias()],
                                                     gyro_arw=1e-6, accel_vrw=1e-6))
    row0 = sd.initial_state_array(NavState(tru.lat[0], tru.lon[0], tru.h[0], tru.vel[0], tru.att[0], tru.t[0]))[:10]
    Rwb, v, p = (a[0] for a in frame.rows_to_w(row0))
    nav = gtsam.NavState(gtsam.Pose3(gtsam.Rot3(Rwb), p), v)
    b = gtsam.imuBias.ConstantBias()
    seg = Segments(g.imu, 0, tru.t[0], rotation_term=rot)
    t = tru.t[0]
    while t < t_end - 1e-9:
        t1 = min(t + step, t_end)
        at = nav.position() if gravity == "local" else None
        pim, _ = integrate(gtsam, m.params(frame, at, centrifugal), seg, t, t1, b)
        nav = pim.predict(nav, b)
        t = t1
    return frame.rows_from_w(nav.pose().rotation().matrix(), nav.velocity(), nav.position())[0]


def _pos_err(row, tru, k):
    from sinslab.core import earth as E
    rm, rn = (float(x) for x in E.radii(tru.lat[k], tru.h[k]))
    return float(math.sqrt(((row[7] - tru.lat[k]) * rm) ** 2 + ((row[8] - tru.lon[k]) * rn * math.cos(tru.lat[k])) ** 2
                           + (row[9] - tru.h[k]) ** 2))


def frame_difference():
    import gtsam

    from sinslab.core.records import NavState
    from sinslab.fusion.graph.frame import LocalFrame
    from sinslab.nav import strapdown as sd
    B = _bench_smoother()
    g = B._trajectory()
    tru = g.truth
    out = {"durations_s": [10.0, 60.0, 200.0], "origin_km": [0.0, 1.0, 10.0, 100.0]}
    init = NavState(tru.lat[0], tru.lon[0], tru.h[0], tru.vel[0], tru.att[0], tru.t[0])
    nav = sd.navigate(g.imu, init, nsub=2)
    ks = [int(round(T / 0.01)) for T in out["durations_s"]]
    kn = [int(np.argmin(np.abs(nav.t - tru.t[k]))) for k in ks]
    out["sinslab_m"] = [_pos_err(np.r_[np.zeros(7), nav.lat[j], nav.lon[j], nav.h[j]], tru, k) for j, k in zip(kn, ks)]
    out["distance_travelled_km"] = [float(np.sum(np.linalg.norm(tru.vel[1:k + 1], axis=1)) * 0.01 / 1e3) for k in ks]
    rn = 6.38e6
    for variant in VARIANTS:
        rows = []
        for d in out["origin_km"]:
            # the origin d km west of the start, along the parallel
            fr = LocalFrame(tru.lat[0], tru.lon[0] - d * 1e3 / (rn * math.cos(tru.lat[0])), tru.h[0])
            rows.append([_pos_err(_free_graph(gtsam, g, fr, tru.t[0] + T, variant), tru, k)
                         for T, k in zip(out["durations_s"], ks)])
        out[f"gtsam_{variant}_m"] = rows
    out.update(_exact_fixes(B, g))
    return out


def _exact_fixes(B, g):
    """Error-free IMU and exact fixes through the filter, the RTS smoother and the graph."""
    from sinslab.core import attitude as A
    from sinslab.core.records import NavState
    from sinslab.fusion.graph import GraphSpec, graph_navigate
    from sinslab.fusion.loosely_coupled import loosely_coupled
    from sinslab.fusion.smoothing import History, smooth
    from sinslab.fusion.spec import FilterGrid, FixSpec
    from sinslab.nav import errstate as es
    tru = g.truth
    t = np.arange(tru.t[0] + 1.0, tru.t[-1] - 1, 1.0)
    t = t[~((t >= B.OUTAGE[0]) & (t < B.OUTAGE[1]))]
    i = np.rint((t - tru.t[0]) / 0.01).astype(int)
    fx = FixSpec(t, np.stack([tru.lat[i], tru.lon[i], tru.h[i]], -1), [0.01, 0.01, 0.01], vel=tru.vel[i], vel_sigma=0.001)
    m = es.ErrorModel("full", [es.gyro_bias(rrw=1e-7), es.accel_bias(arw=1e-6)], gyro_arw=1e-6, accel_vrw=1e-5)
    sd0 = np.r_[[1e-4] * 3, [0.01] * 3, [1e-8, 1e-8, 0.01], [1e-6] * 3, [1e-4] * 3]
    init = NavState(tru.lat[0], tru.lon[0], tru.h[0], tru.vel[0], tru.att[0], tru.t[0])
    grid = FilterGrid(0.02)
    r = loosely_coupled(g.imu, init, fx, np.diag(sd0 ** 2), m, grid=grid, history=History(0.1), progress=False)
    s = smooth(r)
    k = np.rint((r.t - tru.t[0]) / 0.01).astype(int)
    res = {}
    sols = {"filter": r.nav, "rts": s.nav}
    for grav in ("local", "origin"):
        sols[f"graph_{grav}"] = graph_navigate(g.imu, init, fx, np.diag(sd0 ** 2), m, grid=grid,
                                               spec=GraphSpec("batch", gravity=grav)).nav
    from sinslab.core import earth as E
    rm, rn = E.radii(tru.lat[k], tru.h[k])
    for name, nav in sols.items():
        dp = np.column_stack([(nav[:, 7] - tru.lat[k]) * rm, (nav[:, 8] - tru.lon[k]) * rn * np.cos(tru.lat[k]),
                              nav[:, 9] - tru.h[k]])
        phi = A.misalignment(A.euler_to_dcm(tru.att[k]), A.quat_to_dcm(nav[:, :4]))
        res[f"exact_{name}_pos_max_m"] = float(np.max(np.linalg.norm(dp, axis=1)))
        res[f"exact_{name}_att_max_deg"] = float(np.degrees(np.max(np.linalg.norm(phi, axis=1))))
    return res


# ---------------------------------------------------------------------- 2. urban drive
def _urban_fixes(B, seed):
    """1 Hz fixes of the smoother benchmark's car with multipath jumps and biased stretches;
    returns ``(inputs, FixSpec kwargs)``."""
    from sinslab.core.earth import radii
    d = B.drive_inputs(seed, outage=None)
    pf, vf = d["measurements"][0].parts
    rng = np.random.default_rng(1000 + seed)
    t = pf.t_valid
    J = t.size
    err = np.zeros((J, 3))
    jump = rng.random(J) < 0.10
    ang = rng.uniform(0, 2 * np.pi, J)
    mag = rng.uniform(10, 40, J)
    err[jump, 0] = mag[jump] * np.cos(ang[jump])
    err[jump, 1] = mag[jump] * np.sin(ang[jump])
    for s in (60.0, 140.0):
        err[(t >= s) & (t < s + 15), 0] += 8.0            # north
    rm, rn = radii(pf.pos[:, 0], pf.pos[:, 2])
    pos = pf.pos.copy()
    pos[:, 0] += err[:, 0] / rm
    pos[:, 1] += err[:, 1] / (rn * np.cos(pf.pos[:, 0]))
    return d, dict(t=t, pos=pos, sigma=[1.0, 1.0, 2.0], vel=vf.vel, vel_sigma=0.05)


def _scores(B, nav, sig, lay):
    from sinslab.core.earth import radii
    tru = B._trajectory().truth
    t = np.arange(nav.shape[0]) * 0.02 + tru.t[0]
    k = np.rint((t - tru.t[0]) / 0.01).astype(int)
    rm, rn = radii(tru.lat[k], tru.h[k])
    e = np.column_stack([(nav[:, 7] - tru.lat[k]) * rm, (nav[:, 8] - tru.lon[k]) * rn * np.cos(tru.lat[k]),
                         nav[:, 9] - tru.h[k]])
    s = sig[:, lay.slice("dp")] * np.column_stack([rm, rn * np.cos(tru.lat[k]), np.ones_like(rm)])
    hz = np.hypot(e[:, 0], e[:, 1])
    return float(np.sqrt(np.mean(hz ** 2))), float(hz.max()), float(np.mean(np.sum((e / s) ** 2, 1)))


def urban(seeds):
    from sinslab.fusion.graph import GraphSpec, graph_navigate
    from sinslab.fusion.loosely_coupled import loosely_coupled
    from sinslab.fusion.measurements.schedule import RobustWeighting
    from sinslab.fusion.spec import FilterGrid, FixSpec
    from sinslab.nav import errstate as es
    B = _bench_smoother()
    m = es.ErrorModel("full", [es.gyro_bias(rrw=1e-6), es.accel_bias(arw=1e-5)], gyro_arw=B.GYRO_ARW,
                      accel_vrw=B.ACCEL_VRW)
    variants = {"filter": None, "filter_chang": RobustWeighting("chang", 0.01),
                "filter_huber": RobustWeighting("huber", k0=1.5), "filter_igg3": RobustWeighting("igg3", k0=1.5, k1=3.0),
                "graph": None, "graph_huber": RobustWeighting("huber", k0=1.5),
                "graph_igg3": RobustWeighting("igg3", k0=1.5, k1=3.0)}
    acc = {k: [] for k in variants}
    for seed in seeds:
        d, kw = _urban_fixes(B, seed)
        P0 = np.diag(d["sd"] ** 2)
        for name, rob in variants.items():
            fx = FixSpec(**kw, robust=rob)
            if name.startswith("filter"):
                r = loosely_coupled(d["imu"], d["init"], fx, P0, m, grid=FilterGrid(0.02), progress=False)
                acc[name].append(_scores(B, r.nav, r.sigma, m.layout))
            else:
                r = graph_navigate(d["imu"], d["init"], fx, P0, m, grid=FilterGrid(0.02), spec=GraphSpec("batch"))
                acc[name].append(_scores(B, r.nav, r.sigma, m.layout))
    return {"seeds": list(seeds), "nees_dof": 3,
            **{k: dict(zip(("hz_rms_m", "hz_max_m", "nees_mean"), np.mean(v, 0).tolist())) for k, v in acc.items()}}


# ---------------------------------------------------------------------- 3. real drives
DRIVES = {
    "rtklib-drive": ["--imu", "{D}/rtklib-drive/imu_1934.csv", "--fixes", "{D}/rtklib-drive/gnss_1934_sf.pos",
                     "--mount", "rpy:180,-6.79,185.35", "--frame", "frd", "--lever-arm", "[-0.05, 0, 0] m",
                     "--time-sync", "auto", "--velocity-lag", "0.125", "--outages", "15/60@40"],
    "n380": ["--imu", "{N}/n380-imu-nav.csv.zip", "--columns",
             "t=SystemTov[s], dtheta_x=DeltaTheta[0][rad], dtheta_y=DeltaTheta[1][rad], dtheta_z=DeltaTheta[2][rad], "
             "dv_x=DeltaVelocity[0][m/s], dv_y=DeltaVelocity[1][m/s], dv_z=DeltaVelocity[2][m/s]",
             "--mount", "matrix:0,0,-1,0,1,0,1,0,0", "--frame", "frd", "--fixes", "{N}/n380-gnss-pvt.csv.zip",
             "--fix-columns", "t=SystemTov[s], lat=GnssLatitude[rad], lon=GnssLongitude[rad], "
             "h=GnssAltitudeAboveEllipsoid[m], vn=GnssVelocityN[m/s], ve=GnssVelocityE[m/s], vd=GnssVelocityD[m/s], "
             "sd_n=GnssStdvLat[m], sd_e=GnssStdvLon[m], sd_u=GnssStdvAlt[m], sd_vn=GnssStdvN[m/s], "
             "sd_ve=GnssStdvE[m/s], sd_vd=GnssStdvD[m/s], quality=InsGnssBIT.InsMode",
             "--outages", "30/120@60", "--time-sync", "auto"],
}


#: a fixed-lag window longer than the drive's outages (15 s and 30 s)
LONG_LAG = {"rtklib-drive": 20.0, "n380": 40.0}


def _n380_folder():
    import onavdata
    root = Path(onavdata.__file__).resolve().parent
    hits = sorted(root.rglob("2021-04-27C-car-hill-drive*/n380-imu-nav.csv.zip")) or \
        sorted(p for p in root.rglob("n380-imu-nav.csv.zip") if "hill" in str(p))
    return hits[0].parent


def one_drive(drive, estimator, out_json):
    """Child process: ``sinslab navigate`` of ``drive`` with ``estimator`` (``filter``,
    ``rts``: ``--smooth``, else an ``--estimator`` value) and its figures: the estimator's
    CPU time (its ``estimate`` call alone), the process's peak memory, the errors at the
    withheld fixes of each outage."""
    import tempfile

    from sinslab import cli
    from sinslab.fusion.estimators import KalmanEstimator
    from sinslab.fusion.graph.estimator import GraphEstimator
    D = str(DATA.resolve())
    args = [a.replace("{D}", D).replace("{N}", str(_n380_folder()) if drive == "n380" else "") for a in DRIVES[drive]]
    got = {}

    def timed(cls):
        orig = cls.estimate

        def estimate(self, e):
            c = time.process_time()
            out = orig(self, e)
            got.update(cpu=time.process_time() - c, fixes=e.plans[0].facts["spec"], out=out)
            return out
        cls.estimate = estimate

    timed(KalmanEstimator)
    timed(GraphEstimator)
    extra = ["--smooth"] if estimator == "rts" else [] if estimator == "filter" else ["--estimator", estimator]
    with tempfile.TemporaryDirectory() as tmp:
        try:
            cli.app(["-q", "navigate", *args, *extra, "--out", str(Path(tmp) / "run")], prog_name="sinslab",
                    standalone_mode=False)
        except SystemExit:
            pass
    r, smoothed, _ = got["out"]
    t, nav = (smoothed.t, smoothed.nav) if estimator == "rts" else (r.t, r.nav[0])
    res = {"estimator": estimator, "cpu_s": got["cpu"],
           "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
    np.savez(Path(out_json).with_suffix(".npz"), t=t, nav=nav)
    oe = _outage_errors(got["fixes"], t, nav)
    res["outage_end_hz_m"], res["outage_mid_hz_m"] = oe["end"], oe["mid"]
    Path(out_json).write_text(json.dumps(res))


def _outage_errors(fixes, t, nav):
    """Horizontal error of the antenna at the withheld fixes of each outage: at its last
    (``end``: what a forward filter has coasted to) and at its middle (``mid``: the
    smoothers' worst)."""
    from sinslab.core import attitude as A
    from sinslab.core import earth as E
    out = {"end": [], "mid": []}
    for s, ln in fixes.outages:
        m = np.flatnonzero((fixes.t >= s) & (fixes.t < s + ln))
        if not m.size:
            continue
        for what, j in (("end", m[-1]), ("mid", m[np.argmin(np.abs(fixes.t[m] - (s + ln / 2)))])):
            k = int(np.clip(np.searchsorted(t, fixes.t[j]), 1, t.size - 1))
            w = (fixes.t[j] - t[k - 1]) / (t[k] - t[k - 1])
            row = nav[k - 1] + w * (nav[k] - nav[k - 1])
            d = A.quat_to_dcm(row[:4] / np.linalg.norm(row[:4])) @ fixes.lever_arm
            rm, rn = (float(x) for x in E.radii(row[7], row[9]))
            e = (row[8] - fixes.pos[j, 1]) * rn * math.cos(row[7]) + d[0]
            n = (row[7] - fixes.pos[j, 0]) * rm + d[1]
            out[what].append(float(math.hypot(e, n)))
    return out


def real_drives(drives):
    import tempfile
    out = {}
    for drive in drives:
        rows = {}
        with tempfile.TemporaryDirectory() as tmp:
            lag = f"{LONG_LAG[drive]:g}"
            for key, est in (("filter", "filter"), ("rts", "rts"), ("graph_fixed_lag", "fixed-lag:5"),
                             (f"graph_fixed_lag:{lag}", f"fixed-lag:{lag}"), ("graph_batch", "graph")):
                f = Path(tmp) / f"{key.replace(':', '_')}.json"
                subprocess.run([sys.executable, __file__, "--one", drive, est, str(f)], check=True)
                rows[key] = json.loads(f.read_text())
                rows[key]["_sol"] = np.load(f.with_suffix(".npz"))
            ref = rows["rts"]["_sol"]
            for est, r in rows.items():
                sol = r.pop("_sol")
                r["att_vs_rts_rms_deg"] = _att_rms(sol["t"], sol["nav"], ref["t"], ref["nav"])
        out[drive] = rows
    return out


def _att_rms(t, nav, t_ref, nav_ref):
    from sinslab.core import attitude as A
    k = np.searchsorted(t_ref, t)
    ok = (k < t_ref.size) & (np.abs(t_ref[np.minimum(k, t_ref.size - 1)] - t) < 1e-6)
    phi = A.misalignment(A.quat_to_dcm(nav_ref[k[ok], :4]), A.quat_to_dcm(nav[ok, :4]))
    return np.degrees(np.sqrt(np.mean(phi ** 2, 0))).tolist()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--out", default=None)
    ap.add_argument("--one", nargs=3, metavar=("DRIVE", "ESTIMATOR", "JSON"))
    a = ap.parse_args()
    if a.one:
        return one_drive(*a.one)
    res = {"frame": frame_difference(), "urban": urban(range(1, 3 if a.quick else 6))}
    drives = [d for d in ("rtklib-drive", "n380") if d != "rtklib-drive" or (DATA / "rtklib-drive").is_dir()]
    res["real"] = real_drives(drives[:1] if a.quick else drives)
    text = json.dumps(res, indent=1)
    if a.out:
        Path(a.out).write_text(text)
    print(text)


if __name__ == "__main__":
    main()
