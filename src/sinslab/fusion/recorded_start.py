"""The start of a recorded run: the attitude, position and velocity the filter starts
from, found in the data (:func:`solve_start`, :class:`StartSolution`).

Levelling from the mean specific force of the stationary stretch at the start of the
record (fix speed below ``static_speed``); the mean gyro output there (minus the
Earth-rate vertical component) is the initial gyro-bias estimate (MEMS biases are
hundreds of °/h, 40x the Earth rate, so gyrocompassing is impossible and the rest is used
to calibrate instead). Heading: given (``heading``), or taken from the fix velocity once
the vehicle moves faster than ``move_speed`` (the INS attitude is propagated from the
levelled start by the gyros and rotated about the vertical so that the body forward axis
points along the fix course; a car does not drive sideways). The filter starts there.
Without a rest at the start (a flight, a log begun on the move) pitch and roll come from
the fix velocity against the integrated specific force over the first seconds
(:func:`level_in_motion`), the heading from the course as above. Where the gyros would
carry that levelling to the start too long (a taxi and a launch; ``CARRY_LIMIT``), the
whole attitude comes instead from an in-motion alignment over the fixes just before the
start (:mod:`sinslab.nav.motion_alignment`; its heading where its σ beats the course's).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.core import units
from sinslab.core.blocks import BLOCK_ROWS, release_pages
from sinslab.core.records import Fixes, ImuRecord, NavState
from sinslab.core.stamps import stamp_step, whole_intervals
from sinslab.fusion.recorded_spec import ErrorSpec, StartSpec

__all__ = ["StartSolution", "Rest", "Level", "MotionFit", "solve_start", "level_from_rest", "level_in_motion",
           "leveled_start", "moving_speed_threshold", "fix_velocity", "fix_speed", "platform_kind", "fixes_dt",
           "AIRCRAFT_MOVE_SPEED", "AIRCRAFT_MAX_ROLL", "AIRCRAFT_CRAB_SIGMA", "CARRY_LIMIT"]

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
    m = align_in_motion(imu, fixes.t, fix_velocity(fixes), fixes.lat, fixes.h, k0, min(k1, len(imu)))
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
    return align_in_motion(imu, fixes.t, fix_velocity(fixes), fixes.lat, fixes.h, k0, ks, gb)


def _start_by_alignment(imu, fixes, k0, gb, start: StartSpec, move):
    """The start found by the first in-motion alignment after IMU sample ``k0`` whose
    heading σ beats the heading prior (:func:`sinslab.nav.motion_alignment.first_alignment`):
    ``((ks, C_b^n, heading σ, description), fit)``. Refuses, naming what the record lacks
    with its figures, when no window of the record qualifies."""
    from sinslab.nav.motion_alignment import first_alignment
    sc = first_alignment(imu, fixes.t, fix_velocity(fixes), fixes.lat, fixes.h, float(imu.t[k0] - imu.dt),
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


def leveled_start(imu, fixes: Fixes, start: StartSpec):
    """Index range ``(k0, k1)`` of the initial rest (see module notes) or None: until the
    first fix faster than ``static_speed``; when that leaves less than 1 s (a receiver
    whose speed noise exceeds ``static_speed``), until the first fix faster than three
    times its own speed noise (:func:`moving_speed_threshold`)."""
    sp = fix_speed(fixes)
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


def fix_speed(fixes: Fixes):
    """Horizontal speed [m/s] of the fixes (their velocity, or differenced positions)."""
    if fixes.vel is not None:
        return np.hypot(fixes.vel[:, 0], fixes.vel[:, 1])
    rm, rn = E.radii(fixes.lat, fixes.h)
    n = np.gradient(fixes.lat, fixes.t) * rm
    e = np.gradient(fixes.lon, fixes.t) * rn * np.cos(fixes.lat)
    return np.hypot(e, n)


def fix_velocity(fixes: Fixes):
    """ENU velocity [m/s] (J, 3) of the fixes (theirs, or differenced positions)."""
    if fixes.vel is not None:
        return fixes.vel
    rm, rn = E.radii(fixes.lat, fixes.h)
    return np.stack([np.gradient(fixes.lon, fixes.t) * rn * np.cos(fixes.lat),
                     np.gradient(fixes.lat, fixes.t) * rm, np.gradient(fixes.h, fixes.t)], -1)


def _interp_fix(fixes, t):
    lat = np.interp(t, fixes.t, fixes.lat)
    lon = np.interp(t, fixes.t, fixes.lon)
    h = np.interp(t, fixes.t, fixes.h)
    v = fix_velocity(fixes)
    vel = np.array([np.interp(t, fixes.t, v[:, i]) for i in range(3)])
    return lat, lon, h, vel


def _imu_pos_from_antenna(lat, lon, h, C, lever):
    d = C @ lever                                      # ENU offset IMU -> antenna
    rm, rn = E.radii(lat, h)
    return lat - d[1] / float(rm), lon - d[0] / (float(rn) * math.cos(lat)), h - d[2]


def _imu_point_course(fixes: Fixes, imu, lever, gb):
    """Course [rad, clockwise from north] and speed of the IMU point at the fix times: the
    antenna velocity minus ``C (ω × l)``, with ω the vertical gyro (bias ``gb`` removed) and
    C's horizontal axes from the course itself (a car does not drive sideways)."""
    v = fix_velocity(fixes)
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
    v = fix_velocity(fixes)
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




