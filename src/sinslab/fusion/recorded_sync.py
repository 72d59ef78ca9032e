"""IMU time stamps against the GNSS fixes: the offset and clock drift of the IMU's stamps
estimated from turns (:func:`estimate_time_offset`), the part of it beyond doubt
(:func:`significant_time_offset`), and the corrected times (:func:`shifted_times`,
:func:`shift_imu_time`)."""
from __future__ import annotations

import math

import numpy as np

from sinslab.core.blocks import release_pages
from sinslab.core.records import Fixes, ImuRecord
from sinslab.fusion.recorded_start import _imu_point_course, _rate_z_window

__all__ = ["estimate_time_offset", "significant_time_offset", "shift_imu_time", "shifted_times"]


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
