"""The configuration of ``sinslab navigate``: one validated, unit-carrying configuration
(the machinery of the experiments, :mod:`sinslab.app.config`), read from a TOML file
(``--config``), ``--set key=value`` items and the command's options, which are short
forms of its keys (:data:`FLAGS`).

Sections: ``[imu]`` the log and how to read it, ``[gnss]`` the GNSS source (``source =
"fixes"`` with ``[gnss.fixes]`` or ``"raw"`` with ``[gnss.raw]``) and what any source
shares (lever arm, outages), ``[start]``, ``[filter]``, ``[output]``, and one section per
aid named in ``aid`` (the aid's own settings, declared in its module of
:mod:`sinslab.fusion.aids`). Resolution: defaults <- the file <- the options <- ``--set``;
an unknown key, a quantity without its unit, a key of an aid that is not enabled or of
the source not chosen is one line naming the key and where it came from (exit 2). The
run folder's ``config.toml`` is the resolved configuration: ``sinslab navigate --config
runs/x/config.toml`` runs the same navigation again.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Union

from pydantic import Field, PlainValidator, ValidationError, create_model

from sinslab.app.config import (QV, Choice, ConfigError, Number, OrWord, Q, Section, _format_error, deep_merge,
                                flatten, load_toml, parse_set, settings_section)

__all__ = ["FLAGS", "resolve_navigate", "navigate_model", "default_toml", "aids_of", "flag_overrides"]

#: the longest latency, velocity lag [s] and IMU delay accepted, the longest lever arm [m]
MAX_LATENCY = "60 s"
MAX_IMU_DELAY = "3600 s"
MAX_LEVER = "200 m"
Files = Union[str, list[str]]


class ImuKeys(Section):
    """The IMU log and how to read it."""

    file: Files = Field("", description="recorded IMU file; two for accelerometers and gyros in two tables "
                                        "on one time column (--imu)")
    format: Choice(("auto", "psins", "csv", "parquet", "mat", "navego", "kf-gins", "rosbag", "rtklib-imu")) = Field(
        "auto", description="IMU format; auto: from the name and what the file holds (--format)")
    columns: str = Field("auto", description="column map of a CSV/Parquet table or a TOML file (--columns)")
    mount: str = Field("none", description="sensor -> vehicle rotation rpy:R,P,Y | euler:P,R,Y | quat:... | "
                                           "matrix:... (--mount)")
    frame: Choice(("auto", "rfu", "frd", "flu", "rbd")) = Field(
        "auto", description="vehicle axes of the mount: rfu (right-forward-up) | frd | flu | rbd; auto: the "
                            "format's own (frd for RTKLIB IMU logs, else rfu) (--frame)")
    max_gap: Q("time", gt="0 s") = Field("1 s", description="longest IMU gap bridged (--max-gap)")
    allow_gaps: bool = Field(False, description="bridge IMU gaps of any length (--allow-gaps)")
    delay: Q("time", ge="-" + MAX_IMU_DELAY, le=MAX_IMU_DELAY) = Field(
        "0 s", description="added to RTKLIB IMU time stamps (--imu-delay)")
    time_sync: Choice(("none", "auto")) = Field(
        "none", description="auto: estimate the IMU time offset and clock drift from turns (--time-sync)")


class FixesKeys(Section):
    """Position (and velocity) fixes: the loosely coupled source."""

    file: Files = Field("", description="fixes (.pos, CSV, .mat avp, .ubx NAV-PVT); two for positions and "
                                        "velocities in two tables (--fixes, --gnss)")
    format: Choice(("auto", "rtklib-pos", "csv", "mat-avp", "navego", "kf-gins", "rosbag", "two-geo", "ubx")) = Field(
        "auto", description="fix format; auto: from the name and what the file holds (--fix-format)")
    columns: str = Field("auto", description="column map of the fix table or a TOML file (--fix-columns)")
    quality: str = Field("all", description="accepted values of the quality/mode column, e.g. 1,2 (--fix-quality)")
    velocity_lag: Q("time", ge="0 s", le=MAX_LATENCY) = Field(
        "0 s", description="fix velocities describe this long before their stamp (--velocity-lag)")
    latency: Q("time", ge="0 s", le=MAX_LATENCY) = Field("0 s", description="simulated fix latency (--fix-latency)")
    lag: Choice(("aware", "ignore")) = Field("aware", description="how late fixes are applied (--lag)")
    error: Choice(("none", "auto")) = Field(
        "none", description="the fixes' time-correlated error: none (white, as stated) | auto (measured from the "
                            "record and taken as Gauss-Markov states where metre-level)")
    noise: Choice(("stated", "innovations")) = Field(
        "stated", description="the fixes' σ: stated (as the file gives them) | innovations (raised to the long-run "
                              "variance of the fixes' own innovations where larger: optimistic σ, errors that last)")
    velocity_check: OrWord(Q("time", gt="0 s", le="600 s"), "none") = Field(
        "none", description="check each velocity fix against the position fixes over this trailing window "
                            "(e.g. 10 s) and raise its σ by the lasting velocity error they contradict; "
                            "none: no check")
    robust: OrWord(Number(gt=0.0, lt=1.0), "none") = Field(
        "none", description="down-weight a fix whose innovation the filter cannot explain at this probability "
                            "(Chang 2014); none: every fix as stated")


class RawKeys(Section):
    """Raw observations: the tightly coupled source."""

    file: str = Field("", description="u-blox log (RAWX/SFRBX) or RINEX 2/3 observations (--gnss-raw)")
    nav: str = Field("none", description="RINEX 2/3 navigation file (--gnss-nav)")
    max_satellites: list[str] = Field([], description="K@START:DURATION limits (--max-satellites)")
    elevation_mask: Q("angle", ge="0 deg", lt="90 deg") = Field(
        "10 deg", description="satellites below are not used (--elevation-mask)")
    pseudorange_sigma: Q("length", gt="0 m", le="1000 m") = Field(
        "1 m", description="σ of a pseudorange at zenith and strong signal")
    doppler_sigma: Q("velocity", gt="0 m/s", le="100 m/s") = Field(
        "0.05 m/s", description="σ of a range rate at zenith and strong signal")
    gate: OrWord(Number(gt=0.0), "none") = Field(5.0, description="innovation gate of single rows [σ] (none: no gate)")
    phase: Choice(("none", "tdcp")) = Field(
        "none", description="carrier phase without a base: tdcp (time-differenced phase of every signal) | none "
                            "(--phase); with a base station (base) RTK uses the phase")
    phase_sigma: Q("length", gt="0 m", le="1 m") = Field(
        "3 mm", description="σ of a carrier phase at zenith and strong signal (TDCP, RTK)")
    base: str = Field("", description="the base station's raw observations for RTK (--gnss-base); navigation from "
                                      "gnss.raw.nav")
    base_position: OrWord(QV("length"), "none") = Field(
        "none", description="the base antenna's ECEF position \"[X, Y, Z] m\" or \"X,Y,Z m\" (--base-position)")
    ar: Choice(("hold", "continuous", "off")) = Field(
        "hold", description="RTK integer resolution: hold (fix and hold) | continuous (fixed solution reported, "
                            "filter float) | off (float only)")
    ratio: Number(gt=1.0) = Field(3.0, description="RTK ratio-test threshold")
    dynamics: Choice(("static", "kinematic")) = Field(
        "kinematic", description="motion model of RTK without an IMU: static antenna | constant velocity")


class GnssKeys(Section):
    """The GNSS source and what every source shares."""

    source: Choice(("fixes", "raw")) = Field("fixes", description="fixes (loosely coupled) | raw (tightly "
                                                                  "coupled); --fixes / --gnss-raw set it")
    lever_arm: OrWord(QV("length", ge="-" + MAX_LEVER, le=MAX_LEVER), "none") = Field(
        "none", description="IMU -> antenna, vehicle right-forward-up (--lever-arm); none: not measured, "
                            "taken as zero (the time sync then fits the antenna's lag in turns too)")
    outages: str = Field("none", description="START:LEN,... or LEN/PERIOD[@FIRST] (--outages); START and "
                                             "FIRST on the outage_clock")
    outage_clock: Choice(("first-fix", "log", "gps")) = Field(
        "first-fix", description="what an outage's START counts: first-fix (s from the first fix) | log (the "
                                 "log's own stamps, as the files hold them) | gps (GPS time: seconds of week "
                                 "or YYYY-MM-DDTHH:MM:SS) (--outage-clock)")


class StartKeys(Section):
    """How the filter starts."""

    heading: OrWord(Q("angle", ge="-180 deg", le="360 deg"), "none") = Field(
        "none", description="initial heading, clockwise from north (--init heading=); none: from the course")
    course_speed: Q("velocity", gt="0 m/s", le="100 m/s") = Field(
        "2 m/s", description="the course gives the heading above this speed (--init course_speed=)")
    course_spread: Q("angle", gt="0 deg", le="90 deg") = Field(
        "2 deg", description="largest spread of course − gyro heading in the window (--init course_spread=)")
    platform: Choice(("auto", "land", "aircraft", "marine")) = Field(
        "auto", description="aids of a wheeled vehicle only on land; auto: from the fixes (--platform)")
    pitch: OrWord(Q("angle", ge="-90 deg", le="90 deg"), "none") = Field(
        "none", description="initial pitch, nose up (--init pitch=); none: levelled at the rest or in motion")
    roll: OrWord(Q("angle", ge="-180 deg", le="180 deg"), "none") = Field(
        "none", description="initial roll, right wing down (--init roll=); none: levelled at the rest or in motion")
    attitude_sigma: OrWord(QV("angle", gt="0 deg", le="180 deg"), "default") = Field(
        "default", description="1σ of the initial attitude errors east, north, up (≈ pitch/roll, heading) "
                               "(--init attitude_sigma=); default: [1, 1, 5] deg, narrowed where the start "
                               "measures better")
    time: OrWord(Q("time", ge="-1e10 s", le="1e10 s"), "none") = Field(
        "none", description="time the given attitude holds at, as the log stamps it (--init time=); needs "
                            "pitch, roll and heading; none: the first fix (or the rest's start)")
    latitude: OrWord(Q("angle", ge="-90 deg", le="90 deg"), "none") = Field(
        "none", description="the IMU's initial latitude (--init latitude=); none: the fixes' at the start")
    longitude: OrWord(Q("angle", ge="-180 deg", le="360 deg"), "none") = Field(
        "none", description="the IMU's initial longitude (--init longitude=)")
    height: OrWord(Q("length", ge="-1000 km", le="100 km"), "none") = Field(
        "none", description="the IMU's initial ellipsoidal height (--init height=)")
    velocity: OrWord(QV("velocity", ge="-2000 m/s", le="2000 m/s"), "none") = Field(
        "none", description="initial velocity east, north, up (--init velocity=); none: the fixes' at the start")
    position_sigma: OrWord(QV("length", gt="0 m", le="1000 km"), "auto") = Field(
        "auto", description="1σ of the initial position east, north, up (--init position_sigma=); auto: twice "
                            "the σ of the fix nearest the start")
    velocity_sigma: OrWord(QV("velocity", gt="0 m/s", le="1000 m/s"), "auto") = Field(
        "auto", description="1σ of the initial velocity east, north, up (--init velocity_sigma=); auto: twice "
                            "the σ of the fix nearest the start")


class FilterKeys(Section):
    """The filter."""

    imu_errors: str = Field("default", description="error model: a TOML file (ImuErrors keys) or a grade "
                                                   "(consumer | industrial | tactical | navigation); default: "
                                                   "built in, white noise measured at the initial rest (--imu-errors)")
    scale_factors: bool = Field(False, description="estimate gyro/accel scale factors (--scale-factors)")
    smooth: bool = Field(False, description="also the RTS-smoothed solution (--smooth)")


class OutputKeys(Section):
    """What is written."""

    csv_rate: Q("frequency", gt="0 Hz") = Field("1 Hz", description="rate of solution.csv (--csv-rate)")
    strict: bool = Field(False, description="refuse (exit 2) instead of warning about the data or the run "
                                            "(--strict)")
    kml: bool = Field(False, description="also write the track, the fixes and the outages as RUN.kml beside the "
                                         "run folder, as sinslab export RUN --to kml (--kml)")


def _estimator(v):
    from sinslab.core.errors import InputError
    from sinslab.fusion.estimators import canonical_estimator
    try:
        return canonical_estimator(v)
    except InputError as e:
        raise ValueError(str(e)) from None


#: the estimator, a strategy (:mod:`sinslab.fusion.estimators`)
Estimator = Annotated[str, PlainValidator(_estimator)]


#: option -> (dotted key, value kind): the command's options as short forms of keys; a
#: number is written with the unit of the kind (``--max-gap 2`` is ``imu.max_gap = "2 s"``),
#: a file named on the command line made absolute (the run's config.toml re-runs from anywhere)
FLAGS = {
    "--imu": ("imu.file", "files"), "--format": ("imu.format", None), "--columns": ("imu.columns", "maybe_path"),
    "--mount": ("imu.mount", None), "--frame": ("imu.frame", None), "--max-gap": ("imu.max_gap", "s"),
    "--allow-gaps": ("imu.allow_gaps", None), "--imu-delay": ("imu.delay", "s"),
    "--time-sync": ("imu.time_sync", None),
    "--fixes": ("gnss.fixes.file", "files"), "--fix-format": ("gnss.fixes.format", None),
    "--fix-columns": ("gnss.fixes.columns", "maybe_path"), "--fix-quality": ("gnss.fixes.quality", None),
    "--velocity-lag": ("gnss.fixes.velocity_lag", "s"), "--fix-latency": ("gnss.fixes.latency", "s"),
    "--lag": ("gnss.fixes.lag", None), "--lever-arm": ("gnss.lever_arm", None),
    "--outages": ("gnss.outages", None), "--outage-clock": ("gnss.outage_clock", None),
    "--gnss-raw": ("gnss.raw.file", "path"), "--gnss-nav": ("gnss.raw.nav", "path"),
    "--max-satellites": ("gnss.raw.max_satellites", "list"), "--elevation-mask": ("gnss.raw.elevation_mask", "deg"),
    "--gnss-base": ("gnss.raw.base", "path"), "--base-position": ("gnss.raw.base_position", "position"),
    "--phase": ("gnss.raw.phase", None),
    "--platform": ("start.platform", None),
    "--imu-errors": ("filter.imu_errors", "maybe_path"), "--scale-factors": ("filter.scale_factors", None),
    "--smooth": ("filter.smooth", None), "--estimator": ("estimator", None),
    "--csv-rate": ("output.csv_rate", "Hz"), "--strict": ("output.strict", None), "--kml": ("output.kml", None),
}
#: ``--init`` keys -> start keys
INIT_KEYS = {k: k for k in ("heading", "pitch", "roll", "attitude_sigma", "time", "latitude", "longitude",
                            "height", "velocity", "position_sigma", "velocity_sigma", "course_speed",
                            "course_spread")}


def _aid_types():
    from sinslab.fusion.aids import aid_types
    return aid_types()


def navigate_model(aids=(), source="fixes"):
    """The config model of a run with the aids ``aids`` (names) and the GNSS ``source``:
    the fixed sections, the chosen source's sub-section and one section per aid."""
    types = _aid_types()
    sub = {"fixes": (FixesKeys, FixesKeys()), "raw": (RawKeys, RawKeys())}[source]
    gnss = create_model(f"Gnss_{source}", __base__=GnssKeys, **{source: sub})
    fields = {"aid": (list[str], Field([], description="aids beside the GNSS (--aid): "
                                                       + ", ".join(types))),
              "estimator": (Estimator, Field("filter", description="filter (Kalman; --smooth adds the RTS "
                                                                   "smoother) | graph (factor graph, batch) | "
                                                                   "fixed-lag:SECONDS (--estimator)"))}
    fields.update(imu=(ImuKeys, ImuKeys()), gnss=(gnss, gnss()), start=(StartKeys, StartKeys()),
                  filter=(FilterKeys, FilterKeys()), output=(OutputKeys, OutputKeys()))
    for name in aids:
        sec = _aid_section(name)
        fields[name] = (sec, sec())
    return create_model("NavigateConfig", __base__=Section, **fields)


