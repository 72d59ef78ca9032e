"""GNSS alone in ``sinslab navigate`` (no ``--imu``): the rover's raw observations solved
without an INS — the single-point solution, or RTK against a base station
(``--gnss-base BASE --base-position "X,Y,Z m"``, :func:`sinslab.fusion.gnss_alone.rtk_solve`
with the motion model ``gnss.raw.dynamics``) — so that one command line compares GNSS
alone with INS/GNSS (the same line with ``--imu``).

The run folder holds ``solution.csv`` (per epoch: time, status, position ± σ; for RTK the
ratio, integers fixed and formed, double differences, restarts), the figures ``track``
(horizontal position about the first epoch, fixed epochs marked) and, for RTK, ``rtk``
(fix status, ratio, integers, restarts per epoch), and the metrics of the RTK engine
(:func:`sinslab.fusion.rtk_source.rtk_report`: epochs fixed, first fix, ratio, restarts
and skipped signals by cause, the NIS of the double differences) with the mean fixed
antenna, its distance from the base and its spread."""
from __future__ import annotations

import numpy as np

__all__ = ["gnss_alone"]


def _rover(keys):
    from sinslab.core.errors import InputError
    from sinslab.data.gnss import read_gnss_raw
    from sinslab.fusion.gnss import prepare
    nav = None if keys.nav in ("none", "") else keys.nav
    sv = prepare(read_gnss_raw(keys.file, nav))
    if not sv.usable.any():
        raise InputError(f"{keys.file}: no satellite has an ephemeris"
                         + ("" if nav is not None else " (give a navigation file with --gnss-nav)"))
    return sv


def gnss_alone(cfg, echo=print):
    """The GNSS-only run of ``cfg`` (:mod:`sinslab.app.commands.navigate_config`): a
    :class:`~sinslab.app.commands.runner.Output` whose value is ``(solution, None)`` (the
    :class:`~sinslab.fusion.gnss_alone.RtkSolution` or
    :class:`~sinslab.fusion.gnss.SinglePoint`; no reference fixes)."""
    from sinslab.app.commands.navigate_config import config_value
    from sinslab.app.commands.raw_gnss import check_phase_keys
    from sinslab.app.commands.runner import Output
    if cfg.gnss.source != "raw" or not cfg.gnss.raw.file:
        raise ValueError("give the IMU log: --imu FILE (imu.file); without an IMU, raw GNSS observations "
                         "(--gnss-raw FILE) are solved GNSS alone")
    keys = cfg.gnss.raw
    check_phase_keys(keys)
    if keys.phase == "tdcp":
        raise ValueError("--phase tdcp compares each phase change with the INS's position change: give --imu, "
                         "or a base (--gnss-base, --base-position) for RTK without an IMU")
    sv = _rover(keys)
    metrics, table, figures, notes, sol = (_rtk if keys.base else _single_point)(cfg, keys, sv, echo)
    from sinslab.app.commands.runner import Series
    return Output(config=config_value(cfg), metrics=metrics,
                  tables=[Series("solution", table, "GNSS-alone solution per epoch (t_s from the first epoch)")],
                  figures=figures, notes=notes, value=(sol, None))


def _single_point(cfg, keys, sv, echo):
    from sinslab.fusion.gnss import single_point
    sp = single_point(sv, mask=keys.elevation_mask, sigma=keys.pseudorange_sigma, sigma_rate=keys.doppler_sigma)
    ok = np.isfinite(sp.lat)
    for a, ln in _outages(cfg, sv):                 # epochs not used: no solution there
        ok &= ~((sp.t >= a) & (sp.t < a + ln))
    if not ok.any():
        from sinslab.core.errors import InputError
        raise InputError(f"{keys.file}: no epoch has 4 satellites with ephemeris above the mask")
    m = dict(gnss_epochs=int(sp.t.size), gnss_epochs_solved=int(ok.sum()),
             satellites_used_median=float(np.median(sp.n_sat[ok])))
    echo(f"{keys.file}: GNSS alone, single point: {m['gnss_epochs_solved']} of {m['gnss_epochs']} epochs solved, "
         f"median {m['satellites_used_median']:.0f} satellites")
    sig = np.where(ok[:, None], sp.sigma, np.nan)
    table = dict(t_s=sp.t - sp.t[0], t_abs_s=sp.t, status=ok.astype(np.int64),
                 lat_deg=np.where(ok, np.degrees(sp.lat), np.nan), lon_deg=np.where(ok, np.degrees(sp.lon), np.nan),
                 h_m=np.where(ok, sp.h, np.nan), sigma_e_m=sig[:, 1], sigma_n_m=sig[:, 0], sigma_u_m=sig[:, 2],
                 n_sat=sp.n_sat)
    return m, table, [_track(table, "single-point solution")], [
        "GNSS alone: the single-point solution (weighted least squares per epoch, the models of the tightly "
        "coupled rows); status 1 where solved."], sp


