"""Recorded IMU + fix data through the loosely coupled filter: initial attitude from the
data, outages, and evaluation against the fixes.

1. **Initial attitude from the data.** Levelling from the mean specific force of the
   stationary stretch at the start of the record (fix speed below ``static_speed``);
   the mean gyro output there (minus the Earth-rate vertical component) is the initial
   gyro-bias estimate (MEMS biases are hundreds of °/h, 40x the Earth rate, so
   gyrocompassing is impossible and the rest is used to calibrate instead). Heading:
   given (``heading``), or taken from the fix velocity once the vehicle moves faster than
   ``move_speed`` (the INS attitude is propagated from the levelled start by the gyros
   and rotated about the vertical so that the body forward axis points along the fix
   course; a car does not drive sideways). The filter starts there. Without a rest at
   the start (a flight, a log begun on the move) pitch and roll come from the fix
   velocity against the integrated specific force over the first seconds
   (:func:`level_in_motion`), the heading from the course as above. Where the gyros would
   carry that levelling to the start too long (a taxi and a launch; ``CARRY_LIMIT``), the
   whole attitude comes instead from an in-motion alignment over the fixes just before the
   start (:mod:`sinslab.nav.motion_alignment`; its heading where its σ beats the course's).
2. **Filter**: :func:`sinslab.fusion.loosely_coupled.loosely_coupled` with the model and
   P0 from the specs of :class:`NavOptions` (:mod:`sinslab.fusion.recorded_spec`).
3. **Outages and latency.** Fixes whose validity time lies in an outage are dropped; a
   fix valid at t arrives at t + latency (``lag`` as in the filter).

Evaluation: :func:`fix_errors` compares the solution (antenna point) with every fix,
used or not; :func:`outage_end_errors` takes the horizontal error at the last fix of each
outage.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.core import units
from sinslab.core.blocks import BLOCK_ROWS, release_pages
from sinslab.core.records import ImuRecord, NavState
from sinslab.core.records import Fixes
from sinslab.core.stamps import held_runs, stamp_step, whole_intervals
from sinslab.fusion.loosely_coupled import LooselyCoupled, loosely_coupled
from sinslab.fusion.recorded_spec import (PLATFORMS, AidingSpec, ErrorSpec, FixHandling, GridSpec,
                                           NavOptions, StartSpec)
from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec
from sinslab.fusion.smoothing import History, smooth

__all__ = ["NavOptions", "RecordedNav", "navigate_recorded", "recorded_model", "rest_intervals",
           "parse_outages", "periodic_outages", "fix_errors", "outage_end_errors", "level_from_rest",
           "leveled_start", "level_in_motion", "moving_spans", "moving_speed_threshold", "subtract_spans", "platform_kind", "PLATFORMS",
           "ErrorSpec", "FixHandling", "AidingSpec", "StartSpec", "GridSpec"]


#: an aircraft's heading is taken from its course only above this speed [m/s] (flying) and
#: with the wings within this roll [rad] of level (a banked turn slips and crabs)
AIRCRAFT_MOVE_SPEED = 10.0
AIRCRAFT_MAX_ROLL = 10.0 * units.deg
#: 1σ of an aircraft's crab angle (course minus heading in wind) [rad]
AIRCRAFT_CRAB_SIGMA = 10.0 * units.deg
#: pitch and roll carried by the gyros from their levelling to the filter start are
#: replaced by an in-motion alignment when the tilt the carry may add (gyro-bias prior ×
#: time, white noise × √time) exceeds this many times the levelling σ: the carry then
#: dominates (a car's slow first stretch, 26 s: 1.3 times; a taxi and launch, 61 s: 3 times)
CARRY_LIMIT = 2.0
#: an estimated state whose σ at the end is above this fraction of its prior σ is reported as
#: not observable on the record (the data added less than three times the prior's information)
OBSERVED_SIGMA_RATIO = 0.5


@dataclass(frozen=True, eq=False)
class RecordedNav:
    """Result of :func:`navigate_recorded` at the filter epochs (every ``kf_dt``): a view of
    the filter's own result (``run``), with what the front end found and the options.

    ``t`` (M,) [s], ``nav`` (M, 10) ``[q0..q3, vE, vN, vU, lat, lon, h]`` after feedback,
    ``sigma`` (M, n) filter σ, ``gyro_bias`` (M, 3) [rad/s] and ``accel_bias`` (M, 3)
    [m/s²] compensation in use, ``scale`` (M, 6) scale-factor compensation [-] or None,
    ``fix_t`` (J,) validity times of the applied fixes, ``innovation`` (J, m), ``innovation_sigma`` (J, m)
    (the filter's σ of each), ``nis`` (J,) are those of ``run``; ``labels``/``units_`` the state labels and display units
    of its layout.
    """

    run: LooselyCoupled            #: the filter's result
    init: dict = field(default_factory=dict)
    options: NavOptions = None
    smoothed: object = None        #: sinslab.fusion.smoothing.SmoothedRun (``smooth=True``)

    t = property(lambda self: self.run.t)
    nav = property(lambda self: self.run.nav)
    sigma = property(lambda self: self.run.sigma)
    gyro_bias = property(lambda self: self.run.gyro_bias)
    accel_bias = property(lambda self: self.run.accel_bias)
    scale = property(lambda self: self.run.scale)
    fix_t = property(lambda self: self.run.fix_t)
    innovation = property(lambda self: self.run.innovation)
    nis = property(lambda self: self.run.nis)
    innovation_sigma = property(lambda self: self.run.innovation_sigma)   #: (J, m) or None
    labels = property(lambda self: self.run.layout.labels)
    units_ = property(lambda self: self.run.layout.units)

    def with_nav(self, nav):
        """The same result with other navigation rows (e.g. the smoothed ones), for
        :func:`fix_errors`."""
        return dataclasses.replace(self, run=dataclasses.replace(self.run, nav=nav))

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


def level_in_motion(imu: ImuRecord, fixes: Fixes, k0, lat, window=10.0):
    """Pitch and roll [rad] of the body at the start of IMU sample ``k0`` from motion: the
    in-motion alignment of :func:`sinslab.nav.motion_alignment.align_in_motion` over the
    fixes in the first ``window`` s (gravity dominates the fit, so its pitch and roll are
    sound whatever the accelerations; its heading only with strong horizontal ones, so the
    heading is taken from the course instead).

    Returns ``(pitch, roll, fix times used, a-posteriori σ of the fit [m/s])`` or None when
    fewer than 4 fixes fall in the window.
    """
    from sinslab.nav.motion_alignment import align_in_motion
    if k0 >= len(imu):
        return None
    t0 = float(imu.t[k0] - imu.dt)
    k1 = int(np.searchsorted(imu.t, t0 + window + 1e-9))
    m = align_in_motion(imu, fixes.t, _fix_vel_enu(fixes), fixes.lat, fixes.h, k0, min(k1, len(imu)))
    if m is None:
        return None
    att = A.dcm_to_euler(m.C_bn_start)
    return float(att[0]), float(att[1]), m.n_vectors, m.sigma_v


def _align_at_start(imu, fixes, ks, gb, window):
    """The in-motion alignment over the ``window`` s of fixes before the filter start (the
    boundary before IMU sample ``ks``), or None."""
    from sinslab.nav.motion_alignment import align_in_motion
    ts = float(imu.t[ks - 1])
    k0 = int(np.searchsorted(imu.t, ts - window))
    return align_in_motion(imu, fixes.t, _fix_vel_enu(fixes), fixes.lat, fixes.h, k0, ks, gb)


def _start_by_alignment(imu, fixes, k0, gb, start: StartSpec, move):
    """The start found by the first in-motion alignment after IMU sample ``k0`` whose
    heading σ beats the heading prior (:func:`sinslab.nav.motion_alignment.first_alignment`):
    ``((ks, C_b^n, heading σ, description), fit)``. Refuses, naming what the record lacks
    with its figures, when no window of the record qualifies."""
    from sinslab.nav.motion_alignment import first_alignment
    sc = first_alignment(imu, fixes.t, _fix_vel_enu(fixes), fixes.lat, fixes.h, float(imu.t[k0] - imu.dt),
                         window=start.level_window, min_speed=start.move_speed,
                         max_heading_sigma=start.att_sigma[2], gyro_bias=gb)
    if sc.fit is None:
        best = (f"the best of {sc.moving_windows} windows in motion fits the heading to "
                f"{math.degrees(sc.best_heading_sigma):.1f} deg at {sc.best_t - fixes.t[0]:.0f} s after the "
                f"first fix" if sc.moving_windows else f"none of {sc.windows} windows has every fix faster "
                f"than {start.move_speed:g} m/s")
        raise ValueError(
            f"no {start.heading_window:g} s of motion faster than {move:g} m/s with a consistent course, and no "
            f"{start.level_window:g} s of motion whose accelerations show the heading to "
            f"{math.degrees(start.att_sigma[2]):.1f} deg ({best}; fastest fix {sc.max_speed:.1f} m/s, largest "
            f"horizontal acceleration {sc.max_horizontal_accel:.2f} m/s²); give the initial heading "
            "(--init heading=...)")
    f = sc.fit
    ks = int(np.searchsorted(imu.t, f.t_ref - 1e-9)) + 1
    how = (f"in-motion alignment over {f.span:.1f} s of fixes in motion (fix velocity against the "
           f"integrated specific force; no straight stretch needed)")
    return (ks, f.C_bn, float(f.sigma[2]), how), f


#: a correlated fix error below this [m] (RTK) is left to the fixes' white σ
FIX_ERROR_MIN = 0.3


def _fix_error_states(fixes, opt, init):
    """``(fixes, (τ, σ correlated (3,)) or None)``: the fixes' time-correlated errors taken
    into account (``opt.fix.fix_error``; "auto": measured from the record by
    :func:`sinslab.fusion.fix_noise.fix_error_model`).

    - Velocity: a Doppler velocity's error lasts seconds, so successive fixes do not average
      it; each fix's σ is at least the white noise that carries the same information as
      the measured random walk of its integral (``q_v / h`` for fixes ``h`` apart).
    - Position: a correlated part of at least :data:`FIX_ERROR_MIN` lasting more than three
      fix intervals becomes Gauss–Markov states, and the fixes' σ their white part (at
      least the floor): the filter no longer averages metres of correlated error away.
    """
    spec = opt.fix.fix_error
    if spec is None or opt.fix.gnss_raw is not None:
        return fixes, None
    if not isinstance(spec, str):
        tau, corr, white = float(spec[0]), np.broadcast_to(np.asarray(spec[1], float), (3,)), \
            np.broadcast_to(np.asarray(spec[2], float), (3,))
        init["fix_error"] = {"used": True, "model": f"given: tau {tau:g} s", "source": "given"}
        return _fix_white(fixes, white, opt), (tau, np.asarray(corr, float))
    if spec != "auto":
        raise ValueError(f"fix_error must be None, 'auto' or (tau, sigma, white), got {spec!r}")
    from sinslab.fusion.fix_noise import fix_error_model
    m = fix_error_model(fixes)
    if m is None:
        init["fix_error"] = {"used": False, "model": None}
        return fixes, None
    h = float(np.median(np.diff(fixes.t)))
    init["fix_error"] = {"model": m.describe(), "source": "measured from the record"}
    if fixes.sigma_vel is not None and m.velocity_walk is not None:
        sv = np.maximum(fixes.sigma_vel, m.velocity_walk / math.sqrt(h))
        init["fix_error"]["velocity_sigma"] = np.median(sv, 0).tolist()
        fixes = dataclasses.replace(fixes, sigma_vel=sv)
    used = float(np.max(m.correlated)) >= FIX_ERROR_MIN and m.tau >= 3 * h
    init["fix_error"]["used"] = bool(used)
    if not used:
        return fixes, None
    return _fix_white(fixes, m.white, opt), (m.tau, m.correlated)


def _fix_white(fixes, white, opt):
    w = np.maximum(np.asarray(white, float)[[1, 0, 2]], opt.fix.pos_sigma_floor)     # north, east, up
    return dataclasses.replace(fixes, sigma=np.tile(w, (len(fixes), 1)))


def leveled_start(imu, fixes: Fixes, start: StartSpec):
    """Index range ``(k0, k1)`` of the initial rest (see module notes) or None: until the
    first fix faster than ``static_speed``; when that leaves less than 1 s (a receiver
    whose speed noise exceeds ``static_speed``), until the first fix faster than three
    times its own speed noise (:func:`moving_speed_threshold`)."""
    sp = _fix_speed(fixes)
    k0 = int(np.searchsorted(imu.t, max(imu.t0, fixes.t[0]) - 1e-9))
    for thr in (start.static_speed, moving_speed_threshold(fixes, start)):
        moving = np.flatnonzero(sp > thr)
        t_move = fixes.t[moving[0]] if moving.size else fixes.t[-1]
        k1 = int(np.searchsorted(imu.t, min(t_move, imu.t[0] + 120.0)))
        if k1 - k0 >= int(round(1.0 / imu.dt)):
            return k0, k1
    return None


def moving_speed_threshold(fixes: Fixes, start: StartSpec):
    """Per fix, the horizontal speed [m/s] above which the fix says the vehicle moves:
    three times the speed's own noise (the velocity σ, or for position-only fixes the σ
    of a position difference over one interval), at least ``static_speed``."""
    if fixes.vel is not None:
        sv = fixes.sigma_vel if fixes.sigma_vel is not None else np.full((len(fixes), 3), 0.1)
        s_sp = np.hypot(sv[:, 0], sv[:, 1]) / math.sqrt(2)
    else:
        s_sp = np.hypot(fixes.sigma[:, 0], fixes.sigma[:, 1]) / stamp_step(fixes.t)[0]
    return np.maximum(3.0 * s_sp, start.static_speed)


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


def recorded_model(opt: NavOptions, gyro_arw, accel_vrw, fix_error=None):
    """The error model of :func:`navigate_recorded`: the loosely coupled core (φ, δv, δp)
    with gyro and accelerometer bias states (random constant, or random walk with
    ``gyro_rrw``/``accel_rrw``), Gauss–Markov bias blocks (``gyro_markov``/``accel_markov``),
    scale-factor states (``scale_factors``; random constant, walk or Gauss–Markov) and the
    antenna lever arm (``estimate_lever``), from :mod:`sinslab.nav.errstate`."""
    from sinslab.nav import errstate as es
    sensors = [es.gyro_bias(rrw=opt.errors.gyro_rrw), es.accel_bias(arw=opt.errors.accel_rrw)]
    if opt.errors.gyro_markov is not None:
        sensors.append(es.gyro_markov(opt.errors.gyro_markov[1], opt.errors.gyro_markov[0]))
    if opt.errors.accel_markov is not None:
        sensors.append(es.accel_markov(opt.errors.accel_markov[1], opt.errors.accel_markov[0]))
    if opt.errors.scale_factors:
        gs, as_ = _scale_sigmas(opt.errors)
        tg, ta = opt.errors.scale_tau
        sensors += [es.gyro_scale(rw=0.0 if tg else opt.errors.scale_rw[0], tau=tg, sigma=gs if tg else None),
                    es.accel_scale(rw=0.0 if ta else opt.errors.scale_rw[1], tau=ta, sigma=as_ if ta else None)]
    if opt.fix.estimate_lever:
        sensors.append(es.lever_arm())
    if fix_error is not None:
        sensors.append(es.fix_position_error(tau=fix_error[0], sigma=fix_error[1]))
    if opt.aiding.odometer is not None:
        sensors.append(es.odometer_scale())
    if opt.aiding.estimate_vehicle:
        sensors += [es.installation("vm", "xz"), es.lever_arm("nlev")]
    if opt.fix.gnss_raw is not None:
        sensors.append(opt.fix.gnss_raw.clock_block())
    return es.ErrorModel("full", sensors, gyro_arw=gyro_arw, accel_vrw=accel_vrw)


def _scale_sigmas(errors: ErrorSpec):
    return (errors.scale_sigma if errors.gyro_scale_sigma is None else errors.gyro_scale_sigma,
            errors.scale_sigma if errors.accel_scale_sigma is None else errors.accel_scale_sigma)


def _imu_point_course(fixes: Fixes, imu, lever, gb):
    """Course [rad, clockwise from north] and speed of the IMU point at the fix times: the
    antenna velocity minus ``C (ω × l)``, with ω the vertical gyro (bias ``gb`` removed) and
    C's horizontal axes from the course itself (a car does not drive sideways)."""
    v = _fix_vel_enu(fixes)
    wz = _rate_z_at(imu, fixes.t, gb[2])
    crs = np.arctan2(v[:, 0], v[:, 1])
    vi = v[:, :2]
    for _ in range(2):                      # the lever correction needs the course it corrects
        f = np.stack([np.sin(crs), np.cos(crs)], -1)            # forward (E, N)
        r = np.stack([f[:, 1], -f[:, 0]], -1)                   # right
        d = (-wz * lever[1])[:, None] * r + (wz * lever[0])[:, None] * f
        vi = v[:, :2] - d
        crs = np.arctan2(vi[:, 0], vi[:, 1])
    return crs, np.hypot(vi[:, 0], vi[:, 1])


