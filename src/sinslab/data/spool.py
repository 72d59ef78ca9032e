"""An IMU table read a block at a time into memory-mapped files (a spool).

:func:`spool_table_imu` reads a CSV or Parquet IMU table as
:func:`sinslab.data.tables.read_table_imu` does — the same columns, units, mount, stamp
checks, rates to increments, gaps bridged and jitter absorbed on a uniform grid — but one
block of rows at a time, writing each block's samples to files in a folder (the run's
scratch folder) instead of growing arrays. The record it returns is an
:class:`~sinslab.core.records.ImuRecord` over memory-mapped files: whoever reads it reads
the windows it needs from the page cache, and lets their pages go
(:func:`sinslab.core.blocks.release_pages`), so a log of any length costs a block of
memory. The numbers are those of the whole-table reader, bit for bit (every step is per
sample or a sequential sum carried across blocks; the median interval is selected exactly,
:func:`sinslab.core.blocks.block_median`).

A table the block reader cannot take as it comes (two files joined on time, whitespace
delimited, a column used twice) or that is malformed anywhere (a non-number, a NaN, a
stamp out of order, a gap longer than allowed, a bad rest flag) is left to the whole-table
reader: :func:`spool_table_imu` returns None, and the whole reader names the file, line
and cause as always.
"""
from __future__ import annotations

import math
import os

import numpy as np

from sinslab.core.blocks import (BLOCK_ROWS, block_median, block_ranges, is_mapped, release_free_memory,
                                 release_pages)
from sinslab.core.records import ImuRecord
from sinslab.data.frames import sensor_to_body
from sinslab.data.increments import ImuData
from sinslab.data.textguard import BinaryData

__all__ = ["spool_table_imu", "SpoolColumn", "map_times", "spooled"]


class SpoolColumn:
    """A float column (rows,) or (rows, width) written a block at a time to
    ``folder/name.bin``, then mapped read-only (:meth:`finish`)."""

    def __init__(self, folder, name, width=0, dtype=np.float64):
        os.makedirs(folder, exist_ok=True)
        self.path = os.path.join(os.fspath(folder), name + ".bin")
        self.width, self.dtype, self.n = int(width), np.dtype(dtype), 0
        self._fh = open(self.path, "wb")

    def append(self, a):
        a = np.ascontiguousarray(a, dtype=self.dtype)
        self._fh.write(a.data)
        self.n += a.shape[0]

    def finish(self):
        """The column as a read-only ``numpy.memmap``."""
        self._fh.close()
        shape = (self.n, self.width) if self.width else (self.n,)
        if self.n == 0:
            return np.zeros(shape, dtype=self.dtype)
        return np.memmap(self.path, dtype=self.dtype, mode="r", shape=shape)


def _diffs(t, rows):
    """``np.diff(t)`` a block at a time (the pages of ``t`` let go after each block)."""
    n = t.shape[0]
    for a, b in block_ranges(n - 1, rows):
        yield np.diff(t[a:b + 1])
        release_pages(t)


