"""Magnetometer: the heading (or the whole field vector) a three-axis magnetometer reads,
against the Earth's field of IGRF-14 at the run's place and date
(:mod:`sinslab.nav.magnetic`, declination and inclination from the model), with the
residual hard iron estimated (three states,
:func:`sinslab.nav.errstate.magnetometer_bias`) and an innovation gate against local
disturbances (:class:`~sinslab.fusion.measurements.MagneticHeading`,
:class:`~sinslab.fusion.measurements.MagneticField`).

The readings are turned into the IMU body axes by the magnetometer's own ``frame`` and
``mount`` (those of the IMU when the chips share a board), calibrated by the given soft
and hard iron (body axes) or by an ellipsoid fitted to the record (``fit = "ellipsoid"``,
refused when the readings turn too little: a level flight turns the field on a cone),
and their unit is checked against the model: a median magnitude a factor of ten or more
off the model's field is a file in another unit than declared (µT written where gauss is
declared reads 100× the Earth's field), refused with the unit the values fit.

A reading the filter's own covariance cannot explain (a hangar, a car beside the mast,
the motor's current on an electric aircraft) is refused by the gate and counted, not
fatal; the report lists the refused spans, the model's field, the hard iron estimated and
the innovations.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sinslab.fusion.aids.base import (GATE_DESCRIPTIONS, Aid, AidRun, Estimate, Line, Panel, PanelFigure, Plan,
                                      Report, Setup, State, gated, setting)

__all__ = ["Magnetometer"]


@dataclass(frozen=True)
class Magnetometer(Aid):
    """The magnetometer aid (see the module notes)."""

    name = "magnetometer"
    summary = "heading (or the field vector) from a three-axis magnetometer against IGRF-14, hard iron estimated"

    file: str = setting("file", "", "the magnetometer's table: a time column and mx, my, mz (or a column map)")
    columns: str | None = setting("text", "none", "column map over t, mx, my, mz with units, e.g. "
                                  "\"t=time[s], mx=mag_x[G], my=mag_y[G], mz=mag_z[G]\"", none="none")
    unit: str | None = setting("text", "none", "field unit when neither the map nor the header gives one "
                               "(G, mG, uT, nT, T)", none="none")
    frame: str = setting("choice", "rfu", "axis convention of the magnetometer (as the IMU's --frame)",
                         choices=("rfu", "frd", "flu", "rbd"))
    mount: str | None = setting("text", "none", "magnetometer -> body mount (as the IMU's --mount)", none="none")
    date: str | None = setting("text", "none", "date of the record for the geomagnetic model (YYYY-MM-DD)",
                               none="none")
    mode: str = setting("choice", "heading", "what is measured: the heading of the levelled field (1 row) or "
                        "the field vector (3 rows: also pitch and roll)", choices=("heading", "field"))
    sigma: float = setting("angle", "3 deg", "σ of a magnetic heading (mode heading)", gt="0 deg", le="90 deg")
    field_sigma: float = setting("magnetic_field", "1 uT", "σ of each field component (mode field)",
                                 gt="0 uT", le="100 uT")
    soft_iron: str = setting("text", "identity", "soft-iron correction W, body axes, 9 numbers row by row "
                             "(calibrated = W (reading − hard iron))")
    hard_iron: tuple = setting("magnetic_field", "[0, 0, 0] uT", "hard iron removed first, body axes", n=3)
    fit: str = setting("choice", "none", "fit the calibration to the record (ellipsoid, when the readings turn "
                       "enough) instead of the given one", choices=("none", "ellipsoid"))
    estimate: bool = setting("flag", True, "estimate the residual hard iron (3 states)")
    hard_iron_sigma: float = setting("magnetic_field", "5 uT", "prior σ of each residual hard-iron state",
                                     gt="0 uT", le="1000 uT")
    rate: float = setting("frequency", "1 Hz", "magnetometer updates per second", gt="0 Hz", le="1000 Hz")
    gate: float | None = setting("probability", 1e-4, "false-rejection probability of the innovation gate "
                                 "(none: no gate)", none="none", gt=0.0, lt=1.0)
    #: the readings (:class:`sinslab.data.sensors.SensorTable`, set by :meth:`load`)
    table: object = None

    def load(self, inputs):
        if not self.file:
            raise ValueError("magnetometer.file: give the magnetometer's table")
        if self.date is None:
            raise ValueError("magnetometer.date: give the date of the record (YYYY-MM-DD) for the geomagnetic "
                             "model")
        from sinslab.nav.magnetic import decimal_year
        decimal_year(self.date)
        self._soft()
        tab = inputs.read("read_magnetometer", self.file, self.columns, unit=self.unit, frame=self.frame,
                          mount=self.mount)
        return dataclasses.replace(self, table=dataclasses.replace(tab, t=inputs.clock(tab.t)))

    def _soft(self):
        if self.soft_iron.strip().lower() == "identity":
            return np.eye(3)
        try:
            W = np.array([float(x) for x in self.soft_iron.replace("[", " ").replace("]", " ")
                          .replace(";", ",").split(",") if x.strip()])
        except ValueError:
            W = np.zeros(0)
        if W.shape != (9,):
            raise ValueError(f"magnetometer.soft_iron = {self.soft_iron!r}: give 9 numbers row by row or identity")
        return W.reshape(3, 3)

    def _block(self):
        from sinslab.nav import errstate as es
        return es.magnetometer_bias()

    def states(self):
        return (State(self._block(), self.hard_iron_sigma),) if self.estimate else ()

    def plan(self, setup: Setup) -> Plan:
        from sinslab.core.stamps import check_time_base
        from sinslab.fusion.measurements import MagneticField, MagneticHeading
        from sinslab.nav.magnetic import MagCalibration, ellipsoid_fit
        tab = self.table
        check_time_base(tab.t, setup.imu.t0, float(setup.imu.t[-1]), tab.path)
        field = tab.values["field"]
        ref, model = self._reference(setup, tab.t)
        self._check_unit(field, ref)
        cal, fit = MagCalibration(self._soft(), np.asarray(self.hard_iron)), None
        if self.fit == "ellipsoid":
            try:
                cal, fit = ellipsoid_fit(field, float(np.median(np.linalg.norm(ref, axis=1))))
            except ValueError as e:
                raise ValueError(f"magnetometer.fit = ellipsoid: {tab.path}: {e}") from None
        keep = np.flatnonzero((tab.t > setup.t_start) & (tab.t <= setup.t_end))
        if keep.size == 0:
            raise ValueError(f"{tab.path}: no magnetometer reading inside the run ({setup.t_start:.3f}.."
                             f"{setup.t_end:.3f} s)")
        dt = float(np.median(np.diff(tab.t))) if len(tab) > 1 else 1.0
        keep = keep[::max(1, int(round(1.0 / (self.rate * dt))))]
        kw = dict(calibration=cal, gate=self.gate, bias_block=self._block().name if self.estimate else None)
        m = (MagneticHeading(tab.t[keep], field[keep], ref[keep], self.sigma, **kw) if self.mode == "heading"
             else MagneticField(tab.t[keep], field[keep], ref[keep], self.field_sigma, **kw))
        return Plan((("magnetometer", m),), {"model": model, "reference": ref[keep], "fit": fit,
                                             "calibration": cal})

    def _reference(self, setup, t):
        """IGRF-14 at the fixes of the run, interpolated to the readings ``t``: ``(J, 3)``
        ENU [T] and the model's name."""
        from sinslab.nav.magnetic import reference_field
        fx = setup.fixes_used
        h = np.where(np.isfinite(fx.h), fx.h, 0.0)
        rf = reference_field(fx.lat, fx.lon, h, self.date)
        return np.column_stack([np.interp(t, fx.t, rf.b_n[:, i]) for i in range(3)]), rf.model

    def _check_unit(self, field, ref):
        from sinslab.core import units
        from sinslab.nav.magnetic import FIELD_UNITS, likely_field_unit
        tab = self.table
        declared = tab.units["mx"]
        s = units.unit_scale(declared, "magnetic_field")
        F = float(np.median(np.linalg.norm(ref, axis=1)))
        likely = likely_field_unit(field / s, F / s * s)
        if not math.isclose(FIELD_UNITS[likely], s, rel_tol=1e-9):
            med = float(np.median(np.linalg.norm(field, axis=1))) / s
            raise ValueError(f"{tab.path}: the readings' median magnitude {med:.4g} {declared} is "
                             f"{med * s / F:.3g}× the Earth's field here ({F / s:.4g} {declared}, IGRF-14): "
                             f"the file is in {likely}, not {declared}")

    def report(self, plan: Plan, run: AidRun) -> Report:
        (label, m), = plan.measurements
        facts = plan.facts
        ref = facts["reference"]
        from sinslab.nav.magnetic import ReferenceField
        rf = ReferenceField(ref[len(ref) // 2], facts["model"])
        D, I, F = math.degrees(rf.declination), math.degrees(rf.inclination), float(rf.intensity)
        metrics = {"magnetometer_declination_deg": D, "magnetometer_inclination_deg": I,
                   "magnetometer_intensity_uT": F * 1e6, "magnetometer_model": facts["model"]}
        lines = [f"  magnetometer ({self.mode}): {facts['model']} on {self.date}: declination {D:.2f}°, "
                 f"inclination {I:.2f}°, intensity {F * 1e6:.2f} µT"]
        est, figs_lines = (), []
        if self.estimate:
            sl = run.layout.slice(self._block().name)
            b = (m.bias - run.x[-1, sl]) * 1e6                    # δβ = β_used − β_true
            sb = run.sigma[-1, sl] * 1e6
            est = (Estimate("magnetometer_hard_iron", tuple(b.tolist()), tuple(sb.tolist()), "µT",
                            ("right", "forward", "up")),)
            metrics.update(magnetometer_hard_iron_uT=b.tolist(), magnetometer_hard_iron_sigma_uT=sb.tolist())
            lines.append("  magnetometer residual hard iron [µT] (body right, forward, up) " + est[0].text(2))
        if facts["fit"] is not None:
            metrics.update(magnetometer_fit_residual=facts["fit"].residual,
                           magnetometer_fit_coverage=facts["fit"].coverage.tolist())
        marks = []
        if m.gate is not None:
            mt, _, mk = gated(label, run.gates[label], 2.5 / self.rate, run.t_ref)
            metrics.update(mt)
            n_rej, n = mt[f"{label}_updates_rejected"], mt[f"{label}_updates_applied"] + mt[f"{label}_updates_rejected"]
            lines.append(f"  magnetometer: {n_rej} of {n} updates refused by the innovation gate (a field the "
                         f"model does not have: a local disturbance)")
            marks += [mk] if mk else []
        figs = self._figure(label, run)
        return Report(self.name, "magnetometer", estimates=est, metrics=metrics,
                      descriptions=((r"^magnetometer_declination_deg$", "declination of the model's field at the "
                                     "run (east of true north)"),
                                    (r"^magnetometer_inclination_deg$", "inclination (dip) of the model's field"),
                                    (r"^magnetometer_intensity_uT$", "intensity of the model's field"),
                                    (r"^magnetometer_hard_iron(_sigma)?_uT$", "residual hard iron the filter "
                                     "estimated (and its 1σ) at the end, body axes"),
                                    (r"^magnetometer_fit_", "ellipsoid fit: residual of the calibrated magnitude "
                                     "(relative) and the spread of the field's direction"),
                                    (r"^magnetometer_model$", "the geomagnetic model and the package that gave it"),
                                    *GATE_DESCRIPTIONS),
                      figures=figs, notes=(lines[0].strip() + ".",), lines=tuple(lines), marks=tuple(marks))

    def _figure(self, label, run):
        """The innovations of the updates applied with the filter's ±σ."""
        if label not in run.applied:
            return ()
        ap = run.applied[label]
        if len(ap.t_applied) == 0:
            return ()
        nu, sd = np.asarray(list(ap.innovation), dtype=float), np.asarray(list(ap.innovation_sigma), dtype=float)
        tt = np.asarray(ap.t_applied, dtype=float) - float(run.t[0])
        if self.mode == "heading":
            pan = (Panel("heading innovation [deg]", (Line(tt, np.degrees(nu[:, 0]), band=np.degrees(sd[:, 0]),
                                                          style="."),)),)
        else:
            pan = tuple(Panel(f"field {a} innovation [µT]", (Line(tt, nu[:, i] * 1e6, band=sd[:, i] * 1e6,
                                                                  style="."),))
                        for i, a in enumerate(("right", "forward", "up")))
        return (PanelFigure("magnetometer", "magnetometer innovations (computed − measured) of the updates "
                            "applied, with the filter's ±1σ", pan),)
