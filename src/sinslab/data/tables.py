"""Tables with declared units: IMU samples in CSV or Parquet (rates or increments, units
in the column header, ``gx[deg/s]``), fixes in CSV (``t[s], lat[deg], lon[deg], h[m], ...``),
the two-GEO fix list of recorded double-star receivers, and the writers of both tables."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sinslab.core import units
from sinslab.core.atomic import atomic_path
from sinslab.core.records import Fixes, ImuRecord, all_finite
from sinslab.data import columns as _columns
from sinslab.data.frames import sensor_to_body
from sinslab.data.increments import ImuData, check_stamps, rates_to_increments, uniform_increments, where
from sinslab.data.textguard import MAX_LINE_BYTES, BinaryData, BlockGuard, check_text_tail, keep_hint

__all__ = ["read_table_imu", "write_table_imu", "read_fix_csv", "read_fix_table", "write_fix_csv",
           "read_csv_columns", "iter_csv_columns", "read_parquet_columns", "iter_parquet_columns",
           "read_two_geo_csv", "TWO_GEO_COLUMNS", "parse_quality_filter"]


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
                   frame="rfu", mount=None, max_gap=1.0, allow_gaps=False, columns=None) -> ImuData:
    """Read a CSV (or other delimited text) or Parquet table of IMU samples.

    Columns (names case-insensitive, any order, extra columns ignored whatever they hold):
    a time column ``t``/``time``/``timestamp`` (interval end times for increments, sample
    times for rates) and either rates ``gx gy gz`` (or ``wx..``, ``gyro_x..``) with ``ax
    ay az`` (or ``fx..``, ``acc_x..``), or increments ``dtheta_x..`` with ``dv_x..``.
    Units are declared in the header, ``gx[deg/s]``, ``ax[g]``, ``dtheta_x[rad]``,
    ``t[ms]``, or by the options ``gyro_unit``/``accel_unit``/``time_unit``; the unit's
    dimension tells rates from increments. The plain SI names ``t, dtheta_x.., dv_x..``
    and ``t, wx.., fx..`` may omit units (s, rad, m/s, rad/s, m/s²). Indexed names such as
    ``DeltaTheta[0]`` are names; ``DeltaTheta[0][rad]`` carries the unit.

    ``columns``: a column map (:func:`sinslab.data.columns.parse_column_map`: a string
    ``"t=Time[s],dtheta_x=DeltaTheta[0][rad],..."``, a dict or a TOML file) naming the
    file's columns for sinslab's quantities, with units; a unit in the map overrides the
    header's. The key ``stationary`` names a 0/1 rest-flag column, returned in
    ``meta["stationary"] = (t (N,), flags (N,) bool)``. A file without a header needs a
    map of 1-based column positions.

    ``frame``/``mount``: see :func:`sinslab.data.frames.sensor_to_body`. Text is parsed by
    pyarrow's CSV engine (comma, semicolon or tab delimited; whitespace-delimited text
    by numpy); any malformed table raises ValueError naming the file, the line and the
    cause (binary data, a short line, a non-number in a used column, ...).
    """
    plan = _imu_plan(path, columns, gyro_unit, accel_unit, time_unit, kind)
    src, cols, path = plan.src, plan.cols, plan.path
    ti, gi, ai, si = plan.ti, plan.gi, plan.ai, plan.si
    data = src.fetch(plan.idx)
    lines = src.lines
    if not all_finite(data[:, :7]):
        bad = ~np.isfinite(data[:, :7])
        if bad.any():
            r, c = (int(x) for x in np.argwhere(bad)[0])
            raise ValueError(f"{where(path, lines[r])}: NaN/inf or empty value in column "
                             f"{cols[([ti] + gi + ai)[c]][0]!r}")
    t, g, a = plan.convert(data, sensor_to_body(mount, frame))
    check_stamps(t, path, lines)
    meta = plan.meta()
    if isinstance(src, _JoinedSource):
        meta["joined"] = src.report()
    if si is not None:
        f = data[:, 7]
        if not np.all(np.isin(f, (0.0, 1.0))):
            r = int(np.flatnonzero(~np.isin(f, (0.0, 1.0)))[0])
            raise ValueError(f"{where(path, lines[r])}: rest flag column {cols[si][0]!r} holds "
                             f"{f[r]!r}; use 0 (moving) or 1 (at rest)")
        meta["stationary"] = (t.copy(), f.astype(bool))
    fmt = plan.fmt
    if plan.gk == "rate":
        if t.size < 2:
            raise ValueError(f"{path}: needs at least 2 samples for rates")
        dt_nom = float(np.median(np.diff(t)))
        d = np.diff(t)
        if np.all(np.abs(d - dt_nom) <= 1e-4 * dt_nom):
            imu = ImuRecord.from_rates(t, g, a)
            return ImuData(imu, np.zeros((0, 2)), str(path), fmt, t.size, 0.0, meta)
        dth, dvv = rates_to_increments(t, g, a, dt_nom)
    else:
        dth, dvv = g, a
    imu, gaps, jit = uniform_increments(t, dth, dvv, path=path, lines=lines,
                                        max_gap=max_gap, allow_gaps=allow_gaps)
    return ImuData(imu, gaps, str(path), fmt, t.size, jit, meta)


# ----------------------------------------------------------------- table sources ---
class _ImuPlan:
    """What the header of an IMU table says: its source, the columns used (time, gyro,
    accel, rest flags), their scales to SI and kind (rates or increments); the same for a
    table read whole (:func:`read_table_imu`) or a block at a time
    (:func:`sinslab.data.spool.spool_table_imu`)."""

    def __init__(self, src, cols, path, is_parquet, hline, pick, ti, gi, ai, si, gs, gk, gu, as_, au, ts, tu, cmap):
        self.src, self.cols, self.path, self.hline, self.pick = src, cols, path, hline, pick
        self.ti, self.gi, self.ai, self.si = ti, gi, ai, si
        self.gs, self.gk, self.gu, self.as_, self.au, self.ts, self.tu = gs, gk, gu, as_, au, ts, tu
        self.cmap = cmap
        self.fmt = "parquet" if is_parquet else "csv"
        self.idx = [ti] + gi + ai + ([si] if si is not None else [])

    def meta(self):
        """The reader's ``meta`` of the header: units and the column map's columns."""
        meta = {"units": {"gyro": self.gu, "accel": self.au, "time": self.tu}}
        if self.cmap:
            cols = self.cols
            meta["columns"] = {k: f"{cols[i][0]}[{cols[i][1]}]" if cols[i][1] else cols[i][0]
                               for k, i in self.pick["map"].items()}
        return meta

    def convert(self, data, R):
        """Rows ``data`` of the used columns -> time [s] (m,), gyro and accel (m, 3) in SI
        in the body axes (``R`` the sensor -> body rotation), as read."""
        # a scale of 1 (SI columns) multiplies nothing: x·1 is x, the product skipped (one
        # array fewer of the record's size)
        return (data[:, 0] * self.ts, (data[:, 1:4] if self.gs == 1.0 else data[:, 1:4] * self.gs) @ R.T,
                (data[:, 4:7] if self.as_ == 1.0 else data[:, 4:7] * self.as_) @ R.T)


def _imu_plan(path, columns, gyro_unit, accel_unit, time_unit, kind):
    """The :class:`_ImuPlan` of an IMU table (one file or two joined on time)."""
    cmap = _columns.parse_column_map(columns)
    if isinstance(path, (list, tuple)) and len(path) == 1:
        path = path[0]
    if isinstance(path, (list, tuple)):
        src = _JoinedSource([Path(p) for p in path], cmap)
        path, is_parquet = src.path, False
    else:
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"{path}: no such file")
        is_parquet = path.suffix.lower() in (".parquet", ".pq")
        src = _source(path, cmap)
    cols, hline = src.cols, src.hline
    pick = _select(cols, cmap, path, hline, src.raw)
    ti, gi, ai, si = pick["t"], pick["gyro"], pick["accel"], pick.get("stationary")

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
                                     f"in the header ({nm}[deg/s], {nm}[g], ...), in the column map "
                                     f"or give the {sensor} unit as an option")
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
    try:
        ts = units.unit_scale(tu, "time")
    except (ValueError, KeyError):
        raise ValueError(f"{where(path, hline)}: time column {cols[ti][0]!r} has unit {tu!r}, "
                         "not a time unit (s, ms, us, ns, min, h)") from None
    return _ImuPlan(src, cols, path, is_parquet, hline, pick, ti, gi, ai, si, gs, gk, gu, as_, au, ts, tu, cmap)


def _positional(cmap):
    return bool(cmap) and all(isinstance(v[0], int) for v in cmap.values())


def _source(path, cmap):
    return _ParquetSource(path) if path.suffix.lower() in (".parquet", ".pq") else \
        _TextSource(path, headerless=_positional(cmap))


class _JoinedSource:
    """Two tables on one time column read as one (a unit that logs its accelerometers and
    gyros, or its fix positions and velocities, to separate files): the columns of both side by side, the second file's time
    column left out; the rows matched by time stamp within the first file's own stamp
    tolerance (:func:`sinslab.core.stamps.stamp_step`). Rows without a partner are dropped
    and counted; fewer than half matched is an error (not one time base)."""

    def __init__(self, paths, cmap):
        if len(paths) != 2:
            raise ValueError(f"a table comes from one file or two joined on time, got {len(paths)} files")
        for p in paths:
            if not p.exists():
                raise FileNotFoundError(f"{p}: no such file")
        self.paths = paths
        self.path = f"{paths[0]} + {paths[1]}"
        self.srcs = [_source(p, cmap) for p in paths]
        tname = cmap.get("t", (None,))[0]
        self.ti = [self._time_index(s, tname, p) for s, p in zip(self.srcs, paths)]
        a, b = self.srcs
        self.where = [(0, i) for i in range(len(a.cols))] + \
            [(1, i) for i in range(len(b.cols)) if i != self.ti[1]]
        self.cols = [self.srcs[k].cols[i] for k, i in self.where]
        self.raw = [self.srcs[k].raw[i] for k, i in self.where]
        self.hline = a.hline
        self.unmatched = (0, 0)

    @staticmethod
    def _time_index(src, tname, path):
        names = [c[0] for c in src.cols]
        raw_l = [str(r).strip().lower() for r in src.raw]
        if isinstance(tname, int):
            return tname - 1
        cand = [tname] if tname is not None else list(_TIME_NAMES)
        for n in cand:
            hits = [i for i, (a, r) in enumerate(zip(names, raw_l)) if n in (a, r)]
            if len(hits) == 1:
                return hits[0]
        raise ValueError(f"{where(path, src.hline)}: no time column "
                         f"({tname or ', '.join(_TIME_NAMES)}) to join the two files on")

    def fetch(self, idx, allow_empty=False):
        from sinslab.core.stamps import stamp_step
        per = [[self.ti[0]], [self.ti[1]]]
        for i in idx:
            k, j = self.where[i]
            per[k].append(j)
        A_, B_ = (s.fetch(list(dict.fromkeys(c)), allow_empty=True) if allow_empty and isinstance(s, _TextSource)
                  else s.fetch(list(dict.fromkeys(c))) for s, c in zip(self.srcs, per))
        pos = [{c: n for n, c in enumerate(dict.fromkeys(cc))} for cc in per]
        ta, tb = A_[:, 0], B_[:, 0]
        check_stamps(ta, self.paths[0], self.srcs[0].lines)
        check_stamps(tb, self.paths[1], self.srcs[1].lines)
        _, tol = stamp_step(ta) if ta.size > 1 else (0.0, 0.0)
        j = np.clip(np.searchsorted(tb, ta), 1, max(tb.size - 1, 1))
        jn = np.where(np.abs(tb[j - 1] - ta) <= np.abs(tb[np.minimum(j, tb.size - 1)] - ta), j - 1,
                      np.minimum(j, tb.size - 1))
        ok = np.abs(tb[jn] - ta) <= tol
        n_ok = int(ok.sum())
        if n_ok < 0.5 * min(ta.size, tb.size):
            raise ValueError(f"{self.path}: only {n_ok} of {ta.size} time stamps of {self.paths[0].name} "
                             f"match one of {self.paths[1].name} within {tol * 1e3:.3g} ms: the two files "
                             "are not on one time column")
        self.unmatched = (int(ta.size - n_ok), int(tb.size - n_ok))
        keep = np.flatnonzero(ok)
        self.lines = _LineView(self.srcs[0].lines, keep)
        out = np.empty((keep.size, len(idx)))
        for c, i in enumerate(idx):
            k, jj = self.where[i]
            out[:, c] = A_[keep, pos[0][jj]] if k == 0 else B_[jn[keep], pos[1][jj]]
        return out

    def report(self):
        """``{"files", "unmatched"}``: the two files and the rows of each left without a
        partner."""
        return {"files": [str(p) for p in self.paths], "unmatched": list(self.unmatched)}


class _LazyLines:
    """File line of sample i, found only when an error message needs it (the fast path
    assumes nothing; blank or comment lines between samples shift the numbering)."""

    def __init__(self, path, first_body_line):
        self.path, self.first, self._map = path, first_body_line, None

    def __getitem__(self, i):
        if self._map is None:
            with open(self.path, "r", encoding="utf-8", errors="replace") as fh:
                self._map = [n for n, s in enumerate(fh, 1)
                             if n >= self.first and s.strip() and not s.lstrip().startswith(("#", "%"))]
        return self._map[i] if i < len(self._map) else f"row {i + 1}"


class _ParquetSource:
    def __init__(self, path):
        import pyarrow.parquet as pq
        self.path, self.hline = path, None
        try:
            self._schema = pq.read_schema(path)
        except Exception as e:   # noqa: BLE001 - pyarrow raises many kinds
            raise ValueError(f"{path}: cannot read as Parquet ({e})") from None
        self.raw = list(self._schema.names)
        self.cols = [_columns.parse_header_cell(c)[:2] for c in self.raw]

    def fetch(self, idx):
        names = [self.raw[i] for i in idx]
        out = read_parquet_columns(self.path, names)
        self.lines = [f"row {i + 1}" for i in range(out.shape[0])]
        return out


_DELIMS = (",", ";", "\t")


class _TextSource:
    """A delimited text table: header found, binary data refused, columns read by pyarrow
    (or numpy for whitespace-delimited text), every failure diagnosed line by line."""

    def __init__(self, path, headerless=False):
        self.path = path
        check_text_tail(path)
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
            # a header wider than the first read (tens of thousands of columns): read on to its end
            while len(head) < 1 << 28 and not _header_complete(head):
                more = fh.read(1 << 20)
                if not more:
                    break
                head += more
        bom = 3 if head.startswith(b"\xef\xbb\xbf") else 0      # UTF-8 byte-order mark (Excel, Notepad)
        head = head[bom:]
        nul = head.find(b"\x00")
        try:
            text = head.decode("utf-8")
        except UnicodeDecodeError as e:
            if e.start < len(head) - 4:              # not just a character cut at the end
                nul = e.start if nul < 0 else min(nul, e.start)
            text = head[:e.start].decode("utf-8")
        if nul >= 0 and head.count(b"\n", 0, nul) >= 2:     # text lines, then binary data
            BlockGuard(path, bom).check(head[:nul + 1])
        if nul >= 0:
            raise ValueError(f"{path}: not a text table (binary data at byte {nul + bom}); a Parquet, MAT "
                             "or raw binary log? give its format (--format)")
        lines = text.splitlines()
        hline = next((i + 1 for i, s in enumerate(lines)
                      if s.strip() and not s.lstrip().startswith(("#", "%"))), None)
        if hline is None:
            raise ValueError(f"{path}: empty file (no header, no samples)")
        first = lines[hline - 1]
        self.delim = next((d for d in _DELIMS if d in first), None)
        cells = [c.strip() for c in (first.split(self.delim) if self.delim else first.split())]
        numeric = all(_is_number(c) for c in cells)
        if headerless or numeric:
            if not headerless:
                raise ValueError(f"{where(path, hline)}: no header line (the first line holds "
                                 f"{len(cells)} numbers); add a header such as "
                                 "t[s],gx[deg/s],...,az[g] or give a column map of positions "
                                 "(--columns \"t=1[s],gx=2[deg/s],...\")")
            self.raw = [f"#{i + 1}" for i in range(len(cells))]
            self.cols = [(r, None) for r in self.raw]
            self.hline, self.skip = None, hline - 1
        else:
            self.raw = cells
            self.cols = [_columns.parse_header_cell(c)[:2] for c in cells]
            self.hline, self.skip = hline, hline
        self.ncol = len(cells)
        self.lines = _LazyLines(path, self.skip + 1)

    def fetch(self, idx, allow_empty=False):
        """The columns ``idx`` as floats (N, len(idx)); ``allow_empty``: empty cells are NaN
        instead of an error."""
        uniq = list(dict.fromkeys(idx))
        self.allow_empty = allow_empty
        try:
            arr = self._fast(uniq)
        except BinaryData:
            raise
        except Exception:        # noqa: BLE001 - any parse failure: find the line and say why
            self._diagnose(uniq)
            arr = self._slow(uniq)
        if arr.shape[0] == 0:
            raise ValueError(f"{where(self.path, self.hline)}: header only, no samples")
        if uniq == list(idx):
            return arr
        pos = {c: j for j, c in enumerate(uniq)}
        return arr[:, [pos[i] for i in idx]]

    def _fast(self, uniq):
        if self.delim is None:
            # whitespace-delimited text (KF-GINS, PSINS): one compiled pass over plain
            # decimal text (numbers as numpy's parser gives them, a fifth of its time),
            # else numpy's C parser, about ten times the line-by-line reader. Every column
            # is parsed, so that a line of another length fails here as it does there;
            # comment and blank lines are skipped alike
            from sinslab.data.numtext import read_numbers
            arr = read_numbers(self.path, self.skip, self.ncol)
            if arr is not None:
                if arr.shape[0] == 0:
                    return np.empty((0, len(uniq)))
                return arr if uniq == list(range(self.ncol)) else arr[:, uniq]
            import warnings
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)       # "input contained no data"
                try:
                    # one comment character keeps the whole parse in C
                    arr = np.loadtxt(self.path, dtype=float, comments="#", skiprows=self.skip,
                                     ndmin=2, encoding="utf-8")
                except ValueError:
                    arr = np.loadtxt(self.path, dtype=float, comments=("#", "%"), skiprows=self.skip,
                                     ndmin=2, encoding="utf-8-sig")
            if arr.shape[0] == 0:
                return np.empty((0, len(uniq)))
            if arr.shape[1] != self.ncol:
                raise ValueError("a line of another length")
            return arr if uniq == list(range(self.ncol)) else arr[:, uniq]
        return read_csv_columns(self.path, self.skip, self.ncol, uniq, self.delim,
                                allow_empty=self.allow_empty)

    def _rows(self):
        for n, s in _text_lines(self.path):
            if n <= self.skip or not s.strip() or s.lstrip().startswith(("#", "%")):
                continue
            yield n, [p.strip() for p in (s.split(self.delim) if self.delim else s.split())]

    def _diagnose(self, uniq):
        used = set(uniq)
        for n, parts in self._rows():
            if len(parts) != self.ncol:
                raise ValueError(f"{self.path}:{n}: {len(parts)} columns, the header has {self.ncol}"
                                 if self.hline else f"{self.path}:{n}: {len(parts)} columns, the first "
                                 f"line has {self.ncol}")
            for i in used:
                if not _is_number(parts[i]) and not (self.allow_empty and parts[i] == ""):
                    what = "empty value" if parts[i] == "" else f"not a number: {parts[i]!r}"
                    raise ValueError(f"{self.path}:{n}: {what} in column "
                                     f"{self.raw[i]!r}")

    def _slow(self, uniq):
        rows, lines = [], []
        for n, parts in self._rows():
            rows.append([float(parts[i]) if parts[i] != "" else math.nan for i in uniq])
            lines.append(n)
        self.lines = lines
        return np.array(rows, dtype=float).reshape(len(rows), len(uniq))


def _text_lines(path):
    """``(line number, text)`` of a text file, read a line at a time and never more than
    :data:`~sinslab.data.textguard.MAX_LINE_BYTES` at once: binary data (a NUL byte, bytes
    that are not UTF-8 after the first line, a "line" without end) raises
    :class:`~sinslab.data.textguard.BinaryData` with its offset."""
    guard = BlockGuard(path)
    with open(path, "rb") as fh:
        n = 0
        while True:
            raw = fh.readline(MAX_LINE_BYTES + 1)
            if not raw:
                return
            n += 1
            guard.check(raw)
            if not raw.endswith(b"\n"):
                guard.long_line(len(raw))
            s = raw.decode("utf-8", errors="replace")
            if "\ufffd" in s and n > 1:
                try:
                    raw.decode("utf-8")
                except UnicodeDecodeError as e:
                    at = guard.offset - len(raw) + e.start
                    raise BinaryData(f"{path}:{n}: binary data (bytes that are not UTF-8 text) at byte {at:,}: "
                                     f"not text from there — a corrupt log? {keep_hint(path, at)}") from None
            yield n, (s.lstrip("\ufeff") if n == 1 else s)


def _header_complete(head: bytes) -> bool:
    """True if ``head`` holds a whole line that is neither blank nor a comment (the header)."""
    for ln in head.split(b"\n")[:-1]:
        t = ln.strip().lstrip(b"\xef\xbb\xbf")
        if t and not t.startswith((b"#", b"%")):
            return True
    return False


def iter_csv_columns(path, skip, ncol, cols, delim, *, block_size=1 << 20, allow_empty=False):
    """Float columns ``cols`` (indices) of a delimited table, one block at a time.

    The file is read one block of about ``block_size`` bytes (whole lines) at a time and
    each block is parsed by pyarrow's CSV engine; its rows are yielded as a float64 array
    ``(rows, len(cols))``, so a caller that consumes the blocks as they come holds one
    block, whatever the length of the file. (pyarrow's own streaming reader reads ahead
    of its consumer without bound: it held most of a large file.) Parameters and errors
    as in :func:`read_csv_columns`.
    """
    import pyarrow as pa
    from pyarrow import csv as pcsv

    names = [f"c{i}" for i in range(ncol)]
    use = [names[i] for i in cols]
    ropt = pcsv.ReadOptions(column_names=names, use_threads=False, block_size=max(int(block_size), 1 << 12) + (1 << 16))
    popt = pcsv.ParseOptions(delimiter=delim)
    copt = pcsv.ConvertOptions(include_columns=use, column_types={c: pa.float64() for c in use},
                               strings_can_be_null=False)
    with open(path, "rb") as fh:
        for _ in range(skip):
            fh.readline(MAX_LINE_BYTES + 1)
        guard = BlockGuard(path, fh.tell(), skip + 1)
        rest = b""
        while True:
            buf = fh.read(max(int(block_size), 1 << 12))
            guard.check(buf)
            if buf:
                data = rest + buf
                cut = data.rfind(b"\n")
                if cut < 0:
                    guard.long_line(len(data))
                    rest = data
                    continue
                rest, data = data[cut + 1:], memoryview(data)[:cut + 1]
            else:
                data, rest = memoryview(rest), b""
            if bytes(data[-64:]).strip() or bytes(data).strip():
                batch = pcsv.read_csv(pa.py_buffer(data), read_options=ropt, parse_options=popt,
                                      convert_options=copt, memory_pool=pa.system_memory_pool())
                m = batch.num_rows
                out = np.empty((m, len(use)))
                for j, c in enumerate(use):
                    col = batch.column(c).combine_chunks()
                    if col.null_count and not allow_empty:
                        raise ValueError("empty cell")
                    out[:, j] = _float_values(col)
                del batch
                yield out
            if not buf:
                return


def read_csv_columns(path, skip, ncol, cols, delim, *, block_size=1 << 20, allow_empty=False):
    """Float columns ``cols`` (indices) of a delimited table, read in batches.

    The blocks of :func:`iter_csv_columns` are copied into a float64 array sized from the
    file's length (grown if the estimate falls short), so the memory in use is the result
    plus one block, whatever the length of the file (the whole-table reader holds the
    parsed table and its buffers beside the result).

    Parameters
    ----------
    path : path-like
    skip : int
        Lines before the first sample (header included).
    ncol : int
        Columns of a line.
    cols : sequence of int
        Columns to read, in this order.
    delim : str
        Delimiter.
    allow_empty : bool
        Empty cells read as NaN instead of raising.

    Returns
    -------
    ndarray, shape (rows, len(cols))

    Raises
    ------
    ValueError
        An empty cell in a read column (unless ``allow_empty``); pyarrow's own errors for any other malformed
        line (the caller diagnoses them line by line).
    """
    first = None
    n = 0
    out = np.empty((0, len(cols)))
    for blk in iter_csv_columns(path, skip, ncol, cols, delim, block_size=block_size,
                                allow_empty=allow_empty):
        m = blk.shape[0]
        if first is None and m:
            # the first batch is about one block: rows of the file from its bytes, a margin
            first = m + int(1.02 * Path(path).stat().st_size * m / block_size)
            out = np.empty((first, len(cols)))
        if n + m > out.shape[0]:
            grown = np.empty((max(n + m, out.shape[0] + out.shape[0] // 4 + 1024), len(cols)))
            grown[:n] = out[:n]
            out = grown
        out[n:n + m] = blk
        n += m
    return out[:n] if n < out.shape[0] else out


def _float_values(col):
    """A pyarrow array as float64 numpy values (nulls as NaN). A float64 array is read from
    its buffers (no copy): pyarrow's own ``to_numpy`` imports pandas, half a second and
    tens of MB a run that has no other use for it; other types go through it."""
    import pyarrow as pa

    if col.type != pa.float64():
        return col.to_numpy(zero_copy_only=False).astype(float)
    validity, data = col.buffers()[:2]
    vals = np.frombuffer(data, dtype=np.float64, count=col.offset + len(col))[col.offset:]
    if col.null_count:
        bits = np.unpackbits(np.frombuffer(validity, dtype=np.uint8), bitorder="little")
        vals = np.where(bits[col.offset:col.offset + len(col)].astype(bool), vals, np.nan)
    return vals


def iter_parquet_columns(path, names, *, batch_rows=1 << 16):
    """Columns ``names`` of a Parquet file as float64 arrays ``(rows, len(names))``, one
    batch of ``batch_rows`` rows at a time (a caller consuming them holds one batch).

    Raises
    ------
    ValueError
        The file cannot be read as Parquet, holds no rows, or a column is not numeric.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    try:
        pf = pq.ParquetFile(path)
        nrows = pf.metadata.num_rows
        batches = pf.iter_batches(batch_size=batch_rows, columns=list(dict.fromkeys(names)),
                                  use_threads=False)
    except Exception as e:   # noqa: BLE001 - pyarrow raises many kinds
        raise ValueError(f"{path}: cannot read as Parquet ({e})") from None
    if nrows == 0:
        raise ValueError(f"{path}: no samples")
    try:
        for batch in batches:
            out = np.empty((batch.num_rows, len(names)))
            for j, c in enumerate(names):
                col = batch.column(batch.schema.get_field_index(c))
                try:
                    out[:, j] = _float_values(col)
                except (TypeError, ValueError, pa.ArrowInvalid):
                    raise ValueError(f"{path}: column {c!r} is not numeric") from None
            yield out
    except ValueError:
        raise
    except Exception as e:   # noqa: BLE001
        raise ValueError(f"{path}: cannot read as Parquet ({e})") from None


