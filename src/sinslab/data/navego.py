"""NaveGo's MATLAB structs as NaveGo ships and reads them (``ins_gnss.m``'s input
documentation): an IMU struct, a GNSS struct and a reference (truth) struct in a ``.mat``
file, field names as NaveGo spells them.

==========  ==========================================================================
struct      fields read (NaveGo units)
==========  ==========================================================================
IMU         ``t`` (s), ``fb`` (m/s², body x-forward y-right z-down), ``wb`` (rad/s);
            optional error terms ``arw`` (rad/s/√Hz), ``vrw`` (m/s²/√Hz), ``gb_sta`` /
            ``ab_sta`` (static biases NaveGo subtracts from every sample), ``gb_dyn`` /
            ``ab_dyn`` (σ of the Gauss–Markov biases), ``gb_corr`` / ``ab_corr`` (their
            correlation times, s), ``ini_align`` (roll, pitch, yaw rad, yaw clockwise
            from north) and ``ini_align_err`` (their σ)
GNSS        ``t`` (s), ``lat`` / ``lon`` (rad), ``h`` (m), ``vel`` (NED, m/s), ``stdm``
            (position σ north, east, down, m), ``stdv`` (velocity σ NED, m/s), ``larm``
            (IMU → antenna, body x-forward y-right z-down, m)
reference   ``t``, ``lat``, ``lon``, ``h``, ``vel`` (NED), ``roll``, ``pitch``, ``yaw`` (rad)
==========  ==========================================================================

What a struct says about its sensor (noise, biases, σ, lever arm, start attitude) is
returned in ``meta`` in sinslab's vocabulary, for the caller to use and to tell the user:
``meta["error_model"]`` is an ``--imu-errors`` table (unit strings), ``meta["lever_arm"]``
the lever arm in right-forward-up axes.
"""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import attitude as _att
from sinslab.core.records import Fixes, NavSeries
from sinslab.data.frames import sensor_to_body
from sinslab.data.increments import ImuData, check_stamps, rates_to_increments, uniform_increments
from sinslab.data.matfile import loadmat

__all__ = ["IMU_FIELDS", "GNSS_FIELDS", "REF_FIELDS", "find_struct", "read_navego_imu",
           "read_navego_gnss", "read_navego_ref", "imu_struct_meta"]

IMU_FIELDS = ("t", "fb", "wb")
GNSS_FIELDS = ("t", "lat", "lon", "h")
REF_FIELDS = ("t", "lat", "lon", "h", "roll", "pitch", "yaw")


def _fields(v):
    """A MATLAB struct loaded by scipy (a (1, 1) record array) as ``{field: ndarray}``."""
    rec = v.reshape(-1)[0]
    return {n: np.asarray(rec[n]) for n in v.dtype.names}


def find_struct(m, path, need, var=None, what="struct"):
    """``(name, {field: array})`` of the struct of ``m`` (scipy.io.loadmat's dict) holding
    the fields ``need``; ``var`` names it. ``None`` when no struct fits and ``var`` is not
    given (the caller tries other layouts)."""
    structs = {k: v for k, v in m.items() if not k.startswith("__") and isinstance(v, np.ndarray)
               and v.dtype.names is not None and v.size == 1}
    if var is not None:
        if var not in structs:
            return None
        f = _fields(structs[var])
        missing = [n for n in need if n not in f]
        if missing:
            raise ValueError(f"{path}: struct {var!r} has no field(s) {', '.join(missing)} "
                             f"(a NaveGo {what} needs {', '.join(need)}; it has {', '.join(sorted(f))})")
        return var, f
    for k, v in structs.items():
        f = _fields(v)
        if all(n in f for n in need):
            return k, f
    return None


def _struct(m, path, need, var, what):
    """:func:`find_struct`, or one error naming the fields a NaveGo ``what`` needs."""
    hit = find_struct(m, path, need, var, what)
    if hit is None:
        raise ValueError(f"{path}: no NaveGo {what} (fields {', '.join(need)})" + (f" named {var!r}" if var else ""))
    return hit


def _col(f, name, path, var, n=None, width=None):
    a = np.asarray(f[name], dtype=float)
    if width is None:
        a = a.reshape(-1)
    else:
        if a.ndim == 2 and a.shape[1] != width and a.shape[0] == width:
            a = a.T                                     # a 3 x N field: columns are samples
        a = a.reshape(-1, width) if a.size % width == 0 else a
        if a.ndim != 2 or a.shape[1] != width:
            raise ValueError(f"{path}: {var}.{name} has shape {np.shape(f[name])}; NaveGo stores it "
                             f"as N x {width}")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{path}: {var}.{name} has {a.shape[0]} rows but {var}.t has {n}")
    bad = ~np.isfinite(a)
    if bad.any():
        raise ValueError(f"{path}: {var}.{name} row {int(np.argwhere(bad)[0][0]) + 1}: NaN/inf value")
    return a


