"""Loosely coupled INS + position/velocity fixes: the error model and the composition of
the fusion driver that runs it (:func:`loosely_coupled`).

The compiled mechanization (:func:`sinslab.nav.strapdown.step`) runs in blocks between fix
arrivals; the error model of :mod:`sinslab.nav.errstate` (φ, δv, δp, gyro bias ε,
accelerometer bias ∇, optional gyro/accel scale factors; bias random walks,
:func:`lc_model`) is evaluated for the block's epochs (on the block's own rows, or along a
look-ahead run for speed) and discretised; the filter predicts every ``kf_dt`` and is
updated with the antenna position (and velocity) with the lever arm in H, then fed back
(closed loop). Fixes are extrapolated from their validity time to the filter epoch with
the INS velocity (at most ``kf_dt``). A fix valid at t arrives at t + latency;
``lag="aware"`` applies it at its validity epoch, ``lag="ignore"`` on arrival as if current.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E

__all__ = ["loosely_coupled", "LooselyCoupled", "lc_model"]


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


class _NullBar:
    def advance(self, n):
        pass


class _null:
    def __enter__(self):
        return _NullBar()

    def __exit__(self, *a):
        return False
