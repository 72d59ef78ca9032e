"""double-star: paper 003 (Liu, Lin, Lai, Sun 2004) — Beidou-1 two-GEO fixes with a 1 s
position lag fused with a SINS inside short covert windows.

The aircraft trajectory (:func:`sinslab.sim.presets.aircraft_mixed`: level flight, turns,
climb/descent, acceleration) is synthesised with exact IMU increments; each Monte Carlo
run draws the initial navigation errors, the sensor errors (gyro constant drift, gyro and
accelerometer first-order Markov processes, gyro white noise) and the fixes (σ from the
two-GEO error model at the true position, paper eqs 11–15) and runs three filters on
the same data (:func:`sinslab.methods.doublestar.integrate`):

- ``lag-aware``: the paper's method (eqs 4–10): the fix of time t, received at t + ΔT, is
  applied at t from the stored state and predicted to t + ΔT in one step
  (:class:`sinslab.methods.doublestar.StoredStateUpdate`);
- ``lag-ignore``: the fix is applied at its arrival as if current;
- ``zero-lag``: an ideal receiver without delay (same fixes, available at t).

The covariance analysis (paper Figs 2–4) is the lag-aware filter's own covariance along
the error-free trajectory (same schedule, same model); the Monte Carlo RMS errors are
plotted next to it.

Claims (each computed, each able to fail): the lag-aware filter beats the lag-ignoring one;
it is within 10 % of the zero-lag filter (RMS horizontal position error over runs and
time); the Monte Carlo RMS / σ ratio of horizontal position and of attitude lies within
0.8–1.2; the fixes reduce the position error in every window.

Beyond the paper, ``filter.measurement = "ranges"`` (the demo's ``double-star-ranges``):
each run draws the two measured paths and the height source error instead of the fix
(:func:`sinslab.methods.doublestar_ranges.plan_paths`) and runs two lag-aware filters on
the same draws: the paper's, on the fix solved from those paths at the erroneous height
with the diagonal R of eqs 11–15, and :func:`sinslab.methods.doublestar_ranges.integrate_ranges`
on the paths themselves. Its claims are the project's checks: the path filter is no worse
than the paper's, its normalised errors at every window end lie inside their chi-square
band, its Monte Carlo RMS / σ within 0.8–1.2.
"""
from __future__ import annotations

from typing import Literal

import numpy as np

from pydantic import model_validator

from sinslab.core import units
from sinslab.experiments.base import (Axis, Claim, ExperimentConfig, Field, Figure, Metric, Q, QV, Result, Section,
                                      Table, imu_section)

NAME = "double-star"
PURPOSE = "paper 003: Beidou-1 two-GEO fixes with 1 s lag + SINS in covert windows (lag-aware filter)"
PAPER = ("Liu Jianye, Lin Xueyuan, Lai Jizhou, Sun Yongrong: One fusion method of double-star "
         "positioning system and SINS, 2004")
NOTES = [
    "Not stated by the paper, assumed here: gyro Markov correlation time 3600 s, accelerometer "
    "Markov correlation time 1800 s; 'gyro white noise 0.1 deg/h' read as a rate white noise "
    "of 0.1 deg/h per 1 s filter step, i.e. angle random walk 0.1 deg/h*sqrt(s) = 0.00167 deg/sqrt(h); "
    "accelerometer white noise 0 (the paper's model has none).",
    "Initial errors (attitude 100'', 100'', 200''; velocity 1 m/s; position 15 m) and the gyro "
    "constant drift (0.1 deg/h) are 1-sigma values drawn per Monte Carlo run; the Markov "
    "processes start in steady state.",
    "Fix error model: eqs 11-15 as printed (height term with R_N/(R_N+h), h = user height) by "
    "default; the derivation (tests) gives (R_N+h)/r_GEO instead - set fix.height_factor = "
    "\"geometric\". Both values are reported.",
    "Vertical channel held to the true height (the paper's barometric altimeter; the model has "
    "no vertical channel). Fed back to the INS: attitude, velocity, position and gyro constant "
    "drift; the Markov states are kept in the filter.",
    "Fix schedule: inside each window the first request is at the window start, each next "
    "request at the arrival of the previous fix; fixes that would arrive after the window "
    "end are not requested.",
    "Attitude errors are the misalignment angles phi (ENU, computed frame vs true).",
]


# ---------------------------------------------------------------- configuration -------
class Scenario(Section):
    latitude: Q("angle", ge="-85 deg", le="85 deg") = Field("32 deg", description="start latitude")
    longitude: Q("angle", ge="-180 deg", le="360 deg") = Field("118 deg", description="start longitude")
    height: Q("length", ge="-500 m", le="20 km") = Field("1000 m", description="start height")
    speed: Q("velocity", ge="0 m/s", le="1000 m/s") = Field("300 m/s", description="start speed")
    heading: Q("angle", ge="-360 deg", le="360 deg") = Field("0 deg", description="start heading, clockwise from north")
    duration: Q("time", gt="0 s", le="1 d") = Field("1200 s", description="length of the flight")
    sample_interval: Q("time", gt="0 s", le="0.5 s") = Field("0.01 s", description="IMU sampling interval")


class Fix(Section):
    sat_lon1: Q("angle") = Field("80 deg", description="longitude of satellite 1 (round trip / inquiry)")
    sat_lon2: Q("angle") = Field("140 deg", description="longitude of satellite 2")
    ranging_error: Q("length", ge="0 m") = Field("20 m", description="m0: ranging error after differential correction")
    ephemeris_error: Q("length", ge="0 m") = Field("10 m", description="m1: equivalent ranging error of the ephemeris")
    height_error: Q("length", ge="0 m") = Field("50 m", description="dH: height (elevation) error")
    height_factor: Literal["paper", "geometric"] = Field(
        "paper", description="height terms: R_N/(R_N+h) as printed, or (R_N+h)/r_GEO (derived)")
    correlated: bool = Field(False, description="draw north/east fix errors with their correlation "
                                                "(the filter still uses the paper's diagonal R)")
    latency: Q("time", ge="0 s") = Field("1 s", description="delay from request to reception")
    latency_jitter: Q("time", ge="0 s") = Field("0 s", description="latency uniform in latency ± jitter")
    windows: list[QV("time", 2)] = Field(
        ["[296, 305] s", "[596, 605] s", "[896, 905] s", "[1196, 1200] s"],
        description="covert windows [start, end] in which the receiver transmits")


Imu = imu_section("Imu", {
    "gyro_bias_sigma": "0.1 deg/h",
    "gyro_bias_instability": "0.1 deg/h",
    "gyro_corr_time": ("3600 s", "assumed"),
    "gyro_arw": "0.1 deg/h*sqrt(s)",
    "accel_bias_instability": "100 ug",
    "accel_corr_time": ("1800 s", "assumed"),
}, scalar=True, renamed={"gyro_drift": "gyro_bias_sigma", "gyro_markov": "gyro_bias_instability",
                         "gyro_markov_tau": "gyro_corr_time", "gyro_white": "gyro_arw",
                         "accel_markov": "accel_bias_instability", "accel_markov_tau": "accel_corr_time"})


