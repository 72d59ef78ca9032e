"""In-motion coarse alignment from GNSS velocity (optimisation-based alignment).

The attitude is split at a start time t0 (Wu & Pan, "Optimization-based alignment for
inertial navigation systems: theory and algorithm", Aerospace Science and Technology 30,
2013; the velocity-integration form of Wu & Pan, "Velocity/position integration formula",
IEEE TAES 49(2), 2013)::

    C_b^n(t) = C_{n0}^{n(t)} · C_{b0}^{n0} · C_{b(t)}^{b0}

where ``b0``/``n0`` are the body and navigation frames at t0 held fixed in inertial space,
``C_{b(t)}^{b0}`` follows from the gyros (the rate against inertial space, so the Earth's
rotation is in it) and ``C_{n(t)}^{n0}`` from the navigation-frame rate
``ω_in^n = ω_ie^n + ω_en^n`` along the GNSS track. The velocity equation
``v̇ = C_b^n f − (2ω_ie + ω_en) × v + g`` multiplied by ``C_{n(t)}^{n0}`` and integrated
from t0 to t (``∫ C_n^{n0} v̇ dt`` by parts, ``d/dt C_n^{n0} = C_n^{n0} (ω_in×)``) gives::

    C_{b0}^{n0} β(t) = α(t)
    β(t) = ∫ C_{b(τ)}^{b0} f^b dτ                                   (IMU increments)
    α(t) = C_{n(t)}^{n0} v(t) − v(t0) + ∫ C_{n(τ)}^{n0} (ω_ie^n × v − g^n) dτ   (GNSS velocity)

with ENU ``g^n = [0, 0, −g]``. No derivative of the GNSS velocity is taken: its noise enters
α once, while gravity makes α grow by g per second. One pair (α, β) per fix time in the
window. The noise of ``v(t0)`` is common to every α; so ``v(t0)`` is treated as unknown,
``α_j + v(t0) = C β_j + v_true(t0)``, and both sets are centred (the translation of the
Procrustes problem drops out, the residuals are the fixes' own independent noise). The
constant ``C_{b0}^{n0}`` that fits the centred pairs best in the least-squares sense
(Wahba's problem, ``min Σ |α_j − C β_j|²``) is the eigenvector of Davenport's 4×4 matrix K
with the largest eigenvalue (the q-method; Markley & Crassidis, *Fundamentals of Spacecraft
Attitude Determination and Control*, 2014, §5.5.1). Gravity fixes pitch and roll; the
heading is as well determined as the horizontal velocity changes in the window are large
and varied (a straight constant-speed window leaves it free).

Covariance of the fit: with ``b_j = Ĉ β_j`` the error ``φ`` (``Ĉ = (I − φ×) C``) moves the
prediction by ``b_j × φ``, so the Fisher information is ``J = Σ (|b_j|² I − b_j b_jᵀ) / σ²``
and ``cov φ = J⁻¹``; σ per component is estimated from the residuals
(``Σ |α_j − Ĉβ_j|² / (3N − 6)`` for N centred pairs: velocity noise, the IMU errors over
the window and any misfit are in it).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.core.records import ImuRecord

__all__ = ["MotionAlignment", "AlignmentScan", "align_in_motion", "first_alignment", "body_integrals",
           "davenport", "wahba_covariance", "velocity_integrals"]


@dataclass(frozen=True)
class MotionAlignment:
    """Result of :func:`align_in_motion`."""

    C_bn: np.ndarray        #: (3, 3) C_b^n at ``t_ref`` (the end of the window)
    t_ref: float            #: [s] the IMU sample boundary the attitude belongs to
    C_bn_start: np.ndarray  #: (3, 3) C_b^n at the first IMU boundary ``t_first`` (C_{b0}^{n0})
    t_first: float          #: [s]
    cov: np.ndarray         #: (3, 3) covariance of φ (E, N, U) [rad²] from the fit
    sigma_v: float          #: a-posteriori σ of one component of α − Cβ [m/s]
    n_vectors: int          #: fix times used
    span: float             #: [s] from the first to the last fix used

    @property
    def att(self):
        """``[pitch, roll, yaw]`` [rad] at ``t_ref``."""
        return A.dcm_to_euler(self.C_bn)

    @property
    def sigma(self):
        """1σ of φ east, north, up [rad] (up: the heading)."""
        return np.sqrt(np.diag(self.cov))


@njit(cache=True)
def _body_kernel(dth, dvl, dt, gbx, gby, gbz, beta, quat):
    """β at every sample boundary from the first (``beta`` (n+1, 3), zero first) and the
    quaternion of C_{b(t)}^{b0} at the last boundary (``quat`` (4,)): rotation and
    sculling (one-plus-previous-sample) compensation of each Δv."""
    q0, q1, q2, q3 = 1.0, 0.0, 0.0, 0.0
    px, py, pz = 0.0, 0.0, 0.0          # previous sample's Δθ and Δv
    ux, uy, uz = 0.0, 0.0, 0.0
    for k in range(dth.shape[0]):
        ax, ay, az = dth[k, 0] - gbx * dt, dth[k, 1] - gby * dt, dth[k, 2] - gbz * dt
        vx, vy, vz = dvl[k, 0], dvl[k, 1], dvl[k, 2]
        # Δv' = Δv + ½ Δθ×Δv + (Δθ_prev×Δv + Δv_prev×Δθ)/12, in the frame at the sample's start
        wx = vx + 0.5 * (ay * vz - az * vy) + ((py * vz - pz * vy) + (uy * az - uz * ay)) / 12.0
        wy = vy + 0.5 * (az * vx - ax * vz) + ((pz * vx - px * vz) + (uz * ax - ux * az)) / 12.0
        wz = vz + 0.5 * (ax * vy - ay * vx) + ((px * vy - py * vx) + (ux * ay - uy * ax)) / 12.0
        c = A.q2dcm_s(q0, q1, q2, q3)
        beta[k + 1, 0] = beta[k, 0] + c[0] * wx + c[1] * wy + c[2] * wz
        beta[k + 1, 1] = beta[k, 1] + c[3] * wx + c[4] * wy + c[5] * wz
        beta[k + 1, 2] = beta[k, 2] + c[6] * wx + c[7] * wy + c[8] * wz
        r0, r1, r2, r3 = A.rv2q_s(ax, ay, az)
        q0, q1, q2, q3 = A.qmul_s(q0, q1, q2, q3, r0, r1, r2, r3)
        nq = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 / nq, q1 / nq, q2 / nq, q3 / nq
        px, py, pz, ux, uy, uz = ax, ay, az, vx, vy, vz
    quat[0], quat[1], quat[2], quat[3] = q0, q1, q2, q3


def body_integrals(imu: ImuRecord, k0: int, k1: int, gyro_bias=None):
    """``(τ (n+1,), β (n+1, 3), C_{b(τ_n)}^{b0})`` over IMU samples ``k0:k1``: β the specific
    force integrated in the body frame at the boundary ``τ_0 = t[k0] − dt`` [m/s], at every
    sample boundary τ; the gyro bias [rad/s] removed."""
    gb = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, dtype=float)
    n = k1 - k0
    beta = np.zeros((n + 1, 3))
    quat = np.zeros(4)
    _body_kernel(np.ascontiguousarray(imu.dtheta[k0:k1]), np.ascontiguousarray(imu.dv[k0:k1]),
                 float(imu.dt), float(gb[0]), float(gb[1]), float(gb[2]), beta, quat)
    tau = np.r_[imu.t[k0] - imu.dt, imu.t[k0:k1]]
    return tau, beta, A.quat_to_dcm(quat)


def velocity_integrals(t, vel, lat, h):
    """``(α (N, 3), C_{n(t_N)}^{n0})`` from GNSS velocities ``vel`` (N, 3) ENU [m/s] at times
    ``t`` (N,) [s] with latitude ``lat`` [rad] and height ``h`` [m]: α(t_j) in the frame n0
    of ``t[0]`` (α(t_0) = 0), the integrals by the trapezoid rule between the fixes, the
    frame rotation by the mean ω_in^n of each interval."""
    vel = np.asarray(vel, dtype=float)
    u = np.cross(E.wie_n(lat), vel) - E.gravity_vector(lat, h)          # ω_ie × v − g
    win = E.win_n(lat, h, vel)
    C = np.eye(3)
    acc = np.zeros(3)
    alpha = np.zeros((len(t), 3))
    for j in range(1, len(t)):
        T = float(t[j] - t[j - 1])
        Cn = C @ A.rotvec_to_dcm(0.5 * (win[j - 1] + win[j]) * T)
        acc += 0.5 * (C @ u[j - 1] + Cn @ u[j]) * T
        C = Cn
        alpha[j] = C @ vel[j] - vel[0] + acc
    return alpha, C


def davenport(alpha, beta, weights=None):
    """The rotation ``C`` (3, 3) minimising ``Σ w_j |α_j − C β_j|²`` (Wahba's problem) by
    Davenport's q-method: the unit eigenvector of the largest eigenvalue of
    ``K = [[tr B, zᵀ], [z, B + Bᵀ − tr B·I]]``, ``B = Σ w_j α_j β_jᵀ``,
    ``z = [B₃₂ − B₂₃, B₁₃ − B₃₁, B₂₁ − B₁₂]`` (``qᵀKq = Σ w_j α_jᵀ C(q) β_j`` for the
    scalar-first quaternion of :func:`sinslab.core.attitude.quat_to_dcm`)."""
    a, b = np.asarray(alpha, float), np.asarray(beta, float)
    w = np.ones(len(a)) if weights is None else np.asarray(weights, float)
    B = (a * w[:, None]).T @ b
    tr = np.trace(B)
    z = np.array([B[2, 1] - B[1, 2], B[0, 2] - B[2, 0], B[1, 0] - B[0, 1]])
    K = np.empty((4, 4))
    K[0, 0], K[0, 1:], K[1:, 0] = tr, z, z
    K[1:, 1:] = B + B.T - tr * np.eye(3)
    _, vec = np.linalg.eigh(K)
    q = vec[:, -1]
    return A.quat_to_dcm(q / np.linalg.norm(q))


def wahba_covariance(C, alpha, beta, fitted=3):
    """``(cov φ (3, 3), σ)`` of the fit ``α ≈ C β`` (see the module notes): σ of one
    component of the residual from the residuals (3N − ``fitted`` degrees of freedom: 3 for
    the rotation, 6 when the pairs were centred), the covariance
    ``σ² [Σ (|b|² I − b bᵀ)]⁻¹``, ``b = C β``, in the frame of α."""
    a, b = np.asarray(alpha, float), np.asarray(beta, float) @ np.asarray(C).T
    r = a - b
    dof = max(3 * len(a) - fitted, 1)
    s2 = float(np.sum(r * r)) / dof
    J = np.sum(b * b) * np.eye(3) - b.T @ b
    return s2 * np.linalg.inv(J), math.sqrt(s2)


def align_in_motion(imu: ImuRecord, t_fix, vel, lat, h, k0: int, k1: int, gyro_bias=None):
    """Attitude at the end of IMU samples ``k0:k1`` (boundary ``t[k1 − 1]``) from the
    fixes inside their span: velocity ``vel`` (N, 3) ENU [m/s], ``lat`` [rad], ``h`` [m] at
    times ``t_fix`` [s]; the gyro bias [rad/s] removed from the increments.

    The pairs (α, β) of the module notes are formed from the first fix in the span; the
    fitted ``C_{b0}^{n0}`` (the attitude at the first boundary, ``C_bn_start``) is carried to the end, ``C_b^n = (C_{n}^{n0})ᵀ C_{b0}^{n0}
    C_{b}^{b0}``. Returns a :class:`MotionAlignment`, or None when fewer than four fixes
    with finite velocity, latitude and height fall inside the span.
    """
    tau, beta_cum, C_bb0 = body_integrals(imu, k0, k1, gyro_bias)
    t_fix = np.asarray(t_fix, dtype=float)
    ok = np.all(np.isfinite(np.asarray(vel, float)), axis=1) & np.isfinite(np.asarray(lat, float)) & \
        np.isfinite(np.asarray(h, float))
    j = np.flatnonzero((t_fix >= tau[0]) & (t_fix <= tau[-1]) & ok)
    if j.size < 4:
        return None
    tj = t_fix[j]
    alpha, C_nn0 = velocity_integrals(tj, np.asarray(vel, float)[j], np.asarray(lat, float)[j],
                                      np.asarray(h, float)[j])
    # β from the first fix on, in the body frame of the first IMU boundary τ_0 (the
    # increments interpolated linearly inside a sample)
    beta = np.stack([np.interp(tj, tau, beta_cum[:, i]) for i in range(3)], -1)
    beta -= beta[0]
    # v(t0) unknown: α_j + v(t0) against β_j, both centred (module notes)
    a_c, b_c = alpha - alpha.mean(0), beta - beta.mean(0)
    C0 = davenport(a_c, b_c)
    cov, s = wahba_covariance(C0, a_c, b_c, fitted=6)
    # carried to the end: φ there is C_n^{n0}ᵀ φ0 (the frame n turned by ω_in)
    C_end = C_nn0.T @ C0 @ C_bb0
    return MotionAlignment(C_end, float(tau[-1]), C0, float(tau[0]), C_nn0.T @ cov @ C_nn0, s, int(j.size), float(tj[-1] - tj[0]))


@dataclass(frozen=True)
class AlignmentScan:
    """What :func:`first_alignment` found: the fit it accepts (or None) and, for a refusal
    that names what the record lacks, the figures of the windows it tried."""

    fit: MotionAlignment | None     #: the first window whose heading σ met the bound
    windows: int                    #: windows tried
    moving_windows: int             #: of which the fixes were all faster than the speed bound
    best_heading_sigma: float       #: [rad] the smallest heading σ of the moving windows (inf: none)
    best_t: float                   #: [s] end of that window (nan: none)
    max_speed: float                #: [m/s] the fastest fix after ``t_from``
    max_horizontal_accel: float     #: [m/s²] the largest horizontal acceleration of the fixes there


def first_alignment(imu: ImuRecord, t_fix, vel, lat, h, t_from, *, window=10.0, step=1.0,
                    min_speed=2.0, max_heading_sigma=math.radians(3.0), gyro_bias=None):
    """The first in-motion alignment (:func:`align_in_motion`) over ``window`` s of fixes,
    slid by ``step`` s from ``t_from`` [s], whose heading σ is at most
    ``max_heading_sigma`` [rad] and whose fixes are all faster than ``min_speed`` [m/s].

    Unlike a heading taken from the course, the fit needs no straight line: the heading is
    seen through the horizontal accelerations (turns, speed changes, a climb), so a
    vehicle in continuous coordinated turns aligns best. Returns an
    :class:`AlignmentScan` (``fit`` None when no window qualifies, with the figures a
    refusal names).
    """
    t_fix = np.asarray(t_fix, dtype=float)
    vel = np.asarray(vel, dtype=float)
    spd = np.hypot(vel[:, 0], vel[:, 1])
    after = t_fix >= t_from
    if after.sum() >= 3:
        tv, vv = t_fix[after], vel[after]
        acc = np.hypot(np.gradient(vv[:, 0], tv), np.gradient(vv[:, 1], tv))
        max_acc = float(np.max(acc))
    else:
        max_acc = 0.0
    max_spd = float(np.max(spd[after])) if after.any() else 0.0
    n_win = n_mov = 0
    best, best_t = math.inf, math.nan
    t_end = min(float(t_fix[-1]), float(imu.t[-1]))
    t0 = max(float(t_from), float(imu.t0))
    while t0 + window <= t_end + 1e-9:
        n_win += 1
        w = (t_fix >= t0) & (t_fix <= t0 + window)
        if w.sum() >= 4 and np.all(spd[w] > min_speed):
            n_mov += 1
            k0 = int(np.searchsorted(imu.t, t0 + imu.dt - 1e-9))
            k1 = int(np.searchsorted(imu.t, t0 + window + 1e-9))
            fit = align_in_motion(imu, t_fix, vel, lat, h, k0, k1, gyro_bias)
            if fit is not None:
                hs = float(fit.sigma[2])
                if hs < best:
                    best, best_t = hs, fit.t_ref
                if hs <= max_heading_sigma:
                    return AlignmentScan(fit, n_win, n_mov, best, best_t, max_spd, max_acc)
        t0 += step
    return AlignmentScan(None, n_win, n_mov, best, best_t, max_spd, max_acc)
