"""What the recorded-data commands' metrics mean, the claims ``navigate`` checks, and the
command line that re-runs a command.

The commands (``navigate``, ``allan``, ``align``) name their metrics with a unit suffix
(``_m``, ``_deg``, ``_dph``, ...). :func:`metric_info` turns the suffix into the unit
printed by the report and picks a one-line description from :data:`DESCRIPTIONS`
(regular expressions over the metric name, first match wins).

:func:`navigate_claims` checks a recorded-data navigation against what a consistent
filter must show: the normalised innovation squared (NIS) averages the measurement
dimension, and the solution stays within a few fix σ of the fixes it used.

:func:`invocation` rebuilds the command line of the running CLI command from its parsed
parameters (paths made absolute), so the report can print a line that re-runs it from
any folder.
"""
from __future__ import annotations

import math
import os
import re
import shlex
from pathlib import Path

import numpy as np

__all__ = ["UNIT_SUFFIX", "DESCRIPTIONS", "metric_info", "navigate_claims", "invocation"]

#: Metric-name suffix -> unit printed in the report (longest suffix first).
UNIT_SUFFIX = (
    ("_deg_per_h", "deg/h"), ("_deg_sqrth", "deg/sqrt(h)"), ("_ug_sqrthz", "ug/sqrt(Hz)"), ("_dphpsh", "deg/h/sqrt(h)"), ("_ugpsHz", "ug/sqrt(Hz)"),
    ("_ugpsh", "ug/sqrt(h)"), ("_dpsh", "deg/sqrt(h)"), ("_arcmin", "arcmin"),
    ("_arcsec", "arcsec"), ("_dph", "deg/h"), ("_mps", "m/s"), ("_ppm", "ppm"), ("_deg", "deg"),
    ("_mps2", "m/s²"), ("_ug", "ug"), ("_mg", "mg"), ("_m", "m"), ("_s", "s"), ("_hz", "Hz"),
)

