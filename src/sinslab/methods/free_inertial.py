"""Free-inertial error analysis: what an unaided INS does with given sensor and initial
errors, independent of any scenario.

- :func:`linear_error_prediction`: the linear φ-angle error model propagated along a true
  trajectory with the realised sensor errors as input (exact discretisation per step);
- :func:`covariance_analysis`: the same model with bias (and scale-factor) states and
  white-noise densities, P propagated without measurements (σ of every error);
- :func:`envelopes`: closed-form upper bounds of the position, velocity, tilt and heading
  errors in the single-channel Schuler loop;
- :func:`fit_schuler_period`: the Schuler period of a horizontal velocity(-error) series
  with the Foucault split modelled.

Frames and units: ENU navigation frame, SI (rad, m, m/s, s) throughout.
"""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import earth

__all__ = ["fit_schuler_period", "linear_error_prediction", "covariance_analysis", "envelopes"]


def fit_schuler_period(t, v, min_period=1800.0, max_period=3 * 3600.0):
    """Schuler period [s] fitted to a horizontal velocity(-error) series ``v`` (M, 2: E, N).

    The horizontal error oscillation is a pair of counter-rotating circular modes
    (``z = vE + i·vN``): the Foucault (Coriolis) rotation splits the Schuler frequency
    ω_s into ω_s − ω_f and ω_s + ω_f. The model, fitted by least squares with the
    frequencies found by variable projection (grid, then Nelder–Mead), is::

        z(t) = c0 + c1·τ + A·exp(i ω1 t) + B·exp(−i ω2 t),     τ = t / t_end

    and the Schuler period is ``4π / (ω1 + ω2)`` (the Foucault shift cancels).
    """
    from scipy.optimize import minimize

    t = np.asarray(t, float) - float(np.asarray(t)[0])
    v = np.asarray(v, float)
    step = max(1, t.size // 1500)               # the oscillation is slow: 1500 points suffice
    t, v = t[::step], v[::step]
    z = v[:, 0] + 1j * v[:, 1]
    tau = t / max(t[-1], 1e-9)

    def cost(p):
        p1, p2 = p
        if not (min_period / 2 < p1 < 2 * max_period and min_period / 2 < p2 < 2 * max_period):
            return np.inf
        A = np.column_stack([np.ones_like(t), tau, np.exp(2j * np.pi * t / p1),
                             np.exp(-2j * np.pi * t / p2)])
        coef, *_ = np.linalg.lstsq(A, z, rcond=None)
        r = z - A @ coef
        return float(np.vdot(r, r).real)

    grid = np.linspace(min_period, max_period, 150)
    p0 = grid[int(np.argmin([cost((p, p)) for p in grid]))]
    res = minimize(cost, [p0, p0], method="Nelder-Mead",
                   options={"xatol": 1e-3, "fatol": 1e-14, "maxiter": 2000})
    w1, w2 = 2 * np.pi / res.x[0], 2 * np.pi / res.x[1]
    return float(4 * np.pi / (w1 + w2))


def _expm_batch(A):
    """Matrix exponential of a stack (..., n, n): scaling and squaring + 14-term Taylor."""
    norm = float(np.max(np.abs(A).sum(-1))) if A.size else 0.0
    sq = max(0, int(math.ceil(math.log2(norm))) + 1) if norm > 0 else 0
    X = A / 2.0 ** sq
    E = np.broadcast_to(np.eye(A.shape[-1]), A.shape).copy()
    term = E.copy()
    for k in range(1, 15):
        term = term @ X / k
        E += term
    for _ in range(sq):
        E = E @ E
    return E


def linear_error_prediction(truth, ideal, meas, ep, x0, core="horizontal"):
    """Propagate the linear φ-angle error model (:mod:`sinslab.nav.errstate`) along the truth.

    The input is the *realised* sensor error (``meas − ideal`` increments, rotated to the
    navigation frame sample by sample and summed over each output step), so bias, noise
    and scale-factor errors all enter exactly as the navigation saw them; F is evaluated
    at the middle of each step with the mean true specific force. Each step is
    discretised exactly for constant F and input (augmented matrix exponential).

    Returns the state history (len(ep), n): ``core="horizontal"``: φ (3), δvE, δvN, δL, δλ;
    ``core="full"``: φ (3), δv (3), δL, δλ, δh.
    """
    from sinslab.nav import errstate
    from sinslab.core.attitude import euler_to_dcm

    model = errstate.ErrorModel(core)
    n = model.n
    att = truth.att_imu if truth.att_imu is not None else truth.att
    K = int(ep[1] - ep[0])
    m = len(ep) - 1
    ns = m * K
    C = euler_to_dcm(att[:ns + 1])
    Cm = 0.5 * (C[:-1] + C[1:])                                 # per-sample mid attitude
    d_th = np.einsum("kij,kj->ki", Cm, meas.dtheta[:ns] - ideal.dtheta[:ns])
    d_v = np.einsum("kij,kj->ki", Cm, meas.dv[:ns] - ideal.dv[:ns])
    f_n = np.einsum("kij,kj->ki", Cm, ideal.dv[:ns])
    T = float(truth.t[ep[1]] - truth.t[ep[0]])
    u = np.concatenate([d_th.reshape(m, K, 3).sum(1), d_v.reshape(m, K, 3).sum(1)], axis=1) / T
    fn = f_n.reshape(m, K, 3).sum(1) / T
    mid = ep[:-1] + K // 2
    nav = errstate.NavPoint(lat=truth.lat[mid], h=truth.h[mid], vel=truth.vel[mid],
                            Cbn=np.eye(3), fb=fn)
    F = model.F(nav)                                           # (m, n, n)
    B = model.G(errstate.NavPoint(lat=truth.lat[0], h=truth.h[0], vel=truth.vel[0],
                                  Cbn=np.eye(3), fb=fn[0]))[:, :6]   # nav-frame input map
    aug = np.zeros((m, n + 6, n + 6))
    aug[:, :n, :n] = F * T
    aug[:, :n, n:] = B * T
    E = _expm_batch(aug)
    Phi, Gam = E[:, :n, :n], E[:, :n, n:]
    x = np.empty((m + 1, n))
    x[0] = x0
    for k in range(m):
        x[k + 1] = Phi[k] @ x[k] + Gam[k] @ u[k]
    return x


def _cumint(y, t):
    """Cumulative trapezoid integral of y(t) starting at 0."""
    out = np.zeros_like(y, dtype=float)
    out[1:] = np.cumsum(0.5 * (y[1:] + y[:-1]) * np.diff(t))
    return out


def envelopes(t, *, lat, h, eps, n_g, nabla, n_a, sf_g, sf_a, phi0_h, psi0, dv0, dr0,
              acc_cum, rot_cum, speed_max):
    """Closed-form error envelopes (upper bounds) of free-inertial navigation.

    All inputs SI; ``t`` elapsed time [s]; ``eps``/``nabla`` bias magnitudes (3-D norms, a
    bound for any projection on the navigation axes); ``n_g``/``n_a`` random-walk
    magnitudes; ``sf_g``/``sf_a`` largest scale-factor errors; ``phi0_h``, ``psi0`` initial
    tilt and heading error [rad]; ``dv0``, ``dr0`` initial horizontal velocity/position
    errors; ``acc_cum(t) = ∫|a_h| dt`` (horizontal velocity change) and
    ``rot_cum(t) = ∫|ω_ib| dt`` (angle turned by the IMU) from the truth.

    Each source's response in the single-channel Schuler loop (ω_s² = g/R) is bounded by
    the magnitude of its closed form: drift u(t) (monotone) — tilt ≤ u/ω_s, velocity
    ≤ 2Ru, position ≤ R(∫u + u/ω_s); accelerometer bias ∇ — tilt ≤ 2∇/g, velocity ≤ ∇/ω_s,
    position ≤ 2∇/ω_s²; initial tilt φ0 — φ0, gφ0/ω_s, 2Rφ0; initial velocity δv0 —
    δv0/(Rω_s), δv0, δv0/ω_s; white noise at 4σ through the same loop. The heading error
    ψ(t) = ψ0 + εt + sf_g·rot + 4N√t + (ω_ie + V/R)·tilt·t couples into the level channels
    as a drift (ω_ie + V/R)ψ and, in manoeuvres, as velocity impulses ψ·‖Δv‖ (plus the
    accelerometer scale factor times ‖Δv‖).

    Returns a dict of arrays: ``pos``, ``vel``, ``tilt``, ``heading``.
    """
    t = np.asarray(t, float)
    g = float(earth.gravity(lat, h))
    rm, rn = earth.radii(lat, h)
    R = float(np.sqrt(rm * rn))
    ws = math.sqrt(g / R)
    wc = earth.WIE + speed_max / R                # rate coupling heading error into tilt
    st = np.sqrt(t / 2 + 1 / (4 * ws))            # sqrt of ∫cos², ∫sin² over [0, t] (bound)
    # first pass without heading coupling
    psi = psi0 + eps * t + sf_g * rot_cum + 4 * n_g * np.sqrt(t)
    for _ in range(2):
        u = eps + wc * psi                        # effective level drift, monotone in t
        tilt_imp = (psi + sf_a) * acc_cum / (R * ws)   # velocity impulses -> tilt
        tilt = (phi0_h + u / ws + 2 * nabla / g + dv0 / (R * ws) + sf_g * rot_cum
                + tilt_imp + 4 * n_g * st + 4 * n_a * st / (R * ws))
        psi = (psi0 + eps * t + sf_g * rot_cum + 4 * n_g * np.sqrt(t)
               + wc * np.maximum.accumulate(tilt) * t)
    u = eps + wc * psi
    vel = (2 * R * u + nabla / ws + g * phi0_h / ws + dv0 + (psi + sf_a) * acc_cum
           + 4 * R * ws * n_g * st + 4 * n_a * st)
    # impulses J(τ) = (ψ+sf_a)|a|dτ move position by ≤ J·min(t−τ, 1/ω_s)
    cap = 1 / ws
    A = acc_cum
    B = np.concatenate([[0.0], np.cumsum(0.5 * (t[1:] + t[:-1]) * np.diff(A))])   # ∫ τ |a| dτ
    tc = np.clip(t - cap, t[0], None)
    A_c = np.interp(tc, t, A)
    B_c = np.interp(tc, t, B)
    imp_pos = t * (A - A_c) - (B - B_c) + cap * A_c
    pos = (dr0 + R * (_cumint(u, t) + u / ws) + 2 * nabla / ws ** 2 + 2 * R * phi0_h + dv0 / ws
           + (psi + sf_a) * imp_pos
           + 4 * R * n_g * np.sqrt(1.5 * t + 2.25 / ws) + 4 * n_a / ws * st)
    return {"pos": pos, "vel": vel, "tilt": tilt, "heading": psi}


def _euler_to_phi_jacobian(att):
    """d φ / d [pitch, roll, −yaw] at ``att`` (central differences): how the configured
    initial [pitch, roll, heading] errors map to the misalignment φ of the error model."""
    from sinslab.core.attitude import euler_to_dcm, misalignment

    C0 = euler_to_dcm(att)
    J = np.empty((3, 3))
    h = 1e-6
    for k, sgn in enumerate((1.0, 1.0, -1.0)):
        d = np.zeros(3)
        d[k] = sgn * h
        J[:, k] = (misalignment(C0, euler_to_dcm(att + d)) - misalignment(C0, euler_to_dcm(att - d))) / (2 * h)
    return J


def covariance_analysis(truth, ideal, spec, cov_every):
    """Covariance analysis matching :func:`mc_batch`: σ of every error at the Monte Carlo epochs.

    The ENU φ-angle model of :mod:`sinslab.nav.errstate` — core ``"horizontal"`` when the
    vertical channel is held (δh = δv_U = 0, as the mechanization does), ``"full"`` when it
    is free — plus constant gyro and accelerometer bias states (and scale-factor states
    when their σ is not zero) is evaluated along the truth in the middle of every
    covariance step (``cov_every`` updates), discretised exactly (Van Loan,
    :func:`sinslab.estimation.kalman.discretize`, with ARW²/VRW² as white-noise densities), and P0 =
    diag(initial errors², bias σ², scale-factor σ²) is propagated with no measurements by
    :func:`sinslab.estimation.linear.propagate_covariance`.

    Returns
    -------
    t : ndarray (T,)
        Times of the Monte Carlo epochs.
    sigma : ndarray (T, 9)
        σ in the columns of :func:`mc_batch` (position E, N, U [m], velocity [m/s], φ [rad]);
        zero for the held vertical channel.
    model : sinslab.nav.errstate.ErrorModel
    """
    from sinslab.nav import errstate as es
    from sinslab.estimation.kalman import discretize
    from sinslab.estimation.linear import propagate_covariance

    if spec["vertical"] == "damped":
        raise ValueError("the error model has no vertical damping loop: covariance analysis "
                         "needs nav.vertical = 'hold' or 'free'")
    core = "horizontal" if spec["vertical"] == "hold" else "full"
    sensors = [es.gyro_bias(), es.accel_bias()]
    if np.any(spec["gyro_sf_sigma"] > 0):
        sensors.append(es.gyro_scale())
    if np.any(spec["accel_sf_sigma"] > 0):
        sensors.append(es.accel_scale())
    model = es.ErrorModel(core, sensors, gyro_arw=spec["gyro_arw"], accel_vrw=spec["accel_vrw"])
    nsub, mc_every = spec["nsub"], spec["out_every"]
    stride = cov_every * nsub
    m_out = (len(ideal) // nsub) // mc_every
    K = m_out * (mc_every // cov_every)                # covariance steps up to the last MC epoch
    mid = np.arange(K) * stride + stride // 2
    nav = es.NavPoint.from_series(truth, ideal, mid)
    F, G = model.matrices(nav)
    Phi, Qk = discretize(F, model.q, stride * ideal.dt, G=G, method="vanloan")
    # P0: the configured initial errors and sensor σ
    lay = model.layout
    P0 = np.zeros((model.n, model.n))
    att0 = truth.att_imu[0] if truth.att_imu is not None else truth.att[0]
    J = _euler_to_phi_jacobian(att0)
    P0[lay.slice("phi"), lay.slice("phi")] = J @ np.diag(spec["att_sigma"] ** 2) @ J.T
    rm0, rn0 = earth.radii(truth.lat[0], truth.h[0])
    nv = 3 if core == "full" else 2
    sv = lay.slice("dv")
    P0[sv, sv] = np.diag(spec["vel_sigma"][:nv] ** 2)
    sp = lay.slice("dp")
    dp_sig = [spec["pos_sigma"][1] / rm0, spec["pos_sigma"][0] / (rn0 * math.cos(truth.lat[0]))]
    if core == "full":
        dp_sig.append(spec["pos_sigma"][2])
    P0[sp, sp] = np.diag(np.square(dp_sig))
    for name, key in (("eps", "gyro_bias_sigma"), ("nabla", "accel_bias_sigma"),
                      ("kg", "gyro_sf_sigma"), ("ka", "accel_sf_sigma")):
        if name in lay.names:
            sl = lay.slice(name)
            P0[sl, sl] = np.diag(spec[key] ** 2)
    run = propagate_covariance(P0, Phi, Qk, n_steps=K, check=False)
    sig = run.sigma[:: mc_every // cov_every]         # the Monte Carlo epochs
    ep = np.arange(m_out + 1) * mc_every * nsub
    rm, rn = earth.radii(truth.lat[ep], truth.h[ep])
    out = np.zeros((ep.size, 9))
    lab = list(lay.labels)
    out[:, 0] = sig[:, lab.index("dlam")] * rn * np.cos(truth.lat[ep])
    out[:, 1] = sig[:, lab.index("dL")] * rm
    out[:, 3] = sig[:, lab.index("dvE")]
    out[:, 4] = sig[:, lab.index("dvN")]
    for j, c in enumerate("ENU"):
        out[:, 6 + j] = sig[:, lab.index(f"phi{c}")]
    if core == "full":
        out[:, 2] = sig[:, lab.index("dh")]
        out[:, 5] = sig[:, lab.index("dvU")]
    return truth.t[ep], out, model