def parquet_rows(path) -> int:
    """Row count of a Parquet file from its footer (ValueError if it is not Parquet)."""
    import pyarrow.parquet as pq

    try:
        return int(pq.ParquetFile(path).metadata.num_rows)
    except Exception as e:   # noqa: BLE001 - pyarrow raises many kinds
        raise ValueError(f"{path}: cannot read as Parquet ({e})") from None


def read_parquet_columns(path, names, *, batch_rows=1 << 16):
    """Columns ``names`` of a Parquet file as float64 (rows, len(names)), read one batch
    of ``batch_rows`` rows at a time (:func:`iter_parquet_columns`) into an array sized
    from the file's row count, so the memory in use is the result plus one batch.

    Raises
    ------
    ValueError
        The file cannot be read as Parquet, holds no rows, or a column is not numeric.
    """
    out = np.empty((parquet_rows(path), len(names)))
    n = 0
    for blk in iter_parquet_columns(path, names, batch_rows=batch_rows):
        out[n:n + blk.shape[0]] = blk
        n += blk.shape[0]
    return out


def _is_number(s):
    try:
        float(s)
        return True
    except ValueError:
        return False


def _resolve_map(cols, raw, cmap, path, hline, label):
    """``{key: column index}`` of the entries of a column map (a name, raw or parsed, or a
    1-based position); the unit of an entry replaces the header's (``cols`` is updated in
    place). ``label`` names the map in messages."""
    names = [c[0] for c in cols]
    raw_l = [str(r).strip().lower() for r in raw]
    picked = {}
    for key, (src, unit) in cmap.items():
        if isinstance(src, int):
            if src > len(cols):
                raise ValueError(f"{where(path, hline)}: {label} {key}={src}: the file has only "
                                 f"{len(cols)} columns")
            i = src - 1
        else:
            hits = [i for i, (n, r) in enumerate(zip(names, raw_l)) if src in (n, r)]
            if not hits:
                raise ValueError(f"{where(path, hline)}: {label} {key}={src!r}: no such column "
                                 f"(the header has {', '.join(map(str, raw))})")
            if len(hits) > 1:
                raise ValueError(f"{where(path, hline)}: {label} {key}={src!r}: {len(hits)} "
                                 "columns have that name")
            i = hits[0]
        if unit is not None:
            cols[i] = (cols[i][0], unit)
        picked[key] = i
    return picked


