"""``sinslab navigate``: a recorded IMU log, a GNSS source (position/velocity fixes, or raw
observations) and aids through the aided filter into a run folder (solution, errors
against the GNSS, each plug-in's report, figures).

The command's options are short forms of the keys of one validated configuration
(:mod:`sinslab.app.commands.navigate_config`: ``--config FILE.toml``, ``--set
key=value``); the run is a pipeline of plug-ins (:mod:`sinslab.fusion.aids`,
:func:`sinslab.fusion.recorded.navigate_recorded`) whose reports this module writes and
draws: it names no aid's states."""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Optional

import numpy as np

from sinslab.app.commands.panels import panel_figure
from sinslab.app.commands.runner import Command, Figure, Output, Series, cli_call, run_command
from sinslab.app.outputs import default_out_dir
from sinslab.core import units
from sinslab.core.blocks import block_ranges, release_free_memory, release_pages

__all__ = ["NAVIGATE", "navigate_files", "navigate_config", "register"]

NAVIGATE = Command("navigate", "INS + GNSS (fixes or raw observations) and aids on recorded data")

#: ``gnss.fixes.lag``: the lag policy (:mod:`sinslab.fusion.lag`) of each choice
LAG_POLICY = {"aware": "exact", "ignore": "on-arrival"}


def navigate_config(file=None, sets=(), **given):
    """The resolved configuration of a run: ``file`` (TOML), ``sets`` (``--set`` items)
    and the options ``given`` by their Python names (``imu=["log.csv"], fixes=["x.pos"],
    aid="nhc"``), :func:`sinslab.app.commands.navigate_config.resolve_navigate`."""
    from sinslab.app.commands.navigate_config import resolve_navigate
    return resolve_navigate(file, sets, {_option(k): v for k, v in given.items()
                                         if v is not None and v is not False and not (isinstance(v, list) and not v)})


def _option(name):
    return "--" + name.replace("_", "-")


def navigate_files(cfg, *, out=None, echo=print):
    """Navigate the resolved configuration ``cfg`` (:func:`navigate_config`) and write the
    run folder ``out``. Returns ``(summary, RecordedNav, reference fixes)`` (the fixes, or
    the single-point solution of raw observations); without an IMU (GNSS alone,
    :mod:`sinslab.app.commands.gnss_alone`) ``(summary, GNSS solution, None)``.

    Plausibility (:mod:`sinslab.app.plausibility`): the IMU record (length, dead channels,
    ranges, |f| against gravity, gaps) and the run (long stretches where the fix NIS or the
    mean of the normalised innovations says the filter is inconsistent,
    :func:`sinslab.app.plausibility.consistency_findings`) are checked; a warning is printed
    and listed in the report, ``output.strict`` refuses.
    """
    out = Path(out) if out is not None else default_out_dir(NAVIGATE.name)
    summary, res = run_command(NAVIGATE, out, lambda: _compute(cfg, echo), echo=echo)
    if cfg.output.kml:
        from sinslab.app.export import export_run
        echo(f"  -> {export_run(out, 'kml')}")
    return (summary, *res.value)


#: rows of a CSV or Parquet IMU table read at once: such a table is read a block at a
#: time into the run's scratch folder (:func:`sinslab.data.spool.spool_table_imu`) and
#: navigated from there, so the log is never held in memory whole (0: read whole)
IMU_BLOCK_ROWS = 1 << 16


def _scratch(name):
    """A folder ``name`` in the run's scratch folder (None outside a run)."""
    from sinslab.app.commands.runner import scratch_dir

    where = scratch_dir()
    return None if where is None else where / name


def _read_imu(path, fmt, kw):
    """The IMU log: a plain CSV or Parquet table a block at a time into the scratch folder
    (the same record, mapped from files), anything else (or a table the block reader
    leaves to the whole reader: malformed, two files, whitespace-delimited) by
    :func:`sinslab.data.load_imu`."""
    import shutil

    from sinslab.data import load_imu
    from sinslab.data.archive import compression

    where = _scratch("imu") if IMU_BLOCK_ROWS else None
    one = path[0] if isinstance(path, list) and len(path) == 1 else path
    if (where is not None and fmt in ("csv", "parquet") and not isinstance(one, list)
            and Path(one).is_file() and compression(Path(one)) is None):
        from sinslab.data.spool import spool_table_imu

        d = spool_table_imu(one, where, block_rows=IMU_BLOCK_ROWS, **kw)
        if d is not None:
            return d
        shutil.rmtree(where, ignore_errors=True)
    return load_imu(path, fmt, **kw)


def _innovation_labels(m):
    """Names of the m fix innovation components (position north, east[, up], then velocity
    east, north, up: :class:`sinslab.fusion.loosely_coupled.LooselyCoupled`)."""
    n_pos = m - 3 if m > 3 else m
    return ([f"position {a}" for a in ("north", "east", "up")[:n_pos]]
            + [f"velocity {a}" for a in ("east", "north", "up")[:m - n_pos]])


# ----------------------------------------------------------------- before the filter ---
@dataclass
class _Inputs:
    """What an aid may read (:class:`sinslab.fusion.aids.base.Inputs`): the data front
    door, the IMU table and its rest column, the IMU clock correction of the run."""

    imu_path: object
    rest_flags: object
    sync: dict | None

    def read(self, reader, *args, **kw):
        import sinslab.data as D
        if not reader.startswith("read_") or reader not in D.__all__:
            raise ValueError(f"{reader!r} is not a reader of the data front door (sinslab.data)")
        return getattr(D, reader)(*args, **kw)

    def clock(self, t):
        from sinslab.fusion.recorded import shifted_times
        s = self.sync
        return t if s is None else shifted_times(t, s["offset"], s["ppm"], s["t_ref"])


@dataclass
class _Prepared:
    """Everything a run needs, read and checked, before the filter."""

    cfg: object
    data: object
    imu: object
    fx: object
    fix_name: str
    source: object
    aids: list
    opt: object
    sync: dict | None
    em_cfg: dict
    found: list
    errors: object = None       #: the declared error model (ImuErrors) of --imu-errors, or None


def _files(value):
    """A file key's value as the readers take it: one path, or a list of two."""
    return value[0] if isinstance(value, list) and len(value) == 1 else value


def _first(value):
    return value[0] if isinstance(value, list) else value


def _prepare(cfg, echo) -> _Prepared:
    """Read and check the inputs of ``cfg``: the IMU log, the GNSS, the time sync, the
    aids' inputs; the run's options made once."""
    from sinslab.app.commands.navigate_config import aids_of
    from sinslab.app.plausibility import imu_findings, settle
    from sinslab.data import guess_imu_format

    if not cfg.imu.file:
        raise ValueError("give the IMU log: --imu FILE (imu.file)")
    imu_path = _files(cfg.imu.file)
    fmt = guess_imu_format(_first(imu_path), sniff=cfg.imu.columns == "auto") if cfg.imu.format == "auto" \
        else cfg.imu.format
    kw = _reader_options(cfg, fmt)
    _check_before_reading(cfg, fmt, imu_path)
    em = None
    if cfg.filter.imu_errors != "default":
        from sinslab.app.error_model import load_error_model
        em = load_error_model(cfg.filter.imu_errors)
    data = _read_imu(imu_path, fmt, kw)
    found = imu_findings(data.imu, str(imu_path), gaps=data.gaps)
    settle([fd for fd in found if fd.refuse])
    raw, fx, fix_name, fmeta = _gnss(cfg, data.imu, echo)
    found += _check_clocks(data.imu, fx, fix_name, imu_path)
    _say_imu(data, echo)
    _check_latency(cfg, fx, data.imu)
    lever, em = _file_says(data, fmeta, cfg, em, echo)
    imu, sync = _time_sync(cfg, data.imu, fx, lever, echo)
    inputs = _Inputs(_first(imu_path), (data.meta or {}).get("stationary"), sync)
    aids = _with_error_model([a.load(inputs) for a in aids_of(cfg)], em)
    opt = _start_from_file(_options(cfg, em, imu, fx, lever), cfg.start, data, imu, echo)
    if raw is not None:
        from sinslab.app.commands.raw_gnss import gnss_source
        source = gnss_source(cfg.gnss.raw, raw, echo)
    else:
        from sinslab.fusion.loosely_coupled import FixSource
        source = FixSource(fx, opt.fix)
    return _Prepared(cfg, data, imu, fx, fix_name, source, aids, opt, sync, em[2] if em else {}, found,
                     em[0] if em else None)


def _reader_options(cfg, fmt):
    """The IMU reader's keywords from ``[imu]``."""
    kw = {}
    if cfg.imu.mount != "none":
        kw["mount"] = cfg.imu.mount
    if cfg.imu.frame != "auto":
        kw["frame"] = cfg.imu.frame
    if fmt != "psins":
        kw.update(max_gap=cfg.imu.max_gap, allow_gaps=cfg.imu.allow_gaps)
    if fmt == "rtklib-imu":
        kw["delay"] = cfg.imu.delay
    if cfg.imu.columns != "auto":
        if fmt not in ("csv", "parquet"):
            raise ValueError(f"--columns applies to csv and parquet tables, not {fmt!r}")
        kw["columns"] = cfg.imu.columns
    return kw


def _check_before_reading(cfg, fmt, imu_path):
    """What can be refused before any file is read: the mount, the fix table's column map
    and quality filter, an aid of a wheeled vehicle on another platform, the memory."""
    from sinslab.app.validate import check_mount
    check_mount(None if cfg.imu.mount == "none" else cfg.imu.mount, None if cfg.imu.frame == "auto" else cfg.imu.frame)
    fix_path = None
    if cfg.gnss.source == "fixes":
        from sinslab.data.columns import FIX_KEYS, parse_column_map
        from sinslab.data.tables import parse_quality_filter
        f = cfg.gnss.fixes
        parse_quality_filter(None if f.quality == "all" else f.quality)
        parse_column_map(None if f.columns == "auto" else f.columns, keys=FIX_KEYS, option="--fix-columns")
        fix_path = _files(f.file) or None
    from sinslab.fusion.aids import aid_type
    for name in cfg.aid:
        need = aid_type(name).land_only
        if need and cfg.start.platform in ("aircraft", "marine"):
            raise ValueError(f"--aid {name}: {need} assumes a wheeled land vehicle, not --platform "
                             f"{cfg.start.platform}")
    check_memory(imu_path, fmt, cfg.filter.smooth, fix_path=fix_path)


