"""Recorded IMU data through the aided filter: a pipeline of a GNSS source, aids, a start
and the filter, and the evaluation against the fixes.

1. **The GNSS source** (:class:`sinslab.fusion.aids.base.GnssSource`): position/velocity
   fixes (:class:`~sinslab.fusion.loosely_coupled.FixSource`, loosely coupled) or raw
   observations (:class:`~sinslab.fusion.tightly_coupled.RawSource`, tightly coupled).
   Its start fixes (the fixes, or the single-point solutions) are taken inside the IMU
   record, collapsed where a logger repeats them, and start the filter.
2. **The start** (:mod:`sinslab.fusion.recorded_start`): levelling at a rest or in
   motion, the heading given or from the course, the in-motion alignment where the
   levelling would be carried too long; the position and velocity from the fixes.
3. **The estimator** (:mod:`sinslab.fusion.estimators`): the error model of
   :func:`recorded_model` (the IMU's error states, then each aid's and the source's own),
   its prior from the start, the fixes and the plug-ins'
   :class:`~sinslab.fusion.aids.base.State`; the source's measurements, then each aid's
   (:meth:`~sinslab.fusion.aids.base.Aid.plan`), through the filter on one INS core with
   the lag policy of the fixes (the default), or the factor graph on the same inputs.
   Outages: no GNSS measurement valid inside one is used; a fix valid at t arrives at
   t + latency. With the fixes' noise from the innovations (``FixHandling.fix_noise``)
   the filter runs until the σ it takes the fixes with match its own innovations.
4. **The reports**: the source's and one per aid (:class:`RecordedNav`), each from the
   driver's record of its own measurements.

Evaluation: :func:`fix_errors` compares the solution (antenna point) with every fix,
used or not; :func:`outage_end_errors` takes the horizontal error at the last fix of each
outage.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.core import units
from sinslab.core.blocks import BLOCK_ROWS, release_pages
from sinslab.core.records import Fixes, ImuRecord
from sinslab.core.stamps import held_runs
from sinslab.fusion.aids.base import AidRun, Setup
from sinslab.fusion.estimators import Estimation, KalmanEstimator
from sinslab.fusion.loosely_coupled import FixSource
from sinslab.fusion.recorded_spec import PLATFORMS, ErrorSpec, FixHandling, GridSpec, NavOptions, StartSpec
from sinslab.fusion.recorded_start import (AIRCRAFT_MOVE_SPEED, StartSolution, platform_kind, solve_start)
from sinslab.fusion.recorded_sync import (estimate_time_offset, shift_imu_time, shifted_times,
                                          significant_time_offset)
from sinslab.fusion.spec import FilterGrid, InsSpec

__all__ = ["NavOptions", "RecordedNav", "navigate_recorded", "recorded_model", "parse_outages",
           "periodic_outages", "fix_errors", "outage_end_errors", "platform_kind", "PLATFORMS",
           "ErrorSpec", "FixHandling", "StartSpec", "GridSpec", "StartSolution", "AIRCRAFT_MOVE_SPEED",
           "estimate_time_offset", "significant_time_offset", "shift_imu_time", "shifted_times"]


@dataclass(frozen=True, eq=False)
class RecordedNav:
    """Result of :func:`navigate_recorded` at the filter epochs (every ``kf_dt``).

    Attributes
    ----------
    run : sinslab.fusion.driver.DriverResult
        The filter's own result (``t``, ``nav``, ``x``, ``sigma`` ... are views of it).
    start : sinslab.fusion.recorded_start.StartSolution
    source : sinslab.fusion.aids.base.SourceReport
        What the GNSS source did (and how it was coupled).
    aids : tuple of sinslab.fusion.aids.base.Report
        One report per aid, in the run's order (:meth:`report` finds one by name).
    options : NavOptions
    platform : (str, str)
        The platform kind and why.
    outages : tuple of (start, length)
        GNSS outages [s, absolute].
    lever_arm : ndarray (3,)
        IMU -> antenna, body axes [m]: as given, or as estimated at the end.
    grid_end : float
        The last filter epoch [s].
    fixes_after_grid : int
        Start fixes after the last whole filter step (not used).
    held_fixes : (int, int) or None
        Rows of the fix table and the receiver epochs they held, when a logger repeated
        each fix in many rows (collapsed to one per epoch).
    smoothed : sinslab.fusion.smoothing.SmoothedRun or None
        The RTS-smoothed run (``options.grid.smooth``).
    estimator : sinslab.fusion.aids.base.Report or None
        The estimator's own report (the factor graph's; None for the filter).

    ``t`` (M,) [s], ``nav`` (M, 10) ``[q0..q3, vE, vN, vU, lat, lon, h]`` after feedback,
    ``x``, ``sigma`` (M, n), ``gyro_bias`` (M, 3) [rad/s] and ``accel_bias`` (M, 3) [m/s²]
    compensation in use, ``scale`` (M, 6) or None; ``labels``/``units_`` the state labels
    and display units of the layout.
    """

    run: object
    start: StartSolution
    source: object
    aids: tuple
    options: NavOptions
    platform: tuple
    outages: tuple
    lever_arm: np.ndarray
    grid_end: float
    fixes_after_grid: int
    held_fixes: tuple | None = None
    smoothed: object = None
    estimator: object = None

    t = property(lambda self: self.run.t)
    nav = property(lambda self: self.run.nav[0])
    x = property(lambda self: self.run.x)
    sigma = property(lambda self: self.run.sigma)
    gyro_bias = property(lambda self: self.run.gyro_bias[0])
    accel_bias = property(lambda self: self.run.accel_bias[0])
    layout = property(lambda self: self.run.layout)
    labels = property(lambda self: self.run.layout.labels)
    units_ = property(lambda self: self.run.layout.units)

    @property
    def scale(self):
        """(M, 6) gyro and accelerometer scale-factor compensation [-], or None."""
        s = self.run.scale
        return None if s is None else s[0]

    def _fixes(self, i):
        recs = self.source.fix_records
        if recs is None:
            raise AttributeError(f"a {self.source.coupling} run applies no fixes: its rows are in source.rows")
        return recs[i]

    fix_t = property(lambda self: self._fixes(0), doc="(J,) validity times of the fixes applied [s].")
    innovation = property(lambda self: self._fixes(1), doc="(J, m) fix innovations (north, east[, up] [m], "
                                                           "then velocity east, north, up [m/s]).")
    innovation_sigma = property(lambda self: self._fixes(2), doc="(J, m) the filter's σ of each, or None.")
    nis = property(lambda self: self._fixes(3), doc="(J,) NIS of the fixes applied.")

    def report(self, name):
        """The report of the aid ``name``."""
        for r in self.aids:
            if r.name == name:
                return r
        raise KeyError(f"no aid {name!r} in this run (aids: {', '.join(r.name for r in self.aids) or 'none'})")

    def with_nav(self, nav):
        """The same result with other navigation rows (e.g. the smoothed ones), for
        :func:`fix_errors`."""
        return dataclasses.replace(self, run=dataclasses.replace(self.run, nav=(nav, *self.run.nav[1:])))

    def to_pandas(self, smoothed: bool = False) -> "pandas.DataFrame":
        """The solution as a table, one row per filter epoch, units in the column names (the
        columns of a ``navigate`` run's ``solution.csv``): ``t_s`` (since the first epoch)
        and ``t_abs_s`` (the record's time), ``lat_deg``, ``lon_deg``, ``h_m``
        (ellipsoidal), ``vE_mps``, ``vN_mps``, ``vU_mps``, the vehicle's ``pitch_deg``,
        ``roll_deg`` and ``heading_deg`` (clockwise from north, 0–360), the filter σ of every
        state (``sigma_<state>_<display unit>``, e.g. ``sigma_phiU_arcmin``) and the sensor
        compensation in use (``gyro_bias_x_dph`` .., ``accel_bias_x_ug`` ..).

        ``smoothed=True``: the RTS-smoothed navigation and σ instead (a run with
        ``options.grid.smooth``); the compensation columns stay the forward run's.
        """
        import pandas as pd

        if smoothed and (self.smoothed is None or self.smoothed.nav is None):
            raise ValueError("this run was not smoothed (NavOptions.grid.smooth)")
        nav = self.smoothed.nav if smoothed else self.nav
        sigma = self.smoothed.sigma if smoothed else self.sigma
        att = A.quat_to_euler(nav[:, :4])
        cols = {"t_s": self.t - self.t[0], "t_abs_s": self.t, "lat_deg": np.degrees(nav[:, 7]),
                "lon_deg": np.degrees(nav[:, 8]), "h_m": nav[:, 9],
                "vE_mps": nav[:, 4], "vN_mps": nav[:, 5], "vU_mps": nav[:, 6],
                "pitch_deg": np.degrees(att[:, 0]), "roll_deg": np.degrees(att[:, 1]),
                "heading_deg": np.degrees(np.mod(A.yaw_to_heading(att[:, 2]), 2 * np.pi))}
        scale = self.layout.display_scale
        for i, (label, unit) in enumerate(zip(self.labels, self.units_)):
            cols[f"sigma_{label}_{unit.replace('/', 'p')}"] = sigma[:, i] / scale[i]
        for k, ax in enumerate("xyz"):
            cols[f"gyro_bias_{ax}_dph"] = self.gyro_bias[:, k] / units.dph
            cols[f"accel_bias_{ax}_ug"] = self.accel_bias[:, k] / units.ug
        return pd.DataFrame(cols)

    @property
    def att(self):
        """(M, 3) ``[pitch, roll, yaw]`` [rad] of the vehicle body (mount applied on input)."""
        return A.quat_to_euler(self.nav[:, :4])

    @property
    def heading(self):
        """(M,) heading clockwise from north [rad], 0..2π."""
        return np.mod(A.yaw_to_heading(self.att[:, 2]), 2 * np.pi)


# ------------------------------------------------------------------------- outages -----
def parse_outages(text, t_ref=0.0):
    """``"START:LEN,START:LEN"`` (s from ``t_ref``) or ``"LEN/PERIOD[@FIRST]"`` (periodic, first
    outage FIRST s after ``t_ref``, default 40 s) -> list of (start, length) absolute [s]
    (periodic ones are expanded by :func:`periodic_outages` once the end is known: returned
    as a ('periodic', LEN, PERIOD, FIRST) tuple)."""
    if text is None or str(text).strip() in ("", "none"):
        return []
    s = str(text).strip()
    if "/" in s:
        a, _, rest = s.partition("/")
        per, _, first = rest.partition("@")
        try:
            ln, per = float(a), float(per)
            first = float(first) if first else 40.0
        except ValueError:
            raise ValueError(f"cannot read the outages {text!r}; use LEN/PERIOD[@FIRST], e.g. 15/60@40") from None
        if not (0 < ln < per):
            raise ValueError(f"outages {text!r}: need 0 < LEN < PERIOD")
        return [("periodic", ln, per, first)]
    out = []
    for tok in s.split(","):
        a, sep, b = tok.partition(":")
        try:
            st, ln = float(a), float(b)
        except ValueError:
            raise ValueError(f"cannot read the outage {tok!r}; use START:LEN (seconds from the "
                             "first fix), e.g. 100:15") from None
        if not sep or not (ln > 0):
            raise ValueError(f"outage {tok!r}: use START:LEN with LEN > 0")
        out.append((t_ref + st, ln))
    return out


def periodic_outages(t_first, t_last, length, period, first=40.0, end_margin=30.0):
    """Outages of ``length`` s every ``period`` s from ``t_first + first`` until
    ``t_last − end_margin`` (the rtklib-drive source project: first 40 s, stop 30 s
    before the end)."""
    out = []
    s = t_first + first
    while s + length <= t_last - end_margin:
        out.append((s, length))
        s += period
    return out


def _expand_outages(outs, t0, t1):
    res = []
    for o in outs:
        if isinstance(o, tuple) and len(o) == 4 and o[0] == "periodic":
            res += periodic_outages(t0, t1, o[1], o[2], o[3])
        else:
            res.append((float(o[0]), float(o[1])))
    return res


def recorded_model(opt: NavOptions, gyro_arw, accel_vrw, blocks=()):
    """The error model of :func:`navigate_recorded`: the loosely coupled core (φ, δv, δp)
    with gyro and accelerometer bias states (random constant, or random walk with
    ``gyro_rrw``/``accel_rrw``), Gauss–Markov bias blocks (``gyro_markov``/``accel_markov``)
    and scale-factor states (``scale_factors``; random constant, walk or Gauss–Markov) of
    ``opt.errors``, from :mod:`sinslab.nav.errstate`, then the plug-ins' ``blocks`` in order."""
    from sinslab.nav import errstate as es
    e = opt.errors
    sensors = [es.gyro_bias(rrw=e.gyro_rrw), es.accel_bias(arw=e.accel_rrw)]
    if e.gyro_markov is not None:
        sensors.append(es.gyro_markov(e.gyro_markov[1], e.gyro_markov[0]))
    if e.accel_markov is not None:
        sensors.append(es.accel_markov(e.accel_markov[1], e.accel_markov[0]))
    if e.scale_factors:
        gs, as_ = _scale_sigmas(e)
        tg, ta = e.scale_tau
        sensors += [es.gyro_scale(rw=0.0 if tg else e.scale_rw[0], tau=tg, sigma=gs if tg else None),
                    es.accel_scale(rw=0.0 if ta else e.scale_rw[1], tau=ta, sigma=as_ if ta else None)]
    return es.ErrorModel("full", [*sensors, *blocks], gyro_arw=gyro_arw, accel_vrw=accel_vrw)


def _scale_sigmas(errors: ErrorSpec):
    return (errors.scale_sigma if errors.gyro_scale_sigma is None else errors.gyro_scale_sigma,
            errors.scale_sigma if errors.accel_scale_sigma is None else errors.accel_scale_sigma)


# ------------------------------------------------------------------------ the pipeline ---
def navigate_recorded(imu: ImuRecord, source, opt: NavOptions | None = None, *, aids=(),
                      estimator=None, progress=False) -> RecordedNav:
    """INS + a GNSS source + aids on a recorded IMU stream (see the module notes).

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
    source : GnssSource or sinslab.core.records.Fixes
        :class:`~sinslab.fusion.loosely_coupled.FixSource` or
        :class:`~sinslab.fusion.tightly_coupled.RawSource`; plain fixes are taken as a
        :class:`FixSource` with ``opt.fix``.
    opt : NavOptions
    aids : sequence of sinslab.fusion.aids.base.Aid
        Loaded aids (:meth:`~sinslab.fusion.aids.base.Aid.load`), in the order their
        states and measurements enter the run.
    estimator : sinslab.fusion.estimators.Estimator, optional
        The filter (default; with the RTS smoother when ``opt.grid.smooth``) or the
        factor graph (:func:`sinslab.fusion.estimators.estimator_of`).

    With ``opt.fix.fix_noise = "innovations"`` the run is repeated, the fixes' σ floored
    at what the previous run's innovations measured, until they agree (at most
    :data:`FIX_NOISE_PASSES` runs; the source report says which σ were used and why).

    Raises ValueError when the fix times do not overlap the IMU record, when there is no
    usable fix, when an aid of a wheeled vehicle meets another platform, when the
    vehicle never moves and no heading is given, or when the fix noise from the
    innovations meets the factor graph. Fixes after the last whole filter step
    are dropped (:attr:`RecordedNav.fixes_after_grid` counts them).
    """
    opt = opt or NavOptions()
    if isinstance(source, Fixes):
        source = FixSource(source, opt.fix)
    aids = tuple(aids)
    if isinstance(source, FixSource) and opt.fix.fix_noise == "innovations":
        if estimator is not None and not isinstance(estimator, KalmanEstimator):
            raise ValueError("fix noise from the innovations needs the filter's innovations: not with the "
                             "factor graph (use the filter, or the fixes' σ as stated)")
        return _fix_noise_passes(lambda src: _navigate(imu, src, opt, aids, estimator, progress), source)
    return _navigate(imu, source, opt, aids, estimator, progress)


#: most passes of ``fix_noise = "innovations"`` and the relative σ change that ends them
FIX_NOISE_PASSES = 6
FIX_NOISE_TOL = 0.05


def _fix_noise_passes(run, source: FixSource) -> RecordedNav:
    """``FixHandling.fix_noise = "innovations"``: the run repeated with the fixes' σ floored
    at what the previous run's innovations measured
    (:func:`sinslab.fusion.fix_noise.innovation_noise`: the long-run variance, a
    variance-component estimate) until they ask for no more than :data:`FIX_NOISE_TOL` above
    the σ used, at most :data:`FIX_NOISE_PASSES` runs (every run's velocity σ floored at the
    fixes' velocity walk, :meth:`FixSource.prepare`). The last run is returned, its source
    report saying which σ were used and why."""
    from sinslab.fusion.fix_noise import innovation_noise
    history = []
    for _ in range(FIX_NOISE_PASSES):
        res = run(source)
        rep = res.source
        t, inn, sd, _ = rep.fix_records
        est = innovation_noise(t, inn, sd, rep.fix_sigma, governed=_governed(source, t, rep.fix_sigma))
        if est is None:
            return _with_fix_noise(res, source, history, "too few whole 10 s batches of fixes")
        used = np.median(rep.fix_sigma, 0)
        history.append((est[0], used))
        if np.all(est[0] <= used * (1 + FIX_NOISE_TOL)):
            return _with_fix_noise(res, source, history, None)
        floor = np.maximum(used, est[0])
        n_p = floor.size - (3 if rep.fix_sigma.shape[1] in (5, 6) else 0)   # position rows: 3, or 2 (horizontal)
        pos = np.zeros(3)
        pos[:n_p] = floor[:n_p]
        source = dataclasses.replace(source, sigma_floor=(pos, floor[n_p:] if floor.size > n_p else 0.0))
    return _with_fix_noise(res, source, history, f"not settled after {FIX_NOISE_PASSES} runs")


def _governed(source: FixSource, t, sigma):
    """(J, m) bool: where the innovations' σ floor governs the applied fixes at ``t`` taken
    with σ ``sigma`` (J, m): everywhere but the velocity components the velocity check
    (:func:`sinslab.fusion.fix_noise.velocity_check`, ``handling.velocity_check``) raised
    above the σ the other fixes were taken with (their σ is the check's; a fix it raised
    less is taken with the floor like any other), or None without the check."""
    h, fx = source.handling, source.fixes
    m = sigma.shape[1]
    if h.velocity_check is None or not h.use_velocity or fx.vel is None or m not in (5, 6):
        return None
    from sinslab.fusion.fix_noise import velocity_check
    got = velocity_check(fx, h.velocity_check)
    if got is None:
        return None
    stated = np.broadcast_to(np.asarray(0.0 if fx.sigma_vel is None else fx.sigma_vel, float), got[0].shape)
    k = np.clip(np.searchsorted(fx.t, t), 0, len(fx) - 1)
    raised = (got[0] > stated * (1 + 1e-9))[k] & (np.abs(fx.t[k] - t) < 1e-6)[:, None]
    sv = sigma[:, m - 3:]
    floor = np.array([np.median(sv[~raised[:, i], i]) if np.any(~raised[:, i]) else 0.0 for i in range(3)])
    out = np.ones(sigma.shape, bool)
    out[:, m - 3:] = ~(raised & (sv > floor * (1 + 1e-9)))
    return out


def _stated_sigma(source: FixSource, n_p, with_vel):
    """Median σ the fixes are stated with (the σ overrides and floors of the handling
    applied): position north, east[, up] [m] then velocity east, north, up [m/s]."""
    h, fx = source.handling, source.fixes
    ps = np.broadcast_to(np.asarray(h.fix_sigma, float), (3,)) if h.fix_sigma is not None else np.median(fx.sigma, 0)
    out = [np.maximum(ps, h.pos_sigma_floor)[:n_p]]
    if with_vel:
        vs = (np.broadcast_to(np.asarray(h.fix_vel_sigma, float), (3,)) if h.fix_vel_sigma is not None
              else np.median(fx.sigma_vel, 0))
        out.append(np.maximum(vs, h.vel_sigma_floor))
    return np.concatenate(out)


def _with_fix_noise(res: RecordedNav, source, history, trouble):
    """``res`` with its source report saying what the innovation runs did (metrics
    ``fix_noise_*``: the σ stated, measured by the velocity walk and by the last run's
    innovations, and used; one note)."""
    rep = res.source
    m = rep.fix_sigma.shape[1]
    n_p = m - 3 if m in (5, 6) else m
    labels = (["north", "east", "up"][:n_p] + (["vE", "vN", "vU"] if m > n_p else []))
    stated = _stated_sigma(source, n_p, m > n_p)
    used = np.median(rep.fix_sigma, 0)
    metrics = dict(rep.metrics, fix_noise_runs=len(history), fix_noise_components=labels,
                   fix_noise_sigma_stated=stated.tolist(), fix_noise_sigma_used=used.tolist())
    fmt = lambda a: ", ".join(f"{x:.3g}" for x in a)
    words = [f"the file states {fmt(stated)}"]
    walk = rep.metrics.get("fix_noise_velocity_walk_sigma")
    if walk is not None and m > n_p:
        words.append(f"the velocity fixes' walk against the positions asks for {fmt(walk)} (vE, vN, vU)")
    if history:
        metrics["fix_noise_sigma_measured"] = history[-1][0].tolist()
        words.append(f"the innovations of the last run ask for {fmt(history[-1][0])}")
    note = (f"Fix σ from the innovations ({len(history)} run(s); long-run variance over 10 s batches; "
            f"{', '.join(labels)} [m, m/s]): " + "; ".join(words) + f"; used {fmt(used)}"
            + (f" ({trouble})" if trouble else "") + ".")
    return dataclasses.replace(res, source=dataclasses.replace(rep, metrics=metrics, notes=tuple(rep.notes) + (note,)))


def _navigate(imu, source, opt, aids, estimator, progress):
    """One run of :func:`navigate_recorded` (its steps 1–4)."""
    estimator = estimator or KalmanEstimator()
    estimator.check(opt.grid.smooth, source.name, [a.name for a in aids])
    fixes, held = _start_fixes(imu, source.start_fixes(), opt.fix)
    fixes, source = source.prepare(fixes)
    platform = platform_kind(fixes, opt.start.platform)
    _check_land(aids, platform, opt.start.platform)
    outages = _expand_outages(opt.fix.outages, float(fixes.t[0]), float(fixes.t[-1]))
    lever = np.asarray(opt.fix.lever_arm, dtype=float)
    T, nsub, k_kf = _filter_step(imu.dt, opt.grid)
    start = solve_start(imu, fixes, opt.start, opt.errors, lever, nsub, platform)
    states = [s for p in (*aids, source) for s in p.states()]
    model = recorded_model(opt, start.gyro_noise, start.accel_noise, [s.block for s in states])
    n_ep = (len(imu) - start.k) // k_kf
    if n_ep < 2:
        raise ValueError("the IMU record after the initial alignment is shorter than two filter steps")
    t_end = start.t + T * n_ep
    sel = fixes.select((fixes.t > start.t) & (fixes.t <= t_end + 1e-9))
    setup = Setup(imu, T, start.t, t_end, float(fixes.lat[0]), model.layout, start, start.gyro_noise,
                  sel.select(~_in_outages(sel.t, outages)), outages, opt.start, lever, platform)
    P0 = _prior(setup, fixes, opt, states, aids)
    lever_block = next((s.block.name for s in states if s.role == "antenna_lever"), None)
    plans = [source.plan(setup, sel, lever_block), *(a.plan(setup) for a in aids)]
    grid = FilterGrid(T, model_every=0.0, spill=opt.grid.spill)
    ins = InsSpec(nsub=nsub, gyro_bias=start.gyro_bias, start=start.k, t_start=start.t)
    r, sm, est_report = estimator.estimate(Estimation(imu, start, model, P0, ins, grid, plans, opt, progress))
    views = _views(r, plans, sm, T, float(fixes.t[0]))
    if lever_block is not None:
        lever = lever - r.x[-1, model.layout.slice(lever_block)]          # δl = l_used − l_true
    return RecordedNav(r, start, source.report(plans[0], views[0]),
                       tuple(a.report(p, v) for a, p, v in zip(aids, plans[1:], views[1:])), opt, platform,
                       tuple(outages), lever, t_end, int(np.sum(fixes.t > t_end + 1e-9)), held, smoothed=sm,
                       estimator=est_report)


def _start_fixes(imu, fixes: Fixes, fix: FixHandling):
    """The fixes that start the run: inside the IMU record, one per receiver epoch (a
    logger's repeated rows collapsed; ``(rows, epochs)`` returned, else None), with the σ
    overrides of ``fix``."""
    t_lo, t_hi = imu.t0, float(imu.t[-1])
    if len(fixes) == 0 or fixes.t[-1] < t_lo or fixes.t[0] > t_hi:
        span = "no fixes" if len(fixes) == 0 else f"{fixes.t[0]:.3f}..{fixes.t[-1]:.3f} s"
        raise ValueError(f"fix times ({span}) do not overlap the IMU record ({t_lo:.3f}..{t_hi:.3f} s): "
                         "different time bases? (GPST vs UTC differ by 18 s; seconds of week vs "
                         "seconds since 1970; a logging delay)")
    fixes = fixes.select((fixes.t >= t_lo) & (fixes.t <= t_hi))
    held = None
    runs = held_runs(np.column_stack([fixes.lat, fixes.lon, fixes.h, fixes.sigma]
                                     + ([fixes.vel] if fixes.vel is not None else [])))
    if runs is not None:
        # a receiver's fixes repeated in every row of a faster log: one update per epoch
        held = (len(fixes), int(runs.size))
        fixes = fixes.select(runs)
    if len(fixes) < 2:
        raise ValueError("fewer than 2 fixes inside the IMU record")
    if fix.fix_sigma is not None:
        sg = np.broadcast_to(np.asarray(fix.fix_sigma, float), (3,))
        fixes = dataclasses.replace(fixes, sigma=np.tile(sg, (len(fixes), 1)))
    if fix.fix_vel_sigma is not None and fixes.vel is not None:
        sg = np.broadcast_to(np.asarray(fix.fix_vel_sigma, float), (3,))
        fixes = dataclasses.replace(fixes, sigma_vel=np.tile(sg, (len(fixes), 1)))
    return fixes, held


def _check_land(aids, platform, given):
    """Aids that assume a wheeled land vehicle refused on another platform."""
    kind, why = platform
    needs = [a.land_only for a in aids if a.land_only]
    if kind in ("aircraft", "marine") and needs:
        raise ValueError(f"{' and '.join(needs)} assume{'s' if len(needs) == 1 else ''} a wheeled land vehicle; "
                         f"this is {'an' if kind == 'aircraft' else 'a'} {kind} ({why}): drop "
                         + "/".join(a.name for a in aids if a.land_only)
                         + (" (or give the platform as land if it is a car)" if given == "auto" else ""))


def _filter_step(dt, grid: GridSpec):
    """``(T, nsub, k)``: the filter step [s], a whole number ``k`` of IMU samples and of
    ``nsub`` subsamples, nearest the one asked for."""
    nsub = int(grid.nsub)
    k_kf = int(round(grid.kf_dt / dt))
    if k_kf < nsub or k_kf % nsub or abs(k_kf * dt - grid.kf_dt) > 0.02 * dt:
        k_kf = max(nsub, int(round(grid.kf_dt / dt / nsub)) * nsub)
    return k_kf * dt, nsub, k_kf


def _prior(setup: Setup, fixes, opt: NavOptions, states, aids):
    """``P0``: the start's attitude σ, the velocity and position σ given or those of the fix
    nearest the start (twice, floored), the IMU error states' σ, each plug-in state's σ, and the
    correlations the aids add."""
    lay, start = setup.layout, setup.start
    lat_i, _, h_i = start.position
    rm0, rn0 = (float(x) for x in E.radii(lat_i, h_i))
    sp0 = np.zeros(lay.n)
    sp0[lay.slice("phi")] = start.sigma
    jf = int(np.argmin(np.abs(fixes.t - start.t)))
    vs = fixes.sigma_vel[jf] if fixes.sigma_vel is not None else np.full(3, 0.1)
    sp0[lay.slice("dv")] = np.maximum(vs, opt.fix.vel_sigma_floor) * 2
    ps = np.maximum(fixes.sigma[jf], opt.fix.pos_sigma_floor) * 2          # north, east, up
    if start.velocity_sigma is not None:                                   # given, east, north, up
        sp0[lay.slice("dv")] = start.velocity_sigma
    if start.position_sigma is not None:
        ps = np.asarray(start.position_sigma)[[1, 0, 2]]
    sp0[lay.slice("dp")] = [ps[0] / rm0, ps[1] / (rn0 * math.cos(lat_i)), ps[2]]
    e = opt.errors
    sp0[lay.slice("eps")] = e.gyro_bias_sigma
    sp0[lay.slice("nabla")] = e.accel_bias_sigma
    if e.gyro_markov is not None:
        sp0[lay.slice("eps_m")] = e.gyro_markov[0]
    if e.accel_markov is not None:
        sp0[lay.slice("nabla_m")] = e.accel_markov[0]
    if e.scale_factors:
        sp0[lay.slice("kg")], sp0[lay.slice("ka")] = _scale_sigmas(e)
    for s in states:
        sp0[lay.slice(s.block.name)] = s.sigma
    P0 = np.diag(sp0 ** 2)
    for a in aids:
        a.correlate(P0, setup)
    return P0


def _views(r, plans, smoothed, T, t_ref):
    """Per plug-in, the run as its report sees it (:class:`~sinslab.fusion.aids.base.AidRun`):
    the driver's record of its own measurements, by label."""
    from sinslab.fusion.observer import Applied
    ap, dec = r.applied, r.decisions
    out, mi = [], 0
    for p in plans:
        gates, rows, applied = {}, {}, {}
        for label, _ in p.measurements:
            k = np.flatnonzero(ap.measurement == mi)
            applied[label] = Applied(np.zeros(k.size, np.int64), ap.item[k], ap.t_valid[k], ap.t_applied[k],
                                     [ap.innovation[i] for i in k], ap.nis[k],
                                     [ap.innovation_sigma[i] for i in k] if ap.innovation_sigma else [])
            gates[label], rows[label] = dec.gate(mi), dec.rows_of(mi)
            mi += 1
        out.append(AidRun(r.t, r.x, r.sigma, r.layout, smoothed, gates, rows, T, t_ref, applied))
    return out


def _in_outages(t, outages):
    m = np.zeros(np.shape(t), bool)
    for s0, ln in outages:
        m |= (t >= s0) & (t < s0 + ln)
    return m


# ----------------------------------------------------------------------- evaluation ----
def _interp_rows(res: RecordedNav, t):
    """Latitude, longitude, height and attitude (DCM) of the solution at the sorted times
    ``t``, interpolated from the epochs around each block of them (the numbers of
    interpolating in the whole solution; a run on disk is read a window at a time)."""
    out = np.empty((np.size(t), 7))
    i = 0
    span = BLOCK_ROWS * (res.t[1] - res.t[0]) if res.t.size > 1 else math.inf
    while i < out.shape[0]:
        j = max(i + 1, int(np.searchsorted(t, t[i] + span, side="right")))
        lo = max(0, int(np.searchsorted(res.t, t[i])) - 2)
        hi = min(res.t.size, int(np.searchsorted(res.t, t[j - 1])) + 3)
        te, nav = np.asarray(res.t[lo:hi]), np.asarray(res.nav[lo:hi])
        for c, k in enumerate((7, 8, 9, 0, 1, 2, 3)):
            out[i:j, c] = np.interp(t[i:j], te, nav[:, k])
        release_pages(res.t, res.nav)
        i = j
    q = np.ascontiguousarray(out[:, 3:])
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy(), A.quat_to_dcm(q)


def fix_errors(res: RecordedNav, fixes: Fixes, lever_arm=None):
    """Solution (antenna point) minus fix at every fix time inside the solution span.

    Returns ``(t (K,), err (K, 3) east/north/up [m], index (K,) into fixes)``.
    """
    if lever_arm is None:
        lever_arm = res.lever_arm
    lever = np.asarray(lever_arm, dtype=float)
    idx = np.flatnonzero((fixes.t >= res.t[0]) & (fixes.t <= res.t[-1]))
    t = fixes.t[idx]
    lat, lon, h, C = _interp_rows(res, t)
    d = C @ lever
    rm, rn = E.radii(lat, h)
    e = (lon - fixes.lon[idx]) * rn * np.cos(lat) + d[:, 0]
    nn = (lat - fixes.lat[idx]) * rm + d[:, 1]
    u = h - fixes.h[idx] + d[:, 2]
    return t, np.stack([e, nn, u], -1), idx


def outage_end_errors(res: RecordedNav, fixes: Fixes, outages=None):
    """Horizontal error [m] at the last fix inside each outage (the INS has coasted the
    whole outage there). Returns ``(outage starts (k,), errors (k,))``."""
    outs = res.outages if outages is None else outages
    t, err, _ = fix_errors(res, fixes)
    starts, errs = [], []
    for s, ln in outs:
        m = np.flatnonzero((t >= s) & (t < s + ln))
        if m.size:
            starts.append(s)
            errs.append(float(np.hypot(err[m[-1], 0], err[m[-1], 1])))
    return np.array(starts), np.array(errs)
