"""Bounded cost on garbage: a text log with a binary tail (a crashed logger's preallocated
file padded with NUL bytes, 2 GiB or 200 GiB of it) or binary data amid its lines is
refused at the first bad block with its byte offset and line, after reading no more than
the text before it; a file whose size alone cannot fit in memory read whole is refused
before it is read. The holes are sparse files: no disk is used."""
import os
import subprocess
import sys

import numpy as np
import pytest

from sinslab.data import load_imu
from sinslab.data.load import check_fits, estimate_rows
from sinslab.data.textguard import BinaryData, text_extent

HEAD = "t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n"


def _lines(n, t0=1):
    return "".join(f"{0.01 * k:.2f},0.001,0,0.002,0,0,1\n" for k in range(t0, t0 + n))


def _text(tmp_path, name, n=2000):
    p = tmp_path / name
    p.write_text(HEAD + _lines(n))
    return p, p.stat().st_size


@pytest.mark.parametrize("hole", [2 << 30, 200 << 30], ids=["2GiB", "200GiB"])
def test_a_nul_padded_tail_is_refused_at_its_first_byte(tmp_path, hole):
    p, text = _text(tmp_path, "log.csv")
    os.truncate(p, text + hole)
    assert text_extent(p) == text
    with pytest.raises(BinaryData) as e:
        load_imu(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}:2002: binary data (NUL bytes) from byte {text:,} to the end of the file "
                          f"({text + hole:,} bytes)"), msg
    assert f"head -c {text} {p} > FIXED" in msg and "\n" not in msg


def test_the_command_answers_a_200_gib_hole_at_once(tmp_path):
    """The battery's hang: `allan` on a valid header, some samples and a 200 GiB hole. A
    subprocess with a short timeout: without the guards it would read the hole."""
    p, text = _text(tmp_path, "log.csv")
    os.truncate(p, text + (200 << 30))
    r = subprocess.run([sys.executable, "-m", "sinslab.cli", "-q", "allan", str(p), "--out", str(tmp_path / "a")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert f"binary data (NUL bytes) from byte {text:,}" in r.stderr
    assert not (tmp_path / "a").exists()


def test_nul_bytes_amid_the_lines_stop_the_block_reader_at_their_offset(tmp_path):
    """Beyond the first 64 KiB (where the header check looks) and not a tail: found by the
    block reader, at the exact byte and line."""
    a = (HEAD + _lines(10000)).encode()
    p = tmp_path / "mid.csv"
    p.write_bytes(a + b"\x00" * 300 + _lines(500, 10001).encode())
    assert len(a) > 1 << 16 and text_extent(p) is None
    with pytest.raises(BinaryData, match=rf"mid.csv:10002: binary data \(NUL bytes\) at byte {len(a):,}:"):
        load_imu(p)


def test_binary_bytes_without_nul_are_named_too(tmp_path):
    a = (HEAD + _lines(10000)).encode()
    p = tmp_path / "ff.csv"
    p.write_bytes(a + b"\xff\xfe,,3\n" * 50 + _lines(10, 20000).encode())
    with pytest.raises(BinaryData, match=rf"ff.csv:10002: binary data \(bytes that are not UTF-8 text\) at byte {len(a):,}"):
        load_imu(p)
    q = tmp_path / "long.csv"
    q.write_bytes(a + b"\xff" * (17 << 20) + _lines(10, 20000).encode())
    with pytest.raises(BinaryData, match=rf"long.csv:10002: a line of more than 16,777,216 bytes from byte {len(a):,}"):
        load_imu(q)


def test_a_psins_log_with_a_nul_tail(tmp_path):
    head = "% PSINS\n0 0 0 0 0 0\n34 108.9 380 0 10 9.7946\n0.001 0.001 0.001 1 1 1\n"
    p = tmp_path / "log.imu"
    p.write_text(head + "1 2 3 4 5 10000\n" * 100)
    size = p.stat().st_size
    os.truncate(p, size + (1 << 30))
    with pytest.raises(BinaryData, match=rf"log.imu:105: binary data \(NUL bytes\) from byte {size:,}"):
        load_imu(p)


def test_a_log_whose_size_cannot_fit_is_refused_before_reading(tmp_path):
    """Estimate: the file's size over its first lines' length; need: that many samples times
    the whole reader's bytes per sample."""
    p, size = _text(tmp_path, "big.csv", 3000)
    n = estimate_rows(p, "csv")
    assert abs(n - 3000) <= 30
    check_fits(p, "csv", available=1 << 30)
    with pytest.raises(ValueError, match=r"big.csv: about 3,0\d\d IMU samples; reading it \(csv\) takes about "
                                         r"7\d\d KiB of memory, 100 KiB is available"):
        check_fits(p, "csv", available=100 << 10)


def test_clean_logs_pass_untouched(tmp_path):
    p, _ = _text(tmp_path, "ok.csv", 3000)
    d = load_imu(p)
    assert len(d.imu) == 3000 and np.allclose(d.imu.dv[:, 2] / d.imu.dt, 9.80665)
    assert text_extent(p) is None