_SECTIONS: dict = {}


def _aid_section(name):
    """The config section of aid ``name``, from its declared settings."""
    if name not in _SECTIONS:
        from sinslab.fusion.aids.base import settings_of
        t = _aid_types()[name]
        _SECTIONS[name] = settings_section(f"Aid_{name}", settings_of(t), t.summary)
    return _SECTIONS[name]


def aids_of(cfg):
    """The aids of a resolved configuration, in the registry's order: each aid class
    built from its section (SI values, not yet loaded)."""
    types = _aid_types()
    out = []
    for name in cfg.aid:
        sec = getattr(cfg, name)
        out.append(types[name](**{k: getattr(sec, k) for k in type(sec).model_fields}))
    return out


def _tokens(value, where):
    """The aid list as given: a TOML list or a comma string."""
    if isinstance(value, str):
        return [t.strip().lower() for t in value.split(",") if t.strip() and t.strip().lower() != "none"]
    if isinstance(value, list) and all(isinstance(t, str) for t in value):
        return [t.strip().lower() for t in value if t.strip()]
    raise ConfigError(f"config key aid{where}: give a list of aids, e.g. [\"nhc\", \"zupt\"]")


def _enabled(data, origins):
    """``(names in registry order, the settings their aliases set)`` of ``data["aid"]``."""
    from sinslab.fusion.aids import resolve_tokens
    where = f" ({origins['aid']})" if "aid" in origins else ""
    try:
        got = resolve_tokens(_tokens(data.get("aid", []), where))
    except ValueError as e:
        if origins.get("aid", "").startswith("--aid"):
            raise ConfigError(f"{origins['aid']}: {e}") from None
        raise ConfigError(f"config key aid{where}: {e}") from None
    return list(got), got


