"""rtk-outages: what the INS adds to RTK when the satellites come back after an outage.

A car drives 200 s (accelerations, turns) near 35.3° N with an automotive MEMS IMU and a
dual-frequency receiver; a base station stands ``base_distance`` away. Every satellite is
lost for 5, 10 and 30 s (bridges, a tunnel: from 40 s, each next outage 45 s after the
previous return); when they return every signal is a new lock with new integers. Three filters run on the same observations:

- **RTK/INS** (:func:`sinslab.fusion.rtk_ins.rtk_ins`, fix and hold): the INS carries
  the position through the outage, so the first double differences after it meet a prior
  of centimetres to decimetres and the new ambiguities can be fixed at once;
- **RTK alone** (:func:`sinslab.fusion.gnss_alone.rtk_solve`, constant-velocity motion
  model driven by white acceleration of ``filter.accel_noise``): after the outage its
  position is known to metres and the integers must come from the observations alone;
- **RTK/INS float** (integer resolution off): for the consistency of the float solution.

Measured per outage length: the share of the epochs within 1 s of the signals' return
(the first epoch back and the next, at 1 Hz) that are fixed, with and without the INS,
and the median time to the first fixed epoch after the return; over the drive: the share
of epochs with satellites that are fixed, the RMS of the fixed antenna position against
the truth, and the number of double-difference integers fixed wrong (the simulator knows
them). Consistency: the position NEES of the fixed (RTK/INS, integers right) and float
(RTK/INS float) solutions averaged over the runs at epochs just before each outage and at
the end, against the two-sided 99 % χ² band of 3 × runs degrees of freedom — a test
where the simulated errors are the modelled ones (the default; with
``gnss.code_multipath`` > 0 the filters take correlated code errors as white, the NEES is
no test and its claims are left out).

The default receiver sees GPS only on L1/L2 with 1 m code noise (a consumer receiver):
where the INS matters. With GPS + Galileo (``gnss.systems=GE``) RTK alone fixes again
within a second or two as well.
"""
from __future__ import annotations

import functools
import math
from typing import Literal

import numpy as np

from sinslab.experiments.base import (Claim, ExperimentConfig, Field, Figure, Metric, Q, Result, Section, Table,
                                      imu_section)

NAME = "rtk-outages"
PURPOSE = "RTK/INS against RTK alone: integers fixed again after 5, 10 and 30 s GNSS outages of a car"
NOTES = [
    "Fixed within 1 s: the first epoch after the outage and the next one (1 Hz), over every "
    "outage of every run.",
    "Errors of the antenna position (the IMU point, no lever arm) east/north/up against the "
    "simulated truth; fixed RMS over the fixed epochs only.",
]
LENGTHS = (5, 10, 30)


class Scenario(Section):
    base_distance: Q("length", ge="0 m", le="50 km") = Field("5 km", description="rover start to base station")


Imu = imu_section("Imu", {
    "gyro_bias_sigma": ("10 deg/h", "1σ of each run's constant gyro bias"),
    "gyro_arw": "0.2 deg/sqrt(h)",
    "accel_bias_sigma": ("1000 ug", "1σ of each run's constant accelerometer bias"),
    "accel_vrw": "50 ug/sqrt(Hz)",
})


class Gnss(Section):
    systems: Literal["G", "GE"] = Field("G", description="GPS, or GPS + Galileo (Walker constellations)")
    code_sigma: Q("length", gt="0 m") = Field("1 m", description="code noise σ₀ (zenith, strong signal)")
    code_multipath: Q("length", ge="0 m") = Field("0 m", description="code multipath σ (Gauss–Markov, 20 s; "
                                                  "the filters do not model it)")
    phase_sigma: Q("length", gt="0 m") = Field("3 mm", description="phase noise σ₀")


class Filter(Section):
    accel_noise: Q("accel_random_walk", gt="0 m/s^2/sqrt(s)") = Field(
        "1 m/s^2/sqrt(s)", description="white acceleration density of RTK alone's constant-velocity model")
    ratio: float = Field(3.0, gt=1.0, description="ratio-test threshold")
    success: float = Field(0.999, ge=0.0, lt=1.0, description="least bootstrapped success rate of a fix")


