"""free-inertial: pure inertial navigation of a simulated trajectory, compared with truth.

The trajectory generator (:mod:`sinslab.trajectory`) produces the true motion and exact
IMU increments; the IMU error model (:mod:`sinslab.imu`) corrupts them; the strapdown
mechanization (:mod:`sinslab.strapdown`) navigates from the (optionally perturbed) true
initial state without any aiding (the vertical channel is held to the true height by
default, like a perfect barometer, because a free vertical channel diverges in minutes).

Claims (each computed, each able to fail):

- ``schuler_period``: the period fitted to the horizontal velocity error is within 1 % of
  the Schuler period ``2π sqrt(R/g)`` (:func:`sinslab.earth.schuler_period`) at the start
  latitude and the mean height. Only when the run lasts at least one Schuler period.
- ``pos_envelope``, ``vel_envelope``, ``tilt_envelope``, ``heading_envelope``: the errors
  stay inside a closed-form envelope built from the static single-channel Schuler-loop
  error model — for each error source the magnitude bound of its closed-form response,
  summed — plus the heading-error × manoeuvre terms a moving vehicle adds, random terms
  at 4σ (see :func:`envelopes`). The envelope is an upper bound, not a prediction: a
  correct mechanization stays inside it; a wrong Earth rate, Coriolis term, gravity or
  sign does not.
"""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import field_validator, model_validator

from .. import earth, units
from .base import Claim, ExperimentConfig, Field, Figure, Metric, Q, QV, Result, Section

NAME = "free-inertial"
PURPOSE = "pure inertial navigation of a simulated trajectory with IMU errors, compared with truth"
NOTES = [
    "Attitude errors are Euler-angle differences (navigation − truth): pitch, roll and "
    "heading (heading clockwise from north, so heading error = −yaw error).",
    "Position errors are in metres east/north/up of the true position.",
]


# ---------------------------------------------------------------- configuration -------

class Scenario(Section):
    motion: Literal["aircraft_mixed", "static", "ship_manoeuvring"] = Field(
        "aircraft_mixed", description="ready-made motion of sinslab.trajectory")
    motion_file: str = Field("", description="motion TOML file (sinslab.trajectory.load_motion); "
                             "replaces `motion`, and the start when it has a [start] table")
    latitude: Q("angle", ge="-89 deg", le="89 deg") = Field("32 deg", description="start latitude")
    longitude: Q("angle", ge="-180 deg", le="360 deg") = Field("118 deg", description="start longitude")
    height: Q("length", ge="-1000 m", le="30 km") = Field("1000 m", description="start height (ellipsoidal)")
    speed: Q("velocity", ge="0 m/s", le="3000 m/s") = Field(
        "300 m/s", description="start speed (ignored by `static` and `ship_manoeuvring`)")
    heading: Q("angle", ge="-360 deg", le="360 deg") = Field(
        "0 deg", description="start heading, clockwise from north")
    duration: Q("time", gt="0 s", le="30 d") = Field("2 h", description="length of the run")
    sample_interval: Q("time", gt="0 s", le="1 s") = Field("0.01 s", description="IMU sampling interval")

    @field_validator("motion_file")
    @classmethod
    def _motion_file_loads(cls, v: str) -> str:
        if v:
            from .. import trajectory

            try:
                trajectory.load_motion(v)
            except FileNotFoundError:
                raise ValueError(f"{v}: file not found") from None
            except (OSError, ValueError) as e:
                raise ValueError(str(e)) from None
        return v


class Imu(Section):
    gyro_bias: QV("angular_rate") = Field("0.01 deg/h", description="constant gyro bias (x, y, z or one for all)")
    gyro_arw: QV("angle_random_walk", ge="0 deg/sqrt(h)") = Field("0.001 deg/sqrt(h)",
                                                                  description="gyro angle random walk")
    gyro_scale_factor: QV("dimensionless", ge="-0.1", le="0.1") = Field("0 ppm", description="gyro scale-factor error")
    accel_bias: QV("acceleration") = Field("50 ug", description="constant accelerometer bias")
    accel_vrw: QV("velocity_random_walk", ge="0 ug/sqrt(Hz)") = Field("5 ug/sqrt(Hz)",
                                                                      description="accelerometer velocity random walk")
    accel_scale_factor: QV("dimensionless", ge="-0.1", le="0.1") = Field("0 ppm", description="accelerometer scale-factor error")


