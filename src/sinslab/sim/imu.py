"""IMU error model: parameters from datasheet units, applied to increments at compiled speed.

An :class:`ImuErrors` object is a frozen set of sensor error parameters in SI units, one
value per sensor axis (IMU body frame, RFU). Build it from a datasheet with unit strings::

    >>> from sinslab.sim.imu import ImuErrors, apply
    >>> err = ImuErrors.from_datasheet(gyro_bias="0.01 deg/h", gyro_arw="0.001 deg/sqrt(h)",
    ...                                accel_bias="100 ug", accel_vrw="10 ug/sqrt(Hz)")
    >>> noisy = apply(truth_imu, err, seed=1)            # doctest: +SKIP

and write it back as a config fragment with :meth:`ImuErrors.to_toml` / :meth:`ImuErrors.to_dict`.

Error terms (per sensor, per axis; "rate" means ω [rad/s] for gyros, f [m/s^2] for accels)
------------------------------------------------------------------------------------------
The output increment of sample k (interval ``(t_k − dt, t_k]``) is ::

    Δθ_out = (I + S + M)·Δθ_true + (b + x_GM,k + x_RW,k)·dt + ∫trend dt + β·σ_w·w_k + β·rec_k

- ``bias`` b: constant rate bias.
- ``arw`` / ``vrw`` N: white noise on the rate with two-sided PSD N² (angle / velocity
  random walk). On increments: σ(Δθ) = N·sqrt(dt), i.e. σ(Δθ/dt) = N/sqrt(dt).
  ``"0.001 deg/sqrt(h)"`` and ``"10 ug/sqrt(Hz)"`` are the usual units.
- ``bias_instability`` σ with ``corr_time`` τ: first-order Gauss–Markov rate bias
  ``ẋ = −x/τ + w``, simulated by the exact discretisation ``x_{k+1} = φ x_k +
  σ·sqrt(1 − φ²)·w_k``, φ = exp(−dt/τ), started in steady state (x_0 ~ N(0, σ²)).
  **Convention: σ is the steady-state standard deviation of the GM process.** Its Allan
  deviation (:func:`gm_allan_deviation`) peaks at τ_A ≈ 1.893·τ with value ≈ 0.6174·σ.
  A datasheet "bias instability" B in the IEEE-952 sense (flicker floor of the Allan
  deviation = B·sqrt(2 ln 2/π) ≈ 0.664·B) matched at the peak gives σ ≈ 1.076·B; a
  datasheet quoting the *minimum of the Allan deviation curve* directly gives
  σ ≈ 1.620·floor. :func:`gm_sigma_from_allan_floor` does either conversion.
- ``rrw``: rate random walk K, ``ẋ = w`` with PSD K², ``x_{k+1} = x_k + K·sqrt(dt)·w_k``,
  x_0 = 0 (Allan deviation K·sqrt(τ/3)).
- ``scale_factor`` S (diagonal, e.g. ``"200 ppm"``) and ``misalignment`` M (off-diagonal,
  small angles, zero diagonal): the true increment is multiplied by ``I + S + M``.
  ``M[i, j]`` is the sensitivity of sensor axis i to the true rate about/along axis j;
  the datasheet form lists the six off-diagonal elements ``[xy, xz, yx, yz, zx, zy]``.
- ``trend`` (:class:`Trend`): a slow, temperature-like deterministic bias drift, a function
  of the time since the start of the record ``s``:
  ``ramp·s + exp_amplitude·(1 − exp(−s/exp_time)) + sin_amplitude·sin(2π s/sin_period +
  sin_phase)``; integrated exactly over each interval.
- recorded noise (:class:`RecordedNoise`): a recorded noise sequence (rates or
  increments, e.g. a de-meaned static test) added sample by sample.
- ``noise_scale`` β (per sensor): multiplies every zero-mean random term of that sensor —
  white noise, Gauss–Markov, rate random walk and recorded noise — but not the bias,
  scale factor, misalignment or trend. (Paper 001 scales INS #2's gyro noise by
  β ∈ {0.8..1.5}, α = β² − 1.)

Randomness: ``apply(imu, errors, seed)`` with an int seed or a ``numpy.random.Generator``;
the same seed gives the same bytes. The seed (through ``numpy.random.default_rng``) or the
Generator gives four 64-bit words (``Generator.integers``; a Generator is advanced by
that one draw), which seed a xoshiro256++ generator inside the compiled pass (:mod:`sinslab.sim._rng`); normals come
from its ziggurat (numpy's 256-layer layout, exact tail and wedges), drawn sample by
sample, channel by channel (gyro x, y, z, accel x, y, z), white noise then Gauss–Markov
then random walk, only for the active terms, after the Gauss–Markov start values. The
whole model is one pass over the record, with no buffer of normals. (Before this
generator the normals came from ``Generator.standard_normal`` in chunks: the same seed
gives different bytes than with sinslab versions before it, the same statistics.)
"""
from __future__ import annotations

import difflib
import math
import os
from dataclasses import dataclass, field, fields

import numpy as np
from numba import njit

from sinslab.core import units as U
from sinslab.core.records import ImuRecord
from sinslab.core.toml import dump_toml
from sinslab.sim._rng import _kernel_state, _normal, _rng
from sinslab.core.errors import InputError

__all__ = [
    "ImuErrors", "Trend", "RecordedNoise", "apply", "apply_arrays", "apply_arrays_shared", "apply_batch",
    "noise_increments",
    "gm_allan_deviation", "gm_sigma_from_allan_floor", "GM_ALLAN_PEAK", "GM_ALLAN_PEAK_TAU",
]

#: Peak of the Allan deviation of a first-order Gauss–Markov process, in units of its
#: steady-state σ, and where it occurs (in units of the correlation time).
GM_ALLAN_PEAK = 0.6173642831444409
GM_ALLAN_PEAK_TAU = 1.8926177072189478
_FLICKER = math.sqrt(2.0 * math.log(2.0) / math.pi)   # Allan floor / IEEE bias instability B

_SENSORS = ("gyro", "accel")

# --- units used on input (kind) and output (unit string) per quantity ----------------------
_KIND = {
    ("gyro", "bias"): ("angular_rate", "deg/h"),
    ("gyro", "arw"): ("angle_random_walk", "deg/sqrt(h)"),
    ("gyro", "bias_instability"): ("angular_rate", "deg/h"),
    ("gyro", "rrw"): ("rate_random_walk", "deg/h/sqrt(h)"),
    ("accel", "bias"): ("acceleration", "ug"),
    ("accel", "vrw"): ("velocity_random_walk", "ug/sqrt(Hz)"),
    ("accel", "bias_instability"): ("acceleration", "ug"),
    ("accel", "rrw"): ("accel_random_walk", "ug/sqrt(h)"),
}
_HINT = {
    "angle_random_walk": " (a white-noise figure quoted in deg/h is usually meant as deg/sqrt(h), "
                         "as PSINS reads it: write e.g. \"0.001 deg/sqrt(h)\")",
    "velocity_random_walk": " (an accelerometer noise quoted in ug is usually meant as ug/sqrt(Hz): "
                            "write e.g. \"10 ug/sqrt(Hz)\")",
}


