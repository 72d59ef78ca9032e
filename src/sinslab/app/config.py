"""Experiment configuration: pydantic models with unit strings, TOML files, ``--set``.

An experiment's configuration is a pydantic model built from :class:`Section` (unknown
keys are errors) with one nested section per concern (``scenario``, ``imu``, ``init``,
``filter``, ...). Physical values are unit strings validated by :func:`sinslab.core.units.parse`
for the declared kind::

    from sinslab.app.config import ExperimentConfig, Section, Q, QV
    from pydantic import Field

    class Imu(Section):
        gyro_bias: QV("angular_rate") = Field("0.01 deg/h", description="constant drift, per axis")
        accel_bias: QV("acceleration") = "50 ug"

    class Scenario(Section):
        latitude: Q("angle", ge="-90 deg", le="90 deg") = "34.246 deg"
        duration: Q("time", gt="0 s") = "2 h"

    class Config(ExperimentConfig):
        scenario: Scenario = Scenario()
        imu: Imu = Imu()

A validated value is a :class:`Quantity` — a ``float`` holding the SI value that also
remembers the text it came from (``q.text``), so that the resolved ``config.toml`` shows
``"2 h"`` and not ``7200.0``. Vectors (:func:`QV`) are :class:`QuantityVec`, a tuple of
SI floats (``np.asarray(cfg.imu.gyro_bias)``). A bare number is refused unless the key
names its unit (``duration_s: float``), as docs/architecture.md's conventions ask.

The IMU of a simulated run is one shared section type, :class:`ImuSection`: an experiment
builds its ``imu`` section with :func:`imu_section` from the catalogue :data:`IMU_TERMS`
(the names of :class:`sinslab.sim.imu.ImuErrors`, one name per concept), choosing the
terms it honours and their paper defaults, and reads the simulated errors with
``cfg.imu.errors()``. A key that has been renamed stays known to its section
(:attr:`Section.renamed`): using the old name is an error naming the new one.

Resolution order (:func:`resolve`): model defaults (the paper's scenario) → the
experiment's ``quick`` overrides (with ``--quick``) → the TOML file (``--config``) →
``--set key=value`` items. Every problem is a :class:`ConfigError` whose one-line message
names the dotted key (and the file or ``--set`` item it came from).
"""
from __future__ import annotations

import difflib
import json
import math
import re
import tomllib
from pathlib import Path
from typing import Annotated, Any, ClassVar, Iterable, Mapping

from pydantic import (BaseModel, PlainValidator, ConfigDict, Field, PlainSerializer,
                      ValidationError, WithJsonSchema, create_model)

from sinslab.app.errors import UserError
from sinslab.core import units
from sinslab.core.toml import dump_toml

__all__ = ["ConfigError", "Quantity", "QuantityVec", "Q", "QV", "Section", "ExperimentConfig",
           "IMU_TERMS", "ImuSection", "imu_section",
           "load_toml", "parse_set", "deep_merge", "resolve", "dump_toml", "config_to_toml",
           "flatten", "describe", "Field", "Choice", "OrWord", "Number", "Mount", "MountValue", "setting_type",
           "settings_section"]


class ConfigError(UserError):
    """A configuration problem; ``str(err)`` is one line naming the key or file."""


# ------------------------------------------------------------------ quantities ----------

class Quantity(float):
    """An SI float that remembers its source text (``Quantity(7200.0, "2 h")``)."""

    text: str
    kind: str

    def __new__(cls, si: float, text: str, kind: str = ""):
        obj = super().__new__(cls, si)
        obj.text, obj.kind = text, kind
        return obj

    def __repr__(self):
        return f"Quantity({float(self)!r}, {self.text!r})"

    def __reduce__(self):
        return (Quantity, (float(self), self.text, self.kind))


class QuantityVec(tuple):
    """A tuple of SI floats that remembers its source text (str or list of str)."""

    text: Any
    kind: str

    def __new__(cls, si, text, kind: str = ""):
        obj = super().__new__(cls, (float(x) for x in si))
        obj.text, obj.kind = text, kind
        return obj

    def __repr__(self):
        return f"QuantityVec({tuple(self)!r}, {self.text!r})"

    def __reduce__(self):
        return (QuantityVec, (tuple(self), self.text, self.kind))


