"""transfer-alignment: paper 002 — velocity + attitude matching with four attitude
measurement forms (Euler difference, DCM elements, Kain's measured misalignment, the
"optimal" compensated form), 21 states, wing rock, Monte Carlo.

Simulation. The master (aircraft INS) is error-free; the slave is rigidly mounted with the
installation ``C_s^m = Ĉ_s^m exp(φ_α×)`` (nominal ``Ĉ_s^m`` from the installation
attitude, unknown residual φ_α). The carrier flies a wing rock (synthesised with exact
increments); the slave's body rate and specific force are the master's rotated into the
slave axes (no lever arm, no flexure). Each run draws the slave sensor errors (gyro bias,
gyro scale factor, accelerometer bias, accelerometer scale factor, 1σ from the paper) and
propagates the slave's navigation errors with the 21-state model along the true
trajectory (:func:`sinslab.methods.transfer.transfer_model`, 100 Hz sub-steps); its
computed attitude is ``Ĉ_s^n = exp(−φ×) C_s^n`` — so every measurement form sees the exact
nonlinear relation between the attitudes, which is what the paper's comparison is about.
The slave INS is initialised with ``C_m^n Ĉ_s^m`` (the nominal mounting). Measurements
at 10 Hz: velocity difference and one attitude form, with white noise.

Filters (:func:`sinslab.methods.transfer.batch_filter`, vectorised over the runs of a
Dask task): methods 1–3 estimate the whole installation λ (``C_s^m = exp(λ×)``, initial
estimate 0, σ covering it), method 4 the residual φ_α with the compensation. The
diagnosis re-runs methods 1–3 with the compensation, and with the EKF re-linearisation
at the current λ estimate, on the large installation.

The misalignment estimation error is the rotation vector of ``C_s^m,true ᵀ Ĉ_s^m exp(â×)``
[slave axes x, y, z], i.e. λ̂ − λ for methods 1–3 and φ̂_α − φ_α for method 4 to first
order.
"""
from __future__ import annotations

import time

import numpy as np

from sinslab.core import units
from sinslab.experiments.base import Claim, ExperimentConfig, Field, Figure, Metric, Q, QV, Result, Section, Table

NAME = "transfer-alignment"
PURPOSE = "paper 002: transfer alignment, velocity + attitude matching, four attitude measurement forms"
PAPER = ("Attitude matching method of transfer alignment based on the measured misalignment angle "
         "(基于量测失准角的传递对准姿态匹配方法; four attitude-matching methods, 21 states)")
NOTES = [
    "Not stated by the paper, assumed here: measurement noise 0.01 m/s (velocity) and 1 arcmin "
    "(attitude) 1-sigma; initial filter sigma 1 deg for the slave misalignment, 0.1 m/s for the "
    "velocity; installation sigma 1 deg (compensated) or |installation| + 1 deg per axis (whole "
    "installation estimated, methods 1-3).",
    "The paper simulates 5 s; the estimates are shown over the whole run and reported at 5 s and at the end.",
    "Slave navigation errors are propagated with the linear 21-state model along the true trajectory "
    "(100 Hz sub-steps); the attitude measurements are exact nonlinear functions of the attitudes.",
    "Installation attitude [pitch, roll, yaw] of the slave in the master body frame: C_s^m = "
    "R_z(yaw) R_x(pitch) R_y(roll) (sinslab Euler convention); residual phi_alpha in slave axes x, y, z.",
    "EKF diagnosis runs on at most filter.ekf_runs runs (per-run covariance, slower).",
    "Headings are clockwise from north; printed yaw = -heading.",
]


class Scenario(Section):
    latitude: Q("angle", ge="-80 deg", le="80 deg") = Field("34 deg", description="latitude")
    height: Q("length", ge="0 m", le="20 km") = Field("5000 m", description="flight height")
    speed: Q("velocity", ge="0 m/s", le="1000 m/s") = Field("200 m/s", description="carrier speed")
    heading: Q("angle", ge="-360 deg", le="360 deg") = Field("45 deg", description="heading, clockwise from north")
    duration: Q("time", gt="1 s", le="600 s") = Field("60 s", description="length of the alignment")
    sample_interval: Q("time", gt="0 s", le="0.05 s") = Field("0.01 s", description="slave IMU interval")
    wing_rock_amplitude: Q("angle", ge="0 deg", le="60 deg") = Field("20 deg", description="wing-rock roll amplitude")
    wing_rock_period: Q("time", gt="0 s") = Field("6 s", description="wing-rock period")
    report_time: Q("time", gt="0 s") = Field("5 s", description="the paper's simulation length: report time")


