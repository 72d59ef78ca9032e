"""``sinslab allan FILE``: Allan deviation and IEEE noise terms of a recorded IMU file into a
run folder (table, figure, an ImuErrors block for simulation configs)."""
from __future__ import annotations

import math
from pathlib import Path
from typing import Optional

import numpy as np

from sinslab.app.commands.runner import Command, Figure, Output, Series, cli_call, run_command
from sinslab.core import units
from sinslab.sim.allan import AllanResult, allan, imu_errors_from_allan

__all__ = ["ALLAN", "allan_file", "register"]

ALLAN = Command("allan", "Allan deviation and IEEE noise terms of a recorded IMU file")


def _table(res: AllanResult):
    rows = []
    for f in res.gyro:
        rows.append((f.name, f.n_white / units.dpsh, "deg/sqrt(h)" + ("(<=)" if f.n_is_bound else ""), f.bias_instability / units.dph,
                     "deg/h", f.tau_floor, f.rrw / units.dphpsh, "deg/h/sqrt(h)"))
    for f in res.accel:
        rows.append((f.name, f.n_white / units.ugpsHz, "ug/sqrt(Hz)" + ("(<=)" if f.n_is_bound else ""), f.bias_instability / units.ug,
                     "ug", f.tau_floor, f.rrw / units.ug * math.sqrt(3600.0), "ug/sqrt(h)"))
    return rows


def _check_units(path, read_kw) -> None:
    """Refuse ``--gyro-unit``/``--accel-unit`` for a file whose header states its units
    (they would be ignored), and a unit of the wrong kind."""
    for opt, key, kind in (("--gyro-unit", "gyro_unit", ("angular_rate", "angle")),
                           ("--accel-unit", "accel_unit", ("acceleration", "velocity"))):
        unit = read_kw.get(key)
        if not unit:
            continue
        from sinslab.core import units

        try:
            units.unit_scale(unit)
        except ValueError as e:
            raise ValueError(f"{opt} {unit!r}: {e}") from None
        if not any(_is_kind(unit, k) for k in kind):
            raise ValueError(f"{opt} {unit!r}: not a unit of {' or '.join(k.replace('_', ' ') for k in kind)}")
        p = Path(path)
        if p.suffix.lower() == ".imu":
            raise ValueError(f"{opt} {unit!r}: {p} is a PSINS log whose header states its scale "
                             f"factors; the option applies to CSV columns without a unit")
        try:
            with open(p, "r", encoding="utf-8", errors="replace") as fh:
                head = next((ln for ln in fh if ln.strip() and not ln.startswith("#")), "")
        except OSError:
            return                                   # the reader reports the file itself
        if "[" in head and "]" in head:
            raise ValueError(f"{opt} {unit!r}: the header of {p} states the column units "
                             f"({head.strip()[:80]}); the option applies to columns without one")


def _is_kind(unit, kind) -> bool:
    from sinslab.core import units

    try:
        units.unit_scale(unit, kind)
        return True
    except ValueError:
        return False


def allan_file(path, *, fmt=None, out=None, window=None, echo=print, **read_kw):
    """Read a recorded IMU file, compute the Allan deviations and write the run folder.

    Returns ``(summary, AllanResult, ImuErrors)``.
    """
    from sinslab.app.validate import option_window

    option_window("--window", window)
    _check_units(path, read_kw)
    summary, res = run_command(ALLAN, out, lambda: _compute(path, fmt, window, echo, read_kw),
                               echo=echo)
    return (summary, *res.value)