def _bound(text, kind):
    return None if text is None else (units.parse(text, kind), text)


def _check_range(shown, v, lims):
    ge, gt, le, lt = lims
    if ge is not None and not v >= ge[0]:
        raise ValueError(f"{shown} is out of range: must be >= {ge[1]}")
    if gt is not None and not v > gt[0]:
        raise ValueError(f"{shown} is out of range: must be > {gt[1]}")
    if le is not None and not v <= le[0]:
        raise ValueError(f"{shown} is out of range: must be <= {le[1]}")
    if lt is not None and not v < lt[0]:
        raise ValueError(f"{shown} is out of range: must be < {lt[1]}")


#: Magnitudes no vehicle, IMU or error budget reaches, by quantity kind: a value beyond is
#: a typo or a unit slip (``"1e300 deg/h"``, a misalignment of 1e6′) and would only give a
#: confident answer to nonsense (or non-finite numbers deep inside), so a quantity without
#: an upper bound of its own is refused above it.
PLAUSIBLE = {"angle": "360 deg", "angular_rate": "10000 deg/s", "acceleration": "1000 g",
             "velocity": "30 km/s", "length": "10000 km", "angle_random_walk": "100 deg/sqrt(s)",
             "velocity_random_walk": "10 g/sqrt(Hz)", "rate_random_walk": "1000 deg/s/sqrt(s)"}


def _check_plausible(shown, v, kind, lims):
    if kind in PLAUSIBLE and lims[2] is None and lims[3] is None:
        cap = units.parse(PLAUSIBLE[kind], kind)
        if not abs(v) <= cap:
            raise ValueError(f"{shown} is beyond any physical {kind.replace('_', ' ')} a run can "
                             f"use: |value| must be <= {PLAUSIBLE[kind]}")


def Q(kind: str, *, ge: str | None = None, gt: str | None = None, le: str | None = None,
      lt: str | None = None):
    """Type of a scalar quantity of ``kind`` (a key of :data:`sinslab.core.units.KINDS`).

    Bounds are unit strings (``ge="0 deg/h"``); a value outside is an error. Without an
    upper bound, a magnitude beyond :data:`PLAUSIBLE` is an error too.
    """
    if kind not in units.KINDS:
        raise ValueError(f"unknown quantity kind {kind!r}")
    lims = tuple(_bound(b, kind) for b in (ge, gt, le, lt))
    example = units._example_unit(kind)

    def validate(v):
        if isinstance(v, Quantity):
            v = v.text
        if isinstance(v, (int, float)) and not isinstance(v, bool) and kind != "dimensionless":
            raise ValueError(f"{v!r} has no unit; expected {kind.replace('_', ' ')} "
                             f"(write e.g. \"{v} {example}\")")
        if not isinstance(v, (str, int, float)) or isinstance(v, bool):
            raise ValueError(f"{v!r} is not a quantity (expected a string like \"1 {example}\")")
        text = str(v).strip()
        try:
            si = units.parse(text, kind)
        except units.UnitError as e:
            raise ValueError(str(e)) from None
        _check_range(repr(text), si, lims)
        _check_plausible(repr(text), si, kind, lims)
        return Quantity(si, text, kind)

    return Annotated[Quantity, PlainValidator(validate),
                     PlainSerializer(lambda q: q.text, return_type=str),
                     WithJsonSchema({"type": "string", "description": f"{kind} with unit"})]


def QV(kind: str, n: int = 3, *, ge: str | None = None, gt: str | None = None,
       le: str | None = None, lt: str | None = None):
    """Type of an ``n``-vector of ``kind``: ``"0.01 deg/h"`` (all axes),
    ``"[0.003, -0.002, 0.0005] deg/h"`` or ``["0.003 deg/h", "-0.002 deg/h", "0 deg/h"]``."""
    if kind not in units.KINDS:
        raise ValueError(f"unknown quantity kind {kind!r}")
    lims = tuple(_bound(b, kind) for b in (ge, gt, le, lt))
    example = units._example_unit(kind)

    def validate(v):
        if isinstance(v, QuantityVec):
            v = v.text
        items = v if isinstance(v, (list, tuple)) else [v]
        for x in items:
            if isinstance(x, (int, float)) and not isinstance(x, bool):
                raise ValueError(f"{x!r} has no unit; expected {kind.replace('_', ' ')} "
                                 f"(write e.g. \"{x} {example}\")")
            if not isinstance(x, str):
                raise ValueError(f"{x!r} is not a quantity string")
        text = [str(x).strip() for x in v] if isinstance(v, (list, tuple)) else str(v).strip()
        try:
            si = units.parse_vector(text, kind, n)
        except units.UnitError as e:
            raise ValueError(str(e)) from None
        for i, x in enumerate(si):
            _check_range(f"{text!r} (component {i})" if n > 1 else repr(text), x, lims)
            _check_plausible(f"{text!r} (component {i})" if n > 1 else repr(text), x, kind, lims)
        return QuantityVec(si, text, kind)

    return Annotated[QuantityVec, PlainValidator(validate),
                     PlainSerializer(lambda q: q.text),
                     WithJsonSchema({"description": f"{n} x {kind} with unit"})]


