"""Whitespace-delimited tables of decimal numbers (KF-GINS' and PSINS' text files) read by
one compiled pass, giving the doubles ``numpy.loadtxt`` and ``float()`` give.

Exactness: a decimal ``M·10^E`` whose significant digits, trailing zeros dropped, form an
integer ``M <= 2^53`` and whose ``|E| <= 22`` is converted as ``M * 10^E`` or
``M / 10^−E``: both operands are exact doubles and IEEE arithmetic rounds the one product
or quotient correctly, so the result is the correctly rounded value of the decimal
(Clinger's fast path, W. D. Clinger, "How to read floating point numbers accurately",
PLDI 1990) — the value ``float()`` and numpy's parser return. Numbers outside it (more
than 15–16 significant digits, large exponents) are handed to ``float()`` one by one;
anything that is not plain decimal text (``nan``, ``inf``, a comma, a byte that is not
ASCII, a line of another length, a lone carriage return) makes :func:`read_numbers`
decline, and the caller reads the file as before.
"""
from __future__ import annotations

import os

import numpy as np
from numba import njit

__all__ = ["read_numbers"]

#: 10^0 .. 10^22, each an exact double
_POW10 = np.array([10.0 ** k for k in range(23)])
#: largest significand the fast path takes (every integer up to it is a double)
_M_MAX = 2 ** 53
#: at most this many numbers per file go to float() before the file is declined
SLOW_MAX = 1 << 16


_E17 = 10 ** 17


@njit(cache=True)
def _digits(buf, i, n, m, e10, frac):
    """Decimal digits from ``buf[i]`` into the significand ``m`` (at most 18 digits; later
    zeros counted in the exponent ``e10``, a later non-zero digit makes the number
    inexact). Returns ``(i, m, e10, count, inexact)``."""
    count = 0
    inexact = False
    while i < n:
        d = np.int64(buf[i]) - 48
        if d < 0 or d > 9:
            break
        count += 1
        i += 1
        if m < _E17:
            m = m * 10 + d
            if frac:
                e10 -= 1
        elif d > 0:
            inexact = True
        elif not frac:
            e10 += 1
    return i, m, e10, count, inexact


@njit(cache=True)
def _long_significand(buf, i):
    """The significand of more than 18 digits at ``buf[i]`` (a point among them, if any):
    ``(m, e10, inexact)``, its first 18 digits in ``m`` as :func:`_digits` takes them."""
    i, m, e10, _, inexact = _digits(buf, i, buf.size, 0, 0, False)
    if i < buf.size and buf[i] == 46:
        _, m, e10, _, lost = _digits(buf, i + 1, buf.size, m, e10, True)
        inexact |= lost
    return m, e10, inexact