_AX = r"(gyro|accel)_([xyz])"
#: ``{command: [(regex, description), ...]}``; ``{0}``, ``{1}`` are the regex groups.
DESCRIPTIONS = {
    "allan": [
        (rf"^{_AX}_arw_dpsh$", "{0} {1}: angle random walk N (Allan deviation at τ = 1 s of the fitted −1/2 slope)"),
        (rf"^{_AX}_vrw_ugpsHz$", "{0} {1}: velocity random walk N (Allan deviation at τ = 1 s of the fitted −1/2 slope)"),
        (rf"^{_AX}_bias_instability_(dph|ug)$", "{0} {1}: bias instability B = Allan floor / 0.664 (IEEE 952)"),
        (rf"^{_AX}_tau_floor_s$", "{0} {1}: cluster time τ of the Allan floor"),
        (rf"^{_AX}_rrw_(dphpsh|ugpsh)$", "{0} {1}: rate random walk K (fitted +1/2 slope at τ = 3 s)"),
        (r"^upper_bounds$", "terms that are upper bounds only (≤ in the printed table): white noise "
                            "without a clean −1/2 slope, bias instability with no floor before the "
                            "longest cluster time"),
    ],
    "align": [
        (r"^(\w+?)_(pitch|roll|heading)_deg$", "{0} alignment: {1} (heading clockwise from north)"),
        (r"^(\w+?)_sigma_(pitch|roll|heading)_arcmin$", "{0} alignment: 1σ of {1}"),
        (r"^limit_(pitch|roll|heading)_arcmin$", "limit accuracy of the {0} alignment for the assumed sensor biases"),
        (r"^f_norm_mps2$", "mean specific force magnitude over the window"),
        (r"^gravity_mps2$", "normal gravity at the stated latitude and height"),
        (r"^w_norm_over_wie$", "mean angular rate magnitude / Earth rate (≈1 at rest)"),
        (r"^f_var_rms_mps2$", "RMS of the specific-force variation over the window (vibration)"),
        (r"^meas_noise_ug$", "measurement noise σ of the fine alignment's level specific-force measurement"),
        (r"^nis_mean$", "mean normalised innovation squared of the fine alignment (expected: the measurement dimension)"),
        (r"^duration_s$", "length of the aligned window"),
    ],
    "transfer-align": [
        (r"^mounting_arcmin_(\w+)$", "estimated mounting x, y, z (slave relative to master), {0}"),
        (r"^mounting_sigma_arcmin_(\w+)$", "1σ of the mounting estimate, {0}"),
        (r"^gyro_bias_dph_(\w+)$", "estimated slave gyro biases x, y, z, {0}"),
        (r"^gyro_bias_sigma_dph_(\w+)$", "1σ of the slave gyro bias estimate, {0}"),
        (r"^accel_bias_mg_(\w+)$", "estimated slave accelerometer biases x, y, z, {0}"),
        (r"^accel_bias_sigma_mg_(\w+)$", "1σ of the slave accelerometer bias estimate, {0}"),
        (r"^ref_mounting_arcmin$", "the file's reference mounting x, y, z"),
        (r"^ref_gyro_bias_dph$", "the file's reference slave gyro biases x, y, z"),
        (r"^ref_accel_bias_mg$", "the file's reference slave accelerometer biases x, y, z"),
    ],
    "navigate": [
        (r"^duration_s$", "navigated time span"),
        (r"^n_fixes_used$", "fixes applied by the filter"),
        (r"^n_outages$", "simulated fix outages"),
        (r"^outage_end_hz_err_median_m$", "horizontal error at the end of the outages, median"),
        (r"^outage_end_hz_err_max_m$", "horizontal error at the end of the outages, largest"),
        (r"^outage_end_hz_err_m$", "horizontal error at the end of each outage"),
        (r"^hz_err_with_fixes_median_m$", "horizontal solution − fix difference outside outages, median"),
        (r"^hz_err_with_fixes_max_m$", "horizontal solution − fix difference outside outages, largest"),
        (r"^hz_err_with_fixes_p99_m$", "horizontal solution − fix difference outside outages, 99th percentile"),
        (r"^hz_err_with_fixes_median_over_sigma$", "median of horizontal solution − fix over the fixes' stated horizontal σ"),
        (r"^hz_err_settled_p99_over_sigma$", "99th percentile of horizontal solution − fix over the fixes' σ, "
         "outside outages and more than 10 s after one"),
        (r"^nis_verdict$", "the fix noise model judged by the mean NIS: consistent, pessimistic (NIS too low: "
         "σ stated too large) or overconfident (NIS too high)"),
        (r"^nis_mean$", "mean normalised innovation squared of the applied fixes (expected: measurement dimension)"),
        (r"^nis_dof$", "measurement dimension of a fix (3 position, 6 position + velocity)"),
        (r"^(pseudorange|doppler)_nis_mean$", "mean ν²/(H P Hᵀ + R) of the {0} rows used, one at a time (expected: 1)"),
        (r"^(pseudorange|doppler)_nis_verdict$", "the {0} noise model judged by its mean NIS: consistent, pessimistic "
         "(NIS too low: σ stated too large) or overconfident (NIS too high)"),
        (r"^(pseudorange|doppler)_nis_window_max$", "largest NIS per degree of freedom of the {0} rows over a "
         "30-s window, epoch by epoch (expected near 1)"),
        (r"^(pseudorange|doppler)_nis_window_limit$", "the χ² bound per degree of freedom of that window (false "
         "alarm 0.001 per window)"),
        (r"^(pseudorange|doppler)_nis_window_failing$", "share of the epochs whose 30-s window NIS of the {0} rows "
         "is over its χ² bound (a warning where that lasts 30 s)"),
        (r"^final_(pitch|roll|heading)_deg$", "{0} at the end (heading clockwise from north)"),
        (r"^final_sigma_heading_deg$", "filter 1σ of the heading at the end"),
        (r"^gyro_bias_final_dph$", "estimated gyro biases x, y, z at the end"),
        (r"^gyro_bias_sigma_final_dph$", "filter 1σ of the gyro biases x, y, z at the end"),
        (r"^accel_bias_final_ug$", "estimated accelerometer biases x, y, z at the end"),
        (r"^accel_bias_sigma_final_ug$", "filter 1σ of the accelerometer biases x, y, z at the end"),
        (r"^initial_heading_deg$", "heading the filter started from (clockwise from north)"),
        (r"^imu_gaps$", "gaps in the IMU record bridged with the mean rate"),
        (r"^time_sync_offset_s$", "IMU time-stamp offset applied (estimated from turns)"),
        (r"^time_sync_ppm$", "IMU clock drift applied (estimated from turns)"),
        (r"^time_sync_offset_estimate_s$", "IMU time-stamp offset estimated from turns"),
        (r"^time_sync_offset_sigma_s$", "1σ of the time-stamp offset estimate"),
        (r"^time_sync_ppm_estimate$", "IMU clock drift estimated from turns [ppm]"),
        (r"^time_sync_ppm_sigma$", "1σ of the clock drift estimate [ppm]"),
        (r"^time_sync_offset_applied$", "whether the offset was applied (significant at 3σ)"),
        (r"^time_sync_ppm_applied$", "whether the clock drift was applied"),
        (r"^time_sync_windows$", "windows of turns the offset and drift were fitted from"),
        (r"^time_sync_speed_change_offset_s$", "IMU time-stamp offset seen in the speed changes (forward specific "
         "force against the fixes' speed rate; a lever arm cannot fake it)"),
        (r"^time_sync_speed_change_sigma_s$", "1σ of the offset seen in the speed changes"),
        (r"^time_sync_offset_confirmed$", "whether the speed changes confirm the turns' offset (an offset is "
         "applied only then)"),
        (r"^time_sync_threshold_sigmas$", "how many σ the offset and drift had to reach to be applied (3σ, or "
         "Student's t at 1 % for the fit's degrees of freedom)"),
        (r"^initial_heading_sigma_deg$", "1σ of the initial heading (from the fix course window)"),
        (r"^initial_attitude_sigma_deg$", "filter 1σ of the attitude error φE, φN, φU at its first epoch"),
        (r"^start_source_(\w+)$", "where the start's {0} came from: measured (at the rest, in motion), given "
         "(--init), or a default because the record has nothing to measure it from"),
        (r"^fixes_after_grid$", "fixes after the last whole filter step, not used"),
        (r"^filter_gyro_arw_deg_sqrth$", "gyro angle random walk x, y, z the filter assumed"),
        (r"^filter_accel_vrw_ug_sqrthz$", "accelerometer velocity random walk x, y, z the filter assumed"),
        (r"^rest_gyro_noise_deg_sqrth$", "gyro white noise x, y, z measured at the initial rest (vibration included)"),
        (r"^rest_accel_noise_ug_sqrthz$", "accelerometer white noise x, y, z measured at the initial rest"),
        (r"^rest_over_filter_noise_(gyro|accel)$", "{0} noise measured at rest over the filter's, per axis "
         "(a warning beyond 3 or below 1/3)"),
        (r"^platform$", "platform kind (given, or inferred from the fixes' speed and climb rate)"),
        (r"^scale_factor_final_ppm$", "estimated gyro x, y, z and accelerometer x, y, z scale factors at the end"),
        (r"^smoothed_hz_err_rms_m$", "RMS horizontal error of the RTS-smoothed solution at the reference fixes"),
        (r"^forward_hz_err_rms_m$", "RMS horizontal error of the forward filter at the same fixes"),
        (r"^smoothed_err_reference$", "which fixes the two RMS errors above are measured at"),
        (r"^outage_mid_hz_err_forward_m$", "forward horizontal error at the middle of each outage"),
        (r"^outage_mid_hz_err_smoothed_m$", "smoothed horizontal error at the middle of each outage"),
        (r"^outage_mid_hz_err_smoothed_median_m$", "smoothed horizontal error at the middle of the outages, median"),
        (r"^smoothed_stored_epochs$", "filter epochs stored for the backward pass"),
    ],
}


