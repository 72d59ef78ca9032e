"""Plausibility checks of recorded data and of a filter run: garbage in is caught.

A reader accepts any well-formed file; these checks ask whether its numbers can be an
IMU on the Earth, and whether a navigation filter stayed consistent with its data. Each
finding is one line naming the file (or the run), the value and what was expected. A
:class:`Finding` with ``refuse=True`` is one where no answer can mean anything (every
sample zero, magnitudes beyond any IMU's range, a record too short): the command stops
with exit status 2 and writes nothing. The others are warnings: printed as
``warning: ...`` and listed in the report; ``--strict`` turns every warning into a refusal.

Usage in a command's compute function::

    from sinslab.app.plausibility import imu_findings, settle

    found = imu_findings(data.imu, str(path), lat=lat, gaps=data.gaps)
    warnings = settle(found, strict=strict, echo=echo)    # raises CliError on a refusal
    return Output(..., warnings=warnings)

Thresholds are module constants (no tuning per file): see each one's comment.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.app.errors import CliError
from sinslab.core.blocks import block_median, block_ranges, release_pages

__all__ = ["Finding", "imu_findings", "rest_findings", "rest_gravity_findings", "gap_findings",
           "consistency_findings", "settle", "rest_rate_findings", "bias_findings", "overconfidence_findings",
           "grade_of", "GRADES", "unit_slip", "interval_findings", "declared_findings",
           "MIN_SAMPLES", "MAX_RATE_DPS", "MAX_ACCEL_G", "MONITOR_WINDOW_S", "MONITOR_ALPHA",
           "MONITOR_STRETCH_S", "windowed_nis", "WindowedNis", "row_consistency_findings"]

#: fewest samples any command can use (a levelling, an alignment, a first filter step)
MIN_SAMPLES = 10
#: the largest range of any IMU on sale is about ±4000 °/s and ±400 g (shock and
#: projectile units); beyond these a sample is a unit slip or a corrupt record
MAX_RATE_DPS = 5000.0
MAX_ACCEL_G = 500.0
#: |f| on the Earth, at rest or averaged over a ride, is gravity: a median beyond ±50 %
#: is a wrong accelerometer unit (g read as m/s² gives 0.1 g; m/s² read as g, 9.8 g) or
#: column; beyond ±5 % an uncalibrated scale or a wrong unit of a close size
F_REFUSE = 0.5
F_WARN = 0.05
#: a gap is worth a warning when the rotation it hides may exceed this [deg] or the gap
#: itself is this long [s] (a car turning at 10 °/s through a 0.1 s gap: 1°)
GAP_WARN_DEG = 0.5
GAP_WARN_S = 1.0
#: consistency monitors of a run (:func:`consistency_findings`): the window [s] of the
#: NIS and innovation-mean tests, their false-alarm probability per window, and how long
#: [s] the failing windows must last in a row to be reported (one window: a stretch that
#: long is no run of bad luck of overlapping windows)
MONITOR_WINDOW_S = 30.0
MONITOR_ALPHA = 1e-3
MONITOR_STRETCH_S = 30.0


@dataclass(frozen=True)
class Finding:
    """One line about the data or the run; ``refuse``: no answer from it can mean anything."""

    text: str
    refuse: bool = False


def _g(lat, h=0.0) -> float:
    from sinslab.core import earth

    return float(earth.gravity(0.0 if lat is None else float(lat), float(h)))


def imu_findings(imu, source: str, *, lat=None, h=0.0, gaps=None) -> list[Finding]:
    """Checks of a whole IMU record: length, dead channels, ranges, |f| against gravity, gaps.

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
        Increments in the body frame.
    source : str
        The file (and window) named in every line.
    lat, h : float, optional
        Latitude [rad] and height [m] for the local gravity (default: equator, 0 m —
        the normal gravity varies by 0.5 % between equator and poles, inside F_WARN).
    gaps : array (k, 2), optional
        ``[start, length]`` [s] of the bridged gaps (:class:`sinslab.data.increments.ImuData`).
    """
    n = len(imu)
    if n < MIN_SAMPLES:
        return [Finding(f"{source}: only {n} sample{'s' if n != 1 else ''} "
                        f"({n * imu.dt:.3g} s); a run needs at least {MIN_SAMPLES}", True)]
    slow = interval_findings(imu, source)
    if slow:
        return slow
    out: list[Finding] = []
    st = _record_stats(imu)
    if not st["any_w"] and not st["any_f"]:
        return [Finding(f"{source}: every gyro and accelerometer sample is zero: the file "
                        f"holds no measurement", True)]
    dead = []
    for key, sensor, unit, sc in (("w", "gyro", "deg/s", math.degrees(1.0)), ("f", "accel", "m/s^2", 1.0)):
        for k, ax in enumerate("xyz"):
            if st[f"{key}_min"][k] == st[f"{key}_max"][k]:
                dead.append(f"{sensor} {ax} = {st[f'{key}_first'][k] * sc:.6g} {unit}")
    if dead:
        out.append(Finding(f"{source}: constant over all {n} samples: {', '.join(dead)} "
                           f"(a dead, unconnected or saturated channel?)"))
    g = _g(lat, h)
    for key, lim, unit, sc, sensor in (("wn", MAX_RATE_DPS, "deg/s", math.degrees(1.0), "angular rate"),
                                       ("fn", MAX_ACCEL_G, "g", 1.0 / 9.80665, "specific force")):
        i, top = st[f"{key}_argmax"], st[f"{key}_max"]
        if top * sc > lim:
            out.insert(0, Finding(
                f"{source}: {sensor} of {top * sc:.4g} {unit} at t = {imu.t[i]:.6g} s is beyond "
                f"any IMU's range (±{lim:g} {unit}): a wrong unit or a corrupt record", True))
    if not st["any_f"]:
        out.insert(0, Finding(f"{source}: every accelerometer sample is zero; an IMU on the Earth "
                              f"measures about 1 g: no accelerometer data (wrong columns?)", True))
    else:
        med = block_median(lambda: (b for _, b in _magnitudes(imu, "dv")), n)
        r = med / g
        if abs(r - 1.0) > F_WARN:
            hint = ("a wrong accelerometer unit or column" if abs(r - 1.0) > F_REFUSE else
                    "an accelerometer scale error, or a record that is not on the Earth's surface")
            out.append(Finding(f"{source}: median specific force |f| = {med:.4g} m/s^2 = {r:.3g} × "
                               f"local gravity {g:.4f} m/s^2 (expected within ±{F_WARN:.0%}): {hint}",
                               abs(r - 1.0) > F_REFUSE))
    if gaps is not None and len(gaps):
        out += gap_findings(imu, gaps, source)
    return out


#: the longest sample interval of a strapdown IMU log [s]: the slowest units on sale
#: output 1 Hz averages; a longer interval is a time column in another unit (ms read as s)
MAX_SAMPLE_INTERVAL_S = 1.0


def interval_findings(imu, source: str) -> list[Finding]:
    """A sample interval no strapdown IMU logs (beyond :data:`MAX_SAMPLE_INTERVAL_S`): the
    time column is in another unit than declared — milliseconds read as seconds when the
    interval over 1000 is that of a 50 Hz–2 kHz IMU. Every rate, increment and |f| figure
    from such a record is off by the same factor, so this comes before them."""
    dt = float(imu.dt)
    if dt <= MAX_SAMPLE_INTERVAL_S:
        return []
    hint = (f"a time column in milliseconds read as seconds? (then {1e3 / dt:.4g} Hz; declare it t[ms])"
            if 5e-4 <= dt * 1e-3 <= 0.02 else "a time column in another unit than declared?")
    return [Finding(f"{source}: sample interval {dt:.6g} s ({1 / dt:.3g} Hz): no strapdown IMU logs "
                    f"slower than every {MAX_SAMPLE_INTERVAL_S:g} s; {hint}", True)]


def _magnitudes(imu, name):
    """``(first sample, |x / dt| of a block of samples)`` of ``imu.<name>`` a block at a time."""
    arr = getattr(imu, name)
    for a, b in block_ranges(len(imu)):
        x = arr[a:b] / imu.dt
        yield a, np.sqrt(np.sum(x * x, axis=1))
        release_pages(arr)


def _record_stats(imu):
    """What :func:`imu_findings` needs of a whole record, gathered a block at a time: any
    non-zero rate / force, per axis the first, least and largest value, and the largest
    magnitude of each with its (first) sample."""
    st = {"any_w": False, "any_f": False}
    for key, name in (("w", "dtheta"), ("f", "dv")):
        arr = getattr(imu, name)
        lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
        for a, b in block_ranges(len(imu)):
            x = arr[a:b] / imu.dt
            st[f"any_{key}"] |= bool(np.any(x))
            lo, hi = np.minimum(lo, x.min(0)), np.maximum(hi, x.max(0))
            if a == 0:
                st[f"{key}_first"] = x[0].copy()
            release_pages(arr)
        st[f"{key}_min"], st[f"{key}_max"] = lo, hi
        top, at = -1.0, 0
        for a, m in _magnitudes(imu, name):
            i = int(np.argmax(m))
            if m[i] > top:
                top, at = float(m[i]), a + i
        st[f"{key}n_max"], st[f"{key}n_argmax"] = top, at
    return st


def rest_gravity_findings(imu, source: str, *, lat=None, h=0.0) -> list[Finding]:
    """|mean f| of a record at rest against local gravity (within :data:`F_WARN`)."""
    g = _g(lat, h)
    fm = float(np.linalg.norm((imu.dv / imu.dt).mean(axis=0))) if len(imu) else 0.0
    if fm > 0 and abs(fm / g - 1.0) > F_WARN:
        return [Finding(f"{source}: mean specific force at rest {fm:.5g} m/s^2 = {fm / g:.4f} × "
                        f"local gravity {g:.5f} m/s^2 (expected within ±{F_WARN:.0%}): not at "
                        f"rest, or an accelerometer scale or unit error", abs(fm / g - 1.0) > F_REFUSE)]
    return []


def rest_findings(imu, source: str, *, lat=None, h=0.0, pieces: int = 10) -> list[Finding]:
    """Checks of a record that should be at rest (an alignment window): |f| against local
    gravity (:func:`rest_gravity_findings`), and the attitude of ``pieces`` equal parts from
    their mean specific force — pitch or roll steps between parts larger than the noise
    allows mean motion."""
    out = rest_gravity_findings(imu, source, lat=lat, h=h)
    n = len(imu)
    f = imu.dv / imu.dt
    g = _g(lat, h)
    m = n // pieces
    if m < 2:
        return out
    parts = f[: m * pieces].reshape(pieces, m, 3)
    mean = parts.mean(axis=1)
    # levelling of each part (RFU: pitch from y, roll from x against z)
    pitch = np.degrees(np.arctan2(mean[:, 1], np.hypot(mean[:, 0], mean[:, 2])))
    roll = np.degrees(np.arctan2(-mean[:, 0], mean[:, 2]))
    # what white noise alone gives: the σ of a part's mean tilt from the sample scatter
    noise = np.degrees(np.sqrt(np.mean(parts.var(axis=1)[:, :2], axis=0) / m) / max(g, 1e-9))
    tol = np.maximum(6.0 * noise, 0.005)          # 6σ of the difference of two parts, ≥ 0.3′
    for name, a, s in (("pitch", pitch, tol[1]), ("roll", roll, tol[0])):
        step = float(np.ptp(a))
        if step > s:
            i, j = int(np.argmin(a)), int(np.argmax(a))
            t = imu.t[: m * pieces].reshape(pieces, m)
            out.append(Finding(
                f"{source}: {name} from the mean specific force changes by {step:.3g} deg between "
                f"{t[i, 0]:.0f}–{t[i, -1]:.0f} s and {t[j, 0]:.0f}–{t[j, -1]:.0f} s (noise allows "
                f"{s:.2g} deg): the window holds motion; choose a window at rest"))
    return out


#: |ω| at rest within this fraction of Earth rate needs no explanation (a nearly level,
#: quasi-static record of a navigation-grade IMU measures 0.98 ω_ie: sway, scale errors);
#: beyond it the gyro bias must explain it (--gyro-bias), or the heading from
#: gyrocompassing means nothing
W_REST_TOL = 0.5
#: a ratio within this fraction of 180/π (or π/180) is the signature of a unit slip
UNIT_SLIP_TOL = 0.1
_DEG = math.degrees(1.0)


def unit_slip(ratio: float, what: str) -> str | None:
    """The likely unit slip behind ``ratio`` (a measured over an expected magnitude)."""
    if abs(ratio / _DEG - 1.0) < UNIT_SLIP_TOL:
        return f"the ratio is close to 180/π = {_DEG:.1f}: {what} in degrees read as radians?"
    if abs(ratio * _DEG - 1.0) < UNIT_SLIP_TOL:
        return f"the ratio is close to π/180 = {1 / _DEG:.4f}: {what} in radians read as degrees?"
    return None


def rest_rate_findings(imu, source: str, *, lat=None, gyro_bias=None) -> list[Finding]:
    """|mean ω| of a record at rest against Earth rate.

    At rest a gyro triad measures Earth rate ω_ie (15.04 °/h) plus its bias, whatever its
    heading. A ratio beyond :data:`W_REST_TOL` (or five times the assumed 1σ gyro bias
    ``gyro_bias`` [rad/s], when larger) is reported with its likely cause: a unit slip
    when the ratio is 180/π, else a bias larger than assumed or motion. Without
    ``gyro_bias`` (no grade known) only a unit slip is reported.
    """
    from sinslab.core import earth

    w = np.asarray(imu.dtheta, float).sum(axis=0) / (len(imu) * imu.dt)
    wm = float(np.linalg.norm(w))
    r = wm / earth.WIE
    slip = unit_slip(r, "the gyro data")
    dph = 3600.0 * _DEG
    if gyro_bias is None:
        if slip is None:
            return []
        return [Finding(f"{source}: mean angular rate at rest |ω| = {r:.3g} × Earth rate ({wm * dph:.4g} °/h "
                        f"against {earth.WIE * dph:.4g} °/h): {slip} (check the gyro columns' unit; every gyro "
                        f"figure from it is off by that ratio)")]
    tol = max(W_REST_TOL, 5.0 * float(gyro_bias) / earth.WIE)
    if abs(r - 1.0) <= tol:
        return []
    cause = slip or (f"a gyro bias near {abs(wm - earth.WIE) * dph:.3g} °/h, far beyond the assumed "
                     f"{float(gyro_bias) * dph:.3g} °/h (--gyro-bias), or motion in the window")
    return [Finding(f"{source}: mean angular rate at rest |ω| = {r:.3g} × Earth rate ({wm * dph:.4g} °/h "
                    f"against {earth.WIE * dph:.4g} °/h; the assumed gyro bias allows {1 - tol:.2g}–{1 + tol:.3g} ×): "
                    f"{cause}; the heading from gyrocompassing means nothing")]


#: IMU grades: (name, largest gyro angle random walk [°/√h], largest gyro bias [°/h],
#: largest accelerometer bias [mg]), after the typical ranges of Groves, Principles of
#: GNSS, Inertial, and Multisensor Integrated Navigation Systems (2nd ed., 2013), §4.4.
#: A bias beyond the last row is beyond any IMU on sale.
GRADES = (("navigation-grade", 0.01, 0.1, 0.3),
          ("tactical-grade", 0.5, 100.0, 10.0),
          ("industrial MEMS", 5.0, 3600.0, 100.0),
          ("consumer MEMS", math.inf, 36000.0, 500.0))


def grade_of(gyro_arw) -> tuple:
    """The :data:`GRADES` row of a gyro angle random walk [rad/√s] (its noise sets its class)."""
    arw = float(gyro_arw) * _DEG * 60.0                      # rad/√s -> °/√h
    return next(g for g in GRADES if arw <= g[1])


def bias_findings(gyro_bias, accel_bias, source: str, *, gyro_arw=None) -> list[Finding]:
    """Estimated biases (3,) [rad/s], [m/s²] against the grade that ``gyro_arw`` [rad/√s]
    implies (:func:`grade_of`; without it, against any IMU): a bias beyond its grade's
    range is an estimate that absorbed something else (a unit or scale error, a time
    offset, motion the model lacks)."""
    grade = grade_of(gyro_arw) if gyro_arw is not None else GRADES[-1]
    name, _, gb_max, ab_max = grade
    gb = float(np.max(np.abs(gyro_bias))) * 3600.0 * _DEG
    ab = float(np.max(np.abs(accel_bias))) / 9.80665e-3
    out = []
    beyond = "any IMU" if grade is GRADES[-1] else f"a {name} IMU, whose gyro noise was given"
    if gb > gb_max:
        out.append(Finding(f"{source}: estimated gyro bias {gb:.4g} °/h is beyond {beyond} (up to {gb_max:g} °/h): "
                           f"the estimate absorbed a unit or scale error, a time offset or motion the model lacks"))
    if ab > ab_max:
        out.append(Finding(f"{source}: estimated accelerometer bias {ab:.4g} mg is beyond {beyond} (up to "
                           f"{ab_max:g} mg): the estimate absorbed a unit or scale error, a time offset or motion "
                           f"the model lacks"))
    return out


#: an estimate beyond this many times the 1σ its declared error model gives it (a Gaussian
#: prior's 5σ: probability 6e-7 per axis) says the model or the estimate is wrong
DECLARED_FACTOR = 5.0
#: and beyond this many of its own final σ (else the data do not determine it)
SIGNIFICANT_SIGMAS = 3.0


def declared_findings(estimates, source: str, declared: str) -> list[Finding]:
    """Estimated sensor errors against the error model the user declared (``declared``:
    how, e.g. ``--imu-errors industrial``). ``estimates``: ``[(what, estimate (3,), final σ
    (3,), declared 1σ, unit, scale to the unit)]`` in SI; a finding for each kind whose
    largest significant estimate exceeds :data:`DECLARED_FACTOR` × its declared 1σ: the
    IMU is of a lower grade than declared, or the estimate absorbed another error."""
    out = []
    for what, est, sig, dec, unit, sc in estimates:
        est, sig = np.abs(np.asarray(est, float)), np.asarray(sig, float)
        dec = float(np.max(dec)) if np.size(dec) else 0.0
        ok = np.isfinite(est) & (est > SIGNIFICANT_SIGMAS * np.nan_to_num(sig, nan=np.inf))
        if dec <= 0 or not ok.any():
            continue
        k = int(np.argmax(np.where(ok, est, -1.0)))
        if est[k] > DECLARED_FACTOR * dec:
            out.append(Finding(
                f"{source}: estimated {what} {'xyz'[k]} {est[k] * sc:.4g} {unit} is {est[k] / dec:.3g} × the "
                f"{dec * sc:.4g} {unit} (1σ) of the declared error model ({declared}; plausible up to "
                f"{DECLARED_FACTOR:g}σ): an IMU of a lower grade than declared, or an estimate that absorbed a "
                f"unit or scale error, a time offset or motion the model lacks"))
    return out


def overconfidence_findings(applied, source: str, what: str) -> list[Finding]:
    """σ implausibly tight for the data: over a whole run the normalised innovations of a
    consistent filter average to 1 per component (χ² over the total degrees of freedom D:
    beyond its ``1 − MONITOR_ALPHA`` quantile over D the errors are larger than the σ). The
    estimates' σ (``what``) then understate their error by about √(NIS per component)."""
    from scipy.special import chdtri

    nu = [np.asarray(v, float) for v in applied.innovation]
    dof = float(sum(int(np.isfinite(v).sum()) for v in nu))
    nis = np.asarray(applied.nis, float)
    nis = nis[np.isfinite(nis)]
    if dof < 10 or nis.size == 0:
        return []
    per = float(nis.sum()) / dof
    limit = float(chdtri(dof, MONITOR_ALPHA)) / dof
    if per <= limit:
        return []
    return [Finding(f"{source}: the σ of {what} are implausibly tight for the data: the matching innovations "
                    f"are {math.sqrt(per):.3g} times larger than the filter's σ say (NIS per component {per:.3g}, "
                    f"a consistent filter stays below {limit:.3g}); the estimates absorb an error the model "
                    f"lacks (a time offset, a unit or scale error, a lever arm)")]