def _fmt_vec(values, unit):
    """Unit string for 1 or 3 values: ``"0.01 deg/h"`` or ``"[0.003, -0.002, 0.0005] deg/h"``."""
    v = np.asarray(values, dtype=float).reshape(-1) / U.unit_scale(unit)
    v = [float(x) for x in v]
    if len(v) > 1 and all(x == v[0] for x in v):
        v = v[:1]
    if len(v) == 1:
        return f"{_num(v[0])} {unit}"
    return "[" + ", ".join(_num(x) for x in v) + f"] {unit}"


def _num(x):
    """12 significant digits: readable in a config ("30 deg", not "29.999999999999996 deg")."""
    return f"{x:.12g}"


def _parse_vec(key, value, kind, n=3):
    """parse_vector with the config key in every error message (1 or n values)."""
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiu":
        if kind != "dimensionless":
            raise ValueError(f"{key}: {value!r} has no unit; expected {kind.replace('_', ' ')}")
        value = list(value.reshape(-1))
    try:
        out = U.parse_vector(value, kind, n=n)
    except ValueError as e:
        raise ValueError(f"{key}: {e}{_HINT.get(kind, '')}") from None
    if not np.all(np.isfinite(out)):
        raise ValueError(f"{key}: {value!r} is not finite")
    return out


def _parse_per_time(key, value, kind, n=3):
    """Parse a rate-of-change quantity, e.g. ``"0.001 deg/h/h"`` for kind ``angular_rate``.

    The text's unit times one second must be of ``kind``; checked by appending ``*s``.
    """
    def one(x):
        if isinstance(x, str):
            s = x.strip()
            if s.endswith("]") or not s:
                raise ValueError(f"{key}: {x!r} has no unit; expected {kind.replace('_', ' ')} per time")
            return s + " * s"
        return x

    if isinstance(value, (list, tuple)):
        v2 = [one(x) for x in value]
    elif isinstance(value, str):
        v2 = one(value)
    else:
        v2 = value
    try:
        return U.parse_vector(v2, kind, n=n)
    except ValueError as e:
        msg = str(e).replace(" * s", "")
        raise ValueError(f"{key}: {msg} per time (e.g. \"{_example_per_time(kind)}\")") from None


def _example_per_time(kind):
    return "0.001 deg/h/h" if kind == "angular_rate" else "1 ug/h"


def _unknown(key, known, where):
    close = difflib.get_close_matches(key, known, n=1)
    hint = f"; did you mean {close[0]!r}?" if close else f"; known keys: {', '.join(sorted(known))}"
    raise ValueError(f"unknown {where} key {key!r}{hint}")


def _fields_equal(a, b):
    if type(a) is not type(b):
        return NotImplemented
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if x is None or y is None or not np.array_equal(x, y):
                return False
        elif x != y:
            return False
    return True


# --- trend ----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Trend:
    """Slow deterministic bias drift (temperature-like), per axis, SI.

    ``bias(s) = ramp·s + exp_amplitude·(1 − exp(−s/exp_time))
    + sin_amplitude·sin(2π·s/sin_period + sin_phase)``, ``s`` = time since the start of the
    record [s]. Units of ``ramp``: bias per second (rad/s² for gyros, m/s³ for accels);
    amplitudes: bias units; ``exp_time``, ``sin_period``: s (inf = term off); phase: rad.
    """

    ramp: np.ndarray = 0.0
    exp_amplitude: np.ndarray = 0.0
    exp_time: np.ndarray = math.inf
    sin_amplitude: np.ndarray = 0.0
    sin_period: np.ndarray = math.inf
    sin_phase: np.ndarray = 0.0

    _KEYS = ("ramp", "exp_amplitude", "exp_time", "sin_amplitude", "sin_period", "sin_phase")

    def __post_init__(self):
        for f in fields(self):
            object.__setattr__(self, f.name, U.vec3(getattr(self, f.name), f"trend {f.name}", readonly=True))
        for name in ("exp_time", "sin_period"):
            if (getattr(self, name) <= 0).any():
                raise ValueError(f"trend {name} must be > 0")
        for amp, tm in (("exp_amplitude", "exp_time"), ("sin_amplitude", "sin_period")):
            a, t = getattr(self, amp), getattr(self, tm)
            if ((a != 0) & ~np.isfinite(t)).any():
                raise ValueError(f"trend {amp} is set but {tm} is not")
        for name in ("ramp", "exp_amplitude", "sin_amplitude", "sin_phase"):
            if not np.isfinite(getattr(self, name)).all():
                raise ValueError(f"trend {name} is not finite")

    __eq__ = _fields_equal
    __hash__ = None

    @property
    def active(self) -> bool:
        return bool((self.ramp != 0).any() or (self.exp_amplitude != 0).any()
                    or (self.sin_amplitude != 0).any())

    def evaluate(self, s):
        """Bias drift at times ``s`` [s since record start], shape ``(..., 3)``.

        ``ramp·s + exp_amplitude·(1 − exp(−s/exp_time)) + sin_amplitude·sin(2π s/sin_period
        + sin_phase)`` per axis. An axis with no term is exactly +0 and is not evaluated
        (a trend on one gyro costs a third of three)."""
        s = np.asarray(s, dtype=float)[..., None]
        out = np.zeros(s.shape[:-1] + (3,))
        ax = (self.ramp != 0) | (self.exp_amplitude != 0) | (self.sin_amplitude != 0)
        if not ax.any():
            return out
        ea, sa = self.exp_amplitude[ax], self.sin_amplitude[ax]
        with np.errstate(invalid="ignore", divide="ignore"):
            e = np.where(ea != 0, ea * -np.expm1(-s / self.exp_time[ax]), 0.0)
            w = np.where(sa != 0, 2 * np.pi / self.sin_period[ax], 0.0)
        out[..., ax] = self.ramp[ax] * s + e + sa * np.sin(w * s + self.sin_phase[ax])
        return out

    @classmethod
    def from_dict(cls, d, sensor="gyro", prefix=None):
        """From ``{"ramp": "0.001 deg/h/h", "sin_amplitude": "0.002 deg/h", "sin_period": "24 h"}``."""
        prefix = prefix or f"{sensor}_trend"
        if isinstance(d, Trend):
            return d
        if not isinstance(d, dict):
            raise ValueError(f"{prefix}: expected a table of trend parameters, got {d!r}")
        kind = "angular_rate" if sensor == "gyro" else "acceleration"
        kw = {}
        for k, v in d.items():
            key = f"{prefix}.{k}"
            if k == "ramp":
                kw[k] = _parse_per_time(key, v, kind)
            elif k in ("exp_amplitude", "sin_amplitude"):
                kw[k] = _parse_vec(key, v, kind)
            elif k in ("exp_time", "sin_period"):
                kw[k] = _parse_vec(key, v, "time")
            elif k == "sin_phase":
                kw[k] = _parse_vec(key, v, "angle")
            else:
                _unknown(k, cls._KEYS, f"{prefix}")
        try:
            return cls(**kw)
        except ValueError as e:
            raise ValueError(f"{prefix}: {e}") from None

    def to_dict(self, sensor="gyro"):
        """Unit strings; terms that are off are left out."""
        bu = "deg/h" if sensor == "gyro" else "ug"
        out = {}
        if (self.ramp != 0).any():
            out["ramp"] = _fmt_vec(self.ramp, bu + "/h")
        if (self.exp_amplitude != 0).any():
            out["exp_amplitude"] = _fmt_vec(self.exp_amplitude, bu)
            out["exp_time"] = _fmt_vec(np.where(np.isfinite(self.exp_time), self.exp_time, 1.0), "s")
        if (self.sin_amplitude != 0).any():
            out["sin_amplitude"] = _fmt_vec(self.sin_amplitude, bu)
            out["sin_period"] = _fmt_vec(np.where(np.isfinite(self.sin_period), self.sin_period, 1.0), "s")
            if (self.sin_phase != 0).any():
                out["sin_phase"] = _fmt_vec(self.sin_phase, "deg")
        return out


