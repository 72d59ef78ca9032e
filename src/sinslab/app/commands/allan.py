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


#: fewest clusters at τ = 1 s: the white-noise term N is σ(1 s) of the −½ line, and with
#: K clusters σ is known to about 1/√(2(K−1)) (9 clusters: ±25 %); allantools stops at
#: N/9 samples per cluster for the same reason
MIN_CLUSTERS = 9


def _at_longest(f) -> bool:
    """True if the curve's minimum is its longest cluster time: the floor is not reached,
    so the bias instability is an upper bound (the record is too short to show it)."""
    return f.tau_floor >= f.tau[-1] * (1 - 1e-9)


def _table(res: AllanResult):
    """Rows (name, N, N unit, B, B unit, τ_floor, K, K unit); an upper bound is marked
    ``<=`` in front of its unit (N without a clean −½ line, B at the longest τ)."""
    rows = []
    ub = lambda flag: "<= " if flag else ""  # noqa: E731
    for f in res.gyro:
        rows.append((f.name, f.n_white / units.dpsh, ub(f.n_is_bound) + "°/√h", f.bias_instability / units.dph,
                     ub(_at_longest(f)) + "°/h", f.tau_floor, f.rrw / units.dphpsh, "°/h/√h"))
    for f in res.accel:
        rows.append((f.name, f.n_white / units.ugpsHz, ub(f.n_is_bound) + "µg/√Hz", f.bias_instability / units.ug,
                     ub(_at_longest(f)) + "µg", f.tau_floor, f.rrw / units.ug * math.sqrt(3600.0), "µg/√h"))
    return rows


def _check_clusters(imu, source) -> None:
    """Refuse a record too short for an Allan fit: fewer than :data:`MIN_CLUSTERS` clusters
    of 1 s (the cluster time at which the white-noise term is read)."""
    dur = len(imu) * imu.dt
    if dur < MIN_CLUSTERS * 1.0:
        raise ValueError(f"{source}: {dur:.3g} s of data ({len(imu)} samples) is too short for an "
                         f"Allan fit: the noise terms are read at cluster times of 1 s and longer, "
                         f"which need at least {MIN_CLUSTERS} clusters ({MIN_CLUSTERS} s); the bias "
                         f"instability needs minutes to hours")


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


def allan_file(path, *, fmt=None, out=None, window=None, strict=False, echo=print, **read_kw):
    """Read a recorded IMU file, compute the Allan deviations and write the run folder.

    A record (window) shorter than :data:`MIN_CLUSTERS` s is refused; plausibility
    warnings (:mod:`sinslab.app.plausibility`) and terms that are only upper bounds are
    printed and listed in the report; ``strict`` refuses instead.
    Returns ``(summary, AllanResult, ImuErrors)``.
    """
    from sinslab.app.validate import option_window

    option_window("--window", window)
    _check_units(path, read_kw)
    summary, res = run_command(ALLAN, out, lambda: _compute(path, fmt, window, echo, read_kw, strict),
                               echo=echo)
    return (summary, *res.value)


def _compute(path, fmt, window, echo, read_kw, strict=False) -> Output:
    from sinslab.app.plausibility import Finding, imu_findings, rest_rate_findings, settle
    from sinslab.core.progress import stage
    from sinslab.data import load_imu

    with stage(f"reading {Path(path).name}"):
        data = load_imu(path, fmt, **read_kw)
    imu = data.imu
    if window:
        from sinslab.app.validate import check_window, option_window

        check_window("--window", window, float(imu.t[0]) - imu.dt, float(imu.t[-1]), imu.dt)
        imu = imu.slice(*option_window("--window", window))
    src = f"{path}" + (f" (window {window})" if window else "")
    found = imu_findings(imu, src, gaps=data.gaps)
    settle([fd for fd in found if fd.refuse])
    found += rest_rate_findings(imu, src)
    if strict:
        settle(found, strict=True)
    _check_clusters(imu, src)
    dead = [f"{s} {a}" for arr, s in ((imu.dtheta, "gyro"), (imu.dv, "accel"))
            for k, a in enumerate("xyz") if np.ptp(arr[:, k]) == 0]
    if dead:
        raise ValueError(f"{src}: {', '.join(dead)} constant over all {len(imu)} samples: no Allan "
                         f"deviation to fit (a dead or unconnected channel?)")
    with stage(f"Allan deviation of {len(imu) * imu.dt:.0f} s"):
        res = allan(imu)
    short = [f.name for f in res.gyro + res.accel if _at_longest(f)]
    if short:
        found.append(Finding(f"{src}: the Allan curve of {', '.join(short)} still falls at the longest "
                             f"cluster time ({res.gyro[0].tau[-1]:.3g} s): the bias instability there "
                             f"is an upper bound; a longer record shows the floor"))

    errs = imu_errors_from_allan(res)
    toml = errs.to_toml("imu")
    rows = _table(res)
    _say(path, imu, res, rows, toml, echo)
    warnings = settle(found, strict=strict, echo=echo)
    cfg = {"file": str(Path(path).absolute()), "format": data.format, "window": window or ":"}
    notes = ["Bias instability B = Allan floor / 0.664 (IEEE 952).",
             "imu_errors.toml: paste into a simulation config ([imu] table).", toml]
    return Output(config=cfg, metrics=_metrics(rows), tables=[_curves(res)], figures=[_figure(res)],
                  files={"imu_errors.toml": toml}, notes=notes, value=(res, errs),
                  warnings=warnings)