def _select(cols, cmap, path, hline, raw):
    """Column indices of the time, gyro and accelerometer triples (and the rest flag),
    from the column map where it names them, else by the usual names; the unit in a map
    entry replaces the header's (``cols`` is updated in place)."""
    names = [c[0] for c in cols]
    picked = _resolve_map(cols, raw, cmap, path, hline, "column map")
    out = {"map": picked}

    def unique(i):
        if names.count(names[i]) > 1:
            raise ValueError(f"{where(path, hline)}: {names.count(names[i])} columns are named "
                             f"{names[i]!r}; name the ones to use with a column map (--columns)")
        return i

    if "t" in picked:
        out["t"] = picked["t"]
    else:
        ti = next((names.index(n) for n in _TIME_NAMES if n in names), None)
        if ti is None:
            raise ValueError(f"{where(path, hline)}: no time column (t, time or timestamp) in "
                             f"{', '.join(map(str, raw))}; name it with a column map (--columns t=NAME[s])")
        out["t"] = unique(ti)
    if any(k in picked for k in _columns.RATE_KEYS):
        out["gyro"] = [picked[k] for k in _columns.RATE_KEYS[:3]]
        out["accel"] = [picked[k] for k in _columns.RATE_KEYS[3:]]
    elif any(k in picked for k in _columns.INC_KEYS):
        out["gyro"] = [picked[k] for k in _columns.INC_KEYS[:3]]
        out["accel"] = [picked[k] for k in _columns.INC_KEYS[3:]]
    else:
        g_rate, a_rate = _find_cols(names, "gyro_rate"), _find_cols(names, "accel_rate")
        g_inc, a_inc = _find_cols(names, "gyro_inc"), _find_cols(names, "accel_inc")
        gi, ai = g_inc or g_rate, a_inc or a_rate
        if gi is None or ai is None:
            raise ValueError(f"{where(path, hline)}: wrong columns {', '.join(map(str, raw))}: need a "
                             "time column and gyro (gx gy gz | dtheta_x dtheta_y dtheta_z) and "
                             "accelerometer (ax ay az | dv_x dv_y dv_z) columns, or a column map "
                             "(--columns \"t=...,dtheta_x=NAME[rad],...\")")
        out["gyro"], out["accel"] = [unique(i) for i in gi], [unique(i) for i in ai]
    if "stationary" in picked:
        out["stationary"] = picked["stationary"]
    return out


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
        # 15 digits: 12 would quantise a latitude in degrees to ~1 cm
        np.savetxt(tmp, np.column_stack(cols), delimiter=",", header=",".join(names), comments="",
                   fmt="%.15g")
    return Path(path)


