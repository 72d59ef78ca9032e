"""RTKLIB files: ``.pos`` solutions (fixes), ``.tag`` time-tag files, and the IMU CSV
log RTKLIB writes with a tag (the ``rtklib-drive`` data set)."""
from __future__ import annotations

import math
import struct
import warnings
from pathlib import Path

import numpy as np

from sinslab.core import units
from sinslab.core.records import Fixes
from sinslab.data.frames import sensor_to_body
from sinslab.data.increments import ImuData, check_stamps, rates_to_increments, uniform_increments
from sinslab.data.textguard import check_text_tail

__all__ = ["RTKLIB_DRIVE", "read_rtklib_pos", "read_rtklib_tag", "read_rtklib_imu"]

#: checked against the data in tests/data/test_formats.py: sensor axes x back, y right, z up
#: (the config's 180° roll + 180° yaw) plus a residual (roll 0, pitch −6.79°, yaw 5.35°)
#: relative to the car's forward-right-down frame; antenna 5 cm left of the IMU at the
#: same height; logging delay −0.125 s.
RTKLIB_DRIVE = {"mount_rpy_frd_deg": (180.0, -6.79, 185.35), "lever_arm_rfu_m": (-0.05, 0.0, 0.0),
                "delay_s": -0.125}


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
    the 4 Hz epoch — see tests/data/test_formats.py); they are re-sampled to the position times
    (linear interpolation, the last one held).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    hdr = None
    t, vals, lines = [], [], []
    ncol = None
    check_text_tail(path)
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
    check_stamps(t, path, lines)
    v = np.array(vals)
    if np.any(np.abs(v[:, 0]) > 90):
        i = int(np.argmax(np.abs(v[:, 0]) > 90))
        raise ValueError(f"{path}:{lines[i]}: latitude {v[i, 0]} beyond ±90 deg")
    sig = v[:, 5:8].copy()
    sig[sig <= 0] = 0.01
    vel = svel = None
    if ncol >= 16:
        vel = np.stack([v[:, 14], v[:, 13], v[:, 15]], -1)       # vn ve vu -> ENU
        if ncol >= 19:
            svel = np.stack([v[:, 17], v[:, 16], v[:, 18]], -1)
            svel[svel <= 0] = 0.05
        else:
            svel = np.full_like(vel, 0.05)
    fx = Fixes(t, np.radians(v[:, 0]), np.radians(v[:, 1]), v[:, 2], sig, vel, svel,
               v[:, 3].astype(int), str(path))
    if velocity_lag:
        fx = fx.with_velocity_lag(velocity_lag)        # over the whole record, before selection
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
    GPST, 18 s off as UTC — see tests/data/test_formats.py). Returns ``{"start", "end", "ticks",
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
    _tick0, sec = struct.unpack("<II", b[60:68])
    frac = struct.unpack("<d", b[68:76])[0]
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
    over the record instead of 0.06 -> 0.11 s; tests/data/test_formats.py). Use
    :func:`sinslab.fusion.recorded.estimate_time_offset` / ``shift_imu_time`` to synchronise. The time base is
    the tag's (GPST seconds, see :func:`read_rtklib_tag`).
    ``mount``/``frame``: sensor → vehicle axes (:func:`sinslab.data.frames.sensor_to_body`; the sensor axes
    need it on rtklib-drive, see :data:`RTKLIB_DRIVE`).
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    tagp = Path(tag) if tag is not None else Path(str(path) + ".tag")
    if not tagp.exists():
        raise ValueError(f"{path}: no time-tag file {tagp} (RTKLIB writes NAME.tag next to the log)")
    tg = read_rtklib_tag(tagp)
    check_text_tail(path)
    with open(path, "r", encoding="utf-8", errors="replace") as fh:
        text = fh.read().splitlines()
    rows = [(i + 1, s) for i, s in enumerate(text) if s.strip()]
    if not rows:
        raise ValueError(f"{path}: empty file")
    # a record cut by the start or the end of logging (fewer fields) is dropped and
    # counted; anywhere else a short record is an error below
    cut = [rows[k][0] for k in sorted({0, len(rows) - 1}) if len(rows[k][1].split(",")) < 7]
    rows = [r for r in rows if r[0] not in cut]
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
    check_stamps(tick, path, lines)
    sec = tick - tick[0]
    span = tg["end"] - tg["start"]
    scale = span / sec[-1] if (stretch and sec[-1] > 0 and span > 0) else 1.0
    t = tg["start"] + sec * scale + float(delay)
    R = sensor_to_body(mount, frame)
    w = d[:, 3:6] * units.unit_scale(gyro_unit, "angular_rate") @ R.T
    f = d[:, 0:3] * units.unit_scale(accel_unit, "acceleration") @ R.T
    dt_nom = float(np.median(np.diff(t)))
    dth, dvv = rates_to_increments(t, w, f, dt_nom)
    imu, gaps, jit = uniform_increments(t, dth, dvv, path=path, lines=lines, dt=None,
                                        max_gap=max_gap, allow_gaps=allow_gaps)
    return ImuData(imu, gaps, str(path), "rtklib-imu", t.size, jit,
                   {"tag_start": tg["start"], "tag_end": tg["end"], "tick_scale": scale,
                    "delay": float(delay), "mount": R, "truncated_lines": cut})
