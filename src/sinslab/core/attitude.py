"""Attitude: DCM, quaternion, rotation vector and Euler angles in sinslab's convention.

Convention (binding for the whole package)
------------------------------------------
- Navigation frame n = ENU; body frame b = RFU (x right, y forward, z up).
- Euler angles ``att = [pitch θ, roll γ, yaw ψ]`` [rad] with
  ``C_b^n = R_z(ψ) · R_x(θ) · R_y(γ)``, i.e. scipy's ``_rotation().from_euler('ZXY', [ψ, θ, γ])``.
  Yaw ψ is positive counter-clockwise about up; the heading (clockwise from north,
  0–360°) is ``-ψ``: use :func:`yaw_to_heading` / :func:`heading_to_yaw`.
- Quaternions are scalar-first ``[q0, q1, q2, q3]``, Hamilton product, and represent
  ``C_b^n`` (they rotate body vectors into n).
- Misalignment φ of a computed frame n': ``C_b^{n'} = (I − φ×) C_b^n`` (small angle);
  exactly, ``C_b^{n'} = exp(−φ×) C_b^n``.

NED/FRD users: :func:`dcm_from_ned`, :func:`euler_from_ned` and
:func:`vec_ned_to_enu` convert, the matrix :data:`M_ENU_NED` swaps the first two axes
and flips the third (it maps NED to ENU and FRD to RFU, and is its own inverse).

The ``*_s`` functions are numba-compiled scalar versions for hot loops.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from sinslab.core.jitnotice import install as _compile_notice

_compile_notice()   # a status line while the kernels below compile (first run)


def _rotation():
    """scipy's ``Rotation`` class, imported on first use: ``scipy.spatial`` takes about
    25 MB, which a process that only needs the closed forms below never pays."""
    from scipy.spatial.transform import Rotation

    return Rotation

__all__ = [
    "skew", "euler_to_dcm", "dcm_to_euler", "euler_to_quat", "quat_to_euler", "quat_to_dcm",
    "dcm_to_quat", "rotvec_to_dcm", "dcm_to_rotvec", "rotvec_to_quat", "quat_to_rotvec",
    "quat_mul", "quat_conj", "yaw_to_heading", "heading_to_yaw", "misalignment",
    "apply_misalignment", "M_ENU_NED", "dcm_from_ned", "dcm_to_ned", "euler_from_ned",
    "euler_to_ned", "vec_ned_to_enu", "vec_enu_to_ned", "wrap_pi", "wrap_pi_float", "wrap_pi_s",
]

#: Maps NED to ENU and FRD to RFU (and back: it is symmetric and its own inverse).
M_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def skew(v: ArrayLike) -> np.ndarray:
    """Cross-product matrix ``(v×)`` with ``skew(a) @ b == cross(a, b)``; shape ``(..., 3, 3)``."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))      # filled in place: called per epoch in loops
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


# The three conversions the filters call on every run (Euler angles -> quaternion / DCM and
# quaternion -> DCM) are closed forms here rather than scipy's ``Rotation``, so that a
# navigation never imports ``scipy.spatial``. Their products and sums are taken in the order
# scipy takes them, so both give the same bits (the attitude tests compare the two on random
# inputs); the rarer conversions still go through ``Rotation``.
def _compose(p, q):
    """Hamilton product ``p ⊗ q`` of scalar-first quaternion rows ``(n, 4)``, summed as
    ``p0·q_v + q0·p_v + p_v × q_v`` and ``p0·q0 − p_v·q_v`` (scipy's order)."""
    p0, p1, p2, p3 = p.T
    q0, q1, q2, q3 = q.T
    return np.stack([p0 * q0 - (p1 * q1 + p2 * q2 + p3 * q3),
                     p0 * q1 + q0 * p1 + (p2 * q3 - p3 * q2),
                     p0 * q2 + q0 * p2 + (p3 * q1 - p1 * q3),
                     p0 * q3 + q0 * p3 + (p1 * q2 - p2 * q1)], -1)


