"""transfer-alignment: paper 002 — velocity + attitude matching with four attitude
measurement forms (Euler difference, DCM elements, Kain's measured misalignment, the
"optimal" compensated form), 21 states, wing rock, Monte Carlo.

Simulation (the paper's experiment, ``montecarlo.slave = "strapdown"``, the default). The
carrier flies a wing rock (synthesised with exact increments). The master is an aligned
aircraft INS: its solution is the truth with a constant attitude error and a constant
velocity error per run (``master.*``). The slave is rigidly mounted with the installation
``C_s^m = Ĉ_s^m exp(φ_α×)`` (nominal ``Ĉ_s^m`` from the installation attitude, unknown
residual φ_α); its IMU reads the master's true increments rotated into the slave axes (with the
rigid lever arm ``installation.lever_arm``, default none, compensated in the velocity match;
no flexure) with its own errors drawn per run (gyro bias and scale factor,
accelerometer bias and scale factor, 1σ from the paper). Each slave INS is mechanised
(:mod:`sinslab.nav.strapdown`, the lanes of :class:`sinslab.nav.lanes.LaneBank`), starts
from the master's solution times the nominal mounting, and is aligned closed loop
(:func:`sinslab.methods.transfer.align_lanes`): after every 10 Hz update the estimates of
φ, δv and of the sensor errors are fed back. Measurements: velocity difference and one
attitude form, plus white noise drawn per component with exactly the variances R of the
filter.

The linear-model Monte Carlo (``montecarlo.slave = "linear"``) propagates the slave errors
with the 21-state model along the true trajectory and never feeds back; it runs on the
same draws, and with the strapdown slave it is run beside it so the report shows how far
the two agree.

Filters: methods 1–3 estimate the whole installation λ (``C_s^m = exp(λ×)``, initial
estimate 0, σ covering it), method 4 the residual φ_α with the compensation. The
``_comp`` variants run methods 1–3 with the compensation; the EKF diagnosis re-linearises
methods 1–3 at the current λ estimate on the large installation.

Scoring: each form is compared with the truth in the parameterisation it estimates
(:func:`sinslab.methods.transfer.parameterisation`: Euler-angle triple for the Euler and
DCM forms, rotation vector for Kain's and for every EKF-form filter) through one conversion
(:func:`sinslab.methods.transfer.installation_parameters`); the rotation-vector score of
every form is reported beside it, so the verdict table shows which failures are the
form's and which the scoring's. A run whose slave attitude error leaves
``filter.divergence_bound`` in the second half of the run, or whose filter asks for an attitude correction
beyond ``filter.correction_guard`` (or turns non-finite) is counted as diverged and left
out of the statistics.
"""
from __future__ import annotations

import time
from typing import Literal

import numpy as np
from pydantic import model_validator

from sinslab.core import units
from sinslab.experiments.base import (Axis, Claim, ExperimentConfig, Field, Figure, Metric, Q, QV, Result,
                                      Section, Table, imu_section)

NAME = "transfer-alignment"
PURPOSE = "paper 002: transfer alignment, velocity + attitude matching, four attitude measurement forms"
PAPER = ("Attitude matching method of transfer alignment based on the measured misalignment angle "
         "(基于量测失准角的传递对准姿态匹配方法; four attitude-matching methods, 21 states)")
NOTES = [
    "From the paper: the master is error-free (its errors are orders of magnitude below the slave's), "
    "5 s of wing rock simulated. Not stated by the paper, assumed here: measurement noise 0.01 m/s "
    "(velocity) and 1 arcmin (attitude) 1-sigma; the wing rock building up over scenario.wing_rock_ramp; "
    "initial filter sigma 1 deg for the slave misalignment, 0.1 m/s for the velocity; installation sigma "
    "1 deg (compensated) or |installation| + 1 deg per axis (whole installation estimated, methods 1-3); "
    "converged = RMS at the end <= 3 filter sigma. The robustness section shows which verdicts move with "
    "the master's errors, the horizon, the onset and the noise figures.",
    "The verdicts are taken at the end of the run (the paper's 5 s by default); with a longer run the "
    "estimates at scenario.report_time are reported too.",
    "Slave: a mechanised INS per run and filter, closed loop (phi, dv and the sensor errors fed back after "
    "each update). Covariance and gain of the paper-form filters are computed once on the nominal path "
    "(true master attitude, nominal mounting) and shared by the runs; the EKF diagnosis keeps one per run.",
    "Installation attitude [pitch, roll, yaw] of the slave in the master body frame: C_s^m = "
    "R_z(yaw) R_x(pitch) R_y(roll) (sinslab Euler convention); residual phi_alpha in slave axes x, y, z.",
    "EKF diagnosis runs on the first filter.ekf_runs runs (per-run covariance, slower).",
    "Headings are clockwise from north; printed yaw = -heading.",
]


class Scenario(Section):
    latitude: Q("angle", ge="-80 deg", le="80 deg") = Field("34 deg", description="latitude")
    height: Q("length", ge="0 m", le="20 km") = Field("5000 m", description="flight height")
    speed: Q("velocity", ge="0 m/s", le="1000 m/s") = Field("200 m/s", description="carrier speed")
    heading: Q("angle", ge="-360 deg", le="360 deg") = Field("45 deg", description="heading, clockwise from north")
    duration: Q("time", gt="1 s", le="600 s") = Field("5 s", description="length of the alignment (the paper's 5 s)")
    sample_interval: Q("time", gt="0 s", le="0.05 s") = Field("0.01 s", description="slave IMU interval")
    wing_rock_amplitude: Q("angle", ge="0 deg", le="60 deg") = Field("20 deg", description="wing-rock roll amplitude")
    wing_rock_period: Q("time", gt="0 s") = Field("6 s", description="wing-rock period")
    wing_rock_ramp: Q("time", ge="0 s") = Field(
        "1.25 s", description="build-up of the wing rock from level flight (not in the paper; 0: an abrupt start)")
    report_time: Q("time", gt="0 s") = Field("5 s", description="the paper's simulation length: also reported "
                                             "inside a longer run")


class Installation(Section):
    large: QV("angle") = Field("[10, 60, 8] deg", description="large installation attitude [pitch, roll, yaw]")
    small: QV("angle") = Field("[1, 1, 1] deg", description="small installation attitude [pitch, roll, yaw]")
    error: QV("angle") = Field("[40, 30, 20] arcmin", description="unknown installation error phi_alpha [x, y, z]")
    lever_arm: QV("length", le="100 m", ge="-100 m") = Field(
        "[0, 0, 0] m", description="slave IMU position from the master's in master body axes (x right, y forward, "
                                   "z up); rigid, known, compensated in the velocity match")


Imu = imu_section("Imu", {
    "gyro_bias_sigma": ("3.3 deg/h", "slave"),
    "gyro_scale_factor_sigma": ("200 ppm", "slave"),
    "accel_bias_sigma": ("500 ug", "slave, 5e-4 g"),
    "accel_scale_factor_sigma": ("500 ppm", "slave"),
}, scalar=True, renamed={"gyro_bias": "gyro_bias_sigma", "gyro_scale": "gyro_scale_factor_sigma",
                         "accel_bias": "accel_bias_sigma", "accel_scale": "accel_scale_factor_sigma"})


class Master(Section):
    att_error: Q("angle", ge="0 arcsec", le="1 deg") = Field(
        "0 arcmin", description="master attitude error 1σ per axis (E, N, U), constant over a run (paper: "
                                "error-free)")
    vel_error: Q("velocity", ge="0 m/s", le="1 m/s") = Field(
        "0 m/s", description="master velocity error 1σ per axis, constant over a run (paper: error-free)")


