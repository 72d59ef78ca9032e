"""The front door of :mod:`sinslab.data`: read any IMU or fix file by format name (or
from its suffix) and write the formats sinslab can write.

======================  ===========================================  ==================
format                  reader                                       writer
======================  ===========================================  ==================
IMU ``psins``           :func:`sinslab.data.psins.load_psins`        --
IMU ``csv``/``parquet`` :func:`sinslab.data.tables.read_table_imu`   :func:`write_imu`
IMU ``mat``             :func:`sinslab.data.matlab.read_mat_imu`     :func:`write_imu`
IMU ``rtklib-imu``      :func:`sinslab.data.rtklib.read_rtklib_imu`  --
fixes ``rtklib-pos``    :func:`sinslab.data.rtklib.read_rtklib_pos`  --
fixes ``csv``           :func:`sinslab.data.tables.read_fix_csv`     :func:`write_fixes`
fixes ``mat-avp``       :func:`sinslab.data.matlab.read_mat_fixes`   --
fixes ``two-geo``       :func:`sinslab.data.tables.read_two_geo_csv` --
======================  ===========================================  ==================
"""
from __future__ import annotations

from pathlib import Path

from sinslab.core.records import Fixes, ImuRecord
from sinslab.data import matlab, psins, rtklib, tables
from sinslab.data.increments import ImuData

__all__ = ["IMU_FORMATS", "FIX_FORMATS", "guess_imu_format", "load_imu", "read_imu",
           "read_fixes", "write_imu", "write_fixes"]

#: IMU formats understood by :func:`load_imu` (``--format``).
IMU_FORMATS = ("psins", "csv", "parquet", "mat", "rtklib-imu")
#: Fix/solution formats understood by :func:`read_fixes`.
FIX_FORMATS = ("rtklib-pos", "csv", "mat-avp", "two-geo", "ubx")


def guess_imu_format(path) -> str:
    """IMU format from the file name: ``.imu`` psins, ``.parquet`` parquet, ``.mat`` mat, a
    file with an RTKLIB ``.tag`` next to it rtklib-imu, else csv."""
    p = Path(path)
    suf = p.suffix.lower()
    return ("psins" if suf == ".imu" else "parquet" if suf in (".parquet", ".pq") else
            "mat" if suf == ".mat" else "rtklib-imu" if Path(str(p) + ".tag").exists() else "csv")


def _existing_file(path) -> Path:
    """``path`` as a Path, or one clear error when it is missing or not a regular file."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    if not p.is_file():
        raise ValueError(f"{p}: is a directory, not a file" if p.is_dir() else f"{p}: not a regular file")
    return p


def load_imu(path, fmt=None, **kw) -> ImuData:
    """Read any supported IMU file into :class:`~sinslab.data.increments.ImuData` (``fmt``
    from :data:`IMU_FORMATS`, default from the suffix: ``.imu`` psins, ``.parquet``
    parquet, ``.mat`` mat, a ``.csv`` with a ``.tag`` next to it rtklib-imu, else csv).
    Keywords go to the reader."""
    p = _existing_file(path)
    fmt = fmt or guess_imu_format(p)
    if fmt == "psins":
        return psins.load_psins(p, **kw)
    if fmt in ("csv", "parquet"):
        return tables.read_table_imu(p, **kw)
    if fmt == "mat":
        return matlab.read_mat_imu(p, **kw)
    if fmt == "rtklib-imu":
        return rtklib.read_rtklib_imu(p, **kw)
    raise ValueError(f"unknown IMU format {fmt!r}; use one of {IMU_FORMATS}")


def read_imu(path, fmt=None, **kw):
    """Read an IMU file with :func:`load_imu` (any of :data:`IMU_FORMATS`; default from the
    suffix). Returns ``(ImuRecord, PsinsImu | None)``: the PSINS header (attitude, position,
    scale) when the file is a PSINS log, for callers that use it."""
    d = load_imu(path, fmt, **kw)
    return d.imu, d.meta.get("psins")


def read_fixes(path, fmt=None, **kw) -> Fixes:
    """Read position(/velocity) fixes: ``rtklib-pos`` (``.pos``), ``csv`` (columns ``t[s],
    lat[deg], lon[deg]`` + optional ``h[m]``, ``t_arrive[s]``, ``sd_n sd_e sd_u``, ``ve vn
    vu``, ``sd_ve ..``), ``mat-avp`` (a PSINS avp matrix: positions and velocities, σ from
    ``sigma``/``sigma_vel`` keywords, default 1 m / 0.1 m/s) or ``two-geo`` (a recorded
    double-star fix list, :func:`sinslab.data.tables.read_two_geo_csv`) or ``ubx`` (the
    receiver's NAV-PVT solutions in a u-blox log, :func:`sinslab.data.gnss.read_ubx_pvt`;
    ``.ubx``). ``velocity_lag`` [s]
    (any format): the velocities describe the motion that long before their stamps
    (:meth:`sinslab.core.records.Fixes.with_velocity_lag`)."""
    p = _existing_file(path)
    fmt = fmt or {".pos": "rtklib-pos", ".mat": "mat-avp", ".ubx": "ubx"}.get(p.suffix.lower(), "csv")
    lag = kw.pop("velocity_lag", 0.0)
    if fmt == "rtklib-pos":
        return rtklib.read_rtklib_pos(p, velocity_lag=lag, **kw)
    if fmt == "csv":
        fx = tables.read_fix_csv(p)
    elif fmt == "mat-avp":
        fx = matlab.read_mat_fixes(p, kw.get("var"), kw.get("sigma", 1.0), kw.get("sigma_vel", 0.1))
    elif fmt == "two-geo":
        fx = tables.read_two_geo_csv(p)
    elif fmt == "ubx":
        from sinslab.data.gnss import read_ubx_pvt
        fx = read_ubx_pvt(p)
    else:
        raise ValueError(f"unknown fix format {fmt!r}; use one of {FIX_FORMATS}")
    return fx.with_velocity_lag(lag)


def write_imu(path, imu: ImuRecord, fmt=None):
    """Write increments: ``csv`` (header ``t[s],dtheta_x[rad],...,dv_z[m/s]``), ``parquet``
    (same columns) or ``mat`` (variable ``imu`` = PSINS layout N×7 and ``dt``); the format
    defaults from the suffix. Atomic (temporary name + rename). Returns the path."""
    path = Path(path)
    fmt = fmt or {".parquet": "parquet", ".pq": "parquet", ".mat": "mat"}.get(path.suffix.lower(), "csv")
    if fmt in ("csv", "parquet"):
        return tables.write_table_imu(path, imu, fmt)
    if fmt == "mat":
        return matlab.write_mat_imu(path, imu)
    raise ValueError(f"unknown output format {fmt!r}; use csv, parquet or mat")


def write_fixes(path, fx: Fixes):
    """Write fixes as CSV (the columns of :func:`read_fixes`' ``csv`` format), atomically."""
    return tables.write_fix_csv(path, fx)