def read_fix_csv(path, **kw) -> Fixes:
    """Read fixes from a CSV table (:func:`read_fix_table`; keywords go to it)."""
    return read_fix_table(path, **kw)[0]


#: names a fix table's columns are found by (lower case; a dotted vendor name such as
#: ``GnssPosition.Latitude`` is matched by its last part); more through a column map
_FIX_NAMES = {
    "t": _TIME_NAMES + ("gpstime", "gps_time", "utc_time"), "t_arrive": ("t_arrive",),
    "lat": ("lat", "latitude"), "lon": ("lon", "lng", "long", "longitude"),
    "h": ("h", "height", "alt", "altitude", "altitudehae", "hae"),
    "sd_n": ("sd_n", "sdn", "std_n", "stddevn", "sigma_n"),
    "sd_e": ("sd_e", "sde", "std_e", "stddeve", "sigma_e"),
    "sd_u": ("sd_u", "sdu", "std_u", "stddevu", "sigma_u"),
    "ve": ("ve", "vel_e", "v_e", "veast", "east_velocity"), "vn": ("vn", "vel_n", "v_n", "vnorth", "north_velocity"),
    "vu": ("vu", "vel_u", "v_u", "vup", "up_velocity"), "vd": ("vd", "vel_d", "v_d", "vdown", "down_velocity"),
    "sd_ve": ("sd_ve", "sdve", "std_ve"), "sd_vn": ("sd_vn", "sdvn", "std_vn"),
    "sd_vu": ("sd_vu", "sdvu", "std_vu"), "sd_vd": ("sd_vd", "sdvd", "std_vd"),
    "quality": ("quality", "q", "mode", "fix_type", "fixtype", "solution_mode", "solmode", "status"),
}
#: (unit kind, unit assumed when neither header nor map gives one)
_FIX_UNITS = {"t": ("time", "s"), "t_arrive": ("time", "s"), "lat": ("angle", "deg"), "lon": ("angle", "deg"),
              "h": ("length", "m"), **{k: ("length", "m") for k in ("sd_n", "sd_e", "sd_u")},
              **{k: ("velocity", "m/s") for k in ("ve", "vn", "vu", "vd", "sd_ve", "sd_vn", "sd_vu", "sd_vd")}}