class Config(ExperimentConfig):
    runs: int = Field(20, ge=1, le=200, description="simulated drives")
    scenario: Scenario = Scenario()
    imu: Imu = Imu()
    gnss: Gnss = Gnss()
    filter: Filter = Filter()


QUICK = {"runs": 3}

#: CPU seconds of each ``sinslab demo`` run at full scale, robustness re-runs included
#: (quiet machine): the demo starts the longest first.
DEMO_COST_S = {"": 27}

METRICS = {}
for _L in LENGTHS:
    for _w, _d in (("ins", "RTK/INS"), ("alone", "RTK alone")):
        METRICS[f"refix_1s_{_w}_{_L}s"] = Metric("-", f"{_d}: share of the epochs within 1 s of the return "
                                                      f"after the {_L} s outages that are fixed")
        METRICS[f"refix_time_{_w}_{_L}s_median"] = Metric("s", f"{_d}: median time from the return after the "
                                                                f"{_L} s outages to the first fixed epoch")
for _w, _d in (("ins", "RTK/INS"), ("alone", "RTK alone")):
    METRICS[f"fixed_fraction_{_w}"] = Metric("-", f"{_d}: share of the epochs with satellites that are fixed")
    METRICS[f"fixed_rms_horizontal_{_w}"] = Metric("m", f"{_d}: horizontal RMS of the fixed antenna position")
    METRICS[f"fixed_rms_vertical_{_w}"] = Metric("m", f"{_d}: vertical RMS of the fixed antenna position")
    METRICS[f"wrong_integers_{_w}"] = Metric("-", f"{_d}: double-difference integers fixed wrong (all runs)")
METRICS.update({
    "nees_fixed": Metric("-", "RTK/INS fixed solution: position NEES averaged over the runs (per check epoch)"),
    "nees_float": Metric("-", "RTK/INS float solution: position NEES averaged over the runs (per check epoch; "
                              "null with multipath, which the filters do not model)"),
    "nees_band": Metric("-", "two-sided 99 % χ² band of the run-averaged NEES (3 × runs degrees of freedom)"),
})


def outage_windows(lengths):
    """``(start, length)`` of the outages [s]: the first at 40 s, each next 45 s after the
    previous return."""
    out, t = [], 40.0
    for L in lengths:
        out.append((t, float(L)))
        t += float(L) + 45.0
    return tuple(out)


