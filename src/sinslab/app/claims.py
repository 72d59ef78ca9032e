"""Claims: checked statements of a run, with structured measured and expected values.

Experiments (:mod:`sinslab.experiments.base` re-exports :class:`Claim`) and the
recorded-data commands return claims; ``summary.json`` stores them with names and units
(see :class:`Claim`) and the report prints them labelled ("φE 0.10′ · φN −0.47′").

A verdict rests on assumptions: a figure the paper does not state, one reading of its
sentence, a threshold, a horizon. A claim declares them (:meth:`Claim.assume`, an
:class:`Assumption` with its default and whose default it is) and carries the verdicts
under the alternatives a reviewer would try (:meth:`Claim.vary`, :meth:`Claim.with_limits`:
an :class:`Alternative` each). A reading or a threshold is evaluated on the run's own
results; an alternative that changes the physics is a re-run of the experiment, made by
the robustness sweep of :mod:`sinslab.experiments` (``sinslab run NAME --robustness``).
:func:`robustness` turns a claim into its entry of the ``robustness`` section of
``summary.json`` with one label: **robust** (no alternative changes the verdict),
**depends on: …** (the assumptions whose alternatives change it), **decided by
construction** (the set-up fixes the verdict, :meth:`Claim.by_construction`) or **not
swept** (physics alternatives declared but not run).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["Claim", "Assumption", "Alternative", "tally", "robustness", "robustness_section", "declared",
           "SOURCES", "HOW"]


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


#: whose default an assumption is: the paper states it, or the project chose it (the paper is
#: silent, or its figure is read one way of several)
SOURCES = ("paper", "project")
#: how an alternative is evaluated: another reading of the same results, another threshold on
#: the same measured value, or a re-run of the experiment with other physics
HOW = ("reading", "threshold", "rerun")


@dataclass(frozen=True)
class Assumption:
    """What a claim's verdict may depend on: ``name`` (e.g. "master attitude error"),
    ``default`` (the value the run used, as text: "0′: the master is error-free") and
    ``source``: ``"paper"`` when the paper states that default, ``"project"`` when the
    project chose it."""

    name: str
    default: str
    source: str = "project"

    def __post_init__(self):
        if self.source not in SOURCES:
            raise ValueError(f"assumption {self.name!r}: source must be one of {SOURCES}, got {self.source!r}")

    def as_dict(self) -> dict:
        return {"name": self.name, "default": self.default, "source": self.source}


@dataclass
class Alternative:
    """The verdict of a claim under one alternative of one assumption.

    ``value`` is what the claim measures under it (a number, list or dict, as ``measured``);
    ``passed`` the verdict, None when it could not be decided (e.g. nothing to measure).
    ``baseline``: for a re-run at a reduced size, the verdict of the reduced run at the
    default assumptions, which the alternative is compared with (None: compared with the
    claim's own verdict). ``combined``: the assumption of a reading taken in a re-run (the
    alternative then varies two assumptions at once, ``assumption`` with ``combined``)."""

    assumption: str
    name: str
    value: Any
    passed: bool | None
    how: str = "reading"
    baseline: bool | None = None
    note: str = ""
    combined: str = ""

    def __post_init__(self):
        if self.how not in HOW:
            raise ValueError(f"alternative {self.name!r}: how must be one of {HOW}, got {self.how!r}")
        if isinstance(self.value, dict):
            self.value = {str(k): _num(v) for k, v in self.value.items()}
        else:
            self.value = _num(self.value)
        self.passed = None if self.passed is None else bool(self.passed)

    def flips(self, default: bool) -> bool:
        """True when this alternative decides otherwise than its baseline."""
        base = default if self.baseline is None else self.baseline
        return self.passed is not None and self.passed != bool(base)

    def as_dict(self) -> dict:
        d = {"assumption": self.assumption, "name": self.name, "value": self.value, "passed": self.passed,
             "how": self.how}
        if self.baseline is not None:
            d["baseline"] = self.baseline
        if self.note:
            d["note"] = self.note
        if self.combined:
            d["combined"] = self.combined
        return d


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
    #: declared assumptions (:meth:`assume`) and the verdicts under their alternatives
    #: (:meth:`vary`, :meth:`with_limits`, and the re-runs of the robustness sweep)
    assumptions: list = field(default_factory=list)
    alternatives: list = field(default_factory=list)
    #: why the set-up decides the verdict, when it does (:meth:`by_construction`)
    construction: str | None = None

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

    # ---- robustness: what the verdict rests on
    def assume(self, name: str, default: str, source: str = "project") -> "Claim":
        """Declare an assumption the verdict may depend on (once per name); returns the claim."""
        if all(a.name != name for a in self.assumptions):
            self.assumptions.append(Assumption(name, default, source))
        return self

    def vary(self, assumption: str, name: str, value, passed, how: str = "reading", note: str = "") -> "Claim":
        """Record the verdict under one alternative of ``assumption`` (declared with
        :meth:`assume`; ``how``: "reading" or "threshold" — re-runs are the sweep's); returns
        the claim."""
        if all(a.name != assumption for a in self.assumptions):
            raise ValueError(f"claim {self.id!r}: alternative {name!r} of undeclared assumption {assumption!r}")
        self.alternatives.append(Alternative(assumption, name, value, passed, how, note=note))
        return self

    def with_limits(self, assumption: str, limits: dict) -> "Claim":
        """The same measured value against other limits (``{name: limit}``) of a ``<=`` or
        ``>=`` claim, each an alternative of ``assumption`` (a threshold); returns the claim."""
        if self.relation not in ("<=", ">="):
            raise ValueError(f"claim {self.id!r}: with_limits needs a <= or >= claim, not {self.relation!r}")
        for name, lim in limits.items():
            self.vary(assumption, name, self.measured, self.holds_at(lim), how="threshold")
        return self

    def holds_at(self, limit) -> bool:
        """The verdict of a ``<=`` / ``>=`` claim's measured value against ``limit``."""
        m = self.measured
        if not self._ok(m):
            return False
        a, b = np.asarray(m, float), np.asarray(limit, float)
        return bool(np.all(a <= b) if self.relation == "<=" else np.all(a >= b))

    def by_construction(self, reason: str) -> "Claim":
        """Say that the experiment's set-up decides this verdict (``reason``: how); returns
        the claim."""
        self.construction = reason
        return self

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


def tally(claims, robust: dict | None = None) -> str:
    """The verdicts of a run's claims counted by origin, as one line:
    ``"paper: 5 of 9 reproduced, 3 robust · checks: 3 of 3"``.

    ``claims`` are :class:`Claim` s or their ``summary.json`` dicts; claims without an origin
    (summaries written before claims had one) are counted as ``"claims: k of n passed"``.
    ``robust``: the ``robustness`` section of ``summary.json`` (:func:`robustness_section`),
    whose count of robust paper claims is added (and of those not swept, when the physics
    alternatives were not run). Empty when there are no claims."""
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
            text = f"{label}: {k} of {n}" + (f" {verb}" if o != "check" else "")
            if o == "paper" and declared(robust):
                text += f", {robust.get('paper_claims_robust', 0)} robust"
                waiting = sum(1 for c in claims if (c.as_dict() if isinstance(c, Claim) else c).get("origin") == "paper"
                              and robust["claims"].get((c.id if isinstance(c, Claim) else c.get("id")), {})
                              .get("label", "").startswith("not swept"))
                if waiting:
                    text += f" ({waiting} not swept: --robustness)"
            parts.append(text)
    return " · ".join(parts)


def robustness(claim, pending=()) -> dict:
    """The robustness entry of one claim (:class:`Claim`): ``{default, alternatives,
    assumptions, label, depends_on, pending}``. The label names the assumptions one of
    whose alternatives, alone, changes the verdict; when none does, the pairs that do
    ("horizon with scoring"). ``pending``: names of the physics
    assumptions declared for it whose re-runs were not made (the label is then "not swept"
    unless an alternative already changes the verdict)."""
    alts = list(claim.alternatives)
    # one assumption changed at a time decides the label; pairs (a reading taken in a re-run)
    # only when no single one moves the verdict
    flips = []
    for a in alts:
        if not a.combined and a.flips(claim.passed) and a.assumption not in flips:
            flips.append(a.assumption)
    if not flips:
        for a in alts:
            pair = f"{a.assumption} with {a.combined}"
            if a.combined and a.flips(claim.passed) and pair not in flips:
                flips.append(pair)
    pending = [p for p in pending if p not in flips]
    if claim.construction:
        label = f"decided by construction: {claim.construction}"
    elif flips:
        label = "depends on: " + ", ".join(flips)
    elif pending:
        label = "not swept (run with --robustness)"
    elif alts:
        label = "robust"
    else:
        label = "not varied"
    return {"default": claim.passed, "alternatives": [a.as_dict() for a in alts],
            "assumptions": [a.as_dict() for a in claim.assumptions], "label": label,
            "depends_on": flips, "pending": list(pending)}


def declared(section: dict | None) -> bool:
    """True when a robustness section (:func:`robustness_section`) has anything to say: some
    claim declared an assumption or was decided by construction."""
    return bool(section) and any(e.get("label") != "not varied" for e in (section.get("claims") or {}).values())


def is_robust(entry: dict) -> bool:
    """True for a robustness entry labelled robust (:func:`robustness`)."""
    return entry.get("label") == "robust"


def robustness_section(claims, *, swept: bool, pending: dict | None = None, axes=(), cpu_s=None,
                       wall_s=None) -> dict:
    """The ``robustness`` section of ``summary.json``: per claim id its :func:`robustness`
    entry, and ``paper_claims_robust`` / ``paper_claims`` (paper claims labelled robust, and
    all of them), ``swept`` (the physics alternatives were re-run), ``axes`` (the re-runs:
    assumption, alternatives with their ``--set`` items, reduced size) and their CPU and
    wall time."""
    pending = pending or {}
    entries = {c.id: robustness(c, pending.get(c.id, ())) for c in claims}
    paper = [c.id for c in claims if c.origin == "paper"]
    return {"swept": bool(swept), "claims": entries,
            "paper_claims_robust": sum(is_robust(entries[i]) for i in paper), "paper_claims": len(paper),
            "axes": list(axes), "cpu_s": cpu_s, "wall_s": wall_s}