def _gnss(cfg, imu, echo):
    """``(RawGnss or None, fixes, name, what the reader says of them)``: the raw
    observations and their single-point fixes, or the fix file read."""
    from sinslab.data import load_fixes
    if cfg.gnss.source == "raw":
        from sinslab.app.commands.raw_gnss import load_raw
        r = cfg.gnss.raw
        if not r.file:
            raise ValueError("give --gnss FILE (fixes) or --gnss-raw FILE (raw observations)")
        raw, fx = load_raw(r, imu, echo)
        return raw, fx, f"{r.file} (single-point solution)", {}
    f = cfg.gnss.fixes
    if not f.file:
        raise ValueError("give --gnss FILE (fixes) or --gnss-raw FILE (raw observations)")
    path = _files(f.file)
    name = " + ".join(map(str, path)) if isinstance(path, list) else str(path)
    ffmt = None if f.format == "auto" else f.format         # None: the reader tells from name and content
    fx, meta = _read_fixes(lambda: load_fixes(path, ffmt, velocity_lag=f.velocity_lag,
                                              columns=None if f.columns == "auto" else f.columns,
                                              quality=None if f.quality == "all" else f.quality), name, ffmt)
    _say_fix_reading(meta, name, echo)
    _check_fixes(fx, name)
    return None, fx, name, meta


def _check_fixes(fx, name):
    """Fixes no filter can start from, named by their file: fewer than two receiver
    epochs, a position off the Earth (whatever the reader's format)."""
    if len(fx) < 2:                     # after the reader collapsed a logger's repeated rows
        raise ValueError(f"{name}: {'only one receiver epoch' if len(fx) else 'no fix'}: a run needs fixes "
                         "at two times at least")
    for what, v, lim in (("latitude", fx.lat, 90.0), ("longitude", fx.lon, 360.0)):
        bad = np.flatnonzero(~(np.abs(np.degrees(v)) <= lim))
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"{name}: fix {i + 1} (t = {fx.t[i]:.3f} s): {what} {np.degrees(v[i]):.6g} deg is "
                             f"beyond ±{lim:g} deg")


def _say_imu(data, echo):
    imu = data.imu
    if data.meta and "joined" in data.meta:
        un = data.meta["joined"]["unmatched"]
        echo(f"  IMU channels from two files joined on time; rows without a partner dropped: {un[0]} "
             f"of the first, {un[1]} of the second")
    if len(data.gaps):
        echo(f"  {len(data.gaps)} gap(s) in the IMU record bridged with the mean rate: "
             + ", ".join(f"{g[1]:.3f} s at {g[0] - imu.t0:.2f} s" for g in data.gaps[:5])
             + (" ..." if len(data.gaps) > 5 else ""))


def _check_latency(cfg, fx, imu):
    latency = cfg.gnss.fixes.latency if cfg.gnss.source == "fixes" else 0.0
    span = min(float(fx.t[-1]), float(imu.t[-1])) - max(float(fx.t[0]), float(imu.t[0]))
    if span > 0 and latency >= span:
        raise ValueError(f"--fix-latency {latency:g}: at least the {span:.1f} s the fixes and the "
                         f"IMU record share, so no fix would arrive before the record ends")


def _time_sync(cfg, imu, fx, lever, echo):
    """``(imu, sync)``: the IMU record on the fixes' clock (the offset and drift beyond
    doubt, :func:`sinslab.fusion.recorded.significant_time_offset`), or as read."""
    if cfg.imu.time_sync != "auto":
        return imu, None
    from sinslab.data.spool import map_times
    from sinslab.fusion.recorded import estimate_time_offset, shifted_times, significant_time_offset
    # without a lever arm a clock offset cannot be told from the antenna's lag in turns
    est = estimate_time_offset(imu, fx, lever_arm=lever)
    sync = significant_time_offset(est)
    sync.update(windows=len(est["windows"]))
    imu = map_times(imu, partial(shifted_times, offset=sync["offset"], ppm=sync["ppm"], t_ref=sync["t_ref"]),
                    imu.dt * (1.0 - sync["ppm"] * 1e-6), _scratch("imu"))
    echo(f"  IMU time offset {sync['offset_estimate'] * 1e3:.1f} ± {sync['offset_sigma'] * 1e3:.1f} ms "
         f"({_offset_verdict(sync)}), clock "
         f"{sync['ppm_estimate']:.0f} ± {sync['ppm_sigma']:.0f} ppm "
         f"({'applied' if sync['ppm_applied'] else 'not significant, not applied'}); from turn "
         f"rates vs the IMU-point course rate of the fixes in {len(est['windows'])} windows "
         f"(significant: > {sync['threshold_sigmas']:.1f} σ)"
         + (f"; no lever arm given: a lag of {sync['speed_lag_m']:.2f} ± {sync['speed_lag_sigma_m']:.2f} m "
            "/ speed fitted too (an antenna ahead of the IMU)" if sync["speed_lag_m"] is not None else "")
         + _speed_change_words(sync))
    return imu, sync


def _offset_verdict(sync):
    """Applied, or why not: not significant in the turns, or not confirmed by the speed changes."""
    if sync["offset_applied"]:
        return "applied"
    turns = abs(sync["offset_estimate"]) > sync["threshold_sigmas"] * sync["offset_sigma"]
    return ("significant in the turns but not seen in the speed changes: not applied" if turns
            else "not significant, not applied")


def _speed_change_words(sync):
    """The speed changes' view of the IMU clock, for the time-sync line."""
    n = sync.get("speed_change_windows") or 0
    if not n:
        return "; no speed changes to check an offset against" if sync["windows"] else ""
    v, sg = sync["speed_change_offset"] * 1e3, sync["speed_change_offset_sigma"] * 1e3
    return f"; speed changes {v:.1f} ± {sg:.1f} ms in {n} windows"


def _check_clocks(imu, fx, fix_name, imu_path):
    """Refuse an IMU and GNSS whose clocks differ by a second or more (an IMU stamped in UTC
    beside a receiver in GPS time is 18 s off): the turns show it
    (:func:`sinslab.fusion.clock_check.clock_check`); the filter would converge to a wrong
    heading and pass its claims."""
    from sinslab.fusion.clock_check import clock_check
    if fx.t[-1] < imu.t0 or fx.t[0] > imu.t[-1]:
        raise ValueError(f"{fix_name}: the fix times ({fx.t[0]:.3f}..{fx.t[-1]:.3f} s) do not overlap the IMU "
                         f"record {imu_path} ({imu.t0:.3f}..{imu.t[-1]:.3f} s): different time bases? (GPST vs "
                         "UTC differ by 18 s; seconds of week vs seconds since 1970; a logging delay)")
    c = clock_check(imu, fx)
    if c is not None and c.off:
        raise ValueError(f"{imu_path} against {fix_name}: the clocks differ by {c.lag:+.1f} s — "
                         f"{c.describe()}; put the IMU and the GNSS on one time scale")
    return [] if c is None else _turn_rate_findings(c, fix_name, imu_path)


#: a vertical gyro rate that follows the course rate this closely (correlation) has its
#: scale and sign read from the turns
TURN_CORRELATION = 0.6


def _turn_rate_findings(c, fix_name, imu_path):
    """The turns against the gyros (:class:`sinslab.fusion.clock_check.ClockCheck`): a
    vertical rate 180/π times the course rate is a gyro unit slip (refused: every angle of
    the run would be off by it); one that turns against the course, a vertical axis
    pointing down (a wrong --frame or --mount; a warning)."""
    from sinslab.app.plausibility import Finding, unit_slip
    if abs(c.rate_correlation) < TURN_CORRELATION or not np.isfinite(c.rate_ratio):
        return []
    said = (f"{imu_path}: in {c.turning:.0f} s of turns the vertical gyro rate is {c.rate_ratio:.3g} × the course "
            f"rate of {fix_name} (correlation {c.rate_correlation:.2f})")
    slip = unit_slip(abs(c.rate_ratio), "the gyro data")
    if slip is not None:
        raise ValueError(f"{said}: {slip} (check the gyro columns' unit)")
    if c.rate_ratio < 0:
        return [Finding(f"{said}: the IMU's vertical axis points down — check --frame and --mount (a body z "
                        "axis up turns with the course)")]
    return []


def _file_says(data, fmeta, cfg, em, echo):
    """What another tool's files say about the sensor, used where no option says otherwise
    and told once: the lever arm of a NaveGo GNSS struct, the noise model of a NaveGo IMU
    struct. Returns ``(lever arm or None, error model)``."""
    lever = cfg.gnss.lever_arm
    la = fmeta.get("lever_arm")
    if la is not None and lever is None:
        lever = tuple(float(x) for x in la)
        echo(f"  lever arm (IMU -> antenna, right-forward-up) [{', '.join(f'{x:g}' for x in la)}] m from "
             f"{fmeta.get('variable', 'the fix file')}.larm (--lever-arm replaces it)")
    if fmeta.get("sigma_source"):
        echo(f"  fix σ from {fmeta['sigma_source']}")
    table = (data.meta or {}).get("error_model")
    if table is not None and em is None:
        from sinslab.app.error_model import load_error_model
        em = load_error_model(table)
        em[2]["source"] = f"{data.meta.get('variable', data.path)} ({', '.join(data.meta['noise_fields'])})"
        echo(f"  IMU error model from {em[2]['source']} (--imu-errors replaces it)")
    for key, what in (("gyro_static_bias", "gyro"), ("accel_static_bias", "accelerometer")):
        if key in (data.meta or {}):
            echo(f"  {what} static bias of the struct removed from every sample "
                 f"({', '.join(f'{x:.3g}' for x in data.meta[key])} SI), as NaveGo does")
    return lever, em


def _start_from_file(opt, st, data, imu, echo):
    """The initial attitude another tool's IMU file holds (NaveGo's ``ini_align``, with
    ``ini_align_err`` its σ), given to the filter at the first IMU sample as that tool
    gives it, and told once; any attitude or start time given in ``[start]`` wins."""
    meta = data.meta or {}
    att = meta.get("initial_attitude")
    if att is None or any(getattr(st, k) is not None for k in ("pitch", "roll", "heading", "time")):
        return opt
    from sinslab.core import attitude as A
    hd = float(np.mod(A.yaw_to_heading(att[2]), 2 * np.pi))
    kw = dict(pitch=float(att[0]), roll=float(att[1]), heading=hd, init_time=float(imu.t[0]))
    sig = meta.get("initial_attitude_sigma")
    if sig is not None and st.attitude_sigma is None and np.all(np.asarray(sig) > 0):
        kw["att_sigma"] = tuple(float(x) for x in sig)
    name = meta.get("variable", "the IMU file")
    echo(f"  initial attitude pitch {np.degrees(att[0]):.3f}, roll {np.degrees(att[1]):.3f}, heading "
         f"{np.degrees(hd):.3f} deg at the first IMU sample from {name}.ini_align"
         f"{' (σ from ini_align_err)' if 'att_sigma' in kw else ''} (--init replaces it)")
    return opt.replace(**kw)


