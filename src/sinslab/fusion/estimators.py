"""The estimator of a recorded run, a strategy: the error-state Kalman filter (with its
RTS smoother when asked) or the factor graph (``sinslab.fusion.graph``, the optional GTSAM extra: batch or
fixed-lag) on the same inputs.

:func:`sinslab.fusion.recorded.navigate_recorded` makes the inputs once — the IMU, the
start, the error model and its prior, the plug-ins' measurements — as an
:class:`Estimation`, and hands them to the estimator it is given; the estimator returns the
solution as the driver's result (:class:`sinslab.fusion.driver.DriverResult`), the
smoothed run (or None) and its own report (or None), so everything after it (the plug-ins'
reports, the evaluation, the outputs) is the same whichever estimator ran.

Choices (:func:`estimator_of`): ``"filter"``, ``"graph"`` (batch Levenberg–Marquardt over
the whole record), ``"fixed-lag:SECONDS"`` (GTSAM's incremental fixed-lag smoother).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

__all__ = ["Estimation", "Estimator", "KalmanEstimator", "estimator_of", "estimator_name", "canonical_estimator",
           "ESTIMATOR_CHOICES"]

#: the estimators :func:`estimator_of` knows, as a user writes them
ESTIMATOR_CHOICES = ("filter", "graph", "fixed-lag:SECONDS")


@dataclass(frozen=True)
class Estimation:
    """The inputs of a recorded run's estimator, made once by the pipeline.

    Attributes
    ----------
    imu : sinslab.core.records.ImuRecord
    start : sinslab.fusion.recorded_start.StartSolution
    model : sinslab.nav.errstate.ErrorModel
    P0 : ndarray (n, n)
    ins : sinslab.fusion.spec.InsSpec
    grid : sinslab.fusion.spec.FilterGrid
    plans : list of sinslab.fusion.aids.base.Plan
        The GNSS source's plan first, then each aid's.
    opt : sinslab.fusion.recorded_spec.NavOptions
    progress : bool
    """

    imu: Any
    start: Any
    model: Any
    P0: Any
    ins: Any
    grid: Any
    plans: list
    opt: Any
    progress: bool = False


class Estimator(Protocol):
    """A recorded run's estimator."""

    #: ``"filter"``, ``"graph"``, ``"fixed-lag"``
    name: str

    def ready(self) -> None:
        """Refuse at once when what the estimator needs is not installed (one line)."""

    def check(self, smooth: bool, source: str, aids) -> None:
        """Refuse, before any data is processed, what this estimator cannot take (one
        line, :class:`~sinslab.core.errors.InputError`): ``smooth`` whether the RTS
        smoother is asked for, ``source`` the GNSS source's name (``"fixes"``, ``"raw"``),
        ``aids`` the aids' names."""

    def estimate(self, e: Estimation) -> tuple:
        """``(DriverResult, smoothed run or None, report or None)``."""


@dataclass(frozen=True)
class KalmanEstimator:
    """The error-state Kalman filter on one INS core
    (:func:`sinslab.fusion.loosely_coupled.ins_core`), every plug-in's measurements in
    order, the lag policy of the fixes; the RTS smoother over its recorded forward pass
    when ``opt.grid.smooth``."""

    name = "filter"

    def ready(self) -> None:
        return None

    def check(self, smooth, source, aids) -> None:
        return None

    def estimate(self, e: Estimation) -> tuple:
        from sinslab.fusion.loosely_coupled import ins_core
        from sinslab.fusion.smoothing import History, smooth
        opt = e.opt
        core = ins_core(e.imu, e.start.nav_state, e.model, e.ins, e.grid, opt.fix.lag, True)
        r = core.run(e.P0, [m for p in e.plans for _, m in p.measurements], grid=e.grid, lag=opt.fix.lag,
                     history=History(0.1, spill=opt.grid.smooth_spill) if opt.grid.smooth else None,
                     progress=e.progress, label="navigating")
        return r, (smooth(r) if opt.grid.smooth else None), None


def estimator_name(text) -> tuple[str, float | None]:
    """``(kind, window [s])`` of an estimator as a user writes it: ``"filter"``,
    ``"graph"`` (``"batch"``), ``"fixed-lag:SECONDS"`` (a number of seconds or a time with
    its unit, ``"fixed-lag:20 s"``); anything else one line naming the choices
    (:class:`~sinslab.core.errors.InputError`). Cheap: no numerical import."""
    import math

    from sinslab.core import units
    from sinslab.core.errors import InputError
    s = str(text).strip().lower()
    if s in ("filter", "kalman"):
        return "filter", None
    if s in ("graph", "batch"):
        return "graph", None
    if s.startswith("fixed-lag:"):
        w = s.split(":", 1)[1].strip()
        try:
            lag = float(w)                          # a bare number: seconds
        except ValueError:
            try:
                lag = units.parse(w, "time")
            except ValueError:
                lag = float("nan")
        if not (math.isfinite(lag) and lag > 0):
            raise InputError(f"estimator {text!r}: the fixed-lag window must be a time > 0, e.g. fixed-lag:20 s")
        return "fixed-lag", float(lag)
    raise InputError(f"unknown estimator {text!r}: choose " + ", ".join(ESTIMATOR_CHOICES))


def canonical_estimator(text) -> str:
    """The estimator as the run's config.toml writes it (``"fixed-lag:20 s"``)."""
    kind, lag = estimator_name(text)
    return kind if lag is None else f"fixed-lag:{lag:g} s"


def estimator_of(text) -> Estimator:
    """The estimator named ``text`` (:func:`estimator_name`)."""
    kind, lag = estimator_name(text)
    if kind == "filter":
        return KalmanEstimator()
    from sinslab.fusion.graph.estimator import GraphEstimator, GraphSpec
    return GraphEstimator(GraphSpec("batch") if kind == "graph" else GraphSpec("fixed-lag", lag))
