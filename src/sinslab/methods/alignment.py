"""Stationary-base initial alignment: coarse, fine (full 8-state / reduced 5-state), limits.

Method: Yan Gongmin & Qin Yongyuan, "Initial alignment accuracy analysis and simulation of
strapdown inertial navigation system on a stationary base", Computer Simulation 23(10),
2006 (paper 000 of this project). Conventions are sinslab's: n = ENU, b = RFU, computed
frame n' with ``C_b^{n'} = (I − φ×) C_b^n`` — which is also the paper's eq (3), so the
paper's equations carry over without sign changes.

Models (derived again here; ``tests/test_alignment.py`` checks every step)
----------------------------------------------------------------------------
Full order (paper eqs 10, 11, 15, 16; :func:`full_model`),
``X = [φE φN φU εE εN εU ∇E ∇N]`` with ε = C_b^n ε^b, ∇ = C_b^n ∇^b, ω_N = ω_ie cos L,
ω_U = ω_ie sin L::

    φ̇ = φ × ω_ie^n − ε − w_g        Z = [f_E', f_N'] = [−g φN + ∇E,  g φE + ∇N] + v

(the printed eq 15b has lost its sign; H of eq 16 and ``−φ×[0,0,g]`` give ``+g φE``).
Observability rank 5 of 8: the unobservable subspace is spanned by the three vectors that
change ∇N, ∇E, εE together with the φ, ε combinations below.

Reduced order (paper eqs 21–24). The observable combinations (eq 21)::

    φE' = φE + ∇N/g                 φN' = φN − ∇E/g
    φU' = φU + εE/ω_N − tan L·∇E/g
    εN' = εN − ∇N ω_U/g             εU' = εU + ∇N ω_N/g

i.e. ``X' = T X`` with the 5×8 matrix :func:`reduction_matrix`. Then ``T F = F' T`` and
``H = H' T`` exactly (ω_N tan L = ω_U makes the ∇E terms cancel), so X' obeys the closed
5-state model (eq 24)::

    F' = [[0, ω_U, −ω_N, 0, 0], [−ω_U, 0, 0, −1, 0], [ω_N, 0, 0, 0, −1], 0, 0]
    H' = [[0, −g, 0, 0, 0], [g, 0, 0, 0, 0]]

which is completely observable. Taking the reduced estimate as the estimate of
``[φE φN φU εN εU]`` leaves, as t → ∞, the residual (true − estimated) ``X_sub − T X``:

    φE → −∇N/g      φN → ∇E/g      φU → −εE/ω_N + tan L·∇E/g
    εN → ∇N ω_U/g   εU → −∇N ω_N/g                  (:func:`limit_accuracy`)

The full filter's residual tends to the component of the initial error in the null space
of T along the prior ``P0 Tᵀ`` (:func:`full_filter_limit`); with an uninformative prior on
∇ and εE relative to φ it equals the same limits.

The fine-alignment measurement is the horizontal specific force in the computed frame,
averaged over each filter period, with the computed attitude propagated from the gyros at
the known (fixed) position: ``q⁺ = q(−ω_ie^n T) ⊗ q ⊗ q(Δθ)``.

Coarse alignment
----------------
:func:`coarse_align`: the analytic (double-vector, TRIAD) solution from the averaged
specific force and angular rate, with the expected error from given biases (the same
formulas as the limits: coarse alignment already reaches them) and noise.
:func:`coarse_align_inertial`: the inertial-frame ("i-frame", gravity-integration) method
for a swaying base: the specific force is integrated in the body frame frozen in inertial
space at the start, gravity is integrated analytically in the navigation frame frozen at
the start, and the two integrals at two epochs fix the attitude by double vectors
(T. Gaiffe et al., "Highly compact fiber optic gyrocompass for applications at depths up to
3000 meters", Proc. Underwater Technology 2000; Qin Yongyuan, *Inertial Navigation*,
Science Press 2006, §8; PSINS ``alignsb``/``aligni0``).
"""
from __future__ import annotations

import math
import warnings as _warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from sinslab.core import attitude as att_
from sinslab.core import earth, units
from sinslab.estimation import kalman, linear
from sinslab.estimation.filter import KalmanFilter
from sinslab.nav import strapdown as sd
from sinslab.core.attitude import q2dcm_s, qmul_s, rv2q_s
from sinslab.core.errors import InputError
from sinslab.core.records import ImuRecord

__all__ = [
    "POLE_MARGIN", "REST_THRESHOLD", "FULL_STATES", "REDUCED_STATES", "LIMIT_STATES",
    "check_alignment_latitude", "full_model", "reduced_model", "reduction_matrix",
    "limit_accuracy", "full_filter_limit", "RestCheck", "rest_check", "CoarseAlignment",
    "coarse_align", "coarse_align_inertial", "FineAlignment", "fine_align", "residuals",
    "euler_sigma", "noise_from_data", "NotAtRestWarning",
]

POLE_MARGIN = 1.0 * units.deg      #: heading is unobservable within this distance of a pole
REST_THRESHOLD = 0.05              #: [m/s²] RMS variation of 1-s mean specific force at rest
FULL_STATES = ("phiE", "phiN", "phiU", "epsE", "epsN", "epsU", "nabE", "nabN")
REDUCED_STATES = ("phiE", "phiN", "phiU", "epsN", "epsU")
LIMIT_STATES = REDUCED_STATES      #: order of :func:`limit_accuracy`'s result
_FULL_SUB = np.array([0, 1, 2, 4, 5])   # full-state indices of LIMIT_STATES