def _with_error_model(aids, em):
    """The aids with the σ an error-model file's ``[aiding]`` table gives them
    (:data:`sinslab.app.error_model.AID_SETTINGS`)."""
    if em is None:
        return aids
    from sinslab.app.error_model import aid_settings
    return [replace(a, **aid_settings(a.name, em[1])) for a in aids]


def _options(cfg, em, imu, fx, lever):
    """The run's options (:class:`sinslab.fusion.recorded.NavOptions`), made once."""
    from sinslab.app.error_model import NavOptionsDraft, apply_error_model
    from sinslab.fusion.lag import lag_policy
    from sinslab.fusion.recorded import NavOptions
    opt = NavOptionsDraft(NavOptions())
    if lever is not None:
        opt.lever_arm = lever
    opt.smooth = bool(cfg.filter.smooth)
    _spill_smoother(opt, imu, fx)
    if em is not None:
        apply_error_model(opt, em[0], em[1])
    t_ref, t_end = float(fx.t[0]), min(float(fx.t[-1]), float(imu.t[-1]))
    opt.outages = _outages(cfg.gnss.outages, cfg.gnss.outage_clock, t_ref, t_end)
    if cfg.gnss.outages not in ("none", ""):
        from sinslab.app.validate import check_outages
        check_outages("--outages", cfg.gnss.outages, opt.outages, t_ref, t_end)
    if cfg.gnss.source == "fixes":
        f = cfg.gnss.fixes
        opt.fix_latency = float(f.latency)
        opt.lag = lag_policy(LAG_POLICY[f.lag])
        opt.fix_error = None if f.error == "none" else f.error
        opt.robust = f.robust
        opt.fix_noise = f.noise
        opt.velocity_check = None if f.velocity_check is None else float(f.velocity_check)
    opt.scale_factors = bool(cfg.filter.scale_factors) or opt.scale_factors
    opt.move_speed = cfg.start.course_speed
    opt.heading_straight = cfg.start.course_spread
    opt.platform = cfg.start.platform
    _start_given(opt, cfg.start)
    return opt.build()


def _outages(text, clock, t_first, t_end):
    """The outages of ``text`` (``START:LEN,...`` or ``LEN/PERIOD[@FIRST]``) as absolute
    ``(start, length)`` [s] of the log (periodic ones as :func:`parse_outages` gives them,
    their FIRST from the first fix), their START counted on ``clock``: ``first-fix`` (s
    from the first fix at ``t_first``), ``log`` (the log's own stamps) or ``gps`` (GPS
    seconds of week or a GPS calendar time, :func:`_gps_to_log`). An absolute START outside
    ``[t_first, t_end]`` is one line naming the record's span on that clock."""
    from sinslab.fusion.recorded import parse_outages
    if text in (None, "", "none") or clock == "first-fix":
        return tuple(parse_outages(text, t_first))
    s = str(text).strip()
    if "/" in s:
        head, _, first = s.rpartition("@")
        if not head:
            raise ValueError(f"--outages {text!r}: with --outage-clock {clock} give the first outage's time, "
                             "LEN/PERIOD@FIRST")
        t0 = _clock_time(first, clock, t_first, text)
        return tuple(parse_outages(f"{head}@{t0 - t_first!r}", t_first))
    out = []
    for tok in s.split(","):
        a, sep, ln = tok.rpartition(":")          # a calendar START has colons of its own
        if not sep:
            raise ValueError(f"cannot read the outage {tok!r}; use START:LEN, START on the {clock} clock")
        t0 = _clock_time(a, clock, t_first, text)
        if not t_first <= t0 <= t_end:
            span = (f"{t_first:.3f}..{t_end:.3f} s as the log stamps it" if clock == "log" else
                    f"GPS {_log_to_gps_words(t_first)} .. {_log_to_gps_words(t_end)}")
            raise ValueError(f"--outages {text!r}: outage at {a.strip()} ({clock} clock) is outside the record "
                             f"({span})")
        out += parse_outages(f"{t0 - t_first!r}:{ln}", t_first)
    return tuple(out)


def _clock_time(text, clock, t_first, whole):
    """One START on ``clock`` as a log stamp [s]."""
    text = text.strip()
    if clock == "gps":
        return _gps_to_log(text, t_first, whole)
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"--outages {whole!r}: {text!r} is not a time stamp of the log [s]") from None


#: seconds in a GPS week
WEEK_S = 604800.0


def _gps_to_log(text, t_first, whole):
    """A GPS time (seconds of week, or ``YYYY-MM-DDTHH:MM:SS[.s]`` counted without leap
    seconds) as a stamp of a log that counts GPS seconds of week (NaveGo's, KF-GINS's) or
    GPS seconds since 1970 (RTKLIB ``.pos`` as read); a log on another clock is refused."""
    import datetime as dt

    from sinslab.core.gnss import GPS_EPOCH_UNIX
    week_log = 0.0 <= t_first < WEEK_S + 86400.0
    if not (week_log or t_first > GPS_EPOCH_UNIX):
        raise ValueError(f"--outage-clock gps: the log's stamps (first fix at {t_first:.3f} s) count neither GPS "
                         "seconds of week nor seconds since 1970; give the outages with --outage-clock log")
    try:
        if "T" in text or "-" in text[1:]:
            d = dt.datetime.fromisoformat(text.replace("Z", "")).replace(tzinfo=dt.timezone.utc)
            since_1970 = d.timestamp()
            return since_1970 if not week_log else (since_1970 - GPS_EPOCH_UNIX) % WEEK_S
        tow = float(text)
    except ValueError:
        raise ValueError(f"--outages {whole!r}: {text!r} is neither GPS seconds of week nor a GPS time "
                         "YYYY-MM-DDTHH:MM:SS") from None
    if not 0.0 <= tow < WEEK_S:
        raise ValueError(f"--outages {whole!r}: {text!r} s is not a second of the GPS week (0..604800)")
    if week_log:
        return tow
    week_start = GPS_EPOCH_UNIX + math.floor((t_first - GPS_EPOCH_UNIX) / WEEK_S) * WEEK_S
    t = week_start + tow
    return t + WEEK_S if t < t_first - WEEK_S / 2 else t      # a log across the week's turn


def _log_to_gps_words(t):
    """A log stamp [s] as GPS time words (for the message): seconds of week, or the GPS
    calendar time of a stamp counted from 1970."""
    import datetime as dt
    if t < WEEK_S + 86400.0:
        return f"{t:.1f} s"
    return dt.datetime.fromtimestamp(t, dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-5]


def _start_given(opt, st):
    """The start's figures ``[start]`` gives (angles, position, velocity, their σ, time)
    into the options; a position is given whole (latitude, longitude and height)."""
    opt.heading, opt.pitch, opt.roll = st.heading, st.pitch, st.roll
    if st.attitude_sigma is not None:
        opt.att_sigma = tuple(float(x) for x in st.attitude_sigma)
    pos = (st.latitude, st.longitude, st.height)
    if any(v is not None for v in pos):
        if any(v is None for v in pos):
            missing = [n for n, v in zip(("latitude", "longitude", "height"), pos) if v is None]
            raise ValueError(f"--init: a start position needs latitude, longitude and height; {', '.join(missing)} "
                             "missing (start." + ", start.".join(missing) + ")")
        opt.init_position = pos
    for key, name in (("velocity", "init_velocity"), ("position_sigma", "init_position_sigma"),
                      ("velocity_sigma", "init_velocity_sigma"), ("time", "init_time")):
        v = getattr(st, key)
        if v is not None:
            setattr(opt, name, tuple(float(x) for x in v) if np.ndim(v) else float(v))
    if st.time is not None and not (st.heading is not None and st.pitch is not None and st.roll is not None):
        raise ValueError("--init time=: the start time needs the whole attitude given (pitch, roll and heading); "
                         "an attitude found in the data holds where the data shows it")


# ---------------------------------------------------------------------------- the run ---
def _compute(cfg, echo) -> Output:
    import sinslab.fusion.recorded as R         # numba and scipy: only when it runs
    from sinslab.app.commands.navigate_config import config_value
    from sinslab.app.plausibility import settle

    if not cfg.imu.file:                       # the same command without an IMU: GNSS alone
        from sinslab.app.commands.gnss_alone import gnss_alone
        return gnss_alone(cfg, echo)
    from sinslab.fusion.estimators import estimator_of
    est = estimator_of(cfg.estimator)
    est.check(cfg.filter.smooth, cfg.gnss.source, list(cfg.aid))     # before any file is read
    p = _prepare(cfg, echo)
    res = R.navigate_recorded(p.imu, p.source, p.opt, aids=p.aids, estimator=est)
    release_free_memory()              # the filter's working set, before the evaluation's
    recs = res.source.fix_records
    if recs is not None and recs[0].size == 0:
        raise ValueError(f"{p.fix_name}: no fix was applied (outages, latency or the record's end "
                         f"removed all {len(p.fx)}); the solution would be free inertial")
    ev = _Evaluation.of(res, p.fx)
    metrics = _metrics(res, p, ev)
    noise_warn = _noise_check(res.start, metrics, echo)
    claims = _claims(res, p, ev, metrics, echo)
    _say(res, p, ev, metrics, echo)
    p.found += _estimate_findings(res, p, metrics)
    warnings = settle(p.found, strict=cfg.output.strict, echo=echo)
    every = max(1, int(round(1.0 / (cfg.output.csv_rate * (res.t[1] - res.t[0]))))) if res.t.size > 1 else 1
    tables = _tables(res, ev, every, p.fx)
    figures = _figures(res, p, ev)
    notes = _notes(res, p, metrics, noise_warn, echo)
    if res.smoothed is not None:
        _smoothed_outputs(res, p.fx, res.outages, metrics, tables, figures, echo, every)
    for rep in (res.source, *res.aids, *((res.estimator,) if res.estimator is not None else ())):
        _plugin_outputs(rep, metrics, tables, figures, notes, echo, float(res.t[0]))
    described = [d for rep in (res.source, *res.aids, *((res.estimator,) if res.estimator is not None else ()))
                 for d in rep.descriptions]
    purpose = "INS + GNSS loosely coupled: position (and velocity) fixes in the filter, and aids, on recorded data"
    if res.source.rows:
        from sinslab.app.commands.raw_gnss import RAW_DESCRIPTIONS, raw_figures, raw_report
        figures += raw_figures(res, res.source)
        metrics, purpose = raw_report(metrics, len(res.outages), tuple(res.source.rows))
        described = [*described, *RAW_DESCRIPTIONS]
    return Output(config=config_value(cfg), metrics=metrics, tables=tables, figures=figures, notes=notes,
                  files=_error_model_file(p.em_cfg), value=(res, p.fx), claims=claims, warnings=warnings,
                  descriptions=described, purpose=purpose)


