"""free-inertial: pure inertial navigation of a simulated trajectory, compared with truth.

The trajectory generator (:mod:`sinslab.sim.trajectory`) produces the true motion and exact
IMU increments; the IMU error model (:mod:`sinslab.sim.imu`) corrupts them; the strapdown
mechanization (:mod:`sinslab.nav.strapdown`) navigates from the (optionally perturbed) true
initial state without any aiding (the vertical channel is held to the true height by
default, like a perfect barometer, because a free vertical channel diverges in minutes).

Claims (each computed, each able to fail):

- ``schuler_period``: the period fitted to the horizontal velocity error is within 1 % of
  the Schuler period ``2π sqrt(R/g)`` (:func:`sinslab.core.earth.schuler_period`) at the start
  latitude and the mean height. Only when the run lasts at least one Schuler period.
- ``pos_envelope``, ``vel_envelope``, ``tilt_envelope``, ``heading_envelope``: the errors
  stay inside a closed-form envelope built from the static single-channel Schuler-loop
  error model — for each error source the magnitude bound of its closed-form response,
  summed — plus the heading-error × manoeuvre terms a moving vehicle adds, random terms
  at 4σ (see :func:`envelopes`). The envelope is an upper bound, not a prediction: a
  correct mechanization stays inside it; a wrong Earth rate, Coriolis term, gravity or
  sign does not.

Monte Carlo (``--runs N``, N > 1; ``--scheduler ADDRESS`` honoured): besides the single
run above, N runs through :func:`sinslab.estimation.montecarlo.run_campaign` (Dask; a local cluster by
default). Each run draws its constant biases and scale factors from the ``imu.*_sigma`` terms
(``imu.gyro_bias_sigma``, ...; the single run uses ``imu.gyro_bias``, ...) and its initial
errors from the configured ``init`` errors read as **1σ values**, every axis N(0, σ²)
independently (:func:`mc_batch`), plus its own white noise, navigates the same true
trajectory (regenerated deterministically once per worker, not shipped) and returns its errors every ``montecarlo.output_interval``. A
covariance analysis of the matching φ-angle model (:func:`covariance_analysis`: horizontal
core when the height is held, full core when free; none for the damped channel) gives σ
at the same epochs. Claims ``mc_rms_over_sigma_<error>`` (position E/N, velocity E/N, φ
E/N/U): MC RMS / σ at every epoch after ``montecarlo.transient`` within
:func:`mc_ratio_bounds` — 0.8–1.2, widened to the chi-square sampling interval for small N.
"""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import field_validator, model_validator

from sinslab.core import units
from sinslab.experiments.base import (Claim, ExperimentConfig, Field, Figure, Metric, Q, QV, Result, Section,
                                      imu_section)

NAME = "free-inertial"
#: The Monte Carlo campaign (and so --scheduler) needs runs >= 2; one run is the single run.
CAMPAIGN_MIN_RUNS = 2
PURPOSE = "pure inertial navigation of a simulated trajectory with IMU errors, compared with truth"
NOTES = [
    "Attitude errors are Euler-angle differences (navigation − truth): pitch, roll and "
    "heading (heading clockwise from north, so heading error = −yaw error).",
    "Position errors are in metres east/north/up of the true position.",
]


# ---------------------------------------------------------------- configuration -------

