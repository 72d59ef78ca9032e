"""Loosely coupled INS + position/velocity fixes: the error model and the composition of
the fusion driver that runs it (:func:`loosely_coupled`).

One live INS stream (:class:`sinslab.fusion.driver.LiveStream`), the error model of
:mod:`sinslab.nav.errstate` (φ, δv, δp, gyro bias ε, accelerometer bias ∇, optional
gyro/accel scale factors; bias random walks, :func:`lc_model`) and one measurement, the
antenna position (:class:`~sinslab.fusion.measurements.PositionFix`, stacked with a
:class:`~sinslab.fusion.measurements.VelocityFix` when velocities are given), run by
:func:`sinslab.fusion.driver.run` with feedback (closed loop) or feed-forward. Fixes are
extrapolated from their validity time to the filter epoch with the INS velocity (at most ``kf_dt``).
The run is described by specs checked when they are made (:mod:`sinslab.fusion.spec`:
the fixes, the INS stream, the filter grid) and a lag policy (:mod:`sinslab.fusion.lag`).

The composition is two parts any aided run shares: :func:`ins_core` (the INS stream on
the filter grid, the feedback layout, the model checked against them; :meth:`InsCore.run`
runs the driver with whatever measurements) and :func:`fix_measurement` (the fixes as a
measurement of that stream). The tightly coupled filter and the recorded front end
compose the same core with other measurements.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.fusion import driver
from sinslab.fusion.driver import LiveStream
from sinslab.fusion.feedback import FeedbackLayout
from sinslab.fusion.lag import ExactReprocessing
from sinslab.fusion.measurements import (LeverPositionFix, LeverVelocityFix, PositionFix, Stack,
                                         VelocityFix)
from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec
from sinslab.nav import errstate as es

__all__ = ["loosely_coupled", "loosely_coupled_many", "LooselyCoupled", "lc_model", "ins_core", "InsCore",
           "fix_measurement", "FixMeasurement", "FixSource"]


def lc_model(gyro_arw, accel_vrw, gyro_rrw=0.0, accel_rrw=0.0, *, scale_factors=False):
    """The loosely coupled error model: φ, δv, δp = [δL, δλ, δh], gyro bias ε (body),
    accelerometer bias ∇ (body) (15 states), plus gyro and accelerometer scale factors
    ``kg``, ``ka`` (21 states) with ``scale_factors=True``; from :mod:`sinslab.nav.errstate`.

    Parameters
    ----------
    gyro_arw : float or (3,)
        Angle random walk [rad/√s].
    accel_vrw : float or (3,)
        Velocity random walk [m/s/√s].
    gyro_rrw, accel_rrw : float
        Bias random-walk densities [rad/s/√s], [m/s²/√s] (0: random constants).
    """
    sensors = [es.gyro_bias(rrw=gyro_rrw), es.accel_bias(arw=accel_rrw)]
    if scale_factors:
        sensors += [es.gyro_scale(), es.accel_scale()]
    return es.ErrorModel("full", sensors, gyro_arw=gyro_arw, accel_vrw=accel_vrw)


@dataclass(frozen=True)
class LooselyCoupled:
    """Output of :func:`loosely_coupled`, at the filter epochs (every ``kf_dt``).

    Attributes
    ----------
    t : ndarray, shape (M,)
        Epoch times [s] (M = filter steps + 1; row 0 = start).
    nav : ndarray, shape (M, 10)
        Navigation state ``[q0..q3, vE, vN, vU, lat, lon, h]`` after any feedback at that
        epoch (feedback mode) or the free INS (feed-forward mode; subtract ``x``).
    x : ndarray, shape (M, n)
        Error-state estimate after the epoch (after its updates and feedback: the states
        not fed back; in feed-forward mode the whole estimate).
    sigma : ndarray, shape (M, n)
        Filter σ of every state.
    gyro_bias, accel_bias : ndarray, shape (M, 3)
        Sensor compensation in use after the epoch [rad/s], [m/s²].
    scale : ndarray, shape (M, 6) or None
        Gyro and accelerometer scale-factor compensation [-] (models with ``kg``/``ka``).
    fix_t : ndarray, shape (J,)
        Validity times of the applied fixes [s].
    t_applied : ndarray, shape (J,)
        Epochs at which they were processed [s].
    fix_index : ndarray of int, shape (J,)
        Their rows in the fix arrays given.
    innovation : ndarray, shape (J, m)
        Fix innovations: position north, east[, up] [m], then velocity east, north, up
        [m/s] when velocity fixes are used.
    nis : ndarray, shape (J,)
    layout : object
        The error-state layout of the model (names of the states).
    history : sinslab.fusion.smoothing.History or None
        The recorded forward pass (``history=``), for :func:`sinslab.fusion.smoothing.smooth`.
    innovation_sigma : ndarray, shape (J, m) or None
        The filter's σ of each innovation component, √diag(H P Hᵀ + R) [m, m/s].
    """

    t: np.ndarray
    nav: np.ndarray
    x: np.ndarray
    sigma: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    scale: np.ndarray | None
    fix_t: np.ndarray
    t_applied: np.ndarray
    fix_index: np.ndarray
    innovation: np.ndarray
    nis: np.ndarray
    layout: object
    history: object = None
    innovation_sigma: np.ndarray | None = None


def loosely_coupled(imu, init, fixes: FixSpec, P0, model, *, ins: InsSpec = InsSpec(),
                    grid: FilterGrid = FilterGrid(), lag=ExactReprocessing(), feedback=True, aiding=(),
                    history=None, progress=True, label="loosely coupled") -> LooselyCoupled:
    """INS + position(/velocity) fixes with an error-state Kalman filter, on the fusion
    driver (:func:`sinslab.fusion.driver.run`, whose notes derive the loop).

    The strapdown mechanization (:func:`sinslab.nav.strapdown.step`) runs on the IMU stream
    in compiled blocks between the epochs at which fixes are processed; the error-state
    model is evaluated for all filter epochs of a block at once and discretised
    (:func:`sinslab.estimation.kalman.discretize`); the covariance is propagated every
    ``grid.kf_dt`` by one :class:`sinslab.estimation.filter.KalmanFilter`. At a fix the
    filter updates (position, with the lever arm in H, and velocity when given) and, with
    ``feedback=True``, corrects the navigation state (:func:`sinslab.nav.strapdown.correct`)
    and the sensor compensation (biases, scale factors) through
    :class:`sinslab.fusion.feedback.FeedbackLayout`, zeroing those states. Fixes are
    extrapolated from their validity time to the filter epoch with the INS (antenna)
    velocity (at most ``kf_dt``).

    Latency: a fix valid at ``t`` arrives at ``fixes.arrive`` and is processed at the first
    epoch at or after it; the lag policy ``lag`` (:mod:`sinslab.fusion.lag`) says how a late
    one is applied: :class:`~sinslab.fusion.lag.ExactReprocessing` at its validity epoch,
    :class:`~sinslab.fusion.lag.OnArrival` on arrival as if it were valid then (the naive
    filter), or any other policy (e.g. the stored-state update of
    :mod:`sinslab.methods.doublestar`).

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
        IMU increments (with errors), N samples at ``dt``.
    init : sinslab.core.records.NavState
        Initial navigation state (IMU attitude) at the start: ``imu.t0``, or the end of
        sample ``ins.start - 1``.
    fixes : sinslab.fusion.spec.FixSpec
        The fixes (validity times inside the filter span), their σ, arrivals, the antenna
        lever arm (IMU -> antenna, IMU body axes [m]), outages and windows.
    P0 : array_like, shape (n, n)
        Initial covariance of the error state.
    model : sinslab.nav.errstate.ErrorModel
        Error-state model with blocks ``phi``, ``dv``, ``dp`` and optionally ``eps``
        (gyro bias, body), ``nabla`` (accel bias, body), ``kg``/``ka`` (scale factors),
        e.g. :func:`lc_model`, or the horizontal model of paper 003 (``dv``, ``dp`` of 2
        states; with ``ins.vertical="hold"``). A model with a lever-arm block
        (:func:`sinslab.nav.errstate.lever_arm`) named by ``fixes.lever_block`` estimates
        the antenna lever arm: the fixes then use
        :class:`~sinslab.fusion.measurements.LeverPositionFix`/``LeverVelocityFix`` and the
        block's states hold ``l_used − l_true`` [m].
    ins : sinslab.fusion.spec.InsSpec
        How the INS stream runs (subsamples, vertical channel, initial compensation, start).
    grid : sinslab.fusion.spec.FilterGrid
        Filter step, compiled stretch, model look-ahead and discretisation.
    lag : lag policy
        See above.
    feedback : bool or sinslab.fusion.feedback.FeedbackLayout
        Closed loop (``True``: every block of :meth:`FeedbackLayout.from_model`; or the
        layout of the states to feed back) or feed-forward (``False``: the INS runs free;
        ``x`` holds the estimated errors).
    aiding : sequence of measurement objects
        Further measurements of :mod:`sinslab.fusion.measurements` run beside the fixes
        (zero velocity / angular rate, non-holonomic constraints, odometer ...).
    history : sinslab.fusion.smoothing.History, optional
        Record the forward pass for smoothing.
    progress : bool
        Show a progress bar (on a terminal).
    label : str
        The progress bar's label.

    Returns
    -------
    LooselyCoupled
    """
    core = ins_core(imu, init, model, ins, grid, lag, feedback)
    fm = fix_measurement(core, fixes)
    r = core.run(P0, [fm.meas, *aiding], grid=grid, lag=lag, progress=progress, label=label, history=history)
    return fm.result(r)


def loosely_coupled_many(runs, P0, model, *, ins: InsSpec = InsSpec(), grid: FilterGrid = FilterGrid(),
                         lag=ExactReprocessing(), feedback=True, progress=False,
                         label="loosely coupled") -> list:
    """:func:`loosely_coupled` for the runs of a Monte Carlo campaign, in lockstep on the
    run axis of the fusion driver (:func:`sinslab.fusion.driver.run_many`).

    Parameters
    ----------
    runs : sequence of (imu, init, FixSpec) or (imu, init, FixSpec, InsSpec)
        Each run's IMU record, initial state and fixes (and its own INS spec, default
        ``ins``). The runs must share the filter grid and the epochs at which fixes arrive
        (fixes requested on one plan).
    P0, model, ins, grid, lag, feedback, progress, label
        As in :func:`loosely_coupled`, shared by the runs (no aiding, no history here).

    Returns
    -------
    list of LooselyCoupled
        One per run, each equal to :func:`loosely_coupled` on that run alone.
    """
    comp = []
    for k, run in enumerate(runs):
        if len(run) not in (3, 4):
            raise ValueError(f"run {k}: give (imu, init, fixes) or (imu, init, fixes, ins)")
        imu, init, fixes, *own = run
        core = ins_core(imu, init, model, own[0] if own else ins, grid, lag, feedback)
        comp.append((core, fix_measurement(core, fixes)))
    if not comp:
        raise ValueError("loosely_coupled_many needs at least one run")
    c0 = comp[0][0]
    rs = driver.run_many([driver.Lane((c.ins,), (f.meas,)) for c, f in comp], c0.model, P0, grid=grid,
                         feedback=c0.feedback, lag=lag, progress=progress, label=label)
    return [f.result(r) for (_, f), r in zip(comp, rs)]


@dataclass(frozen=True)
class InsCore:
    """One INS stream made ready for the driver (:func:`ins_core`): the model checked
    against it, the stream bound to the filter grid (epochs ``t_ep``) and the feedback
    layout (None: feed-forward)."""

    model: object
    ins: LiveStream
    feedback: object
    t_ep: np.ndarray
    imu: object

    def run(self, P0, measurements, *, grid: FilterGrid, lag=ExactReprocessing(), history=None,
            progress=False, label="aided"):
        """:func:`sinslab.fusion.driver.run` of the stream with ``measurements`` (in that
        order); returns the :class:`~sinslab.fusion.driver.DriverResult`."""
        return driver.run([self.ins], self.model, P0, list(measurements), grid=grid, feedback=self.feedback,
                          lag=lag, progress=progress, label=label, history=history)


def ins_core(imu, init, model, ins: InsSpec = InsSpec(), grid: FilterGrid = FilterGrid(),
             lag=ExactReprocessing(), feedback=True) -> InsCore:
    """The INS stream, the feedback layout and the model of one aided run. The specs are
    valid on their own; what is checked here is how they fit together (the model's
    blocks against the vertical channel, the lag policy)."""
    lay = model.layout
    names = list(lay.names)
    for req in ("phi", "dv", "dp"):
        if req not in names:
            raise ValueError(f"the model needs a {req!r} block (has {names})")
    s_vel, s_pos = lay.slice("dv"), lay.slice("dp")
    if ins.vertical == "free" and (s_pos.stop - s_pos.start != 3 or s_vel.stop - s_vel.start != 3):
        raise ValueError("the model needs the full core (3 velocity and 3 position errors) "
                         "unless the vertical channel is held (vertical='hold')")
    if feedback is True:
        fb = FeedbackLayout.from_model(lay)
    elif feedback is False or feedback is None:
        fb = None
    else:
        fb = feedback
    scaled = fb is not None and (fb.gyro_scale is not None or fb.accel_scale is not None)
    for a in ("on_arrival", "corrected_nav", "needs_model", "update"):
        if not hasattr(lag, a):
            raise ValueError(f"lag must be a lag policy of sinslab.fusion.lag, got {lag!r}")
    stream = LiveStream.of(imu, init, ins, scaled=scaled)
    T, t0, n_ep = stream.bind(grid.kf_dt)
    return InsCore(model, stream, fb, t0 + T * np.arange(n_ep + 1), imu)


@dataclass(frozen=True)
class FixMeasurement:
    """The fixes of one run as a measurement (``meas``) and what :meth:`result` needs to
    unpack the driver's record of them."""

    meas: object
    fix_t: np.ndarray
    n_z: int
    use_vel: bool

    def records(self, ap, mi=0):
        """The driver's record of the fixes (measurement ``mi`` of the run's
        :class:`~sinslab.fusion.observer.Applied` ``ap``): ``(fix_t, t_applied, fix_index,
        innovation (J, m), nis, innovation_sigma (J, m) or None)``."""
        k = np.flatnonzero(ap.measurement == mi)            # the fixes (aiding records left out)
        m_z = self.n_z + (3 if self.use_vel else 0)
        inn = np.array([ap.innovation[i] for i in k]).reshape(-1, m_z)
        sd = np.array([ap.innovation_sigma[i] for i in k]).reshape(-1, m_z) if ap.innovation_sigma else None
        return self.fix_t[ap.item[k]], ap.t_applied[k], ap.item[k], inn, ap.nis[k], sd

    def result(self, r) -> LooselyCoupled:
        fix_t, t_app, idx, inn, nis, sd = self.records(r.applied)
        scale = r.scale                         # made on each call: once
        return LooselyCoupled(r.t, r.nav[0], r.x, r.sigma, r.gyro_bias[0], r.accel_bias[0],
                              scale[0] if scale is not None else None, fix_t,
                              t_app, idx, inn, nis, r.layout, r.history, sd)