def _rate_z_window(imu, x_lo, x_hi, gb_z=0.0):
    """The vertical gyro rate ``dθ_z / dt − gb_z`` [rad/s] and its times (each sample's
    rate the mean over its interval: at ``t − dt/2``) of the samples around
    ``[x_lo, x_hi]`` [s]: enough that interpolating at any time in there gives what
    interpolating in the whole record gives."""
    t = imu.t
    lo = max(0, int(np.searchsorted(t, x_lo)) - 2)
    hi = min(len(imu), int(np.searchsorted(t, x_hi)) + 3)
    return np.asarray(t[lo:hi]) - 0.5 * imu.dt, np.asarray(imu.dtheta[lo:hi, 2]) / imu.dt - gb_z


def _rate_z_at(imu, x, gb_z=0.0):
    """``np.interp`` of the vertical gyro rate (:func:`_rate_z_window`) at the sorted times
    ``x`` [s], the samples read a window at a time (the same numbers)."""
    x = np.asarray(x, dtype=float)
    out = np.empty(x.size)
    span = BLOCK_ROWS * imu.dt
    i = 0
    while i < x.size:
        j = max(i + 1, int(np.searchsorted(x, x[i] + span, side="right")))
        tw, wz = _rate_z_window(imu, x[i], x[j - 1], gb_z)
        out[i:j] = np.interp(x[i:j], tw, wz)
        release_pages(imu.t, imu.dtheta)
        i = j
    return out


