"""Why a filter enters a GNSS outage off in velocity: the receiver's stated σ against its real
errors, and the filter's innovations, on NaveGo's Turin drive.

    python benchmarks/outage_entry.py [--navego DIR | --ref REF.mat --gnss GNSS.mat] [--out FIGURES.json]

DIR is NaveGo's ``examples/real-data`` folder (its ``ref.mat`` and ``ekinox_gnss.mat``; the
``NAVEGO_REAL_DATA`` environment variable names it too), read by sinslab's NaveGo reader;
the IMU is made from the reference at the two grades of ``tools/navego_drive.py`` (tactical
``ekinox``, consumer ``mpu``), seven 40 s outages. Without the files the script says so and
exits 0 (the figures file then holds ``skipped``).

Printed, against the reference solution:

- **the fixes**: the stated σ beside the real error's RMS per axis (position north, east,
  up; velocity east, north, up), the velocity error's autocorrelation at 0.2, 1, 5 and 10 s,
  and its *long-run* σ (``√(mean n ē²)`` over 10 s batches: the white σ that carries the
  information N successive fixes really carry); the height error's mean and scatter (the
  floor of the vertical RMS: the fixes are the only height source); the receiver's own
  velocity error in the 10 s before each outage; the fixes' error model ``fix_error="auto"``
  measures from them alone (:func:`sinslab.fusion.fix_noise.fix_error_model`: white and
  Gauss–Markov position σ, τ, the velocity error's walk and correlation time, the share of
  fixes at rest left out);
- **the filter's innovations** with the σ as stated: the per-axis mean of ν²/S over the run
  and over the 30 s before each outage, and the innovations' lag-1 autocorrelation (a
  consistent filter's innovations are white, Mehra & Peschon 1971);
- **seven runs per grade**: ``default`` (the file's σ), ``auto`` (``fix_error="auto"``: the
  fixes' error structure measured from the record, :mod:`sinslab.fusion.fix_noise`: the
  position's Gauss–Markov part as states of the filter), ``auto+check`` (with the check below),
  ``innovations`` (``fix_noise="innovations"``: the σ measured from the filter's own
  innovations, :func:`sinslab.fusion.fix_noise.innovation_noise`), ``check``
  (``velocity_check=10``: each velocity fix checked against the position fixes over the 10 s
  before it, :func:`sinslab.fusion.fix_noise.velocity_check`), ``innov+check`` (both) and
  ``navego`` (the same filter with NaveGo's own tuning, 2.5 m and 0.5 m/s: a well-tuned
  reference): horizontal and vertical RMS, the horizontal error at each outage end (and
  their median), the velocity error at each outage start; for the innovation runs the σ used;
- **paired over IMU noise seeds** (``--seeds N``, default 10: seeds 1..N, the same real
  fixes; each seed's IMU drawn once and run by every filter of :data:`COMPARED`: ours,
  ``auto+check`` and ``innov+check``, and NaveGo's tuning): per grade, per filter of ours
  and per outage the mean outage-end horizontal error of each
  (and the mean horizontal velocity error at the outage's start),
  the mean paired difference ``d̄`` (ours − reference) and its standard error
  ``SE = std(d, ddof=1)/√N``, and a verdict fixed before any result was seen: an outage is
  **no worse** when ``d̄ ≤ 0``, or when ``d̄ ≤ 2 SE`` (not significantly worse) *and*
  ``d̄ ≤ 0.05 × `` the reference's mean end (worse by no more than 5 %); otherwise it is
  **worse**. Beside it, each filter's horizontal and vertical RMS over the drive, mean and
  sample standard deviation over the seeds. ``--paired-only`` skips the single-seed
  figures above.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
LAGS_S = (0.2, 1.0, 5.0, 10.0)
BATCH_S = 10.0


def _navego_drive():
    spec = importlib.util.spec_from_file_location("navego_drive", ROOT / "tools" / "navego_drive.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _at(tru, t):
    return np.clip(np.rint((t - tru.t[0]) / 0.01).astype(int), 0, tru.t.size - 1)


def fix_figures(fx, tru, meta, outs):
    """The fixes against the reference (see the module notes)."""
    from sinslab.core.earth import radii
    k = _at(tru, fx.t)
    rm, rn = radii(tru.lat[k], tru.h[k])
    up = float(np.asarray(meta.get("lever_arm", np.zeros(3)))[2])      # the antenna above the IMU point
    ep = np.stack([(fx.lat - tru.lat[k]) * rm, (fx.lon - tru.lon[k]) * rn * np.cos(tru.lat[k]),
                   fx.h - tru.h[k] - up], -1)                            # north, east, up
    ev = fx.vel - tru.vel[k]                                             # east, north, up
    h = float(np.median(np.diff(fx.t)))
    ac = {f"{lag:g}": [float(np.corrcoef(ev[:-m, i], ev[m:, i])[0, 1]) for i in range(3)]
          for lag in LAGS_S for m in [max(1, int(round(lag / h)))]}
    b = np.floor((fx.t - fx.t[0]) / BATCH_S).astype(int)
    n = np.bincount(b).astype(float)
    s = np.stack([np.bincount(b, ev[:, i]) for i in range(3)], -1)[n > 0]
    long_run = np.sqrt(np.mean(s ** 2 / n[n > 0, None], 0) * h)         # σ of a white noise with that density
    before = [np.mean(ev[(fx.t >= st - 10.0) & (fx.t < st), :2], 0).tolist() for st, _ in outs]
    from sinslab.fusion.fix_noise import fix_error_model
    m = fix_error_model(fx)
    model = None if m is None else {"white": m.white.tolist(), "correlated": m.correlated.tolist(), "tau": m.tau,
                                    "velocity_walk": m.velocity_walk.tolist(), "velocity_tau": m.velocity_tau,
                                    "rest_fraction": m.rest_fraction}
    return {"pos_sigma_stated": np.median(fx.sigma, 0).tolist(), "pos_err_rms": np.sqrt(np.mean(ep ** 2, 0)).tolist(),
            "vel_sigma_stated": np.median(fx.sigma_vel, 0).tolist(), "vel_err_rms": np.sqrt(np.mean(ev ** 2, 0)).tolist(),
            "vel_err_autocorr": ac, "vel_long_run_sigma": (long_run / np.sqrt(h)).tolist(),
            "height_err_mean": float(np.mean(ep[:, 2])), "height_err_std": float(np.std(ep[:, 2])),
            "vel_err_before_outages": before, "fix_error_model": model}


def innovation_figures(res, outs):
    """Per-axis mean ν²/S (whole run and the 30 s before each outage) and lag-1
    autocorrelation of the fix innovations (north, east, up [m], east, north, up [m/s])."""
    z = res.innovation / res.innovation_sigma
    t = res.fix_t
    pre = [np.mean(z[(t >= st - 30.0) & (t < st)] ** 2, 0).tolist() for st, _ in outs]
    return {"nis_mean": float(np.mean(res.nis)), "z2_mean": np.mean(z ** 2, 0).tolist(), "z2_before_outages": pre,
            "autocorr_lag1": [float(np.corrcoef(z[:-1, i], z[1:, i])[0, 1]) for i in range(z.shape[1])]}


RUNS = (("default", {}), ("auto", {"fix_error": "auto"}), ("auto+check", {"fix_error": "auto", "velocity_check": 10.0}),
        ("innovations", {"fix_noise": "innovations"}),
        ("check", {"velocity_check": 10.0}), ("innov+check", {"fix_noise": "innovations", "velocity_check": 10.0}),
        ("navego", {"fix_sigma": (2.5, 2.5, 2.5), "fix_vel_sigma": (0.5, 0.5, 0.5)}))


def _runs(nd, d, grade):
    out = {}
    for name, kw in RUNS:
        r = nd.run(*d, grade, **kw)
        out[name] = {"hz_rms": r[0], "vert_rms": r[1], "outage_ends": r[2].tolist(),
                     "outage_end_median": float(np.median(r[2])), "dv_at_starts": r[3].tolist()}
        m = r[6].source.metrics
        if "fix_noise_sigma_used" in m:
            out[name].update(sigma_used=m["fix_noise_sigma_used"], runs=m["fix_noise_runs"])
    return out


#: the IMU noise seeds of the paired evaluation: seeds 1..N (which of two filters ends an
#: outage closer moves with the IMU's own noise, so one seed cannot decide)
PAIRED_SEEDS = 10
#: the runs compared per seed: ours (each compared with the reference), then the reference
COMPARED = ("auto+check", "innov+check", "navego")
#: the verdict's rule (chosen before the results): no worse when d̄ ≤ 0, or when
#: d̄ ≤ NO_WORSE_SE standard errors and d̄ ≤ NO_WORSE_FRACTION of the reference's mean end
NO_WORSE_SE = 2.0
NO_WORSE_FRACTION = 0.05


def paired_verdict(ours, ref):
    """The paired comparison of one outage over seeds: ``ours``, ``ref`` (N,) outage-end
    errors [m] of the same IMU draws. Returns ``{"ours_mean", "ref_mean", "diff_mean",
    "diff_se", "verdict"}`` with the rule of the module notes."""
    ours, ref = np.asarray(ours, float), np.asarray(ref, float)
    d = ours - ref
    dm = float(np.mean(d))
    se = float(np.std(d, ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("inf")
    rm = float(np.mean(ref))
    ok = dm <= 0.0 or (dm <= NO_WORSE_SE * se and dm <= NO_WORSE_FRACTION * rm)
    return {"ours_mean": float(np.mean(ours)), "ref_mean": rm, "diff_mean": dm, "diff_se": se,
            "verdict": "no worse" if ok else "worse"}


def _paired(nd, ref, gnss, grade, n_seeds=PAIRED_SEEDS, compared=COMPARED):
    """The paired evaluation over IMU noise seeds 1..``n_seeds`` (see the module notes):
    each of ``compared[:-1]`` against ``compared[-1]``."""
    kw = dict(RUNS)
    per = {name: {"ends": [], "hz_rms": [], "vert_rms": [], "dv_at_starts": []} for name in compared}
    for seed in range(1, n_seeds + 1):
        d = nd._drive(ref, gnss, grade, seed=seed)
        for name in compared:
            r = nd.run(*d, grade, **kw[name])
            for key, v in zip(("hz_rms", "vert_rms", "ends", "dv_at_starts"), (r[0], r[1], r[2], r[3])):
                per[name][key].append(np.asarray(v).tolist())
    *ours, reference = compared
    refr = np.array(per[reference]["ends"])
    ref_dv = np.mean(per[reference]["dv_at_starts"], 0)
    outages = {}
    for name in ours:
        o = np.array(per[name]["ends"])
        dv = np.mean(per[name]["dv_at_starts"], 0)
        outages[name] = [dict(paired_verdict(o[:, i], refr[:, i]), ours_dv_start=float(dv[i]),
                              ref_dv_start=float(ref_dv[i])) for i in range(o.shape[1])]
    stats = lambda a: {"mean": float(np.mean(a)), "std": float(np.std(a, ddof=1)) if len(a) > 1 else 0.0}  # noqa: E731
    return {"seeds": n_seeds, "ours": list(ours), "reference": reference,
            "outages": outages,
            "hz_rms": {name: stats(per[name]["hz_rms"]) for name in compared},
            "vert_rms": {name: stats(per[name]["vert_rms"]) for name in compared},
            "per_seed": per}


def _print(fig):
    f = fig["fixes"]
    fmt = lambda a, p=2: " ".join(f"{x:.{p}f}" for x in a)  # noqa: E731
    print(f"fixes: position σ stated {fmt(f['pos_sigma_stated'])} m, error RMS {fmt(f['pos_err_rms'])} m (N E U)")
    print(f"       velocity σ stated {fmt(f['vel_sigma_stated'], 3)} m/s, error RMS {fmt(f['vel_err_rms'], 3)} m/s, "
          f"long-run σ {fmt(f['vel_long_run_sigma'], 2)} m/s (E N U)")
    print("       velocity error autocorrelation " + "; ".join(f"{k} s: {fmt(v)}" for k, v in f["vel_err_autocorr"].items()))
    print(f"       height error {f['height_err_mean']:.2f} ± {f['height_err_std']:.2f} m")
    print("       receiver velocity error (E N) in the 10 s before each outage [m/s]: "
          + "  ".join(fmt(v) for v in f["vel_err_before_outages"]))
    m = f["fix_error_model"]
    if m:
        print(f"       fix error model (E N U): white {fmt(m['white'])} m, correlated {fmt(m['correlated'])} m over "
              f"{m['tau']:.0f} s; velocity walk {fmt(m['velocity_walk'])} m/√s lasting {m['velocity_tau']:.0f} s; "
              f"{100 * m['rest_fraction']:.0f} % of the fixes at rest left out")
    i = fig["innovations"]
    print(f"innovations (σ as stated): mean NIS {i['nis_mean']:.2f}; mean ν²/S {fmt(i['z2_mean'])} "
          f"(pN pE pU vE vN vU); lag-1 autocorrelation {fmt(i['autocorr_lag1'])}")
    print("       30 s before each outage: " + "  ".join(fmt(v, 1) for v in i["z2_before_outages"]))
    for grade in ("ekinox", "mpu"):
        print(f"{grade}: {'run':<12} {'hz RMS':>6} {'vert':>6} {'median':>6}  outage ends [m]{'':22}|δv| at starts [m/s]")
        for name, r in fig[grade].items():
            print(f"{'':{len(grade) + 2}}{name:<12} {r['hz_rms']:6.2f} {r['vert_rms']:6.2f} {r['outage_end_median']:6.2f}  "
                  + " ".join(f"{x:5.1f}" for x in r["outage_ends"]) + "   " + " ".join(f"{x:4.2f}" for x in r["dv_at_starts"])
                  + (f"   σ used {fmt(r['sigma_used'])} ({r['runs']} runs)" if "sigma_used" in r else ""))
    for grade in ("ekinox", "mpu"):
        p = fig.get(f"{grade}_paired")
        if p:
            _print_paired(grade, p)


def _print_paired(grade, p):
    r = p["reference"]
    for o in p["ours"]:
        print(f"{grade}, paired over IMU seeds 1..{p['seeds']}: {o} against {r} "
              f"(no worse: d̄ ≤ 0, or d̄ ≤ {NO_WORSE_SE:g} SE and ≤ {100 * NO_WORSE_FRACTION:g} % of the reference)")
        print(f"  {'outage':>6} {o:>12} {r:>8} {'d̄ ± SE [m]':>16} {'d̄/ref':>7}  {'verdict':<9} |δv| at the start [m/s]")
        for i, x in enumerate(p["outages"][o]):
            print(f"  {i + 1:6d} {x['ours_mean']:12.2f} {x['ref_mean']:8.2f} {x['diff_mean']:+8.2f} ± {x['diff_se']:5.2f} "
                  f"{100 * x['diff_mean'] / x['ref_mean']:+6.1f}%  {x['verdict']:<9} {x['ours_dv_start']:.3f} "
                  f"{x['ref_dv_start']:.3f}")
        for key in ("hz_rms", "vert_rms"):
            print(f"  {key}: " + "; ".join(f"{n} {p[key][n]['mean']:.2f} ± {p[key][n]['std']:.2f} m" for n in (o, r)))


def measure(ref, gnss, n_seeds=PAIRED_SEEDS, paired_only=False):
    """All the figures (see the module notes)."""
    t0 = time.time()
    load = os.getloadavg()[0]
    nd = _navego_drive()
    if paired_only:
        fig = {f"{g}_paired": _paired(nd, ref, gnss, g, n_seeds) for g in ("ekinox", "mpu")}
        fig.update(load_before=load, load_after=os.getloadavg()[0], seconds=time.time() - t0)
        return fig
    d = nd._drive(ref, gnss, "ekinox")
    imu, fx, tru, meta = d
    outs = nd._outages(fx)
    from sinslab.core import units as U
    from sinslab.fusion import recorded as R
    g = nd.GRADES["ekinox"][1]
    opt = R.NavOptions.of(lever_arm=tuple(meta["lever_arm"]), rest_noise=False, outages=outs,
                          gyro_arw=U.parse(g["gyro"], "angle_random_walk"),
                          accel_vrw=U.parse(g["accel"] + "/sqrt(Hz)", "velocity_random_walk"),
                          gyro_bias_sigma=U.parse(g["gb"], "angular_rate"),
                          accel_bias_sigma=U.parse(g["ab"], "acceleration"))
    res = R.navigate_recorded(imu, fx, opt)
    fig = {"fixes": fix_figures(fx, tru, meta, outs), "innovations": innovation_figures(res, outs),
           "ekinox": _runs(nd, d, "ekinox"), "mpu": _runs(nd, nd._drive(ref, gnss, "mpu"), "mpu"),
           "ekinox_paired": _paired(nd, ref, gnss, "ekinox", n_seeds), "mpu_paired": _paired(nd, ref, gnss, "mpu", n_seeds)}
    fig.update(load_before=load, load_after=os.getloadavg()[0], seconds=time.time() - t0)
    return fig


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--navego", default=os.environ.get("NAVEGO_REAL_DATA"),
                    help="NaveGo's examples/real-data folder (ref.mat, ekinox_gnss.mat)")
    ap.add_argument("--ref", help="NaveGo's examples/real-data/ref.mat")
    ap.add_argument("--gnss", help="NaveGo's examples/real-data/ekinox_gnss.mat")
    ap.add_argument("--out", help="write the figures as JSON here")
    ap.add_argument("--seeds", type=int, default=PAIRED_SEEDS, help="IMU noise seeds of the paired evaluation (1..N)")
    ap.add_argument("--paired-only", action="store_true", help="only the paired evaluation")
    a = ap.parse_args(argv)
    if a.seeds < 2:
        print("outage_entry: error: --seeds must be at least 2 (a standard error needs two)", file=sys.stderr)
        return 2
    if a.navego and not (a.ref or a.gnss):
        a.ref, a.gnss = str(Path(a.navego) / "ref.mat"), str(Path(a.navego) / "ekinox_gnss.mat")
    missing = [p for p in (a.ref, a.gnss) if not p or not Path(p).is_file()]
    if missing:
        why = "NaveGo's ref.mat and ekinox_gnss.mat not given or not found (--navego, --ref, --gnss): skipped"
        print(f"outage_entry: {why}")
        fig = {"skipped": why}
    else:
        fig = measure(a.ref, a.gnss, a.seeds, a.paired_only)
        if a.paired_only:
            for grade in ("ekinox", "mpu"):
                _print_paired(grade, fig[f"{grade}_paired"])
        else:
            _print(fig)
        print(f"(load {fig['load_before']:.2f} before, {fig['load_after']:.2f} after; {fig['seconds']:.0f} s)")
    if a.out:
        Path(a.out).write_text(json.dumps(fig, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