class Installation(Section):
    large: QV("angle") = Field("[10, 60, 8] deg", description="large installation attitude [pitch, roll, yaw]")
    small: QV("angle") = Field("[1, 1, 1] deg", description="small installation attitude [pitch, roll, yaw]")
    error: QV("angle") = Field("[40, 30, 20] arcmin", description="unknown installation error phi_alpha [x, y, z]")


class Imu(Section):
    gyro_bias: Q("angular_rate", ge="0 deg/h") = Field("3.3 deg/h", description="slave gyro bias 1σ")
    gyro_scale: Q("dimensionless", ge="0 ppm") = Field("200 ppm", description="slave gyro scale factor 1σ")
    accel_bias: Q("acceleration", ge="0 ug") = Field("500 ug", description="slave accelerometer bias 1σ (5e-4 g)")
    accel_scale: Q("dimensionless", ge="0 ppm") = Field("500 ppm", description="slave accelerometer scale factor 1σ")


class Filter(Section):
    kf_dt: Q("time", gt="0 s") = Field("0.1 s", description="filter (measurement) interval")
    vel_noise: Q("velocity", gt="0 m/s") = Field("0.01 m/s", description="velocity measurement noise 1σ")
    att_noise: Q("angle", gt="0 arcsec") = Field("1 arcmin", description="attitude measurement noise 1σ")
    att_sigma0: Q("angle", gt="0 arcsec") = Field("1 deg", description="initial slave misalignment σ")
    vel_sigma0: Q("velocity", gt="0 m/s") = Field("0.1 m/s", description="initial velocity error σ")
    inst_sigma0: Q("angle", gt="0 arcsec") = Field("1 deg", description="initial residual installation σ")
    ekf_runs: int = Field(50, ge=1, description="runs of the EKF diagnosis")
    converge_ratio: float = Field(3.0, gt=0, description="converged: RMS error at the end <= this × filter σ (every axis)")


class Config(ExperimentConfig):
    runs: int = Field(200, ge=1, le=100000, description="Monte Carlo runs")
    scenario: Scenario = Scenario()
    installation: Installation = Installation()
    imu: Imu = Imu()
    filter: Filter = Filter()


QUICK = {"runs": 30, "scenario": {"duration": "30 s"}, "filter": {"ekf_runs": 8}}

_M = ("euler", "dcm", "kain", "optimal")
_C = ("large", "small")
METRICS = {}
for _m in _M:
    for _c in _C:
        METRICS[f"misalign_rms_end_arcmin_{_m}_{_c}"] = Metric("arcmin", f"{_m}, {_c} installation: RMS over runs of the misalignment error at the end [x, y, z]")
        METRICS[f"misalign_sigma_end_arcmin_{_m}_{_c}"] = Metric("arcmin", f"{_m}, {_c}: filter σ at the end (mean over runs)")
        METRICS[f"misalign_rms_5s_arcmin_{_m}_{_c}"] = Metric("arcmin", f"{_m}, {_c}: RMS misalignment error at the report time (5 s)")
        METRICS[f"misalign_sigma_5s_arcmin_{_m}_{_c}"] = Metric("arcmin", f"{_m}, {_c}: filter σ at the report time")
        METRICS[f"converged_{_m}_{_c}"] = Metric("-", f"{_m}, {_c}: RMS at the end <= converge_ratio × σ on every axis")
    METRICS[f"update_cost_us_{_m}"] = Metric("us", f"{_m}: wall time of one z + H evaluation")
    METRICS[f"update_flops_{_m}"] = Metric("-", f"{_m}: floating-point operations of z + H (counted)")
for _m in _M[:3]:
    for _v in ("comp", "ekf"):
        METRICS[f"misalign_rms_end_arcmin_{_m}_large_{_v}"] = Metric("arcmin", f"{_m}, large installation, {'with the compensation' if _v == 'comp' else 'EKF re-linearised'}: RMS error at the end")
        METRICS[f"misalign_sigma_end_arcmin_{_m}_large_{_v}"] = Metric("arcmin", f"the same: filter σ at the end")
        METRICS[f"converged_{_m}_large_{_v}"] = Metric("-", "the same: converged")