def _heading_in_motion(fixes: Fixes, imu, k0, pre0, nsub, start: StartSpec, lever, gb, move_speed=None,
                       max_roll=math.inf):
    """Heading from the first ``heading_window`` seconds of motion faster than
    ``move_speed`` in which the course of the IMU-point velocity and the heading carried by
    the gyros from the levelled rest (started at yaw 0) differ by a constant within
    ``heading_straight`` (no skid, no noisy course): that constant is the initial yaw
    offset, averaged over the window. Works through turns, since the gyros carry them.

    Returns ``(ks, C_b^n at the end of sample ks − 1, heading σ [rad], description)`` or None.
    """
    from sinslab.nav import strapdown as sd
    crs, spi = _imu_point_course(fixes, imu, lever, gb)
    fast = spi > (start.move_speed if move_speed is None else move_speed)
    t_rest = float(imu.t[k0])
    cand = np.flatnonzero(fast & (fixes.t > t_rest))
    dt = imu.dt
    # the window is a whole number of the stream's own intervals, its length tested with
    # the stamps' own jitter (a receiver stamps "1 s" fixes 1.000019 s apart)
    n_iv, f_dt, f_tol = whole_intervals(fixes.t, start.heading_window)
    for j in cand:
        w = np.flatnonzero((fixes.t >= fixes.t[j]) & (fixes.t <= fixes.t[j] + n_iv * (f_dt + f_tol)))
        if fixes.t[w[-1]] - fixes.t[j] < n_iv * (f_dt - f_tol) or not fast[w].all():
            continue
        st = pre0.copy()
        k = k0
        az, kk, roll = [], [], []
        for i in w:                          # INS heading of the forward axis at each fix
            ke = int(np.searchsorted(imu.t, fixes.t[i] - 1e-9))
            ke = max(k, ke - (ke - k0) % nsub)
            if ke > k:
                sd.step(st, imu.dtheta[k:ke], imu.dv[k:ke], dt, nsub, gyro_bias=gb)
                k = ke
            C = A.quat_to_dcm(st[:4])
            az.append(math.atan2(C[0, 1], C[1, 1]))             # forward axis, clockwise from north
            kk.append(k)
            roll.append(abs(A.dcm_to_euler(C)[1]))
        if max(roll) > max_roll:                # banked: an aircraft's course leaves its heading
            continue
        off = np.unwrap(crs[w] - np.array(az))
        if np.ptp(off) > start.heading_straight:
            continue
        mean = float(np.mean(off))
        if fixes.vel is not None:
            sv = fixes.sigma_vel[w] if fixes.sigma_vel is not None else np.full((w.size, 3), 0.1)
            s_meas = np.hypot(sv[:, 0], sv[:, 1]) / math.sqrt(2) / spi[w]
            sig = math.sqrt(float(np.mean(s_meas ** 2) + np.var(off)) / w.size)
        else:
            sig = math.sqrt(float(np.var(off)) / w.size + float(np.mean(np.hypot(
                fixes.sigma[w, 0], fixes.sigma[w, 1]) / spi[w] / fixes_dt(fixes))) ** 2 / w.size)
        C = A.quat_to_dcm(st[:4])
        Rz = A.euler_to_dcm(np.array([0.0, 0.0, -mean]))        # heading +mean = yaw −mean
        how = (f"course of the IMU-point velocity minus the gyro heading over "
               f"{fixes.t[w[-1]] - fixes.t[j]:.1f} s of motion")
        return kk[-1], Rz @ C, sig, how
    return None


def platform_kind(fixes: Fixes, platform="auto"):
    """``(kind, reason)``: the platform as given, or with ``"auto"`` from the fixes: an
    aircraft when the horizontal speed exceeds 70 m/s or the climb rate exceeds 3 m/s at
    more than 2 % of the fixes (a car would need a 10 % grade at 30 m/s; car drives on
    hills stay below 1 m/s, a small UAV exceeds 3 m/s at 7 % of its fixes); else land (a
    ship is not told from a car by its fixes)."""
    if platform != "auto":
        return platform, "given"
    v = _fix_vel_enu(fixes)
    sp = np.hypot(v[:, 0], v[:, 1])
    vu = np.abs(v[:, 2]) if np.all(np.isfinite(v[:, 2])) else np.zeros(len(fixes))
    if sp.max() > 70.0:
        return "aircraft", f"horizontal speed up to {sp.max():.0f} m/s"
    if np.mean(vu > 3.0) > 0.02:
        return "aircraft", f"climbing or descending faster than 3 m/s at {100 * np.mean(vu > 3.0):.0f} % of the fixes"
    return "land", "from the fixes: speed and climb rate of a land vehicle"


def fixes_dt(fixes):
    """Median interval of the fixes [s]."""
    return float(np.median(np.diff(fixes.t))) if len(fixes) > 1 else 1.0


def rest_intervals(imu: ImuRecord, aiding: AidingSpec, start: StartSpec, lat, rest=None, gyro_bias=None,
                   fixes=None):
    """Stationary intervals for ZUPT/ZARU [s], shape (K, 2): from the log's rest flags
    (``zupt="flags"``) or the IMU detector (:func:`sinslab.fusion.stationarity.detect`)
    with thresholds calibrated on the initial rest ``rest = (k0, k1)`` (the scatter of
    specific force and rate and the mean rate of the engine-on car at rest, ×1.5; the gyro
    bias measured there removed), trimmed by 0.5 s at both ends and at least ``rest_min``
    long; then cut wherever one of ``fixes`` (those the filter uses) says the vehicle
    moves (:func:`moving_spans`): a detector cannot tell rest from steady driving on a
    smooth road, a fix can."""
    iv = _rest_candidates(imu, aiding, lat, rest, gyro_bias)
    if fixes is not None and len(fixes) > 1 and iv.size:
        iv = subtract_spans(iv, moving_spans(fixes, start))
    return iv[(iv[:, 1] - iv[:, 0]) >= max(aiding.rest_min - 1.0, 0.1)] if iv.size else iv