def fix_measurement(core: InsCore, fixes: FixSpec) -> FixMeasurement:
    """The fix measurement of a run: positions (stacked with velocities when given), the
    lever-arm forms when ``fixes.lever_block`` names the model's block estimating it;
    the fix times checked against the model and the core's filter grid."""
    return _fix_measurement(fixes, core.model.layout, core.t_ep[0], core.t_ep[-1], core.t_ep[1] - core.t_ep[0],
                            core.imu.t[-1])


def _fix_measurement(fixes: FixSpec, lay, t_first, t_last, T, t_imu_end) -> FixMeasurement:
    s_vel, s_pos = lay.slice("dv"), lay.slice("dp")
    n_pos = s_pos.stop - s_pos.start
    fix_t = fixes.t
    J = fix_t.size
    n_z = 3 if n_pos == 3 else 2
    if fixes.n_pos < n_z:
        raise ValueError(f"fix_pos must have shape ({J}, {n_z}) for {J} fix times, got {fixes.pos.shape}")
    use_vel = fixes.vel is not None
    if use_vel and s_vel.stop - s_vel.start != 3:
        raise ValueError("velocity fixes need a model with 3 velocity errors")
    if J and (fix_t[0] < t_first - 1e-9 or fix_t[-1] > t_last + 1e-9):
        tail = (f"; the grid is whole kf_dt = {T:g} s steps from the start, the IMU data end at "
                f"{t_imu_end:.3f} s: drop the {int(np.sum(fix_t > t_last + 1e-9))} fixes after "
                "the last step" if t_first - 1e-9 <= fix_t[0] <= t_last else "")
        raise ValueError(f"fix times {fix_t[0]:.3f}..{fix_t[-1]:.3f} s lie outside the filter grid "
                         f"{t_first:.3f}..{t_last:.3f} s{tail}")
    sched = dict(t_arrive=fixes.arrive, lever_arm=fixes.lever_arm, outages=fixes.outages,
                 windows=fixes.windows, robust=fixes.robust)
    sigma = fixes.sigma[:, :n_z]
    if fixes.lever_block is not None:
        meas = LeverPositionFix(fix_t, fixes.pos, sigma, lever_block=fixes.lever_block, **sched)
        if use_vel:
            meas = Stack(meas, LeverVelocityFix(fix_t, fixes.vel, fixes.vel_sigma, lever_block=fixes.lever_block,
                                                **sched))
    else:
        meas = PositionFix(fix_t, fixes.pos, sigma, **sched)
        if use_vel:
            meas = Stack(meas, VelocityFix(fix_t, fixes.vel, fixes.vel_sigma, **sched))
    return FixMeasurement(meas, fix_t, n_z, use_vel)


