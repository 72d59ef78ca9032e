"""Allan deviation of recorded IMU data (``sinslab allan FILE``).

For each gyro and accelerometer axis the overlapping Allan deviation (``allantools.oadev``)
of the rate (increment / dt) is computed on octave-spaced cluster times, and the IEEE-952
noise terms are read off it:

- **angle / velocity random walk N** — the −½ slope line: the median of σ(τ)·√τ over
  τ in [10 τ0, min(1 s, τ_min/10)] (above the quantization knee, below the floor), i.e.
  σ(1 s) of that line; a least-squares fit of ``σ²(τ) = N²/τ + B_f² + K² τ/3`` (relative
  residuals, non-negative coefficients) is drawn. When the curve has no clean −½ slope
  there (base motion of a "static" vehicle, quantization), N is reported as the upper
  bound min σ(τ)·√τ over τ up to the minimum, flagged ``n_is_bound``;
- **bias instability B** — the curve's minimum divided by 0.664 (IEEE; the flicker floor
  is 0.664·B), with the cluster time of the minimum;
- **rate random walk K** — from that fit (the +½ slope line, σ(3 s) = K); reported as 0
  when the curve does not rise after its minimum (record too short to show it).

The :class:`sinslab.sim.imu.ImuErrors` block converts them for simulation: ARW/VRW = N,
bias instability as a first-order Gauss–Markov process whose Allan peak equals the
measured floor (σ = floor/0.6174, correlation time = τ_min/1.893), RRW = K. The data must
be recorded at rest; the mean (bias and the Earth rate/gravity) does not affect the
Allan deviation but the 1-σ of a moving record would be dominated by the motion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from sinslab.core import units
from sinslab.core.records import ImuRecord

__all__ = ["AxisFit", "AllanResult", "allan", "fit_axis", "imu_errors_from_allan", "register"]

_FLICKER = 0.664


@dataclass
class AxisFit:
    """Noise terms of one axis (SI: gyro rad/s family, accel m/s² family)."""

    name: str
    tau: np.ndarray
    adev: np.ndarray
    n_white: float          #: ARW [rad/√s] or VRW [m/s/√s]
    bias_instability: float  #: B (IEEE) [rad/s] or [m/s²]
    floor: float            #: minimum of the Allan deviation
    tau_floor: float        #: its cluster time [s]
    rrw: float              #: K [rad/s/√s] or [m/s²/√s]
    fit: np.ndarray = field(default=None)   #: fitted curve on ``tau``
    n_is_bound: bool = False  #: no clean −½ slope: ``n_white`` is an upper bound


@dataclass
class AllanResult:
    gyro: list
    accel: list
    dt: float
    duration: float


def fit_axis(tau, adev, name=""):
    """Fit N, B, K to one Allan-deviation curve (see module notes)."""
    tau = np.asarray(tau, dtype=float)
    adev = np.asarray(adev, dtype=float)
    ok = np.isfinite(adev) & (adev > 0)
    tau, adev = tau[ok], adev[ok]
    if tau.size < 3:
        raise ValueError(f"{name}: too few cluster times for an Allan fit")
    i_min = int(np.argmin(adev))
    floor, tau_floor = float(adev[i_min]), float(tau[i_min])
    from scipy.optimize import nnls
    A = np.stack([1.0 / tau, np.ones_like(tau), tau / 3.0], -1)
    y = adev ** 2
    w = 1.0 / y                                           # relative residuals
    coef, _ = nnls(A * w[:, None], y * w)
    n2, b2, k2 = coef
    fit = np.sqrt(A @ coef)
    # white noise from the -1/2 line: short cluster times, where it dominates
    # (quantization bends the first decade; slow terms the long end): τ in [10 τ0, min(1 s, τ_min/10)]
    short = (tau >= 10 * tau[0] - 1e-12) & (tau <= min(1.0, tau_floor / 10))
    line = adev * np.sqrt(tau)
    bound = False
    if short.sum() >= 3 and line[short].max() / line[short].min() < 1.5:
        n_white = float(np.median(line[short]))
    else:
        # no clean -1/2 slope (base motion, quantization): sigma(tau) >= N/sqrt(tau) everywhere,
        # so the smallest sigma*sqrt(tau) up to the floor is an upper bound on N
        upto = (tau >= 10 * tau[0] - 1e-12) & (tau <= tau_floor)
        n_white = float(line[upto].min()) if upto.any() else float(line.min())
        bound = True
    k = math.sqrt(k2) if (k2 > 0 and tau_floor < tau[-1] / 2) else 0.0
    return AxisFit(name, tau, adev, n_white, floor / _FLICKER, floor, tau_floor, k, fit, bound)


def allan(imu: ImuRecord, *, max_clusters=None, progress=False) -> AllanResult:
    """Overlapping Allan deviation and noise terms of every axis of ``imu``."""
    import allantools

    n = len(imu)
    if n < 100:
        raise ValueError(f"the IMU record has {n} samples; the Allan deviation needs at least 100")
    rate = 1.0 / imu.dt
    m_max = n // 9 if max_clusters is None else int(max_clusters)
    ms = np.unique(np.round(np.logspace(0, math.log10(max(m_max, 2)), 60)).astype(int))
    taus = ms * imu.dt
    out = {"gyro": [], "accel": []}
    for sensor, arr in (("gyro", imu.dtheta), ("accel", imu.dv)):
        for k, ax in enumerate("xyz"):
            y = arr[:, k] / imu.dt
            t2, ad, _, _ = allantools.oadev(y, rate=rate, data_type="freq", taus=taus)
            out[sensor].append(fit_axis(t2, ad, f"{sensor} {ax}"))
    return AllanResult(out["gyro"], out["accel"], imu.dt, n * imu.dt)


def imu_errors_from_allan(res: AllanResult):
    """An :class:`sinslab.sim.imu.ImuErrors` with the measured noise terms (see module notes)."""
    from sinslab.sim.imu import GM_ALLAN_PEAK, GM_ALLAN_PEAK_TAU, ImuErrors

    def vec(fits, attr):
        return np.array([getattr(f, attr) for f in fits])

    g, a = res.gyro, res.accel
    return ImuErrors(
        gyro_arw=vec(g, "n_white"), gyro_bias_instability=vec(g, "floor") / GM_ALLAN_PEAK,
        gyro_corr_time=vec(g, "tau_floor") / GM_ALLAN_PEAK_TAU, gyro_rrw=vec(g, "rrw"),
        accel_vrw=vec(a, "n_white"), accel_bias_instability=vec(a, "floor") / GM_ALLAN_PEAK,
        accel_corr_time=vec(a, "tau_floor") / GM_ALLAN_PEAK_TAU, accel_rrw=vec(a, "rrw"))


def _table(res: AllanResult):
    rows = []
    for f in res.gyro:
        rows.append((f.name, f.n_white / units.dpsh, "deg/sqrt(h)" + ("(<=)" if f.n_is_bound else ""), f.bias_instability / units.dph,
                     "deg/h", f.tau_floor, f.rrw / units.dphpsh, "deg/h/sqrt(h)"))
    for f in res.accel:
        rows.append((f.name, f.n_white / units.ugpsHz, "ug/sqrt(Hz)" + ("(<=)" if f.n_is_bound else ""), f.bias_instability / units.ug,
                     "ug", f.tau_floor, f.rrw / units.ug * math.sqrt(3600.0), "ug/sqrt(h)"))
    return rows


def allan_file(path, *, fmt=None, out=None, window=None, echo=print, **read_kw):
    """Read a recorded IMU file, compute the Allan deviations and write the run folder."""

    from sinslab import __version__
    from sinslab.data import io
    from sinslab.app import plotting
    from sinslab.app.config import dump_toml
    from sinslab.app.outputs import RunDir, command_summary, default_out_dir
    from sinslab.sim.imu import ImuErrors  # noqa: F401

    data = io.load_imu(path, fmt, **read_kw)
    imu = data.imu
    if window:
        a, _, b = str(window).partition(":")
        imu = imu.slice(float(a) if a else None, float(b) if b else None)
    out = out if out is not None else default_out_dir("allan")
    rd = RunDir(out, "allan")
    rd.check()
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
    rd.prepare()
    rd.write_text("config.toml", f"# sinslab {__version__} — allan\n" + dump_toml(cfg))
    rd.write_text("imu_errors.toml", toml)
    tab = {"tau_s": res.gyro[0].tau}
    for f in res.gyro:
        if f.tau.size == tab["tau_s"].size:
            tab[f"{f.name.replace(' ', '_')}_adev_dph"] = f.adev / units.dph
    for f in res.accel:
        if f.tau.size == tab["tau_s"].size:
            tab[f"{f.name.replace(' ', '_')}_adev_ug"] = f.adev / units.ug
    rd.write_table("allan", tab, "overlapping Allan deviation per axis")
    fig, axes = plotting.figure(1, 2, sharex=False, width=11.0, row_height=4.2)
    for ax, fits, sc, unit in ((axes[0], res.gyro, units.dph, "deg/h"), (axes[1], res.accel, units.ug, "ug")):
        for f, c in zip(fits, plotting.COLORS):
            ax.loglog(f.tau, f.adev / sc, "-", color=c, lw=1.2, label=f.name)
            ax.loglog(f.tau, f.fit / sc, ":", color=c, lw=1)
            ax.plot([f.tau_floor], [f.floor / sc], "o", color=c, ms=4)
        ax.set_xlabel("cluster time τ [s]")
        ax.set_ylabel(f"Allan deviation [{unit}]")
        ax.legend(fontsize=8)
    fig.suptitle("Overlapping Allan deviation (dotted: fitted N/τ, B, K terms; dots: floor)")
    rd.write_figure("allan", fig, "Allan deviation of each gyro and accelerometer axis, with the fit.")
    summary = rd.complete(command_summary(
        rd, "allan", "Allan deviation and IEEE noise terms of a recorded IMU file", cfg, metrics,
        ["Bias instability B = Allan floor / 0.664 (IEEE 952).",
         "imu_errors.toml: paste into a simulation config ([imu] table).", toml]))
    echo(f"  -> {out}")
    return summary, res, errs


def register(app):
    """Add ``sinslab allan`` and ``sinslab navigate`` (called from sinslab.cli)."""
    import typer

    @app.command()
    def allan(file: Path = typer.Argument(..., help="recorded IMU file (at rest)"),
              format: Optional[str] = typer.Option(None, "--format", help="psins | csv | parquet | mat | rtklib-imu"),
              window: Optional[str] = typer.Option(None, "--window", metavar="START:END", help="time window [s]"),
              gyro_unit: Optional[str] = typer.Option(None, "--gyro-unit", help="unit of gyro columns without one"),
              accel_unit: Optional[str] = typer.Option(None, "--accel-unit", help="unit of accel columns without one"),
              out: Optional[Path] = typer.Option(None, "--out", "-o", help="output folder [default: runs/allan-<timestamp>]")) -> None:
        """Allan deviation of recorded IMU data: ARW/VRW, bias instability, RRW and an ImuErrors block."""
        from sinslab.cli import CliError, user_errors

        kw = {}
        if gyro_unit:
            kw["gyro_unit"] = gyro_unit
        if accel_unit:
            kw["accel_unit"] = accel_unit
        with user_errors():
            try:
                allan_file(file, fmt=format, out=out, window=window, echo=typer.echo, **kw)
            except (ValueError, FileNotFoundError) as e:
                raise CliError(str(e)) from None

    from sinslab.fusion import integration
    integration.register(app)
    return allan