def moving_spans(fixes: Fixes, start: StartSpec):
    """Time spans [s] (K, 2) in which fixes say the vehicle moves: one fix interval either
    side of every fix faster than :func:`moving_speed_threshold`."""
    fdt, _ = stamp_step(fixes.t)
    mv = _fix_speed(fixes) > moving_speed_threshold(fixes, start)
    return np.stack([fixes.t[mv] - fdt, fixes.t[mv] + fdt], -1)


def subtract_spans(iv, spans):
    """Intervals ``iv`` (K, 2) minus the union of ``spans`` (L, 2), both [s]."""
    out = []
    spans = np.asarray(spans, dtype=float).reshape(-1, 2)
    spans = spans[np.argsort(spans[:, 0])] if spans.size else spans
    for a, b in np.asarray(iv, dtype=float).reshape(-1, 2):
        hit = spans[(spans[:, 1] > a) & (spans[:, 0] < b)]
        cur = a
        for sa, sb in hit:
            if sa > cur:
                out.append((cur, min(sa, b)))
            cur = max(cur, sb)
            if cur >= b:
                break
        if cur < b:
            out.append((cur, b))
    return np.array(out, dtype=float).reshape(-1, 2)


def _rest_candidates(imu, aiding: AidingSpec, lat, rest, gyro_bias):
    from sinslab.fusion import stationarity as st
    if aiding.zupt == "flags":
        t, fl = aiding.rest_flags
        iv = st.from_flags(t, fl, min_duration=aiding.rest_min)
    else:
        gb = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, float)
        kw = {}
        if rest is not None:
            k0, k1 = rest
            k = max(1, int(round(1.0 / imu.dt)))
            m = (k1 - k0) // k
            if m >= 1:
                f = (imu.dv[k0:k0 + m * k] / imu.dt).reshape(m, k, 3)
                w = ((imu.dtheta[k0:k0 + m * k] - gb * imu.dt) / imu.dt).reshape(m, k, 3)
                g = float(E.gravity(lat, 0.0))
                kw = dict(f_std=max(1.5 * float(np.linalg.norm(f.std(1), axis=1).max()), 0.02),
                          f_tol=max(1.5 * float(np.abs(np.linalg.norm(f.mean(1), axis=1) - g).max()), 0.05),
                          w_max=max(1.5 * float(np.linalg.norm(w.mean(1), axis=1).max()), 0.002),
                          w_std=max(1.5 * float(np.linalg.norm(w.std(1), axis=1).max()), 1e-4))
        iv = st.detect(imu, lat, min_duration=aiding.rest_min, gyro_bias=gb, **kw)
    iv = np.asarray(iv, dtype=float).reshape(-1, 2)
    return np.stack([iv[:, 0] + 0.5, iv[:, 1] - 0.5], -1) if iv.size else iv


