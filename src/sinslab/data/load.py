"""The front door of :mod:`sinslab.data`: read any IMU or fix file by format name (or
from its suffix) and write the formats sinslab can write.

=======================  ==============================================  ==============================
format                   reader                                          writer
=======================  ==============================================  ==============================
IMU ``psins``            :func:`sinslab.data.psins.load_psins`           --
IMU ``csv``/``parquet``  :func:`sinslab.data.tables.read_table_imu`      :func:`write_imu`
IMU ``mat``              :func:`sinslab.data.matlab.read_mat_imu`        :func:`write_imu`
IMU ``navego``           :func:`sinslab.data.navego.read_navego_imu`     --
IMU ``kf-gins``          :func:`sinslab.data.kfgins.read_kfgins_imu`     ``kfgins.write_kfgins_imu``
IMU ``rosbag``           :func:`sinslab.data.rosbag.read_rosbag_imu`     --
IMU ``rtklib-imu``       :func:`sinslab.data.rtklib.read_rtklib_imu`     --
fixes ``rtklib-pos``     :func:`sinslab.data.rtklib.read_rtklib_pos`     --
fixes ``csv``            :func:`sinslab.data.tables.read_fix_csv`        :func:`write_fixes`
fixes ``mat-avp``        :func:`sinslab.data.matlab.read_mat_fixes`      --
fixes ``navego``         :func:`sinslab.data.navego.read_navego_gnss`    --
fixes ``kf-gins``        :func:`sinslab.data.kfgins.read_kfgins_gnss`    ``kfgins.write_kfgins_gnss``
fixes ``rosbag``         :func:`sinslab.data.rosbag.read_rosbag_fixes`   --
fixes ``two-geo``        :func:`sinslab.data.tables.read_two_geo_csv`    --
truth                    :func:`read_truth`                              --
=======================  ==============================================  ==============================

The truth (a reference solution) comes from a KF-GINS ``.nav``, a NaveGo reference struct
or a PSINS avp file. Other tools' files are chosen by what they hold as well as by their
name: a ``.mat`` with a NaveGo struct, a headerless table of 7 numbers a line (KF-GINS /
OB_GINS), a ``.pos`` without RTKLIB's ``%`` header, a ROS bag (``.bag``, or a ROS 2 folder).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from sinslab.core.records import Fixes, ImuRecord
from sinslab.data import kfgins, matlab, psins, rosbag, rtklib, tables
from sinslab.data.increments import ImuData

__all__ = ["IMU_FORMATS", "FIX_FORMATS", "guess_imu_format", "guess_fix_format", "load_imu", "read_imu",
           "read_fixes", "load_fixes", "read_truth", "write_imu", "write_fixes", "check_fits", "estimate_rows"]

#: IMU formats understood by :func:`load_imu` (``--format``).
IMU_FORMATS = ("psins", "csv", "parquet", "mat", "navego", "kf-gins", "rosbag", "rtklib-imu")
#: Fix/solution formats understood by :func:`read_fixes`.
FIX_FORMATS = ("rtklib-pos", "csv", "mat-avp", "navego", "kf-gins", "rosbag", "two-geo", "ubx")


def guess_imu_format(path, sniff=True) -> str:
    """IMU format from the file name and, with ``sniff``, what it holds: a ROS bag rosbag,
    ``.imu`` psins, ``.parquet`` parquet, ``.mat`` mat (a NaveGo struct in it is found by
    the reader), ``.bin`` or a headerless table of 7/8 numbers a line in the KF-GINS layout
    kf-gins, a file with an RTKLIB ``.tag`` next to it rtklib-imu, else csv."""
    p = Path(path)
    suf = p.suffix.lower()
    if rosbag.is_rosbag(p):
        return "rosbag"
    if suf == ".imu":
        return "psins"
    if suf in (".parquet", ".pq"):
        return "parquet"
    if suf == ".mat":
        return "mat"
    if Path(str(p) + ".tag").exists():
        return "rtklib-imu"
    if sniff and p.is_file() and kfgins.sniff(p) == "kf-gins-imu":
        return "kf-gins"
    return "csv"


def guess_fix_format(path) -> str:
    """Fix format from the name and what the file holds: a ROS bag rosbag, ``.mat``
    mat-avp (a NaveGo struct in it is found by the reader), ``.ubx`` ubx, a headerless
    table of 7 or 13 numbers a line (latitude, longitude in degrees) kf-gins — also under
    the ``.pos`` name KF-GINS and OB_GINS give it —, another ``.pos`` rtklib-pos, else csv."""
    p = Path(path)
    suf = p.suffix.lower()
    if rosbag.is_rosbag(p):
        return "rosbag"
    if suf in (".mat", ".ubx"):
        return {".mat": "mat-avp", ".ubx": "ubx"}[suf]
    if p.is_file() and kfgins.sniff(p) == "kf-gins-gnss":
        return "kf-gins"
    return "rtklib-pos" if suf == ".pos" else "csv"


def _existing_file(path) -> Path:
    """``path`` as a Path, or one clear error when it is missing or not a regular file (a
    ROS 2 bag folder is taken as the file it stands for)."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"{p}: no such file")
    if p.is_dir() and rosbag.is_rosbag(p):
        return p
    if not p.is_file():
        raise ValueError(f"{p}: is a directory, not a file" if p.is_dir() else f"{p}: not a regular file")
    return p