def _compute(path, fmt, window, echo, read_kw) -> Output:
    from sinslab.app import plotting            # matplotlib: only when a command runs
    from sinslab.data import load_imu

    data = load_imu(path, fmt, **read_kw)
    imu = data.imu
    if window:
        from sinslab.app.validate import check_window, option_window

        check_window("--window", window, float(imu.t[0]) - imu.dt, float(imu.t[-1]))
        imu = imu.slice(*option_window("--window", window))
    res = allan(imu)
    errs = imu_errors_from_allan(res)
    toml = errs.to_toml("imu")
    rows = _table(res)
    echo(f"{path}: {len(imu)} samples at {1 / imu.dt:g} Hz, {res.duration:.1f} s")
    echo(f"  {'axis':<8s} {'N (ARW/VRW)':>22s} {'bias instab. B':>18s} {'at tau':>9s} {'RRW K':>22s}")
    for nm, nv, nu, bv, bu, tf, kv, ku in rows:
        echo(f"  {nm:<8s} {nv:12.4g} {nu:<12s}{bv:10.4g} {bu:<7s} {tf:8.3g}s {kv:10.3g} {ku}")
    echo("  ImuErrors for a simulation config (bias instability as a Gauss-Markov process "
         "with the same Allan peak):")
    for line in toml.splitlines():
        echo("    " + line)
    metrics = {}
    for nm, nv, nu, bv, bu, tf, kv, ku in rows:
        key = nm.replace(" ", "_")
        s, _ = nm.split()
        metrics[f"{key}_{'arw_dpsh' if s == 'gyro' else 'vrw_ugpsHz'}"] = nv
        metrics[f"{key}_bias_instability_{'dph' if s == 'gyro' else 'ug'}"] = bv
        metrics[f"{key}_tau_floor_s"] = tf
        metrics[f"{key}_rrw_{'dphpsh' if s == 'gyro' else 'ugpsh'}"] = kv
    cfg = {"file": str(path), "format": data.format, "window": window or ":"}
    tab = {"tau_s": res.gyro[0].tau}
    for f in res.gyro:
        if f.tau.size == tab["tau_s"].size:
            tab[f"{f.name.replace(' ', '_')}_adev_dph"] = f.adev / units.dph
    for f in res.accel:
        if f.tau.size == tab["tau_s"].size:
            tab[f"{f.name.replace(' ', '_')}_adev_ug"] = f.adev / units.ug
    tables = [Series("allan", tab, "overlapping Allan deviation per axis")]
    fig, axes = plotting.figure(1, 2, sharex=False, width=11.0, row_height=4.6)
    for ax, fits, sc, unit in ((axes[0], res.gyro, units.dph, "deg/h"), (axes[1], res.accel, units.ug, "ug")):
        for f, c in zip(fits, plotting.COLORS):
            ax.loglog(f.tau, f.adev / sc, "-", color=c, lw=1.2, label=f.name)
            # the reported terms, not an overall fit: N/√τ (σ(1 s) = N) and K·√(τ/3)
            ax.loglog(f.tau, f.n_white / np.sqrt(f.tau) / sc, "--" if not f.n_is_bound else ":",
                      color=c, lw=1)
            if f.rrw > 0:
                ax.loglog(f.tau, f.rrw * np.sqrt(f.tau / 3.0) / sc, "-.", color=c, lw=0.8)
            ax.plot([f.tau_floor], [f.floor / sc], "o", color=c, ms=4)
        ax.plot([], [], "k--", lw=1, label="N/√τ (white noise)")
        ax.plot([], [], "k:", lw=1, label="N/√τ, N an upper bound")
        ax.plot([], [], "k-.", lw=0.8, label="K·√(τ/3) (rate random walk)")
        ax.plot([], [], "ko", ms=4, label="floor = 0.664·B")
        ax.set_xlabel("cluster time τ [s]")
        ax.set_ylabel(f"Allan deviation [{unit}]")
        # below the axes: the curves fill every corner of the log-log panel
        ax.legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.14))
    fig.suptitle("Overlapping Allan deviation and the reported noise terms")
    figures = [Figure("allan", fig, "Allan deviation of each gyro and accelerometer axis with the "
                      "terms the report gives: the N/√τ line, the floor (bias instability B) and "
                      "the K·√(τ/3) line. Where base motion or dither adds a hump the noise "
                      "model has no term for (the horizontal axes of a vehicle that sways), N "
                      "is the upper bound min σ·√τ: its dotted line touches the curve once and "
                      "lies below it elsewhere, by construction.")]
    notes = ["Bias instability B = Allan floor / 0.664 (IEEE 952).",
             "imu_errors.toml: paste into a simulation config ([imu] table).", toml]
    return Output(config=cfg, metrics=metrics, tables=tables, figures=figures,
                  files={"imu_errors.toml": toml}, notes=notes, value=(res, errs))


def register(app):
    """Add the ``sinslab allan`` command to the typer ``app`` (called from sinslab.cli)."""
    import typer

    @app.command()
    def allan(file: Path = typer.Argument(..., help="recorded IMU file (at rest)"),
              format: Optional[str] = typer.Option(None, "--format", help="psins | csv | parquet | mat | rtklib-imu"),
              window: Optional[str] = typer.Option(None, "--window", metavar="START:END", help="time window [s]"),
              gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="unit of gyro columns without one"),
              accel_unit: Optional[str] = typer.Option(None, "--accel-unit", help="unit of accel columns without one"),
              out: Optional[Path] = typer.Option(None, "--out", "-o", help="output folder [default: runs/allan-<timestamp>]"),
              force: bool = typer.Option(False, "--force", help="replace whatever --out holds (another run, other files)")) -> None:
        """Allan deviation of recorded IMU data: ARW/VRW, bias instability, RRW and an ImuErrors block."""
        kw = {}
        if gyro_unit:
            kw["gyro_unit"] = gyro_unit
        if accel_unit:
            kw["accel_unit"] = accel_unit
        cli_call(allan_file, file, fmt=format, out=out, window=window, echo=typer.echo, force=force, **kw)

    return allan