# ------------------------------------------------------------------------ the filter ---
def navigate_recorded(imu: ImuRecord, fixes: Fixes, opt: NavOptions | None = None,
                      *, progress=False) -> RecordedNav:
    """Loosely coupled INS + fixes on a recorded IMU stream (see the module notes).

    Raises ValueError when the fix times do not overlap the IMU record, when there is no
    usable fix, or when the vehicle never moves and no heading is given. Fixes after the
    last whole filter step are dropped (``init["fixes_after_grid"]`` counts them).
    """
    from sinslab.fusion.measurements import NonHolonomic, ZeroRate, ZeroVelocity
    from sinslab.nav import strapdown as sd

    opt = opt or NavOptions()
    t_lo, t_hi = imu.t0, float(imu.t[-1])
    if len(fixes) == 0 or fixes.t[-1] < t_lo or fixes.t[0] > t_hi:
        span = "no fixes" if len(fixes) == 0 else f"{fixes.t[0]:.3f}..{fixes.t[-1]:.3f} s"
        raise ValueError(f"fix times ({span}) do not overlap the IMU record ({t_lo:.3f}..{t_hi:.3f} s): "
                         "different time bases? (GPST vs UTC differ by 18 s; seconds of week vs "
                         "seconds since 1970; a logging delay)")
    fixes = fixes.select((fixes.t >= t_lo) & (fixes.t <= t_hi))
    init = {}
    runs = held_runs(np.column_stack([fixes.lat, fixes.lon, fixes.h, fixes.sigma]
                                     + ([fixes.vel] if fixes.vel is not None else [])))
    if runs is not None:
        # a receiver's fixes repeated in every row of a faster log: one update per epoch
        init["held_fixes"] = (len(fixes), int(runs.size))
        fixes = fixes.select(runs)
    if len(fixes) < 2:
        raise ValueError("fewer than 2 fixes inside the IMU record")
    init["platform"] = platform_kind(fixes, opt.aiding.platform)
    kind, why = init["platform"]
    if kind in ("aircraft", "marine") and (opt.aiding.nhc_sigma is not None or opt.aiding.odometer is not None):
        raise ValueError(f"the non-holonomic constraint and the odometer assume a wheeled land vehicle; "
                         f"this is {'an' if kind == 'aircraft' else 'a'} {kind} ({why}): drop nhc/odometer"
                         + (" (or give the platform as land if it is a car)" if opt.aiding.platform == "auto" else ""))
    if opt.fix.fix_sigma is not None:
        sg = np.broadcast_to(np.asarray(opt.fix.fix_sigma, float), (3,))
        fixes = dataclasses.replace(fixes, sigma=np.tile(sg, (len(fixes), 1)))
    if opt.fix.fix_vel_sigma is not None and fixes.vel is not None:
        sg = np.broadcast_to(np.asarray(opt.fix.fix_vel_sigma, float), (3,))
        fixes = dataclasses.replace(fixes, sigma_vel=np.tile(sg, (len(fixes), 1)))
    fixes, fix_error = _fix_error_states(fixes, opt, init)
    outages = _expand_outages(opt.fix.outages, float(fixes.t[0]), float(fixes.t[-1]))
    lever = np.asarray(opt.fix.lever_arm, dtype=float)
    dt = imu.dt
    nsub = int(opt.grid.nsub)
    k_kf = int(round(opt.grid.kf_dt / dt))
    if k_kf < nsub or k_kf % nsub or abs(k_kf * dt - opt.grid.kf_dt) > 0.02 * dt:
        k_kf = max(nsub, int(round(opt.grid.kf_dt / dt / nsub)) * nsub)
    T = k_kf * dt
    lat0 = float(fixes.lat[0])

    # --- initial attitude: levelling at rest, heading given or from straight motion
    rest = leveled_start(imu, fixes, opt.start)
    gb = np.zeros(3)
    if rest is not None:
        k0, k1 = rest
        pitch, roll, wb, fmean = level_from_rest(imu, k0, k1, lat0)
        if opt.errors.rest_bias:
            gb = wb.copy()
        # white-noise densities of the unit as it stands (engine vibration included)
        sq = math.sqrt(dt)
        g_meas = np.std(imu.dtheta[k0:k1], 0) / dt * sq
        a_meas = np.std(imu.dv[k0:k1], 0) / dt * sq
        init.update(rest_gyro_noise=g_meas.tolist(), rest_accel_noise=a_meas.tolist())
        if opt.errors.rest_noise:
            arw = np.maximum(g_meas, opt.errors.gyro_arw)
            vrw = np.maximum(a_meas, opt.errors.accel_vrw)
            init.update(rest_gyro_arw=arw.tolist(), rest_accel_vrw=vrw.tolist())
        init.update(rest_start=float(imu.t[k0] - dt), rest_end=float(imu.t[k1 - 1]),
                    level_pitch=pitch, level_roll=roll, rest_gyro_mean=wb.tolist(),
                    rest_f_norm=float(np.linalg.norm(fmean)))
    else:
        # no standstill (an aircraft, a log started on the move): level in motion from the
        # GNSS acceleration against the specific force, from the first fix on
        k0 = int(np.searchsorted(imu.t, max(imu.t0, float(fixes.t[0])) + dt - 1e-9))
        lv = level_in_motion(imu, fixes, k0, lat0, opt.start.level_window)
        if lv is None:
            pitch, roll = 0.0, 0.0
            init.update(rest_start=None, level_source="none: no rest and too few fixes in motion; pitch "
                        "and roll start at 0 with the initial attitude σ")
        else:
            pitch, roll, n_used, resid = lv
            init.update(rest_start=None, level_pitch=pitch, level_roll=roll, level_residual=resid,
                        level_source=f"in motion: fix velocity against the integrated specific force at "
                        f"{n_used} fixes (no rest at the start)")
    forced_fit = None
    if opt.start.heading is not None:
        ks = k0
        ts = float(imu.t[ks] - dt) if ks > 0 else imu.t0
        att0 = np.array([pitch, roll, A.heading_to_yaw(opt.start.heading)])
        init["heading_source"] = "given"
        init["heading_sigma"] = None
    else:
        pre = sd.initial_state_array(NavState(lat0, float(fixes.lon[0]), float(fixes.h[0]),
                                              np.zeros(3), np.array([pitch, roll, 0.0])))
        # an aircraft is carried, taxied and launched before its course shows its heading
        air = init["platform"][0] == "aircraft"
        move = max(opt.start.move_speed, AIRCRAFT_MOVE_SPEED) if air else opt.start.move_speed
        found = _heading_in_motion(fixes, imu, k0, pre, nsub, opt.start, lever, gb, move,
                                   AIRCRAFT_MAX_ROLL if air else math.inf)
        if found is None:
            # no straight, level stretch (an aircraft in continuous turns): the in-motion
            # alignment sees the heading through the turns' accelerations instead
            found, forced_fit = _start_by_alignment(imu, fixes, k0, gb, opt.start, move)
        ks, C, h_sig, how = found
        ts = float(imu.t[ks - 1]) if ks > 0 else imu.t0
        att0 = A.dcm_to_euler(C)
        init["heading_source"] = how
        init["heading_sigma"] = h_sig
    g_noise = np.asarray(init.get("rest_gyro_arw", opt.errors.gyro_arw))
    # pitch and roll levelled (at the rest or in motion) and carried by the gyros to the
    # start: when the tilt the residual gyro bias (its prior σ) and the white noise may add
    # on the way dominates the levelling's own σ (CARRY_LIMIT times it), the attitude comes
    # instead from the motion just before the start (nav.motion_alignment), if its fit says
    # it is better; a rest just before the motion keeps its levelling
    t_lev = init["rest_end"] if init.get("rest_end") is not None else float(imu.t[k0] - dt)
    carried = max(float(ts - t_lev), 0.0)
    tilt = math.hypot(float(np.max(opt.errors.gyro_bias_sigma)) * carried, float(np.max(g_noise)) * math.sqrt(carried))
    long_carry = opt.start.motion_alignment and tilt > CARRY_LIMIT * max(opt.start.att_sigma[:2])
    fit = forced_fit if forced_fit is not None else (
        _align_at_start(imu, fixes, ks, gb, opt.start.level_window) if long_carry else None)
    if fit is not None and (forced_fit is not None or float(np.max(fit.sigma[:2])) < tilt):
        h_fit = math.hypot(float(fit.sigma[2]), opt.start.heading_sigma_floor)
        course = math.inf if opt.start.heading is not None else math.hypot(init["heading_sigma"], (
            AIRCRAFT_CRAB_SIGMA if init["platform"][0] == "aircraft" else opt.start.heading_sigma_floor))
        use_h = forced_fit is not None or h_fit < course
        att0 = np.r_[fit.att[:2], fit.att[2] if use_h else att0[2]]
        init.update(motion_alignment={"window_s": fit.span, "fixes": fit.n_vectors, "sigma_v": fit.sigma_v,
                                      "sigma": fit.sigma.tolist(), "heading": bool(use_h), "carried_s": carried})
        if use_h:
            init.update(heading_source=f"in-motion alignment over {fit.span:.1f} s of fixes before the start "
                        f"(fix velocity against the integrated specific force)", heading_sigma=float(fit.sigma[2]))
    else:
        fit = None
    lat_a, lon_a, h_a, v0 = _interp_fix(fixes, ts)
    C0 = A.euler_to_dcm(att0)
    lat_i, lon_i, h_i = _imu_pos_from_antenna(lat_a, lon_a, h_a, C0, lever)
    init.update(t_start=ts, pitch=float(att0[0]), roll=float(att0[1]),
                heading=float(np.mod(A.yaw_to_heading(att0[2]), 2 * np.pi)),
                gyro_bias0=gb.tolist())

    # --- model, initial covariance and the fixes used
    a_noise = np.asarray(init.get("rest_accel_vrw", opt.errors.accel_vrw))
    init.update(filter_gyro_arw=np.broadcast_to(g_noise, (3,)).tolist(),
                filter_accel_vrw=np.broadcast_to(a_noise, (3,)).tolist())
    model = recorded_model(opt, g_noise, a_noise, fix_error)
    lay = model.layout
    n = model.n
    rm0, rn0 = (float(x) for x in E.radii(lat_i, h_i))
    sp0 = np.zeros(n)
    sp0[lay.slice("phi")] = opt.start.att_sigma
    if init.get("heading_sigma") is not None:
        # the heading found in motion, its σ widened by what the window cannot see (a
        # slip angle, a mount yaw error of a few tenths of a degree), never above the prior
        sp0[lay.slice("phi").start + 2] = min(opt.start.att_sigma[2], math.hypot(
            init["heading_sigma"], opt.start.heading_sigma_floor))
        if fit is not None and init["motion_alignment"]["heading"]:
            # the fit's heading (specific force against the fix velocity: no crab, no slip)
            sp0[lay.slice("phi").start + 2] = math.hypot(init["heading_sigma"], opt.start.heading_sigma_floor)
        elif init["platform"][0] == "aircraft":
            # an aircraft crabs into the wind: its course is its heading only to ~10°
            sp0[lay.slice("phi").start + 2] = math.hypot(init["heading_sigma"], AIRCRAFT_CRAB_SIGMA)
    st = lay.slice("phi").start
    if fit is not None:
        # the levelling σ (an accelerometer bias tilts a fit as it tilts a rest) and the fit's own
        sp0[st:st + 2] = np.hypot(sp0[st:st + 2], fit.sigma[:2])
        init.update(initial_tilt_sigma=float(np.max(sp0[st:st + 2])))
    elif init.get("rest_end") is not None and ts > init["rest_end"]:
        # levelled at the rest and carried by the gyros to the start (a taxi and a launch, a
        # slow first stretch): the σ at the start grows with the tilt they may add on the way
        sp0[st:st + 2] = np.hypot(sp0[st:st + 2], tilt)
        init.update(tilt_carried_s=carried, initial_tilt_sigma=float(np.max(sp0[st:st + 2])))
    jf = int(np.argmin(np.abs(fixes.t - ts)))
    vs = fixes.sigma_vel[jf] if fixes.sigma_vel is not None else np.full(3, 0.1)
    sp0[lay.slice("dv")] = np.maximum(vs, opt.fix.vel_sigma_floor) * 2
    ps = np.maximum(fixes.sigma[jf], opt.fix.pos_sigma_floor) * 2
    sp0[lay.slice("dp")] = [ps[0] / rm0, ps[1] / (rn0 * math.cos(lat_i)), ps[2]]
    sp0[lay.slice("eps")] = opt.errors.gyro_bias_sigma
    sp0[lay.slice("nabla")] = opt.errors.accel_bias_sigma
    if fix_error is not None:
        sp0[lay.find("fix_error")] = np.maximum(fix_error[1], 1e-3)
    if opt.errors.gyro_markov is not None:
        sp0[lay.slice("eps_m")] = opt.errors.gyro_markov[0]
    if opt.errors.accel_markov is not None:
        sp0[lay.slice("nabla_m")] = opt.errors.accel_markov[0]
    if opt.errors.scale_factors:
        sp0[lay.slice("kg")], sp0[lay.slice("ka")] = _scale_sigmas(opt.errors)
    if opt.fix.estimate_lever:
        sp0[lay.slice("lev")] = opt.fix.lever_sigma
    if opt.aiding.odometer is not None:
        sp0[lay.slice("kod")] = opt.aiding.odometer_scale_sigma
    if opt.aiding.estimate_vehicle:
        sp0[lay.slice("vm")] = opt.aiding.vehicle_mount_sigma
        sp0[lay.slice("nlev")] = opt.aiding.nhc_lever_sigma
    if opt.fix.gnss_raw is not None:
        sp0[lay.slice("clk")] = opt.fix.gnss_raw.clock_sigmas()
    n_ep = (len(imu) - ks) // k_kf
    if n_ep < 2:
        raise ValueError("the IMU record after the initial alignment is shorter than two filter steps")
    t_end = ts + T * n_ep
    init["fixes_after_grid"] = int(np.sum(fixes.t > t_end + 1e-9))
    init["grid_end"] = t_end
    sel = fixes.select((fixes.t > ts) & (fixes.t <= t_end + 1e-9))
    use_vel = opt.fix.use_velocity and sel.vel is not None

    # --- aiding
    every = max(1, int(round(opt.aiding.aiding_dt / T)))
    gate = opt.aiding.aid_gate
    named = []
    if opt.aiding.zupt is not None:
        used = sel.select(~_in_outages(sel.t, outages))
        iv = rest_intervals(imu, opt.aiding, opt.start, lat0, rest, gb, fixes=used)
        iv = iv[iv[:, 1] > ts] if iv.size else iv
        init["rest_intervals"] = iv.tolist()
        if len(iv):
            named.append(("zupt", ZeroVelocity(iv, opt.aiding.zupt_sigma, every=every, gate=gate)))
            if opt.aiding.zaru:
                zs = opt.aiding.zaru_sigma if opt.aiding.zaru_sigma is not None else \
                    2.0 * float(np.max(g_noise)) / math.sqrt(T)
                init["zaru_sigma"] = zs
                # every epoch: each holds the rate of its own step, thinning discards them
                named.append(("zaru", ZeroRate(iv, zs, every=1, gate=gate)))
    Cvb = A.euler_to_dcm(np.asarray(opt.aiding.vehicle_mount, float)) if opt.aiding.vehicle_mount is not None else np.eye(3)
    if opt.aiding.nhc_sigma is not None:
        named.append(("nhc", NonHolonomic(
            opt.aiding.nhc_sigma, mount=Cvb, lever_arm=Cvb.T @ np.asarray(opt.aiding.nhc_lever_arm, float), every=every,
            gate=gate, mount_block="vm" if opt.aiding.estimate_vehicle else None,
            lever_block="nlev" if opt.aiding.estimate_vehicle else None, pitch_gradient=opt.aiding.nhc_pitch_gradient,
            correlation_time=opt.aiding.nhc_correlation_time, dt=T)))
    if opt.aiding.odometer is not None:
        named.append(("odometer", _odometer(opt.aiding.odometer, opt.aiding, T, t_lo, t_hi)))
    aiding = [m for _, m in named]

    if opt.fix.gnss_raw is not None:
        # tightly coupled: the satellites' own measurements in place of the fixes
        aiding += list(opt.fix.gnss_raw.make(lever_arm=lever, outages=outages, t_start=ts))
        sel = sel.select(np.zeros(len(sel), bool))
        use_vel = False
    P0 = np.diag(sp0 ** 2)
    if opt.fix.estimate_lever:
        # the start position is the antenna's minus C l_used: its error is −C δl, so the
        # position and lever-arm errors start correlated (else the fixes pin a wrong start)
        D = np.array([[0.0, 1.0 / rm0, 0.0], [1.0 / (rn0 * math.cos(lat_i)), 0.0, 0.0], [0.0, 0.0, 1.0]])
        J = -D @ C0
        spp, slv = lay.slice("dp"), lay.slice("lev")
        Sl = np.eye(3) * opt.fix.lever_sigma ** 2
        P0[spp, spp] += J @ Sl @ J.T
        P0[spp, slv] = J @ Sl
        P0[slv, spp] = (J @ Sl).T

    # --- the filter (the one INS + fix driver)
    fix_spec = FixSpec(sel.t, np.stack([sel.lat, sel.lon, sel.h], -1), np.maximum(sel.sigma, opt.fix.pos_sigma_floor),
                       vel=_fix_vel_enu(sel) if use_vel else None,
                       vel_sigma=np.maximum(sel.sigma_vel, opt.fix.vel_sigma_floor) if use_vel else None,
                       latency=opt.fix.fix_latency, lever_arm=lever, outages=outages, robust=opt.fix.robust)
    r = loosely_coupled(imu, NavState(lat_i, lon_i, h_i, v0, att0), fix_spec, P0, model,
                        ins=InsSpec(nsub=nsub, gyro_bias=gb, start=ks, t_start=ts),
                        grid=FilterGrid(T, model_every=0.0, spill=opt.grid.spill), lag=opt.fix.lag, aiding=aiding,
                        history=History(0.1, spill=opt.grid.smooth_spill) if opt.grid.smooth else None, progress=progress, label="navigating")
    init["outages"] = outages
    init["aiding_gate"] = {nm: {"applied": m.gate.passed, "rejected": len(m.gate.rejected),
                                "rejected_spans": _spans(m.gate.rejected, 2.5 * T * m.every)}
                           for nm, m in named if getattr(m, "gate", None) is not None}
    if opt.fix.gnss_raw is not None:
        init["gnss_clock"] = opt.fix.gnss_raw.clock_estimate(r.t, r.x, lay)
    if opt.fix.estimate_lever:
        sl = lay.slice("lev")
        init["lever_arm_estimate"] = (lever - r.x[-1, sl]).tolist()     # δl = l_used − l_true
        init["lever_arm_sigma"] = r.sigma[-1, sl].tolist()
    if opt.aiding.estimate_vehicle:
        # the true mount is (I + ψ×) C_used: small angles added to pitch (x) and yaw (z)
        psi, s_psi = r.x[-1, lay.slice("vm")], r.sigma[-1, lay.slice("vm")]
        m0 = np.zeros(3) if opt.aiding.vehicle_mount is None else np.asarray(opt.aiding.vehicle_mount, float)
        init["vehicle_mount_estimate"] = [float(m0[0] + psi[0]), float(m0[1]), float(m0[2] + psi[1])]
        init["vehicle_mount_sigma"] = [float(s_psi[0]), None, float(s_psi[1])]
        sl = lay.slice("nlev")
        init["nhc_lever_estimate"] = (np.asarray(opt.aiding.nhc_lever_arm, float) - Cvb @ r.x[-1, sl]).tolist()
        init["nhc_lever_sigma"] = np.sqrt(np.diag(Cvb @ np.diag(r.sigma[-1, sl] ** 2) @ Cvb.T)).tolist()
        # a state the drive told little about keeps most of its prior σ: its estimate is the
        # prior's guess, not a measurement (a flat drive does not see the lever's height)
        init["nhc_lever_observable"] = [bool(x <= OBSERVED_SIGMA_RATIO * opt.aiding.nhc_lever_sigma)
                                        for x in init["nhc_lever_sigma"]]
        init["vehicle_mount_observable"] = [bool(s_psi[0] <= OBSERVED_SIGMA_RATIO * opt.aiding.vehicle_mount_sigma),
                                            None, bool(s_psi[1] <= OBSERVED_SIGMA_RATIO * opt.aiding.vehicle_mount_sigma)]
    return RecordedNav(r, init, opt, smoothed=smooth(r) if opt.grid.smooth else None)


