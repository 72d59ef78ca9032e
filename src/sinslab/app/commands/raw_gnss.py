"""Raw GNSS in ``sinslab navigate`` (``--gnss-raw FILE [--gnss-nav FILE]``,
``--max-satellites K@START:DURATION``, the ``[gnss.raw]`` section): reading and checking
the observations, and what the run folder shows of the satellites beside the raw
source's report (:class:`sinslab.fusion.tightly_coupled.RawSource`) — their claims and
figures (sky plot, satellites used and rejected per epoch, receiver clock, residuals per
satellite)."""
from __future__ import annotations

import math
import re

import numpy as np

__all__ = ["load_raw", "parse_max_satellites", "raw_claims", "raw_figures", "raw_report", "RAW_DESCRIPTIONS",
           "raw_consistency_findings", "gnss_source", "load_base", "check_phase_keys", "rtk_options"]


def parse_max_satellites(items, t_first, t_last=math.inf, seen=None):
    """``["3@60:20", ...]`` -> ``((3, t_first + 60, 20), ...)``: at most K satellites from
    START [s after the first GNSS epoch] for DURATION [s]. A limit that changes nothing is
    refused, not taken as a no-op: a window that starts after the run's last epoch
    ``t_last`` [s], or a K no epoch of the window exceeds (``seen``: ``(epoch times,
    satellites with an ephemeris at each)``)."""
    out = []
    for text in items or ():
        m = re.fullmatch(r"\s*(\d+)\s*@\s*([0-9.eE+-]+)\s*:\s*([0-9.eE+-]+)\s*", str(text))
        if not m:
            raise ValueError(f"--max-satellites {text!r}: use K@START:DURATION (e.g. 3@60:20: at most "
                             "3 satellites from 60 s after the first GNSS epoch for 20 s)")
        k, s, d = int(m.group(1)), float(m.group(2)), float(m.group(3))
        if not (math.isfinite(s) and s >= 0 and math.isfinite(d) and d > 0):
            raise ValueError(f"--max-satellites {text!r}: START must be >= 0 s and DURATION > 0 s")
        if t_first + s > t_last:
            raise ValueError(f"--max-satellites {text!r}: START {s:g} s is after the run's last GNSS epoch "
                             f"({t_last - t_first:.1f} s after the first): the limit would apply to no epoch")
        if seen is not None:
            t_e, n_e = seen
            inside = (t_e >= t_first + s) & (t_e <= t_first + s + d)
            most = int(n_e[inside].max()) if inside.any() else 0
            if k >= most:
                raise ValueError(f"--max-satellites {text!r}: no epoch of the window has more than {most} "
                                 f"satellite(s) with an ephemeris, so at most {k} changes nothing")
        out.append((k, t_first + s, d))
    return tuple(out)


def load_raw(keys, imu, echo=print):
    """Read and check the raw GNSS of ``navigate`` (``keys`` the ``[gnss.raw]`` section);
    returns ``(RawGnss, fixes)`` with the single-point fixes that start the filter.

    One-line errors (the file and the cause): no raw measurements, no ephemeris for any
    satellite, observations outside the IMU record, satellites below the mask only;
    satellites without ephemeris are skipped and counted."""
    from sinslab.core.errors import InputError
    from sinslab.data.gnss import read_gnss_raw
    from sinslab.fusion.gnss import prepare
    from sinslab.fusion.tightly_coupled import RawGnss

    path, nav = keys.file, None if keys.nav in ("none", "") else keys.nav
    obs = read_gnss_raw(path, nav)
    sv = prepare(obs)
    t0, t1 = float(imu.t0), float(imu.t[-1])
    inside = (sv.t_epoch >= t0) & (sv.t_epoch <= t1)
    if not inside.any():
        raise InputError(f"{path}: the observations ({sv.t_epoch[0]:.3f}..{sv.t_epoch[-1]:.3f} s, GPS "
                         f"time) lie outside the IMU record ({t0:.3f}..{t1:.3f} s)")
    if not sv.usable.any():
        raise InputError(f"{path}: no satellite has an ephemeris"
                         + ("" if nav is not None else " (give a navigation file with --gnss-nav)"))
    seen = (sv.t_epoch, np.bincount(sv.epoch[sv.usable], minlength=sv.t_epoch.size))
    raw = RawGnss(sv, max_satellites=parse_max_satellites(keys.max_satellites, float(sv.t_epoch[0]),
                                                          min(float(sv.t_epoch[-1]), t1), seen),
                  mask=keys.elevation_mask, pseudorange_sigma=keys.pseudorange_sigma,
                  doppler_sigma=keys.doppler_sigma, gate=keys.gate, phase=keys.phase, phase_sigma=keys.phase_sigma)
    sp = raw.single_point()
    if not np.isfinite(sp.lat).any():
        from sinslab.fusion.gnss import single_point
        if np.isfinite(single_point(sv, mask=-math.pi / 2).lat).any():
            raise InputError(f"{path}: every satellite is below the {math.degrees(raw.mask):g} deg "
                             "elevation mask")
        raise InputError(f"{path}: no epoch has 4 satellites with ephemeris: the filter cannot start")
    no_eph = sorted(set(sv.sat[~sv.usable].tolist()))
    if no_eph:
        echo(f"  {len(no_eph)} satellite(s) without ephemeris skipped: {', '.join(no_eph)}")
    return raw, raw.fixes()