@njit(cache=True, nogil=True)
def add_trend_terms(dth, s, k_of, ramp, ea, decay, sa, wave, dt):
    """``dth[:, a] += (ramp[k]·s + (ea[k]·decay[:, k] if ea[k] ≠ 0 else 0) + sa[k]·wave[:, k])·dt``
    for the axes ``a`` with a trend term (``k = k_of[a] ≥ 0``), ``+= 0`` for the others: the
    operations of :meth:`Trend.evaluate` in its order, sample by sample
    (no fused multiply-add: the same bits). ``wave`` of one row: the same at every sample."""
    step = np.uint64(1 if wave.shape[0] > 1 else 0)
    for i_ in range(dth.shape[0]):
        i = np.uint64(i_)          # unsigned: no negative-index wraparound per load
        for a_ in range(3):
            a = np.uint64(a_)
            k = k_of[a]
            if k < 0:
                dth[i, a] += 0.0
            else:
                u = np.uint64(k)
                e = ea[u] * decay[i, u] if ea[u] != 0 else 0.0
                dth[i, a] += (ramp[u] * s[i] + e + sa[u] * wave[i * step, u]) * dt


# --- recorded noise -------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class RecordedNoise:
    """A recorded noise sequence added to the output, sample by sample.

    Attributes
    ----------
    gyro, accel : ndarray (K, 3) or None
        Noise of the gyros [rad/s or rad] and accelerometers [m/s^2 or m/s]; None = none.
    kind : "rate" or "increment"
        Rates are multiplied by dt; increments are added as they are.
    dt : float or None
        Sampling interval of the recording [s]; when given it must equal the record's
        (the noise's spectrum depends on it).
    cycle : bool
        Repeat the recording from its start when the record is longer (else an error).
    source : str or None
        File the arrays were read from (kept for :meth:`ImuErrors.to_dict`).
    """

    gyro: np.ndarray | None = None
    accel: np.ndarray | None = None
    kind: str = "rate"
    dt: float | None = None
    cycle: bool = False
    source: str | None = None

    def __post_init__(self):
        if self.kind not in ("rate", "increment"):
            raise ValueError(f"recorded_noise.kind must be 'rate' or 'increment', got {self.kind!r}")
        n = None
        for name in ("gyro", "accel"):
            a = getattr(self, name)
            if a is None:
                continue
            a = np.ascontiguousarray(a, dtype=float)
            if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] == 0:
                raise ValueError(f"recorded_noise.{name} must have shape (K, 3), got {a.shape}")
            bad = ~np.isfinite(a)
            if bad.any():
                raise ValueError(f"recorded_noise.{name} has a NaN/inf value at sample "
                                 f"{int(np.argwhere(bad)[0][0])}")
            if n is not None and a.shape[0] != n:
                raise ValueError(f"recorded_noise gyro and accel lengths differ ({n} vs {a.shape[0]})")
            n = a.shape[0]
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        if n is None:
            raise ValueError("recorded_noise has neither gyro nor accel samples")
        if self.dt is not None:
            dt = float(self.dt)
            if not (dt > 0 and math.isfinite(dt)):
                raise ValueError(f"recorded_noise.dt must be > 0, got {self.dt!r}")
            object.__setattr__(self, "dt", dt)

    __eq__ = _fields_equal
    __hash__ = None

    def __len__(self):
        return (self.gyro if self.gyro is not None else self.accel).shape[0]

    @classmethod
    def load(cls, path, kind="rate", dt=None, cycle=False, gyro_unit=None, accel_unit=None):
        """Read ``.npz`` (arrays ``gyro``, ``accel``), ``.npy`` (K, 6) or text/CSV (K, 6 columns).

        Values in the file are SI unless ``gyro_unit`` / ``accel_unit`` name their unit
        (e.g. ``"deg/h"``, ``"ug"`` for rates).
        """
        path = os.fspath(path)
        if not os.path.exists(path):
            raise ValueError(f"recorded_noise.source: file {path!r} does not exist")
        ext = os.path.splitext(path)[1].lower()
        if ext == ".npz":
            with np.load(path) as z:
                g = z["gyro"] if "gyro" in z else None
                a = z["accel"] if "accel" in z else None
        else:
            if ext == ".npy":
                arr = np.load(path)
            else:
                with open(path) as fh:
                    head = fh.readline()
                arr = np.loadtxt(path, delimiter="," if "," in head else None, ndmin=2)
            if arr.ndim != 2 or arr.shape[1] != 6:
                raise ValueError(f"recorded_noise.source {path!r}: expected 6 columns "
                                 f"(gyro xyz, accel xyz), got shape {arr.shape}")
            g, a = arr[:, :3], arr[:, 3:]
        if g is not None and gyro_unit:
            g = g * U.unit_scale(gyro_unit)
        if a is not None and accel_unit:
            a = a * U.unit_scale(accel_unit)
        return cls(g, a, kind, dt, cycle, path)


# --- the parameter object ---------------------------------------------------------------------
_IDENT_KEYS = {
    "gyro": ("bias", "arw", "bias_instability", "corr_time", "rrw", "scale_factor",
             "misalignment", "trend", "noise_scale"),
    "accel": ("bias", "vrw", "bias_instability", "corr_time", "rrw", "scale_factor",
              "misalignment", "trend", "noise_scale"),
}
_DATASHEET_KEYS = tuple(f"{s}_{k}" for s in _SENSORS for k in _IDENT_KEYS[s]) + ("recorded_noise",)