class Scenario(Section):
    motion: Literal["aircraft_mixed", "static", "ship_manoeuvring"] = Field(
        "aircraft_mixed", description="ready-made motion of sinslab.sim.trajectory")
    motion_file: str = Field("", description="motion TOML file (sinslab.sim.trajectory.load_motion); "
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
            from sinslab.sim import trajectory

            try:
                trajectory.load_motion(v)
            except FileNotFoundError:
                raise ValueError(f"{v}: file not found") from None
            except (OSError, ValueError) as e:
                raise ValueError(str(e)) from None
        return v


Imu = imu_section("Imu", {
    "gyro_bias": ("0.01 deg/h", "x, y, z or one for all"),
    "gyro_arw": "0.001 deg/sqrt(h)",
    "gyro_scale_factor": "0 ppm",
    "accel_bias": "50 ug",
    "accel_vrw": "5 ug/sqrt(Hz)",
    "accel_scale_factor": "0 ppm",
    "gyro_bias_sigma": ("0.01 deg/h", "Monte Carlo (--runs N > 1)"),
    "gyro_scale_factor_sigma": ("0 ppm", "Monte Carlo"),
    "accel_bias_sigma": ("50 ug", "Monte Carlo"),
    "accel_scale_factor_sigma": ("0 ppm", "Monte Carlo"),
})


class Init(Section):
    att_err: QV("angle") = Field("[0, 0, 0] arcsec", description="initial attitude error [pitch, roll, heading]")
    vel_err: QV("velocity") = Field("[0, 0, 0] m/s", description="initial velocity error [east, north, up]")
    pos_err: QV("length") = Field("[0, 0, 0] m", description="initial position error [east, north, up]")


class Nav(Section):
    nsub: int = Field(2, ge=1, le=5, description="samples per update (coning/sculling order)")
    vertical: Literal["hold", "damped", "free"] = Field(
        "hold", description="vertical channel: held to the true height, damped towards it, or free")
    output_interval: Q("time", gt="0 s") = Field("1 s", description="interval of the error series")


class MonteCarlo(Section):
    output_interval: Q("time", gt="0 s") = Field(
        "10 s", description="interval of the Monte Carlo error histories and of the RMS/σ comparison")
    cov_step: Q("time", gt="0 s") = Field(
        "1 s", description="step of the covariance analysis (F frozen at the truth in mid-step)")
    transient: Q("time", ge="0 s") = Field(
        "1 min", description="start of the RMS/σ comparison (epochs before it are shown, not judged)")


class Config(ExperimentConfig):
    runs: int = Field(1, ge=1, le=100000, description="Monte Carlo runs: 1 = the single simulation; "
                      "N > 1 adds an N-run Monte Carlo campaign (Dask) and a covariance analysis")
    scenario: Scenario = Scenario()
    imu: Imu = Imu()
    init: Init = Init()
    nav: Nav = Nav()
    montecarlo: MonteCarlo = MonteCarlo()

    @model_validator(mode="after")
    def _long_enough(self):
        upd = self.nav.nsub * float(self.scenario.sample_interval)
        step = max(1, round(float(self.nav.output_interval) / upd)) * upd
        if float(self.scenario.duration) < 2 * step:
            raise ValueError(f"scenario.duration {self.scenario.duration.text!r} is shorter than two "
                             f"output intervals ({2 * step:g} s)")
        if self.runs > 1:
            m = self.montecarlo
            cov_every, mc_every = _mc_strides(self)
            if float(self.scenario.duration) < 2 * mc_every * upd:
                raise ValueError(f"scenario.duration {self.scenario.duration.text!r} is shorter than two "
                                 f"Monte Carlo output intervals ({2 * mc_every * upd:g} s)")
            if float(m.transient) >= float(self.scenario.duration):
                raise ValueError(f"montecarlo.transient {m.transient.text!r} is not shorter than "
                                 f"scenario.duration {self.scenario.duration.text!r}")
        return self


def _mc_strides(cfg) -> tuple[int, int]:
    """Covariance step and Monte Carlo output interval in navigation updates (the latter a
    whole multiple of the former)."""
    upd = cfg.nav.nsub * float(cfg.scenario.sample_interval)
    cov_every = max(1, int(round(float(cfg.montecarlo.cov_step) / upd)))
    k = max(1, int(round(float(cfg.montecarlo.output_interval) / (cov_every * upd))))
    return cov_every, k * cov_every


#: Lower end of error / envelope: the envelope is a loose upper bound (0.06-0.4 of it is
#: reached on the default flight), but the same configured sensor errors drive the error,
#: so it cannot stay three orders of magnitude below the envelope unless the run does not
#: have those errors or they left the linear regime (a tumbling attitude caps the position
#: error at the size of the Earth: 2.5e-8 of the envelope with a 1e9 deg/h gyro bias).
ENVELOPE_MIN_RATIO = 1e-3
#: Tolerances of the linear-model claims: linearisation, the 1-step discretisation of F and
#: the mid-step specific force leave residuals of about a percent of the error itself.
LIN_REL, LIN_ABS_POS, LIN_ABS_VEL, LIN_ABS_ATT = 0.01, 0.5, 0.001, 0.2

QUICK = {"scenario": {"duration": "10 min", "sample_interval": "0.02 s"}}

#: Further scenarios for ``sinslab demo``: Monte Carlo RMS next to covariance-analysis σ.
DEMO_VARIANTS = {"mc200": ["runs=200"]}

#: CPU seconds of each ``sinslab demo`` run at full scale, robustness re-runs included
#: (quiet machine): the demo starts the longest first.
DEMO_COST_S = {"": 3.4, "mc200": 15}

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
    # Monte Carlo (--runs N > 1)
    "mc_runs": Metric("-", "Monte Carlo runs"),
    "mc_campaign_s": Metric("s", "wall time of the Monte Carlo campaign (Dask, incl. cluster start)"),
    "mc_covariance_s": Metric("s", "wall time of the covariance analysis"),
    "mc_ratio_bounds": Metric("-", "accepted interval of MC RMS / σ: chi-square sampling interval "
                                   "(two-sided 0.999) for the number of runs, at least [0.8, 1.2]"),
    "mc_transient_s": Metric("s", "epochs before this time are not judged"),
    "mc_final_rms_horiz_pos_m": Metric("m", "Monte Carlo RMS horizontal position error at the end"),
    "mc_final_sigma_horiz_pos_m": Metric("m", "covariance-analysis horizontal position σ at the end"),
    "mc_rms_over_sigma_min": Metric("-", "smallest MC RMS / σ over all compared errors and epochs"),
    "mc_rms_over_sigma_max": Metric("-", "largest MC RMS / σ over all compared errors and epochs"),
    **{f"mc_rms_over_sigma_{k}": Metric("-", f"[min, max] over time of MC RMS / covariance σ, {lab}")
       for k, lab in (("pos_e", "east position"), ("pos_n", "north position"),
                      ("vel_e", "east velocity"), ("vel_n", "north velocity"),
                      ("phi_e", "misalignment φE"), ("phi_n", "misalignment φN"),
                      ("phi_u", "misalignment φU"))},
}


