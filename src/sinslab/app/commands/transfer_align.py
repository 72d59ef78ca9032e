"""``sinslab transfer-align --slave FILE --master FILE``: transfer alignment of a recorded
slave IMU against a recorded master INS solution (mounting angles and slave biases with
σ) into a run folder.

Inputs
------
- slave: increments, any format of :func:`sinslab.data.load_imu` (``.mat`` variable
  ``mimu``/``imu``, CSV/Parquet with unit headers);
- master: a PSINS ``avp`` matrix in a ``.mat`` (variable ``fogavp``/``avp``: pitch roll yaw
  [rad], vE vN vU [m/s], lat lon [rad], h [m], t [s]) or a CSV/Parquet table with the
  columns ``t, pitch, roll, yaw, ve, vn, vu, lat, lon, h`` each carrying its unit in the
  header (``pitch[deg]``);
- reference values (``mu0`` mounting angles [rad], ``eb0`` gyro bias [rad/s], ``db0``
  accelerometer bias [m/s²]) are read from the master or slave ``.mat`` when present and
  compared with the estimates.

The filter's process noise is an input (``--gyro-arw``, ``--accel-vrw``,
``--gyro-bias-instability``, ``--accel-bias-instability``; the bias instabilities are
modelled as random walks of the bias states): the estimates and their σ depend on it.

A slave and a master that do not share their motion (the norms of their rotation rates do
not follow each other, e.g. records of two vehicles or shifted clocks) are refused: the
filter would otherwise return a mounting with a small σ that means nothing.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from sinslab.app.commands.runner import Command, Figure, Output, Series, cli_call, run_command
from sinslab.core import units

__all__ = ["transfer_align_file", "read_master", "register"]

_MASTER_COLS = ("t", "pitch", "roll", "yaw", "ve", "vn", "vu", "lat", "lon", "h")
_MASTER_KINDS = ("time", "angle", "angle", "angle", "velocity", "velocity", "velocity", "angle", "angle", "length")


def read_master(path):
    """Master solution ``(t, att (M,3), vel (M,3), pos (M,3) [lat, lon rad, h m])``."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    if path.suffix.lower() == ".mat":
        from sinslab.data.matlab import read_mat_avp
        s = read_mat_avp(path)
        return s.t, s.att, s.vel, np.column_stack([s.lat, s.lon, s.h])
    import pandas as pd
    try:
        df = pd.read_parquet(path) if path.suffix.lower() in (".parquet", ".pq") else pd.read_csv(path)
    except Exception as e:  # noqa: BLE001
        raise ValueError(f"{path}: cannot read the master table ({e})") from None
    cols = {}
    for c in df.columns:
        name, _, rest = str(c).partition("[")
        cols[name.strip().lower()] = (c, rest.rstrip("]").strip())
    out = []
    for name, kind in zip(_MASTER_COLS, _MASTER_KINDS):
        if name not in cols:
            raise ValueError(f"{path}: master table lacks column {name!r} (need {', '.join(_MASTER_COLS)} with units)")
        c, unit = cols[name]
        if not unit:
            raise ValueError(f"{path}: column {c!r} has no unit; write it as '{name}[unit]'")
        scale = float(units.parse(f"1 {unit}", kind))
        out.append(df[c].to_numpy(float) * scale)
    a = np.column_stack(out)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{path}: NaN/inf in the master table")
    return a[:, 0], a[:, 1:4], a[:, 4:7], a[:, 7:10]


def _loadmat(path):
    """``scipy.io.loadmat`` with a one-line error naming the file."""
    import scipy.io

    try:
        return scipy.io.loadmat(path)
    except (ValueError, TypeError, OSError, NotImplementedError) as e:
        raise ValueError(f"{path}: not a readable MATLAB .mat file ({e})") from None