def simulate_drive(seed, *, duration=200.0, canyon=(), systems="GE", code_sigma=0.3, code_multipath=0.0,
                   phase_sigma=0.003, phase=None, base_offset=(3000.0, 4000.0, 10.0), gyro_bias_sigma=None,
                   accel_bias_sigma=None, gyro_arw=None, accel_vrw=None, dt=0.01, segments=None, orbits=None):
    """A simulated car drive with raw GNSS at the antenna (the IMU point) and a base.

    The motion: accelerate, straight, turns (the default segments, or ``segments`` of
    :mod:`sinslab.sim.trajectory`, cut at ``duration`` [s]), IMU sampled every ``dt`` [s]; IMU errors drawn from ``seed`` (σ of constant biases [rad/s], [m/s²], white noise
    [rad/√s], [m/s/√s], scalars or per axis; defaults: 10 °/h, 1 mg, 0.2 °/√h, 50 µg/√Hz); 1 Hz observations of
    Walker GPS (and Galileo; or the constellations ``orbits``) on L1/L2 (E1/E5b) at the
    antenna and at a base ``base_offset``
    (ENU [m] from the start) with code σ₀ and Gauss–Markov code multipath [m], phase σ₀ [m]
    (or a given :class:`sinslab.sim.gnss.PhaseErrors`), outages ``canyon``; the initial
    state drawn from its σ (1 m, 0.1 m/s, 0.5°/0.5°/2°).

    Returns a dict: imu, init, truth, rover, base (RtkBase), sim, sigma0 (the 15 core and
    sensor σ), arw, vrw.
    """
    from sinslab.core import attitude as A
    from sinslab.core import earth as E
    from sinslab.core import units as u
    from sinslab.core.records import NavState
    from sinslab.fusion.gnss import SatelliteObservations
    from sinslab.fusion.rtk import RtkBase
    from sinslab.sim import gnss as SG
    from sinslab.sim import imu as IM

    gb = 10 * u.dph if gyro_bias_sigma is None else gyro_bias_sigma
    ab = 1e-3 * 9.80665 if accel_bias_sigma is None else accel_bias_sigma
    arw = 0.2 * u.deg / 60.0 if gyro_arw is None else gyro_arw
    vrw = 50e-6 * 9.80665 if accel_vrw is None else accel_vrw
    g = _motion(dt, duration) if segments is None else _motion.__wrapped__(dt, duration, segments)
    tru = g.truth
    rng = np.random.default_rng(seed)
    err = IM.ImuErrors(gyro_bias=rng.normal(0, gb, 3), accel_bias=rng.normal(0, ab, 3), gyro_arw=arw, accel_vrw=vrw)
    imu = IM.apply(g.imu, err, rng)
    te = np.arange(1.0, tru.t[-1] - 0.5, 1.0)
    k = np.searchsorted(tru.t, te - 1e-9)
    lat0, lon0, h0 = tru.lat[0], tru.lon[0], tru.h[0]
    rb = E.geodetic_to_ecef(lat0, lon0, h0) + E.enu_to_ecef_matrix(lat0, lon0) @ np.asarray(base_offset, float)
    walkers = orbits or [SG.Walker(), SG.Walker(planes=3, per_plane=8, system="E", raan0=0.4, radius=29_600e3)]
    ph = phase or SG.PhaseErrors(phase_sigma=phase_sigma, multipath=(code_multipath, 0.0, 20.0))
    sim = SG.simulate_observations(te, tru.lat[k], tru.lon[k], tru.h[k], tru.vel[k], walkers[:len(systems)],
                                   SG.GnssErrors(pseudorange_sigma=code_sigma, canyon=canyon), seed=rng,
                                   phase=ph, base=SG.BaseStation(position=tuple(rb)))
    rm, rn = E.radii(lat0, h0)
    s_att = np.radians([0.5, 0.5, 2.0])
    dp, phi = rng.normal(0, 1.0, 3), rng.normal(0, s_att)
    C = A.apply_misalignment(A.euler_to_dcm(tru.att[0]), phi)
    init = NavState(lat0 + dp[1] / rm, lon0 + dp[0] / (rn * math.cos(lat0)), h0 + dp[2],
                    tru.vel[0] + rng.normal(0, 0.1, 3), A.dcm_to_euler(C))
    sigma0 = np.r_[s_att, np.full(3, 0.1), 1.0 / rm, 1.0 / (rn * math.cos(lat0)), 1.0, np.broadcast_to(gb, 3),
                   np.broadcast_to(ab, 3)]
    return dict(imu=imu, init=init, truth=tru, rover=SatelliteObservations(**sim.fields),
                base=RtkBase(SatelliteObservations(**sim.base.fields), rb), sim=sim, sigma0=sigma0, arw=arw, vrw=vrw)


@functools.lru_cache(maxsize=2)
def _motion(dt, duration, segments=None):
    """The car's error-free motion and IMU increments (``segments``, default: accelerate,
    straight, turns) sampled every ``dt`` [s] for ``duration`` [s]. The default drive is
    made once per process and shared by the runs of a campaign: they differ only in the
    errors drawn onto it (its arrays are only read)."""
    from sinslab.core import units as u
    from sinslab.sim import trajectory as tr

    segs = segments or [tr.Accelerate(duration=10.0, accel=1.5), tr.Level(duration=30.0),
                        tr.Turn(duration=20.0, rate=4.5 * u.deg), tr.Level(duration=40.0),
                        tr.Turn(duration=10.0, rate=-9 * u.deg), tr.Level(duration=60.0),
                        tr.Turn(duration=20.0, rate=4.5 * u.deg), tr.Level(duration=60.0)]
    return tr.generate(segs, tr.Start(lat=math.radians(35.3), lon=math.radians(139.5), h=50.0,
                                      heading=math.radians(30)), dt, duration=duration)