def _axis_quat(axis, angle):
    """Quaternion rows of rotations by ``angle`` [rad] ``(n,)`` about body axis 0, 1 or 2."""
    q = np.zeros(angle.shape + (4,))
    q[:, 0] = np.cos(angle / 2)
    q[:, 1 + axis] = np.sin(angle / 2)
    return q


def _quat_of_euler(att):
    """Scalar-first quaternion rows (not canonicalised) of ``att`` ``(n, 3)``:
    ``q(R_z(ψ)) ⊗ q(R_x(θ)) ⊗ q(R_y(γ))``."""
    q = _compose(_axis_quat(2, att[:, 2]), _axis_quat(0, att[:, 0]))
    return _compose(q, _axis_quat(1, att[:, 1]))


def _dcm_of_unit_quat(q):
    """``C_b^n`` ``(n, 3, 3)`` of scalar-first quaternions ``(n, 4)`` taken as unit."""
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    C = np.empty(q.shape[:1] + (3, 3))
    C[:, 0, 0] = x2 - y2 - z2 + w2
    C[:, 1, 0] = 2 * (xy + zw)
    C[:, 2, 0] = 2 * (xz - yw)
    C[:, 0, 1] = 2 * (xy - zw)
    C[:, 1, 1] = -x2 + y2 - z2 + w2
    C[:, 2, 1] = 2 * (yz + xw)
    C[:, 0, 2] = 2 * (xz + yw)
    C[:, 1, 2] = 2 * (yz - xw)
    C[:, 2, 2] = -x2 - y2 + z2 + w2
    return C


def euler_to_dcm(att: ArrayLike) -> np.ndarray:
    """``C_b^n`` from ``att = [pitch, roll, yaw]`` [rad]; shape ``(..., 3) -> (..., 3, 3)``."""
    att = np.asarray(att, dtype=float)
    return _dcm_of_unit_quat(_quat_of_euler(att.reshape(-1, 3))).reshape(att.shape[:-1] + (3, 3))


def dcm_to_euler(C: ArrayLike) -> np.ndarray:
    """``att = [pitch, roll, yaw]`` [rad] from ``C_b^n``; pitch in [−90°, 90°], others in (−180°, 180°].

    Closed form: θ = asin(C32), γ = atan2(−C31, C33), ψ = atan2(−C12, C22)
    (1-based element indices).
    """
    C = np.asarray(C, dtype=float)
    pitch = np.arcsin(np.clip(C[..., 2, 1], -1.0, 1.0))
    roll = np.arctan2(-C[..., 2, 0], C[..., 2, 2])
    yaw = np.arctan2(-C[..., 0, 1], C[..., 1, 1])
    return np.stack([pitch, roll, yaw], -1)


def _q_scipy_to_ours(q):
    return np.concatenate([q[..., 3:4], q[..., :3]], -1)


def _q_ours_to_scipy(q):
    q = np.asarray(q, dtype=float)
    return np.concatenate([q[..., 1:4], q[..., 0:1]], -1)


def euler_to_quat(att: ArrayLike) -> np.ndarray:
    """Scalar-first quaternion of ``C_b^n`` from ``[pitch, roll, yaw]`` [rad]."""
    att = np.asarray(att, dtype=float)
    q = _quat_of_euler(att.reshape(-1, 3))
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)       # canonical: q0 >= 0
    return q.reshape(att.shape[:-1] + (4,))


def quat_to_dcm(q: ArrayLike) -> np.ndarray:
    """``C_b^n`` from a scalar-first quaternion (normalised first)."""
    q = np.asarray(q, dtype=float)
    r = q.reshape(-1, 4)
    n = np.sqrt(r[:, 1] * r[:, 1] + r[:, 2] * r[:, 2] + r[:, 3] * r[:, 3] + r[:, 0] * r[:, 0])
    if np.any(n == 0):
        raise ValueError("a quaternion of zero norm has no attitude")
    return _dcm_of_unit_quat(r / n[:, None]).reshape(q.shape[:-1] + (3, 3))


def dcm_to_quat(C: ArrayLike) -> np.ndarray:
    """Scalar-first quaternion (q0 >= 0) of a DCM."""
    C = np.asarray(C, dtype=float)
    q = _q_scipy_to_ours(_rotation().from_matrix(C.reshape(-1, 3, 3)).as_quat())
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q.reshape(C.shape[:-2] + (4,))