class Init(Section):
    att_err: QV("angle") = Field("[0, 0, 0] arcsec", description="initial attitude error [pitch, roll, heading]")
    vel_err: QV("velocity") = Field("[0, 0, 0] m/s", description="initial velocity error [east, north, up]")
    pos_err: QV("length") = Field("[0, 0, 0] m", description="initial position error [east, north, up]")


class Nav(Section):
    nsub: int = Field(2, ge=1, le=5, description="samples per update (coning/sculling order)")
    vertical: Literal["hold", "damped", "free"] = Field(
        "hold", description="vertical channel: held to the true height, damped towards it, or free")
    output_interval: Q("time", gt="0 s") = Field("1 s", description="interval of the error series")


class Config(ExperimentConfig):
    runs: int = Field(1, ge=1, le=1, description="Monte Carlo runs (free-inertial: 1 only, for now)")
    scenario: Scenario = Scenario()
    imu: Imu = Imu()
    init: Init = Init()
    nav: Nav = Nav()

    @model_validator(mode="after")
    def _long_enough(self):
        upd = self.nav.nsub * float(self.scenario.sample_interval)
        step = max(1, round(float(self.nav.output_interval) / upd)) * upd
        if float(self.scenario.duration) < 2 * step:
            raise ValueError(f"scenario.duration {self.scenario.duration.text!r} is shorter than two "
                             f"output intervals ({2 * step:g} s)")
        return self


#: Tolerances of the linear-model claims: linearisation, the 1-step discretisation of F and
#: the mid-step specific force leave residuals of about a percent of the error itself.
LIN_REL, LIN_ABS_POS, LIN_ABS_VEL, LIN_ABS_ATT = 0.01, 0.5, 0.001, 0.2

QUICK = {"scenario": {"duration": "10 min", "sample_interval": "0.02 s"}}

METRICS = {
    "max_horiz_pos_err_m": Metric("m", "largest horizontal position error over the run"),
    "final_horiz_pos_err_m": Metric("m", "horizontal position error at the end"),
    "max_horiz_vel_err_mps": Metric("m/s", "largest horizontal velocity error over the run"),
    "final_att_err_arcsec": Metric("arcsec", "attitude error at the end: [pitch, roll, heading]"),
    "schuler_period_min": Metric("min", "period fitted to the horizontal velocity error "
                                        "(null when the run is shorter than one Schuler period)"),
    "schuler_period_theory_min": Metric("min", "Schuler period 2π·sqrt(R/g) at start latitude, mean height"),
    "schuler_period_direct_min": Metric("min", "period fitted directly to the velocity error (on a "
                                               "manoeuvring trajectory polluted by the rotating bias forcing)"),
    "linear_model_pos_residual_m": Metric("m", "max |horizontal position error − linear error model|"),
    "linear_model_vel_residual_mps": Metric("m/s", "max |horizontal velocity error − linear error model|"),
    "linear_model_att_residual_arcsec": Metric("arcsec", "max |misalignment φ − linear error model|"),
    "pos_envelope_ratio": Metric("-", "max over time of horizontal position error / closed-form envelope"),
    "vel_envelope_ratio": Metric("-", "max over time of horizontal velocity error / closed-form envelope"),
    "tilt_envelope_ratio": Metric("-", "max over time of pitch/roll error / closed-form envelope"),
    "heading_envelope_ratio": Metric("-", "max over time of heading error / closed-form envelope"),
    "distance_m": Metric("m", "distance travelled (horizontal)"),
    "samples": Metric("-", "IMU samples navigated"),
}


# ---------------------------------------------------------------- analysis helpers ------

