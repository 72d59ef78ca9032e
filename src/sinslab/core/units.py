"""Units: SI constants for navigation quantities and a parser for unit strings.

sinslab works in SI internally (rad, m, s). Units appear only at the edges: configs
give strings such as ``"0.01 deg/h"`` or ``"10 ug/sqrt(Hz)"`` and reports print
navigation units. Multiply by a constant to go to SI, divide to come back::

    >>> from sinslab import units as u
    >>> 0.01 * u.dph            # 0.01 deg/h in rad/s
    4.84813681109536e-08
    >>> u.parse("10 arcmin", "angle") / u.arcmin
    10.0

The parser tracks dimensions as exponents of (angle, length, time), so that
``"10 m"`` given where an angle is expected is an error naming both.
"""
from __future__ import annotations

import math
import re
from fractions import Fraction
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "deg", "arcmin", "arcsec", "dph", "dpsh", "dphpsh", "g0", "mg", "ug", "ugpsHz",
    "ppm", "nm", "hour", "minute", "KINDS", "parse", "parse_vector", "format_quantity", "vec3",
]

# --- constants (multiply a value in the named unit to get SI) -------------------------
g0 = 9.80665                      #: standard gravity [m/s^2], defines g, mg, ug
deg = math.pi / 180.0             #: degree [rad]
arcmin = deg / 60.0               #: arc minute [rad]
arcsec = deg / 3600.0             #: arc second [rad]
hour = 3600.0                     #: hour [s]
minute = 60.0                     #: minute [s]
dph = deg / hour                  #: deg/h [rad/s]
dpsh = deg / math.sqrt(hour)      #: deg/sqrt(h), angle random walk [rad/sqrt(s)]
dphpsh = deg / hour / math.sqrt(hour)  #: deg/h/sqrt(h), rate random walk [rad/s/sqrt(s)]
mg = 1e-3 * g0                    #: milli-g [m/s^2]
ug = 1e-6 * g0                    #: micro-g [m/s^2]
ugpsHz = ug                       #: ug/sqrt(Hz) == ug*sqrt(s), velocity random walk [m/s/sqrt(s)]
ppm = 1e-6                        #: parts per million [-]
nm = 1852.0                       #: nautical mile [m]

# --- parser -----------------------------------------------------------------------------
# Dimension = exponents of (angle, length, time, magnetic flux density).  Angles are a
# dimension here on purpose: it catches "10 m" where "10 arcmin" was meant. The flux
# density is a base dimension of its own (no mass or current here): a magnetometer's "G"
# is never read as anything but a field.
_ONE = (Fraction(0), Fraction(0), Fraction(0), Fraction(0))


def _dim(a=0, l=0, t=0, b=0):
    return (Fraction(a), Fraction(l), Fraction(t), Fraction(b))