def gap_findings(imu, gaps, source: str) -> list[Finding]:
    """A warning for the gaps whose bridging may hide a rotation: the rate next to each gap
    times its length bounds the rotation the mean-rate bridge may have missed."""
    gaps = np.asarray(gaps, float).reshape(-1, 2)
    k = max(1, int(round(1.0 / imu.dt)))                  # 1 s of samples on each side
    worst = []
    for t0, ln in gaps:
        i = int(np.searchsorted(imu.t, t0))
        near = np.degrees(np.sqrt(np.sum((imu.dtheta[max(0, i - k): i + k + int(ln / imu.dt)] / imu.dt) ** 2,
                                         axis=1)))
        rate = float(near.max()) if near.size else 0.0
        worst.append((rate * ln, ln, t0, rate))
    rot, ln, t0, rate = max(worst)
    longest = max(g[1] for g in gaps)
    if rot < GAP_WARN_DEG and longest < GAP_WARN_S:
        return []
    return [Finding(f"{source}: {len(gaps)} gap(s) bridged with the mean rate, longest "
                    f"{longest:.3g} s; the gap of {ln:.3g} s at {t0 - imu.t[0] + imu.dt:.2f} s lies "
                    f"next to turn rates up to {rate:.3g} deg/s, so up to {rot:.3g} deg of rotation "
                    f"(and the velocity change across it) is interpolated, not measured")]