#: Peak memory of reading a log whole, per sample [bytes], beyond the process' own: the
#: parsed columns, the rates, the increments and the reader's temporaries (measured on a
#: million samples: a CSV table 220 B, a PSINS log 129 B; an RTKLIB log keeps its text
#: lines too; a MAT file is loaded whole by scipy, then converted), rounded up.
WHOLE_READ_BYTES = {"csv": 256, "parquet": 256, "psins": 160, "rtklib-imu": 512, "mat": 256}


def estimate_rows(path, fmt) -> int | None:
    """Samples in an IMU file estimated without reading it: a Parquet file's row count, a
    MAT file's size over 7 float64 per sample, a text log's size (up to a binary tail,
    :func:`sinslab.data.textguard.text_extent`) over the mean length of its first lines."""
    import os

    from sinslab.data.textguard import text_extent

    try:
        if fmt == "parquet":
            import pyarrow.parquet as pq

            return int(pq.ParquetFile(path).metadata.num_rows)
        size = os.path.getsize(path)
        if fmt == "mat":
            return size // 56
        size = text_extent(path) or size
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
    except Exception:                                      # noqa: BLE001 - the reader names what is wrong
        return None
    lines = [ln for ln in head.split(b"\n")[1:-1] if ln.strip()]
    if not lines:
        return None
    return int(size / ((sum(len(ln) for ln in lines) + len(lines)) / len(lines)))


def check_fits(path, fmt, available=None) -> None:
    """Refuse, before reading, an IMU file that a reader holding it whole cannot fit in
    memory: its estimated samples (:func:`estimate_rows`) times
    :data:`WHOLE_READ_BYTES` against the memory available. A text log ending in binary
    data is refused for that first (:func:`sinslab.data.textguard.check_text_tail`)."""
    from sinslab.core.memory import available_memory, human_size
    from sinslab.data.textguard import check_text_tail

    if fmt in ("csv", "psins", "rtklib-imu"):
        check_text_tail(path)
    n = estimate_rows(path, fmt)
    if n is None or fmt not in WHOLE_READ_BYTES:
        return
    need = n * WHOLE_READ_BYTES[fmt]
    avail = available_memory() if available is None else int(available)
    if need > avail:
        raise ValueError(f"{path}: about {n:,} IMU samples; reading it ({fmt}) takes about "
                         f"{human_size(need)} of memory, {human_size(avail)} is available (split the "
                         "log, or run where more memory is free)")