def _error_model_file(em):
    """``{"imu_errors.toml": text}``: the error model the run resolved (its grade and
    tables, itself an ``--imu-errors`` file), when one was given."""
    if not em:
        return {}
    from sinslab.core.toml import dump_toml
    data = {"grade": em["grade"]} if "grade" in em else {}
    for k, v in em.items():
        if "." in k:
            tab, key = k.split(".", 1)
            data.setdefault(tab, {})[key] = v
    return {"imu_errors.toml": f"# the filter's error model of this run, resolved from {em['source']}\n"
                               + dump_toml(data)}


@dataclass
class _Evaluation:
    """The solution against the reference fixes: times, errors (east, north, up [m]) and
    the fixes' rows, horizontal errors, which lie in an outage, the error at each outage's end."""

    t: np.ndarray
    err: np.ndarray
    idx: np.ndarray
    hz: np.ndarray
    in_out: np.ndarray
    oe: np.ndarray

    @classmethod
    def of(cls, res, fx):
        from sinslab.fusion.recorded import fix_errors, outage_end_errors
        t, err, idx = fix_errors(res, fx)
        _, oe = outage_end_errors(res, fx)
        in_out = np.zeros(t.size, bool)
        for s, ln in res.outages:
            in_out |= (t >= s) & (t < s + ln)
        return cls(t, err, idx, np.hypot(err[:, 0], err[:, 1]), in_out, oe)


def _metrics(res, p, ev):
    """The run's own metrics (the plug-ins add theirs)."""
    from sinslab.core import attitude as A
    hz, ok, oe = ev.hz, ~ev.in_out, ev.oe
    lab = list(res.labels)
    i_gb, i_ab = [lab.index(f"eps_{a}") for a in "xyz"], [lab.index(f"nabla_{a}") for a in "xyz"]
    att = A.quat_to_euler(res.nav[-1:, :4])[0]      # the last epoch's (the tables make the rest)
    st = res.start
    m = {"duration_s": float(res.t[-1] - res.t[0]), "n_outages": len(res.outages),
         "outage_end_hz_err_median_m": float(np.median(oe)) if oe.size else None,
         "outage_end_hz_err_max_m": float(np.max(oe)) if oe.size else None, "outage_end_hz_err_m": oe.tolist(),
         "hz_err_with_fixes_median_m": float(np.median(hz[ok])) if ok.any() else None,
         "hz_err_with_fixes_max_m": float(np.max(hz[ok])) if ok.any() else None,
         "hz_err_with_fixes_p99_m": float(np.percentile(hz[ok], 99)) if ok.any() else None,
         "final_pitch_deg": float(np.degrees(att[0])), "final_roll_deg": float(np.degrees(att[1])),
         "final_heading_deg": float(np.degrees(np.mod(A.yaw_to_heading(att[2]), 2 * np.pi))),
         "final_sigma_heading_deg": float(np.degrees(res.sigma[-1, 2])),
         "gyro_bias_final_dph": (res.gyro_bias[-1] / units.dph).tolist(),
         "gyro_bias_sigma_final_dph": (res.sigma[-1, i_gb] / units.dph).tolist(),
         "accel_bias_final_ug": (res.accel_bias[-1] / units.ug).tolist(),
         "accel_bias_sigma_final_ug": (res.sigma[-1, i_ab] / units.ug).tolist(),
         "initial_heading_deg": float(np.degrees(st.heading)), "imu_gaps": int(len(p.data.gaps)),
         "initial_heading_sigma_deg": float(np.degrees(st.heading_sigma)) if st.heading_sigma is not None else None,
         "initial_attitude_sigma_deg": np.degrees(res.sigma[0, :3]).tolist(),
         "fixes_after_grid": int(res.fixes_after_grid),
         "filter_gyro_arw_deg_sqrth": (np.asarray(st.gyro_noise) / (units.deg / 60)).tolist(),
         "filter_accel_vrw_ug_sqrthz": (np.asarray(st.accel_noise) / units.ug).tolist()}
    m.update({f"start_source_{k}": v for k, v in st.sources.items()})
    s = p.sync
    if s is not None:
        m.update(time_sync_offset_s=s["offset"], time_sync_ppm=s["ppm"], time_sync_offset_estimate_s=s["offset_estimate"],
                 time_sync_offset_sigma_s=s["offset_sigma"], time_sync_ppm_estimate=s["ppm_estimate"],
                 time_sync_ppm_sigma=s["ppm_sigma"], time_sync_offset_applied=s["offset_applied"],
                 time_sync_ppm_applied=s["ppm_applied"], time_sync_windows=s["windows"],
                 time_sync_threshold_sigmas=s["threshold_sigmas"],
                 time_sync_speed_change_offset_s=s.get("speed_change_offset"),
                 time_sync_speed_change_sigma_s=s.get("speed_change_offset_sigma"),
                 time_sync_offset_confirmed=s.get("offset_confirmed"))
    m["platform"] = res.platform[0]
    if res.scale is not None:
        m["scale_factor_final_ppm"] = (res.scale[-1] * 1e6).tolist()
    return m


def _claims(res, p, ev, metrics, echo):
    """The source's checks: the fixes' NIS and residuals against their σ
    (:func:`sinslab.app.described.navigate_claims`) and the run's consistency findings,
    or the satellites' NIS (:func:`sinslab.app.commands.raw_gnss.raw_claims`); the
    initial rest's |f| against gravity."""
    recs = res.source.fix_records
    if recs is None:
        from sinslab.app.commands.raw_gnss import raw_claims, raw_consistency_findings
        from sinslab.app.plausibility import row_consistency_findings
        claims, extra = raw_claims(res.source.rows)
        found, window = row_consistency_findings(res.source.rows)
        # the windowed NIS above judges overconfidence; the satellites' windows add their biases
        p.found += found + [f for f in raw_consistency_findings(res.source.rows)
                            if not f.text.startswith("the filter is overconfident")]
        extra.update(window)
    else:
        from sinslab.app.described import SETTLE_S, navigate_claims
        from sinslab.app.plausibility import consistency_findings
        fix_t, inn, sd, nis = recs
        settling = np.zeros(ev.t.size, bool)
        for s0, ln in res.outages:
            settling |= (ev.t >= s0 + ln) & (ev.t < s0 + ln + SETTLE_S)
        ok = ~ev.in_out
        claims, extra = navigate_claims(
            nis, inn.shape[1] if inn.ndim == 2 else 3, ev.hz[ok],
            np.hypot(*np.maximum(p.fx.sigma[ev.idx], p.opt.fix.pos_sigma_floor)[ok, :2].T), ~settling[ok])
        if nis.size and extra["nis_verdict"] != "consistent":
            hint = ("; the white noise is the built-in default, not measured (no rest at the start): the "
                    "unit's, --imu-errors FILE or a grade, may explain it" if extra["nis_verdict"].startswith(
                        "overconfident") and not res.start.noise_measured and not p.em_cfg else "")
            echo(f"  mean NIS {res.source.metrics['nis_mean']:.2f} for a fix of dimension {extra['nis_dof']}: "
                 f"{extra['nis_verdict']}{hint}")
        if sd is not None:
            p.found += consistency_findings(fix_t, inn, sd, nis, _innovation_labels(inn.shape[1]))
    metrics.update(extra)
    if res.start.rest is not None:        # |f| at the initial rest against gravity
        from sinslab.app.plausibility import rest_gravity_findings
        at_rest = p.imu.slice(res.start.rest.t0, res.start.rest.t1)
        p.found += rest_gravity_findings(at_rest, f"{_files(p.cfg.imu.file)} (initial rest)", lat=float(p.fx.lat[0]),
                                         h=float(p.fx.h[0]))
    return claims


def _estimate_findings(res, p, metrics):
    """The run's estimated biases (and scale factors) against the IMU's grade: the declared
    error model's 1σ (``--imu-errors``, :func:`sinslab.app.plausibility.declared_findings`),
    else the class the noise measured at the initial rest puts the IMU in
    (:func:`sinslab.app.plausibility.bias_findings`)."""
    from sinslab.app import plausibility as P
    src = f"{_files(p.cfg.imu.file)} (the run's estimates)"
    gb, ab = np.asarray(metrics["gyro_bias_final_dph"]) * units.dph, np.asarray(metrics["accel_bias_final_ug"]) * units.ug
    if p.errors is None:
        return P.bias_findings(gb, ab, src, gyro_arw=float(np.median(res.start.gyro_noise)))
    e = p.errors
    est = [("gyro bias", gb, np.asarray(metrics["gyro_bias_sigma_final_dph"]) * units.dph, e.gyro_bias,
            "°/h", 1 / units.dph),
           ("accelerometer bias", ab, np.asarray(metrics["accel_bias_sigma_final_ug"]) * units.ug, e.accel_bias,
            "µg", 1 / units.ug)]
    if res.scale is not None:
        sc = res.scale[-1]
        est += [("gyro scale factor", sc[:3], np.zeros(3), e.gyro_scale_factor, "ppm", 1e6),
                ("accelerometer scale factor", sc[3:], np.zeros(3), e.accel_scale_factor, "ppm", 1e6)]
    return P.declared_findings(est, src, f"--imu-errors {p.cfg.filter.imu_errors}")