#: a correlated fix error below this [m] (RTK) is left to the fixes' white σ
FIX_ERROR_MIN = 0.3


@dataclass(frozen=True)
class FixSource:
    """Position (and velocity) fixes as the GNSS source of a recorded run
    (:class:`sinslab.fusion.aids.base.GnssSource`; loosely coupled): the fixes start the
    filter and are its measurement, with the σ floors, latency, robust weighting and lever
    arm of ``handling`` (:class:`sinslab.fusion.recorded_spec.FixHandling`). With
    ``handling.fix_error`` their time-correlated position error becomes states of the
    source (:meth:`prepare`)."""

    fixes: object
    handling: object
    #: (τ [s], σ correlated (3,) [m]) of the fix-error states, or None (set by :meth:`prepare`)
    fix_error: tuple | None = None
    #: what :meth:`prepare` found of the fixes' error ({"model", "source", "used", ...}), or None
    fix_error_info: dict | None = None
    #: σ floors of the fixes ((3,) north, east, up [m]; (3,) east, north, up [m/s]) measured
    #: from the innovations of an earlier pass (sinslab.fusion.fix_noise.innovation_noise), or None
    sigma_floor: tuple | None = None
    #: with ``handling.fix_noise = "innovations"``: the velocity σ floor (3,) east, north, up
    #: [m/s] of the fixes' velocity walk against their positions (set by :meth:`prepare`), or None
    walk_floor: np.ndarray | None = None
    #: what the velocity check (``handling.velocity_check``) found, or None (set by :meth:`prepare`)
    velocity_check_info: dict | None = None
    name = "fixes"

    def start_fixes(self):
        return self.fixes

    def prepare(self, fixes):
        """``(fixes, source)``: the fixes' time-correlated errors taken into account
        (:meth:`_lasting_errors`) and, with ``handling.fix_noise = "innovations"``, the
        velocity σ floor of their measured velocity walk
        (:func:`sinslab.fusion.fix_noise.velocity_walk_sigma`: the part of a lasting velocity
        error a filter that follows its fixes absorbs and its innovations cannot show)."""
        import dataclasses
        fixes, source = self._lasting_errors(fixes)
        h = self.handling
        if h.velocity_check is not None and h.use_velocity and fixes.vel is not None:
            fixes, source = source._velocity_check(fixes)
        if h.fix_noise == "innovations" and h.use_velocity and fixes.vel is not None:
            from sinslab.fusion.fix_noise import velocity_walk_sigma
            source = dataclasses.replace(source, walk_floor=velocity_walk_sigma(fixes))
        return fixes, source

    def _velocity_check(self, fixes):
        """``(fixes, source)``: each velocity fix's σ raised by the lasting error the
        position fixes over the window before it contradict
        (:func:`sinslab.fusion.fix_noise.velocity_check`); what it found in
        :attr:`velocity_check_info`."""
        import dataclasses
        from sinslab.fusion.fix_noise import velocity_check
        got = velocity_check(fixes, self.handling.velocity_check)
        if got is None:
            return fixes, self
        sv, d, scatter = got
        stated = np.broadcast_to(np.asarray(0.0 if fixes.sigma_vel is None else fixes.sigma_vel, float), sv.shape)
        info = {"window_s": float(self.handling.velocity_check), "sigma_stated_median": np.median(stated, 0).tolist(),
                "sigma_median": np.median(sv, 0).tolist(), "sigma_p99": np.percentile(sv, 99, 0).tolist(),
                "sigma_max": np.max(sv, 0).tolist(),
                "mean_error_rms": np.sqrt(np.mean(d ** 2, 0)).tolist(), "scatter": scatter.tolist(),
                "raised_fraction": float(np.mean(np.any(sv > stated * (1 + 1e-9), axis=1)))}
        return dataclasses.replace(fixes, sigma_vel=sv), dataclasses.replace(self, velocity_check_info=info)

    def _lasting_errors(self, fixes):
        """``(fixes, source)``: the fixes' time-correlated errors taken into account
        (``handling.fix_error``; "auto": measured from the record by
        :func:`sinslab.fusion.fix_noise.fix_error_model`; a model or tuple: given, see
        :func:`sinslab.fusion.fix_noise.given_fix_error`).

        - Velocity: a Doppler velocity's error lasts seconds, so successive fixes do not
          average it; each fix's σ is at least the white noise that carries the same
          information as the measured random walk of its integral (``q_v / h`` for fixes
          ``h`` apart).
        - Position: a correlated part (measured: of at least :data:`FIX_ERROR_MIN` lasting
          more than three fix intervals; given: as given) becomes Gauss–Markov states, and the fixes' σ their white part
          (at least the floor): the filter no longer averages metres of correlated error away.
        """
        import dataclasses
        from sinslab.fusion.fix_noise import fix_error_model, given_fix_error
        spec = self.handling.fix_error
        if spec is None:
            return fixes, self
        if isinstance(spec, str) and spec == "auto":
            m = fix_error_model(fixes)
            if m is None:
                return fixes, dataclasses.replace(self, fix_error_info={"used": False, "model": None})
            info = {"model": m.describe(), "source": "measured from the record"}
        else:
            m = given_fix_error(spec)
            info = {"model": m.describe(), "source": "given"}
        h = float(np.median(np.diff(fixes.t)))
        floor = m.velocity_floor(h)
        if fixes.sigma_vel is not None and floor is not None:
            sv = np.maximum(fixes.sigma_vel, floor)
            info["velocity_sigma"] = np.median(sv, 0).tolist()
            fixes = dataclasses.replace(fixes, sigma_vel=sv)
        # a model given by hand is used as given; a measured one where it is metre-level and lasts
        info["used"] = info["source"] == "given" or bool(float(np.max(m.correlated)) >= FIX_ERROR_MIN
                                                         and m.tau >= 3 * h)
        if not info["used"]:
            return fixes, dataclasses.replace(self, fix_error_info=info)
        return self._white(fixes, m.white), dataclasses.replace(self, fix_error=(m.tau, m.correlated),
                                                                fix_error_info=info)

    def _white(self, fixes, white):
        import dataclasses
        w = np.maximum(np.asarray(white, float)[[1, 0, 2]], self.handling.pos_sigma_floor)     # north, east, up
        return dataclasses.replace(fixes, sigma=np.tile(w, (len(fixes), 1)))

    def states(self):
        if self.fix_error is None:
            return ()
        from sinslab.fusion.aids.base import State
        tau, corr = self.fix_error
        return (State(es.fix_position_error(tau=tau, sigma=corr), np.maximum(corr, 1e-3)),)

    def plan(self, setup, fixes, lever_block):
        from sinslab.fusion.aids.base import Plan
        from sinslab.fusion.recorded_start import fix_velocity
        h = self.handling
        use_vel = h.use_velocity and fixes.vel is not None
        pf, vf = self.sigma_floor if self.sigma_floor is not None else (0.0, 0.0)
        if self.walk_floor is not None:
            vf = np.maximum(vf, self.walk_floor)
        spec = FixSpec(fixes.t, np.stack([fixes.lat, fixes.lon, fixes.h], -1),
                       np.maximum(np.maximum(fixes.sigma, h.pos_sigma_floor), pf),
                       vel=fix_velocity(fixes) if use_vel else None,
                       vel_sigma=np.maximum(np.maximum(fixes.sigma_vel, h.vel_sigma_floor), vf) if use_vel else None,
                       latency=h.fix_latency, lever_arm=setup.lever_arm, outages=setup.outages,
                       lever_block=lever_block, robust=h.robust)
        fm = _fix_measurement(spec, setup.layout, setup.t_start, setup.t_end, setup.T, float(setup.imu.t[-1]))
        return Plan((("fixes", fm.meas),), {"fix": fm, "spec": spec})

    def report(self, plan, run):
        from sinslab.fusion.aids.base import SourceReport
        fix_t, _, idx, inn, nis, sd = plan.facts["fix"].records(run.applied["fixes"])
        spec = plan.facts["spec"]
        sg = spec.sigma[idx, :plan.facts["fix"].n_z]
        if spec.vel is not None:
            sg = np.hstack([sg, spec.vel_sigma[idx]])
        metrics = {"n_fixes_used": int(fix_t.size), "nis_mean": float(np.mean(nis)) if nis.size else None}
        if self.walk_floor is not None:
            metrics["fix_noise_velocity_walk_sigma"] = self.walk_floor.tolist()
        notes = ()
        vc = self.velocity_check_info
        if vc is not None:
            from sinslab.fusion.fix_noise import VELOCITY_CHECK_SIGMAS
            fmt = lambda a: ", ".join(f"{x:.3g}" for x in a)  # noqa: E731
            metrics.update({f"fix_velocity_check_{k}": v for k, v in vc.items()})
            notes += (f"Velocity fixes checked against the positions over {vc['window_s']:g} s: the error they "
                      f"contradict {fmt(vc['mean_error_rms'])} m/s RMS (vE, vN, vU; robust scatter "
                      f"{fmt(vc['scatter'])}); {100 * vc['raised_fraction']:.1f} % of the fixes past "
                      f"{VELOCITY_CHECK_SIGMAS:g}× the scatter, their σ (stated "
                      f"{fmt(vc['sigma_stated_median'])}) raised to median {fmt(vc['sigma_median'])}, 99th percentile "
                      f"{fmt(vc['sigma_p99'])}, largest {fmt(vc['sigma_max'])} m/s.",)
        fe = self.fix_error_info
        if fe is not None:
            notes += (f"Fix errors that last: {fe['model'] or 'no correlated error found'}"
                      + (f" ({fe['source']})" if fe.get("source") else "")
                      + ("; taken as Gauss–Markov states" if fe["used"] else "; the fixes stay white") + ".",)
        return SourceReport(self.name, "position/velocity fixes", metrics=metrics, notes=notes,
                            coupling="loosely coupled", fix_records=(fix_t, inn, sd, nis), reference="fixes",
                            fix_sigma=sg)