def Choice(choices, what: str = "value"):
    """Type of a string that is one of ``choices`` (one-line error listing them)."""
    allowed = tuple(choices)

    def validate(v):
        if not isinstance(v, str) or v.strip().lower() not in allowed:
            raise ValueError(f"{v!r}: choose one of {', '.join(allowed)}")
        return v.strip().lower()

    return Annotated[str, PlainValidator(validate), WithJsonSchema({"enum": list(allowed)})]


def OrWord(inner, word: str):
    """``inner`` or the word ``word`` (``"none"``, ``"auto"``) meaning "not given": the
    value is then None, and the config shows the word."""
    meta = getattr(inner, "__metadata__", ())
    val = next((m.func for m in meta if isinstance(m, PlainValidator)), None)
    ser = next((m.func for m in meta if isinstance(m, PlainSerializer)), None)

    def validate(v):
        if v is None or (isinstance(v, str) and v.strip().lower() == word):
            return None
        if val is None:
            return v
        return val(v)

    def serialize(v):
        if v is None:
            return word
        return ser(v) if ser is not None else v

    return Annotated[Any, PlainValidator(validate), PlainSerializer(serialize),
                     WithJsonSchema({"description": f"a value or \"{word}\""})]


def Number(*, ge=None, gt=None, le=None, lt=None, integer: bool = False):
    """Type of a plain number (the key names its unit, or it has none), with bounds."""
    def validate(v):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (integer and not float(v).is_integer()):
            raise ValueError(f"{v!r} is not {'a whole number' if integer else 'a number'}")
        x = int(v) if integer else float(v)
        lims = tuple(None if b is None else (b, f"{b:g}") for b in (ge, gt, le, lt))
        if not math.isfinite(x):
            raise ValueError(f"{v!r} is not finite")
        _check_range(repr(v), x, lims)
        return x

    return Annotated[float, PlainValidator(validate), WithJsonSchema({"type": "number"})]


def setting_type(st):
    """The pydantic type of a plug-in's declared setting
    (:class:`sinslab.fusion.aids.base.Setting`)."""
    b = st.bounds
    if st.kind in units.KINDS:
        t = Q(st.kind, **b) if st.n == 1 else QV(st.kind, st.n, **b)
    elif st.kind == "flag":
        t = bool
    elif st.kind == "choice":
        t = Choice(st.choices)
    elif st.kind in ("probability", "number", "count"):
        t = Number(**b, integer=st.kind == "count")
    elif st.kind == "mount":
        t = Mount()
    else:
        t = str
    return OrWord(t, st.none) if st.none is not None else t


class MountValue(tuple):
    """A rotation given as a mount string: ``(pitch, roll, yaw)`` [rad] of it, and the text."""

    def __new__(cls, att, text):
        obj = super().__new__(cls, (float(x) for x in att))
        obj.text = text
        return obj

    def __reduce__(self):
        return (MountValue, (tuple(self), self.text))


def Mount():
    """Type of a rotation string (``euler:P,R,Y`` deg, ``rpy:R,P,Y``, ``quat:...``,
    ``matrix:...``) read by :func:`sinslab.data.frames.sensor_to_body`, held as the Euler
    angles ``(pitch, roll, yaw)`` [rad] of the rotation."""
    def validate(v):
        if isinstance(v, MountValue):
            return v
        from sinslab.core import attitude as A
        from sinslab.data.frames import sensor_to_body
        if not isinstance(v, str):
            raise ValueError(f"{v!r} is not a mount string (e.g. \"euler:1.2,0,-1.5\")")
        return MountValue(A.dcm_to_euler(sensor_to_body(v.strip(), "rfu")), v.strip())

    return Annotated[MountValue, PlainValidator(validate), PlainSerializer(lambda m: m.text, return_type=str),
                     WithJsonSchema({"type": "string"})]