@dataclass(frozen=True, eq=False)
class ImuErrors:
    """IMU error parameters, SI, per axis (IMU body frame). Frozen; the default is error-free.

    Build from datasheet strings with :meth:`from_datasheet` / :meth:`from_dict`; see the
    module docstring for the model and the units of each term.

    Attributes (gyro; accel likewise with ``vrw`` for ``arw``)
    ----------------------------------------------------------
    gyro_bias : (3,) rad/s
    gyro_arw : (3,) rad/sqrt(s)                  angle random walk N
    gyro_bias_instability : (3,) rad/s           steady-state σ of the Gauss–Markov bias
    gyro_corr_time : (3,) s                      its correlation time (inf = unset)
    gyro_rrw : (3,) rad/s/sqrt(s)                rate random walk K
    gyro_scale_factor : (3,) -                   diagonal of S
    gyro_misalignment : (3, 3) rad              M, zero diagonal
    gyro_trend : Trend or None
    gyro_noise_scale : (3,) -                    β on the random terms (default 1)
    recorded_noise : RecordedNoise or None
    """

    gyro_bias: np.ndarray = 0.0
    gyro_arw: np.ndarray = 0.0
    gyro_bias_instability: np.ndarray = 0.0
    gyro_corr_time: np.ndarray = math.inf
    gyro_rrw: np.ndarray = 0.0
    gyro_scale_factor: np.ndarray = 0.0
    gyro_misalignment: np.ndarray = None
    gyro_trend: Trend | None = None
    gyro_noise_scale: np.ndarray = 1.0
    accel_bias: np.ndarray = 0.0
    accel_vrw: np.ndarray = 0.0
    accel_bias_instability: np.ndarray = 0.0
    accel_corr_time: np.ndarray = math.inf
    accel_rrw: np.ndarray = 0.0
    accel_scale_factor: np.ndarray = 0.0
    accel_misalignment: np.ndarray = None
    accel_trend: Trend | None = None
    accel_noise_scale: np.ndarray = 1.0
    recorded_noise: RecordedNoise | None = field(default=None)

    def __post_init__(self):
        for s in _SENSORS:
            w = "arw" if s == "gyro" else "vrw"
            for k, nonneg in (("bias", False), (w, True), ("bias_instability", True),
                              ("rrw", True), ("scale_factor", False), ("noise_scale", True)):
                name = f"{s}_{k}"
                v = U.vec3(getattr(self, name), name, nonneg=nonneg, readonly=True)
                if not np.isfinite(v).all():
                    raise ValueError(f"{name} is not finite")
                object.__setattr__(self, name, v)
            name = f"{s}_corr_time"
            tc = U.vec3(getattr(self, name), name, readonly=True)
            if (tc <= 0).any():
                raise ValueError(f"{name} must be > 0, got {tc.tolist()}")
            object.__setattr__(self, name, tc)
            bi = getattr(self, f"{s}_bias_instability")
            if ((bi > 0) & ~np.isfinite(tc)).any():
                raise ValueError(f"{s}_bias_instability is set but {s}_corr_time is not "
                                 f"(give e.g. {s}_corr_time=\"300 s\")")
            name = f"{s}_misalignment"
            m = getattr(self, name)
            m = np.zeros((3, 3)) if m is None else np.array(m, dtype=float)
            if m.shape != (3, 3):
                raise ValueError(f"{name} must be a 3x3 matrix, got shape {m.shape}")
            if not np.isfinite(m).all():
                raise ValueError(f"{name} is not finite")
            if (np.diag(m) != 0).any():
                raise ValueError(f"{name} must have a zero diagonal (the diagonal is the scale factor)")
            m.setflags(write=False)
            object.__setattr__(self, name, m)
            tr = getattr(self, f"{s}_trend")
            if isinstance(tr, dict):
                tr = Trend.from_dict(tr, s)
            if tr is not None and not isinstance(tr, Trend):
                raise ValueError(f"{s}_trend must be a Trend or a table, got {tr!r}")
            object.__setattr__(self, f"{s}_trend", tr if (tr is not None and tr.active) else None)
        rn = self.recorded_noise
        if rn is not None and not isinstance(rn, RecordedNoise):
            if isinstance(rn, (tuple, list)) and len(rn) == 2:
                rn = RecordedNoise(rn[0], rn[1])
            else:
                raise ValueError("recorded_noise must be a RecordedNoise or a (gyro, accel) pair")
            object.__setattr__(self, "recorded_noise", rn)

    __eq__ = _fields_equal
    __hash__ = None

    # -- construction from datasheet units --------------------------------------------------
    @classmethod
    def from_datasheet(cls, **kw) -> "ImuErrors":
        """Build from datasheet quantities given as unit strings.

        Each rate-like item takes one value (all axes) or three (x, y, z): ``"0.01 deg/h"``,
        ``["0.003 deg/h", "-0.002 deg/h", "0.0005 deg/h"]`` or ``"[0.003, -0.002, 0.0005] deg/h"``.

        Keys (gyro / accel): ``gyro_bias`` ("deg/h"), ``gyro_arw`` ("deg/sqrt(h)"),
        ``gyro_bias_instability`` ("deg/h", GM steady-state σ), ``gyro_corr_time`` ("s"),
        ``gyro_rrw`` ("deg/h/sqrt(h)"), ``gyro_scale_factor`` ("ppm" or a bare fraction),
        ``gyro_misalignment`` (six off-diagonal angles ``"[xy, xz, yx, yz, zx, zy] arcsec"``
        or a 3x3 nested list), ``gyro_trend`` (table: ``ramp`` "deg/h/h", ``exp_amplitude``,
        ``exp_time``, ``sin_amplitude``, ``sin_period``, ``sin_phase``),
        ``gyro_noise_scale`` (β, bare number); ``accel_bias`` ("ug"), ``accel_vrw``
        ("ug/sqrt(Hz)"), ``accel_bias_instability`` ("ug"), ``accel_corr_time``,
        ``accel_rrw`` ("ug/sqrt(h)"), ``accel_scale_factor``, ``accel_misalignment``,
        ``accel_trend`` (ramp in "ug/h"), ``accel_noise_scale``; ``recorded_noise``: a
        ``(gyro, accel)`` pair of SI rate arrays (K, 3), a :class:`RecordedNoise`, or a
        table ``{source = "file.npz", kind = "rate"|"increment", dt = "0.01 s",
        cycle = false}``.

        Raises
        ------
        ValueError
            Naming the key: unknown key, bare number where a unit is needed, wrong
            dimension, wrong number of values.
        """
        return cls.from_dict(kw)

    @classmethod
    def from_dict(cls, d: dict) -> "ImuErrors":
        """Inverse of :meth:`to_dict` (same keys as :meth:`from_datasheet`)."""
        if not isinstance(d, dict):
            raise ValueError(f"IMU errors: expected a table of keys, got {type(d).__name__}")
        out = {}
        for key, v in d.items():
            if key not in _DATASHEET_KEYS:
                _unknown(key, _DATASHEET_KEYS, "IMU error")
            if key == "recorded_noise":
                out[key] = _parse_recorded(v)
                continue
            s, k = key.split("_", 1)
            if k == "corr_time":
                out[key] = _parse_vec(key, v, "time")
            elif k in ("scale_factor", "noise_scale"):
                out[key] = _parse_vec(key, v, "dimensionless")
            elif k == "misalignment":
                out[key] = _parse_misalignment(key, v)
            elif k == "trend":
                out[key] = Trend.from_dict(v, s, key)
            else:
                kind = _KIND[(s, k)][0]
                out[key] = _parse_vec(key, v, kind)
        try:
            return cls(**out)
        except ValueError as e:
            raise ValueError(f"IMU errors: {e}") from None

    @classmethod
    def from_toml(cls, text: str, table: str | None = "imu") -> "ImuErrors":
        """From TOML text; ``table`` is the (dotted) table holding the keys, None = top level."""
        import tomllib
        d = tomllib.loads(text)
        for part in (table.split(".") if table else []):
            if part not in d:
                raise ValueError(f"TOML has no table [{table}]")
            d = d[part]
        return cls.from_dict(d)

    # -- serialisation -----------------------------------------------------------------------
    def to_dict(self, full: bool = False) -> dict:
        """Datasheet form: unit strings, ready for a config file.

        Terms that are off (zero / default) are left out unless ``full``.
        """
        out = {}
        for s in _SENSORS:
            w = "arw" if s == "gyro" else "vrw"
            for k in ("bias", w, "bias_instability"):
                v = getattr(self, f"{s}_{k}")
                if full or (v != 0).any():
                    out[f"{s}_{k}"] = _fmt_vec(v, _KIND[(s, k)][1])
            tc = getattr(self, f"{s}_corr_time")
            if np.isfinite(tc).all() and (full or (tc != 0).any()):
                out[f"{s}_corr_time"] = _fmt_vec(tc, "s")
            v = getattr(self, f"{s}_rrw")
            if full or (v != 0).any():
                out[f"{s}_rrw"] = _fmt_vec(v, _KIND[(s, "rrw")][1])
            v = getattr(self, f"{s}_scale_factor")
            if full or (v != 0).any():
                out[f"{s}_scale_factor"] = _fmt_vec(v, "ppm")
            m = getattr(self, f"{s}_misalignment")
            if full or (m != 0).any():
                off = m[~np.eye(3, dtype=bool)]
                out[f"{s}_misalignment"] = "[" + ", ".join(
                    _num(float(x)) for x in off / U.arcsec) + "] arcsec"
            tr = getattr(self, f"{s}_trend")
            if tr is not None:
                out[f"{s}_trend"] = tr.to_dict(s)
            v = getattr(self, f"{s}_noise_scale")
            if full or (v != 1).any():
                out[f"{s}_noise_scale"] = float(v[0]) if (v == v[0]).all() else [float(x) for x in v]
        rn = self.recorded_noise
        if rn is not None:
            r = {"source": rn.source if rn.source else "<in-memory>", "kind": rn.kind,
                 "samples": len(rn), "cycle": rn.cycle}
            if rn.dt is not None:
                r["dt"] = f"{rn.dt!r} s"
            out["recorded_noise"] = r
        return out

    def to_toml(self, table: str | None = "imu", full: bool = False) -> str:
        """TOML fragment of :meth:`to_dict` under ``[table]`` (top level if None)."""
        return dump_toml(self.to_dict(full), table=table)

    # -- conveniences --------------------------------------------------------------------------
    def replace(self, **changes) -> "ImuErrors":
        """A copy with some SI fields changed (``dataclasses.replace``)."""
        import dataclasses
        return dataclasses.replace(self, **changes)

    def with_noise_scale(self, gyro=1.0, accel=1.0) -> "ImuErrors":
        """A copy with the random terms scaled by β (``gyro``, ``accel``)."""
        return self.replace(gyro_noise_scale=gyro, accel_noise_scale=accel)

    @property
    def is_deterministic(self) -> bool:
        """True when no random term is active (apply then ignores the seed)."""
        for s in _SENSORS:
            w = "arw" if s == "gyro" else "vrw"
            beta = getattr(self, f"{s}_noise_scale")
            for k in (w, "bias_instability", "rrw"):
                if ((getattr(self, f"{s}_{k}") * beta) != 0).any():
                    return False
        return True


