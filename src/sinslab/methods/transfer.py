"""Transfer alignment: velocity + attitude matching of a slave INS against a master INS.

The master (body frame m) is an accurate INS taken as error-free; the slave (body frame s)
is mounted with an installation attitude ``C_s^m`` and navigates with its own IMU. The
filter estimates the slave's misalignment φ^n, velocity error δv^n, the installation
misalignment and the slave's sensor errors (21 states, :func:`transfer_model`).

Conventions (sinslab): n = ENU, bodies RFU, ``att = [pitch, roll, yaw]`` with
``C_b^n = R_z(ψ) R_x(θ) R_y(γ)``; the slave's computed attitude is
``Ĉ_s^n = exp(−φ×) C_s^n ≈ (I − φ×) C_s^n``; the true slave attitude is
``C_s^n = C_m^n C_s^m``. The installation is written

- without compensation (methods 1–3 of the paper): ``C_s^m = exp(λ×)``, λ the *whole*
  installation attitude (small only when the slave is mounted nearly parallel);
- with a known compensation ``Ĉ_s^m`` (method 4, and optionally any method):
  ``C_s^m = Ĉ_s^m exp(φ_α×)`` with φ_α the small residual.

Both cases are one formula with the *reference attitude* ``C_r = C_m^n Ĉ_s^m``
(``Ĉ_s^m = I`` without compensation) and the installation state ``a`` (λ or φ_α)::

    Ĉ_s^n = exp(−φ×) · C_r · exp(a×)

Attitude measurements (:class:`AttitudeMatch`; the four methods of "Attitude matching
method of transfer alignment based on the measured misalignment angle", after Kain's
measured misalignment):

1. ``"euler"``  z = att(Ĉ_s^n) − att(C_r) (wrapped), ordered [pitch, roll, yaw];
2. ``"dcm"``    z = [Ĉ12 − C12, Ĉ31 − C31, Ĉ32 − C32] of ``Ĉ_s^n − C_r`` (1-based);
3. ``"kain"``   z = φ_m, ``C_r^T Ĉ_s^n = exp(φ_m×)``, i.e. ``Ĉ_n^s C_r = I − (φ_m×)``;
   to first order ``φ_m = a − C_r^T φ`` (paper eq 16);
4. ``"optimal"`` method 3 right-multiplied by the compensation ``Ĉ_s^m`` (paper eqs
   17–23): the same formula with ``C_r = C_m^n Ĉ_s^m``; ``φ_m = φ_α − C_n^s φ``.

``H`` is the Jacobian of z over ``[φE φN φU, a_x a_y a_z]``: by default at ``φ = 0, a = 0``
(the paper's linearisation; with a large uncompensated installation this is where it
fails), or re-linearised at the current installation estimate ``â`` (EKF form,
:meth:`AttitudeMatch.H` with ``a0``).

Euler-angle row of H (derived here, sinslab convention, C = C_r, elements 1-based,
``fθ = 1/√(1−C32²)``, ``fγ = 1/(C31²+C33²)``, ``fψ = 1/(C12²+C22²)``)::

    δθ = fθ (−C22 φE + C12 φN + C33 ax − C31 az)
    δγ = fγ [(C21C33 − C31C23) φE + (C13C31 − C11C33) φN − C31C32 ax − C32C33 az] + ay
    δψ = fψ [C12C32 φE + C22C32 φN + (C12C23 − C13C22) ax + (C11C22 − C12C21) az] − φU

The paper's printed eqs 7–8 differ: the ay term of δγ and the φU term of δψ carry the
factor fγ / fψ (they must not), and in sinslab's yaw (counter-clockwise) the φN, ax, az
and φU coefficients of δψ have the opposite sign; read as the clockwise heading the
printed φN, ax, az signs are right but the φE term then has the wrong sign.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from sinslab.core.attitude import (dcm_to_euler, dcm_to_quat, dcm_to_rotvec, q2dcm_s, q2euler_s, qmul_s,
                                   rotvec_to_dcm, skew, wrap_pi, wrap_pi_s)
from sinslab.estimation.kernels import (gain_correct, innovation, predict_lanes, predicted_dense,
                                        sequential_update_lanes, state_predict_dense)
from sinslab.estimation.linear import propagate_covariance, sparsity
from sinslab.nav import errstate

__all__ = [
    "KINDS", "AttitudeMatch", "VelocityMatch", "transfer_model", "jr", "jr_inv", "jl_inv",
    "AttitudeMeasurement", "VelocityMeasurement", "MasterRecord", "batch_filter",
    "paper_euler_H", "FLOPS", "align_recorded", "TransferResult", "TransferMeasurement",
    "align_lanes", "LaneAlignment", "CommonGains", "lane_gains", "batch_gains", "PARAMETERISATION", "parameterisation", "installation_parameters",
    "rate_correlation", "rate_norms", "rate_lag", "propagate_errors",
]

KINDS = ("euler", "dcm", "kain", "optimal")

# indices of C12, C31, C32 (1-based) in a row-major 3x3
_DCM_ELEMENTS = ((0, 1), (2, 0), (2, 1))


# ----------------------------------------------------------------- SO(3) Jacobians ----
def jr(a):
    """Right Jacobian of SO(3): ``exp((a+δ)×) ≈ exp(a×) exp((J_r(a) δ)×)``; (3,) -> (3, 3)."""
    a = np.asarray(a, dtype=float)
    t = float(np.linalg.norm(a))
    K = skew(a)
    if t < 1e-6:
        return np.eye(3) - 0.5 * K + K @ K / 6.0
    return np.eye(3) - (1.0 - math.cos(t)) / t ** 2 * K + (t - math.sin(t)) / t ** 3 * K @ K


def jr_inv(a):
    """Inverse right Jacobian: ``log(exp(a×) exp(δ×)) ≈ a + J_r⁻¹(a) δ``."""
    a = np.asarray(a, dtype=float)
    t = float(np.linalg.norm(a))
    K = skew(a)
    if t < 1e-6:
        return np.eye(3) + 0.5 * K + K @ K / 12.0
    c = 1.0 / t ** 2 - (1.0 + math.cos(t)) / (2.0 * t * math.sin(t))
    return np.eye(3) + 0.5 * K + c * K @ K


def jl_inv(a):
    """Inverse left Jacobian: ``log(exp(δ×) exp(a×)) ≈ a + J_l⁻¹(a) δ`` (= J_r⁻¹(−a))."""
    return jr_inv(-np.asarray(a, dtype=float))


def _jr_many(a):
    """:func:`jr` of many vectors, (R, 3) -> (R, 3, 3), the same operations row by row."""
    t = np.linalg.norm(a, axis=-1)[:, None, None]
    K = skew(a)
    small = t < 1e-6
    ts = np.where(small, 1.0, t)
    big = np.eye(3) - (1.0 - np.cos(ts)) / ts ** 2 * K + (ts - np.sin(ts)) / ts ** 3 * K @ K
    return np.where(small, np.eye(3) - 0.5 * K + K @ K / 6.0, big)


def _jl_inv_many(a):
    """:func:`jl_inv` of many vectors, (R, 3) -> (R, 3, 3)."""
    K = skew(-a)
    t = np.linalg.norm(a, axis=-1)[:, None, None]
    small = t < 1e-6
    ts = np.where(small, 1.0, t)
    c = 1.0 / ts ** 2 - (1.0 + np.cos(ts)) / (2.0 * ts * np.sin(ts))
    return np.where(small, np.eye(3) + 0.5 * K + K @ K / 12.0, np.eye(3) + 0.5 * K + c * K @ K)


def _check_dcm(C, name):
    C = np.asarray(C, dtype=float)
    if C.shape != (3, 3) or not np.all(np.isfinite(C)):
        raise ValueError(f"{name} must be a finite 3x3 DCM, got shape {C.shape}")
    return C


# ------------------------------------------------------------- attitude measurement ---
class AttitudeMatch:
    """One of the four attitude-matching measurements (z and its H).

    Parameters
    ----------
    kind : {"euler", "dcm", "kain", "optimal"}
        Measurement form (see the module docstring).
    compensation : array_like (3, 3), optional
        Known installation DCM ``Ĉ_s^m`` (slave body -> master body). With it the
        installation state is the residual φ_α (``C_s^m = Ĉ_s^m exp(φ_α×)``); without
        it the state is the whole installation λ (``C_s^m = exp(λ×)``). ``"optimal"`` is
        ``"kain"`` with a compensation (identity when none is given).

    Notes
    -----
    All arguments named ``C_m_n`` are the master ``C_m^n`` and ``C_s_n_hat`` the slave's
    computed ``Ĉ_s^n`` (body -> ENU).
    """

    def __init__(self, kind: str, compensation=None):
        if kind not in KINDS:
            raise ValueError(f"unknown attitude-matching kind {kind!r}; choose from {list(KINDS)}")
        self.kind = kind
        self.compensation = np.eye(3) if compensation is None else _check_dcm(compensation, "compensation")
        if abs(np.linalg.det(self.compensation) - 1.0) > 1e-6:
            raise ValueError("compensation must be a rotation matrix (det 1)")
        self.compensated = compensation is not None

    # -- the measured quantity
    def reference(self, C_m_n):
        """Reference attitude ``C_r = C_m^n Ĉ_s^m`` (3, 3)."""
        return _check_dcm(C_m_n, "C_m_n") @ self.compensation

    def _g(self, C, Cr):
        if self.kind == "euler":
            return wrap_pi(dcm_to_euler(C) - dcm_to_euler(Cr))
        if self.kind == "dcm":
            D = C - Cr
            return np.array([D[i, j] for i, j in _DCM_ELEMENTS])
        return dcm_to_rotvec(Cr.T @ C)

    def z(self, C_m_n, C_s_n_hat):
        """Measurement [rad or -] (3,) from the master and the slave's computed DCM."""
        return self._g(_check_dcm(C_s_n_hat, "C_s_n_hat"), self.reference(C_m_n))

    def predict(self, C_m_n, phi, a):
        """Model value ``h(φ, a)`` of z for ``Ĉ_s^n = exp(−φ×) C_r exp(a×)`` (exact)."""
        Cr = self.reference(C_m_n)
        C = rotvec_to_dcm(-np.asarray(phi, float)) @ Cr @ rotvec_to_dcm(np.asarray(a, float))
        return self._g(C, Cr)

    # -- its Jacobian
    def H(self, C_m_n, C_s_n_hat=None, a0=None):
        """Jacobian (3, 6) of z over ``[φE φN φU, a_x a_y a_z]`` at ``φ = 0``, ``a = a0``.

        Parameters
        ----------
        C_m_n : (3, 3)
            Master attitude.
        C_s_n_hat : (3, 3), optional
            Slave computed attitude; unused by the linearisation at the model point
            (``Ĉ_s^n = C_r exp(a0×)`` there) and accepted for the common face.
        a0 : (3,), optional
            Installation estimate to linearise at (EKF form); default 0 (paper form).
        """
        Cr = self.reference(C_m_n)
        a0 = np.zeros(3) if a0 is None else np.asarray(a0, dtype=float)
        if self.kind in ("kain", "optimal"):
            # z = log(exp(−(C_rᵀφ)×) exp(a×)): left perturbation −J_l⁻¹(a0) C_rᵀ, right J_r⁻¹ J_r = I
            return np.hstack([-jl_inv(a0) @ Cr.T, np.eye(3)])
        C0 = Cr @ rotvec_to_dcm(a0) if a0.any() else Cr
        Jr = jr(a0) if a0.any() else np.eye(3)
        H = np.empty((3, 6))
        for i in range(3):
            e = np.zeros(3)
            e[i] = 1.0
            H[:, i] = self._dg(C0, -skew(e) @ C0)
            H[:, 3 + i] = self._dg(C0, C0 @ skew(Jr[:, i]))
        return H

    def _dg(self, C, dC):
        """Differential of the measured quantity at C along dC (Euler / DCM forms)."""
        if self.kind == "dcm":
            return np.array([dC[i, j] for i, j in _DCM_ELEMENTS])
        # θ = asin(C32), γ = atan2(−C31, C33), ψ = atan2(−C12, C22)
        dth = dC[2, 1] / math.sqrt(1.0 - C[2, 1] ** 2)
        dga = (C[2, 0] * dC[2, 2] - C[2, 2] * dC[2, 0]) / (C[2, 0] ** 2 + C[2, 2] ** 2)
        dps = (C[0, 1] * dC[1, 1] - C[1, 1] * dC[0, 1]) / (C[0, 1] ** 2 + C[1, 1] ** 2)
        return np.array([dth, dga, dps])

    def innovation_z(self, C_m_n, C_s_n_hat, phi_hat=None, a_hat=None, relinearise=False):
        """``(z_eff, H)`` for a linear update ``z_eff − H x̂``.

        Paper form: ``z_eff = z`` and H at 0. EKF form (``relinearise=True``): H at
        ``a_hat`` and ``z_eff = z − h(x̂) + H x̂`` so that the innovation is ``z − h(x̂)``.
        """
        z = self.z(C_m_n, C_s_n_hat)
        if not relinearise:
            return z, self.H(C_m_n)
        phi_hat = np.zeros(3) if phi_hat is None else np.asarray(phi_hat, float)
        a_hat = np.zeros(3) if a_hat is None else np.asarray(a_hat, float)
        H = self.H(C_m_n, a0=a_hat)
        x = np.concatenate([phi_hat, a_hat])
        d = z - self.predict(C_m_n, phi_hat, a_hat)
        if self.kind == "euler":
            d = wrap_pi(d)
        return d + H @ x, H

    def innovation_many(self, C_m_n, C_s_n_hat, phi_hat, a_hat):
        """EKF-form :meth:`innovation_z` of many runs.

        Parameters
        ----------
        C_m_n : (3, 3) or (R, 3, 3)
            Master attitude, common to the runs or one per run.
        C_s_n_hat : (R, 3, 3)
            Slave computed attitudes of the runs.
        phi_hat, a_hat : (R, 3)
            Current estimates of φ [rad] and of the installation state [rad].

        Returns
        -------
        z_eff : (R, 3) ; H : (R, 3, 6)
            Per run, what :meth:`innovation_z` with ``relinearise=True`` returns (the same
            formulas, evaluated on stacked arrays instead of one run at a time).
        """
        Cr = self.reference_many(C_m_n)
        phi_hat = np.asarray(phi_hat, float)
        a_hat = np.asarray(a_hat, float)
        nr = a_hat.shape[0]
        H = np.empty((nr, 3, 6))
        if self.kind in ("kain", "optimal"):
            H[:, :, :3] = -_jl_inv_many(a_hat) @ np.swapaxes(Cr, -1, -2)
            H[:, :, 3:] = np.eye(3)
        else:
            nz = a_hat.any(axis=1)[:, None, None]
            C0 = np.where(nz, Cr @ rotvec_to_dcm(a_hat), Cr)
            Jr = np.where(nz, _jr_many(a_hat), np.eye(3))
            for i in range(3):
                e = np.zeros(3)
                e[i] = 1.0
                H[:, :, i] = self._dg_many(C0, -skew(e) @ C0)
                H[:, :, 3 + i] = self._dg_many(C0, C0 @ skew(Jr[:, :, i]))
        z = self._g_many(np.asarray(C_s_n_hat, float), Cr)
        pred = self._g_many(rotvec_to_dcm(-phi_hat) @ Cr @ rotvec_to_dcm(a_hat), Cr)
        d = z - pred
        if self.kind == "euler":
            d = wrap_pi(d)
        x = np.concatenate([phi_hat, a_hat], axis=1)
        return d + np.einsum("rij,rj->ri", H, x), H

    def H_many(self, C_m_n):
        """:meth:`H` at ``φ = 0``, ``a = 0`` (the paper's linearisation) of many master
        attitudes (K, 3, 3): (K, 3, 6), the same formulas on stacked arrays."""
        Cr = self.reference_many(C_m_n)
        H = np.empty(Cr.shape[:-2] + (3, 6))
        if self.kind in ("kain", "optimal"):
            H[..., :3] = -np.swapaxes(Cr, -1, -2)
            H[..., 3:] = np.eye(3)
            return H
        for i in range(3):
            e = np.zeros(3)
            e[i] = 1.0
            H[..., i] = self._dg_many(Cr, -skew(e) @ Cr)
            H[..., 3 + i] = self._dg_many(Cr, Cr @ skew(e))
        return H

    def reference_many(self, C_m_n):
        """:meth:`reference` of one (3, 3) or many (R, 3, 3) master attitudes."""
        C = np.asarray(C_m_n, dtype=float)
        if C.shape[-2:] != (3, 3) or C.ndim not in (2, 3):
            raise ValueError(f"C_m_n must be (3, 3) or (R, 3, 3), got {C.shape}")
        return C @ self.compensation

    def z_many(self, C_m_n, C_s_n_hat):
        """:meth:`z` of many slave attitudes (R, 3, 3) against one (3, 3) or R master
        attitudes; (R, 3)."""
        return self._g_many(np.asarray(C_s_n_hat, float), self.reference_many(C_m_n))

    def _g_many(self, C, Cr):
        """:meth:`_g` of many attitudes C (R, 3, 3) against one reference or one per attitude."""
        if self.kind == "euler":
            return wrap_pi(dcm_to_euler(C) - dcm_to_euler(Cr))
        if self.kind == "dcm":
            D = C - Cr
            return np.stack([D[..., i, j] for i, j in _DCM_ELEMENTS], -1)
        return dcm_to_rotvec(np.swapaxes(Cr, -1, -2) @ C)

    def _dg_many(self, C, dC):
        """:meth:`_dg` of many (C, dC) pairs, (R, 3, 3) each -> (R, 3)."""
        if self.kind == "dcm":
            return np.stack([dC[:, i, j] for i, j in _DCM_ELEMENTS], -1)
        dth = dC[:, 2, 1] / np.sqrt(1.0 - C[:, 2, 1] ** 2)
        dga = (C[:, 2, 0] * dC[:, 2, 2] - C[:, 2, 2] * dC[:, 2, 0]) / (C[:, 2, 0] ** 2 + C[:, 2, 2] ** 2)
        dps = (C[:, 0, 1] * dC[:, 1, 1] - C[:, 1, 1] * dC[:, 0, 1]) / (C[:, 0, 1] ** 2 + C[:, 1, 1] ** 2)
        return np.stack([dth, dga, dps], -1)


