"""Tables written a chunk at a time (sinslab.app.tablefile): the CSV equals pandas' bytes
(every k-th row counted over the whole table, whatever the chunks), the Parquet file holds
every row exactly, and a writer that fails leaves nothing under a final name."""
import numpy as np
import pandas as pd
import pytest

from sinslab.app.outputs import RunDir
from sinslab.app.tablefile import TableWriter


def _table(n, seed=3):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-12, 12, size=(n, 3))
    x[5, 1] = np.nan
    x[8, 2] = -np.inf
    x[13, 0] = -0.0
    return {"t_s": np.arange(n) * 0.02, "a_m": x[:, 0], "b_deg": x[:, 1], "c": x[:, 2]}


@pytest.mark.parametrize("every,chunks", [(1, [1000]), (7, [3, 64, 500, 1, 432]), (50, [333, 667])])
def test_chunks_give_pandas_bytes_and_every_row(tmp_path, every, chunks):
    tab = _table(sum(chunks))
    with TableWriter(tmp_path, "s", list(tab), csv_every=every, parquet=True) as w:
        a = 0
        for m in chunks:
            w.write({k: v[a:a + m] for k, v in tab.items()})
            a += m
    pd.DataFrame(tab).iloc[::every].to_csv(tmp_path / "ref.csv", index=False, float_format="%.10g")
    assert (tmp_path / "s.csv").read_bytes() == (tmp_path / "ref.csv").read_bytes()
    back = pd.read_parquet(tmp_path / "s.parquet")
    assert list(back.columns) == list(tab) and w.rows == len(back) == sum(chunks)
    for k, v in tab.items():                             # every row, bit for bit
        assert np.array_equal(back[k].to_numpy(), v, equal_nan=True)


def test_a_failing_writer_leaves_nothing(tmp_path):
    tab = _table(100)
    with pytest.raises(ValueError, match="columns"):
        with TableWriter(tmp_path, "s", list(tab), csv_every=2, parquet=True) as w:
            w.write(tab)
            w.write({"t_s": tab["t_s"]})                 # a chunk without the other columns
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(KeyboardInterrupt):
        with TableWriter(tmp_path, "s", list(tab), parquet=True) as w:
            w.write(tab)
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_run_folder_table_writer_records_like_write_table(tmp_path):
    tab = _table(2500)
    a = RunDir(tmp_path / "a", "x").prepare()
    b = RunDir(tmp_path / "b", "x").prepare()
    ia = a.write_table("s", tab, "d", large_rows=1000)            # chunked float path
    ib = b.write_table("s", pd.DataFrame(tab), "d", large_rows=1000)    # pandas
    assert ia == ib and ia["csv_every"] == 3 and ia["parquet"] == "s.parquet"
    assert (a.path / "s.csv").read_bytes() == (b.path / "s.csv").read_bytes()
    assert a.files == b.files == ["s.parquet", "s.csv"]


def test_chunked_table_writes_the_files_of_its_whole_table(tmp_path):
    """A table made a chunk of rows at a time gives the files of the same table given whole."""
    from sinslab.app.tablefile import ChunkedTable

    tab = _table(1000)
    calls = []

    def rows(a, b):
        calls.append((a, b))
        return {k: v[a:b] for k, v in tab.items()}

    a = RunDir(tmp_path / "a", "x").prepare()
    b = RunDir(tmp_path / "b", "x").prepare()
    ia = a.write_table("s", ChunkedTable.of(rows, 1000, chunk_rows=300), "d", csv_every=7)
    ib = b.write_table("s", tab, "d", csv_every=7)
    assert ia == ib and calls[1:] == [(0, 300), (300, 600), (600, 900), (900, 1000)]
    assert (a.path / "s.csv").read_bytes() == (b.path / "s.csv").read_bytes()
    pa_, pb = pd.read_parquet(a.path / "s.parquet"), pd.read_parquet(b.path / "s.parquet")
    assert pa_.equals(pb)                       # the same rows (in row groups of other sizes)


_WRITE_PEAK = r"""
import resource, sys
import numpy as np
from sinslab.app.tablefile import ChunkedTable, TableWriter
rows, cols = int(sys.argv[1]), 16
def make(a, b):
    k = np.arange(a, b, dtype=float)
    return {f"c{j}": np.sin(k * (j + 1) * 1e-3) for j in range(cols)}
tab = ChunkedTable.of(make, rows, chunk_rows=1 << 15)
with TableWriter(sys.argv[2], "s", tab.columns, csv_every=50, parquet=True) as w:
    for ch in tab.chunks():
        w.write(ch)
print("PEAK", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def test_peak_memory_of_writing_does_not_grow_with_the_table(tmp_path):
    """1 h and 8 h of 50 Hz filter epochs (16 columns: 23 MB and 184 MB of values) written
    from chunks: the writing process peaks at the same resident memory to within a few
    chunks (a chunk is 4 MB), the files hold every row."""
    import os
    import subprocess
    import sys

    import pyarrow.parquet as pq

    peaks = {}
    for hours in (1, 8):
        rows = hours * 3600 * 50
        d = tmp_path / str(hours)
        d.mkdir()
        r = subprocess.run([sys.executable, "-c", _WRITE_PEAK, str(rows), str(d)], capture_output=True,
                           text=True, env=dict(os.environ, OMP_NUM_THREADS="1"), timeout=300)
        assert r.returncode == 0, r.stderr
        peaks[hours] = int(r.stdout.split("PEAK")[-1]) / 1024            # MB
        assert pq.ParquetFile(d / "s.parquet").metadata.num_rows == rows
    assert peaks[8] - peaks[1] < 16, peaks          # 161 MB more values, the same peak