def quat_to_euler(q: ArrayLike) -> np.ndarray:
    """``[pitch, roll, yaw]`` [rad] from a scalar-first quaternion of ``C_b^n``."""
    return dcm_to_euler(quat_to_dcm(q))


def rotvec_to_dcm(r: ArrayLike) -> np.ndarray:
    """DCM ``exp(r×)`` of a rotation vector [rad]."""
    r = np.asarray(r, dtype=float)
    return _rotation().from_rotvec(r.reshape(-1, 3)).as_matrix().reshape(r.shape[:-1] + (3, 3))


def dcm_to_rotvec(C: ArrayLike) -> np.ndarray:
    """Rotation vector [rad] (norm <= π) of a DCM."""
    C = np.asarray(C, dtype=float)
    return _rotation().from_matrix(C.reshape(-1, 3, 3)).as_rotvec().reshape(C.shape[:-2] + (3,))


def rotvec_to_quat(r: ArrayLike) -> np.ndarray:
    """Scalar-first quaternion of a rotation vector [rad]."""
    r = np.asarray(r, dtype=float)
    return _q_scipy_to_ours(_rotation().from_rotvec(r.reshape(-1, 3)).as_quat()).reshape(
        r.shape[:-1] + (4,))


def quat_to_rotvec(q: ArrayLike) -> np.ndarray:
    """Rotation vector [rad] of a scalar-first quaternion."""
    q = np.asarray(q, dtype=float)
    return _rotation().from_quat(_q_ours_to_scipy(q.reshape(-1, 4))).as_rotvec().reshape(
        q.shape[:-1] + (3,))


def quat_mul(p: ArrayLike, q: ArrayLike) -> np.ndarray:
    """Hamilton product ``p ⊗ q`` of scalar-first quaternions (broadcasts)."""
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    p0, p1, p2, p3 = np.moveaxis(p, -1, 0)
    q0, q1, q2, q3 = np.moveaxis(q, -1, 0)
    return np.stack([p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
                     p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
                     p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
                     p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0], -1)


def quat_conj(q: ArrayLike) -> np.ndarray:
    """Conjugate (inverse for unit quaternions) of a scalar-first quaternion."""
    q = np.array(q, dtype=float)
    q[..., 1:] *= -1.0
    return q


def wrap_pi(a: ArrayLike) -> np.ndarray:
    """Wrap angles [rad] to (−π, π]. :func:`wrap_pi_s` is the compiled scalar form."""
    a = np.asarray(a, dtype=float)
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


def wrap_pi_float(a: float) -> float:
    """:func:`wrap_pi` of one angle [rad] as a Python float, the same bits: Python's float
    ``%`` and numpy's ``mod`` are one algorithm (``fmod``, then the divisor added when
    the signs differ; a zero takes the divisor's sign), without numpy's per-call cost."""
    return math.pi - (math.pi - float(a)) % (2 * math.pi)


def yaw_to_heading(yaw: ArrayLike) -> np.ndarray:
    """Heading clockwise from north in [0, 2π) [rad] from sinslab yaw ψ (CCW about up)."""
    return np.mod(-np.asarray(yaw, dtype=float), 2 * np.pi)


def heading_to_yaw(heading: ArrayLike) -> np.ndarray:
    """sinslab yaw ψ in (−π, π] [rad] from a heading clockwise from north [rad]."""
    return wrap_pi(-np.asarray(heading, dtype=float))


def misalignment(C_true: ArrayLike, C_computed: ArrayLike) -> np.ndarray:
    """Misalignment φ [rad] of a computed attitude: ``C_computed = exp(−φ×) C_true``.

    Both arguments are ``C_b^n`` (``(..., 3, 3)``). For small angles this is the
    φ-angle of the error models: ``C_b^{n'} = (I − φ×) C_b^n``.
    """
    C_true = np.asarray(C_true, dtype=float)
    C_computed = np.asarray(C_computed, dtype=float)
    return -dcm_to_rotvec(C_computed @ np.swapaxes(C_true, -1, -2))