def _refs(*paths):
    for p in paths:
        if Path(p).suffix.lower() == ".mat":
            m = _loadmat(p)
            r = {k: np.asarray(m[k], float).ravel() for k in ("mu0", "eb0", "db0") if k in m}
            if r:
                return r
    return {}


def _parse_mount(text):
    """``--mount [pitch, roll, yaw]``: pitch within ±90°, roll and yaw within ±180°."""
    if text is None:
        return None
    from sinslab.core.attitude import euler_to_dcm
    try:
        v = units.parse_vector(text, "angle", 3)
    except ValueError as e:
        raise ValueError(f"--mount {text!r}: {e} (give units, e.g. \"[10, 60, 8] deg\")") from None
    for name, x, lim in zip(("pitch", "roll", "yaw"), v, (90.0, 180.0, 180.0)):
        if not (np.isfinite(x) and abs(np.degrees(x)) <= lim):
            raise ValueError(f"--mount {text!r}: {name} {np.degrees(x):.6g} deg is out of range, must be within "
                             f"±{lim:g} deg ([pitch, roll, yaw] of the installation)")
    return euler_to_dcm(np.asarray(v, float))


TRANSFER_ALIGN = Command("transfer-align", "transfer alignment of a recorded slave IMU against a master INS")


#: Process noise used when none is given (SI): gyro ARW 1 deg/sqrt(h), accelerometer VRW
#: 1 mm/s/sqrt(s), bias states random constants.
PROCESS_NOISE = {"gyro_arw": "1 deg/sqrt(h)", "accel_vrw": "1 mm/s/sqrt(s)",
                 "gyro_bias_instability": "0 deg/h/sqrt(h)", "accel_bias_instability": "0 ug/sqrt(s)"}
_NOISE_KINDS = {"gyro_arw": "angle_random_walk", "accel_vrw": "velocity_random_walk",
                "gyro_bias_instability": "rate_random_walk", "accel_bias_instability": "accel_random_walk"}
#: Largest process noise accepted: beyond these no IMU is meant (the noisiest consumer
#: MEMS: ARW ~ 5 °/√h, VRW ~ 1 mm/s/√s·10, bias random walks tens of °/h/√h and µg/√s·100)
_NOISE_MAX = {"gyro_arw": "100 deg/sqrt(h)", "accel_vrw": "1 m/s/sqrt(s)",
              "gyro_bias_instability": "1000 deg/h/sqrt(h)", "accel_bias_instability": "0.1 m/s^2/sqrt(s)"}
#: Rotation rates of slave and master that correlate less than this (when the master moves)
#: mean an unrelated pair.
MIN_RATE_CORRELATION = 0.5
#: Below this spread of the master's rotation rate [rad/s] the check cannot tell.
MIN_MOTION = 0.002


def _process_noise(noise):
    """SI values of the process-noise texts (defaults for the ones not given)."""
    from sinslab.app.validate import option_quantity

    out = {}
    for k, default in PROCESS_NOISE.items():
        text = (noise or {}).get(k) or default
        out[k] = (option_quantity("--" + k.replace("_", "-"), text, _NOISE_KINDS[k], ge="0 " + default.split(" ", 1)[1],
                                  le=_NOISE_MAX[k]), text)
    unknown = set(noise or {}) - set(PROCESS_NOISE)
    if unknown:
        raise ValueError(f"unknown process-noise setting(s) {sorted(unknown)}; known: {sorted(PROCESS_NOISE)}")
    return out