def _say(res, p, ev, metrics, echo):
    """The run on the terminal."""
    imu, fx, st = p.imu, p.fx, res.start
    hz, ok = ev.hz, ~ev.in_out
    echo(f"{p.data.path}: {len(imu)} samples at {1 / imu.dt:.4g} Hz; {p.fix_name}: {len(fx)} fixes"
         f"{' with velocity' if fx.vel is not None else ''}")
    if st.rest is None:
        echo(f"  no rest at the start: pitch {np.degrees(st.pitch):.2f} deg, roll "
             f"{np.degrees(st.roll):.2f} deg {st.level.source}")
    if not st.noise_measured and not p.em_cfg:
        echo(f"  {_default_noise_words(metrics)}")
    echo(f"  start {st.t - fx.t[0]:.2f} s after the first fix; heading "
         f"{np.degrees(st.heading):.2f} deg (clockwise from north, {st.heading_source})")
    sig0 = metrics["initial_attitude_sigma_deg"]
    if st.motion_fit is not None:
        ma = st.motion_fit
        echo(f"  attitude from an in-motion alignment over {ma.window_s:.1f} s of fixes before the start (the gyros "
             f"would have carried the levelling {ma.carried_s:.1f} s): filter σ at the start pitch/roll "
             f"{sig0[0]:.1f}, {sig0[1]:.1f} deg, heading {sig0[2]:.1f} deg"
             f"{'' if ma.heading else ' (heading from the course)'}")
    if st.tilt_carried_s > 1.0:
        echo(f"  pitch and roll carried by the gyros {st.tilt_carried_s:.1f} s from the rest: filter σ at "
             f"the start pitch/roll {sig0[0]:.1f}, {sig0[1]:.1f} deg, heading {sig0[2]:.1f} deg")
    if ev.oe.size:
        echo(f"  {len(res.outages)} outages: horizontal error at their end median {np.median(ev.oe):.2f} m, "
             f"max {np.max(ev.oe):.2f} m")
    if ok.any():
        against = "with fixes" if res.source.reference == "fixes" else f"against {res.source.reference}"
        echo(f"  {against}: horizontal error median {np.median(hz[ok]):.3f} m, 99th "
             f"percentile {np.percentile(hz[ok], 99):.3f} m, max {np.max(hz[ok]):.3f} m")
    echo(f"  final attitude pitch {metrics['final_pitch_deg']:.3f} deg, roll {metrics['final_roll_deg']:.3f} deg, "
         f"heading {metrics['final_heading_deg']:.3f} deg (sigma {metrics['final_sigma_heading_deg']:.3f})")
    echo(f"  gyro bias [°/h] {np.round(metrics['gyro_bias_final_dph'], 1).tolist()}, accel bias [µg] "
         f"{np.round(metrics['accel_bias_final_ug'], 0).tolist()}")


def _notes(res, p, metrics, noise_warn, echo):
    """The report's notes on the start, the time sync and the error model."""
    st, fx, s = res.start, p.fx, p.sync
    notes = ["Heading is clockwise from north.",
             f"Initial attitude: {st.heading_source}; levelling over the initial rest." if st.rest is not None else
             f"No rest at the start: pitch and roll {st.level.source}; heading {st.heading_source}."]
    if st.motion_fit is not None:
        notes.append(f"Initial attitude from an in-motion alignment over {st.motion_fit.window_s:.1f} s of fixes "
                     f"before the start, not the rest's levelling carried {st.motion_fit.carried_s:.1f} s by the gyros.")
    if st.heading_sigma is not None:
        notes.append(f"Initial heading {np.degrees(st.heading):.2f} deg ± {np.degrees(st.heading_sigma):.2f} deg "
                     "(1σ of the course window).")
    if metrics["fixes_after_grid"]:
        notes.append(f"{metrics['fixes_after_grid']} fix(es) after the last whole filter step "
                     f"({res.grid_end - fx.t[0]:.3f} s after the first fix) were not used.")
        echo(f"  {metrics['fixes_after_grid']} fix(es) after the last whole filter step dropped")
    if s is not None:
        notes.append(f"Time sync: offset {s['offset_estimate'] * 1e3:.1f} ± {s['offset_sigma'] * 1e3:.1f} ms "
                     f"({'applied' if s['offset_applied'] else 'not applied: not significant at 3σ'}), "
                     f"clock {s['ppm_estimate']:.0f} ± {s['ppm_sigma']:.0f} ppm "
                     f"({'applied' if s['ppm_applied'] else 'not applied'}).")
    if noise_warn:
        notes.append(noise_warn)
    em = p.em_cfg
    notes.append("Error model: " + ("; ".join(f"{k} = {v}" for k, v in em.items()) if em else
                                    "built-in defaults (white noise measured at the initial rest)." if
                                    st.noise_measured else _default_noise_words(metrics)))
    notes.append("Start: " + "; ".join(f"{k.replace('_', ' ')} {v}" for k, v in st.sources.items()) + ".")
    return notes


def _default_noise_words(metrics):
    """The one line that says the white noise is the built-in default, not measured."""
    return (f"white noise: the built-in default (gyro {np.round(metrics['filter_gyro_arw_deg_sqrth'], 4).tolist()} "
            f"deg/sqrt(h), accel {np.round(metrics['filter_accel_vrw_ug_sqrthz'], 0).tolist()} ug/sqrt(Hz)), not "
            "measured: no rest at the start; give the unit's with --imu-errors FILE or a grade (consumer | "
            "industrial | tactical | navigation)")


def _plugin_outputs(rep, metrics, tables, figures, notes, echo, t0):
    """A plug-in's report (:class:`sinslab.fusion.aids.base.Report`) into the run folder:
    its metrics, tables, notes, terminal lines and figures of panels."""
    metrics.update(rep.metrics)
    for line in rep.lines:
        echo(line)
    notes += list(rep.notes)
    tables += [Series(t.name, t.columns, t.description) for t in rep.tables]
    for f in rep.figures:
        figures.append(panel_figure(f, t0))


def _tables(res, ev, every, fx):
    sol = Series("solution", _solution_table(res), f"navigation solution at every filter epoch with filter sigma "
                 f"(Parquet; the CSV every {every}-th epoch, {1 / (every * (res.t[1] - res.t[0])):.4g} Hz)"
                 if res.t.size > 1 else "navigation solution", csv_every=every)
    err = Series("fix_errors", {"t_s": ev.t - res.t[0], "east_m": ev.err[:, 0], "north_m": ev.err[:, 1],
                                "up_m": ev.err[:, 2], "in_outage": ev.in_out.astype(float)},
                 f"solution (antenna) minus {res.source.reference} at every fix time")
    # the reference positions themselves, for the map (sinslab export, --kml)
    ref = Series("fixes", {"t_s": ev.t - res.t[0], "lat_deg": np.degrees(fx.lat[ev.idx]),
                           "lon_deg": np.degrees(fx.lon[ev.idx]), "h_m": fx.h[ev.idx],
                           "in_outage": ev.in_out.astype(float)},
                 f"the {res.source.reference} inside the solution's span (in_outage 1: withheld)")
    return [sol, err, ref]


def _figures(res, p, ev):
    """The track, the errors against the reference (with what the aids mark) and the σ."""
    return [_track_figure(res, p.fx), _error_figure(res, ev), _sigma_figure(res)]


def _track_figure(res, fx):
    from sinslab.app import plotting            # matplotlib: once the run has computed
    from sinslab.core import earth as E
    lat0, lon0 = fx.lat[0], fx.lon[0]
    rm, rn = E.radii(lat0, fx.h[0])
    xe = (fx.lon - lon0) * rn * math.cos(lat0)
    yn = (fx.lat - lat0) * rm
    t_tr, lat_tr, lon_tr = _track_points(res)
    se = (lon_tr - lon0) * rn * math.cos(lat0)
    sn = (lat_tr - lat0) * rm
    fig, axes = plotting.figure(1, 1, width=7.5, row_height=6.5)
    ax = axes[0]
    ax.plot(xe, yn, "k.", ms=1.5, label="fixes")
    ax.plot(se, sn, "-", color=plotting.COLORS[0], lw=1, label="INS/fix solution")
    for s, ln in res.outages:
        m = (t_tr >= s) & (t_tr < s + ln)
        ax.plot(se[m], sn[m], "-", color=plotting.COLORS[1], lw=2)
    ax.plot([], [], "-", color=plotting.COLORS[1], lw=2, label="during outages")
    ax.set_aspect("equal", "datalim")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.legend()
    return Figure("track", fig, "Track on a local ENU map (origin at the first fix); outages in red.")


def _error_figure(res, ev):
    from sinslab.app import plotting
    fig, axes = plotting.figure(3, 1, width=9.0)
    tt = ev.t - res.t[0]
    marks = [mk for rep in (res.source, *res.aids) for mk in rep.marks]
    for ax, k, nm in zip(axes, range(3), ("east", "north", "up")):
        ax.plot(tt, ev.err[:, k], ".", ms=1.5, color=plotting.COLORS[k])
        ax.set_ylabel(f"{nm} error [m]")
        for s, ln in res.outages:
            ax.axvspan(s - res.t[0], s + ln - res.t[0], color="0.85", lw=0)
        for mk in marks:
            for a, b in mk.spans:
                if mk.kind == "band":
                    ax.axvspan(a - res.t[0], b - res.t[0], color=plotting.COLORS[2], alpha=0.15, lw=0)
                else:
                    ax.axvspan(a - res.t[0], b - res.t[0], ymin=0.9, ymax=1.0, color=plotting.COLORS[3], lw=0)
    axes[-1].set_xlabel("time [s]")
    labels = list(dict.fromkeys((("; green: " if mk.kind == "band" else "; top bar: ") + mk.label)
                                for mk in marks if mk.spans))
    fig.suptitle(f"Solution minus {res.source.reference} (grey: outages" + "".join(labels) + ")")
    return Figure("errors", fig, f"Position error of the solution (antenna) versus {res.source.reference}.")


def _sigma_figure(res):
    from sinslab.app import plotting
    sig = res.sigma
    lab = list(res.labels)
    i_gb, i_ab = [lab.index(f"eps_{a}") for a in "xyz"], [lab.index(f"nabla_{a}") for a in "xyz"]
    fig, axes = plotting.figure(3, 1, width=9.0)
    ts_ = _Shifted(res.t)
    _semilogy(axes[0], ts_, lambda a, b: np.degrees(sig[a:b, 0:3]) * 60, release=(sig,), lw=1)
    axes[0].set_ylabel("attitude σ [arcmin]")
    axes[0].legend(["φE", "φN", "φU"], fontsize=8)
    _semilogy(axes[1], ts_, lambda a, b: sig[a:b, i_gb] / units.dph, release=(sig,), lw=1)
    axes[1].set_ylabel("gyro bias σ [°/h]")
    axes[1].legend(["x", "y", "z"], fontsize=8)
    _semilogy(axes[2], ts_, lambda a, b: sig[a:b, i_ab] / units.ug, release=(sig,), lw=1)
    axes[2].set_ylabel("accel bias σ [µg]")
    axes[2].legend(["x", "y", "z"], fontsize=8)
    axes[2].set_xlabel("time [s]")
    return Figure("sigma", fig, "Filter standard deviations of attitude and sensor biases.")


#: pixel columns a filter-epoch series is thinned to before it is plotted (more than any
#: figure's width: the writer thins it again to the axes' own, keeping the envelope)
PLOT_COLUMNS = 2000