def _parse_misalignment(key, v):
    if isinstance(v, np.ndarray) and v.shape == (3, 3) and v.dtype.kind in "fiu":
        raise ValueError(f"{key}: a bare 3x3 matrix has no unit; give angles, e.g. \"10 arcsec\"")
    if isinstance(v, (list, tuple)) and len(v) == 3 and all(isinstance(r, (list, tuple)) for r in v):
        rows = [_parse_vec(f"{key}[{i}]", list(r), "angle") for i, r in enumerate(v)]
        m = np.array(rows)
        if (np.diag(m) != 0).any():
            raise ValueError(f"{key}: the diagonal must be zero (it is the scale factor)")
        return m
    one = (isinstance(v, str) and not v.strip().startswith("[")) or (
        isinstance(v, (list, tuple)) and len(v) == 1)
    try:
        if one:
            raise ValueError(f"{v!r} is a single value")
        off = U.parse_vector(v, "angle", n=6)
    except ValueError as e:
        raise ValueError(f"{key}: {e}; give the six off-diagonal angles "
                         f"\"[xy, xz, yx, yz, zx, zy] arcsec\" or a 3x3 table") from None
    m = np.zeros((3, 3))
    m[~np.eye(3, dtype=bool)] = off
    return m


def _parse_recorded(v):
    if v is None or isinstance(v, RecordedNoise):
        return v
    if isinstance(v, (tuple, list)) and len(v) == 2 and not isinstance(v[0], str):
        return RecordedNoise(v[0], v[1])
    if isinstance(v, (str, os.PathLike)):
        return RecordedNoise.load(v)
    if isinstance(v, dict):
        known = ("source", "kind", "dt", "cycle", "samples", "gyro_unit", "accel_unit")
        for k in v:
            if k not in known:
                _unknown(k, known, "recorded_noise")
        src = v.get("source")
        if not src or src == "<in-memory>":
            raise ValueError("recorded_noise.source: the noise was given in memory; pass "
                             "recorded_noise=(gyro, accel) arrays or a file name")
        dt = v.get("dt")
        dt = None if dt is None else U.parse(dt, "time")
        rn = RecordedNoise.load(src, kind=v.get("kind", "rate"), dt=dt, cycle=bool(v.get("cycle", False)),
                                gyro_unit=v.get("gyro_unit"), accel_unit=v.get("accel_unit"))
        if "samples" in v and int(v["samples"]) != len(rn):
            raise ValueError(f"recorded_noise.samples: file {src!r} has {len(rn)} samples, "
                             f"config says {v['samples']}")
        return rn
    raise ValueError(f"recorded_noise: expected (gyro, accel) arrays, a file name or a table, got {v!r}")


# --- Allan helpers ------------------------------------------------------------------------------
def gm_allan_deviation(tau, sigma, corr_time):
    """Allan deviation of a first-order Gauss–Markov process (steady-state σ, time T).

    ``σ_A²(τ) = (σ T/τ)² · (2τ/T − 3 + 4 e^{−τ/T} − e^{−2τ/T})``: ~ sqrt(2σ²T/τ) for
    τ ≫ T (white), ~ σ sqrt(2τ/(3T)) for τ ≪ T (rate random walk), peak 0.6174 σ at
    τ ≈ 1.893 T.
    """
    x = np.asarray(tau, dtype=float) / corr_time
    small = x < 1e-3
    xs = np.where(small, 1.0, x)
    f = (2 * xs - 3 + 4 * np.exp(-xs) - np.exp(-2 * xs)) / xs ** 2
    f = np.where(small, 2 * x / 3 - x * x / 2, f)
    return sigma * np.sqrt(f)