# ------------------------------------------------------------------------- one drive
def _options(cfg, ar="hold"):
    from sinslab.fusion.rtk import RtkOptions
    return RtkOptions(phase_sigma=cfg.gnss.phase_sigma, code_sigma=cfg.gnss.code_sigma, mask=math.radians(10.0),
                      ar_mask=math.radians(10.0), ar=ar, ratio=cfg.filter.ratio, success=cfg.filter.success,
                      iono="broadcast")


def _drive(cfg, seed):
    windows = outage_windows(LENGTHS)
    duration = windows[-1][0] + windows[-1][1] + 25.0
    d = cfg.scenario.base_distance / math.sqrt(2.0)
    imu = cfg.imu.errors()
    return simulate_drive(seed, duration=duration, canyon=tuple((0, s, L) for s, L in windows),
                          systems=cfg.gnss.systems, code_sigma=cfg.gnss.code_sigma,
                          code_multipath=cfg.gnss.code_multipath, phase_sigma=cfg.gnss.phase_sigma,
                          base_offset=(d, d, 10.0), gyro_bias_sigma=cfg.imu.sigma("gyro_bias"),
                          accel_bias_sigma=cfg.imu.sigma("accel_bias"), gyro_arw=imu.gyro_arw,
                          accel_vrw=imu.accel_vrw), windows


def _filters(cfg, d):
    """The three filters on one drive: (RTK/INS log, RTK/INS float log, RTK alone solution)."""
    from sinslab.fusion.carrier import max_signals, slot_count
    from sinslab.fusion.gnss_alone import rtk_solve
    from sinslab.fusion.rtk_ins import rtk_ins, rtk_model
    from sinslab.fusion.spec import FilterGrid
    model = rtk_model(d["arw"], d["vrw"], slots=slot_count(max_signals(d["rover"])))
    P0 = np.zeros((model.n, model.n))
    P0[:15, :15] = np.diag(d["sigma0"] ** 2)
    modes = ("hold", "off") if _consistent(cfg) else ("hold",)
    logs = [rtk_ins(d["imu"], d["init"], d["rover"], d["base"], P0, model, _options(cfg, ar), grid=FilterGrid(0.1)).rtk
            for ar in modes]
    alone = rtk_solve(d["rover"], d["base"], _options(cfg), dynamics="kinematic", accel_noise=cfg.filter.accel_noise)
    return logs[0].arrays(), logs[1].arrays() if len(logs) > 1 else None, alone


def _consistent(cfg):
    """The simulated errors are those the filters model (no multipath): the NEES is a test."""
    return cfg.gnss.code_multipath == 0.0


def _wrong(fixed_dd, t, d):
    """Double-difference integers fixed that differ from the simulator's."""
    sim = d["sim"]
    f, b = sim.fields, sim.base.fields
    tr_ = {(int(e), s): a for e, s, a in zip(f["epoch"], f["sat"], sim.ambiguity)}
    tb = {(int(e), s): a for e, s, a in zip(b["epoch"], b["sat"], sim.base.ambiguity)}
    e_of = {float(x): e for e, x in enumerate(d["rover"].t_epoch)}
    n = 0
    for tt, (pairs, ints) in zip(t, fixed_dd):
        e = e_of[float(tt)]
        for (s, q, k), v in zip(pairs, ints):
            n += int(v != (tr_[e, s][k] - tb[e, s][k]) - (tr_[e, q][k] - tb[e, q][k]))
    return n


def _stats(t, status, fixed_pos, fixed_dd, d, windows):
    """Per filter: fixed within 1 s and time to fix after each window, fixed ENU errors,
    wrong integers, share fixed."""
    from sinslab.core import earth as E
    tru = d["truth"]
    k = np.searchsorted(tru.t, t - 1e-9)
    truth = E.geodetic_to_ecef(tru.lat[k], tru.lon[k], tru.h[k])
    C = E.enu_to_ecef_matrix(tru.lat[0], tru.lon[0])
    fx = status == 2
    within, ttf = [], []
    for s, L in windows:
        back = t >= s + L - 1e-6
        within.append(fx[back & (t <= s + L + 1.0 + 1e-6)])
        first = t[back & fx]
        ttf.append(float(first[0] - (s + L)) if first.size else math.inf)
    idx = np.flatnonzero(fx)
    return dict(within=within, ttf=ttf, err=(fixed_pos[fx] - truth[fx]) @ C,
                wrong=_wrong([fixed_dd[i] for i in idx], t[idx], d), fixed=int(fx.sum()), seen=int((status > 0).sum()))


