"""Text readers against binary data: bounded cost on garbage.

A text log that ends in binary data — a logger's preallocated file whose unfilled end is
NUL bytes, a log glued to a binary dump — must be refused where the text ends, not parsed
as one endless line (a 2 GiB hole read as a "line" costs gigabytes and minutes).

- :func:`check_text_tail` looks at the file's last block: if it holds NUL bytes, the start
  of the binary tail is found by bisection over blocks (about 20 reads for 200 GiB) and
  the file is refused at once with that byte offset, before any parsing or any estimate
  of its rows (:func:`text_extent` gives the offset without raising).
- :class:`BlockGuard` checks each block a streaming reader reads: the first NUL byte or
  over-long line ends the read with its byte offset and line.

Both raise :class:`BinaryData`, a ``ValueError`` whose one-line message names the file, the
offset, and how to keep the text part.
"""
from __future__ import annotations

import os

__all__ = ["BinaryData", "BLOCK", "MAX_LINE_BYTES", "text_extent", "check_text_tail", "BlockGuard", "keep_hint"]

#: bytes read per probe of :func:`text_extent`
BLOCK = 1 << 16
#: longest text line accepted [bytes]: far beyond any log's line (a header of tens of
#: thousands of columns is a few hundred kB); a longer "line" is binary data without NULs
MAX_LINE_BYTES = 1 << 24
#: the line number of an offset is counted only this far into a file (it costs a read)
_COUNT_LINES_UP_TO = 1 << 26


class BinaryData(ValueError):
    """Binary data where text was expected (one line: file, byte offset, what to do)."""


def _has_nul(fh, start: int, size: int) -> int:
    """Offset of the first NUL byte in ``[start, start + BLOCK)`` of ``fh``, or -1."""
    fh.seek(start)
    k = fh.read(min(BLOCK, size - start)).find(b"\x00")
    return -1 if k < 0 else start + k


def _nul_from(fh, start: int, size: int) -> bool:
    """True if ``[start, start + BLOCK)`` of ``fh`` (clipped to the file) is all NUL."""
    fh.seek(start)
    return not fh.read(min(BLOCK, size - start)).strip(b"\x00")


def text_extent(path) -> int | None:
    """The byte offset where the file's binary tail of NUL bytes begins (the padding of a
    preallocated file: NULs from there to the end), or None when the file does not end in
    NULs. The first block holding a NUL is found by bisection; from its first NUL on, that
    block and blocks sampled after it must be all NUL — else None (NULs amid the text are
    left to the reader, which stops at the first)."""
    size = os.path.getsize(path)
    if size == 0:
        return None
    with open(path, "rb") as fh:
        fh.seek(size - 1)
        if fh.read(1) != b"\x00":
            return None
        last = (size - 1) // BLOCK
        lo, hi = 0, last
        while lo < hi:
            mid = (lo + hi) // 2
            if _has_nul(fh, mid * BLOCK, size) >= 0:
                hi = mid
            else:
                lo = mid + 1
        off = _has_nul(fh, lo * BLOCK, size)
        probes = {off, *(min(size - 1, (lo + (last - lo) * k // 8) * BLOCK) for k in range(1, 9))}
        if off < 0 or not all(_nul_from(fh, b, size) for b in probes if b >= off):
            return None
        return off


def _line_of(path, offset: int) -> int | None:
    """1-based line number of byte ``offset`` (None beyond :data:`_COUNT_LINES_UP_TO`)."""
    if offset > _COUNT_LINES_UP_TO:
        return None
    n = 1
    with open(path, "rb") as fh:
        left = offset
        while left > 0:
            buf = fh.read(min(left, 1 << 20))
            if not buf:
                break
            n += buf.count(b"\n")
            left -= len(buf)
    return n


def keep_hint(path, offset: int) -> str:
    """How to keep the text part of a file whose data turn binary at ``offset``."""
    return f"keep the text before it (head -c {offset} {os.fspath(path)} > FIXED) and read that"


def check_text_tail(path) -> None:
    """Raise :class:`BinaryData` if the file ends in a binary (NUL) tail (see
    :func:`text_extent`); cost: a few block reads, whatever the file's size."""
    off = text_extent(path)
    if off is None:
        return
    size = os.path.getsize(path)
    line = _line_of(path, off)
    at = f"{path}:{line}" if line is not None else f"{path}"
    raise BinaryData(f"{at}: binary data (NUL bytes) from byte {off:,} to the end of the file "
                     f"({size:,} bytes): the text stops there — a logger's preallocated file never "
                     f"filled, or a cut log? {keep_hint(path, off)}")


class BlockGuard:
    """Checks the blocks a streaming reader reads from ``path``, in order: ``check(buf)``
    raises :class:`BinaryData` at the first NUL byte, naming its byte offset and line."""

    def __init__(self, path, offset: int = 0, line: int = 1):
        self.path, self.offset, self.line = path, int(offset), int(line)

    def check(self, buf) -> None:
        k = buf.find(b"\x00")
        if k >= 0:
            line = self.line + buf.count(b"\n", 0, k)
            raise BinaryData(f"{self.path}:{line}: binary data (NUL bytes) at byte {self.offset + k:,}: "
                             f"not text from there — a corrupt or padded log? "
                             f"{keep_hint(self.path, self.offset + k)}")
        self.offset += len(buf)
        self.line += buf.count(b"\n")

    def long_line(self, pending: int) -> None:
        """Raise if a line has run ``pending`` bytes without an end (binary data without NULs)."""
        if pending > MAX_LINE_BYTES:
            start = self.offset - pending
            raise BinaryData(f"{self.path}:{self.line}: a line of more than {MAX_LINE_BYTES:,} bytes from "
                             f"byte {start:,}: binary data, not text — {keep_hint(self.path, start)}")