# ---------------------------------------------------------------- Monte Carlo ------------
#: Errors compared between Monte Carlo and covariance analysis: (key, label, display unit).
MC_ERRORS = (("pos_e", "position east", "m"), ("pos_n", "position north", "m"),
             ("vel_e", "velocity east", "m/s"), ("vel_n", "velocity north", "m/s"),
             ("phi_e", "misalignment φE", "arcsec"), ("phi_n", "misalignment φN", "arcsec"),
             ("phi_u", "misalignment φU", "arcsec"))
#: Columns of a run's error history: position E, N, U [m], velocity E, N, U [m/s], φ E, N, U [rad].
MC_COLS = {"pos_e": 0, "pos_n": 1, "vel_e": 3, "vel_n": 4, "phi_e": 6, "phi_n": 7, "phi_u": 8}
#: The required bound on Monte Carlo RMS / covariance σ, and the two-sided probability of
#: the chi-square interval that widens it for small campaigns (see :func:`mc_ratio_bounds`).
MC_RATIO_BOUNDS, MC_ALPHA = (0.8, 1.2), 0.001

_MC_CACHE: dict = {}


def mc_ratio_bounds(n_runs: int, alpha: float = MC_ALPHA) -> tuple[float, float]:
    """Acceptance interval of the Monte Carlo RMS / covariance σ ratio for ``n_runs`` runs.

    Where the linear model holds, every error of a run is a zero-mean Gaussian with the
    covariance-analysis variance σ², so ``N·RMS²/σ² ~ χ²_N`` at each epoch. The interval is
    the two-sided ``1 − alpha`` chi-square interval of ``RMS/σ`` — ``sqrt(χ²_N(α/2)/N)``,
    ``sqrt(χ²_N(1−α/2)/N)`` — widened to at least 0.8–1.2. For N = 200 the
    chi-square interval (0.84–1.17) lies inside 0.8–1.2, so the bound is 0.8–1.2; for
    N = 20 it is 0.52–1.54.
    """
    from scipy import stats

    n = int(n_runs)
    lo, hi = np.sqrt(stats.chi2.ppf([alpha / 2, 1 - alpha / 2], n) / n)
    return float(min(MC_RATIO_BOUNDS[0], lo)), float(max(MC_RATIO_BOUNDS[1], hi))


