"""Loosely coupled INS + position/velocity fixes: the driver, and recorded data (``sinslab navigate``).

The pipeline
------------
1. **Initial attitude from the data.** Levelling from the mean specific force of the
   stationary stretch at the start of the record (fix speed below ``static_speed``);
   the mean gyro output there (minus the Earth-rate vertical component) is the initial
   gyro-bias estimate (MEMS biases are hundreds of °/h, 40x the Earth rate, so
   gyrocompassing is impossible and the rest is used to calibrate instead). Heading:
   given (``heading``), or taken from the fix velocity once the vehicle moves faster than
   ``move_speed`` (the INS attitude is propagated from the levelled start by the gyros
   and rotated about the vertical so that the body forward axis points along the fix
   course; a car does not drive sideways). The filter starts there.
2. **Filter** (:func:`loosely_coupled`, sinslab's one INS + fix driver, also used by
   :func:`sinslab.methods.doublestar.integrate` and ``benchmarks/estimation.py``). The compiled
   mechanization (:func:`sinslab.nav.strapdown.step`) runs in blocks between fix arrivals;
   the error model of :mod:`sinslab.nav.errstate` (φ, δv, δp, gyro bias ε, accelerometer
   bias ∇, optional gyro/accel scale factors; bias random walks, :func:`lc_model`) is
   evaluated for the block's epochs (on the block's own rows, or along a look-ahead run
   for speed) and discretised; the :class:`sinslab.estimation.kalman.KalmanFilter` predicts every
   ``kf_dt`` and is updated with the antenna position (and velocity, when the fix file
   has it) with the lever arm in H, then fed back (closed loop) through
   :class:`sinslab.estimation.kalman.FeedbackLayout`. Fixes are extrapolated from their validity
   time to the filter epoch with the INS velocity (at most ``kf_dt``).
3. **Outages and latency.** Fixes whose validity time lies in an outage are dropped
   (``windows``: fixes are processed only inside them). A fix valid at t arrives at
   t + latency; ``lag="aware"`` applies it at its validity epoch with
   :meth:`KalmanFilter.update_lagged` (exact re-processing, the INS output of that epoch
   taken from the driver's navigation history; or paper 003's one-step form),
   ``lag="ignore"`` applies it on arrival as if current (the naive filter).

:func:`navigate_recorded` is the recorded-data front end: initial attitude from the data
(step 1), the model and P0 from :class:`NavOptions`, then :func:`loosely_coupled`.

Evaluation: :func:`fix_errors` compares the solution (antenna point) with every fix,
used or not; :func:`outage_end_errors` takes the horizontal error at the last fix of each
outage.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.core import units
from sinslab.data.io import Fixes
from sinslab.core.records import ImuRecord, NavState

__all__ = ["loosely_coupled", "LooselyCoupled", "lc_model", "NavOptions", "RecordedNav",
           "navigate_recorded", "parse_outages", "periodic_outages", "fix_errors",
           "outage_end_errors", "level_from_rest", "leveled_start"]


@dataclass
class NavOptions:
    """Settings of :func:`navigate_recorded` (SI units)."""

    lever_arm: tuple = (0.0, 0.0, 0.0)      #: IMU -> antenna, vehicle RFU axes [m]
    outages: tuple = ()                     #: ((start, length), ...) absolute times [s]
    fix_latency: float = 0.0                #: [s]
    lag: str = "aware"                      #: "aware" | "ignore"
    heading: float | None = None            #: initial heading, clockwise from north [rad]
    use_velocity: bool = True
    gyro_arw: float = 0.0038 * units.deg    #: [rad/sqrt(s)] (0.0038 deg/s/sqrt(Hz))
    accel_vrw: float = 70 * units.ug        #: [m/s/sqrt(s)]
    gyro_rrw: float = 3.8e-5 * units.deg * 2   #: gyro bias random walk [rad/s/sqrt(s)]
    accel_rrw: float = 7 * units.ug * 4     #: accel bias random walk [m/s^2/sqrt(s)]
    gyro_bias_sigma: float = 0.05 * units.deg   #: initial 1σ [rad/s] (after rest calibration)
    accel_bias_sigma: float = 0.2           #: initial 1σ [m/s^2]
    scale_factors: bool = False
    scale_sigma: float = 0.01               #: initial 1σ of scale-factor states [-]
    att_sigma: tuple = (1.0 * units.deg, 1.0 * units.deg, 5.0 * units.deg)  #: φE φN φU
    pos_sigma_floor: float = 0.05           #: fix σ floor [m] (timing, antenna phase centre)
    vel_sigma_floor: float = 0.05           #: [m/s]
    static_speed: float = 0.05              #: [m/s] below it the vehicle is at rest
    move_speed: float = 2.0                 #: [m/s] heading from the fix course above it
    kf_dt: float = 0.02                     #: filter step [s]
    nsub: int = 2
    rest_bias: bool = True                  #: initial gyro bias from the initial rest
    rest_noise: bool = True                 #: white noise per axis from the initial rest
    #: (sample scatter at rest × sqrt(dt), floored at gyro_arw/accel_vrw: engine vibration
    #: in a car is far above a datasheet's noise density)

    def check(self):
        la = np.asarray(self.lever_arm, dtype=float)
        if la.shape != (3,) or not np.all(np.isfinite(la)):
            raise ValueError(f"lever arm must be 3 finite numbers [m], got {self.lever_arm!r}")
        if self.lag not in ("aware", "ignore"):
            raise ValueError(f"lag must be 'aware' or 'ignore', got {self.lag!r}")
        if not (self.fix_latency >= 0 and math.isfinite(self.fix_latency)):
            raise ValueError(f"fix latency must be >= 0 s, got {self.fix_latency}")
        for o in self.outages:
            s, ln = (o[2], o[1]) if o[0] == "periodic" else o
            if not (ln > 0 and math.isfinite(s)):
                raise ValueError(f"outage {s}:{ln}: length must be > 0")


@dataclass
class RecordedNav:
    """Result of :func:`navigate_recorded` at the filter epochs (every ``kf_dt``)."""

    t: np.ndarray                  #: (M,) [s]
    nav: np.ndarray                #: (M, 10) [q0..q3, vE, vN, vU, lat, lon, h] after feedback
    sigma: np.ndarray              #: (M, n) filter σ
    labels: tuple                  #: state labels
    units_: tuple                  #: display units of the states
    gyro_bias: np.ndarray          #: (M, 3) compensation in use [rad/s]
    accel_bias: np.ndarray         #: (M, 3) [m/s^2]
    scale: np.ndarray | None       #: (M, 6) gyro, accel scale-factor compensation [-]
    fix_t: np.ndarray              #: (J,) validity times of the applied fixes
    innovation: np.ndarray         #: (J, m)
    nis: np.ndarray                #: (J,)
    init: dict = field(default_factory=dict)
    options: NavOptions = None

    @property
    def att(self):
        """(M, 3) ``[pitch, roll, yaw]`` [rad] of the vehicle body (mount applied on input)."""
        return A.quat_to_euler(self.nav[:, :4])

    @property
    def heading(self):
        """(M,) heading clockwise from north [rad], 0..2π."""
        return np.mod(A.yaw_to_heading(self.att[:, 2]), 2 * np.pi)

    def sigma_of(self, block_prefix):
        idx = [i for i, l in enumerate(self.labels) if l.startswith(block_prefix)]
        return self.sigma[:, idx]


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


# ---------------------------------------------------------------------- initial state --
def level_from_rest(imu: ImuRecord, k0, k1, lat):
    """Pitch, roll [rad] and the gyro-bias estimate [rad/s] from samples ``k0:k1`` at rest."""
    f = imu.dv[k0:k1].sum(0) / ((k1 - k0) * imu.dt)
    w = imu.dtheta[k0:k1].sum(0) / ((k1 - k0) * imu.dt)
    pitch = math.atan2(f[1], math.hypot(f[0], f[2]))
    roll = math.atan2(-f[0], f[2])
    C = A.euler_to_dcm(np.array([pitch, roll, 0.0]))
    up_b = C.T @ np.array([0.0, 0.0, 1.0])
    w_bias = w - up_b * (E.WIE * math.sin(lat))       # horizontal Earth rate (<15 deg/h) kept
    return pitch, roll, w_bias, f


def leveled_start(imu, fixes: Fixes, opt: NavOptions):
    """Index range of the initial rest and levelling results (see module notes)."""
    sp = _fix_speed(fixes)
    moving = np.flatnonzero(sp > opt.static_speed)
    t_move = fixes.t[moving[0]] if moving.size else fixes.t[-1]
    k1 = int(np.searchsorted(imu.t, min(t_move, imu.t[0] + 120.0)))
    k0 = int(np.searchsorted(imu.t, max(imu.t0, fixes.t[0]) - 1e-9))
    if k1 - k0 < int(round(1.0 / imu.dt)):
        return None
    return k0, k1


def _fix_speed(fixes: Fixes):
    if fixes.vel is not None:
        return np.hypot(fixes.vel[:, 0], fixes.vel[:, 1])
    rm, rn = E.radii(fixes.lat, fixes.h)
    n = np.gradient(fixes.lat, fixes.t) * rm
    e = np.gradient(fixes.lon, fixes.t) * rn * np.cos(fixes.lat)
    return np.hypot(e, n)


def _fix_vel_enu(fixes: Fixes):
    if fixes.vel is not None:
        return fixes.vel
    rm, rn = E.radii(fixes.lat, fixes.h)
    return np.stack([np.gradient(fixes.lon, fixes.t) * rn * np.cos(fixes.lat),
                     np.gradient(fixes.lat, fixes.t) * rm, np.gradient(fixes.h, fixes.t)], -1)


def _interp_fix(fixes, t):
    lat = np.interp(t, fixes.t, fixes.lat)
    lon = np.interp(t, fixes.t, fixes.lon)
    h = np.interp(t, fixes.t, fixes.h)
    v = _fix_vel_enu(fixes)
    vel = np.array([np.interp(t, fixes.t, v[:, i]) for i in range(3)])
    return lat, lon, h, vel


def _imu_pos_from_antenna(lat, lon, h, C, lever):
    d = C @ lever                                      # ENU offset IMU -> antenna
    rm, rn = E.radii(lat, h)
    return lat - d[1] / float(rm), lon - d[0] / (float(rn) * math.cos(lat)), h - d[2]


# ------------------------------------------------------------------ the driver ---------
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
    from sinslab.nav import errstate as es
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


def _vec3_or(a):
    return np.zeros(3) if a is None else np.asarray(a, dtype=float).reshape(3).copy()


def loosely_coupled(imu, init, fix_t, fix_pos, fix_sigma, P0, *, model=None, gyro_arw=None,
                    accel_vrw=None, fix_vel=None, vel_sigma=None, lever_arm=None,
                    fix_lag=0.0, fix_arrive=None, lag="aware", lag_method="exact",
                    outages=(), windows=None, kf_dt=0.1, nsub=2, feedback=True,
                    vertical="free", height=None, gyro_bias=None, accel_bias=None, start=0,
                    t_start=None, max_block=10.0, model_every=10.0, discretization="series",
                    progress=True, label="loosely coupled") -> LooselyCoupled:
    """INS + position(/velocity) fixes with an error-state Kalman filter: sinslab's one
    driver of the filter beside the mechanization.

    The strapdown mechanization (:func:`sinslab.nav.strapdown.step`) runs on the IMU stream
    in compiled blocks between the epochs at which fixes are processed; the error-state
    model is evaluated for all filter epochs of a block at once and discretised
    (:func:`sinslab.nav.errstate.discretize`); the covariance is propagated every ``kf_dt`` by
    one :class:`sinslab.estimation.kalman.KalmanFilter`. At a fix the filter updates (position, with
    the lever arm in H, and velocity when given) and, with ``feedback=True``, corrects the
    navigation state (:func:`sinslab.nav.strapdown.correct`) and the sensor compensation
    (biases, scale factors) through :class:`sinslab.estimation.kalman.FeedbackLayout`, zeroing those
    states. Fixes are extrapolated from their validity time to the filter epoch with the
    INS (antenna) velocity (at most ``kf_dt``).

    Latency: a fix valid at ``t`` arrives at ``fix_arrive`` (default ``t + fix_lag``) and
    is processed at the first epoch at or after it. ``lag="aware"`` applies it at its
    validity epoch with :meth:`KalmanFilter.update_lagged` (``lag_method="exact"``:
    re-processing, measurement from the INS output of that epoch before its feedback;
    ``"paper003"``: the one-step form of paper 003, measurement from the corrected output
    of that epoch); ``lag="ignore"`` applies a late fix on arrival as if it were valid
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
        Latency, see above.
    outages : sequence of (start, length) [s]
        Fixes valid inside are dropped.
    windows : sequence of (start, end) [s], optional
        Fixes are processed only at epochs inside these windows (others are dropped).
    kf_dt : float
        Filter step [s]; a multiple of ``nsub * imu.dt``.
    nsub : int
        Mechanization subsamples (coning/sculling).
    feedback : bool or sinslab.estimation.kalman.FeedbackLayout
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
    progress : bool
        Show a progress bar (on a terminal).

    Returns
    -------
    LooselyCoupled
    """
    from sinslab.nav import errstate as es
    from sinslab.nav import strapdown as sd
    from sinslab.estimation.kalman import FeedbackLayout, KalmanFilter
    from sinslab.core.progress import progress as _progress

    # --- model and layout
    if model is None:
        if gyro_arw is None or accel_vrw is None:
            raise ValueError("give a model or gyro_arw [rad/sqrt(s)] and accel_vrw [m/s/sqrt(s)]")
        model = lc_model(gyro_arw, accel_vrw)
    lay = model.layout
    n = model.n
    names = list(lay.names)
    for req in ("phi", "dv", "dp"):
        if req not in names:
            raise ValueError(f"the model needs a {req!r} block (has {names})")
    s_att, s_vel, s_pos = lay.slice("phi"), lay.slice("dv"), lay.slice("dp")
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
    s_gb = lay.slice("eps") if "eps" in names else None
    s_kg = fb.gyro_scale if fb is not None else None
    s_ka = fb.accel_scale if fb is not None else None
    scaled = s_kg is not None or s_ka is not None
    if lag not in ("aware", "ignore"):
        raise ValueError(f"lag must be 'aware' or 'ignore', got {lag!r}")
    if lag_method not in ("exact", "paper003"):
        raise ValueError(f"lag_method must be 'exact' or 'paper003', got {lag_method!r}")

    # --- filter grid
    dt = imu.dt
    k_kf = int(round(kf_dt / dt))
    if k_kf < 1 or abs(k_kf * dt - kf_dt) > 1e-6 * kf_dt or k_kf % nsub:
        raise ValueError(f"kf_dt={kf_dt} s must be a multiple of nsub*dt = {nsub * dt} s")
    T = k_kf * dt
    start = int(start)
    n_ep = (len(imu) - start) // k_kf
    if n_ep < 1:
        raise ValueError(f"the IMU record ({len(imu) - start} samples) is shorter than one filter step")
    t0 = float(t_start) if t_start is not None else (float(imu.t[start - 1]) if start > 0 else imu.t0)
    t_ep = t0 + T * np.arange(n_ep + 1)
    t_rel = T * np.arange(n_ep + 1)              # filter clock (absolute stamps lose digits)
    if vertical == "hold":
        hgt = np.asarray(height, dtype=float)
        if hgt.ndim == 0:
            hgt = np.full(len(imu) + 1, float(hgt))
        if hgt.shape != (len(imu) + 1,):
            raise ValueError(f"height must have {len(imu) + 1} values (IMU epochs), got {hgt.shape}")
        vkw = dict(vertical="hold")
    else:
        hgt = None
        vkw = {}

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
            raise ValueError(f"fix times {fix_t[0]:.6g}..{fix_t[-1]:.6g} s lie outside the IMU data "
                             f"{t_ep[0]:.6g}..{t_ep[-1]:.6g} s")
        if np.any(~(fix_sigma > 0)) or (use_vel and np.any(~(vel_sigma > 0))):
            raise ValueError("fix_sigma and vel_sigma must be > 0")
        if arrive.shape != (J,) or np.any(~(arrive >= fix_t)):
            raise ValueError("fix arrival times must not precede the validity times (fix_lag >= 0)")
    lever = None if lever_arm is None else np.asarray(lever_arm, dtype=float).reshape(3)
    if lever is not None and not np.any(lever):
        lever = None
    e_valid = np.ceil((fix_t - t0) / T - 1e-6).astype(np.int64)     # epoch the fix is valid at
    e_arr = np.ceil((arrive - t0) / T - 1e-6).astype(np.int64)      # epoch it is processed at
    keep = e_arr <= n_ep
    for s, ln in outages:
        keep &= ~((fix_t >= s) & (fix_t < s + ln))
    if windows is not None:
        w = np.asarray(windows, dtype=float).reshape(-1, 2)
        te = t_ep[np.minimum(e_arr, n_ep)]
        keep &= ((te[:, None] >= w[:, 0] - 1e-9) & (te[:, None] <= w[:, 1] + 1e-9)).any(1)
    late = arrive > fix_t
    arrivals = {}
    for j in np.flatnonzero(keep):
        arrivals.setdefault(int(e_arr[j]), []).append(int(j))
    lagged = keep & (e_arr > e_valid) & (lag == "aware")
    hist = int(np.max(e_arr[lagged] - e_valid[lagged])) + 3 if lagged.any() else 0
    keep_F = lag_method == "paper003" and hist > 0

    # --- state, filter, histories
    state = sd.initial_state_array(init)
    filt = KalmanFilter(np.zeros(n), P0, t0=0.0, history=hist, check=False)
    gb = _vec3_or(gyro_bias)
    ab = _vec3_or(accel_bias)
    kg = np.zeros(3)
    ka = np.zeros(3)
    nav_h = np.empty((n_ep + 1, 10))
    nav_pre = np.empty((n_ep + 1, 10)) if hist else nav_h   # INS output before feedback
    w_h = np.empty((n_ep + 1, 3)) if hist else None          # compensated rate of the step to it
    x_h = np.zeros((n_ep + 1, n))
    sig_h = np.empty((n_ep + 1, n))
    gb_h = np.empty((n_ep + 1, 3))
    ab_h = np.empty((n_ep + 1, 3))
    sc_h = np.zeros((n_ep + 1, 6)) if scaled else None
    F_h = np.empty((n_ep, n, n)) if keep_F else None
    Qc_h = np.empty((n_ep, n, n)) if keep_F else None
    nav_h[0] = state[:10]
    nav_pre[0] = state[:10]
    sig_h[0] = filt.sigma
    gb_h[0], ab_h[0] = gb, ab
    n_use = n_ep * k_kf
    if not scaled:
        dth_sum = imu.dtheta[start:start + n_use].reshape(n_ep, k_kf, 3).sum(1)
        dv_sum = imu.dv[start:start + n_use].reshape(n_ep, k_kf, 3).sum(1)
    if hist:
        w_h[0] = imu.dtheta[start:start + k_kf].sum(0) / T - gb
    used, t_used, innov, nis = [], [], [], []
    stops = sorted(set(arrivals) | {n_ep})
    per = k_kf // nsub
    max_ep = max(1, int(round(max_block / T)))
    la_ep = max(1, int(round(model_every / T)))
    la_end = -1
    la0 = 0
    Phi_la = Q_la = None
    m_z = n_z + (3 if use_vel else 0)
    q = model.q

    def increments(e_a, e_b):
        """Compensated-scale increments of epochs e_a..e_b and their per-epoch mean rates."""
        a, b = start + e_a * k_kf, start + e_b * k_kf
        dth, dvb = imu.dtheta[a:b], imu.dv[a:b]
        if scaled:
            dth = dth * (1.0 - kg)
            dvb = dvb * (1.0 - ka)
            ws = dth.reshape(-1, k_kf, 3).sum(1) / T - gb
            fs = dvb.reshape(-1, k_kf, 3).sum(1) / T - ab
        else:
            ws = dth_sum[e_a:e_b] / T - gb
            fs = dv_sum[e_a:e_b] / T - ab
        return dth, dvb, ws, fs, a, b

    def run(st, e_a, e_b, dth, dvb, a, b):
        out = np.empty((e_b - e_a, 10))
        if hgt is not None:
            vkw["height"] = hgt[a:b + 1]
        sd.step(st, dth, dvb, dt, nsub, gyro_bias=gb, accel_bias=ab, out=out, out_every=per, **vkw)
        return out

    def measure(navv, wv, j, t_at):
        """z, H, R of fix j against the INS row ``navv`` at time t_at."""
        lat, lon, h = navv[7], navv[8], navv[9]
        rm, rn = E.radii(lat, h)
        rm, rnc = float(rm), float(rn) * math.cos(lat)
        v_ant = navv[4:7]
        z = np.empty(m_z)
        H = np.zeros((m_z, n))
        if lever is not None:
            C = A.quat_to_dcm(navv[:4])
            Cl = C @ lever
            vlev = C @ np.cross(wv, lever)
            v_ant = v_ant + vlev
            H[0:3, s_att] = A.skew(Cl)[[1, 0, 2]][:n_z]
        dtf = t_at - fix_t[j]                       # fix extrapolated to the epoch
        dlon = (lon - fix_pos[j, 1] + math.pi) % (2 * math.pi) - math.pi
        z[0] = (lat - fix_pos[j, 0]) * rm - v_ant[1] * dtf
        z[1] = dlon * rnc - v_ant[0] * dtf
        H[0, s_pos.start] = rm
        H[1, s_pos.start + 1] = rnc
        if n_z == 3:
            z[2] = (h - fix_pos[j, 2]) - v_ant[2] * dtf
            H[2, s_pos.start + 2] = 1.0
        if lever is not None:
            z[0:n_z] += Cl[[1, 0, 2]][:n_z]
        R = np.empty(m_z)
        R[:n_z] = fix_sigma[j] ** 2
        if use_vel:
            z[n_z:] = v_ant - fix_vel[j]
            H[n_z:, s_vel] = np.eye(3)
            if lever is not None:
                H[n_z:, s_att] = A.skew(vlev)
                if s_gb is not None:
                    H[n_z:, s_gb] = -C @ A.skew(lever)
            R[n_z:] = vel_sigma[j] ** 2
        return z, H, R

    nav_lag = nav_h if lag_method == "paper003" else nav_pre
    with _progress(label, total=n_ep, unit="steps") if progress else _null() as bar:
        e0 = 0
        si = 0
        while e0 < n_ep:
            while stops[si] <= e0:
                si += 1
            e1 = min(stops[si], e0 + max_ep)
            m = e1 - e0
            dth, dvb, ws, fs, a, b = increments(e0, e1)
            out = run(state, e0, e1, dth, dvb, a, b)
            rows = np.vstack([nav_h[e0][None], out])                 # epochs e0..e1
            if e1 > la_end:
                # error model for the next stretch, from a look-ahead free run of the INS
                la0 = e0
                la_end = max(e1, min(n_ep, e0 + la_ep))
                if la_end > e1:
                    la = state.copy()                                 # at epoch e1
                    ldth, ldv, lws, lfs, la_a, la_b = increments(e1, la_end)
                    la_out = run(la, e1, la_end, ldth, ldv, la_a, la_b)
                    la_rows = np.vstack([rows, la_out[:-1]])          # epochs e0..la_end-1
                    w_la, f_la = np.vstack([ws, lws]), np.vstack([fs, lfs])
                else:
                    la_rows, w_la, f_la = rows[:-1], ws, fs
                C = A.quat_to_dcm(la_rows[:, :4])
                F, G = model.matrices(es.NavPoint(la_rows[:, 7], la_rows[:, 9], la_rows[:, 4:7],
                                                  C, f_la, w_la))
                Phi_la, Q_la = es.discretize(F, G, q, T, discretization)
                if keep_F:
                    F_h[la0:la_end] = F
                    Qc_h[la0:la_end] = (G * q) @ np.swapaxes(G, -1, -2)
            sl = slice(e0 - la0, e1 - la0)
            filt.predict_many(Phi_la[sl], Q_la[sl], T, sigma_out=sig_h[e0 + 1:e1 + 1],
                              x_out=x_h[e0 + 1:e1 + 1])
            nav_h[e0 + 1:e1 + 1] = rows[1:]
            if hist:
                nav_pre[e0 + 1:e1 + 1] = rows[1:]
                w_h[e0 + 1:e1 + 1] = ws
            gb_h[e0 + 1:e1 + 1] = gb
            ab_h[e0 + 1:e1 + 1] = ab
            if scaled:
                sc_h[e0 + 1:e1 + 1] = np.concatenate([kg, ka])
            fixes_here = arrivals.get(e1, []) if e1 == stops[si] else []
            for j in fixes_here:
                ev = int(e_valid[j])
                if lagged[j] and ev < e1:
                    z, H, R = measure(nav_lag[ev], w_h[ev], j, t_ep[ev])
                    kw = dict(F=F_h[ev], Qc=Qc_h[ev]) if keep_F else {}
                    res = filt.update_lagged(z, H, R, t_rel[ev], method=lag_method, tol=1e-6, **kw)
                else:
                    # on time, or the lag ignored: a late fix taken as valid now
                    t_at = t_ep[e1] if (lag == "aware" or not late[j]) else fix_t[j]
                    z, H, R = measure(rows[-1], ws[-1], j, t_at)
                    res = filt.update(z, H, R)
                used.append(j)
                t_used.append(t_ep[e1])
                innov.append(res.innovation)
                nis.append(res.nis)
            if fixes_here:
                if fb is not None:
                    gb, ab, d = fb.apply(filt, state, gb, ab)
                    if scaled:
                        if s_kg is not None:
                            kg = kg + d[s_kg]
                        if s_ka is not None:
                            ka = ka + d[s_ka]
                        sc_h[e1] = np.concatenate([kg, ka])
                    nav_h[e1] = state[:10]
                    gb_h[e1] = gb
                    ab_h[e1] = ab
                x_h[e1] = filt.x
                sig_h[e1] = filt.sigma
            bar.advance(m)
            e0 = e1
    used = np.array(used, dtype=np.int64)
    return LooselyCoupled(t_ep, nav_h, x_h, sig_h, gb_h, ab_h, sc_h, fix_t[used], np.array(t_used),
                          used, np.array(innov).reshape(-1, m_z), np.array(nis), lay)


# ------------------------------------------------------------------------ the filter ---
def navigate_recorded(imu: ImuRecord, fixes: Fixes, opt: NavOptions | None = None,
                      *, progress=False) -> RecordedNav:
    """Loosely coupled INS + fixes on a recorded IMU stream (see the module notes).

    Raises ValueError when the fix times do not overlap the IMU record, when there is no
    usable fix, or when the vehicle never moves and no heading is given.
    """
    from sinslab.nav import strapdown as sd

    opt = opt or NavOptions()
    opt.check()
    t_lo, t_hi = imu.t0, float(imu.t[-1])
    if len(fixes) == 0 or fixes.t[-1] < t_lo or fixes.t[0] > t_hi:
        span = "no fixes" if len(fixes) == 0 else f"{fixes.t[0]:.3f}..{fixes.t[-1]:.3f} s"
        raise ValueError(f"fix times ({span}) do not overlap the IMU record ({t_lo:.3f}..{t_hi:.3f} s): "
                         "different time bases? (GPST vs UTC differ by 18 s; seconds of week vs "
                         "seconds since 1970; a logging delay)")
    fixes = fixes.select((fixes.t >= t_lo) & (fixes.t <= t_hi))
    if len(fixes) < 2:
        raise ValueError("fewer than 2 fixes inside the IMU record")
    outages = _expand_outages(opt.outages, float(fixes.t[0]), float(fixes.t[-1]))
    lever = np.asarray(opt.lever_arm, dtype=float)
    dt = imu.dt
    nsub = int(opt.nsub)
    k_kf = int(round(opt.kf_dt / dt))
    if k_kf < nsub or k_kf % nsub or abs(k_kf * dt - opt.kf_dt) > 0.02 * dt:
        k_kf = max(nsub, int(round(opt.kf_dt / dt / nsub)) * nsub)
    T = k_kf * dt
    fvel = _fix_vel_enu(fixes)
    sp = np.hypot(fvel[:, 0], fvel[:, 1])
    lat0 = float(fixes.lat[0])

    # --- initial attitude: levelling at rest, heading given or from the fix course
    rest = leveled_start(imu, fixes, opt)
    init = {}
    gb = np.zeros(3)
    if rest is not None:
        k0, k1 = rest
        pitch, roll, wb, fmean = level_from_rest(imu, k0, k1, lat0)
        if opt.rest_bias:
            gb = wb.copy()
        if opt.rest_noise:
            sq = math.sqrt(dt)
            arw = np.maximum(np.std(imu.dtheta[k0:k1], 0) / dt * sq, opt.gyro_arw)
            vrw = np.maximum(np.std(imu.dv[k0:k1], 0) / dt * sq, opt.accel_vrw)
            init.update(rest_gyro_arw=arw.tolist(), rest_accel_vrw=vrw.tolist())
        init.update(rest_start=float(imu.t[k0] - dt), rest_end=float(imu.t[k1 - 1]),
                    level_pitch=pitch, level_roll=roll, rest_gyro_mean=wb.tolist(),
                    rest_f_norm=float(np.linalg.norm(fmean)))
    else:
        k0, pitch, roll = 0, 0.0, 0.0
        init.update(rest_start=None, note="no rest at the start: pitch and roll start at 0 with the "
                    "initial attitude σ")
    if opt.heading is not None:
        ks = k0
        ts = float(imu.t[ks] - dt) if ks > 0 else imu.t0
        att0 = np.array([pitch, roll, A.heading_to_yaw(opt.heading)])
        init["heading_source"] = "given"
    else:
        mv = np.flatnonzero((sp > opt.move_speed) & (fixes.t > imu.t[k0]))
        if mv.size == 0:
            raise ValueError(f"the vehicle never moves faster than {opt.move_speed} m/s; give the "
                             "initial heading (--init heading=...)")
        t_m = float(fixes.t[mv[0]])
        ks = int(np.searchsorted(imu.t, t_m))
        ks -= (ks - k0) % nsub
        pre = sd.initial_state_array(NavState(lat0, float(fixes.lon[0]), float(fixes.h[0]),
                                              np.zeros(3), np.array([pitch, roll, 0.0])))
        sd.step(pre, imu.dtheta[k0:ks], imu.dv[k0:ks], dt, nsub, gyro_bias=gb)
        C = A.quat_to_dcm(pre[:4])
        yaw_fwd = math.atan2(-C[0, 1], C[1, 1])
        ts = float(imu.t[ks - 1]) if ks > 0 else imu.t0
        _, _, _, v = _interp_fix(fixes, ts)
        yaw_v = math.atan2(-v[0], v[1])
        Rz = A.euler_to_dcm(np.array([0.0, 0.0, yaw_v - yaw_fwd]))
        att0 = A.dcm_to_euler(Rz @ C)
        init["heading_source"] = f"fix course at {ts - fixes.t[0]:.2f} s after the first fix"
    lat_a, lon_a, h_a, v0 = _interp_fix(fixes, ts)
    C0 = A.euler_to_dcm(att0)
    lat_i, lon_i, h_i = _imu_pos_from_antenna(lat_a, lon_a, h_a, C0, lever)
    init.update(t_start=ts, pitch=float(att0[0]), roll=float(att0[1]),
                heading=float(np.mod(A.yaw_to_heading(att0[2]), 2 * np.pi)),
                gyro_bias0=gb.tolist())

    # --- model, initial covariance and the fixes used
    g_noise = np.asarray(init.get("rest_gyro_arw", opt.gyro_arw))
    a_noise = np.asarray(init.get("rest_accel_vrw", opt.accel_vrw))
    model = lc_model(g_noise, a_noise, opt.gyro_rrw, opt.accel_rrw, scale_factors=opt.scale_factors)
    lay = model.layout
    n = model.n
    rm0, rn0 = (float(x) for x in E.radii(lat_i, h_i))
    sp0 = np.zeros(n)
    sp0[lay.slice("phi")] = opt.att_sigma
    jf = int(np.argmin(np.abs(fixes.t - ts)))
    vs = fixes.sigma_vel[jf] if fixes.sigma_vel is not None else np.full(3, 0.1)
    sp0[lay.slice("dv")] = np.maximum(vs, opt.vel_sigma_floor) * 2
    ps = np.maximum(fixes.sigma[jf], opt.pos_sigma_floor) * 2
    sp0[lay.slice("dp")] = [ps[0] / rm0, ps[1] / (rn0 * math.cos(lat_i)), ps[2]]
    sp0[lay.slice("eps")] = opt.gyro_bias_sigma
    sp0[lay.slice("nabla")] = opt.accel_bias_sigma
    if opt.scale_factors:
        sp0[lay.slice("kg")] = opt.scale_sigma
        sp0[lay.slice("ka")] = opt.scale_sigma
    n_ep = (len(imu) - ks) // k_kf
    if n_ep < 2:
        raise ValueError("the IMU record after the initial alignment is shorter than two filter steps")
    sel = fixes.select((fixes.t > ts) & (fixes.t <= ts + T * n_ep))
    use_vel = opt.use_velocity and sel.vel is not None

    # --- the filter (the one INS + fix driver)
    r = loosely_coupled(
        imu, NavState(lat_i, lon_i, h_i, v0, att0), sel.t, np.stack([sel.lat, sel.lon, sel.h], -1),
        np.maximum(sel.sigma, opt.pos_sigma_floor), np.diag(sp0 ** 2), model=model,
        fix_vel=_fix_vel_enu(sel) if use_vel else None,
        vel_sigma=np.maximum(sel.sigma_vel, opt.vel_sigma_floor) if use_vel else None,
        lever_arm=lever, fix_lag=opt.fix_latency, lag=opt.lag, outages=outages, kf_dt=T,
        nsub=nsub, gyro_bias=gb, start=ks, t_start=ts, model_every=0.0, progress=progress, label="navigating")
    init["outages"] = outages
    return RecordedNav(r.t, r.nav, r.sigma, lay.labels, lay.units, r.gyro_bias, r.accel_bias, r.scale,
                       r.fix_t, r.innovation, r.nis, init, opt)


class _NullBar:
    def advance(self, n):
        pass


class _null:
    def __enter__(self):
        return _NullBar()

    def __exit__(self, *a):
        return False


# ----------------------------------------------------------------------- evaluation ----
def _interp_rows(res: RecordedNav, t):
    nav = res.nav
    lat = np.interp(t, res.t, nav[:, 7])
    lon = np.interp(t, res.t, nav[:, 8])
    h = np.interp(t, res.t, nav[:, 9])
    q = np.stack([np.interp(t, res.t, nav[:, i]) for i in range(4)], -1)
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return lat, lon, h, A.quat_to_dcm(q)


def fix_errors(res: RecordedNav, fixes: Fixes, lever_arm=None):
    """Solution (antenna point) minus fix at every fix time inside the solution span.

    Returns ``(t (K,), err (K, 3) east/north/up [m], index (K,) into fixes)``.
    """
    lever = np.asarray(res.options.lever_arm if lever_arm is None else lever_arm, dtype=float)
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
    outs = res.init.get("outages", []) if outages is None else outages
    t, err, _ = fix_errors(res, fixes)
    starts, errs = [], []
    for s, ln in outs:
        m = np.flatnonzero((t >= s) & (t < s + ln))
        if m.size:
            starts.append(s)
            errs.append(float(np.hypot(err[m[-1], 0], err[m[-1], 1])))
    return np.array(starts), np.array(errs)


# --------------------------------------------------------------------------- the CLI ---
def _vec3(text, kind, what):
    try:
        return units.parse_vector(text, kind, 3)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{what}: {e}") from None


def _parse_init(text):
    """``heading=30 deg`` (clockwise from north) -> dict; empty -> {}."""
    out = {}
    if not text:
        return out
    for tok in str(text).split(","):
        k, sep, v = tok.partition("=")
        k = k.strip().lower()
        if not sep or k not in ("heading",):
            raise ValueError(f"--init {text!r}: use heading=ANGLE (e.g. heading=\"30 deg\")")
        out["heading"] = units.parse(v.strip(), "angle")
    return out


def navigate_files(imu_path, fix_path, *, fmt=None, fix_format=None, lever_arm=None, mount=None,
                   frame=None, outages=None, fix_latency=0.0, lag="aware", init=None,
                   time_sync="none", velocity_lag=0.0, imu_delay=0.0, scale_factors=False,
                   max_gap=1.0, allow_gaps=False, out=None, echo=print, options=None):
    """Read an IMU file and a fix file, run :func:`navigate_recorded`, write the run folder.

    Returns ``(summary, RecordedNav, Fixes)``.
    """

    from sinslab import __version__
    from sinslab.data import io
    from sinslab.app import plotting
    from sinslab.app.config import dump_toml
    from sinslab.app.outputs import RunDir, command_summary, default_out_dir

    fmt_eff = fmt or io.guess_imu_format(imu_path)
    kw = {}
    if mount is not None:
        kw["mount"] = mount
    if frame is not None:
        kw["frame"] = frame
    if fmt_eff != "psins":
        kw.update(max_gap=max_gap, allow_gaps=allow_gaps)
    if fmt_eff == "rtklib-imu":
        kw["delay"] = imu_delay
    data = io.load_imu(imu_path, fmt_eff, **kw)
    ffmt = fix_format or ("rtklib-pos" if str(fix_path).lower().endswith(".pos") else None)
    fx = io.read_fixes(fix_path, ffmt, **({"velocity_lag": velocity_lag} if ffmt == "rtklib-pos" else {}))
    imu = data.imu
    if len(data.gaps):
        echo(f"  {len(data.gaps)} gap(s) in the IMU record bridged with the mean rate: "
             + ", ".join(f"{g[1]:.3f} s at {g[0] - imu.t0:.2f} s" for g in data.gaps[:5])
             + (" ..." if len(data.gaps) > 5 else ""))
    sync = None
    if time_sync == "auto":
        sync = io.estimate_time_offset(imu, fx)
        imu = io.shift_imu_time(imu, sync["offset"], sync["ppm"], sync["t_ref"])
        echo(f"  IMU time stamps corrected by {sync['offset'] * 1e3:.1f} ms (at the middle) and "
             f"{sync['ppm']:.0f} ppm (from turn rates vs fix course rates)")
    elif time_sync != "none":
        raise ValueError(f"--time-sync must be 'auto' or 'none', got {time_sync!r}")
    opt = options or NavOptions()
    if lever_arm is not None:
        opt.lever_arm = tuple(_vec3(lever_arm, "length", "--lever-arm") if isinstance(lever_arm, str)
                              else lever_arm)
    t_ref = float(fx.t[0])
    opt.outages = tuple(parse_outages(outages, t_ref)) if isinstance(outages, (str, type(None))) else tuple(outages)
    opt.fix_latency = float(fix_latency)
    opt.lag = lag
    opt.scale_factors = bool(scale_factors)
    ini = _parse_init(init) if isinstance(init, (str, type(None))) else dict(init)
    if "heading" in ini:
        opt.heading = ini["heading"]
    out = out if out is not None else default_out_dir("navigate")
    rd = RunDir(out, "navigate")
    rd.check()
    res = navigate_recorded(imu, fx, opt)
    t, err, idx = fix_errors(res, fx)
    hz = np.hypot(err[:, 0], err[:, 1])
    starts, oe = outage_end_errors(res, fx)
    outs = res.init["outages"]
    in_out = np.zeros(t.size, bool)
    for s, ln in outs:
        in_out |= (t >= s) & (t < s + ln)
    lab = list(res.labels)
    i_gb = [lab.index(f"eps_{a}") for a in "xyz"]
    i_ab = [lab.index(f"nabla_{a}") for a in "xyz"]
    att = res.att
    metrics = {
        "duration_s": float(res.t[-1] - res.t[0]), "n_fixes_used": int(res.fix_t.size),
        "n_outages": len(outs), "outage_end_hz_err_median_m": float(np.median(oe)) if oe.size else None,
        "outage_end_hz_err_max_m": float(np.max(oe)) if oe.size else None,
        "outage_end_hz_err_m": oe.tolist(),
        "hz_err_with_fixes_median_m": float(np.median(hz[~in_out])) if (~in_out).any() else None,
        "hz_err_with_fixes_max_m": float(np.max(hz[~in_out])) if (~in_out).any() else None,
        "nis_mean": float(np.mean(res.nis)) if res.nis.size else None,
        "final_pitch_deg": float(np.degrees(att[-1, 0])), "final_roll_deg": float(np.degrees(att[-1, 1])),
        "final_heading_deg": float(np.degrees(res.heading[-1])),
        "final_sigma_heading_deg": float(np.degrees(res.sigma[-1, 2])),
        "gyro_bias_final_dph": (res.gyro_bias[-1] / units.dph).tolist(),
        "gyro_bias_sigma_final_dph": (res.sigma[-1, i_gb] / units.dph).tolist(),
        "accel_bias_final_ug": (res.accel_bias[-1] / units.ug).tolist(),
        "accel_bias_sigma_final_ug": (res.sigma[-1, i_ab] / units.ug).tolist(),
        "initial_heading_deg": float(np.degrees(res.init["heading"])),
        "imu_gaps": int(len(data.gaps)),
    }
    if sync is not None:
        metrics.update(time_sync_offset_s=sync["offset"], time_sync_ppm=sync["ppm"])
    if res.scale is not None:
        metrics["scale_factor_final_ppm"] = (res.scale[-1] * 1e6).tolist()
    cfg = {"imu": str(imu_path), "fixes": str(fix_path), "format": data.format,
           "lever_arm": f"[{', '.join(f'{x:g}' for x in opt.lever_arm)}] m",
           "mount": str(mount) if mount is not None else "none", "frame": frame or "rfu",
           "outages": str(outages or "none"), "fix_latency": f"{fix_latency:g} s", "lag": lag,
           "init": str(init or ""), "time_sync": time_sync, "velocity_lag": f"{velocity_lag:g} s",
           "imu_delay": f"{imu_delay:g} s", "scale_factors": bool(scale_factors)}
    echo(f"{imu_path}: {len(imu)} samples at {1 / imu.dt:.4g} Hz; {fix_path}: {len(fx)} fixes"
         f"{' with velocity' if fx.vel is not None else ''}")
    echo(f"  start {res.init['t_start'] - fx.t[0]:.2f} s after the first fix; heading "
         f"{np.degrees(res.init['heading']):.2f} deg (clockwise from north, {res.init['heading_source']})")
    if oe.size:
        echo(f"  {len(outs)} outages: horizontal error at their end median {np.median(oe):.2f} m, "
             f"max {np.max(oe):.2f} m")
    if (~in_out).any():
        echo(f"  with fixes: horizontal error median {np.median(hz[~in_out]):.3f} m")
    echo(f"  final attitude pitch {metrics['final_pitch_deg']:.3f} deg, roll {metrics['final_roll_deg']:.3f} deg, "
         f"heading {metrics['final_heading_deg']:.3f} deg (sigma {metrics['final_sigma_heading_deg']:.3f})")
    echo(f"  gyro bias [deg/h] {np.round(metrics['gyro_bias_final_dph'], 1).tolist()}, accel bias [ug] "
         f"{np.round(metrics['accel_bias_final_ug'], 0).tolist()}")

    rd.prepare()
    rd.write_text("config.toml", f"# sinslab {__version__} — navigate\n" + dump_toml(cfg))
    sig = res.sigma
    sol = {"t_s": res.t - res.t[0], "t_abs_s": res.t, "lat_deg": np.degrees(res.nav[:, 7]),
           "lon_deg": np.degrees(res.nav[:, 8]), "h_m": res.nav[:, 9],
           "vE_mps": res.nav[:, 4], "vN_mps": res.nav[:, 5], "vU_mps": res.nav[:, 6],
           "pitch_deg": np.degrees(att[:, 0]), "roll_deg": np.degrees(att[:, 1]),
           "heading_deg": np.degrees(res.heading)}
    for i, (l, u_) in enumerate(zip(res.labels, res.units_)):
        sc = {"arcmin": units.arcmin, "deg/h": units.dph, "ug": units.ug, "ppm": units.ppm}.get(u_, 1.0)
        if l.startswith("dp") and l in ("dpL", "dplat", "dL"):
            pass
        sol[f"sigma_{l}_{u_.replace('/', 'p')}"] = sig[:, i] / sc
    for k, a in enumerate("xyz"):
        sol[f"gyro_bias_{a}_dph"] = res.gyro_bias[:, k] / units.dph
        sol[f"accel_bias_{a}_ug"] = res.accel_bias[:, k] / units.ug
    rd.write_table("solution", sol, "navigation solution at the filter epochs with filter sigma")
    rd.write_table("fix_errors", {"t_s": t - res.t[0], "east_m": err[:, 0], "north_m": err[:, 1],
                                  "up_m": err[:, 2], "in_outage": in_out.astype(int)},
                   "solution (antenna) minus fix at every fix time")
    # figures
    lat0, lon0 = fx.lat[0], fx.lon[0]
    rm, rn = E.radii(lat0, fx.h[0])
    xe = (fx.lon - lon0) * rn * math.cos(lat0)
    yn = (fx.lat - lat0) * rm
    se = (res.nav[:, 8] - lon0) * rn * math.cos(lat0)
    sn = (res.nav[:, 7] - lat0) * rm
    fig, axes = plotting.figure(1, 1, width=7.5, row_height=6.5)
    ax = axes[0]
    ax.plot(xe, yn, "k.", ms=1.5, label="fixes")
    ax.plot(se, sn, "-", color=plotting.COLORS[0], lw=1, label="INS/fix solution")
    for s, ln in outs:
        m = (res.t >= s) & (res.t < s + ln)
        ax.plot(se[m], sn[m], "-", color=plotting.COLORS[1], lw=2)
    ax.plot([], [], "-", color=plotting.COLORS[1], lw=2, label="during outages")
    ax.set_aspect("equal", "datalim")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.legend()
    rd.write_figure("track", fig, "Track on a local ENU map (origin at the first fix); outages in red.")
    fig, axes = plotting.figure(3, 1, width=9.0)
    tt = t - res.t[0]
    for ax, k, nm in zip(axes, range(3), ("east", "north", "up")):
        ax.plot(tt, err[:, k], ".", ms=1.5, color=plotting.COLORS[k])
        ax.set_ylabel(f"{nm} error [m]")
        for s, ln in outs:
            ax.axvspan(s - res.t[0], s + ln - res.t[0], color="0.85", lw=0)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Solution minus fixes (grey: simulated outages)")
    rd.write_figure("errors", fig, "Position error of the solution (antenna) versus every fix.")
    fig, axes = plotting.figure(3, 1, width=9.0)
    ts_ = res.t - res.t[0]
    axes[0].semilogy(ts_, np.degrees(sig[:, 0:3]) * 60, lw=1)
    axes[0].set_ylabel("attitude σ [arcmin]")
    axes[0].legend(["φE", "φN", "φU"], fontsize=8)
    axes[1].semilogy(ts_, sig[:, i_gb] / units.dph, lw=1)
    axes[1].set_ylabel("gyro bias σ [deg/h]")
    axes[2].semilogy(ts_, sig[:, i_ab] / units.ug, lw=1)
    axes[2].set_ylabel("accel bias σ [ug]")
    axes[2].set_xlabel("time [s]")
    rd.write_figure("sigma", fig, "Filter standard deviations of attitude and sensor biases.")
    summary = rd.complete(command_summary(
        rd, "navigate", "loosely coupled INS + position/velocity fixes on recorded data", cfg, metrics,
        ["Heading is clockwise from north.",
         f"Initial attitude: {res.init.get('heading_source')}; levelling over the initial rest."
         if res.init.get("rest_start") else "No rest at the start."]))
    echo(f"  -> {out}")
    return summary, res, fx


def register(app):
    """Add ``sinslab navigate`` to the typer app (registered via sinslab.sim.allan.register)."""
    import typer

    @app.command()
    def navigate(imu: Path = typer.Option(..., "--imu", help="recorded IMU file"),
                 fixes: Path = typer.Option(..., "--fixes", "--gnss", help="position(/velocity) fixes (.pos, CSV, .mat avp)"),
                 format: Optional[str] = typer.Option(None, "--format", help="IMU format: psins | csv | parquet | mat | rtklib-imu"),
                 fix_format: Optional[str] = typer.Option(None, "--fix-format", help="rtklib-pos | csv | mat-avp"),
                 lever_arm: Optional[str] = typer.Option(None, "--lever-arm", help='IMU -> antenna in vehicle right-forward-up axes, e.g. "[-0.05, 0, 0] m"'),
                 mount: Optional[str] = typer.Option(None, "--mount", help="sensor -> vehicle rotation: rpy:R,P,Y or euler:P,R,Y (deg)"),
                 frame: Optional[str] = typer.Option(None, "--frame", help="vehicle axes of the mount: rfu | frd | flu"),
                 outages: Optional[str] = typer.Option(None, "--outages", help="START:LEN,... (s from the first fix) or LEN/PERIOD[@FIRST]"),
                 fix_latency: float = typer.Option(0.0, "--fix-latency", help="simulated fix latency [s]"),
                 lag: str = typer.Option("aware", "--lag", help="aware | ignore (how late fixes are applied)"),
                 init: Optional[str] = typer.Option(None, "--init", help='heading="30 deg" (clockwise from north); default: from the fix course'),
                 time_sync: str = typer.Option("none", "--time-sync", help="auto: estimate the IMU time offset and clock drift from turns"),
                 velocity_lag: float = typer.Option(0.0, "--velocity-lag", help="fix velocities describe this many s before their stamp"),
                 imu_delay: float = typer.Option(0.0, "--imu-delay", help="add to RTKLIB IMU time stamps [s]"),
                 scale_factors: bool = typer.Option(False, "--scale-factors", help="estimate gyro/accel scale factors"),
                 max_gap: float = typer.Option(1.0, "--max-gap", help="longest IMU gap bridged [s]"),
                 allow_gaps: bool = typer.Option(False, "--allow-gaps", help="bridge IMU gaps of any length"),
                 out: Optional[Path] = typer.Option(None, "--out", "-o", help="output folder [default: runs/navigate-<timestamp>]")) -> None:
        """Loosely coupled INS + position/velocity fixes on recorded data (outages, latency, lever arm)."""
        from sinslab.cli import CliError, user_errors

        with user_errors():
            try:
                navigate_files(imu, fixes, fmt=format, fix_format=fix_format, lever_arm=lever_arm,
                               mount=mount, frame=frame, outages=outages, fix_latency=fix_latency,
                               lag=lag, init=init, time_sync=time_sync, velocity_lag=velocity_lag,
                               imu_delay=imu_delay, scale_factors=scale_factors, max_gap=max_gap,
                               allow_gaps=allow_gaps, out=out, echo=typer.echo)
            except (ValueError, FileNotFoundError) as e:
                raise CliError(str(e)) from None

    return navigate
