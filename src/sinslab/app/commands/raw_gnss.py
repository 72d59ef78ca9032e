"""Raw GNSS in ``sinslab navigate`` (``--gnss-raw FILE [--gnss-nav FILE]``,
``--max-satellites K@START:DURATION``): reading and checking the observations, the
tightly coupled settings, and what the run folder shows of the satellites — their
claims, tables and figures (sky plot, satellites used and rejected per epoch, receiver
clock, residuals per satellite)."""
from __future__ import annotations

import math
import re

import numpy as np

__all__ = ["load_raw", "parse_max_satellites", "raw_claims", "raw_outputs"]


def parse_max_satellites(items, t_first):
    """``["3@60:20", ...]`` -> ``((3, t_first + 60, 20), ...)``: at most K satellites from
    START [s after the first GNSS epoch] for DURATION [s]."""
    out = []
    for text in items or ():
        m = re.fullmatch(r"\s*(\d+)\s*@\s*([0-9.eE+-]+)\s*:\s*([0-9.eE+-]+)\s*", str(text))
        if not m:
            raise ValueError(f"--max-satellites {text!r}: use K@START:DURATION (e.g. 3@60:20: at most "
                             "3 satellites from 60 s after the first GNSS epoch for 20 s)")
        k, s, d = int(m.group(1)), float(m.group(2)), float(m.group(3))
        if not (math.isfinite(s) and s >= 0 and math.isfinite(d) and d > 0):
            raise ValueError(f"--max-satellites {text!r}: START must be >= 0 s and DURATION > 0 s")
        out.append((k, t_first + s, d))
    return tuple(out)


def load_raw(path, nav, max_satellites, imu, echo=print):
    """Read and check the raw GNSS of ``navigate``; returns ``(RawGnss, fixes)`` with the
    single-point fixes that start the filter.

    One-line errors (the file and the cause): no raw measurements, no ephemeris for any
    satellite, observations outside the IMU record, satellites below the mask only;
    satellites without ephemeris are skipped and counted."""
    from sinslab.core.errors import InputError
    from sinslab.data.gnss import read_gnss_raw
    from sinslab.fusion.gnss import prepare
    from sinslab.fusion.tightly_coupled import RawGnss

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
    raw = RawGnss(sv, max_satellites=parse_max_satellites(max_satellites, float(sv.t_epoch[0])))
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


def raw_claims(raw):
    """Claims of a tightly coupled run (the project's checks, ``origin="check"``): per kind,
    the filter is not overconfident about the rows it used — mean ν²/(H P Hᵀ + R), one row
    at a time, by the NIS rule of the loosely coupled runs
    (:func:`sinslab.app.described.nis_claim`): a mean well below 1 is a pessimistic noise
    model (``<kind>_nis_verdict``), not a failure; well above 1 fails."""
    from sinslab.app.described import nis_claim
    claims = []
    extra = {}
    for m in raw.measurements:
        nis = np.concatenate([n[u] for n, u in zip(m.log.nis, m.log.used)]) if m.log.nis else np.zeros(0)
        key = "pseudorange" if m.kind == "pseudorange" else "doppler"
        what = "pseudoranges" if key == "pseudorange" else "range rates (Doppler)"
        claim, mean, verdict = nis_claim(f"{key}_nis_not_overconfident", f"the {what}", nis, 1,
                                         rows=f"{what} used (one row at a time)",
                                         empty=f"no {what} used", origin="check")
        claims.append(claim)
        extra[f"{key}_nis_mean"] = mean
        extra[f"{key}_nis_verdict"] = verdict
    return claims, extra