#: Floating-point operations of one z + H of each form (paper linearisation, closed forms;
#: a trigonometric function, sqrt or division counts as one):
#: euler: z = 6 angle extractions + 3 differences; H = 31 multiplications, 7 additions,
#: 3 divisions, 1 sqrt (fθ, fγ, fψ and the 12 non-trivial entries) -> 51;
#: dcm: z = 3 differences, H = copies of master elements -> 3;
#: kain: z = C_rᵀĈ (27 mul + 18 add) + small-angle extraction (6), H = −C_rᵀ (copies) -> 51;
#: optimal: kain plus C_r = C_m^n Ĉ_s^m (45) -> 96.
FLOPS = {"euler": 51, "dcm": 3, "kain": 51, "optimal": 96}


def paper_euler_H(C):
    """Euler-angle H (3, 6) exactly as printed in the paper's eqs 6–8 (for comparison)."""
    c = lambda i, j: C[i - 1, j - 1]  # noqa: E731
    ft = 1.0 / math.sqrt(1.0 - c(3, 2) ** 2)
    fg = 1.0 / (c(3, 1) ** 2 + c(3, 3) ** 2)
    fp = 1.0 / (c(1, 2) ** 2 + c(2, 2) ** 2)
    H = np.zeros((3, 6))
    H[0] = ft * np.array([-c(2, 2), c(1, 2), 0.0, c(3, 3), 0.0, -c(3, 1)])
    H[1] = fg * np.array([c(2, 1) * c(3, 3) - c(3, 1) * c(2, 3), c(1, 3) * c(3, 1) - c(1, 1) * c(3, 3), 0.0,
                          -c(3, 1) * c(3, 2), 1.0, -c(3, 2) * c(3, 3)])
    H[2] = fp * np.array([c(1, 2) * c(3, 2), -c(2, 2) * c(3, 2), 1.0, c(1, 3) * c(2, 2) - c(1, 2) * c(2, 3),
                          0.0, c(1, 2) * c(2, 1) - c(1, 1) * c(2, 2)])
    return H