def _check_sections(data, names, origins):
    """Keys of an aid that is not enabled, or of the GNSS source not chosen: one line."""
    types = _aid_types()
    for key in flatten(data):
        head = key.split(".")[0]
        if head in types and head not in names:
            where = f" ({origins[key]})" if key in origins else ""
            raise ConfigError(f"config key {key}{where}: the {head} aid is not enabled: add --aid {head} "
                              f"(or aid = [\"{head}\"])")
    src = (data.get("gnss") or {}).get("source", "fixes")
    other = {"fixes": "raw", "raw": "fixes"}.get(src)
    for key in flatten(data):
        if other and key.startswith(f"gnss.{other}."):
            where = f" ({origins[key]})" if key in origins else ""
            raise ConfigError(f"config key {key}{where}: the GNSS source is {src} (gnss.source), not {other}: "
                              f"give either --fixes (fixes) or --gnss-raw (raw observations)")
    return src


def resolve_navigate(file=None, sets=(), given=None):
    """The resolved configuration: defaults <- ``file`` <- the options ``given``
    (``{option: value}``, :func:`flag_overrides`) <- ``sets`` (``--set`` items). Raises
    :class:`~sinslab.app.config.ConfigError` (one line naming the key and its origin)."""
    data, origins = {}, {}
    if file is not None:
        fdata = load_toml(file)
        origins.update({k: f"config file {file}" for k in flatten(fdata)})
        data = fdata
    flags, flag_origins, enable = flag_overrides(given or {})
    data = deep_merge(data, flags)
    origins.update(flag_origins)
    if enable:
        where = f" ({origins['aid']})" if "aid" in origins else ""
        data["aid"] = _tokens(data.get("aid", []), where) + [n for n in enable]
    sdata, sorigin = parse_set(list(sets or ()))
    origins.update({k: f"--set {v}" for k, v in sorigin.items()})
    data = deep_merge(data, sdata)
    names, alias = _enabled(data, origins)
    src = _check_sections(data, names, origins)
    for n, kv in alias.items():                 # an alias's settings, under what is given
        data[n] = deep_merge(kv, data.get(n) or {})
    data["aid"] = names
    model = navigate_model(names, src if src in ("fixes", "raw") else "fixes")
    try:
        return model.model_validate(deep_merge(model().model_dump(mode="json"), data))
    except ValidationError as err:
        raise ConfigError(_flag_error(model, err, origins)) from None


