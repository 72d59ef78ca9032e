"""Loosely coupled INS + position/velocity fixes: the error model and the composition of
the fusion driver that runs it (:func:`loosely_coupled`).

One live INS stream (:class:`sinslab.fusion.driver.LiveStream`), the error model of
:mod:`sinslab.nav.errstate` (φ, δv, δp, gyro bias ε, accelerometer bias ∇, optional
gyro/accel scale factors; bias random walks, :func:`lc_model`) and one measurement, the
antenna position (:class:`~sinslab.fusion.measurements.PositionFix`, stacked with a
:class:`~sinslab.fusion.measurements.VelocityFix` when velocities are given), run by
:func:`sinslab.fusion.driver.run` with feedback (closed loop) or feed-forward. Fixes are
extrapolated from their validity time to the filter epoch with the INS velocity (at most ``kf_dt``). A fix valid at t arrives at t + latency;
``lag="aware"`` applies it at its validity epoch, ``lag="ignore"`` on arrival as if current.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sinslab.fusion import driver
from sinslab.fusion.driver import LiveStream
from sinslab.fusion.feedback import FeedbackLayout
from sinslab.fusion.lag import ExactReprocessing, OnArrival
from sinslab.fusion.measurements import (LeverPositionFix, LeverVelocityFix, PositionFix, Stack,
                                         VelocityFix)
from sinslab.nav import errstate as es

__all__ = ["loosely_coupled", "loosely_coupled_many", "LooselyCoupled", "lc_model"]


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
    return es.ErrorModel("full", sensors, gyro_noise=gyro_arw, accel_noise=accel_vrw)


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


def loosely_coupled(imu, init, fix_t, fix_pos, fix_sigma, P0, *, model=None, gyro_arw=None,
                    accel_vrw=None, fix_vel=None, vel_sigma=None, lever_arm=None,
                    fix_lag=0.0, fix_arrive=None, lag="aware", lag_method="exact",
                    outages=(), windows=None, kf_dt=0.1, nsub=2, feedback=True,
                    vertical="free", height=None, gyro_bias=None, accel_bias=None, start=0,
                    t_start=None, max_block=10.0, model_every=10.0, discretization="series",
                    aiding=(), progress=True, label="loosely coupled", history=None) -> LooselyCoupled:
    """INS + position(/velocity) fixes with an error-state Kalman filter, on the fusion
    driver (:func:`sinslab.fusion.driver.run`, whose notes derive the loop).

    The strapdown mechanization (:func:`sinslab.nav.strapdown.step`) runs on the IMU stream
    in compiled blocks between the epochs at which fixes are processed; the error-state
    model is evaluated for all filter epochs of a block at once and discretised
    (:func:`sinslab.estimation.kalman.discretize`); the covariance is propagated every
    ``kf_dt`` by one :class:`sinslab.estimation.filter.KalmanFilter`. At a fix the filter
    updates (position, with the lever arm in H, and velocity when given) and, with
    ``feedback=True``, corrects the navigation state (:func:`sinslab.nav.strapdown.correct`)
    and the sensor compensation (biases, scale factors) through
    :class:`sinslab.fusion.feedback.FeedbackLayout`, zeroing those states. Fixes are extrapolated from their validity time to the filter epoch with the
    INS (antenna) velocity (at most ``kf_dt``).

    Latency: a fix valid at ``t`` arrives at ``fix_arrive`` (default ``t + fix_lag``) and
    is processed at the first epoch at or after it. ``lag="aware"`` applies it at its
    validity epoch with the lag policy ``lag_method`` (``"exact"``:
    :class:`sinslab.fusion.lag.ExactReprocessing`, measurement from the INS output of that
    epoch before its feedback; or any lag policy object, e.g. the stored-state update of
    :mod:`sinslab.methods.doublestar`); ``lag="ignore"`` applies a late fix on arrival as if it were valid
    then (the naive filter).

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
        IMU increments (with errors), N samples at ``dt``.
    init : sinslab.core.records.NavState
        Initial navigation state (IMU attitude) at the start: ``imu.t0``, or the end of
        sample ``start - 1``.
    fix_t : array_like, shape (J,)
        Validity times of the fixes [s], increasing, inside the filter span.
    fix_pos : array_like, shape (J, 3) or (J, 2)
        Fix positions ``[lat, lon, h]`` [rad, rad, m] of the antenna; ``(J, 2)`` (no
        height) only for a model with a 2-state horizontal position block.
    fix_sigma : array_like, shape (3,), (2,), (J, 3) or (J, 2)
        Fix standard deviations north, east[, up] [m].
    P0 : array_like, shape (n, n)
        Initial covariance of the error state.
    model : sinslab.nav.errstate.ErrorModel, optional
        Error-state model with blocks ``phi``, ``dv``, ``dp`` and optionally ``eps``
        (gyro bias, body), ``nabla`` (accel bias, body), ``kg``/``ka`` (scale factors),
        or the horizontal model of paper 003 (``dv``, ``dp`` of 2 states; give
        ``vertical="hold"``). Default :func:`lc_model` (``gyro_arw`` [rad/√s],
        ``accel_vrw`` [m/s/√s] needed).
    fix_vel, vel_sigma : array_like, shape (J, 3), optional
        Fix (antenna) velocities ENU [m/s] and their σ (J, 3) or (3,) [m/s].
    lever_arm : array_like (3,), optional
        IMU -> antenna in IMU body axes [m].
    fix_lag, fix_arrive, lag, lag_method
        Latency, see above (``lag_method``: ``"exact"`` or a lag policy object).
    outages : sequence of (start, length) [s]
        Fixes valid inside are dropped.
    windows : sequence of (start, end) [s], optional
        Fixes are processed only at epochs inside these windows (others are dropped).
    kf_dt : float
        Filter step [s]; a multiple of ``nsub * imu.dt``.
    nsub : int
        Mechanization subsamples (coning/sculling).
    feedback : bool or sinslab.fusion.feedback.FeedbackLayout
        Closed loop (``True``: every block of :meth:`FeedbackLayout.from_model`; or the
        layout of the states to feed back) or feed-forward (``False``: the INS runs free;
        ``x`` holds the estimated errors).
    vertical : {"free", "hold"}
        ``"hold"``: the vertical channel is held to ``height`` (N+1,) or float [m] at the
        IMU epochs (for models without a vertical channel).
    gyro_bias, accel_bias : array_like (3,), optional
        Initial sensor compensation [rad/s], [m/s²].
    start : int
        First IMU sample used (the filter starts at the end of sample ``start - 1``).
    t_start : float, optional
        Start time [s] if not that end time (e.g. ``imu.t[start] - imu.dt``).
    max_block : float
        Longest stretch [s] the INS is run in one compiled call when no fix arrives.
    model_every : float
        The error model F, G (and Φ, Q_k) is evaluated for all filter epochs of the next
        ``model_every`` seconds at once, along a look-ahead run of the INS from the current
        (corrected) state; the linearisation point then differs from the corrected path
        only by the feedback applied within that stretch (metres and arc-seconds with
        1 Hz fixes). ``model_every <= kf_dt`` evaluates it on the corrected path exactly
        (slower).
    discretization : {"series", "vanloan"}
        Φ, Q_k of each step from F, G frozen at the epoch.
    aiding : sequence of measurement objects
        Further measurements of :mod:`sinslab.fusion.measurements` run beside the fixes
        (zero velocity / angular rate, non-holonomic constraints, odometer ...). A model
        with a lever-arm block ``lev`` (:func:`sinslab.nav.errstate.lever_arm`) estimates the
        antenna lever arm: the fixes then use
        :class:`~sinslab.fusion.measurements.LeverPositionFix`/``LeverVelocityFix`` and
        ``x[:, lev]`` holds ``l_used − l_true`` [m].
    progress : bool
        Show a progress bar (on a terminal).
    history : sinslab.fusion.smoothing.History, optional
        Record the forward pass for smoothing.

    Returns
    -------
    LooselyCoupled
    """
    c = _compose(imu, init, fix_t, fix_pos, fix_sigma, model=model, gyro_arw=gyro_arw,
                 accel_vrw=accel_vrw, fix_vel=fix_vel, vel_sigma=vel_sigma, lever_arm=lever_arm,
                 fix_lag=fix_lag, fix_arrive=fix_arrive, lag=lag, lag_method=lag_method,
                 outages=outages, windows=windows, kf_dt=kf_dt, nsub=nsub, feedback=feedback,
                 vertical=vertical, height=height, gyro_bias=gyro_bias, accel_bias=accel_bias,
                 start=start, t_start=t_start)
    r = driver.run([c.ins], c.model, P0, [c.meas, *aiding], kf_dt=kf_dt, feedback=c.feedback,
                   lag=c.policy, max_block=max_block, model_every=model_every,
                   discretization=discretization, progress=progress, label=label, history=history)
    return c.result(r)


#: The arguments of :func:`loosely_coupled` that differ between the runs of
#: :func:`loosely_coupled_many` (the data of each run); all others are shared.
PER_RUN = ("imu", "init", "fix_t", "fix_pos", "fix_sigma", "fix_vel", "vel_sigma", "fix_arrive",
           "gyro_bias", "accel_bias")


def loosely_coupled_many(runs, P0, *, kf_dt=0.1, max_block=10.0, model_every=10.0,
                         discretization="series", progress=False, label="loosely coupled",
                         **shared) -> list:
    """:func:`loosely_coupled` for the runs of a Monte Carlo campaign, in lockstep on the
    run axis of the fusion driver (:func:`sinslab.fusion.driver.run_many`).

    Parameters
    ----------
    runs : sequence of dict
        Per run the arguments of :data:`PER_RUN` (``imu``, ``init``, ``fix_t``,
        ``fix_pos``, ``fix_sigma`` required; ``fix_vel``, ``vel_sigma``, ``fix_arrive``,
        ``gyro_bias``, ``accel_bias`` optional). The runs must share the filter grid and
        the epochs at which fixes arrive (fixes requested on one plan).
    P0, kf_dt, max_block, model_every, discretization, progress, label
        As in :func:`loosely_coupled`.
    **shared
        The other keyword arguments of :func:`loosely_coupled` (``model``, ``lag``,
        ``lag_method``, ``windows``, ``feedback``, ``vertical``, ``height``, ...), the
        same for every run; ``aiding`` and ``history`` are not available here.

    Returns
    -------
    list of LooselyCoupled
        One per run, each equal to :func:`loosely_coupled` on that run alone.
    """
    bad = sorted(set(shared) & (set(PER_RUN) | {"aiding", "history"}))
    if bad:
        raise ValueError(f"loosely_coupled_many: {', '.join(bad)} belong in the runs "
                         "(or are not available for a campaign)")
    comp = []
    for k, run in enumerate(runs):
        extra = sorted(set(run) - set(PER_RUN))
        if extra:
            raise ValueError(f"run {k}: unknown per-run argument(s) {', '.join(extra)}; "
                             f"a run gives {', '.join(PER_RUN)}")
        args = dict(run)
        comp.append(_compose(args.pop("imu"), args.pop("init"), args.pop("fix_t"), args.pop("fix_pos"),
                             args.pop("fix_sigma"), kf_dt=kf_dt, **shared, **args))
    if not comp:
        raise ValueError("loosely_coupled_many needs at least one run")
    c0 = comp[0]
    rs = driver.run_many([driver.Lane((c.ins,), (c.meas,)) for c in comp], c0.model, P0, kf_dt=kf_dt,
                         feedback=c0.feedback, lag=c0.policy, max_block=max_block,
                         model_every=model_every, discretization=discretization, progress=progress,
                         label=label)
    return [c.result(r) for c, r in zip(comp, rs)]


@dataclass(frozen=True)
class _Composed:
    """One run made ready for the driver: the model, the INS stream, the fix measurement,
    the feedback layout and lag policy, and what :meth:`result` needs to unpack its output."""

    model: object
    ins: LiveStream
    meas: object
    feedback: object
    policy: object
    fix_t: np.ndarray
    n_z: int
    use_vel: bool

    def result(self, r) -> LooselyCoupled:
        ap = r.applied
        k = np.flatnonzero(ap.measurement == 0)            # the fixes (aiding records left out)
        m_z = self.n_z + (3 if self.use_vel else 0)
        inn = np.array([ap.innovation[i] for i in k]).reshape(-1, m_z)
        sd = np.array([ap.innovation_sigma[i] for i in k]).reshape(-1, m_z) if ap.innovation_sigma else None
        return LooselyCoupled(r.t, r.nav[0], r.x, r.sigma, r.gyro_bias[0], r.accel_bias[0],
                              r.scale[0] if r.scale is not None else None, self.fix_t[ap.item[k]],
                              ap.t_applied[k], ap.item[k], inn, ap.nis[k], r.layout, r.history, sd)


def _compose(imu, init, fix_t, fix_pos, fix_sigma, *, model=None, gyro_arw=None, accel_vrw=None,
             fix_vel=None, vel_sigma=None, lever_arm=None, fix_lag=0.0, fix_arrive=None,
             lag="aware", lag_method="exact", outages=(), windows=None, kf_dt=0.1, nsub=2,
             feedback=True, vertical="free", height=None, gyro_bias=None, accel_bias=None,
             start=0, t_start=None) -> _Composed:
    """Check the arguments of :func:`loosely_coupled` and make the stream, the fix
    measurement, the feedback layout and the lag policy of one run."""
    # --- model and layout
    if model is None:
        if gyro_arw is None or accel_vrw is None:
            raise ValueError("give a model or gyro_arw [rad/sqrt(s)] and accel_vrw [m/s/sqrt(s)]")
        model = lc_model(gyro_arw, accel_vrw)
    lay = model.layout
    names = list(lay.names)
    for req in ("phi", "dv", "dp"):
        if req not in names:
            raise ValueError(f"the model needs a {req!r} block (has {names})")
    s_vel, s_pos = lay.slice("dv"), lay.slice("dp")
    n_pos = s_pos.stop - s_pos.start
    if vertical not in ("free", "hold"):
        raise ValueError(f"vertical must be 'free' or 'hold', got {vertical!r}")
    if vertical == "free" and (n_pos != 3 or s_vel.stop - s_vel.start != 3):
        raise ValueError("the model needs the full core (3 velocity and 3 position errors) "
                         "unless the vertical channel is held (vertical='hold')")
    if feedback is True:
        fb = FeedbackLayout.from_model(lay)
    elif feedback is False or feedback is None:
        fb = None
    else:
        fb = feedback
    scaled = fb is not None and (fb.gyro_scale is not None or fb.accel_scale is not None)
    if lag not in ("aware", "ignore"):
        raise ValueError(f"lag must be 'aware' or 'ignore', got {lag!r}")
    if isinstance(lag_method, str):
        if lag_method != "exact":
            raise ValueError(f"lag_method must be 'exact' or a lag policy object, got {lag_method!r}")
        policy = ExactReprocessing()
    else:
        policy = lag_method
    if lag == "ignore":
        policy = OnArrival()

    # --- the INS stream on the filter grid
    ins = LiveStream(imu, init, nsub=nsub, vertical=vertical, height=height, gyro_bias=gyro_bias,
                     accel_bias=accel_bias, scaled=scaled, start=start, t_start=t_start)
    T, t0, n_ep = ins.bind(kf_dt)
    t_ep = t0 + T * np.arange(n_ep + 1)

    # --- fixes
    fix_t = np.atleast_1d(np.asarray(fix_t, dtype=float))
    J = fix_t.size
    fix_pos = np.asarray(fix_pos, dtype=float)
    n_z = 3 if n_pos == 3 else 2
    if fix_pos.ndim != 2 or fix_pos.shape[0] != J or fix_pos.shape[1] not in (2, 3) or fix_pos.shape[1] < n_z:
        raise ValueError(f"fix_pos must have shape ({J}, {n_z}) for {J} fix times, got {fix_pos.shape}")
    fix_sigma = np.asarray(fix_sigma, dtype=float)
    fix_sigma = np.broadcast_to(fix_sigma, (J, fix_sigma.shape[-1]))[:, :n_z]
    use_vel = fix_vel is not None
    if use_vel:
        if s_vel.stop - s_vel.start != 3:
            raise ValueError("velocity fixes need a model with 3 velocity errors")
        fix_vel = np.asarray(fix_vel, dtype=float).reshape(J, 3)
        vel_sigma = np.broadcast_to(np.asarray(vel_sigma, dtype=float), (J, 3))
    arrive = fix_t + float(fix_lag) if fix_arrive is None else np.asarray(fix_arrive, dtype=float)
    if J:
        if not (np.all(np.isfinite(fix_t)) and np.all(np.isfinite(fix_pos[:, :n_z]))):
            raise ValueError("fix times/positions contain NaN/inf")
        if np.any(np.diff(fix_t) <= 0):
            raise ValueError("fix times must be strictly increasing")
        if fix_t[0] < t_ep[0] - 1e-9 or fix_t[-1] > t_ep[-1] + 1e-9:
            tail = (f"; the grid is whole kf_dt = {T:g} s steps from the start, the IMU data end at "
                    f"{imu.t[-1]:.3f} s: drop the {int(np.sum(fix_t > t_ep[-1] + 1e-9))} fixes after "
                    "the last step" if t_ep[0] - 1e-9 <= fix_t[0] <= t_ep[-1] else "")
            raise ValueError(f"fix times {fix_t[0]:.3f}..{fix_t[-1]:.3f} s lie outside the filter grid "
                             f"{t_ep[0]:.3f}..{t_ep[-1]:.3f} s{tail}")
        if np.any(~(fix_sigma > 0)) or (use_vel and np.any(~(vel_sigma > 0))):
            raise ValueError("fix_sigma and vel_sigma must be > 0")
        if arrive.shape != (J,) or np.any(~(arrive >= fix_t)):
            raise ValueError("fix arrival times must not precede the validity times (fix_lag >= 0)")
    sched = dict(t_arrive=arrive, lever_arm=lever_arm, outages=outages, windows=windows)
    if "lev" in names:
        lev = dict(sched, lever_arm=np.zeros(3) if lever_arm is None else lever_arm)
        meas = LeverPositionFix(fix_t, fix_pos, fix_sigma, **lev)
        if use_vel:
            meas = Stack(meas, LeverVelocityFix(fix_t, fix_vel, vel_sigma, **lev))
    else:
        meas = PositionFix(fix_t, fix_pos, fix_sigma, **sched)
        if use_vel:
            meas = Stack(meas, VelocityFix(fix_t, fix_vel, vel_sigma, **sched))

    return _Composed(model, ins, meas, fb, policy, fix_t, n_z, use_vel)
