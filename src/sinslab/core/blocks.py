"""Long arrays a block at a time: block ranges, the exact median of values met block by
block, and letting the pages of memory-mapped arrays go.

A record spilled to memory-mapped files (an IMU log read a block at a time, a filter's
per-epoch record) is walked in blocks; what is computed from it is computed from one
block at a time, and the pages a block touched are let go before the next one
(:func:`release_pages`), so the process holds a block, not the record.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import mmap
import sys

import numpy as np
from typing import Any, Callable, Iterable

__all__ = ["BLOCK_ROWS", "block_ranges", "release_pages", "block_median", "kth_smallest", "is_mapped",
           "release_free_memory"]

#: rows of a record read or computed at once when it is walked a block at a time
BLOCK_ROWS = 1 << 16


def block_ranges(n: int, rows: int = BLOCK_ROWS, multiple: int = 1) -> list[tuple[int, int]]:
    """``(a, b)`` ranges covering ``0..n`` in blocks of about ``rows`` rows (a multiple of
    ``multiple``; the last block holds what is left)."""
    step = max(multiple, (max(1, int(rows)) // multiple) * multiple)
    return [(a, min(n, a + step)) for a in range(0, n, step)]


def is_mapped(a: object) -> bool:
    """True if ``a`` is a memory-mapped array (or a view of one): read it a window at a
    time and let the pages go."""
    b = a
    while isinstance(b, np.ndarray):
        if isinstance(b, np.memmap):
            return True
        b = b.base
    return isinstance(b, mmap.mmap)


def release_pages(*arrays: object) -> None:
    """Let the pages of memory-mapped arrays go from this process' resident memory.

    For each ``numpy.memmap`` (or view of one) the file mapping is told it is not needed
    (``MADV_DONTNEED``): a shared file mapping keeps its data in the file and the page
    cache, and a later read maps it back in from there. So a record spilled to disk and
    walked a chunk at a time holds one chunk in the process, not every chunk it has
    touched. An object with a ``release_pages()`` method (a view over several arrays) is
    asked to release its own; anything else is left alone.
    """
    for a in arrays:
        if hasattr(a, "release_pages"):
            a.release_pages()
            continue
        if not isinstance(a, np.ndarray):
            continue
        b: Any = a
        while b is not None and not isinstance(b, mmap.mmap):
            b = getattr(b, "base", None)
        if b is not None and hasattr(mmap, "MADV_DONTNEED"):
            b.madvise(mmap.MADV_DONTNEED)


def _keys(x):
    """float64 -> uint64 keys in the order of the values (negative values' bits flipped)."""
    u = np.ascontiguousarray(x, dtype=np.float64).view(np.uint64)
    neg = (u >> np.uint64(63)).astype(bool)
    return np.where(neg, ~u, u | np.uint64(1 << 63))


def kth_smallest(blocks: Callable[[], Iterable[np.ndarray]], k: int, n: int | None = None) -> float:
    """The ``k``-th smallest (0-based) of the values of ``blocks()`` (a function returning
    a new iterator of 1-D float arrays each time; NaN-free), exactly, holding one block
    and a histogram: a radix selection on the values' bit patterns, 16 bits a pass, the
    candidates gathered and partitioned once they are few."""
    prefix, shift, rank = np.uint64(0), 64, int(k)
    for _ in range(4):
        shift -= 16
        counts = np.zeros(1 << 16, dtype=np.int64)
        hi = 64 - (shift + 16)
        for blk in blocks():
            key = _keys(blk)
            if hi:
                key = key[(key >> np.uint64(shift + 16)) == (prefix >> np.uint64(shift + 16))]
            counts += np.bincount(((key >> np.uint64(shift)) & np.uint64(0xFFFF)).astype(np.int64),
                                  minlength=1 << 16)
        cum = np.cumsum(counts)
        b = int(np.searchsorted(cum, rank, side="right"))
        rank -= int(cum[b - 1]) if b else 0
        prefix = prefix | (np.uint64(b) << np.uint64(shift))
        if shift == 0:              # every bit of the key known: the value itself
            u = prefix & ~np.uint64(1 << 63) if prefix >> np.uint64(63) else ~prefix
            return float(np.array([u], dtype=np.uint64).view(np.float64)[0])
        if counts[b] <= BLOCK_ROWS:
            top = np.uint64(shift)
            cand = [np.asarray(blk, dtype=np.float64)[(_keys(blk) >> top) == (prefix >> top)]
                    for blk in blocks()]
            return float(np.partition(np.concatenate(cand), rank)[rank])
    raise AssertionError("unreachable")


def block_median(blocks: Callable[[], Iterable[np.ndarray]], n: int) -> float:
    """``numpy.median`` of the ``n`` values of ``blocks()`` (see :func:`kth_smallest`),
    the same number: the middle value, or the mean of the two middle ones."""
    if n < 1:
        raise ValueError("the median of no values")
    if n % 2:
        return float(kth_smallest(blocks, n // 2))
    return float(np.mean(np.array([kth_smallest(blocks, n // 2 - 1), kth_smallest(blocks, n // 2)])))


def _malloc_trim():
    """glibc's ``malloc_trim`` (None where the C library has none)."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None)
        return getattr(libc, "malloc_trim", None)
    except OSError:
        return None


_TRIM = _malloc_trim() if sys.platform.startswith("linux") else None


def release_free_memory() -> None:
    """Give the memory this process has freed back to the system.

    Allocators keep freed memory for later use: glibc's malloc keeps freed blocks in its
    heap (numpy arrays of up to tens of MB come from there once larger ones have been
    freed), and pyarrow's allocator keeps its pages. Between the stages of a command,
    whose working sets differ (filtering, then writing tables, then drawing), that memory
    would stay resident and add up; released, the next stage reuses the system's pages.
    Costs a few milliseconds; does nothing where neither allocator is in use.
    """
    pa = sys.modules.get("pyarrow")
    if pa is not None:
        pa.default_memory_pool().release_unused()
    if _TRIM is not None:
        _TRIM(0)