# ------------------------------------------------------------------ the 21-state model -
def transfer_model(installation_name="lam"):
    """21-state transfer-alignment model (paper eqs 29–33) from :mod:`sinslab.nav.errstate`.

    States ``[φ (3, n), δv (3, n), a (3, slave body: λ or φ_α), ε (3, gyro bias, body),
    k_g (3, gyro scale factor), ∇ (3, accel bias, body), k_a (3, accel scale factor)]``;
    the position is taken from the master (``"attvel"`` core). All sensor and installation
    states are random constants. Signs follow sinslab (errors measured − true, φ from
    ``Ĉ = (I − φ×) C``): ``φ̇ = −ω_in×φ + δω_in − C_s^n(ε + diag(ω) k_g)``,
    ``δv̇ = f^n×φ + C_s^n(∇ + diag(f) k_a) − (2ω_ie+ω_en)×δv + ...``.
    """
    return errstate.ErrorModel("attvel", [errstate.installation(installation_name), errstate.gyro_bias(),
                                          errstate.gyro_scale(), errstate.accel_bias(), errstate.accel_scale()])


class VelocityMatch:
    """Velocity matching ``z = v_s − v_m`` [m/s] (ENU), ``H = [0 I 0]`` on the 21 states."""

    def __init__(self, n=21, dv_slice=slice(3, 6)):
        self.H = np.zeros((3, n))
        self.H[np.arange(3), np.arange(dv_slice.start, dv_slice.stop)] = 1.0

    def z(self, v_m, v_s_hat):
        return np.asarray(v_s_hat, float) - np.asarray(v_m, float)


# ------------------------------------------------------- driver measurement plug-ins ---
class MasterRecord:
    """Master INS output held by a measurement: times [s], attitudes, velocities (ENU).

    ``att`` (N, 3) ``[pitch, roll, yaw]`` [rad]; ``vel`` (N, 3) [m/s]. :meth:`at` linearly
    interpolates velocity and interpolates attitude on SO(3) between neighbouring samples.
    """

    def __init__(self, t, att, vel):
        from sinslab.core.attitude import euler_to_dcm
        self.t = np.asarray(t, float)
        if self.t.ndim != 1 or self.t.size < 2 or np.any(np.diff(self.t) <= 0):
            raise ValueError("master times must be a strictly increasing 1-D array of >= 2 samples")
        self.C = euler_to_dcm(np.asarray(att, float))
        self.vel = np.asarray(vel, float)

    def at(self, t):
        """``(C_m^n, v_m)`` at time t (inside the record)."""
        if not (self.t[0] - 1e-9 <= t <= self.t[-1] + 1e-9):
            raise ValueError(f"time {t:g} s is outside the master record [{self.t[0]:g}, {self.t[-1]:g}] s")
        i = int(np.clip(np.searchsorted(self.t, t) - 1, 0, self.t.size - 2))
        w = (t - self.t[i]) / (self.t[i + 1] - self.t[i])
        C0, C1 = self.C[i], self.C[i + 1]
        C = C0 @ rotvec_to_dcm(w * dcm_to_rotvec(C0.T @ C1))
        return C, (1 - w) * self.vel[i] + w * self.vel[i + 1]

    def take(self, idx):
        """The record at the samples ``idx`` (increasing integer indices), values unchanged."""
        idx = np.asarray(idx, dtype=np.int64)
        out = object.__new__(MasterRecord)
        out.t, out.C, out.vel = self.t[idx], self.C[idx], self.vel[idx]
        if out.t.size < 2 or np.any(np.diff(out.t) <= 0):
            raise ValueError("a master record needs >= 2 samples at increasing times")
        return out


class _MasterTimed:
    """Schedule of a measurement whose items are the master epochs (valid = arrival)."""

    def epochs(self, grid):
        """``{filter epoch: [master items]}`` for the master epochs on the filter grid."""
        t = self.master.t
        e = np.ceil((t - grid.t0) / grid.T - 1e-6).astype(np.int64)
        on = (e >= 0) & (e <= grid.n) & (np.abs(grid.t0 + e * grid.T - t) <= 1e-6 * grid.T + 1e-9)
        out = {}
        for j in np.flatnonzero(on):
            out.setdefault(int(e[j]), []).append(int(j))
        return out

    def times(self, item):
        t = float(self.master.t[item])
        return t, t


class VelocityMeasurement(_MasterTimed):
    """Driver plug-in: velocity matching against a master record (``matrices(ep)``)."""

    def __init__(self, master: MasterRecord, sigma, stream=0, dv_slice=slice(3, 6)):
        self.master, self.stream, self.dv_slice = master, stream, dv_slice
        self.R = np.broadcast_to(np.asarray(sigma, float) ** 2, (3,)).copy()

    def matrices(self, ep):
        C, v = self.master.at(ep.t)
        nav = ep.streams[self.stream]
        H = np.zeros((3, ep.n))
        H[np.arange(3), np.arange(self.dv_slice.start, self.dv_slice.stop)] = 1.0
        return np.asarray(nav.vel) - v, H, self.R


class AttitudeMeasurement(_MasterTimed):
    """Driver plug-in: attitude matching of one :class:`AttitudeMatch` kind.

    ``phi_slice``/``a_slice`` locate φ and the installation state in the layout. With
    ``relinearise`` the H is taken at :attr:`a_hat` (set by the caller after each update,
    EKF form) and z is shifted so that the innovation is ``z − h(x̂)``.
    """

    def __init__(self, match: AttitudeMatch, master: MasterRecord, sigma, stream=0,
                 phi_slice=slice(0, 3), a_slice=slice(6, 9), relinearise=False):
        self.match, self.master, self.stream = match, master, stream
        self.phi_slice, self.a_slice, self.relinearise = phi_slice, a_slice, relinearise
        self.R = np.broadcast_to(np.asarray(sigma, float) ** 2, (3,)).copy()
        self.a_hat = np.zeros(3)

    def matrices(self, ep):
        C, _ = self.master.at(ep.t)
        nav = ep.streams[self.stream]
        z, h6 = self.match.innovation_z(C, np.asarray(nav.C_bn), None, self.a_hat, self.relinearise)
        H = np.zeros((3, ep.n))
        H[:, self.phi_slice] = h6[:, :3]
        H[:, self.a_slice] = h6[:, 3:]
        return z, H, self.R


class TransferMeasurement(_MasterTimed):
    """Driver plug-in: velocity + attitude matching as one 6-row update at each master epoch."""

    def __init__(self, velocity: VelocityMeasurement, attitude: AttitudeMeasurement):
        self.velocity, self.attitude, self.master = velocity, attitude, velocity.master

    def matrices(self, ep):
        zv, Hv, Rv = self.velocity.matrices(ep)
        za, Ha, Ra = self.attitude.matrices(ep)
        return np.concatenate([zv, za]), np.vstack([Hv, Ha]), np.concatenate([Rv, Ra])