def check_phase_keys(keys):
    """The carrier-phase keys of ``[gnss.raw]`` that contradict each other: one line."""
    has_base, has_pos = bool(keys.base), keys.base_position is not None
    if has_base and not has_pos:
        raise ValueError("--gnss-base needs --base-position: the base antenna's ECEF X,Y,Z (e.g. "
                         "\"-3959400.631,3385704.533,3667523.111 m\")")
    if has_pos and not has_base:
        raise ValueError("--base-position needs --gnss-base (the base station's observations)")
    if has_base and keys.phase == "tdcp":
        raise ValueError("--phase tdcp is the carrier phase without a base; with --gnss-base RTK uses the phase")


def load_base(keys, rover, echo=print):
    """The base station of ``[gnss.raw]`` (``base``, ``base_position``; navigation from
    ``nav``) read, prepared and checked against the rover (:func:`sinslab.fusion.rtk.check_pair`:
    one-line errors; its warnings printed). Returns the :class:`~sinslab.fusion.rtk.RtkBase`."""
    from sinslab.data.gnss import read_gnss_raw
    from sinslab.fusion.gnss import prepare
    from sinslab.fusion.rtk import RtkBase, check_pair

    nav = None if keys.nav in ("none", "") else keys.nav
    base = RtkBase(prepare(read_gnss_raw(keys.base, nav)), np.asarray(keys.base_position, float), str(keys.base))
    for w in check_pair(rover, base, str(keys.file), rtk_options(keys)):
        echo(f"  warning: {w}")
    return base


def rtk_options(keys):
    """The RTK options of ``[gnss.raw]``."""
    from sinslab.fusion.rtk import RtkOptions
    return RtkOptions(phase_sigma=keys.phase_sigma, code_sigma=keys.pseudorange_sigma, mask=keys.elevation_mask,
                      ar_mask=keys.elevation_mask, ar=keys.ar, ratio=keys.ratio,
                      gate=keys.gate if keys.gate is not None else 1e6)


def gnss_source(keys, raw, echo=print):
    """The GNSS source of raw observations: RTK against a base
    (:class:`sinslab.fusion.rtk_source.RtkSource`) or the satellites' own rows, with
    time-differenced phase when ``phase = "tdcp"`` (:class:`sinslab.fusion.tightly_coupled.RawSource`)."""
    check_phase_keys(keys)
    if keys.base or keys.phase == "tdcp":
        from sinslab.fusion.rtk import check_phase
        check_phase(raw.sv, str(keys.file))
    if keys.base:
        from sinslab.fusion.rtk_source import RtkSource
        return RtkSource(raw, load_base(keys, raw.sv, echo), rtk_options(keys))
    from sinslab.fusion.tightly_coupled import RawSource
    return RawSource(raw)


_SYSTEM_NAMES = {"G": "GPS", "E": "Galileo", "C": "BeiDou", "R": "GLONASS", "J": "QZSS"}