def _text_block_bytes(path, skip, rows):
    """Bytes of about ``rows`` lines of a text table (from its first lines after ``skip``)."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    lines = head.split(b"\n")[skip:-1]
    per = (sum(len(x) for x in lines) + len(lines)) / max(len(lines), 1) if lines else 64.0
    return int(max(1 << 12, rows * per))


def spool_table_imu(path, folder, *, block_rows=BLOCK_ROWS, gyro_unit=None, accel_unit=None,
                    time_unit=None, kind=None, frame="rfu", mount=None, max_gap=1.0, allow_gaps=False,
                    columns=None) -> ImuData | None:
    """:func:`sinslab.data.tables.read_table_imu` a block of about ``block_rows`` rows at a
    time, into memory-mapped files in ``folder`` (see the module notes): the same
    :class:`~sinslab.data.increments.ImuData`, its record's arrays mapped from files; None
    when the table must be read whole (then nothing is left in ``folder`` that matters)."""
    from sinslab.data import tables as tb

    if isinstance(path, (list, tuple)):
        if len(path) != 1:
            return None
        path = path[0]
    plan = tb._imu_plan(path, columns, gyro_unit, accel_unit, time_unit, kind)
    src = plan.src
    if isinstance(src, tb._TextSource):
        if src.delim is None or len(set(plan.idx)) != len(plan.idx):
            return None
        blocks = tb.iter_csv_columns(plan.path, src.skip, src.ncol, plan.idx, src.delim,
                                     block_size=_text_block_bytes(plan.path, src.skip, block_rows))
    elif isinstance(src, tb._ParquetSource):
        blocks = tb.iter_parquet_columns(plan.path, [src.raw[i] for i in plan.idx], batch_rows=block_rows)
    else:
        return None
    R = sensor_to_body(mount, frame)
    T, G, A = SpoolColumn(folder, "t_raw"), SpoolColumn(folder, "g_raw", 3), SpoolColumn(folder, "a_raw", 3)
    F = SpoolColumn(folder, "rest", 0, np.bool_) if plan.si is not None else None
    prev = None
    try:
        for data in blocks:
            if not np.isfinite(data[:, :7]).all():
                return None
            t, g, a = plan.convert(data, R)
            if not (np.diff(t if prev is None else np.r_[prev, t]) > 0).all():
                return None
            if F is not None:
                f = data[:, 7]
                if not np.isin(f, (0.0, 1.0)).all():
                    return None
                F.append(f.astype(bool))
            T.append(t)
            G.append(g)
            A.append(a)
            if t.size:
                prev = t[-1]
    except BinaryData:   # the whole reader would stop at the same byte, after reading up to it again
        raise
    except Exception:    # noqa: BLE001 - malformed somewhere: the whole reader says where and why
        return None
    # the blocks' arrays came from malloc's heap, which would keep what they freed
    release_free_memory()
    t, g, a = T.finish(), G.finish(), A.finish()
    n = t.shape[0]
    if n < 2:
        return None
    meta = plan.meta()
    if F is not None:
        meta["stationary"] = (t, F.finish())
    dt_nom = block_median(lambda: _diffs(t, block_rows), n - 1)
    if plan.gk == "rate":
        if _uniform(t, dt_nom, block_rows, rel_tol=1e-4):
            d = (float(t[-1]) - float(t[0])) / (n - 1)        # ImuRecord.from_rates: the mean interval
            if not _uniform(t, d, block_rows):
                return None
            dth, dv = _scaled(folder, g, a, d, block_rows)
            return ImuData(ImuRecord.checked(t, dth, dv, d), np.zeros((0, 2)), str(plan.path), plan.fmt, n,
                           0.0, meta)
        g, a = _rates_to_increments(folder, t, g, a, dt_nom, block_rows)
    out = _uniform_increments(folder, t, g, a, dt_nom, max_gap, allow_gaps, block_rows)
    if out is None:
        return None
    imu, gaps, jitter = out
    return ImuData(imu, gaps, str(plan.path), plan.fmt, n, jitter, meta)


def _uniform(t, dt, rows, rel_tol=1e-3):
    """Every interval of ``t`` within ``rel_tol`` of ``dt`` (the check of an ImuRecord)."""
    return all(np.all(np.abs(d - dt) <= rel_tol * dt) for d in _diffs(t, rows))


def _scaled(folder, g, a, d, rows):
    """``g·d``, ``a·d`` (rates times the interval: increments) into the spool."""
    X, Y = SpoolColumn(folder, "dtheta", 3), SpoolColumn(folder, "dv", 3)
    for p, q in block_ranges(g.shape[0], rows):
        X.append(np.asarray(g[p:q]) * d)
        Y.append(np.asarray(a[p:q]) * d)
        release_pages(g, a)
    return X.finish(), Y.finish()


def _rates_to_increments(folder, t, w, f, dt_nom, rows):
    """:func:`sinslab.data.increments.rates_to_increments` a block at a time (the rates at
    both ends of a gap averaged; each times its actual interval)."""
    X, Y = SpoolColumn(folder, "dtheta_raw", 3), SpoolColumn(folder, "dv_raw", 3)
    t_prev, w_prev, f_prev = float(t[0]) - dt_nom, None, None
    for p, q in block_ranges(t.shape[0], rows):
        tt, ww, ff = np.asarray(t[p:q]), np.array(w[p:q], dtype=float), np.array(f[p:q], dtype=float)
        d = np.diff(np.r_[t_prev, tt])
        big = np.flatnonzero(d > 1.5 * dt_nom)
        big = big[big + p > 0]
        if big.size:
            wl = np.vstack([w_prev if p else ww[:1], ww])      # row i-1 of the original rates
            fl = np.vstack([f_prev if p else ff[:1], ff])
            w_src, f_src = ww.copy(), ff.copy()
            ww[big] = 0.5 * (w_src[big] + wl[big])
            ff[big] = 0.5 * (f_src[big] + fl[big])
            w_last, f_last = w_src[-1:], f_src[-1:]
        else:
            w_last, f_last = ww[-1:].copy(), ff[-1:].copy()
        X.append(ww * d[:, None])
        Y.append(ff * d[:, None])
        t_prev, w_prev, f_prev = float(tt[-1]), w_last, f_last
        release_pages(t, w, f)
    return X.finish(), Y.finish()


def _uniform_increments(folder, t, dth, dv, dt_nom, max_gap, allow_gaps, rows):
    """:func:`sinslab.data.increments.uniform_increments` a block at a time; None where it
    would raise (a gap longer than ``max_gap``, a record it finds not uniform)."""
    n = t.shape[0]
    gaps, ss, cnt, dev_ok = [], 0.0, 0, True
    for k, (p, q) in enumerate(block_ranges(n - 1, rows)):
        d = np.diff(t[p:q + 1])
        gi = np.flatnonzero(d > 1.5 * dt_nom)
        if gi.size:
            if not allow_gaps and np.any(d[gi] > max_gap):
                return None
            gaps.append(np.stack([np.asarray(t[p:q])[gi], d[gi]], -1))
        ok = d <= 1.5 * dt_nom
        ss += float(np.sum((d[ok] - dt_nom) ** 2))
        cnt += int(ok.sum())
        dev_ok &= bool(np.all(np.abs(d - dt_nom) <= 1e-4 * dt_nom))
        release_pages(t)
    gaps = np.concatenate(gaps) if gaps else np.zeros((0, 2))
    jitter = math.sqrt(ss / cnt) if cnt else 0.0
    t0, t1 = float(t[0]), float(t[-1])
    if len(gaps) == 0 and abs(t1 - t0 - (n - 1) * dt_nom) <= 1e-9 * max(1.0, abs(t1)) and dev_ok:
        dt = (t1 - t0) / (n - 1)
        if not _uniform(t, dt, rows):
            return None
        return ImuRecord.checked(t, dth, dv, dt), gaps, jitter
    # cumulative angle and velocity interpolated onto the uniform grid and differenced
    tc0 = t0 - dt_nom
    m = int(math.floor((t1 - tc0) / dt_nom + 1e-9))
    Tg, X, Y = SpoolColumn(folder, "t", 0), SpoolColumn(folder, "dtheta", 3), SpoolColumn(folder, "dv", 3)
    tc_prev, c_prev = tc0, np.zeros((2, 3))
    ci_prev = np.zeros((2, 3))                         # the cumulative sums at grid point 0 (= tc0)
    k_next = 1
    blocks = block_ranges(n, rows)
    for j, (p, q) in enumerate(blocks):
        tc = np.r_[tc_prev, t[p:q]]
        c = [np.cumsum(np.vstack([c_prev[i:i + 1], np.asarray(x[p:q])]), 0) for i, x in enumerate((dth, dv))]
        last = j == len(blocks) - 1
        k_hi = m + 1 if last else min(m + 1, int(math.ceil((tc[-1] - tc0) / dt_nom)) + 2)
        kk = np.arange(k_next, k_hi)
        gv = tc0 + dt_nom * kk
        if not last:
            gv = gv[gv < tc[-1]]
        if gv.size:
            out = []
            for i in range(2):
                ci = np.stack([np.interp(gv, tc, c[i][:, col]) for col in range(3)], -1)
                out.append(np.diff(np.vstack([ci_prev[i:i + 1], ci]), axis=0))
                ci_prev[i] = ci[-1]
            Tg.append(gv)
            X.append(out[0])
            Y.append(out[1])
            k_next += gv.size
        tc_prev = float(tc[-1])
        c_prev = np.stack([c[0][-1], c[1][-1]])
        release_pages(t, dth, dv)
    tg = Tg.finish()
    if tg.shape[0] < 1:
        return None
    dt = (float(tg[-1]) - float(tg[0])) / (tg.shape[0] - 1) if tg.shape[0] > 1 else dt_nom
    if tg.shape[0] > 1 and not _uniform(tg, dt, rows):
        return None
    return ImuRecord.checked(tg, X.finish(), Y.finish(), dt), gaps, jitter


def map_times(imu: ImuRecord, fn, dt, folder, rows=BLOCK_ROWS) -> ImuRecord:
    """``imu`` with times ``fn(t)`` (elementwise; ``dt`` the interval they should have,
    checked as :class:`~sinslab.core.records.ImuRecord` checks it, which keeps the mean
    interval of the new times): for a spooled record the new times are written a block at
    a time into ``folder`` (None or an in-memory record: ``fn(imu.t)`` in memory)."""
    if folder is None or not is_mapped(imu.t):
        return ImuRecord(fn(imu.t), imu.dtheta, imu.dv, dt)
    n = len(imu)
    name = "t_shifted"
    k = 0
    while os.path.exists(os.path.join(os.fspath(folder), name + ".bin")):
        k += 1
        name = f"t_shifted{k}"
    T = SpoolColumn(folder, name)
    for p, q in block_ranges(n, rows):
        T.append(fn(np.asarray(imu.t[p:q])))
        release_pages(imu.t)
    t = T.finish()
    mean = (float(t[-1]) - float(t[0])) / (n - 1) if n > 1 else dt
    if abs(dt - mean) > 1e-3 * mean or not _uniform(t, mean, rows):
        raise ValueError(f"the shifted IMU times are not uniform at {dt} s")
    return ImuRecord.checked(t, imu.dtheta, imu.dv, mean)


def spooled(imu) -> bool:
    """True if ``imu``'s arrays are mapped from files (read it a window at a time)."""
    return is_mapped(getattr(imu, "dtheta", None))