METRICS.update({
    "dcm_heading_rms_c22zero_arcmin": Metric("arcmin", "DCM form, heading 90°: RMS φU estimation error at the end"),
    "kain_heading_rms_c22zero_arcmin": Metric("arcmin", "Kain form, same flight: RMS φU estimation error at the end"),
    "dcm_heading_sigma_c22zero_arcmin": Metric("arcmin", "DCM form, heading 90°: filter σ of φU at the end"),
    "dcm_phiU_H_norm_c22zero": Metric("-", "DCM form, heading 90°: largest norm of the φU column of H over the run"),
    "dcm_phiU_H_norm_nominal": Metric("-", "DCM form, nominal heading: smallest norm of the φU column of H over the run"),
    "dcm_H_rank_c22zero": Metric("-", "rank of the DCM H over [φ, λ] at heading 90°"),
    "h_fd_max_rel_err": Metric("-", "largest relative error of every H against central differences of its z"),
    "runs": Metric("-", "Monte Carlo runs"),
})
del _m, _c


# ----------------------------------------------------------------- scenario set-up ----
def _case(cfg: Config, inst_att, heading):
    """Trajectory-dependent arrays of one case: Φ per filter step, C_m^n, C_s^n."""
    from sinslab.core.attitude import euler_to_dcm
    from sinslab.methods import transfer as tm
    from sinslab.nav.errstate import NavPoint
    from sinslab.sim import trajectory as tr

    s, fl = cfg.scenario, cfg.filter
    dt, T = float(s.sample_interval), float(s.duration)
    k_kf = int(round(float(fl.kf_dt) / dt))
    start = tr.Start(lat=float(s.latitude), lon=108.0 * units.deg, h=float(s.height), speed=float(s.speed),
                     heading=float(heading))
    segs = [{"kind": "wing_rock", "duration": f"{T + 1.0} s", "amplitude": f"{s.wing_rock_amplitude / units.deg} deg",
             "period": f"{float(s.wing_rock_period)} s", "ramp": f"{min(float(s.wing_rock_period), T / 4)} s"}]
    gen = tr.generate(segs, start, dt, duration=T)
    truth, imu = gen.truth, gen.imu
    Cm = euler_to_dcm(truth.att)                          # (N+1, 3, 3)
    Csm_nom = euler_to_dcm(np.asarray(inst_att))
    Csm = Csm_nom @ _rv2dcm(np.asarray(cfg.installation.error))
    Cs = Cm @ Csm
    N = len(imu)
    wb_m = np.vstack([imu.dtheta[:1], imu.dtheta]) / dt   # epoch k uses sample k-1
    fb_m = np.vstack([imu.dv[:1], imu.dv]) / dt
    wb_s = wb_m @ Csm                                     # C_m^s ω = Csmᵀ ω -> row form ω Csm
    fb_s = fb_m @ Csm
    model = tm.transfer_model()
    mid = np.arange(N)
    F = model.F(NavPoint(truth.lat[mid], truth.h[mid], truth.vel[mid], Cs[mid], fb_s[mid], wb_s[mid]))
    n = model.n
    Fd = F * dt
    Phis = np.eye(n) + Fd + 0.5 * Fd @ Fd                 # per sample, O(dt³)
    K = N // k_kf
    Phis = Phis[:K * k_kf].reshape(K, k_kf, n, n)
    Phi = np.broadcast_to(np.eye(n), (K, n, n)).copy()
    for j in range(k_kf):
        Phi = Phis[:, j] @ Phi
    ep = np.arange(K + 1) * k_kf
    return dict(Phi=Phi, Cm=Cm[ep], Cs=Cs[ep], t=truth.t[ep], Csm=Csm, Csm_nom=Csm_nom, n=n,
                layout=model.layout)


def _rv2dcm(v):
    from sinslab.core.attitude import rotvec_to_dcm
    return rotvec_to_dcm(np.asarray(v, float))