def _vec3(f, name):
    """An optional 1x3 (or 3x1, or scalar) field as 3 floats, or None."""
    if name not in f or np.asarray(f[name]).size == 0:
        return None
    a = np.asarray(f[name], dtype=float).reshape(-1)
    if a.size == 1:
        a = np.repeat(a, 3)
    if a.size != 3 or not np.all(np.isfinite(a)):
        return None
    return a


def _unit_list(v, unit):
    return "[" + ", ".join(f"{x:.12g}" for x in v) + f"] {unit}"


def imu_struct_meta(f):
    """What a NaveGo IMU struct says about its sensor, in sinslab's vocabulary: an error
    model table (``[imu]`` keys of ``--imu-errors`` as unit strings; the Gauss–Markov biases
    ``gb_dyn``/``gb_corr`` become ``*_bias_instability``/``*_corr_time``, which is NaveGo's
    bias model and prior), the start attitude and its σ, the static biases."""
    imu, found = {}, []
    for key, name, unit in (("gyro_arw", "arw", "rad/s/sqrt(Hz)"), ("accel_vrw", "vrw", "m/s^2/sqrt(Hz)"),
                            ("gyro_bias_instability", "gb_dyn", "rad/s"),
                            ("accel_bias_instability", "ab_dyn", "m/s^2")):
        v = _vec3(f, name)
        if v is not None and np.any(v > 0):
            imu[key] = _unit_list(np.abs(v), unit)
            found.append(name)
    for key, name, dyn in (("gyro_corr_time", "gb_corr", "gyro_bias_instability"),
                           ("accel_corr_time", "ab_corr", "accel_bias_instability")):
        v = _vec3(f, name)
        if dyn in imu:
            if v is None or not np.all(v > 0):
                imu.pop(dyn)                  # a Gauss-Markov σ without τ: a random constant instead
                imu[dyn.replace("_instability", "")] = _unit_list(np.abs(_vec3(f, name[:2] + "_dyn")),
                                                                   "rad/s" if name[0] == "g" else "m/s^2")
            else:
                imu[key] = f"{float(np.min(v)):.12g} s"
                found.append(name)
    meta = {"fields": sorted(f), "noise_fields": found}
    if "gyro_arw" in imu and "accel_vrw" in imu:
        table = {"imu": imu}
        ia_err = _vec3(f, "ini_align_err")
        if ia_err is not None and np.all(ia_err > 0):
            # NaveGo's order roll, pitch, yaw; sinslab's [initial] attitude is pitch, roll, heading
            table["initial"] = {"attitude": [f"{ia_err[1]:.12g} rad", f"{ia_err[0]:.12g} rad",
                                             f"{ia_err[2]:.12g} rad"]}
        meta["error_model"] = table
    ia = _vec3(f, "ini_align")
    if ia is not None:
        meta["initial_attitude"] = _att.euler_from_ned(ia)          # sinslab [pitch, roll, yaw]
        err = _vec3(f, "ini_align_err")
        if err is not None:
            meta["initial_attitude_sigma"] = np.array([err[1], err[0], err[2]])
    for key, name in (("gyro_static_bias", "gb_sta"), ("accel_static_bias", "ab_sta")):
        v = _vec3(f, name)
        if v is not None and np.any(v != 0):
            meta[key] = v
    return meta


def read_navego_imu(path, m=None, var=None, *, frame="frd", mount=None, max_gap=1.0,
                    allow_gaps=False) -> ImuData:
    """Read a NaveGo IMU struct (fields ``t``, ``fb``, ``wb``; see the module notes) from a
    ``.mat`` file (``m``: the file's loaded dict, when the caller has it). The rates become
    increments over the interval ending at each stamp (NaveGo applies ``wb(i)`` over
    ``t(i) − t(i−1)``), the static biases ``gb_sta``/``ab_sta`` are subtracted as NaveGo
    does, and the axes are NaveGo's forward-right-down unless ``frame``/``mount`` say
    otherwise. ``meta`` carries :func:`imu_struct_meta` and the struct's name."""
    m = loadmat(path) if m is None else m
    var, f = _struct(m, path, IMU_FIELDS, var, "IMU struct")
    t = _col(f, "t", path, var)
    if t.size < 2:
        raise ValueError(f"{path}: {var}.t has {t.size} samples; needs at least 2")
    fb = _col(f, "fb", path, var, t.size, 3)
    wb = _col(f, "wb", path, var, t.size, 3)
    lines = [f"{var} row {i + 1}" for i in range(t.size)]
    check_stamps(t, path, lines)
    meta = imu_struct_meta(f)
    meta["variable"] = var
    if "gyro_static_bias" in meta:
        wb = wb - meta["gyro_static_bias"]
    if "accel_static_bias" in meta:
        fb = fb - meta["accel_static_bias"]
    R = sensor_to_body(mount, frame)
    dt_nom = float(np.median(np.diff(t)))
    dth, dv = rates_to_increments(t, wb @ R.T, fb @ R.T, dt_nom)
    imu, gaps, jit = uniform_increments(t, dth, dv, path=path, lines=lines, max_gap=max_gap,
                                        allow_gaps=allow_gaps)
    return ImuData(imu, gaps, str(path), "navego", t.size, jit, meta)