def settings_section(name: str, settings: Mapping, doc: str = "") -> type[Section]:
    """A :class:`Section` of a plug-in's declared settings (``{key: Setting}``, each with
    its unit kind, default text and description)."""
    fields = {k: (setting_type(st), Field(st.text, description=st.doc + (f" ({st.flag})" if st.flag else "")))
              for k, st in settings.items()}
    return create_model(name, __base__=Section, __doc__=doc or None, **fields)


# ------------------------------------------------------------------ models --------------

class Section(BaseModel):
    """Base of every config section: unknown keys are errors.

    ``renamed`` maps a key this section used to have to its new key, relative to the
    section (``{"gyro_noise": "gyro_arw"}``, or ``{"gyro_bias": "imu.gyro_bias"}`` for a key
    moved into a sub-section): the old key is still refused, with the new one named.
    """

    # strict: a TOML boolean is no seed or count, a float no integer, a number no flag
    # (pydantic's lax mode takes true as 1 and 2.0 as 2); quantities have their own checks
    model_config = ConfigDict(extra="forbid", validate_default=True, strict=True)
    renamed: ClassVar[dict[str, str]] = {}


class ExperimentConfig(Section):
    """Base of an experiment's top-level config: adds ``seed`` and ``runs``."""

    seed: int = Field(0, ge=0, description="seed of every random draw (same seed, same bytes)")
    runs: int = Field(1, ge=1, description="Monte Carlo runs (1 = a single simulation)")


# ------------------------------------------------------------------ the IMU section ------

#: The IMU error terms an ``imu`` section may expose: ``name -> (quantity kind, bounds,
#: description)``; the names and SI meanings of :class:`sinslab.sim.imu.ImuErrors`. A true
#: value the simulated IMU carries and a 1σ from which each run draws its own value are two
#: concepts with two names: ``gyro_bias`` is the bias, ``gyro_bias_sigma`` its 1σ.
IMU_TERMS: dict[str, tuple[str, dict, str]] = {
    "gyro_bias": ("angular_rate", {}, "constant gyro bias (body x, y, z)"),
    "gyro_bias_sigma": ("angular_rate", {"ge": "0 deg/h"},
                        "1σ of the constant gyro bias, drawn per run"),
    "gyro_arw": ("angle_random_walk", {"ge": "0 deg/sqrt(h)"}, "gyro angle random walk (white rate noise)"),
    "gyro_bias_instability": ("angular_rate", {"ge": "0 deg/h"},
                              "first-order Gauss–Markov gyro bias, steady-state σ"),
    "gyro_corr_time": ("time", {"gt": "0 s"}, "correlation time of the Gauss–Markov gyro bias"),
    "gyro_rrw": ("rate_random_walk", {"ge": "0 deg/h/sqrt(h)"}, "gyro rate random walk"),
    "gyro_scale_factor": ("dimensionless", {"ge": "-0.1", "le": "0.1"}, "gyro scale-factor error"),
    "gyro_scale_factor_sigma": ("dimensionless", {"ge": "0 ppm"}, "1σ of the gyro scale-factor error, drawn per run"),
    "accel_bias": ("acceleration", {}, "constant accelerometer bias (body x, y, z)"),
    "accel_bias_sigma": ("acceleration", {"ge": "0 ug"}, "1σ of the constant accelerometer bias, drawn per run"),
    "accel_vrw": ("velocity_random_walk", {"ge": "0 ug/sqrt(Hz)"},
                  "accelerometer velocity random walk (white specific-force noise)"),
    "accel_bias_instability": ("acceleration", {"ge": "0 ug"},
                               "first-order Gauss–Markov accelerometer bias, steady-state σ"),
    "accel_corr_time": ("time", {"gt": "0 s"}, "correlation time of the Gauss–Markov accelerometer bias"),
    "accel_rrw": ("accel_random_walk", {"ge": "0 ug/sqrt(s)"}, "accelerometer bias random walk"),
    "accel_scale_factor": ("dimensionless", {"ge": "-0.1", "le": "0.1"}, "accelerometer scale-factor error"),
    "accel_scale_factor_sigma": ("dimensionless", {"ge": "0 ppm"},
                                 "1σ of the accelerometer scale-factor error, drawn per run"),
}