def _stretches(t, bad):
    """``[(duration [s], start, stop)]`` of the runs of ``bad`` (stop exclusive), longest first."""
    edges = np.flatnonzero(np.diff(np.r_[0, bad.astype(int), 0]))
    return sorted(((float(t[b - 1] - t[a]), int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])),
                  reverse=True)


def _window_sums(t, x):
    """Sums of ``x`` (n, ...) over the window of :data:`MONITOR_WINDOW_S` centred on each
    ``t``, and the window bounds ``lo, hi`` (rows ``lo[i]:hi[i]``)."""
    lo = np.searchsorted(t, t - MONITOR_WINDOW_S / 2)
    hi = np.searchsorted(t, t + MONITOR_WINDOW_S / 2, side="right")
    c = np.concatenate([np.zeros((1, *x.shape[1:])), np.cumsum(x, axis=0)])
    return c[hi] - c[lo], lo, hi


@dataclass(frozen=True)
class WindowedNis:
    """The NIS of :data:`MONITOR_WINDOW_S` windows against their χ² bound
    (:func:`windowed_nis`): ``worst`` the largest window NIS per degree of freedom,
    ``limit`` the bound per degree of freedom there, ``failing`` the share of windows over
    their bound, ``stretches`` how many runs of failing windows; ``finding`` (the longest
    run's span words) where one lasts :data:`MONITOR_STRETCH_S`, else None."""

    worst: float
    limit: float
    failing: float
    stretches: int
    finding: str | None
    worst_words: str