def transfer_align_file(slave, master, *, methods=("optimal",), mount=None, windows=(None,), out=None,
                        vel_sigma=0.1, att_sigma_arcmin=1.0, noise=None, strict=False, echo=print):
    """Run the alignment for each method and window; write the run folder.

    ``noise`` maps the keys of :data:`PROCESS_NOISE` to unit strings (defaults for the
    ones not given).

    Returns ``(summary, results, refs)``: ``results`` maps ``(method, window key)`` to a
    :class:`sinslab.methods.transfer.TransferResult`, ``refs`` the file's reference values.
    """
    from sinslab.methods import transfer as tm

    for m in methods:
        if m not in tm.KINDS:
            raise ValueError(f"--method {m!r}: choose from {', '.join(tm.KINDS)}")
    comp = _parse_mount(mount)
    pn = _process_noise(noise)
    if Path(slave).suffix.lower() == ".mat":
        mm = _loadmat(slave) if Path(slave).is_file() else None
        if mm is not None and not any(k in mm for k in ("imu", "mimu", "simu")):
            raise ValueError(f"{slave}: .mat lacks the slave IMU variable (imu, mimu or simu)")
    if Path(master).suffix.lower() == ".mat" and Path(master).is_file():
        mm = _loadmat(master)
        if not any(k in mm for k in ("avp", "fogavp", "avpr")):
            raise ValueError(f"{master}: .mat lacks the master solution variable (avp, fogavp or avpr)")
    summary, res = run_command(TRANSFER_ALIGN, out, lambda: _compute(slave, master, methods, comp, mount, windows,
                                                                  vel_sigma, att_sigma_arcmin, pn, echo, strict),
                               echo=echo)
    results, refs = res.value
    return summary, results, refs


def _compute(slave, master, methods, comp, mount, windows, vel_sigma, att_sigma_arcmin, pn, echo, strict=False):
    from sinslab.app.plausibility import settle

    imu, master_rec, pos, nsub, found = _read_pair(slave, master, windows)
    refs = _refs(master, slave)
    metrics, rows, results = _align_all(imu, master_rec, pos, nsub, methods, comp, windows, vel_sigma,
                                        att_sigma_arcmin, pn, echo, found)
    if refs:
        metrics.update(_reference(refs, echo))
    warnings = settle(found, strict=strict, echo=echo)
    cfg = {"slave": str(slave), "master": str(master), "methods": list(methods), "mount": mount or "none",
           "windows": ["all" if w is None else f"{w[0]:g}:{w[1]:g}" for w in windows],
           "vel_sigma_mps": vel_sigma, "att_sigma_arcmin": att_sigma_arcmin,
           **{k: text for k, (_, text) in pn.items()}}
    import pandas as pd
    (m0, w0), r0 = next(iter(results.items()))
    tables = [Series("estimates", pd.DataFrame(rows), "final estimates with σ per method and window"),
              Series("history", {"t_s": r0.t, **{f"{l}": r0.x[:, i] for i, l in enumerate(r0.layout.labels)},
                                 **{f"sigma_{l}": r0.sigma[:, i] for i, l in enumerate(r0.layout.labels)}},
                     f"state estimates and σ (SI) over time, {m0}, window {w0}")]
    notes = ["Mounting angles: the installation state a (C_s^m = exp(a×), or C_s^m = Ĉ_s^m exp(a×) with --mount), "
             "slave axes x, y, z.",
             "Biases: slave gyro and accelerometer biases (measured minus true), body axes.",
             "Filter: 21 states through the fusion driver, velocity + attitude matching at the master rate, "
             "feedback of φ, δv and biases; the slave position is navigated freely (not reset to the master's)."]
    return Output(config=cfg, metrics=metrics, tables=tables, figures=[_figure(results, refs)], notes=notes,
                  value=(results, refs), warnings=warnings)