_ATOMS: dict[str, tuple[float, tuple]] = {
    "rad": (1.0, _dim(1)), "mrad": (1e-3, _dim(1)), "urad": (1e-6, _dim(1)),
    "deg": (deg, _dim(1)), "arcmin": (arcmin, _dim(1)), "arcsec": (arcsec, _dim(1)),
    "m": (1.0, _dim(0, 1)), "km": (1e3, _dim(0, 1)), "cm": (1e-2, _dim(0, 1)),
    "mm": (1e-3, _dim(0, 1)), "nm": (nm, _dim(0, 1)), "NM": (nm, _dim(0, 1)),
    "s": (1.0, _dim(0, 0, 1)), "ms": (1e-3, _dim(0, 0, 1)), "min": (minute, _dim(0, 0, 1)),
    "h": (hour, _dim(0, 0, 1)), "hr": (hour, _dim(0, 0, 1)), "d": (86400.0, _dim(0, 0, 1)),
    "day": (86400.0, _dim(0, 0, 1)),
    "Hz": (1.0, _dim(0, 0, -1)), "kHz": (1e3, _dim(0, 0, -1)),
    "g": (g0, _dim(0, 1, -2)), "mg": (mg, _dim(0, 1, -2)), "ug": (ug, _dim(0, 1, -2)),
    "Gal": (1e-2, _dim(0, 1, -2)), "mGal": (1e-5, _dim(0, 1, -2)),
    "kn": (nm / hour, _dim(0, 1, -1)), "knot": (nm / hour, _dim(0, 1, -1)),
    "ppm": (ppm, _ONE), "ppb": (1e-9, _ONE), "%": (1e-2, _ONE), "1": (1.0, _ONE),
    "T": (1.0, _dim(b=1)), "mT": (1e-3, _dim(b=1)), "uT": (1e-6, _dim(b=1)), "nT": (1e-9, _dim(b=1)),
    "G": (1e-4, _dim(b=1)), "mG": (1e-7, _dim(b=1)),
}
_ALIASES = {"°": "deg", "degree": "deg", "degrees": "deg", "'": "arcmin", "′": "arcmin",
            '"': "arcsec", "″": "arcsec", "sec": "s", "hour": "h", "hours": "h",
            "µg": "ug", "μg": "ug", "µT": "uT", "μT": "uT", "gauss": "G", "Gauss": "G",
            "tesla": "T", "minutes": "min", "percent": "%"}

#: Named physical kinds accepted by :func:`parse` and their dimensions.
KINDS: dict[str, tuple] = {
    "dimensionless": _ONE,
    "angle": _dim(1),
    "angular_rate": _dim(1, 0, -1),           # deg/h
    "angle_random_walk": _dim(1, 0, Fraction(-1, 2)),   # deg/sqrt(h)
    "rate_random_walk": _dim(1, 0, Fraction(-3, 2)),    # deg/h/sqrt(h)
    "length": _dim(0, 1),
    "velocity": _dim(0, 1, -1),
    "acceleration": _dim(0, 1, -2),           # ug, m/s^2
    "velocity_random_walk": _dim(0, 1, Fraction(-3, 2)),  # ug/sqrt(Hz), m/s/sqrt(h)
    "accel_random_walk": _dim(0, 1, Fraction(-5, 2)),     # ug/sqrt(s)  (acceleration RRW)
    "time": _dim(0, 0, 1),
    "frequency": _dim(0, 0, -1),
    "magnetic_field": _dim(b=1),              # T, uT, nT, G (gauss), mG
}

_NUM = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")
_TOKEN = re.compile(r"\s*(sqrt|√|²|³|\(|\)|\*|/|\^|[-+]?\d+(?:\.\d+)?|[A-Za-z%°'′\"″µμ]+|·)")


class UnitError(ValueError):
    """A unit string that does not parse, or has the wrong dimension."""


def _dim_name(d):
    for k, v in KINDS.items():
        if v == d:
            return k
    parts = [f"{n}^{e}" for n, e in zip(("angle", "length", "time", "magnetic field"), d) if e != 0]
    return " ".join(parts) or "dimensionless"


def _tokens(s: str) -> list[str]:
    out, pos = [], 0
    s = s.strip()
    while pos < len(s):
        m = _TOKEN.match(s, pos)
        if not m or m.end() == pos:
            raise UnitError(f"cannot read unit {s!r} at {s[pos:]!r}")
        out.append(m.group(1))
        pos = m.end()
    return out