def _flag_error(model, err, origins):
    """The one-line error; a value that came from an option names the option."""
    loc = ".".join(str(x) for x in err.errors()[0]["loc"])
    origin = origins.get(loc, "")
    if origin.startswith("--") and not origin.startswith("--set"):
        msg = err.errors()[0]["msg"]
        msg = msg[len("Value error, "):] if msg.startswith("Value error, ") else msg
        if msg.startswith(("'", '"')):          # the message shows the value: name the option alone
            label = origin.split("=")[0] if origin.startswith("--init ") else origin.split(" ")[0]
            return f"{label} {msg}"
        return f"{origin}: {msg}"
    return _format_error(model, err, origins)


def _unit(value, kind):
    """An option's number as the key's unit string."""
    if kind in ("s", "Hz", "deg") and isinstance(value, (int, float)) and not isinstance(value, bool):
        return f"{value!r} {kind}" if math.isfinite(value) else f"{value} {kind}"
    return value


def _aid_flags():
    """``{option: (aid name, key, kind)}`` of the options the aids declare."""
    from sinslab.fusion.aids.base import settings_of
    return {st.flag: (n, k, st.kind) for n, t in _aid_types().items() for k, st in settings_of(t).items()
            if st.flag}


def flag_overrides(given: dict):
    """``{option: value}`` of the options given -> ``(nested dict, {dotted key: origin},
    aids the options enable)``. An aid's input named by its option (``--odometer FILE``)
    enables the aid."""
    out, origins, enable = {}, {}, []
    if "--fixes" in given and "--gnss-raw" in given:
        raise ConfigError("give either --gnss (fixes) or --gnss-raw (raw observations), not both")
    aid_flags = _aid_flags()
    for opt, value in given.items():
        shown = value[0] if isinstance(value, (list, tuple)) and value else value
        if opt == "--init":
            from_file = Path(str(value)).is_file()
            for k, v in (_init_file(value) if from_file else _init_items(value)).items():
                _put(out, f"start.{INIT_KEYS[k]}", v)
                origins[f"start.{INIT_KEYS[k]}"] = f"--init {value} ({k})" if from_file else f"--init {k}={v}"
            continue
        if opt == "--aid":
            out["aid"], origins["aid"] = value, f"--aid {value}"
            continue
        if opt in aid_flags:
            name, key, kind = aid_flags[opt]
            if kind == "file":
                value = str(_abs(value)) if Path(str(value)).exists() else value
                enable.append(name)
            _put(out, f"{name}.{key}", value)
            origins[f"{name}.{key}"] = f"{opt} {shown}"
            continue
        key, kind = FLAGS[opt]
        if kind == "files":
            value = [str(_abs(p)) for p in value] if isinstance(value, (list, tuple)) else str(_abs(value))
            value = value[0] if isinstance(value, list) and len(value) == 1 else value
        elif kind == "path":
            value = str(_abs(value))
        elif kind == "maybe_path":                  # a file, or a text (a map, a grade)
            value = str(_abs(value)) if Path(str(value)).is_file() else value
        elif kind == "list":
            value = list(value)
        elif kind == "position":                    # "X,Y,Z m" as the vector key takes it
            value = _position_text(value)
        _put(out, key, _unit(value, kind))
        origins[key] = f"{opt} {shown}"
        if opt in ("--fixes", "--gnss-raw"):
            _put(out, "gnss.source", "fixes" if opt == "--fixes" else "raw")
            origins["gnss.source"] = f"{opt} {shown}"
    return out, origins, enable


