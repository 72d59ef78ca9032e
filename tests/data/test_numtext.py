"""The compiled reader of whitespace-delimited decimal text gives numpy.loadtxt's doubles
(the correctly rounded values of Python's float()) bit for bit, and declines what is not
plain decimal text."""
import numpy as np
import pytest

from sinslab.data import numtext
from sinslab.data.numtext import read_numbers


def _bits(a):
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


AWKWARD = [
    # Clinger's fast-path edges: 2^53 and one past it, 10^22 and 10^23, 22-digit exponents
    "9007199254740992", "9007199254740993", "-9007199254740993e-5", "1e22", "1e23", "1e-22",
    "1e-23", "123456789012345678", "1234567890123456789", "12345678901234567890123",
    "0.1", "0.2", "0.3", "1.7976931348623157e308", "2.2250738585072014e-308", "4.9e-324",
    "2.4703282292062327e-324", "1e-400", "1e400", "-1e400",
    # halfway and near-halfway cases (round to even)
    "9007199254740993.0", "9007199254740995", "0.50000000000000011102230246251565404",
    "1.00000000000000011102230246251565404236316680908203125",
    "7.2057594037927933e16", "8.589973e9",
    # zeros, signs, forms
    "0", "-0", "+0", "0.000", "-0.0e5", "0e-999", "0e999", "+1", "-1.", ".5", "-.5", "5.",
    "1E5", "1e+05", "1e-05", "001.2500", "000000000000000000000000001",
    "1000000000000000000000000", "100000000000000000000000.5",
    "0.00000000000000000000000000012345", "3600.000000000", "357076.005000000",
    "-2.703075907642e-07", "4.221897912060e-07", "123456.78901234567890e-3",
]


def test_awkward_numbers_equal_float_and_loadtxt(tmp_path):
    """Each awkward decimal as float() gives it, and numpy.loadtxt on the same file."""
    rng = np.random.default_rng(3)
    vals = AWKWARD + [repr(float(x)) for x in rng.standard_normal(200) * 10.0 ** rng.integers(-30, 30, 200)]
    vals += [f"{x:.12e}" for x in rng.standard_normal(200)] + [f"{x:.9f}" for x in rng.uniform(0, 6e5, 200)]
    vals += [f"{x:.17g}" for x in rng.uniform(-1, 1, 200)]
    ncol = 5
    vals += ["1"] * (-len(vals) % ncol)
    rows = [vals[i:i + ncol] for i in range(0, len(vals), ncol)]
    path = tmp_path / "awkward.txt"
    lines = ["# a comment line", ""]
    for k, r in enumerate(rows):
        sep = "\t" if k % 3 == 0 else "  " if k % 3 == 1 else " "
        lines.append((" " if k % 2 else "") + sep.join(r) + ("  # trailing note" if k % 5 == 0 else ""))
    path.write_text("\r\n".join(lines[:10]) + "\r\n" + "\n".join(lines[10:]) + "\n")
    got = read_numbers(path, 0, ncol)
    assert got is not None
    ref = np.array([[float(x) for x in r] for r in rows])
    assert np.array_equal(_bits(got), _bits(ref))
    lt = np.loadtxt(path, comments="#", ndmin=2)
    assert np.array_equal(_bits(got), _bits(lt))


def test_chunks_growth_and_skipped_header(tmp_path, monkeypatch):
    """Lines across the buffer's edge, a first line longer than the rest (the row estimate
    short: the output grows) and skipped header lines give the same numbers."""
    monkeypatch.setattr(numtext, "CHUNK", 256)
    rng = np.random.default_rng(4)
    x = rng.standard_normal((300, 3))
    body = "\n".join(f"{a:.12e} {b:.6f} {float(c)!r}" for a, b, c in x)
    path = tmp_path / "t.txt"
    path.write_text("t gx gy\n" + "1" + " " * 200 + "2 3\n" + body)        # no final line feed
    got = read_numbers(path, 1, 3)
    assert np.array_equal(_bits(got[1:]), _bits(np.array([[float(f"{a:.12e}"), float(f"{b:.6f}"), c]
                                                          for a, b, c in x])))
    assert got[0].tolist() == [1.0, 2.0, 3.0]