#: the report rows of a tightly coupled run: its own rows (satellites, rows used and
#: refused, their NIS) described, and the rows the loosely coupled run names after its
#: fixes described against what they compare with here, the single-point solution
RAW_DESCRIPTIONS = [
    (r"^gnss_epochs_used$", "GNSS epochs with at least one pseudorange used"),
    (r"^gnss_epochs$", "GNSS epochs inside the run"),
    (r"^pseudoranges_used$", "pseudorange rows the filter used"),
    (r"^pseudoranges_rejected$", "pseudorange rows refused by the innovation gate"),
    (r"^doppler_used$", "range-rate (Doppler) rows the filter used"),
    (r"^doppler_rejected$", "range-rate (Doppler) rows refused by the innovation gate"),
    (r"^satellites_below_mask$", "pseudorange rows left out: satellite below the elevation mask"),
    (r"^satellites_over_limit$", "pseudorange rows left out by --max-satellites"),
    (r"^observations_without_ephemeris$", "observations of satellites without an ephemeris, skipped"),
    (r"^satellites_used_median$", "satellites whose pseudorange was used per epoch, median"),
    (r"^satellites_used_min$", "satellites whose pseudorange was used per epoch, fewest"),
    (r"^gnss_systems$", "constellations used (G GPS, E Galileo, C BeiDou, R GLONASS, J QZSS)"),
    (r"^elevation_mask_deg$", "satellites below it are not used"),
    (r"^hz_err_with_fixes_median_m$", "horizontal solution − single-point solution outside outages, median"),
    (r"^hz_err_with_fixes_max_m$", "horizontal solution − single-point solution outside outages, largest"),
    (r"^hz_err_with_fixes_p99_m$", "horizontal solution − single-point solution outside outages, 99th percentile"),
    (r"^outage_end_hz_err_median_m$", "horizontal error against the single-point solution at the end of the "
                                      "outages, median"),
    (r"^outage_end_hz_err_max_m$", "horizontal error against the single-point solution at the end of the "
                                   "outages, largest"),
    (r"^outage_end_hz_err_m$", "horizontal error against the single-point solution at the end of each outage"),
    (r"^fixes_after_grid$", "single-point fixes after the last whole filter step, not used"),
]
#: the tightly coupled run's rows first (the loosely coupled run leads with its fixes')
_RAW_FIRST = ("gnss_systems", "gnss_epochs_used", "gnss_epochs", "satellites_used_median", "satellites_used_min",
              "pseudoranges_used", "pseudoranges_rejected", "pseudorange_nis_mean", "pseudorange_nis_verdict",
              "doppler_used", "doppler_rejected", "doppler_nis_mean", "doppler_nis_verdict",
              "satellites_below_mask", "satellites_over_limit", "observations_without_ephemeris",
              "elevation_mask_deg")


def raw_report(metrics, n_outages, kinds=("pseudoranges", "range_rates")):
    """``(metrics, purpose)`` of a tightly coupled run's report: its own rows first, the
    outage rows last when there was no outage, and the line under the title that says what
    the run coupled (``kinds``: the names of the source's row records)."""
    first = {k: metrics[k] for k in _RAW_FIRST if k in metrics}
    rest = {k: v for k, v in metrics.items() if k not in first}
    last = {k: rest.pop(k) for k in list(rest) if k.startswith("outage_end_") or k == "n_outages"} \
        if n_outages == 0 else {}
    systems = ", ".join(_SYSTEM_NAMES.get(c, c) for c in str(metrics.get("gnss_systems", "")))
    names = [k.replace("_", " ") for k in kinds]
    what = " and ".join(names) if len(names) < 3 else ", ".join(names[:-1]) + " and " + names[-1]
    purpose = (f"INS + GNSS tightly coupled: {what} of raw observations"
               f"{f' ({systems})' if systems else ''} in the filter, and aids, on recorded data")
    return {**first, **rest, **last}, purpose