def _semilogy(ax, t, y, release=(), **kw):
    """``ax.semilogy`` of the columns of ``y`` against ``t``, each thinned to its envelope
    over :data:`PLOT_COLUMNS` columns first (:func:`sinslab.app.plotting.minmax_decimate`),
    so a long run's figure does not hold a copy of every epoch until it is drawn.

    ``y`` an array (N,) or (N, k), or a function ``(a, b) ->`` its rows ``a:b``; ``t``
    (N,) (an array mapped from a file is fine). A long series is thinned a block of
    groups at a time (the same points: the groups are those of the whole series), so
    neither it nor a copy is held whole; ``release``: arrays ``y`` reads, whose pages are
    let go after each block (a run on disk)."""
    from sinslab.app.plotting import minmax_decimate

    n = t.shape[0]
    get = y if callable(y) else (lambda a, b: np.asarray(y)[a:b])
    if n <= 4 * PLOT_COLUMNS:
        ys = np.asarray(get(0, n))
        tt = np.asarray(t[:n])
        for col in (ys.T if ys.ndim == 2 else [ys]):
            ax.semilogy(*minmax_decimate(tt, col, PLOT_COLUMNS), **kw)
        return
    edges = np.linspace(0, n, PLOT_COLUMNS + 1).astype(np.int64)
    per = max(1, BLOCK_GROUPS)
    pieces = None
    for g0 in range(0, PLOT_COLUMNS, per):
        g1 = min(PLOT_COLUMNS, g0 + per)
        a, b = int(edges[g0]), int(edges[g1])
        ys, tt = np.asarray(get(a, b)), np.asarray(t[a:b], dtype=float)
        cols = ys.T if ys.ndim == 2 else [ys]
        pieces = pieces or [([], []) for _ in cols]
        for (px, py), col in zip(pieces, cols):
            xk, yk = minmax_decimate(tt, col, g1 - g0, edges=edges[g0:g1 + 1] - a)
            px.append(xk)
            py.append(yk)
        release_pages(t, *release)
    for px, py in pieces:
        ax.semilogy(np.concatenate(px), np.concatenate(py), **kw)


#: filter epochs of the solution tables made and written at once (a Parquet row group each)
TABLE_CHUNK_ROWS = 1 << 14
#: groups of :func:`_semilogy` thinned at once
BLOCK_GROUPS = 64
#: most points of the track figure: a longer solution is drawn every k-th epoch (far more
#: points than the figure has pixels either way)
TRACK_POINTS = 1 << 15


class _Shifted:
    """``t − t[0]`` of a series of times, made a slice at a time (``shape``, slicing)."""

    def __init__(self, t):
        self.t, self.t0, self.shape = t, t[0], t.shape

    def __getitem__(self, key):
        return np.asarray(self.t[key]) - self.t0

    def release_pages(self):
        release_pages(self.t)