def gm_sigma_from_allan_floor(value, convention="ieee"):
    """Steady-state σ of a GM process whose Allan-deviation peak matches a datasheet figure.

    ``convention="ieee"``: ``value`` is the bias-instability coefficient B (Allan floor =
    0.664·B), σ = 0.664·B / 0.6174 ≈ 1.076·B. ``convention="floor"``: ``value`` is the
    minimum of the Allan-deviation curve itself, σ = floor / 0.6174 ≈ 1.620·floor.
    """
    if convention == "ieee":
        return value * _FLICKER / GM_ALLAN_PEAK
    if convention == "floor":
        return value / GM_ALLAN_PEAK
    raise ValueError(f"convention must be 'ieee' or 'floor', got {convention!r}")


# --- compiled kernels ----------------------------------------------------------------------------
# one pass over the record per error model; normals from the in-kernel generator of
# sinslab.sim._rng, whose draw is inlined into each kernel (a change there compiles them
# again: sinslab.core.jitcache stamps a cached kernel with the modules its file imports)
@njit(cache=True, nogil=True)
def _kernel(dth, dv, tend, t0, dt, state, K, use_k, bias_dt, wsig, wact, gsig, gphi, gdrv, gact,
            rstep, ract, has_trend, tr_ramp, tr_ea, tr_et, tr_esh, tr_sa, tr_sw, tr_ssh, tr_sp,
            has_rec, rec_g, rec_a, rec_gain, rec_n, out_dth, out_dv):
    """All samples in one pass. K: (2,3,3) I+S+M; per-channel parameters (6,), channels gyro
    xyz, accel xyz; *act: the term is on for that channel. Normals are drawn sample by
    sample, channel by channel, white then Gauss-Markov then random walk (only active terms);
    the Gauss-Markov start values are drawn first."""
    n = dth.shape[0]
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    gx = np.zeros(6)
    rx = np.zeros(6)
    for c in range(6):                     # stationary Gauss-Markov start
        if gact[c]:
            z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
            gx[c] = gsig[c] * z
    kr = 0
    for k in range(n):
        for s in range(2):
            if s == 0:
                x0, x1, x2 = dth[k, 0], dth[k, 1], dth[k, 2]
            else:
                x0, x1, x2 = dv[k, 0], dv[k, 1], dv[k, 2]
            for i in range(3):
                c = 3 * s + i
                if use_k:
                    y = K[s, i, 0] * x0 + K[s, i, 1] * x1 + K[s, i, 2] * x2
                elif i == 0:
                    y = x0
                elif i == 1:
                    y = x1
                else:
                    y = x2
                e = bias_dt[c]
                if wact[c]:
                    z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
                    e += wsig[c] * z
                if gact[c]:
                    e += gx[c] * dt
                    z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
                    gx[c] = gphi[c] * gx[c] + gdrv[c] * z
                if ract[c]:
                    e += rx[c] * dt
                    z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
                    rx[c] += rstep[c] * z
                if has_trend:
                    tm = tend[k] - 0.5 * dt - t0
                    tr = tr_ramp[c] * tm * dt
                    if tr_ea[c] != 0.0:
                        tr += tr_ea[c] * (dt - tr_esh[c] * math.exp(-tm / tr_et[c]))
                    if tr_sa[c] != 0.0:
                        tr += tr_sa[c] * tr_ssh[c] * math.sin(tr_sw[c] * tm + tr_sp[c])
                    e += tr
                if has_rec:
                    if s == 0:
                        e += rec_gain[c] * rec_g[kr, i]
                    else:
                        e += rec_gain[c] * rec_a[kr, i]
                if s == 0:
                    out_dth[k, i] = y + e
                else:
                    out_dv[k, i] = y + e
        kr += 1
        if kr == rec_n:
            kr = 0


@njit(cache=True, nogil=True)
def _kernel_white(dth, dv, state, K, use_k, bias_dt, wsig, wact, out_dth, out_dv):
    """:func:`_kernel` for the common model of constant bias and white noise only (no
    Gauss-Markov, random walk, trend or recorded noise): the same draws in the same order
    and the same arithmetic, so the same bytes, without the per-channel tests of the terms
    that are off (0.6 of the time of :func:`_kernel` on such a model)."""
    n = dth.shape[0]
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    for k in range(n):
        for s in range(2):
            if s == 0:
                x0, x1, x2 = dth[k, 0], dth[k, 1], dth[k, 2]
            else:
                x0, x1, x2 = dv[k, 0], dv[k, 1], dv[k, 2]
            for i in range(3):
                c = 3 * s + i
                if use_k:
                    y = K[s, i, 0] * x0 + K[s, i, 1] * x1 + K[s, i, 2] * x2
                elif i == 0:
                    y = x0
                elif i == 1:
                    y = x1
                else:
                    y = x2
                e = bias_dt[c]
                if wact[c]:
                    z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
                    e += wsig[c] * z
                if s == 0:
                    out_dth[k, i] = y + e
                else:
                    out_dv[k, i] = y + e


@njit(cache=True, nogil=True)
def _kernel_white_all(dth, dv, state, bias_dt, wsig, out_dth, out_dv):
    """:func:`_kernel_white` with white noise on all six channels and no scale factor or
    misalignment, unrolled over the channels with the parameters in scalars: same draws,
    same arithmetic (y + (bias + σ·z)), same bytes, 0.6 of the time of
    :func:`_kernel_white` (~13 ns per sample: six normals of ~2 ns and the stores)."""
    n = dth.shape[0]
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    b0, b1, b2, b3, b4, b5 = bias_dt[0], bias_dt[1], bias_dt[2], bias_dt[3], bias_dt[4], bias_dt[5]
    w0, w1, w2, w3, w4, w5 = wsig[0], wsig[1], wsig[2], wsig[3], wsig[4], wsig[5]
    for k in range(n):
        z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        out_dth[k, 0] = dth[k, 0] + (b0 + w0 * z)
        z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        out_dth[k, 1] = dth[k, 1] + (b1 + w1 * z)
        z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        out_dth[k, 2] = dth[k, 2] + (b2 + w2 * z)
        z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        out_dv[k, 0] = dv[k, 0] + (b3 + w3 * z)
        z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        out_dv[k, 1] = dv[k, 1] + (b4 + w4 * z)
        z, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        out_dv[k, 2] = dv[k, 2] + (b5 + w5 * z)