def windowed_nis(t, nis, dof) -> WindowedNis:
    """The NIS summed over the window of :data:`MONITOR_WINDOW_S` around each time ``t``
    [s] (sorted): ``nis`` (n,) the NIS of each record, ``dof`` (n,) its degrees of freedom.
    Under consistency a window's sum is χ² with the window's degrees of freedom (Mehra &
    Peschon 1971); beyond its ``1 − MONITOR_ALPHA`` quantile the errors are larger than the
    filter's σ say. Only this side is judged: a pessimistic model is safe."""
    from scipy.special import chdtri
    t, nis, dof = (np.asarray(x, float) for x in (t, nis, dof))
    s_nis, _, _ = _window_sums(t, nis)
    d, _, _ = _window_sums(t, dof)
    limit = chdtri(np.maximum(d, 1.0), MONITOR_ALPHA)
    ok = d > 0
    if not ok.any():
        return WindowedNis(math.nan, math.nan, 0.0, 0, None, "no window with a record used")
    bad = (s_nis > limit) & ok
    runs = _stretches(t, bad) if bad.any() else []
    ratio = np.where(ok, s_nis / np.maximum(d, 1.0), -np.inf)
    i = int(np.argmax(ratio))
    finding = None
    if runs and runs[0][0] >= MONITOR_STRETCH_S:
        dur, a, b = runs[0]
        i = a + int(np.argmax(ratio[a:b]))
        finding = f"{dur:.0f} s ({t[a] - t[0]:.0f}–{t[b - 1] - t[0]:.0f} s after"
    words = (f"{MONITOR_WINDOW_S:g}-s NIS per degree of freedom up to {ratio[i]:.3g} where a consistent filter "
             f"stays below {limit[i] / d[i]:.3g} (χ² of the window's {d[i]:.0f} degrees of freedom, false alarm "
             f"{MONITOR_ALPHA:g} per window)")
    return WindowedNis(float(ratio[i]), float(limit[i] / d[i]), float(bad[ok].mean()), len(runs), finding, words)