def fit_schuler_period(t, v, min_period=1800.0, max_period=3 * 3600.0):
    """Schuler period [s] fitted to a horizontal velocity(-error) series ``v`` (M, 2: E, N).

    The horizontal error oscillation is a pair of counter-rotating circular modes
    (``z = vE + i·vN``): the Foucault (Coriolis) rotation splits the Schuler frequency
    ω_s into ω_s − ω_f and ω_s + ω_f. The model, fitted by least squares with the
    frequencies found by variable projection (grid, then Nelder–Mead), is::

        z(t) = c0 + c1·τ + A·exp(i ω1 t) + B·exp(−i ω2 t),     τ = t / t_end

    and the Schuler period is ``4π / (ω1 + ω2)`` (the Foucault shift cancels).
    """
    from scipy.optimize import minimize

    t = np.asarray(t, float) - float(np.asarray(t)[0])
    v = np.asarray(v, float)
    step = max(1, t.size // 1500)               # the oscillation is slow: 1500 points suffice
    t, v = t[::step], v[::step]
    z = v[:, 0] + 1j * v[:, 1]
    tau = t / max(t[-1], 1e-9)

    def cost(p):
        p1, p2 = p
        if not (min_period / 2 < p1 < 2 * max_period and min_period / 2 < p2 < 2 * max_period):
            return np.inf
        A = np.column_stack([np.ones_like(t), tau, np.exp(2j * np.pi * t / p1),
                             np.exp(-2j * np.pi * t / p2)])
        coef, *_ = np.linalg.lstsq(A, z, rcond=None)
        r = z - A @ coef
        return float(np.vdot(r, r).real)

    grid = np.linspace(min_period, max_period, 150)
    p0 = grid[int(np.argmin([cost((p, p)) for p in grid]))]
    res = minimize(cost, [p0, p0], method="Nelder-Mead",
                   options={"xatol": 1e-3, "fatol": 1e-14, "maxiter": 2000})
    w1, w2 = 2 * np.pi / res.x[0], 2 * np.pi / res.x[1]
    return float(4 * np.pi / (w1 + w2))


def _expm_batch(A):
    """Matrix exponential of a stack (..., n, n): scaling and squaring + 14-term Taylor."""
    norm = float(np.max(np.abs(A).sum(-1))) if A.size else 0.0
    sq = max(0, int(math.ceil(math.log2(norm))) + 1) if norm > 0 else 0
    X = A / 2.0 ** sq
    E = np.broadcast_to(np.eye(A.shape[-1]), A.shape).copy()
    term = E.copy()
    for k in range(1, 15):
        term = term @ X / k
        E += term
    for _ in range(sq):
        E = E @ E
    return E


def linear_error_prediction(truth, ideal, meas, ep, x0, core="horizontal"):
    """Propagate the linear φ-angle error model (:mod:`sinslab.errstate`) along the truth.

    The input is the *realised* sensor error (``meas − ideal`` increments, rotated to the
    navigation frame sample by sample and summed over each output step), so bias, noise
    and scale-factor errors all enter exactly as the navigation saw them; F is evaluated
    at the middle of each step with the mean true specific force. Each step is
    discretised exactly for constant F and input (augmented matrix exponential).

    Returns the state history (len(ep), n): ``core="horizontal"``: φ (3), δvE, δvN, δL, δλ;
    ``core="full"``: φ (3), δv (3), δL, δλ, δh.
    """
    from .. import errstate
    from ..attitude import euler_to_dcm

    model = errstate.ErrorModel(core)
    n = model.n
    att = truth.att_imu if truth.att_imu is not None else truth.att
    K = int(ep[1] - ep[0])
    m = len(ep) - 1
    ns = m * K
    C = euler_to_dcm(att[:ns + 1])
    Cm = 0.5 * (C[:-1] + C[1:])                                 # per-sample mid attitude
    d_th = np.einsum("kij,kj->ki", Cm, meas.dtheta[:ns] - ideal.dtheta[:ns])
    d_v = np.einsum("kij,kj->ki", Cm, meas.dv[:ns] - ideal.dv[:ns])
    f_n = np.einsum("kij,kj->ki", Cm, ideal.dv[:ns])
    T = float(truth.t[ep[1]] - truth.t[ep[0]])
    u = np.concatenate([d_th.reshape(m, K, 3).sum(1), d_v.reshape(m, K, 3).sum(1)], axis=1) / T
    fn = f_n.reshape(m, K, 3).sum(1) / T
    mid = ep[:-1] + K // 2
    nav = errstate.NavPoint(lat=truth.lat[mid], h=truth.h[mid], vel=truth.vel[mid],
                            Cbn=np.eye(3), fb=fn)
    F = model.F(nav)                                           # (m, n, n)
    B = model.G(errstate.NavPoint(lat=truth.lat[0], h=truth.h[0], vel=truth.vel[0],
                                  Cbn=np.eye(3), fb=fn[0]))[:, :6]   # nav-frame input map
    aug = np.zeros((m, n + 6, n + 6))
    aug[:, :n, :n] = F * T
    aug[:, :n, n:] = B * T
    E = _expm_batch(aug)
    Phi, Gam = E[:, :n, :n], E[:, :n, n:]
    x = np.empty((m + 1, n))
    x[0] = x0
    for k in range(m):
        x[k + 1] = Phi[k] @ x[k] + Gam[k] @ u[k]
    return x


def _cumint(y, t):
    """Cumulative trapezoid integral of y(t) starting at 0."""
    out = np.zeros_like(y, dtype=float)
    out[1:] = np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))
    return out