def _unit(name: str) -> str:
    for suf, unit in UNIT_SUFFIX:
        if name.endswith(suf):
            return unit
    for suf, unit in UNIT_SUFFIX:                     # unit inside: mounting_arcmin_kain
        if f"{suf}_" in name:
            return unit
    return ""


def metric_info(command: str, metrics: dict, extra=()) -> dict:
    """``{name: {"unit", "description"}}`` for the metrics of ``command``; ``extra``
    ``((regex, description), ...)`` rules of the run's plug-ins, tried first (an aid
    describes its own metrics: :attr:`sinslab.fusion.aids.base.Report.descriptions`)."""
    rules = [*extra, *DESCRIPTIONS.get(command, [])]
    out = {}
    for name in metrics:
        desc = ""
        for rx, text in rules:
            m = re.match(rx, name)
            if m:
                desc = text.format(*m.groups())
                break
        unit = _unit(name)
        if name.endswith("_ppm"):
            unit = "ppm"
        if isinstance(metrics[name], bool):          # a yes/no answer has no unit
            unit = ""
        out[name] = {"unit": unit, "description": desc}
    if "runtime_s" in metrics:
        out["runtime_s"] = {"unit": "s", "description": "wall time of the computation"}
    return out


# ------------------------------------------------------------------------- navigate ------
#: Band for the mean NIS around the measurement dimension m: a factor of 2 either way is
#: a fix noise model off by √2 in σ, the point where a filter on recorded data is
#: mistuned (a consistent filter gives m within a few percent over hundreds of fixes).
NIS_FACTOR = 2.0
#: Solution − fix allowed, in units of the consistent value: after an update the residual's
#: variance is R − HPHᵀ <= R, so the median of |horizontal residual| / σ_h is at most
#: √(ln 2) (Rayleigh median); three times that leaves room for σ stated somewhat too small.
#: The median, not the RMS: the first fixes after an outage carry the coasted error.
FIX_RESIDUAL_SIGMAS = 3.0