class ImuSection(Section):
    """The IMU section of an experiment: a subset of :data:`IMU_TERMS` (built by
    :func:`imu_section`), validated once, read by :meth:`errors`.

    Each term is a :class:`Quantity` (one value for all axes) or a :class:`QuantityVec`
    (x, y, z), SI. The ``*_sigma`` terms are not errors of the IMU but the spread a
    campaign draws them from; :meth:`errors` leaves them out.
    """

    def errors(self):
        """The simulated IMU's errors: :class:`sinslab.sim.imu.ImuErrors` of this section's
        error terms (the ones it does not have are zero; ``*_sigma`` terms are left out)."""
        import numpy as np
        from sinslab.sim.imu import ImuErrors

        return ImuErrors(**{k: np.asarray(getattr(self, k), dtype=float) for k in type(self).model_fields
                            if k in IMU_TERMS and not k.endswith("_sigma")})

    def sigma(self, name: str):
        """The (3,) 1σ of term ``name`` (``"gyro_bias"`` reads ``gyro_bias_sigma``), SI."""
        import numpy as np

        return np.broadcast_to(np.asarray(getattr(self, f"{name}_sigma"), dtype=float), (3,)).copy()


def imu_section(name: str, defaults: Mapping[str, str | tuple[str, str]], *,
                scalar: bool | Iterable[str] = False, renamed: Mapping[str, str] | None = None,
                doc: str = "") -> type[ImuSection]:
    """An :class:`ImuSection` type exposing the terms of ``defaults`` (keys of :data:`IMU_TERMS`).

    Parameters
    ----------
    name : str
        Class name (shown nowhere a user sees; for reprs).
    defaults : mapping
        ``term -> default`` (a unit string, the paper's value) or ``term -> (default, note)``,
        the note appended to the term's description.
    scalar : bool or iterable of str
        Terms taking one value for all axes (the experiment's model is isotropic); the others
        take one value or three (x, y, z). ``True``: every term.
    renamed : mapping, optional
        Old key -> new key of this section (see :class:`Section`).
    """
    unknown = set(defaults) - set(IMU_TERMS)
    if unknown:
        raise ValueError(f"imu_section: unknown IMU term(s) {', '.join(sorted(unknown))}; "
                         f"known: {', '.join(IMU_TERMS)}")
    one = set(defaults) if scalar is True else set(scalar or ())
    fields = {}
    for term, value in defaults.items():
        default, note = (value, "") if isinstance(value, str) else value
        kind, bounds, desc = IMU_TERMS[term]
        typ = Q(kind, **bounds) if term in one else QV(kind, **bounds)
        fields[term] = (typ, Field(default, description=f"{desc}; {note}" if note else desc))
    cls = create_model(name, __base__=ImuSection, __doc__=doc or ImuSection.__doc__, **fields)
    cls.renamed = dict(renamed or {})
    return cls


# ------------------------------------------------------------------ sources -------------