def apply_misalignment(C_true: ArrayLike, phi: ArrayLike) -> np.ndarray:
    """``C_b^{n'} = exp(−φ×) C_b^n``: the computed attitude for a misalignment φ [rad]."""
    return rotvec_to_dcm(-np.asarray(phi, dtype=float)) @ np.asarray(C_true, dtype=float)


# --- NED/FRD conversions --------------------------------------------------------------------
def dcm_from_ned(C_frd_ned: ArrayLike) -> np.ndarray:
    """``C_rfu^enu`` from a NED-tool attitude matrix ``C_frd^ned``."""
    return M_ENU_NED @ np.asarray(C_frd_ned, dtype=float) @ M_ENU_NED


def dcm_to_ned(C_rfu_enu: ArrayLike) -> np.ndarray:
    """``C_frd^ned`` from sinslab's ``C_rfu^enu``."""
    return M_ENU_NED @ np.asarray(C_rfu_enu, dtype=float) @ M_ENU_NED


def euler_from_ned(rpy_ned: ArrayLike) -> np.ndarray:
    """sinslab ``[pitch, roll, yaw]`` from NED-convention ``[roll φ, pitch θ, yaw ψ]`` [rad].

    The NED convention is aerospace 3-2-1 (``C_frd^ned = R_z(ψ) R_y(θ) R_x(φ)``, yaw
    clockwise from north). Pitch and roll carry over unchanged; the yaw changes sign.
    """
    r = np.asarray(rpy_ned, dtype=float)
    e = r.reshape(-1, 3)
    # q(R_z(ψ)) ⊗ q(R_y(θ)) ⊗ q(R_x(φ)): scipy's ``from_euler("ZYX")`` in its order, so
    # the same bits without importing scipy.spatial
    q = _compose(_compose(_axis_quat(2, e[:, 2]), _axis_quat(1, e[:, 1])), _axis_quat(0, e[:, 0]))
    return dcm_to_euler(dcm_from_ned(_dcm_of_unit_quat(q))).reshape(r.shape)


def euler_to_ned(att: ArrayLike) -> np.ndarray:
    """NED-convention ``[roll, pitch, yaw]`` [rad] (yaw in (−π, π]) from sinslab ``att``."""
    att = np.asarray(att, dtype=float)
    C = dcm_to_ned(euler_to_dcm(att.reshape(-1, 3)))
    zyx = _rotation().from_matrix(C).as_euler("ZYX")
    return np.stack([zyx[:, 2], zyx[:, 1], zyx[:, 0]], -1).reshape(att.shape)


def vec_ned_to_enu(v: ArrayLike) -> np.ndarray:
    """Vector(s) from NED to ENU (also FRD -> RFU): ``[y, x, -z]``."""
    v = np.asarray(v, dtype=float)
    return np.stack([v[..., 1], v[..., 0], -v[..., 2]], -1)


vec_enu_to_ned = vec_ned_to_enu  # the permutation is its own inverse


# --- numba scalar kernels for hot loops -----------------------------------------------------
@njit(cache=True, inline="always")
def qmul_s(a0: float, a1: float, a2: float, a3: float,
           b0: float, b1: float, b2: float, b3: float) -> tuple[float, float, float, float]:
    """Hamilton product of scalar-first quaternions, scalar form."""
    return (a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3, a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1, a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0)


@njit(cache=True, inline="always")
def rv2q_s(x: float, y: float, z: float) -> tuple[float, float, float, float]:
    """Quaternion of rotation vector (x, y, z) [rad], scalar form.

    Below 1e-3 rad the closed form's Taylor series to fourth order, which is exact in
    double precision there (the dropped n⁶ terms are < 1e-22) and needs no square root,
    sine, cosine or division: the rotation of the navigation frame in one strapdown
    update (~1e-6 rad) and the body's at low rates, on the longest chain of dependent
    operations of an update."""
    n2 = x * x + y * y + z * z
    if n2 < 1e-6:
        s = 0.5 - n2 * (1.0 / 48.0 - n2 * (1.0 / 3840.0))
        c = 1.0 - n2 * (0.125 - n2 * (1.0 / 384.0))
    else:
        n = math.sqrt(n2)
        s = math.sin(0.5 * n) / n
        c = math.cos(0.5 * n)
    return c, x * s, y * s, z * s


