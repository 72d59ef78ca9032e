"""RTK as the GNSS source of a recorded run (:class:`RtkSource`): the rover's raw
observations against a base station's, double-differenced code and phase with integer
ambiguities (:class:`sinslab.fusion.rtk_ins.DoubleDifferences`) in place of the
satellites' pseudoranges; and what a run of the RTK engine reports — with an INS or
without (:func:`rtk_metrics`, :func:`rtk_columns`, :func:`rtk_panels`).

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

from sinslab.core import earth as E
from sinslab.fusion.rtk import STATUS, RtkBase, RtkOptions

__all__ = ["RtkSource", "rtk_metrics", "rtk_columns", "rtk_panels"]


def rtk_metrics(a, counts, slips, nis=None):
    """The metrics of a run of the RTK engine from its per-epoch record ``a``
    (:meth:`sinslab.fusion.rtk.RtkLog.arrays`): epochs solved and fixed, the share fixed,
    the first fix [epochs from the first solved, s], the median ratio and number of
    integers of the fixed epochs, ambiguity restarts by cause and receiver (``slips``),
    signals left out, rows rejected and fixes refused (``counts``), and the mean NIS of
    the double differences used (``nis`` ``{"ph" | "code": [sum, rows]}``)."""
    st = np.asarray(a["status"])
    seen = st > STATUS["none"]
    fx = st == STATUS["fixed"]
    first = np.flatnonzero(fx)
    t = np.asarray(a["t"], float)
    s0 = np.flatnonzero(seen)
    ratio = np.asarray(a["ratio"], float)[fx]
    ratio = ratio[np.isfinite(ratio)]
    m = dict(rtk_epochs=int(st.size), rtk_epochs_solved=int(seen.sum()), rtk_epochs_fixed=int(fx.sum()),
             rtk_fixed_fraction=float(fx.sum() / max(int(seen.sum()), 1)),
             rtk_first_fix_epochs=int(first[0] - s0[0] + 1) if first.size else None,
             rtk_first_fix_s=float(t[first[0]] - t[s0[0]]) if first.size else None,
             rtk_ratio_median=float(np.median(ratio)) if ratio.size else None,
             rtk_integers_fixed_median=float(np.median(np.asarray(a["n_fixed"])[fx])) if fx.any() else 0.0)
    m.update({f"restarts_{k}": int(v) for k, v in slips.items()})
    m.update(epochs_without_base=counts["no_base_epoch"], signals_without_base_signal=counts["no_base_signal"],
             signals_half_cycle=counts["half_cycle"], signals_without_state=counts["no_slot"],
             code_rows_rejected=counts["code_rejected"], phase_rows_rejected=counts["phase_rejected"],
             fixes_refused_by_validation=counts["fix_rejected"])
    for k, name in (("ph", "phase"), ("code", "code")):
        if nis is not None and nis[k][1]:
            m[f"{name}_dd_nis_mean"], m[f"{name}_dd_rows"] = nis[k][0] / nis[k][1], int(nis[k][1])
    return m


def rtk_columns(a, t_ref=0.0):
    """Per epoch of the record ``a``: time [s from ``t_ref``], status (0 none, 1 float,
    2 fixed), ratio, integers fixed and formed, double differences of phase and code,
    ambiguities restarted, and the antenna (fixed where fixed, else float) as latitude,
    longitude [deg], height [m] with σ east, north, up [m]."""
    st = np.asarray(a["status"])
    fixed = st == STATUS["fixed"]
    pos = np.where(fixed[:, None], np.asarray(a["fixed_pos"]), np.asarray(a["float_pos"]))
    cov = np.where(fixed[:, None, None], np.asarray(a["fixed_cov"]), np.asarray(a["float_cov"]))
    ok = np.all(np.isfinite(pos), 1)
    lat, lon, h = (np.full(st.size, np.nan) for _ in range(3))
    sig = np.full((st.size, 3), np.nan)
    if ok.any():
        lat[ok], lon[ok], h[ok] = E.ecef_to_geodetic(pos[ok])
        C = E.enu_to_ecef_matrix(lat[ok], lon[ok])
        sig[ok] = np.sqrt(np.maximum(np.einsum("nji,njk,nki->ni", C, cov[ok], C), 0.0))
    return dict(t_s=np.asarray(a["t"], float) - t_ref, status=st, ratio=np.asarray(a["ratio"], float),
                n_fixed=np.asarray(a["n_fixed"]), n_amb=np.asarray(a["n_amb"]), n_phase=np.asarray(a["n_phase"]),
                n_code=np.asarray(a["n_code"]), n_slip=np.asarray(a["n_slip"]), lat_deg=np.degrees(lat),
                lon_deg=np.degrees(lon), h_m=h, sigma_e_m=sig[:, 0], sigma_n_m=sig[:, 1], sigma_u_m=sig[:, 2])


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
        eng = plan.facts["dd"].engine
        if eng is None:
            raise ValueError("no GNSS epoch reached the RTK measurement (outages or the record's end removed them)")
        a = eng.log.arrays()
        m = rtk_metrics(a, dict(eng.counts, no_slot=eng.slots.full), eng.slip_counts, getattr(eng, "nis", None))
        cols = rtk_columns(a, float(run.t[0]))
        line = (f"  RTK against {self.base.source}: {m['rtk_epochs_fixed']} of {m['rtk_epochs_solved']} epochs "
                f"fixed ({100 * m['rtk_fixed_fraction']:.1f} %), first fix at epoch {m['rtk_first_fix_epochs']}, "
                f"median {m['rtk_integers_fixed_median']:.0f} integers")
        note = ("RTK: double-differenced code and phase of every carrier against the base, single-difference "
                "ambiguity states, integers by LAMBDA (ratio test, bootstrapped success rate, partial fixing, "
                "validated, held); the filter starts from the rover's single-point solution and the fix tables "
                "compare with it. t_abs_s is GPS time.")
        return SourceReport(self.name, "RTK: double differences against a base station", metrics=m,
                            tables=(Table("rtk_epochs", cols, "per GNSS epoch: fix status, ratio, integers fixed "
                                          "and formed, double differences, restarts, antenna position ± σ"),),
                            figures=(PanelFigure("rtk", "RTK per epoch: fix status, ratio, integers fixed and "
                                                 "formed, ambiguities restarted", rtk_panels(cols)),),
                            notes=(note,), lines=(line,), coupling="RTK (double differences)",
                            reference="the single-point solution")