def _say(path, imu, res, rows, toml, echo):
    """The noise terms on the terminal."""
    echo(f"{path}: {len(imu)} samples at {1 / imu.dt:g} Hz, {res.duration:.1f} s")
    echo(f"  {'axis':<8s} {'N (ARW/VRW)':>22s} {'bias instab. B':>18s} {'at tau':>9s} {'RRW K':>22s}")
    for nm, nv, nu, bv, bu, tf, kv, ku in rows:
        mn, mb = ("≤" if u.startswith("<= ") else "" for u in (nu, bu))
        echo(f"  {nm:<8s} {mn + format(nv, '.4g'):>12s} {nu.removeprefix('<= '):<12s}"
             f"{mb + format(bv, '.4g'):>10s} {bu.removeprefix('<= '):<7s} {tf:8.3g}s {kv:10.3g} {ku}")
    echo("  ImuErrors for a simulation config (bias instability as a Gauss-Markov process "
         "with the same Allan peak):")
    for line in toml.splitlines():
        echo("    " + line)
    if any(r[2].startswith("<= ") or r[4].startswith("<= ") for r in rows):
        echo("  (≤: an upper bound — no clean −½ slope for N, or no floor before the longest "
             "cluster time for B)")


def _metrics(rows):
    metrics = {}
    for nm, nv, nu, bv, bu, tf, kv, ku in rows:
        key = nm.replace(" ", "_")
        s, _ = nm.split()
        metrics[f"{key}_{'arw_dpsh' if s == 'gyro' else 'vrw_ugpsHz'}"] = nv
        metrics[f"{key}_bias_instability_{'dph' if s == 'gyro' else 'ug'}"] = bv
        metrics[f"{key}_tau_floor_s"] = tf
        metrics[f"{key}_rrw_{'dphpsh' if s == 'gyro' else 'ugpsh'}"] = kv
    metrics["upper_bounds"] = [f"{r[0].replace(' ', '_')}_{t}" for r in rows for t, u in
                               (("white_noise", r[2]), ("bias_instability", r[4])) if u.startswith("<= ")]
    return metrics


def _curves(res):
    """The ``allan`` table: the Allan deviation of every axis."""
    tab = {"tau_s": res.gyro[0].tau}
    for f in res.gyro:
        if f.tau.size == tab["tau_s"].size:
            tab[f"{f.name.replace(' ', '_')}_adev_dph"] = f.adev / units.dph
    for f in res.accel:
        if f.tau.size == tab["tau_s"].size:
            tab[f"{f.name.replace(' ', '_')}_adev_ug"] = f.adev / units.ug
    return Series("allan", tab, "overlapping Allan deviation per axis")


def _figure(res):
    from sinslab.app import plotting            # matplotlib: only when a command runs
    fig, axes = plotting.figure(1, 2, sharex=False, width=11.0, row_height=4.6)
    for ax, fits, sc, unit in ((axes[0], res.gyro, units.dph, "°/h"), (axes[1], res.accel, units.ug, "µg")):
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
    return Figure("allan", fig, "Allan deviation of each gyro and accelerometer axis with the "
                  "terms the report gives: the N/√τ line, the floor (bias instability B) and "
                  "the K·√(τ/3) line. Where base motion or dither adds a hump the noise "
                  "model has no term for (the horizontal axes of a vehicle that sways), N "
                  "is the upper bound min σ·√τ: its dotted line touches the curve once and "
                  "lies below it elsewhere, by construction.")


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
              strict: bool = typer.Option(False, "--strict", help="refuse (exit 2, nothing written) instead of warning about the data"),
              force: bool = typer.Option(False, "--force", help="replace whatever --out holds (another run, other files)")) -> None:
        """Allan deviation of recorded IMU data: ARW/VRW, bias instability, RRW and an ImuErrors block."""
        kw = {}
        if gyro_unit:
            kw["gyro_unit"] = gyro_unit
        if accel_unit:
            kw["accel_unit"] = accel_unit
        cli_call(allan_file, file, fmt=format, out=out, window=window, strict=strict, echo=typer.echo,
                 force=force, **kw)

    return allan