# ------------------------------------------------------------------- the start solution
@dataclass(frozen=True)
class Rest:
    """The stationary stretch the run starts with: IMU samples ``k0:k1``, from ``t0`` to
    ``t1`` [s]; the mean gyro output there ``gyro_mean`` (3,) [rad/s] (minus the Earth
    rate's vertical part), ``f_norm`` ‖mean specific force‖ [m/s²], and the white noise
    measured there, ``gyro_noise`` [rad/√s] and ``accel_noise`` [m/s/√s] (3,) each."""

    k0: int
    k1: int
    t0: float
    t1: float
    gyro_mean: np.ndarray
    f_norm: float
    gyro_noise: np.ndarray
    accel_noise: np.ndarray


@dataclass(frozen=True)
class Level:
    """Pitch and roll [rad] as levelled (at the rest or in motion), how (``source``, None
    at a rest) and the residual of an in-motion levelling [m/s] (None otherwise)."""

    pitch: float | None
    roll: float | None
    source: str | None = None
    residual: float | None = None


@dataclass(frozen=True)
class MotionFit:
    """The in-motion alignment the start took its attitude from: over ``window_s`` s of
    ``fixes`` before the start, a-posteriori velocity σ ``sigma_v`` [m/s], attitude σ
    (pitch, roll, yaw) [rad], whether its heading was used, and how long [s] the gyros
    would have carried the levelling instead."""

    window_s: float
    fixes: int
    sigma_v: float
    sigma: tuple
    heading: bool
    carried_s: float


@dataclass(frozen=True)
class StartSolution:
    """Where and how the filter starts (:func:`solve_start`).

    Attributes
    ----------
    t : float
        Start time [s] (the end of IMU sample ``k - 1``).
    k : int
        First IMU sample of the filter.
    att : ndarray (3,)
        ``[pitch, roll, yaw]`` [rad] of the body at the start.
    position : tuple
        ``(lat, lon, h)`` [rad, rad, m] of the IMU point.
    velocity : ndarray (3,)
        ENU [m/s] (the fixes' at the start).
    sigma : ndarray (3,)
        Prior σ of the attitude errors φE, φN, φU [rad].
    heading_source : str
    heading_sigma : float or None
        1σ [rad] of the heading found in motion (None: given).
    level : Level
    rest : Rest or None
    motion_fit : MotionFit or None
    tilt_carried_s : float
        How long [s] the gyros carried the rest's levelling to the start, when the tilt
        σ was widened for it (0 otherwise).
    tilt_sigma : float or None
        Prior σ of pitch and roll when widened (a carry or an in-motion fit).
    gyro_bias : ndarray (3,)
        Initial gyro-bias compensation [rad/s] (the rest's mean rate, or zero).
    gyro_noise, accel_noise : ndarray (3,)
        White noise the filter assumes [rad/√s], [m/s/√s].
    """

    t: float
    k: int
    att: np.ndarray
    position: tuple
    velocity: np.ndarray
    sigma: np.ndarray
    heading_source: str
    heading_sigma: float | None
    level: Level
    rest: Rest | None
    motion_fit: MotionFit | None
    tilt_carried_s: float
    tilt_sigma: float | None
    gyro_bias: np.ndarray
    gyro_noise: np.ndarray
    accel_noise: np.ndarray

    @property
    def pitch(self):
        return float(self.att[0])

    @property
    def roll(self):
        return float(self.att[1])

    @property
    def heading(self):
        """Heading clockwise from north [rad], 0..2π."""
        return float(np.mod(A.yaw_to_heading(self.att[2]), 2 * np.pi))

    @property
    def nav_state(self) -> NavState:
        """The initial navigation state of the IMU point."""
        return NavState(*self.position, self.velocity, self.att)


