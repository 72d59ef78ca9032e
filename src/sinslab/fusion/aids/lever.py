"""The GNSS antenna's lever arm estimated: three states for the error of the lever arm
the fixes use (``δl = l_used − l_true``, IMU -> antenna, body axes), offered to the GNSS
source (role ``"antenna_lever"``), whose position and velocity fixes then carry them
(:class:`~sinslab.fusion.measurements.LeverPositionFix`,
:class:`~sinslab.fusion.measurements.LeverVelocityFix`).

The start position is the antenna's minus ``C l_used``: its error is ``−C δl``, so the
prior of the position and lever-arm errors is correlated (:meth:`AntennaLever.correlate`;
else the fixes would pin a wrong start).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.fusion.aids.base import Aid, AidRun, Estimate, Plan, Report, Setup, State, setting

__all__ = ["AntennaLever"]


@dataclass(frozen=True)
class AntennaLever(Aid):
    """The antenna lever-arm states (see the module notes)."""

    name = "lever"
    summary = "estimate the GNSS antenna's lever arm from the fixes (3 states)"

    sigma: float = setting("length", "1 m", "prior σ of each lever-arm component", gt="0 m", le="100 m")

    def _block(self):
        from sinslab.nav import errstate as es
        return es.lever_arm()

    def states(self):
        return (State(self._block(), self.sigma, role="antenna_lever"),)

    def correlate(self, P0, setup: Setup):
        from sinslab.core import earth as E
        from sinslab.core import attitude as A
        lat, _, h = setup.start.position
        rm0, rn0 = (float(x) for x in E.radii(lat, h))
        D = np.array([[0.0, 1.0 / rm0, 0.0], [1.0 / (rn0 * math.cos(lat)), 0.0, 0.0], [0.0, 0.0, 1.0]])
        J = -D @ A.euler_to_dcm(setup.start.att)
        lay = setup.layout
        spp, slv = lay.slice("dp"), lay.slice(self._block().name)
        Sl = np.eye(3) * self.sigma ** 2
        P0[spp, spp] += J @ Sl @ J.T
        P0[spp, slv] = J @ Sl
        P0[slv, spp] = (J @ Sl).T

    def plan(self, setup: Setup) -> Plan:
        return Plan((), {"lever_arm": np.asarray(setup.lever_arm, dtype=float)})

    def report(self, plan: Plan, run: AidRun) -> Report:
        sl = run.layout.slice(self._block().name)
        est = (plan.facts["lever_arm"] - run.x[-1, sl]).tolist()     # δl = l_used − l_true
        sig = run.sigma[-1, sl].tolist()
        e = Estimate("lever_arm", tuple(est), tuple(sig), "m", ("right", "forward", "up"))
        return Report(self.name, "antenna lever arm", estimates=(e,),
                      metrics={"lever_arm_estimate_m": est, "lever_arm_sigma_m": sig},
                      notes=("Antenna lever arm estimated (vehicle right, forward, up): " + e.text() + " m.",),
                      lines=("  lever arm estimate [m] " + e.text(),),
                      descriptions=((r"^lever_arm_estimate_m$", "estimated antenna lever arm (vehicle right, forward, up)"),
                                    (r"^lever_arm_sigma_m$", "1σ of the lever-arm estimate")))