def _spans(times, gap):
    """Sorted times [s] merged into ``[start, end]`` spans where consecutive ones are less
    than ``gap`` apart."""
    t = np.asarray(times, dtype=float)
    if t.size == 0:
        return []
    br = np.flatnonzero(np.diff(t) >= gap)
    return [[float(t[a]), float(t[b])] for a, b in zip(np.r_[0, br + 1], np.r_[br, t.size - 1])]


def _in_outages(t, outages):
    m = np.zeros(np.shape(t), bool)
    for s0, ln in outages:
        m |= (t >= s0) & (t < s0 + ln)
    return m


def _odometer(odo, aiding: AidingSpec, T, t_lo, t_hi):
    """The wheel-speed measurement of the options (vehicle axes: the mount is applied to
    the IMU on input), updated about ``odometer_rate`` times a second."""
    from sinslab.fusion.measurements import Odometer
    if odo.t[-1] < t_lo or odo.t[0] > t_hi:
        raise ValueError(f"odometer times ({odo.source}: {odo.t[0]:.3f}..{odo.t[-1]:.3f} s) do not "
                         f"overlap the IMU record ({t_lo:.3f}..{t_hi:.3f} s): different time bases?")
    every = max(1, int(round(1.0 / (aiding.odometer_rate * T))))
    return Odometer(odo.t, odo.speed, aiding.odometer_sigma, lever_arm=np.asarray(aiding.odometer_lever),
                    every=every, gate=aiding.aid_gate)


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
        lever_arm = res.init.get("lever_arm_estimate", res.options.fix.lever_arm)
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
    outs = res.init.get("outages", []) if outages is None else outages
    t, err, _ = fix_errors(res, fixes)
    starts, errs = [], []
    for s, ln in outs:
        m = np.flatnonzero((t >= s) & (t < s + ln))
        if m.size:
            starts.append(s)
            errs.append(float(np.hypot(err[m[-1], 0], err[m[-1], 1])))
    return np.array(starts), np.array(errs)