def nis_claim(cid: str, about: str, nis, dof: int, *, rows="applied fixes", empty="no fixes applied",
              origin=None):
    """The one NIS rule of recorded-data runs: ``(claim, mean NIS, verdict)``.

    The claim ``cid`` holds when the mean NIS of the finite values is at most
    ``NIS_FACTOR × dof`` (not overconfident). A mean below ``dof / NIS_FACTOR`` passes too:
    the noise is stated larger than it is (the solution is sound, its σ too wide), and the
    verdict says "pessimistic noise model"; above the band it is "overconfident noise
    model", inside it "consistent", with no value ``empty``.

    Parameters
    ----------
    cid : str
        Claim id.
    about : str
        What the filter is not overconfident about ("the fixes", "the pseudoranges").
    nis : array (J,)
        Normalised innovation squared of each applied measurement (NaN ignored).
    dof : int
        Dimension of one measurement.
    rows : str
        What the J values are, for the statement ("applied fixes").
    """
    from sinslab.app.claims import Claim

    nis = np.asarray(nis, float)
    nis = nis[np.isfinite(nis)]
    mean_nis = float(np.mean(nis)) if nis.size else float("nan")
    hi = dof * NIS_FACTOR
    verdict = (empty if not nis.size else "overconfident noise model" if mean_nis > hi else
               "pessimistic noise model" if mean_nis < dof / NIS_FACTOR else "consistent")
    claim = Claim.at_most(
        cid,
        f"the filter is not overconfident about {about}: mean NIS of the {nis.size} {rows} at most "
        f"{NIS_FACTOR:g}× the measurement dimension {dof} (a mean below {dof / NIS_FACTOR:g} is a pessimistic "
        f"noise model, not a failure: here {verdict})", mean_nis if nis.size else float("nan"), hi, "",
        origin=origin)
    return claim, mean_nis, verdict