def _params(cfg):
    """The plain numbers a Monte Carlo task needs."""
    fl, im = cfg.filter, cfg.imu
    return dict(gyro_bias=float(im.gyro_bias), gyro_scale=float(im.gyro_scale), accel_bias=float(im.accel_bias),
                accel_scale=float(im.accel_scale), vel_noise=float(fl.vel_noise), att_noise=float(fl.att_noise),
                att_sigma0=float(fl.att_sigma0), vel_sigma0=float(fl.vel_sigma0), inst_sigma0=float(fl.inst_sigma0))


def _filter_setup(p, case, kind, compensated):
    """(match, P0) of one filter variant on one case."""
    from sinslab.core.attitude import dcm_to_rotvec
    from sinslab.methods import transfer as tm

    match = tm.AttitudeMatch(kind, case["Csm_nom"] if compensated else None)
    if compensated:
        s_inst = np.full(3, p["inst_sigma0"])
    else:
        s_inst = np.abs(dcm_to_rotvec(case["Csm_nom"])) + 1.0 * units.deg
    sig0 = np.concatenate([np.full(3, p["att_sigma0"]), np.full(3, p["vel_sigma0"]), s_inst,
                           np.full(3, p["gyro_bias"]), np.full(3, p["gyro_scale"]),
                           np.full(3, p["accel_bias"]), np.full(3, p["accel_scale"])])
    return match, np.diag(sig0 ** 2)


def _variants():
    """(key, case, kind, compensated, ekf) of every filter run."""
    v = []
    for c in _C:
        for m in _M:
            v.append((f"{m}_{c}", c, m, m == "optimal", False))
    for m in _M[:3]:
        v.append((f"{m}_large_comp", "large", m, True, False))
        v.append((f"{m}_large_ekf", "large", m, False, True))
    v.append(("dcm_c22", "c22", "dcm", False, False))
    v.append(("kain_c22", "c22", "kain", False, False))
    return v


def _batch(seeds, p, cases, record_every, ekf_runs, variants=None):
    """One Dask task: the runs of ``seeds`` through every filter variant."""
    from sinslab.core.attitude import dcm_to_rotvec, rotvec_to_dcm, misalignment
    from sinslab.methods import transfer as tm

    R = len(seeds)
    rngs = [np.random.default_rng(s) for s in seeds]
    sens = np.stack([np.concatenate([r.standard_normal(3) * p["gyro_bias"], r.standard_normal(3) * p["gyro_scale"],
                                     r.standard_normal(3) * p["accel_bias"],
                                     r.standard_normal(3) * p["accel_scale"]]) for r in rngs])
    noise = {c: np.stack([r.standard_normal((cases[c]["Cm"].shape[0], 6)) for r in rngs]) for c in cases}
    out = {}
    truth_cache = {}
    for key, c, kind, comp, ekf in (variants or _variants()):
        if c not in cases:
            continue
        case = cases[c]
        if c not in truth_cache:
            n = case["n"]
            Kp1 = case["Cm"].shape[0]
            x = np.zeros((R, n))
            x[:, 9:] = sens
            x[:, 0:3] = misalignment(case["Cs"][0], case["Cm"][0] @ case["Csm_nom"])[None, :]
            xs = np.empty((R, Kp1, n))
            xs[:, 0] = x
            for k in range(Kp1 - 1):
                x = x @ case["Phi"][k].T
                xs[:, k + 1] = x
            nz = noise[c]
            C_hat = rotvec_to_dcm(-(xs[:, :, 0:3] + nz[:, :, 3:] * p["att_noise"])) @ case["Cs"][None]
            z_vel = xs[:, :, 3:6] + nz[:, :, :3] * p["vel_noise"]
            truth_cache[c] = (xs, C_hat, z_vel)
        xs, C_hat, z_vel = truth_cache[c]
        match, P0 = _filter_setup(p, case, kind, comp)
        nr = min(R, ekf_runs) if ekf else R
        est, sig = tm.batch_filter(case["Phi"], case["Cm"], z_vel[:nr], C_hat[:nr], match, np.zeros(case["n"]), P0,
                                   np.full(3, p["vel_noise"] ** 2), np.full(3, p["att_noise"] ** 2),
                                   relinearise=ekf, record_every=record_every)
        rec = np.arange(0, case["Cm"].shape[0], record_every)
        a_hat = est[:, :, 6:9]
        Cest = match.compensation[None, None] @ rotvec_to_dcm(a_hat)
        err = dcm_to_rotvec(np.einsum("ji,rkjl->rkil", case["Csm"], Cest))
        sa = sig[..., 6:9] if sig.ndim == 3 else np.broadcast_to(sig[None, :, 6:9], (nr,) + sig[:, 6:9].shape)
        if nr < R:    # pad the EKF diagnosis with NaN runs (statistics use nan-aware means)
            pad = np.full((R - nr,) + err.shape[1:], np.nan)
            err, sa = np.concatenate([err, pad]), np.concatenate([sa, pad])
        out[f"err_{key}"] = err
        out[f"sig_{key}"] = np.ascontiguousarray(sa)
        if c == "c22":
            phiU_err = est[:, :, 2] - xs[:, rec, 2]
            sU = sig[:, 2] if sig.ndim == 2 else sig[:, :, 2]
            out[f"phiU_{key}"] = phiU_err
            out[f"sigU_{key}"] = np.broadcast_to(sU, phiU_err.shape).copy()
    return out