def _mc_spec(cfg: Config, segments, start, mount) -> dict:
    """Everything a Monte Carlo task needs, small enough to send to every worker: the
    trajectory is regenerated (deterministically) on each worker, not shipped."""
    import hashlib
    import pickle

    s, n, i, ini = cfg.scenario, cfg.nav, cfg.imu, cfg.init
    errs = i.errors()
    cov_every, mc_every = _mc_strides(cfg)
    traj = (segments, start, mount, float(s.sample_interval), float(s.duration))
    return dict(
        traj=traj, key=hashlib.sha1(pickle.dumps((traj, n.vertical))).hexdigest(),
        nsub=n.nsub, vertical=n.vertical, out_every=mc_every,
        att_sigma=np.abs(np.asarray(ini.att_err, float)), vel_sigma=np.abs(np.asarray(ini.vel_err, float)),
        pos_sigma=np.abs(np.asarray(ini.pos_err, float)),
        gyro_bias_sigma=i.sigma("gyro_bias"), accel_bias_sigma=i.sigma("accel_bias"),
        gyro_sf_sigma=i.sigma("gyro_scale_factor"), accel_sf_sigma=i.sigma("accel_scale_factor"),
        gyro_arw=errs.gyro_arw.copy(), accel_vrw=errs.accel_vrw.copy())