class Filter(Section):
    kf_dt: Q("time", gt="0 s") = Field("0.1 s", description="filter (measurement) interval")
    vel_noise: Q("velocity", gt="0 m/s") = Field("0.01 m/s", description="velocity measurement noise 1σ")
    att_noise: Q("angle", gt="0 arcsec") = Field("1 arcmin", description="attitude measurement noise 1σ")
    p0_attitude: Q("angle", gt="0 arcsec") = Field("1 deg", description="1σ of the slave misalignment in P0")
    p0_velocity: Q("velocity", gt="0 m/s") = Field("0.1 m/s", description="1σ of the velocity error in P0")
    p0_installation: Q("angle", gt="0 arcsec") = Field("1 deg", description="1σ of the residual installation in P0")
    ekf_runs: int = Field(50, ge=1, description="runs of the EKF diagnosis")
    converge_ratio: float = Field(3.0, gt=0, description="converged: no run diverged and RMS error at the end <= this × filter σ (every axis)")
    divergence_bound: Q("angle", gt="0 deg", le="90 deg") = Field(
        "5 deg", description="a run whose slave attitude error exceeds this in the second half of the run has diverged")
    correction_guard: Q("angle", gt="0 deg", le="180 deg") = Field(
        "30 deg", description="an update asking for a larger attitude correction stops the run (diverged): "
                              "the small-angle error model no longer holds")
    renamed = {"att_sigma0": "p0_attitude", "vel_sigma0": "p0_velocity", "inst_sigma0": "p0_installation"}


class Montecarlo(Section):
    slave: Literal["strapdown", "linear"] = Field(
        "strapdown", description="strapdown: mechanised slave INS aligned closed loop (the paper's set-up); "
                                 "linear: the 21-state error model along the truth, open loop (fast)")
    compare_linear: bool = Field(True, description="with the strapdown slave, also run the linear model on the same draws")


class Config(ExperimentConfig):
    runs: int = Field(200, ge=1, le=100000, description="Monte Carlo runs")
    scenario: Scenario = Scenario()
    installation: Installation = Installation()
    imu: Imu = Imu()
    master: Master = Master()
    filter: Filter = Filter()
    montecarlo: Montecarlo = Montecarlo()

    @model_validator(mode="after")
    def _onset_fits(self):
        s = self.scenario
        if 2 * float(s.wing_rock_ramp) > float(s.duration) + 1.0:
            raise ValueError(f"scenario.wing_rock_ramp ({float(s.wing_rock_ramp):g} s) must fit twice in the "
                             f"wing rock of scenario.duration + 1 s ({float(s.duration) + 1:g} s)")
        return self


QUICK = {"runs": 30, "filter": {"ekf_runs": 8}}

#: CPU seconds of each ``sinslab demo`` run at full scale, robustness re-runs included
#: (quiet machine): the demo starts the longest first.
DEMO_COST_S = {"": 11}

_M = ("euler", "dcm", "kain", "optimal")
_F = _M + ("euler_comp", "dcm_comp", "kain_comp")      # forms scored per case
_C = ("large", "small")
METRICS = {
    "slave_model": Metric("-", "how the slave errors were propagated: strapdown (mechanised, closed loop) or linear"),
    "feedback": Metric("-", "estimates fed back into the slave INS after each update"),
    "linear_verdicts_agree": Metric("-", "forms × cases whose linear-model verdict equals the strapdown one"),
    "linear_verdicts_total": Metric("-", "forms × cases compared between the linear model and the strapdown slave"),
}
for _f in _F:
    _form = _f.replace("_comp", " with the compensation")
    for _c in _C:
        _k = f"{_f}_{_c}"
        METRICS[f"misalign_rms_end_arcmin_{_k}"] = Metric("arcmin", f"{_form}, {_c} installation: RMS over runs of the installation estimation error at the end (own parameterisation) [x, y, z]")
        METRICS[f"misalign_sigma_end_arcmin_{_k}"] = Metric("arcmin", f"{_form}, {_c}: filter σ at the end (mean over runs)")
        METRICS[f"misalign_rms_5s_arcmin_{_k}"] = Metric("arcmin", f"{_form}, {_c}: RMS installation error at the report time (5 s)")
        METRICS[f"misalign_sigma_5s_arcmin_{_k}"] = Metric("arcmin", f"{_form}, {_c}: filter σ at the report time")
        METRICS[f"rms_over_sigma_5s_{_k}"] = Metric("-", f"{_form}, {_c}: RMS / σ at the report time per axis (own parameterisation)")
        METRICS[f"rms_over_sigma_{_k}"] = Metric("-", f"{_form}, {_c}: RMS / σ at the end per axis (own parameterisation)")
        METRICS[f"rms_over_sigma_rotvec_{_k}"] = Metric("-", f"{_form}, {_c}: RMS / σ at the end per axis scored as a rotation vector")
        METRICS[f"margin_{_k}"] = Metric("-", f"{_form}, {_c}: converge_ratio minus the worst axis RMS/σ (negative: fails; null: every run diverged)")
        METRICS[f"diverged_runs_{_k}"] = Metric("-", f"{_form}, {_c}: runs that diverged")
        METRICS[f"converged_{_k}"] = Metric("-", f"{_form}, {_c}: no run diverged and RMS at the end <= converge_ratio × σ on every axis")
        METRICS[f"converged_linear_{_k}"] = Metric("-", f"{_form}, {_c}: the verdict of the linear-model Monte Carlo on the same draws")
        METRICS[f"linear_minus_strapdown_rms_arcmin_{_k}"] = Metric("arcmin", f"{_form}, {_c}: RMS over runs of the difference of the final estimates, linear model minus strapdown slave")
for _m in _M:
    METRICS[f"update_cost_us_{_m}"] = Metric("us", f"{_m}: wall time of one z + H evaluation")
    METRICS[f"update_flops_{_m}"] = Metric("-", f"{_m}: floating-point operations of z + H (counted)")
for _m in _M[:3]:
    METRICS[f"misalign_rms_end_arcmin_{_m}_large_ekf"] = Metric("arcmin", f"{_m}, large installation, EKF re-linearised: RMS error at the end")
    METRICS[f"misalign_sigma_end_arcmin_{_m}_large_ekf"] = Metric("arcmin", "the same: filter σ at the end")
    METRICS[f"diverged_runs_{_m}_large_ekf"] = Metric("-", "the same: runs that diverged")
    METRICS[f"converged_{_m}_large_ekf"] = Metric("-", "the same: converged")
METRICS.update({
    "dcm_heading_rms_c22zero_arcmin": Metric("arcmin", "DCM form, heading 90°: RMS heading (φU) error at the end"),
    "kain_heading_rms_c22zero_arcmin": Metric("arcmin", "Kain form, same flight: RMS heading (φU) error at the end"),
    "dcm_heading_sigma_c22zero_arcmin": Metric("arcmin", "DCM form, heading 90°: filter σ of φU at the end"),
    "dcm_phiU_H_norm_c22zero": Metric("-", "DCM form, heading 90°: largest norm of the φU column of H over the run"),
    "dcm_phiU_H_norm_nominal": Metric("-", "DCM form, nominal heading: smallest norm of the φU column of H over the run"),
    "dcm_H_rank_c22zero": Metric("-", "rank of the DCM H over [φ, λ] at heading 90°"),
    "h_fd_max_rel_err": Metric("-", "largest relative error of every H against central differences of its z"),
    "runs": Metric("-", "Monte Carlo runs"),
})
del _f, _c, _k, _m, _form


