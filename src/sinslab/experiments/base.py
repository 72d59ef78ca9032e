"""What an experiment module writes, and what the framework does for it.

An experiment is one module in :mod:`sinslab.experiments` declaring::

    NAME = "static-alignment"                     # the CLI name
    PURPOSE = "one line shown by `sinslab list`"
    PAPER = "Yan, Qin: ..., Computer Simulation 23(10), 2006"   # optional: source of the defaults
    NOTES = ["latitude not stated by the paper: 34.246 deg N"]   # optional, shown in report

    class Config(ExperimentConfig):               # sinslab.app.config; defaults = paper scenario
        scenario: Scenario = Scenario()
        imu: Imu = Imu()

    QUICK = {"scenario": {"duration": "5 min"}}    # overrides applied by --quick

    METRICS = {                                    # every metric it returns, declared
        "final_err_phiE_arcmin": Metric("arcmin", "east attitude estimation error at the end"),
    }

    def run(config: Config, ctx: RunContext) -> Result:
        from sinslab.sim import trajectory        # numerical modules: imported here
        ...
        return Result(metrics={...}, claims=[Claim.within(...)], series={...},
                      figures=[Figure("att_err", fig, "caption")])

The module's top level imports what ``Config`` needs (pydantic, numpy,
:mod:`sinslab.core.units`, this module) and nothing that pulls in numba, scipy,
matplotlib, pandas or dask: ``sinslab config NAME`` imports the module alone and builds
the default ``Config``, validators included (``tests/app/test_startup.py``). A validator
that needs a method module imports it inside the validator and calls only functions that
need none of those packages.

The framework (:func:`sinslab.experiments.execute`) resolves and validates the config,
claims the output folder, writes ``config.toml`` first, calls ``run``, adds the
``runtime_s`` metric, then writes the series (CSV/Parquet), figures (PNG + SVG), tables,
``summary.json`` and ``report.html`` — each file atomically. ``run`` itself never
writes files and never prints; it may log a line through ``ctx.log`` and show progress
with ``ctx.progress(...)`` (see :mod:`sinslab.core.progress`).

Monte Carlo: ``config.runs`` (``--runs N``) and ``ctx.scheduler`` (``--scheduler``: an
address or ``"sync"``; ``sinslab demo`` passes one ``distributed.Client`` that all its
campaigns share; None starts a local cluster per campaign) are passed through; an experiment that supports it returns its statistics as extra metrics
(e.g. ``final_err_phiE_arcmin_rms``), a :class:`Table` (per-run or per-state statistics,
shown in the report and written as CSV) and extra figures. Nothing else changes. A module
whose campaign starts only from some number of runs declares it as ``CAMPAIGN_MIN_RUNS``
(default 1), so that ``--scheduler`` with fewer runs is refused instead of ignored.

Robustness: every claim declares what its verdict rests on and the alternatives a referee
would try (:mod:`sinslab.app.claims`: :meth:`Claim.assume`, :meth:`Claim.vary`,
:meth:`Claim.with_limits` for readings and thresholds, evaluated by ``run`` on its own
results). An alternative that changes the physics is an :class:`Axis` of the module's
``ROBUSTNESS(cfg)`` (a function of the resolved config, returning a list)::

    def ROBUSTNESS(cfg):
        return [Axis("master attitude error", "0′: the master is error-free (paper)",
                     {"0.5′": ["master.att_error=0.5 arcmin"], "2′": ["master.att_error=2 arcmin"]},
                     claims=("small_all_converge",), reduced=("runs=60",), source="paper")]

``sinslab run NAME --robustness`` re-runs the experiment for each alternative, with the
axis's ``reduced`` ``--set`` items (a smaller scenario that decides the same: the reduced
run at the default assumptions is made too and its verdicts are the baseline the
alternatives are compared with), and adds each listed claim's verdict as an alternative. A
re-run has ``ctx.claims_only`` set: ``run`` may skip figures and series files.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from sinslab.core import progress as _progress
from sinslab.app.config import (ExperimentConfig, Field, ImuSection, Q, QV, Section,  # noqa: F401
                                imu_section)                                           # (re-exported)
from sinslab.app.outputs import Figure  # noqa: F401  (re-exported: what run returns)
from sinslab.app.claims import Claim  # noqa: F401  (re-exported: what run returns)

__all__ = ["Claim", "Axis", "Metric", "Figure", "Table", "Result", "RunContext", "Experiment",
           "ExperimentConfig", "Section", "ImuSection", "imu_section", "Q", "QV", "Field", "METRIC_NAME"]

#: Metric names: stable snake_case; SI unless the name carries its unit (``_arcmin``).
METRIC_NAME = re.compile(r"^[a-z][a-zA-Z0-9]*(_[a-zA-Z0-9]+)*$")


@dataclass(frozen=True)
class Metric:
    """Declaration of a metric: its unit (as printed) and a one-line description."""

    unit: str
    description: str


@dataclass(frozen=True)
class Axis:
    """A physics assumption of the robustness sweep.

    assumption : str
        What is varied ("master attitude error"); the name the claims declare it by.
    default : str
        The run's default, as text, and whose it is (``source``: "paper" or "project").
    alternatives : {name: [dotted key=value, ...]}
        Each alternative's ``--set`` items (on top of the run's configuration).
    claims : ids of the claims whose verdicts it may change (empty: every claim).
    reduced : ``--set`` items of the smaller scenario the alternatives are run at (empty:
        at the run's own size); ``demo``: those of ``sinslab demo`` (None: as ``reduced``).
    readings : also record, per alternative, the verdicts of the re-run claims' own readings.
    in_demo : False leaves the axis out of ``sinslab demo``'s sweep (its claims say "not
        swept" there; ``sinslab run NAME --robustness`` runs it).
    """

    assumption: str
    default: str
    alternatives: Mapping[str, tuple]
    claims: tuple = ()
    reduced: tuple = ()
    demo: tuple | None = None
    source: str = "project"
    readings: bool = False
    in_demo: bool = True

    def sets(self, demo: bool = False) -> tuple:
        """The reduction's ``--set`` items at the sweep's size."""
        return tuple(self.reduced if (self.demo is None or not demo) else self.demo)


@dataclass
class Table:
    """A small table (e.g. Monte Carlo statistics) shown in the report and written as CSV."""

    name: str
    data: Any            # pandas.DataFrame or dict of equal-length columns
    caption: str = ""


@dataclass
class Result:
    """What ``run`` returns; the framework writes it out.

    metrics : {name: number | list | None}; names declared in the module's ``METRICS``.
    claims : list of :class:`Claim`.
    series : {name: DataFrame or dict of 1-D arrays} — time series, written as
        ``name.csv`` (``name.parquet`` too when longer than 100k rows).
    figures : list of :class:`Figure`.
    tables : list of :class:`Table` — shown in the report (Monte Carlo statistics ...).
    notes : lines of text for the report (assumptions, conventions of printed angles).
    """

    metrics: dict[str, Any]
    claims: list[Claim] = field(default_factory=list)
    series: dict[str, Any] = field(default_factory=dict)
    figures: list[Figure] = field(default_factory=list)
    tables: list[Table] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


@dataclass
class RunContext:
    """What the framework hands to ``run`` besides the config."""

    name: str
    out: Path
    seed: int = 0
    runs: int = 1
    quick: bool = False
    scheduler: object = None          # address, "sync", a distributed.Client, or None
    log: Callable[[str], None] = lambda msg: None
    #: folder of the finished Monte Carlo tasks of this output folder and configuration
    #: (kept when the run fails, reused by a rerun into the same folder, removed at the end)
    campaigns: Path | None = None
    config_key: str = ""
    #: a re-run of the robustness sweep: only the claims are used (figures and series may
    #: be skipped)
    claims_only: bool = False

    def campaign_store(self, label: str) -> dict:
        """``store``/``store_key`` arguments of a campaign named ``label`` (see
        :func:`sinslab.estimation.montecarlo.run_campaign`); empty without a folder."""
        if self.campaigns is None:
            return {}
        return {"store": self.campaigns / label, "store_key": self.config_key}

    def rng(self, *stream: int) -> np.random.Generator:
        """Generator for the run's seed (and optional sub-stream ids): same seed, same bytes."""
        return np.random.default_rng([self.seed, *stream])

    def progress(self, description: str, total: float | None = None, unit: str = "", *,
                 enabled: bool = True):
        """Progress bar context manager (:func:`sinslab.core.progress.progress`; none in a
        re-run of the robustness sweep)."""
        return _progress.progress(description, total, unit, enabled=enabled and not self.claims_only)


@dataclass(frozen=True)
class Experiment:
    """A registered experiment: the module's declarations, checked."""

    name: str
    purpose: str
    config: type[ExperimentConfig]
    run: Callable[[ExperimentConfig, RunContext], Result]
    quick: Mapping = field(default_factory=dict)
    metrics: Mapping[str, Metric] = field(default_factory=dict)
    paper: str = ""
    notes: tuple = ()
    module: str = ""
    #: ``{suffix: [dotted key=value, ...]}``: further scenarios that ``sinslab demo`` runs
    #: as ``NAME-suffix`` (e.g. the paper's laboratory variant or a Monte Carlo campaign).
    variants: Mapping[str, tuple] = field(default_factory=dict)
    #: ``{suffix: seconds}`` ("" the default scenario): the CPU time of each demo run at full
    #: scale, its robustness re-runs included; ``sinslab demo`` starts the longest first
    #: (an estimate that orders the runs, never read as a result; a run without one: 0).
    demo_cost: Mapping[str, float] = field(default_factory=dict)
    #: ``ROBUSTNESS(cfg) -> [Axis]`` of the module (None: no physics alternatives)
    robustness: Callable | None = None

    def axes(self, cfg) -> list:
        """The physics alternatives of the robustness sweep for the resolved ``cfg``."""
        axes = list(self.robustness(cfg)) if self.robustness is not None else []
        if not all(isinstance(a, Axis) for a in axes):
            raise TypeError(f"{self.module}.ROBUSTNESS must return Axis objects")
        return axes

    @classmethod
    def from_module(cls, mod) -> "Experiment":
        missing = [a for a in ("NAME", "PURPOSE", "Config", "run") if not hasattr(mod, a)]
        if missing:
            raise TypeError(f"experiment module {mod.__name__} lacks {', '.join(missing)}")
        if not (isinstance(mod.Config, type) and issubclass(mod.Config, ExperimentConfig)):
            raise TypeError(f"{mod.__name__}.Config must subclass sinslab.app.config.ExperimentConfig")
        metrics = dict(getattr(mod, "METRICS", {}))
        metrics.setdefault("runtime_s", Metric("s", "wall time of the experiment's computation"))
        bad = [m for m in metrics if not METRIC_NAME.match(m)]
        if bad:
            raise TypeError(f"{mod.__name__}: metric names must be snake_case: {bad}")
        return cls(name=mod.NAME, purpose=mod.PURPOSE, config=mod.Config, run=mod.run,
                   quick=dict(getattr(mod, "QUICK", {})), metrics=metrics,
                   paper=getattr(mod, "PAPER", ""), notes=tuple(getattr(mod, "NOTES", ())),
                   module=mod.__name__,
                   variants={k: tuple(v) for k, v in getattr(mod, "DEMO_VARIANTS", {}).items()},
                   demo_cost={k: float(v) for k, v in getattr(mod, "DEMO_COST_S", {}).items()},
                   robustness=getattr(mod, "ROBUSTNESS", None))
