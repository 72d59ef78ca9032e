"""Schuler oscillation suppression by delayed alignment (paper 004).

Method: Zhao Lin, Li Jiushun, Cheng Jianhua, Jia Chun, Wang Qiufan, "Schuler oscillation
restriction of shipborne SINS based on delayed alignment", Systems Engineering and
Electronics 38(10), 2016 (paper 004 of this project).

Principle (paper §2, eqs 6–10, re-derived)
-------------------------------------------
Two strapdown solutions run on one IMU stream. Solution 1 aligns on ``[t0, t1]`` and
navigates from t1; solution 2 keeps aligning until ``t2 = t1 + T_s/2`` (T_s = 2π/ω_s, the
local Schuler period) and navigates from t2. A converged alignment leaves the same
residual errors whenever it stops (they are set by the sensor biases, paper 000), so on a
base whose motion does not depend on time the two error histories are the same function
of the time since the start of navigation: ``e1(t) = f(t − t1)``, ``e2(t) = f(t − t2)``.
For the Schuler part ``f_s(t) = A sin(ω_s t + α)``,

    ½ [f_s(t − t1) + f_s(t − t1 − π/ω_s)] = ½ A [sin(θ) + sin(θ − π)] = 0,

while a 24 h part ``B sin(ω_ie t + β)`` becomes ``B cos(ω_ie π/(2ω_s)) sin(...)`` — scaled by
cos(π·T_s/(2·86164 s)) ≈ 0.996, i.e. kept. A Foucault-modulated Schuler term
``A cos(ω_f t) sin(ω_s t)`` (paper eq 11, ω_f = ω_ie sin L) is not cancelled: its mean is
``−A sin(ω_f T_s/4) sin(ω_f (t − T_s/4)) sin(ω_s t)``, a residual of ``sin(ω_f T_s/4)``
(≈ 0.066 at 45.75°), so on a still base the mean reduces the Schuler band by at most
``1/sin(ω_f T_s/4)`` (≈ 15×). Line by line, a component of frequency ω is scaled by
``|cos(ω d/2)|`` for a delay d (:func:`mean_factors`). From t2 on, the output is the mean of
the two solutions (paper eq 12) — position, velocity and attitude (quaternion mean).

What the mean does *not* remove: oscillations excited after t2 (manoeuvres, sensor noise)
are excited identically in both solutions, so they stay in the mean; the method removes the
Schuler oscillation that the initial (alignment) errors and the constant sensor errors
started. Undamped navigation, no external aid; the vertical channel is held.

API
---
:func:`delayed_alignment` — the full method on any IMU record (simulated or recorded) at a
known site: coarse alignment (inertial-frame by default, valid on a swaying base, or the
analytic double-vector one) on ``[t0, t0 + coarse_time]``, then the Kalman fine alignment
of :mod:`sinslab.methods.alignment`, run twice on prefixes of the same stream — to t1 for solution 1
and to t2 for solution 2 — so each solution starts from its own real alignment; then both
navigate in one pass over the remaining data (chunks of the stream step both states).

:func:`delayed_injected` — the paper's simulation mode: both solutions start from the truth
plus the same injected initial errors, at t1 and at t2.

:func:`navigate_pair` — the shared core: two given initial states at two epochs of one
record, one pass, outputs on a common grid and their mean.

Times ``t1``, ``coarse_time``, ``delay`` are durations [s] measured from the start of the
record (``imu.t0``); the output series carry the record's own time stamps.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sinslab.methods import alignment as al
from sinslab.core import attitude as att_
from sinslab.core import earth, units
from sinslab.nav import strapdown
from sinslab.core.records import ImuRecord, NavSeries, NavState
from sinslab.core.errors import InputError

__all__ = ["AlignmentOptions", "InitialErrors", "DelayedResult", "half_schuler_delay", "mean_factors",
           "delayed_alignment", "delayed_injected", "navigate_pair", "mean_solution",
           "check_delay"]


def half_schuler_delay(lat, h=0.0) -> float:
    """T_s/2 = π sqrt(R/g) [s] at latitude ``lat`` [rad] and height ``h`` [m] (≈ 42.2 min)."""
    return 0.5 * float(earth.schuler_period(lat, h))


def mean_factors(lat, delay=None, h=0.0) -> dict:
    """How the mean of two solutions ``delay`` apart scales each line of a time-invariant
    error history: ``|½ (1 + e^{−iωd})| = |cos(ω d/2)|`` for the Schuler line ω_s, the
    Foucault side lines ω_s ∓ ω_f (ω_f = ω_ie sin L) and the 24 h line ω_ie.

    With the default delay T_s/2 the Schuler line is cancelled (0), both side lines are
    scaled by ``sin(ω_f T_s/4)`` and the 24 h line by ``cos(ω_ie T_s/4)``; on a still base,
    where the history is Foucault-modulated, ``1/sin(ω_f T_s/4)`` is the most the mean can
    reduce the Schuler band by. Returns ``{"schuler", "schuler_minus", "schuler_plus",
    "earth"}``: factors (mean / single amplitude, 0..1).
    """
    d = half_schuler_delay(lat, h) if delay is None else check_delay(delay)
    ws = float(earth.schuler_frequency(lat, h))
    wf = abs(float(earth.foucault_frequency(lat)))
    return {name: abs(math.cos(w * d / 2.0))
            for name, w in (("schuler", ws), ("schuler_minus", ws - wf), ("schuler_plus", ws + wf),
                            ("earth", earth.WIE))}


def check_delay(delay) -> float:
    """A delay as seconds: a positive finite number [s] or a time string (``"42.2 min"``)."""
    if isinstance(delay, bool):
        raise ValueError(f"delay must be a positive duration, got {delay!r}")
    if isinstance(delay, str):
        try:
            d = units.parse(delay, "time")
        except ValueError as e:
            raise ValueError(f"delay must be a positive duration: {e}") from None
    else:
        try:
            d = float(delay)
        except (TypeError, ValueError):
            raise ValueError(f"delay must be a positive duration, got {delay!r}") from None
    if not (math.isfinite(d) and d > 0):
        raise ValueError(f"delay must be a positive duration, got {delay!r}")
    return d


@dataclass(frozen=True)
class AlignmentOptions:
    """How both solutions align (the same settings for both; only the stop time differs).

    Attributes
    ----------
    coarse : {"inertial", "analytic"}
        Coarse method on ``[0, coarse_time]``: the inertial-frame (gravity integration)
        method for a swaying base, or the double-vector one for a base at rest.
    coarse_time : float
        Length of the coarse alignment [s].
    model : {"reduced", "full"}
        Fine-alignment Kalman model (paper 000: 5 or 8 states).
    period : float
        Fine-alignment filter period [s].
    gyro_arw, accel_vrw : float or None
        Noise densities [rad/√s], [m/s/√s] used to tune the fine filter. On a swaying
        base give them (the data-derived defaults of :func:`sinslab.methods.alignment.fine_align`
        count the sway as noise).
    p0_att : tuple of 3 floats or None
        1σ initial misalignment [rad] of the fine filter (None: its default).
    compensate_gyro : bool
        Subtract the estimated n-frame drift (εN, εU combinations of the reduced model,
        or ε of the full model) as a body-frame gyro bias while navigating. Off by
        default (the paper compensates nothing).
    """

    coarse: str = "inertial"
    coarse_time: float = 300.0
    model: str = "reduced"
    period: float = 1.0
    gyro_arw: float | None = None
    accel_vrw: float | None = None
    p0_att: tuple | None = None
    compensate_gyro: bool = False

    def __post_init__(self):
        if self.coarse not in ("inertial", "analytic"):
            raise ValueError(f"coarse must be 'inertial' or 'analytic', got {self.coarse!r}")
        if self.model not in ("reduced", "full"):
            raise ValueError(f"model must be 'reduced' or 'full', got {self.model!r}")
        for name in ("coarse_time", "period"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive duration [s], got {v!r}")


@dataclass(frozen=True)
class InitialErrors:
    """Errors injected into both solutions' initial states (computed − true).

    Attributes
    ----------
    att : (3,)
        ``[pitch, roll, yaw]`` errors [rad] of the Euler angles (heading error = −yaw error).
    vel : (3,)
        ``[vE, vN, vU]`` errors [m/s].
    pos : (3,)
        ``[lat, lon, h]`` errors [rad, rad, m].
    """

    att: tuple = (0.0, 0.0, 0.0)
    vel: tuple = (0.0, 0.0, 0.0)
    pos: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        for name in ("att", "vel", "pos"):
            a = np.asarray(getattr(self, name), dtype=float).reshape(-1)
            if a.shape != (3,) or not np.all(np.isfinite(a)):
                raise ValueError(f"initial {name} errors must be 3 finite numbers, got "
                                 f"{getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(x) for x in a))

    def apply(self, s: NavState) -> NavState:
        """The true state ``s`` with these errors added."""
        return NavState(s.lat + self.pos[0], s.lon + self.pos[1], s.h + self.pos[2],
                        s.vel + np.asarray(self.vel), att_.wrap_pi(s.att + np.asarray(self.att)),
                        s.t)


@dataclass(frozen=True)
class DelayedResult:
    """Both solutions and their mean.

    Attributes
    ----------
    sol1 : NavSeries
        Solution 1 from t1 to the end.
    sol2 : NavSeries
        Solution 2 from t2 to the end (same epochs as ``sol1`` from t2 on).
    mean : NavSeries
        Mean of the two from t2 on (position, velocity; attitude as the normalised
        quaternion mean). ``att`` is the carrier attitude when a mount was given,
        ``att_imu`` the IMU's.
    t1, t2 : float
        Epochs [s] (record time) at which the solutions start navigating.
    delay : float
        ``t2 − t1`` [s] as realised on the sample grid.
    schuler_period : float
        T_s [s] used for the default delay.
    init1, init2 : NavState
        Initial states of the two solutions (IMU attitude).
    mode : str
        ``"aligned"`` or ``"injected"``.
    align1, align2 : FineAlignment or None
        The two fine alignments (aligned mode).
    coarse : CoarseAlignment or None
    gyro_bias1, gyro_bias2 : ndarray (3,) or None
        Body-frame gyro biases compensated in each solution (``compensate_gyro``).
    """

    sol1: NavSeries
    sol2: NavSeries
    mean: NavSeries
    t1: float
    t2: float
    delay: float
    schuler_period: float
    init1: NavState
    init2: NavState
    mode: str
    align1: object = None
    align2: object = None
    coarse: object = None
    gyro_bias1: np.ndarray | None = None
    gyro_bias2: np.ndarray | None = None
    notes: tuple = field(default=())

    @property
    def sol1_from_t2(self) -> NavSeries:
        """Solution 1 on the epochs of ``mean``."""
        k = int(np.searchsorted(self.sol1.t, self.mean.t[0] - 1e-9))
        return self.sol1.at(slice(k, k + len(self.mean)))


# ------------------------------------------------------------------------ helpers
def _gcd_lcm(a, b):
    return a * b // math.gcd(a, b)


def mean_solution(rows1, rows2):
    """Mean of two state-row arrays (same epochs): arithmetic for v, lat, lon, h; for the
    attitude the normalised sum of the quaternions (sign-aligned), which is the rotation
    halfway between the two (exact for a pair)."""
    out = 0.5 * (rows1 + rows2)
    q1, q2 = rows1[:, :4], rows2[:, :4]
    sgn = np.where(np.sum(q1 * q2, axis=1) < 0, -1.0, 1.0)[:, None]
    q = q1 + sgn * q2
    out[:, :4] = q / np.linalg.norm(q, axis=1, keepdims=True)
    return out


def navigate_pair(imu: ImuRecord, init1: NavState, e1: int, init2: NavState, e2: int, *,
                  nsub=2, out_every=1, vertical="hold", height=None, mount=None,
                  gyro_bias1=None, gyro_bias2=None, chunk=1 << 19, progress=None):
    """Navigate two solutions through one record in one pass.

    Parameters
    ----------
    imu : ImuRecord
    init1, init2 : NavState
        Initial states (IMU attitude) at epochs ``e1 < e2`` (epoch index: 0 = ``imu.t0``,
        ``k + 1`` = end of sample k).
    e1, e2 : int
        ``e2 − e1`` must be a multiple of ``nsub·out_every`` (common output grid).
    nsub, out_every : int
        Samples per update; output every ``out_every`` updates.
    vertical : {"hold", "free", "damped"}
        Vertical channel; "hold"/"damped" use ``height``.
    height : float, array (N + 1,) or None
        Held / reference height [m] (None: each solution's initial height, constant).
    mount : array (N + 1, 3) or None
        Mount Euler angles of C_imu^carrier at the epochs (output carrier attitude).
    gyro_bias1, gyro_bias2 : (3,) or None
        Body-frame gyro biases [rad/s] each solution compensates.

    Returns
    -------
    (sol1, sol2, mean) : NavSeries
    """
    n_all = len(imu)
    oes = int(nsub) * int(out_every)
    if not 0 <= e1 < e2 < n_all:
        raise ValueError(f"start epochs must satisfy 0 <= e1 < e2 < {n_all}, got {e1}, {e2}")
    if (e2 - e1) % oes:
        raise ValueError(f"e2 − e1 = {e2 - e1} samples is not a multiple of nsub·out_every = {oes}")
    nend = e1 + ((n_all - e1) // oes) * oes
    if nend <= e2:
        raise ValueError("no complete output interval after the second start")
    hmode = vertical in ("hold", "damped")
    if hmode and height is not None and np.ndim(height) > 0:
        height = np.asarray(height, dtype=float)
        if height.shape != (n_all + 1,):
            raise ValueError(f"height must have {n_all + 1} epochs, got shape {height.shape}")
    s1 = strapdown.initial_state_array(init1)
    s2 = strapdown.initial_state_array(init2)
    m1 = (nend - e1) // oes
    m2 = (nend - e2) // oes
    rows1 = np.empty((m1 + 1, strapdown.NAV))
    rows2 = np.empty((m2 + 1, strapdown.NAV))
    rows1[0] = s1[:strapdown.NAV]
    rows2[0] = s2[:strapdown.NAV]
    csz = max(oes, (int(chunk) // oes) * oes)
    bounds = sorted(set(list(range(e1, nend, csz)) + [e2, nend]))
    r1 = r2 = 1
    dt = imu.dt

    def hslice(h0, a, b):
        if not hmode:
            return None
        if height is None:
            return h0
        if np.ndim(height) == 0:
            return float(height)
        return height[a:b + 1]

    from sinslab.core.progress import progress as bar
    h1, h2 = init1.h, init2.h
    with bar("navigating two solutions", total=nend - e1, unit="samples",
             enabled=progress is not False) as pb:
        for a, b in zip(bounds[:-1], bounds[1:]):
            kw = dict(vertical=vertical, out_every=int(out_every))
            u = strapdown.step(s1, imu.dtheta[a:b], imu.dv[a:b], dt, nsub, height=hslice(h1, a, b),
                               gyro_bias=gyro_bias1, out=rows1[r1:], **kw)
            r1 += u // out_every
            if a >= e2:
                u2 = strapdown.step(s2, imu.dtheta[a:b], imu.dv[a:b], dt, nsub,
                                    height=hslice(h2, a, b), gyro_bias=gyro_bias2,
                                    out=rows2[r2:], **kw)
                r2 += u2 // out_every
            if not (np.all(np.isfinite(s1[:10])) and np.all(np.isfinite(s2[:10]))):
                raise InputError(f"navigation became non-finite by t = {imu.t[b - 1]:.6g} s")
            pb.advance(b - a)
    ep1 = e1 + oes * np.arange(m1 + 1)
    ep2 = e2 + oes * np.arange(m2 + 1)
    tt = np.concatenate([[imu.t0], imu.t])
    k = (e2 - e1) // oes
    rows_mean = mean_solution(rows1[k:], rows2)
    m1_ = None if mount is None else np.asarray(mount, dtype=float)[ep1]
    m2_ = None if m1_ is None else m1_[k:]
    return (strapdown.rows_to_series(tt[ep1], rows1, m1_),
            strapdown.rows_to_series(tt[ep2], rows2, m2_),
            strapdown.rows_to_series(tt[ep2], rows_mean, m2_))


def _grid(imu, t1, delay, step_align, oes, what):
    """Epoch indices of t1 and t2 on the grid (t1 on the alignment grid, delay on lcm)."""
    n_all = len(imu)
    dt = imu.dt
    T = n_all * dt
    e1 = int(round(t1 / dt))
    e1 -= e1 % step_align if step_align > 1 else 0
    g = _gcd_lcm(step_align, oes)
    d = max(g, int(round(delay / dt / g)) * g)
    e2 = e1 + d
    if e2 >= n_all - oes:
        raise ValueError(f"t2 = t1 + delay = {(e1 + d) * dt:.6g} s is beyond the end of the data "
                         f"({T:.6g} s) for the {what}")
    return e1, e2


def _check_record(imu, lat, h):
    if not isinstance(imu, ImuRecord):
        raise ValueError(f"imu must be an ImuRecord, got {type(imu).__name__}")
    Ts = float(earth.schuler_period(lat, h))
    T = len(imu) * imu.dt
    if T < Ts:
        raise ValueError(f"the record ({T:.6g} s) is shorter than one Schuler period "
                         f"({Ts:.6g} s = {Ts / 60:.4g} min)")
    return Ts


def _check_time(name, v, lo=0.0):
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a time in seconds, got {v!r}") from None
    if not (math.isfinite(v) and v >= lo):
        raise ValueError(f"{name} must be a finite time >= {lo:g} s, got {v!r}")
    return v


def _drift_to_body(fine, C_bn):
    """Body-frame gyro bias from the fine alignment's n-frame drift estimate."""
    x = fine.x[-1]
    if fine.model == "full":
        eps_n = x[3:6]
    else:                                  # reduced: [φE φN φU εN' εU']; εE not observable
        eps_n = np.array([0.0, x[3], x[4]])
    return C_bn.T @ eps_n


def delayed_alignment(imu: ImuRecord, lat, lon, h, t1, *, delay=None,
                      options: AlignmentOptions | None = None, nsub=2, out_every=1,
                      vertical="hold", height=None, mount=None, progress=None) -> DelayedResult:
    """Delayed-alignment Schuler suppression on one IMU record at a known site.

    Parameters
    ----------
    imu : ImuRecord
        The stream: at rest or swaying at the site from its start until at least t2
        (moored ship, swinging table), then anything.
    lat, lon, h : float
        Site position [rad, rad, m] (known during alignment; the initial position of both
        solutions).
    t1 : float
        End of solution 1's alignment [s after the record start]; > ``coarse_time``.
    delay : float or str, optional
        ``t2 − t1`` [s] or a time string; default T_s/2 at the site.
    options : AlignmentOptions
    nsub, out_every, vertical, height, mount
        As in :func:`navigate_pair`.

    Returns
    -------
    DelayedResult

    Raises
    ------
    ValueError
        Record shorter than one Schuler period, a delay that is not a positive duration,
        t1 not after the coarse alignment, t2 beyond the end of the data.
    """
    opt = options or AlignmentOptions()
    Ts = _check_record(imu, lat, h)
    delay = half_schuler_delay(lat, h) if delay is None else check_delay(delay)
    t1 = _check_time("t1", t1)
    dt = imu.dt
    kc = int(round(opt.coarse_time / dt))
    nper = max(1, int(round(opt.period / dt)))
    if t1 < opt.coarse_time + 2 * nper * dt:
        raise ValueError(f"t1 = {t1:g} s leaves no time for fine alignment after the "
                         f"{opt.coarse_time:g} s coarse alignment")
    oes = int(nsub) * int(out_every)
    e1, e2 = _grid(imu, t1 - opt.coarse_time, delay, nper, oes, "delayed alignment")
    e1 += kc
    e2 += kc
    if e2 >= len(imu) - oes:
        raise ValueError(f"t2 = {e2 * dt:.6g} s is beyond the end of the data ({len(imu) * dt:.6g} s)")
    coarse_rec = imu.slice(None, imu.t[kc - 1])
    if opt.coarse == "inertial":
        coarse = al.coarse_align_inertial(coarse_rec, lat, h)
    else:
        coarse = al.coarse_align(coarse_rec, lat, h)
    fkw = dict(h=h, model=opt.model, period=nper * dt, gyro_arw=opt.gyro_arw,
               accel_vrw=opt.accel_vrw, rest_threshold=np.inf)
    if opt.p0_att is not None:
        fkw["p0_att"] = opt.p0_att
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", al.NotAtRestWarning)
        # two real alignments on prefixes of the same stream
        f1 = al.fine_align(ImuRecord(imu.t[kc:e1], imu.dtheta[kc:e1], imu.dv[kc:e1], dt),
                           lat, coarse.att, **fkw)
        f2 = al.fine_align(ImuRecord(imu.t[kc:e2], imu.dtheta[kc:e2], imu.dv[kc:e2], dt),
                           lat, coarse.att, **fkw)
    tt = np.concatenate([[imu.t0], imu.t])
    init1 = NavState(lat, lon, h, np.zeros(3), f1.att, tt[e1])
    init2 = NavState(lat, lon, h, np.zeros(3), f2.att, tt[e2])
    gb1 = gb2 = None
    if opt.compensate_gyro:
        gb1 = _drift_to_body(f1, att_.euler_to_dcm(f1.att))
        gb2 = _drift_to_body(f2, att_.euler_to_dcm(f2.att))
    sol1, sol2, mean = navigate_pair(imu, init1, e1, init2, e2, nsub=nsub, out_every=out_every,
                                     vertical=vertical, height=height, mount=mount,
                                     gyro_bias1=gb1, gyro_bias2=gb2, progress=progress)
    return DelayedResult(sol1, sol2, mean, float(tt[e1]), float(tt[e2]), (e2 - e1) * dt, Ts,
                         init1, init2, "aligned", f1, f2, coarse, gb1, gb2)


def _truth_at(truth, t, what):
    if isinstance(truth, NavState):
        return truth
    if not isinstance(truth, NavSeries):
        raise ValueError(f"truth must be a NavSeries (or NavStates), got {type(truth).__name__}")
    k = int(np.argmin(np.abs(truth.t - t)))
    if abs(truth.t[k] - t) > 1e-6 * max(1.0, abs(t)):
        raise ValueError(f"the truth has no epoch at {what} = {t:.9g} s (nearest {truth.t[k]:.9g} s)")
    return NavState.from_series(truth, k, imu_frame=True)


def delayed_injected(imu: ImuRecord, truth, t1, errors: InitialErrors, *, delay=None,
                     nsub=2, out_every=1, vertical="hold", height=None, mount=None,
                     progress=None) -> DelayedResult:
    """The paper's simulation mode: both solutions start from truth + the same errors.

    Parameters
    ----------
    imu : ImuRecord
    truth : NavSeries or (NavState, NavState)
        True states; a series must contain the epochs t1 and t2 (record time), a pair
        gives the states at t1 and t2 directly (IMU attitude).
    t1 : float
        Start of solution 1 [s after the record start].
    errors : InitialErrors
        Added to the true state at t1 (solution 1) and at t2 (solution 2).
    delay : float or str, optional
        Default T_s/2 at the true position at t1.

    Returns
    -------
    DelayedResult
    """
    if not isinstance(errors, InitialErrors):
        raise ValueError(f"errors must be InitialErrors, got {type(errors).__name__}")
    t1 = _check_time("t1", t1)
    pair = isinstance(truth, (tuple, list))
    tt = np.concatenate([[imu.t0], imu.t])
    dt = imu.dt
    e1_guess = int(round(t1 / dt))
    if e1_guess >= len(tt):
        raise ValueError(f"t1 = {t1:g} s is beyond the end of the data ({len(imu) * dt:g} s)")
    s1_true = truth[0] if pair else _truth_at(truth, tt[e1_guess], "t1")
    Ts = _check_record(imu, s1_true.lat, s1_true.h)
    delay = half_schuler_delay(s1_true.lat, s1_true.h) if delay is None else check_delay(delay)
    oes = int(nsub) * int(out_every)
    e1, e2 = _grid(imu, t1, delay, 1, oes, "injected start")
    s1_true = truth[0] if pair else _truth_at(truth, tt[e1], "t1")
    s2_true = truth[1] if pair else _truth_at(truth, tt[e2], "t2")
    init1 = errors.apply(s1_true)
    init2 = errors.apply(s2_true)
    init1 = NavState(init1.lat, init1.lon, init1.h, init1.vel, init1.att, tt[e1])
    init2 = NavState(init2.lat, init2.lon, init2.h, init2.vel, init2.att, tt[e2])
    sol1, sol2, mean = navigate_pair(imu, init1, e1, init2, e2, nsub=nsub, out_every=out_every,
                                     vertical=vertical, height=height, mount=mount,
                                     progress=progress)
    return DelayedResult(sol1, sol2, mean, float(tt[e1]), float(tt[e2]), (e2 - e1) * dt, Ts,
                         init1, init2, "injected")