def navigate_claims(nis, dof: int, hz_err_with_fixes, fix_sigma_h, settled=None) -> tuple[list, dict]:
    """Claims of a recorded-data navigation; returns ``(claims, extra metrics)``.

    - ``nis_not_overconfident``: the mean NIS of the applied fixes is at most
      ``NIS_FACTOR`` × the measurement dimension. A mean below ``dof / NIS_FACTOR`` is not a
      failure but a pessimistic noise model (noise stated larger than it is: the solution
      is sound, its σ too wide), reported in ``nis_verdict``.
    - ``fix_residual``: the median horizontal solution − fix in units of the fixes' σ.
    - ``fix_residual_p99``: its 99th percentile over the *settled* fixes (outside outages
      and more than ``SETTLE_S`` after one): a median passes while a stretch of the drive
      is ruined (a rest applied at 24 m/s, 173 m off while the median read 0.8 m); the
      Rayleigh 99th percentile is √(2 ln 100) = 3.03, allowed ``FIX_RESIDUAL_SIGMAS``× that.

    Parameters
    ----------
    nis : array (J,)
        Normalised innovation squared of each applied fix.
    dof : int
        Measurement dimension of one fix (3 position, 6 position + velocity).
    hz_err_with_fixes : array (K,) [m]
        Horizontal solution − fix difference at the fix times outside outages (the first
        fixes after an outage included: the median is not moved by them).
    fix_sigma_h : array (K,) [m]
        The same fixes' stated horizontal σ (root sum of squares of east and north σ).
    settled : array (K,) of bool, optional
        Which of them come more than ``SETTLE_S`` after an outage (default: all).
    """
    from sinslab.app.claims import Claim

    claim, _, verdict = nis_claim("nis_not_overconfident", "the fixes", nis, dof, origin="check")
    claims = [claim]
    e = np.asarray(hz_err_with_fixes, float)
    s = np.asarray(fix_sigma_h, float)
    ok = np.isfinite(e) & np.isfinite(s) & (s > 0)
    ratio = float(np.median(e[ok] / s[ok])) if ok.any() else float("nan")
    limit = FIX_RESIDUAL_SIGMAS * math.sqrt(math.log(2.0))
    claims.append(Claim.at_most(
        "fix_residual",
        "the solution follows the fixes it uses: median of horizontal solution − fix (outside "
        "outages) in units of the fixes' stated horizontal σ; a consistent filter gives at most "
        f"√(ln 2) = 0.83 (Rayleigh median), allowed {FIX_RESIDUAL_SIGMAS:g}× that", ratio, limit, "σ",
        origin="check"))
    st = ok if settled is None else ok & np.asarray(settled, bool)
    p99 = float(np.percentile(e[st] / s[st], 99)) if st.any() else float("nan")
    claims.append(Claim.at_most(
        "fix_residual_p99",
        f"no stretch of the solution leaves the fixes: 99th percentile of horizontal solution − fix "
        f"over the fixes' σ, outside outages and more than {SETTLE_S:g} s after one; a consistent "
        f"filter gives at most √(2 ln 100) = 3.03 (Rayleigh), allowed {FIX_RESIDUAL_SIGMAS:g}× that",
        p99, FIX_RESIDUAL_SIGMAS * math.sqrt(2 * math.log(100.0)), "σ", origin="check"))
    return claims, {"nis_dof": int(dof), "hz_err_with_fixes_median_over_sigma": ratio,
                    "hz_err_settled_p99_over_sigma": p99, "nis_verdict": verdict}


#: seconds after an outage before the fixes count as settled for the 99th-percentile claim
SETTLE_S = 10.0


# ------------------------------------------------------------------------- invocation ----
def invocation() -> str | None:
    """The CLI line of the running click/typer command, paths absolute; None outside the CLI.

    Rebuilt from the parsed parameters (not ``sys.argv``), so it is the same whether the
    command was started from a shell or a test runner; options left at their default are
    omitted.
    """
    import importlib

    ctx = None
    for pkg in ("typer._click", "click"):            # typer >= 0.2x vendors its own click
        try:
            glob = importlib.import_module(f"{pkg}.globals")
        except ImportError:
            continue
        ctx = glob.get_current_context(silent=True)
        if ctx is not None:
            break
    if ctx is None:
        return None
    words = ["sinslab", ctx.info_name] if ctx.parent is not None else ["sinslab"]
    for p in ctx.command.params:
        if p.name not in ctx.params:
            continue
        v = ctx.params[p.name]
        if getattr(p, "param_type_name", "") == "argument":
            words += [_word(x) for x in (v if isinstance(v, (list, tuple)) else [v]) if x is not None]
            continue
        if v is None or v == p.default or p.name in ("help", "install_completion", "show_completion"):
            continue
        opt = max(p.opts, key=len)
        if getattr(p, "is_flag", False):
            if isinstance(v, bool):
                if v:
                    words.append(opt)
                elif p.secondary_opts:
                    words.append(p.secondary_opts[0])
            continue
        for x in (v if getattr(p, "multiple", False) else [v]):
            words += [opt, _word(x)]
    return shlex.join(str(w) for w in words)


def _word(v) -> str:
    if isinstance(v, os.PathLike):
        return str(Path(v).absolute())
    return str(v)
