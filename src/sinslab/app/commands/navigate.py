"""``sinslab navigate``: recorded IMU + fix files through the loosely coupled filter into a
run folder (solution, fix errors, figures, report)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from types import MappingProxyType
from typing import Optional

import numpy as np

from sinslab.app.commands.runner import Command, Figure, Output, Series, cli_call, run_command
from sinslab.core import units
from sinslab.core.blocks import block_ranges, release_free_memory, release_pages

__all__ = ["NAVIGATE", "NavigateRequest", "navigate_files", "register"]

NAVIGATE = Command("navigate", "loosely coupled INS + position/velocity fixes on recorded data")

#: ``--lag``: the lag policy (:mod:`sinslab.fusion.lag`) of each choice
LAG_POLICY = {"aware": "exact", "ignore": "on-arrival"}


# --------------------------------------------------------------------------- the CLI ---
def _vec3(text, kind, what):
    try:
        return units.parse_vector(text, kind, 3)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{what}: {e}") from None


def _parse_init(text):
    """``heading=30 deg`` (clockwise from north) -> dict; empty -> {}."""
    out = {}
    if not text:
        return out
    from sinslab.app.validate import option_quantity

    for tok in str(text).split(","):
        k, sep, v = tok.partition("=")
        k = k.strip().lower()
        if not sep or k not in ("heading", "course_speed", "course_spread"):
            raise ValueError(f"--init {text!r}: use heading=ANGLE (e.g. heading=\"30 deg\"), "
                             "course_speed=SPEED, course_spread=ANGLE")
        if k == "course_speed":
            out[k] = option_quantity(f"--init {k}", v.strip(), "velocity", gt="0 m/s", le="100 m/s")
        elif k == "course_spread":
            out[k] = option_quantity(f"--init {k}", v.strip(), "angle", gt="0 deg", le="90 deg")
        else:
            out[k] = option_quantity(f"--init {k}", v.strip(), "angle", ge="-180 deg", le="360 deg")
    return out


_AIDS = ("zupt", "zaru", "nhc", "lever")


def _parse_aid(text):
    """``"zupt,zaru,nhc,lever"`` -> set; None/"none" -> empty."""
    if text is None:
        return set()
    toks = [t.strip().lower() for t in (text if isinstance(text, (list, tuple, set)) else str(text).split(","))]
    toks = [t for t in toks if t and t != "none"]
    bad = [t for t in toks if t not in _AIDS]
    if bad:
        raise ValueError(f"--aid {text!r}: unknown {', '.join(bad)}; use a comma list of {', '.join(_AIDS)}")
    return set(toks)


@dataclass(frozen=True, eq=False)
class NavigateRequest:
    """The options of ``sinslab navigate`` as given, checked and parsed once at the edge
    (before any file is read); :func:`navigate_files` and what it calls read them from here.

    The option text is kept for the run's ``config.toml``; its parsed values are
    ``lever_arm`` (3,) [m], ``aids`` (the ``--aid`` set), ``initial`` (the ``--init``
    keys in SI) and ``lag_policy`` (a :mod:`sinslab.fusion.lag` policy). ``options`` a
    :class:`~sinslab.fusion.recorded.NavOptions` to start from (None: the defaults).
    See :func:`navigate_files` for the rest.
    """

    imu_path: object
    fix_path: object = None
    fmt: str | None = None
    fix_format: str | None = None
    lever_arm: object = None
    mount: str | None = None
    frame: str | None = None
    outages: object = None
    fix_latency: float = 0.0
    lag: str = "aware"
    init: object = None
    time_sync: str = "none"
    velocity_lag: float = 0.0
    imu_delay: float = 0.0
    scale_factors: bool = False
    max_gap: float = 1.0
    allow_gaps: bool = False
    options: object = None
    columns: str | None = None
    imu_errors: str | None = None
    aid: str | None = None
    rest: str | None = None
    csv_rate: float = 1.0
    smooth: bool = False
    odometer: str | None = None
    odometer_units: str | None = None
    odometer_lever: str | None = None
    odometer_sigma: str | None = None
    fix_columns: str | None = None
    fix_quality: str | None = None
    vehicle_mount: str | None = None
    nhc_lever: str | None = None
    platform: str = "auto"
    gnss_raw: object = None
    gnss_nav: object = None
    max_satellites: object = None
    elevation_mask: float = 10.0
    strict: bool = False
    aids: frozenset = field(init=False)
    initial: MappingProxyType = field(init=False)
    lag_policy: object = field(init=False)

    def __post_init__(self):
        from sinslab.app.validate import check_mount, check_navigate_options
        from sinslab.fusion.lag import lag_policy

        put = partial(object.__setattr__, self)
        put("lever_arm", check_navigate_options(
            fix_latency=self.fix_latency, velocity_lag=self.velocity_lag, imu_delay=self.imu_delay,
            max_gap=self.max_gap, lag=self.lag, time_sync=self.time_sync, rest=self.rest, aid=self.aid,
            lever_arm=self.lever_arm))
        check_mount(self.mount, self.frame)
        put("initial", MappingProxyType(_parse_init(self.init) if isinstance(self.init, (str, type(None)))
                                        else dict(self.init)))
        put("aids", frozenset(_parse_aid(self.aid)))
        put("lag_policy", lag_policy(LAG_POLICY[self.lag]))
        if isinstance(self.imu_path, (list, tuple)):
            put("imu_path", self.imu_path[0] if len(self.imu_path) == 1 else list(self.imu_path))
        if isinstance(self.fix_path, (list, tuple)):        # positions and velocities in two tables
            put("fix_path", None if not self.fix_path else self.fix_path[0] if len(self.fix_path) == 1
                else list(self.fix_path))

    @property
    def smo(self):
        """``--smooth`` and ``--odometer*`` as :func:`_smooth_odometer_options` reads them."""
        return dict(smooth=self.smooth, odometer=self.odometer, units=self.odometer_units,
                    lever=self.odometer_lever, sigma=self.odometer_sigma)

    @property
    def vehicle(self):
        """``--vehicle-mount``, ``--nhc-lever``, ``--platform`` as :func:`_vehicle_options` reads them."""
        return dict(mount=self.vehicle_mount, lever=self.nhc_lever, platform=self.platform)

    @property
    def raw(self):
        """The raw-GNSS options."""
        return dict(path=self.gnss_raw, nav=self.gnss_nav, max_satellites=self.max_satellites,
                    mask_deg=self.elevation_mask)


def navigate_files(req: NavigateRequest, *, out=None, echo=print):
    """Read an IMU file and a fix file, run :func:`navigate_recorded`, write the run folder
    ``out``: ``req`` the command's options, already checked (the fields named below).

    Raw GNSS: ``gnss_raw`` a u-blox log or RINEX observation file (``gnss_nav`` a RINEX
    navigation file) replaces the fix file: pseudoranges and Doppler per satellite in the
    filter (tightly coupled, :mod:`sinslab.app.commands.raw_gnss`); ``max_satellites``
    limits like ``["3@60:20"]``; ``elevation_mask`` [deg] the satellites' elevation mask.

    Recorded-unit options: ``columns`` a column map of the IMU table
    (:func:`sinslab.data.columns.parse_column_map`); ``imu_errors`` the filter's error
    model, a TOML file or grade name (:mod:`sinslab.app.error_model`); ``aid`` aiding
    beyond the fixes, a comma list of ``zupt``, ``zaru``, ``nhc``, ``lever`` (antenna
    lever-arm estimation); ``rest`` where ZUPT/ZARU find rest, ``auto`` (IMU detector) or
    ``flags`` (the log's rest column, default when the column map names one);
    ``csv_rate`` [Hz] the rate of ``solution.csv`` (``solution.parquet`` holds every filter
    epoch); ``fix_columns`` a column map of the fix table (the syntax of ``columns``, keys
    :data:`sinslab.data.columns.FIX_KEYS`); ``fix_quality`` the accepted values of its
    quality/mode column (``"4,5"``); ``vehicle_mount`` the IMU body (after ``mount``) in the
    vehicle frame, a mount string (``"euler:P,R,Y"`` degrees) — with ``nhc`` its pitch and
    yaw are also estimated, as is the NHC lever ``nhc_lever`` (IMU -> rear-axle centre,
    vehicle RFU) — and ``platform`` auto | land | aircraft | marine (NHC and the odometer
    are refused off land).

    Plausibility (:mod:`sinslab.app.plausibility`): the IMU record (length, dead channels,
    ranges, |f| against gravity, gaps) and the run (long stretches where the fix NIS or the
    mean of the normalised innovations says the filter is inconsistent,
    :func:`sinslab.app.plausibility.consistency_findings`) are checked; a warning is printed
    and listed in the report, ``strict`` refuses.

    Returns ``(summary, RecordedNav, Fixes)``.
    """
    summary, res = run_command(NAVIGATE, out, lambda: _compute(req, echo), echo=echo)
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


def _compute(req: NavigateRequest, echo) -> Output:
    from sinslab.app.described import navigate_claims
    from sinslab.core import attitude as A
    from sinslab.core import earth as E         # numba and scipy: only when it runs
    from sinslab.data import guess_imu_format, load_fixes
    from sinslab.data.spool import map_times
    from sinslab.fusion.recorded import (NavOptions, estimate_time_offset, fix_errors,
                                         navigate_recorded, outage_end_errors, parse_outages,
                                         shifted_times, significant_time_offset)

    imu_one = req.imu_path[0] if isinstance(req.imu_path, list) else req.imu_path     # the table odometer columns come from
    fmt_eff = req.fmt or guess_imu_format(imu_one, sniff=req.columns is None)
    kw = {}
    if req.mount is not None:
        kw["mount"] = req.mount
    if req.frame is not None:
        kw["frame"] = req.frame
    if fmt_eff != "psins":
        kw.update(max_gap=req.max_gap, allow_gaps=req.allow_gaps)
    if fmt_eff == "rtklib-imu":
        kw["delay"] = req.imu_delay
    if req.columns is not None:
        if fmt_eff not in ("csv", "parquet"):
            raise ValueError(f"--columns applies to csv and parquet tables, not {fmt_eff!r}")
        kw["columns"] = req.columns
    aids = req.aids
    # option values checked before any file is read
    from sinslab.app.error_model import NavOptionsDraft
    from sinslab.data.columns import FIX_KEYS, parse_column_map
    from sinslab.data.tables import parse_quality_filter
    _vehicle_options(NavOptionsDraft(NavOptions()), req.vehicle or {}, False)
    parse_quality_filter(req.fix_quality)
    parse_column_map(req.fix_columns, keys=FIX_KEYS, option="--fix-columns")
    if (req.vehicle or {}).get("platform") in ("aircraft", "marine") and "nhc" in aids:
        raise ValueError(f"--aid nhc: the non-holonomic constraint assumes a wheeled land vehicle, "
                         f"not --platform {req.vehicle['platform']}")
    check_memory(req.imu_path, fmt_eff, bool((req.smo or {}).get("smooth")), fix_path=req.fix_path)
    if not (isinstance(req.csv_rate, (int, float)) and math.isfinite(req.csv_rate) and req.csv_rate > 0):
        raise ValueError(f"--csv-rate must be a positive number of Hz, got {req.csv_rate!r}")
    em = None
    if req.imu_errors is not None:
        from sinslab.app.error_model import load_error_model
        em = load_error_model(req.imu_errors)
    data = _read_imu(req.imu_path, fmt_eff, kw)
    from sinslab.app.plausibility import consistency_findings, imu_findings, settle

    found = imu_findings(data.imu, str(req.imu_path), gaps=data.gaps)
    settle([fd for fd in found if fd.refuse])
    raw_gnss = None
    if req.raw and req.raw.get("path") is not None:
        from sinslab.app.commands.raw_gnss import load_raw
        if req.fix_path is not None:
            raise ValueError("give either --gnss (fixes) or --gnss-raw (raw observations), not both")
        raw_gnss, fx = load_raw(req.raw["path"], req.raw.get("nav"), req.raw.get("max_satellites"), data.imu, echo,
                                mask_deg=req.raw.get("mask_deg", 10.0))
        fix_name = f"{req.raw['path']} (single-point solution)"
    elif req.fix_path is None:
        raise ValueError("give --gnss FILE (fixes) or --gnss-raw FILE (raw observations)")
    else:
        fix_name = " + ".join(map(str, req.fix_path)) if isinstance(req.fix_path, list) else str(req.fix_path)
        ffmt = req.fix_format             # None: the reader tells the format from the name and content
        fx, fmeta = _read_fixes(lambda: load_fixes(req.fix_path, ffmt, velocity_lag=req.velocity_lag,
                                                   columns=req.fix_columns, quality=req.fix_quality),
                                fix_name, ffmt)
        _say_fix_reading(fmeta, fix_name, echo)
    imu = data.imu
    _check_clocks(imu, fx, fix_name, req)
    if data.meta and "joined" in data.meta:
        un = data.meta["joined"]["unmatched"]
        echo(f"  IMU channels from two files joined on time; rows without a partner dropped: {un[0]} "
             f"of the first, {un[1]} of the second")
    if len(data.gaps):
        echo(f"  {len(data.gaps)} gap(s) in the IMU record bridged with the mean rate: "
             + ", ".join(f"{g[1]:.3f} s at {g[0] - imu.t0:.2f} s" for g in data.gaps[:5])
             + (" ..." if len(data.gaps) > 5 else ""))
    span = min(float(fx.t[-1]), float(imu.t[-1])) - max(float(fx.t[0]), float(imu.t[0]))
    if span > 0 and req.fix_latency >= span:
        raise ValueError(f"--fix-latency {req.fix_latency:g}: at least the {span:.1f} s the fixes and the "
                         f"IMU record share, so no fix would arrive before the record ends")
    # the options are assembled here and made once (frozen, checked) before the run
    opt = NavOptionsDraft(req.options or NavOptions())
    if req.lever_arm is not None:
        opt.lever_arm = req.lever_arm
    em = _file_says(data, fmeta if raw_gnss is None else {}, req, opt, em, echo)
    sync = None
    if req.time_sync == "auto":
        # without a lever arm a clock offset cannot be told from the antenna's lag in turns
        est = estimate_time_offset(imu, fx, lever_arm=opt.lever_arm if (req.lever_arm is not None or (
            raw_gnss is None and fmeta.get("lever_arm") is not None)) else None)
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
    elif req.time_sync != "none":
        raise ValueError(f"--time-sync must be 'auto' or 'none', got {req.time_sync!r}")
    odo_cfg = _smooth_odometer_options(opt, req.smo or {}, imu_one, sync)
    _spill_smoother(opt, imu, fx)
    em_cfg = {}
    if em is not None:
        from sinslab.app.error_model import apply_error_model
        apply_error_model(opt, em[0], em[1])
        em_cfg = em[2]
    nhc_cfg = opt.nhc_sigma
    opt.nhc_sigma = (nhc_cfg or (0.1, 0.1)) if "nhc" in aids else None
    if "zupt" in aids or "zaru" in aids:
        has_flags = data.meta and "stationary" in data.meta
        src_rest = req.rest or ("flags" if has_flags else "auto")
        if src_rest not in ("auto", "flags"):
            raise ValueError(f"--rest must be 'auto' or 'flags', got {req.rest!r}")
        if src_rest == "flags":
            if not has_flags:
                raise ValueError("--rest flags: the IMU table has no rest-flag column (name it in "
                                 "--columns as stationary=COLUMN)")
            opt.rest_flags = data.meta["stationary"]
        opt.zupt = src_rest
        opt.zaru = "zaru" in aids
    opt.estimate_lever = "lever" in aids
    veh_cfg = _vehicle_options(opt, req.vehicle or {}, "nhc" in aids)
    t_ref = float(fx.t[0])
    opt.outages = tuple(parse_outages(req.outages, t_ref)) if isinstance(req.outages, (str, type(None))) else tuple(req.outages)
    if isinstance(req.outages, str):
        from sinslab.app.validate import check_outages

        check_outages("--outages", req.outages, opt.outages, t_ref, min(float(fx.t[-1]), float(imu.t[-1])))
    opt.fix_latency = float(req.fix_latency)
    opt.lag = req.lag_policy
    opt.scale_factors = bool(req.scale_factors) or opt.scale_factors
    ini = req.initial
    if "heading" in ini:
        opt.heading = ini["heading"]
    if "course_speed" in ini:
        opt.move_speed = ini["course_speed"]
    if "course_spread" in ini:
        opt.heading_straight = ini["course_spread"]
    opt.gnss_raw = raw_gnss
    opt = opt.build()
    res = navigate_recorded(imu, fx, opt)
    release_free_memory()              # the filter's working set, before the evaluation's
    if res.fix_t.size == 0 and raw_gnss is None:
        raise ValueError(f"{fix_name}: no fix was applied (outages, latency or the record's end "
                         f"removed all {len(fx)}); the solution would be free inertial")
    t, err, idx = fix_errors(res, fx)
    hz = np.hypot(err[:, 0], err[:, 1])
    starts, oe = outage_end_errors(res, fx)
    outs = res.init["outages"]
    in_out = np.zeros(t.size, bool)
    for s, ln in outs:
        in_out |= (t >= s) & (t < s + ln)
    lab = list(res.labels)
    i_gb = [lab.index(f"eps_{a}") for a in "xyz"]
    i_ab = [lab.index(f"nabla_{a}") for a in "xyz"]
    att = A.quat_to_euler(res.nav[-1:, :4])[0]      # the last epoch's (the tables make the rest)
    metrics = {
        "duration_s": float(res.t[-1] - res.t[0]), "n_fixes_used": int(res.fix_t.size),
        "n_outages": len(outs), "outage_end_hz_err_median_m": float(np.median(oe)) if oe.size else None,
        "outage_end_hz_err_max_m": float(np.max(oe)) if oe.size else None,
        "outage_end_hz_err_m": oe.tolist(),
        "hz_err_with_fixes_median_m": float(np.median(hz[~in_out])) if (~in_out).any() else None,
        "hz_err_with_fixes_max_m": float(np.max(hz[~in_out])) if (~in_out).any() else None,
        "hz_err_with_fixes_p99_m": float(np.percentile(hz[~in_out], 99)) if (~in_out).any() else None,
        "nis_mean": float(np.mean(res.nis)) if res.nis.size else None,
        "final_pitch_deg": float(np.degrees(att[0])), "final_roll_deg": float(np.degrees(att[1])),
        "final_heading_deg": float(np.degrees(np.mod(A.yaw_to_heading(att[2]), 2 * np.pi))),
        "final_sigma_heading_deg": float(np.degrees(res.sigma[-1, 2])),
        "gyro_bias_final_dph": (res.gyro_bias[-1] / units.dph).tolist(),
        "gyro_bias_sigma_final_dph": (res.sigma[-1, i_gb] / units.dph).tolist(),
        "accel_bias_final_ug": (res.accel_bias[-1] / units.ug).tolist(),
        "accel_bias_sigma_final_ug": (res.sigma[-1, i_ab] / units.ug).tolist(),
        "initial_heading_deg": float(np.degrees(res.init["heading"])),
        "imu_gaps": int(len(data.gaps)),
    }
    hs = res.init.get("heading_sigma")
    metrics["initial_heading_sigma_deg"] = float(np.degrees(hs)) if hs is not None else None
    metrics["initial_attitude_sigma_deg"] = np.degrees(res.sigma[0, :3]).tolist()
    metrics["fixes_after_grid"] = int(res.init.get("fixes_after_grid", 0))
    metrics["filter_gyro_arw_deg_sqrth"] = (np.asarray(res.init["filter_gyro_arw"]) / (units.deg / 60)).tolist()
    metrics["filter_accel_vrw_ug_sqrthz"] = (np.asarray(res.init["filter_accel_vrw"]) / units.ug).tolist()
    noise_warn = _noise_check(res.init, metrics, echo)
    from sinslab.app.described import SETTLE_S
    settling = np.zeros(t.size, bool)
    for s0, ln in outs:
        settling |= (t >= s0 + ln) & (t < s0 + ln + SETTLE_S)
    if raw_gnss is None:
        claims, extra = navigate_claims(
            res.nis, res.innovation.shape[1] if res.innovation.ndim == 2 else 3, hz[~in_out],
            np.hypot(*np.maximum(fx.sigma[idx], opt.fix.pos_sigma_floor)[~in_out, :2].T),
            ~settling[~in_out])
    else:
        from sinslab.app.commands.raw_gnss import raw_claims
        claims, extra = raw_claims(raw_gnss)
    metrics.update(extra)
    if raw_gnss is None:            # the fix NIS (a raw run's per-row NIS is in its own claims)
        if res.nis.size and extra["nis_verdict"] != "consistent":
            echo(f"  mean NIS {metrics['nis_mean']:.2f} for a fix of dimension {extra['nis_dof']}: "
                 f"{extra['nis_verdict']}")
        if res.innovation_sigma is not None:
            found += consistency_findings(res.fix_t, res.innovation, res.innovation_sigma, res.nis,
                                          _innovation_labels(res.innovation.shape[1]))
    if res.init.get("rest_start") is not None:        # |f| at the initial rest against gravity
        from sinslab.app.plausibility import rest_gravity_findings

        at_rest = imu.slice(res.init["rest_start"], res.init["rest_end"])
        found += rest_gravity_findings(at_rest, f"{req.imu_path} (initial rest)", lat=float(fx.lat[0]),
                                       h=float(fx.h[0]))
    if sync is not None:
        metrics.update(time_sync_offset_s=sync["offset"], time_sync_ppm=sync["ppm"],
                       time_sync_offset_estimate_s=sync["offset_estimate"],
                       time_sync_offset_sigma_s=sync["offset_sigma"],
                       time_sync_ppm_estimate=sync["ppm_estimate"], time_sync_ppm_sigma=sync["ppm_sigma"],
                       time_sync_offset_applied=sync["offset_applied"],
                       time_sync_ppm_applied=sync["ppm_applied"], time_sync_windows=sync["windows"],
                       time_sync_threshold_sigmas=sync["threshold_sigmas"],
                       time_sync_speed_change_offset_s=sync.get("speed_change_offset"),
                       time_sync_speed_change_sigma_s=sync.get("speed_change_offset_sigma"),
                       time_sync_offset_confirmed=sync.get("offset_confirmed"))
    if "lever_arm_estimate" in res.init:
        metrics["lever_arm_estimate_m"] = res.init["lever_arm_estimate"]
        metrics["lever_arm_sigma_m"] = res.init["lever_arm_sigma"]
    if "vehicle_mount_estimate" in res.init:
        ve, vs = res.init["vehicle_mount_estimate"], res.init["vehicle_mount_sigma"]
        metrics["vehicle_mount_estimate_deg"] = np.degrees(ve).tolist()
        metrics["vehicle_mount_sigma_deg"] = [None if x is None else float(np.degrees(x)) for x in vs]
        metrics["nhc_lever_estimate_m"] = res.init["nhc_lever_estimate"]
        metrics["nhc_lever_sigma_m"] = res.init["nhc_lever_sigma"]
        metrics["nhc_lever_observable"] = res.init["nhc_lever_observable"]
        metrics["vehicle_mount_observable"] = res.init["vehicle_mount_observable"]
        echo(_vehicle_words(res.init, opt.aiding))
    metrics["platform"] = res.init["platform"][0]
    if opt.aiding.zupt is not None:
        metrics["rest_intervals"] = len(res.init.get("rest_intervals", []))
        metrics["rest_total_s"] = float(sum(b - a for a, b in res.init.get("rest_intervals", [])))
    for nm, g in res.init.get("aiding_gate", {}).items():
        metrics[f"{nm}_updates_applied"] = g["applied"]
        metrics[f"{nm}_updates_rejected"] = g["rejected"]
        if g["rejected"]:
            sp_ = g["rejected_spans"]
            echo(f"  {nm.upper()}: {g['rejected']} of {g['applied'] + g['rejected']} updates rejected by the "
                 f"innovation gate (the filter's own velocity/rate contradicts them), in {len(sp_)} span(s) from "
                 + ", ".join(f"{a - fx.t[0]:.1f}-{b - fx.t[0]:.1f} s" for a, b in sp_[:4])
                 + (" ..." if len(sp_) > 4 else ""))
    if res.scale is not None:
        metrics["scale_factor_final_ppm"] = (res.scale[-1] * 1e6).tolist()
    cfg = {"imu": (" + ".join(map(_abs, req.imu_path)) if isinstance(req.imu_path, (list, tuple))
                   else _abs(req.imu_path)),
           "fixes": (fix_name if req.fix_path is None else " + ".join(map(_abs, req.fix_path))
                     if isinstance(req.fix_path, list) else _abs(req.fix_path)),
           "format": data.format,
           "lever_arm": f"[{', '.join(f'{x:g}' for x in opt.fix.lever_arm)}] m",
           "mount": str(req.mount) if req.mount is not None else "none", "frame": req.frame or "rfu",
           "outages": str(req.outages or "none"), "fix_latency": f"{req.fix_latency:g} s", "lag": req.lag,
           "init": str(req.init or ""), "time_sync": req.time_sync, "velocity_lag": f"{req.velocity_lag:g} s",
           "imu_delay": f"{req.imu_delay:g} s", "scale_factors": bool(opt.errors.scale_factors),
           "columns": str(req.columns) if req.columns is not None else "auto",
           "fix_columns": str(req.fix_columns) if req.fix_columns is not None else "auto",
           "fix_quality": str(req.fix_quality) if req.fix_quality is not None else "all",
           "aid": ",".join(sorted(aids)) or "none", "rest": opt.aiding.zupt or "none",
           "csv_rate": f"{req.csv_rate:g} Hz", "heading_window": f"{opt.start.heading_window:g} s",
           "imu_errors": {**({"source": "built-in defaults (white noise measured at the initial "
                                        "rest, floored at the defaults)"} if not em_cfg else em_cfg)}}
    echo(f"{data.path}: {len(imu)} samples at {1 / imu.dt:.4g} Hz; {fix_name}: {len(fx)} fixes"
         f"{' with velocity' if fx.vel is not None else ''}")
    if not res.init.get("rest_start"):
        echo(f"  no rest at the start: pitch {np.degrees(res.init['pitch']):.2f} deg, roll "
             f"{np.degrees(res.init['roll']):.2f} deg {res.init.get('level_source')}")
    echo(f"  start {res.init['t_start'] - fx.t[0]:.2f} s after the first fix; heading "
         f"{np.degrees(res.init['heading']):.2f} deg (clockwise from north, {res.init['heading_source']})")
    if res.init.get("motion_alignment"):
        ma = res.init["motion_alignment"]
        echo(f"  attitude from an in-motion alignment over {ma['window_s']:.1f} s of fixes before the start (the gyros "
             f"would have carried the levelling {ma['carried_s']:.1f} s): filter σ at the start pitch/roll "
             f"{metrics['initial_attitude_sigma_deg'][0]:.1f}, {metrics['initial_attitude_sigma_deg'][1]:.1f} deg, "
             f"heading {metrics['initial_attitude_sigma_deg'][2]:.1f} deg"
             f"{'' if ma['heading'] else ' (heading from the course)'}")
    if res.init.get("tilt_carried_s", 0.0) > 1.0:
        echo(f"  pitch and roll carried by the gyros {res.init['tilt_carried_s']:.1f} s from the rest: filter σ at "
             f"the start pitch/roll {metrics['initial_attitude_sigma_deg'][0]:.1f}, "
             f"{metrics['initial_attitude_sigma_deg'][1]:.1f} deg, heading {metrics['initial_attitude_sigma_deg'][2]:.1f} deg")
    if oe.size:
        echo(f"  {len(outs)} outages: horizontal error at their end median {np.median(oe):.2f} m, "
             f"max {np.max(oe):.2f} m")
    if (~in_out).any():
        echo(f"  with fixes: horizontal error median {np.median(hz[~in_out]):.3f} m, 99th percentile "
             f"{np.percentile(hz[~in_out], 99):.3f} m, max {np.max(hz[~in_out]):.3f} m")
    echo(f"  final attitude pitch {metrics['final_pitch_deg']:.3f} deg, roll {metrics['final_roll_deg']:.3f} deg, "
         f"heading {metrics['final_heading_deg']:.3f} deg (sigma {metrics['final_sigma_heading_deg']:.3f})")
    echo(f"  gyro bias [°/h] {np.round(metrics['gyro_bias_final_dph'], 1).tolist()}, accel bias [µg] "
         f"{np.round(metrics['accel_bias_final_ug'], 0).tolist()}")
    warnings = settle(found, strict=req.strict, echo=echo)

    sig = res.sigma
    every = max(1, int(round(1.0 / (req.csv_rate * (res.t[1] - res.t[0]))))) if res.t.size > 1 else 1
    tables = [Series("solution", _solution_table(res), f"navigation solution at every filter epoch with filter sigma "
                     f"(Parquet; the CSV every {every}-th epoch, {1 / (every * (res.t[1] - res.t[0])):.4g} Hz)"
                     if res.t.size > 1 else "navigation solution", csv_every=every),
              Series("fix_errors", {"t_s": t - res.t[0], "east_m": err[:, 0], "north_m": err[:, 1],
                                    "up_m": err[:, 2], "in_outage": in_out.astype(float)},
                     "solution (antenna) minus fix at every fix time")]
    figures = []
    # figures
    from sinslab.app import plotting            # matplotlib: once the run has computed
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
    for s, ln in outs:
        m = (t_tr >= s) & (t_tr < s + ln)
        ax.plot(se[m], sn[m], "-", color=plotting.COLORS[1], lw=2)
    ax.plot([], [], "-", color=plotting.COLORS[1], lw=2, label="during outages")
    ax.set_aspect("equal", "datalim")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.legend()
    figures.append(Figure("track", fig, "Track on a local ENU map (origin at the first fix); outages in red."))
    fig, axes = plotting.figure(3, 1, width=9.0)
    tt = t - res.t[0]
    rest_iv = res.init.get("rest_intervals", [])
    gated = [sp_ for g in res.init.get("aiding_gate", {}).values() for sp_ in g["rejected_spans"]]
    for ax, k, nm in zip(axes, range(3), ("east", "north", "up")):
        ax.plot(tt, err[:, k], ".", ms=1.5, color=plotting.COLORS[k])
        ax.set_ylabel(f"{nm} error [m]")
        for s, ln in outs:
            ax.axvspan(s - res.t[0], s + ln - res.t[0], color="0.85", lw=0)
        for a, b in rest_iv:
            ax.axvspan(a - res.t[0], b - res.t[0], color=plotting.COLORS[2], alpha=0.15, lw=0)
        for a, b in gated:
            ax.axvspan(a - res.t[0], b - res.t[0], ymin=0.9, ymax=1.0, color=plotting.COLORS[3], lw=0)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Solution minus fixes (grey: outages"
                 + ("; green: rest (ZUPT/ZARU)" if rest_iv else "")
                 + ("; top bar: aiding rejected by the gate" if gated else "") + ")")
    figures.append(Figure("errors", fig, "Position error of the solution (antenna) versus every fix."))
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
    figures.append(Figure("sigma", fig, "Filter standard deviations of attitude and sensor biases."))
    if res.smoothed is not None:
        _smoothed_outputs(res, fx, outs, metrics, tables, figures, echo, every)
    cfg.update(odo_cfg)
    cfg.update(veh_cfg)
    notes = ["Heading is clockwise from north.",
             f"Initial attitude: {res.init.get('heading_source')}; levelling over the initial rest."
             if res.init.get("rest_start") else
             f"No rest at the start: pitch and roll {res.init.get('level_source')}; heading "
             f"{res.init.get('heading_source')}."]
    if res.init.get("motion_alignment"):
        notes.append(f"Initial attitude from an in-motion alignment over {res.init['motion_alignment']['window_s']:.1f} s "
                     f"of fixes before the start, not the rest's levelling carried "
                     f"{res.init['motion_alignment']['carried_s']:.1f} s by the gyros.")
    if hs is not None:
        notes.append(f"Initial heading {np.degrees(res.init['heading']):.2f} deg ± "
                     f"{np.degrees(hs):.2f} deg (1σ of the course window).")
    if metrics["fixes_after_grid"]:
        notes.append(f"{metrics['fixes_after_grid']} fix(es) after the last whole filter step "
                     f"({res.init['grid_end'] - fx.t[0]:.3f} s after the first fix) were not used.")
        echo(f"  {metrics['fixes_after_grid']} fix(es) after the last whole filter step dropped")
    if sync is not None:
        notes.append(f"Time sync: offset {sync['offset_estimate'] * 1e3:.1f} ± {sync['offset_sigma'] * 1e3:.1f} ms "
                     f"({'applied' if sync['offset_applied'] else 'not applied: not significant at 3σ'}), "
                     f"clock {sync['ppm_estimate']:.0f} ± {sync['ppm_sigma']:.0f} ppm "
                     f"({'applied' if sync['ppm_applied'] else 'not applied'}).")
    if "lever_arm_estimate" in res.init:
        le, ls = res.init["lever_arm_estimate"], res.init["lever_arm_sigma"]
        notes.append("Antenna lever arm estimated (vehicle right, forward, up): "
                     + ", ".join(f"{a:.3f} ± {b:.3f}" for a, b in zip(le, ls)) + " m.")
        echo("  lever arm estimate [m] " + ", ".join(f"{a:.3f} ± {b:.3f}" for a, b in zip(le, ls)))
    if opt.aiding.zupt is not None:
        notes.append(f"ZUPT{'/ZARU' if opt.aiding.zaru else ''} on {metrics['rest_intervals']} rest interval(s), "
                     f"{metrics['rest_total_s']:.0f} s in all ({opt.aiding.zupt} detection).")
    if noise_warn:
        notes.append(noise_warn)
    notes.append("Error model: " + ("; ".join(f"{k} = {v}" for k, v in em_cfg.items()) if em_cfg else
                                    "built-in defaults (white noise measured at the initial rest)."))
    if raw_gnss is not None:
        from sinslab.app.commands.raw_gnss import raw_outputs
        raw_outputs(res, raw_gnss, metrics, tables, figures, notes, echo)
        cfg.update(gnss_raw=str(req.raw["path"]), gnss_nav=str(req.raw.get("nav") or "none"),
                   max_satellites=",".join(req.raw.get("max_satellites") or ()) or "none",
                   elevation_mask_deg=float(req.raw.get("mask_deg", 10.0)))
    return Output(config=cfg, metrics=metrics, tables=tables, figures=figures, notes=notes,
                  value=(res, fx), claims=claims, warnings=warnings)


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


def _abs(path) -> str:
    """A path as the report's re-run line gives it (absolute), for config.toml."""
    return str(Path(path).absolute())


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


def _vehicle_words(init, aiding):
    """The vehicle states on the terminal: value ± σ where the drive observed them, "not
    observable" (with the σ left of the prior's) where it did not."""
    ve, vs, vo = init["vehicle_mount_estimate"], init["vehicle_mount_sigma"], init["vehicle_mount_observable"]
    d = np.degrees

    def angle(i, name):
        if vo[i]:
            return f"{name} {d(ve[i]):.2f} ± {d(vs[i]):.2f} deg"
        return f"{name} not observable (σ {d(vs[i]):.2f} of the prior {d(aiding.vehicle_mount_sigma):.2f} deg)"
    lev = [f"{a:.2f} ± {b:.2f}" if ok else f"{'xyz'[i]} not observable (σ {b:.2f} of the prior "
           f"{aiding.nhc_lever_sigma:.2f})" for i, (a, b, ok) in
           enumerate(zip(init["nhc_lever_estimate"], init["nhc_lever_sigma"], init["nhc_lever_observable"]))]
    return (f"  vehicle mount (IMU in the vehicle) {angle(0, 'pitch')}, {angle(2, 'yaw')}; NHC lever [m] "
            + ", ".join(lev))


def _offset_verdict(sync):
    """Applied, or why not: not significant in the turns, or not confirmed by the speed changes."""
    if sync["offset_applied"]:
        return "applied"
    turns = abs(sync["offset_estimate"]) > sync["threshold_sigmas"] * sync["offset_sigma"]
    return ("significant in the turns but not seen in the speed changes: not applied" if turns
            else "not significant, not applied")


def _check_clocks(imu, fx, fix_name, req):
    """Refuse an IMU and GNSS whose clocks differ by a second or more (an IMU stamped in UTC
    beside a receiver in GPS time is 18 s off): the turns show it
    (:func:`sinslab.fusion.clock_check.clock_check`); the filter would converge to a wrong
    heading and pass its claims."""
    from sinslab.fusion.clock_check import clock_check
    c = clock_check(imu, fx)
    if c is not None and c.off:
        raise ValueError(f"{req.imu_path} against {fix_name}: the clocks differ by {c.lag:+.1f} s — "
                         f"{c.describe()}; put the IMU and the GNSS on one time scale")


def _speed_change_words(sync):
    """The speed changes' view of the IMU clock, for the time-sync line."""
    n = sync.get("speed_change_windows") or 0
    if not n:
        return "; no speed changes to check an offset against" if sync["windows"] else ""
    v, sg = sync["speed_change_offset"] * 1e3, sync["speed_change_offset_sigma"] * 1e3
    return f"; speed changes {v:.1f} ± {sg:.1f} ms in {n} windows"


def _file_says(data, fmeta, req, opt, em, echo):
    """What another tool's files say about the sensor, used where no option says otherwise
    and told once: the lever arm of a NaveGo GNSS struct, the noise model of a NaveGo IMU
    struct. Returns the error model to use."""
    la = fmeta.get("lever_arm")
    if la is not None and req.lever_arm is None:
        opt.lever_arm = tuple(float(x) for x in la)
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
    return em


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


def _noise_check(init, metrics, echo):
    """The unit's white noise measured at the initial rest against the filter's: the
    densities into the metrics and, when an axis differs by more than ``NOISE_FACTOR``,
    a warning on the terminal; returns the warning (or "")."""
    if "rest_gyro_noise" not in init:
        return ""
    gm = np.asarray(init["rest_gyro_noise"]) / (units.deg / 60)
    am = np.asarray(init["rest_accel_noise"]) / units.ug
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


def _vehicle_options(opt, veh, nhc):
    """``--vehicle-mount``, ``--nhc-lever``, ``--platform`` into the options (with NHC the
    mount's pitch and yaw and the NHC lever are estimated from the values given);
    returns their config entries."""
    from sinslab.core import attitude as A
    from sinslab.data.frames import sensor_to_body
    from sinslab.fusion.recorded import PLATFORMS
    plat = veh.get("platform") or "auto"
    if plat not in PLATFORMS:
        raise ValueError(f"--platform must be one of {', '.join(PLATFORMS)}, got {plat!r}")
    opt.platform = plat
    cfg = {"platform": plat}
    if veh.get("mount") is not None:
        try:
            opt.vehicle_mount = tuple(A.dcm_to_euler(sensor_to_body(str(veh["mount"]), "rfu")))
        except ValueError as e:
            raise ValueError(f"--vehicle-mount: {e}") from None
        cfg["vehicle_mount"] = str(veh["mount"])
    if veh.get("lever") is not None:
        opt.nhc_lever_arm = tuple(_vec3(veh["lever"], "length", "--nhc-lever"))
        cfg["nhc_lever"] = f"[{', '.join(f'{x:g}' for x in opt.nhc_lever_arm)}] m"
    opt.estimate_vehicle = bool(nhc)
    cfg["vehicle_states"] = bool(nhc)
    return cfg


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
    Parquet file, or a text table's size over the mean length of its first lines; None
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
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as fh:
            head = fh.read(1 << 16)
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


# ------------------------------------------------------- smoothing and odometer ---
#: fastest wheel speed accepted [m/s] (above any car's or train's; 720 km/h)
MAX_WHEEL_SPEED = 200.0


def _smooth_odometer_options(opt, smo, imu_path, sync):
    """Put ``--smooth`` and ``--odometer*`` into the options; returns their config entries."""
    from sinslab.data.odometer import read_odometer
    opt.smooth = bool(smo.get("smooth"))
    cfg = {"smooth": opt.smooth}
    spec = smo.get("odometer")
    if spec is None:
        for k in ("units", "lever", "sigma"):
            if smo.get(k) is not None:
                raise ValueError(f"--odometer-{k} needs --odometer FILE|COLUMN")
        return cfg
    odo = read_odometer(spec, imu_path, speed_unit=smo.get("units"))
    if odo.speed.size and not np.max(odo.speed) <= MAX_WHEEL_SPEED:
        i = int(np.argmax(odo.speed))
        raise ValueError(f"--odometer {odo.source}: speed {odo.speed[i]:.4g} m/s at t = {odo.t[i]:.6g} s "
                         f"is beyond any wheeled vehicle (<= {MAX_WHEEL_SPEED:g} m/s); a wrong unit "
                         f"(--odometer-units) or column?")
    if sync is not None:
        odo = odo.shifted(sync["offset"], sync["ppm"], sync["t_ref"])
    opt.odometer = odo
    if smo.get("lever") is not None:
        opt.odometer_lever = tuple(_vec3(smo["lever"], "length", "--odometer-lever"))
    if smo.get("sigma") is not None:
        from sinslab.app.validate import option_quantity

        opt.odometer_sigma = option_quantity("--odometer-sigma", smo["sigma"], "velocity",
                                             gt="0 m/s", le="100 m/s")
    cfg.update(odometer=odo.source, odometer_lever=f"[{', '.join(f'{x:g}' for x in opt.odometer_lever)}] m",
               odometer_sigma=f"{opt.odometer_sigma:g} m/s")
    return cfg


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
    if res.options.aiding.odometer is not None:
        i = [j for j, l in enumerate(res.labels) if l.startswith("kod")][0]
        metrics.update(odometer_scale_final_ppm=float(sm.x[-1, i] * 1e6),
                       odometer_scale_sigma_ppm=float(sm.sigma[-1, i] * 1e6))
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
    ip = list(res.labels).index("dL")
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


def register(app):
    """Add ``sinslab navigate`` to the typer ``app`` (called from sinslab.cli)."""
    import typer

    @app.command()
    def navigate(imu: list[Path] = typer.Option(..., "--imu", help="recorded IMU file; twice for accelerometers and gyros in two tables on one time column"),
                 fixes: Optional[list[Path]] = typer.Option(None, "--fixes", "--gnss", help="position(/velocity) fixes (.pos, CSV, .mat avp, .ubx NAV-PVT); twice for positions and velocities in two tables on one time column"),
                 gnss_raw: Optional[Path] = typer.Option(None, "--gnss-raw", help="raw GNSS instead of fixes (tightly coupled): u-blox log (RAWX/SFRBX) or RINEX 2/3 observations"),
                 gnss_nav: Optional[Path] = typer.Option(None, "--gnss-nav", help="RINEX 2/3 navigation file (ephemerides) for --gnss-raw"),
                 max_satellites: Optional[list[str]] = typer.Option(None, "--max-satellites", help="K@START:DURATION: at most K satellites (highest first) from START s after the first GNSS epoch (repeatable)"),
                 elevation_mask: float = typer.Option(10.0, "--elevation-mask", help="satellites below this elevation [deg] are not used (--gnss-raw)"),
                 format: Optional[str] = typer.Option(None, "--format", help="IMU format: psins | csv | parquet | mat | rtklib-imu"),
                 fix_format: Optional[str] = typer.Option(None, "--fix-format", help="rtklib-pos | csv | mat-avp"),
                 lever_arm: Optional[str] = typer.Option(None, "--lever-arm", help='IMU -> antenna in vehicle right-forward-up axes, e.g. "[-0.05, 0, 0] m"'),
                 mount: Optional[str] = typer.Option(None, "--mount", help="sensor -> vehicle rotation: rpy:R,P,Y | euler:P,R,Y (deg) | quat:W,X,Y,Z | matrix:M11,...,M33"),
                 frame: Optional[str] = typer.Option(None, "--frame", help="vehicle axes of the mount: rfu (right-forward-up, default) | frd (forward-right-down) | flu (forward-left-up) | rbd (right-back-down)"),
                 outages: Optional[str] = typer.Option(None, "--outages", help="START:LEN,... (s from the first fix) or LEN/PERIOD[@FIRST]"),
                 fix_latency: float = typer.Option(0.0, "--fix-latency", help="simulated fix latency [s]"),
                 lag: str = typer.Option("aware", "--lag", help="aware | ignore (how late fixes are applied)"),
                 init: Optional[str] = typer.Option(None, "--init", help='heading="30 deg" (clockwise from north); default: from the fix course above course_speed (2 m/s) with course − gyro heading within course_spread (2 deg)'),
                 time_sync: str = typer.Option("none", "--time-sync", help="auto: estimate the IMU time offset and clock drift from turns"),
                 velocity_lag: float = typer.Option(0.0, "--velocity-lag", help="fix velocities describe this many s before their stamp"),
                 imu_delay: float = typer.Option(0.0, "--imu-delay", help="add to RTKLIB IMU time stamps [s]"),
                 scale_factors: bool = typer.Option(False, "--scale-factors", help="estimate gyro/accel scale factors"),
                 max_gap: float = typer.Option(1.0, "--max-gap", help="longest IMU gap bridged [s]"),
                 allow_gaps: bool = typer.Option(False, "--allow-gaps", help="bridge IMU gaps of any length"),
                 columns: Optional[str] = typer.Option(None, "--columns", help='IMU column map "t=Time[s],dtheta_x=DeltaTheta[0][rad],..." or a TOML file'),
                 imu_errors: Optional[str] = typer.Option(None, "--imu-errors", help="filter error model: a TOML file (ImuErrors keys) or a grade: consumer | industrial | tactical | navigation"),
                 aid: Optional[str] = typer.Option(None, "--aid", help="aiding beyond the fixes: comma list of zupt, zaru, nhc, lever"),
                 rest: Optional[str] = typer.Option(None, "--rest", help="rest for ZUPT/ZARU: auto (IMU detector) | flags (the log's column)"),
                 csv_rate: float = typer.Option(1.0, "--csv-rate", help="rate of solution.csv [Hz] (solution.parquet: every filter epoch)"),
                 out: Optional[Path] = typer.Option(None, "--out", "-o", help="output folder [default: runs/navigate-<timestamp>]"),
                 force: bool = typer.Option(False, "--force", help="replace whatever --out holds (another run, other files)"),
                 # smoothing and wheel odometer
                 smooth: bool = typer.Option(False, "--smooth", help="also write the RTS-smoothed solution (forward + backward pass)"),
                 odometer: Optional[str] = typer.Option(None, "--odometer", help="wheel speeds: FILE (t, speed columns) or a COLUMN of the IMU table"),
                 odometer_units: Optional[str] = typer.Option(None, "--odometer-units", help="speed unit if the header has none, e.g. km/h"),
                 odometer_lever: Optional[str] = typer.Option(None, "--odometer-lever", help='IMU -> wheel point, vehicle right-forward-up, e.g. "[0, -1.2, -0.3] m"'),
                 odometer_sigma: Optional[str] = typer.Option(None, "--odometer-sigma", help='wheel speed noise per update [default "0.1 m/s"]'),
                 fix_columns: Optional[str] = typer.Option(None, "--fix-columns", help='fix column map "t=time[s],lat=Pos.Latitude[deg],vd=Vel.Down[m/s],quality=Mode,..." or a TOML file'),
                 fix_quality: Optional[str] = typer.Option(None, "--fix-quality", help="accepted values of the fixes' quality/mode column (RTKLIB Q), e.g. 1,2"),
                 vehicle_mount: Optional[str] = typer.Option(None, "--vehicle-mount", help='IMU body (after --mount) in the vehicle frame, e.g. "euler:1.2,0,-1.5" (pitch, roll, yaw deg); with --aid nhc pitch and yaw are estimated from it'),
                 nhc_lever: Optional[str] = typer.Option(None, "--nhc-lever", help='IMU -> rear-axle centre, vehicle right-forward-up, e.g. "[0, -1.4, -0.5] m" (estimated from it with --aid nhc)'),
                 platform: str = typer.Option("auto", "--platform", help="auto | land | aircraft | marine: NHC and odometer only on land (auto: from the fixes)"),
                 strict: bool = typer.Option(False, "--strict", help="refuse (exit 2, nothing written) instead of warning about the data or the run")) -> None:
        """INS + position/velocity fixes (loosely coupled) or raw GNSS pseudoranges/Doppler (tightly coupled) on recorded data."""
        cli_call(lambda: navigate_files(NavigateRequest(
            imu, fixes, fmt=format, fix_format=fix_format, lever_arm=lever_arm, mount=mount, frame=frame,
            outages=outages, fix_latency=fix_latency, lag=lag, init=init, time_sync=time_sync,
            velocity_lag=velocity_lag, imu_delay=imu_delay, scale_factors=scale_factors,
            max_gap=max_gap, allow_gaps=allow_gaps, columns=columns, imu_errors=imu_errors, aid=aid,
            rest=rest, csv_rate=csv_rate, smooth=smooth, odometer=odometer,
            odometer_units=odometer_units, odometer_lever=odometer_lever,
            odometer_sigma=odometer_sigma, fix_columns=fix_columns, fix_quality=fix_quality,
            vehicle_mount=vehicle_mount, nhc_lever=nhc_lever, platform=platform, gnss_raw=gnss_raw,
            gnss_nav=gnss_nav, max_satellites=max_satellites, elevation_mask=elevation_mask,
            strict=strict), out=out, echo=typer.echo), force=force)

    return navigate