@njit(cache=True, nogil=True)
def _kernel_white_all_shared(dth, dv, state, bias_dt, wsig, out_dth, out_dv):
    """:func:`_kernel_white_all` for V error models on one random stream: ``bias_dt``,
    ``wsig`` (V, 6), ``out_dth``, ``out_dv`` (V, n, 3). Each normal is drawn once and used
    by every model with the single kernel's arithmetic ``x + (b + σ·z)``, so model j gets
    the bytes :func:`_kernel_white_all` gives it from the same state. The six draws of a
    sample are unrolled into scalars before the loop over the models, which then writes
    each model's six values: a loop over the channels around the models' loop cost ~1.5x
    the time (the draws stay in the same order, so the stream and the bytes are the same)."""
    n = dth.shape[0]
    V = bias_dt.shape[0]
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    for k in range(n):
        z0, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        z1, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        z2, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        z3, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        z4, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        z5, s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
        x0, x1, x2 = dth[k, 0], dth[k, 1], dth[k, 2]
        y0, y1, y2 = dv[k, 0], dv[k, 1], dv[k, 2]
        for j in range(V):
            out_dth[j, k, 0] = x0 + (bias_dt[j, 0] + wsig[j, 0] * z0)
            out_dth[j, k, 1] = x1 + (bias_dt[j, 1] + wsig[j, 1] * z1)
            out_dth[j, k, 2] = x2 + (bias_dt[j, 2] + wsig[j, 2] * z2)
            out_dv[j, k, 0] = y0 + (bias_dt[j, 3] + wsig[j, 3] * z3)
            out_dv[j, k, 1] = y1 + (bias_dt[j, 4] + wsig[j, 4] * z4)
            out_dv[j, k, 2] = y2 + (bias_dt[j, 5] + wsig[j, 5] * z5)


def _prepare(errors: ImuErrors, dt, n):
    """The kernel that applies ``errors`` at interval ``dt`` [s] to n samples and its
    parameters: ``(path, params, random)``. ``path`` is ``"white_all"``
    (:func:`_kernel_white_all`), ``"white"`` (:func:`_kernel_white`) or ``"general"``
    (:func:`_kernel`); ``params`` the arguments between the generator state and the
    outputs (after ``tend, t0, dt`` for the general kernel); ``random``: some random term
    is active, so the kernel's generator state is drawn."""
    if not isinstance(errors, ImuErrors):
        raise ValueError(f"errors must be an ImuErrors, got {type(errors).__name__}")
    e = errors
    K = np.empty((2, 3, 3))
    for s_i, s in enumerate(_SENSORS):
        K[s_i] = np.eye(3) + np.diag(getattr(e, f"{s}_scale_factor")) + getattr(e, f"{s}_misalignment")
    use_k = bool((K != np.eye(3)).any())
    cat = lambda a, b: np.ascontiguousarray(np.concatenate([a, b]), dtype=float)  # noqa: E731
    beta = cat(e.gyro_noise_scale, e.accel_noise_scale)
    bias_dt = cat(e.gyro_bias, e.accel_bias) * dt
    wsig = cat(e.gyro_arw, e.accel_vrw) * beta * math.sqrt(dt)
    bi = cat(e.gyro_bias_instability, e.accel_bias_instability) * beta
    tc = cat(e.gyro_corr_time, e.accel_corr_time)
    gphi = np.exp(-dt / tc)
    gdrv = bi * np.sqrt(-np.expm1(-2.0 * dt / tc))
    rstep = cat(e.gyro_rrw, e.accel_rrw) * beta * math.sqrt(dt)
    wact, gact, ract = wsig != 0, bi != 0, rstep != 0

    trs = [e.gyro_trend or Trend(), e.accel_trend or Trend()]
    has_trend = e.gyro_trend is not None or e.accel_trend is not None
    tr_ramp = cat(trs[0].ramp, trs[1].ramp)
    tr_ea = cat(trs[0].exp_amplitude, trs[1].exp_amplitude)
    tr_et = cat(trs[0].exp_time, trs[1].exp_time)
    tr_et = np.where(np.isfinite(tr_et), tr_et, 1.0)
    tr_esh = 2.0 * tr_et * np.sinh(dt / (2.0 * tr_et))
    tr_sa = cat(trs[0].sin_amplitude, trs[1].sin_amplitude)
    per = cat(trs[0].sin_period, trs[1].sin_period)
    tr_sw = np.where(np.isfinite(per), 2.0 * np.pi / np.where(np.isfinite(per), per, 1.0), 0.0)
    tr_ssh = np.where(tr_sw != 0, 2.0 * np.sin(0.5 * tr_sw * dt) / np.where(tr_sw != 0, tr_sw, 1.0), dt)
    tr_sp = cat(trs[0].sin_phase, trs[1].sin_phase)

    rn = e.recorded_noise
    dummy = np.zeros((1, 3))
    if rn is not None:
        if rn.dt is not None and abs(rn.dt - dt) > 1e-6 * dt:
            raise ValueError(f"recorded noise was sampled at dt = {rn.dt!r} s but the IMU record "
                             f"has dt = {dt!r} s")
        if len(rn) < n and not rn.cycle:
            raise ValueError(f"recorded noise has {len(rn)} samples, the IMU record {n} "
                             f"(set cycle=True to repeat it)")
        gain = beta * (dt if rn.kind == "rate" else 1.0)
        rec_g = rn.gyro if rn.gyro is not None else dummy
        rec_a = rn.accel if rn.accel is not None else dummy
        if rn.gyro is None:
            gain[:3] = 0.0
        if rn.accel is None:
            gain[3:] = 0.0
        if rn.gyro is None and rn.accel is not None:
            rec_g = np.zeros((len(rn), 3))
        if rn.accel is None:
            rec_a = np.zeros((len(rn), 3))
        rec_n = len(rn)
    else:
        gain, rec_g, rec_a, rec_n = np.zeros(6), dummy, dummy, 1

    random = bool(wact.any() or gact.any() or ract.any())
    if not (gact.any() or ract.any() or has_trend or rn is not None):
        if not use_k and wact.all():
            return "white_all", (bias_dt, wsig), random
        return "white", (K, use_k, bias_dt, wsig, wact), random
    return "general", (K, use_k, bias_dt, wsig, wact, bi, gphi, gdrv, gact, rstep, ract, has_trend,
                       tr_ramp, tr_ea, tr_et, tr_esh, tr_sa, tr_sw, tr_ssh, tr_sp, rn is not None,
                       rec_g, rec_a, gain, rec_n), random


def _run(dth, dv, tend, t0, dt, errors: ImuErrors, rng, out_dth, out_dv):
    _run_prepared(dth, dv, tend, t0, dt, _prepare(errors, dt, dth.shape[0]), rng, out_dth, out_dv)


def _run_prepared(dth, dv, tend, t0, dt, prepared, rng, out_dth, out_dv):
    path, params, random = prepared
    state = _kernel_state(rng) if random else np.ones(4, np.uint64)
    if path == "white_all":
        _kernel_white_all(dth, dv, state, *params, out_dth, out_dv)
    elif path == "white":
        _kernel_white(dth, dv, state, *params, out_dth, out_dv)
    else:
        _kernel(dth, dv, tend, t0, dt, state, *params, out_dth, out_dv)