def _fd_check(rng, n=20):
    """Largest relative error of every H (kinds × compensation × EKF point) vs central differences."""
    from sinslab.core.attitude import euler_to_dcm
    from sinslab.methods import transfer as tm

    worst = 0.0
    for kind in _M:
        for comp in (False, True):
            for ekf in (False, True):
                for _ in range(n):
                    att = lambda: np.array([rng.uniform(-60, 60), rng.uniform(-170, 170), rng.uniform(-179, 179)]) * units.deg  # noqa: E731
                    Cm = euler_to_dcm(att())
                    m = tm.AttitudeMatch(kind, euler_to_dcm(att()) if comp else None)
                    a0 = rng.normal(0, 0.5, 3) if ekf else np.zeros(3)
                    H = m.H(Cm, a0=a0)
                    J = np.zeros((3, 6))
                    h = 1e-6
                    for i in range(6):
                        d = np.zeros(6)
                        d[i] = h
                        J[:, i] = (m.predict(Cm, d[:3], a0 + d[3:]) - m.predict(Cm, -d[:3], a0 - d[3:])) / (2 * h)
                    worst = max(worst, float(np.max(np.abs(H - J)) / np.max(np.abs(J))))
    return worst


def _cost(case):
    """Wall time [µs] of one z + H evaluation per form (median of repeated timings)."""
    from sinslab.methods import transfer as tm

    Cm, Ch = case["Cm"][10], case["Cs"][10]
    res = {}
    for kind in _M:
        m = tm.AttitudeMatch(kind, case["Csm_nom"] if kind == "optimal" else None)
        ts = []
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(200):
                m.z(Cm, Ch)
                m.H(Cm, Ch)
            ts.append((time.perf_counter() - t0) / 200 * 1e6)
        res[kind] = float(np.median(ts))
    return res