class Init(Section):
    att_err: QV("angle", ge="0 arcsec") = Field("[100, 100, 200] arcsec",
                                                description="initial misalignment σ [east, north, up]")
    vel_err: Q("velocity", ge="0 m/s") = Field("1 m/s", description="initial horizontal velocity error σ")
    pos_err: Q("length", ge="0 m") = Field("15 m", description="initial horizontal position error σ")


class Filter(Section):
    kf_dt: Q("time", gt="0 s") = Field("1 s", description="filter step (fix requests are on this grid)")
    nsub: int = Field(2, ge=1, le=5, description="samples per strapdown update")
    lag_method: Literal["paper003", "exact"] = Field(
        "paper003", description="lag-aware update: the paper's one-step form or exact re-processing")
    measurement: Literal["fix", "ranges"] = Field(
        "fix", description="what the filter takes: the two-GEO fix (the paper's three filters) or the two "
                           "measured paths and the height source (lag-aware), compared with the paper's "
                           "lag-aware fix filter on the same draws")


class Config(ExperimentConfig):
    runs: int = Field(200, ge=1, le=100000, description="Monte Carlo runs")
    scenario: Scenario = Scenario()
    fix: Fix = Fix()
    imu: Imu = Imu()
    init: Init = Init()
    filter: Filter = Filter()

    @model_validator(mode="after")
    def _consistent(self):
        """Cross-key checks, so bad input fails before a run folder is made."""
        from sinslab.methods import doublestar as ds

        s, f, fl = self.scenario, self.fix, self.filter
        dt, kf = float(s.sample_interval), float(fl.kf_dt)
        k = round(kf / dt)
        if k < 1 or abs(k * dt - kf) > 1e-6 * kf or k % fl.nsub:
            raise ValueError(f"filter.kf_dt {fl.kf_dt.text!r} must be a multiple of filter.nsub x "
                             f"scenario.sample_interval ({fl.nsub * dt:g} s)")
        try:
            ds.check_windows([tuple(float(x) for x in w) for w in f.windows], 0.0, float(s.duration))
        except ValueError as e:
            raise ValueError(f"fix.windows: {e}") from None
        try:
            ds.request_schedule([tuple(float(x) for x in w) for w in f.windows], float(f.latency),
                                jitter=float(f.latency_jitter), grid=kf, rng=np.random.default_rng(0))
        except ValueError as e:
            raise ValueError(f"fix.latency: {e}") from None
        try:
            ds.check_geometry(float(s.latitude), float(f.sat_lon1), float(f.sat_lon2))
        except ValueError as e:
            raise ValueError(f"fix / scenario.latitude: {e}") from None
        return self


QUICK = {"runs": 40, "scenario": {"sample_interval": "0.05 s"}}

#: ``double-star-ranges`` in ``sinslab demo``: the two paths in the filter against the
#: paper's fix filter, 100 runs.
DEMO_VARIANTS = {"ranges": ["filter.measurement=ranges", "runs=100"]}

#: CPU seconds of each ``sinslab demo`` run at full scale, robustness re-runs included
#: (quiet machine): the demo starts the longest first.
DEMO_COST_S = {"": 19, "ranges": 9}

METRICS = {
    "fix_sigma_ns_m": Metric("m", "two-GEO fix σ north-south at the start position (eqs 11-15, configured height factor)"),
    "fix_sigma_ew_m": Metric("m", "two-GEO fix σ east-west at the start position"),
    "fix_sigma_ns_geometric_m": Metric("m", "the same with the derived height factor (R_N+h)/r_GEO"),
    "fix_sigma_ew_geometric_m": Metric("m", "the same with the derived height factor"),
    "fix_sigma_ns_linearised_m": Metric("m", "exact first-order σ north-south on WGS-84 (no r_i≈r_s approximation)"),
    "fix_sigma_ew_linearised_m": Metric("m", "exact first-order σ east-west on WGS-84"),
    "pos_sigma_at_end_m": Metric("m", "covariance analysis: horizontal position σ at the end (lag-aware filter)"),
    "pos_sigma_before_first_window_m": Metric("m", "covariance analysis: horizontal position σ at the first window start"),
    "rms_pos_err_lagaware_m": Metric("m", "Monte Carlo RMS horizontal position error over runs and time, lag-aware filter"),
    "rms_pos_err_lagignore_m": Metric("m", "the same, filter ignoring the lag"),
    "rms_pos_err_zerolag_m": Metric("m", "the same, ideal zero-lag filter"),
    "rms_pos_err_in_windows_lagaware_m": Metric("m", "Monte Carlo RMS horizontal position error over runs and the "
                                                "samples inside the fix windows, lag-aware filter"),
    "rms_pos_err_in_windows_zerolag_m": Metric("m", "the same, ideal zero-lag filter"),
    "max_pos_err_outside_windows_m": Metric("m", "largest Monte Carlo RMS horizontal position error outside the windows (lag-aware)"),
    "mc_rms_over_sigma_pos": Metric("-", "mean over time of MC RMS / σ, horizontal position (lag-aware)"),
    "mc_rms_over_sigma_att": Metric("-", "mean over time of MC RMS / σ, attitude (3 axes combined, lag-aware)"),
    "mc_rms_over_sigma_vel": Metric("-", "mean over time of MC RMS / σ, horizontal velocity (lag-aware)"),
    "window_pos_rms_ratio": Metric("-", "per window: MC RMS horizontal position error at the window end / at its start"),
    "fixes_per_run": Metric("-", "fixes applied per run"),
    "runs": Metric("-", "Monte Carlo runs"),
    # filter.measurement = "ranges"
    "rms_pos_err_fix_m": Metric("m", "Monte Carlo RMS horizontal position error over runs and time, the "
                                     "paper's lag-aware filter on fixes solved from the drawn paths"),
    "rms_pos_err_ranges_m": Metric("m", "the same, lag-aware filter on the two drawn paths and the height source"),
    "window_end_pos_rms_fix_m": Metric("m", "per window: MC RMS horizontal position error at the window end, fix filter"),
    "window_end_pos_rms_ranges_m": Metric("m", "per window: the same, path filter"),
    "pos_sigma_at_end_fix_m": Metric("m", "covariance analysis: horizontal position σ at the end, fix filter"),
    "pos_sigma_at_end_ranges_m": Metric("m", "covariance analysis: horizontal position σ at the end, path filter"),
    "mc_rms_over_sigma_pos_fix": Metric("-", "mean over time of MC RMS / σ, horizontal position, fix filter"),
    "mc_rms_over_sigma_pos_ranges": Metric("-", "mean over time of MC RMS / σ, horizontal position, path filter"),
    "nees_window_end_north_ranges": Metric("-", "per window end: mean over runs of (north error / filter σ)², path filter"),
    "nees_window_end_east_ranges": Metric("-", "per window end: mean over runs of (east error / filter σ)², path filter"),
    "requests_per_run": Metric("-", "path requests applied per run (path filter)"),
}