_RECORD_FIELDS = ("t", "dtheta", "dv", "dt", "rel_tol")


def _new_record(imu: ImuRecord, dth, dv):
    """``imu`` with new increments, without re-validating its (already valid) time column,
    which would cost as much as applying the errors. Falls back to the constructor if
    ImuRecord ever gains fields this does not know."""
    if tuple(f.name for f in fields(ImuRecord)) != _RECORD_FIELDS:
        return ImuRecord(imu.t, dth, dv, imu.dt)
    rec = object.__new__(ImuRecord)
    for name, v in zip(_RECORD_FIELDS, (imu.t, dth, dv, imu.dt, imu.rel_tol)):
        object.__setattr__(rec, name, v)
    return rec


def apply(imu: ImuRecord, errors: ImuErrors, seed) -> ImuRecord:
    """IMU record with the sensor errors applied to its increments.

    Parameters
    ----------
    imu : ImuRecord
        True increments (IMU body frame).
    errors : ImuErrors
        The error model.
    seed : int or numpy.random.Generator
        Randomness; the same int gives the same bytes. A Generator is advanced.

    Returns
    -------
    ImuRecord
        Same time column, erroneous ``dtheta`` and ``dv``. The trend's time origin is the
        start of the record, ``imu.t0``.
    """
    if not isinstance(imu, ImuRecord):
        raise ValueError(f"imu must be an ImuRecord, got {type(imu).__name__}")
    rng = _rng(seed)
    n = len(imu)
    out_dth = np.empty((n, 3))
    out_dv = np.empty((n, 3))
    _run(imu.dtheta, imu.dv, imu.t, imu.t0, imu.dt, errors, rng, out_dth, out_dv)
    if not (np.isfinite(out_dth[-1]).all() and np.isfinite(out_dv[-1]).all()):
        raise InputError("IMU errors produced non-finite increments (check the parameters)")
    return _new_record(imu, out_dth, out_dv)


def apply_arrays(dtheta, dv, t, dt, errors: ImuErrors, seed):
    """:func:`apply` on bare arrays: the same draws and arithmetic, hence the same bytes,
    without building (and re-checking the time column of) an :class:`ImuRecord` — for
    loops that feed long records chunk by chunk on a regular grid they made themselves.

    Parameters
    ----------
    dtheta, dv : array (n, 3)
        True increments [rad], [m/s] (IMU body frame).
    t : array (n,)
        End time of each interval [s], regular with step ``dt`` (not checked).
    dt : float
        Sampling interval [s].
    errors : ImuErrors
    seed : int or numpy.random.Generator

    Returns
    -------
    dtheta, dv : ndarray (n, 3)
        New arrays with the errors applied.
    """
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    dv = np.ascontiguousarray(dv, dtype=float)
    t = np.asarray(t, dtype=float)
    n = dtheta.shape[0]
    out_dth = np.empty((n, 3))
    out_dv = np.empty((n, 3))
    _run(dtheta, dv, t, float(t[0] - dt), float(dt), errors, _rng(seed), out_dth, out_dv)
    return out_dth, out_dv


def apply_arrays_shared(dtheta, dv, t, dt, errors, seed, *, out=None):
    """:func:`apply_arrays` for several error models driven by one random stream — the
    same noise realisation at several noise scales β or biases (paper 001's INS #2 at
    each β), or with and without a term that draws nothing (a trend).

    Model j gets the bytes of ``apply_arrays(dtheta, dv, t, dt, errors[j], g)`` with ``g``
    in the state ``seed`` has now, and the generator is left as such a call leaves it
    (models with a random term all advance it alike; a model without one leaves it).
    Models of constant bias and white noise on all six channels (no scale factor or
    misalignment) share each normal draw, which is most of the cost; other models are
    applied one after another from the same generator state.

    Parameters
    ----------
    dtheta, dv, t, dt, seed
        As for :func:`apply_arrays`.
    errors : sequence of ImuErrors
        V >= 1 models.
    out : (ndarray, ndarray), optional
        Two C-contiguous float arrays (V, n, 3) to write the result into (a caller going
        through a long record chunk by chunk reuses them instead of new pages per chunk).

    Returns
    -------
    dtheta, dv : ndarray (V, n, 3)
    """
    errors = list(errors)
    if not errors:
        raise ValueError("apply_arrays_shared needs at least one error model")
    dtheta = np.ascontiguousarray(dtheta, dtype=float)
    dv = np.ascontiguousarray(dv, dtype=float)
    t = np.asarray(t, dtype=float)
    n = dtheta.shape[0]
    rng = _rng(seed)
    if out is None:
        out_dth, out_dv = np.empty((len(errors), n, 3)), np.empty((len(errors), n, 3))
    else:
        out_dth, out_dv = out
        for a in out:
            if (not isinstance(a, np.ndarray) or a.shape != (len(errors), n, 3) or a.dtype != np.float64
                    or not a.flags.c_contiguous):
                raise ValueError(f"out must be two C-contiguous float64 arrays of shape {(len(errors), n, 3)}")
    prep = [_prepare(e, float(dt), n) for e in errors]
    if all(path == "white_all" for path, _, _ in prep):
        bias_dt = np.stack([p[0] for _, p, _ in prep])
        wsig = np.stack([p[1] for _, p, _ in prep])
        _kernel_white_all_shared(dtheta, dv, _kernel_state(rng), bias_dt, wsig, out_dth, out_dv)
        return out_dth, out_dv
    start = rng.bit_generator.state
    end = start
    for j, pj in enumerate(prep):
        rng.bit_generator.state = start
        _run_prepared(dtheta, dv, t, float(t[0] - dt), float(dt), pj, rng, out_dth[j], out_dv[j])
        if pj[2]:                   # every model with a random term draws the same four words
            end = rng.bit_generator.state
    rng.bit_generator.state = end
    return out_dth, out_dv


def apply_batch(imu: ImuRecord, errors: ImuErrors, seeds) -> list[ImuRecord]:
    """:func:`apply` for several seeds (one record each, same bytes as separate calls)."""
    return [apply(imu, errors, s) for s in seeds]


def noise_increments(n: int, dt: float, errors: ImuErrors, rng, t0: float = 0.0):
    """The additive error increments alone (bias, noise, GM, random walk, trend, recorded).

    Returns ``(dtheta_err, dv_err)``, each (n, 3): what :func:`apply` adds to a zero input
    (with the same seed, ``apply(imu)`` equals ``(I+S+M)·imu + noise_increments``). Useful
    to synthesise a "recorded" static noise file, e.g. for :class:`RecordedNoise`.
    """
    n = int(n)
    if n <= 0:
        raise ValueError(f"n must be > 0, got {n}")
    dt = float(dt)
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"dt must be > 0, got {dt!r}")
    z = np.zeros((n, 3))
    tend = t0 + dt * np.arange(1, n + 1)
    out_dth = np.empty((n, 3))
    out_dv = np.empty((n, 3))
    _run(z, z, tend, float(t0), dt, errors, _rng(rng), out_dth, out_dv)
    return out_dth, out_dv