def _nees(t, pos, cov, d, at):
    from sinslab.core import earth as E
    tru = d["truth"]
    out = []
    for ta in at:
        i = np.flatnonzero(np.isclose(t, ta))
        if not i.size or not np.all(np.isfinite(pos[i[0]])):
            out.append(np.nan)
            continue
        k = int(np.searchsorted(tru.t, ta - 1e-9))
        e = pos[i[0]] - E.geodetic_to_ecef(tru.lat[k], tru.lon[k], tru.h[k])
        out.append(float(e @ np.linalg.solve(cov[i[0]], e)))
    return out


def one_run(cfg, seed, trace=False):
    """One drive and its three filters, reduced to what the campaign adds up (and, with
    ``trace``, the horizontal errors of both solutions over time for the figure)."""
    d, windows = _drive(cfg, seed)
    ins, flt, alone = _filters(cfg, d)
    at = [s - 1.0 for s, _ in windows] + [float(d["rover"].t_epoch[-1])]
    out = dict(ins=_stats(ins["t"], ins["status"], ins["fixed_pos"], ins["fixed_dd"], d, windows),
               alone=_stats(alone.t, alone.status, alone.fixed_pos, alone.fixed_dd, d, windows),
               nees_fixed=_nees(ins["t"], ins["fixed_pos"], ins["fixed_cov"], d, at),
               nees_float=_nees(flt["t"], flt["float_pos"], flt["float_cov"], d, at) if flt is not None else None)
    if trace:
        out["trace"] = dict(ins=_horizontal(ins["t"], ins["status"], ins["fixed_pos"], ins["float_pos"], d),
                            alone=_horizontal(alone.t, alone.status, alone.fixed_pos, alone.float_pos, d))
    return out


def _horizontal(t, status, fixed_pos, float_pos, d):
    from sinslab.core import earth as E
    tru = d["truth"]
    k = np.searchsorted(tru.t, t - 1e-9)
    pos = np.where((status == 2)[:, None], fixed_pos, float_pos)
    e = (pos - E.geodetic_to_ecef(tru.lat[k], tru.lon[k], tru.h[k])) @ E.enu_to_ecef_matrix(tru.lat[0], tru.lon[0])
    return dict(t=t, status=status, h=np.hypot(e[:, 0], e[:, 1]))


# ------------------------------------------------------------------------- campaign
def run(cfg: Config, ctx) -> Result:
    runs = []
    with ctx.progress("rtk-outages", total=cfg.runs, unit="drives") as bar:
        for i in range(cfg.runs):
            runs.append(one_run(cfg, [cfg.seed, i], trace=i == 0))
            bar.advance(1)
    metrics, rows = _metrics(cfg, runs)
    claims = _claims(cfg, metrics)
    return Result(metrics=metrics, claims=claims, figures=_figures(cfg, runs, metrics),
                  tables=[Table("refix", rows, "Fixed within 1 s of the satellites' return and median time to "
                                "the first fix after it, per outage length")])


def _metrics(cfg, runs):
    from sinslab.estimation.montecarlo import chi2_bounds
    m, rows = {}, {"outage_s": [], "fixed_1s_rtk_ins": [], "fixed_1s_rtk_alone": [],
                   "time_to_fix_rtk_ins_s": [], "time_to_fix_rtk_alone_s": []}
    for j, L in enumerate(LENGTHS):
        rows["outage_s"].append(L)
        for w, col in (("ins", "rtk_ins"), ("alone", "rtk_alone")):
            within = np.concatenate([r[w]["within"][j] for r in runs])
            ttf = np.array([r[w]["ttf"][j] for r in runs])
            m[f"refix_1s_{w}_{L}s"] = float(within.mean()) if within.size else float("nan")
            m[f"refix_time_{w}_{L}s_median"] = float(np.median(ttf))
            rows[f"fixed_1s_{col}"].append(m[f"refix_1s_{w}_{L}s"])
            rows[f"time_to_fix_{col}_s"].append(m[f"refix_time_{w}_{L}s_median"])
    for w in ("ins", "alone"):
        err = np.concatenate([r[w]["err"] for r in runs])
        m[f"fixed_fraction_{w}"] = sum(r[w]["fixed"] for r in runs) / max(sum(r[w]["seen"] for r in runs), 1)
        m[f"fixed_rms_horizontal_{w}"] = float(np.sqrt(np.mean(np.sum(err[:, :2] ** 2, 1)))) if err.size else None
        m[f"fixed_rms_vertical_{w}"] = float(np.sqrt(np.mean(err[:, 2] ** 2))) if err.size else None
        m[f"wrong_integers_{w}"] = int(sum(r[w]["wrong"] for r in runs))
    for k in ("nees_fixed", "nees_float"):
        m[k] = [float(v) for v in np.mean([r[k] for r in runs], 0)] if runs[0][k] is not None else None
    lo, hi = chi2_bounds(3, len(runs), alpha=0.01)
    m["nees_band"] = [float(lo), float(hi)]
    return m, rows