class _Parser:
    """Recursive descent over  expr := term (('*'|'/') term)* ;  term := factor ('^' num)? ;
    factor := atom | 'sqrt' '(' expr ')' | '√' factor | '(' expr ')'; '²', '³' are exponents."""

    def __init__(self, text):
        self.text = text
        self.t = _tokens(text)
        self.i = 0

    def peek(self):
        return self.t[self.i] if self.i < len(self.t) else None

    def take(self, want=None):
        tok = self.peek()
        if tok is None or (want is not None and tok != want):
            raise UnitError(f"cannot read unit {self.text!r}: expected {want or 'more'}")
        self.i += 1
        return tok

    def expr(self):
        scale, dim = self.term()
        while self.peek() in ("*", "/", "·"):
            op = self.take()
            s2, d2 = self.term()
            if op == "/":
                scale, dim = scale / s2, tuple(a - b for a, b in zip(dim, d2))
            else:
                scale, dim = scale * s2, tuple(a + b for a, b in zip(dim, d2))
        return scale, dim

    def term(self):
        scale, dim = self.factor()
        if self.peek() in ("^", "²", "³"):
            op = self.take()
            e = Fraction(self.take()) if op == "^" else Fraction(2 if op == "²" else 3)
            scale, dim = scale ** float(e), tuple(a * e for a in dim)
        return scale, dim

    def factor(self):
        tok = self.take()
        if tok == "sqrt":
            self.take("(")
            s, d = self.expr()
            self.take(")")
            return math.sqrt(s), tuple(a / 2 for a in d)
        if tok == "√":                      # as printed in papers: °/√h, µg/√Hz, √(h)
            s, d = self.factor()
            return math.sqrt(s), tuple(a / 2 for a in d)
        if tok == "(":
            s, d = self.expr()
            self.take(")")
            return s, d
        name = _ALIASES.get(tok, tok)
        if name not in _ATOMS:
            raise UnitError(f"unknown unit {tok!r} in {self.text!r}")
        return _ATOMS[name]

    def parse(self):
        out = self.expr()
        if self.peek() is not None:
            raise UnitError(f"cannot read unit {self.text!r}: unexpected {self.peek()!r}")
        return out


def unit_scale(unit: str, kind: str | None = None) -> float:
    """SI value of one ``unit`` (e.g. ``unit_scale("deg/h") == dph``), checking its kind."""
    scale, dim = _Parser(unit).parse()
    if kind is not None:
        _check_kind(unit, dim, kind)
    return scale


def _check_kind(text, dim, kind):
    if kind not in KINDS:
        raise ValueError(f"unknown quantity kind {kind!r}; known: {', '.join(KINDS)}")
    if KINDS[kind] != dim:
        raise UnitError(f"{text!r} is {_dim_name(dim)}, expected {kind.replace('_', ' ')}")


def parse(text: str | float | int, kind: str | None = None) -> float:
    """Parse ``"<number> <unit>"`` into SI.

    Parameters
    ----------
    text : str
        A number followed by a unit expression, e.g. ``"0.01 deg/h"``, ``"100 ug"``,
        ``"0.001 deg/sqrt(h)"``, ``"10 ug/sqrt(Hz)"``, ``"10 arcmin"``, ``"42.2 min"``,
        ``"9.8 m/s^2"``.  A bare number is accepted only for ``kind="dimensionless"``.
    kind : str, optional
        Expected physical kind (a key of :data:`KINDS`); a mismatch raises
        :class:`UnitError` naming both.

    Returns
    -------
    float
        The value in SI units (rad, m, s and their combinations).

    Notes
    -----
    ``ug/sqrt(Hz)`` and ``m/s/sqrt(h)`` have the same dimension (velocity random walk);
    so do ``deg/sqrt(h)`` and ``deg/h/sqrt(Hz)`` (angle random walk).
    """
    if isinstance(text, bool):
        raise UnitError(f"{text!r} is not a quantity")
    if isinstance(text, (int, float, np.floating, np.integer)):
        if kind in (None, "dimensionless"):
            return float(text)
        raise UnitError(f"{text!r} has no unit; expected {kind.replace('_', ' ')} "
                        f"(write e.g. \"{text} {_example_unit(kind)}\")")
    if not isinstance(text, str):
        raise UnitError(f"{text!r} is not a quantity string")
    m = _NUM.match(text)
    if not m:
        raise UnitError(f"{text!r} does not start with a number")
    value, unit = float(m.group(1)), m.group(2)
    if not math.isfinite(value):
        raise UnitError(f"{text!r} is not finite")
    if unit == "":
        if kind in (None, "dimensionless"):
            return value
        raise UnitError(f"{text!r} has no unit; expected {kind.replace('_', ' ')}")
    scale, dim = _Parser(unit).parse()
    if kind is not None:
        _check_kind(text, dim, kind)
    return value * scale