def envelopes(t, *, lat, h, eps, n_g, nabla, n_a, sf_g, sf_a, phi0_h, psi0, dv0, dr0,
              acc_cum, rot_cum, speed_max):
    """Closed-form error envelopes (upper bounds) of free-inertial navigation.

    All inputs SI; ``t`` elapsed time [s]; ``eps``/``nabla`` bias magnitudes (3-D norms, a
    bound for any projection on the navigation axes); ``n_g``/``n_a`` random-walk
    magnitudes; ``sf_g``/``sf_a`` largest scale-factor errors; ``phi0_h``, ``psi0`` initial
    tilt and heading error [rad]; ``dv0``, ``dr0`` initial horizontal velocity/position
    errors; ``acc_cum(t) = ∫|a_h| dt`` (horizontal velocity change) and
    ``rot_cum(t) = ∫|ω_ib| dt`` (angle turned by the IMU) from the truth.

    Each source's response in the single-channel Schuler loop (ω_s² = g/R) is bounded by
    the magnitude of its closed form: drift u(t) (monotone) — tilt ≤ u/ω_s, velocity
    ≤ 2Ru, position ≤ R(∫u + u/ω_s); accelerometer bias ∇ — tilt ≤ 2∇/g, velocity ≤ ∇/ω_s,
    position ≤ 2∇/ω_s²; initial tilt φ0 — φ0, gφ0/ω_s, 2Rφ0; initial velocity δv0 —
    δv0/(Rω_s), δv0, δv0/ω_s; white noise at 4σ through the same loop. The heading error
    ψ(t) = ψ0 + εt + sf_g·rot + 4N√t + (ω_ie + V/R)·tilt·t couples into the level channels
    as a drift (ω_ie + V/R)ψ and, in manoeuvres, as velocity impulses ψ·|Δv| (plus the
    accelerometer scale factor times |Δv|).

    Returns a dict of arrays: ``pos``, ``vel``, ``tilt``, ``heading``.
    """
    t = np.asarray(t, float)
    g = float(earth.gravity(lat, h))
    rm, rn = earth.radii(lat, h)
    R = float(np.sqrt(rm * rn))
    ws = math.sqrt(g / R)
    wc = earth.WIE + speed_max / R                # rate coupling heading error into tilt
    st = np.sqrt(t / 2 + 1 / (4 * ws))            # sqrt of ∫cos², ∫sin² over [0, t] (bound)
    # first pass without heading coupling
    psi = psi0 + eps * t + sf_g * rot_cum + 4 * n_g * np.sqrt(t)
    for _ in range(2):
        u = eps + wc * psi                        # effective level drift, monotone in t
        tilt_imp = (psi + sf_a) * acc_cum / (R * ws)   # velocity impulses -> tilt
        tilt = (phi0_h + u / ws + 2 * nabla / g + dv0 / (R * ws) + sf_g * rot_cum
                + tilt_imp + 4 * n_g * st + 4 * n_a * st / (R * ws))
        psi = (psi0 + eps * t + sf_g * rot_cum + 4 * n_g * np.sqrt(t)
               + wc * np.maximum.accumulate(tilt) * t)
    u = eps + wc * psi
    vel = (2 * R * u + nabla / ws + g * phi0_h / ws + dv0 + (psi + sf_a) * acc_cum
           + 4 * R * ws * n_g * st + 4 * n_a * st)
    # impulses J(τ) = (ψ+sf_a)|a|dτ move position by ≤ J·min(t−τ, 1/ω_s)
    cap = 1 / ws
    A = acc_cum
    B = np.concatenate([[0.0], np.cumsum(0.5 * (t[1:] + t[:-1]) * np.diff(A))])   # ∫ τ |a| dτ
    tc = np.clip(t - cap, t[0], None)
    A_c = np.interp(tc, t, A)
    B_c = np.interp(tc, t, B)
    imp_pos = t * (A - A_c) - (B - B_c) + cap * A_c
    pos = (dr0 + R * (_cumint(u, t) + u / ws) + 2 * nabla / ws ** 2 + 2 * R * phi0_h + dv0 / ws
           + (psi + sf_a) * imp_pos
           + 4 * R * n_g * np.sqrt(1.5 * t + 2.25 / ws) + 4 * n_a / ws * st)
    return {"pos": pos, "vel": vel, "tilt": tilt, "heading": psi}


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