def _position_text(text):
    """``"X,Y,Z m"`` or ``"[X, Y, Z] m"`` -> ``"[X, Y, Z] m"`` (a unit is required)."""
    t = str(text).strip()
    if t.startswith("["):
        return t
    nums, _, unit = t.rpartition(" ")
    if not nums or "," not in nums:
        raise ConfigError(f"--base-position {text!r}: give the base antenna's ECEF X,Y,Z with a unit, e.g. "
                          "\"-3959400.631,3385704.533,3667523.111 m\"")
    return f"[{nums}] {unit}"


def _init_items(text):
    """``--init "pitch=1.2 deg, roll=-0.4 deg, heading=30 deg, velocity=[3, 4, 0] m/s"`` ->
    ``{key: text}`` (commas inside brackets belong to a vector)."""
    out = {}
    for tok in _split_outside_brackets(str(text or "")):
        if not tok.strip():
            continue
        k, sep, v = tok.partition("=")
        k = k.strip().lower()
        if not sep or k not in INIT_KEYS:
            raise ConfigError(f"--init {text!r}: use KEY=VALUE items, e.g. heading=\"30 deg\", "
                              f"velocity=\"[3, 4, 0] m/s\"; keys: {', '.join(INIT_KEYS)}")
        out[k] = v.strip().strip("\"'")
    return out