def _rest_level(imu, fixes, start: StartSpec, errors: ErrorSpec, lat0):
    """``(k0, Level, Rest or None, gyro bias, gyro noise, accel noise)``: levelled at the
    initial rest (its mean rate the gyro bias, its scatter the white noise unless
    ``errors.rest_noise`` is off) or, without one, in motion from the first fix on."""
    dt = imu.dt
    rest = leveled_start(imu, fixes, start)
    gb = np.zeros(3)
    g_noise, a_noise = np.asarray(errors.gyro_arw), np.asarray(errors.accel_vrw)
    if rest is not None:
        k0, k1 = rest
        pitch, roll, wb, fmean = level_from_rest(imu, k0, k1, lat0)
        if errors.rest_bias:
            gb = wb.copy()
        # white-noise densities of the unit as it stands (engine vibration included)
        sq = math.sqrt(dt)
        g_meas = np.std(imu.dtheta[k0:k1], 0) / dt * sq
        a_meas = np.std(imu.dv[k0:k1], 0) / dt * sq
        if errors.rest_noise:
            g_noise, a_noise = np.maximum(g_meas, errors.gyro_arw), np.maximum(a_meas, errors.accel_vrw)
        r = Rest(k0, k1, float(imu.t[k0] - dt), float(imu.t[k1 - 1]), wb, float(np.linalg.norm(fmean)),
                 g_meas, a_meas)
        return k0, Level(pitch, roll), r, gb, g_noise, a_noise
    # no standstill (an aircraft, a log started on the move): level in motion from the
    # GNSS acceleration against the specific force, from the first fix on
    k0 = int(np.searchsorted(imu.t, max(imu.t0, float(fixes.t[0])) + dt - 1e-9))
    lv = level_in_motion(imu, fixes, k0, lat0, start.level_window)
    if lv is None:
        level = Level(None, None, "none: no rest and too few fixes in motion; pitch and roll start at 0 "
                      "with the initial attitude σ")
    else:
        pitch, roll, n_used, resid = lv
        level = Level(pitch, roll, f"in motion: fix velocity against the integrated specific force at "
                      f"{n_used} fixes (no rest at the start)", resid)
    return k0, level, None, gb, g_noise, a_noise


def _heading(imu, fixes, k0, level, start: StartSpec, lever, gb, nsub, aircraft):
    """``(ks, att, heading σ or None, how, forced fit or None)``: the heading given, or found
    in motion (:func:`_heading_in_motion`) from the levelled attitude, or, without a
    straight stretch, from the first in-motion alignment that shows it
    (:func:`_start_by_alignment`, whose fit is then the start's)."""
    from sinslab.nav import strapdown as sd
    pitch, roll = (0.0, 0.0) if level.pitch is None else (level.pitch, level.roll)
    if start.heading is not None:
        return k0, np.array([pitch, roll, A.heading_to_yaw(start.heading)]), None, "given", None
    lat0 = float(fixes.lat[0])
    pre = sd.initial_state_array(NavState(lat0, float(fixes.lon[0]), float(fixes.h[0]),
                                          np.zeros(3), np.array([pitch, roll, 0.0])))
    # an aircraft is carried, taxied and launched before its course shows its heading
    move = max(start.move_speed, AIRCRAFT_MOVE_SPEED) if aircraft else start.move_speed
    found = _heading_in_motion(fixes, imu, k0, pre, nsub, start, lever, gb, move,
                               AIRCRAFT_MAX_ROLL if aircraft else math.inf)
    forced = None
    if found is None:
        # no straight, level stretch (an aircraft in continuous turns): the in-motion
        # alignment sees the heading through the turns' accelerations instead
        found, forced = _start_by_alignment(imu, fixes, k0, gb, start, move)
    ks, C, h_sig, how = found
    return ks, A.dcm_to_euler(C), h_sig, how, forced


