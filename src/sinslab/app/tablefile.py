"""Tables written a chunk at a time: a Parquet file of every row and a CSV of every k-th.

A run's long series (the navigation solution at every filter epoch: tens of columns,
hundreds of thousands of rows per hour) are written by :class:`TableWriter` from chunks of
rows as they come, so the memory a table needs is one chunk, whatever the length of the
run — no DataFrame, no Arrow table of the whole series beside the arrays it is made of.

Both files are written under hidden temporary names next to their final ones
(:func:`sinslab.core.atomic.atomic_path`) and renamed only when the last chunk is in
(:meth:`TableWriter.close`); a failure or an interrupt on the way removes them, so no
half-written table ever carries its final name.

The CSV holds every ``csv_every``-th row counted over the whole table (rows 0, k, 2k, ...,
whatever the chunk boundaries), its floats formatted as ``%.10g`` with NaN as an empty
field: byte for byte what ``pandas.DataFrame.to_csv(index=False, float_format="%.10g")``
writes for float columns (:func:`csv_rows`).
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from sinslab.core.atomic import atomic_path

__all__ = ["TableWriter", "ChunkedTable", "csv_rows", "float_columns"]


def float_columns(table) -> dict | None:
    """``{name: float 1-D array}`` of a dict of equal-length 1-D float columns whose
    names a CSV can hold unquoted; None for anything else (integer or text columns,
    DataFrames), which the caller writes another way."""
    if not isinstance(table, dict) or not table:
        return None
    cols = {str(k): np.asarray(v) for k, v in table.items()}
    shapes = {c.shape for c in cols.values()}
    if (len(shapes) != 1 or len(next(iter(shapes))) != 1
            or any(c.dtype.kind != "f" for c in cols.values())
            or any(ch in k for k in cols for ch in ',"\n\r')):
        return None
    return cols


@dataclass(frozen=True)
class ChunkedTable:
    """A float table made a chunk of rows at a time as it is written: ``rows(a, b)`` gives
    ``{column: 1-D float array}`` of rows ``a..b−1`` (every chunk the same columns), so a
    table computed from a run's arrays never exists whole beside them.

    ``chunk_rows`` rows per call; :meth:`of` reads the column names from the first row.
    """

    columns: tuple
    n_rows: int
    rows: Callable[[int, int], dict]
    chunk_rows: int = 1 << 15

    @classmethod
    def of(cls, rows, n_rows, chunk_rows=1 << 15):
        return cls(tuple(rows(0, min(1, n_rows))), int(n_rows), rows, int(chunk_rows))

    def chunks(self):
        """The table's chunks, in order."""
        for a in range(0, self.n_rows, self.chunk_rows):
            yield self.rows(a, min(a + self.chunk_rows, self.n_rows))


def csv_rows(cols) -> str:
    """CSV text of the rows of ``cols`` (dict of equal-length float arrays), one line per
    row ending in a newline, floats as ``%.10g`` and NaN as an empty field."""
    arr = np.column_stack([np.asarray(c, dtype=float) for c in cols.values()])
    if not len(arr):
        return ""
    text = np.char.mod("%.10g", arr)
    text[np.isnan(arr)] = ""
    return "\n".join(",".join(row) for row in text.tolist()) + "\n"


#: rows of CSV text formatted at once by :meth:`TableWriter.write`
CSV_SLICE_ROWS = 1024


class TableWriter:
    """Write a float table into ``folder`` as ``NAME.csv`` (every ``csv_every``-th row) and,
    with ``parquet=True``, ``NAME.parquet`` (every row), a chunk of rows at a time.

    Use as a context manager (the files are renamed into place when the block ends
    normally, removed when it raises), or call :meth:`close` / :meth:`discard`::

        with TableWriter(folder, "solution", columns, csv_every=50) as w:
            for chunk in chunks:            # {column: 1-D float array}, same columns each time
                w.write(chunk)

    Parameters
    ----------
    folder : path-like
        Where the files go (a run's staging folder).
    name : str
        Table name (file stem).
    columns : sequence of str
        Column names, in order; every chunk has exactly these.
    csv_every : int
        Keep every k-th row (counted from the table's first row) in the CSV.
    parquet : bool
        Also write every row as Parquet (float64 columns, one row group per chunk).
    """

    def __init__(self, folder, name, columns, *, csv_every=1, parquet=False):
        self.folder, self.name = Path(folder), str(name)
        self.columns = [str(c) for c in columns]
        self.every = max(1, int(csv_every))
        self.rows = 0
        self._stack = contextlib.ExitStack()
        self._pq = None
        try:
            csv_tmp = self._stack.enter_context(atomic_path(self.folder / f"{self.name}.csv"))
            self._csv = self._stack.enter_context(open(csv_tmp, "w", encoding="utf-8", newline=""))
            self._csv.write(",".join(self.columns) + "\n")
            if parquet:
                import pyarrow as pa
                import pyarrow.parquet as pq

                pq_tmp = self._stack.enter_context(atomic_path(self.folder / f"{self.name}.parquet"))
                self._schema = pa.schema([(c, pa.float64()) for c in self.columns])
                # plain encoding: a float column of navigation data has few repeated values,
                # so the dictionary pyarrow tries first is given up after costing ~1 kB of
                # memory per row of a chunk and four times the CPU, and the file comes out
                # larger than plain
                self._pq = pq.ParquetWriter(pq_tmp, self._schema, use_dictionary=False)
                self._stack.callback(self._pq.close)     # closed before its rename
        except BaseException:
            self.discard()
            raise

    @property
    def files(self) -> list[str]:
        """The file names this writer produces."""
        return [f"{self.name}.csv"] + ([f"{self.name}.parquet"] if self._pq is not None else [])

    def write(self, chunk) -> None:
        """Append the rows of ``chunk`` (``{column: 1-D float array}``, the writer's columns)."""
        if list(map(str, chunk)) != self.columns:
            raise ValueError(f"table {self.name}: a chunk has columns {list(chunk)}, the table {self.columns}")
        cols = [np.asarray(chunk[c], dtype=float) for c in chunk]
        m = cols[0].shape[0] if cols else 0
        if any(c.shape != (m,) for c in cols):
            raise ValueError(f"table {self.name}: the columns of a chunk differ in length")
        if m == 0:
            return
        if self._pq is not None:
            import pyarrow as pa

            # from the arrays' buffers (no copy; pa.array of a numpy array would import pandas)
            arrs = [pa.Array.from_buffers(pa.float64(), m, [None, pa.py_buffer(np.ascontiguousarray(c))])
                    for c in cols]
            self._pq.write_table(pa.Table.from_arrays(arrs, schema=self._schema))
        first = (-self.rows) % self.every               # the chunk's first row kept in the CSV
        if first < m:
            kept = [a[first::self.every] for a in cols]
            # formatted a slice at a time: the text of a whole chunk (fixed-width strings,
            # then one Python string per field) takes several times the chunk's own memory
            for b in range(0, kept[0].shape[0], CSV_SLICE_ROWS):
                self._csv.write(csv_rows({c: a[b:b + CSV_SLICE_ROWS] for c, a in zip(self.columns, kept)}))
        self.rows += m

    def close(self) -> None:
        """Finish both files and rename them to their final names."""
        self._stack.close()

    def discard(self) -> None:
        """Remove what was written (nothing keeps its final name)."""
        self._stack.__exit__(RuntimeError, RuntimeError("discarded"), None)

    def __enter__(self):
        return self

    def __exit__(self, et, ev, tb):
        if et is None:
            self.close()
        else:
            self._stack.__exit__(et, ev, tb)
        return False