# ----------------------------------------------------------------- scenario set-up ----
def _lever(imu, truth, Cm, r):
    """Slave increments' velocity part and the slave's velocity with a lever arm.

    The slave IMU sits at ``r`` [m] (master body axes) from the master's navigation point,
    rigidly: its specific force is ``f_m + ω̇ × r + ω × (ω × r)`` (ω = ω_im^m, the gravity
    difference over r neglected), its velocity ``v_m + C_m^n (ω_nm^m × r)``. Returns the
    master-axis velocity increments at the slave (N, 3) and the slave velocity at the
    IMU epochs (N+1, 3) [m/s]. The rate at the sample boundaries is interpolated between
    the neighbouring samples' mean rates, so ∫ω̇ dt telescopes exactly.
    """
    from sinslab.core import earth

    dt = imu.dt
    w = imu.dtheta / dt
    wb = np.empty((w.shape[0] + 1, 3))
    wb[1:-1] = 0.5 * (w[:-1] + w[1:])
    wb[0] = 1.5 * w[0] - 0.5 * w[1]
    wb[-1] = 1.5 * w[-1] - 0.5 * w[-2]
    dv = imu.dv + np.cross(wb[1:] - wb[:-1], r) + dt * np.cross(w, np.cross(w, r))
    rm, rn = earth.radii(truth.lat, truth.h)
    ve, vn = truth.vel[:, 0], truth.vel[:, 1]
    w_in = earth.wie_n(truth.lat) + np.stack([-vn / (rm + truth.h), ve / (rn + truth.h),
                                              ve * np.tan(truth.lat) / (rn + truth.h)], -1)
    w_nm = wb - np.einsum("kji,kj->ki", Cm, w_in)              # C_n^m ω_in^n
    return dv, truth.vel + np.einsum("kij,kj->ki", Cm, np.cross(w_nm, r))


def _case(cfg: Config, inst_att, heading):
    """Trajectory-dependent arrays of one case: Φ per filter step, the truth at the filter
    epochs (``vel``: the velocity at the slave's place, the master's plus the lever-arm
    term) and the slave's true increments."""
    from sinslab.core.attitude import euler_to_dcm, rotvec_to_dcm
    from sinslab.methods import transfer as tm
    from sinslab.nav.errstate import NavPoint
    from sinslab.sim import trajectory as tr

    s, fl = cfg.scenario, cfg.filter
    dt, T = float(s.sample_interval), float(s.duration)
    k_kf = int(round(float(fl.kf_dt) / dt))
    start = tr.Start(lat=float(s.latitude), lon=108.0 * units.deg, h=float(s.height), speed=float(s.speed),
                     heading=float(heading))
    segs = [{"kind": "wing_rock", "duration": f"{T + 1.0} s", "amplitude": f"{s.wing_rock_amplitude / units.deg} deg",
             "period": f"{float(s.wing_rock_period)} s", "ramp": f"{float(s.wing_rock_ramp)} s"}]
    gen = tr.generate(segs, start, dt, duration=T)
    truth, imu = gen.truth, gen.imu
    Cm = euler_to_dcm(truth.att)                          # (N+1, 3, 3)
    Csm_nom = euler_to_dcm(np.asarray(inst_att))
    Csm = Csm_nom @ rotvec_to_dcm(np.asarray(cfg.installation.error, float))
    Cs = Cm @ Csm
    N = len(imu)
    r = np.asarray(cfg.installation.lever_arm, float)
    dv_m, vel = _lever(imu, truth, Cm, r) if np.any(r) else (imu.dv, truth.vel)
    wb_m = np.vstack([imu.dtheta[:1], imu.dtheta]) / dt   # epoch k uses sample k-1
    fb_m = np.vstack([dv_m[:1], dv_m]) / dt
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
    return dict(Phi=Phi, Cm=Cm[ep], Cs=Cs[ep], t=truth.t[ep], vel=vel[ep], Csm=Csm, Csm_nom=Csm_nom, n=n,
                layout=model.layout, k_kf=k_kf, dt=dt,
                dth_s=np.ascontiguousarray(imu.dtheta[:K * k_kf] @ Csm),
                dv_s=np.ascontiguousarray(dv_m[:K * k_kf] @ Csm),
                pos0=np.array([truth.lat[0], truth.lon[0], truth.h[0]]))


def _params(cfg):
    """The plain numbers a Monte Carlo task needs."""
    fl, im, ms = cfg.filter, cfg.imu, cfg.master
    return dict(gyro_bias=float(im.gyro_bias_sigma), gyro_scale=float(im.gyro_scale_factor_sigma),
                accel_bias=float(im.accel_bias_sigma), accel_scale=float(im.accel_scale_factor_sigma),
                vel_noise=float(fl.vel_noise), att_noise=float(fl.att_noise),
                att_sigma0=float(fl.p0_attitude), vel_sigma0=float(fl.p0_velocity),
                inst_sigma0=float(fl.p0_installation),
                master_att=float(ms.att_error), master_vel=float(ms.vel_error),
                bound=float(fl.divergence_bound), guard=float(fl.correction_guard), slave=cfg.montecarlo.slave,
                compare_linear=bool(cfg.montecarlo.compare_linear))


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


def _variants(full=True, ekf=True):
    """(key, case, kind, compensated, ekf) of every filter run (``full=False``: the four
    forms on the two installations only; ``ekf=False``: without the EKF diagnosis, which no
    claim reads)."""
    v = []
    for c in _C:
        for m in _M:
            v.append((f"{m}_{c}", c, m, m == "optimal", False))
        if full:
            for m in _M[:3]:
                v.append((f"{m}_comp_{c}", c, m, True, False))
    if full:
        for m in _M[:3] if ekf else ():
            v.append((f"{m}_large_ekf", "large", m, False, True))
        v.append(("dcm_c22", "c22", "dcm", False, False))
        v.append(("kain_c22", "c22", "kain", False, False))
    return v


def _draws(seeds, p, cases):
    """Per-run random draws shared by every filter and both slave models: sensor errors
    (R, 12) = [ε, k_g, ∇, k_a], master attitude (R, 3) [rad, ENU] and velocity (R, 3) [m/s]
    errors, and per case the measurement noise (R, K+1, 6) in units of z."""
    R = len(seeds)
    rngs = [np.random.default_rng(s) for s in seeds]
    sens = np.stack([np.concatenate([r.standard_normal(3) * p["gyro_bias"], r.standard_normal(3) * p["gyro_scale"],
                                     r.standard_normal(3) * p["accel_bias"],
                                     r.standard_normal(3) * p["accel_scale"]]) for r in rngs])
    master = np.stack([r.standard_normal(6) for r in rngs]) if R else np.zeros((0, 6))
    scale = np.array([p["vel_noise"]] * 3 + [p["att_noise"]] * 3)
    noise = {c: np.stack([r.standard_normal((cases[c]["Cm"].shape[0], 6)) for r in rngs]) * scale for c in cases}
    return sens, master[:, :3] * p["master_att"], master[:, 3:] * p["master_vel"], noise


def _run_index(seed):
    """Index of a run in its campaign (the last entry of its spawn key)."""
    key = getattr(seed, "spawn_key", ())
    return int(key[-1]) if key else 0


