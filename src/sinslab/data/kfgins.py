"""The text and binary files of KF-GINS and OB_GINS (i2Nav, Wuhan University) and of the
data sets published in their layout, as their READMEs define them.

==============  ======================================================================
file            columns
==============  ======================================================================
IMU text        seconds of GPS week; Δθ x y z (rad); Δv x y z (m/s); OB_GINS: an 8th
                column, the odometer speed (m/s). Axes forward-right-down.
IMU ``.bin``    the same 7 values as little-endian doubles, record after record
GNSS position   seconds of week; latitude, longitude (deg); ellipsoidal height (m); σ
                north, east, down (m). The 13-column form KF-GINS also reads holds the
                velocity north, east, down (m/s) after the height and its σ after the
                position σ.
truth ``.nav``  GPS week; seconds of week; latitude, longitude (deg); height (m);
                velocity north, east, down (m/s); roll, pitch, yaw (deg, yaw clockwise
                from north)
==============  ======================================================================

Files carry no header; :func:`sniff` tells them from other tables by what they hold (the
number of columns, and values of the right size), so that ``load_imu``/``read_fixes``
choose these readers without a format name.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sinslab.core import attitude as _att
from sinslab.core.records import Fixes, NavSeries
from sinslab.data.frames import sensor_to_body
from sinslab.data.increments import ImuData, check_stamps, uniform_increments

__all__ = ["sniff", "read_kfgins_imu", "read_kfgins_gnss", "read_kfgins_nav", "write_kfgins_imu",
           "write_kfgins_gnss", "write_kfgins_nav"]

_IMU_MAP = ("t=1[s],dtheta_x=2[rad],dtheta_y=3[rad],dtheta_z=4[rad],"
            "dv_x=5[m/s],dv_y=6[m/s],dv_z=7[m/s]")


def _first_rows(path, n=3):
    """The first ``n`` non-comment lines of a text file as lists of floats, or None when a
    line is not all numbers (or the file is not text)."""
    rows = []
    try:
        with open(path, "rb") as fh:
            head = fh.read(1 << 14)
    except OSError:
        return None
    if b"\x00" in head:
        return None
    try:
        text = head.decode("utf-8", errors="strict")
    except UnicodeDecodeError:
        return None
    lines = text.splitlines()
    if len(head) == 1 << 14 and lines:
        lines = lines[:-1]                       # the last line may be cut by the read
    for s in lines:
        s = s.strip()
        if not s or s.startswith(("#", "%")):
            continue
        try:
            rows.append([float(x) for x in s.replace(",", " ").split()])
        except ValueError:
            return None
        if len(rows) == n:
            break
    return rows or None


def _binary_rows(path, ncol=7, n=3):
    p = Path(path)
    size = p.stat().st_size
    if size == 0 or size % (8 * ncol):
        return None
    a = np.fromfile(p, dtype="<f8", count=ncol * n)
    return a.reshape(-1, ncol)


def _imu_like(rows):
    a = np.asarray(rows, dtype=float)
    if a.ndim != 2 or a.shape[1] not in (7, 8) or not np.all(np.isfinite(a)):
        return False
    d = np.diff(a[:, 0])
    return (a.shape[0] < 2 or bool(np.all((d > 0) & (d < 1.0)))) and bool(
        np.all(np.abs(a[:, 1:4]) < 1.0) and np.all(np.abs(a[:, 4:7]) < 50.0))


def sniff(path) -> str | None:
    """What a headerless file holds, from its first rows: ``"kf-gins-imu"`` (7 or 8
    columns, increasing seconds less than 1 s apart, increments of the right size; text or
    ``.bin`` doubles), ``"kf-gins-gnss"`` (7 or 13 columns, latitude and longitude in
    degrees, σ > 0), ``"kf-gins-nav"`` (11 columns, a week number first), or None."""
    p = Path(path)
    if p.suffix.lower() == ".bin":
        b = _binary_rows(p)
        return "kf-gins-imu" if b is not None and _imu_like(b) else None
    rows = _first_rows(p)
    if not rows or len({len(r) for r in rows}) != 1:
        return None
    a = np.asarray(rows, dtype=float)
    w = a.shape[1]
    if w in (7, 8) and _imu_like(a) and (w == 8 or not _gnss_like(a)):
        return "kf-gins-imu"
    if w in (7, 13) and _gnss_like(a):
        return "kf-gins-gnss"
    if w == 11 and np.all(a[:, 0] == np.round(a[:, 0])) and np.all(np.abs(a[:, 2]) <= 90) \
            and np.all(np.abs(a[:, 3]) <= 360):
        return "kf-gins-nav"
    return None


def _gnss_like(a):
    w = a.shape[1]
    s0 = 4 if w == 7 else 7
    return bool(np.all(np.abs(a[:, 1]) <= 90) and np.all(np.abs(a[:, 2]) <= 360)
                and np.all(np.abs(a[:, 1:3]) > 1.0)           # degrees, not radians or increments
                and np.all(a[:, s0:s0 + 3] > 0))


def read_kfgins_imu(path, *, frame="frd", mount=None, max_gap=1.0, allow_gaps=False) -> ImuData:
    """Read a KF-GINS / OB_GINS IMU file (text, 7 or 8 columns, or ``.bin`` doubles; see
    the module notes). Axes forward-right-down unless ``frame``/``mount`` say otherwise.
    OB_GINS's 8th column (odometer speed, m/s) is returned in ``meta["odometer"] =
    (t, speed)``."""
    p = Path(path)
    if p.suffix.lower() == ".bin":
        size = p.stat().st_size
        if size == 0 or size % 56:
            raise ValueError(f"{p}: {size} bytes is not a whole number of 7-double records "
                             "(56 bytes each); not a KF-GINS binary IMU file")
        a = np.fromfile(p, dtype="<f8").reshape(-1, 7)
        bad = ~np.isfinite(a)
        if bad.any():
            raise ValueError(f"{p}: record {int(np.argwhere(bad)[0][0]) + 1}: NaN/inf value")
        lines = [f"record {i + 1}" for i in range(a.shape[0])]
        R = sensor_to_body(mount, frame)
        imu, gaps, jit = uniform_increments(a[:, 0], a[:, 1:4] @ R.T, a[:, 4:7] @ R.T, path=p,
                                            lines=lines, max_gap=max_gap, allow_gaps=allow_gaps)
        return ImuData(imu, gaps, str(p), "kf-gins", a.shape[0], jit, {"layout": "binary"})
    from sinslab.data.tables import read_table_imu
    rows = _first_rows(p, 1)
    if not rows or len(rows[0]) not in (7, 8):
        raise ValueError(f"{p}: a KF-GINS IMU text file has 7 columns (8 with an odometer); "
                         f"the first line has {len(rows[0]) if rows else 'no'} numbers")
    d = read_table_imu(p, columns=_IMU_MAP, frame=frame, mount=mount, max_gap=max_gap,
                       allow_gaps=allow_gaps)
    meta = {"layout": "text", "columns": len(rows[0])}
    if len(rows[0]) == 8:
        from sinslab.data.tables import _TextSource
        src = _TextSource(p, headerless=True)
        tv = src.fetch([0, 7])
        meta["odometer"] = (tv[:, 0].copy(), tv[:, 1].copy())
    return ImuData(d.imu, d.gaps, str(p), "kf-gins", d.n_raw, d.jitter, meta)


def _read_numeric(path, widths, what):
    p = Path(path)
    rows, lines = [], []
    with open(p, encoding="utf-8", errors="replace") as fh:
        for i, s in enumerate(fh, 1):
            s = s.strip()
            if not s or s.startswith(("#", "%")):
                continue
            try:
                v = [float(x) for x in s.replace(",", " ").split()]
            except ValueError:
                raise ValueError(f"{p}:{i}: not a number in a {what} line ({s[:60]!r})") from None
            if len(v) not in widths:
                raise ValueError(f"{p}:{i}: {len(v)} columns; a {what} line has "
                                 f"{' or '.join(map(str, widths))}")
            if rows and len(v) != len(rows[0]):
                raise ValueError(f"{p}:{i}: {len(v)} columns where the first line has {len(rows[0])}")
            if not all(math.isfinite(x) for x in v):
                raise ValueError(f"{p}:{i}: NaN/inf value")
            rows.append(v)
            lines.append(i)
    if not rows:
        raise ValueError(f"{p}: empty file (no {what} lines)")
    return np.asarray(rows, dtype=float), lines


def read_kfgins_gnss(path):
    """Read a KF-GINS / OB_GINS GNSS position file (7 columns, or 13 with the NED velocity
    and its σ). Returns ``(Fixes, meta)``: σ from the file (north, east, down → north,
    east, up), velocity turned to ENU."""
    p = Path(path)
    a, lines = _read_numeric(p, (7, 13), "KF-GINS GNSS")
    t = a[:, 0]
    check_stamps(t, p, lines)
    if np.any(np.abs(a[:, 1]) > 90) or np.any(np.abs(a[:, 2]) > 360):
        i = int(np.flatnonzero((np.abs(a[:, 1]) > 90) | (np.abs(a[:, 2]) > 360))[0])
        raise ValueError(f"{p}:{lines[i]}: latitude/longitude out of range (degrees expected)")
    n = t.size
    s0 = 4 if a.shape[1] == 7 else 7
    sig = a[:, s0:s0 + 3]
    if np.any(sig <= 0):
        i = int(np.flatnonzero(np.any(sig <= 0, axis=1))[0])
        raise ValueError(f"{p}:{lines[i]}: position σ must be > 0")
    vel = sv = None
    if a.shape[1] == 13:
        vel = _att.vec_ned_to_enu(a[:, 4:7])
        sv = np.abs(_att.vec_ned_to_enu(a[:, 10:13]))
        sv = np.where(sv > 0, sv, 0.1)
    fx = Fixes(t, np.radians(a[:, 1]), np.radians(a[:, 2]), a[:, 3], sig, vel, sv, np.zeros(n, int), str(p))
    return fx, {"format": "kf-gins", "columns": a.shape[1], "sigma_source": f"{p.name} (per line)",
                "velocity_frame": "NED" if vel is not None else None}


def read_kfgins_nav(path) -> NavSeries:
    """Read a KF-GINS / OB_GINS navigation result or ground truth (``.nav``, 11 columns) as a
    :class:`NavSeries` on its seconds of week (ENU velocity, sinslab attitude)."""
    p = Path(path)
    a, lines = _read_numeric(p, (11,), "KF-GINS .nav")
    check_stamps(a[:, 1], p, lines)
    att = _att.euler_from_ned(np.radians(a[:, 8:11]))
    return NavSeries(a[:, 1], np.radians(a[:, 2]), np.radians(a[:, 3]), a[:, 4],
                     _att.vec_ned_to_enu(a[:, 5:8]), att)


def write_kfgins_imu(path, imu, binary=None):
    """Write increments in the KF-GINS layout (text, or ``.bin`` doubles when ``binary`` or
    the suffix says so), axes forward-right-down. Atomic. Returns the path."""
    from sinslab.core.atomic import atomic_path
    p = Path(path)
    R = sensor_to_body(None, "frd").T                      # RFU -> FRD
    a = np.column_stack([imu.t, imu.dtheta @ R.T, imu.dv @ R.T])
    binary = p.suffix.lower() == ".bin" if binary is None else binary
    with atomic_path(p) as tmp:
        if binary:
            a.astype("<f8").tofile(tmp)
        else:
            np.savetxt(tmp, a, fmt="%.6f" + " %.17g" * 6)
    return p


def write_kfgins_gnss(path, fx: Fixes):
    """Write fixes as a KF-GINS GNSS file (7 columns; 13 with velocities). Atomic."""
    from sinslab.core.atomic import atomic_path
    p = Path(path)
    cols = [fx.t, np.degrees(fx.lat), np.degrees(fx.lon), fx.h]
    if fx.vel is not None:
        cols += list(_att.vec_enu_to_ned(fx.vel).T)
    cols += list(fx.sigma.T)
    if fx.vel is not None:
        cols += list(_att.vec_enu_to_ned(fx.sigma_vel).T)
    with atomic_path(p) as tmp:
        np.savetxt(tmp, np.column_stack(cols), fmt="%.3f %.10f %.10f" + " %.4f" * (len(cols) - 3))
    return p


def write_kfgins_nav(path, s: NavSeries, week=0):
    """Write a :class:`NavSeries` as a KF-GINS ``.nav`` file. Atomic."""
    from sinslab.core.atomic import atomic_path
    p = Path(path)
    rpy = np.degrees(_att.euler_to_ned(s.att))
    a = np.column_stack([np.full(len(s), week), s.t, np.degrees(s.lat), np.degrees(s.lon), s.h,
                         _att.vec_enu_to_ned(s.vel), rpy])
    with atomic_path(p) as tmp:
        np.savetxt(tmp, a, fmt="%d %.3f %.10f %.10f %.4f" + " %.6f" * 6)
    return p