def _motion_fit(imu, fixes, ks, ts, t_lev, att0, h_sig, gb, g_noise, start: StartSpec, errors: ErrorSpec,
                aircraft, forced=None):
    """The in-motion alignment before the start where the gyros would carry the levelling
    too long: when the tilt the residual gyro bias (its prior σ) and the white noise may
    add on the way dominates the levelling's own σ (``CARRY_LIMIT`` times it) and the fit
    says it is better; or the ``forced`` fit the heading came from. Returns ``(att,
    MotionFit or None, fit or None, carried [s], tilt [rad], heading σ, heading source or
    None)``."""
    carried = max(float(ts - t_lev), 0.0)
    tilt = math.hypot(float(np.max(errors.gyro_bias_sigma)) * carried, float(np.max(g_noise)) * math.sqrt(carried))
    long_carry = start.motion_alignment and tilt > CARRY_LIMIT * max(start.att_sigma[:2])
    fit = forced if forced is not None else (
        _align_at_start(imu, fixes, ks, gb, start.level_window) if long_carry else None)
    if fit is None or not (forced is not None or float(np.max(fit.sigma[:2])) < tilt):
        return att0, None, None, carried, tilt, h_sig, None
    h_fit = math.hypot(float(fit.sigma[2]), start.heading_sigma_floor)
    course = math.inf if start.heading is not None else math.hypot(h_sig, (
        AIRCRAFT_CRAB_SIGMA if aircraft else start.heading_sigma_floor))
    use_h = forced is not None or h_fit < course
    att = np.r_[fit.att[:2], fit.att[2] if use_h else att0[2]]
    mf = MotionFit(fit.span, fit.n_vectors, fit.sigma_v, tuple(fit.sigma.tolist()), bool(use_h), carried)
    if not use_h:
        return att, mf, fit, carried, tilt, h_sig, None
    return att, mf, fit, carried, tilt, float(fit.sigma[2]), (
        f"in-motion alignment over {fit.span:.1f} s of fixes before the start (fix velocity against "
        "the integrated specific force)")


def _attitude_sigma(start: StartSpec, h_sig, mf, fit, aircraft, rest, ts, carried, tilt):
    """Prior σ of φE, φN, φU (3,) [rad], the carried time and the widened tilt σ."""
    s = np.zeros(3)
    s[:] = start.att_sigma
    if h_sig is not None:
        # the heading found in motion, its σ widened by what the window cannot see (a
        # slip angle, a mount yaw error of a few tenths of a degree), never above the prior
        s[2] = min(start.att_sigma[2], math.hypot(h_sig, start.heading_sigma_floor))
        if mf is not None and mf.heading:
            # the fit's heading (specific force against the fix velocity: no crab, no slip)
            s[2] = math.hypot(h_sig, start.heading_sigma_floor)
        elif aircraft:
            # an aircraft crabs into the wind: its course is its heading only to ~10°
            s[2] = math.hypot(h_sig, AIRCRAFT_CRAB_SIGMA)
    if fit is not None:
        # the levelling σ (an accelerometer bias tilts a fit as it tilts a rest) and the fit's own
        s[0:2] = np.hypot(s[0:2], fit.sigma[:2])
        return s, 0.0, float(np.max(s[0:2]))
    if rest is not None and ts > rest.t1:
        # levelled at the rest and carried by the gyros to the start (a taxi and a launch, a
        # slow first stretch): the σ at the start grows with the tilt they may add on the way
        s[0:2] = np.hypot(s[0:2], tilt)
        return s, carried, float(np.max(s[0:2]))
    return s, 0.0, None


def solve_start(imu: ImuRecord, fixes: Fixes, start: StartSpec, errors: ErrorSpec, lever, nsub,
                platform=("land", "")) -> StartSolution:
    """The start of the filter from the data (see the module notes): levelling, heading,
    in-motion alignment where the levelling would be carried too long, and the IMU point's
    position and velocity at the start from the fixes (antenna, ``lever`` body axes [m]).

    Raises ValueError when the vehicle never moves fast and straight enough for a heading
    and none is given."""
    dt = imu.dt
    lat0 = float(fixes.lat[0])
    aircraft = platform[0] == "aircraft"
    k0, level, rest, gb, g_noise, a_noise = _rest_level(imu, fixes, start, errors, lat0)
    ks, att0, h_sig, how, forced = _heading(imu, fixes, k0, level, start, lever, gb, nsub, aircraft)
    ts = (float(imu.t[ks] - dt) if ks > 0 else imu.t0) if start.heading is not None else \
        (float(imu.t[ks - 1]) if ks > 0 else imu.t0)
    t_lev = rest.t1 if rest is not None else float(imu.t[k0] - dt)
    att0, mf, fit, carried, tilt, h_sig, how_fit = _motion_fit(imu, fixes, ks, ts, t_lev, att0, h_sig, gb,
                                                               g_noise, start, errors, aircraft, forced)
    sigma, carried_s, tilt_sigma = _attitude_sigma(start, h_sig, mf, fit, aircraft, rest, ts, carried, tilt)
    lat_a, lon_a, h_a, v0 = _interp_fix(fixes, ts)
    C0 = A.euler_to_dcm(att0)
    pos = _imu_pos_from_antenna(lat_a, lon_a, h_a, C0, np.asarray(lever, dtype=float))
    return StartSolution(ts, ks, att0, pos, v0, sigma, how_fit or how, h_sig, level, rest, mf, carried_s,
                         tilt_sigma, gb, np.broadcast_to(g_noise, (3,)).copy(),
                         np.broadcast_to(a_noise, (3,)).copy())
