"""Barometer: the pressure height of a barometric altimeter against the INS height
(:class:`~sinslab.fusion.measurements.Barometer`), with its bias estimated (one state,
:func:`sinslab.nav.errstate.barometer_bias`).

A pressure height is the height of the standard atmosphere at the pressure read: it is
off the ellipsoid height by the reference pressure of the day, the geoid, the temperature
profile and, on an aircraft, the static-port error that changes with airspeed. The bias
starts at the median of the readings minus the GNSS heights over the first
``bias_window`` of the run (``bias = "auto"``) or at the value given, and is estimated
while the GNSS holds the height; through an outage the barometer then holds it.
By default the bias is a slowly varying Gauss–Markov process (``drift_sigma`` over
``drift_time``): over a short record it is all but constant, over a long one it follows
the weather; ``drift_sigma = "none"`` makes it a random constant.

A table on another clock than the IMU's is refused (its stamps barely overlap the IMU
record); a reading the filter's covariance cannot explain (a pressure jump, ground effect
at take-off) is refused by the gate and counted.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from sinslab.fusion.aids.base import (GATE_DESCRIPTIONS, Aid, AidRun, Estimate, Line, Panel, PanelFigure, Plan,
                                      Report, Setup, State, gated, setting)

__all__ = ["BarometricAltimeter"]


@dataclass(frozen=True)
class BarometricAltimeter(Aid):
    """The barometer aid (see the module notes)."""

    name = "barometer"
    summary = "barometric height with its (slowly varying) bias estimated"

    file: str = setting("file", "", "the barometer's table: a time column and the pressure height h")
    columns: str | None = setting("text", "none", "column map over t, h with units, e.g. "
                                  "\"t=time[s], h=baro_alt[m]\"", none="none")
    unit: str | None = setting("text", "none", "height unit when neither the map nor the header gives one "
                               "(default m)", none="none")
    sigma: float = setting("length", "2 m", "σ of a pressure height (noise and the static-port error that "
                           "changes with airspeed)", gt="0 m", le="1000 m")
    rate: float = setting("frequency", "1 Hz", "barometer updates per second", gt="0 Hz", le="1000 Hz")
    bias: float | None = setting("length", "auto", "bias removed from the readings at the start (auto: the "
                                 "median of readings minus GNSS heights over bias_window)", none="auto")
    bias_window: float = setting("time", "10 s", "span of the run's first fixes the automatic bias is found "
                                 "over", gt="0 s", le="1 h")
    bias_sigma: float = setting("length", "3 m", "prior σ of the bias state", gt="0 m", le="10000 m")
    drift_sigma: float | None = setting("length", "3 m", "steady-state σ of the bias's slow variation "
                                        "(none: a constant bias)", none="none", gt="0 m", le="10000 m")
    drift_time: float = setting("time", "1 h", "correlation time of that variation", gt="0 s", le="1000 h")
    gate: float | None = setting("probability", 1e-4, "false-rejection probability of the innovation gate "
                                 "(none: no gate)", none="none", gt=0.0, lt=1.0)
    #: the readings (:class:`sinslab.data.sensors.SensorTable`, set by :meth:`load`)
    table: object = None

    def load(self, inputs):
        if not self.file:
            raise ValueError("barometer.file: give the barometer's table")
        tab = inputs.read("read_barometer", self.file, self.columns, unit=self.unit)
        return dataclasses.replace(self, table=dataclasses.replace(tab, t=inputs.clock(tab.t)))

    def _block(self):
        from sinslab.nav import errstate as es
        if self.drift_sigma is None:
            return es.barometer_bias()
        return es.barometer_bias(tau=self.drift_time, sigma=self.drift_sigma)

    def states(self):
        return (State(self._block(), self.bias_sigma),)

    def plan(self, setup: Setup) -> Plan:
        from sinslab.core.stamps import check_time_base
        from sinslab.fusion.measurements import Barometer
        tab = self.table
        check_time_base(tab.t, setup.imu.t0, float(setup.imu.t[-1]), tab.path)
        keep = np.flatnonzero((tab.t > setup.t_start) & (tab.t <= setup.t_end))
        if keep.size == 0:
            raise ValueError(f"{tab.path}: no barometer reading inside the run ({setup.t_start:.3f}.."
                             f"{setup.t_end:.3f} s)")
        dt = float(np.median(np.diff(tab.t))) if len(tab) > 1 else 1.0
        keep = keep[::max(1, int(round(1.0 / (self.rate * dt))))]
        t, h = tab.t[keep], tab.values["h"][keep]
        b0, how = (self.bias, "given") if self.bias is not None else self._auto_bias(setup, tab)
        m = Barometer(t, h, self.sigma, bias=b0, bias_block=self._block().name, gate=self.gate)
        return Plan((("barometer", m),), {"bias0": b0, "how": how})

    def _auto_bias(self, setup, tab):
        """Median of the readings minus the GNSS heights over the first ``bias_window`` of
        fixes in the run."""
        fx = setup.fixes_used
        w = (fx.t >= setup.t_start) & (fx.t <= setup.t_start + self.bias_window) & np.isfinite(fx.h)
        if w.sum() < 1:
            raise ValueError(f"barometer.bias = auto: no GNSS height in the first {self.bias_window:g} s of the "
                             "run to find the barometer's bias from; give barometer.bias")
        d = np.interp(fx.t[w], tab.t, tab.values["h"]) - fx.h[w]
        return float(np.median(d)), f"median of {int(w.sum())} readings minus GNSS heights at the start"

    def report(self, plan: Plan, run: AidRun) -> Report:
        (label, m), = plan.measurements
        sl = run.layout.slice(self._block().name)
        b = m.bias - run.x[:, sl][:, 0]                    # δb = b_used − b_true
        sb = run.sigma[:, sl][:, 0]
        est = (Estimate("barometer_bias", (float(b[-1]),), (float(sb[-1]),), "m"),)
        metrics = {"barometer_bias_m": float(b[-1]), "barometer_bias_sigma_m": float(sb[-1]),
                   "barometer_bias_start_m": plan.facts["bias0"]}
        drift = ("a random constant" if self.drift_sigma is None else
                 f"Gauss–Markov, {self.drift_sigma:g} m over {self.drift_time:g} s")
        lines = [f"  barometer bias {plan.facts['bias0']:.2f} m at the start ({plan.facts['how']}), "
                 f"{b[-1]:.2f} ± {sb[-1]:.2f} m at the end ({drift})"]
        marks = []
        if m.gate is not None:
            mt, _, mk = gated(label, run.gates[label], 2.5 / self.rate, run.t_ref)
            metrics.update(mt)
            n_rej = mt[f"{label}_updates_rejected"]
            lines.append(f"  barometer: {n_rej} of {n_rej + mt[f'{label}_updates_applied']} updates refused by "
                         "the innovation gate")
            marks += [mk] if mk else []
        t0 = float(run.t[0])
        pans = [Panel("barometer bias [m]", (Line(run.t - t0, b, band=sb),))]
        ap = run.applied.get(label)
        if ap is not None and len(ap.t_applied):
            nu = np.asarray([v[0] for v in ap.innovation])
            sd = np.asarray([v[0] for v in ap.innovation_sigma])
            pans.append(Panel("height innovation [m]", (Line(np.asarray(ap.t_applied) - t0, nu, band=sd,
                                                             style="."),)))
        fig = PanelFigure("barometer", "barometer bias estimated (with its ±1σ) and the innovations of the "
                          "updates applied", tuple(pans))
        return Report(self.name, "barometer", estimates=est, metrics=metrics,
                      descriptions=((r"^barometer_bias_m$", "barometer bias (pressure height minus ellipsoid "
                                     "height) at the end, forward filter"),
                                    (r"^barometer_bias_sigma_m$", "filter 1σ of that bias"),
                                    (r"^barometer_bias_start_m$", "bias removed at the start"),
                                    *GATE_DESCRIPTIONS),
                      figures=(fig,), notes=(lines[0].strip() + ".",), lines=tuple(lines), marks=tuple(marks))
