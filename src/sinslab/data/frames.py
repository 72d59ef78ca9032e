"""Body-axis conventions and sensor mounts: matrices that take sensor-axis vectors to
sinslab's RFU body frame (x right, y forward, z up), with rotation checks."""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import attitude as _att

__all__ = ["frame_matrix", "check_rotation", "rpy_frd_matrix", "sensor_to_body", "quat_mount"]

_FRAMES = {
    # rows: RFU components from the source components
    "rfu": np.eye(3),
    "frd": np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]),   # [y, x, -z]
    "flu": np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),   # [-y, x, z]
    "rbd": np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]),
}


def frame_matrix(frame: str) -> np.ndarray:
    """Matrix taking vectors from a source body-axis convention to sinslab's RFU.

    ``"rfu"`` (x right, y forward, z up), ``"frd"`` (x forward, y right, z down: NED-style
    tools), ``"flu"`` (x forward, y left, z up: ROS), ``"rbd"``.
    """
    try:
        return _FRAMES[str(frame).lower()].copy()
    except KeyError:
        raise ValueError(f"unknown body frame {frame!r}; use one of {sorted(_FRAMES)}") from None


def check_rotation(M, what="mount rotation", tol=1e-6) -> np.ndarray:
    """Return ``M`` as a (3, 3) array if it is a proper rotation (orthonormal, det +1)."""
    M = np.asarray(M, dtype=float)
    if M.shape != (3, 3):
        raise ValueError(f"{what} must be a 3x3 matrix, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        i, j = (int(x) for x in np.argwhere(~np.isfinite(M))[0])
        raise ValueError(f"{what}: element ({i + 1}, {j + 1}) is {M[i, j]}; a rotation matrix "
                         f"needs finite numbers")
    err = float(np.max(np.abs(M @ M.T - np.eye(3))))
    if err > tol:
        raise ValueError(f"{what} is not a rotation: |M Mᵀ − I| = {err:.3g} (> {tol:g})")
    if np.linalg.det(M) < 0:
        raise ValueError(f"{what} is not a rotation: determinant {np.linalg.det(M):.6g} "
                         "(a reflection; check the axis signs)")
    return M


def rpy_frd_matrix(rpy) -> np.ndarray:
    """``C_sensor→body`` from roll, pitch, yaw [rad] in the forward-right-down convention
    of Groves' ``Euler_to_CTM`` (``C = R1(φ) R2(θ) R3(ψ)``, passive rotations): the
    matrix the source of ``rtklib-drive`` multiplies the sensor vectors by."""
    r, p, y = (float(v) for v in np.asarray(rpy, dtype=float).reshape(3))
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array([[cp * cy, cp * sy, -sp],
                     [-cr * sy + sr * sp * cy, cr * cy + sr * sp * sy, sr * cp],
                     [sr * sy + cr * sp * cy, -sr * cy + cr * sp * sy, cr * cp]])


def sensor_to_body(mount=None, frame="rfu") -> np.ndarray:
    """The sensor-to-body mount ``C_sensor→body``: the rotation taking sensor-axis vectors
    to sinslab's RFU body axes (the other mount, IMU body to the vehicle axes of wheel
    constraints, is :func:`sinslab.fusion.measurements.vehicle_from_body`).

    Parameters
    ----------
    mount : None, (3, 3) array, (4,) quaternion, or str
        ``None``: the sensor axes are the vehicle axes of ``frame``. A matrix:
        ``C_sensor→body`` in the ``frame`` convention (checked to be a rotation); a
        scalar-first unit quaternion of it (:func:`quat_mount`). A string
        ``"rpy:R,P,Y"`` (degrees; Groves/NED convention, :func:`rpy_frd_matrix`),
        ``"euler:PITCH,ROLL,YAW"`` (degrees; sinslab convention, ``C_sensor→body =
        euler_to_dcm``), ``"quat:W,X,Y,Z"`` or ``"matrix:M11,M12,...,M33"`` (row by row,
        brackets and semicolons allowed: ``"matrix:[[0,1,0],[-1,0,0],[0,0,1]]"``).
    frame : str
        Axis convention of the vehicle body frame the mount refers to (see
        :func:`frame_matrix`); the result is converted to RFU.
    """
    P = frame_matrix(frame)
    if mount is None:
        return P
    if isinstance(mount, str):
        M = _mount_from_text(mount)
    else:
        M = np.asarray(mount, dtype=float)
        if M.shape == (4,):
            M = quat_mount(M, str(mount))
    return P @ check_rotation(M)


_MOUNT_HELP = ("use 'rpy:R,P,Y' or 'euler:PITCH,ROLL,YAW' (degrees), 'quat:W,X,Y,Z' or "
               "'matrix:M11,M12,...,M33' (row by row; brackets allowed)")


def quat_mount(q, text="", tol=1e-3) -> np.ndarray:
    """``C_sensor→body`` from a scalar-first unit quaternion ``[w, x, y, z]`` (sinslab's
    convention, :func:`sinslab.core.attitude.quat_to_dcm`: the quaternion rotates sensor
    vectors into body axes). A norm off 1 by more than ``tol`` is refused (a quaternion
    given in another order or as a vector part only)."""
    q = np.asarray(q, dtype=float).reshape(-1)
    if q.size != 4 or not np.all(np.isfinite(q)):
        raise ValueError(f"mount {text!r}: a quaternion needs 4 finite numbers W,X,Y,Z")
    nq = float(np.linalg.norm(q))
    if abs(nq - 1.0) > tol:
        raise ValueError(f"mount {text!r}: quaternion norm {nq:.6g} is not 1 (scalar first: W,X,Y,Z)")
    return _att.quat_to_dcm(q / nq)


def _mount_from_text(mount: str) -> np.ndarray:
    kind, sep, vals = mount.partition(":")
    kind = kind.strip().lower()
    if not sep:
        raise ValueError(f"cannot read the mount {mount!r}; {_MOUNT_HELP}")
    try:
        v = np.array([float(x) for x in vals.replace("[", " ").replace("]", " ").replace(";", ",")
                      .replace(",", " ").split()])
    except ValueError:
        raise ValueError(f"cannot read the mount {mount!r}; {_MOUNT_HELP}") from None
    if kind in ("rpy", "euler"):
        if v.size != 3:
            raise ValueError(f"mount {mount!r} needs three angles")
        if not np.all(np.isfinite(v) & (np.abs(v) <= 360.0)):
            bad = v[~(np.isfinite(v) & (np.abs(v) <= 360.0))][0]
            raise ValueError(f"mount {mount!r}: angle {bad:g} deg out of range; each angle must be "
                             f"a finite number of degrees within ±360")
        v = np.radians(v)
        return rpy_frd_matrix(v) if kind == "rpy" else _att.euler_to_dcm(v)
    if kind in ("quat", "q"):
        return quat_mount(v, mount)
    if kind in ("matrix", "dcm"):
        if v.size != 9:
            raise ValueError(f"mount {mount!r}: a matrix needs 9 numbers (row by row), got {v.size}")
        return check_rotation(v.reshape(3, 3), f"mount {mount!r}")
    raise ValueError(f"unknown mount kind {kind!r}; {_MOUNT_HELP}")
