"""`sinslab navigate` estimates its memory before reading the IMU log: the sample count
estimate against the true count (text: within 2 %; Parquet: exact), the need of a log
read a block at a time (bounded but for the fixes) and of one read whole (per sample), and
a log that cannot fit refused with one line, exit status 2 and nothing written."""
import numpy as np
import pytest
from typer.testing import CliRunner

from sinslab.app.commands import navigate as nav
from sinslab.core.records import ImuRecord
from sinslab.data import write_imu


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("mem")
    rng = np.random.default_rng(0)
    n = 5000
    imu = ImuRecord(0.005 * np.arange(1, n + 1), rng.normal(scale=1e-5, size=(n, 3)),
                    rng.normal(scale=1e-3, size=(n, 3)) + [0, 0, 0.049])
    write_imu(d / "imu.csv", imu, "csv")
    write_imu(d / "imu.parquet", imu, "parquet")
    (d / "fx.csv").write_text("t[s],lat[deg],lon[deg],h[m]\n1.0,30,110,10\n2.0,30,110,10\n")
    return d, n


def test_sample_estimate(logs):
    d, n = logs
    assert abs(nav.estimate_samples(d / "imu.csv", "csv") - n) <= 0.02 * n
    assert nav.estimate_samples(d / "imu.parquet", "parquet") == n
    assert nav.estimate_samples(d / "imu.csv", "mat") is None


def test_need_of_a_log_read_in_blocks(logs):
    """A plain table is read a block at a time: fixed + one block + the filter's record
    (up to its spill size) + the fixes; with smoothing the smoothed solution per sample
    and the smoother's record in memory, at most."""
    d, n = logs
    plain = nav.check_memory(d / "imu.parquet", "parquet", False, available=1 << 40)
    with_fixes = nav.check_memory(d / "imu.parquet", "parquet", False, available=1 << 40, fix_path=d / "fx.csv")
    smooth = nav.check_memory(d / "imu.parquet", "parquet", True, available=1 << 40)
    assert plain == nav.MEMORY_FIXED + nav.MEMORY_BLOCK + n * nav.MEMORY_RECORD_PER_SAMPLE
    assert with_fixes - plain == 2 * nav.MEMORY_PER_FIX
    assert smooth - plain == (n * (nav.MEMORY_PER_SAMPLE[True] - nav.MEMORY_PER_SAMPLE[False])
                              + nav.SMOOTH_SPILL_ABOVE)


def test_need_of_a_long_log_read_in_blocks_is_bounded(logs, monkeypatch):
    """1 h and 8 h at 200 Hz (as the sample estimate says): the same need (the record on
    disk beyond its spill size), where a log read whole needs 8 times the per-sample part."""
    d, _ = logs
    need = {}
    for h in (1, 8):
        monkeypatch.setattr(nav, "estimate_samples", lambda p, f, h=h: h * 720_000 if f == "parquet" else 0)
        need[h] = nav.check_memory(d / "imu.parquet", "parquet", False, available=1 << 40)
    assert need[8] == need[1] < nav.MEMORY_FIXED + 720_000 * nav.MEMORY_PER_SAMPLE[False]


def test_need_of_a_log_read_whole_grows_with_samples(logs, monkeypatch):
    d, n = logs
    monkeypatch.setattr(nav, "IMU_BLOCK_ROWS", 0)               # read whole
    plain = nav.check_memory(d / "imu.parquet", "parquet", False, available=1 << 40)
    smooth = nav.check_memory(d / "imu.parquet", "parquet", True, available=1 << 40)
    assert plain == nav.MEMORY_FIXED + n * nav.MEMORY_PER_SAMPLE[False]
    assert smooth - plain == (n * (nav.MEMORY_PER_SAMPLE[True] - nav.MEMORY_PER_SAMPLE[False])
                              + nav.SMOOTH_SPILL_ABOVE)       # the record in memory, at most


def test_refused_in_one_line(logs, tmp_path, monkeypatch):
    from sinslab.app import validate
    from sinslab.cli import app

    d, _ = logs
    monkeypatch.setattr(validate, "available_memory", lambda: 100 * 2 ** 20)
    out = tmp_path / "run"
    res = CliRunner().invoke(app, ["-q", "navigate", "--imu", str(d / "imu.csv"), "--fixes", str(d / "fx.csv"),
                                   "--out", str(out)])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and "IMU samples" in lines[0] and "100 MiB is available" in lines[0], res.output
    assert not out.exists()


def test_a_nul_tail_is_no_samples(logs, tmp_path, monkeypatch):
    """A logger's preallocated file: the text, then a 200 GiB hole of NUL bytes (sparse: no
    disk used). The estimate counts the text's rows only, so --smooth is not refused for
    memory the hole would need; the reader refuses the hole at its byte offset."""
    from sinslab.app import validate
    from sinslab.cli import app

    d, n = logs
    padded = tmp_path / "padded.csv"
    padded.write_bytes((d / "imu.csv").read_bytes())
    text = padded.stat().st_size
    with open(padded, "r+b") as fh:
        fh.truncate(200 * 2 ** 30)
    assert abs(nav.estimate_samples(padded, "csv") - n) <= 0.02 * n
    monkeypatch.setattr(validate, "available_memory", lambda: 4 * 2 ** 30)
    out = tmp_path / "run"
    res = CliRunner().invoke(app, ["-q", "navigate", "--imu", str(padded), "--fixes", str(d / "fx.csv"), "--smooth",
                                   "--out", str(out)])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1 and f"binary data (NUL bytes) from byte {text:,}" in lines[0], res.output
    assert not out.exists()