def read_navego_gnss(path, m=None, var=None):
    """Read a NaveGo GNSS struct (``t``, ``lat``/``lon`` rad, ``h``, optional ``vel`` NED,
    ``stdm``, ``stdv``, ``larm``). Returns ``(Fixes, meta)``: the fixes with the struct's σ
    (``stdm`` north, east, down → sinslab's north, east, up; ``stdv`` NED → east, north,
    up), ``meta`` with ``variable``, ``sigma_source`` and ``lever_arm`` (``larm`` from
    forward-right-down to right-forward-up, or None)."""
    m = loadmat(path) if m is None else m
    var, f = _struct(m, path, GNSS_FIELDS, var, "GNSS struct")
    t = _col(f, "t", path, var)
    n = t.size
    lat, lon, h = (_col(f, k, path, var, n) for k in ("lat", "lon", "h"))
    check_stamps(t, path, [f"{var} row {i + 1}" for i in range(n)])
    if np.any(np.abs(lat) > math.pi / 2) or np.any(np.abs(lon) > 2 * math.pi):
        raise ValueError(f"{path}: {var}.lat/lon beyond ±90°/±360° in radians: NaveGo stores "
                         "them in radians — are they degrees?")
    meta = {"variable": var, "fields": sorted(f)}
    stdm, stdv = _vec3(f, "stdm"), _vec3(f, "stdv")
    if stdm is not None and np.all(stdm > 0):
        sigma = np.tile(np.abs(stdm), (n, 1))
        meta["sigma_source"] = f"{var}.stdm"
    else:
        sigma = np.tile([1.0, 1.0, 2.0], (n, 1))
        meta["sigma_source"] = "default 1, 1, 2 m (no stdm in the struct)"
    vel = sv = None
    if "vel" in f and np.asarray(f["vel"]).size:
        vel = _att.vec_ned_to_enu(_col(f, "vel", path, var, n, 3))
        sv = np.tile(np.abs(_att.vec_ned_to_enu(stdv)) if stdv is not None and np.all(stdv > 0)
                     else [0.1, 0.1, 0.1], (n, 1))
        meta["velocity_sigma_source"] = (f"{var}.stdv" if stdv is not None and np.all(stdv > 0)
                                         else "default 0.1 m/s (no stdv in the struct)")
    larm = _vec3(f, "larm")
    meta["lever_arm"] = None if larm is None else _att.vec_ned_to_enu(larm)
    return Fixes(t, lat, lon, h, sigma, vel, sv, np.zeros(n, int), str(path)), meta


def read_navego_ref(path, m=None, var=None) -> NavSeries:
    """Read a NaveGo reference (truth) struct: positions (rad, m), NED velocity, roll,
    pitch, yaw (rad, yaw clockwise from north) -> :class:`NavSeries` (ENU, sinslab
    attitude). Fields longer than ``t`` (NaveGo's own files carry some) are cut to it."""
    m = loadmat(path) if m is None else m
    var, f = _struct(m, path, REF_FIELDS, var, "reference struct")
    t = _col(f, "t", path, var)
    n = t.size
    check_stamps(t, path, [f"{var} row {i + 1}" for i in range(n)])
    lat, lon, h, roll, pitch, yaw = (_col(f, k, path, var, n) for k in ("lat", "lon", "h", "roll", "pitch", "yaw"))
    vel = (_att.vec_ned_to_enu(_col(f, "vel", path, var, n, 3)) if "vel" in f
           else np.full((n, 3), np.nan))
    att = _att.euler_from_ned(np.stack([roll, pitch, yaw], -1))
    return NavSeries(t, lat, lon, h, vel, att)