# ---------------------------------------------------------------- the experiment --------

def _motion(cfg: Config):
    from .. import trajectory as tr

    s = cfg.scenario
    T = float(s.duration)
    start = tr.Start(lat=float(s.latitude), lon=float(s.longitude), h=float(s.height),
                     speed=float(s.speed), heading=float(s.heading))
    if s.motion_file:
        m = tr.load_motion(s.motion_file)            # validated with the config
        return m.segments, (m.start or start), m.mount
    if s.motion == "static":
        return tr.static(T), tr.Start(lat=start.lat, lon=start.lon, h=start.h, heading=start.heading), None
    if s.motion == "ship_manoeuvring":
        return (tr.ship_manoeuvring(T), tr.Start(lat=start.lat, lon=start.lon, h=start.h,
                                                   heading=start.heading), None)
    return tr.aircraft_mixed(T), start, None


def run(cfg: Config, ctx) -> Result:
    from .. import imu as imu_mod
    from .. import strapdown, trajectory
    from ..records import NavState
    from .. import plotting as P

    s, n = cfg.scenario, cfg.nav
    dt, T = float(s.sample_interval), float(s.duration)
    upd = n.nsub * dt
    out_every = max(1, int(round(float(n.output_interval) / upd)))

    segments, start, mount = _motion(cfg)
    ctx.log(f"{NAME}: synthesising {T:g} s of motion at {1 / dt:g} Hz")
    gen = trajectory.generate(segments, start, dt, duration=T, mount=mount)
    truth_full, ideal = gen.truth, gen.imu

    errors = imu_mod.ImuErrors.from_datasheet(
        gyro_bias=cfg.imu.gyro_bias.text, gyro_arw=cfg.imu.gyro_arw.text,
        gyro_scale_factor=cfg.imu.gyro_scale_factor.text, accel_bias=cfg.imu.accel_bias.text,
        accel_vrw=cfg.imu.accel_vrw.text, accel_scale_factor=cfg.imu.accel_scale_factor.text)
    meas = imu_mod.apply(ideal, errors, ctx.rng(1))

    # initial state: truth + configured errors
    t0 = NavState.from_series(truth_full, 0)
    rm, rn = earth.radii(t0.lat, t0.h)
    dpos = np.asarray(cfg.init.pos_err)
    datt = np.asarray(cfg.init.att_err)
    init = NavState(lat=t0.lat + dpos[1] / rm, lon=t0.lon + dpos[0] / (rn * math.cos(t0.lat)),
                    h=t0.h + dpos[2], vel=t0.vel + np.asarray(cfg.init.vel_err),
                    att=t0.att + np.array([datt[0], datt[1], -datt[2]]), t=t0.t)
    height = truth_full.h if n.vertical != "free" else None
    ctx.log(f"{NAME}: navigating {len(meas)} samples")
    nav = strapdown.navigate(meas, init, nsub=n.nsub, vertical=n.vertical, height=height,
                             mount=gen.mount, out_every=out_every)

    # truth on the navigation epochs (epoch index j·out_every·nsub)
    ep = np.arange(len(nav)) * out_every * n.nsub
    truth = truth_full.at(ep)
    if not np.allclose(truth.t, nav.t, atol=1e-6 * max(dt, 1.0)):
        raise RuntimeError("navigation and truth epochs disagree")
    t = nav.t - nav.t[0]
    rm_t, rn_t = earth.radii(truth.lat, truth.h)
    pos_err = np.column_stack([_wrap(nav.lon - truth.lon) * rn_t * np.cos(truth.lat),
                               (nav.lat - truth.lat) * rm_t, nav.h - truth.h])
    vel_err = nav.vel - truth.vel
    att_err = np.column_stack([_wrap(nav.att[:, 0] - truth.att[:, 0]),
                               _wrap(nav.att[:, 1] - truth.att[:, 1]),
                               -_wrap(nav.att[:, 2] - truth.att[:, 2])])
    hpos = np.hypot(pos_err[:, 0], pos_err[:, 1])
    hvel = np.hypot(vel_err[:, 0], vel_err[:, 1])
    lat0, h_mean = float(truth.lat[0]), float(np.mean(truth.h))

    # ---- oracle 1: the linear error model driven by the realised sensor errors
    from ..attitude import euler_to_dcm, misalignment

    att_t = truth.att_imu if truth.att_imu is not None else truth.att
    att_n = nav.att_imu if nav.att_imu is not None else nav.att
    phi_act = misalignment(euler_to_dcm(att_t), euler_to_dcm(att_n))
    core = {"hold": "horizontal", "free": "full"}.get(n.vertical)
    lin = None
    if core is not None:
        x0 = np.concatenate([phi_act[0], (init.vel - t0.vel)[: 2 if core == "horizontal" else 3],
                             [init.lat - t0.lat, init.lon - t0.lon] + ([init.h - t0.h] if core == "full" else [])])
        with ctx.progress("linear error model", None):
            X = linear_error_prediction(truth_full, ideal, meas, ep, x0, core)
        nv = 2 if core == "horizontal" else 3
        lin_pos = np.column_stack([X[:, 3 + nv + 1] * rn_t * np.cos(truth.lat), X[:, 3 + nv] * rm_t])
        lin_vel = X[:, 3:5]
        lin_phi = X[:, :3]
        res_pos = float(np.max(np.hypot(*(pos_err[:, :2] - lin_pos).T)))
        res_vel = float(np.max(np.hypot(*(vel_err[:, :2] - lin_vel).T)))
        res_phi = float(np.max(np.linalg.norm(phi_act - lin_phi, axis=1)))
        lin = dict(pos=lin_pos, vel=lin_vel, phi=lin_phi, res_pos=res_pos, res_vel=res_vel,
                   res_phi=res_phi)

    # ---- oracle 2: the Schuler period, from the free response to a velocity perturbation
    ts_theory = float(earth.schuler_period(lat0, h_mean))
    schuler = schuler_direct = None
    if t[-1] >= ts_theory:
        dvp = 1.0
        init_p = NavState(lat=init.lat, lon=init.lon, h=init.h, vel=init.vel + [0.0, dvp, 0.0],
                          att=init.att, t=init.t)
        nav_p = strapdown.navigate(meas, init_p, nsub=n.nsub, vertical=n.vertical, height=height,
                                   mount=gen.mount, out_every=out_every)
        schuler = fit_schuler_period(t, (nav_p.vel - nav.vel)[:, :2])
        schuler_direct = fit_schuler_period(t, vel_err[:, :2])

    # ---- oracle 3: closed-form static-error-model envelopes (loose upper bounds)
    vh_full = truth_full.vel[:, :2]
    dvh = np.linalg.norm(np.diff(vh_full, axis=0), axis=1)
    acc_cum_full = np.concatenate([[0.0], np.cumsum(dvh)])
    rot_cum_full = np.concatenate([[0.0], np.cumsum(np.linalg.norm(ideal.dtheta, axis=1))])
    dist_full = np.concatenate([[0.0], np.cumsum(np.linalg.norm(vh_full[:-1] + vh_full[1:], axis=1) * dt / 2)])
    env = envelopes(
        t, lat=lat0, h=h_mean,
        eps=float(np.linalg.norm(cfg.imu.gyro_bias)), n_g=float(np.linalg.norm(cfg.imu.gyro_arw)),
        nabla=float(np.linalg.norm(cfg.imu.accel_bias)), n_a=float(np.linalg.norm(cfg.imu.accel_vrw)),
        sf_g=float(np.max(np.abs(cfg.imu.gyro_scale_factor))),
        sf_a=float(np.max(np.abs(cfg.imu.accel_scale_factor))),
        phi0_h=float(np.hypot(datt[0], datt[1])), psi0=abs(float(datt[2])),
        dv0=float(np.hypot(*np.asarray(cfg.init.vel_err)[:2])),
        dr0=float(np.hypot(dpos[0], dpos[1])),
        acc_cum=acc_cum_full[ep], rot_cum=rot_cum_full[ep],
        speed_max=float(np.max(np.linalg.norm(vh_full, axis=1))))
    tilt = np.max(np.abs(att_err[:, :2]), axis=1)
    ratios = {k: float(np.max(e / np.maximum(env[b], 1e-300)))
              for k, e, b in (("pos", hpos, "pos"), ("vel", hvel, "vel"), ("tilt", tilt, "tilt"),
                              ("heading", np.abs(att_err[:, 2]), "heading"))}

    metrics = {
        "max_horiz_pos_err_m": float(hpos.max()),
        "final_horiz_pos_err_m": float(hpos[-1]),
        "max_horiz_vel_err_mps": float(hvel.max()),
        "final_att_err_arcsec": (att_err[-1] / units.arcsec).tolist(),
        "schuler_period_min": None if schuler is None else schuler / 60.0,
        "schuler_period_theory_min": ts_theory / 60.0,
        "schuler_period_direct_min": None if schuler_direct is None else schuler_direct / 60.0,
        "linear_model_pos_residual_m": None if lin is None else lin["res_pos"],
        "linear_model_vel_residual_mps": None if lin is None else lin["res_vel"],
        "linear_model_att_residual_arcsec": None if lin is None else lin["res_phi"] / units.arcsec,
        "pos_envelope_ratio": ratios["pos"],
        "vel_envelope_ratio": ratios["vel"],
        "tilt_envelope_ratio": ratios["tilt"],
        "heading_envelope_ratio": ratios["heading"],
        "distance_m": float(dist_full[ep[-1]]),
        "samples": int(len(meas)),
    }

    claims, notes = [], []
    if schuler is not None:
        claims.append(Claim.within(
            "schuler_period", "period of the velocity-error response to a 1 m/s initial north "
            "velocity error (two solutions on the same IMU data, Foucault split removed) equals "
            "the Schuler period 2π·sqrt(R/g) at the start latitude and mean height [min]",
            schuler / 60.0, ts_theory / 60.0, rel=0.01, unit="min"))
    else:
        notes.append(f"run shorter than one Schuler period ({ts_theory / 60:.1f} min): "
                     "no period fitted, claim schuler_period not evaluated")
    if lin is not None:
        scale_p = float(np.max(np.hypot(*lin["pos"].T)))
        scale_v = float(np.max(np.hypot(*lin["vel"].T)))
        scale_a = float(np.max(np.linalg.norm(lin["phi"], axis=1)))
        claims += [
            Claim.at_most("pos_linear_model", "horizontal position error = linear error model "
                          "driven by the realised sensor errors: max residual [m] within "
                          f"{LIN_REL:.0%} of the model's peak + {LIN_ABS_POS:g} m",
                          lin["res_pos"], LIN_REL * scale_p + LIN_ABS_POS, "m"),
            Claim.at_most("vel_linear_model", "horizontal velocity error = linear error model: "
                          f"max residual [m/s] within {LIN_REL:.0%} of the model's peak + "
                          f"{LIN_ABS_VEL:g} m/s", lin["res_vel"], LIN_REL * scale_v + LIN_ABS_VEL, "m/s"),
            Claim.at_most("att_linear_model", "misalignment φ = linear error model: max residual "
                          f"[arcsec] within {LIN_REL:.0%} of the model's peak + {LIN_ABS_ATT:g} arcsec",
                          lin["res_phi"] / units.arcsec,
                          (LIN_REL * scale_a) / units.arcsec + LIN_ABS_ATT, "arcsec"),
        ]
    else:
        notes.append("damped vertical channel: the linear-model claims are not evaluated "
                     "(the model has no damping loop)")
    for key, what in (("pos", "horizontal position error"), ("vel", "horizontal velocity error"),
                      ("tilt", "pitch and roll errors"), ("heading", "heading error")):
        claims.append(Claim.at_most(
            f"{key}_envelope", f"{what}: max over time of error / closed-form static-error-model "
            "envelope (a loose upper bound on a manoeuvring trajectory)", ratios[key], 1.0))

    # ---- series and figures
    series = {
        "errors": {
            "t_s": nav.t,
            "pos_err_e_m": pos_err[:, 0], "pos_err_n_m": pos_err[:, 1], "pos_err_u_m": pos_err[:, 2],
            "vel_err_e_mps": vel_err[:, 0], "vel_err_n_mps": vel_err[:, 1], "vel_err_u_mps": vel_err[:, 2],
            "att_err_pitch_arcsec": att_err[:, 0] / units.arcsec,
            "att_err_roll_arcsec": att_err[:, 1] / units.arcsec,
            "att_err_heading_arcsec": att_err[:, 2] / units.arcsec,
            "env_pos_m": env["pos"], "env_vel_mps": env["vel"],
            "env_tilt_arcsec": env["tilt"] / units.arcsec, "env_heading_arcsec": env["heading"] / units.arcsec,
        },
        "truth": {
            "t_s": truth.t, "lat_deg": truth.lat / units.deg, "lon_deg": truth.lon / units.deg,
            "h_m": truth.h, "vel_e_mps": truth.vel[:, 0], "vel_n_mps": truth.vel[:, 1],
            "vel_u_mps": truth.vel[:, 2], "pitch_deg": truth.att[:, 0] / units.deg,
            "roll_deg": truth.att[:, 1] / units.deg,
            "heading_deg": np.mod(-truth.att[:, 2], 2 * np.pi) / units.deg,
        },
    }
    tt, tlabel = P.time_axis(t)
    figs = []
    fig, ax = P.figure(2)
    P.components(ax[0], tt, pos_err[:, :2], ["east", "north"], "position error [m]")
    if lin is not None:
        P.components(ax[0], tt, lin["pos"], ["east, linear model", "north, linear model"],
                     styles=[dict(ls="--", color="k", lw=0.8), dict(ls=":", color="k", lw=0.8)])
    P.components(ax[1], tt, np.maximum(hpos, 1e-3), ["horizontal"], "horizontal [m], log")
    ax[1].semilogy(tt, env["pos"], ls="--", color="0.3", lw=1.0, label="closed-form envelope (upper bound)")
    ax[1].set_ylim(max(1e-3 * float(hpos.max()), 1e-3), 2 * float(max(env["pos"].max(), hpos.max())))
    ax[1].legend(fontsize="small")
    ax[1].set_xlabel(tlabel)
    figs.append(Figure("pos_err", fig, "Position error of free-inertial navigation (navigation − truth); "
                                       "black: linear error model driven by the realised sensor errors"))
    fig, ax = P.figure(2)
    P.components(ax[0], tt, vel_err[:, :2], ["east", "north"], "velocity error [m/s]")
    if lin is not None:
        P.components(ax[0], tt, lin["vel"], ["east, linear model", "north, linear model"],
                     styles=[dict(ls="--", color="k", lw=0.8), dict(ls=":", color="k", lw=0.8)])
    P.components(ax[1], tt, np.maximum(hvel, 1e-6), ["horizontal"], "horizontal [m/s], log")
    ax[1].semilogy(tt, env["vel"], ls="--", color="0.3", lw=1.0, label="closed-form envelope (upper bound)")
    ax[1].set_ylim(max(1e-3 * float(hvel.max()), 1e-6), 2 * float(max(env["vel"].max(), hvel.max())))
    ax[1].legend(fontsize="small")
    ax[1].set_xlabel(tlabel)
    cap = "Velocity error (navigation − truth); black: linear error model"
    if schuler is not None:
        cap += (f"; Schuler period fitted to the free response {schuler / 60:.2f} min vs "
                f"2π·sqrt(R/g) = {ts_theory / 60:.2f} min")
    figs.append(Figure("vel_err", fig, cap))
    fig, ax = P.figure(2)
    P.components(ax[0], tt, att_err[:, :2] / units.arcsec, ["pitch", "roll"], "pitch, roll error [arcsec]")
    P.components(ax[1], tt, att_err[:, 2:] / units.arcsec, ["heading"], "heading error [arcsec]")
    ax[1].set_xlabel(tlabel)
    figs.append(Figure("att_err", fig, "Attitude error: pitch, roll, heading (heading clockwise from north)"))
    fig, ax = P.figure(1, row_height=4.0, width=6.0)
    e_km = _wrap(truth.lon - truth.lon[0]) * rn_t * np.cos(truth.lat) / 1e3
    n_km = (truth.lat - truth.lat[0]) * rm_t / 1e3
    ax[0].plot(e_km, n_km, color=P.COLORS[0], lw=1.2)
    ax[0].plot(e_km[0], n_km[0], "o", color=P.COLORS[2], label="start")
    ax[0].set_xlabel("east [km]")
    ax[0].set_ylabel("north [km]")
    ax[0].set_aspect("equal", adjustable="datalim")
    ax[0].legend(fontsize="small")
    figs.append(Figure("track", fig, f"True ground track ({s.motion_file or s.motion})"))

    notes.append(f"Vertical channel: {n.vertical}"
                 + (" (held to the true height, a perfect barometer)" if n.vertical == "hold" else "")
                 + f"; {n.nsub} samples per update; error series every {out_every * upd:g} s.")
    return Result(metrics=metrics, claims=claims, series=series, figures=figs, notes=notes)