def _claims(cfg, m):
    lo, hi = m["nees_band"]
    ok = lambda v: bool(np.all(np.isfinite(v)) and np.all((np.asarray(v) > lo) & (np.asarray(v) < hi)))  # noqa: E731
    out = [
        Claim.at_most("fixed_rms_horizontal_ins", "RTK/INS fixed position: horizontal RMS ≤ 2 cm",
                      m["fixed_rms_horizontal_ins"], 0.02, unit="m", origin="check"),
        Claim.at_least("refix_1s_ins_10s", "RTK/INS fixed again within 1 s after the 10 s outages at ≥ 95 % of "
                       "those epochs", m["refix_1s_ins_10s"], 0.95, origin="check"),
        Claim.equals("no_wrong_integers_ins", "RTK/INS fixes no double-difference integer wrong",
                     m["wrong_integers_ins"], 0, origin="check"),
    ]
    if not _consistent(cfg):           # multipath the filters do not model: the NEES is no test
        return out
    return out + [
        Claim("nees_fixed_in_band", "RTK/INS fixed-solution position NEES inside the 99 % χ² band",
              m["nees_fixed"], f"within {lo:.2f}..{hi:.2f}", ok(m["nees_fixed"]), origin="check"),
        Claim("nees_float_in_band", "RTK/INS float-solution position NEES inside the 99 % χ² band",
              m["nees_float"], f"within {lo:.2f}..{hi:.2f}", ok(m["nees_float"]), origin="check"),
    ]


def _figures(cfg, runs, m):
    from sinslab.app import plotting as P
    fig, axes = P.figure(1, 2, sharex=False, width=10.0, row_height=3.4,
                         title=f"integers fixed again after an outage ({cfg.gnss.systems}, {cfg.runs} drives)")
    ax = axes[0]
    x = np.arange(len(LENGTHS))
    for off, w, lab, c in ((-0.2, "ins", "RTK/INS", "#1f77b4"), (0.2, "alone", "RTK alone", "#ff7f0e")):
        ax.bar(x + off, [m[f"refix_1s_{w}_{L}s"] for L in LENGTHS], 0.38, label=lab, color=c)
    ax.set_xticks(x, [f"{L} s" for L in LENGTHS])
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("share fixed within 1 s of the return")
    ax.set_xlabel("outage")
    ax.legend(fontsize="small")
    ax = axes[1]
    tr = runs[0]["trace"]
    for w, lab, c in (("ins", "RTK/INS", "#1f77b4"), ("alone", "RTK alone", "#ff7f0e")):
        t, st, h = tr[w]["t"], tr[w]["status"], tr[w]["h"]
        ax.semilogy(t, np.where(st > 0, h, np.nan), color=c, lw=0.8, label=f"{lab}")
        ax.semilogy(t[st == 2], h[st == 2], ".", color=c, ms=2)
    for s, L in outage_windows(LENGTHS):
        ax.axvspan(s, s + L, color="0.88", lw=0)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("horizontal error [m] (dots: fixed)")
    ax.legend(fontsize="small")
    return [Figure("refix", fig, "Left: share of the epochs within 1 s of the satellites' return that are fixed, "
                   "with the INS and without. Right: the first drive, horizontal error of each solution (fixed "
                   "epochs dotted); grey: no satellite.")]