@njit(cache=True)
def _parse(buf, i, row, ns, ncol, out, slow):
    """Rows of ``ncol`` numbers from ``buf[i:]`` into ``out`` from row ``row``; blank lines
    and ``#`` comments skipped. Numbers outside the fast path: ``(row, column, start,
    end)`` into ``slow`` from ``ns``. Returns ``(i, rows, slow count, status)``: status 0
    done, 1 not plain text, 2 ``out`` full (call again from ``i`` with more rows).

    Written as one loop for its speed (~15 ns a number): an inlined helper given ``buf``
    costs an atomic reference-count increment and decrement per call, and an index of a
    signed type costs a test for a negative index per byte; the offsets, never negative,
    index as unsigned (``u(i)``)."""
    n = buf.size
    u = np.uint64
    while i < n:
        if row >= out.shape[0]:
            return i, row, ns, 2
        col = 0
        while i < n:
            c = buf[u(i)]
            if c == 32 or c == 9:
                i += 1
                continue
            if c == 10:
                i += 1
                break
            if c == 13:
                if i + 1 < n and buf[u(i + 1)] == 10:
                    i += 2
                    break
                return i, row, ns, 1
            if c == 35:                                # a comment to the line's end
                while i < n and buf[u(i)] != 10:
                    i += 1
                i += 1
                break
            if col >= ncol:
                return i, row, ns, 1
            a = i
            neg = c == 45
            if neg or c == 43:                         # - +
                i += 1
            # every digit of the significand goes into m; more than 18 (m may have
            # wrapped) are read again by the rule that keeps the first 18
            s = i
            m = 0
            while i < n:
                d = np.int64(buf[u(i)]) - 48
                if d < 0 or d > 9:
                    break
                m = m * 10 + d
                i += 1
            count = i - s
            e10 = 0
            if i < n and buf[u(i)] == 46:              # .
                i += 1
                f = i
                # four digits a step while there are four: one branch, four independent
                # products
                while i + 4 <= n:
                    d0 = np.int64(buf[u(i)]) - 48
                    d1 = np.int64(buf[u(i + 1)]) - 48
                    d2 = np.int64(buf[u(i + 2)]) - 48
                    d3 = np.int64(buf[u(i + 3)]) - 48
                    if not ((d0 >= 0) & (d0 <= 9) & (d1 >= 0) & (d1 <= 9) & (d2 >= 0) & (d2 <= 9)
                            & (d3 >= 0) & (d3 <= 9)):
                        break
                    m = m * 10000 + (d0 * 1000 + d1 * 100 + d2 * 10 + d3)
                    i += 4
                # the rest as the integer part's loop: not a shared helper, which given
                # the buffer costs an atomic reference-count update and its undoing per
                # number
                while i < n:
                    d = np.int64(buf[u(i)]) - 48
                    if d < 0 or d > 9:
                        break
                    m = m * 10 + d
                    i += 1
                e10 = f - i
                count += i - f
            if count == 0:
                return i, row, ns, 1
            inexact = False
            if count > 18:
                m, e10, inexact = _long_significand(buf, s)
            if i < n and (buf[u(i)] == 101 or buf[u(i)] == 69):     # e E
                i += 1
                eneg = False
                if i < n and (buf[u(i)] == 45 or buf[u(i)] == 43):
                    eneg = buf[u(i)] == 45
                    i += 1
                ed = 0
                ev = 0
                while i < n:
                    d = np.int64(buf[u(i)]) - 48
                    if d < 0 or d > 9:
                        break
                    if ev < 100000:
                        ev = ev * 10 + d
                    ed += 1
                    i += 1
                if ed == 0:
                    return i, row, ns, 1
                e10 += -ev if eneg else ev
            if i < n:
                c = buf[u(i)]
                if not (c == 32 or c == 9 or c == 10 or c == 13 or c == 35):
                    return i, row, ns, 1
            exact = not inexact
            v = 0.0
            if exact and m != 0:
                while m > _M_MAX and m % 10 == 0:      # trailing zeros of a long significand
                    m //= 10
                    e10 += 1
                if m > _M_MAX or e10 < -22 or e10 > 22:
                    exact = False
                else:
                    v = float(m)
                    v = v * _POW10[e10] if e10 >= 0 else v / _POW10[-e10]
            if exact:
                out[u(row), u(col)] = -v if neg else v
            else:
                if ns >= slow.shape[0]:
                    return i, row, ns, 1
                slow[ns, 0] = row
                slow[ns, 1] = col
                slow[ns, 2] = a
                slow[ns, 3] = i
                ns += 1
            col += 1
        if col == 0:
            continue
        if col != ncol:
            return i, row, ns, 1
        row += 1
    return i, row, ns, 0


@njit(cache=True)
def _last_line_end(buf, end):
    """Offset after the last line feed of ``buf[:end]`` (0: none)."""
    for j in range(end - 1, -1, -1):
        if buf[j] == 10:
            return j + 1
    return 0


#: bytes read and parsed at a time (a longer line makes :func:`read_numbers` decline)
CHUNK = 1 << 20


def read_numbers(path, skip, ncol):
    """The numbers of a whitespace-delimited text file, or None when it is not plain.

    The file is read a :data:`CHUNK` at a time into one buffer, each chunk's whole lines
    parsed in one compiled call.

    Parameters
    ----------
    path : str or path-like
    skip : int
        Lines at the top that are not data (a header, comments).
    ncol : int
        Numbers on every data line.

    Returns
    -------
    ndarray (N, ncol) float64 or None
        The values ``numpy.loadtxt(path, comments="#", skiprows=skip)`` gives, bit for
        bit; None: the file holds something else than decimal numbers in ``ncol``
        columns, blank lines and ``#`` comments (the caller's general reader then reads it
        and says what is wrong).
    """
    buf = np.empty(CHUNK, dtype=np.uint8)
    view = memoryview(buf)
    slow = np.empty((SLOW_MAX, 4), dtype=np.int64)
    with open(path, "rb") as fh:
        for _ in range(skip):
            fh.readline()
        first = fh.tell()
        line = len(fh.readline())
        fh.seek(first)
        # rows for the file's length at the first line's, a tenth more; grown if short
        cap = 16 + int(1.1 * (os.fstat(fh.fileno()).st_size - first) / max(line, 2))
        out = np.empty((cap, ncol))
        rows = keep = 0
        while True:
            got = fh.readinto(view[keep:])
            end = keep + got
            n = end if got == 0 else _last_line_end(buf, end)
            if n == 0 and end == CHUNK:
                return None                    # a line longer than the buffer
            i = 0
            while True:
                i, rows, ns, status = _parse(buf[:n], i, rows, 0, ncol, out, slow)
                if status == 1:
                    return None
                for r, c, a, b in slow[:ns].tolist():
                    out[r, c] = float(bytes(view[a:b]))
                if status == 0:
                    break
                more = np.empty((2 * out.shape[0], ncol))
                more[:rows] = out[:rows]
                out = more
            keep = end - n
            buf[:keep] = buf[n:end]
            if got == 0:
                break
    # the rows beyond the last were never written: their pages were never touched
    return out[:rows]
