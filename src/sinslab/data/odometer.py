"""Wheel-speed (odometer) series: a column of the IMU table or a separate file with its
own time stamps.

A file is a CSV (comma or whitespace separated, ``#``/``%`` comments) with a header
naming a time column (``t``, ``time``, ``timestamp``, ``t_s``, ``time_s``, ``tow``) and a
speed column (``speed``, ``v``, ``odometer``, ``odo``, ``wheel_speed``, ``vel``), units
in brackets: ``t[s],speed[km/h]``. Units may be omitted for SI (s, m/s) or given by the
``units`` option. Speeds are the forward speed of the wheel point, finite and >= 0.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sinslab.core import units

__all__ = ["OdometerSeries", "read_odometer"]

_TIME = ("t", "time", "timestamp", "t_s", "time_s", "tow")
_SPEED = ("speed", "v", "odometer", "odo", "wheel_speed", "vel")
_HDR = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$")


@dataclass(frozen=True)
class OdometerSeries:
    """Wheel speed samples.

    Attributes
    ----------
    t : ndarray (J,)
        Time stamps [s], strictly increasing, on the clock of the IMU record.
    speed : ndarray (J,)
        Forward speed [m/s], >= 0.
    source : str
        ``FILE`` or ``FILE:COLUMN``, for messages.
    """

    t: np.ndarray
    speed: np.ndarray
    source: str

    def shifted(self, offset=0.0, ppm=0.0, t_ref=0.0):
        """Times corrected like :func:`sinslab.fusion.recorded.shift_imu_time`."""
        t = self.t - (offset + ppm * 1e-6 * (self.t - t_ref))
        return OdometerSeries(t, self.speed, self.source)


def _table(path):
    from sinslab.data.textguard import check_text_tail

    check_text_tail(path)
    with open(path, "r", encoding="utf-8", errors="replace") as fh:
        lines = fh.read().splitlines()
    body = [(i + 1, s) for i, s in enumerate(lines) if s.strip() and not s.lstrip().startswith(("#", "%"))]
    if len(body) < 2:
        raise ValueError(f"{path}: no header and samples")
    hline, hdr = body[0]
    delim = "," if "," in hdr else None
    cols = []
    for c in (hdr.split(delim) if delim else hdr.split()):
        m = _HDR.match(c.strip())
        if not m:
            raise ValueError(f"{path}:{hline}: cannot read the column name {c.strip()!r} "
                             "(expected NAME or NAME[unit], e.g. speed[km/h])")
        cols.append((m.group(1).lower(), (m.group(2) or "").strip() or None))
    return body, hline, delim, cols


def _column(body, delim, j, path):
    out = np.empty(len(body) - 1)
    for i, (ln, s) in enumerate(body[1:]):
        parts = s.split(delim) if delim else s.split()
        try:
            out[i] = float(parts[j])
        except (IndexError, ValueError):
            raise ValueError(f"{path}:{ln}: cannot read column {j + 1} as a number") from None
    return out


def _scale(unit, option, kind, what, where):
    u = option or unit
    if u is None:
        return 1.0
    try:
        return units.unit_scale(u, kind)
    except (ValueError, KeyError) as e:
        raise ValueError(f"{where}: unit {u!r} of the {what} is not a {kind} unit ({e})") from None


def read_odometer(spec, imu_path=None, *, speed_unit=None, time_unit=None) -> OdometerSeries:
    """Read wheel speeds from ``spec``: an existing file (own time column), or the name of
    a column of the IMU table ``imu_path`` (its time column).

    Parameters
    ----------
    spec : str or path
        ``FILE`` or ``COLUMN``.
    imu_path : str or path, optional
        The IMU table (CSV with a header) for a column name.
    speed_unit, time_unit : str, optional
        Units when the header does not give them (``km/h``, ``m/s``; ``s``, ``ms``);
        override the header.

    Raises
    ------
    ValueError
        Naming the file (and line): no such file or column, unknown units, non-finite or
        negative speeds, times not strictly increasing.
    """
    p = Path(str(spec))
    if p.is_dir():
        raise ValueError(f"{p}: is a directory, expected an odometer file or a column name")
    if p.is_file():
        path, col = p, None
    else:
        if imu_path is None or Path(str(spec)).suffix.lower() in (".csv", ".txt", ".dat"):
            raise ValueError(f"{spec}: no such odometer file")
        path, col = Path(imu_path), str(spec).strip().lower()
    try:
        body, hline, delim, cols = _table(path)
    except ValueError as e:
        if col is None:
            raise
        raise ValueError(f"{spec}: neither an odometer file nor a column of the IMU table ({e})") from None
    names = [c[0] for c in cols]
    if col is None:
        js = [names.index(n) for n in _SPEED if n in names]
        if not js:
            raise ValueError(f"{path}:{hline}: no speed column (one of {', '.join(_SPEED)}) in "
                             f"{', '.join(names)}")
        js = js[0]
        source = str(path)
    else:
        if col not in names:
            raise ValueError(f"{path}:{hline}: no column {spec!r} for the odometer (columns: "
                             f"{', '.join(names)}); give a file or a column of the IMU table")
        js = names.index(col)
        source = f"{path}:{spec}"
    jt = [names.index(n) for n in _TIME if n in names]
    if not jt:
        raise ValueError(f"{path}:{hline}: no time column (one of {', '.join(_TIME)})")
    jt = jt[0]
    st = _scale(cols[jt][1], time_unit, "time", "time column", f"{path}:{hline}")
    ss = _scale(cols[js][1], speed_unit, "velocity", f"speed column {names[js]!r}", f"{path}:{hline}")
    t = _column(body, delim, jt, path) * st
    v = _column(body, delim, js, path) * ss
    lines = [ln for ln, _ in body[1:]]
    bad = np.flatnonzero(~np.isfinite(v) | ~np.isfinite(t))
    if bad.size:
        raise ValueError(f"{path}:{lines[bad[0]]}: non-finite odometer time or speed")
    bad = np.flatnonzero(v < 0)
    if bad.size:
        raise ValueError(f"{path}:{lines[bad[0]]}: negative wheel speed {v[bad[0]] / ss:g} "
                         "(the odometer gives the speed, >= 0)")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise ValueError(f"{path}:{lines[bad[0] + 1]}: odometer times not strictly increasing")
    if t.size < 2:
        raise ValueError(f"{path}: fewer than 2 odometer samples")
    return OdometerSeries(t, v, source)