def _mc_setup(spec, gen=None):
    """The worker's copy of the trajectory and of what every run shares (truth at the output
    epochs, the held vertical rate): made once per process and cached."""
    from sinslab.sim import trajectory
    from sinslab.core.records import NavState
    from sinslab.nav import strapdown

    hit = _MC_CACHE.get(spec["key"])
    if hit is not None:
        return hit
    segments, start, mount, dt, T = spec["traj"]
    if gen is None:
        gen = trajectory.generate(segments, start, dt, duration=T, mount=mount)
    truth = gen.truth
    per = spec["out_every"] * spec["nsub"]
    m_out = (len(gen.imu) // spec["nsub"]) // spec["out_every"]
    ep = np.arange(m_out + 1) * per
    tr = truth.at(ep)
    h_full = truth.h.copy()
    # every run holds to the same true height: its vertical rate is computed once here
    vup = strapdown.held_vup(h_full, gen.imu.dt) if spec["vertical"] == "hold" else None
    S = dict(ideal=gen.imu, mount=gen.mount, h_full=h_full, vup=vup, truth=tr,
             init=NavState.from_series(truth, 0))
    _MC_CACHE.clear()                                  # one trajectory per process at a time
    _MC_CACHE[spec["key"]] = S
    return S


def _mc_inputs(rng, spec, S):
    """One run's IMU record and initial state from its generator: 21 standard normals —
    initial errors (pitch, roll, heading; velocity E, N, U; position E, N, U), gyro and
    accelerometer constant biases and scale factors (body x, y, z), each times its 1σ —
    then the white noise of :func:`sinslab.sim.imu.apply`."""
    from sinslab.sim import imu as imu_mod
    from sinslab.core import earth
    from sinslab.core.records import NavState

    t0 = S["init"]
    rm0, rn0 = earth.radii(t0.lat, t0.h)
    z = rng.standard_normal(21)
    datt, dvel, dpos = (z[0:3] * spec["att_sigma"], z[3:6] * spec["vel_sigma"],
                        z[6:9] * spec["pos_sigma"])
    errs = imu_mod.ImuErrors(
        gyro_bias=z[9:12] * spec["gyro_bias_sigma"], accel_bias=z[12:15] * spec["accel_bias_sigma"],
        gyro_scale_factor=z[15:18] * spec["gyro_sf_sigma"],
        accel_scale_factor=z[18:21] * spec["accel_sf_sigma"],
        gyro_arw=spec["gyro_arw"], accel_vrw=spec["accel_vrw"])
    meas = imu_mod.apply(S["ideal"], errs, rng)
    init = NavState(lat=t0.lat + dpos[1] / rm0, lon=t0.lon + dpos[0] / (rn0 * math.cos(t0.lat)),
                    h=t0.h + dpos[2], vel=t0.vel + dvel,
                    att=t0.att + np.array([datt[0], datt[1], -datt[2]]), t=t0.t)
    return meas, init


def _mc_navigate(meas, init, spec, S, vup):
    from sinslab.nav import strapdown

    nav = strapdown.navigate(meas, init, nsub=spec["nsub"], vertical=spec["vertical"],
                             height=S["h_full"] if spec["vertical"] != "free" else None, vup=vup,
                             mount=S["mount"], out_every=spec["out_every"], progress=False)
    if nav.t.size != S["truth"].t.size:
        raise RuntimeError("Monte Carlo navigation and truth epochs disagree")
    return nav


def mc_run(seed, spec):
    """One Monte Carlo run on its own: the definition :func:`mc_batch` stacks.

    From ``default_rng(seed)`` the inputs of :func:`_mc_inputs`; the run navigates the
    common true trajectory with :func:`sinslab.nav.strapdown.navigate` (same vertical mode,
    nsub and mount as the single run) and returns its errors (navigation − truth) every
    ``spec["out_every"]`` updates, (T, 9): position E, N, U [m], velocity E, N, U [m/s],
    misalignment φ E, N, U [rad] (``attitude.misalignment`` of the IMU frame).
    """
    S = _mc_setup(spec)
    nav = _mc_navigate(*_mc_inputs(np.random.default_rng(seed), spec, S), spec, S, None)
    return _mc_errors(_mc_rows(nav), S)


def _mc_rows(nav):
    """A run's output as rows (M, 9): lon, lat, h, velocity, attitude (IMU frame)."""
    r = np.empty((nav.t.size, 9))
    r[:, 0], r[:, 1], r[:, 2], r[:, 3:6] = nav.lon, nav.lat, nav.h, nav.vel
    r[:, 6:9] = nav.att_imu if nav.att_imu is not None else nav.att
    return r


def _mc_errors(rows, S):
    """Errors (..., M, 9) of :func:`mc_run` from rows (..., M, 9) of :func:`_mc_rows`
    (one run or several stacked in front), by :func:`sinslab.nav.compare.row_errors` in one
    pass over all runs."""
    from sinslab.core.records import NavSeries
    from sinslab.nav import compare

    flat = rows.reshape(-1, 9)
    t = S["truth"].t
    nav = NavSeries(t=np.tile(t, flat.shape[0] // t.size), lat=flat[:, 1], lon=flat[:, 0], h=flat[:, 2],
                    vel=flat[:, 3:6], att=flat[:, 6:9])
    e = compare.row_errors(nav, S["truth"], imu_frame=True)
    return np.stack([e[k] for k in _MC_ERRORS], -1).reshape(rows.shape)


#: The columns of a Monte Carlo run's errors, as :func:`sinslab.nav.compare.row_errors` names them.
_MC_ERRORS = ("east", "north", "up", "vE", "vN", "vU", "phiE", "phiN", "phiU")


def mc_batch(seeds, spec):
    """Monte Carlo campaign function (:func:`sinslab.estimation.montecarlo.run_campaign`):
    the runs of :func:`mc_run` for ``seeds``, stacked.

    Each run's sensor errors and navigation are compiled loops over its own record; the
    held vertical rate is computed once for all runs, and the errors of all runs are formed
    in one pass over (runs × epochs) — the same numbers as :func:`mc_run` per seed.

    Returns
    -------
    dict
        ``err`` (B, T, 9): the errors of :func:`mc_run`.
    """
    S = _mc_setup(spec)
    rows = np.stack([_mc_rows(_mc_navigate(*_mc_inputs(np.random.default_rng(seed), spec, S), spec, S,
                                           S["vup"]))
                     for seed in seeds])
    return {"err": _mc_errors(rows, S)}


def mc_moments(out):
    """What the campaign's statistics need of each run of :func:`mc_batch` (summed over
    the runs where they are computed): the errors and their squares."""
    return {"err": out["err"], "err2": out["err"] ** 2}


def monte_carlo(cfg: Config, ctx, gen, segments, start, mount):
    """Run the campaign and the covariance analysis; metrics, claims, series, figures, tables."""
    import time

    from sinslab.estimation import montecarlo as mc
    from sinslab.methods.free_inertial import covariance_analysis
    from sinslab.app import plotting as P
    from sinslab.experiments.base import Table

    n = int(cfg.runs)
    spec = _mc_spec(cfg, segments, start, mount)
    _mc_setup(spec, gen)                               # this process (sync / 1-worker paths)
    cov_every, mc_every = _mc_strides(cfg)
    upd = cfg.nav.nsub * float(cfg.scenario.sample_interval)
    notes = [f"Monte Carlo: {n} runs; every run draws its biases and scale factors from "
             "imu.*_sigma and its initial errors from init (read as 1σ), each axis N(0, σ²) "
             "independently, plus its own white noise (ARW, VRW); all runs share one true trajectory. Errors "
             f"every {mc_every * upd:g} s; covariance analysis with {cov_every * upd:g} s steps."]
    cov_ok = cfg.nav.vertical != "damped"
    sigma = None
    t_cov = time.perf_counter()
    if cov_ok:
        with ctx.progress("covariance analysis", None):
            t, sigma, model = covariance_analysis(gen.truth, gen.imu, spec, cov_every)
    t_cov = time.perf_counter() - t_cov
    ctx.log(f"{NAME}: Monte Carlo, {n} runs")
    t_mc = time.perf_counter()
    sums = mc.run_campaign(mc_batch, n, cfg.seed, scheduler=ctx.scheduler, kwargs=dict(spec=spec),
                           reduce=mc_moments, **ctx.campaign_store("mc"))
    t_mc = time.perf_counter() - t_mc
    t_ep = gen.truth.t[np.arange(sums["err"].shape[0]) * mc_every * cfg.nav.nsub]
    summ = mc.summarize_sums(n, sums["err"], sums["err2"], sigma=sigma)
    lo, hi = mc_ratio_bounds(n)
    tr = float(cfg.montecarlo.transient)
    te = t_ep - t_ep[0]
    metrics = {"mc_runs": n, "mc_campaign_s": t_mc, "mc_covariance_s": t_cov,
               "mc_ratio_bounds": [lo, hi], "mc_transient_s": tr,
               "mc_final_rms_horiz_pos_m": float(np.hypot(summ.rms[-1, 0], summ.rms[-1, 1]))}
    claims = []
    ser = {"t_s": t_ep}
    scale = {"m": 1.0, "m/s": 1.0, "arcsec": units.arcsec}
    rows = []
    if cov_ok:
        ratio = summ.rms_over_sigma()
        metrics["mc_final_sigma_horiz_pos_m"] = float(np.hypot(sigma[-1, 0], sigma[-1, 1]))
        all_r = []
        for key, label, unit in MC_ERRORS:
            c = MC_COLS[key]
            sg = sigma[:, c]
            judged = (te >= tr) & (sg > 1e-9 * max(float(sg.max()), 1e-300))
            r = ratio[judged, c]
            mm = [float(r.min()), float(r.max())] if r.size else [float("nan")] * 2
            all_r.append(mm)
            metrics[f"mc_rms_over_sigma_{key}"] = mm
            claims.append(Claim(
                f"mc_rms_over_sigma_{key}",
                f"{label}: Monte Carlo RMS ({n} runs) / covariance-analysis σ at every epoch from "
                f"t = {tr:g} s to the end — [min, max] over time",
                mm, [lo, hi],
                bool(r.size and np.all(np.isfinite(r)) and mm[0] >= lo and mm[1] <= hi),
                names=["min", "max"], relation="between", origin="check"))
            u = scale[unit]
            rows.append({"error": label, "unit": unit, "final_mc_rms": summ.rms[-1, c] / u,
                         "final_sigma": sg[-1] / u, "final_mc_mean": summ.mean[-1, c] / u,
                         "ratio_min": mm[0], "ratio_max": mm[1],
                         "ratio_mean": float(np.mean(r)) if r.size else float("nan")})
            ser[f"sigma_{key}_{unit.replace('/', 'p')}"] = sg / u
        a = np.asarray(all_r)
        metrics["mc_rms_over_sigma_min"] = float(np.min(a[:, 0]))
        metrics["mc_rms_over_sigma_max"] = float(np.max(a[:, 1]))
    else:
        notes.append("damped vertical channel: no covariance analysis (the error model has no "
                     "damping loop); the Monte Carlo statistics are shown alone")
    for key, label, unit in MC_ERRORS:
        c = MC_COLS[key]
        u = scale[unit]
        ser[f"rms_{key}_{unit.replace('/', 'p')}"] = summ.rms[:, c] / u
        ser[f"mean_{key}_{unit.replace('/', 'p')}"] = summ.mean[:, c] / u

    # ---- figures
    tt, tlabel = P.time_axis(te)
    figs = []
    fig, ax = P.figure(4, row_height=2.3)
    groups = (("position [m]", ("pos_e", "pos_n")), ("velocity [m/s]", ("vel_e", "vel_n")),
              ("φE, φN [arcsec]", ("phi_e", "phi_n")), ("φU [arcsec]", ("phi_u",)))
    for a_, (ylab, keys) in zip(ax, groups):
        for j, key in enumerate(keys):
            c = MC_COLS[key]
            unit = dict((k, u_) for k, _, u_ in MC_ERRORS)[key]
            col = P.COLORS[j]
            a_.plot(tt, summ.rms[:, c] / scale[unit], color=col, lw=1.3, label=f"{key}: MC RMS")
            if cov_ok:
                a_.plot(tt, sigma[:, c] / scale[unit], color=col, lw=1.0, ls="--", label=f"{key}: σ")
        a_.set_ylabel(ylab)
        a_.legend(fontsize="x-small", ncol=2, loc="upper left")
    ax[-1].set_xlabel(tlabel)
    figs.append(Figure("mc_rms_sigma", fig, f"Monte Carlo RMS over {n} runs (solid) and "
                       "covariance-analysis σ (dashed) of every error versus time"))
    if cov_ok:
        fig, ax = P.figure(1, row_height=3.2)
        for j, (key, label, unit) in enumerate(MC_ERRORS):
            ax[0].plot(tt, ratio[:, MC_COLS[key]], lw=1.0, color=P.COLORS[j % len(P.COLORS)],
                       ls="-" if j < len(P.COLORS) else ":", label=key)
        ax[0].axhspan(lo, hi, color="0.85", zorder=0, label=f"accepted [{lo:.3g}, {hi:.3g}]")
        if tr > 0:
            ax[0].axvspan(0.0, tr * tt[-1] / te[-1], color="0.6", alpha=0.3, zorder=0,
                          label="transient (not judged)")
        ax[0].set_ylim(max(0.0, min(lo, np.nanmin(ratio[1:])) - 0.1), max(hi, np.nanmax(ratio[1:])) + 0.1)
        ax[0].set_ylabel("MC RMS / σ")
        ax[0].legend(fontsize="x-small", ncol=3, loc="lower right")
        ax[0].set_xlabel(tlabel)
        figs.append(Figure("mc_ratio", fig, f"Monte Carlo RMS / covariance σ ({n} runs); grey band: "
                           "the accepted interval (chi-square sampling interval, at least 0.8–1.2)"))
    tables = [Table("mc_vs_covariance", {k: [r_[k] for r_ in rows] for k in rows[0]},
                    f"Monte Carlo ({n} runs) versus covariance analysis: values at the end, "
                    f"ratio RMS/σ over t ≥ {tr:g} s")] if rows else []
    return metrics, claims, {"montecarlo": ser}, figs, tables, notes


# ---------------------------------------------------------------- the experiment --------

def _motion(cfg: Config):
    from sinslab.sim import presets
    from sinslab.sim import trajectory as tr

    s = cfg.scenario
    T = float(s.duration)
    start = tr.Start(lat=float(s.latitude), lon=float(s.longitude), h=float(s.height),
                     speed=float(s.speed), heading=float(s.heading))
    if s.motion_file:
        m = tr.load_motion(s.motion_file)            # validated with the config
        return m.segments, (m.start or start), m.mount
    if s.motion == "static":
        return presets.static(T), tr.Start(lat=start.lat, lon=start.lon, h=start.h, heading=start.heading), None
    if s.motion == "ship_manoeuvring":
        return (presets.ship_manoeuvring(T), tr.Start(lat=start.lat, lon=start.lon, h=start.h,
                                                        heading=start.heading), None)
    return presets.aircraft_mixed(T), start, None


def run(cfg: Config, ctx) -> Result:
    from sinslab.sim import imu as imu_mod
    from sinslab.nav import strapdown
    from sinslab.sim import trajectory
    from sinslab.core import earth
    from sinslab.core.attitude import wrap_pi, yaw_to_heading
    from sinslab.core.records import NavState
    from sinslab.nav import compare
    from sinslab.methods.free_inertial import (envelopes, fit_schuler_period,
                                              linear_error_prediction)
    from sinslab.app import plotting as P

    s, n = cfg.scenario, cfg.nav
    dt, T = float(s.sample_interval), float(s.duration)
    upd = n.nsub * dt
    out_every = max(1, int(round(float(n.output_interval) / upd)))

    segments, start, mount = _motion(cfg)
    ctx.log(f"{NAME}: synthesising {T:g} s of motion at {1 / dt:g} Hz")
    gen = trajectory.generate(segments, start, dt, duration=T, mount=mount)
    truth_full, ideal = gen.truth, gen.imu

    meas = imu_mod.apply(ideal, cfg.imu.errors(), ctx.rng(1))

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
    e = compare.row_errors(nav, truth)
    pos_err = np.column_stack([e["east"], e["north"], e["up"]])
    vel_err = np.column_stack([e["vE"], e["vN"], e["vU"]])
    att_err = np.column_stack([e["pitch"], e["roll"], -e["yaw"]])        # heading error = −yaw error
    hpos = np.hypot(pos_err[:, 0], pos_err[:, 1])
    hvel = np.hypot(vel_err[:, 0], vel_err[:, 1])
    lat0, h_mean = float(truth.lat[0]), float(np.mean(truth.h))

    # ---- oracle 1: the linear error model driven by the realised sensor errors
    ei = compare.row_errors(nav, truth, imu_frame=True)
    phi_act = np.column_stack([ei["phiE"], ei["phiN"], ei["phiU"]])
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
            schuler / 60.0, ts_theory / 60.0, rel=0.01, unit="min", origin="check"))
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
                          lin["res_pos"], LIN_REL * scale_p + LIN_ABS_POS, "m", origin="check"),
            Claim.at_most("vel_linear_model", "horizontal velocity error = linear error model: "
                          f"max residual [m/s] within {LIN_REL:.0%} of the model's peak + "
                          f"{LIN_ABS_VEL:g} m/s", lin["res_vel"], LIN_REL * scale_v + LIN_ABS_VEL, "m/s",
                          origin="check"),
            Claim.at_most("att_linear_model", "misalignment φ = linear error model: max residual "
                          f"[arcsec] within {LIN_REL:.0%} of the model's peak + {LIN_ABS_ATT:g} arcsec",
                          lin["res_phi"] / units.arcsec,
                          (LIN_REL * scale_a) / units.arcsec + LIN_ABS_ATT, "arcsec", origin="check"),
        ]
    else:
        notes.append("damped vertical channel: the linear-model claims are not evaluated "
                     "(the model has no damping loop)")
    for key, what in (("pos", "horizontal position error"), ("vel", "horizontal velocity error"),
                      ("tilt", "pitch and roll errors"), ("heading", "heading error")):
        r = ratios[key]
        claims.append(Claim(
            f"{key}_envelope", f"gross-error check only (the band spans three decades): {what}: "
            "max over time of error / closed-form static-error-model envelope (a loose upper "
            "bound on a manoeuvring trajectory, reached at least in part by errors that the same "
            "sensor errors drive)", r, [ENVELOPE_MIN_RATIO, 1.0],
            bool(np.isfinite(r) and ENVELOPE_MIN_RATIO <= r <= 1.0), relation="between", origin="check"))

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
            "heading_deg": yaw_to_heading(truth.att[:, 2]) / units.deg,
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
    e_km = wrap_pi(truth.lon - truth.lon[0]) * rn_t * np.cos(truth.lat) / 1e3
    n_km = (truth.lat - truth.lat[0]) * rm_t / 1e3
    ax[0].plot(e_km, n_km, color=P.COLORS[0], lw=1.2)
    ax[0].plot(e_km[0], n_km[0], "o", color=P.COLORS[2], label="start")
    ax[0].set_xlabel("east [km]")
    ax[0].set_ylabel("north [km]")
    ax[0].set_aspect("equal", adjustable="datalim")
    ax[0].legend(fontsize="small")
    figs.append(Figure("track", fig, f"True ground track ({s.motion_file or s.motion})"))

    tables = []
    if cfg.runs > 1:
        m_mc, c_mc, s_mc, f_mc, t_mc, n_mc = monte_carlo(cfg, ctx, gen, segments, start, mount)
        metrics.update(m_mc)
        claims += c_mc
        series.update(s_mc)
        figs += f_mc
        tables += t_mc
        notes += n_mc

    notes.append(f"Vertical channel: {n.vertical}"
                 + (" (held to the true height, a perfect barometer)" if n.vertical == "hold" else "")
                 + f"; {n.nsub} samples per update; error series every {out_every * upd:g} s.")
    return Result(metrics=metrics, claims=claims, series=series, figures=figs, tables=tables,
                  notes=notes)