def parse_vector(text: str | float | Sequence[str | float], kind: str | None = None, n: int = 3) -> np.ndarray:
    """Parse one quantity (broadcast to ``n``) or a list of ``n`` quantities into SI.

    Accepts ``"0.01 deg/h"``, ``["0.003 deg/h", "-0.002 deg/h", "0.0005 deg/h"]`` or
    ``"[0.003, -0.002, 0.0005] deg/h"``.
    """
    if isinstance(text, (list, tuple, np.ndarray)):
        vals = [parse(t, kind) for t in text]
        if len(vals) == 1:
            vals = vals * n
    else:
        s = str(text).strip()
        m = re.match(r"^\[([^\]]*)\]\s*(.*)$", s)
        if m:
            nums = [x for x in re.split(r"[,\s]+", m.group(1).strip()) if x]
            unit = m.group(2)
            vals = [parse(f"{x} {unit}".strip(), kind) for x in nums]
        else:
            vals = [parse(s, kind)] * n
    if len(vals) != n:
        raise UnitError(f"{text!r}: expected {n} values, got {len(vals)}")
    return np.asarray(vals, dtype=float)


def _example_unit(kind):
    return {"angle": "deg", "angular_rate": "deg/h", "angle_random_walk": "deg/sqrt(h)",
            "rate_random_walk": "deg/h/sqrt(h)", "length": "m", "velocity": "m/s",
            "acceleration": "ug", "velocity_random_walk": "ug/sqrt(Hz)", "time": "s",
            "frequency": "Hz", "accel_random_walk": "ug/sqrt(s)"}.get(kind, "")


def format_quantity(value_si: float, unit: str, digits: int = 6) -> str:
    """Format an SI value in ``unit``: ``format_quantity(4.85e-8, "deg/h") -> '0.01 deg/h'``."""
    return f"{value_si / unit_scale(unit):.{digits}g} {unit}"


# --- small validators -------------------------------------------------------------------
def vec3(value: ArrayLike | None, name: str = "value", *, default: ArrayLike | None = None, nonneg: bool = False,
         finite: bool = False, readonly: bool = False) -> np.ndarray:
    """A per-axis quantity (SI numbers, not unit strings) as a new float array of shape (3,).

    Parameters
    ----------
    value : float, or sequence of 1 or 3 floats, or None
        One value is used for all three axes.
    name : str
        What the value is, for the error message.
    default : float or sequence, optional
        Used when ``value`` is None (None without a default is an error).
    nonneg, finite : bool
        Also require every component ``>= 0`` / finite (NaN is always refused; ``inf`` is
        allowed unless ``finite``, e.g. an infinite correlation time).
    readonly : bool
        Return a read-only array (for frozen dataclasses).

    Raises
    ------
    ValueError
        Naming ``name``: wrong number of values, NaN, infinite (``finite``) or negative
        (``nonneg``) components.
    """
    if value is None:
        if default is None:
            raise ValueError(f"{name} is missing")
        value = default
    a = np.array(value, dtype=float)
    if a.ndim == 0:
        a = np.full(3, float(a))
    a = a.reshape(-1)
    if a.shape == (1,):
        a = np.repeat(a, 3)
    if a.shape != (3,):
        raise ValueError(f"{name} must be 1 or 3 values, got shape {np.shape(value)}")
    if np.isnan(a).any():
        raise ValueError(f"{name} is NaN")
    if finite and not np.isfinite(a).all():
        raise ValueError(f"{name} must be finite, got {a.tolist()}")
    if nonneg and (a < 0).any():
        raise ValueError(f"{name} must be >= 0, got {a.tolist()}")
    if readonly:
        a.setflags(write=False)
    return a
