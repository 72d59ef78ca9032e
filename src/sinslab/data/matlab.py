"""MATLAB ``.mat`` files in the PSINS layouts: IMU matrices ``[Δθ (3), Δv (3), t]`` and
``avp`` navigation solutions ``[att (3), vel (3), lat, lon, h, t]``; a file that holds a
NaveGo struct instead is read by :mod:`sinslab.data.navego` (chosen by what the file holds)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sinslab.core.atomic import atomic_path
from sinslab.core.records import Fixes, ImuRecord, NavSeries
from sinslab.data.frames import sensor_to_body
from sinslab.data.increments import ImuData, check_stamps, uniform_increments
from sinslab.data.matfile import loadmat as _loadmat

__all__ = ["read_mat_imu", "read_mat_avp", "read_mat_fixes", "read_mat_fixes_any", "read_mat_truth",
           "write_mat_imu"]


def _mat_var(m, path, var, ncols, prefer):
    arrs = {k: v for k, v in m.items() if not k.startswith("__") and isinstance(v, np.ndarray)
            and v.ndim == 2 and v.dtype.kind in "fiu"}
    if var is not None:
        if var not in arrs:
            raise ValueError(f"{path}: no numeric matrix {var!r} (has {sorted(arrs)})")
        a = arrs[var]
    else:
        cand = [k for k in prefer if k in arrs] or [k for k, v in arrs.items() if v.shape[1] in ncols]
        if not cand:
            raise ValueError(f"{path}: no matrix with {' or '.join(map(str, ncols))} columns "
                             f"(variables {sorted(arrs)}); name it with var=")
        var, a = cand[0], arrs[cand[0]]
    if a.shape[1] not in ncols:
        raise ValueError(f"{path}: variable {var!r} has {a.shape[1]} columns; expected "
                         f"{' or '.join(map(str, ncols))}")
    a = np.asarray(a, dtype=float)
    if a.shape[0] == 0:
        raise ValueError(f"{path}: variable {var!r} is empty")
    bad = ~np.isfinite(a)
    if bad.any():
        raise ValueError(f"{path}: variable {var!r} row {int(np.argwhere(bad)[0, 0]) + 1}: NaN/inf value")
    return var, a


def read_mat_imu(path, var=None, *, dt=None, frame=None, mount=None, max_gap=1.0,
                 allow_gaps=False) -> ImuData:
    """Read a PSINS-layout IMU matrix from a ``.mat`` file: rows ``[Δθx Δθy Δθz (rad),
    Δvx Δvy Δvz (m/s), t (s)]`` (interval end times), or 6 columns without time (give
    ``dt``). ``var`` defaults to ``imu``/``mimu``/the first 6/7-column matrix. A file whose
    IMU is a NaveGo struct (fields ``t``, ``fb``, ``wb``) is read by
    :func:`sinslab.data.navego.read_navego_imu` (axes forward-right-down unless ``frame``
    is given)."""
    from sinslab.data import navego
    m = _loadmat(path)
    if navego.find_struct(m, path, navego.IMU_FIELDS, var) is not None:
        return navego.read_navego_imu(path, m, var, frame=frame or "frd", mount=mount, max_gap=max_gap,
                                      allow_gaps=allow_gaps)
    var, a = _mat_var(m, path, var, (6, 7), ("imu", "mimu", "simu"))
    if a.shape[1] == 6:
        if dt is None:
            raise ValueError(f"{path}: variable {var!r} has no time column; give dt")
        t = float(dt) * np.arange(1, a.shape[0] + 1)
    else:
        t = a[:, 6]
    R = sensor_to_body(mount, frame or "rfu")
    imu, gaps, jit = uniform_increments(t, a[:, 0:3] @ R.T, a[:, 3:6] @ R.T, path=path,
                                        lines=[f"row {i + 1}" for i in range(a.shape[0])],
                                        max_gap=max_gap, allow_gaps=allow_gaps)
    return ImuData(imu, gaps, str(path), "mat", a.shape[0], jit, {"variable": var})


def read_mat_avp(path, var=None):
    """Read a PSINS ``avp`` solution matrix: rows ``[pitch roll yaw (rad), vE vN vU (m/s),
    lat lon (rad), h (m), t (s)]`` (10 columns; yaw counter-clockwise from north, the
    sinslab convention). Returns :class:`sinslab.core.records.NavSeries`."""
    m = _loadmat(path)
    var, a = _mat_var(m, path, var, (10,), ("avp", "fogavp", "avpr"))
    t = a[:, 9]
    check_stamps(t, path, [f"row {i + 1}" for i in range(t.size)])
    if np.any(np.abs(a[:, 6]) > math.pi / 2):
        raise ValueError(f"{path}: variable {var!r}: latitude beyond ±90° — is it in radians?")
    return NavSeries(t, a[:, 6], a[:, 7], a[:, 8], a[:, 3:6], a[:, 0:3])


def read_mat_fixes(path, var=None, sigma=1.0, sigma_vel=0.1) -> Fixes:
    """Fixes from a PSINS ``avp`` matrix (:func:`read_mat_avp`): its positions and
    velocities, with constant σ ``sigma`` [m] (north, east, up) and ``sigma_vel`` [m/s]."""
    s = read_mat_avp(path, var)
    J = len(s)
    return Fixes(s.t, s.lat, s.lon, s.h, np.full((J, 3), float(sigma)),
                 s.vel, np.full((J, 3), float(sigma_vel)), np.zeros(J, int), str(path))


def read_mat_fixes_any(path, var=None, sigma=1.0, sigma_vel=0.1):
    """Fixes from a ``.mat`` file, chosen by what it holds: a NaveGo GNSS struct
    (:func:`sinslab.data.navego.read_navego_gnss`, its own σ and lever arm) or a PSINS
    ``avp`` matrix (:func:`read_mat_fixes`). Returns ``(Fixes, meta)``."""
    from sinslab.data import navego
    m = _loadmat(path)
    if navego.find_struct(m, path, navego.GNSS_FIELDS, var) is not None:
        fx, meta = navego.read_navego_gnss(path, m, var)
        meta["format"] = "navego"
        return fx, meta
    s = read_mat_avp(path, var)
    J = len(s)
    return (Fixes(s.t, s.lat, s.lon, s.h, np.full((J, 3), float(sigma)), s.vel,
                  np.full((J, 3), float(sigma_vel)), np.zeros(J, int), str(path)),
            {"format": "mat-avp", "sigma_source": f"constant {float(sigma):g} m, {float(sigma_vel):g} m/s"})


def read_mat_truth(path, var=None) -> NavSeries:
    """A reference trajectory from a ``.mat`` file: a NaveGo reference struct
    (:func:`sinslab.data.navego.read_navego_ref`) or a PSINS ``avp`` matrix."""
    from sinslab.data import navego
    m = _loadmat(path)
    if navego.find_struct(m, path, navego.REF_FIELDS, var) is not None:
        return navego.read_navego_ref(path, m, var)
    return read_mat_avp(path, var)


def write_mat_imu(path, imu: ImuRecord):
    """Write increments as a ``.mat`` file: variable ``imu`` (PSINS layout N×7,
    ``[Δθ (3), Δv (3), t]``) and ``dt``. Atomic. Returns the path."""
    import scipy.io
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            scipy.io.savemat(fh, {"imu": np.column_stack([imu.dtheta, imu.dv, imu.t]), "dt": imu.dt})
    return path