def row_consistency_findings(rows) -> tuple[list[Finding], dict]:
    """The windowed NIS monitor (:func:`windowed_nis`) on the rows of a tightly coupled run
    (``{label: RowLog}``: pseudoranges, range rates), epoch by epoch: a warning where a
    kind's window NIS stays over its bound for :data:`MONITOR_STRETCH_S`, and per kind the
    metrics ``<kind>_nis_window_max`` (per degree of freedom), ``<kind>_nis_window_limit``
    there and ``<kind>_nis_window_failing`` (share of epochs)."""
    out, metrics = [], {}
    for label, log in rows.items():
        key = "pseudorange" if label == "pseudoranges" else "doppler"
        what = "pseudorange" if key == "pseudorange" else "range-rate (Doppler)"
        t, nis, dof = log.nis_per_epoch()
        if t.size < 10:
            continue
        w = windowed_nis(t, nis, dof)
        metrics.update({f"{key}_nis_window_max": w.worst, f"{key}_nis_window_limit": w.limit,
                        f"{key}_nis_window_failing": w.failing})
        if w.finding is not None:
            out.append(Finding(
                f"the filter is overconfident about its {what} rows for {w.finding} the first GNSS epoch; "
                f"{w.stretches} such stretch(es), {w.failing:.0%} of the epochs): {w.worst_words}: their errors "
                "are larger than their σ say (multipath, a clock jump, a wrong σ, an IMU–GNSS time offset)"))
    return out, metrics


