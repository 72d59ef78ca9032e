"""Tables with declared units: IMU samples in CSV or Parquet (rates or increments, units
in the column header, ``gx[deg/s]``), fixes in CSV (``t[s], lat[deg], lon[deg], h[m], ...``),
the two-GEO fix list of recorded double-star receivers, and the writers of both tables."""
from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from sinslab.core import units
from sinslab.core.atomic import atomic_path
from sinslab.core.records import Fixes, ImuRecord
from sinslab.data.frames import mount_matrix
from sinslab.data.increments import ImuData, check_stamps, rates_to_increments, uniform_increments, where

__all__ = ["read_table_imu", "write_table_imu", "read_fix_csv", "write_fix_csv",
           "read_two_geo_csv", "TWO_GEO_COLUMNS"]


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
_HDR = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$")


def _parse_header(cols, path, line):
    out = []
    for c in cols:
        m = _HDR.match(str(c))
        if not m:
            raise ValueError(f"{where(path, line)}: cannot read the column name {str(c)!r} "
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
    raise ValueError(f"{where(path, line)}: column {name!r} has unit {unit!r}, not a {sensor} unit "
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
    see :func:`sinslab.data.frames.mount_matrix`. Raises ValueError naming the file and line of the problem.
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
            raise ValueError(f"{where(path, hline)}: header only, no samples")
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
        raise ValueError(f"{where(path, hline)}: duplicated column names {names}")
    ti = next((names.index(n) for n in _TIME_NAMES if n in names), None)
    if ti is None:
        raise ValueError(f"{where(path, hline)}: no time column (t, time or timestamp) in {header}")
    g_rate, a_rate = _find_cols(names, "gyro_rate"), _find_cols(names, "accel_rate")
    g_inc, a_inc = _find_cols(names, "gyro_inc"), _find_cols(names, "accel_inc")
    gi = g_inc or g_rate
    ai = a_inc or a_rate
    if gi is None or ai is None:
        raise ValueError(f"{where(path, hline)}: wrong columns {header}: need a time column and gyro "
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
                    raise ValueError(f"{where(path, hline)}: column {nm!r} has no unit; declare it "
                                     f"in the header ({nm}[deg/s], {nm}[g], ...) or give the "
                                     f"{sensor} unit as an option")
            s, k = _unit_kind(un, sensor, path, hline, nm)
            scales.append(s)
            kinds.append(k)
            us.append(un)
        if len(set(us)) > 1 or len(set(kinds)) > 1:
            raise ValueError(f"{where(path, hline)}: mixed units in the {sensor} columns "
                             f"({', '.join(f'{cols[i][0]}[{u}]' for i, u in zip(idx, us))}); "
                             "use one unit for all three axes")
        return scales[0], kinds[0], us[0]

    gs, gk, gu = col_scale(gi, "gyro", gyro_unit)
    as_, ak, au = col_scale(ai, "accel", accel_unit)
    if gk != ak:
        raise ValueError(f"{where(path, hline)}: mixed units: gyro columns are "
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
        raise ValueError(f"{where(path, where_line(r))}: NaN/inf value in the samples")
    t = data[:, ti] * ts
    R = mount_matrix(mount, frame)
    g = data[:, gi] * gs @ R.T
    a = data[:, ai] * as_ @ R.T
    check_stamps(t, path, lines)
    if gk == "rate":
        dt_nom = float(np.median(np.diff(t))) if t.size > 1 else float("nan")
        if t.size < 2:
            raise ValueError(f"{path}: needs at least 2 samples for rates")
        d = np.diff(t)
        if np.all(np.abs(d - dt_nom) <= 1e-4 * dt_nom):
            imu = ImuRecord.from_rates(t, g, a)
            return ImuData(imu, np.zeros((0, 2)), str(path), "parquet" if is_parquet else "csv",
                           t.size, 0.0, {"units": {"gyro": gu, "accel": au, "time": tu}})
        dth, dvv = rates_to_increments(t, g, a, dt_nom)
    else:
        dth, dvv = g, a
    imu, gaps, jit = uniform_increments(t, dth, dvv, path=path, lines=lines,
                                        max_gap=max_gap, allow_gaps=allow_gaps)
    return ImuData(imu, gaps, str(path), "parquet" if is_parquet else "csv", t.size, jit,
                   {"units": {"gyro": gu, "accel": au, "time": tu}})


# ---------------------------------------------------------------------------- writers ---
_INC_COLS = ["t[s]", "dtheta_x[rad]", "dtheta_y[rad]", "dtheta_z[rad]",
             "dv_x[m/s]", "dv_y[m/s]", "dv_z[m/s]"]


def write_table_imu(path, imu: ImuRecord, fmt="csv"):
    """Write increments as a ``csv`` (header ``t[s],dtheta_x[rad],...,dv_z[m/s]``) or
    ``parquet`` table (same columns), atomically. Returns the path."""
    path = Path(path)
    a = np.column_stack([imu.t, imu.dtheta, imu.dv])
    if fmt == "csv":
        with atomic_path(path) as tmp:
            np.savetxt(tmp, a, delimiter=",", header=",".join(_INC_COLS), comments="", fmt="%.17g")
    elif fmt == "parquet":
        import pandas as pd
        with atomic_path(path) as tmp:
            pd.DataFrame(a, columns=_INC_COLS).to_parquet(tmp, index=False)
    else:
        raise ValueError(f"unknown table format {fmt!r}; use csv or parquet")
    return path


# ------------------------------------------------------------------------------ fixes ---
_FIX_COLS = ["t[s]", "lat[deg]", "lon[deg]", "h[m]", "sd_n[m]", "sd_e[m]", "sd_u[m]"]
_FIX_VCOLS = ["ve[m/s]", "vn[m/s]", "vu[m/s]", "sd_ve[m/s]", "sd_vn[m/s]", "sd_vu[m/s]"]


def write_fix_csv(path, fx: Fixes):
    """Write fixes as CSV (the columns :func:`read_fix_csv` reads), atomically: ``h`` and
    ``sd_u`` are left out for horizontal fixes (all heights NaN), ``t_arrive`` is written
    when any fix arrives after its validity time."""
    two_d = bool(np.all(np.isnan(fx.h)))
    cols, names = [fx.t], ["t[s]"]
    if np.any(fx.t_arrive != fx.t):
        cols.append(fx.t_arrive)
        names.append("t_arrive[s]")
    cols += [np.degrees(fx.lat), np.degrees(fx.lon)]
    names += ["lat[deg]", "lon[deg]"]
    if not two_d:
        cols.append(fx.h)
        names.append("h[m]")
    cols += list(fx.sigma.T[:2 if two_d else 3])
    names += ["sd_n[m]", "sd_e[m]"] + ([] if two_d else ["sd_u[m]"])
    if fx.vel is not None:
        cols += [*fx.vel.T, *fx.sigma_vel.T]
        names += _FIX_VCOLS
    with atomic_path(Path(path)) as tmp:
        np.savetxt(tmp, np.column_stack(cols), delimiter=",", header=",".join(names), comments="",
                   fmt="%.12g")
    return Path(path)


def read_fix_csv(path) -> Fixes:
    """Read fixes from CSV: columns ``t[s], lat[deg], lon[deg]`` and optional ``h[m]``
    (without it: horizontal fixes, NaN height), ``t_arrive[s]``, ``sd_n sd_e sd_u`` [m]
    (default 1 m), ``ve vn vu`` [m/s] with ``sd_ve sd_vn sd_vu`` (default 0.1 m/s); units
    may be given in the header."""
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
    need = ["t", "lat", "lon"]
    for n in need:
        if n not in names:
            raise ValueError(f"{path}:1: no column {n!r} (need t, lat[deg], lon[deg]; optional "
                             "h[m], t_arrive[s], sd_n sd_e sd_u [m], ve vn vu [m/s], sd_ve sd_vn sd_vu)")
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
    check_stamps(t, path, list(range(2, len(t) + 2)))
    lat, lon = col("lat", "angle", "deg"), col("lon", "angle", "deg")
    two_d = "h" not in names
    h = np.full(t.size, np.nan) if two_d else col("h", "length", "m")
    sig = np.stack([col(n, "length", "m") if n in names else
                    np.full(t.size, np.nan if (two_d and n == "sd_u") else 1.0)
                    for n in ("sd_n", "sd_e", "sd_u")], -1)
    t_arr = col("t_arrive", "time", "s") if "t_arrive" in names else None
    vel = svel = None
    if all(n in names for n in ("ve", "vn", "vu")):
        vel = np.stack([col(n, "velocity", "m/s") for n in ("ve", "vn", "vu")], -1)
        svel = np.stack([col(n, "velocity", "m/s") if n in names else np.full(t.size, 0.1)
                         for n in ("sd_ve", "sd_vn", "sd_vu")], -1)
    return Fixes(t, lat, lon, h, sig, vel, svel, np.zeros(t.size, int), str(path), t_arr)


#: Columns of a recorded two-GEO fix list (:func:`read_two_geo_csv`); ``t_arrive_s`` is
#: optional (default: no lag).
TWO_GEO_COLUMNS = ("t_valid_s", "t_arrive_s", "lat_deg", "lon_deg", "sigma_ns_m", "sigma_ew_m")


def read_two_geo_csv(path) -> Fixes:
    """Read recorded two-GEO (double-star) fixes from a CSV file whose header line names
    the columns :data:`TWO_GEO_COLUMNS` (any order, extra columns ignored): validity time
    [s] on the IMU's time base, reception time [s], latitude and longitude [deg], σ
    north/east [m]. Returns horizontal :class:`~sinslab.core.records.Fixes` (NaN height)."""
    import csv

    with open(path, newline="") as fh:
        rows = list(csv.reader(line for line in fh if line.strip() and not line.startswith("#")))
    if not rows:
        raise ValueError(f"fix file {path}: empty")
    head = [h.strip() for h in rows[0]]
    need = [c for c in TWO_GEO_COLUMNS if c != "t_arrive_s"]
    miss = [c for c in need if c not in head]
    if miss:
        raise ValueError(f"fix file {path}: missing column(s) {', '.join(miss)} "
                         f"(header: {', '.join(head)})")
    body = rows[1:]
    if not body:
        raise ValueError(f"fix file {path}: no fixes after the header")
    try:
        data = np.array([[float(x) for x in r] for r in body])
    except ValueError as e:
        raise ValueError(f"fix file {path}: {e}") from None
    if data.ndim != 2 or data.shape[1] != len(head):
        raise ValueError(f"fix file {path}: every line needs {len(head)} values")
    col = {h: data[:, i] for i, h in enumerate(head)}
    tv = col["t_valid_s"]
    nan = np.full(tv.size, np.nan)
    return Fixes(tv, np.radians(col["lat_deg"]), np.radians(col["lon_deg"]), nan,
                 np.stack([col["sigma_ns_m"], col["sigma_ew_m"], nan], -1),
                 path=str(path), t_arrive=col.get("t_arrive_s", tv))