def _read_pair(slave, master, windows):
    """``(slave IMU, master record, master positions, subsamples, findings)``: the two files
    read and checked, each on its own and against each other (overlap, windows, intervals,
    common motion, rates); refusals raised."""
    from sinslab.app.plausibility import imu_findings, settle
    from sinslab.data import load_imu
    from sinslab.core.progress import stage
    from sinslab.methods import transfer as tm

    with stage("reading " + " and ".join(dict.fromkeys(Path(p).name for p in (slave, master)))):
        data = load_imu(slave)
        imu = data.imu
        found = imu_findings(imu, f"slave {slave}", lat=None, gaps=data.gaps)
        settle([fd for fd in found if fd.refuse])
        mt, att, vel, pos = read_master(master)
        _check_master(master, mt, att, vel, pos)
    lo, hi = max(mt[0], imu.t[0]), min(mt[-1], imu.t[-1])
    if hi - lo <= 0:
        raise ValueError(f"slave [{imu.t[0]:g}, {imu.t[-1]:g}] s and master [{mt[0]:g}, {mt[-1]:g}] s do not overlap in time")
    dtm = float(np.median(np.diff(mt)))
    from sinslab.app.validate import check_window
    for w in windows:           # a clipped window would align over less than asked for
        if w is not None:       # (within one master interval: the first epoch may start it)
            check_window("--window", f"{w[0]:g}:{w[1]:g}", float(lo), float(hi), max(dtm, imu.dt))
    ratio = dtm / imu.dt
    if abs(ratio - round(ratio)) > 1e-3 or round(ratio) < 1:
        raise ValueError(f"master interval {dtm:g} s is not a multiple of the slave interval {imu.dt:g} s")
    nsub = 2 if round(ratio) % 2 == 0 else 1
    master_rec = tm.MasterRecord(mt, att, vel)
    for w in windows:
        corr, motion = tm.rate_correlation(imu, master_rec, *(w or (None, None)))
        if motion >= MIN_MOTION and not corr >= MIN_RATE_CORRELATION:
            where = "" if w is None else f" in the window {w[0]:g}:{w[1]:g} s"
            raise ValueError(f"slave {slave} and master {master} show no common motion{where}: their rotation rates "
                             f"correlate at {corr:.2f} (need >= {MIN_RATE_CORRELATION:g}); not the same vehicle, "
                             "or the clocks differ")
    found += _rate_findings(imu, master_rec, slave, master, dtm)
    settle([fd for fd in found if fd.refuse])
    return imu, master_rec, pos, nsub, found


_AM, _DPH, _MG = units.arcmin, units.dph, 1e-3 * 9.80665


def _align_all(imu, master_rec, pos, nsub, methods, comp, windows, vel_sigma, att_sigma_arcmin, pn, echo, found):
    """Every method on every window: ``(metrics, table rows, {(method, window): result})``;
    the checks of each result added to ``found``."""
    from sinslab.core.progress import stage
    from sinslab.methods import transfer as tm
    metrics, rows, results = {}, [], {}
    am, dph, mg = _AM, _DPH, _MG
    for w in windows:
        t0, t1 = (None, None) if w is None else w
        wkey = "all" if w is None else f"{t0:g}_{t1:g}s".replace(".", "p")
        for m in methods:
            with stage(f"transfer alignment, {m}" + ("" if w is None else f", window {t0:g}:{t1:g} s")):
                r = tm.align_recorded(imu, master_rec, pos, m, compensation=comp,
                                      t_start=t0, t_end=t1, vel_sigma=vel_sigma, att_sigma=att_sigma_arcmin * am,
                                      gyro_arw=pn["gyro_arw"][0], accel_vrw=pn["accel_vrw"][0],
                                      gyro_bias_rw=pn["gyro_bias_instability"][0],
                                      accel_bias_rw=pn["accel_bias_instability"][0], nsub=nsub)
            results[(m, wkey)] = r
            found += _result_findings(r, f"{m}, window {wkey}", pn)
            k = f"{m}_{wkey}"
            metrics[f"mounting_arcmin_{k}"] = r.mounting / am
            metrics[f"mounting_sigma_arcmin_{k}"] = r.mounting_sigma / am
            metrics[f"gyro_bias_dph_{k}"] = r.gyro_bias / dph
            metrics[f"gyro_bias_sigma_dph_{k}"] = r.gyro_bias_sigma / dph
            metrics[f"accel_bias_mg_{k}"] = r.accel_bias / mg
            metrics[f"accel_bias_sigma_mg_{k}"] = r.accel_bias_sigma / mg
            rows.append(_row(m, wkey, r))
            pm = lambda v, s, f: ", ".join(f"{a:{f}} ± {b:{f}}" for a, b in zip(v, s))  # noqa: E731
            echo(f"{m:8s} {wkey:>10s}: mounting [{pm(r.mounting / am, r.mounting_sigma / am, '.2f')}] arcmin; "
                 f"gyro bias [{pm(r.gyro_bias / dph, r.gyro_bias_sigma / dph, '.1f')}] deg/h; "
                 f"accel bias [{pm(r.accel_bias / mg, r.accel_bias_sigma / mg, '.2f')}] mg")
    return metrics, rows, results


