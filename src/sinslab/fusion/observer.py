"""What the fusion driver decided while it ran, recorded beside the loop: the updates it
applied (:class:`Applied`), the decisions of each measurement's innovation gate
(:class:`GateLog`) and, for a measurement whose rows are gated one by one, every
candidate row with its innovation and fate (:class:`RowLog`).

Recording is an observer of the loop (filterpy's saver), not a duty of the
measurements: a measurement says what it computed (``matrices``, :class:`Rows` with their
metadata), the driver decides, and :class:`Recorder` keeps what it decided.
:class:`Decisions` is the part of a :class:`~sinslab.fusion.driver.DriverResult` that
holds the gates' and rows' records by measurement index.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Applied", "GateLog", "RowLog", "Decisions", "Recorder"]


@dataclass(frozen=True)
class Applied:
    """Measurement records applied by the driver (arrays of length J, in processing order).

    Attributes
    ----------
    measurement : int array
        Index of the measurement in the list given.
    item : int array
        Item of that measurement.
    t_valid, t_applied : float arrays [s]
        Validity time and the epoch at which it was processed.
    innovation : list of ndarray
        Innovations (NaN where a component was not used).
    nis : float array
    innovation_sigma : list of ndarray
        √diag(S) of each innovation, ``S = H P Hᵀ + R`` of the prior (NaN where not used):
        the filter's own σ of each innovation component.
    """

    measurement: np.ndarray
    item: np.ndarray
    t_valid: np.ndarray
    t_applied: np.ndarray
    innovation: list
    nis: np.ndarray
    innovation_sigma: list = field(default_factory=list)


@dataclass
class GateLog:
    """The decisions of one measurement's innovation gate: ``passed`` updates let
    through, ``rejected`` the times [s] of the updates it refused."""

    passed: int = 0
    rejected: list = field(default_factory=list)


@dataclass
class RowLog:
    """Every candidate row of a row-gated measurement, epoch by epoch (lists of equal
    length, one entry per epoch the measurement was asked for).

    ``t`` [s] the items' validity times; ``meta`` ``{name: [array per epoch]}`` what the
    measurement said of each candidate (:attr:`Rows.meta`); ``innovation`` (z − H x⁻,
    NaN where no row was formed or no prior given), ``sigma`` (√R), ``nis``
    (ν²/(H P Hᵀ + R)), ``used`` and ``rejected`` (bool: in the update; refused by the row
    gate) per candidate; ``skipped`` ``{cause: [count per epoch]}``.
    """

    t: list = field(default_factory=list)
    meta: dict = field(default_factory=dict)
    innovation: list = field(default_factory=list)
    sigma: list = field(default_factory=list)
    nis: list = field(default_factory=list)
    used: list = field(default_factory=list)
    rejected: list = field(default_factory=list)
    skipped: dict = field(default_factory=dict)

    def counts(self):
        """Totals: rows ``used``, ``rejected`` by the gate, and each cause of ``skipped``."""
        out = dict(used=int(sum(int(np.sum(u)) for u in self.used)),
                   rejected=int(sum(int(np.sum(r)) for r in self.rejected)))
        out.update({k: int(sum(v)) for k, v in self.skipped.items()})
        return out

    def used_per_epoch(self):
        """(E,) int: rows used at each epoch."""
        return np.array([int(u.sum()) for u in self.used], dtype=np.int64)

    def nis_per_epoch(self):
        """``(t, nis, dof)`` (E,) each: the epochs' times [s], the sum of ν²/(H P Hᵀ + R)
        over the rows used at each epoch and their number. The rows of an epoch are applied
        one at a time, each against the covariance the previous ones left, so their NIS are
        independent χ²(1) under consistency and the sum is χ² with ``dof`` degrees of
        freedom (Bar-Shalom, Li & Kirubarajan 2001, §5.4)."""
        t = np.asarray(self.t, dtype=float)
        nis = np.array([float(np.sum(n[u])) for n, u in zip(self.nis, self.used)])
        return t, nis, self.used_per_epoch().astype(float)

    def add(self, t, rows, rejected, nu, nis):
        """One epoch: ``rows`` (:class:`~sinslab.fusion.measurements.Rows`) and the
        gate's decisions over the rows formed."""
        c = rows.formed.size
        self.t.append(float(t))
        for k, v in rows.meta.items():
            self.meta.setdefault(k, []).append(v)
        for name, vals in (("innovation", nu), ("sigma", np.sqrt(rows.R)), ("nis", nis)):
            full = np.full(c, np.nan)
            full[rows.formed] = vals
            getattr(self, name).append(full)
        formed = np.flatnonzero(rows.formed)
        used, rej = np.zeros(c, bool), np.zeros(c, bool)
        used[formed[~rejected]] = True
        rej[formed[rejected]] = True
        self.used.append(used)
        self.rejected.append(rej)
        for k, v in rows.skipped.items():
            self.skipped.setdefault(k, []).append(int(v))


@dataclass(frozen=True)
class Decisions:
    """The gates' and row gates' records of a run, by measurement index."""

    gates: dict
    rows: dict

    def gate(self, mi) -> GateLog:
        """Measurement ``mi``'s gate record (empty for a measurement without a gate)."""
        return self.gates.get(mi, GateLog())

    def rows_of(self, mi) -> RowLog | None:
        """Measurement ``mi``'s row record (None for a measurement without a row gate)."""
        return self.rows.get(mi)


class Recorder:
    """The driver's observer of one run (lane): what it applied and decided."""

    def __init__(self):
        self.a_m, self.a_j, self.a_tv, self.a_t, self.a_nu, self.a_nis, self.a_sd = ([] for _ in range(7))
        self.gates, self.rows = {}, {}

    def applied(self, mi, j, tv, t, res):
        """An update applied: measurement ``mi``'s item ``j`` valid at ``tv``, processed at
        epoch time ``t``, with the filter's :class:`~sinslab.estimation.filter` result."""
        self.a_m.append(mi)
        self.a_j.append(j)
        self.a_tv.append(tv)
        self.a_t.append(t)
        self.a_nu.append(res.innovation)
        self.a_nis.append(res.nis)
        self.a_sd.append(np.sqrt(np.abs(np.diagonal(res.S))))

    def gated(self, mi, t, passed):
        """Measurement ``mi``'s gate let an update through (``passed``) or refused it at ``t``."""
        g = self.gates.setdefault(mi, GateLog())
        if passed:
            g.passed += 1
        else:
            g.rejected.append(float(t))

    def row_decisions(self, mi, t, rows, rejected, nu, nis):
        """Measurement ``mi``'s candidate rows at item time ``t`` and the row gate's decisions."""
        self.rows.setdefault(mi, RowLog()).add(t, rows, rejected, nu, nis)

    def result(self):
        """``(Applied, Decisions)``."""
        applied = Applied(np.array(self.a_m, dtype=np.int64), np.array(self.a_j, dtype=np.int64),
                          np.array(self.a_tv, dtype=float), np.array(self.a_t, dtype=float), self.a_nu,
                          np.array(self.a_nis, dtype=float), self.a_sd)
        return applied, Decisions(self.gates, self.rows)
