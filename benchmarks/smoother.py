"""RTS smoothing of fusion-driver runs: consistency, outages, odometer, speed.

Run: ``.venv/bin/python benchmarks/smoother.py [--quick] [--runs N] [--out FILE]``;
``.venv/bin/python benchmarks/record.py smoother`` runs it and stores its figures in
``docs/benchmarks.json``, the record docs/methods/smoother.md quotes them from.

1. Monte Carlo on a simulated car drive (``drive_run``): 201 s, 1 Hz position (1, 1, 2 m)
   and velocity (0.05 m/s) fixes with their noise, a 60 s GNSS outage (100–160 s), every
   run drawing its initial errors and sensor biases from P0 and its own IMU noise. Per
   state and checked epoch, ``RMS(smoothed error) / smoothed σ`` over the runs against the
   two-sided χ²(N) band at overall level 1e-3 (Bonferroni over all checks); horizontal
   error of the smoothed solution in the middle of the outage against the forward filter's
   at the end of the outage (RMS over the runs, and σ).
2. The same drive with a wheel odometer (2 % scale error, 0.05 m/s noise, 2 cm/s
   quantisation at 20 Hz, forward speed of the rear-axle point) and the non-holonomic
   constraint: outage-end error with and without it, forward and smoothed.
3. Speed: 1 h of 200 Hz IMU, loosely coupled filter with 1 Hz fixes and the covariance at
   10 Hz (benchmarks/estimation.py's scenario), forward pass without and with the history,
   then the backward pass and the corrected solution (best of 5 interleaved, wall and CPU
   time: the machine is shared); memory of the history.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
os.environ.setdefault("SINSLAB_QUIET", "1")

import numpy as np  # noqa: E402

from sinslab.core import attitude as A  # noqa: E402
from sinslab.core import units as u  # noqa: E402
from sinslab.core.earth import radii  # noqa: E402
from sinslab.core.records import NavState  # noqa: E402
from sinslab.fusion import driver  # noqa: E402
from sinslab.fusion.spec import FilterGrid  # noqa: E402
from sinslab.fusion.feedback import FeedbackLayout  # noqa: E402
from sinslab.fusion.measurements import Odometer, PositionFix, Stack, VelocityFix  # noqa: E402
from sinslab.fusion.smoothing import History, smooth  # noqa: E402
from sinslab.nav import errstate as es  # noqa: E402
from sinslab.sim import imu as IM  # noqa: E402
from sinslab.sim import trajectory as tr  # noqa: E402

OUTAGE = (100.0, 160.0)
GYRO_ARW = 0.3 * u.deg / 60            # [rad/sqrt(s)]
ACCEL_VRW = 100 * u.ug                  # [m/s/sqrt(s)]
KF_DT = 0.02
_GEN = {}


def _trajectory():
    if "g" not in _GEN:
        segs = [tr.Accelerate(duration=11.0, accel=2.0), tr.Level(duration=40.0),
                tr.Turn(duration=20.0, rate=4.5 * u.deg, coordinated=False), tr.Level(duration=30.0),
                tr.Turn(duration=20.0, rate=-4.5 * u.deg, coordinated=False), tr.Level(duration=80.0)]
        start = tr.Start(lat=32 * u.deg, lon=118 * u.deg, h=50.0, speed=0.0, heading=45 * u.deg)
        _GEN["g"] = tr.generate(segs, start, 0.01)
    return _GEN["g"]


def drive_model(odometer=False):
    """Error model (15 states; + odometer scale) and its initial standard deviations."""
    blocks = [es.gyro_bias(), es.accel_bias()] + ([es.odometer_scale()] if odometer else [])
    m = es.ErrorModel("full", blocks, gyro_arw=GYRO_ARW, accel_vrw=ACCEL_VRW)
    lay = m.layout
    sd = np.zeros(m.n)
    sd[lay.slice("phi")] = [0.2 * u.deg] * 2 + [2 * u.deg]
    sd[lay.slice("dv")] = 0.1
    sd[lay.slice("dp")] = [3 / 6.4e6, 3 / 5.4e6, 3.0]
    sd[lay.slice("eps")] = 20 * u.dph
    sd[lay.slice("nabla")] = 1000 * u.ug
    if odometer:
        sd[lay.slice("kod")] = 0.05
    return m, sd


def drive_inputs(seed, *, odometer=False, outage=OUTAGE, latency=0.0):
    """Inputs of one simulated drive: ``dict(model, sd, imu, init, measurements, errors,
    k_true)`` (initial errors and biases drawn from P0, fixes with their noise)."""
    gen = _trajectory()
    tru = gen.truth
    m, sd = drive_model(odometer)
    lay = m.layout
    rng = np.random.default_rng(seed)
    x0 = sd * rng.standard_normal(m.n)
    err = IM.ImuErrors(gyro_bias=x0[lay.slice("eps")], gyro_arw=np.full(3, GYRO_ARW),
                       accel_bias=x0[lay.slice("nabla")], accel_vrw=np.full(3, ACCEL_VRW))
    meas = IM.apply(gen.imu, err, rng)
    dp = x0[lay.slice("dp")]
    Cc = A.rotvec_to_dcm(-x0[lay.slice("phi")]) @ A.euler_to_dcm(tru.att[0])
    init = NavState(tru.lat[0] + dp[0], tru.lon[0] + dp[1], tru.h[0] + dp[2],
                    tru.vel[0] + x0[lay.slice("dv")], A.dcm_to_euler(Cc), tru.t[0])
    t = np.arange(tru.t[0] + 1.0, tru.t[-1] - 1, 1.0)
    if outage is not None:
        t = t[~((t >= outage[0]) & (t < outage[1]))]
    i = np.rint((t - tru.t[0]) / 0.01).astype(int)
    rm, rn = radii(tru.lat[i], tru.h[i])
    pn = rng.standard_normal((t.size, 3)) * [1.0, 1.0, 2.0]
    pos = np.stack([tru.lat[i] + pn[:, 0] / rm, tru.lon[i] + pn[:, 1] / (rn * np.cos(tru.lat[i])),
                    tru.h[i] + pn[:, 2]], -1)
    ta = t + latency
    ms = [Stack(PositionFix(t, pos, [1.0, 1.0, 2.0], t_arrive=ta),
                VelocityFix(t, tru.vel[i] + 0.05 * rng.standard_normal((t.size, 3)), 0.05, t_arrive=ta))]
    k_true = 0.0
    if odometer:
        # rear-axle point 1 m behind the IMU: its forward speed, +2 %, noise, 2 cm/s steps
        lever = np.array([0.0, -1.0, 0.0])
        C = A.euler_to_dcm(tru.att)
        wb = gen.imu.dtheta / gen.imu.dt
        vb = np.einsum("kji,kj->ki", C, tru.vel)
        vb[1:] += np.cross(wb, lever)
        k_true = x0[lay.slice("kod")][0]
        t_odo = tru.t[::5]
        s = np.maximum(0.0, (1 + k_true) * vb[::5, 1] + 0.05 * rng.standard_normal(t_odo.size))
        s = np.round(s / 0.02) * 0.02
        ms.append(Odometer(t_odo, s, math.hypot(0.05, 0.02 / math.sqrt(12)), lever_arm=lever,
                           nhc_sigma=(0.05, 0.05), every=5))
    # the odometer's H (∂z/∂k = −s̃) is exact for the state k = 1 − v/s̃ = k_s/(1 + k_s) of a
    # reading s̃ = (1 + k_s) v
    return dict(model=m, sd=sd, imu=meas, init=init, measurements=ms, errors=err,
                k_true=k_true / (1 + k_true))


def drive_forward(d, history=None):
    """The forward pass of :func:`drive_inputs` ``d`` on the driver (closed loop)."""
    m = d["model"]
    return driver.run([driver.LiveStream(d["imu"], d["init"], nsub=2)], m, np.diag(d["sd"] ** 2),
                      d["measurements"], grid=FilterGrid(KF_DT), feedback=FeedbackLayout.from_model(m.layout),
                      history=history)


def drive_run(seed, *, odometer=False, every=0.1, outage=OUTAGE):
    """One simulated drive through the driver with history and its smoothing.

    Returns ``(forward DriverResult, SmoothedRun, truth errors dict)``; the truth dict
    holds the forward and smoothed errors (computed − true) of every state at every
    filter epoch, ``fwd`` and ``smo`` (M, n), in the model's units.
    """
    d = drive_inputs(seed, odometer=odometer, outage=outage)
    r = drive_forward(d, History(every))
    sm = smooth(r)
    return r, sm, drive_truth(d, r, sm)


def drive_truth(d, r, sm):
    """Forward (``fwd``) and smoothed (``smo``) errors of every state at every epoch."""
    tru = _trajectory().truth
    lay, err, k_true = d["model"].layout, d["errors"], d["k_true"]
    k = np.rint((r.t - tru.t[0]) / 0.01).astype(int)
    return dict(fwd=_errors(r.nav[0], r.gyro_bias[0], r.accel_bias[0], r.x, tru, k, err, lay, k_true),
                smo=_errors(sm.nav, sm.gyro_bias, sm.accel_bias, sm.x, tru, k, err, lay, k_true))


def _errors(rows, gb, ab, x, tru, k, err, lay, k_true):
    """Errors of a solution (computed − true) in the units of the states: φ, δv, δp, and
    the residual of the sensor estimates (compensation + remaining estimate − true)."""
    out = np.zeros_like(x)
    C = A.quat_to_dcm(rows[:, :4])
    out[:, lay.slice("phi")] = A.misalignment(A.euler_to_dcm(tru.att[k]), C)
    out[:, lay.slice("dv")] = rows[:, 4:7] - tru.vel[k]
    out[:, lay.slice("dp")] = np.stack([rows[:, 7] - tru.lat[k], rows[:, 8] - tru.lon[k],
                                        rows[:, 9] - tru.h[k]], -1)
    # bias states are b_true − compensation (compensated rate = true + b − gb); the error of
    # the estimate gb + x is therefore (gb + x) − b, with x = 0 for a smoothed solution
    # whose compensation already holds x
    out[:, lay.slice("eps")] = gb - err.gyro_bias
    out[:, lay.slice("nabla")] = ab - err.accel_bias
    if "kod" in lay.names:
        out[:, lay.slice("kod")] = x[:, lay.slice("kod")] - k_true
    return out


def hz_error(rows, k_rows, tru_idx):
    """Horizontal position error [m] of rows against the truth samples ``tru_idx``."""
    tru = _trajectory().truth
    rm, rn = radii(tru.lat[tru_idx], tru.h[tru_idx])
    return np.hypot((rows[k_rows, 7] - tru.lat[tru_idx]) * rm,
                    (rows[k_rows, 8] - tru.lon[tru_idx]) * rn * np.cos(tru.lat[tru_idx]))


CHECK_T = (50.0, OUTAGE[0] + 30.0, OUTAGE[1] - 0.1, 190.0)   # with fixes, outage mid/end, late


def monte_carlo(runs, *, seed0=100, level=1e-3):
    """Consistency of the smoothed σ and the outage figures over ``runs`` drives."""
    from scipy.stats import chi2
    e2s = e2f = None
    hz_mid = []
    hz_end_f = []
    sig_mid = []
    sig_end_f = []
    sig_ok = True
    for j in range(runs):
        r, sm, tr_ = drive_run(seed0 + j)
        t = r.t - r.t[0]
        if e2s is None:
            ks = np.array([int(np.argmin(np.abs(t - c))) for c in CHECK_T])
            e2s = np.zeros((ks.size, r.x.shape[1]))
            e2f = np.zeros_like(e2s)
            lay = r.layout
            ip = lay.slice("dp").start
        e2s += (tr_["smo"][ks] / sm.sigma[ks]) ** 2
        e2f += (tr_["fwd"][ks] / sm.sigma[ks]) ** 2
        # at the stored epochs (between them the smoothed σ is interpolated)
        sig_ok &= bool(np.all(sm.sigma_stored <= r.sigma[sm.stored] * (1 + 1e-9) + 1e-300))
        k_mid, k_end = ks[1], ks[2]
        tru = _trajectory().truth
        ti = np.rint((r.t[[k_mid, k_end]] - tru.t[0]) / 0.01).astype(int)
        hz_mid.append(hz_error(sm.nav, [k_mid], ti[:1])[0])
        hz_end_f.append(hz_error(r.nav[0], [k_end], ti[1:])[0])
        rm, rn = radii(r.nav[0][k_mid, 7], 0.0)
        sig_mid.append(math.hypot(sm.sigma[k_mid, ip] * rm, sm.sigma[k_mid, ip + 1] * rn * math.cos(r.nav[0][k_mid, 7])))
        sig_end_f.append(math.hypot(r.sigma[k_end, ip] * rm, r.sigma[k_end, ip + 1] * rn * math.cos(r.nav[0][k_end, 7])))
    n_checks = e2s.size
    a = level / n_checks
    lo, hi = math.sqrt(chi2.ppf(a / 2, runs) / runs), math.sqrt(chi2.ppf(1 - a / 2, runs) / runs)
    ratio_s = np.sqrt(e2s / runs)
    ratio_f = np.sqrt(e2f / runs)
    rms = lambda v: float(np.sqrt(np.mean(np.square(v))))  # noqa: E731
    return {
        "runs": runs, "band": [lo, hi], "checks": int(n_checks), "check_times_s": list(CHECK_T),
        "labels": list(lay.labels),
        "smoothed_rms_over_sigma": ratio_s.tolist(),
        "smoothed_ratio_min": float(ratio_s.min()), "smoothed_ratio_max": float(ratio_s.max()),
        "inside_band": bool(np.all((ratio_s >= lo) & (ratio_s <= hi))),
        "forward_over_smoothed_sigma_max": float(ratio_f.max()),
        "smoothed_sigma_le_forward": sig_ok,
        "outage_mid_smoothed_hz_rms_m": rms(hz_mid), "outage_end_forward_hz_rms_m": rms(hz_end_f),
        "outage_ratio": rms(hz_mid) / rms(hz_end_f),
        "outage_mid_smoothed_hz_sigma_m": float(np.mean(sig_mid)),
        "outage_end_forward_hz_sigma_m": float(np.mean(sig_end_f)),
    }


def odometer_outage(runs, seed0=300):
    """Outage-end horizontal error with and without the odometer (RMS over runs)."""
    out = {}
    tru = _trajectory().truth
    for odo in (False, True):
        f, s = [], []
        for j in range(runs):
            r, sm, _ = drive_run(seed0 + j, odometer=odo)
            k_end = int(np.argmin(np.abs(r.t - r.t[0] - (OUTAGE[1] - 0.1))))
            k_mid = int(np.argmin(np.abs(r.t - r.t[0] - 0.5 * (OUTAGE[0] + OUTAGE[1]))))
            ti = np.rint((r.t[[k_mid, k_end]] - tru.t[0]) / 0.01).astype(int)
            f.append(hz_error(r.nav[0], [k_end], ti[1:])[0])
            s.append(hz_error(sm.nav, [k_mid], ti[:1])[0])
        key = "odometer" if odo else "gnss_only"
        out[f"{key}_outage_end_forward_hz_rms_m"] = float(np.sqrt(np.mean(np.square(f))))
        out[f"{key}_outage_mid_smoothed_hz_rms_m"] = float(np.sqrt(np.mean(np.square(s))))
    return out


def storage(seed=7):
    """Smoothed results with the history in float32 and memory-mapped on disk against the
    in-memory float64 history: largest difference in smoothed σ units (x) and relative (σ)."""
    import tempfile
    d = drive_inputs(seed)
    ref = smooth(drive_forward(d, History(0.1)))
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, h in (("float32", History(0.1, dtype=np.float32)), ("spill", History(0.1, spill=tmp))):
            s = smooth(drive_forward(d, h))
            out[f"{name}_max_dx_over_sigma"] = float(np.max(np.abs(s.x_stored - ref.x_stored) / ref.sigma_stored))
            out[f"{name}_max_rel_dsigma"] = float(np.max(np.abs(s.sigma_stored / ref.sigma_stored - 1)))
            out[f"{name}_MB"] = h.nbytes() / 1e6
    return out


def speed(duration):
    """1 h (or ``duration`` s) of 200 Hz IMU, LC filter with P at 10 Hz: forward without and
    with the history, backward pass + corrected solution."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from estimation import lc_scenario
    from sinslab.fusion import loosely_coupled as integ
    from sinslab.fusion.spec import FixSpec
    meas, init, ft, fix, sig, P0, kw, truth = lc_scenario(duration)
    short = meas.slice(None, meas.t0 + 20.0)
    sel = ft <= short.t[-1]
    w = integ.loosely_coupled(short, init, FixSpec(ft[sel], fix[sel], sig), P0, progress=False,
                              history=History(0.1), **kw)
    smooth(w)                                    # compile outside the timing
    res = {}
    # the machine is shared: interleave the contenders, keep the best wall and CPU time
    wall = {"f": math.inf, "h": math.inf, "s": math.inf}
    cpu = dict(wall)

    def timed(key, fn):
        c0, t0 = time.process_time(), time.perf_counter()
        out = fn()
        wall[key] = min(wall[key], time.perf_counter() - t0)
        cpu[key] = min(cpu[key], time.process_time() - c0)
        return out

    for _ in range(5):
        timed("f", lambda: integ.loosely_coupled(meas, init, FixSpec(ft, fix, sig), P0,
                                                 progress=False, **kw))
        h = History(0.1)
        r = timed("h", lambda: integ.loosely_coupled(meas, init, FixSpec(ft, fix, sig), P0,
                                                     progress=False, history=h, **kw))
        sm = timed("s", lambda: smooth(r))
    best_f, best_h, best_s = wall["f"], wall["h"], wall["s"]
    k = np.rint((r.t - truth.t[0]) / meas.dt).astype(int)
    late = r.t > r.t[0] + min(300.0, duration / 3)
    rm, rn = radii(truth.lat[k], truth.h[k])

    def hz(rows):
        return np.hypot((rows[:, 7] - truth.lat[k]) * rm, (rows[:, 8] - truth.lon[k]) * rn * np.cos(truth.lat[k]))

    res.update({
        "speed_duration_s": duration, "speed_imu_samples": len(meas), "speed_filter_epochs": int(r.t.size),
        "forward_s": best_f, "forward_with_history_s": best_h, "backward_s": best_s,
        "backward_over_forward": best_s / best_f,
        "smoothed_total_over_forward": (best_h + best_s) / best_f,
        "forward_cpu_s": cpu["f"], "forward_with_history_cpu_s": cpu["h"], "backward_cpu_s": cpu["s"],
        "backward_over_forward_cpu": cpu["s"] / cpu["f"],
        "smoothed_total_over_forward_cpu": (cpu["h"] + cpu["s"]) / cpu["f"],
        "history_MB": h.nbytes() / 1e6, "history_stored_epochs": int(h.epochs.size),
        "forward_hz_err_rms_m": float(np.sqrt(np.mean(hz(r.nav)[late] ** 2))),
        "smoothed_hz_err_rms_m": float(np.sqrt(np.mean(hz(sm.nav)[late] ** 2))),
    })
    return res


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="small sizes (smoke test)")
    p.add_argument("--runs", type=int, default=None, help="Monte Carlo runs (default 100)")
    p.add_argument("--out", default=None, help="write the figures as JSON")
    a = p.parse_args(argv)
    runs = a.runs or (4 if a.quick else 100)
    out = {}
    t0 = time.perf_counter()
    out["monte_carlo"] = monte_carlo(runs)
    out["odometer"] = odometer_outage(max(2, runs // 5))
    out["storage"] = storage()
    out["speed"] = speed(120.0 if a.quick else 3600.0)
    out["elapsed_s"] = time.perf_counter() - t0
    txt = json.dumps(out, indent=1)
    if a.out:
        with open(a.out, "w") as fh:
            fh.write(txt)
    print(txt)
    return out


if __name__ == "__main__":
    main()