def _row(m, wkey, r):
    """The ``estimates`` table's row of one method and window."""
    am, dph, mg = _AM, _DPH, _MG
    row = dict(method=m, window=wkey, t_start=r.t[0], t_end=r.t[-1])
    for j, a in enumerate("xyz"):
        row[f"mount_{a}_arcmin"] = r.mounting[j] / am
        row[f"mount_{a}_sigma_arcmin"] = r.mounting_sigma[j] / am
    for j, a in enumerate("xyz"):
        row[f"eb_{a}_dph"] = r.gyro_bias[j] / dph
        row[f"eb_{a}_sigma_dph"] = r.gyro_bias_sigma[j] / dph
    for j, a in enumerate("xyz"):
        row[f"db_{a}_mg"] = r.accel_bias[j] / mg
        row[f"db_{a}_sigma_mg"] = r.accel_bias_sigma[j] / mg
    return row


def _reference(refs, echo):
    """The file's reference values as metrics, and on the terminal."""
    am, dph, mg = _AM, _DPH, _MG
    metrics = {}
    if "mu0" in refs:
        metrics["ref_mounting_arcmin"] = refs["mu0"] / am
    if "eb0" in refs:
        metrics["ref_gyro_bias_dph"] = refs["eb0"] / dph
    if "db0" in refs:
        metrics["ref_accel_bias_mg"] = refs["db0"] / mg
    echo("reference (file): mounting " + (f"{np.round(refs['mu0'] / am, 2).tolist()} arcmin" if "mu0" in refs else "-")
         + ", gyro bias " + (f"{np.round(refs['eb0'] / dph, 1).tolist()} deg/h" if "eb0" in refs else "-")
         + ", accel bias " + (f"{np.round(refs['db0'] / mg, 2).tolist()} mg" if "db0" in refs else "-"))
    return metrics


def _figure(results, refs):
    """Estimates ± σ over time of every method and window, with the file's references."""
    from sinslab.app import plotting
    am, dph, mg = _AM, _DPH, _MG
    fig, ax = plotting.figure(3, 3, width=11.0, row_height=2.3, title="transfer alignment on recorded data")
    sl = next(iter(results.values())).layout.slice
    for (m, wkey), r in results.items():
        tt = r.t - r.t[0]
        for j in range(3):
            for i, (blk, sc) in enumerate((("lam", am), ("eps", dph), ("nabla", mg))):
                a = ax[i * 3 + j]
                v, s = r.x[:, sl(blk)][:, j] / sc, r.sigma[:, sl(blk)][:, j] / sc
                ln, = a.plot(tt, v, lw=0.9, label=f"{m} {wkey}")
                a.fill_between(tt, v - s, v + s, color=ln.get_color(), alpha=0.15)
    for j, a in enumerate("xyz"):
        ax[j].set_title(f"mounting {a} [arcmin]", fontsize="small")
        ax[3 + j].set_title(f"gyro bias {a} [deg/h]", fontsize="small")
        ax[6 + j].set_title(f"accel bias {a} [mg]", fontsize="small")
        for i, key, sc in ((0, "mu0", am), (1, "eb0", dph), (2, "db0", mg)):
            if key in refs:
                ax[i * 3 + j].axhline(refs[key][j] / sc, color="k", ls="--", lw=0.8)
    ax[0].legend(fontsize="x-small")
    for a in ax[-3:]:
        a.set_xlabel("time since the start of the window [s]")
    return Figure("estimates", fig, "Estimates ± σ over time per method/window; dashed: the file's reference values")


