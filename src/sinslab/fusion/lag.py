"""Lag policies of the fusion driver: how a measurement valid at an earlier epoch than the
one it arrives at is applied.

This is the one lag vocabulary of the compositions and methods: a lag is always a policy
object (:class:`ExactReprocessing`, :class:`OnArrival`, or a method's own, e.g.
:class:`sinslab.methods.doublestar.StoredStateUpdate`); when the arrival is the validity
time there is no lag to handle. A name from a command line or a config file becomes a
policy once, at the app's edge, by :func:`lag_policy`.

A policy has a ``name``, three attributes and one method:

``on_arrival`` (bool)
    Apply a late measurement at its arrival epoch as if it were valid then (no lagged
    update at all).
``corrected_nav`` (bool)
    Form the lagged measurement from the navigation output of its validity epoch
    *after* the feedback applied at that epoch (True) or *before* it (False).
``needs_model`` (bool)
    The driver keeps the continuous model ``F`` and ``Qc = G diag(q) Gᵀ`` of every
    epoch and passes those of the validity epoch to :meth:`update`.
``update(filt, z, H, R, t_m, *, F, Qc, tol)``
    Apply the measurement to the :class:`sinslab.estimation.filter.KalmanFilter` and
    return its :class:`sinslab.estimation.kalman.UpdateResult`. ``t_m`` is on the
    filter's own clock.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ExactReprocessing", "OnArrival", "POLICIES", "lag_policy"]


@dataclass(frozen=True)
class ExactReprocessing:
    """Insert the measurement at its validity epoch and re-process the stored steps and
    measurements up to now (:meth:`KalmanFilter.update_lagged`): for a linear system the
    result equals that of a filter that received it on time. The measurement is formed
    from the INS output of its epoch before that epoch's feedback. The default."""

    name = "exact"
    on_arrival = False
    corrected_nav = False
    needs_model = False

    def update(self, filt, z, H, R, t_m, *, F=None, Qc=None, tol=1e-6):
        return filt.update_lagged(z, H, R, t_m, tol=tol)


@dataclass(frozen=True)
class OnArrival:
    """Ignore the lag: a late measurement is applied at its arrival epoch, compared with
    the navigation output of that epoch, as if it were valid then (the naive filter)."""

    name = "on-arrival"
    on_arrival = True
    corrected_nav = False
    needs_model = False

    def update(self, filt, z, H, R, t_m, *, F=None, Qc=None, tol=1e-6):
        raise RuntimeError("OnArrival applies measurements on arrival; no lagged update")


#: the policies of this module by name
POLICIES = {p.name: p for p in (ExactReprocessing, OnArrival)}


def lag_policy(name, extra=()):
    """The lag policy called ``name``: one of :data:`POLICIES` or of the policy classes
    ``extra`` (a method's own, each with a ``name``); a policy object is returned as it is.

    Raises
    ------
    ValueError
        An unknown name, listing the known ones.
    """
    if not isinstance(name, str):
        return name
    known = {**POLICIES, **{p.name: p for p in extra}}
    if name not in known:
        raise ValueError(f"unknown lag policy {name!r}; one of {', '.join(known)}")
    return known[name]()