def parse_quality_filter(spec):
    """``"4,5"`` / ``[4, 5]`` / None -> a set of accepted quality values (None: all)."""
    if spec is None or (isinstance(spec, str) and spec.strip().lower() in ("", "all")):
        return None
    toks = spec.split(",") if isinstance(spec, str) else list(spec)
    try:
        out = {int(str(x).strip()) for x in toks if str(x).strip()}
    except ValueError:
        raise ValueError(f"--fix-quality {spec!r}: give the accepted quality/mode values as "
                         "integers, e.g. 4,5") from None
    if not out:
        raise ValueError(f"--fix-quality {spec!r}: no value given")
    return out


def _fix_select(cols, raw, cmap, path, hline):
    """Column index of every fix quantity the table has: from the map, else by name."""
    names = [c[0] for c in cols]
    out = _resolve_map(cols, raw, cmap, path, hline, "--fix-columns")
    taken = set(out.values())
    for key, aliases in _FIX_NAMES.items():
        if key in out or (key == "vd" and "vu" in out) or (key == "vu" and "vd" in out):
            continue
        hits = [i for i, n in enumerate(names) if i not in taken and (n in aliases or n.rsplit(".", 1)[-1] in aliases)]
        if len(hits) > 1:
            exact = [i for i in hits if names[i] in aliases]
            if len(exact) != 1:
                raise ValueError(f"{where(path, hline)}: {len(hits)} columns could be {key!r} "
                                 f"({', '.join(str(raw[i]) for i in hits)}); name the one to use with "
                                 f"--fix-columns {key}=NAME")
            hits = exact
        if hits:
            out[key] = hits[0]
            taken.add(hits[0])
    miss = [k for k in ("t", "lat", "lon") if k not in out]
    if miss:
        raise ValueError(f"{where(path, hline)}: no {', '.join(miss)} column among "
                         f"{', '.join(map(str, raw))}; name them with --fix-columns "
                         "\"t=NAME[s], lat=NAME[deg], lon=NAME[deg], ...\"")
    return out