def raw_outputs(res, raw, metrics, tables, figures, notes, echo=print):
    """Satellite metrics, the ``gnss_satellites`` and ``gnss_clock`` tables and the
    figures of a tightly coupled run."""
    from sinslab.app import plotting
    from sinslab.app.commands.runner import Figure, Series

    pr = raw.measurements[0]
    dp = raw.measurements[1] if len(raw.measurements) > 1 else None
    c = pr.log.counts()
    n_used = np.array([int(u.sum()) for u in pr.log.used])
    metrics.update(
        gnss_epochs_used=int(np.sum(n_used > 0)), gnss_epochs=len(pr.log.t),
        pseudoranges_used=c["used"], pseudoranges_rejected=c["rejected"],
        doppler_used=dp.log.counts()["used"] if dp else 0,
        doppler_rejected=dp.log.counts()["rejected"] if dp else 0,
        satellites_below_mask=c["below_mask"], satellites_over_limit=c["over_limit"],
        observations_without_ephemeris=c["no_ephemeris"],
        satellites_used_median=float(np.median(n_used)) if n_used.size else 0.0,
        satellites_used_min=int(n_used.min()) if n_used.size else 0,
        gnss_systems="".join(raw.systems), elevation_mask_deg=math.degrees(raw.mask))
    echo(f"  raw GNSS: {metrics['gnss_epochs_used']} of {metrics['gnss_epochs']} epochs used, "
         f"{c['used']} pseudoranges ({c['rejected']} rejected by the gate), median "
         f"{metrics['satellites_used_median']:.0f} satellites ({metrics['gnss_systems']})")
    # per satellite and epoch
    rows = {"t_s": [], "sat": [], "elevation_deg": [], "azimuth_deg": [], "cn0_dbhz": [],
            "pr_innovation_m": [], "pr_sigma_m": [], "pr_used": [], "pr_rejected": [],
            "doppler_innovation_mps": [], "doppler_used": [], "doppler_rejected": []}
    t0 = float(res.t[0])
    for k, t in enumerate(pr.log.t):
        n = pr.log.sat[k].size
        rows["t_s"].append(np.full(n, t - t0))
        rows["sat"].append(pr.log.sat[k])
        rows["elevation_deg"].append(np.degrees(pr.log.el[k]))
        rows["azimuth_deg"].append(np.degrees(pr.log.az[k]))
        rows["cn0_dbhz"].append(pr.log.cn0[k])
        rows["pr_innovation_m"].append(pr.log.innovation[k])
        rows["pr_sigma_m"].append(pr.log.sigma[k])
        rows["pr_used"].append(pr.log.used[k].astype(int))
        rows["pr_rejected"].append(pr.log.rejected[k].astype(int))
        if dp is not None and k < len(dp.log.t):
            rows["doppler_innovation_mps"].append(dp.log.innovation[k])
            rows["doppler_used"].append(dp.log.used[k].astype(int))
            rows["doppler_rejected"].append(dp.log.rejected[k].astype(int))
        else:
            rows["doppler_innovation_mps"].append(np.full(n, np.nan))
            rows["doppler_used"].append(np.zeros(n, int))
            rows["doppler_rejected"].append(np.zeros(n, int))
    cols = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in rows.items()}
    tables.append(Series("gnss_satellites", cols, "per epoch and satellite: elevation, azimuth, C/N0, "
                         "pseudorange and Doppler innovations (before the update), σ, used/rejected"))
    lab = list(res.labels)
    sl = slice(lab.index("clk_bias"), lab.index("clk_bias") + 1 + len(raw.systems))
    clock = res.init.get("gnss_clock")
    if clock is not None:
        ck = {"t_s": res.t - t0, "bias_m": clock[:, 0], "drift_mps": clock[:, 1],
              "sigma_bias_m": res.sigma[:, sl][:, 0], "sigma_drift_mps": res.sigma[:, sl][:, 1]}
        for j, s in enumerate(raw.systems[1:]):
            ck[f"isb_{s}_m"] = clock[:, 2 + j]
        tables.append(Series("gnss_clock", ck, "receiver clock estimate (bias, drift, inter-system "
                             "biases against the first system) and σ at every filter epoch"))
    # figures
    sats = cols["sat"]
    # sky plot on plain axes: radius 90° − elevation, azimuth clockwise from north
    fig, axes = plotting.figure(1, 1, width=6.5, row_height=6.5, sharex=False)
    ax = axes[0]
    ax.grid(False)
    circ = np.linspace(0, 2 * np.pi, 181)
    for r_ in (30, 60, 90):
        ax.plot(r_ * np.sin(circ), r_ * np.cos(circ), "-", color="0.75", lw=0.8)
        ax.text(2, r_ - 6, f"{90 - r_}°", fontsize=7, color="0.4")
    for a_ in range(0, 360, 45):
        ax.plot([0, 90 * np.sin(np.radians(a_))], [0, 90 * np.cos(np.radians(a_))], "-", color="0.85", lw=0.6)
    names = sorted(set(sats.tolist()))
    colour = {}
    for s_ in names:
        colour.setdefault(s_[0], plotting.COLORS[len(colour) % len(plotting.COLORS)])
    for s_ in names:
        m = sats == s_
        rr_ = 90 - cols["elevation_deg"][m]
        az_ = np.radians(cols["azimuth_deg"][m])
        ax.plot(rr_ * np.sin(az_), rr_ * np.cos(az_), ".", ms=2, color=colour[s_[0]])
        ax.text(rr_[-1] * np.sin(az_[-1]) + 2, rr_[-1] * np.cos(az_[-1]) + 2, s_, fontsize=7)
    for sys_, c_ in colour.items():
        ax.plot([], [], ".", color=c_, label={"G": "GPS", "E": "Galileo", "C": "BeiDou", "R": "GLONASS",
                                              "J": "QZSS"}.get(sys_, sys_))
    ax.set_xlim(-95, 95)
    ax.set_ylim(-95, 95)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_xlabel("west ← → east   (rings: elevation 0°, 30°, 60°)")
    ax.set_ylabel("south ← → north")
    ax.legend(fontsize=8, loc="lower right")
    figures.append(Figure("skyplot", fig, "Sky plot: satellite tracks over the run seen from the INS "
                          "antenna (centre: zenith; azimuth clockwise from north; label at the last epoch)."))
    fig, axes = plotting.figure(2, 1, width=9.0)
    tt = np.array(pr.log.t) - t0
    axes[0].step(tt, n_used, where="post", label="used", color=plotting.COLORS[0])
    axes[0].step(tt, [int(r.sum()) for r in pr.log.rejected], where="post", label="rejected by the gate",
                 color=plotting.COLORS[1])
    axes[0].step(tt, [int(np.isfinite(i).sum()) for i in pr.log.innovation], where="post", lw=0.8,
                 label="candidates (ephemeris, mask, limit)", color="0.5")
    axes[0].set_ylabel("satellites")
    axes[0].legend(fontsize=8)
    for s in sorted(set(sats.tolist())):
        m = (sats == s) & (cols["pr_used"] == 1)
        axes[1].plot(cols["t_s"][m], cols["pr_innovation_m"][m], ".", ms=1.5, label=s)
    axes[1].set_ylabel("pseudorange innovation [m]")
    axes[1].set_xlabel("time [s]")
    axes[1].legend(fontsize=6, ncol=6, markerscale=4)
    figures.append(Figure("satellites", fig, "Satellites used and rejected per epoch; pseudorange "
                          "innovation of each satellite used (predicted minus measured, before the update)."))
    if clock is not None:
        fig, axes = plotting.figure(2, 1, width=9.0)
        ts_ = res.t - t0
        axes[0].plot(ts_, clock[:, 0] - clock[0, 0], lw=1)
        axes[0].set_ylabel(f"clock bias − {clock[0, 0]:.0f} m [m]")
        axes[1].plot(ts_, clock[:, 1], lw=1)
        axes[1].set_ylabel("clock drift [m/s]")
        axes[1].set_xlabel("time [s]")
        figures.append(Figure("clock", fig, "Receiver clock bias and drift estimated by the filter."))
    notes.append(f"Tightly coupled: pseudoranges{' and Doppler' if dp else ''} of {metrics['gnss_systems']} "
                 f"satellites above {metrics['elevation_mask_deg']:g} deg; the filter starts from the "
                 "single-point solution (GNSS-only least squares) and the fix tables compare with it. "
                 "t_abs_s is GPS time (seconds since 1970 without leap seconds).")