# ------------------------------------------------------------ IMU / fix time sync ---
__all__ += ["estimate_time_offset", "significant_time_offset", "shift_imu_time", "shifted_times"]


def estimate_time_offset(imu: ImuRecord, fixes: Fixes, *, window=60.0, min_speed=2.0,
                         search=1.0, step=0.005, lever_arm=None, gyro_bias=None):
    """Estimate how late the IMU time stamps are relative to the fixes, from turns.

    The IMU vertical-axis rate (body z, RFU; the vehicle is roughly level) is
    (each sample the mean over its interval) is cross-correlated with the course rate of
    the fix velocities (speed > ``min_speed``) in windows of ``window`` s (shortened so the
    overlap holds at least four; windows without a clear turn, peak correlation < 0.5,
    are skipped). The fix
    velocities are first moved from the antenna to the IMU point
    (``v − C (ω × l)`` with ``lever_arm`` l, vehicle RFU [m]): in a turn the antenna's course
    leads or lags the body's by ``l_y ω̇ / v``, which reads as a time offset of ``l_y / v``
    (0.1 s for 1 m at 10 m/s). A straight line through the per-window lags gives an offset
    and a clock-rate error, with standard errors from the scatter about the line.

    The same windows are also read along track (:func:`_speed_change_lags`: the forward
    specific force against the rate of change of the fixes' speed), which a lever arm
    cannot fake; :func:`significant_time_offset` applies an offset only when they confirm it.

    Returns ``{"offset": lag at t_ref [s], "offset_sigma", "t_ref", "ppm": drift
    [1e-6 s/s], "ppm_sigma", "windows": [(t_mid, lag, correlation), ...],
    "window_inv_speed": [mean 1/speed in each window's turns [s/m], ...], "lever_given",
    "speed_windows": [(t_mid, lag, correlation), ...]}`` (σ = inf when too few windows to
    judge; no window at all when the record has no turn: nothing to apply); the
    corrected IMU times are ``t − (offset + ppm·1e-6·(t − t_ref))``.
    :func:`significant_time_offset` keeps only what is significant.
    """
    if fixes.vel is None:
        raise ValueError("time-offset estimation needs fix velocities")
    lever = np.zeros(3) if lever_arm is None else np.asarray(lever_arm, dtype=float)
    gb = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, dtype=float)
    crs, sp = _imu_point_course(fixes, imu, lever, gb)
    crs = np.unwrap(crs)
    slow = sp < min_speed
    cr = -np.gradient(crs, fixes.t)                       # counter-clockwise rate
    cr[slow] = 0.0
    lo = max(fixes.t[0], imu.t[0]) + search
    hi = min(fixes.t[-1], imu.t[-1]) - search
    if hi - lo < 20.0:
        raise ValueError("IMU and fixes overlap too little to estimate a time offset")
    window = min(window, (hi - lo) / 4)
    nwin = max(1, int((hi - lo) // window))
    edges = np.linspace(lo, hi, nwin + 1)
    lags = np.arange(-search, search + step / 2, step)
    res, inv_speed = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        grid = np.arange(a, b, 0.02)
        ref = np.interp(grid, fixes.t, cr)
        if np.std(ref) < 1e-3:
            continue
        # the rate is the mean over its interval; the samples of this window only
        tw, wz = _rate_z_window(imu, grid[0] + lags[0], grid[-1] + lags[-1])
        c = np.array([np.corrcoef(np.interp(grid + o, tw, wz), ref)[0, 1] for o in lags])
        release_pages(imu.t, imu.dtheta)
        i = int(np.nanargmax(c))
        if c[i] < 0.5:                                        # no clear turn in this window
            continue
        if 0 < i < len(c) - 1:                                # parabolic refinement
            den = c[i - 1] - 2 * c[i] + c[i + 1]
            sh = 0.5 * (c[i - 1] - c[i + 1]) / den if den < 0 else 0.0
        else:
            sh = 0.0
        turning = np.abs(ref) > 0.3 * np.max(np.abs(ref))
        inv_v = float(np.mean(1.0 / np.maximum(np.interp(grid[turning], fixes.t, sp), min_speed)))
        res.append((0.5 * (a + b), float(lags[i] + sh * step), float(c[i])))
        inv_speed.append(inv_v)
    out = _lag_line(res, 0.5 * (lo + hi))
    out.update(windows=res, step=float(step), window_inv_speed=inv_speed, lever_given=lever_arm is not None,
               imu_dt=float(imu.dt), speed_windows=_speed_change_lags(imu, fixes, edges, lags, sp, min_speed))
    return out


def _lag_line(res, t_mid):
    """Offset at the mean window time and drift of the window lags ``res`` (a line, σ from
    the scatter about it; a mean with two windows; nothing to apply without a window)."""
    if not res:
        return {"offset": 0.0, "offset_sigma": math.inf, "t_ref": float(t_mid), "ppm": 0.0, "ppm_sigma": math.inf}
    tm = np.array([r[0] for r in res])
    lg = np.array([r[1] for r in res])
    t_ref = float(tm.mean())
    n = len(res)
    x = tm - t_ref
    if n >= 3:
        b_, a_ = np.polyfit(x, lg, 1)
        s2 = float(np.sum((lg - a_ - b_ * x) ** 2)) / (n - 2)
        sa, sb = math.sqrt(s2 / n), math.sqrt(s2 / float(np.sum(x ** 2)))
    else:
        b_, a_ = 0.0, float(lg.mean())
        sa = float(np.std(lg, ddof=1)) / math.sqrt(n) if n == 2 else math.inf
        sb = math.inf
    return {"offset": float(a_), "offset_sigma": sa, "t_ref": t_ref, "ppm": float(b_ * 1e6), "ppm_sigma": sb * 1e6}


def _speed_change_lags(imu, fixes, edges, lags, speed, min_speed, highpass=4.0):
    """Per window of ``edges``, the lag [s] of the IMU's forward specific force behind the
    rate of change of the fixes' speed: ``[(t_mid, lag, correlation), ...]``.

    A second look at the IMU clock that a lever arm cannot fake: an antenna ahead of the
    IMU delays its course in a turn by ``l_y / v`` (what the turn lags must take out with
    the lever arm) but not its speed, which a rigid body shares along track. Both signals
    are high-passed (a ``highpass`` s moving mean removed: the road grade's gravity and the
    accelerometer bias go), the IMU's averaged over one fix interval as the speed's
    difference quotient averages it; windows whose speed changes are weak (σ < 0.05 m/s²)
    or whose peak correlation is below 0.5 are skipped."""
    from scipy.ndimage import uniform_filter1d
    if len(fixes) < 3:
        return []
    acc = np.gradient(speed, fixes.t)
    step_f = float(np.median(np.diff(fixes.t)))
    n_hp, n_fix = max(1, int(round(highpass / 0.02))), max(1, int(round(2 * step_f / 0.02)))
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        grid = np.arange(a, b, 0.02)
        ref = np.interp(grid, fixes.t, acc)
        ref = ref - uniform_filter1d(ref, n_hp, mode="nearest")
        if np.std(ref) < 0.05:
            continue
        lo_k = max(0, int(np.searchsorted(imu.t, grid[0] + lags[0])) - 2)
        hi_k = min(len(imu), int(np.searchsorted(imu.t, grid[-1] + lags[-1])) + 3)
        tw = np.asarray(imu.t[lo_k:hi_k]) - 0.5 * imu.dt
        fy = np.asarray(imu.dv[lo_k:hi_k, 1]) / imu.dt
        c = np.empty(lags.size)
        for i, o in enumerate(lags):
            x = uniform_filter1d(np.interp(grid + o, tw, fy), n_fix, mode="nearest")
            c[i] = np.corrcoef(x - uniform_filter1d(x, n_hp, mode="nearest"), ref)[0, 1]
        release_pages(imu.t, imu.dv)
        i = int(np.nanargmax(c))
        if c[i] >= 0.5:
            out.append((0.5 * (a + b), float(lags[i]), float(c[i])))
    return out


def _lsq(X, y, k, p=0.01):
    """Least squares ``y ≈ X c``: coefficients, their standard errors from the scatter about
    the fit (inf without a degree of freedom left or for a singular X) and the multiple of
    the standard error that is significant: ``k``, or Student's t of the two-sided level
    ``p`` at the fit's degrees of freedom when larger (a σ from three windows is itself
    uncertain)."""
    from scipy.special import stdtrit      # Student's t quantile, without scipy.stats' import
    n, m = X.shape
    c = np.linalg.lstsq(X, y, rcond=None)[0]
    if n <= m or np.linalg.matrix_rank(X) < m:
        return c, np.full(m, math.inf), math.inf
    s2 = float(np.sum((y - X @ c) ** 2)) / (n - m)
    kt = max(k, float(-stdtrit(n - X.shape[1], p / 2)))
    return c, np.sqrt(np.maximum(np.diag(np.linalg.inv(X.T @ X)) * s2, 0.0)), kt


def significant_time_offset(est: dict, k: float = 3.0) -> dict:
    """The part of :func:`estimate_time_offset` to apply: only what the windows support
    beyond doubt.

    - The lags are fitted with a line (offset at ``t_ref`` and clock drift); the drift is
      applied only when significant (else the offset is re-estimated without it), the
      offset only when significant and larger than the lag resolution (the search step)
      and one IMU sample interval (the stamps resolve no less). Significant: beyond ``k``
      σ and beyond Student's t at the 1 % two-sided level for the fit's degrees of freedom
      (``threshold_sigmas``: 9.9σ with two degrees of freedom, 3.4σ with eight), σ from
      the scatter of the windows about the fit.
    - Without a lever arm (``est["lever_given"]`` False) a clock offset is confounded with
      the antenna's position: an antenna ``l`` ahead of the IMU lags the body's course by
      ``l / v``, a different lag at every speed (on one clock that lag is all there is:
      ignored, it read as a +0.24 s offset and a −1200 ppm clock). The lags are then fitted
      as ``τ + l / v_k`` too (``v_k`` the speed in window k's turns; ``speed_lag_m`` = l),
      and an offset (drift) is applied only when it is significant in both fits and the
      two agree within their σ; turns all at one speed cannot separate τ from l (σ of τ
      infinite: nothing applied).

    - The offset must also show in the speed changes (``est["speed_windows"]``): the same
      sign at one-sided 95 % (Student's t of their scatter) and within the threshold of the
      turns' value. A wrong lever arm reads in turns as an offset of ``l_y / v`` (on the
      one-clock n380 hill drive, a lever 1.5 m off read as a significant 268 ms); the speed
      changes, which a rigid body shares along track, do not move with it.

    Returns ``{"offset", "ppm", "t_ref", "offset_applied", "ppm_applied", "offset_sigma",
    "offset_estimate", "ppm_estimate", "ppm_sigma", "speed_lag_m", "speed_lag_sigma_m",
    "threshold_sigmas", "speed_change_offset", "speed_change_offset_sigma",
    "speed_change_windows", "offset_confirmed"}``.
    """
    w = est["windows"]
    lg = np.array([x[1] for x in w])
    xs = np.array([x[0] for x in w]) - est["t_ref"]
    floor = max(est.get("step", 0.0), est.get("imu_dt", 0.0))

    def fit(cols):
        """Offset (σ, applied?) and drift (σ, applied?) of the lags on ``cols`` + a line."""
        c, sc, kt = _lsq(np.column_stack([np.ones(lg.size), *cols, xs]), lg, k)
        ppm, s_ppm = float(c[-1] * 1e6), float(sc[-1] * 1e6)
        ppm_ok = math.isfinite(s_ppm) and abs(ppm) > kt * s_ppm
        if not ppm_ok:
            c, sc, kt = _lsq(np.column_stack([np.ones(lg.size), *cols]), lg, k)
        off_ok = math.isfinite(sc[0]) and abs(c[0]) > max(kt * sc[0], floor)
        return dict(off=float(c[0]), s_off=float(sc[0]), off_ok=bool(off_ok), ppm=ppm, s_ppm=s_ppm,
                    ppm_ok=bool(ppm_ok), kt=kt, c=c, sc=sc)

    r = fit([])
    out = {"t_ref": est["t_ref"], "speed_lag_m": None, "speed_lag_sigma_m": None}
    if not est.get("lever_given", True):
        j = fit([np.asarray(est["window_inv_speed"], float)])
        out.update(speed_lag_m=float(j["c"][1]), speed_lag_sigma_m=float(j["sc"][1]))
        # beyond doubt: significant with and without the lever term, and the same
        for a_, s_, ok_ in (("off", "s_off", "off_ok"), ("ppm", "s_ppm", "ppm_ok")):
            agree = abs(r[a_] - j[a_]) <= j["kt"] * math.hypot(r[s_], j[s_])
            j[ok_] = bool(j[ok_] and r[ok_] and agree)
        r = j
    sw = est.get("speed_windows")
    if sw is not None:
        # a second signature the lever arm cannot fake: the speed changes must show the
        # offset too — the same sign at 95 % (Student's t), and within the turn fit's
        # significance threshold of it — or it is not applied (a wrong lever arm makes the
        # turns alone read a lag of l_y / v as an offset)
        ls = np.array([x[1] for x in sw], dtype=float)
        c2, sc2, _ = _lsq(np.ones((ls.size, 1)), ls, k) if ls.size else (np.array([math.nan]), [math.inf], math.inf)
        from scipy.special import stdtrit
        t95 = float(-stdtrit(max(ls.size - 1, 1), 0.05))           # one-sided 95 %: the sign is tested
        seen = bool(math.isfinite(sc2[0]) and abs(c2[0]) > t95 * sc2[0] and np.sign(c2[0]) == np.sign(r["off"])
                    and abs(c2[0] - r["off"]) <= r["kt"] * math.hypot(sc2[0], r["s_off"]))
        out.update(speed_change_offset=float(c2[0]) if ls.size else None,
                   speed_change_offset_sigma=float(sc2[0]) if ls.size else None,
                   speed_change_windows=int(ls.size), offset_confirmed=seen)
        if r["off_ok"] and not seen:
            r = dict(r, off_ok=False)
    out.update(offset=r["off"] if r["off_ok"] else 0.0, ppm=r["ppm"] if r["ppm_ok"] else 0.0,
               offset_applied=r["off_ok"], ppm_applied=r["ppm_ok"], offset_sigma=r["s_off"],
               offset_estimate=r["off"], ppm_estimate=r["ppm"], ppm_sigma=r["s_ppm"], threshold_sigmas=r["kt"])
    return out


def shifted_times(t, offset=0.0, ppm=0.0, t_ref=0.0):
    """IMU times corrected by a clock offset and drift: ``t − (offset + ppm·1e-6·(t − t_ref))`` [s]."""
    return t - (offset + ppm * 1e-6 * (t - t_ref))


def shift_imu_time(imu: ImuRecord, offset=0.0, ppm=0.0, t_ref=0.0) -> ImuRecord:
    """IMU record with times :func:`shifted_times` (uniform grid kept)."""
    return ImuRecord(shifted_times(imu.t, offset, ppm, t_ref), imu.dtheta, imu.dv, imu.dt * (1.0 - ppm * 1e-6))