#: what a bias of the fix innovations that lasts points to
BIAS_CAUSES = "lever arm, time offset, mount, a bias prior too tight"


def consistency_findings(t, innovation, innovation_sigma, nis, labels=None, *, item="fix",
                         items="fixes", source="fix", causes=BIAS_CAUSES, bias_floor=0.0) -> list[Finding]:
    """Warnings where the filter is inconsistent with its fixes for a long stretch.

    A consistent Kalman filter's innovations are zero-mean, white, with the covariance
    ``S = H P Hᵀ + R`` it computes (Mehra & Peschon 1971), so over a window of
    :data:`MONITOR_WINDOW_S` holding ``k`` fixes

    - the **NIS** sum is χ² with the window's degrees of freedom (the used components of
      its ``k`` fixes): a sum beyond its ``1 − MONITOR_ALPHA`` quantile says the errors are
      larger than the filter's σ (overconfident). Only this side is a warning: a filter
      whose σ are larger than its errors (a pessimistic noise model) is safe, and its
      whole-run mean NIS says so;
    - the **innovation mean** of each component, normalised by its σ (``√S_ii``) and
      scaled by ``√k``, is standard normal: beyond the two-sided ``MONITOR_ALPHA`` quantile
      (Bonferroni over the components) it is a bias the filter does not model — a lever
      arm, time offset, mount, or a bias prior too tight — even where the NIS looks fine.

    A window failing is a false alarm with probability :data:`MONITOR_ALPHA`; a warning
    needs the failing windows to last :data:`MONITOR_STRETCH_S` in a row.

    Parameters
    ----------
    t : array (J,)
        Validity times of the applied fixes [s].
    innovation, innovation_sigma : arrays (J, m)
        Innovations and the filter's σ of each (NaN where a component was not used).
    nis : array (J,)
        Normalised innovation squared of each fix over its used components.
    labels : list of str, optional
        Names of the m components (for the message).
    bias_floor : float
        Report a component's window mean only beyond this many σ too (0: wherever it is
        significant). Errors that stay within σ for minutes are the noise model's
        business where they are known to be correlated (a satellite's ionospheric
        residual and multipath): there only a mean beyond the σ itself is an error.
    item, items, source, causes : str
        What a row of ``t`` is, in the singular and the plural, whose innovations these
        are and what a lasting bias of them points to, for the messages: the loosely
        coupled source's fixes by default; the epochs of a measurement's rows (``item="epoch",
        items="epochs", source="pseudorange"``).
    """
    t = np.asarray(t, float)
    nu = np.asarray(innovation, float).reshape(t.size, -1)
    sd = np.asarray(innovation_sigma, float).reshape(nu.shape)
    nis = np.asarray(nis, float)
    keep = np.isfinite(t) & np.isfinite(nis)
    t, nu, sd, nis = t[keep], nu[keep], sd[keep], nis[keep]
    if t.size < 10:
        return []
    m = nu.shape[1]
    labels = list(labels) if labels is not None and len(labels) == m else [f"component {i + 1}" for i in range(m)]
    used = np.isfinite(nu) & np.isfinite(sd) & (sd > 0)
    z = np.where(used, nu / np.where(used, sd, 1.0), 0.0)
    out = []
    w = windowed_nis(t, nis, used.sum(axis=1).astype(float))
    if w.finding is not None:
        out.append(Finding(
            f"the filter is overconfident{'' if source == 'fix' else f' about the {source}s'} for {w.finding} the "
            f"first applied {item}; {w.stretches} such stretch(es), {w.failing:.0%} of the {items}): {w.worst_words}: "
            f"its errors are larger than its σ say "
            f"(noise model, lever arm, time offset or mount off)"))
    bias = _bias_finding(t, z, used, labels, item=item, items=items, source=source, causes=causes,
                         bias_floor=bias_floor)
    if bias is not None:
        out.append(bias)
    return out