def raw_claims(rows):
    """Claims of a tightly coupled run (the project's checks, ``origin="check"``): per kind,
    the filter is not overconfident about the rows it used — mean ν²/(H P Hᵀ + R), one row
    at a time, by the NIS rule of the loosely coupled runs
    (:func:`sinslab.app.described.nis_claim`): a mean well below 1 is a pessimistic noise
    model (``<kind>_nis_verdict``), not a failure; well above 1 fails."""
    from sinslab.app.described import nis_claim
    claims = []
    extra = {}
    for label, log in rows.items():
        nis = np.concatenate([n[u] for n, u in zip(log.nis, log.used)]) if log.nis else np.zeros(0)
        key = "pseudorange" if label == "pseudoranges" else "doppler"
        what = "pseudoranges" if key == "pseudorange" else "range rates (Doppler)"
        claim, mean, verdict = nis_claim(f"{key}_nis_not_overconfident", f"the {what}", nis, 1,
                                         rows=f"{what} used (one row at a time)",
                                         empty=f"no {what} used", origin="check")
        claims.append(claim)
        extra[f"{key}_nis_mean"] = mean
        extra[f"{key}_nis_verdict"] = verdict
    return claims, extra




#: a satellite's innovations averaging beyond this many σ over a monitor window: beyond
#: what its noise model allows at all (within σ, a bias lasting minutes is the normal
#: ionospheric residual and multipath of single-frequency pseudoranges, not a finding)
RAW_BIAS_FLOOR = 3.0


def raw_consistency_findings(rows):
    """The innovation windows of a tightly coupled run (:func:`sinslab.app.plausibility.consistency_findings`
    over the epochs, each satellite a component): a stretch where the rows used are
    larger than the filter's σ say (the windowed NIS), or where one satellite's
    innovations average beyond :data:`RAW_BIAS_FLOOR` σ (multipath, a wrong inter-system
    bias). The σ of a row's
    innovation is √(H P Hᵀ + R) = |ν| / √NIS."""
    from sinslab.app.plausibility import consistency_findings
    out = []
    for label, what in (("pseudoranges", "pseudorange"), ("range_rates", "range rate")):
        log = rows.get(label)
        if log is None or not log.t or "sat" not in log.meta:
            continue
        sats = log.meta["sat"]
        names = sorted({str(x) for a in sats for x in a})
        col = {n: j for j, n in enumerate(names)}
        nu = np.full((len(log.t), len(names)), np.nan)
        sd = nu.copy()
        nis = np.zeros(len(log.t))
        for k, (v, n, u, sk) in enumerate(zip(log.innovation, log.nis, log.used, sats)):
            v, n, u = np.asarray(v, float), np.asarray(n, float), np.asarray(u, bool)
            ok = u & np.isfinite(v) & np.isfinite(n) & (n > 0)
            j = [col[str(x)] for x in np.asarray(sk)[ok]]
            nu[k, j], sd[k, j] = v[ok], np.abs(v[ok]) / np.sqrt(n[ok])
            nis[k] = float(np.sum(n[ok]))
        out += consistency_findings(np.asarray(log.t, float), nu, sd, nis, [f"{what} {x}" for x in names],
                                    item="epoch", items="epochs", source=what, bias_floor=RAW_BIAS_FLOOR,
                                    causes="multipath or a badly tracked signal of that satellite, an inter-system "
                                           "bias, a lever arm or time offset")
    return out


def raw_figures(res, rep):
    """The sky plot, the satellites per epoch and the receiver clock of a tightly coupled
    run, from its source's report (:class:`sinslab.fusion.aids.base.SourceReport`)."""
    from sinslab.app import plotting
    cols = next(t.columns for t in rep.tables if t.name == "gnss_satellites")
    names = sorted(set(cols["sat"].tolist()))
    colour = {}
    for s_ in names:
        colour.setdefault(s_[0], plotting.COLORS[len(colour) % len(plotting.COLORS)])
    mask = math.radians(rep.metrics["elevation_mask_deg"])
    systems = rep.metrics["gnss_systems"]
    out = [_skyplot(cols, names, colour, mask),
           _satellites_figure(cols, rep.rows, colour, float(res.t[0]))]
    if rep.clock is not None:
        out.append(_clock_figure(res, rep.clock, systems, colour))
    return out


