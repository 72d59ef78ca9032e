"""RTK as the GNSS source of a recorded run (:class:`RtkSource`): the rover's raw
observations against a base station's, double-differenced code and phase with integer
ambiguities (:class:`sinslab.fusion.rtk_ins.DoubleDifferences`) in place of the
satellites' pseudoranges; and what a run of the RTK engine reports — with an INS or
without (:func:`rtk_report`, :func:`rtk_panels`).

The source plugs into :func:`sinslab.fusion.recorded.navigate_recorded` like the fix and
raw sources (:class:`sinslab.fusion.aids.base.GnssSource`): the rover's single-point
solutions start the filter and are what the solution is compared with; its states are
the ambiguity states (:func:`sinslab.nav.errstate.carrier_ambiguities`, one per signal
tracked and 8 spare, prior σ 0: each starts when its signal does); its report holds per
epoch the fix status, ratio, integers fixed and the float and fixed antenna positions.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sinslab.fusion.rtk import RtkBase, RtkOptions

__all__ = ["RtkSource", "rtk_report", "rtk_panels"]


def rtk_report(sol, t_ref, base_position):
    """What a run of the RTK engine reports (with an INS or without), from its
    :class:`~sinslab.fusion.gnss_alone.RtkSolution`: ``(metrics, per-epoch columns, terminal
    line)`` — the metrics of :meth:`~sinslab.fusion.gnss_alone.RtkSolution.summary`, the
    columns of :meth:`~sinslab.fusion.gnss_alone.RtkSolution.table` with ``t_s`` from
    ``t_ref`` and ``t_abs_s`` the receiver's time [s], and the baseline: the antenna minus
    ``base_position`` (ECEF [m]) east, north, up at the base [m]."""
    m = sol.summary()
    cols = sol.table()
    cols = dict(t_s=cols["t_s"] - t_ref, t_abs_s=cols["t_s"], **{k: v for k, v in cols.items() if k != "t_s"})
    enu = sol.enu_errors(base_position)
    cols.update(baseline_e_m=enu[:, 0], baseline_n_m=enu[:, 1], baseline_u_m=enu[:, 2])
    first = "no fix" if m["rtk_first_fix_epochs"] is None else f"first fix at epoch {m['rtk_first_fix_epochs']}"
    ratio = "" if m["rtk_ratio_min"] is None else f", least ratio {m['rtk_ratio_min']:.1f}"
    line = (f"{m['rtk_epochs_fixed']} of {m['rtk_epochs_solved']} epochs fixed "
            f"({100 * m['rtk_fixed_fraction']:.1f} %), {first}, median {m['rtk_integers_fixed_median']:.0f} "
            f"integers fixed{ratio}; {sum(v for k, v in m.items() if k.startswith('restarts_'))} ambiguity restarts")
    return m, cols, line


def rtk_panels(cols):
    """The panels of the RTK figure: fix status, ratio (log), integers fixed and formed,
    ambiguities restarted, against time [s]."""
    from sinslab.fusion.aids.base import Line, Panel
    t = cols["t_s"]
    ratio = np.where(cols["status"] > 0, cols["ratio"], np.nan)
    return (Panel("status (0 none, 1 float, 2 fixed)", (Line(t, cols["status"], "status", style="."),)),
            Panel("ratio", (Line(t, ratio, "second/best squared norm", style="."),), log=True),
            Panel("integers", (Line(t, cols["n_fixed"], "fixed"), Line(t, cols["n_amb"], "formed"))),
            Panel("restarts", (Line(t, cols["n_slip"], "ambiguities restarted", style="."),)))


@dataclass(frozen=True, eq=False)
class RtkSource:
    """RTK against a base as the GNSS source of a recorded run (see the module notes).

    Attributes
    ----------
    raw : sinslab.fusion.tightly_coupled.RawGnss
        The rover's observations (with signals) and its single-point solution.
    base : RtkBase
    options : RtkOptions
    """

    raw: object
    base: RtkBase
    options: RtkOptions = RtkOptions()
    name = "rtk"

    def start_fixes(self):
        return self.raw.fixes()

    def prepare(self, fixes):
        return fixes, self

    def states(self):
        from sinslab.fusion.aids.base import State
        from sinslab.fusion.carrier import max_signals, slot_count
        from sinslab.nav import errstate as es
        return (State(es.carrier_ambiguities(slot_count(max_signals(self.raw.sv))), 0.0),)

    def plan(self, setup, fixes, lever_block):
        from sinslab.fusion.aids.base import Plan
        from sinslab.fusion.rtk_ins import DoubleDifferences
        if lever_block is not None:
            raise ValueError("the antenna lever-arm states (--aid lever) are estimated from position and "
                             "velocity fixes; with RTK the lever arm given (--lever-arm) is used")
        dd = DoubleDifferences(self.raw.sv, self.base, self.options, lever_arm=setup.lever_arm,
                               outages=setup.outages)
        return Plan((("double_differences", dd),), {"dd": dd})

    def report(self, plan, run):
        from sinslab.fusion.aids.base import PanelFigure, SourceReport, Table
        from sinslab.fusion.gnss_alone import solution_of
        eng = plan.facts["dd"].engine
        if eng is None or not eng.log.t:
            raise ValueError("no GNSS epoch reached the RTK measurement (outages or the record's end removed them)")
        m, cols, line = rtk_report(solution_of(eng), float(run.t[0]), self.base.position)
        note = ("RTK: double-differenced code and phase of every carrier against the base, single-difference "
                "ambiguity states, integers by LAMBDA (ratio test, bootstrapped success rate, partial fixing, "
                f"validated, {self.options.ar}); the filter starts from the rover's single-point solution and the fix "
                "tables compare with it. rtk_epochs: t_abs_s is the receiver's GPS time.")
        return SourceReport(self.name, "RTK: double differences against a base station", metrics=m,
                            tables=(Table("rtk_epochs", cols, "per GNSS epoch: fix status, ratio, integers fixed "
                                          "and formed, double differences, restarts, antenna position ± σ, "
                                          "baseline from the base east/north/up"),),
                            figures=(PanelFigure("rtk", "RTK per epoch: fix status, ratio, integers fixed and "
                                                 "formed, ambiguities restarted", rtk_panels(cols)),),
                            notes=(note,), lines=(f"  RTK against {self.base.source}: {line}",),
                            coupling="RTK (double differences)", reference="the single-point solution")
