"""The non-holonomic constraint of a wheeled land vehicle and the IMU's mount in it: no
lateral and no vertical velocity of the rear-axle centre in vehicle axes
(:class:`~sinslab.fusion.measurements.NonHolonomic`), with the mount's pitch and yaw and
the lever arm to that point estimated from the values given (``estimate``; roll is not
observable from the constraint).

The mount ``vehicle_mount`` is the IMU body (after the reader's ``--mount``) in the
vehicle frame (a case bolted 1-2° off the car's axes); the states are small angles ψ
added to its pitch (x) and yaw (z), the true mount ``(I + ψ×) C_used``, and the lever's
error ``δl = l_used − l_true`` in body axes. The vertical row's σ grows with the body's
pitch on its suspension under longitudinal acceleration (``pitch_gradient``, measured on a
car against its RTK fixes: docs/recorded-data.md), over ``correlation_time``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sinslab.core import units
from sinslab.fusion.aids.base import (GATE_DESCRIPTIONS, Aid, AidRun, Estimate, Plan, Report, Setup, State, every,
                                     gated, setting)

__all__ = ["Nhc", "OBSERVED_SIGMA_RATIO"]

#: an estimated state whose σ at the end is above this fraction of its prior σ is reported as
#: not observable on the record (the data added less than three times the prior's information)
OBSERVED_SIGMA_RATIO = 0.5


@dataclass(frozen=True)
class Nhc(Aid):
    """The non-holonomic constraint and the vehicle mount (see the module notes)."""

    name = "nhc"
    summary = "non-holonomic constraint of a wheeled vehicle, with the IMU's mount and the axle lever estimated"
    land_only = "the non-holonomic constraint"

    sigma: tuple = setting("velocity", "[0.1, 0.1] m/s", "σ of the lateral and vertical velocity of the "
                           "rear-axle centre (skid, suspension)", n=2, gt="0 m/s", le="10 m/s")
    vehicle_mount: tuple | None = setting("mount", "none", "the IMU body (after --mount) in the vehicle frame, "
                                          "e.g. euler:1.2,0,-1.5 (pitch, roll, yaw deg); none: aligned",
                                          none="none", flag="--vehicle-mount")
    lever: tuple = setting("length", "[0, 0, 0] m", "IMU -> rear-axle centre, vehicle right-forward-up",
                           n=3, flag="--nhc-lever")
    estimate: bool = setting("flag", True, "estimate the mount's pitch and yaw and the lever (5 states)")
    mount_sigma: float = setting("angle", "2 deg", "prior σ of the mount's pitch and yaw", gt="0 deg", le="30 deg")
    lever_sigma: float = setting("length", "0.5 m", "prior σ of each lever component", gt="0 m", le="10 m")
    pitch_gradient_deg_per_mps2: float = setting(
        "number", 0.3, "body pitch on the suspension per longitudinal acceleration [deg per m/s²] that "
        "widens the vertical row's σ (0: the fixed σ alone)", ge=0.0, le=10.0)
    correlation_time: float = setting("time", "1 s", "how long that pitch lasts (a manoeuvre)", gt="0 s")
    interval: float = setting("time", "0.1 s", "a constraint update every this", gt="0 s", le="60 s")
    gate: float | None = setting("probability", 1e-6, "false-rejection probability of the innovation gate "
                                 "of each update (none: no gate)", none="none", gt=0.0, lt=1.0)

    def _blocks(self):
        """The mount (pitch and yaw) and lever blocks."""
        from sinslab.nav import errstate as es
        return es.installation("vm", "xz"), es.lever_arm("nlev")

    def _mount(self):
        from sinslab.core import attitude as A
        return A.euler_to_dcm(np.asarray(self.vehicle_mount, float)) if self.vehicle_mount is not None else np.eye(3)

    def states(self):
        if not self.estimate:
            return ()
        vm, nlev = self._blocks()
        return State(vm, self.mount_sigma), State(nlev, self.lever_sigma)

    def plan(self, setup: Setup) -> Plan:
        from sinslab.fusion.measurements import NonHolonomic
        vm, nlev = self._blocks()
        Cvb = self._mount()
        m = NonHolonomic(self.sigma, mount=Cvb, lever_arm=Cvb.T @ np.asarray(self.lever, float),
                         every=every(self.interval, setup.T), gate=self.gate,
                         mount_block=vm.name if self.estimate else None,
                         lever_block=nlev.name if self.estimate else None,
                         pitch_gradient=self.pitch_gradient_deg_per_mps2 * units.deg,
                         correlation_time=self.correlation_time, dt=setup.T)
        return Plan((("nhc", m),))

    def _estimates(self, run: AidRun):
        """The mount (pitch, roll, yaw) [rad] and the lever [m] estimated, with σ."""
        vm, nlev = self._blocks()
        lay = run.layout
        # the true mount is (I + ψ×) C_used: small angles added to pitch (x) and yaw (z)
        psi, s_psi = run.x[-1, lay.slice(vm.name)], run.sigma[-1, lay.slice(vm.name)]
        m0 = np.zeros(3) if self.vehicle_mount is None else np.asarray(self.vehicle_mount, float)
        mount = [float(m0[0] + psi[0]), float(m0[1]), float(m0[2] + psi[1])]
        mount_sigma = [float(s_psi[0]), None, float(s_psi[1])]
        Cvb = self._mount()
        sl = lay.slice(nlev.name)
        lever = (np.asarray(self.lever, float) - Cvb @ run.x[-1, sl]).tolist()
        lever_sigma = np.sqrt(np.diag(Cvb @ np.diag(run.sigma[-1, sl] ** 2) @ Cvb.T)).tolist()
        return mount, mount_sigma, lever, lever_sigma

    def _words(self, ve, vs, vo, le, ls, lo):
        """The vehicle states on the terminal: value ± σ where the drive observed them, "not
        observable" (with the σ left of the prior's) where it did not."""
        d = np.degrees

        def angle(i, name):
            if vo[i]:
                return f"{name} {d(ve[i]):.2f} ± {d(vs[i]):.2f} deg"
            return f"{name} not observable (σ {d(vs[i]):.2f} of the prior {d(self.mount_sigma):.2f} deg)"
        lev = [f"{a:.2f} ± {b:.2f}" if ok else f"{'xyz'[i]} not observable (σ {b:.2f} of the prior "
               f"{self.lever_sigma:.2f})" for i, (a, b, ok) in enumerate(zip(le, ls, lo))]
        return (f"  vehicle mount (IMU in the vehicle) {angle(0, 'pitch')}, {angle(2, 'yaw')}; NHC lever [m] "
                + ", ".join(lev))

    def report(self, plan: Plan, run: AidRun) -> Report:
        (_, m), = plan.measurements
        metrics, lines, marks, est = {}, [], [], []
        if self.estimate:
            ve, vs, le, ls = self._estimates(run)
            # a state the drive told little about keeps most of its prior σ: its estimate is the
            # prior's guess, not a measurement (a flat drive does not see the lever's height)
            lo = [bool(x <= OBSERVED_SIGMA_RATIO * self.lever_sigma) for x in ls]
            vo = [bool(vs[0] <= OBSERVED_SIGMA_RATIO * self.mount_sigma), None,
                  bool(vs[2] <= OBSERVED_SIGMA_RATIO * self.mount_sigma)]
            metrics.update(vehicle_mount_estimate_deg=np.degrees(ve).tolist(),
                           vehicle_mount_sigma_deg=[None if x is None else float(np.degrees(x)) for x in vs],
                           nhc_lever_estimate_m=le, nhc_lever_sigma_m=ls, nhc_lever_observable=lo,
                           vehicle_mount_observable=vo)
            est = [Estimate("vehicle_mount", tuple(np.degrees(ve)), tuple(None if x is None else float(np.degrees(x))
                                                                        for x in vs), "deg", ("pitch", "roll", "yaw")),
                   Estimate("nhc_lever", tuple(le), tuple(ls), "m", ("right", "forward", "up"))]
            lines.append(self._words(ve, vs, vo, le, ls, lo))
        if m.gate is not None:
            mt, ln, mk = gated("nhc", run.gates["nhc"], 2.5 * run.T * m.every, run.t_ref)
            metrics.update(mt)
            lines += ln
            marks += [mk] if mk else []
        return Report(self.name, "non-holonomic constraint and vehicle mount", estimates=tuple(est),
                      metrics=metrics, lines=tuple(lines), marks=tuple(marks), descriptions=DESCRIPTIONS)


#: what the metrics of the report mean
DESCRIPTIONS = (
    (r"^vehicle_mount_estimate_deg$", "estimated IMU mount in the vehicle frame: pitch, roll (not estimated), yaw"),
    (r"^vehicle_mount_sigma_deg$", "1σ of the vehicle-mount estimate (pitch, -, yaw)"),
    (r"^nhc_lever_estimate_m$", "estimated IMU -> NHC point (rear-axle centre) lever, vehicle right, forward, up"),
    (r"^nhc_lever_sigma_m$", "1σ of the NHC lever estimate"),
    (r"^nhc_lever_observable$", "per axis, whether the drive observed the NHC lever (σ at most half its prior)"),
    (r"^vehicle_mount_observable$", "whether the drive observed the mount pitch, -, yaw (σ at most half its prior)"),
    *GATE_DESCRIPTIONS)