# ------------------------------------------- compiled epoch steps over the runs ---
#: Codes of the measured attitude quantity in the compiled steps: Euler-angle difference,
#: DCM-element difference, rotation vector of ``C_rᵀ Ĉ_s^n`` (Kain's and the optimal form).
_FORM = {"euler": 0, "dcm": 1, "kain": 2, "optimal": 2}


def _reference_rows(match, C_m_n):
    """What the compiled steps need of the reference attitudes ``C_r`` (..., 3, 3) of the
    form ``match.kind``: their Euler angles (euler), the elements C12, C31, C32 (dcm) or
    their quaternion (kain, optimal); (..., 4), unused entries zero."""
    Cr = np.asarray(C_m_n, dtype=float) @ match.compensation
    out = np.zeros(Cr.shape[:-2] + (4,))
    f = _FORM[match.kind]
    if f == 0:
        out[..., :3] = dcm_to_euler(Cr)
    elif f == 1:
        for c, (i, j) in enumerate(_DCM_ELEMENTS):
            out[..., c] = Cr[..., i, j]
    else:
        out[:] = dcm_to_quat(Cr)
    return out


@njit(cache=True)
def _rotvec_of_quat(q0, q1, q2, q3):
    """Rotation vector [rad] (norm <= π) of a unit quaternion, the formulas of
    ``scipy.spatial.transform.Rotation.as_rotvec`` (series below 1e-3 rad)."""
    if q0 < 0.0:
        q0, q1, q2, q3 = -q0, -q1, -q2, -q3
    angle = 2.0 * math.atan2(math.sqrt(q1 * q1 + q2 * q2 + q3 * q3), q0)
    if angle <= 1e-3:
        a2 = angle * angle
        scale = 2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0
    else:
        scale = angle / math.sin(0.5 * angle)
    return scale * q1, scale * q2, scale * q3


@njit(cache=True)
def _measured_attitude(form, q0, q1, q2, q3, ref, z):
    """The attitude rows ``z[3:6]`` of a slave whose computed attitude is the unit
    quaternion q, against the reference row ``ref`` of :func:`_reference_rows`."""
    if form == 0:
        p, r, y = q2euler_s(q0, q1, q2, q3)
        z[3] = wrap_pi_s(p - ref[0])
        z[4] = wrap_pi_s(r - ref[1])
        z[5] = wrap_pi_s(y - ref[2])
    elif form == 1:
        C = q2dcm_s(q0, q1, q2, q3)
        z[3] = C[1] - ref[0]
        z[4] = C[6] - ref[1]
        z[5] = C[7] - ref[2]
    else:
        # C_rᵀ Ĉ_s^n = C(q_r* ⊗ q)
        a0, a1, a2, a3 = qmul_s(ref[0], -ref[1], -ref[2], -ref[3], q0, q1, q2, q3)
        z[3], z[4], z[5] = _rotvec_of_quat(a0, a1, a2, a3)


@njit(cache=True)
def _stopped(l, k, x, fb, diverged_at):
    """A stopped lane l at epoch k: NaN state, no correction, the first such epoch kept."""
    if diverged_at[l] < 0:
        diverged_at[l] = k
    for i in range(x.shape[1]):
        x[l, i] = np.nan
    for c in range(fb.shape[1]):
        fb[l, c] = 0.0


@njit(cache=True)
def _lane_measurements(S, active, ref, vm, lane_master, noise, form, Z):
    """The velocity + attitude measurement ``Z`` (L, 6) of the active lanes: their INS
    states ``S`` (rows of :class:`~sinslab.nav.lanes.LaneBank`) against their master
    (``ref`` (nm, 4) of :func:`_reference_rows`, velocity ``vm`` (nm, 3)) plus the
    measurement noise ``noise`` (nm, 6) of that master; ``form`` a code of :data:`_FORM`."""
    for l in range(S.shape[0]):
        if not active[l]:
            continue
        m = lane_master[l]
        q0, q1, q2, q3 = S[l, 0], S[l, 1], S[l, 2], S[l, 3]
        nq = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0, q1, q2, q3 = q0 / nq, q1 / nq, q2 / nq, q3 / nq
        z = Z[l]
        for c in range(3):
            z[c] = S[l, 4 + c] - vm[m, c]
        _measured_attitude(form, q0, q1, q2, q3, ref[m], z)
        for c in range(6):
            z[c] += noise[m, c]


@njit(cache=True, inline="always")
def _matched_update(x, H, G, z, wrap, nu):
    """The paper-form update of one filter, ``x <- x + G (z − H x)`` with the common gain
    ``G`` (n, 6) (estimation's :func:`~sinslab.estimation.kernels.innovation` and
    :func:`~sinslab.estimation.kernels.gain_correct`); with ``wrap`` (Euler-angle form) the
    attitude innovation rows 3..5 wrapped to (−π, π]. ``nu`` (6,) a work array."""
    innovation(x, H, z, nu)
    if wrap:
        for i in range(3, 6):
            nu[i] = wrap_pi_s(nu[i])
    gain_correct(x, G, nu)


@njit(cache=True)
def _lane_filters(X, active, Phi, predict, H, G, Z, wrap, nu, tmp):
    """One epoch of the paper-form filters of the active lanes, in place on ``X`` (L, n):
    the prediction with ``Phi`` (when ``predict``), then :func:`_matched_update` with the
    common ``H`` (6, n), gain ``G`` (n, 6) and each lane's measurement ``Z[l]``."""
    for l in range(X.shape[0]):
        if not active[l]:
            continue
        x = X[l]
        if predict:
            state_predict_dense(x, Phi, tmp)
        _matched_update(x, H, G, Z[l], wrap, nu)


@njit(cache=True)
def _lane_feedback(X, active, comp, i_comp, fed, i_fb, phi_bound, diverged_at, k, fb):
    """The divergence guard and feedback of epoch k after the lanes' updates.

    A lane whose state is not finite or whose φ̂ (states ``i_fb[:3]``) exceeds
    ``phi_bound`` is stopped (``active``), its first stopped epoch written to
    ``diverged_at``; stopped lanes get NaN states and zero corrections. The active lanes'
    sensor estimates (states ``i_comp``, in the order of the bank's ``comp``) are added to
    ``comp``, their φ̂, δv̂ (states ``i_fb``) copied to ``fb`` (L, 6) for the INS
    correction and the fed-back states (``fed``) zeroed."""
    L, n = X.shape
    for l in range(L):
        if not active[l]:
            _stopped(l, k, X, fb, diverged_at)
            continue
        ok = True
        for i in range(n):
            if not math.isfinite(X[l, i]):
                ok = False
        p0, p1, p2 = X[l, i_fb[0]], X[l, i_fb[1]], X[l, i_fb[2]]
        if not math.sqrt(p0 * p0 + p1 * p1 + p2 * p2) <= phi_bound:
            ok = False
        if not ok:
            active[l] = False
            _stopped(l, k, X, fb, diverged_at)
            continue
        for c in range(12):
            comp[l, c] += X[l, i_comp[c]]
        for c in range(6):
            fb[l, c] = X[l, i_fb[c]]
        for i in range(n):
            if fed[i]:
                X[l, i] = 0.0


@njit(cache=True)
def _lane_attitudes(S, active, out):
    """``Ĉ_s^n`` (L, 3, 3) of the active lanes' INS states into ``out`` (others untouched)."""
    for l in range(S.shape[0]):
        if not active[l]:
            continue
        q0, q1, q2, q3 = S[l, 0], S[l, 1], S[l, 2], S[l, 3]
        nq = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        C = q2dcm_s(q0 / nq, q1 / nq, q2 / nq, q3 / nq)
        for i in range(3):
            for j in range(3):
                out[l, i, j] = C[3 * i + j]