def _rtk(cfg, keys, sv, echo):
    from sinslab.app.commands.panels import panel_figure
    from sinslab.app.commands.raw_gnss import load_base, rtk_options
    from sinslab.fusion.aids.base import PanelFigure
    from sinslab.fusion.gnss_alone import rtk_solve
    from sinslab.fusion.rtk import check_phase
    from sinslab.fusion.rtk_source import rtk_panels, rtk_report
    check_phase(sv, str(keys.file))
    base = load_base(keys, sv, echo)
    sol = rtk_solve(sv, base, rtk_options(keys), dynamics=keys.dynamics, outages=_outages(cfg, sv))
    m, cols, line = rtk_report(sol, float(sv.t_epoch[0]), base.position)
    m.update(_baseline(sol, base))
    echo(f"{keys.file}: GNSS alone, RTK against {keys.base} ({keys.dynamics}): {line}")
    if "rtk_baseline_m" in m:
        echo(f"  mean fixed antenna {m['rtk_baseline_m']:.3f} m from the base, spread (1σ) east "
             f"{1e3 * m['rtk_fixed_spread_e_m']:.1f}, north {1e3 * m['rtk_fixed_spread_n_m']:.1f}, up "
             f"{1e3 * m['rtk_fixed_spread_u_m']:.1f} mm")
    figs = [_track(cols, "RTK solution", fixed=cols["status"] == 2),
            panel_figure(PanelFigure("rtk", "RTK per epoch: fix status, ratio, integers fixed and formed, "
                                     "ambiguities restarted", rtk_panels(cols)), 0.0)]
    note = (f"GNSS alone, RTK: double-differenced code and phase against {keys.base} at the base position given, "
            f"{keys.dynamics} motion model, integers by LAMBDA (ratio ≥ {keys.ratio:g}, bootstrapped success rate, "
            f"partial fixing, validated, {keys.ar}). t_s from the first epoch; t_abs_s the receiver's GPS time.")
    return m, cols, figs, [note], sol


def _outages(cfg, sv):
    """``--outages`` (s from the first GNSS epoch) as absolute ``(start, length)`` [s]."""
    from sinslab.app.validate import check_outages
    from sinslab.fusion.recorded import parse_outages, periodic_outages
    t0, t1 = float(sv.t_epoch[0]), float(sv.t_epoch[-1])
    outs = parse_outages(cfg.gnss.outages, t0)
    if outs:
        check_outages("--outages", cfg.gnss.outages, outs, t0, t1)
    return [o for x in outs for o in (periodic_outages(t0, t1, *x[1:]) if x[0] == "periodic" else [x])]


def _baseline(sol, base):
    """The mean fixed antenna: ECEF [m], its distance from the base [m] and the spread
    (1σ east, north, up [m]) of the fixed epochs about it (a static survey's check)."""
    fx = sol.fixed & np.all(np.isfinite(sol.fixed_pos), 1)
    if not fx.any():
        return {}
    mean = sol.fixed_pos[fx].mean(0)
    e = sol.enu_errors(mean, "fixed_pos")[fx]
    return dict(rtk_fixed_mean_x_m=float(mean[0]), rtk_fixed_mean_y_m=float(mean[1]),
                rtk_fixed_mean_z_m=float(mean[2]),
                rtk_baseline_m=float(np.linalg.norm(mean - np.asarray(base.position, float))),
                **{f"rtk_fixed_spread_{c}_m": float(np.std(e[:, k])) for k, c in enumerate("enu")})


def _track(cols, what, fixed=None):
    """The horizontal track about the first epoch [m], fixed epochs marked."""
    from sinslab.app import plotting
    from sinslab.app.commands.runner import Figure
    from sinslab.core import earth as E
    lat, lon = np.radians(cols["lat_deg"]), np.radians(cols["lon_deg"])
    ok = np.isfinite(lat)
    fig, axes = plotting.figure(1, 1, sharex=False, width=6.5, row_height=5.5, title=f"{what}: horizontal track")
    ax = axes[0]
    if ok.any():
        i0 = int(np.flatnonzero(ok)[0])
        rm, rn = E.radii(lat[i0], float(cols["h_m"][i0]))
        east, north = (lon - lon[i0]) * rn * np.cos(lat[i0]), (lat - lat[i0]) * rm
        ax.plot(east[ok], north[ok], ".-", lw=0.6, ms=2, color=plotting.COLORS[0], label=what)
        if fixed is not None and fixed.any():
            ax.plot(east[fixed], north[fixed], ".", ms=3, color=plotting.COLORS[1], label="fixed")
        ax.legend(fontsize=8)
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_aspect("equal", adjustable="datalim")
    return Figure("track", fig, f"Horizontal track of the {what} about its first epoch.")