def load_imu(path, fmt=None, **kw) -> ImuData:
    """Read any supported IMU file into :class:`~sinslab.data.increments.ImuData` (``fmt``
    from :data:`IMU_FORMATS`, default from the suffix: ``.imu`` psins, ``.parquet``
    parquet, ``.mat`` mat, a ``.csv`` with a ``.tag`` next to it rtklib-imu, else csv).
    Keywords go to the reader. A text log may come as ``.gz`` or in a ``.zip``
    (:mod:`sinslab.data.archive`); ``path`` may be a pair of csv/parquet tables on one time
    column (accelerometers in one, gyros in the other), joined on their stamps."""
    import contextlib

    from sinslab.data.archive import compression, plain_file
    paths = list(path) if isinstance(path, (list, tuple)) else [path]
    ps = [_existing_file(p) for p in paths]
    if fmt in (None, "rosbag") and rosbag.is_rosbag(ps[0]):
        return rosbag.read_rosbag_imu(ps[0], **kw)
    with contextlib.ExitStack() as stack:
        qs = [stack.enter_context(plain_file(p)) for p in ps]
        fmt = fmt or guess_imu_format(ps[0] if compression(ps[0]) is None else qs[0],
                                      sniff="columns" not in kw)
        if len(qs) > 1 and fmt not in ("csv", "parquet"):
            raise ValueError(f"IMU channels from two files: csv or parquet tables only, not {fmt!r}")
        for q in qs:
            check_fits(q, fmt)
        if fmt == "psins":
            d = psins.load_psins(qs[0], **kw)
        elif fmt in ("csv", "parquet"):
            d = tables.read_table_imu(qs if len(qs) > 1 else qs[0], **kw)
        elif fmt == "mat":
            d = matlab.read_mat_imu(qs[0], **kw)
        elif fmt == "navego":
            from sinslab.data.navego import read_navego_imu
            d = read_navego_imu(qs[0], **kw)
        elif fmt == "kf-gins":
            d = kfgins.read_kfgins_imu(qs[0], **kw)
        elif fmt == "rosbag":
            d = rosbag.read_rosbag_imu(qs[0], **kw)
        elif fmt == "rtklib-imu":
            d = rtklib.read_rtklib_imu(qs[0], **kw)
        else:
            raise ValueError(f"unknown IMU format {fmt!r}; use one of {IMU_FORMATS}")
    if any(q != p for q, p in zip(qs, ps)):          # read from an unpacked copy: the archive's name
        d = dataclasses.replace(d, path=" + ".join(map(str, ps)))
    return d


def read_imu(path, fmt=None, **kw):
    """Read an IMU file with :func:`load_imu` (any of :data:`IMU_FORMATS`; default from the
    suffix). Returns ``(ImuRecord, PsinsImu | None)``: the PSINS header (attitude, position,
    scale) when the file is a PSINS log, for callers that use it."""
    d = load_imu(path, fmt, **kw)
    return d.imu, d.meta.get("psins")


def read_fixes(path, fmt=None, **kw) -> Fixes:
    """Read position(/velocity) fixes: ``rtklib-pos`` (``.pos``), ``csv`` (a table read by
    :func:`sinslab.data.tables.read_fix_table`: columns by name or a column map, NED or
    ENU velocity, a quality column, held fixes collapsed), ``mat-avp`` (a PSINS avp
    matrix: positions and velocities, σ from ``sigma``/``sigma_vel`` keywords, default 1 m
    / 0.1 m/s), ``two-geo`` (a recorded double-star fix list,
    :func:`sinslab.data.tables.read_two_geo_csv`) or ``ubx`` (the receiver's NAV-PVT
    solutions in a u-blox log, :func:`sinslab.data.gnss.read_ubx_pvt`); text formats may come as ``.gz`` or in a
    ``.zip``. ``velocity_lag`` [s] (any format): the velocities describe the motion that
    long before their stamps (:meth:`sinslab.core.records.Fixes.with_velocity_lag`).
    See :func:`load_fixes` for the keywords and what was done to the table."""
    return load_fixes(path, fmt, **kw)[0]


