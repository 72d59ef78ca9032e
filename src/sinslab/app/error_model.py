"""The filter's IMU error model for recorded data, in the simulator's vocabulary.

``sinslab navigate --imu-errors FILE.toml`` (or a grade name) reads a table in the
datasheet units of :class:`sinslab.sim.imu.ImuErrors` and turns it into the options of
:class:`sinslab.fusion.recorded.NavOptions`:

==============================  =============================================================
ImuErrors key (``[imu]``)       filter
==============================  =============================================================
``gyro_arw`` / ``accel_vrw``    white noise of the filter, used as given (no floor)
``gyro_bias`` / ``accel_bias``  initial σ of the bias states (random constant)
``gyro_rrw`` / ``accel_rrw``    random walk of those states
``*_bias_instability`` +        a first-order Gauss–Markov bias block, σ and τ
``*_corr_time``
``*_scale_factor``              σ of scale-factor states (added when non-zero)
==============================  =============================================================

Other tables of the file: ``[scale]`` ``gyro_corr_time`` / ``accel_corr_time`` (the scale
factors become Gauss–Markov with that τ) or ``gyro_rw`` / ``accel_rw`` (random walk,
"ppm/sqrt(h)"); ``[initial]`` ``attitude`` (σ pitch, roll, heading, e.g.
``["1 deg", "1 deg", "5 deg"]``); ``[fixes]`` ``position_sigma`` / ``velocity_sigma``
(replace every fix's σ), ``position_floor`` / ``velocity_floor``; ``[aiding]``
``zupt_sigma``, ``zaru_sigma``, ``nhc_sigma`` (lateral, vertical), ``lever_sigma`` (the σ of
those aids when they are enabled, :func:`aid_settings`).
``grade = "tactical"`` at the top starts from a named grade (:data:`GRADES`); the keys
given replace the grade's.

The resolved model is returned as a flat dict of unit strings for the run's
``config.toml`` and report.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sinslab.core import units as U
from sinslab.fusion.recorded_spec import FIELD_GROUP

__all__ = ["GRADES", "GRADE_SOURCES", "load_error_model", "apply_error_model", "aid_settings", "AID_SETTINGS"]

#: Named grades: representative datasheet values inside the classes of El-Sheimy & Youssef
#: (2020), "Inertial sensors technologies for navigation applications: state of the art
#: and future trends", Satellite Navigation 1:2, Table 1 (gyro drift, gyro random walk,
#: accelerometer bias per grade), and Groves (2013), *Principles of GNSS, Inertial, and
#: Multisensor Integrated Navigation Systems*, 2nd ed., section 4.4 (noise densities and
#: scale factors by grade). One value per class, chosen mid-range; a real unit's
#: datasheet or Allan analysis (``sinslab allan``) is always better.
GRADES = {
    "consumer": {"gyro_bias": "360 deg/h", "gyro_arw": "1 deg/sqrt(h)",
                 "gyro_scale_factor": "10000 ppm",
                 "accel_bias": "10000 ug", "accel_vrw": "300 ug/sqrt(Hz)",
                 "accel_scale_factor": "10000 ppm"},
    "industrial": {"gyro_bias": "20 deg/h", "gyro_arw": "0.3 deg/sqrt(h)",
                   "gyro_scale_factor": "1000 ppm",
                   "accel_bias": "2000 ug", "accel_vrw": "100 ug/sqrt(Hz)",
                   "accel_scale_factor": "1000 ppm"},
    "tactical": {"gyro_bias": "1 deg/h", "gyro_arw": "0.1 deg/sqrt(h)",
                 "gyro_scale_factor": "300 ppm",
                 "accel_bias": "1000 ug", "accel_vrw": "50 ug/sqrt(Hz)",
                 "accel_scale_factor": "300 ppm"},
    "navigation": {"gyro_bias": "0.01 deg/h", "gyro_arw": "0.002 deg/sqrt(h)",
                   "gyro_scale_factor": "10 ppm",
                   "accel_bias": "50 ug", "accel_vrw": "10 ug/sqrt(Hz)",
                   "accel_scale_factor": "50 ppm"},
}
GRADES["consumer-mems"] = GRADES["consumer"]
#: one line per grade for the docs and the report
GRADE_SOURCES = "El-Sheimy & Youssef (2020) Table 1; Groves (2013) sec. 4.4"

_TABLES = {"imu", "scale", "initial", "fixes", "aiding"}
_KEYS = {
    "scale": {"gyro_corr_time": "time", "accel_corr_time": "time",
              "gyro_rw": None, "accel_rw": None},
    "initial": {"attitude": "angle"},
    "fixes": {"position_sigma": "length", "velocity_sigma": "velocity",
              "position_floor": "length", "velocity_floor": "velocity"},
    "aiding": {"zupt_sigma": "velocity", "zaru_sigma": "angular_rate", "nhc_sigma": "velocity",
               "lever_sigma": "length"},
}


def _read(spec):
    if isinstance(spec, dict):
        return dict(spec), "<dict>"
    s = str(spec).strip()
    if s.lower() in GRADES:
        return {"grade": s.lower()}, s
    p = Path(s)
    if not p.is_file():
        raise ValueError(f"--imu-errors {s!r}: neither a file nor a grade ({', '.join(sorted(GRADES))})")
    import tomllib
    try:
        text = p.read_bytes().decode("utf-8-sig")          # a byte-order mark is not TOML
    except UnicodeDecodeError as e:
        raise ValueError(f"--imu-errors {p}: not UTF-8 text (byte {e.start}); a binary file? "
                         f"give a TOML file or a grade ({', '.join(sorted(GRADES))})") from None
    except OSError as e:
        raise ValueError(f"--imu-errors {p}: cannot read ({e.strerror or e})") from None
    try:
        return tomllib.loads(text), str(p)
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"--imu-errors {p}: not valid TOML ({e})") from None


def load_error_model(spec):
    """Read an error model (TOML file path, grade name or dict, see the module notes).

    Returns ``(ImuErrors, extras, resolved)``: the :class:`sinslab.sim.imu.ImuErrors` of
    the ``[imu]`` table over the grade, ``extras`` ``{table: {key: SI value}}`` of the other
    tables, and ``resolved`` the flat dict of unit strings written to the run's config.
    Raises ValueError naming the key: unknown table or key, wrong unit, unknown grade.
    """
    from sinslab.sim.imu import ImuErrors
    d, src = _read(spec)
    grade = d.pop("grade", None)
    extra_top = set(d) - _TABLES
    if extra_top:
        raise ValueError(f"{src}: unknown key(s) {', '.join(sorted(extra_top))}; use grade = \"...\" and "
                         f"the tables {', '.join(sorted(_TABLES))}")
    imu = {}
    if grade is not None:
        g = str(grade).strip().lower()
        if g not in GRADES:
            raise ValueError(f"{src}: unknown grade {grade!r}; use one of {', '.join(sorted(GRADES))}")
        imu.update(GRADES[g])
    imu.update(d.get("imu", {}))
    if not imu:
        raise ValueError(f"{src}: no IMU error terms: give grade = \"...\" or an [imu] table")
    try:
        err = ImuErrors.from_datasheet(**imu)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{src}: [imu] {e}") from None
    extras, resolved = {}, {"source": src}
    if grade is not None:
        resolved["grade"] = str(grade)
    resolved.update({f"imu.{k}": (v if isinstance(v, str) else str(v)) for k, v in imu.items()})
    for tab, keys in _KEYS.items():
        t = d.get(tab, {})
        if not isinstance(t, dict):
            raise ValueError(f"{src}: [{tab}] must be a table")
        unknown = set(t) - set(keys)
        if unknown:
            raise ValueError(f"{src}: [{tab}] unknown key(s) {', '.join(sorted(unknown))}; "
                             f"use {', '.join(keys)}")
        out = {}
        for k, v in t.items():
            kind = keys[k]
            try:
                out[k] = _parse_any(v, kind)
            except (ValueError, TypeError) as e:
                raise ValueError(f"{src}: [{tab}] {k} = {v!r}: {e}") from None
            resolved[f"{tab}.{k}"] = str(v)
        extras[tab] = out
    if extras["scale"].get("gyro_rw") is not None and extras["scale"].get("gyro_corr_time") is not None:
        raise ValueError(f"{src}: [scale] give gyro_rw or gyro_corr_time, not both")
    if extras["scale"].get("accel_rw") is not None and extras["scale"].get("accel_corr_time") is not None:
        raise ValueError(f"{src}: [scale] give accel_rw or accel_corr_time, not both")
    return err, extras, resolved


def _parse_any(v, kind):
    """A quantity or a list of quantities (``["1 deg", "2 deg"]`` or ``"[1, 2] deg"``) in SI."""
    if isinstance(v, (list, tuple)):
        return np.array([U.parse(x, kind) for x in v])
    st = str(v).strip()
    if st.startswith("["):
        n = len([x for x in st[1:st.index("]")].replace(",", " ").split() if x])
        return U.parse_vector(st, kind, n)
    return U.parse(v, kind)


def _per_axis_max(v):
    return float(np.max(np.abs(np.asarray(v, dtype=float))))


class NavOptionsDraft:
    """The spec fields of a :class:`sinslab.fusion.recorded.NavOptions` being assembled
    from command-line options and files, by field name: reads fall through to ``base``,
    assignments are collected, and :meth:`build` makes each spec concerned once (frozen,
    checked)."""

    def __init__(self, base):
        object.__setattr__(self, "_base", base)
        object.__setattr__(self, "_set", {})

    def __getattr__(self, k):
        s = object.__getattribute__(self, "_set")
        return s[k] if k in s else object.__getattribute__(self, "_base").field(k)

    def __setattr__(self, k, v):
        if k not in FIELD_GROUP:
            raise AttributeError(f"NavOptions has no field {k!r}")
        self._set[k] = v

    def build(self):
        """The options: ``base`` with the fields set (checked once, here)."""
        return self._base.replace(**self._set)


def apply_error_model(opt, err, extras):
    """Set the fields of a :class:`sinslab.fusion.recorded.NavOptions` from
    :func:`load_error_model`'s ``(err, extras)``: returns the new options (a
    :class:`NavOptionsDraft` given is filled in and returned instead). The white noise is
    the model's (``rest_noise`` off: no floor, no measurement at rest)."""
    draft = isinstance(opt, NavOptionsDraft)
    opt = opt if draft else NavOptionsDraft(opt)
    opt.gyro_arw = np.asarray(err.gyro_arw, dtype=float).copy()
    opt.accel_vrw = np.asarray(err.accel_vrw, dtype=float).copy()
    opt.rest_noise = False
    opt.gyro_rrw = np.asarray(err.gyro_rrw, dtype=float).copy()
    opt.accel_rrw = np.asarray(err.accel_rrw, dtype=float).copy()
    opt.gyro_bias_sigma = np.maximum(np.abs(err.gyro_bias), 1e-12)
    opt.accel_bias_sigma = np.maximum(np.abs(err.accel_bias), 1e-12)
    for s in ("gyro", "accel"):
        bi = np.asarray(getattr(err, f"{s}_bias_instability"), dtype=float)
        tc = np.asarray(getattr(err, f"{s}_corr_time"), dtype=float)
        if np.any(bi > 0):
            tau = float(np.min(tc[np.isfinite(tc)]))
            setattr(opt, f"{s}_markov", (np.maximum(bi, 1e-12), tau))
    gsf, asf = np.abs(err.gyro_scale_factor), np.abs(err.accel_scale_factor)
    if np.any(gsf > 0) or np.any(asf > 0):
        opt.scale_factors = True
        opt.gyro_scale_sigma = max(_per_axis_max(gsf), 1e-9)
        opt.accel_scale_sigma = max(_per_axis_max(asf), 1e-9)
    sc = extras.get("scale", {})
    opt.scale_rw = (float(sc.get("gyro_rw", 0.0)), float(sc.get("accel_rw", 0.0)))
    opt.scale_tau = (sc.get("gyro_corr_time"), sc.get("accel_corr_time"))
    if (opt.scale_rw != (0.0, 0.0) or opt.scale_tau != (None, None)) and not opt.scale_factors:
        raise ValueError("[scale] sets a scale-factor model but [imu] gives no scale factor σ "
                         "(gyro_scale_factor / accel_scale_factor)")
    ini = extras.get("initial", {})
    if "attitude" in ini:
        a = np.broadcast_to(np.asarray(ini["attitude"], dtype=float), (3,))
        opt.att_sigma = tuple(float(x) for x in a)
    fx = extras.get("fixes", {})
    if "position_sigma" in fx:
        opt.fix_sigma = tuple(np.broadcast_to(np.asarray(fx["position_sigma"], float), (3,)))
    if "velocity_sigma" in fx:
        opt.fix_vel_sigma = tuple(np.broadcast_to(np.asarray(fx["velocity_sigma"], float), (3,)))
    if "position_floor" in fx:
        opt.pos_sigma_floor = float(fx["position_floor"])
    if "velocity_floor" in fx:
        opt.vel_sigma_floor = float(fx["velocity_floor"])
    if not math.isfinite(float(np.max(opt.gyro_arw))) or float(np.max(opt.gyro_arw)) <= 0 \
            or float(np.max(opt.accel_vrw)) <= 0:
        raise ValueError("the error model needs white noise: gyro_arw and accel_vrw > 0")
    return opt if draft else opt.build()


#: ``[aiding]`` key of an error-model file -> (aid, setting, components): the σ it gives an
#: aid of :mod:`sinslab.fusion.aids` when that aid is enabled
AID_SETTINGS = {"zupt_sigma": ("zupt", "sigma", 1), "zaru_sigma": ("zupt", "zaru_sigma", 1),
                "nhc_sigma": ("nhc", "sigma", 2), "lever_sigma": ("lever", "sigma", 1)}


def aid_settings(aid, extras):
    """``{setting: value}`` an error model's ``[aiding]`` table gives the aid named ``aid``."""
    out = {}
    for key, v in extras.get("aiding", {}).items():
        name, setting, n = AID_SETTINGS[key]
        if name == aid:
            out[setting] = float(v) if n == 1 else tuple(np.broadcast_to(np.asarray(v, float), (n,)))
    return out