def _check_geodetic(col, keep, cols, pick, path, lines):
    """The first kept row whose latitude is beyond ±90° or longitude beyond ±360°: one line
    naming the file, the line, the value and, when the declared unit makes it so, the
    likely unit slip (degrees under a radian header)."""
    for k, lim in (("lat", 90.0), ("lon", 360.0)):
        deg = np.degrees(col[k])
        bad = keep & (np.abs(deg) > lim)
        if bad.any():
            i = int(np.argmax(bad))
            name, un = cols[pick[k]][0], cols[pick[k]][1] or "deg"
            slip = (f" (the column is declared in {un}: values in degrees labelled radians?)"
                    if un.strip().lower().startswith("rad") and abs(deg[i]) <= lim * 180 / np.pi else "")
            raise ValueError(f"{where(path, lines[i])}: {'latitude' if k == 'lat' else 'longitude'} "
                             f"{deg[i]:.6g} deg (column {name!r}) is beyond ±{lim:g} deg{slip}")


def read_fix_table(path, *, columns=None, quality=None) -> tuple:
    """Read position(/velocity) fixes from a CSV (or other delimited text) or Parquet table,
    as units export them.

    Columns are found by name (case-insensitive; ``t``/``time``/``timestamp``..., ``lat``/
    ``latitude``, ``lon``/``longitude``, ``h``/``height``/``altitude``, ``sd_n sd_e sd_u``,
    ``ve vn vu`` or ``vn ve vd`` (NED: down), ``sd_ve``..., a quality/mode column; a dotted
    vendor name ``GnssPosition.Latitude`` by its last part) or through ``columns``, a map
    with units in the syntax of the IMU's (:func:`sinslab.data.columns.parse_column_map`
    with :data:`sinslab.data.columns.FIX_KEYS`, ``--fix-columns``:
    ``"t=time[s], lat=GnssPosition.Latitude[deg], vd=GnssVelocity.Down[m/s], quality=GnssSolution.Mode"``).
    Units from the map, else the header (``lat[rad]``), else t s, lat/lon deg, h m, σ m,
    velocities m/s. Without ``h``: horizontal fixes (NaN height); default σ 1 m and 0.1 m/s.

    ``quality``: the accepted values of the quality/mode column (a set, or ``"4,5"``);
    other rows are dropped. Rows without a position (empty or NaN latitude/longitude: a
    receiver without a fix) are dropped and counted. A *held* stream — a receiver's
    fixes repeated in every row of a faster log (:func:`sinslab.core.stamps.held_runs`)
    — is collapsed to the first row of each receiver epoch.

    Returns ``(Fixes, meta)``; ``meta`` holds ``rows``, ``held`` (rows, epochs) or None,
    ``no_position`` (rows dropped), ``quality_counts`` ({value: rows}), ``quality_kept``,
    ``columns`` (the column of each quantity) and ``velocity_frame`` ("ENU" | "NED" | None).
    """
    from sinslab.core.stamps import held_runs
    cmap = _columns.parse_column_map(columns, keys=_columns.FIX_KEYS, option="--fix-columns")
    keep_q = parse_quality_filter(quality)
    if isinstance(path, (list, tuple)) and len(path) == 1:
        path = path[0]
    if isinstance(path, (list, tuple)):
        # positions and velocities in two tables on one time column
        src = _JoinedSource([Path(p) for p in path], cmap)
        path = src.path
    else:
        path = Path(path)
        if not path.exists():
            raise FileNotFoundError(f"{path}: no such file")
        src = _source(path, cmap)
    cols, hline = src.cols, src.hline
    pick = _fix_select(cols, src.raw, cmap, path, hline)
    keys = list(pick)
    a = _fetch_allow_nan(src, [pick[k] for k in keys])
    lines = src.lines
    col = {}
    for j, k in enumerate(keys):
        if k == "quality":
            col[k] = a[:, j]
            continue
        kind, default = _FIX_UNITS[k]
        un = cols[pick[k]][1] or default
        try:
            col[k] = a[:, j] * units.unit_scale(un, kind)
        except (ValueError, KeyError):
            raise ValueError(f"{where(path, hline)}: column {cols[pick[k]][0]!r} ({k}) has unit {un!r}, "
                             f"not a {kind} unit") from None
    n_rows = a.shape[0]
    meta = {"rows": n_rows, "columns": {k: str(src.raw[i]) for k, i in pick.items()},
            "velocity_frame": "NED" if "vd" in pick else "ENU" if "vu" in pick else None}
    t = col["t"]
    bad = ~np.isfinite(t)
    if bad.any():
        raise ValueError(f"{where(path, lines[int(np.argmax(bad))])}: time stamp is not a finite number")
    keep = np.ones(n_rows, bool)
    if "quality" in col:
        q = col["quality"]
        qi = np.where(np.isfinite(q), q, -1).astype(int)
        vals, cnt = np.unique(qi, return_counts=True)
        meta["quality_counts"] = {int(v): int(c) for v, c in zip(vals, cnt)}
        if keep_q is not None:
            keep &= np.isin(qi, sorted(keep_q))
        meta["quality_kept"] = sorted(keep_q) if keep_q is not None else "all"
    elif keep_q is not None:
        raise ValueError(f"{where(path, hline)}: --fix-quality given but the table has no quality/mode "
                         "column; name it with --fix-columns quality=NAME")
    nopos = ~(np.isfinite(col["lat"]) & np.isfinite(col["lon"]))
    meta["no_position"] = int(np.sum(nopos & keep))
    keep &= ~nopos
    _check_geodetic(col, keep, cols, pick, path, lines)
    for k in ("h", "ve", "vn", "vu", "vd"):
        if k in col:
            b = keep & ~np.isfinite(col[k])
            if b.any():
                raise ValueError(f"{where(path, lines[int(np.argmax(b))])}: NaN/inf or empty value in "
                                 f"column {src.raw[pick[k]]!r} of a row with a position")
    idx = np.flatnonzero(keep)
    if idx.size == 0:
        raise ValueError(f"{path}: no fixes" + (f" with quality in {sorted(keep_q)} (the table has "
                                                 f"{meta.get('quality_counts')})" if keep_q else ""))
    check_stamps(t[idx], path, _LineView(lines, idx))
    J = idx.size
    two_d = "h" not in col
    vel = svel = None
    if "vu" in col or "vd" in col:
        if not ("ve" in col and "vn" in col):
            raise ValueError(f"{where(path, hline)}: a vertical velocity without ve and vn columns")
        vu = col["vu"] if "vu" in col else -col["vd"]
        vel = np.stack([col["ve"], col["vn"], vu], -1)
        su = "sd_vu" if "sd_vu" in col else "sd_vd"
        svel = np.stack([col[k] if k in col else np.full(n_rows, 0.1) for k in ("sd_ve", "sd_vn", su)], -1)
    sig = np.stack([col[k] if k in col else np.full(n_rows, np.nan if (two_d and k == "sd_u") else 1.0)
                    for k in ("sd_n", "sd_e", "sd_u")], -1)
    h = np.full(n_rows, np.nan) if two_d else col["h"]
    changing = [col["lat"], col["lon"], h] + ([] if vel is None else list(vel.T)) + list(sig.T)
    runs = held_runs(np.stack(changing, -1)[idx])
    meta["held"] = None
    if runs is not None:
        meta["held"] = (int(J), int(runs.size))
        idx = idx[runs]
    sel = (lambda x: None if x is None else x[idx])
    q_out = col["quality"][idx].astype(int) if "quality" in col else np.zeros(idx.size, int)
    fx = Fixes(t[idx], col["lat"][idx], col["lon"][idx], h[idx], sig[idx], sel(vel), sel(svel), q_out,
               str(path), col["t_arrive"][idx] if "t_arrive" in col else None)
    return fx, meta


class _LineView:
    """Lines of the kept rows ``idx`` of a table (``lines[idx[i]]``), looked up lazily."""

    def __init__(self, lines, idx):
        self.lines, self.idx = lines, idx

    def __getitem__(self, i):
        return self.lines[int(self.idx[i])]


def _fetch_allow_nan(src, idx):
    """The columns ``idx`` of a table source, empty cells as NaN (a receiver log leaves the
    position empty when it has no fix)."""
    if isinstance(src, (_TextSource, _JoinedSource)):
        return src.fetch(idx, allow_empty=True)
    return src.fetch(idx)


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
