"""The batched CSV column reader (sinslab.data.tables.read_csv_columns) against numpy's
text parser: the same numbers whatever the block size (one batch, many batches, a row
count estimate that falls short and grows), and an empty cell refused."""
import numpy as np
import pytest

from sinslab.data.tables import read_csv_columns


@pytest.fixture()
def table(tmp_path):
    rng = np.random.default_rng(3)
    a = rng.normal(size=(3000, 5)) * np.array([1.0, 1e-6, 1e3, 1e-12, 7.0])
    p = tmp_path / "t.csv"
    np.savetxt(p, a, delimiter=",", fmt="%.17g", header="a,b,c,d,e", comments="")
    return p, a


@pytest.mark.parametrize("block", [1 << 20, 4096, 1000])
def test_same_numbers_any_block(table, block):
    p, a = table
    got = read_csv_columns(p, 1, 5, [3, 0, 4], ",", block_size=block)
    np.testing.assert_array_equal(got, np.loadtxt(p, delimiter=",", skiprows=1)[:, [3, 0, 4]])
    assert got.shape == (3000, 3) and got.flags.c_contiguous


def test_empty_cell(tmp_path):
    p = tmp_path / "e.csv"
    p.write_text("a,b\n1,2\n3,\n")
    with pytest.raises(ValueError, match="empty cell"):
        read_csv_columns(p, 1, 2, [0, 1], ",")


@pytest.mark.parametrize("rows", [1 << 16, 700, 1])
def test_parquet_same_numbers_any_batch(table, tmp_path, rows):
    import pyarrow as pa
    import pyarrow.parquet as pq

    from sinslab.data.tables import read_parquet_columns

    _, a = table
    p = tmp_path / "t.parquet"
    pq.write_table(pa.table({k: a[:, i] for i, k in enumerate("abcde")}), p, row_group_size=1000)
    got = read_parquet_columns(p, ["d", "a", "e"], batch_rows=rows if rows > 1 else 3)
    np.testing.assert_array_equal(got, a[:, [3, 0, 4]])


def test_parquet_not_numeric(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    from sinslab.data.tables import read_parquet_columns

    p = tmp_path / "s.parquet"
    pq.write_table(pa.table({"a": [1.0, 2.0], "b": ["x", "y"]}), p)
    with pytest.raises(ValueError, match="column 'b' is not numeric"):
        read_parquet_columns(p, ["a", "b"])


def test_blocks_one_at_a_time_make_the_table(table, tmp_path):
    """The block iterators yield the table in pieces of at most one block (CSV: a block of
    bytes; Parquet: a batch of rows) whose concatenation is the whole table."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from sinslab.data.tables import iter_csv_columns, iter_parquet_columns

    p, a = table
    blocks = list(iter_csv_columns(p, 1, 5, [1, 2], ",", block_size=4096))
    shortest = min(len(ln) + 1 for ln in p.read_bytes().split(b"\n")[1:] if ln)
    assert len(blocks) > 10 and max(b.shape[0] for b in blocks) <= 4096 // shortest
    np.testing.assert_array_equal(np.concatenate(blocks), a[:, [1, 2]])
    q = tmp_path / "n.parquet"
    pq.write_table(pa.table({"a": pa.array([1.0, None, 3.0, 4.0]), "i": pa.array([1, 2, 3, 4])}), q)
    blocks = list(iter_parquet_columns(q, ["a", "i"], batch_rows=3))
    assert [b.shape for b in blocks] == [(3, 2), (1, 2)]
    got = np.concatenate(blocks)             # a null as NaN, integers as floats
    np.testing.assert_array_equal(got, [[1, 1], [np.nan, 2], [3, 3], [4, 4]])


def test_empty_cells_allowed_read_as_nan(tmp_path):
    p = tmp_path / "e.csv"
    p.write_text("a,b\n1,2\n3,\n,5\n")
    np.testing.assert_array_equal(read_csv_columns(p, 1, 2, [1, 0], ",", allow_empty=True),
                                  [[2, 1], [np.nan, 3], [5, np.nan]])