@pytest.mark.parametrize("text", ["1 2\n3 nan\n", "1 2\n3 inf\n", "1 2\n3,5 4\n", "1 2\n3 4 5\n",
                                  "1 2\n3\n", "1 2\r3 4\n", "1 2\n1_0 4\n", "1 2\n0x10 4\n",
                                  "1 2\n- 4\n", "1 2\n1e 4\n", "1 2\n1.2.3 4\n", "1 2\n\u00b5 4\n",
                                  "1 2\n3\v4\n"])
def test_declines_what_is_not_plain_decimal_text(tmp_path, text):
    """Anything else (non-numbers, other lengths, a lone carriage return, other bytes)
    is left to the general reader, which reads or refuses it as before."""
    path = tmp_path / "x.txt"
    path.write_bytes(text.encode("utf-8"))
    assert read_numbers(path, 0, 2) is None


def test_many_long_numbers_fall_back(tmp_path, monkeypatch):
    """Numbers outside the fast path beyond SLOW_MAX: declined, not misread."""
    monkeypatch.setattr(numtext, "SLOW_MAX", 4)
    path = tmp_path / "x.txt"
    path.write_text("\n".join(f"0.1234567890123456{k} 1" for k in range(7)) + "\n")     # 2^53 < M
    assert read_numbers(path, 0, 2) is None
    path.write_text("0.5 1\n0.25 2\n")
    assert read_numbers(path, 0, 2).tolist() == [[0.5, 1.0], [0.25, 2.0]]


def _random_decimal(rng):
    """A decimal in any of the forms float() reads: sign, integer and fraction digits
    (none to 25, runs of leading or trailing zeros), exponent with sign and zeros."""
    def digits(k):
        d = "".join(rng.choice(list("0123456789"), k)) if k else ""
        r = rng.random()
        return "0" * int(rng.integers(1, 8)) + d if r < 0.15 else d + "0" * int(rng.integers(1, 8)) if r < 0.3 else d
    long_ = rng.random() < 0.1
    ni = int(rng.integers(0, 26 if long_ else 8))
    nf = int(rng.integers(0, 26 if long_ else 16))
    a, b = digits(ni), digits(nf)
    if not a and not b:
        a = str(rng.integers(0, 10))
    s = a + ("." + b if b or rng.random() < 0.2 else "")
    if rng.random() < 0.6:
        e = str(int(rng.integers(0, 40 if rng.random() < 0.9 else 400)))
        s += str(rng.choice(["e", "E"])) + str(rng.choice(["", "+", "-"])) + "0" * int(rng.integers(0, 3) == 0) + e
    return str(rng.choice(["", "", "-", "+"])) + s


def test_random_decimals_equal_float_and_loadtxt(tmp_path):
    """Fuzz: 20 000 random decimals (the fast path's every branch: significands of 1 to
    more than 18 digits, exponents inside and beyond ±22, signed zeros) read as float()
    and numpy.loadtxt read them, bit for bit."""
    rng = np.random.default_rng(11)
    ncol = 5
    vals = [_random_decimal(rng) for _ in range(20000)]
    rows = [vals[i:i + ncol] for i in range(0, len(vals), ncol)]
    path = tmp_path / "fuzz.txt"
    path.write_text("\n".join(" ".join(r) for r in rows) + "\n")
    got = read_numbers(path, 0, ncol)
    assert got is not None
    ref = np.array([[float(x) for x in r] for r in rows])
    assert np.array_equal(_bits(got), _bits(ref))
    assert np.array_equal(_bits(got), _bits(np.loadtxt(path, ndmin=2)))
