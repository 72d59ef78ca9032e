"""The contract of a recorded run's plug-ins: aids (:class:`Aid`) and GNSS sources
(:class:`GnssSource`).

A recorded run (:func:`sinslab.fusion.recorded.navigate_recorded`) is a pipeline: a
GNSS source (fixes or raw observations), a list of aids (odometer, non-holonomic
constraint, ZUPT/ZARU, antenna lever arm, ...), a start and the filter. It iterates the
plug-ins it is given and never names what they hold: each one owns

- its **settings**, a frozen dataclass of SI values declared with :func:`setting` (unit
  kind, default as a unit string, description, command-line short form): the app turns
  the declarations into a config section (TOML, ``--set``, units checked once at the
  edge, KF-GINS' one options struct converted to SI once) and builds the dataclass;
- its **input files**, read in :meth:`Aid.load` through the data front door the app
  hands it (:class:`Inputs`);
- its **states** (:class:`State`: an error-state block of :mod:`sinslab.nav.errstate` and
  the prior σ of its states) and any correlation of their prior with the core's
  (:meth:`Aid.correlate`);
- its **measurements** (:meth:`Aid.plan`, measurement objects of the driver's protocol,
  :class:`sinslab.fusion.measurements.Measurement`), labelled so that the driver's record
  of them comes back by label (:class:`AidRun`);
- its **report** (:class:`Report`: estimates ± σ, metrics, tables, figures of plain
  panels, notes, terminal lines, spans to mark on the run's error figure), pure data
  that the app writes and draws.

A new aid is one module of :mod:`sinslab.fusion.aids` with a subclass of :class:`Aid` and
one line in the registry (:data:`sinslab.fusion.aids.AIDS`); its measurement class may
live in the same module or in :mod:`sinslab.fusion.measurements`. Modules stay cheap to
import (``sinslab config navigate`` reads the settings of every aid): numerical imports
go inside the methods.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np

from sinslab.core import units

__all__ = ["Setting", "setting", "settings_of", "Inputs", "State", "Setup", "Plan", "AidRun", "Estimate",
           "Line", "Panel", "PanelFigure", "Table", "Mark", "Report", "Aid", "GnssSource", "SourceReport",
           "merged_spans", "gated", "every", "GATE_DESCRIPTIONS"]

#: kinds of a setting that are not a quantity of :data:`sinslab.core.units.KINDS`
PLAIN_KINDS = ("flag", "choice", "text", "file", "probability", "number", "count", "mount")


@dataclass(frozen=True)
class Setting:
    """The declaration of one setting of a plug-in.

    Attributes
    ----------
    kind : str
        A quantity kind of :data:`sinslab.core.units.KINDS` (the value a unit string,
        ``n`` components), or one of :data:`PLAIN_KINDS`: ``flag`` (bool), ``choice``
        (one of ``choices``), ``text``, ``file`` (a path or a name the aid understands),
        ``probability`` (in (0, 1)), ``number`` (a float whose unit the key names),
        ``count`` (an int), ``mount`` (an ``euler:P,R,Y``-style rotation, given to the
        aid as ``(pitch, roll, yaw)`` [rad]).
    text : object
        The default as the config shows it (``"0.1 m/s"``, ``true``, ``"none"``).
    doc : str
        One line for ``sinslab config navigate`` and the docs.
    n : int
        Components of a vector quantity.
    choices : tuple of str
    bounds : dict
        ``ge``/``gt``/``le``/``lt`` unit strings (numbers for ``number``/``count``).
    none : str or None
        A word that means "not given" (``"none"``, ``"auto"``): the value is then None.
    flag : str or None
        The command-line option that is a short form of this key (``--odometer-sigma``).
    """

    kind: str
    text: Any
    doc: str
    n: int = 1
    choices: tuple = ()
    bounds: dict = field(default_factory=dict)
    none: str | None = None
    flag: str | None = None

    def si(self, value):
        """A config value (unit string, word, bool, number) in SI, as the dataclass holds
        it: a float, a tuple of ``n`` floats, a bool, a str or None."""
        if self.none is not None and (value is None or value == self.none):
            return None
        if self.kind in units.KINDS:
            if self.n == 1:
                return units.parse(value, self.kind)
            return tuple(float(x) for x in units.parse_vector(value, self.kind, self.n))
        if self.kind == "flag":
            return bool(value)
        if self.kind in ("probability", "number"):
            return float(value)
        if self.kind == "count":
            return int(value)
        return value


def setting(kind, text, doc, *, n=1, choices=(), none=None, flag=None, **bounds):
    """A dataclass field declaring a setting (:class:`Setting`); its default is ``text``
    in SI (``setting("velocity", "0.1 m/s", ...)`` defaults to 0.1)."""
    if kind not in units.KINDS and kind not in PLAIN_KINDS:
        raise ValueError(f"unknown setting kind {kind!r}")
    s = Setting(kind, text, doc, n, tuple(choices), dict(bounds), none, flag)
    default = None if kind == "mount" and text == none else s.si(text)
    return field(default=default, metadata={"setting": s})


def settings_of(cls) -> dict:
    """``{name: Setting}`` of a plug-in class, in declaration order."""
    return {f.name: f.metadata["setting"] for f in dataclasses.fields(cls) if "setting" in f.metadata}


class Inputs(Protocol):
    """What a plug-in may read (the app's side of :meth:`Aid.load`)."""

    #: the IMU file(s) as given: an aid may read a column of the IMU table
    imu_path: object
    #: ``(t (N,), flags (N,) bool)`` of the IMU table's rest column, or None
    rest_flags: tuple | None

    def read(self, reader: str, *args, **kw):
        """``sinslab.data.<reader>(*args, **kw)``: a reader of the data front door
        (``read_*`` names of :mod:`sinslab.data`), its errors naming the file."""

    def clock(self, t):
        """Times ``t`` [s] of a sensor on the IMU's clock, corrected like the IMU's own
        stamps (the time offset and drift the run estimated and applied; else ``t``)."""


@dataclass(frozen=True)
class State:
    """An error-state block a plug-in owns (:mod:`sinslab.nav.errstate`) and the prior σ
    of its states (scalar or one per state). ``role`` offers the block to others:
    ``"antenna_lever"`` is the GNSS antenna's lever arm, which the GNSS source's
    measurements then estimate."""

    block: Any
    sigma: Any
    role: str | None = None


@dataclass(frozen=True)
class Setup:
    """What the plug-ins see when they make their measurements (and correlate their prior).

    Attributes
    ----------
    imu : sinslab.core.records.ImuRecord
    T : float
        Filter step [s].
    t_start, t_end : float
        First and last filter epoch [s].
    lat : float
        Latitude of the first GNSS fix [rad] (gravity and Earth rate at the site).
    layout : sinslab.nav.errstate.StateLayout
    start : sinslab.fusion.recorded_start.StartSolution
    gyro_noise : ndarray (3,)
        Gyro white noise the filter assumes [rad/√s].
    fixes_used : sinslab.core.records.Fixes
        The GNSS fixes inside the filter span and outside the outages (of the raw
        source: its single-point solutions there).
    outages : list of (start, length)
        GNSS outages [s].
    start_spec : sinslab.fusion.recorded_spec.StartSpec
    lever_arm : ndarray (3,)
        IMU -> GNSS antenna, body axes [m] (the value a lever-arm state is the error of).
    platform : (str, str)
        The platform kind and why.
    """

    imu: Any
    T: float
    t_start: float
    t_end: float
    lat: float
    layout: Any
    start: Any
    gyro_noise: Any
    fixes_used: Any
    outages: list
    start_spec: Any
    lever_arm: Any
    platform: tuple


@dataclass(frozen=True)
class Plan:
    """What a plug-in contributes to one run: ``measurements`` ``((label, measurement),
    ...)`` in processing order, and ``facts`` the plug-in found while making them (read
    back by its own :meth:`Aid.report`)."""

    measurements: tuple = ()
    facts: Any = None


@dataclass(frozen=True)
class AidRun:
    """A finished run as a plug-in's report sees it.

    Attributes
    ----------
    t, x, sigma : ndarray (M,), (M, n), (M, n)
        Filter epochs, estimate after each epoch (the states not fed back) and σ.
    layout : sinslab.nav.errstate.StateLayout
    smoothed : sinslab.fusion.smoothing.SmoothedRun or None
    gates : dict
        ``{label: sinslab.fusion.observer.GateLog}`` of the plug-in's measurements.
    rows : dict
        ``{label: sinslab.fusion.observer.RowLog or None}``.
    T : float
        Filter step [s].
    t_ref : float
        The first GNSS fix [s] (times in terminal lines are counted from it).
    applied : dict
        ``{label: (t_applied (J,), innovation list, nis (J,), innovation σ list)}``:
        the driver's record of the updates of each of the plug-in's measurements.
    """

    t: Any
    x: Any
    sigma: Any
    layout: Any
    smoothed: Any
    gates: dict
    rows: dict
    T: float
    t_ref: float
    applied: dict


@dataclass(frozen=True)
class Estimate:
    """A quantity a plug-in estimated: ``value`` and ``sigma`` ((k,), None where a
    component is not estimated) in ``unit`` (as shown), with component ``labels``."""

    name: str
    value: tuple
    sigma: tuple
    unit: str
    labels: tuple = ()

    def text(self, digits=3):
        """``"a ± b, ..."`` of the components."""
        return ", ".join(f"{v:.{digits}f}" + ("" if s is None else f" ± {s:.{digits}f}")
                         for v, s in zip(self.value, self.sigma))


@dataclass(frozen=True)
class Line:
    """One drawn series of a panel: ``y`` against ``t`` [s from the filter start], with
    an optional band ``y ± band``; ``style`` a matplotlib format (``"-"``, ``"."``)."""

    t: Any
    y: Any
    label: str = ""
    band: Any = None
    style: str = "-"


@dataclass(frozen=True)
class Panel:
    """One row of a figure: its lines, y label, log scale, and spans [s from the start]
    shaded behind them."""

    ylabel: str
    lines: tuple
    log: bool = False
    spans: tuple = ()


@dataclass(frozen=True)
class PanelFigure:
    """A figure of panels stacked on one time axis (the app draws it)."""

    name: str
    caption: str
    panels: tuple
    title: str = ""


@dataclass(frozen=True)
class Table:
    """A table the run folder gets: ``columns`` ``{name: (N,) array}``."""

    name: str
    columns: dict
    description: str = ""


@dataclass(frozen=True)
class Mark:
    """Spans ``((start, end), ...)`` [s, absolute] to mark on the run's error figure:
    ``kind`` ``"band"`` (shaded across the axes, e.g. rest) or ``"bar"`` (a bar at the top,
    e.g. updates refused by a gate); ``label`` for the figure's title."""

    kind: str
    spans: tuple
    label: str


@dataclass(frozen=True)
class Report:
    """What a plug-in did in a run, as data: the app writes and draws it.

    ``metrics`` go into ``summary.json`` (names with a unit suffix, SI or as named);
    ``descriptions`` ``{metric regex: description}`` explain them in the report;
    ``notes`` are report lines, ``lines`` terminal lines."""

    name: str
    title: str
    estimates: tuple = ()
    metrics: dict = field(default_factory=dict)
    descriptions: tuple = ()
    tables: tuple = ()
    figures: tuple = ()
    notes: tuple = ()
    lines: tuple = ()
    marks: tuple = ()


class Aid:
    """Base of an aid plug-in: a frozen dataclass of settings (:func:`setting`) and the
    methods below (the defaults: no inputs, no states, no correlation). Subclasses set

    ``name``
        The registry key, the config section and the ``--aid`` token.
    ``summary``
        One line for ``--help`` and the docs.
    ``land_only``
        What the aid assumes of a wheeled land vehicle (``"the non-holonomic
        constraint"``), or None: the run refuses it off land.
    ``aliases``
        Other ``--aid`` tokens that enable this aid with some settings
        (``{"zaru": {"zaru": True}}``).
    """

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    land_only: ClassVar[str | None] = None
    aliases: ClassVar[dict] = {}

    def load(self, inputs: Inputs) -> "Aid":
        """This aid with its input files read (default: it has none)."""
        return self

    def states(self) -> tuple:
        """Its error-state blocks with their prior σ (:class:`State`), in order."""
        return ()

    def correlate(self, P0, setup: Setup) -> None:
        """Add to ``P0`` (in place) the prior correlation of its states with the others'."""

    def plan(self, setup: Setup) -> Plan:
        """Its measurements for this run."""
        raise NotImplementedError

    def report(self, plan: Plan, run: AidRun) -> Report:
        """What it did."""
        raise NotImplementedError


@dataclass(frozen=True)
class SourceReport(Report):
    """A GNSS source's report: a :class:`Report` and what the app checks the run by.

    ``coupling`` says how the GNSS entered (``"loosely coupled"``: position/velocity
    fixes; ``"tightly coupled"``: pseudoranges and Doppler); ``fix_records`` (fixes only)
    ``(t (J,), innovation (J, m), innovation σ (J, m) or None, nis (J,))`` of the fixes
    applied; ``rows`` ``{label: RowLog}`` the satellites' rows and ``clock`` ``(estimate
    (M, k), σ (M, k))`` the receiver clock (raw only); ``reference`` what the solution is
    compared with (the fixes, or the single-point solution); ``fix_sigma`` (J, m) the σ
    each applied fix was taken with (fixes only)."""

    coupling: str = ""
    fix_records: tuple | None = None
    fix_sigma: np.ndarray | None = None
    rows: dict = field(default_factory=dict)
    clock: tuple | None = None
    reference: str = "fixes"


class GnssSource(Protocol):
    """A GNSS source of a recorded run: position/velocity fixes
    (:class:`sinslab.fusion.loosely_coupled.FixSource`) or raw observations
    (:class:`sinslab.fusion.tightly_coupled.RawSource`)."""

    #: ``"fixes"`` | ``"raw"``
    name: str

    def start_fixes(self):
        """The :class:`~sinslab.core.records.Fixes` that start the filter (levelling in
        motion, heading from the course) and that the solution is compared with."""

    def prepare(self, fixes):
        """``(fixes, source)``: what the source makes of its start fixes once they are in the
        record (the fix source measures their time-correlated error and may take it as
        states of its own); the source returned is the one the run goes on with."""

    def states(self) -> tuple:
        """Its error-state blocks (a receiver clock, the fixes' correlated error) with their
        prior σ."""

    def plan(self, setup: Setup, fixes, lever_block) -> Plan:
        """Its measurements (first in the run): ``fixes`` the start fixes inside the
        filter span, ``lever_block`` the block estimating the antenna lever arm (or None)."""

    def report(self, plan: Plan, run: AidRun) -> SourceReport:
        """What it did."""


def merged_spans(times, gap):
    """Sorted times [s] merged into ``((start, end), ...)`` spans where consecutive ones
    are less than ``gap`` apart."""
    t = np.asarray(times, dtype=float)
    if t.size == 0:
        return ()
    br = np.flatnonzero(np.diff(t) >= gap)
    return tuple((float(t[a]), float(t[b])) for a, b in zip(np.r_[0, br + 1], np.r_[br, t.size - 1]))


#: descriptions of the metrics :func:`gated` makes
GATE_DESCRIPTIONS = ((r"^(\w+?)_updates_applied$", "{0} updates inside the innovation gate, applied"),
                     (r"^(\w+?)_updates_rejected$", "{0} updates the innovation gate rejected (the filter's own "
                      "state contradicts the assumption, e.g. rest while moving)"))


def gated(label, log, gap, t_ref):
    """What an innovation gate did, for a report: ``(metrics, lines, mark or None)`` of
    the measurement ``label``'s :class:`~sinslab.fusion.observer.GateLog` (refusals merged
    into spans less than ``gap`` s apart; times in lines from ``t_ref``)."""
    rejected = len(log.rejected)
    metrics = {f"{label}_updates_applied": log.passed, f"{label}_updates_rejected": rejected}
    spans = merged_spans(log.rejected, gap)
    if not rejected:
        return metrics, (), None
    line = (f"  {label.upper()}: {rejected} of {log.passed + rejected} updates rejected by the innovation gate "
            f"(the filter's own velocity/rate contradicts them), in {len(spans)} span(s) from "
            + ", ".join(f"{a - t_ref:.1f}-{b - t_ref:.1f} s" for a, b in spans[:4])
            + (" ..." if len(spans) > 4 else ""))
    return metrics, (line,), Mark("bar", spans, "aiding rejected by the gate")


def every(interval, T):
    """Filter epochs between two updates made every ``interval`` s (at least 1)."""
    return max(1, int(round(interval / T)))
