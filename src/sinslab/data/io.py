"""Reading recorded IMU data.

PSINS ``.imu`` text logs (Yan Gongmin's PSINS toolbox, "PSINS-format SIMU log")
------------------------------------------------------------------------------
Lines starting with ``%`` are comments. Then three header lines::

    pitch0 roll0 yaw0 (deg)  VE0 VN0 VU0 (m/s)     # "maybe inaccurate"; yaw CCW from north
    lat0 lon0 (deg)  h0 (m)  t0 (s)  dt (ms)  g (m/s^2)
    gf_x gf_y gf_z (arcsec/count)  af_x af_y af_z (ug·s/count)

and one line per sample of six integer counts: gyro x y z, accel x y z. Angle increments
are ``counts · gf`` arcsec; velocity increments ``counts · af · 1e-6 · g`` m/s with the
header's ``g`` (checked on ``lasergyro.imu``: the mean vertical increment then gives
|f| = 9.7955 m/s², the local normal gravity at 34.246° N, 380 m; with 9.80665 it would
be 0.25 % high). Axes X right, Y forward, Z up: sinslab's RFU body frame. The header yaw
is counter-clockwise from north, i.e. sinslab's yaw ψ (heading = −ψ).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sinslab.core import units
from sinslab.core.records import ImuRecord

__all__ = ["PsinsImu", "read_psins_imu", "read_imu"]


@dataclass(frozen=True)
class PsinsImu:
    """A PSINS ``.imu`` log.

    Attributes
    ----------
    imu : ImuRecord
        Increments (rad, m/s), RFU body frame, ``t = t0 + k·dt`` (interval end times).
    att0 : ndarray (3,)
        Header ``[pitch, roll, yaw]`` [rad] (sinslab convention; approximate).
    vel0 : ndarray (3,)
        Header velocity ENU [m/s].
    lat, lon, h : float
        Header position [rad, rad, m].
    g : float
        Header gravity [m/s²], the accelerometer scale's g.
    gyro_scale, accel_scale : ndarray (3,)
        [rad per count], [m/s per count].
    path : str
    """

    imu: ImuRecord
    att0: np.ndarray
    vel0: np.ndarray
    lat: float
    lon: float
    h: float
    g: float
    gyro_scale: np.ndarray
    accel_scale: np.ndarray
    path: str


def _header_line(line, n, what, path, lineno):
    try:
        vals = [float(x) for x in line.replace(",", " ").split()]
    except ValueError:
        raise ValueError(f"{path}:{lineno}: cannot read the {what} header line {line.strip()!r}") from None
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise ValueError(f"{path}:{lineno}: the {what} header line needs {n} finite numbers, "
                         f"got {line.strip()!r}")
    return vals


def read_psins_imu(path) -> PsinsImu:
    """Read a PSINS ``.imu`` text log (see the module notes). ValueError on a bad file."""
    path = Path(path)
    headers = []
    with open(path, "r", encoding="utf-8", errors="replace") as fh:
        lineno = 0
        for line in fh:
            lineno += 1
            s = line.strip()
            if not s or s.startswith("%"):
                continue
            headers.append((s, lineno))
            if len(headers) == 3:
                break
        if len(headers) < 3:
            raise ValueError(f"{path}: not a PSINS .imu log (expected 3 header lines, found "
                             f"{len(headers)})")
        names = ("attitude/velocity", "position/time/g", "scale factor")
        h = [_header_line(s, 6, nm, path, ln) for (s, ln), nm in zip(headers, names)]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)     # "input contained no data"
                data = np.loadtxt(fh, comments="%", ndmin=2)
        except ValueError as e:
            raise ValueError(f"{path}: bad sample line after line {lineno}: {e}") from None
    if data.size == 0:
        raise ValueError(f"{path}: no samples after the header")
    if data.shape[1] != 6:
        raise ValueError(f"{path}: sample lines need 6 columns (gyro x y z, accel x y z), "
                         f"got {data.shape[1]}")
    if not np.all(np.isfinite(data)):
        i = int(np.argwhere(~np.isfinite(data))[0, 0])
        raise ValueError(f"{path}: non-finite value in sample {i}")
    pitch, roll, yaw, ve, vn, vu = h[0]
    lat, lon, hgt, t0, dt_ms, g = h[1]
    if not dt_ms > 0:
        raise ValueError(f"{path}: sampling interval {dt_ms} ms must be > 0")
    if not 9.0 < g < 10.5:
        raise ValueError(f"{path}: header gravity {g} m/s^2 is not plausible")
    if abs(lat) > 90:
        raise ValueError(f"{path}: header latitude {lat} deg is beyond ±90 deg")
    gs = np.array(h[2][:3]) * units.arcsec
    as_ = np.array(h[2][3:]) * 1e-6 * g
    dt = dt_ms * 1e-3
    n = data.shape[0]
    t = t0 + dt * np.arange(1, n + 1)
    imu = ImuRecord(t, data[:, :3] * gs, data[:, 3:] * as_, dt)
    return PsinsImu(imu, np.radians([pitch, roll, yaw]), np.array([ve, vn, vu]),
                    math.radians(lat), math.radians(lon), hgt, g, gs, as_, str(path))


def read_imu(path, fmt=None, **kw):
    """Read an IMU file with :func:`load_imu` (any of :data:`IMU_FORMATS`; default from the
    suffix). Returns ``(ImuRecord, PsinsImu | None)``: the PSINS header (attitude, position,
    scale) when the file is a PSINS log, for callers that use it."""
    d = load_imu(path, fmt, **kw)
    return d.imu, d.meta.get("psins")


# =========================================================================================
# Generic readers and writers (recorded-data issue): tables of IMU samples with declared
# units, RTKLIB solutions and tagged IMU logs, MATLAB matrices, frame conversion, gaps.
# =========================================================================================
import re as _re
import struct as _struct

from sinslab.core import attitude as _att

__all__ += ["ImuData", "Fixes", "frame_matrix", "mount_matrix", "check_rotation",
            "rpy_frd_matrix", "load_imu", "read_table_imu", "read_rtklib_pos",
            "read_rtklib_tag", "read_rtklib_imu", "read_mat_imu", "read_mat_avp",
            "write_imu", "write_fixes", "read_fixes", "IMU_FORMATS", "FIX_FORMATS",
            "uniform_increments", "RTKLIB_DRIVE", "estimate_time_offset", "shift_imu_time", "guess_imu_format"]

#: IMU formats understood by :func:`load_imu` (``--format``).
IMU_FORMATS = ("psins", "csv", "parquet", "mat", "rtklib-imu")
#: Fix/solution formats understood by :func:`read_fixes`.
FIX_FORMATS = ("rtklib-pos", "csv", "mat-avp")

#: Facts about ``../shared/data/rtklib-drive`` (from its README and drive_config.py),
#: checked against the data in tests/test_io.py: sensor axes x back, y right, z up
#: (the config's 180° roll + 180° yaw) plus a residual (roll 0, pitch −6.79°, yaw 5.35°)
#: relative to the car's forward-right-down frame; antenna 5 cm left of the IMU at the
#: same height; logging delay −0.125 s.
RTKLIB_DRIVE = {"mount_rpy_frd_deg": (180.0, -6.79, 185.35), "lever_arm_rfu_m": (-0.05, 0.0, 0.0),
                "delay_s": -0.125}


def _where(path, line=None):
    return f"{path}:{line}" if line is not None else f"{path}"


# ------------------------------------------------------------------------- frames -------
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
    if M.shape != (3, 3) or not np.all(np.isfinite(M)):
        raise ValueError(f"{what} must be a finite 3x3 matrix, got shape {M.shape}")
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


def mount_matrix(mount=None, frame="rfu") -> np.ndarray:
    """Rotation taking sensor-axis vectors to sinslab's RFU vehicle body axes.

    Parameters
    ----------
    mount : None, (3, 3) array, or str
        ``None``: the sensor axes are the vehicle axes of ``frame``. A matrix:
        ``C_sensor→body`` in the ``frame`` convention (checked to be a rotation). A string
        ``"rpy:R,P,Y"`` (degrees; Groves/NED convention, :func:`rpy_frd_matrix`) or
        ``"euler:PITCH,ROLL,YAW"`` (degrees; sinslab convention, ``C_sensor→body =
        euler_to_dcm``).
    frame : str
        Axis convention of the vehicle body frame the mount refers to (see
        :func:`frame_matrix`); the result is converted to RFU.
    """
    P = frame_matrix(frame)
    if mount is None:
        return P
    if isinstance(mount, str):
        kind, _, vals = mount.partition(":")
        try:
            v = np.radians([float(x) for x in vals.replace(" ", "").split(",")])
        except ValueError:
            raise ValueError(f"cannot read the mount {mount!r}; use 'rpy:R,P,Y' or "
                             "'euler:PITCH,ROLL,YAW' in degrees") from None
        if v.size != 3:
            raise ValueError(f"mount {mount!r} needs three angles")
        if kind.strip().lower() == "rpy":
            M = rpy_frd_matrix(v)
        elif kind.strip().lower() == "euler":
            M = _att.euler_to_dcm(v)
        else:
            raise ValueError(f"unknown mount kind {kind!r}; use 'rpy:' or 'euler:'")
    else:
        M = np.asarray(mount, dtype=float)
    return P @ check_rotation(M)


# --------------------------------------------------------------------- containers -------
@dataclass(frozen=True)
class ImuData:
    """An IMU recording read by :func:`load_imu`.

    Attributes
    ----------
    imu : ImuRecord
        Increments on a uniform grid, RFU vehicle body axes (mount applied).
    gaps : ndarray, shape (k, 2)
        ``[start, length]`` [s] of the gaps found in the raw time stamps (intervals longer
        than 1.5 nominal intervals); they are bridged with the mean rate across the gap.
    path : str
    format : str
    n_raw : int
        Samples in the file.
    jitter : float
        RMS deviation of the raw sampling interval from the nominal one [s].
    meta : dict
        Format-specific extras (PSINS header, RTKLIB tag times ...).
    """

    imu: ImuRecord
    gaps: np.ndarray
    path: str
    format: str
    n_raw: int
    jitter: float = 0.0
    meta: dict = None


@dataclass(frozen=True)
class Fixes:
    """Position (and velocity) fixes, e.g. GNSS solutions.

    Attributes
    ----------
    t : ndarray (J,)
        Validity times [s] (same time base as the IMU file).
    lat, lon, h : ndarray (J,)
        [rad, rad, m] (ellipsoidal height).
    sigma : ndarray (J, 3)
        Position standard deviations north, east, up [m].
    vel : ndarray (J, 3) or None
        Velocity ENU [m/s].
    sigma_vel : ndarray (J, 3) or None
        Velocity standard deviations east, north, up [m/s].
    quality : ndarray (J,)
        Solution quality flag (RTKLIB Q: 1 fix, 2 float, 5 single; 0 unknown).
    path : str
    """

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    sigma: np.ndarray
    vel: np.ndarray | None
    sigma_vel: np.ndarray | None
    quality: np.ndarray
    path: str = ""

    def __len__(self):
        return self.t.size

    def select(self, mask):
        m = np.asarray(mask)
        return Fixes(self.t[m], self.lat[m], self.lon[m], self.h[m], self.sigma[m],
                     None if self.vel is None else self.vel[m],
                     None if self.sigma_vel is None else self.sigma_vel[m], self.quality[m], self.path)


# -------------------------------------------------------------- time -> uniform grid -----
def _check_stamps(t, path, lines):
    bad = ~np.isfinite(t)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{_where(path, lines[i])}: time stamp is not a finite number")
    d = np.diff(t)
    if (d == 0).any():
        i = int(np.argmax(d == 0)) + 1
        raise ValueError(f"{_where(path, lines[i])}: duplicated time stamp {float(t[i])!r}")
    if (d < 0).any():
        i = int(np.argmax(d < 0)) + 1
        raise ValueError(f"{_where(path, lines[i])}: time stamps not sorted ({float(t[i])!r} follows {float(t[i - 1])!r})")


def uniform_increments(t, dth, dv, *, path="", lines=None, dt=None, max_gap=1.0, allow_gaps=False):
    """Increments at (possibly jittery or gappy) end times -> a uniform :class:`ImuRecord`.

    The cumulative angle and velocity (sums of increments at the raw end times) are
    interpolated linearly onto a uniform grid and differenced: jitter is absorbed, a gap
    is bridged with the mean rate across it. Gaps longer than ``max_gap`` [s] raise
    ValueError unless ``allow_gaps``. Returns ``(ImuRecord, gaps (k, 2), jitter_rms)``.
    """
    t = np.asarray(t, dtype=float)
    n = t.size
    lines = list(range(1, n + 1)) if lines is None else lines
    if n < 2:
        raise ValueError(f"{_where(path)}: needs at least 2 samples, got {n}")
    _check_stamps(t, path, lines)
    d = np.diff(t)
    dt_nom = float(np.median(d)) if dt is None else float(dt)
    gap_i = np.flatnonzero(d > 1.5 * dt_nom)
    gaps = np.stack([t[gap_i], d[gap_i]], -1) if gap_i.size else np.zeros((0, 2))
    if gap_i.size and not allow_gaps:
        long_ = gap_i[d[gap_i] > max_gap]
        if long_.size:
            i = int(long_[0])
            raise ValueError(f"{_where(path, lines[i + 1])}: gap of {d[i]:.3f} s in the IMU record "
                             f"after t = {t[i]:.3f} s (longer than max_gap = {max_gap:g} s); "
                             "allow it explicitly to navigate across")
    ok = d <= 1.5 * dt_nom
    jitter = float(np.sqrt(np.mean((d[ok] - dt_nom) ** 2))) if ok.any() else 0.0
    if gap_i.size == 0 and abs(t[-1] - t[0] - (n - 1) * dt_nom) <= 1e-9 * max(1.0, abs(t[-1])) \
            and np.all(np.abs(d - dt_nom) <= 1e-4 * dt_nom):
        return ImuRecord(t, dth, dv, dt_nom), gaps, jitter
    tc = np.concatenate([[t[0] - dt_nom], t])
    m = int(math.floor((tc[-1] - tc[0]) / dt_nom + 1e-9))
    grid = tc[0] + dt_nom * np.arange(m + 1)
    out = []
    for a in (dth, dv):
        c = np.vstack([np.zeros((1, 3)), np.cumsum(a, 0)])
        ci = np.stack([np.interp(grid, tc, c[:, k]) for k in range(3)], -1)
        out.append(np.diff(ci, axis=0))
    return ImuRecord(grid[1:], out[0], out[1], dt_nom), gaps, jitter


def _rates_to_increments(t, w, f, dt_nom):
    """Rectangular rule with the actual intervals; across a gap the mean of the rates at
    its two ends is held."""
    d = np.diff(t, prepend=t[0] - dt_nom)
    big = d > 1.5 * dt_nom
    w = np.array(w, dtype=float)
    f = np.array(f, dtype=float)
    if big.any():
        i = np.flatnonzero(big)
        i = i[i > 0]
        w[i] = 0.5 * (w[i] + w[i - 1])
        f[i] = 0.5 * (f[i] + f[i - 1])
    return w * d[:, None], f * d[:, None]


# ------------------------------------------------------------------- table columns ------
_COLSETS = {
    "gyro_rate": [("gx", "gy", "gz"), ("wx", "wy", "wz"), ("gyro_x", "gyro_y", "gyro_z"),
                  ("omega_x", "omega_y", "omega_z"), ("gyrox", "gyroy", "gyroz")],
    "accel_rate": [("ax", "ay", "az"), ("fx", "fy", "fz"), ("acc_x", "acc_y", "acc_z"),
                   ("accel_x", "accel_y", "accel_z"), ("accx", "accy", "accz")],
    "gyro_inc": [("dtheta_x", "dtheta_y", "dtheta_z"), ("dthx", "dthy", "dthz"), ("dax", "day", "daz")],
    "accel_inc": [("dv_x", "dv_y", "dv_z"), ("dvx", "dvy", "dvz")],
}
_TIME_NAMES = ("t", "time", "timestamp", "t_s", "time_s", "tow")
# names whose unit may be omitted (plain SI columns t,dtheta_x..,dv_x.. or t,wx..,fx..)
_SI_NAMES = {"t", "dtheta_x", "dtheta_y", "dtheta_z", "dv_x", "dv_y", "dv_z",
             "wx", "wy", "wz", "fx", "fy", "fz"}
_HDR = _re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$")


def _parse_header(cols, path, line):
    out = []
    for c in cols:
        m = _HDR.match(str(c))
        if not m:
            raise ValueError(f"{_where(path, line)}: cannot read the column name {str(c)!r} "
                             "(expected NAME or NAME[unit], e.g. gx[deg/s])")
        out.append((m.group(1).lower(), (m.group(2) or "").strip() or None))
    return out


def _find_cols(names, which):
    for triple in _COLSETS[which]:
        if all(x in names for x in triple):
            return [names.index(x) for x in triple]
    return None


def _unit_kind(unit, sensor, path, line, name):
    """(scale, 'rate'|'inc') for a declared unit of a gyro/accel column."""
    kinds = (("angular_rate", "rate"), ("angle", "inc")) if sensor == "gyro" else \
        (("acceleration", "rate"), ("velocity", "inc"))
    for kind, what in kinds:
        try:
            return units.unit_scale(unit, kind), what
        except (ValueError, KeyError):
            continue
    exp = "deg/s, rad/s (rates) or deg, rad (increments)" if sensor == "gyro" else \
        "g, m/s^2 (rates) or m/s (increments)"
    raise ValueError(f"{_where(path, line)}: column {name!r} has unit {unit!r}, not a {sensor} unit "
                     f"({exp})")


def read_table_imu(path, *, gyro_unit=None, accel_unit=None, time_unit=None, kind=None,
                   frame="rfu", mount=None, max_gap=1.0, allow_gaps=False) -> ImuData:
    """Read a CSV or Parquet table of IMU samples.

    Columns (names case-insensitive, any order, extra columns ignored): a time column
    ``t``/``time``/``timestamp`` (interval end times for increments, sample times for
    rates) and either rates ``gx gy gz`` (or ``wx..``, ``gyro_x..``) with ``ax ay az`` (or
    ``fx..``, ``acc_x..``), or increments ``dtheta_x..`` with ``dv_x..``. Units are
    declared in the header, ``gx[deg/s]``, ``ax[g]``, ``dtheta_x[rad]``, ``t[ms]``, or by
    the options ``gyro_unit``/``accel_unit``/``time_unit``; the unit's dimension tells
    rates from increments. The plain SI names ``t, dtheta_x.., dv_x..`` and
    ``t, wx.., fx..`` may omit units (s, rad, m/s, rad/s, m/s²). ``frame``/``mount``:
    see :func:`mount_matrix`. Raises ValueError naming the file and line of the problem.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    is_parquet = path.suffix.lower() in (".parquet", ".pq")
    if is_parquet:
        import pandas as pd
        try:
            df = pd.read_parquet(path)
        except Exception as e:   # noqa: BLE001 - pyarrow raises many kinds
            raise ValueError(f"{path}: cannot read as Parquet ({e})") from None
        header = [str(c) for c in df.columns]
        hline = None
        if len(df) == 0:
            raise ValueError(f"{path}: no samples")
        try:
            data = df.to_numpy(dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{path}: non-numeric values in the table") from None
        lines = [f"row {i + 1}" for i in range(len(df))]
        where_line = lambda i: lines[i]      # noqa: E731
    else:
        with open(path, "r", encoding="utf-8", errors="replace") as fh:
            text = fh.read().splitlines()
        body = [(i + 1, s) for i, s in enumerate(text) if s.strip() and not s.lstrip().startswith(("#", "%"))]
        if not body:
            raise ValueError(f"{path}: empty file (no header, no samples)")
        hline, hdr = body[0]
        delim = "," if "," in hdr else None
        header = [c.strip() for c in (hdr.split(delim) if delim else hdr.split())]
        rows = body[1:]
        if not rows:
            raise ValueError(f"{_where(path, hline)}: header only, no samples")
        ncol = len(header)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                data = np.loadtxt([s for _, s in rows], delimiter=delim, ndmin=2)
            if data.shape[1] != ncol:
                raise ValueError("column count")
        except ValueError:
            for ln, s in rows:
                parts = [p.strip() for p in (s.split(delim) if delim else s.split())]
                if len(parts) != ncol:
                    raise ValueError(f"{path}:{ln}: {len(parts)} columns, the header has {ncol}") from None
                for p in parts:
                    try:
                        float(p)
                    except ValueError:
                        raise ValueError(f"{path}:{ln}: not a number: {p!r}") from None
            raise
        lines = [ln for ln, _ in rows]
        where_line = lambda i: lines[i]      # noqa: E731
    cols = _parse_header(header, path, hline)
    names = [c[0] for c in cols]
    if len(set(names)) != len(names):
        raise ValueError(f"{_where(path, hline)}: duplicated column names {names}")
    ti = next((names.index(n) for n in _TIME_NAMES if n in names), None)
    if ti is None:
        raise ValueError(f"{_where(path, hline)}: no time column (t, time or timestamp) in {header}")
    g_rate, a_rate = _find_cols(names, "gyro_rate"), _find_cols(names, "accel_rate")
    g_inc, a_inc = _find_cols(names, "gyro_inc"), _find_cols(names, "accel_inc")
    gi = g_inc or g_rate
    ai = a_inc or a_rate
    if gi is None or ai is None:
        raise ValueError(f"{_where(path, hline)}: wrong columns {header}: need a time column and gyro "
                         "(gx gy gz | dtheta_x dtheta_y dtheta_z) and accelerometer (ax ay az | "
                         "dv_x dv_y dv_z) columns")

    def col_scale(idx, sensor, opt):
        scales, kinds, us = [], [], []
        for i in idx:
            nm, un = cols[i]
            if un is None:
                un = opt
            if un is None:
                if nm in _SI_NAMES:
                    un = {"dtheta": "rad", "dv": "m/s", "w": "rad/s", "f": "m/s^2"}[
                        "dtheta" if nm.startswith("dtheta") else "dv" if nm.startswith("dv")
                        else nm[0]]
                else:
                    raise ValueError(f"{_where(path, hline)}: column {nm!r} has no unit; declare it "
                                     f"in the header ({nm}[deg/s], {nm}[g], ...) or give the "
                                     f"{sensor} unit as an option")
            s, k = _unit_kind(un, sensor, path, hline, nm)
            scales.append(s)
            kinds.append(k)
            us.append(un)
        if len(set(us)) > 1 or len(set(kinds)) > 1:
            raise ValueError(f"{_where(path, hline)}: mixed units in the {sensor} columns "
                             f"({', '.join(f'{cols[i][0]}[{u}]' for i, u in zip(idx, us))}); "
                             "use one unit for all three axes")
        return scales[0], kinds[0], us[0]

    gs, gk, gu = col_scale(gi, "gyro", gyro_unit)
    as_, ak, au = col_scale(ai, "accel", accel_unit)
    if gk != ak:
        raise ValueError(f"{_where(path, hline)}: mixed units: gyro columns are "
                         f"{'rates' if gk == 'rate' else 'increments'} [{gu}] but accelerometer "
                         f"columns are {'rates' if ak == 'rate' else 'increments'} [{au}]")
    if kind is not None and kind != {"rate": "rates", "inc": "increments"}[gk]:
        raise ValueError(f"{path}: kind={kind!r} but the declared units are "
                         f"{'rates' if gk == 'rate' else 'increments'}")
    tu = cols[ti][1] or time_unit or "s"
    ts = units.unit_scale(tu, "time")
    bad = ~np.isfinite(data[:, [ti] + gi + ai])
    if bad.any():
        r = int(np.argwhere(bad)[0, 0])
        raise ValueError(f"{_where(path, where_line(r))}: NaN/inf value in the samples")
    t = data[:, ti] * ts
    R = mount_matrix(mount, frame)
    g = data[:, gi] * gs @ R.T
    a = data[:, ai] * as_ @ R.T
    _check_stamps(t, path, lines)
    if gk == "rate":
        dt_nom = float(np.median(np.diff(t))) if t.size > 1 else float("nan")
        if t.size < 2:
            raise ValueError(f"{path}: needs at least 2 samples for rates")
        d = np.diff(t)
        if np.all(np.abs(d - dt_nom) <= 1e-4 * dt_nom):
            imu = ImuRecord.from_rates(t, g, a)
            return ImuData(imu, np.zeros((0, 2)), str(path), "parquet" if is_parquet else "csv",
                           t.size, 0.0, {"units": {"gyro": gu, "accel": au, "time": tu}})
        dth, dvv = _rates_to_increments(t, g, a, dt_nom)
    else:
        dth, dvv = g, a
    imu, gaps, jit = uniform_increments(t, dth, dvv, path=path, lines=lines,
                                        max_gap=max_gap, allow_gaps=allow_gaps)
    return ImuData(imu, gaps, str(path), "parquet" if is_parquet else "csv", t.size, jit,
                   {"units": {"gyro": gu, "accel": au, "time": tu}})


# --------------------------------------------------------------------------- RTKLIB -----
def _gpst_seconds(date, time, path, line):
    """Seconds of a calendar stamp 'YYYY/MM/DD HH:MM:SS.sss' counted like POSIX time
    (no leap seconds): for GPST stamps this is 'GPS calendar seconds'."""
    import datetime as _dt
    try:
        y, mo, d = (int(x) for x in date.split("/"))
        hh, mm, ss = time.split(":")
        sec = float(ss)
        base = _dt.datetime(y, mo, d, int(hh), int(mm), tzinfo=_dt.timezone.utc).timestamp()
    except (ValueError, TypeError):
        raise ValueError(f"{path}:{line}: cannot read the time stamp {date} {time!r}") from None
    return base + sec


def read_rtklib_pos(path, *, min_quality=None, velocity_lag=0.0) -> Fixes:
    """Read an RTKLIB ``.pos`` solution (lat/lon/height output, GPST or UTC calendar time
    or GPS week + seconds).

    Columns after the time: latitude, longitude [deg], height [m], Q, ns, sdn, sde, sdu,
    sdne, sdeu, sdun [m], age, ratio, and optionally vn, ve, vu [m/s] and their σ. Times
    are seconds of the calendar stamp counted without leap seconds (for GPST stamps:
    GPST seconds since 1970-01-01, the convention of RTKLIB's tag files). Velocity
    columns are north, east, up (checked against position differences on rtklib-drive);
    they are returned ENU. ``min_quality``: keep epochs with ``1 <= Q <= min_quality``.
    ``velocity_lag`` [s]: the velocities describe the motion ``velocity_lag`` s before their
    stamp (on rtklib-drive they match the position differences best 0.125 s earlier — half
    the 4 Hz epoch — see tests/test_io.py); they are re-sampled to the position times
    (linear interpolation, the last one held).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    hdr = None
    t, vals, lines = [], [], []
    ncol = None
    with open(path, "r", encoding="utf-8", errors="replace") as fh:
        for ln, line in enumerate(fh, 1):
            s = line.strip()
            if not s:
                continue
            if s.startswith("%"):
                if "latitude" in s or "x-ecef" in s or "e-baseline" in s or "GPST" in s or "UTC" in s:
                    hdr = (ln, s)
                    if "x-ecef" in s or "e-baseline" in s:
                        raise ValueError(f"{path}:{ln}: only the lat/lon/height solution format is "
                                         "supported (this file is ECEF or ENU baseline)")
                continue
            p = s.split()
            if "/" in p[0]:
                tt = _gpst_seconds(p[0], p[1], path, ln)
                rest = p[2:]
            else:
                try:
                    week, tow = int(p[0]), float(p[1])
                except (ValueError, IndexError):
                    raise ValueError(f"{path}:{ln}: cannot read the time stamp {' '.join(p[:2])!r}") from None
                tt = 315964800.0 + week * 604800.0 + tow
                rest = p[2:]
            if ":" in rest[0] if rest else False:
                raise ValueError(f"{path}:{ln}: degree-minute-second latitude is not supported; "
                                 "output decimal degrees from RTKLIB")
            try:
                v = [float(x) for x in rest]
            except ValueError:
                raise ValueError(f"{path}:{ln}: not a number in {s!r}") from None
            if ncol is None:
                ncol = len(v)
                if ncol < 11:
                    raise ValueError(f"{path}:{ln}: {ncol} value columns; an RTKLIB lat/lon/height "
                                     "solution has at least 11 (lat lon h Q ns sdn sde sdu sdne sdeu sdun)")
            elif len(v) != ncol:
                raise ValueError(f"{path}:{ln}: {len(v)} value columns, the first epoch had {ncol}")
            if not all(math.isfinite(x) for x in v):
                raise ValueError(f"{path}:{ln}: NaN/inf value")
            t.append(tt)
            vals.append(v)
            lines.append(ln)
    if not t:
        raise ValueError(f"{path}: no solution epochs")
    if hdr is not None and "UTC" in hdr[1] and "GPST" not in hdr[1]:
        pass    # UTC stamps: the caller's IMU time base must be UTC too (documented)
    t = np.array(t)
    _check_stamps(t, path, lines)
    v = np.array(vals)
    if np.any(np.abs(v[:, 0]) > 90):
        i = int(np.argmax(np.abs(v[:, 0]) > 90))
        raise ValueError(f"{path}:{lines[i]}: latitude {v[i, 0]} beyond ±90 deg")
    sig = v[:, 5:8].copy()
    sig[sig <= 0] = 0.01
    vel = svel = None
    if ncol >= 16:
        vel = np.stack([v[:, 14], v[:, 13], v[:, 15]], -1)       # vn ve vu -> ENU
        if velocity_lag:
            vel = np.stack([np.interp(t + float(velocity_lag), t, vel[:, i]) for i in range(3)], -1)
        if ncol >= 19:
            svel = np.stack([v[:, 17], v[:, 16], v[:, 18]], -1)
            svel[svel <= 0] = 0.05
        else:
            svel = np.full_like(vel, 0.05)
    fx = Fixes(t, np.radians(v[:, 0]), np.radians(v[:, 1]), v[:, 2], sig, vel, svel,
               v[:, 3].astype(int), str(path))
    if min_quality is not None:
        fx = fx.select((fx.quality >= 1) & (fx.quality <= min_quality))
        if len(fx) == 0:
            raise ValueError(f"{path}: no epoch with quality 1..{min_quality}")
    return fx


def read_rtklib_tag(path) -> dict:
    """Read an RTKLIB time-tag file (``.tag``): 60-byte text header "TIMETAG RTKLIB ...",
    uint32 tick at open, uint32 + float64 start time, then (uint32 tick ms since open,
    uint32 file position) pairs.

    The start time is what RTKLIB's stream writer stores: GPST (``utc2gpst(timeget())``),
    counted like POSIX seconds. The data README calls it UTC; the data say GPST (the IMU
    turn rates line up with the GNSS course changes within 0.1 s when the tag is read as
    GPST, 18 s off as UTC — see tests/test_io.py). Returns ``{"start", "end", "ticks",
    "fpos", "header"}`` (``end = start + last tick``).
    """
    path = Path(path)
    try:
        b = path.read_bytes()
    except OSError as e:
        raise ValueError(f"{path}: cannot read the tag file ({e})") from None
    if len(b) < 76 or not b.startswith(b"TIMETAG"):
        raise ValueError(f"{path}: not an RTKLIB time-tag file (no 'TIMETAG' header)")
    head = b[:60].rstrip(b"\0").decode("ascii", "replace")
    _tick0, sec = _struct.unpack("<II", b[60:68])
    frac = _struct.unpack("<d", b[68:76])[0]
    e = np.frombuffer(b[76:76 + (len(b) - 76) // 8 * 8], dtype="<u4").reshape(-1, 2)
    start = sec + frac
    end = start + (float(e[-1, 0]) / 1000.0 if len(e) else 0.0)
    return {"start": start, "end": end, "ticks": e[:, 0].astype(float), "fpos": e[:, 1].astype(float),
            "header": head}


def read_rtklib_imu(path, *, tag=None, delay=0.0, mount=None, frame="frd", accel_unit="g",
                    gyro_unit="deg/s", stretch=False, max_gap=1.0, allow_gaps=False) -> ImuData:
    """Read the RTKLIB-logged IMU CSV of ``rtklib-drive``: rows ``ax ay az [g], gx gy gz
    [deg/s], tick [ms]``, no header, with its ``.tag`` file (default ``path + ".tag"``).

    Time: the ms ticks are counted from the first row from the tag's start time, then
    ``delay`` [s] is added (the source project's logging delay is −0.125 s). With
    ``stretch`` the ticks are scaled to span the tag's start..end as the source project
    does (+257 ppm on rtklib-drive) — off by default: against the GNSS turn rates the IMU
    clock runs *fast* by ~170 ppm, so the stretch doubles the drift (0.09 -> 0.22 s late
    over the record instead of 0.06 -> 0.11 s; tests/test_io.py). Use
    :func:`estimate_time_offset` / :func:`shift_imu_time` to synchronise. The time base is
    the tag's (GPST seconds, see :func:`read_rtklib_tag`).
    ``mount``/``frame``: sensor → vehicle axes (:func:`mount_matrix`; the sensor axes
    need it on rtklib-drive, see :data:`RTKLIB_DRIVE`).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    tagp = Path(tag) if tag is not None else Path(str(path) + ".tag")
    if not tagp.exists():
        raise ValueError(f"{path}: no time-tag file {tagp} (RTKLIB writes NAME.tag next to the log)")
    tg = read_rtklib_tag(tagp)
    with open(path, "r", encoding="utf-8", errors="replace") as fh:
        text = fh.read().splitlines()
    rows = [(i + 1, s) for i, s in enumerate(text) if s.strip()]
    if not rows:
        raise ValueError(f"{path}: empty file")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = np.loadtxt([s for _, s in rows], delimiter=",", ndmin=2)
    except ValueError:
        for ln, s in rows:
            p = s.split(",")
            if len(p) != 7:
                raise ValueError(f"{path}:{ln}: {len(p)} columns; expected 7 (ax ay az gx gy gz tick)") from None
            for x in p:
                try:
                    float(x)
                except ValueError:
                    raise ValueError(f"{path}:{ln}: not a number: {x.strip()!r}") from None
        raise
    if d.shape[1] != 7:
        raise ValueError(f"{path}:{rows[0][0]}: {d.shape[1]} columns; expected 7 (ax ay az gx gy gz tick)")
    lines = [ln for ln, _ in rows]
    bad = ~np.isfinite(d)
    if bad.any():
        i = int(np.argwhere(bad)[0, 0])
        raise ValueError(f"{path}:{lines[i]}: NaN/inf value")
    tick = d[:, 6] / 1000.0
    _check_stamps(tick, path, lines)
    sec = tick - tick[0]
    span = tg["end"] - tg["start"]
    scale = span / sec[-1] if (stretch and sec[-1] > 0 and span > 0) else 1.0
    t = tg["start"] + sec * scale + float(delay)
    R = mount_matrix(mount, frame)
    w = d[:, 3:6] * units.unit_scale(gyro_unit, "angular_rate") @ R.T
    f = d[:, 0:3] * units.unit_scale(accel_unit, "acceleration") @ R.T
    dt_nom = float(np.median(np.diff(t)))
    dth, dvv = _rates_to_increments(t, w, f, dt_nom)
    imu, gaps, jit = uniform_increments(t, dth, dvv, path=path, lines=lines, dt=None,
                                        max_gap=max_gap, allow_gaps=allow_gaps)
    return ImuData(imu, gaps, str(path), "rtklib-imu", t.size, jit,
                   {"tag_start": tg["start"], "tag_end": tg["end"], "tick_scale": scale,
                    "delay": float(delay), "mount": R})


# ---------------------------------------------------------------------------- MATLAB ----
def _loadmat(path):
    import scipy.io
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        return scipy.io.loadmat(path)
    except Exception as e:  # noqa: BLE001 - scipy raises several kinds
        raise ValueError(f"{path}: cannot read as a MATLAB .mat file ({e})") from None


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


def read_mat_imu(path, var=None, *, dt=None, frame="rfu", mount=None, max_gap=1.0,
                 allow_gaps=False) -> ImuData:
    """Read a PSINS-layout IMU matrix from a ``.mat`` file: rows ``[Δθx Δθy Δθz (rad),
    Δvx Δvy Δvz (m/s), t (s)]`` (interval end times), or 6 columns without time (give
    ``dt``). ``var`` defaults to ``imu``/``mimu``/the first 6/7-column matrix."""
    m = _loadmat(path)
    var, a = _mat_var(m, path, var, (6, 7), ("imu", "mimu", "simu"))
    if a.shape[1] == 6:
        if dt is None:
            raise ValueError(f"{path}: variable {var!r} has no time column; give dt")
        t = float(dt) * np.arange(1, a.shape[0] + 1)
    else:
        t = a[:, 6]
    R = mount_matrix(mount, frame)
    imu, gaps, jit = uniform_increments(t, a[:, 0:3] @ R.T, a[:, 3:6] @ R.T, path=path,
                                        lines=[f"row {i + 1}" for i in range(a.shape[0])],
                                        max_gap=max_gap, allow_gaps=allow_gaps)
    return ImuData(imu, gaps, str(path), "mat", a.shape[0], jit, {"variable": var})


def read_mat_avp(path, var=None):
    """Read a PSINS ``avp`` solution matrix: rows ``[pitch roll yaw (rad), vE vN vU (m/s),
    lat lon (rad), h (m), t (s)]`` (10 columns; yaw counter-clockwise from north, the
    sinslab convention). Returns :class:`sinslab.core.records.NavSeries`."""
    from sinslab.core.records import NavSeries
    m = _loadmat(path)
    var, a = _mat_var(m, path, var, (10,), ("avp", "fogavp", "avpr"))
    t = a[:, 9]
    _check_stamps(t, path, [f"row {i + 1}" for i in range(t.size)])
    if np.any(np.abs(a[:, 6]) > math.pi / 2):
        raise ValueError(f"{path}: variable {var!r}: latitude beyond ±90° — is it in radians?")
    return NavSeries(t, a[:, 6], a[:, 7], a[:, 8], a[:, 3:6], a[:, 0:3])


# ---------------------------------------------------------------------------- writers ---
_INC_COLS = ["t[s]", "dtheta_x[rad]", "dtheta_y[rad]", "dtheta_z[rad]",
             "dv_x[m/s]", "dv_y[m/s]", "dv_z[m/s]"]


def write_imu(path, imu: ImuRecord, fmt=None):
    """Write increments: ``csv`` (header ``t[s],dtheta_x[rad],...,dv_z[m/s]``), ``parquet``
    (same columns) or ``mat`` (variable ``imu`` = PSINS layout N×7 and ``dt``); the format
    defaults from the suffix. Atomic (temporary name + rename). Returns the path."""
    from sinslab.core.atomic import atomic_path
    path = Path(path)
    fmt = fmt or {".parquet": "parquet", ".pq": "parquet", ".mat": "mat"}.get(path.suffix.lower(), "csv")
    a = np.column_stack([imu.t, imu.dtheta, imu.dv])
    if fmt == "csv":
        with atomic_path(path) as tmp:
            np.savetxt(tmp, a, delimiter=",", header=",".join(_INC_COLS), comments="", fmt="%.17g")
    elif fmt == "parquet":
        import pandas as pd
        with atomic_path(path) as tmp:
            pd.DataFrame(a, columns=_INC_COLS).to_parquet(tmp, index=False)
    elif fmt == "mat":
        import scipy.io
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                scipy.io.savemat(fh, {"imu": np.column_stack([imu.dtheta, imu.dv, imu.t]),
                                      "dt": imu.dt})
    else:
        raise ValueError(f"unknown output format {fmt!r}; use csv, parquet or mat")
    return path


_FIX_COLS = ["t[s]", "lat[deg]", "lon[deg]", "h[m]", "sd_n[m]", "sd_e[m]", "sd_u[m]"]
_FIX_VCOLS = ["ve[m/s]", "vn[m/s]", "vu[m/s]", "sd_ve[m/s]", "sd_vn[m/s]", "sd_vu[m/s]"]


def write_fixes(path, fx: Fixes):
    """Write fixes as CSV (columns of :func:`read_fixes`' CSV format)."""
    from sinslab.core.atomic import atomic_path
    cols = [fx.t, np.degrees(fx.lat), np.degrees(fx.lon), fx.h, *fx.sigma.T]
    names = list(_FIX_COLS)
    if fx.vel is not None:
        cols += [*fx.vel.T, *fx.sigma_vel.T]
        names += _FIX_VCOLS
    with atomic_path(Path(path)) as tmp:
        np.savetxt(tmp, np.column_stack(cols), delimiter=",", header=",".join(names), comments="",
                   fmt="%.12g")
    return Path(path)


def _read_fix_csv(path):
    import pandas as pd
    path = Path(path)
    try:
        df = pd.read_csv(path, comment="#")
    except Exception as e:  # noqa: BLE001
        raise ValueError(f"{path}: cannot read as CSV ({e})") from None
    if len(df) == 0:
        raise ValueError(f"{path}: no fixes")
    cols = _parse_header(df.columns, path, 1)
    names = [c[0] for c in cols]
    need = ["t", "lat", "lon", "h"]
    for n in need:
        if n not in names:
            raise ValueError(f"{path}:1: no column {n!r} (need t, lat[deg], lon[deg], h[m]; optional "
                             "sd_n sd_e sd_u [m], ve vn vu [m/s], sd_ve sd_vn sd_vu)")
    try:
        a = df.to_numpy(dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{path}: non-numeric values") from None
    bad = ~np.isfinite(a)
    if bad.any():
        raise ValueError(f"{path}:{int(np.argwhere(bad)[0, 0]) + 2}: NaN/inf value")

    def col(n, kind, default_unit):
        i = names.index(n)
        u = cols[i][1] or default_unit
        return a[:, i] * units.unit_scale(u, kind)

    t = col("t", "time", "s")
    _check_stamps(t, path, list(range(2, len(t) + 2)))
    lat, lon = col("lat", "angle", "deg"), col("lon", "angle", "deg")
    h = col("h", "length", "m")
    sig = np.stack([col(n, "length", "m") if n in names else np.full(t.size, 1.0)
                    for n in ("sd_n", "sd_e", "sd_u")], -1)
    vel = svel = None
    if all(n in names for n in ("ve", "vn", "vu")):
        vel = np.stack([col(n, "velocity", "m/s") for n in ("ve", "vn", "vu")], -1)
        svel = np.stack([col(n, "velocity", "m/s") if n in names else np.full(t.size, 0.1)
                         for n in ("sd_ve", "sd_vn", "sd_vu")], -1)
    return Fixes(t, lat, lon, h, sig, vel, svel, np.zeros(t.size, int), str(path))


def read_fixes(path, fmt=None, **kw) -> Fixes:
    """Read position(/velocity) fixes: ``rtklib-pos`` (``.pos``), ``csv`` (columns ``t[s],
    lat[deg], lon[deg], h[m]`` + optional ``sd_n sd_e sd_u``, ``ve vn vu``, ``sd_ve ..``) or
    ``mat-avp`` (a PSINS avp matrix: positions and velocities, σ from ``sigma``/
    ``sigma_vel`` keywords, default 1 m / 0.1 m/s)."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    fmt = fmt or {".pos": "rtklib-pos", ".mat": "mat-avp"}.get(p.suffix.lower(), "csv")
    if fmt == "rtklib-pos":
        return read_rtklib_pos(p, **kw)
    if fmt == "csv":
        return _read_fix_csv(p)
    if fmt == "mat-avp":
        s = read_mat_avp(p, kw.get("var"))
        J = len(s)
        return Fixes(s.t, s.lat, s.lon, s.h, np.full((J, 3), float(kw.get("sigma", 1.0))),
                     s.vel, np.full((J, 3), float(kw.get("sigma_vel", 0.1))), np.zeros(J, int), str(p))
    raise ValueError(f"unknown fix format {fmt!r}; use one of {FIX_FORMATS}")


def guess_imu_format(path) -> str:
    """IMU format from the file name: ``.imu`` psins, ``.parquet`` parquet, ``.mat`` mat, a
    file with an RTKLIB ``.tag`` next to it rtklib-imu, else csv."""
    p = Path(path)
    suf = p.suffix.lower()
    return ("psins" if suf == ".imu" else "parquet" if suf in (".parquet", ".pq") else
            "mat" if suf == ".mat" else "rtklib-imu" if Path(str(p) + ".tag").exists() else "csv")


def load_imu(path, fmt=None, **kw) -> ImuData:
    """Read any supported IMU file into :class:`ImuData` (``fmt`` from :data:`IMU_FORMATS`,
    default from the suffix: ``.imu`` psins, ``.parquet`` parquet, ``.mat`` mat, a ``.csv``
    with a ``.tag`` next to it rtklib-imu, else csv). Keywords go to the reader."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    fmt = fmt or guess_imu_format(p)
    if fmt == "psins":
        extra = set(kw) - {"mount", "frame"}
        if extra:
            raise ValueError(f"options {sorted(extra)} do not apply to PSINS files")
        ps = read_psins_imu(p)
        imu = ps.imu
        if kw.get("mount") is not None or kw.get("frame", "rfu") != "rfu":
            R = mount_matrix(kw.get("mount"), kw.get("frame", "rfu"))
            imu = ImuRecord(imu.t, imu.dtheta @ R.T, imu.dv @ R.T, imu.dt)
        return ImuData(imu, np.zeros((0, 2)), str(p), "psins", len(imu), 0.0, {"psins": ps})
    if fmt in ("csv", "parquet"):
        return read_table_imu(p, **kw)
    if fmt == "mat":
        return read_mat_imu(p, **kw)
    if fmt == "rtklib-imu":
        return read_rtklib_imu(p, **kw)
    raise ValueError(f"unknown IMU format {fmt!r}; use one of {IMU_FORMATS}")


def estimate_time_offset(imu: ImuRecord, fixes: Fixes, *, window=120.0, min_speed=2.0,
                         search=1.0, step=0.005):
    """Estimate how late the IMU time stamps are relative to the fixes, from turns.

    The IMU vertical-axis rate (body z, RFU; the vehicle is roughly level) is
    cross-correlated with the course rate of the fix velocities (speed > ``min_speed``)
    in windows of ``window`` s; a straight line through the per-window lags gives an
    offset and a clock-rate error. Returns ``{"offset": lag at t_ref [s], "t_ref",
    "ppm": drift [1e-6 s/s], "windows": [(t_mid, lag, correlation), ...]}``; the
    corrected IMU times are ``t − (offset + ppm·1e-6·(t − t_ref))``.
    """
    if fixes.vel is None:
        raise ValueError("time-offset estimation needs fix velocities")
    sp = np.hypot(fixes.vel[:, 0], fixes.vel[:, 1])
    crs = np.unwrap(np.arctan2(fixes.vel[:, 0], fixes.vel[:, 1]))
    cr = -np.gradient(crs, fixes.t)                       # counter-clockwise rate
    cr[sp < min_speed] = 0.0
    wz = imu.dtheta[:, 2] / imu.dt
    lo = max(fixes.t[0], imu.t[0]) + search
    hi = min(fixes.t[-1], imu.t[-1]) - search
    if hi - lo < window / 2:
        raise ValueError("IMU and fixes overlap too little to estimate a time offset")
    nwin = max(1, int((hi - lo) // window))
    edges = np.linspace(lo, hi, nwin + 1)
    lags = np.arange(-search, search + step / 2, step)
    res = []
    for a, b in zip(edges[:-1], edges[1:]):
        grid = np.arange(a, b, 0.02)
        ref = np.interp(grid, fixes.t, cr)
        if np.std(ref) < 1e-3:
            continue
        c = np.array([np.corrcoef(np.interp(grid + o, imu.t, wz), ref)[0, 1] for o in lags])
        i = int(np.nanargmax(c))
        if 0 < i < len(c) - 1:                                # parabolic refinement
            den = c[i - 1] - 2 * c[i] + c[i + 1]
            sh = 0.5 * (c[i - 1] - c[i + 1]) / den if den < 0 else 0.0
        else:
            sh = 0.0
        res.append((0.5 * (a + b), float(lags[i] + sh * step), float(c[i])))
    if not res:
        raise ValueError("no turns found to estimate the IMU time offset")
    tm = np.array([r[0] for r in res])
    lg = np.array([r[1] for r in res])
    t_ref = float(tm.mean())
    if len(res) >= 2:
        b_, a_ = np.polyfit(tm - t_ref, lg, 1)
    else:
        b_, a_ = 0.0, float(lg[0])
    return {"offset": float(a_), "t_ref": t_ref, "ppm": float(b_ * 1e6), "windows": res}


def shift_imu_time(imu: ImuRecord, offset=0.0, ppm=0.0, t_ref=0.0) -> ImuRecord:
    """IMU record with times ``t − (offset + ppm·1e-6·(t − t_ref))`` (uniform grid kept)."""
    t = imu.t - (offset + ppm * 1e-6 * (imu.t - t_ref))
    dt = imu.dt * (1.0 - ppm * 1e-6)
    return ImuRecord(t, imu.dtheta, imu.dv, dt)