#: a master faster than this [m/s] is no vehicle a slave IMU rides on with it
MAX_MASTER_SPEED = 1000.0
#: heights of a master solution [m]: below the deepest mine, above any aircraft
MASTER_HEIGHT = (-12e3, 100e3)
#: slave and master rotation rates lining up best at a clock shift beyond this many master
#: intervals (and at least 50 ms) mean their clocks differ
MAX_LAG_INTERVALS = 1.0
#: the master's rotation rate over the slave's differing from 1 by more than this is a
#: scale error (a unit slip: 180/π)
RATE_SCALE_TOL = 0.1


def _check_master(path, t, att, vel, pos) -> None:
    """Refuse a master solution that cannot be one: time stamps not increasing (reversed
    or unsorted), an attitude, latitude, speed or height beyond the physical ranges (the
    angles' likely unit slip named)."""
    d = np.diff(t)
    if d.size and not np.all(d > 0):
        i = int(np.argmax(~(d > 0)))
        order = "in reverse order" if np.all(d < 0) else "not sorted by time"
        raise ValueError(f"{path}: master time stamps do not increase at epoch {i + 2} ({t[i]:.6g} s, then "
                         f"{t[i + 1]:.6g} s): the record is {order}")
    deg = np.degrees
    checks = (("pitch", att[:, 0], 90.0), ("roll", att[:, 1], 360.0), ("yaw", att[:, 2], 720.0),
              ("latitude", pos[:, 0], 90.0))
    for name, x, lim in checks:
        i = int(np.argmax(np.abs(x)))
        if abs(deg(x[i])) > lim:
            hint = (" — degrees read as radians?" if abs(x[i]) <= lim else "")
            raise ValueError(f"{path}: master {name} {deg(x[i]):.6g} deg at t = {t[i]:.6g} s is beyond ±{lim:g} deg"
                             f"{hint} (the angles are read in radians unless the column says [deg])")
    sp = np.linalg.norm(vel, axis=1)
    i = int(np.argmax(sp))
    if sp[i] > MAX_MASTER_SPEED:
        raise ValueError(f"{path}: master speed {sp[i]:.6g} m/s at t = {t[i]:.6g} s is beyond any vehicle "
                         f"(<= {MAX_MASTER_SPEED:g} m/s): a wrong velocity unit or column?")
    lo, hi = MASTER_HEIGHT
    bad = np.flatnonzero((pos[:, 2] < lo) | (pos[:, 2] > hi))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{path}: master height {pos[i, 2]:.6g} m at t = {t[i]:.6g} s is outside {lo:g}..{hi:g} m: "
                         f"a wrong unit or column?")


def _rate_findings(imu, master_rec, slave, master, dtm) -> list:
    """Whether slave and master measure the same rotation on the same clock: the scale of
    the master's rotation rate against the slave's (1; 180/π is a unit slip: refused) and
    the clock shift that lines them up best (:func:`sinslab.methods.transfer.rate_lag`)."""
    import math

    from sinslab.app.plausibility import Finding, unit_slip
    from sinslab.methods import transfer as tm

    lag, c_best, c0, scale = tm.rate_lag(imu, master_rec)
    if not np.isfinite(lag):
        return []
    out = []
    if abs(scale - 1.0) > RATE_SCALE_TOL:
        slip = unit_slip(scale, "")
        if slip is not None:
            big, small = (("master's attitude", "slave's gyro data") if scale > 1 else
                          ("slave's gyro data", "master's attitude"))
            slip = (f"a unit slip (180/π = {math.degrees(1.0):.1f}): the {big} in degrees read as radians, or the "
                    f"{small} in radians read as degrees")
        out.append(Finding(f"the master's rotation rate ({master}) is {scale:.4g} × the slave's ({slave}), where both "
                           f"measure the same rotation: " + (slip or "a unit or scale error of one of them"),
                           slip is not None))
    if abs(lag) > max(MAX_LAG_INTERVALS * dtm, 0.05):
        out.append(Finding(f"slave and master rotation rates line up best with the master's clock {abs(lag):.3g} s "
                           f"{'late' if lag > 0 else 'early'} (correlation {c_best:.3f} there, {c0:.3f} as stamped): "
                           f"their clocks differ by about that, and the mounting and biases absorb it — correct the "
                           f"master's time column (or the slave's)"))
    return out