def _track_points(res):
    """Times [s], latitudes and longitudes [rad] of the track figure: every epoch up to
    :data:`TRACK_POINTS`, every k-th beyond. Taken a block at a time: a stride through
    a record on disk touches every page of it, and each block's are let go before the
    next."""
    step = -(-res.t.size // TRACK_POINTS)
    t, lat, lon = [], [], []
    for a, b in block_ranges(res.t.size, multiple=step):      # blocks start on the stride
        # copies: a view would read the pages back in when the blocks are joined
        t.append(np.array(res.t[a:b:step]))
        lat.append(np.array(res.nav[a:b:step, 7]))
        lon.append(np.array(res.nav[a:b:step, 8]))
        release_pages(res.t, res.nav)
    return tuple(np.concatenate(c) if c else np.empty(0) for c in (t, lat, lon))


def _scale_of(unit):
    """Display unit of a state -> its SI scale."""
    return {"arcmin": units.arcmin, "arcsec": units.arcsec, "deg/h": units.dph, "ug": units.ug,
            "ppm": units.ppm}.get(unit, 1.0)


def _solution_table(res):
    """``solution``: navigation, filter σ and sensor compensation at every filter epoch,
    made a chunk of epochs at a time as it is written (no second copy of the run)."""
    from sinslab.app.tablefile import ChunkedTable
    from sinslab.core import attitude as A

    t0 = res.t[0]
    states = [(i, f"sigma_{l}_{u_.replace('/', 'p')}", _scale_of(u_))
              for i, (l, u_) in enumerate(zip(res.labels, res.units_))]

    def rows(a, b):
        # the epochs before this chunk are written: a run on disk lets their pages go
        release_pages(res.t, res.nav, res.sigma, res.gyro_bias, res.accel_bias)
        nav = res.nav[a:b]
        att = A.quat_to_euler(nav[:, :4])
        sol = {"t_s": res.t[a:b] - t0, "t_abs_s": res.t[a:b], "lat_deg": np.degrees(nav[:, 7]),
               "lon_deg": np.degrees(nav[:, 8]), "h_m": nav[:, 9],
               "vE_mps": nav[:, 4], "vN_mps": nav[:, 5], "vU_mps": nav[:, 6],
               "pitch_deg": np.degrees(att[:, 0]), "roll_deg": np.degrees(att[:, 1]),
               "heading_deg": np.degrees(np.mod(A.yaw_to_heading(att[:, 2]), 2 * np.pi))}
        for i, name, sc in states:
            sol[name] = res.sigma[a:b, i] / sc
        for k, ax in enumerate("xyz"):
            sol[f"gyro_bias_{ax}_dph"] = res.gyro_bias[a:b, k] / units.dph
            sol[f"accel_bias_{ax}_ug"] = res.accel_bias[a:b, k] / units.ug
        return sol

    return ChunkedTable.of(rows, res.t.size, TABLE_CHUNK_ROWS)


def _smoothed_table(res):
    """``smoothed``: forward (``fwd_``) and smoothed (``smo_``) solutions and σ at every
    filter epoch, made a chunk of epochs at a time as it is written."""
    from sinslab.app.tablefile import ChunkedTable
    from sinslab.core import attitude as A

    sm = res.smoothed
    t0 = res.t[0]
    states = [(i, f"sigma_{l}_{u_.replace('/', 'p')}", _scale_of(u_))
              for i, (l, u_) in enumerate(zip(res.labels, res.units_))]

    def rows(a, b):
        release_pages(res.t, res.sigma)
        fw, sn = sm.forward_nav[a:b], sm.nav[a:b]
        att_f, att_s = A.quat_to_euler(fw[:, :4]), A.quat_to_euler(sn[:, :4])
        cols = {"t_s": res.t[a:b] - t0, "t_abs_s": res.t[a:b]}
        for nm, f, g, sc in (("lat_deg", fw[:, 7], sn[:, 7], 180 / math.pi),
                             ("lon_deg", fw[:, 8], sn[:, 8], 180 / math.pi),
                             ("h_m", fw[:, 9], sn[:, 9], 1.0),
                             ("vE_mps", fw[:, 4], sn[:, 4], 1.0),
                             ("vN_mps", fw[:, 5], sn[:, 5], 1.0),
                             ("vU_mps", fw[:, 6], sn[:, 6], 1.0),
                             ("pitch_deg", att_f[:, 0], att_s[:, 0], 180 / math.pi),
                             ("roll_deg", att_f[:, 1], att_s[:, 1], 180 / math.pi),
                             ("heading_deg", np.mod(A.yaw_to_heading(att_f[:, 2]), 2 * np.pi),
                              np.mod(A.yaw_to_heading(att_s[:, 2]), 2 * np.pi), 180 / math.pi)):
            cols[f"fwd_{nm}"] = f * sc
            cols[f"smo_{nm}"] = g * sc
        for i, name, sc in states:
            cols[f"fwd_{name}"] = res.sigma[a:b, i] / sc
            cols[f"smo_{name}"] = sm.sigma[a:b, i] / sc
        return cols

    return ChunkedTable.of(rows, res.t.size, TABLE_CHUNK_ROWS)


def _read_fixes(read, path, fmt):
    """``read()`` of the fix file, any reader error naming it: a file in another format makes
    a reader fail anywhere (an IndexError on a short line), which is the file's fault, not a
    bug."""
    try:
        return read()
    except (IndexError, KeyError, UnicodeDecodeError, ValueError) as e:
        msg = str(e) or type(e).__name__
        if str(path) in msg:
            raise ValueError(msg) from None
        what = f"not readable as {fmt}" if fmt else "not readable"
        raise ValueError(f"--fixes {path}: {what} ({type(e).__name__ + ': ' if not isinstance(e, ValueError) else ''}"
                         f"{msg}); give --fix-format rtklib-pos | csv | mat-avp") from None


def _say_fix_reading(meta, path, echo):
    """What the fix reader did to the table, on the terminal (a user must not find out
    from the results that 30 000 rows were 600 fixes)."""
    if meta.get("compressed"):
        echo(f"  {path}: read from a {meta['compressed']} file")
    if meta.get("held"):
        rows, ep = meta["held"]
        echo(f"  {path}: {rows} rows hold {ep} receiver epochs (each fix repeated ~{rows / ep:.0f}x by "
             "the logger): collapsed to the first row of each epoch")
    if meta.get("no_position"):
        echo(f"  {path}: {meta['no_position']} rows without a position dropped")
    if meta.get("quality_counts") is not None:
        echo(f"  {path}: quality/mode values {meta['quality_counts']} (rows); kept: {meta['quality_kept']}")
    if meta.get("velocity_frame") == "NED":
        echo(f"  {path}: velocity north, east, down (turned to east, north, up)")


#: measured rest noise and the filter's white noise may differ by this factor unwarned
NOISE_FACTOR = 3.0


def _noise_check(start, metrics, echo):
    """The unit's white noise measured at the initial rest against the filter's: the
    densities into the metrics and, when an axis differs by more than ``NOISE_FACTOR``,
    a warning on the terminal; returns the warning (or "")."""
    if start.rest is None:
        return ""
    gm = np.asarray(start.rest.gyro_noise) / (units.deg / 60)
    am = np.asarray(start.rest.accel_noise) / units.ug
    gf = np.asarray(metrics["filter_gyro_arw_deg_sqrth"])
    af = np.asarray(metrics["filter_accel_vrw_ug_sqrthz"])
    metrics["rest_gyro_noise_deg_sqrth"] = gm.tolist()
    metrics["rest_accel_noise_ug_sqrthz"] = am.tolist()
    rg, ra = gm / gf, am / af
    metrics["rest_over_filter_noise_gyro"] = rg.tolist()
    metrics["rest_over_filter_noise_accel"] = ra.tolist()
    off = [f"{nm} {a} {r:.2g}x" for nm, rr in (("gyro", rg), ("accel", ra)) for a, r in zip("xyz", rr)
           if r > NOISE_FACTOR or r < 1 / NOISE_FACTOR]
    if not off:
        return ""
    msg = (f"Warning: the white noise measured at the initial rest (gyro {np.round(gm, 3).tolist()} deg/sqrt(h), "
           f"accel {np.round(am, 0).tolist()} ug/sqrt(Hz)) differs from the filter's (gyro "
           f"{np.round(gf, 3).tolist()} deg/sqrt(h), accel {np.round(af, 0).tolist()} ug/sqrt(Hz)) by more than "
           f"{NOISE_FACTOR:g}x ({', '.join(off)}: measured / filter): vibration above the datasheet noise makes "
           "the filter overconfident, a noise model far above it pessimistic")
    echo("  " + msg)
    return msg


# ------------------------------------------------------------- memory estimate ---
#: Peak resident memory of one navigate process: a fixed part (interpreter, numpy, numba
#: and its loaded kernels, scipy, pyarrow, matplotlib) and, for a log read whole (not a
#: plain CSV/Parquet table), a part per IMU sample (the record and its reading, the
#: filter's outputs, metrics and figures; the tables are written a chunk at a time; with
#: ``--smooth`` the smoothed solution too, and the forward pass' record in memory up to
#: ``SMOOTH_SPILL_ABOVE``, on disk beyond). Upper bounds from
#: ``benchmarks/navigate_cost.py``: a log read in blocks peaks at 281 MB for 10 and for
#: 60 min at 200 Hz (fixed part, one block, the record up to its spill size and the
#: fixes), the per-sample slopes were measured on logs read whole.
MEMORY_FIXED = 300 * 2 ** 20
MEMORY_PER_SAMPLE = {False: 220, True: 360}
#: A log read a block at a time (:func:`streamed`) holds, beyond the fixed part, one IMU
#: block (:data:`IMU_BLOCK_ROWS` rows: its text and arrays, ~30 MB), one chunk of the
#: solution table (:data:`TABLE_CHUNK_ROWS` epochs: its columns, text and Parquet row
#: group, ~12 MB) and the track's points up to :data:`TRACK_POINTS` (~1 MB, and the
#: figure drawn from them)
MEMORY_BLOCK = 64 * 2 ** 20
#: the filter's per-epoch record per IMU sample (200 Hz samples, 50 Hz epochs), held in
#: memory up to :data:`RECORD_SPILL_ABOVE`
MEMORY_RECORD_PER_SAMPLE = 130
#: per fix: the fix itself, its measurement schedule and the filter's record of its
#: update (innovation, σ, NIS), its error against the solution (~1 kB measured)
MEMORY_PER_FIX = 1024


def estimate_samples(path, fmt):
    """Number of IMU samples in ``path`` estimated without reading it: the row count of a
    Parquet file, or a text table's size (up to a NUL tail,
    :func:`sinslab.data.textguard.text_extent`) over the mean length of its first lines; None
    for other formats and compressed files. Of channels in two tables joined on time
    (``path`` a list) the first table is counted."""
    import os

    if isinstance(path, (list, tuple)):
        path = path[0]
    if str(path).lower().endswith((".gz", ".zip")):
        return None

    if fmt == "parquet":
        import pyarrow.parquet as pq
        try:
            return int(pq.ParquetFile(path).metadata.num_rows)
        except Exception:        # noqa: BLE001 - the reader names what is wrong
            return None
    if fmt != "csv":
        return None
    from sinslab.data.textguard import text_extent
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
        # a preallocated log's NUL tail holds no sample (the reader refuses it at its offset)
        size = text_extent(path) or size
    except OSError:
        return None
    lines = head.split(b"\n")
    body = [ln for ln in lines[1:-1] if ln.strip()]        # after the header; complete lines
    if not body:
        return None
    per_line = (sum(len(ln) for ln in body) + len(body)) / len(body)
    return int((size - len(lines[0]) - 1) / per_line)


def streamed(imu_path, fmt) -> bool:
    """True if navigate reads this IMU log a block at a time (:func:`_read_imu`): one plain
    CSV or Parquet table."""
    from sinslab.data.archive import compression

    one = imu_path[0] if isinstance(imu_path, (list, tuple)) and len(imu_path) == 1 else imu_path
    if not IMU_BLOCK_ROWS or fmt not in ("csv", "parquet") or isinstance(one, (list, tuple)):
        return False
    try:
        return Path(one).is_file() and compression(Path(one)) is None
    except OSError:
        return False


def check_memory(imu_path, fmt, smooth, available=None, fix_path=None):
    """Refuse, before reading, an IMU log whose navigation cannot fit in memory.

    A log read a block at a time (:func:`streamed`) needs :data:`MEMORY_FIXED` plus
    :data:`MEMORY_BLOCK` (an IMU block, a table chunk, the figures' points at their caps)
    plus what still grows with the log: the filter's per-epoch record up to
    :data:`RECORD_SPILL_ABOVE` (on disk beyond), :data:`MEMORY_PER_FIX` per fix (their
    rows estimated from ``fix_path``'s size, :func:`estimate_samples`) and, with
    ``smooth``, the smoothed solution (:data:`MEMORY_PER_SAMPLE` ``[True]`` minus
    ``[False]`` per sample) and the most of the smoother's record held in memory
    (:data:`SMOOTH_SPILL_ABOVE`). Any other log is read whole: :data:`MEMORY_FIXED` plus
    :data:`MEMORY_PER_SAMPLE` per estimated sample (:func:`estimate_samples`), with
    ``smooth`` plus the smoother's record up to its spill size. ``available`` defaults to
    the memory the system can give a new allocation. Returns the estimate [bytes] or None
    (no estimate for the format).

    Raises
    ------
    ValueError
        One line naming the file, its estimated samples, the need and what is available.
    """
    from sinslab.app.validate import _size, available_memory

    n = estimate_samples(imu_path, fmt)
    if n is None:
        return None
    smooth_part = n * (MEMORY_PER_SAMPLE[True] - MEMORY_PER_SAMPLE[False]) + SMOOTH_SPILL_ABOVE if smooth else 0
    if streamed(imu_path, fmt):
        fixes = 0
        for fp in ([] if fix_path is None else fix_path if isinstance(fix_path, (list, tuple)) else [fix_path]):
            fixes += estimate_samples(fp, "csv") or 0
        need = (MEMORY_FIXED + MEMORY_BLOCK + min(n * MEMORY_RECORD_PER_SAMPLE, RECORD_SPILL_ABOVE)
                + fixes * MEMORY_PER_FIX + smooth_part)
    else:
        need = MEMORY_FIXED + n * MEMORY_PER_SAMPLE[False] + smooth_part
    avail = available_memory() if available is None else int(available)
    if need > avail:
        name = " + ".join(map(str, imu_path)) if isinstance(imu_path, (list, tuple)) else imu_path
        raise ValueError(f"{name}: about {n:,} IMU samples; navigate{' --smooth' if smooth else ''} "
                         f"needs about {_size(need)} of memory, {_size(avail)} is available "
                         "(split the log, or run where more memory is free)")
    return need


# ------------------------------------------------------------------ smoothing ---
#: the smoother's record of the forward pass goes to disk (the run's scratch folder) when
#: it would hold more than this in memory (estimated for 21 states)
SMOOTH_SPILL_ABOVE = 64 * 2 ** 20


#: the filter's per-epoch record (rows, estimates, σ, compensation) goes to disk when it
#: would hold more than this in memory
RECORD_SPILL_ABOVE = 16 * 2 ** 20
#: bytes of that record per filter epoch (21 states: row, rates, x, σ, biases, time)
RECORD_BYTES_PER_EPOCH = 8 * (10 + 3 + 3 + 2 * 21 + 6 + 1)


def _spill_smoother(opt, imu, fx):
    """On a long log, record the filter's run on disk: the driver's per-epoch arrays
    (:class:`sinslab.fusion.spec.FilterGrid` ``spill``) and, with ``--smooth``, the
    forward pass' history are written to memory-mapped files as the filter runs and read
    back a chunk at a time (:class:`sinslab.fusion.smoothing.History`), so they do not
    hold memory in proportion to the log. The numbers are the same either way."""
    from sinslab.app.commands.runner import scratch_dir
    from sinslab.fusion.smoothing import History

    where = scratch_dir()
    if where is None:
        return
    duration = float(imu.t[-1] - imu.t0)
    if duration / opt.kf_dt * RECORD_BYTES_PER_EPOCH > RECORD_SPILL_ABOVE:
        opt.spill = str(where / "filter")
    if not opt.smooth:
        return
    if History.estimate_bytes(21, duration, 0.1, len(fx)) > SMOOTH_SPILL_ABOVE:
        opt.smooth_spill = str(where / "smoother")


def _smoothed_outputs(res, fx, outs, metrics, tables, figures, echo, csv_every=1):
    """Forward and smoothed solutions side by side, their errors against the fixes that
    were not used (inside outages; all fixes without outages), figures."""

    from sinslab.app import plotting
    from sinslab.core import earth as E
    from sinslab.fusion.recorded import fix_errors
    sm = res.smoothed
    t, err_f, _ = fix_errors(res, fx)
    _, err_s, _ = fix_errors(res.with_nav(sm.nav), fx)
    hz_f, hz_s = np.hypot(err_f[:, 0], err_f[:, 1]), np.hypot(err_s[:, 0], err_s[:, 1])
    in_out = np.zeros(t.size, bool)
    mids = []
    for s0, ln in outs:
        m = (t >= s0) & (t < s0 + ln)
        in_out |= m
        if m.any():
            mids.append(int(np.flatnonzero(m)[np.argmin(np.abs(t[m] - (s0 + 0.5 * ln)))]))
    sel = in_out if in_out.any() else np.ones(t.size, bool)
    rms = lambda v: float(np.sqrt(np.mean(v ** 2))) if v.size else None  # noqa: E731
    metrics.update(
        smoothed_hz_err_rms_m=rms(hz_s[sel]), forward_hz_err_rms_m=rms(hz_f[sel]),
        smoothed_err_reference="fixes inside the outages (not used)" if in_out.any() else "all fixes (used)",
        outage_mid_hz_err_forward_m=hz_f[mids].tolist(), outage_mid_hz_err_smoothed_m=hz_s[mids].tolist(),
        outage_mid_hz_err_smoothed_median_m=float(np.median(hz_s[mids])) if mids else None,
        smoothed_stored_epochs=int(sm.stored.size))
    echo(f"  smoothed: horizontal error RMS {metrics['smoothed_hz_err_rms_m']:.3f} m "
         f"(forward {metrics['forward_hz_err_rms_m']:.3f} m) at {metrics['smoothed_err_reference']}")
    tables.append(Series("smoothed", _smoothed_table(res), "forward (fwd_) and smoothed (smo_) solutions and σ at every "
                         f"filter epoch (Parquet; the CSV every {csv_every}-th epoch, like the solution)",
                         csv_every=csv_every))
    fig, axes = plotting.figure(2, 1, width=9.0)
    tt = t - res.t[0]
    axes[0].plot(tt, hz_f, ".", ms=1.5, color=plotting.COLORS[0], label="forward")
    axes[0].plot(tt, hz_s, ".", ms=1.5, color=plotting.COLORS[1], label="smoothed")
    axes[0].set_ylabel("horizontal error [m]")
    axes[0].legend()
    lat = res.nav[:, 7]
    rm, rn = E.radii(lat, res.nav[:, 9])
    ip = res.layout.slice("dp").start
    sh_f = np.hypot(res.sigma[:, ip] * rm, res.sigma[:, ip + 1] * rn * np.cos(lat))
    sh_s = np.hypot(sm.sigma[:, ip] * rm, sm.sigma[:, ip + 1] * rn * np.cos(lat))
    ts_ = res.t - res.t[0]
    _semilogy(axes[1], ts_, sh_f, lw=1, color=plotting.COLORS[0], label="forward")
    _semilogy(axes[1], ts_, sh_s, lw=1, color=plotting.COLORS[1], label="smoothed")
    axes[1].set_ylabel("horizontal σ [m]")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        for s0, ln in outs:
            ax.axvspan(s0 - res.t[0], s0 + ln - res.t[0], color="0.85", lw=0)
    fig.suptitle("Forward filter and smoother (grey: outages)")
    figures.append(Figure("smoothed", fig, "Horizontal error against the fixes and horizontal σ, "
                          "forward filter and RTS smoother."))


#: the command's own options: (name, type, option names, help); the aids' options come
#: from their declared settings (:func:`_aid_options`)
_OPTIONS = (
    ("config", "path", ("--config", "-c"), "TOML configuration (sinslab config navigate prints the defaults; a run "
                                           "folder's config.toml re-runs it)"),
    ("set_", "strs", ("--set", "-s"), 'override a dotted config key, e.g. nhc.sigma="[0.2, 0.1] m/s" (repeatable)'),
    ("imu", "paths", ("--imu",), "recorded IMU file; twice for accelerometers and gyros in two tables on one time "
                                 "column (imu.file)"),
    ("fixes", "paths", ("--fixes", "--gnss"), "position(/velocity) fixes (.pos, CSV, .mat avp, .ubx NAV-PVT); twice "
                                              "for positions and velocities in two tables on one time column "
                                              "(gnss.fixes.file)"),
    ("gnss_raw", "path", ("--gnss-raw",), "raw GNSS instead of fixes (tightly coupled): u-blox log (RAWX/SFRBX) or "
                                          "RINEX 2/3 observations (gnss.raw.file)"),
    ("gnss_nav", "path", ("--gnss-nav",), "RINEX 2/3 navigation file (ephemerides) for --gnss-raw"),
    ("max_satellites", "strs", ("--max-satellites",), "K@START:DURATION: at most K satellites (highest first) from "
                                                      "START s after the first GNSS epoch (repeatable)"),
    ("elevation_mask", "float", ("--elevation-mask",), "satellites below this elevation [deg] are not used "
                                                       "(--gnss-raw; default 10)"),
    ("gnss_base", "path", ("--gnss-base",), "RTK: the base station's raw observations (RINEX or u-blox; navigation "
                                            "from --gnss-nav) beside --gnss-raw (gnss.raw.base)"),
    ("base_position", "str", ("--base-position",), 'RTK: the base antenna\'s ECEF position, e.g. '
                                                   '"-3959400.631,3385704.533,3667523.111 m" (gnss.raw.base_position)'),
    ("phase", "str", ("--phase",), "carrier phase without a base: tdcp (time-differenced phase) | none "
                                   "(gnss.raw.phase)"),
    ("format", "str", ("--format",), "IMU format: psins | csv | parquet | mat | rtklib-imu"),
    ("fix_format", "str", ("--fix-format",), "rtklib-pos | csv | mat-avp"),
    ("lever_arm", "str", ("--lever-arm",), 'IMU -> antenna in vehicle right-forward-up axes, e.g. "[-0.05, 0, 0] m"'),
    ("mount", "str", ("--mount",), "sensor -> vehicle rotation: rpy:R,P,Y | euler:P,R,Y (deg) | quat:W,X,Y,Z | "
                                   "matrix:M11,...,M33"),
    ("frame", "str", ("--frame",), "vehicle axes of the mount: rfu (right-forward-up) | frd (forward-right-down) | "
                                   "flu (forward-left-up) | rbd (right-back-down); default: the format's own"),
    ("outages", "str", ("--outages",), "START:LEN,... or LEN/PERIOD[@FIRST]; START and FIRST on --outage-clock "
                                       "(default s from the first fix)"),
    ("outage_clock", "str", ("--outage-clock",), "first-fix | log (the log's own stamps) | gps (GPS seconds of week or "
                                                 "YYYY-MM-DDTHH:MM:SS): what an outage's START counts"),
    ("fix_latency", "float", ("--fix-latency",), "simulated fix latency [s]"),
    ("lag", "str", ("--lag",), "aware | ignore (how late fixes are applied)"),
    ("init", "str", ("--init",), 'the start as KEY=VALUE items: heading, pitch, roll, attitude_sigma, time, latitude, '
                                 'longitude, height, velocity (ENU), position_sigma, velocity_sigma (ENU), e.g. '
                                 '"pitch=1.2 deg, roll=-0.4 deg, heading=30 deg, attitude_sigma=[0.1, 0.1, 0.5] deg"; '
                                 'or a KF-GINS YAML configuration (its initial state); default: found in the data '
                                 '(heading from the fix course above course_speed, 2 m/s)'),
    ("time_sync", "str", ("--time-sync",), "auto: estimate the IMU time offset and clock drift from turns"),
    ("velocity_lag", "float", ("--velocity-lag",), "fix velocities describe this many s before their stamp"),
    ("imu_delay", "float", ("--imu-delay",), "add to RTKLIB IMU time stamps [s]"),
    ("scale_factors", "bool", ("--scale-factors",), "estimate gyro/accel scale factors"),
    ("max_gap", "float", ("--max-gap",), "longest IMU gap bridged [s] (default 1)"),
    ("allow_gaps", "bool", ("--allow-gaps",), "bridge IMU gaps of any length"),
    ("columns", "str", ("--columns",), 'IMU column map "t=Time[s],dtheta_x=DeltaTheta[0][rad],..." or a TOML file'),
    ("imu_errors", "str", ("--imu-errors",), "filter error model: a TOML file (ImuErrors keys) or a grade: consumer | "
                                             "industrial | tactical | navigation"),
    ("aid", "str", ("--aid",), "aids beside the GNSS, a comma list (each has its config section: sinslab config "
                               "navigate)"),
    ("csv_rate", "float", ("--csv-rate",), "rate of solution.csv [Hz] (solution.parquet: every filter epoch; default 1)"),
    ("out", "path", ("--out", "-o"), "output folder [default: runs/navigate-<timestamp>]"),
    ("force", "bool", ("--force",), "replace whatever --out holds (another run, other files)"),
    ("smooth", "bool", ("--smooth",), "also write the RTS-smoothed solution (forward + backward pass)"),
    ("estimator", "str", ("--estimator",), "filter | graph (factor graph, batch; needs sinslab[graph]) | "
                                           "fixed-lag:SECONDS (the graph's fixed-lag smoother)"),
    ("fix_columns", "str", ("--fix-columns",), 'fix column map "t=time[s],lat=Pos.Latitude[deg],vd=Vel.Down[m/s],'
                                               'quality=Mode,..." or a TOML file'),
    ("fix_quality", "str", ("--fix-quality",), "accepted values of the fixes' quality/mode column (RTKLIB Q), e.g. 1,2"),
    ("platform", "str", ("--platform",), "auto | land | aircraft | marine: aids of a wheeled vehicle only on land "
                                         "(auto: from the fixes)"),
    ("strict", "bool", ("--strict",), "refuse (exit 2, nothing written) instead of warning about the data or the run"),
    ("kml", "bool", ("--kml",), "also write the track, the GNSS fixes and the outages as RUN.kml beside the run "
                                "folder (Google Earth; sinslab export RUN --to kml|geojson does it later)"),
)


def _aid_options():
    """``(name, "str", (option,), help)`` of every option an aid declares (a setting's
    ``flag``): the registry gives the command its options."""
    from sinslab.fusion.aids import aid_types
    from sinslab.fusion.aids.base import settings_of
    return tuple((st.flag[2:].replace("-", "_"), "str", (st.flag,), f"{st.doc} ({name}.{key}; enables it)"
                  if st.kind == "file" else f"{st.doc} ({name}.{key})")
                 for name, t in aid_types().items() for key, st in settings_of(t).items() if st.flag)


def register(app):
    """Add ``sinslab navigate`` to the typer ``app`` (called from sinslab.cli): its own
    options and those the aids of the registry declare, each a short form of a config key."""
    import inspect

    import typer
    types = {"path": Optional[Path], "paths": Optional[list[Path]], "strs": Optional[list[str]],
             "str": Optional[str], "float": Optional[float], "bool": bool}
    params = [inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, annotation=types[kind],
                                default=typer.Option(False if kind == "bool" else None, *opts, help=text,
                                                     **({"metavar": "KEY=VALUE"} if name == "set_" else {})))
              for name, kind, opts, text in (*_OPTIONS, *_aid_options())]

    def navigate(**kw) -> None:
        """INS + GNSS fixes (loosely coupled) or raw pseudoranges/Doppler (tightly coupled), and aids, on recorded data.

        Every option is a short form of a key of the run's configuration (--config FILE.toml,
        --set key=value); the run folder's config.toml re-runs it."""
        config, sets, out, force = kw.pop("config"), kw.pop("set_"), kw.pop("out"), kw.pop("force")
        cli_call(lambda: navigate_files(navigate_config(config, sets or (), **kw), out=out, echo=typer.echo),
                 force=force)

    navigate.__signature__ = inspect.Signature(params, return_annotation=None)
    navigate.__annotations__ = {p.name: p.annotation for p in params}
    return app.command()(navigate)