@njit(cache=True)
def _feedforward(zz, H, Kg, Phi, x, wrap, record_every, xs):
    """The state recursion of the paper-form :func:`batch_filter`, run by run: at every
    epoch k :func:`_matched_update` with the common ``H[k]`` (6, n) and gain ``Kg[k]``
    (n, 6) from ``zz[:, k]`` (R, K+1, 6), the state recorded into ``xs`` (R, M, n) every
    ``record_every`` epochs, then the prediction with ``Phi[k]``. ``x`` (R, n) holds the
    initial states and is overwritten."""
    R, n = x.shape
    Kp1 = zz.shape[1]
    nu = np.empty(6)
    tmp = np.empty(n)
    for r in range(R):
        xr = x[r]
        for k in range(Kp1):
            _matched_update(xr, H[k], Kg[k], zz[r, k], wrap, nu)
            if k % record_every == 0:
                for i in range(n):
                    xs[r, k // record_every, i] = xr[i]
            if k < Kp1 - 1:
                state_predict_dense(xr, Phi[k], tmp)


def propagate_errors(Phi, x0):
    """Error states of many runs propagated open loop through the transitions ``Phi``
    (K, n, n) from ``x0`` (R, n): ``x_{k+1} = Φ_k x_k``, (R, K+1, n). Compiled run by run
    (estimation's state prediction), so a run's numbers do not depend on the runs stacked
    with it."""
    x0 = np.asarray(x0, dtype=float)
    Phi = np.ascontiguousarray(Phi, dtype=float)
    xs = np.empty((x0.shape[0], Phi.shape[0] + 1, x0.shape[1]))
    xs[:, 0] = x0
    _propagate(Phi, xs)
    return xs


@njit(cache=True)
def _propagate(Phi, xs):
    for r in range(xs.shape[0]):
        for k in range(Phi.shape[0]):
            predicted_dense(xs[r, k], Phi[k], xs[r, k + 1])


# ------------------------------------------------------- runs-vectorised Kalman filter --
def batch_filter(Phi, Cm, z_vel, C_slave, match: AttitudeMatch, x0, P0, R_vel, R_att,
                 Qk=None, relinearise=False, phi_slice=slice(0, 3), dv_slice=slice(3, 6),
                 a_slice=slice(6, 9), record_every=1, att_noise=None, gains=None):
    """Kalman filter over many runs at once (common trajectory, per-run data), feed-forward.

    Parameters
    ----------
    Phi : (K, n, n)
        Transition matrices from epoch k to k+1 (common to the runs: the dynamics depend on
        the trajectory only). Epoch 0 is updated first, then predicted.
    Cm : (K+1, 3, 3)
        Master attitude ``C_m^n`` at the update epochs.
    z_vel : (R, K+1, 3)
        Velocity measurements [m/s] of every run.
    C_slave : (R, K+1, 3, 3)
        Slave computed ``Ĉ_s^n`` of every run at the update epochs.
    match : AttitudeMatch
    x0 : (n,) ; P0 : (n, n)
    R_vel, R_att : (3,)
        Measurement variances.
    Qk : (n, n), optional
        Process noise per step.
    att_noise : (R, K+1, 3), optional
        Noise added to the attitude measurement z of each run [units of z], drawn by the
        caller with the variances ``R_att`` the filter assumes.
    relinearise : bool
        EKF form (per-run covariance); otherwise the covariance and gain are common to all
        runs and only the state recursion is per run.
    gains : CommonGains, optional
        :func:`batch_gains` of these arguments, made once for several calls (paper form).

    Returns
    -------
    xs : (R, M, n), sig : (M, n) or (R, M, n)
        Posterior estimates and σ at the recorded epochs (every ``record_every``-th).
    """
    Kp1 = Cm.shape[0]
    R_runs = z_vel.shape[0]
    n = P0.shape[0]
    Qk = np.zeros((n, n)) if Qk is None else Qk
    Hv = np.zeros((3, n))
    Hv[np.arange(3), np.arange(dv_slice.start, dv_slice.stop)] = 1.0
    idx_rec = list(range(0, Kp1, record_every))
    xs = np.empty((R_runs, len(idx_rec), n))
    x = np.broadcast_to(np.asarray(x0, float), (R_runs, n)).copy()
    cols = np.r_[np.arange(phi_slice.start, phi_slice.stop), np.arange(a_slice.start, a_slice.stop)]
    r = 0
    if not relinearise:
        G = batch_gains(Phi, Cm, match, P0, R_vel, R_att, Qk, phi_slice, dv_slice, a_slice,
                        record_every) if gains is None else gains
        # the gains are common to the runs: the loop over epochs carries only the states
        z_att = match.z_many(Cm, C_slave)
        if att_noise is not None:
            z_att = z_att + att_noise
        zz = np.ascontiguousarray(np.concatenate([z_vel, z_att], axis=2))
        _feedforward(zz, np.ascontiguousarray(G.H), np.ascontiguousarray(G.K), np.ascontiguousarray(Phi, dtype=float),
                     x, match.kind == "euler", int(record_every), xs)
        return xs, G.sigma
    P = np.broadcast_to(np.array(P0, float), (R_runs, n, n)).copy()
    sig = np.empty((R_runs, len(idx_rec), n))
    runs = _PerLane(Phi, Qk, R_vel, R_att, R_runs)
    for k in range(Kp1):
        H = np.zeros((R_runs, 6, n))
        H[:, :3] = Hv
        zz = np.empty((R_runs, 6))
        zz[:, :3] = z_vel[:, k]
        z6, H6 = match.innovation_many(Cm[k], C_slave[:, k], x[:, phi_slice], x[:, a_slice])
        H[:, 3:, cols] = H6
        zz[:, 3:] = z6 if att_noise is None else z6 + att_noise[:R_runs, k]
        runs.update(x, P, zz, H)
        if r < len(idx_rec) and idx_rec[r] == k:
            xs[:, r] = x
            sig[:, r] = np.sqrt(np.diagonal(P, axis1=1, axis2=2))
            r += 1
        if k < Kp1 - 1:
            runs.predict(k, x, P)
    return xs, sig


class _PerLane:
    """The filters of the EKF form, one covariance per lane (run), stepped with
    estimation's kernels: :meth:`predict` (``P <- Φ_k P Φ_kᵀ + Q_k``, ``x <- Φ_k x``) and
    :meth:`update` (sequential scalar Joseph updates of the six rows, R diagonal)."""

    def __init__(self, Phi, Qk, R_vel, R_att, lanes):
        self.Phi = np.ascontiguousarray(Phi, dtype=float)
        self.Q = np.ascontiguousarray(Qk, dtype=float)
        self.r = np.ascontiguousarray(np.concatenate([R_vel, R_att]), dtype=float)
        self.nzc, self.nnz = sparsity(self.Phi)
        n = self.Q.shape[0]
        # the sensor and installation states (random constants) are the diagonal rows of
        # every Φ_k: the dense part of Φ P Φᵀ is the first `tail` rows
        off = np.any((self.Phi != 0.0) & ~np.eye(n, dtype=bool), axis=(0, 2))
        self.tail = int(np.flatnonzero(off)[-1]) + 1 if off.any() else 0
        self.T1, self.W, self.tmp = np.empty((n, n)), np.empty((self.tail, self.tail)), np.empty(n)
        self.nis = np.empty(lanes)

    def predict(self, k, x, P):
        """Predict the lanes' ``x`` (L, n), ``P`` (L, n, n) in place with ``Φ_k``."""
        predict_lanes(x, P, self.Phi[k], self.Q, self.tail, self.nzc[k], self.nnz[k], self.T1, self.W, self.tmp)

    def update(self, x, P, z, H):
        """Update each lane in place with its ``z`` (L, 6) and ``H`` (L, 6, n). A lane with a
        non-finite z (a stopped lane, or an INS gone wrong) gets a NaN estimate and
        covariance, as the update of such a z would give, so the caller's guard stops it."""
        sequential_update_lanes(x, P, z, H, self.r, self.nis)
        bad = self.nis < 0.0
        x[bad] = np.nan
        P[bad] = np.nan


class CommonGains(NamedTuple):
    """The covariance recursion of a filter whose gains do not depend on the data (paper
    linearisation): measurement matrix ``H`` (K+1, 6, n), gain ``K`` (K+1, n, 6) at every
    filter epoch, σ ``sigma`` (M, n) after the updates of the recorded epochs."""

    H: np.ndarray
    K: np.ndarray
    sigma: np.ndarray


def _stacked_H(match, C_lin, n, dv_idx, cols):
    """[velocity rows; attitude rows at C_lin[k]] (K+1, 6, n) of the paper linearisation."""
    H = np.zeros((C_lin.shape[0], 6, n))
    H[:, np.arange(3), dv_idx] = 1.0
    H[:, 3:, cols] = match.H_many(C_lin)
    return H


def _common_gains(Phi, Hs, P0, R_vel, R_att, Qk, record_every):
    """:class:`CommonGains` of the paper form's covariance recursion: the update at epoch 0
    with ``Hs[0]``, then per step k the prediction with ``Phi[k]``, ``Qk`` and the update at
    epoch k+1 with ``Hs[k+1]``, all stepped by estimation's covariance loop
    (:func:`~sinslab.estimation.linear.propagate_covariance`: sequential scalar Joseph
    updates of the six rows, their gains composed into each epoch's gain). The loop
    predicts before it updates, so its first step is the identity without noise (no time
    passes before the first update; exact: ``I P Iᵀ`` is P)."""
    K, n = Phi.shape[0], P0.shape[0]
    Phi_t = np.concatenate([np.eye(n)[None], np.asarray(Phi, dtype=float)])
    Q_t = np.stack([np.zeros((n, n)), np.asarray(Qk, dtype=float)])
    run = propagate_covariance(P0, Phi_t, Q_t, Hs, np.diag(np.concatenate([R_vel, R_att])),
                               Q_index=np.minimum(np.arange(K + 1), 1), keep_gain=True)
    return CommonGains(Hs, run.gain, run.sigma[1::record_every])


def batch_gains(Phi, Cm, match: AttitudeMatch, P0, R_vel, R_att, Qk=None, phi_slice=slice(0, 3),
                dv_slice=slice(3, 6), a_slice=slice(6, 9), record_every=1):
    """:class:`CommonGains` of :func:`batch_filter` in the paper form (same arguments):
    made once, they serve every batch of runs on the same trajectory and variant."""
    n = P0.shape[0]
    Qk = np.zeros((n, n)) if Qk is None else Qk
    cols = np.r_[np.arange(phi_slice.start, phi_slice.stop), np.arange(a_slice.start, a_slice.stop)]
    Hs = _stacked_H(match, Cm, n, np.arange(dv_slice.start, dv_slice.stop), cols)
    return _common_gains(Phi, Hs, P0, R_vel, R_att, Qk, record_every)


def lane_gains(Phi, match: AttitudeMatch, P0, R_vel, R_att, C_lin, *, Qk=None, layout=None, record_every=1):
    """:class:`CommonGains` of :func:`align_lanes` in the paper form (``relinearise=False``,
    same arguments): made once, they serve every bank of lanes on the same trajectory and
    variant."""
    lay = transfer_model().layout if layout is None else layout
    sl, n = lay.slice, lay.n
    cols = np.r_[np.arange(n)[sl("phi")], np.arange(n)[sl("lam")]]
    Qk = np.zeros((n, n)) if Qk is None else np.asarray(Qk, float)
    Hs = _stacked_H(match, C_lin, n, np.arange(n)[sl("dv")], cols)
    return _common_gains(Phi, Hs, P0, R_vel, R_att, Qk, record_every)


# ---------------------------------------------------- closed loop over many slave INS ---
class LaneAlignment:
    """Output of :func:`align_lanes` (L lanes, M recorded epochs).

    Attributes
    ----------
    a : (L, M, 3) installation estimate after each recorded update [rad] (NaN once the
        lane has diverged)
    sigma : (M, n) or (L, M, n) filter σ (common to the lanes unless re-linearised)
    sensors : (L, 12) final sensor compensation fed back [ε rad/s, ∇ m/s², k_g, k_a]
    attitude : (L, M, 3, 3) slave computed ``Ĉ_s^n`` after each recorded update (after
        its feedback)
    diverged : (L,) bool ; diverged_at : (L,) first filter epoch found diverged (−1: never)
    epochs : (M,) filter epochs recorded
    """

    def __init__(self, a, sigma, sensors, attitude, diverged, diverged_at, epochs):
        self.a, self.sigma, self.sensors, self.attitude = a, sigma, sensors, attitude
        self.diverged, self.diverged_at, self.epochs = diverged, diverged_at, epochs


def align_lanes(bank, k_kf, Phi, match: AttitudeMatch, P0, R_vel, R_att, master_C, master_v, lane_master,
                *, C_lin=None, Qk=None, relinearise=False, meas_noise=None, layout=None, phi_bound=math.radians(30.0),
                record_every=1, gains=None):
    """Closed-loop transfer alignment of L slave INS at once (velocity + attitude matching).

    Every lane is a slave INS in ``bank`` (:class:`sinslab.nav.lanes.LaneBank`) with its
    own filter state. At each filter epoch k (every ``k_kf`` IMU samples; epoch 0 is the
    start) the lanes are compared with their master, updated, and the estimates of φ, δv
    and of the slave's gyro and accelerometer biases and scale factors are fed back (the
    INS corrected, the sensor compensation increased, those states zeroed), as the
    filter of paper 002 does; the installation state stays in the filter. Then the lanes
    navigate to the next epoch and the filter predicts.

    Covariance: with the paper's linearisation (``relinearise=False``) H depends only on
    the reference attitude, taken from ``C_lin`` — the attitude the filter linearises at,
    common to the lanes — so P and the gain are common (:func:`lane_gains`) and only the
    states are per lane, stepped by compiled calls over the lanes, lane by lane (a lane's
    numbers do not depend on the lanes beside it). With ``relinearise`` (EKF form, H at
    each lane's installation estimate and master attitude) every lane carries its own P.
    Either way the filters step with estimation's kernels, the one Kalman core.

    Parameters
    ----------
    bank : LaneBank
        L slave INS at the start epoch (their raw IMU records and compensation).
    k_kf : int
        IMU samples per filter step.
    Phi : (K, n, n)
        Transition from epoch k to k+1 (common); K filter steps follow epoch 0.
    match : AttitudeMatch
    P0 : (n, n) ; R_vel, R_att : (3,) measurement variances
    master_C : (nm, K+1, 3, 3) ; master_v : (nm, K+1, 3)
        Master solutions ``C_m^n`` and velocity [m/s] at the filter epochs.
    lane_master : (L,) int
        Master (and noise row) of each lane.
    C_lin : (K+1, 3, 3), optional
        Master attitude at which the common H is formed (default: master 0).
    Qk : (n, n), optional
        Process noise per step.
    meas_noise : (nm, K+1, 6), optional
        Noise added to ``[z_vel, z_att]`` (units of z; the caller draws it with the
        variances ``R_vel``, ``R_att``).
    layout : StateLayout, optional
        Default ``transfer_model().layout``.
    phi_bound : float
        A lane whose update asks for a correction ‖φ̂‖ above this [rad] (beyond which the
        small-angle error model does not hold), or whose state turns non-finite, or whose
        INS leaves the valid latitudes, is stopped and counted as diverged; the others go
        on.
    record_every : int
        Record the epochs 0, record_every, 2·record_every, ...
    gains : CommonGains, optional
        :func:`lane_gains` of these arguments, made once for several banks (paper form).

    Returns
    -------
    LaneAlignment
    """
    lay = transfer_model().layout if layout is None else layout
    n = lay.n
    K = Phi.shape[0]
    L = bank.lanes
    lane_master = np.asarray(lane_master, dtype=np.int64)
    Qk = np.zeros((n, n)) if Qk is None else np.asarray(Qk, float)
    rec = list(range(0, K + 1, record_every))
    a_out, att_out = np.full((L, len(rec), 3), np.nan), np.full((L, len(rec), 3, 3), np.nan)
    x, diverged_at = np.zeros((L, n)), np.full(L, -1, dtype=np.int64)
    if relinearise:
        sig = _per_lane_loop(bank, k_kf, Phi, match, P0, R_vel, R_att, Qk, master_C, master_v, lane_master,
                             meas_noise, lay, phi_bound, rec, x, diverged_at, a_out, att_out)
    else:
        # the covariance and gains are common to the lanes: made before the loop over epochs
        C_lin = master_C[0] if C_lin is None else C_lin
        G = lane_gains(Phi, match, P0, R_vel, R_att, C_lin, Qk=Qk, layout=lay,
                       record_every=record_every) if gains is None else gains
        sig = G.sigma
        _common_gain_loop(bank, k_kf, Phi, match, G, master_C, master_v, lane_master, meas_noise, lay, phi_bound,
                          rec, x, diverged_at, a_out, att_out)
    return LaneAlignment(a_out, sig, bank.comp.copy(), att_out, diverged_at >= 0, diverged_at, np.array(rec))


def _per_lane_loop(bank, k_kf, Phi, match, P0, R_vel, R_att, Qk, master_C, master_v, lane_master, meas_noise, lay,
                   phi_bound, rec, x, diverged_at, a_out, att_out):
    """The epochs of :func:`align_lanes` in the EKF form: every lane its own covariance
    (:class:`_PerLane`) and H at its own installation estimate and master attitude; ``x``,
    ``diverged_at``, ``a_out`` and ``att_out`` filled in place. Returns σ (L, M, n)."""
    sl = lay.slice
    n, L, M = lay.n, bank.lanes, len(rec)
    i_phi, i_dv, i_a = sl("phi"), sl("dv"), sl("lam")
    fed = np.r_[np.arange(n)[i_phi], np.arange(n)[i_dv], np.arange(n)[sl("eps")], np.arange(n)[sl("nabla")],
                np.arange(n)[sl("kg")], np.arange(n)[sl("ka")]]
    cols = np.r_[np.arange(n)[i_phi], np.arange(n)[i_a]]
    P = np.broadcast_to(np.array(P0, float), (L, n, n)).copy()
    sig = np.empty((L, M, n))
    lanes = _PerLane(Phi, Qk, R_vel, R_att, L)
    r = 0
    for k in range(Phi.shape[0] + 1):
        if k > 0:
            bank.advance(k_kf)
            lanes.predict(k - 1, x, P)
        # the measurement of the active lanes (a stopped lane's NaN state has no attitude:
        # its z stays NaN, and the update leaves it NaN)
        on = bank.active.copy()
        mk = lane_master[on]
        z = np.full((L, 6), np.nan)
        H = np.zeros((L, 6, n))
        H[:, np.arange(3), np.arange(n)[i_dv]] = 1.0
        z[on, :3] = bank.velocity()[on] - master_v[mk, k]
        z[on, 3:], H6 = match.innovation_many(master_C[mk, k], bank.attitude()[on], x[on][:, i_phi], x[on][:, i_a])
        H[np.ix_(on, np.arange(3, 6), cols)] = H6
        if meas_noise is not None:
            z[on] += meas_noise[mk, k]
        if match.kind == "euler":
            _wrap_attitude_innovation(z, H, x)
        lanes.update(x, P, z, H)
        # divergence guard before the correction reaches the INS
        bad = bank.active & ~(np.all(np.isfinite(x), axis=1)
                              & (np.linalg.norm(x[:, i_phi], axis=1) <= phi_bound))
        bank.stop(bad)
        on = bank.active
        diverged_at[~on & (diverged_at < 0)] = k
        x[~on] = np.nan
        bank.correct(np.where(on[:, None], x[:, i_phi], 0.0), np.where(on[:, None], x[:, i_dv], 0.0))
        bank.compensate(gyro_bias=x[:, sl("eps")], accel_bias=x[:, sl("nabla")], gyro_scale=x[:, sl("kg")],
                        accel_scale=x[:, sl("ka")])
        x[np.ix_(on, fed)] = 0.0
        if r < M and rec[r] == k:
            a_out[on, r] = x[on][:, i_a]
            att_out[on, r] = bank.attitude()[on]
            sig[:, r] = np.sqrt(np.diagonal(P, axis1=-2, axis2=-1))
            r += 1
    return sig


def _wrap_attitude_innovation(z, H, x):
    """Shift the attitude rows of ``z`` (L, 6) by the multiple of 2π that brings their
    innovation against ``x`` (L, n) (rows ``H`` (L, 6, n)) into (−π, π] (Euler-angle form;
    rows already inside are left as they are)."""
    nu = z[:, 3:] - np.einsum("lij,lj->li", H[:, 3:], x)
    out = ~((nu > -np.pi) & (nu <= np.pi))
    z[:, 3:] -= np.where(out, nu - wrap_pi(nu), 0.0)


def _common_gain_loop(bank, k_kf, Phi, match, G, master_C, master_v, lane_master, meas_noise, lay, phi_bound, rec,
                      x, diverged_at, a_out, att_out):
    """The epochs of :func:`align_lanes` in the paper form (gains ``G`` common to the lanes):
    per epoch the bank's compiled advance, the lanes' measurements, their filters' step
    (:func:`_lane_filters`: estimation's kernels) and the guard and feedback
    (:func:`_lane_feedback`), each one compiled call over the lanes, and the bank's compiled
    correction; ``x``, ``diverged_at``, ``a_out`` (L, M, 3) and ``att_out`` (L, M, 3, 3)
    filled in place."""
    sl = lay.slice
    n = lay.n
    L = bank.lanes
    M = len(rec)
    idx = np.arange(n)
    i_comp = np.r_[idx[sl("eps")], idx[sl("nabla")], idx[sl("kg")], idx[sl("ka")]]
    i_fb = np.r_[idx[sl("phi")], idx[sl("dv")]]
    fed = np.zeros(n, dtype=np.bool_)
    fed[np.r_[i_fb, i_comp]] = True
    i_a = sl("lam")
    # per epoch, contiguous rows of every master: its reference, velocity and noise
    ref = np.ascontiguousarray(np.swapaxes(_reference_rows(match, master_C), 0, 1))
    vm = np.ascontiguousarray(np.swapaxes(np.asarray(master_v, float), 0, 1))
    noise = (np.zeros((ref.shape[0], ref.shape[1], 6)) if meas_noise is None
             else np.ascontiguousarray(np.swapaxes(np.asarray(meas_noise, float), 0, 1)))
    Phi = np.ascontiguousarray(Phi, dtype=float)
    Hs, Ks = np.ascontiguousarray(G.H), np.ascontiguousarray(G.K)
    lane_master = np.ascontiguousarray(lane_master, dtype=np.int64)
    form, wrap = _FORM[match.kind], match.kind == "euler"
    Z, fb = np.zeros((L, 6)), np.zeros((L, 6))
    nu, tmp = np.empty(6), np.empty(n)
    att_rec = np.full((M, L, 3, 3), np.nan)
    r = 0
    for k in range(Phi.shape[0] + 1):
        if k > 0:
            bank.advance(k_kf)
        _lane_measurements(bank.state, bank.active, ref[k], vm[k], lane_master, noise[k], form, Z)
        _lane_filters(x, bank.active, Phi[k - 1], k > 0, Hs[k], Ks[k], Z, wrap, nu, tmp)
        _lane_feedback(x, bank.active, bank.comp, i_comp, fed, i_fb, float(phi_bound), diverged_at, k, fb)
        bank.correct(fb[:, :3], fb[:, 3:])
        if r < M and rec[r] == k:
            on = bank.active
            a_out[on, r] = x[on, i_a]
            _lane_attitudes(bank.state, on, att_rec[r])
            r += 1
    att_out[:] = np.swapaxes(att_rec, 0, 1)


def rate_norms(imu, master: MasterRecord, t_start=None, t_end=None, shift=0.0, _cum=None):
    """``(t, |ω_m|, |ω_s|)`` [s, rad/s, rad/s] over the master intervals in the window: the
    master's rotation rate from its attitude change, the slave's from its increments over
    the same interval with the slave's clock read ``shift`` [s] later (``shift`` > 0: the
    master's stamps are late by that much). None when fewer than 11 master epochs."""
    mt = master.t
    lo = max(mt[0], imu.t0) if t_start is None else max(float(t_start), mt[0], imu.t0)
    hi = min(mt[-1], imu.t[-1]) if t_end is None else min(float(t_end), mt[-1], imu.t[-1])
    sel = np.flatnonzero((mt >= lo - 1e-9) & (mt <= hi + 1e-9))
    if sel.size < 11:
        return None
    t = mt[sel]
    C = master.C[sel]
    w_m = np.linalg.norm(dcm_to_rotvec(np.swapaxes(C[:-1], 1, 2) @ C[1:]), axis=1) / np.diff(t)
    th, te = _cum if _cum is not None else _cumulative_angle(imu)
    i = np.clip(np.searchsorted(te, t - shift - 0.5 * imu.dt), 0, te.size - 1)
    w_s = np.linalg.norm(np.diff(th[i], axis=0), axis=1) / np.diff(t)
    return t, w_m, w_s


def _cumulative_angle(imu):
    """The slave's summed increments (N+1, 3) [rad] at the times (N+1,) [s] they end."""
    return (np.vstack([np.zeros(3), np.cumsum(imu.dtheta, axis=0)]),
            np.concatenate([[imu.t0], imu.t]))


def rate_correlation(imu, master: MasterRecord, t_start=None, t_end=None):
    """Whether a slave IMU and a master solution share their motion.

    The norm of the rotation rate does not depend on the mounting, so for a slave rigidly
    mounted on the master's vehicle (and on the same clock) ``|ω_s|`` from the slave's
    increments and ``|ω_m|`` from the master's attitude change follow each other.

    Parameters
    ----------
    imu : ImuRecord ; master : MasterRecord
    t_start, t_end : float, optional
        Window [s] (default: the overlap).

    Returns
    -------
    corr : float
        Correlation coefficient of ``|ω_s|`` and ``|ω_m|`` over the master intervals in the
        window (NaN when fewer than 10 intervals or when neither moves).
    motion : float
        Standard deviation of ``|ω_m|`` [rad/s] (how much the master's rate varies).
    """
    r = rate_norms(imu, master, t_start, t_end)
    if r is None:
        return float("nan"), 0.0
    _, w_m, w_s = r
    motion = float(np.std(w_m))
    if motion == 0.0 or np.std(w_s) == 0.0:
        return float("nan"), motion
    return float(np.corrcoef(w_m, w_s)[0, 1]), motion


def rate_lag(imu, master: MasterRecord, t_start=None, t_end=None, max_lag=2.0):
    """The clock offset that lines the slave's rotation rate up with the master's best.

    The correlation of ``|ω_m|`` and ``|ω_s|`` (:func:`rate_norms`) over slave-clock shifts
    in ``±max_lag`` [s] in steps of the slave interval, its peak refined by a parabola
    through the three best. Returns ``(lag [s], correlation there, correlation at 0,
    scale)``: ``lag`` > 0 means the master's stamps are late; ``scale`` is the least-squares
    ``k`` of ``|ω_m| ≈ k |ω_s|`` at the lag (1 when both are in the same unit). NaNs when the
    window has too few epochs or no motion.
    """
    step = float(imu.dt)
    lags = np.arange(-max_lag, max_lag + 0.5 * step, step)
    c = np.full(lags.size, np.nan)
    cum = _cumulative_angle(imu)
    for k, lag in enumerate(lags):
        r = rate_norms(imu, master, t_start, t_end, shift=lag, _cum=cum)
        if r is not None and np.std(r[1]) > 0 and np.std(r[2]) > 0:
            c[k] = np.corrcoef(r[1], r[2])[0, 1]
    if not np.isfinite(c).any():
        return float("nan"), float("nan"), float("nan"), float("nan")
    k = int(np.nanargmax(c))
    lag = float(lags[k])
    if 0 < k < lags.size - 1 and np.all(np.isfinite(c[k - 1:k + 2])):
        den = c[k - 1] - 2 * c[k] + c[k + 1]
        if den < 0:
            lag += 0.5 * step * float(c[k - 1] - c[k + 1]) / float(den)
    zero = int(np.argmin(np.abs(lags)))
    _, w_m, w_s = rate_norms(imu, master, t_start, t_end, shift=lag, _cum=cum)
    scale = float(np.dot(w_m, w_s) / np.dot(w_s, w_s)) if np.dot(w_s, w_s) > 0 else float("nan")
    return lag, float(c[k]), float(c[zero]), scale


# -------------------------------------------------- what each form's estimate means ---
#: The parameterisation in which each attitude form's installation estimate is scored.
#: The Kain forms measure ``log(C_rᵀ Ĉ_s^n)``, exactly the rotation vector of the
#: installation when φ = 0; the Euler-angle and DCM-element forms measure differences of
#: Euler angles / DCM elements whose second-order terms follow the Euler-angle triple of the
#: installation [pitch, roll, yaw] about slave x, y, z (the paper's λ, small angles).
PARAMETERISATION = {"euler": "euler", "dcm": "euler", "kain": "rotvec", "optimal": "rotvec"}


def parameterisation(kind, relinearise=False):
    """What the installation estimate of a filter is: :data:`PARAMETERISATION` of its form
    with the paper's linearisation at a = 0; a rotation vector for every form when H is
    re-linearised at the estimate (the EKF form models ``C_r exp(a×)`` exactly)."""
    if kind not in KINDS:
        raise ValueError(f"unknown attitude-matching kind {kind!r}; choose from {list(KINDS)}")
    return "rotvec" if relinearise else PARAMETERISATION[kind]


def installation_parameters(C, parameterisation):
    """The installation rotation ``C`` (..., 3, 3) (slave -> master body, or the residual
    ``Ĉ_s^mᵀ C_s^m``) as the three numbers a form estimates [rad]: ``"rotvec"``
    (rotation vector, slave x y z) or ``"euler"`` ([pitch, roll, yaw] with
    ``C = R_z(yaw) R_x(pitch) R_y(roll)``, about slave x, y, z)."""
    if parameterisation == "rotvec":
        return dcm_to_rotvec(C)
    if parameterisation == "euler":
        return dcm_to_euler(C)
    raise ValueError(f"unknown parameterisation {parameterisation!r}; use 'rotvec' or 'euler'")


# ------------------------------------------------------------ recorded-data alignment ---
class TransferResult:
    """Output of :func:`align_recorded`.

    Attributes
    ----------
    t : (M,) update epochs [s]
    x : (M, 21) state after each update (φ, δv reset by feedback; ε, ∇ the accumulated
        feedback compensation, i.e. the total estimate)
    sigma : (M, 21) filter σ
    layout : StateLayout
    mounting : (3,) final installation estimate [rad] (``a``: λ, or φ_α on top of the
        compensation), ``mounting_sigma`` its σ
    gyro_bias, accel_bias : (3,) final slave bias estimates [rad/s], [m/s²] with σ
    """

    def __init__(self, t, x, sigma, layout, applied=None):
        self.t, self.x, self.sigma, self.layout = t, x, sigma, layout
        #: the matching updates (:class:`sinslab.fusion.driver.Applied`: innovations, their
        #: σ and NIS), for the caller's consistency checks
        self.applied = applied
        sl = layout.slice
        self.mounting, self.mounting_sigma = x[-1, sl("lam")], sigma[-1, sl("lam")]
        self.gyro_bias, self.gyro_bias_sigma = x[-1, sl("eps")], sigma[-1, sl("eps")]
        self.accel_bias, self.accel_bias_sigma = x[-1, sl("nabla")], sigma[-1, sl("nabla")]


def align_recorded(imu, master: MasterRecord, master_pos, kind="optimal", *, compensation=None, t_start=None,
                   t_end=None, vel_sigma=0.1, att_sigma=3e-4, att_sigma0=1e-2, vel_sigma0=0.5, inst_sigma0=1e-2,
                   gyro_bias_sigma0=1e-3, accel_bias_sigma0=0.1, gyro_scale_sigma0=1e-3, accel_scale_sigma0=1e-3,
                   gyro_arw=0.0, accel_vrw=0.0, gyro_bias_rw=0.0, accel_bias_rw=0.0, nsub=2):
    """Transfer alignment of a recorded slave IMU against a recorded master solution.

    Runs through the fusion driver (:func:`sinslab.fusion.driver.run`): one live stream
    (the slave INS), the :class:`TransferMeasurement` plug-in (velocity + ``kind``
    attitude matching) at every master epoch, feedback of φ and δv into the slave INS and
    of the gyro and accelerometer biases into its sensor compensation; the installation
    and scale-factor states stay in the filter.

    The time window ``[t_start, t_end]`` selects the master epochs inside it; the slave
    IMU record is sliced to the increments after the first of them, and the slave INS
    starts there from the master's position, velocity and attitude times the
    compensation. The first master epoch is the initial condition; the updates start
    at the second.

    Position: the 21-state model takes no position error (``"attvel"`` core) and the slave
    position is *not* reset to the master's: it is navigated freely by the slave INS, kept
    close to the master's only through the velocity feedback (the horizontal position
    error grows as the integral of the residual velocity error, with the vertical channel
    free). It enters the filter only through the Earth-rate and transport-rate terms of
    the error model and the slave's gravity, where metres of error are negligible. No
    lever arm between master and slave is modelled.

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
        Slave increments [rad], [m/s] (RFU body axes), end times ``imu.t`` [s].
    master : MasterRecord
        Master attitude and velocity (ENU).
    master_pos : (M, 3)
        Master ``[lat, lon (rad), h (m)]`` at ``master.t``.
    kind : {"euler", "dcm", "kain", "optimal"}
        Attitude measurement form.
    compensation : (3, 3), optional
        Known installation ``Ĉ_s^m``; the installation state is then the residual φ_α.
    t_start, t_end : float, optional
        Window [s]; default the overlap of the two records.
    vel_sigma [m/s], att_sigma [rad] : measurement noise σ
    *_sigma0 : initial σ (SI); gyro_arw [rad/√s], accel_vrw [m/s/√s] : process noise
    gyro_bias_rw [rad/s/√s], accel_bias_rw [m/s²/√s] : random walk of the bias states
        (the bias instability as the filter models it; 0: random constants)
    nsub : int
        Mechanization subsamples; the master interval must be a multiple of ``nsub·imu.dt``.

    Returns
    -------
    TransferResult
        At the filter epochs (the master epochs of the window).
    """
    from sinslab.core.attitude import dcm_to_euler
    from sinslab.core.records import NavState
    from sinslab.fusion import driver as drv
    from sinslab.fusion.spec import FilterGrid
    from sinslab.fusion.feedback import FeedbackLayout

    mt = master.t
    lo = max(mt[0], imu.t0) if t_start is None else max(float(t_start), mt[0], imu.t0)
    hi = min(mt[-1], imu.t[-1]) if t_end is None else min(float(t_end), mt[-1], imu.t[-1])
    ep = np.flatnonzero((mt >= lo - 1e-9) & (mt <= hi + 1e-9))
    if ep.size < 3:
        raise ValueError(f"slave and master records overlap in fewer than 3 master epochs in [{lo:g}, {hi:g}] s")
    t0, t1 = float(mt[ep[0]]), float(mt[ep[-1]])
    # the window: master epochs t0..t1, slave increments ending in (t0, t1]
    win = master.take(ep)
    pos = np.asarray(master_pos, float)[ep]
    imu_w = imu.slice(t0 + 0.5 * imu.dt, t1 + 0.5 * imu.dt)
    if abs(imu_w.t0 - t0) > 1e-6 * imu.dt + 1e-9:
        raise ValueError(f"the slave IMU samples do not start at the master epoch {t0:g} s "
                         f"(first interval starts at {imu_w.t0:g} s)")
    model = errstate.ErrorModel("attvel", [errstate.installation("lam"), errstate.gyro_bias(rrw=gyro_bias_rw),
                                           errstate.gyro_scale(), errstate.accel_bias(arw=accel_bias_rw),
                                           errstate.accel_scale()],
                                gyro_arw=gyro_arw, accel_vrw=accel_vrw)
    lay = model.layout
    match = AttitudeMatch(kind, compensation)
    Cm0, vm0 = win.at(t0)
    init = NavState(pos[0, 0], pos[0, 1], pos[0, 2], vm0, dcm_to_euler(Cm0 @ match.compensation), imu_w.t0)
    stream = drv.LiveStream(imu_w, init, nsub=nsub)
    meas = TransferMeasurement(VelocityMeasurement(win, vel_sigma, dv_slice=lay.slice("dv")),
                               AttitudeMeasurement(match, win, att_sigma, phi_slice=lay.slice("phi"),
                                                   a_slice=lay.slice("lam")))
    sig0 = np.concatenate([np.full(3, att_sigma0), np.full(3, vel_sigma0), np.full(3, inst_sigma0),
                           np.full(3, gyro_bias_sigma0), np.full(3, gyro_scale_sigma0),
                           np.full(3, accel_bias_sigma0), np.full(3, accel_scale_sigma0)])
    fb = FeedbackLayout.from_model(lay, pos=None, gyro_scale=None, accel_scale=None)
    kf_dt = float(np.median(np.diff(win.t)))
    res = drv.run([stream], model, np.diag(sig0 ** 2), [meas], grid=FilterGrid(kf_dt), feedback=fb)
    x = np.array(res.x, float)
    x[:, lay.slice("eps")] = res.gyro_bias[0]
    x[:, lay.slice("nabla")] = res.accel_bias[0]
    return TransferResult(np.asarray(res.t), x, np.asarray(res.sigma), lay, res.applied)
