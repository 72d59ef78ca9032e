"""``sinslab align``: coarse + fine alignment of a recorded IMU file at rest into a run folder."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import numpy as np

from sinslab.app.commands.runner import Command, Figure, Output, Series, cli_call, run_command
from sinslab.core import units

#: the method this command applies (printed in its report)
PAPER = ("Yan Gongmin, Qin Yongyuan: Initial alignment accuracy analysis and simulation of SINS "
         "on a stationary base, Computer Simulation 23(10), 2006")

__all__ = ["ALIGN", "align_file", "register"]

ALIGN = Command("align", "coarse and fine alignment of a recorded IMU file at rest (paper 000 methods)",
                paper=PAPER)


def _parse_window(window):
    from sinslab.app.validate import option_window

    return option_window("--window", window)


def _check_options(lat, h, window, gyro_arw, accel_vrw, gyro_bias, accel_bias, model, period):
    """Every option of ``sinslab align`` checked before the file is read (one-line errors
    naming the option)."""
    from sinslab.app.validate import option_choice, option_quantity

    if lat is not None:
        option_quantity("--lat", lat, "angle", ge="-90 deg", le="90 deg")
    if h is not None:
        option_quantity("--height", h, "length", ge="-12 km", le="100 km")
    _parse_window(window)
    # upper bounds: beyond them no IMU is meant, and the small-angle limit-accuracy
    # formulas (φ = ∇/g, φU = ε/(ω_ie cos L)) would print meaningless angles
    option_quantity("--gyro-arw", gyro_arw, "angle_random_walk", ge="0 deg/sqrt(h)",
                    le="100 deg/sqrt(h)")
    if accel_vrw not in (None, "", "auto"):
        option_quantity("--accel-vrw", accel_vrw, "velocity_random_walk", ge="0 ug/sqrt(Hz)",
                        le="100000 ug/sqrt(Hz)")
    option_quantity("--gyro-bias", gyro_bias, "angular_rate", ge="0 deg/h", le="1000 deg/h")
    option_quantity("--accel-bias", accel_bias, "acceleration", ge="0 ug", le="100 mg")
    option_choice("--model", model, ("reduced", "full"))
    option_quantity("--period", period, "time", gt="0 s")


def _heading_check(r, duration, heading_sigma):
    """A warning (with the σ) when the window cannot support the heading it gives: too
    short for the record's own scatter to be measured, or fine and analytic headings more
    than 3σ apart."""
    co, fa = r["coarse"], r["fine"]
    s_f = math.degrees(float(heading_sigma))
    if co.phi_sigma_data is None:
        return (f"the {duration:g} s window is too short to check the heading: the fine "
                f"heading σ {s_f:.3g} deg only reflects the assumed --gyro-arw; gyrocompassing "
                f"needs the earth rate measured above the sensor noise (use at least tens of seconds)")
    s_c = math.degrees(float(co.att_sigma[2])) if co.att_sigma is not None else 0.0
    d = (math.degrees(float(fa.att[2] - co.att[2])) + 180.0) % 360.0 - 180.0
    s = math.hypot(s_f, s_c)
    if abs(d) > 3.0 * s:
        return (f"fine and analytic-coarse headings differ by {abs(d):.3g} deg, more than 3σ "
                f"(σ {s_f:.3g} deg fine, {s_c:.3g} deg coarse): the {duration:g} s window does not "
                f"determine the heading")
    return None


def align_file(path, *, fmt=None, lat=None, h=None, window=None, out=None,
               gyro_arw="0.01 deg/sqrt(h)", accel_vrw=None, gyro_bias="0.01 deg/h",
               accel_bias="100 ug", model="reduced", period="1 s", feedback=True, strict=False,
               echo=print):
    """Align a recorded IMU file at rest and write the usual outputs into ``out``.

    Prints (via ``echo``) pitch, roll and heading (clockwise from north) with 1σ from the
    analytic coarse, the inertial-frame coarse and the Kalman fine alignment, and the
    limit accuracy for the assumed biases. Writes config.toml, summary.json,
    alignment.csv (fine attitude and σ vs time), alignment.png/svg and report.html.
    Returns the summary dict. Plausibility warnings (:mod:`sinslab.app.plausibility`: |f|
    against gravity, dead channels, motion inside the window, a window too short for
    heading) are printed and listed in the report; ``strict`` refuses instead.
    """
    _check_options(lat, h, window, gyro_arw, accel_vrw, gyro_bias, accel_bias, model, period)
    summary, _ = run_command(ALIGN, out, lambda: _compute(
        path, fmt=fmt, lat=lat, h=h, window=window, gyro_arw=gyro_arw, accel_vrw=accel_vrw,
        gyro_bias=gyro_bias, accel_bias=accel_bias, model=model, period=period,
        feedback=feedback, strict=strict, echo=echo), echo=echo)
    return summary


def _compute(path, *, fmt, lat, h, window, gyro_arw, accel_vrw, gyro_bias, accel_bias, model,
             period, feedback, echo, strict=False) -> Output:
    from sinslab.app.plausibility import Finding, settle
    from sinslab.core.progress import stage
    from sinslab.methods.alignment import align_record

    gb = units.parse(gyro_bias, "angular_rate")
    imu, ps, lat_r, h_r, found = _read(path, fmt, lat, h, window, gb)
    ga = units.parse(gyro_arw, "angle_random_walk")
    av = None if accel_vrw in (None, "", "auto") else units.parse(accel_vrw, "velocity_random_walk")
    ab = units.parse(accel_bias, "acceleration")
    T = units.parse(period, "time")
    with stage(f"alignment over {len(imu) * imu.dt:.0f} s"):
        r = align_record(imu, lat_r, h_r, gyro_arw=ga, accel_vrw=av, gyro_bias=gb, accel_bias=ab,
                         model=model, period=T, feedback=feedback)
    fa = r["fine"]
    hw = _heading_check(r, len(imu) * imu.dt, fa.att_sigma[2])
    if hw:
        r["warnings"] = list(r["warnings"]) + [hw]
    found += [Finding(w_) for w_ in r["warnings"]]
    cfg = {"file": str(Path(path).absolute()), "format": fmt or ("psins" if ps is not None else "csv"),
           "latitude": f"{math.degrees(lat_r):.8g} deg", "height": f"{h_r:.6g} m",
           "window": window or ":", "gyro_arw": gyro_arw, "accel_vrw": accel_vrw or "auto",
           "gyro_bias": gyro_bias, "accel_bias": accel_bias, "model": model, "period": period,
           "feedback": bool(feedback)}
    _say(path, imu, lat_r, h_r, r, model, feedback, gyro_bias, accel_bias, echo)
    warnings = settle(found, strict=strict, echo=echo)
    tables, figures = _outputs(fa)
    return Output(config=cfg, metrics=_metrics(r, imu), tables=tables, figures=figures,
                  notes=["Heading is clockwise from north."], value=r, warnings=warnings)


def _read(path, fmt, lat, h, window, gb):
    """``(imu, PSINS header or None, latitude [rad], height [m], findings)``: the record in
    its window, checked (refusals raised; ``gb`` the gyro bias [rad/s] the rest's rate may
    carry)."""
    from sinslab.app.plausibility import imu_findings, rest_findings, rest_rate_findings, settle
    from sinslab.data import read_imu
    from sinslab.methods import alignment as al
    from sinslab.core.progress import stage

    with stage(f"reading {Path(path).name}"):
        imu, ps = read_imu(path, fmt)
    if lat is None:
        if ps is None:
            raise ValueError("--lat is required for a CSV file (PSINS logs carry it in the header)")
        lat_r = ps.lat
    else:
        lat_r = units.parse(lat, "angle")
    h_r = (ps.h if ps is not None else 0.0) if h is None else units.parse(h, "length")
    lo, hi = _parse_window(window)
    if lo is not None or hi is not None:
        from sinslab.app.validate import check_window

        check_window("--window", window, float(imu.t[0]) - imu.dt, float(imu.t[-1]), imu.dt)
        imu = imu.slice(lo, hi)
    src = f"{path}" + (f" (window {window})" if window else "")
    found = imu_findings(imu, src, lat=lat_r, h=h_r)
    if not any(fd.refuse for fd in found):
        found += rest_findings(imu, src, lat=lat_r, h=h_r) + rest_rate_findings(imu, src, lat=lat_r, gyro_bias=gb)
    settle([fd for fd in found if fd.refuse])
    al.check_alignment_latitude(lat_r)
    return imu, ps, lat_r, h_r, found


def _angles(att):
    """Pitch, roll [deg] and heading clockwise from north [deg]."""
    from sinslab.core import attitude as A      # numba and scipy: only when it runs
    return (math.degrees(att[0]), math.degrees(att[1]), math.degrees(float(A.yaw_to_heading(att[2]))))


def _say(path, imu, lat_r, h_r, r, model, feedback, gyro_bias, accel_bias, echo):
    """The three alignments on the terminal."""
    from sinslab.core import earth
    co, ci, fa = r["coarse"], r["inertial"], r["fine"]
    rows = [("coarse (analytic)", _angles(co.att), co.att_sigma),
            ("coarse (inertial frame)", _angles(ci.att), None),
            (f"fine ({model}, {'closed' if feedback else 'open'} loop)", _angles(fa.att), fa.att_sigma)]
    echo(f"{path}: {len(imu)} samples, {imu.t0:.3f}..{imu.t[-1]:.3f} s, dt {imu.dt * 1e3:g} ms, "
         f"latitude {math.degrees(lat_r):.6f} deg, height {h_r:g} m")
    echo(f"  |f| = {r['f_norm']:.6f} m/s^2 (normal gravity {r['g']:.6f}); "
         f"|w| = {r['w_norm'] / earth.WIE:.5f} w_ie; 1-s specific-force variation "
         f"{fa.rest.f_rms * 1e3:.3g} mm/s^2 RMS")
    echo("  (heading clockwise from north; sigma from the filter / averaging noise)")
    for name, (p_, r_, hd), sg in rows:
        s = "" if sg is None else (f"  sigma {sg[0] / units.arcmin:.3g}', {sg[1] / units.arcmin:.3g}', "
                                   f"{sg[2] / units.arcmin:.3g}'")
        echo(f"  {name:<34s} pitch {p_:9.4f} deg  roll {r_:9.4f} deg  heading {hd:9.4f} deg{s}")
    la = r["limit_att"] / units.arcmin
    echo(f"  limit accuracy for 1-sigma biases {gyro_bias}, {accel_bias}: pitch {la[0]:.3g}', "
         f"roll {la[1]:.3g}', heading {la[2]:.3g}'")


def _metrics(r, imu):
    from sinslab.core import earth
    co, ci, fa = r["coarse"], r["inertial"], r["fine"]
    la = r["limit_att"] / units.arcmin
    metrics = {}
    for key, att, sg in (("coarse", co.att, co.att_sigma), ("inertial", ci.att, None),
                         ("fine", fa.att, fa.att_sigma)):
        p_, r_, hd = _angles(att)
        metrics[f"{key}_pitch_deg"], metrics[f"{key}_roll_deg"], metrics[f"{key}_heading_deg"] = p_, r_, hd
        if sg is not None:
            metrics[f"{key}_sigma_pitch_arcmin"] = float(sg[0] / units.arcmin)
            metrics[f"{key}_sigma_roll_arcmin"] = float(sg[1] / units.arcmin)
            metrics[f"{key}_sigma_heading_arcmin"] = float(sg[2] / units.arcmin)
    metrics.update(
        f_norm_mps2=r["f_norm"], gravity_mps2=r["g"], w_norm_over_wie=r["w_norm"] / earth.WIE,
        f_var_rms_mps2=fa.rest.f_rms, meas_noise_ug=(np.sqrt(np.diag(fa.R)) / units.ug).tolist(),
        limit_pitch_arcmin=float(la[0]), limit_roll_arcmin=float(la[1]),
        limit_heading_arcmin=float(la[2]), nis_mean=float(np.mean(fa.nis)),
        duration_s=float(len(imu) * imu.dt))
    return metrics


def _outputs(fa):
    """The ``alignment`` table and figure of the fine alignment."""
    from sinslab.app import plotting            # matplotlib: only when a command runs
    from sinslab.core import attitude as A
    tm = fa.t
    hd = np.degrees(A.yaw_to_heading(fa.att_path[:, 2]))
    tables = [Series("alignment", {"t_s": tm, "pitch_deg": np.degrees(fa.att_path[:, 0]),
                                   "roll_deg": np.degrees(fa.att_path[:, 1]), "heading_deg": hd,
                                   "sigma_phiE_arcmin": fa.sigma[:, 0] / units.arcmin,
                                   "sigma_phiN_arcmin": fa.sigma[:, 1] / units.arcmin,
                                   "sigma_phiU_arcmin": fa.sigma[:, 2] / units.arcmin})]
    fig, axes = plotting.figure(3, 1, width=8.0)
    for ax, y, s_, lab in zip(axes, (np.degrees(fa.att_path[:, 0]), np.degrees(fa.att_path[:, 1]), hd),
                              (fa.sigma[:, 1], fa.sigma[:, 0], fa.sigma[:, 2]),
                              ("pitch [°]", "roll [°]", "heading [°]")):
        ax.plot(tm - tm[0], y, "b-", lw=1)
        k = max(1, len(tm) // 10)
        ax.fill_between(tm[k:] - tm[0], y[k:] - np.degrees(s_[k:]), y[k:] + np.degrees(s_[k:]),
                        color="b", alpha=0.15, lw=0)
        ax.set_ylabel(lab)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Fine alignment: attitude estimate ±1σ (heading clockwise from north)")
    return tables, [Figure("alignment", fig, "Fine-alignment attitude estimate (±1σ band) versus time.")]


def register(app):
    """Add the ``sinslab align`` command to the typer ``app`` (called from sinslab.cli)."""
    import typer

    @app.command()
    def align(imu: Path = typer.Option(..., "--imu", help="recorded IMU file (at rest)"),
              format: Optional[str] = typer.Option(None, "--format", help="psins | csv | parquet | mat | rtklib-imu [default: from the suffix]"),
              lat: Optional[str] = typer.Option(None, "--lat", help='latitude, e.g. "34.246 deg" [default: PSINS header]'),
              height: Optional[str] = typer.Option(None, "--height", help='height, e.g. "380 m"'),
              window: Optional[str] = typer.Option(None, "--window", metavar="START:END", help="time window [s]"),
              out: Optional[Path] = typer.Option(None, "--out", "-o", help="output folder [default: runs/align-<timestamp>]"),
              gyro_arw: str = typer.Option("0.01 deg/sqrt(h)", "--gyro-arw", help="gyro angle random walk (Q)"),
              accel_vrw: Optional[str] = typer.Option(None, "--accel-vrw", help="accel noise for R [default: from the data]"),
              gyro_bias: str = typer.Option("0.01 deg/h", "--gyro-bias", help="assumed 1σ gyro bias (limit accuracy)"),
              accel_bias: str = typer.Option("100 ug", "--accel-bias", help="assumed 1σ accel bias (limit accuracy)"),
              model: str = typer.Option("reduced", "--model", help="reduced | full"),
              period: str = typer.Option("1 s", "--period", help="filter period"),
              open_loop: bool = typer.Option(False, "--open-loop", help="no attitude feedback"),
              strict: bool = typer.Option(False, "--strict", help="refuse (exit 2, nothing written) instead of warning about the data"),
              force: bool = typer.Option(False, "--force", help="replace whatever --out holds (another run, other files)")) -> None:
        """Coarse and fine alignment of a recorded IMU file at rest (pitch, roll, heading with σ)."""
        cli_call(align_file, imu, fmt=format, lat=lat, h=height, window=window, out=out,
                 gyro_arw=gyro_arw, accel_vrw=accel_vrw, gyro_bias=gyro_bias,
                 accel_bias=accel_bias, model=model, period=period, feedback=not open_loop,
                 strict=strict, echo=typer.echo, force=force)

    return align