def _init_file(path):
    """``--init FILE``: the initial state of a KF-GINS configuration (YAML) as start keys
    (:func:`sinslab.data.kfgins.read_kfgins_start`)."""
    from sinslab.data.kfgins import read_kfgins_start
    try:
        return read_kfgins_start(path)
    except ValueError as e:
        raise ConfigError(f"--init: {e}") from None


def _split_outside_brackets(text):
    """``text`` split at the commas that are not inside ``[...]``."""
    out, depth, cur = [], 0, ""
    for ch in text:
        depth += {"[": 1, "]": -1}.get(ch, 0)
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
        else:
            cur += ch
    return out + [cur]


def _put(d, key, value):
    parts = key.split(".")
    for p in parts[:-1]:
        d = d.setdefault(p, {})
    d[parts[-1]] = value


def _abs(path) -> Path:
    """A file named on the command line, absolute (the run's config.toml re-runs from anywhere)."""
    return Path(path).absolute()


def default_toml(header: str) -> str:
    """The defaults (``sinslab config navigate``): the resolved configuration of a run with
    no aid, and each aid's section with its defaults, commented out (enable it with
    ``aid = [...]``)."""
    from sinslab.app.config import config_to_toml
    from sinslab.core.toml import dump_toml
    text = config_to_toml(navigate_model()(), header)
    for name in _aid_types():
        sec = _aid_section(name)
        block = dump_toml({name: sec().model_dump(mode="json")})
        text += f"\n# {name}: {_aid_types()[name].summary} (add \"{name}\" to aid)\n"
        text += "".join(f"# {ln}\n" if ln else "#\n" for ln in block.strip().splitlines())
    return text


def config_value(cfg) -> dict[str, Any]:
    """The resolved configuration as the run folder's ``config.toml`` holds it."""
    return cfg.model_dump(mode="json")