_MODES = ("lag-aware", "lag-ignore", "zero-lag")
_KEY = {"lag-aware": "lagaware", "lag-ignore": "lagignore", "zero-lag": "zerolag"}


# ---------------------------------------------------------------- one Monte Carlo batch ---
def _setup(cfg: Config, quick=False):
    """Everything a run needs, as plain picklable values."""
    from sinslab.methods import doublestar as ds
    from sinslab.sim import presets
    from sinslab.sim import trajectory as tr

    s, f, im, ini, fl = cfg.scenario, cfg.fix, cfg.imu, cfg.init, cfg.filter
    dt, T = float(s.sample_interval), float(s.duration)
    kf_dt = float(fl.kf_dt)
    k_kf = int(round(kf_dt / dt))
    windows = [tuple(float(x) for x in w) for w in f.windows]
    start = tr.Start(lat=float(s.latitude), lon=float(s.longitude), h=float(s.height),
                     speed=float(s.speed), heading=float(s.heading))
    gen = tr.generate(presets.aircraft_mixed(T), start, dt, duration=T)
    model_args = dict(gyro_arw=float(im.gyro_arw), gyro_markov_sigma=float(im.gyro_bias_instability),
                      gyro_markov_tau=float(im.gyro_corr_time),
                      accel_markov_sigma=float(im.accel_bias_instability),
                      accel_markov_tau=float(im.accel_corr_time))
    model = ds.horizontal_model(**model_args)
    P0 = ds.initial_covariance(model, start.lat, start.h, np.asarray(ini.att_err), float(ini.vel_err),
                               float(ini.pos_err), float(im.gyro_bias_sigma), float(im.gyro_bias_instability),
                               float(im.accel_bias_instability))
    fix_args = dict(sat_lon1=float(f.sat_lon1), sat_lon2=float(f.sat_lon2), m0=float(f.ranging_error),
                    m1=float(f.ephemeris_error), dH=float(f.height_error), latency=float(f.latency),
                    latency_jitter=float(f.latency_jitter), grid=kf_dt, correlated=bool(f.correlated),
                    height_factor=f.height_factor)
    ep = np.arange(len(gen.imu) // k_kf + 1) * k_kf
    return dict(truth=gen.truth, imu=gen.imu, ep=ep, windows=windows, model_args=model_args, P0=P0,
                fix_args=fix_args, kf_dt=kf_dt, nsub=int(fl.nsub), lag=ds.lag_policy(fl.lag_method),
                imu_errors=im.errors())


def _inputs(rng, S, plan=None, zero_errors=False):
    """One run's IMU record, initial state and fixes, drawn from ``rng`` in a fixed order:
    16 normals (initial errors and gyro constant drift, each times its σ), the IMU noise,
    the fix errors (and, with a random latency, the fix schedule first). ``plan``: the
    run-independent :class:`~sinslab.methods.doublestar.FixPlan` of a constant latency, or
    any object whose ``draw(rng)`` makes the measurements (a
    :class:`~sinslab.methods.doublestar_ranges.PathPlan` gives ``(paths, fixes)``)."""
    from sinslab.methods import doublestar as ds
    from sinslab.sim import imu as imu_mod
    from sinslab.core.attitude import apply_misalignment, dcm_to_euler, euler_to_dcm
    from sinslab.core.records import Fixes, NavState

    truth, ideal, P0 = S["truth"], S["imu"], S["P0"]
    if zero_errors:
        x0 = np.zeros(16)
        meas = ideal
    else:
        x0 = rng.standard_normal(16) * np.sqrt(np.diag(P0))
        meas = imu_mod.apply(ideal, S["imu_errors"].replace(gyro_bias=x0[7:10]), rng)
    att0 = dcm_to_euler(apply_misalignment(euler_to_dcm(truth.att[0]), x0[:3]))
    init = NavState(truth.lat[0] + x0[5], truth.lon[0] + x0[6], truth.h[0],
                    truth.vel[0] + np.array([x0[3], x0[4], 0.0]), att0, truth.t[0])
    if zero_errors:     # covariance analysis: exact fixes, the filter keeps the model σ in R
        fixes = ds.simulate_fixes(truth, S["windows"], rng=np.random.default_rng(0), **S["fix_args"])
        lat, lon, _ = ds._interp_truth(truth, fixes.t)
        fixes = Fixes(fixes.t, lat, lon, fixes.h, fixes.sigma, t_arrive=fixes.t_arrive)
    elif plan is not None:
        fixes = plan.draw(rng)
    else:
        fixes = ds.simulate_fixes(truth, S["windows"], rng=rng, **S["fix_args"])
    return meas, init, fixes


def _filters(meas, init, fixes, S, model, height):
    """The three filters of one run on the same data: {mode: Integration}."""
    from sinslab.methods import doublestar as ds

    return {mode: ds.integrate(meas, init, fixes, model, S["P0"], mode=mode, lag=S["lag"],
                               height=height, windows=S["windows"], kf_dt=S["kf_dt"], nsub=S["nsub"])
            for mode in _MODES}


def _one(rng, S, zero_errors=False):
    """One run: draw errors, run the three filters; errors at the filter epochs."""
    from sinslab.methods import doublestar as ds

    model = ds.horizontal_model(**S["model_args"])
    res = _filters(*_inputs(rng, S, zero_errors=zero_errors), S, model, S["truth"].h)
    tt = S["truth"].at(S["ep"])
    out = {}
    for mode, r in res.items():
        k = _KEY[mode]
        out[f"phi_{k}"], out[f"dv_{k}"], out[f"dp_{k}"] = ds.horizontal_errors(r.nav, tt)
    out["sigma"] = res["lag-aware"].sigma
    out["nfix"] = np.array(len(res["lag-aware"].applied))
    return out


#: Runs whose filters step in lockstep on the driver's run axis (their inputs are held at
#: once: ~7 MB of IMU record per run).
LANES = 8


def _squares(out):
    """What the campaign's statistics need of each run of :func:`_batch` (summed over the
    runs where they are computed): per filter the squared errors of horizontal position
    (north, east and their sum), velocity and attitude at every epoch; the fixes applied."""
    sq = {"nfix": out["nfix"]}
    for k in _KEY.values():
        for q in ("dp", "dv", "phi"):
            sq[f"{q}_{k}"] = out[f"{q}_{k}"] ** 2
        sq[f"pos_h_{k}"] = sq[f"dp_{k}"].sum(-1)
    return sq


def _batch(seeds, S):
    """A Monte Carlo task: the runs of ``seeds`` stacked.

    What the runs share is made once — the error model, the fix plan of a constant
    latency (schedule, truth and σ at the requests), the held height with its vertical
    rate per block. Each run draws its inputs from its own generator; with a constant
    latency the runs share the fix schedule and each filter steps up to :data:`LANES` runs
    in lockstep on the fusion driver's run axis (:func:`sinslab.methods.doublestar.integrate_many`;
    with a random latency every run has its own schedule and runs alone). The errors of all
    runs and filters against the truth are formed in one pass over (filters × runs ×
    epochs). The same numbers as :func:`_one` per seed.
    """
    from sinslab.methods import doublestar as ds
    from sinslab.nav import strapdown as sd

    truth = S["truth"]
    model = ds.horizontal_model(**S["model_args"])
    held = sd.HeldHeight(truth.h, S["imu"].dt)
    fa = S["fix_args"]
    plan = (ds.plan_fixes(truth, S["windows"], **fa) if fa["latency_jitter"] == 0 else None)
    B, M = len(seeds), S["ep"].size
    nav = np.empty((len(_MODES), B, M, 10))
    sigma = np.empty((B, M, 16))
    nfix = np.empty(B, dtype=np.int64)
    width = LANES if plan is not None else 1
    for g0 in range(0, B, width):
        runs = [_inputs(np.random.default_rng(seed), S, plan) for seed in seeds[g0:g0 + width]]
        for i, mode in enumerate(_MODES):
            res = ds.integrate_many(runs, model, S["P0"], mode=mode, lag=S["lag"],
                                    height=held, windows=S["windows"], kf_dt=S["kf_dt"], nsub=S["nsub"])
            for b, r in enumerate(res, g0):
                nav[i, b] = r.nav
                if mode == "lag-aware":
                    sigma[b] = r.sigma
                    nfix[b] = len(r.applied)
    phi, dv, dp = ds.horizontal_errors(nav, truth.at(S["ep"]))
    out = {}
    for i, mode in enumerate(_MODES):
        k = _KEY[mode]
        out[f"phi_{k}"], out[f"dv_{k}"], out[f"dp_{k}"] = phi[i], dv[i], dp[i]
    out["sigma"], out["nfix"] = sigma, nfix
    return out


# ---------------------------------------------------------------- the two paths in the filter
def _path_args(S):
    """The fix settings as :func:`sinslab.methods.doublestar_ranges.plan_paths` takes them
    (the path errors carry their own correlation: ``fix.correlated`` has no say)."""
    return {k: v for k, v in S["fix_args"].items() if k != "correlated"}


class _FreshPaths:
    """A random latency: each run draws its own schedule, then its errors, from one generator."""

    def __init__(self, S):
        self.truth, self.windows, self.args = S["truth"], S["windows"], _path_args(S)

    def draw(self, rng):
        from sinslab.methods import doublestar_ranges as dr

        return dr.plan_paths(self.truth, self.windows, rng=rng, **self.args).draw(rng)


def _ranges_pair(runs, S, model, height):
    """The paper's lag-aware fix filter and the lag-aware path filter on the runs ``[(imu,
    init, (paths, fixes))]`` (same draws): two lists of Integration."""
    from sinslab.methods import doublestar as ds
    from sinslab.methods import doublestar_ranges as dr

    fa = S["fix_args"]
    common = dict(mode="lag-aware", lag=S["lag"], height=height, windows=S["windows"],
                  kf_dt=S["kf_dt"], nsub=S["nsub"])
    fix = ds.integrate_many([(m, i, d[1]) for m, i, d in runs], model, S["P0"], **common)
    rng_sigma, h_sigma = float(np.hypot(fa["m0"], fa["m1"])), fa["dH"]
    ranges = [dr.integrate_ranges(m, i, d[1].t, d[0], model, S["P0"], sat_lon1=fa["sat_lon1"],
                                  sat_lon2=fa["sat_lon2"], range_sigma=rng_sigma, height_sigma=h_sigma,
                                  t_arrive=d[1].t_arrive, **common) for m, i, d in runs]
    return fix, ranges


def _batch_ranges(seeds, S):
    """A Monte Carlo task of ``filter.measurement = "ranges"``: per run one draw of the
    initial errors, the IMU noise and the path and height errors (:func:`_inputs` order),
    the fix solved from those paths and both filters on them. With a constant latency the
    fix filter steps :data:`LANES` runs in lockstep; the path filter runs each alone."""
    from sinslab.methods import doublestar as ds
    from sinslab.methods import doublestar_ranges as dr
    from sinslab.nav import strapdown as sd

    truth = S["truth"]
    model = ds.horizontal_model(**S["model_args"])
    held = sd.HeldHeight(truth.h, S["imu"].dt)
    pa = _path_args(S)
    const = pa["latency_jitter"] == 0
    plan = dr.plan_paths(truth, S["windows"], **pa) if const else _FreshPaths(S)
    B, M = len(seeds), S["ep"].size
    nav = np.empty((2, B, M, 10))
    sigma = np.empty((2, B, M, 2))
    nreq = np.empty(B, dtype=np.int64)
    width = LANES if const else 1
    for g0 in range(0, B, width):
        runs = [_inputs(np.random.default_rng(seed), S, plan) for seed in seeds[g0:g0 + width]]
        fix, ranges = _ranges_pair(runs, S, model, held)
        for b, (f, r) in enumerate(zip(fix, ranges), g0):
            nav[0, b], nav[1, b] = f.nav, r.nav
            sigma[0, b], sigma[1, b] = f.sigma[:, 5:7], r.sigma[:, 5:7]
            nreq[b] = len(r.applied)
    _, _, dp = ds.horizontal_errors(nav, truth.at(S["ep"]))
    return {"dp_fix": dp[0], "dp_ranges": dp[1], "sdp_fix": sigma[0], "sdp_ranges": sigma[1], "nreq": nreq}


def _squares_ranges(out, scale, ends):
    """What the path campaign's statistics need of each run of :func:`_batch_ranges` (summed
    over the runs where they are computed): squared horizontal position errors of both
    filters, the squared normalised errors of the path filter at the window ends ``ends``
    (against its own σ, per axis north/east, ``scale`` (M, 2) turning (δL, δλ) into metres),
    and the requests."""
    z2 = (out["dp_ranges"][:, ends] / (out["sdp_ranges"][:, ends] * scale[ends])) ** 2
    return {"pos_h_fix": (out["dp_fix"] ** 2).sum(-1), "pos_h_ranges": (out["dp_ranges"] ** 2).sum(-1),
            "z2_ends": z2, "nreq": out["nreq"]}


def _run_ranges(cfg, ctx, S):
    """``filter.measurement = "ranges"``: the path filter against the paper's fix filter."""
    import functools

    from sinslab.app import plotting as P
    from sinslab.core.earth import radii
    from sinslab.estimation import montecarlo as mc
    from sinslab.methods import doublestar as ds
    from sinslab.methods import doublestar_ranges as dr

    truth, windows = S["truth"], S["windows"]
    tt = truth.at(S["ep"])
    t = tt.t
    rm, rn = radii(tt.lat, tt.h)
    scale = np.stack([rm, rn * np.cos(tt.lat)], -1)            # (δL, δλ) -> (north, east) [m]

    ctx.log(f"{NAME}: covariance analysis (fix and path filters)")
    model = ds.horizontal_model(**S["model_args"])
    meas, init, fixes = _inputs(None, S, zero_errors=True)
    clean = dr.plan_paths(truth, windows, rng=np.random.default_rng(0), **_path_args(S)).clean
    cf, cr = _ranges_pair([(meas, init, (clean, fixes))], S, model, truth.h)
    s_pos = {"fix": cf[0].sigma[:, 5:7] * scale, "ranges": cr[0].sigma[:, 5:7] * scale}
    s_h = {k: np.hypot(*v.T) for k, v in s_pos.items()}

    n = int(cfg.runs)
    ctx.log(f"{NAME}: Monte Carlo, {n} runs, fix and path filters on the same draws")
    ends = [int(np.argmin(np.abs(t - b))) for _, b in windows]
    res = mc.run_campaign(_batch_ranges, n, cfg.seed, scheduler=ctx.scheduler, kwargs=dict(S=S),
                          reduce=functools.partial(_squares_ranges, scale=scale, ends=ends),
                          **ctx.campaign_store("mc-ranges"))
    rms = {}
    for k in ("fix", "ranges"):
        rms[k] = dict(pos_h=np.sqrt(res[f"pos_h_{k}"] / n), total=float(np.sqrt(np.sum(res[f"pos_h_{k}"]) / (n * t.size))))
    nees_n = [float(v) for v in res["z2_ends"][:, 0] / n]
    nees_e = [float(v) for v in res["z2_ends"][:, 1] / n]
    # 2 axes x W window ends: each checked at 1 % / (2 W), the family at 1 % (Bonferroni)
    lo, hi = (float(v) for v in mc.chi2_bounds(1, n, alpha=0.01 / max(1, 2 * len(ends))))
    ratio = {k: float(np.mean(rms[k]["pos_h"][1:] / s_h[k][1:])) for k in rms}
    win_end = {k: [float(rms[k]["pos_h"][j]) for j in ends] for k in rms}
    metrics = {
        "rms_pos_err_fix_m": rms["fix"]["total"], "rms_pos_err_ranges_m": rms["ranges"]["total"],
        "window_end_pos_rms_fix_m": win_end["fix"], "window_end_pos_rms_ranges_m": win_end["ranges"],
        "pos_sigma_at_end_fix_m": float(s_h["fix"][-1]), "pos_sigma_at_end_ranges_m": float(s_h["ranges"][-1]),
        "mc_rms_over_sigma_pos_fix": ratio["fix"], "mc_rms_over_sigma_pos_ranges": ratio["ranges"],
        "nees_window_end_north_ranges": nees_n, "nees_window_end_east_ranges": nees_e,
        "requests_per_run": float(res["nreq"] / n), "runs": n,
    }
    win_names = [f"{a:g}–{b:g} s" for a, b in windows]
    band = (f"inside the two-sided chi-square band of the mean over {n} runs at every window end "
            f"({lo:.3g}..{hi:.3g}; the {2 * len(ends)} checks at 99 % together)")
    claims = [
        Claim.at_most("ranges_beat_fix", "RMS horizontal position error (runs x time) of the lag-aware "
                      "filter on the two paths and the height source / that of the paper's lag-aware "
                      "filter on the fixes solved from the same paths (same draws)",
                      rms["ranges"]["total"] / rms["fix"]["total"], 1.0, origin="check"),
        Claim("ranges_nees_north", "path filter: mean over runs of (north error / filter σ)² " + band,
              nees_n, [lo, hi], all(lo <= v <= hi for v in nees_n), names=win_names, relation="between",
              origin="check"),
        Claim("ranges_nees_east", "path filter: mean over runs of (east error / filter σ)² " + band,
              nees_e, [lo, hi], all(lo <= v <= hi for v in nees_e), names=win_names, relation="between",
              origin="check"),
        Claim.within("ranges_mc_consistent_pos", "Monte Carlo RMS / covariance-analysis σ, horizontal "
                     "position, path filter (mean over time)", ratio["ranges"], 1.0, abs=0.2, origin="check"),
    ]
    claims[0].assume("bar", "≤ 1: better at all").with_limits("bar", {"≤ 0.95: 5 % better": 0.95})
    lo95, hi95 = (float(v) for v in mc.chi2_bounds(1, n, alpha=0.05))
    for c, vals in ((claims[1], nees_n), (claims[2], nees_e)):
        c.assume("band", "99 % for the 8 checks together (the project's)")
        c.vary("band", f"95 % for each check alone ({lo95:.3g}..{hi95:.3g})", vals,
               all(lo95 <= v <= hi95 for v in vals), how="threshold")
    claims[3].assume("band", "1 ± 0.2 (the project's)").vary(
        "band", "1 ± 0.1", ratio["ranges"], abs(ratio["ranges"] - 1) <= 0.1, how="threshold")

    ser = {"t_s": t}
    for k in ("fix", "ranges"):
        ser[f"sigma_pos_h_{k}_m"] = s_h[k]
        ser[f"rms_pos_h_{k}_m"] = rms[k]["pos_h"]
    fig, ax = P.figure(1, row_height=3.6)
    _shade(ax[0], windows)
    for i, (k, lab) in enumerate((("fix", "paper: two-GEO fixes"), ("ranges", "two paths + height source"))):
        ax[0].plot(t, rms[k]["pos_h"], color=P.COLORS[i], lw=1.2, label=f"{lab}: RMS {rms[k]['total']:.1f} m")
        ax[0].plot(t, s_h[k], color=P.COLORS[i], lw=0.8, ls="--", label=f"{lab}: σ (covariance analysis)")
    ax[0].set_yscale("log")
    ax[0].set_ylabel("horizontal position error [m]")
    ax[0].set_xlabel("time [s]")
    ax[0].legend(fontsize="small", loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2)
    fig.suptitle("Fix filter and path filter on the same draws (lag-aware)")
    figs = [Figure("fix_vs_ranges", fig, f"Monte Carlo RMS horizontal position error ({n} runs) and filter σ "
                                         f"of the paper's fix filter and of the filter on the two measured "
                                         f"paths; orange: fix windows")]
    table = Table("fix_vs_ranges", {
        "filter": ["fix (paper)", "paths + height"],
        "rms_pos_h_m": [rms["fix"]["total"], rms["ranges"]["total"]],
        "mc_rms_over_sigma_pos": [ratio["fix"], ratio["ranges"]],
        "pos_sigma_at_end_m": [float(s_h["fix"][-1]), float(s_h["ranges"][-1])],
        **{f"rms_pos_h_end_{a:g}_{b:g}_m": [win_end["fix"][i], win_end["ranges"][i]]
           for i, (a, b) in enumerate(windows)},
    }, "Monte Carlo RMS horizontal position error of the fix and path filters on the same draws")
    notes = [
        "filter.measurement = ranges: each run draws the two path errors (σ = sqrt(m0² + m1²) each) and "
        "the height source error ΔH per request; the path filter takes the paths with ΔH as noise "
        "correlated between them, the paper's filter the fix solved from the same paths at the "
        "erroneous height with the diagonal R of eqs 11-15 (configured height factor). Both lag-aware, "
        "same schedule, IMU and initial errors.",
    ]
    return Result(metrics=metrics, claims=claims, series={"fix_vs_ranges": ser}, figures=figs,
                  tables=[table], notes=notes)


# ---------------------------------------------------------------- helpers -----------------
def _sigmas(sigma, truth):
    """Filter σ (M, 16) -> attitude (M, 3) rad, velocity (M, 2) m/s, position N/E (M, 2) m."""
    from sinslab.core.earth import radii

    rm, rn = radii(truth.lat, truth.h)
    return sigma[:, 0:3], sigma[:, 3:5], np.stack([sigma[:, 5] * rm, sigma[:, 6] * rn * np.cos(truth.lat)], -1)


def _in_windows(t, windows):
    m = np.zeros(t.shape, dtype=bool)
    for a, b in windows:
        m |= (t >= a - 1e-9) & (t <= b + 1e-9)
    return m


def fix_map(lat_deg, lon_deg, fa, h=0.0):
    """σ N/S and E/W [m] over a latitude/longitude grid (degrees) for the fix settings ``fa``."""
    from sinslab.methods import doublestar as ds

    L, Lo = np.meshgrid(np.asarray(lat_deg) * units.deg, np.asarray(lon_deg) * units.deg, indexing="ij")
    fe = ds.fix_error(L, Lo, fa["sat_lon1"], fa["sat_lon2"], fa["m0"], fa["m1"], fa["dH"], h,
                      height_factor=fa["height_factor"])
    return fe.ns, fe.ew


def _map_figure(fa, start_lat, start_lon, h, name="fix_sigma_map"):
    from sinslab.app import plotting as P

    lat = np.arange(15.0, 55.0 + 1e-9, 0.5)
    lon = np.arange(70.0, 140.0 + 1e-9, 0.5)
    ns, ew = fix_map(lat, lon, fa, h)
    fig, ax = P.figure(1, 2, sharex=False, width=11.0, row_height=4.2)
    for a, z, title in ((ax[0], ns, "north-south σ [m]"), (ax[1], ew, "east-west σ [m]")):
        from matplotlib.ticker import MaxNLocator

        lev = MaxNLocator(14).tick_values(float(z.min()), float(z.max()))
        cs = a.contourf(lon, lat, z, levels=lev, cmap="viridis", extend="max")
        a.contour(lon, lat, z, levels=lev, colors="k", linewidths=0.4)
        fig.colorbar(cs, ax=a, shrink=0.9)
        for sl in (fa["sat_lon1"], fa["sat_lon2"]):
            if 70 <= sl / units.deg <= 140:
                a.axvline(sl / units.deg, color="w", ls="--", lw=1.0)
        a.plot(start_lon / units.deg, start_lat / units.deg, "r*", ms=10, label="start")
        a.set_xlabel("longitude [deg E]")
        a.set_ylabel("latitude [deg N]")
        a.set_title(title)
    ax[0].legend(loc="lower left", fontsize="small")
    return Figure(name, fig,
                  f"Two-GEO fix σ (paper eqs 11-15, height factor '{fa['height_factor']}') over "
                  f"15-55° N, 70-140° E for satellites at {fa['sat_lon1'] / units.deg:g}° E and "
                  f"{fa['sat_lon2'] / units.deg:g}° E (dashed), m0 = {fa['m0']:g} m, m1 = {fa['m1']:g} m, "
                  f"ΔH = {fa['dH']:g} m, height {h:g} m"), lat, lon, ns, ew


def _shade(ax, windows):
    for a, b in windows:
        ax.axvspan(a, b, color="orange", alpha=0.25, lw=0)


# ---------------------------------------------------------------- robustness -------------
#: Assumptions of the verdicts (names shared by the claims and the sweep's axes)
HEIGHT, GYRO_NOISE, MARKOV, CORRELATED, JITTER = (
    "height factor of eqs 13-14", "reading of 'gyro white noise 0.1°/h'", "Markov correlation times",
    "fix error correlation", "latency jitter")


def ROBUSTNESS(cfg):
    """The physics alternatives of the fix filter's claims: re-runs of 50 runs at 20 Hz (the
    demo's: 30 runs, the height factor and the fix correlation only) — the claims are ratios
    of Monte Carlo RMS and σ, which that decides."""
    if cfg.filter.measurement == "ranges":
        return []
    red = ("runs=50", "scenario.sample_interval=0.05 s")
    demo = ("runs=30", "scenario.sample_interval=0.05 s")
    f, im = cfg.fix, cfg.imu
    return [
        Axis(HEIGHT, _default(cfg, HEIGHT), {"derived: (R_N + h)/r_GEO": ["fix.height_factor=geometric"]}
             if f.height_factor == "paper" else {"as printed": ["fix.height_factor=paper"]},
             reduced=red, demo=demo, source="paper"),
        Axis(GYRO_NOISE, _default(cfg, GYRO_NOISE), {"ten times it": [
            f"imu.gyro_arw={10 * float(im.gyro_arw) / units.unit_scale('deg/h*sqrt(s)'):g} deg/h*sqrt(s)"]},
             reduced=red, in_demo=False),
        Axis(MARKOV, _default(cfg, MARKOV), {"300 s each": ["imu.gyro_corr_time=300 s", "imu.accel_corr_time=300 s"]},
             reduced=red, in_demo=False),
        Axis(CORRELATED, _default(cfg, CORRELATED), {"correlated as eqs 11-15 give them": ["fix.correlated=true"]}
             if not f.correlated else {"uncorrelated": ["fix.correlated=false"]}, reduced=red, demo=demo),
        Axis(JITTER, _default(cfg, JITTER), {"± 0.5 s": ["fix.latency_jitter=0.5 s"]}, reduced=red, in_demo=False),
    ]


def _default(cfg, what):
    """The run's default of an assumption, as text."""
    f, im = cfg.fix, cfg.imu
    if what == HEIGHT:
        return "as printed, R_N/(R_N + h)" if f.height_factor == "paper" else "derived, (R_N + h)/r_GEO"
    if what == GYRO_NOISE:
        return (f"rate white noise {float(im.gyro_arw) / units.unit_scale('deg/h*sqrt(s)'):g} °/h per 1 s step "
                "(the project's reading)")
    if what == MARKOV:
        return (f"gyro {float(im.gyro_corr_time):g} s, accelerometer {float(im.accel_corr_time):g} s "
                "(not in the paper)")
    if what == CORRELATED:
        return "north and east drawn independently" if not f.correlated else "drawn with their correlation"
    return f"none: every fix {float(f.latency):g} s late (the paper)"


def _claims(cfg, la_t, li_t, zl_t, r_pos, r_att, win_ratio, win_sigma_ratio, win_names):
    """The paper's statement and the project's checks, with their assumptions and bars."""
    every = (HEIGHT, GYRO_NOISE, MARKOV, CORRELATED, JITTER)

    def assume(c, *extra):
        for a in every + extra:
            c.assume(a, _default(cfg, a), "paper" if a in (HEIGHT, JITTER) else "project")
        return c

    c1 = assume(Claim.at_most("lagaware_beats_lagignore",
                              "RMS horizontal position error (runs x time) of the lag-aware filter / that of "
                              "the filter applying each fix as if current", la_t / li_t, 1.0, origin="check"))
    c1.assume("bar", "≤ 1: better at all").with_limits("bar", {"≤ 0.5: at least twice as good": 0.5})
    c2 = assume(Claim.within("lagaware_near_zerolag",
                             "RMS horizontal position error of the lag-aware filter / that of an ideal "
                             "zero-lag filter with the same fixes (within 10 %: the project's margin)",
                             la_t / zl_t, 1.0, abs=0.10, origin="check"))
    c2.assume("margin", "10 % (the project's)").vary("margin", "5 %", la_t / zl_t, abs(la_t / zl_t - 1) <= 0.05,
                                                     how="threshold")
    out = [c1, c2]
    for cid, what, r in (("mc_consistent_pos", "horizontal position", r_pos), ("mc_consistent_att", "attitude (3 axes)", r_att)):
        c = assume(Claim.within(cid, f"Monte Carlo RMS / covariance-analysis σ, {what}, lag-aware filter (mean "
                                "over time; ± 0.2: the project's band)", r, 1.0, abs=0.2, origin="check"))
        c.assume("band", "1 ± 0.2 (the project's)").vary("band", "1 ± 0.1 (2σ of 200 runs' RMS/σ)", r,
                                                         abs(r - 1) <= 0.1, how="threshold")
        out.append(c)
    c = assume(Claim.at_most("fixes_reduce_error", "in every window the Monte Carlo RMS horizontal position error at "
                             "the window end / at its start (per window)", win_ratio, 1.0, names=win_names,
                             origin="paper"))
    c.assume("bar", "≤ 1: reduced at all").with_limits("bar", {"≤ 0.5: at least halved": 0.5})
    out.append(c)
    c = assume(Claim.at_most("fixes_reduce_sigma", "in every window the covariance-analysis horizontal position σ at "
                             "the window end / at its start (per window)", win_sigma_ratio, 1.0, names=win_names,
                             origin="check"))
    c.assume("bar", "≤ 1: reduced at all").with_limits("bar", {"≤ 0.5: at least halved": 0.5})
    out.append(c)
    return out


# ---------------------------------------------------------------- the experiment ---------
def run(cfg: Config, ctx) -> Result:
    from sinslab.methods import doublestar as ds
    from sinslab.estimation import montecarlo as mc
    from sinslab.app import plotting as P

    S = _setup(cfg, ctx.quick)
    if cfg.filter.measurement == "ranges":
        return _run_ranges(cfg, ctx, S)
    truth, windows, fa = S["truth"], S["windows"], S["fix_args"]
    tt = truth.at(S["ep"])
    t = tt.t
    lat0, lon0, h0 = float(truth.lat[0]), float(truth.lon[0]), float(truth.h[0])

    # ---- fix error model at the start
    fe = ds.fix_error(lat0, lon0, fa["sat_lon1"], fa["sat_lon2"], fa["m0"], fa["m1"], fa["dH"], h0,
                      height_factor=fa["height_factor"])
    fg = ds.fix_error(lat0, lon0, fa["sat_lon1"], fa["sat_lon2"], fa["m0"], fa["m1"], fa["dH"], h0,
                      height_factor="geometric")
    fl = ds.fix_error_linearised(lat0, lon0, fa["sat_lon1"], fa["sat_lon2"], fa["m0"], fa["m1"], fa["dH"], h0)

    # ---- covariance analysis: the filters' own covariance along the error-free trajectory
    ctx.log(f"{NAME}: covariance analysis")
    cov = _one(None, S, zero_errors=True)
    s_att, s_vel, s_pos = _sigmas(cov["sigma"], tt)
    s_pos_h = np.hypot(*s_pos.T)

    # ---- Monte Carlo
    n = int(cfg.runs)
    ctx.log(f"{NAME}: Monte Carlo, {n} runs")
    res = mc.run_campaign(_batch, n, cfg.seed, scheduler=ctx.scheduler, kwargs=dict(S=S), reduce=_squares,
                          **ctx.campaign_store("mc"))
    rms = {}
    for mode in _MODES:
        k = _KEY[mode]
        rms[k] = dict(pos_h=np.sqrt(res[f"pos_h_{k}"] / n), pos=np.sqrt(res[f"dp_{k}"] / n),
                      vel=np.sqrt(res[f"dv_{k}"] / n), att=np.sqrt(res[f"phi_{k}"] / n),
                      total=float(np.sqrt(np.sum(res[f"pos_h_{k}"]) / (n * t.size))))
    la = rms["lagaware"]
    ratio_pos_t = la["pos_h"] / s_pos_h
    ratio_att_t = np.sqrt((la["att"] ** 2).sum(-1) / (s_att ** 2).sum(-1))
    ratio_vel_t = np.sqrt((la["vel"] ** 2).sum(-1) / (s_vel ** 2).sum(-1))
    r_pos, r_att, r_vel = float(np.mean(ratio_pos_t[1:])), float(np.mean(ratio_att_t[1:])), float(np.mean(ratio_vel_t[1:]))
    outside = ~_in_windows(t, windows)
    max_out = float(np.max(la["pos_h"][outside]))
    in_win = {k: float(np.sqrt(np.mean(rms[k]["pos_h"][~outside] ** 2))) for k in rms}
    win_ratio, win_sigma_ratio = [], []
    for a, b in windows:
        ia = int(np.argmin(np.abs(t - a)))
        ib = int(np.argmin(np.abs(t - b)))
        win_ratio.append(float(la["pos_h"][ib] / la["pos_h"][ia]))
        win_sigma_ratio.append(float(s_pos_h[ib] / s_pos_h[ia]))
    first = int(np.argmin(np.abs(t - windows[0][0]))) if windows else 0

    metrics = {
        "fix_sigma_ns_m": float(fe.ns), "fix_sigma_ew_m": float(fe.ew),
        "fix_sigma_ns_geometric_m": float(fg.ns), "fix_sigma_ew_geometric_m": float(fg.ew),
        "fix_sigma_ns_linearised_m": float(fl.ns), "fix_sigma_ew_linearised_m": float(fl.ew),
        "pos_sigma_at_end_m": float(s_pos_h[-1]),
        "pos_sigma_before_first_window_m": float(s_pos_h[first]),
        "rms_pos_err_lagaware_m": rms["lagaware"]["total"],
        "rms_pos_err_lagignore_m": rms["lagignore"]["total"],
        "rms_pos_err_zerolag_m": rms["zerolag"]["total"],
        "rms_pos_err_in_windows_lagaware_m": in_win["lagaware"],
        "rms_pos_err_in_windows_zerolag_m": in_win["zerolag"],
        "max_pos_err_outside_windows_m": max_out,
        "mc_rms_over_sigma_pos": r_pos, "mc_rms_over_sigma_att": r_att, "mc_rms_over_sigma_vel": r_vel,
        "window_pos_rms_ratio": win_ratio,
        "fixes_per_run": float(res["nfix"] / n),
        "runs": n,
    }
    win_names = [f"{a:g}–{b:g} s" for a, b in windows]
    la_t, li_t, zl_t = rms["lagaware"]["total"], rms["lagignore"]["total"], rms["zerolag"]["total"]
    claims = _claims(cfg, la_t, li_t, zl_t, r_pos, r_att, win_ratio, win_sigma_ratio, win_names)
    if ctx.claims_only:
        return Result(metrics=metrics, claims=claims)

    # ---- series
    ser = {"t_s": t}
    for i, c in enumerate("ENU"):
        ser[f"sigma_phi{c}_arcsec"] = s_att[:, i] / units.arcsec
        ser[f"rms_phi{c}_arcsec"] = la["att"][:, i] / units.arcsec
    for i, c in enumerate("EN"):
        ser[f"sigma_v{c}_mps"] = s_vel[:, i]
        ser[f"rms_v{c}_mps"] = la["vel"][:, i]
    for i, c in enumerate("NE"):
        ser[f"sigma_p{c}_m"] = s_pos[:, i]
        ser[f"rms_p{c}_m"] = la["pos"][:, i]
    ser["sigma_pos_h_m"] = s_pos_h
    for k in ("lagaware", "lagignore", "zerolag"):
        ser[f"rms_pos_h_{k}_m"] = rms[k]["pos_h"]
    mfig, mlat, mlon, mns, mew = _map_figure(fa, lat0, lon0, h0)
    LA, LO = np.meshgrid(mlat, mlon, indexing="ij")
    series = {"covariance_vs_mc": ser,
              "fix_sigma_map": {"lat_deg": LA.ravel(), "lon_deg": LO.ravel(), "sigma_ns_m": mns.ravel(),
                                "sigma_ew_m": mew.ravel()}}

    # ---- figures (paper Figs 2-4 + comparison + map)
    figs = []
    specs = [("att", "Attitude error", 2, s_att / units.arcsec, la["att"] / units.arcsec,
              ["φE", "φN", "φU"], "arcsec"),
             ("vel", "Horizontal velocity error", 3, s_vel, la["vel"], ["δvE", "δvN"], "m/s"),
             ("pos", "Horizontal position error", 4, s_pos, la["pos"], ["north", "east"], "m")]
    for name, title, paper_fig, sg, rm_, labels, unit in specs:
        fig, ax = P.figure(len(labels), row_height=2.1, title=f"{title} (the paper's Fig. {paper_fig})")
        for i, a in enumerate(ax):
            _shade(a, windows)
            a.plot(t, sg[:, i], color=P.COLORS[i], lw=1.3, label=f"{labels[i]} σ (covariance analysis)")
            a.plot(t, rm_[:, i], color="k", lw=0.8, ls="--", label=f"Monte Carlo RMS ({n} runs)")
            a.set_ylabel(f"{labels[i]} [{unit}]")
            a.legend(fontsize="x-small", loc="best", framealpha=0.6)
        ax[-1].set_xlabel("time [s]")
        figs.append(Figure(f"{name}_sigma", fig, f"{title} σ of the lag-aware filter (covariance analysis) "
                                                 f"and Monte Carlo RMS; orange: fix windows (the paper's "
                                                 f"Fig. {paper_fig})"))
    fig, ax = P.figure(1, row_height=3.6)
    _shade(ax[0], windows)
    for i, (k, lab) in enumerate((("lagaware", "lag-aware (paper eqs 4-10)"), ("lagignore", "lag ignored"),
                                  ("zerolag", "ideal zero lag"))):
        ax[0].plot(t, rms[k]["pos_h"], color=P.COLORS[i], lw=1.2 if i != 2 else 0.9,
                   ls="-" if i != 2 else ":", label=f"{lab}: RMS {rms[k]['total']:.1f} m")
    ax[0].plot(t, s_pos_h, color="0.4", lw=0.8, ls="--", label="σ (covariance analysis, lag-aware)")
    ax[0].set_yscale("log")
    ax[0].set_ylabel("horizontal position error [m]")
    ax[0].set_xlabel("time [s]")
    # below the axes: inside, every corner holds a curve
    ax[0].legend(fontsize="small", loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2)
    fig.suptitle("Horizontal position error of the three filters")
    figs.append(Figure("filters_compared", fig, f"Monte Carlo RMS horizontal position error of the three "
                                                f"filters ({n} runs); orange: fix windows"))
    figs.append(mfig)
    other = "geometric" if fa["height_factor"] == "paper" else "paper"
    figs.append(_map_figure(dict(fa, height_factor=other), lat0, lon0, h0, f"fix_sigma_map_{other}")[0])

    table = Table("filters", {
        "filter": ["lag-aware", "lag-ignore", "zero-lag"],
        "rms_pos_h_m": [la_t, li_t, zl_t],
        "rms_pos_h_outside_windows_m": [float(np.sqrt(np.mean(rms[k]["pos_h"][outside] ** 2)))
                                        for k in ("lagaware", "lagignore", "zerolag")],
        "rms_pos_h_in_windows_m": [in_win[k] for k in ("lagaware", "lagignore", "zerolag")],
        "rms_pos_h_at_end_m": [float(rms[k]["pos_h"][-1]) for k in ("lagaware", "lagignore", "zerolag")],
    }, "Monte Carlo RMS horizontal position error of the three filters")
    fix_table = Table("fix_error_start", {
        "model": ["eqs 11-15 (configured)", "eqs 11-15, height factor (R_N+h)/r_GEO", "exact first order (WGS-84)"],
        "ns_m": [float(fe.ns), float(fg.ns), float(fl.ns)], "ew_m": [float(fe.ew), float(fg.ew), float(fl.ew)],
        "ns_range_m": [float(fe.ns_range), float(fg.ns_range), float(fl.ns_range)],
        "ew_range_m": [float(fe.ew_range), float(fg.ew_range), float(fl.ew_range)],
        "ns_ephem_m": [float(fe.ns_ephem), float(fg.ns_ephem), float(fl.ns_ephem)],
        "ew_ephem_m": [float(fe.ew_ephem), float(fg.ew_ephem), float(fl.ew_ephem)],
        "ns_height_m": [float(fe.ns_height), float(fg.ns_height), float(fl.ns_height)],
        "ew_height_m": [float(fe.ew_height), float(fg.ew_height), float(fl.ew_height)],
    }, "Fix σ and its contributions at the start position")
    return Result(metrics=metrics, claims=claims, series=series, figures=figs, tables=[table, fix_table])