def _result_findings(r, what, pn) -> list:
    """Plausibility of one alignment's estimates: biases within the grade of the gyro
    noise given (``--gyro-arw``), σ consistent with the matching innovations."""
    from sinslab.app.plausibility import bias_findings, overconfidence_findings

    return (bias_findings(r.gyro_bias, r.accel_bias, what, gyro_arw=pn["gyro_arw"][0])
            + (overconfidence_findings(r.applied, what, "the mounting and biases") if r.applied is not None else []))


def _window(text):
    from sinslab.app.validate import option_window

    lo, hi = option_window("--window", text)
    if lo is None or hi is None:
        raise ValueError(f"--window {text!r}: use START:END in seconds (both given)")
    return lo, hi


def register(app):
    """Add ``sinslab transfer-align`` (called from sinslab.cli)."""
    import typer

    @app.command("transfer-align")
    def transfer_align(slave: Path = typer.Option(..., "--slave", help="slave IMU increments (.mat, CSV, Parquet)"),
                       master: Path = typer.Option(..., "--master", help="master INS solution (.mat avp, CSV, Parquet)"),
                       method: list[str] = typer.Option(["optimal"], "--method", help="euler | dcm | kain | optimal (repeatable)"),
                       mount: Optional[str] = typer.Option(None, "--mount", help="known installation [pitch, roll, yaw] with units"),
                       window: list[str] = typer.Option([], "--window", metavar="START:END", help="time window(s) [s]"),
                       gyro_arw: str = typer.Option(PROCESS_NOISE["gyro_arw"], "--gyro-arw", help="filter process noise: gyro angle random walk"),
                       accel_vrw: str = typer.Option(PROCESS_NOISE["accel_vrw"], "--accel-vrw", help="filter process noise: accelerometer velocity random walk"),
                       gyro_bias_instability: str = typer.Option(PROCESS_NOISE["gyro_bias_instability"], "--gyro-bias-instability",
                                                                 help="random walk of the gyro bias states"),
                       accel_bias_instability: str = typer.Option(PROCESS_NOISE["accel_bias_instability"], "--accel-bias-instability",
                                                                  help="random walk of the accelerometer bias states"),
                       out: Optional[Path] = typer.Option(None, "--out", "-o", help="output folder"),
                       strict: bool = typer.Option(False, "--strict", help="refuse (exit 2, nothing written) instead of warning about the data or the estimates"),
                       force: bool = typer.Option(False, "--force", help="replace whatever --out holds (another run, other files)")) -> None:
        """Transfer alignment on recorded data: mounting angles and slave biases with σ."""
        def go():
            wins = [_window(w) for w in window] or [None]
            noise = dict(gyro_arw=gyro_arw, accel_vrw=accel_vrw, gyro_bias_instability=gyro_bias_instability,
                         accel_bias_instability=accel_bias_instability)
            return transfer_align_file(slave, master, methods=tuple(method), mount=mount, windows=wins, out=out,
                                       noise=noise, strict=strict, echo=typer.echo)

        cli_call(go, force=force)
