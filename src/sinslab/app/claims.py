"""Claims: checked statements of a run, with structured measured and expected values.

Experiments (:mod:`sinslab.experiments.base` re-exports :class:`Claim`) and the
recorded-data commands return claims; ``summary.json`` stores them with names and units
(see :class:`Claim`) and the report prints them labelled ("φE 0.10′ · φN −0.47′").
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Claim", "tally"]


def _num(x):
    """Plain Python number (or list) for JSON; NaN stays NaN here (None in JSON)."""
    if isinstance(x, np.ndarray) and x.ndim == 0:
        x = x.item()
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_num(v) for v in np.asarray(x).tolist()]
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x)
    return x


def _fmt(x, digits=4):
    if isinstance(x, np.ndarray) and x.ndim == 0:
        x = x.item()
    if isinstance(x, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_fmt(v, digits) for v in x) + "]"
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "n/a"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    if isinstance(x, (float, np.floating)):
        return f"{float(x):.{digits}g}"
    return str(x)


@dataclass
class Claim:
    """A checked statement of an experiment (one row of the report's claims table).

    ``measured`` is what the run produced (a number, a list of numbers, or a dict
    ``{name: number | list}``); ``expected`` says what would make the claim true (a
    number/list for the helpers, or text for a criterion no relation expresses);
    ``passed`` is the verdict. A claim must be able to fail: compute ``passed`` from the
    run, never assert it. The helpers build the common shapes and keep the criterion and
    the verdict consistent; a measurement that is NaN/None never passes.

    ``names`` labels the components of a list ``measured`` (``["φE", "φN", "φU"]``) and
    ``unit`` gives their unit (one string, or one per component) so the report prints
    "φE 0.10′ · φN −0.47′". ``origin`` says whose sentence the claim tests: ``"paper"``
    (a statement the paper makes) or ``"check"`` (a test the project adds: consistency,
    covariance against Monte Carlo, ...). In ``summary.json`` a claim is::

        {"id", "statement", "passed", "origin": "paper" | "check" | null,
         "measured": {"value": <number | list | dict>, "names": [...] | null, "unit": str | [...]},
         "expected": {"relation": "<=" | ">=" | "==" | "within" | "between" | "text",
                      "value": <number | list | null>, "tolerance": <number | list | null>,
                      "rel_tolerance": <number | null>, "unit": ..., "text": "<= 0.07 ′"}}
    """

    id: str
    statement: str
    measured: Any
    expected: Any
    passed: bool
    names: Any = None
    unit: Any = ""
    relation: str = ""
    tolerance: Any = None
    rel_tolerance: float | None = None
    origin: str | None = None

    def __post_init__(self):
        if self.origin not in (None, "paper", "check"):
            raise ValueError(f"claim {self.id!r}: origin must be 'paper' or 'check', "
                             f"got {self.origin!r}")
        if isinstance(self.measured, dict):
            self.measured = {str(k): _num(v) for k, v in self.measured.items()}
        else:
            self.measured = _num(self.measured)
        self.expected = _num(self.expected)
        self.tolerance = _num(self.tolerance)
        self.passed = bool(self.passed)
        if self.names is not None:
            self.names = [str(n) for n in self.names]
        if isinstance(self.unit, (list, tuple)):
            self.unit = [str(u) for u in self.unit]
        if not self.relation:
            self.relation = "text" if isinstance(self.expected, str) else "=="

    def criterion(self) -> str:
        """The expectation as one line of text (units attached)."""
        if self.relation == "text":
            return str(self.expected)
        u = self.unit if isinstance(self.unit, str) else ""
        if self.relation == "between":
            lo, hi = self.expected
            return f"between {_fmt(lo)} and {_fmt(hi)} {u}".strip()
        if self.relation == "within":
            tol = (f"{self.rel_tolerance * 100:g} %" if self.rel_tolerance is not None
                   and self.tolerance is None else f"{_fmt(self.tolerance)} {u}".strip())
            return f"{_fmt(self.expected, 6)} {u}".strip() + " ± " + tol
        op = {"<=": "<=", ">=": ">=", "==": "=="}.get(self.relation, self.relation)
        return f"{op} {_fmt(self.expected, 6)} {u}".strip()

    def as_dict(self) -> dict:
        return {"id": self.id, "statement": self.statement,
                "measured": {"value": self.measured, "names": self.names, "unit": self.unit},
                "expected": {"relation": self.relation,
                             "value": None if self.relation == "text" else self.expected,
                             "tolerance": self.tolerance, "rel_tolerance": self.rel_tolerance,
                             "unit": self.unit, "text": self.criterion()},
                "passed": self.passed, "origin": self.origin}

    @staticmethod
    def _ok(v) -> bool:
        return v is not None and np.all(np.isfinite(np.asarray(v, dtype=float)))

    @classmethod
    def within(cls, id: str, statement: str, measured, target, *, rel: float | None = None,
               abs: float | None = None, unit="", names=None, origin=None) -> "Claim":
        """``|measured − target| <= abs`` or ``<= rel·|target|`` (every component)."""
        if rel is None and abs is None:
            raise ValueError("Claim.within needs rel or abs")
        tol = np.asarray(abs if abs is not None else 0.0, float)
        if rel is not None:
            tol = np.maximum(tol, rel * np.abs(np.asarray(target, float)))
        ok = cls._ok(measured) and bool(np.all(
            np.abs(np.asarray(measured, float) - np.asarray(target, float)) <= tol))
        return cls(id, statement, measured, target, ok, names=names, unit=unit, relation="within",
                   tolerance=abs, rel_tolerance=rel, origin=origin)

    @classmethod
    def at_most(cls, id: str, statement: str, measured, limit, unit="", names=None,
                origin=None) -> "Claim":
        """``measured <= limit`` (every component)."""
        ok = cls._ok(measured) and bool(np.all(np.asarray(measured, float) <= np.asarray(limit, float)))
        return cls(id, statement, measured, limit, ok, names=names, unit=unit, relation="<=",
                   origin=origin)

    @classmethod
    def at_least(cls, id: str, statement: str, measured, limit, unit="", names=None,
                 origin=None) -> "Claim":
        """``measured >= limit`` (every component)."""
        ok = cls._ok(measured) and bool(np.all(np.asarray(measured, float) >= np.asarray(limit, float)))
        return cls(id, statement, measured, limit, ok, names=names, unit=unit, relation=">=",
                   origin=origin)

    @classmethod
    def equals(cls, id: str, statement: str, measured, expected, names=None, unit="",
               origin=None) -> "Claim":
        """Exact equality (ranks, counts, orderings)."""
        return cls(id, statement, measured, expected, _num(measured) == _num(expected),
                   names=names, unit=unit, relation="==", origin=origin)


def tally(claims) -> str:
    """The verdicts of a run's claims counted by origin, as one line:
    ``"paper: 5 of 9 reproduced · checks: 3 of 3"``.

    ``claims`` are :class:`Claim` s or their ``summary.json`` dicts; claims without an origin
    (summaries written before claims had one) are counted as ``"claims: k of n passed"``.
    Empty when there are no claims."""
    counts = {}
    for c in claims:
        d = c.as_dict() if isinstance(c, Claim) else c
        o = d.get("origin")
        k, n = counts.get(o, (0, 0))
        counts[o] = (k + bool(d.get("passed")), n + 1)
    parts = []
    for o, label, verb in (("paper", "paper", "reproduced"), ("check", "checks", "passed"),
                           (None, "claims", "passed")):
        if o in counts:
            k, n = counts[o]
            parts.append(f"{label}: {k} of {n}" + (f" {verb}" if o != "check" else ""))
    return " · ".join(parts)