def _skyplot(cols, names, colour, mask):
    """Sky plot on plain axes: radius 90° − elevation, azimuth clockwise from north."""
    from sinslab.app import plotting
    from sinslab.app.commands.runner import Figure
    fig, axes = plotting.figure(1, 1, width=6.5, row_height=6.5, sharex=False)
    ax = axes[0]
    ax.grid(False)
    circ = np.linspace(0, 2 * np.pi, 181)
    for r_ in (30, 60, 90):
        ax.plot(r_ * np.sin(circ), r_ * np.cos(circ), "-", color="0.75", lw=0.8)
        ax.text(2, r_ - 6, f"{90 - r_}°", fontsize=7, color="0.4")
    for a_ in range(0, 360, 45):
        ax.plot([0, 90 * np.sin(np.radians(a_))], [0, 90 * np.cos(np.radians(a_))], "-", color="0.85", lw=0.6)
    r_mask = 90 - math.degrees(mask)
    ax.plot(r_mask * np.sin(circ), r_mask * np.cos(circ), "--", color="0.5", lw=0.8,
            label=f"elevation mask {math.degrees(mask):g}°")
    sats = cols["sat"]
    for s_ in names:
        m = sats == s_
        rr_ = 90 - cols["elevation_deg"][m]
        az_ = np.radians(cols["azimuth_deg"][m])
        ax.plot(rr_ * np.sin(az_), rr_ * np.cos(az_), ".", ms=2, color=colour[s_[0]])
        ax.text(rr_[-1] * np.sin(az_[-1]) + 2, rr_[-1] * np.cos(az_[-1]) + 2, s_, fontsize=7)
    for sys_, c_ in colour.items():
        ax.plot([], [], ".", color=c_, label=_SYSTEM_NAMES.get(sys_, sys_))
    ax.set_xlim(-95, 95)
    ax.set_ylim(-95, 95)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_xlabel("west ← → east   (rings: elevation 0°, 30°, 60°)")
    ax.set_ylabel("south ← → north")
    ax.legend(fontsize=8, loc="lower right")
    return Figure("skyplot", fig, "Sky plot: satellite tracks over the run seen from the INS "
                  "antenna (centre: zenith; azimuth clockwise from north; label at the last epoch).")


def _satellites_figure(cols, rows, colour, t0):
    """Candidates, rows used and refused per epoch; pseudorange innovations per satellite."""
    from sinslab.app import plotting
    from sinslab.app.commands.runner import Figure
    pr, dp = rows["pseudoranges"], rows.get("range_rates")
    t_label = "time since the filter start [s]"
    sys_colour = {k: plotting.COLORS[j % len(plotting.COLORS)] for j, k in enumerate(colour)}
    fig, axes = plotting.figure(3, 1, width=9.0, sharex=False)
    tt = np.array(pr.t) - t0
    axes[0].step(tt, [int(np.isfinite(i).sum()) for i in pr.innovation], where="post", lw=2.5,
                 label="candidates (with ephemeris, above the mask, within the limit)", color="0.75")
    axes[0].step(tt, pr.used_per_epoch(), where="post", lw=1, label="pseudoranges used", color=plotting.COLORS[0])
    axes[0].step(tt, [int(r.sum()) for r in pr.rejected], where="post", lw=1,
                 label="pseudoranges rejected by the gate", color=plotting.COLORS[1])
    if dp is not None:
        axes[0].step(np.array(dp.t) - t0, [int(r.sum()) for r in dp.rejected], where="post",
                     lw=1, ls="--", label="range rates rejected by the gate", color=plotting.COLORS[4])
    axes[0].set_ylim(bottom=-0.5)
    axes[0].set_ylabel("satellites per epoch")
    axes[0].set_xlabel(t_label)
    axes[0].legend(fontsize=7, loc="center right")
    sats, used = cols["sat"], cols["pr_used"] == 1
    used_sats = sorted({s for s in sats[used].tolist()})
    for s in used_sats:
        m = (sats == s) & used
        axes[1].plot(cols["t_s"][m], cols["pr_innovation_m"][m], ".", ms=1.5, color=sys_colour[s[0]])
    rj = cols["pr_rejected"] == 1
    if rj.any():
        axes[1].plot(cols["t_s"][rj], cols["pr_innovation_m"][rj], "x", ms=4, color="k",
                     label="rejected by the gate")
    for sys_, c_ in sys_colour.items():
        axes[1].plot([], [], ".", color=c_, label=_SYSTEM_NAMES.get(sys_, sys_))
    axes[1].set_ylabel("pseudorange\ninnovation z − Hx⁻ [m]")
    axes[1].set_xlabel(t_label)
    axes[1].legend(fontsize=7, ncol=4, markerscale=3, loc="lower left")
    _innovation_boxes(axes[2], cols, used_sats, sys_colour)
    return Figure("satellites", fig, "Satellites used and rejected per epoch, pseudorange "
                  "innovations per satellite. Candidates, rows used and rows refused by the "
                  "innovation gate at each epoch; the innovation z − Hx⁻ (before the update, "
                  "coloured by system) of every pseudorange used, and its spread per satellite.")


