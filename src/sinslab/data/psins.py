"""PSINS ``.imu`` text logs (Yan Gongmin's PSINS toolbox, "PSINS-format SIMU log").

Lines starting with ``%`` are comments. Then three header lines::

    pitch0 roll0 yaw0 (deg)  VE0 VN0 VU0 (m/s)     # "maybe inaccurate"; yaw CCW from north
    lat0 lon0 (deg)  h0 (m)  t0 (s)  dt (ms)  g (m/s^2)
    gf_x gf_y gf_z (arcsec/count)  af_x af_y af_z (ug·s/count)

and one line per sample of six integer counts: gyro x y z, accel x y z. Angle increments
are ``counts · gf`` arcsec; velocity increments ``counts · af · 1e-6 · g`` m/s with the
header's ``g`` (checked on ``lasergyro.imu``: the mean vertical increment then gives
‖f‖ = 9.7955 m/s², the local normal gravity at 34.246° N, 380 m; with 9.80665 it would
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
from sinslab.data.frames import sensor_to_body
from sinslab.data.increments import ImuData

__all__ = ["PsinsImu", "read_psins_imu", "load_psins"]


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


def _shown(line: str, limit: int = 60) -> str:
    """A line as quoted in a message: at most ``limit`` characters."""
    s = line.strip()
    return repr(s if len(s) <= limit else s[:limit] + "...")


def _is_binary(text: str) -> bool:
    """True for bytes that are not text (NUL, undecodable or many control characters)."""
    if "\x00" in text or "\ufffd" in text:
        return True
    ctrl = sum(1 for c in text if ord(c) < 32 and c not in "\t\r\n")
    return ctrl > 0.05 * max(1, len(text))


def _header_line(line, n, what, path, lineno):
    if _is_binary(line):
        raise ValueError(f"{path}: not a PSINS .imu log (binary data, not text)")
    try:
        vals = [float(x) for x in line.replace(",", " ").split()]
    except ValueError:
        raise ValueError(f"{path}:{lineno}: not a PSINS .imu log: cannot read the {what} header "
                         f"line {_shown(line)}") from None
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise ValueError(f"{path}:{lineno}: the {what} header line needs {n} finite numbers, "
                         f"got {_shown(line)}")
    return vals


def _bad_sample_line(path, first_lineno):
    """(line number, message) of the first sample line that is not six numbers."""
    with open(path, "r", encoding="utf-8", errors="replace") as fh:
        lines = fh.readlines()
    last = max((i for i, ln in enumerate(lines) if ln.strip()), default=-1)
    for i in range(first_lineno, len(lines)):
        s = lines[i].strip()
        if not s or s.startswith("%"):
            continue
        toks = s.split("%", 1)[0].replace(",", " ").split()
        try:
            [float(t) for t in toks]
            ok = len(toks) == 6
        except ValueError:
            ok = False
        if not ok:
            if _is_binary(s):
                return i + 1, "binary data, not sample text"
            why = f"expected 6 numbers (gyro x y z, accel x y z), got {_shown(s, 40)}"
            if i == last:
                why += "; the file looks truncated"
            return i + 1, why
    return None, "unreadable sample lines"


def read_psins_imu(path) -> PsinsImu:
    """Read a PSINS ``.imu`` text log (see the module notes). ValueError on a bad file."""
    from sinslab.data.textguard import check_text_tail

    path = Path(path)
    check_text_tail(path)
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
        except ValueError:
            bad, why = _bad_sample_line(path, lineno)
            raise ValueError(f"{path}:{bad}: {why}" if bad else f"{path}: {why}") from None
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


def load_psins(path, mount=None, frame="rfu", **extra) -> ImuData:
    """A PSINS ``.imu`` log as :class:`ImuData` (``mount``/``frame``: see
    :func:`~sinslab.data.frames.sensor_to_body`; the header is in ``meta["psins"]``)."""
    if extra:
        raise ValueError(f"options {sorted(extra)} do not apply to PSINS files")
    ps = read_psins_imu(path)
    imu = ps.imu
    if mount is not None or frame != "rfu":
        R = sensor_to_body(mount, frame)
        imu = ImuRecord(imu.t, imu.dtheta @ R.T, imu.dv @ R.T, imu.dt)
    return ImuData(imu, np.zeros((0, 2)), str(path), "psins", len(imu), 0.0, {"psins": ps})