class NotAtRestWarning(UserWarning):
    """The record's specific force varies more than a base at rest allows."""


# ------------------------------------------------------------------------------ models
def check_alignment_latitude(lat: float) -> float:
    """Return ``lat`` [rad] as float; ValueError beyond ±90°, InputError (a ValueError)
    within 1° of a pole."""
    lat = float(lat)
    earth.check_latitude(lat)
    if abs(lat) > math.pi / 2 - POLE_MARGIN:
        raise InputError(f"latitude {math.degrees(lat):.4f} deg is within "
                         f"{math.degrees(POLE_MARGIN):g} deg of a pole: the horizontal Earth rate "
                         f"ω_ie cos L vanishes there and heading is unobservable")
    return lat


def _rates(lat):
    return earth.WIE * math.cos(lat), earth.WIE * math.sin(lat)


def full_model(lat: float, g: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Paper 000's 8-state stationary fine-alignment model (ENU), eqs 11, 16.

    States ``X = [φE φN φU εE εN εU ∇E ∇N]`` (ε, ∇ in n, random constants)::

        φ̇ = φ×ω_ie^n − ε − w_g        (= −ω_ie×φ − ε − w_g)
        Z = [f̃_E, f̃_N] = [−g φN + ∇E, g φE + ∇N] + v

    Parameters
    ----------
    lat : float
        Latitude [rad].
    g : float, optional
        Gravity [m/s²]; default normal gravity at ``lat``, h = 0.

    Returns
    -------
    F : ndarray (8, 8)
    G : ndarray (8, 3)
        Gyro white noise (n frame) input: ``[−I₃; 0]``.
    H : ndarray (2, 8)
    """
    lat = float(lat)
    g = float(earth.gravity(lat, 0.0)) if g is None else float(g)
    wN, wU = _rates(lat)
    F = np.zeros((8, 8))
    F[0:3, 0:3] = -att_.skew(np.array([0.0, wN, wU]))
    F[0:3, 3:6] = -np.eye(3)
    G = np.zeros((8, 3))
    G[0:3, :] = -np.eye(3)
    H = np.zeros((2, 8))
    H[0, 1], H[0, 6] = -g, 1.0
    H[1, 0], H[1, 7] = g, 1.0
    return F, G, H


def reduced_model(lat: float, g: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Paper eq 24: ``(F' (5,5), G' (5,3), H' (2,5))`` of ``[φE' φN' φU' εN' εU']``."""
    wN, wU = _rates(float(lat))
    F = np.zeros((5, 5))
    F[0, 1], F[0, 2] = wU, -wN
    F[1, 0], F[1, 3] = -wU, -1.0
    F[2, 0], F[2, 4] = wN, -1.0
    G = np.zeros((5, 3))
    G[:3] = -np.eye(3)
    H = np.zeros((2, 5))
    H[0, 1] = -float(g)
    H[1, 0] = float(g)
    return F, G, H


def reduction_matrix(lat: float, g: float) -> np.ndarray:
    """``T`` (5×8) of paper eq 21: reduced state ``X' = T X`` of the full state X."""
    lat = float(lat)
    g = float(g)
    wN, wU = _rates(lat)
    T = np.zeros((5, 8))
    T[0, 0], T[0, 7] = 1.0, 1.0 / g
    T[1, 1], T[1, 6] = 1.0, -1.0 / g
    T[2, 2], T[2, 3], T[2, 6] = 1.0, 1.0 / wN, -math.tan(lat) / g
    T[3, 4], T[3, 7] = 1.0, -wU / g
    T[4, 5], T[4, 7] = 1.0, wN / g
    return T


def _nav_biases(att, gyro_bias, accel_bias, frame):
    gb = np.broadcast_to(np.asarray(gyro_bias, dtype=float), (3,))
    ab = np.broadcast_to(np.asarray(accel_bias, dtype=float), (3,))
    if frame == "body":
        C = att_.euler_to_dcm(np.asarray(att, dtype=float))
        return C @ gb, C @ ab
    if frame == "nav":
        return gb.copy(), ab.copy()
    raise ValueError(f"frame must be 'body' or 'nav', got {frame!r}")


def limit_accuracy(lat: float, att: ArrayLike, gyro_bias: float | ArrayLike, accel_bias: float | ArrayLike, *,
                   h: float = 0.0, g: float | None = None, frame: str = "body") -> np.ndarray:
    """Limit accuracy of stationary alignment (residual = true − estimated, t → ∞).

    Parameters
    ----------
    lat : float
        Latitude [rad] (not within 1° of a pole).
    att : array_like (3,)
        ``[pitch, roll, yaw]`` of the IMU [rad] (used to project body biases; ignored for
        ``frame="nav"``).
    gyro_bias, accel_bias : float or array_like (3,)
        Constant gyro drift [rad/s] and accelerometer bias [m/s²].
    h : float
        Height [m] (for normal gravity when ``g`` is not given).
    g : float, optional
        Gravity magnitude [m/s²].
    frame : {"body", "nav"}
        Frame of the given biases.

    Returns
    -------
    ndarray (5,)
        ``[φE, φN, φU, εN, εU]`` limits [rad, rad, rad, rad/s, rad/s] (order
        :data:`LIMIT_STATES`): ``−∇N/g, ∇E/g, −εE/(ω_ie cos L) + tan L·∇E/g,
        ∇N ω_ie sin L/g, −∇N ω_ie cos L/g``.
    """
    lat = check_alignment_latitude(lat)
    g = float(earth.gravity(lat, h)) if g is None else float(g)
    eps, nab = _nav_biases(att, gyro_bias, accel_bias, frame)
    wN, wU = _rates(lat)
    return np.array([-nab[1] / g, nab[0] / g, -eps[0] / wN + math.tan(lat) * nab[0] / g,
                     nab[1] * wU / g, -nab[1] * wN / g])


def full_filter_limit(lat: float, g: float, x0: ArrayLike, P0: ArrayLike) -> np.ndarray:
    """Noise-free limit of the full 8-state filter started at X0 = 0 with covariance P0.

    The observable part ``T X`` is learned exactly; the rest is split by the prior:
    ``X̂ → P0 Tᵀ (T P0 Tᵀ)⁻¹ T X``. Its residual ``(I − P0 Tᵀ (T P0 Tᵀ)⁻¹ T) x0`` lies in
    the null space of T, on which F vanishes, so it is constant in time.

    Returns the 8-vector residual (true − estimated) for the true initial state ``x0``.
    """
    T = reduction_matrix(lat, g)
    P0 = np.asarray(P0, dtype=float)
    x0 = np.asarray(x0, dtype=float)
    Pi = P0 @ T.T @ np.linalg.solve(T @ P0 @ T.T, T)
    return x0 - Pi @ x0


# ---------------------------------------------------------------------------- rest check
@dataclass(frozen=True)
class RestCheck:
    """Is the record at rest? (specific-force variation of 1-s means)

    Attributes
    ----------
    f_rms : float
        RMS over windows of ``|f̄_w − f̄|`` [m/s²].
    f_max : float
        Largest window deviation [m/s²].
    window : float
        Window length [s].
    threshold : float
        Threshold on ``f_rms`` [m/s²].
    at_rest : bool
    message : str
        Empty when at rest, else the warning text.
    """

    f_rms: float
    f_max: float
    window: float
    threshold: float
    at_rest: bool
    message: str = ""


def _block_means(a, nper):
    n = a.shape[0] // nper
    return a[: n * nper].reshape(n, nper, -1).sum(1)


def rest_check(imu: ImuRecord, threshold: float = REST_THRESHOLD, window: float = 1.0) -> RestCheck:
    """Check the record for motion: RMS of 1-s mean specific-force deviations vs ``threshold``."""
    nper = max(1, int(round(window / imu.dt)))
    if len(imu) < 2 * nper:
        nper = max(1, len(imu) // 2)
    fb = _block_means(imu.dv, nper) / (nper * imu.dt)
    d = np.linalg.norm(fb - fb.mean(0), axis=1) if fb.shape[0] > 1 else np.zeros(1)
    rms, mx = float(np.sqrt(np.mean(d ** 2))), float(d.max())
    ok = rms <= threshold
    msg = "" if ok else (f"record is not at rest: the {nper * imu.dt:g}-s mean specific force "
                         f"varies by {rms:.3g} m/s^2 RMS (max {mx:.3g}) > threshold {threshold:g} "
                         f"m/s^2; stationary-alignment results are unreliable")
    return RestCheck(rms, mx, nper * imu.dt, float(threshold), ok, msg)


def noise_from_data(imu: ImuRecord, tau: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Estimate white-noise densities from the record: Allan deviation at ``tau`` × sqrt(tau).

    Returns ``(gyro_arw [rad/sqrt(s)] (3,), accel_vrw [m/s/sqrt(s)] (3,))``. Any
    disturbance at that time scale counts as noise (conservative for a filter).
    """
    nper = max(1, int(round(tau / imu.dt)))
    T = nper * imu.dt
    out = []
    for a in (imu.dtheta, imu.dv):
        m = _block_means(a, nper) / T
        if m.shape[0] < 3:
            raise ValueError("record too short to estimate its noise")
        adev = np.sqrt(0.5 * np.mean(np.diff(m, axis=0) ** 2, axis=0))
        out.append(adev * math.sqrt(T))
    return out[0], out[1]


# ------------------------------------------------------------------------ helpers
def euler_sigma(C: ArrayLike, P_phi: ArrayLike, delta: float = 1e-6) -> np.ndarray:
    """1σ of ``[pitch, roll, yaw]`` [rad] for a misalignment covariance ``P_phi`` (3×3).

    Uses the numerical Jacobian of the Euler angles of ``exp(−φ×) C`` w.r.t. φ.
    """
    C = np.asarray(C, dtype=float)
    J = np.empty((3, 3))
    for i in range(3):
        e = np.zeros(3)
        e[i] = delta
        a1 = att_.dcm_to_euler(att_.apply_misalignment(C, e))
        a0 = att_.dcm_to_euler(att_.apply_misalignment(C, -e))
        J[:, i] = att_.wrap_pi(a1 - a0) / (2 * delta)
    cov = J @ np.asarray(P_phi, dtype=float) @ J.T
    return np.sqrt(np.maximum(np.diag(cov), 0.0))


# ------------------------------------------------------------------- coarse alignment
@dataclass(frozen=True)
class CoarseAlignment:
    """Result of a coarse alignment.

    Attributes
    ----------
    att : ndarray (3,)
        ``[pitch, roll, yaw]`` [rad] of the IMU (at the end of the record for the
        inertial-frame method).
    C_bn : ndarray (3, 3)
    f_mean, w_mean : ndarray (3,)
        Mean specific force [m/s²] and angular rate [rad/s] in the body frame.
    phi_bias : ndarray (3,) or None
        Expected misalignment [rad] (φE, φN, φU) caused by the given biases.
    phi_sigma : ndarray (3,) or None
        1σ misalignment [rad] from the given noise densities.
    phi_sigma_data : ndarray (3,)
        1σ misalignment [rad] from the scatter of the record's 1-s means (noise and
        disturbance as recorded).
    att_sigma : ndarray (3,) or None
        1σ of ``[pitch, roll, yaw]`` [rad] from ``phi_sigma`` (or ``phi_sigma_data``).
    method : str
    duration : float
    rest : RestCheck
    warnings : tuple of str
    """

    att: np.ndarray
    C_bn: np.ndarray
    f_mean: np.ndarray
    w_mean: np.ndarray
    phi_bias: np.ndarray | None
    phi_sigma: np.ndarray | None
    phi_sigma_data: np.ndarray | None
    att_sigma: np.ndarray | None
    method: str
    duration: float
    rest: RestCheck | None = None
    warnings: tuple = ()

    @property
    def heading(self) -> float:
        """Heading clockwise from north [rad], 0..2π."""
        return float(att_.yaw_to_heading(self.att[2]))


def _triad(v1n, v2n, v1b, v2b):
    """C_b^n from two non-parallel vector pairs (v1 exact, v2 fixes the rotation about it)."""
    def frame(a, b):
        u1 = a / np.linalg.norm(a)
        c = np.cross(a, b)
        nc = np.linalg.norm(c)
        if nc < 1e-12 * np.linalg.norm(a) * np.linalg.norm(b):
            raise ValueError("double-vector alignment: the two reference vectors are parallel")
        u2 = c / nc
        return np.column_stack([u1, u2, np.cross(u1, u2)])
    return frame(v1n, v2n) @ frame(v1b, v2b).T


def _phi_noise_sigma(lat, g, sf, sw):
    wN = earth.WIE * math.cos(lat)
    return np.array([sf[1] / g, sf[0] / g,
                     math.sqrt((sw[0] / wN) ** 2 + (math.tan(lat) * sf[0] / g) ** 2)])


def coarse_align(imu: ImuRecord, lat: float, h: float = 0.0, *, gyro_bias: float | ArrayLike | None = None,
                 accel_bias: float | ArrayLike | None = None, gyro_arw: float | ArrayLike | None = None,
                 accel_vrw: float | ArrayLike | None = None, rest_threshold: float = REST_THRESHOLD) -> CoarseAlignment:
    """Analytic (double-vector) coarse alignment at rest from averaged Δθ and Δv.

    The mean specific force ``f̄^b`` and angular rate ``ω̄^b`` are matched to ``[0, 0, g]``
    and ``ω_ie^n`` with the TRIAD construction (gravity exact, Earth rate fixing heading).

    Parameters
    ----------
    imu : ImuRecord
        Record at rest (a warning is issued and kept otherwise).
    lat, h : float
        Latitude [rad] (not within 1° of a pole), height [m].
    gyro_bias, accel_bias : float or array_like (3,), optional
        Body-frame biases [rad/s, m/s²] for the expected error ``phi_bias``:
        ``φE = −∇N/g, φN = ∇E/g, φU = −εE/(ω_ie cos L) + tan L·∇E/g`` (n-frame projections).
    gyro_arw, accel_vrw : float or array_like (3,), optional
        White-noise densities [rad/√s, m/s/√s] for ``phi_sigma`` (averaging over the
        record: σ_ω = N/√T).

    Returns
    -------
    CoarseAlignment
    """
    lat = check_alignment_latitude(lat)
    g = float(earth.gravity(lat, h))
    T = len(imu) * imu.dt
    f = imu.dv.sum(0) / T
    w = imu.dtheta.sum(0) / T
    C = _triad(np.array([0.0, 0.0, g]), earth.wie_n(lat), f, w)
    att = att_.dcm_to_euler(C)
    rest = rest_check(imu, rest_threshold)
    warns = () if rest.at_rest else (rest.message,)
    if warns:
        _warnings.warn(rest.message, NotAtRestWarning, stacklevel=2)
    phi_bias = None
    if gyro_bias is not None or accel_bias is not None:
        gb = 0.0 if gyro_bias is None else gyro_bias
        ab = 0.0 if accel_bias is None else accel_bias
        phi_bias = limit_accuracy(lat, att, gb, ab, g=g)[:3]
    phi_sigma = None
    if gyro_arw is not None or accel_vrw is not None:
        sw = C @ np.diag(units.vec3(gyro_arw, "gyro_arw", default=0.0, nonneg=True, finite=True) ** 2) @ C.T / T
        sf = C @ np.diag(units.vec3(accel_vrw, "accel_vrw", default=0.0, nonneg=True, finite=True) ** 2) @ C.T / T
        phi_sigma = _phi_noise_sigma(lat, g, np.sqrt(np.diag(sf)), np.sqrt(np.diag(sw)))
    phi_sigma_data = None
    nper = max(1, int(round(1.0 / imu.dt)))
    nb = len(imu) // nper
    if nb >= 3:
        fb = C @ (_block_means(imu.dv, nper) / (nper * imu.dt)).T
        wb = C @ (_block_means(imu.dtheta, nper) / (nper * imu.dt)).T
        phi_sigma_data = _phi_noise_sigma(lat, g, fb.std(1, ddof=1) / math.sqrt(nb),
                                          wb.std(1, ddof=1) / math.sqrt(nb))
    ps = phi_sigma if phi_sigma is not None else phi_sigma_data
    att_sigma = None if ps is None else euler_sigma(C, np.diag(ps ** 2))
    return CoarseAlignment(att, C, f, w, phi_bias, phi_sigma, phi_sigma_data, att_sigma,
                           "analytic", T, rest, warns)


@njit(cache=True, inline="always")
def _rotated_dv(a0, a1, a2, a3, tx, ty, tz, ux, uy, uz):
    """C(a)·(Δv + ½ Δθ×Δv): one sample's velocity increment with its rotation compensation,
    in the frame of the attitude quaternion a at the sample's start (scalars)."""
    c = q2dcm_s(a0, a1, a2, a3)
    vx = ux + 0.5 * (ty * uz - tz * uy)
    vy = uy + 0.5 * (tz * ux - tx * uz)
    vz = uz + 0.5 * (tx * uy - ty * ux)
    return (c[0] * vx + c[1] * vy + c[2] * vz, c[3] * vx + c[4] * vy + c[5] * vz,
            c[6] * vx + c[7] * vy + c[8] * vz)


@njit(cache=True)
def _inertial_integrals(dth, dv, k1):
    """Integrate f in the body frame frozen at t0: V(t_k1), V(t_end), q_b^{ib0}(t_end)."""
    a0, a1, a2, a3 = 1.0, 0.0, 0.0, 0.0
    V = np.zeros(3)
    V1 = np.zeros(3)
    for k in range(dth.shape[0]):
        tx, ty, tz = dth[k, 0], dth[k, 1], dth[k, 2]
        nx, ny, nz = _rotated_dv(a0, a1, a2, a3, tx, ty, tz, dv[k, 0], dv[k, 1], dv[k, 2])
        V[0] += nx
        V[1] += ny
        V[2] += nz
        r0, r1, r2, r3 = rv2q_s(tx, ty, tz)
        a0, a1, a2, a3 = qmul_s(a0, a1, a2, a3, r0, r1, r2, r3)
        nn = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
        a0, a1, a2, a3 = a0 / nn, a1 / nn, a2 / nn, a3 / nn
        if k == k1:
            V1[0], V1[1], V1[2] = V[0], V[1], V[2]
    q = np.array([a0, a1, a2, a3])
    return V1, V, q


def _gravity_integral_i0(lat, g, t):
    """∫_0^t C_n^{i0}(τ) [0,0,g] dτ, C_n^{i0}(τ) = exp(ω_ie τ u×), u = [0, cos L, sin L]."""
    u = np.array([0.0, math.cos(lat), math.sin(lat)])
    U = att_.skew(u)
    W = earth.WIE
    M = t * np.eye(3) + (1 - math.cos(W * t)) / W * U + (t - math.sin(W * t) / W) * (U @ U)
    return M @ np.array([0.0, 0.0, g])


def coarse_align_inertial(imu: ImuRecord, lat: float, h: float = 0.0, *, t_mid: float | None = None,
                          rest_threshold: float | None = None) -> CoarseAlignment:
    """Inertial-frame coarse alignment, robust to sway (angular and linear oscillation).

    ``C_b^n(t) = C_{i0}^n(t) · C_{ib0}^{i0} · C_b^{ib0}(t)``: ``C_b^{ib0}`` integrates the
    gyros from the start (no Earth rate); ``V^{ib0}(t) = ∫ C_b^{ib0} f^b dt`` integrates the
    specific force in that frozen body frame — oscillatory accelerations integrate to
    bounded velocities; ``V^{i0}(t) = ∫ C_n^{i0}(τ) [0,0,g] dτ`` is the same integral of the
    reference gravity in the navigation frame frozen at the start (closed form, the
    Earth's rotation about its axis); the pairs at ``t_mid`` and at the end give
    ``C_{ib0}^{i0}`` by double vectors (Gaiffe et al. 2000; Qin 2006 §8; PSINS aligni0).

    Parameters
    ----------
    imu : ImuRecord
        Record on a base fixed in position (swaying allowed). Longer is better: heading
        comes from the rotation of gravity in inertial space (ω_ie cos L · t).
    lat, h : float
        Latitude [rad], height [m].
    t_mid : float, optional
        Time [s] of the first vector (default: the middle of the record).
    rest_threshold : float, optional
        If given, a record whose specific force varies more is flagged (the method does
        not need it; off by default).

    Returns
    -------
    CoarseAlignment
        Attitude at the end of the record (``phi_bias``/``phi_sigma`` are None).
    """
    lat = check_alignment_latitude(lat)
    g = float(earth.gravity(lat, h))
    N = len(imu)
    if N < 4:
        raise ValueError("inertial-frame alignment needs at least 4 samples")
    if t_mid is None:
        k1 = N // 2 - 1
    else:
        k1 = int(np.searchsorted(imu.t, t_mid, side="right")) - 1
        if not 0 <= k1 < N - 1:
            raise ValueError(f"t_mid {t_mid} s is outside the record ({imu.t0}..{imu.t[-1]} s)")
    V1b, V2b, qb = _inertial_integrals(imu.dtheta, imu.dv, k1)
    t1 = (k1 + 1) * imu.dt
    t2 = N * imu.dt
    V1i = _gravity_integral_i0(lat, g, t1)
    V2i = _gravity_integral_i0(lat, g, t2)
    C_ib0_i0 = _triad(V2i, V1i, V2b, V1b)
    u = np.array([0.0, math.cos(lat), math.sin(lat)])
    C_n_i0 = att_.rotvec_to_dcm(earth.WIE * t2 * u)
    C = C_n_i0.T @ C_ib0_i0 @ att_.quat_to_dcm(qb)
    T = N * imu.dt
    warns: tuple[str, ...] = ()
    rest = None
    if rest_threshold is not None:
        rest = rest_check(imu, rest_threshold)
        warns = () if rest.at_rest else (rest.message,)
    return CoarseAlignment(att_.dcm_to_euler(C), C, imu.dv.sum(0) / T, imu.dtheta.sum(0) / T,
                           None, None, None, None, "inertial", T, rest, warns)


# ---------------------------------------------------------------------- fine alignment
@njit(cache=True)
def _propagate(q, dth, dv, dt, wn, k0, nper, nsteps, q_out, f_out):
    """Attitude-only propagation at a fixed position; in place on q (4,).

    For each of ``nsteps`` periods of ``nper`` samples from sample ``k0``: the mean
    specific force in the computed frame -> f_out[j], the quaternion at the end -> q_out[j].
    Per sample: ``q⁺ = q(−ω_ie dt) ⊗ q ⊗ q(Δθ)``; velocity increment in n'
    ``C (Δv + ½Δθ×Δv) − ½(ω_ie dt)×(C Δv)`` (body and frame rotation compensation).
    """
    a0, a1, a2, a3 = q[0], q[1], q[2], q[3]
    e0, e1, e2, e3 = rv2q_s(-wn[0] * dt, -wn[1] * dt, -wn[2] * dt)
    wx, wy, wz = wn[0], wn[1], wn[2]
    hx = 0.5 * dt
    k = k0
    T = nper * dt
    for j in range(nsteps):
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for i in range(nper):
            tx, ty, tz = dth[k, 0], dth[k, 1], dth[k, 2]
            nx, ny, nz = _rotated_dv(a0, a1, a2, a3, tx, ty, tz, dv[k, 0], dv[k, 1], dv[k, 2])
            # the n frame turns by ω_ie dt meanwhile: − ½ (ω_ie dt) × (C Δv)
            sx += nx - hx * (wy * nz - wz * ny)
            sy += ny - hx * (wz * nx - wx * nz)
            sz += nz - hx * (wx * ny - wy * nx)
            r0, r1, r2, r3 = rv2q_s(tx, ty, tz)
            a0, a1, a2, a3 = qmul_s(a0, a1, a2, a3, r0, r1, r2, r3)
            a0, a1, a2, a3 = qmul_s(e0, e1, e2, e3, a0, a1, a2, a3)
            nn = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
            a0, a1, a2, a3 = a0 / nn, a1 / nn, a2 / nn, a3 / nn
            k += 1
        f_out[j, 0] = sx / T
        f_out[j, 1] = sy / T
        f_out[j, 2] = sz / T
        q_out[j, 0], q_out[j, 1], q_out[j, 2], q_out[j, 3] = a0, a1, a2, a3
    q[0], q[1], q[2], q[3] = a0, a1, a2, a3


@dataclass(frozen=True)
class FineAlignment:
    """Result of a fine alignment.

    Attributes
    ----------
    model : str
        ``"full"`` (8 states) or ``"reduced"`` (5 states).
    states : tuple of str
        State names (:data:`FULL_STATES` or :data:`REDUCED_STATES`).
    t : ndarray (K+1,)
        Epochs [s] (row 0: the start).
    x : ndarray (K+1, n)
        State estimate after each update (SI: rad, rad/s, m/s²).
    sigma : ndarray (K+1, n)
        Its 1σ.
    q : ndarray (K+1, 4)
        Computed attitude quaternion at each epoch (before any feedback of that epoch).
    att : ndarray (3,)
        Final ``[pitch, roll, yaw]`` [rad]: the computed attitude corrected by the estimate.
    att_sigma : ndarray (3,)
        Filter 1σ of ``att`` [rad] (observable part only; see :func:`limit_accuracy` for
        the bias-limited part).
    att_path : ndarray (K+1, 3)
        Corrected attitude at every epoch.
    nis : ndarray (K,)
        Normalised innovation squared per update (2 dof).
    lat, h, g, period : float
    feedback : bool
    rest : RestCheck
    gyro_arw, accel_vrw : ndarray (3,)
        Noise densities used in Q and R (for R from data: the E, N Allan deviations ×√T
        and their mean).
    R : ndarray (2, 2)
        Measurement-noise covariance used.
    z : ndarray (K, 2)
        The measurements ``[f_E', f_N']`` [m/s²] (mean over each period).
    Phi, Qk, P0 : ndarray
        The filter's discrete model and initial covariance.
    warnings : tuple of str
    """

    model: str
    states: tuple
    t: np.ndarray
    x: np.ndarray
    sigma: np.ndarray
    q: np.ndarray
    att: np.ndarray
    att_sigma: np.ndarray
    att_path: np.ndarray
    nis: np.ndarray
    lat: float
    h: float
    g: float
    period: float
    feedback: bool
    rest: RestCheck
    gyro_arw: np.ndarray
    accel_vrw: np.ndarray
    P_final: np.ndarray | None = field(repr=False, default=None)
    R: np.ndarray | None = field(repr=False, default=None)
    z: np.ndarray | None = field(repr=False, default=None)
    Phi: np.ndarray | None = field(repr=False, default=None)
    Qk: np.ndarray | None = field(repr=False, default=None)
    P0: np.ndarray | None = field(repr=False, default=None)
    warnings: tuple = ()

    @property
    def phi(self) -> np.ndarray:
        """Estimated misalignment φ̂ (K+1, 3) [rad] of the computed attitude ``q``."""
        return self.x[:, :3]

    @property
    def heading(self) -> float:
        """Heading clockwise from north [rad], 0..2π."""
        return float(att_.yaw_to_heading(self.att[2]))

    def estimates(self) -> np.ndarray:
        """``(K+1, 5)`` estimates of ``[φE φN φU εN εU]`` (order :data:`LIMIT_STATES`)."""
        return self.x[:, _FULL_SUB] if self.model == "full" else self.x


def fine_align(imu: ImuRecord, lat: float, att0: ArrayLike, *, h: float = 0.0, model: str = "reduced",
               period: float = 1.0, gyro_arw: float | ArrayLike | None = None,
               accel_vrw: float | ArrayLike | None = None,
               p0_att: ArrayLike = (100 * units.arcmin, 100 * units.arcmin, 600 * units.arcmin),
               p0_gyro_bias: float = 0.01 * units.dph, p0_accel_bias: float = 100 * units.ug,
               feedback: bool = False, rest_threshold: float = REST_THRESHOLD,
               t0_propagate: float | None = None) -> FineAlignment:
    """Kalman fine alignment at rest (paper 000), full 8-state or reduced 5-state.

    The computed attitude starts at ``att0`` and is propagated with the gyros (Earth
    rate removed, fixed position); every ``period`` the mean specific force in the
    computed frame gives ``Z = [f_E', f_N']``; a linear Kalman filter (sinslab.estimation.kalman)
    with the full model (paper eqs 11, 16) or the reduced one (eq 24) estimates φ (and
    ε, ∇ or their observable combinations).

    Parameters
    ----------
    imu : ImuRecord
        Record at rest (swaying is absorbed by the attitude propagation; linear motion is
        flagged by :func:`rest_check` and carried in ``warnings``).
    lat, h : float
        Latitude [rad] (ValueError within 1° of a pole), height [m].
    att0 : array_like (3,)
        Initial ``[pitch, roll, yaw]`` [rad] (e.g. from :func:`coarse_align`).
    model : {"reduced", "full"}
    period : float
        Filter period [s] (rounded to whole samples).
    gyro_arw : float or array_like (3,), optional
        Body-frame gyro white noise [rad/√s] for Q; default :func:`noise_from_data`
        (which counts any angular motion as noise: give the sensor's value when known).
    accel_vrw : float or array_like (3,), optional
        Body-frame accelerometer white noise [m/s/√s] for R = (C Q_a Cᵀ)_hor / T; default:
        R from the data, the Allan deviation at τ = ``period`` of the horizontal specific
        force in the open-loop computed frame (sensor noise plus whatever disturbance the
        attitude propagation does not remove).
    p0_att : array_like (3,)
        1σ initial φ [rad] (the paper: 100·(10′,10′,60′)² as variance, i.e. 10× these).
    p0_gyro_bias, p0_accel_bias : float
        1σ of the (n-frame) ε and ∇ states [rad/s, m/s²]; the reduced model uses the
        gyro value for εN', εU'.
    feedback : bool
        Closed loop: after each update the φ estimate corrects the computed attitude and
        is zeroed. Open loop (default, as in the paper): the attitude runs free.
    rest_threshold : float
        [m/s²] for :func:`rest_check`.

    Returns
    -------
    FineAlignment
    """
    lat = check_alignment_latitude(lat)
    if model not in ("full", "reduced"):
        raise ValueError(f"model must be 'full' or 'reduced', got {model!r}")
    if not period > 0:
        raise ValueError(f"period must be > 0, got {period}")
    g = float(earth.gravity(lat, h))
    nper = max(1, int(round(period / imu.dt)))
    T = nper * imu.dt
    K = len(imu) // nper
    if K < 2:
        raise ValueError(f"record of {len(imu) * imu.dt:g} s is shorter than two filter periods")
    rest = rest_check(imu, rest_threshold)
    warns = [] if rest.at_rest else [rest.message]
    if warns:
        _warnings.warn(rest.message, NotAtRestWarning, stacklevel=2)
    att0 = np.asarray(att0, dtype=float).reshape(3)
    C0 = att_.euler_to_dcm(att0)
    wn = earth.wie_n(lat)
    if gyro_arw is None:
        gyro_arw = noise_from_data(imu, T)[0]
    gyro_arw = units.vec3(gyro_arw, "gyro_arw", nonneg=True, finite=True)
    if accel_vrw is None:
        # measurement noise as the filter sees it: Allan deviation at τ = T of the
        # horizontal specific force in the (open-loop) computed frame
        fm = np.empty((K, 3))
        _propagate(att_.euler_to_quat(att0).astype(float), imu.dtheta, imu.dv, imu.dt, wn,
                   0, nper, K, np.empty((K, 4)), fm)
        adev = np.sqrt(0.5 * np.mean(np.diff(fm[:, :2], axis=0) ** 2, axis=0))
        R = np.diag(np.maximum(adev, 1e-12) ** 2)
        vrw = np.r_[adev, adev.mean()] * math.sqrt(T)
    else:
        vrw = units.vec3(accel_vrw, "accel_vrw", nonneg=True, finite=True)
        R = (C0 @ np.diag(vrw ** 2) @ C0.T)[:2, :2] / T
        if abs(R[0, 1]) <= 1e-9 * math.sqrt(R[0, 0] * R[1, 1]):
            R = np.diag(np.diag(R))          # isotropic noise: exactly diagonal (scalar updates)
    if model == "full":
        F, G, H = full_model(lat, g)
        sig0 = np.r_[np.asarray(p0_att, float), [p0_gyro_bias] * 3, [p0_accel_bias] * 2]
        names: tuple[str, ...] = FULL_STATES
    else:
        F, G, H = reduced_model(lat, g)
        sig0 = np.r_[np.asarray(p0_att, float), [p0_gyro_bias] * 2]
        names = REDUCED_STATES
    n = F.shape[0]
    Qg = C0 @ np.diag(gyro_arw ** 2) @ C0.T
    Phi, Qk = kalman.discretize(F, Qg, T, G=G)
    P0 = np.diag(sig0 ** 2)
    q = att_.euler_to_quat(att0).astype(float)
    qs = np.empty((K + 1, 4))
    qs[0] = q
    t = imu.t0 + T * np.arange(K + 1)
    if not feedback:
        fm = np.empty((K, 3))
        _propagate(q, imu.dtheta, imu.dv, imu.dt, wn, 0, nper, K, qs[1:], fm)
        zs = fm[:, :2].copy()
        run = linear.run_linear(np.zeros(n), P0, Phi, Qk, H, R, zs)
        assert run.x is not None                # a data run keeps its estimates
        x, sig, nis = run.x, run.sigma, run.nis
        Pf = run.P_saved[-1]
    else:
        kf = KalmanFilter(np.zeros(n), P0, t0=t[0], check=False)
        x = np.empty((K + 1, n))
        sig = np.empty((K + 1, n))
        nis = np.empty(K)
        zs = np.empty((K, 2))
        x[0], sig[0] = kf.x, kf.sigma
        fm = np.empty((1, 3))
        qo = np.empty((1, 4))
        for j in range(K):
            _propagate(q, imu.dtheta, imu.dv, imu.dt, wn, j * nper, nper, 1, qo, fm)
            qs[j + 1] = q
            kf.predict(Phi, Qk, T)
            zs[j] = fm[0, :2]
            res = kf.update(zs[j], H, R)
            x[j + 1], sig[j + 1], nis[j] = kf.x, kf.sigma, res.nis
            d = kf.feedback(slice(0, 3))
            # C_true ≈ exp(φ̂×) C_comp: the attitude part of the feedback correction
            q[:] = sd.correct_rows(np.r_[q, np.zeros(6)], phi=d[:3])[:4]
        Pf = kf.P
    Cq = att_.quat_to_dcm(qs)
    Cc = att_.apply_misalignment(Cq, -x[:, :3])
    att_path = att_.dcm_to_euler(Cc)
    att_sigma = euler_sigma(Cc[-1], Pf[:3, :3])
    return FineAlignment(model, names, t, x, sig, qs, att_path[-1], att_sigma, att_path,
                         np.asarray(nis), lat, float(h), g, T, bool(feedback), rest,
                         gyro_arw, vrw, Pf, R, zs, Phi, Qk, P0, tuple(warns))


def residuals(fine: FineAlignment, C_true: ArrayLike, gyro_bias_n: ArrayLike) -> np.ndarray:
    """Residual (true − estimated) of ``[φE φN φU εN εU]`` at every epoch, (K+1, 5).

    ``C_true`` is the true ``C_b^n`` (3×3, or (K+1, 3, 3)); ``gyro_bias_n`` the true
    n-frame gyro drift [rad/s] (3,) or (K+1, 3).
    """
    phi_true = att_.misalignment(np.asarray(C_true, dtype=float), att_.quat_to_dcm(fine.q))
    eps = np.broadcast_to(np.asarray(gyro_bias_n, dtype=float), (len(fine.t), 3))
    true = np.column_stack([phi_true, eps[:, 1], eps[:, 2]])
    return true - fine.estimates()


def align_record(imu: ImuRecord, lat: float, h: float = 0.0, *, gyro_arw: float | ArrayLike = 0.01 * units.dpsh,
                 accel_vrw: float | ArrayLike | None = None, gyro_bias: float = 0.01 * units.dph,
                 accel_bias: float = 100 * units.ug, model: str = "reduced",
                 period: float = 1.0, feedback: bool = True) -> dict[str, Any]:
    """Coarse (analytic and inertial-frame) and fine alignment of a record at rest.

    ``gyro_bias``/``accel_bias`` are assumed 1σ sensor biases, used only for the limit
    accuracy the result cannot beat (``limit_*``: RSS over axes of the limit formulas
    with the body biases projected by the aligned attitude). Returns a dict of results
    (angles in rad; ``sinslab align`` prints them in display units), the fine result under
    ``fine``.
    """
    import warnings as _w

    with _w.catch_warnings(record=True) as caught:
        _w.simplefilter("always")
        co = coarse_align(imu, lat, h)
        ci = coarse_align_inertial(imu, lat, h)
        fa = fine_align(imu, lat, ci.att, h=h, model=model, period=period, gyro_arw=gyro_arw,
                           accel_vrw=accel_vrw, feedback=feedback)
    warns = sorted({str(w.message) for w in caught})
    g = float(earth.gravity(lat, h))
    T = len(imu) * imu.dt
    f = imu.dv.sum(0) / T
    w = imu.dtheta.sum(0) / T
    # the limit formulas for independent 1σ biases on every axis: RSS of each axis' effect
    lim2 = np.zeros(5)
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0
        lim2 += limit_accuracy(lat, fa.att, e * gyro_bias, 0.0, g=g) ** 2
        lim2 += limit_accuracy(lat, fa.att, 0.0, e * accel_bias, g=g) ** 2
    lim = np.sqrt(lim2)
    lim_att = euler_sigma(att_.euler_to_dcm(fa.att), np.diag(lim[:3] ** 2))
    return dict(coarse=co, inertial=ci, fine=fa, warnings=warns, g=g, f_mean=f, w_mean=w,
                f_norm=float(np.linalg.norm(f)), w_norm=float(np.linalg.norm(w)),
                f_horizontal=float(np.linalg.norm(f[:2])),
                limit=lim, limit_att=lim_att)