def load_toml(path: str | Path) -> dict:
    """Read a TOML config file; ConfigError (naming the file) if unreadable, empty or bad."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise ConfigError(f"config file {p}: not found") from None
    except IsADirectoryError:
        raise ConfigError(f"config file {p}: is a folder, not a file") from None
    except OSError as e:
        raise ConfigError(f"config file {p}: cannot read ({e.strerror or e})") from None
    try:
        text = raw.decode("utf-8-sig")          # a byte-order mark (some editors) is not TOML
    except UnicodeDecodeError:
        raise ConfigError(f"config file {p}: not UTF-8 text") from None
    if not text.strip():
        raise ConfigError(f"config file {p}: is empty")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"config file {p}: not valid TOML ({e})") from None
    if not data:
        raise ConfigError(f"config file {p}: holds no settings")
    return data


_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")


def parse_set(items: list[str] | tuple[str, ...] | None) -> tuple[dict, dict[str, str]]:
    """Parse ``--set key=value`` items into a nested dict (and key -> item map).

    The value is read as a TOML value when it is one (``3``, ``true``, ``"2 h"``,
    ``["1 deg", "2 deg", "3 deg"]``); otherwise it is taken as a plain string, so the shell
    form ``--set imu.gyro_bias="0.02 deg/h"`` (quotes eaten by the shell) works.
    """
    out: dict = {}
    origin: dict[str, str] = {}
    for item in items or ():
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected key=value (e.g. imu.gyro_bias=\"0.02 deg/h\")")
        key, value = (s.strip() for s in item.split("=", 1))
        if not _KEY.match(key):
            raise ConfigError(f"--set {item!r}: {key!r} is not a dotted config key")
        if value == "":
            raise ConfigError(f"--set {item!r}: no value for {key}")
        try:
            parsed = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            parsed = value
        d = out
        parts = key.split(".")
        for part in parts[:-1]:
            d = d.setdefault(part, {})
            if not isinstance(d, dict):
                raise ConfigError(f"--set {item!r}: {part} is set both as a value and a section")
        d[parts[-1]] = parsed
        origin[key] = item
    return out, origin


def deep_merge(base: Mapping, over: Mapping) -> dict:
    """Recursive dict merge; ``over`` wins; neither input is modified."""
    out = dict(base)
    for k, v in over.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = v
    return out


def flatten(d: Mapping, prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}``."""
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


def _model_at(model_cls, path):
    """The model class of the section at ``path`` (list of keys), or None."""
    m = model_cls
    for part in path:
        f = getattr(m, "model_fields", {}).get(part)
        ann = getattr(f, "annotation", None) if f else None
        if not (isinstance(ann, type) and issubclass(ann, BaseModel)):
            return None
        m = ann
    return m


def _format_error(model_cls, err: ValidationError, origins: dict[str, str]) -> str:
    e = err.errors()[0]
    loc = [str(x) for x in e["loc"]]
    key = ".".join(loc)
    where = ""
    for k in (key, *[".".join(loc[:i]) for i in range(len(loc) - 1, 0, -1)]):
        if k in origins:
            where = f" ({origins[k]})"
            break
    else:                                   # a whole unknown section: name where it came from
        inner = [v for k, v in origins.items() if k.startswith(key + ".")]
        if inner:
            where = f" ({inner[-1]})"
    if e["type"] == "extra_forbidden":
        parent = _model_at(model_cls, [x for x in loc[:-1]])
        new = getattr(parent, "renamed", {}).get(loc[-1]) if parent else None
        if new:
            return f"config key {key}{where} has been renamed: use {'.'.join(loc[:-1] + [new])}"
        known = list(parent.model_fields) if parent else []
        hint = difflib.get_close_matches(loc[-1], known + list(getattr(parent, "renamed", {})), n=1)
        hint = [getattr(parent, "renamed", {}).get(h, h) for h in hint]
        msg = f"unknown config key {key}{where}"
        if hint:
            msg += f"; did you mean {'.'.join(loc[:-1] + hint)}?"
        elif known:
            msg += f"; known keys{' in ' + '.'.join(loc[:-1]) if loc[:-1] else ''}: {', '.join(known)}"
        return msg
    msg = e["msg"]
    got = e.get("input")
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    elif e["type"] in ("int_type", "float_type") and isinstance(got, (bool, str, float)):
        want = "an integer" if e["type"] == "int_type" else "a number"
        msg = (f"{str(got).lower()} is a boolean, not {want}" if isinstance(got, bool) else
               f"{got!r} is text, not {want}" + (" (write it without quotes)" if _is_number(got) else "")
               if isinstance(got, str) else f"{got!r} is not {want} (a whole number)")
    elif e["type"] == "bool_type" and isinstance(got, (int, float, str)):
        msg = f"{got!r} is not a boolean: write true or false"
    elif "input" in e and not isinstance(e["input"], (dict, list)):
        msg = f"{msg[0].lower()}{msg[1:]} (got {e['input']!r})"
    if not key:                              # a check across keys (model validator)
        return f"config: {msg}"
    return f"config key {key}{where}: {msg}"


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def resolve(model_cls: type[ExperimentConfig], *, quick: Mapping | None = None,
            file: str | Path | None = None, sets: list[str] | None = None,
            overrides: Mapping | None = None) -> ExperimentConfig:
    """Build the resolved config: defaults <- quick <- file <- overrides <- --set items."""
    data = model_cls().model_dump(mode="json")
    origins: dict[str, str] = {}
    if quick:
        data = deep_merge(data, quick)
    if file is not None:
        fdata = load_toml(file)
        for k in flatten(fdata):
            origins[k] = f"config file {file}"
        data = deep_merge(data, fdata)
    if overrides:
        data = deep_merge(data, overrides)
    sdata, sorigin = parse_set(sets)
    for k, item in sorigin.items():
        origins[k] = f"--set {item}"
    data = deep_merge(data, sdata)
    try:
        cfg = model_cls.model_validate(data)
    except ValidationError as err:
        raise ConfigError(_format_error(model_cls, err, origins)) from None
    _check_steps(cfg, origins)
    _check_used_when(cfg, origins)
    return cfg