_INV2PI = 1.0 / (2.0 * math.pi)


@njit(cache=True)
def wrap_pi_s(a: float) -> float:
    """Wrap an angle [rad] to (−π, π], scalar form: unchanged inside the interval (where
    :func:`wrap_pi` may round it by an ulp of π). (Multiplying by 1/2π instead of
    dividing: the same result except where the quotient is within an ulp of an integer,
    fixed by the last test.)"""
    if -math.pi < a <= math.pi:
        return a
    b = a + 2.0 * math.pi * math.floor((math.pi - a) * _INV2PI)
    if b <= -math.pi:
        b += 2.0 * math.pi
    return b


@njit(cache=True, inline="always")
def q2dcm_s(q0: float, q1: float, q2: float, q3: float) -> tuple[float, ...]:
    """DCM elements (row-major, 9 scalars) of a unit scalar-first quaternion."""
    return (1 - 2 * (q2 * q2 + q3 * q3), 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2),
            2 * (q1 * q2 + q0 * q3), 1 - 2 * (q1 * q1 + q3 * q3), 2 * (q2 * q3 - q0 * q1),
            2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), 1 - 2 * (q1 * q1 + q2 * q2))


@njit(cache=True, inline="always")
def euler2q_s(pitch: float, roll: float, yaw: float) -> tuple[float, float, float, float]:
    """Scalar-first quaternion of ``R_z(yaw) R_x(pitch) R_y(roll)``, scalar form."""
    cz, sz = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    cx, sx = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * roll), math.sin(0.5 * roll)
    # qz ⊗ qx ⊗ qy
    a0, a1, a2, a3 = qmul_s(cz, 0.0, 0.0, sz, cx, sx, 0.0, 0.0)
    return qmul_s(a0, a1, a2, a3, cy, 0.0, sy, 0.0)


@njit(cache=True, inline="always")
def q2euler_s(q0: float, q1: float, q2: float, q3: float) -> tuple[float, float, float]:
    """``(pitch, roll, yaw)`` [rad] of a unit scalar-first quaternion, scalar form."""
    c12 = 2 * (q1 * q2 - q0 * q3)
    c22 = 1 - 2 * (q1 * q1 + q3 * q3)
    c31 = 2 * (q1 * q3 - q0 * q2)
    c32 = 2 * (q2 * q3 + q0 * q1)
    c33 = 1 - 2 * (q1 * q1 + q2 * q2)
    if c32 > 1.0:
        c32 = 1.0
    elif c32 < -1.0:
        c32 = -1.0
    return math.asin(c32), math.atan2(-c31, c33), math.atan2(-c12, c22)


@njit(cache=True, inline="always")
def euler_dcm_sc(sp: float, cp: float, sr: float, cr: float, sy: float, cy: float) -> tuple[float, ...]:
    """``C_b^n = R_z(yaw) R_x(pitch) R_y(roll)`` (9 scalars, row-major) from the sines and
    cosines of pitch, roll and yaw: scalar form for hot loops that cache the trigonometry."""
    return (cy * cr - sy * sp * sr, -sy * cp, cy * sr + sy * sp * cr,
            sy * cr + cy * sp * sr, cy * cp, sy * sr - cy * sp * cr,
            -cp * sr, sp, cp * cr)


@njit(cache=True, inline="always")
def euler_rates_to_body_sc(sp: float, cp: float, sr: float, cr: float, pitchd: float, rolld: float,
                           yawd: float) -> tuple[float, float, float]:
    """Body angular rate ω_nb^b [rad/s] from Euler-angle rates (same convention as
    :func:`euler_dcm_sc`; sines/cosines of pitch and roll given):
    ``ω = R_y(−γ)[θ̇, 0, 0] + [0, γ̇, 0] + R_y(−γ) R_x(−θ)[0, 0, ψ̇]``."""
    return (cr * pitchd - sr * cp * yawd, rolld + sp * yawd, sr * pitchd + cr * cp * yawd)
