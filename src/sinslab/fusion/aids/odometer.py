"""Wheel odometer: the forward speed of a wheel point from a series with its own time
stamps (a file, or a column of the IMU table), against the INS velocity of that point in
vehicle axes (:class:`~sinslab.fusion.measurements.Odometer`), with the odometer's scale
factor ``k`` estimated (``v_fwd = (1 − k)·reading``, one state,
:func:`sinslab.nav.errstate.odometer_scale`).

The series is read through the data front door (:func:`sinslab.data.odometer.read_odometer`)
and put on the IMU's clock like the IMU stamps when the run corrected them; a speed no
wheeled vehicle reaches is refused as a unit or column slip.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from sinslab.fusion.aids.base import (GATE_DESCRIPTIONS, Aid, AidRun, Estimate, Plan, Report, Setup, State, gated,
                                     setting)

__all__ = ["WheelOdometer", "MAX_WHEEL_SPEED"]

#: fastest wheel speed accepted [m/s] (above any car's or train's; 720 km/h)
MAX_WHEEL_SPEED = 200.0


@dataclass(frozen=True)
class WheelOdometer(Aid):
    """The wheel odometer and its scale factor (see the module notes)."""

    name = "odometer"
    summary = "wheel speeds (a file or a column of the IMU table) with the odometer scale factor estimated"
    land_only = "the odometer"

    file: str = setting("file", "", "wheel speeds: FILE (t, speed columns) or a COLUMN of the IMU table",
                        flag="--odometer")
    units: str | None = setting("text", "none", "speed unit when the header has none, e.g. km/h", none="none",
                                flag="--odometer-units")
    lever: tuple = setting("length", "[0, 0, 0] m", "IMU -> wheel point, vehicle right-forward-up", n=3,
                           flag="--odometer-lever")
    sigma: float = setting("velocity", "0.1 m/s", "wheel speed noise per update (noise and quantisation)",
                           gt="0 m/s", le="100 m/s", flag="--odometer-sigma")
    scale_sigma: float = setting("dimensionless", "0.02", "prior σ of the odometer scale factor", gt="0", le="1")
    rate: float = setting("frequency", "10 Hz", "odometer updates per second", gt="0 Hz", le="1000 Hz")
    gate: float | None = setting("probability", 1e-6, "false-rejection probability of the innovation gate "
                                 "of each update (none: no gate)", none="none", gt=0.0, lt=1.0)
    #: the speeds read (:class:`sinslab.data.odometer.OdometerSeries`, set by :meth:`load`)
    series: object = None

    def load(self, inputs):
        if not self.file:
            raise ValueError("odometer.file: give the wheel speeds (--odometer FILE|COLUMN)")
        odo = inputs.read("read_odometer", self.file, inputs.imu_path, speed_unit=self.units)
        if odo.speed.size and not np.max(odo.speed) <= MAX_WHEEL_SPEED:
            i = int(np.argmax(odo.speed))
            raise ValueError(f"--odometer {odo.source}: speed {odo.speed[i]:.4g} m/s at t = {odo.t[i]:.6g} s "
                             f"is beyond any wheeled vehicle (<= {MAX_WHEEL_SPEED:g} m/s); a wrong unit "
                             f"(--odometer-units) or column?")
        return dataclasses.replace(self, series=dataclasses.replace(odo, t=inputs.clock(odo.t)))

    def _block(self):
        from sinslab.nav import errstate as es
        return es.odometer_scale()

    def states(self):
        return (State(self._block(), self.scale_sigma),)

    def plan(self, setup: Setup) -> Plan:
        from sinslab.fusion.measurements import Odometer
        odo, T = self.series, setup.T
        t_lo, t_hi = setup.imu.t0, float(setup.imu.t[-1])
        if odo.t[-1] < t_lo or odo.t[0] > t_hi:
            raise ValueError(f"odometer times ({odo.source}: {odo.t[0]:.3f}..{odo.t[-1]:.3f} s) do not "
                             f"overlap the IMU record ({t_lo:.3f}..{t_hi:.3f} s): different time bases?")
        n = max(1, int(round(1.0 / (self.rate * T))))
        m = Odometer(odo.t, odo.speed, self.sigma, lever_arm=np.asarray(self.lever), every=n, gate=self.gate,
                     scale_block=self._block().name)
        return Plan((("odometer", m),))

    def report(self, plan: Plan, run: AidRun) -> Report:
        (_, m), = plan.measurements
        i = run.layout.slice(self._block().name).start
        k, s = float(run.x[-1, i]), float(run.sigma[-1, i])
        est = [Estimate("odometer_scale", (k * 1e6,), (s * 1e6,), "ppm")]
        metrics = {"odometer_scale_forward_ppm": k * 1e6, "odometer_scale_forward_sigma_ppm": s * 1e6}
        if run.smoothed is not None:
            metrics.update(odometer_scale_final_ppm=float(run.smoothed.x[-1, i] * 1e6),
                           odometer_scale_sigma_ppm=float(run.smoothed.sigma[-1, i] * 1e6))
        lines, marks = [f"  odometer scale factor {k * 1e6:.0f} ± {s * 1e6:.0f} ppm (forward filter)"], []
        if m.gate is not None:
            mt, ln, mk = gated("odometer", run.gates["odometer"], 2.5 * run.T * m.every, run.t_ref)
            metrics.update(mt)
            lines += ln
            marks += [mk] if mk else []
        return Report(self.name, "wheel odometer", estimates=tuple(est), metrics=metrics,
                      descriptions=DESCRIPTIONS,
                      lines=tuple(lines), marks=tuple(marks))


#: what the metrics of the report mean
DESCRIPTIONS = (
    (r"^odometer_scale_forward_ppm$", "odometer scale factor k at the end, forward filter (v = (1 − k)·reading)"),
    (r"^odometer_scale_forward_sigma_ppm$", "filter 1σ of the odometer scale factor at the end"),
    (r"^odometer_scale_final_ppm$", "smoothed odometer scale-factor state at the end (k of v = (1 − k)·reading)"),
    (r"^odometer_scale_sigma_ppm$", "smoothed 1σ of the odometer scale factor at the end"),
    *GATE_DESCRIPTIONS)