#: Names of a filter's step (a time quantity): a step holds at least one IMU sample
STEP_NAMES = ("period", "kf_dt", "model_dt")


def _fields(model, prefix=""):
    """``(dotted key, value, field info, section)`` of every leaf field of a config."""
    for name, f in type(model).model_fields.items():
        v = getattr(model, name)
        if isinstance(v, BaseModel):
            yield from _fields(v, f"{prefix}{name}.")
        else:
            yield f"{prefix}{name}", v, f, model


def _origin(key: str, origins: Mapping[str, str]) -> str:
    return f" ({origins[key]})" if key in origins else ""


def _check_steps(cfg, origins) -> None:
    """A filter step (:data:`STEP_NAMES`, a time) shorter than the IMU's sample interval
    (a ``sample_interval`` key of the same config) holds no sample: refused, naming both."""
    leaves = list(_fields(cfg))
    dts = [(k, v) for k, v, _, _ in leaves if k.rsplit(".", 1)[-1] == "sample_interval" and isinstance(v, Quantity)]
    if not dts:
        return
    dk, dt = max(dts, key=lambda kv: float(kv[1]))
    for key, v, _, _ in leaves:
        if key.rsplit(".", 1)[-1] in STEP_NAMES and isinstance(v, Quantity) and v.kind == "time" \
                and float(v) < float(dt) * (1 - 1e-9):
            raise ConfigError(f"config key {key}{_origin(key, origins)}: {v.text!r} is shorter than the IMU sample "
                              f"interval {dk} = {dt.text!r}: a filter step holds at least one sample")


def _check_used_when(cfg, origins) -> None:
    """A key the user set (file or ``--set``) that the configuration's mode ignores is
    refused: its field declares ``json_schema_extra={"used_when": {other_key: value}}``
    (keys of its section) and the section's ``other_key`` has another value."""
    for key, _, f, sec in _fields(cfg):
        cond = (f.json_schema_extra or {}).get("used_when") if isinstance(f.json_schema_extra, dict) else None
        if not cond or key not in origins:
            continue
        base = key.rsplit(".", 1)[0] + "." if "." in key else ""
        for other, want in cond.items():
            have = getattr(sec, other)
            if have != want:
                raise ConfigError(f"config key {key}{_origin(key, origins)} is used only with {base}{other} = "
                                  f"{want!r} (here {have!r}) and would be ignored: set {base}{other} = {want!r} "
                                  f"or drop it")


def config_to_toml(cfg: BaseModel, header: str = "") -> str:
    """The resolved config as TOML text, with ``header`` as leading comment lines."""
    head = "".join(f"# {line}\n" if line else "#\n" for line in header.splitlines())
    return head + dump_toml(cfg.model_dump(mode="json"))


def describe(model_cls: type[BaseModel]) -> list[tuple[str, Any, str]]:
    """``[(dotted key, default (as written in TOML), description), ...]`` of a config model."""
    def walk(m, data, prefix):
        out = []
        for name, f in m.model_fields.items():
            ann = f.annotation
            if isinstance(ann, type) and issubclass(ann, BaseModel):
                out.extend(walk(ann, data.get(name) or {}, f"{prefix}{name}."))
            else:
                out.append((f"{prefix}{name}", data.get(name), f.description or ""))
        return out
    return walk(model_cls, model_cls().model_dump(mode="json"), "")