# ----------------------------------------------------------------------- run ---------
def run(cfg: Config, ctx) -> Result:
    from sinslab.app import plotting as P
    from sinslab.estimation import montecarlo as mc
    from sinslab.methods import transfer as tm

    s, ins, fl = cfg.scenario, cfg.installation, cfg.filter
    ctx.log(f"{NAME}: trajectories")
    cases = {"large": _case(cfg, ins.large, s.heading), "small": _case(cfg, ins.small, s.heading),
             "c22": _case(cfg, ins.small, 90.0 * units.deg)}
    t_ep = cases["large"]["t"]
    record_every = max(1, int(round(0.5 / float(fl.kf_dt))))
    rec = np.arange(0, t_ep.size, record_every)
    t = t_ep[rec] - t_ep[0]
    i5 = int(np.argmin(np.abs(t - float(s.report_time))))
    n = int(cfg.runs)
    ctx.log(f"{NAME}: Monte Carlo, {n} runs")
    res = mc.run_campaign(_batch, n, cfg.seed, scheduler=ctx.scheduler,
                          kwargs=dict(p=_params(cfg), cases=cases,
                                      record_every=record_every, ekf_runs=int(fl.ekf_runs)))
    # every run gets the EKF variant only in its task's first ekf_runs: keep the first ekf_runs overall
    am = 1.0 / units.arcmin
    metrics, rows, stats = {}, [], {}
    for key, c, kind, comp, ekf in _variants():
        err, sg = res[f"err_{key}"], res[f"sig_{key}"]
        if ekf:
            ok = np.where(np.all(np.isfinite(err[:, 0]), -1))[0][:int(fl.ekf_runs)]
            err, sg = err[ok], sg[ok]
        rms = np.sqrt(np.mean(err ** 2, 0)) * am          # (M, 3)
        sig = np.mean(sg, 0) * am
        conv = bool(np.all(rms[-1] <= float(fl.converge_ratio) * sig[-1]))
        stats[key] = dict(rms=rms, sig=sig, conv=conv, first=err[0] * am, first_sig=sg[0] * am)
        if key.endswith("_c22"):
            continue
        metrics[f"misalign_rms_end_arcmin_{key}"] = rms[-1]
        metrics[f"misalign_sigma_end_arcmin_{key}"] = sig[-1]
        if not (comp and kind != "optimal") and not ekf:
            metrics[f"misalign_rms_5s_arcmin_{key}"] = rms[i5]
            metrics[f"misalign_sigma_5s_arcmin_{key}"] = sig[i5]
        metrics[f"converged_{key}"] = conv
        rows.append(dict(filter=key, case=c, kind=kind, compensation=comp, ekf=ekf, runs=err.shape[0],
                         rms_5s_x=rms[i5, 0], rms_5s_y=rms[i5, 1], rms_5s_z=rms[i5, 2],
                         sig_5s_x=sig[i5, 0], sig_5s_y=sig[i5, 1], sig_5s_z=sig[i5, 2],
                         rms_end_x=rms[-1, 0], rms_end_y=rms[-1, 1], rms_end_z=rms[-1, 2],
                         sig_end_x=sig[-1, 0], sig_end_y=sig[-1, 1], sig_end_z=sig[-1, 2], converged=conv))
    # C22 = 0
    pU = {k: res[f"phiU_{k}_c22"] for k in ("dcm", "kain")}
    rmsU = {k: float(np.sqrt(np.mean(v[:, -1] ** 2))) * am for k, v in pU.items()}
    sigU = float(np.mean(res["sigU_dcm_c22"][:, -1])) * am
    c22 = cases["c22"]
    Hn = [np.linalg.norm(tm.AttitudeMatch("dcm").H(C)[:, 2]) for C in c22["Cm"]]
    Hn_nom = [np.linalg.norm(tm.AttitudeMatch("dcm").H(C)[:, 2]) for C in cases["small"]["Cm"]]
    rank = int(np.linalg.matrix_rank(tm.AttitudeMatch("dcm").H(c22["Cm"][c22["Cm"].shape[0] // 2]), tol=1e-6))
    metrics.update(dcm_heading_rms_c22zero_arcmin=rmsU["dcm"], kain_heading_rms_c22zero_arcmin=rmsU["kain"],
                   dcm_heading_sigma_c22zero_arcmin=sigU, dcm_phiU_H_norm_c22zero=float(np.max(Hn)),
                   dcm_phiU_H_norm_nominal=float(np.min(Hn_nom)), dcm_H_rank_c22zero=rank)
    fd = _fd_check(ctx.rng(99))
    metrics["h_fd_max_rel_err"] = fd
    cost = _cost(cases["large"])
    for k in _M:
        metrics[f"update_cost_us_{k}"] = cost[k]
        metrics[f"update_flops_{k}"] = int(tm.FLOPS[k])
    metrics["runs"] = n

    # ---- claims (SPEC 002 "reproduced means")
    claims = []
    big = {m: metrics[f"converged_{m}_large"] for m in _M}
    claims.append(Claim.equals("large_methods_1_3_fail",
                               "large installation: methods 1-3 (euler, dcm, kain) do not converge to the true misalignment",
                               [big["euler"], big["dcm"], big["kain"]], [False, False, False],
                               names=["euler", "dcm", "kain"]))
    claims.append(Claim.equals("large_method_4_converges", "large installation: method 4 (optimal) converges",
                               big["optimal"], True))
    claims.append(Claim.equals("small_all_converge", "small installation: all four methods converge",
                               [metrics[f"converged_{m}_small"] for m in _M], [True] * 4, names=list(_M)))
    claims.append(Claim.at_most("c22_phiU_column_zero", "DCM form at heading 90° (C22 = 0): φU column of H vanishes",
                                metrics["dcm_phiU_H_norm_c22zero"], 1e-3))
    claims.append(Claim.at_least("c22_heading_worse", "DCM form at C22 = 0: heading error RMS at the end ≥ 2 × Kain's",
                                 rmsU["dcm"] / max(rmsU["kain"], 1e-12), 2.0, "×"))
    claims.append(Claim.at_most("h_fd", "every H matches central differences of its z", fd, 1e-6))
    claims.append(Claim.equals("compensation_fixes_1_3",
                               "diagnosis: with the installation compensation methods 1-3 converge on the large installation",
                               [metrics[f"converged_{m}_large_comp"] for m in _M[:3]], [True] * 3,
                               names=list(_M[:3])))

    # why a convergence verdict is what it is: the worst RMS / σ ratio at the end
    notes = []
    for key, st in stats.items():
        ratio = st["rms"][-1] / st["sig"][-1]
        j = int(np.argmax(ratio))
        notes.append(f"{key}: RMS/σ at the end {np.round(ratio, 2).tolist()} (worst axis {'xyz'[j]}: "
                     f"RMS {st['rms'][-1, j]:.3g}′, σ {st['sig'][-1, j]:.3g}′) -> "
                     f"{'converged' if st['conv'] else 'not converged'} at ratio {float(fl.converge_ratio):g}")

    # ---- figures
    figs = []
    for c in _C:
        fig, ax = P.figure(4, 3, width=12.0, row_height=2.2, title=f"{c} installation: misalignment estimation error ± σ")
        for i, m in enumerate(_M):
            st = stats[f"{m}_{c}"]
            for j, a in enumerate("xyz"):
                axx = ax[i * 3 + j]
                axx.plot(t, st["first"][:, j], lw=0.8, label="run 0 error")
                axx.fill_between(t, -st["first_sig"][:, j], st["first_sig"][:, j], alpha=0.3, label="±σ")
                axx.plot(t, st["rms"][:, j], "k--", lw=0.8, label="RMS over runs")
                axx.set_title(f"{m} {a}", fontsize="small")
                if j == 0:
                    axx.set_ylabel("arcmin")
        ax[0].legend(fontsize="x-small")
        for axx in ax[-3:]:
            axx.set_xlabel("t [s]")
        figs.append(Figure(f"misalign_{c}", fig, f"Installation misalignment estimation error of run 0 with its filter σ "
                                                 f"and the RMS over {n} runs, per method, {c} installation (paper Figs 1-4)"))
    fig, ax = P.figure(1, 2, width=10.0, row_height=3.2, title="heading 90° (C22 = 0): φU estimation error")
    for k in ("dcm", "kain"):
        ax[0].plot(t, np.sqrt(np.mean(pU[k] ** 2, 0)) * am, label=f"{k} RMS")
        ax[0].plot(t, np.mean(res[f"sigU_{k}_c22"], 0) * am, "--", label=f"{k} σ")
    ax[0].set_ylabel("arcmin")
    ax[0].legend(fontsize="small")
    ax[1].plot(c22["t"] - c22["t"][0], Hn, label="heading 90°")
    ax[1].plot(cases["small"]["t"] - cases["small"]["t"][0], Hn_nom, label=f"heading {s.heading / units.deg:g}°")
    ax[1].set_ylabel("|H[:, φU]| (DCM form)")
    ax[1].legend(fontsize="small")
    for a in ax:
        a.set_xlabel("t [s]")
    figs.append(Figure("c22_zero", fig, "DCM element form at heading 90° (C22 = 0): the φU column of H vanishes and "
                                        "the heading error is estimated only through velocity matching"))
    import pandas as pd
    series = {}
    for key in stats:
        st = stats[key]
        series[f"rms_{key}"] = {"t": t, **{f"rms_{a}_arcmin": st["rms"][:, j] for j, a in enumerate("xyz")},
                                **{f"sigma_{a}_arcmin": st["sig"][:, j] for j, a in enumerate("xyz")}}
    tables = [Table("misalignment_stats", pd.DataFrame(rows),
                    f"Misalignment estimation error RMS over runs and mean filter σ [arcmin] at {t[i5]:g} s and at the end")]
    return Result(metrics=metrics, claims=claims, series=series, figures=figs, tables=tables, notes=notes)