def _innovation_boxes(ax, cols, used_sats, sys_colour):
    """Per satellite: the spread of the innovations of the rows used."""
    sats, used = cols["sat"], cols["pr_used"] == 1
    data_, labels_ = [], []
    for s in used_sats:
        m = (sats == s) & used
        data_.append(cols["pr_innovation_m"][m])
        labels_.append(f"{s}\n{int(m.sum())}")
    if data_:
        bp = ax.boxplot(data_, whis=(5, 95), showfliers=False, patch_artist=True)
        for patch, s in zip(bp["boxes"], used_sats):
            patch.set_facecolor(sys_colour[s[0]])
            patch.set_alpha(0.6)
        ax.set_xticks(range(1, len(labels_) + 1), labels_, fontsize=6)
    ax.axhline(0, color="0.5", lw=0.6)
    ax.set_ylabel("pseudorange\ninnovation [m]")
    ax.set_xlabel("satellite (rows used); box: quartiles, whiskers: 5th and 95th percentiles")
    skipped = sorted(set(sats.tolist()) - set(used_sats))
    if skipped:
        ax.set_title(f"never used (no ephemeris, below the mask or over the limit): {', '.join(skipped)}",
                     fontsize=7)


def _clock_figure(res, clock_sigma, systems, colour):
    """The receiver clock's bias, drift and inter-system biases with ± 1σ."""
    from sinslab.app import plotting
    from sinslab.app.commands.runner import Figure
    clock, sg = clock_sigma
    sys_colour = {k: plotting.COLORS[j % len(plotting.COLORS)] for j, k in enumerate(colour)}
    n_isb = clock.shape[1] - 2
    fig, axes = plotting.figure(3 if n_isb else 2, 1, width=9.0)
    ts_ = res.t - float(res.t[0])
    b_ref = round(float(clock[0, 0]))
    axes[0].plot(ts_, clock[:, 0] - b_ref, lw=1)
    ref_txt = f"{'+' if b_ref < 0 else '−'} {abs(b_ref):,d} m".replace(",", " ")
    axes[0].set_ylabel(f"clock bias [m]\n({ref_txt})")
    axes[1].plot(ts_, clock[:, 1], lw=1, label="estimate")
    axes[1].fill_between(ts_, clock[:, 1] - sg[:, 1], clock[:, 1] + sg[:, 1], color="0.85", lw=0, label="± 1σ")
    axes[1].set_ylabel("clock drift [m/s]")
    axes[1].legend(fontsize=7)
    for j, s in enumerate(systems[1:]):
        c_ = sys_colour.get(s, None)
        axes[2].plot(ts_, clock[:, 2 + j], lw=1, color=c_,
                     label=f"{_SYSTEM_NAMES.get(s, s)} − {_SYSTEM_NAMES.get(systems[0], systems[0])}")
        axes[2].fill_between(ts_, clock[:, 2 + j] - sg[:, 2 + j], clock[:, 2 + j] + sg[:, 2 + j],
                             color=c_, alpha=0.15, lw=0)
    if n_isb:
        # the first epochs' σ (tens of metres) would flatten the estimates
        settled = ts_ >= min(5.0, float(ts_[-1]) / 2)
        lo_, hi_ = clock[settled, 2:].min(), clock[settled, 2:].max()
        pad = max(1.0, 3 * float(np.median(sg[settled, 2:])), 0.2 * (hi_ - lo_))
        axes[2].set_ylim(lo_ - pad, hi_ + pad)
        axes[2].set_ylabel("inter-system bias [m]\n(± 1σ shaded)")
        axes[2].legend(fontsize=7)
    axes[-1].set_xlabel("time since the filter start [s]")
    return Figure("clock", fig, "Receiver clock bias and drift estimated by the filter. Bias (1 m = 3.34 ns), "
                  "drift (1 m/s = 3.34 ns/s) and inter-system biases against the first "
                  "system, with ± 1σ.")