def load_fixes(path, fmt=None, *, columns=None, quality=None, velocity_lag=0.0, **kw):
    """:func:`read_fixes` with what the reader did: returns ``(Fixes, meta)``.

    ``columns``: a fix column map (``--fix-columns``, csv tables only); ``quality``: the
    accepted quality/mode values (``"4,5"``; csv: its quality column, rtklib-pos: Q).
    ``meta`` (csv: see :func:`sinslab.data.tables.read_fix_table`) holds ``format``,
    ``compressed`` ("gz" | "zip" | None) and, for a csv table, the rows read, held
    fixes collapsed, rows without a position and the quality counts.
    """
    import contextlib

    from sinslab.data.archive import compression, plain_file
    paths = list(path) if isinstance(path, (list, tuple)) else [path]
    ps = [_existing_file(x) for x in paths]
    p = ps[0] if len(ps) == 1 else " + ".join(map(str, ps))
    if len(ps) == 1 and fmt in (None, "rosbag") and rosbag.is_rosbag(ps[0]):
        fx, meta = rosbag.read_rosbag_fixes(ps[0], **{k: v for k, v in kw.items()
                                                      if k in ("topic", "velocity_topic", "sigma")})
        meta["compressed"] = None
        return fx.with_velocity_lag(velocity_lag), meta
    comp = None if ps[0].is_dir() else compression(ps[0])
    with contextlib.ExitStack() as stack:
        qs = [stack.enter_context(plain_file(x)) for x in ps]
        q = qs[0]
        fmt = fmt or guess_fix_format(q)
        if len(qs) > 1 and fmt != "csv":
            raise ValueError(f"fixes from two files: csv tables only, not {fmt!r}")
        if columns is not None and fmt != "csv":
            raise ValueError(f"--fix-columns applies to csv fix tables, not {fmt!r}")
        meta = {"format": fmt, "compressed": comp}
        keep_q = tables.parse_quality_filter(quality)
        if fmt == "rtklib-pos":
            fx = rtklib.read_rtklib_pos(q, velocity_lag=velocity_lag, **kw)
            if keep_q is not None:
                fx = fx.select(np.isin(fx.quality, sorted(keep_q)))
                if len(fx) == 0:
                    raise ValueError(f"{p}: no epoch with Q in {sorted(keep_q)}")
            return _named(fx, p, comp), meta
        if fmt == "csv":
            fx, m = tables.read_fix_table(qs if len(qs) > 1 else q, columns=columns, quality=keep_q)
            meta.update(m)
        elif keep_q is not None:
            raise ValueError(f"--fix-quality applies to csv and rtklib-pos fixes, not {fmt!r}")
        elif fmt in ("mat-avp", "navego"):
            fx, m = matlab.read_mat_fixes_any(q, kw.get("var"), kw.get("sigma", 1.0), kw.get("sigma_vel", 0.1))
            if fmt == "navego" and m["format"] != "navego":
                raise ValueError(f"{p}: no NaveGo GNSS struct (fields t, lat, lon, h)")
            meta.update(m)
        elif fmt == "kf-gins":
            fx, m = kfgins.read_kfgins_gnss(q)
            meta.update(m)
        elif fmt == "rosbag":
            raise ValueError(f"{p}: not a ROS bag (a .bag file, or a ROS 2 folder with metadata.yaml)")
        elif fmt == "two-geo":
            fx = tables.read_two_geo_csv(q)
        elif fmt == "ubx":
            from sinslab.data.gnss import read_ubx_pvt
            fx = read_ubx_pvt(q)
        else:
            raise ValueError(f"unknown fix format {fmt!r}; use one of {FIX_FORMATS}")
    return _named(fx.with_velocity_lag(velocity_lag), p, comp), meta


def _named(fx, p, comp):
    """Fixes read from an unpacked copy (or two files) carry the given name(s)."""
    return dataclasses.replace(fx, path=str(p)) if (comp or not isinstance(p, Path)) else fx


def read_truth(path, fmt=None):
    """A reference trajectory (:class:`sinslab.core.records.NavSeries`): a KF-GINS /
    OB_GINS ``.nav`` (11 columns), a NaveGo reference struct or a PSINS ``avp`` matrix in a
    ``.mat`` (``fmt`` "kf-gins" | "mat"; default from the name and content)."""
    p = _existing_file(path)
    fmt = fmt or ("mat" if p.suffix.lower() == ".mat" else "kf-gins")
    if fmt == "mat":
        return matlab.read_mat_truth(p)
    if fmt == "kf-gins":
        return kfgins.read_kfgins_nav(p)
    raise ValueError(f"unknown truth format {fmt!r}; use kf-gins or mat")


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