def _bias_finding(t, z, used, labels, *, item, items, source, causes, bias_floor):
    """The innovation-mean half of :func:`consistency_findings`: ``z`` (J, m) the
    innovations over their σ (0 where ``used`` is False); a :class:`Finding` where some
    component's :data:`MONITOR_WINDOW_S` mean, scaled by √k, stays beyond the two-sided
    Bonferroni quantile for :data:`MONITOR_STRETCH_S`, else None."""
    # scipy.special's normal quantile (what scipy.stats' norm.isf evaluates, the same
    # value), not scipy.stats: its import takes ~35 MB and ~0.4 s
    from scipy.special import ndtri

    m = z.shape[1]
    s_z, _, _ = _window_sums(t, z)
    k, _, _ = _window_sums(t, used.astype(float))
    u = s_z / np.sqrt(np.maximum(k, 1.0))
    q = -ndtri(MONITOR_ALPHA / (2 * m))
    bad_c = (np.abs(u) > q) & (k > 0) & (np.abs(s_z) >= bias_floor * np.maximum(k, 1.0))
    bad = bad_c.any(axis=1)
    runs = _stretches(t, bad) if bad.any() else []
    if runs and runs[0][0] >= MONITOR_STRETCH_S:
        dur, a, b = runs[0]
        i, c = np.unravel_index(int(np.argmax(np.abs(u[a:b]))), u[a:b].shape)
        i += a
        worst = [labels[j] for j in range(m) if bad_c[a:b, j].any()]
        return Finding(
            f"the {source} innovations are biased for {dur:.0f} s ({t[a] - t[0]:.0f}–{t[b - 1] - t[0]:.0f} s after "
            f"the first applied {item}; {len(runs)} such stretch(es), {bad.mean():.0%} of the {items}) in "
            f"{', '.join(worst)}: {MONITOR_WINDOW_S:g}-s mean of the {labels[c]} innovation "
            f"{s_z[i, c] / max(k[i, c], 1.0):+.2f} σ over {k[i, c]:.0f} {items}, {abs(u[i, c]):.1f} times its "
            f"spread 1/√{k[i, c]:.0f} where a consistent filter stays within {q:.2f} (false alarm "
            f"{MONITOR_ALPHA:g} per window): an error the filter does not model ({causes})")
    return None


def settle(findings, *, strict: bool = False, echo=print) -> list[str]:
    """Refuse on the first refusing finding (any finding with ``strict``): raise
    :class:`CliError` with its line (and, with ``strict``, that ``--strict`` refused it).
    Otherwise print each as ``warning: ...`` and return their texts for the report."""
    for fd in findings:
        if fd.refuse:
            raise CliError(fd.text)
    if strict and findings:
        more = f" (and {len(findings) - 1} more warning(s))" if len(findings) > 1 else ""
        raise CliError(f"{findings[0].text}{more}; refused because of --strict")
    for fd in findings:
        echo(f"  warning: {fd.text}")
    return [fd.text for fd in findings]