def _strapdown(case, p, match, P0, sens, m_att, m_vel, noise, rows, ekf, record_every, cache, gains=None):
    """The closed-loop filter of one variant over the runs ``rows`` (mechanised slaves)."""
    from sinslab.core.attitude import dcm_to_euler, rotvec_to_dcm
    from sinslab.core.records import NavState
    from sinslab.methods import transfer as tm
    from sinslab.nav import strapdown as sd
    from sinslab.nav.lanes import LaneBank

    R = len(rows)
    dt = case["dt"]
    Cm, Cs = case["Cm"], case["Cs"]
    gb, kg, ab, ka = (sens[rows, 3 * i:3 * i + 3] for i in range(4))
    dth = case["dth_s"][None] * (1.0 + kg[:, None]) + gb[:, None] * dt
    dvv = case["dv_s"][None] * (1.0 + ka[:, None]) + ab[:, None] * dt
    # the master's solution: truth with constant errors; the slave starts from it × the nominal mounting
    mC = rotvec_to_dcm(-m_att[rows])[:, None] @ Cm[None]                      # (R, K+1, 3, 3)
    mv = case["vel"][None] + m_vel[rows][:, None]
    lat, lon, h = case["pos0"]
    init = np.stack([sd.initial_state_array(NavState(lat, lon, h, mv[r, 0], dcm_to_euler(mC[r, 0] @ case["Csm_nom"]),
                                                     0.0)) for r in range(R)])
    bank = LaneBank(init, dth, dvv, np.arange(R), dt, nsub=2)
    res = tm.align_lanes(bank, case["k_kf"], case["Phi"], match, P0, np.full(3, p["vel_noise"] ** 2),
                         np.full(3, p["att_noise"] ** 2), mC, mv, np.arange(R), C_lin=Cm, relinearise=ekf,
                         meas_noise=noise[rows], phi_bound=p["guard"], record_every=record_every, gains=gains)
    # the slave's true attitude error at the recorded epochs: divergence (over the second
    # half of the run, so an early transient the filter recovers from is not counted) and
    # the heading error
    Ct = Cs[res.epochs]
    phi = _misalignment_many(Ct[None], res.attitude)
    late = np.linalg.norm(np.nan_to_num(phi[:, phi.shape[1] // 2:], nan=np.inf), axis=-1)
    far = ~np.all(late <= p["bound"], axis=1)
    div = res.diverged | far
    a = np.where(div[:, None, None], np.nan, res.a)
    sig = res.sigma[:, :, 6:9] if res.sigma.ndim == 3 else np.broadcast_to(res.sigma[None, :, 6:9], a.shape)
    return a, np.ascontiguousarray(sig), div, np.where(div[:, None], np.nan, phi[..., 2]), (
        res.sigma[..., 2] if res.sigma.ndim == 3 else np.broadcast_to(res.sigma[None, :, 2], a.shape[:2])), (
        np.linalg.norm(phi, axis=-1))


def _misalignment_many(C_true, C_hat):
    """φ (…, 3) of ``Ĉ = exp(−φ×) C`` for stacked attitudes (NaN where Ĉ is NaN)."""
    from sinslab.core.attitude import dcm_to_rotvec

    ok = np.all(np.isfinite(C_hat), axis=(-2, -1))
    C_hat = np.where(ok[..., None, None], C_hat, np.eye(3))
    phi = dcm_to_rotvec(np.broadcast_to(C_true, C_hat.shape) @ np.swapaxes(C_hat, -1, -2))
    return np.where(ok[..., None], phi, np.nan)


def _linear(case, p, match, P0, sens, m_att, m_vel, noise, rows, ekf, record_every, cache, gains=None):
    """The open-loop linear-model filter of one variant (the slave errors propagated with
    the 21-state model along the truth, never fed back). ``cache`` keeps the propagated
    errors of a case for the other variants of the task."""
    from sinslab.core.attitude import misalignment, rotvec_to_dcm
    from sinslab.methods import transfer as tm

    R = len(rows)
    n, Kp1 = case["n"], case["Cm"].shape[0]
    key = (id(case), rows.tobytes())
    if key not in cache:
        x = np.zeros((R, n))
        x[:, 9:] = sens[rows]
        x[:, 0:3] = misalignment(case["Cs"][0], case["Cm"][0] @ case["Csm_nom"])[None, :]
        xs = tm.propagate_errors(case["Phi"], x)
        C_hat = rotvec_to_dcm(-xs[:, :, 0:3]) @ case["Cs"][None]
        mC = rotvec_to_dcm(-m_att[rows])[:, None] @ case["Cm"][None]
        # the master's attitude error as a rotation of the slave attitude seen against the
        # true master: exp(φ_m×) Ĉ_s (the same z for the Kain forms, to first order for the others)
        cache[key] = xs, case["Cm"][None] @ np.swapaxes(mC, -1, -2) @ C_hat
    xs, C_rel = cache[key]
    z_vel = xs[:, :, 3:6] - m_vel[rows][:, None] + noise[rows][:, :, :3]
    est, sig = tm.batch_filter(case["Phi"], case["Cm"], z_vel, C_rel, match, np.zeros(n), P0,
                               np.full(3, p["vel_noise"] ** 2), np.full(3, p["att_noise"] ** 2),
                               relinearise=ekf, record_every=record_every, att_noise=noise[rows][:, :, 3:],
                               gains=gains)
    rec = np.arange(0, Kp1, record_every)
    sa = sig[..., 6:9] if sig.ndim == 3 else np.broadcast_to(sig[None, :, 6:9], (R,) + sig[:, 6:9].shape)
    sU = sig[..., 2] if sig.ndim == 3 else np.broadcast_to(sig[None, :, 2], (R, rec.size))
    return (est[:, :, 6:9], np.ascontiguousarray(sa), np.zeros(R, bool), est[:, :, 2] - xs[:, rec, 2], sU,
            np.linalg.norm(xs[:, rec, 0:3], axis=-1))


def _common_gains(p, cases, record_every, variants=None):
    """Per (variant key, model prefix of :func:`_batch`) the covariance recursion of the
    paper-form filters (:func:`sinslab.methods.transfer.lane_gains` for the mechanised
    slave, :func:`~sinslab.methods.transfer.batch_gains` for the linear model): common to
    every run, so made once for a campaign instead of once in each task."""
    from sinslab.methods import transfer as tm

    r_vel, r_att = np.full(3, p["vel_noise"] ** 2), np.full(3, p["att_noise"] ** 2)
    models = [("", p["slave"] == "strapdown")]
    if p["slave"] == "strapdown" and p["compare_linear"]:
        models.append(("lin_", False))
    out = {}
    for key, c, kind, comp, ekf in (variants or _variants()):
        if c not in cases or ekf:
            continue
        case = cases[c]
        match, P0 = _filter_setup(p, case, kind, comp)
        for pre, lanes in models:
            out[(key, pre)] = (
                tm.lane_gains(case["Phi"], match, P0, r_vel, r_att, case["Cm"], record_every=record_every) if lanes
                else tm.batch_gains(case["Phi"], case["Cm"], match, P0, r_vel, r_att, record_every=record_every))
    return out


def _batch(seeds, p, cases, record_every, ekf_runs, variants=None, gains=None):
    """One Dask task: the runs of ``seeds`` through every filter variant, with the slave
    model of ``p["slave"]`` (and the linear model beside the strapdown one when asked).

    Returns per variant key the installation estimates ``a_<key>`` (R, M, 3) [rad], their σ
    ``sig_<key>``, the divergence flags ``div_<key>`` (R,), the heading error ``phiU_<key>``
    and its σ ``sigU_<key>`` (R, M), the norm of the slave's attitude error ``phin_<key>``
    (R, M) (NaN after a run was stopped); the linear model's under ``lin_`` prefixes; the
    campaign index of each run ``run`` (R,). EKF variants run on the runs with campaign
    index < ``ekf_runs`` only (NaN rows elsewhere).
    ``gains``: :func:`_common_gains` of the campaign (each call makes its own when not given).
    """
    R = len(seeds)
    sens, m_att, m_vel, noise = _draws(seeds, p, cases)
    idx = np.array([_run_index(s) for s in seeds])
    models = [("", _strapdown if p["slave"] == "strapdown" else _linear)]
    if p["slave"] == "strapdown" and p["compare_linear"]:
        models.append(("lin_", _linear))
    out, cache = {"run": idx}, {}
    for key, c, kind, comp, ekf in (variants or _variants()):
        if c not in cases:
            continue
        case = cases[c]
        match, P0 = _filter_setup(p, case, kind, comp)
        rows = np.flatnonzero(idx < ekf_runs) if ekf else np.arange(R)
        for pre, fn in models:
            if ekf and pre:
                continue
            M = -(-case["Cm"].shape[0] // record_every)
            full = [np.full((R, M, 3), np.nan), np.full((R, M, 3), np.nan), np.ones(R, bool),
                    np.full((R, M), np.nan), np.full((R, M), np.nan), np.full((R, M), np.nan)]
            if rows.size:
                part = fn(case, p, match, P0, sens, m_att, m_vel, noise[c], rows, ekf, record_every, cache,
                          gains=(gains or {}).get((key, pre)))
                for f, v in zip(full, part):
                    f[rows] = v[:, :M] if v.ndim > 1 else v
            if ekf:
                full[2][np.setdiff1d(np.arange(R), rows)] = False
            for name, v in zip(("a", "sig", "div", "phiU", "sigU", "phin"), full):
                out[f"{pre}{name}_{key}"] = v
    return out


# ----------------------------------------------------------------------- scoring -----
def _score(a, case, kind, comp, ekf=False):
    """Installation estimation errors of one variant [rad] (R, M, 3): in the filter's own
    parameterisation, and with the estimate read as a rotation vector."""
    from sinslab.core.attitude import dcm_to_rotvec, rotvec_to_dcm, wrap_pi
    from sinslab.methods import transfer as tm

    C_res = case["Csm_nom"].T @ case["Csm"] if comp else case["Csm"]
    par = tm.parameterisation(kind, ekf)
    own = a - tm.installation_parameters(C_res, par)
    if par == "euler":
        own = wrap_pi(own)
    ok = np.all(np.isfinite(a), axis=-1)
    rv = dcm_to_rotvec(C_res.T @ rotvec_to_dcm(np.where(ok[..., None], a, 0.0)))
    return own, np.where(ok[..., None], rv, np.nan)


#: Runs of the main campaign whose outputs travel whole beside the sums: the figures draw
#: the first run that did not diverge and, for a form whose runs all diverged, runs 0–8.
FIGURE_RUNS = 9


#: Calls of the task function per worker in the main campaign: a call's cost grows with its
#: runs (the lanes are stepped one by one in compiled code) and the EKF diagnosis makes the
#: calls holding the first runs heavier, so several calls per worker balance the load.
TASKS_PER_WORKER = 4


def _campaign(p, cases, n, seed, ctx, record_every, ekf_runs, variants=None, label="mc", keep_first=0,
              tasks_per_worker=TASKS_PER_WORKER):
    """The Monte Carlo of ``variants`` over ``n`` runs, its statistics summed on the workers
    (:func:`_sums`): the sums, and with ``keep_first`` the pair (sums, whole outputs of the
    runs of index below it)."""
    import functools

    from sinslab.estimation import montecarlo as mc

    variants = variants or _variants()
    models = [""] + (["lin_"] if p["slave"] == "strapdown" and p["compare_linear"] else [])
    scoring = {c: {"Csm": cases[c]["Csm"], "Csm_nom": cases[c]["Csm_nom"]} for c in cases}
    return mc.run_campaign(_batch, n, seed, scheduler=ctx.scheduler, tasks_per_worker=tasks_per_worker,
                           kwargs=dict(p=p, cases=cases, record_every=record_every, ekf_runs=ekf_runs,
                                       variants=variants,
                                       gains=_common_gains(p, cases, record_every, variants)),
                           reduce=functools.partial(_sums, variants=variants, scoring=scoring, ekf_runs=ekf_runs,
                                                    models=models),
                           gather=functools.partial(_first_runs, n=keep_first) if keep_first else None,
                           **ctx.campaign_store(label))


def _first_runs(out, n):
    """The whole outputs of the runs of campaign index below ``n`` in one call's output."""
    on = out["run"] < n
    return {k: v[on] for k, v in out.items()}


def _sums(out, variants, scoring, ekf_runs, models):
    """What the statistics need of each run of :func:`_batch` (summed over the runs where
    they are computed, :func:`sinslab.estimation.montecarlo.run_campaign`'s ``reduce``).

    Per variant key and model prefix: the runs it was run on (``n_``: every run, or those
    of index < ``ekf_runs`` for the EKF diagnosis), those that diverged (``nd_``) and those
    kept (``nk_``), and over the kept runs the squared installation error in the form's own
    parameterisation (``e2_``, (M, 3)) and read as a rotation vector (``r2_``), and the
    filter σ (``sg_``); with the linear model beside the strapdown slave, the squared
    difference of their final estimates over the runs neither diverged in (``dl_``, (3,))
    and those runs (``nb_``); for the heading-90° variants the squared heading error where
    finite (``u2_``), those runs per epoch (``nu_``) and its σ (``su_``). Sums of squares,
    counts and σ only, so the RMS, the mean σ and the verdicts follow from the totals.
    """
    idx = out["run"]
    sq = {}
    for key, c, kind, comp, ekf in variants:
        if c not in scoring:
            continue
        if c == "c22":
            v = out[f"phiU_{key}"]
            ok = np.isfinite(v)
            sq[f"u2_{key}"] = np.where(ok, v, 0.0) ** 2
            sq[f"nu_{key}"] = ok
            sq[f"su_{key}"] = out[f"sigU_{key}"]
            continue
        for pre in models:
            if ekf and pre:
                continue
            a, sg, div = out[f"{pre}a_{key}"], out[f"{pre}sig_{key}"], out[f"{pre}div_{key}"]
            on = idx < ekf_runs if ekf else np.ones(idx.shape, bool)
            keep = on & ~div
            own, rv = _score(a, scoring[c], kind, comp, ekf)
            k3 = keep[:, None, None]
            sq[f"{pre}n_{key}"] = on
            sq[f"{pre}nd_{key}"] = on & div
            sq[f"{pre}nk_{key}"] = keep
            sq[f"{pre}e2_{key}"] = np.where(k3, own, 0.0) ** 2
            sq[f"{pre}r2_{key}"] = np.where(k3, rv, 0.0) ** 2
            sq[f"{pre}sg_{key}"] = np.where(k3, sg, 0.0)
        if len(models) > 1 and not ekf:
            both = ~(out[f"div_{key}"] | out[f"lin_div_{key}"])
            d = out[f"lin_a_{key}"][:, -1] - out[f"a_{key}"][:, -1]
            sq[f"dl_{key}"] = np.where(both[:, None], d, 0.0) ** 2
            sq[f"nb_{key}"] = both
    return sq


def _stats(e2, sg, nk, nd, runs, ratio):
    """RMS over the runs that did not diverge, mean σ, verdict and margin (arcmin, -) from
    the sums of :func:`_sums`: squared errors ``e2`` and σ ``sg`` (M, 3) over the ``nk``
    runs kept, ``nd`` diverged of ``runs``."""
    am = 1.0 / units.arcmin
    nk, n_div = int(nk), int(nd)
    if nk:
        rms = np.sqrt(e2 / nk) * am
        sig = sg / nk * am
    else:
        rms = np.full(e2.shape, np.nan)
        sig = np.full(e2.shape, np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        r_end = rms[-1] / sig[-1]
    worst = float(np.max(r_end)) if np.all(np.isfinite(r_end)) else float("inf")
    conv = bool(n_div == 0 and worst <= ratio)
    return dict(rms=rms, sig=sig, conv=conv, n_div=n_div, runs=int(runs), ratio=r_end, worst=worst,
                margin=ratio - worst)


def _variant_stats(sums, cases, variants, ratio, pre="", ekf_runs=None, head=None):
    """Per variant key the statistics of :func:`_stats` (own parameterisation; ``"rv"``: read
    as a rotation vector) from the campaign's sums; with ``head`` (the whole outputs of the
    first runs) also the error history and σ of the first run kept among them (``first``,
    ``first_sig`` [arcmin]; the first run when none of them was kept)."""
    am = 1.0 / units.arcmin
    out = {}
    for key, c, kind, comp, ekf in variants:
        if c == "c22":
            continue
        g = lambda q: sums[f"{pre}{q}_{key}"]  # noqa: E731
        st = _stats(g("e2"), g("sg"), g("nk"), g("nd"), g("n"), ratio)
        st["rv"] = _stats(g("r2"), g("sg"), g("nk"), g("nd"), g("n"), ratio)
        if head is not None:
            a, sg, div = head[f"{pre}a_{key}"], head[f"{pre}sig_{key}"], head[f"{pre}div_{key}"]
            keep = ~div & ((head["run"] < ekf_runs) if ekf else True)
            own, _ = _score(a, cases[c], kind, comp, ekf)
            j = int(np.argmax(keep)) if keep.any() else 0
            st["first"], st["first_sig"] = own[j] * am, sg[j] * am
        out[key] = st
    return out


# ----------------------------------------------------------------------- run ---------
def run(cfg: Config, ctx) -> Result:
    from sinslab.app import plotting as P
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
    ratio = float(fl.converge_ratio)
    p = _params(cfg)
    slave = cfg.montecarlo.slave
    # a re-run of the robustness sweep needs the verdicts only: no EKF diagnosis, no linear
    # model beside the mechanised slaves
    if ctx.claims_only:
        p["compare_linear"] = False
    variants = _variants(ekf=not ctx.claims_only)
    ctx.log(f"{NAME}: Monte Carlo, {n} runs, {slave} slave")
    sums, head = _campaign(p, cases, n, cfg.seed, ctx, record_every, int(fl.ekf_runs), variants=variants,
                           keep_first=FIGURE_RUNS)
    stats = _variant_stats(sums, cases, variants, ratio, ekf_runs=int(fl.ekf_runs), head=head)
    lin = (_variant_stats(sums, cases, [v for v in variants if not v[4]], ratio, pre="lin_")
           if slave == "strapdown" and p["compare_linear"] else None)
    am = 1.0 / units.arcmin
    metrics = {"slave_model": slave, "feedback": slave == "strapdown"}
    rows = []
    agree = total = 0
    for key, c, kind, comp, ekf in variants:
        if c == "c22":
            continue
        st = stats[key]
        metrics[f"misalign_rms_end_arcmin_{key}"] = st["rms"][-1]
        metrics[f"misalign_sigma_end_arcmin_{key}"] = st["sig"][-1]
        metrics[f"diverged_runs_{key}"] = st["n_div"]
        metrics[f"converged_{key}"] = st["conv"]
        row = dict(filter=key, case=c, kind=kind, compensation=comp, ekf=ekf,
                   estimates=tm.parameterisation(kind, ekf), runs=st["runs"], diverged=st["n_div"])
        if not ekf:
            metrics[f"misalign_rms_5s_arcmin_{key}"] = st["rms"][i5]
            metrics[f"misalign_sigma_5s_arcmin_{key}"] = st["sig"][i5]
            with np.errstate(invalid="ignore", divide="ignore"):
                metrics[f"rms_over_sigma_5s_{key}"] = st["rms"][i5] / st["sig"][i5]
            metrics[f"rms_over_sigma_{key}"] = st["ratio"]
            metrics[f"rms_over_sigma_rotvec_{key}"] = st["rv"]["ratio"]
            metrics[f"margin_{key}"] = st["margin"]
        for j, ax in enumerate("xyz"):
            row[f"rms_end_{ax}"] = st["rms"][-1, j]
            row[f"sig_end_{ax}"] = st["sig"][-1, j]
        for j, ax in enumerate("xyz"):
            row[f"ratio_{ax}"] = st["ratio"][j]
        for j, ax in enumerate("xyz"):
            row[f"ratio_rotvec_{ax}"] = st["rv"]["ratio"][j]
        row.update(margin=st["margin"], converged=st["conv"], converged_if_rotvec=st["rv"]["conv"])
        if lin is not None and not ekf:
            lk = lin[key]
            metrics[f"converged_linear_{key}"] = lk["conv"]
            nb = int(sums[f"nb_{key}"])
            metrics[f"linear_minus_strapdown_rms_arcmin_{key}"] = (np.sqrt(sums[f"dl_{key}"] / nb) * am if nb
                                                                   else np.full(3, np.nan))
            row.update(converged_linear=lk["conv"], linear_worst_ratio=lk["worst"])
            agree += int(lk["conv"] == st["conv"])
            total += 1
        rows.append(row)
    if lin is not None:
        metrics["linear_verdicts_agree"] = agree
        metrics["linear_verdicts_total"] = total
    # C22 = 0: the heading error of the slave (strapdown: its true φU after feedback)
    # heading error RMS over the runs still running, and the mean σ, at every recorded epoch
    with np.errstate(invalid="ignore", divide="ignore"):
        pU = {k: np.sqrt(sums[f"u2_{k}_c22"] / sums[f"nu_{k}_c22"]) for k in ("dcm", "kain")}
    sU = {k: sums[f"su_{k}_c22"] / n for k in ("dcm", "kain")}
    rmsU = {k: float(v[-1]) * am for k, v in pU.items()}
    sigU = float(sU["dcm"][-1]) * am
    c22 = cases["c22"]
    Hn = [np.linalg.norm(tm.AttitudeMatch("dcm").H(C)[:, 2]) for C in c22["Cm"]]
    Hn_nom = [np.linalg.norm(tm.AttitudeMatch("dcm").H(C)[:, 2]) for C in cases["small"]["Cm"]]
    rank = int(np.linalg.matrix_rank(tm.AttitudeMatch("dcm").H(c22["Cm"][c22["Cm"].shape[0] // 2]), tol=1e-6))
    metrics.update(dcm_heading_rms_c22zero_arcmin=rmsU["dcm"], kain_heading_rms_c22zero_arcmin=rmsU["kain"],
                   dcm_heading_sigma_c22zero_arcmin=sigU, dcm_phiU_H_norm_c22zero=float(np.max(Hn)),
                   dcm_phiU_H_norm_nominal=float(np.min(Hn_nom)), dcm_H_rank_c22zero=rank)
    # a re-run of the robustness sweep varies the physics: the H check and the cost of the
    # forms, which none of its alternatives changes, are the run's own
    fd = None if ctx.claims_only else _fd_check(ctx.rng(99))
    if fd is not None:
        metrics["h_fd_max_rel_err"] = fd
        cost = _cost(cases["large"])
        for k in _M:
            metrics[f"update_cost_us_{k}"] = cost[k]
            metrics[f"update_flops_{k}"] = int(tm.FLOPS[k])
    metrics["runs"] = n

    claims = _claims(cfg, metrics, stats, rmsU, fd, i5 if t[-1] > float(s.report_time) + 1e-9 else None)
    if ctx.claims_only:
        return Result(metrics=metrics, claims=claims)
    notes = _verdict_notes(stats, ratio, lin)
    figs = _figures(P, cfg, stats, t, n, pU, sU, head, c22, cases, Hn, Hn_nom)
    import pandas as pd
    series = {}
    for key, st in stats.items():
        series[f"rms_{key}"] = {"t": t, **{f"rms_{a}_arcmin": st["rms"][:, j] for j, a in enumerate("xyz")},
                                **{f"sigma_{a}_arcmin": st["sig"][:, j] for j, a in enumerate("xyz")}}
    tables = [Table("misalignment_stats", pd.DataFrame(rows),
                    "Installation estimation error at the end, RMS over the runs that did not diverge and mean filter "
                    "σ [arcmin]; ratio = RMS/σ in the form's own parameterisation ('estimates'), ratio_rotvec with the "
                    f"estimate read as a rotation vector; margin = {ratio:g} − worst ratio")]
    return Result(metrics=metrics, claims=claims, series=series, figures=figs, tables=tables, notes=notes)


def _label(form, st, both=False):
    """A verdict's name with its numbers: RMS/σ per axis and the margin, or the divergences;
    ``both``: also the RMS/σ with the estimate read as a rotation vector."""
    if st["n_div"] and st["n_div"] == st["runs"]:
        return f"{form} (all {st['n_div']} runs diverged)"
    r = ", ".join(f"{v:.2f}" for v in st["ratio"])
    div = f"; {st['n_div']} runs diverged" if st["n_div"] else ""
    rv = ""
    if both and not np.allclose(st["ratio"], st["rv"]["ratio"], equal_nan=True):
        rv = " as estimated, " + ", ".join(f"{v:.2f}" for v in st["rv"]["ratio"]) + " as a rotation vector"
    return f"{form} (RMS/σ {r}{rv}; margin {st['margin']:+.2f}{div})"


#: Assumptions of the convergence verdicts (names shared by the claims and the sweep's axes)
MASTER, HORIZON, ONSET, ATT_NOISE, VEL_NOISE, DRAW, SCORING, BAR = (
    "master errors", "horizon", "wing-rock onset", "attitude measurement noise", "velocity measurement noise",
    "Monte Carlo draws", "scoring of the estimate", "convergence bar")
#: the claims whose verdict is a convergence verdict
_CONV = ("large_methods_1_3_fail", "large_method_4_converges", "small_all_converge", "c22_heading_worse",
         "compensation_fixes_1_3")


def ROBUSTNESS(cfg):
    """The physics alternatives of the convergence verdicts (re-runs; the 60 s horizon with
    60 runs, the paper's 5 s ones at full size; the demo's with 60 and 30 runs, without the
    velocity noise and the other seed)."""
    am = float(cfg.master.att_error) / units.arcmin
    master = {"0.5′ and 0.01 m/s (the project's former master)": ["master.att_error=0.5 arcmin",
                                                                   "master.vel_error=0.01 m/s"]}
    master.update({f"{v:g}′": [f"master.att_error={v:g} arcmin"] for v in (1, 2, 3) if v != am})
    demo = ("runs=60",)                     # the demo's: 60 runs a re-run
    return [
        Axis(MASTER, _default(cfg, MASTER), master, claims=_CONV, source="paper", demo=demo),
        Axis(HORIZON, _default(cfg, HORIZON),
             {"a 60 s run, 6 s onset (the project's former default)": ["scenario.duration=60 s",
                                                                      "scenario.wing_rock_ramp=6 s"]},
             claims=_CONV, reduced=("runs=60",), demo=("runs=30",), source="paper", readings=True),
        Axis(ONSET, _default(cfg, ONSET), {"abrupt (0 s)": ["scenario.wing_rock_ramp=0 s"],
                                           "3 s": ["scenario.wing_rock_ramp=3 s"]}, claims=_CONV, demo=demo),
        Axis(ATT_NOISE, _default(cfg, ATT_NOISE), {f"{v:g}′": [f"filter.att_noise={v:g} arcmin"] for v in (0.1, 10)},
             claims=_CONV, demo=demo),
        Axis(VEL_NOISE, _default(cfg, VEL_NOISE), {"0.1 m/s": ["filter.vel_noise=0.1 m/s"]}, claims=_CONV,
             in_demo=False),
        Axis(DRAW, _default(cfg, DRAW), {f"seed {cfg.seed + 1}": [f"seed={cfg.seed + 1}"]}, claims=_CONV,
             in_demo=False),
    ]


def _default(cfg, what):
    """The run's default of an assumption, as text."""
    s, fl, ms = cfg.scenario, cfg.filter, cfg.master
    if what == MASTER:
        a, v = float(ms.att_error) / units.arcmin, float(ms.vel_error)
        return ("error-free, as the paper" if a == 0 and v == 0 else f"{a:g}′ and {v:g} m/s 1σ per axis")
    if what == HORIZON:
        return f"a {float(s.duration):g} s run judged at its end" + (" (the paper's 5 s)" if float(s.duration) == 5 else "")
    if what == ONSET:
        return f"{float(s.wing_rock_ramp):g} s build-up (not in the paper)"
    if what == ATT_NOISE:
        return f"{float(fl.att_noise) / units.arcmin:g}′ 1σ, drawn as assumed (not in the paper)"
    if what == VEL_NOISE:
        return f"{float(fl.vel_noise):g} m/s 1σ, drawn as assumed (not in the paper)"
    if what == DRAW:
        return f"seed {cfg.seed}, {cfg.runs} runs"
    if what == SCORING:
        return "in the form's own parameterisation (Euler triple for methods 1-2, rotation vector for 3-4)"
    return f"no run diverged and RMS ≤ {float(fl.converge_ratio):g} × filter σ on every axis (the project's)"


def _conv_claim(cid, text, keys, forms, expected, stats, cfg, i5, origin="paper"):
    """A convergence claim over ``keys`` with its readings: the scoring as a rotation vector,
    other bars, and (inside a longer run) the verdict at the report time."""
    both = any(k.endswith("_small") for k in keys)
    c = Claim.equals(cid, text, [stats[k]["conv"] for k in keys], expected,
                     names=[_label(f, stats[k], both) for k, f in zip(keys, forms)], origin=origin)
    ratio = float(cfg.filter.converge_ratio)
    for a in (MASTER, HORIZON, ONSET, ATT_NOISE, VEL_NOISE, DRAW, SCORING, BAR):
        c.assume(a, _default(cfg, a), "paper" if a in (MASTER, HORIZON) else "project")
    rv = [stats[k]["rv"]["conv"] for k in keys]
    c.vary(SCORING, "every estimate read as a rotation vector", rv, rv == list(expected))
    for bar in (2.0, 5.0):
        got = [bool(stats[k]["n_div"] == 0 and stats[k]["worst"] <= bar) for k in keys]
        c.vary(BAR, f"RMS ≤ {bar:g} σ", got, got == list(expected), how="threshold")
    if i5 is not None:
        got = []
        for k in keys:
            st = stats[k]
            with np.errstate(invalid="ignore", divide="ignore"):
                w = np.max(st["rms"][i5] / st["sig"][i5])
            got.append(bool(st["n_div"] == 0 and np.isfinite(w) and w <= ratio))
        c.vary(HORIZON, f"judged at {float(cfg.scenario.report_time):g} s inside the run", got, got == list(expected))
    return c


def _claims(cfg, metrics, stats, rmsU, fd, i5=None):
    """The paper's statements and the project's checks; every convergence verdict carries
    its RMS/σ per axis and margin in its name, the assumptions it rests on and its readings
    (``i5``: the record index of the report time inside a longer run, else None)."""
    big = ["euler_large", "dcm_large", "kain_large"]
    small = [f"{m}_small" for m in _M]
    comp = [f"{m}_comp_large" for m in _M[:3]]
    claims = [
        _conv_claim("large_methods_1_3_fail", "large installation: methods 1-3 (euler, dcm, kain) do not converge "
                    "to the true misalignment", big, _M[:3], [False] * 3, stats, cfg, i5),
        _conv_claim("large_method_4_converges", "large installation: method 4 (optimal) converges",
                    ["optimal_large"], ["optimal"], [True], stats, cfg, i5),
        _conv_claim("small_all_converge", "small installation: all four methods converge, each scored in what it "
                    "estimates (RMS/σ as estimated and as a rotation vector in the names)", small, _M, [True] * 4,
                    stats, cfg, i5),
        Claim.at_most("c22_phiU_column_zero", "DCM form at heading 90° (C22 = 0): φU column of H vanishes",
                      metrics["dcm_phiU_H_norm_c22zero"], 1e-3, origin="paper").by_construction(
            "the flight is set at heading 90°, where C22 = cos θ cos ψ is zero whatever the wing rock"),
    ]
    worse = rmsU["dcm"] / max(rmsU["kain"], 1e-12)
    c = Claim.at_least("c22_heading_worse", "DCM form at C22 = 0: heading error RMS at the end ≥ 2 × Kain's "
                       "(2×: the project's bar)", worse, 2.0, "×", origin="paper")
    for a in (MASTER, HORIZON, ONSET, ATT_NOISE, VEL_NOISE, DRAW):
        c.assume(a, _default(cfg, a), "paper" if a in (MASTER, HORIZON) else "project")
    c.assume("bar on the heading ratio", "2× (the project's)").with_limits(
        "bar on the heading ratio", {"1.2×": 1.2, "5×": 5.0})
    claims.append(c)
    if fd is not None:
        c = Claim.at_most("h_fd", "every H matches central differences of its z", fd, 1e-6, origin="check")
        c.assume("tolerance", "1e-6 relative").with_limits("tolerance", {"1e-8": 1e-8})
        claims.append(c)
    claims.append(_conv_claim("compensation_fixes_1_3", "with the installation compensation methods 1-3 converge "
                              "on the large installation", comp, _M[:3], [True] * 3, stats, cfg, i5, origin="check"))
    return claims


def _verdict_notes(stats, ratio, lin):
    notes = []
    for key, st in stats.items():
        r = st["ratio"]
        j = int(np.nanargmax(np.nan_to_num(r, nan=np.inf))) if np.isfinite(st["worst"]) else 0
        text = (f"{key}: RMS/σ at the end {np.round(r, 2).tolist()} (worst axis {'xyz'[j]}: RMS {st['rms'][-1, j]:.3g}′, "
                f"σ {st['sig'][-1, j]:.3g}′), margin {st['margin']:.2f} to {ratio:g}, {st['n_div']} diverged -> "
                f"{'converged' if st['conv'] else 'not converged'}; scored as a rotation vector "
                f"{np.round(st['rv']['ratio'], 2).tolist()} -> {'converged' if st['rv']['conv'] else 'not converged'}")
        if lin is not None and key in lin:
            text += f"; linear model: {'converged' if lin[key]['conv'] else 'not converged'} (worst {lin[key]['worst']:.2f})"
        notes.append(text)
    return notes


def _figures(P, cfg, stats, t, n, pU, sU, head, c22, cases, Hn, Hn_nom):
    """The report's figures; ``pU``, ``sU``: RMS heading error and mean σ of the heading-90°
    variants per recorded epoch [rad]; ``head``: whole outputs of the campaign's first runs."""
    s = cfg.scenario
    am = 1.0 / units.arcmin
    figs = []
    for c in _C:
        fig, ax = P.figure(4, 3, width=12.0, row_height=2.2, title=f"{c} installation: installation estimation error ± σ")
        for i, m in enumerate(_M):
            st = stats[f"{m}_{c}"]
            if st["n_div"] == st["runs"]:
                # every run diverged: how the slave's attitude error ran away instead
                phin = head[f"phin_{m}_{c}"] / units.deg
                for j in range(3):
                    axx = ax[i * 3 + j]
                    for r in range(j * 3, min(j * 3 + 3, phin.shape[0])):
                        axx.plot(t, phin[r], lw=0.8, label=f"run {r}")
                    axx.axhline(float(cfg.filter.divergence_bound) / units.deg, color="k", ls="--", lw=0.8)
                    axx.set_yscale("log")
                    axx.set_title(f"{m}: slave |φ| [deg], runs {j * 3}-{j * 3 + 2} (all {st['n_div']} diverged)",
                                  fontsize="small")
                    if axx.get_lines()[:-1]:
                        axx.legend(fontsize="x-small")
                continue
            for j, a in enumerate("xyz"):
                axx = ax[i * 3 + j]
                axx.plot(t, st["first"][:, j], lw=0.8, label="first run kept: error")
                axx.fill_between(t, -st["first_sig"][:, j], st["first_sig"][:, j], alpha=0.3, label="±σ")
                axx.plot(t, st["rms"][:, j], "k--", lw=0.8, label="RMS over runs")
                axx.set_title(f"{m} {a} ({st['n_div']} diverged)", fontsize="small")
                if j == 0:
                    axx.set_ylabel("arcmin")
        ax[0].legend(fontsize="x-small")
        for axx in ax[-3:]:
            axx.set_xlabel("t [s]")
        figs.append(Figure(f"misalign_{c}", fig, f"Installation estimation error (own parameterisation) of the first run "
                                                 f"that did not diverge, its filter σ and the RMS over {n} runs, per "
                                                 f"method, {c} installation, {cfg.montecarlo.slave} slave (paper Figs 1-4); "
                                                 "a form whose runs all diverged shows its slaves' attitude error |φ| "
                                                 "until they were stopped (dashed: the divergence bound)"))
    fig, ax = P.figure(1, 2, width=10.0, row_height=3.2, title="heading 90° (C22 = 0): heading error φU")
    for k in ("dcm", "kain"):
        ax[0].plot(t, pU[k] * am, label=f"{k} RMS")
        ax[0].plot(t, sU[k] * am, "--", label=f"{k} σ")
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
    return figs


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


