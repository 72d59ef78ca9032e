"""Trajectory generator: motion segments -> truth and exact IMU increments.

A motion is a list of segments (:class:`Static`, :class:`Accelerate`, :class:`Turn`,
:class:`Climb`, :class:`Level`, :class:`WingRock`, :class:`Ship`) flown from a
:class:`Start`, optionally with the IMU on a moving mount (:mod:`sinslab.sim.indexing`:
rotate-stop indexing or a swinging table). :func:`generate` returns the truth (position,
ENU velocity, attitude of the carrier and of the IMU) and the IMU increments
``Δθ = ∫ω_ib^b dt``, ``Δv = ∫f^b dt`` in the IMU frame, consistent with
:mod:`sinslab.core.earth` (same radii, normal gravity and Earth rate), so that error-free
strapdown navigation of the increments reproduces the truth.

Model
-----
The carrier's velocity follows a *track*: speed ``V``, track yaw ``ψ_v`` (``= −course``)
and path angle ``θ_v``::

    v^n = R_z(ψ_v) R_x(θ_v) [0, V, 0]^T + [0, 0, ḣ_heave]

The body attitude is the track plus offsets: pitch ``θ_v + θ_sway``, yaw ``ψ_v + ψ_sway``,
roll ``φ_bank + γ_offset`` where ``tan φ_bank = V·ω/g0`` during coordinated turns
(ω = heading rate; right turn, right wing down = positive roll). Each of these
channels is a sum of smooth pieces — rate trapezoids with quintic smooth-step corners
(accelerations, turns, indexing rotations), quintic transitions (climbs), sinusoids with
smooth envelopes (wing rock, ship sway) — so velocity, attitude and their first two
derivatives are continuous. ``ω_nb^b`` follows from the analytic Euler-angle rates and

    ω_ib^b = ω_nb^b + C_n^b (ω_ie^n + ω_en^n),
    f^b    = C_n^b (v̇^n + (2ω_ie^n + ω_en^n) × v^n − g^n),   g^n = [0, 0, −g(L, h)].

With a mount, ``C_b^n = C_c^n C_b^c`` and ``ω_ib^b = C_c^b ω_ic^c + ω_cb^b`` (IMU at the
navigation point, no lever arm).

Numerics: every epoch ``t_k = t0 + k·dt`` is evaluated once (velocity, attitude, rates,
Earth terms); the increment over ``[t_k, t_k+1]`` is the exact integral of the polynomial
through the 8 neighbouring epochs (order 8), and position is integrated with the same
weights. Intervals whose stencil straddles a breakpoint of the profiles (segment and ramp
boundaries, where third derivatives jump) are split at the breakpoints and integrated
with Gauss–Legendre quadrature of the same order, positions by collocation. Increment
errors are ~1e-15 rad / ~1e-14 m/s (tests). Everything per sample runs in one numba
kernel; segments are first compiled into parameter arrays (channel terms and pieces).

Units: SI inside (rad, m, s). Configs/TOML give unit strings (``"3 deg/s"``); heading in
:class:`Start` is clockwise from north, the Euler yaw in the outputs is ``−heading``.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import ClassVar

import numpy as np
from numba import njit

from sinslab.core import earth, units
from sinslab.sim import indexing
from sinslab.core.attitude import euler_dcm_sc, euler_rates_to_body_sc
from sinslab.core.records import ImuRecord, NavSeries

__all__ = [
    "Start", "Segment", "Static", "Accelerate", "Turn", "Climb", "Level", "WingRock", "Ship",
    "SEGMENT_KINDS", "segment_from_dict", "segments_from_list", "load_segments", "load_motion",
    "dump_segments", "Motion", "Generated", "generate", "static", "aircraft_mixed",
    "ship_manoeuvring", "total_duration",
]

G0 = units.g0          # gravity used for the coordinated-turn bank angle (a body attitude only)

_DUMP_UNITS = {"time": "s", "angle": "deg", "angular_rate": "deg/s", "velocity": "m/s",
               "acceleration": "m/s^2", "length": "m"}


def _q(kind):
    return field(metadata={"q": kind})


def _qd(kind, default):
    return field(default=default, metadata={"q": kind})


# --- start -------------------------------------------------------------------------------
@dataclass(frozen=True)
class Start:
    """Initial condition of a motion (SI: rad, m, m/s).

    ``heading`` is clockwise from north (the Euler yaw is ``−heading``); ``pitch`` is
    the initial path angle (and body pitch), ``roll`` a constant body roll.
    """

    lat: float = _q("angle")
    lon: float = _q("angle")
    h: float = _qd("length", 0.0)
    speed: float = _qd("velocity", 0.0)
    heading: float = _qd("angle", 0.0)
    pitch: float = _qd("angle", 0.0)
    roll: float = _qd("angle", 0.0)

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise ValueError(f"start: key {f.name!r} must be a number in SI units, got {v!r}")
            v = float(v)
            if not math.isfinite(v):
                raise ValueError(f"start: key {f.name!r} is not finite")
            object.__setattr__(self, f.name, v)
        if abs(self.lat) > math.pi / 2:
            raise ValueError(f"start: key 'lat': latitude {math.degrees(self.lat):.6g} deg is beyond ±90 deg")
        if abs(self.pitch) >= math.pi / 2:
            raise ValueError("start: key 'pitch' must be within ±90 deg")

    @classmethod
    def from_dict(cls, d: dict) -> "Start":
        """From a table of unit strings, e.g. ``{lat="32 deg", lon="118 deg", h="1000 m"}``."""
        return cls(**_parse_fields(cls, d, "start"))

    def to_dict(self) -> dict:
        return _dump_fields(self)


# --- segments ----------------------------------------------------------------------------
def _parse_fields(cls, d, where, extra=None):
    """Parse a table of unit strings into SI keyword arguments of dataclass ``cls``.

    ``extra`` maps additional allowed keys (handled by the caller) to the field they stand
    in for (that field is then not required)."""
    if not isinstance(d, dict):
        raise ValueError(f"{where}: expected a table, got {type(d).__name__}")
    extra = extra or {}
    flds = {f.name: f for f in fields(cls)}
    out = {}
    for key, value in d.items():
        if key == "kind" or key in extra:
            continue
        if key not in flds:
            raise ValueError(f"{where}: unknown key {key!r}; allowed: "
                             f"{', '.join(list(flds) + list(extra))}")
        q = flds[key].metadata.get("q")
        if q is None:                                   # booleans
            if not isinstance(value, bool):
                raise ValueError(f"{where}: key {key!r} must be true or false, got {value!r}")
            out[key] = value
            continue
        try:
            out[key] = units.parse(value, q)
        except ValueError as e:
            raise ValueError(f"{where}: key {key!r}: {e}") from None
    covered = {v for k, v in extra.items() if k in d}
    for name, f in flds.items():
        if name not in out and name not in covered and f.default is _MISSING \
                and f.default_factory is _MISSING:
            raise ValueError(f"{where}: missing key {name!r}")
    return out


from dataclasses import MISSING as _MISSING  # noqa: E402


def _fmt(v, q):
    u = _DUMP_UNITS[q]
    return f"{indexing.short_number(v, units.unit_scale(u))} {u}"


def _dump_fields(obj):
    d = {}
    for f in fields(obj):
        v = getattr(obj, f.name)
        if v is None:
            continue
        q = f.metadata.get("q")
        d[f.name] = v if q is None else _fmt(v, q)
    return d


@dataclass(frozen=True)
class Segment:
    """Base of the motion segments: a duration [s] (> 0) and kind-specific fields (SI)."""

    kind: ClassVar[str] = ""

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if f.metadata.get("q") is None:
                if not isinstance(v, bool):
                    raise ValueError(f"key {f.name!r} must be true or false, got {v!r}")
                continue
            if v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)):
                raise ValueError(f"key {f.name!r} must be a number in SI units, got {v!r}")
            if not math.isfinite(float(v)):
                raise ValueError(f"key {f.name!r} is not finite")
            object.__setattr__(self, f.name, float(v))
        if not self.duration > 0:
            raise ValueError(f"key 'duration' must be > 0, got {self.duration!r} s")
        self._check()

    def _check(self):
        pass

    def _transition_ok(self):
        """Default ``transition`` (min(5 s, duration)) and check it fits (Climb, Level)."""
        if self.transition is None:
            object.__setattr__(self, "transition", min(5.0, self.duration))
        self._ramp_ok("transition", 1)

    def _ramp_ok(self, key, n=2):
        r = getattr(self, key)
        if r < 0:
            raise ValueError(f"key {key!r} must be >= 0, got {r!r} s")
        if n * r > self.duration * (1 + 1e-12):
            raise ValueError(f"key {key!r}: {n} x {r:g} s does not fit in duration {self.duration:g} s")

    @classmethod
    def from_dict(cls, d: dict, index: int | None = None) -> "Segment":
        """From a table of unit strings (``{kind="turn", duration="60 s", rate="3 deg/s"}``)."""
        where = f"segment {index} ({cls.kind})" if index is not None else f"segment ({cls.kind})"
        kw = _parse_fields(cls, d, where, cls._extra_keys())
        kw = cls._from_parsed(kw, d, where)
        try:
            return cls(**kw)
        except (TypeError, ValueError) as e:
            raise ValueError(f"{where}: {e}") from None

    @classmethod
    def _extra_keys(cls):
        return None

    @classmethod
    def _from_parsed(cls, kw, raw, where):
        return kw

    def to_dict(self) -> dict:
        return {"kind": self.kind, **_dump_fields(self)}


@dataclass(frozen=True)
class Static(Segment):
    """The carrier stands still (speed must be 0 at its start)."""

    duration: float = _q("time")
    kind: ClassVar[str] = "static"


@dataclass(frozen=True)
class Accelerate(Segment):
    """Along-track acceleration ``accel`` [m/s²] (negative: decelerate).

    The acceleration rises to ``accel`` along a smooth step of ``ramp`` seconds and falls
    back at the end: the speed changes by ``accel·(duration − ramp)``.
    """

    duration: float = _q("time")
    accel: float = _q("acceleration")
    ramp: float = _qd("time", 1.0)
    kind: ClassVar[str] = "accelerate"

    def _check(self):
        self._ramp_ok("ramp")

    @property
    def speed_change(self) -> float:
        return self.accel * (self.duration - self.ramp)


@dataclass(frozen=True)
class Turn(Segment):
    """Constant-rate turn: heading rate ``rate`` [rad/s], positive = turning right.

    The rate rises and falls along smooth steps of ``ramp`` seconds, so the heading changes
    by ``rate·(duration − ramp)``. In a config, ``angle`` (the heading change) may be
    given instead of ``rate``. ``coordinated``: bank the carrier with
    ``tan φ = V·ω/g0`` (roll-in and roll-out follow the rate ramps); otherwise the turn is
    flat (ship, car).
    """

    duration: float = _q("time")
    rate: float = _q("angular_rate")
    ramp: float = _qd("time", 2.0)
    coordinated: bool = True
    kind: ClassVar[str] = "turn"

    def _check(self):
        self._ramp_ok("ramp")
        if abs(self.rate) >= math.pi:
            raise ValueError(f"key 'rate' is implausibly large ({math.degrees(self.rate):g} deg/s)")

    @classmethod
    def _extra_keys(cls):
        return {"angle": "rate"}

    @classmethod
    def _from_parsed(cls, kw, raw, where):
        if ("angle" in raw) == ("rate" in raw):
            raise ValueError(f"{where}: give exactly one of 'rate' or 'angle'")
        if "angle" in raw:
            try:
                ang = units.parse(raw["angle"], "angle")
            except ValueError as e:
                raise ValueError(f"{where}: key 'angle': {e}") from None
            ramp = kw.get("ramp", 2.0)
            if "duration" not in kw or kw["duration"] <= ramp:
                raise ValueError(f"{where}: key 'duration' must exceed 'ramp' to turn by an angle")
            kw["rate"] = ang / (kw["duration"] - ramp)
        return kw

    @property
    def angle(self) -> float:
        return self.rate * (self.duration - self.ramp)


@dataclass(frozen=True)
class Climb(Segment):
    """Change the path angle (and body pitch) to ``angle`` [rad] (negative: descend) over the
    first ``transition`` seconds (default min(5 s, duration)) along a smooth step, then
    hold it. ``kind="descend"`` in a
    config takes a positive angle downwards."""

    duration: float = _q("time")
    angle: float = _q("angle")
    transition: float | None = _qd("time", None)
    kind: ClassVar[str] = "climb"

    def _check(self):
        self._transition_ok()
        if abs(self.angle) >= math.pi / 2:
            raise ValueError("key 'angle' must be within ±90 deg")


@dataclass(frozen=True)
class Level(Segment):
    """Level flight / uniform motion: the path angle returns to 0 over ``transition``
    seconds (default min(5 s, duration); nothing changes if it is 0 already); speed and
    course are held."""

    duration: float = _q("time")
    transition: float | None = _qd("time", None)
    kind: ClassVar[str] = "level"

    def _check(self):
        self._transition_ok()


@dataclass(frozen=True)
class WingRock(Segment):
    """Sinusoidal roll ``amplitude·E(t)·sin(2π t/period)`` with a smooth envelope ``E``
    rising over ``ramp`` seconds and falling over the last ``ramp`` seconds
    (default: one period)."""

    duration: float = _q("time")
    amplitude: float = _q("angle")
    period: float = _q("time")
    ramp: float | None = _qd("time", None)
    kind: ClassVar[str] = "wing_rock"

    def _check(self):
        if not self.period > 0:
            raise ValueError(f"key 'period' must be > 0, got {self.period!r} s")
        if self.ramp is None:
            object.__setattr__(self, "ramp", min(self.period, self.duration / 2))
        self._ramp_ok("ramp")


_SHIP_CH = ("pitch", "roll", "yaw", "heave", "speed", "course")


@dataclass(frozen=True)
class Ship(Segment):
    """Ship motion: sinusoidal sway in pitch, roll and yaw (body only), heave (vertical
    displacement), speed (around the speed at the segment start) and course (track and
    heading together). Each sinusoid ``A·E(t)·sin(2π t/T)`` has a smooth envelope rising
    over ``ramp`` seconds and falling over the last ``ramp`` seconds. Amplitudes default
    to 0 (channel off)."""

    duration: float = _q("time")
    pitch_amplitude: float = _qd("angle", 0.0)
    pitch_period: float = _qd("time", 8.0)
    roll_amplitude: float = _qd("angle", 0.0)
    roll_period: float = _qd("time", 12.0)
    yaw_amplitude: float = _qd("angle", 0.0)
    yaw_period: float = _qd("time", 15.0)
    heave_amplitude: float = _qd("length", 0.0)
    heave_period: float = _qd("time", 10.0)
    speed_amplitude: float = _qd("velocity", 0.0)
    speed_period: float = _qd("time", 300.0)
    course_amplitude: float = _qd("angle", 0.0)
    course_period: float = _qd("time", 600.0)
    ramp: float = _qd("time", 10.0)
    kind: ClassVar[str] = "ship"

    def _check(self):
        for c in _SHIP_CH:
            if not getattr(self, f"{c}_period") > 0:
                raise ValueError(f"key '{c}_period' must be > 0")
        self._ramp_ok("ramp")


SEGMENT_KINDS: dict[str, type] = {c.kind: c for c in
                                  (Static, Accelerate, Turn, Climb, Level, WingRock, Ship)}
_NEGATED = {"decelerate": ("accelerate", "accel"), "descend": ("climb", "angle")}


def segment_from_dict(d: dict, index: int | None = None) -> Segment:
    """One segment from a config table; ``kind`` selects the class.

    ``kind="decelerate"`` is an :class:`Accelerate` with the sign of ``accel`` flipped,
    ``kind="descend"`` a :class:`Climb` with the sign of ``angle`` flipped.
    """
    where = f"segment {index}" if index is not None else "segment"
    if not isinstance(d, dict):
        raise ValueError(f"{where}: expected a table, got {type(d).__name__}")
    kind = d.get("kind")
    if kind in _NEGATED:
        base, key = _NEGATED[kind]
        seg = SEGMENT_KINDS[base].from_dict({**d, "kind": base}, index)
        return type(seg)(**{f.name: (-getattr(seg, f.name) if f.name == key else getattr(seg, f.name))
                            for f in fields(seg)})
    if kind not in SEGMENT_KINDS:
        raise ValueError(f"{where}: key 'kind': unknown {kind!r}; known: "
                         f"{', '.join(list(SEGMENT_KINDS) + list(_NEGATED))}")
    return SEGMENT_KINDS[kind].from_dict(d, index)


def segments_from_list(items) -> list[Segment]:
    """Segments from a list of tables or :class:`Segment` objects."""
    out = []
    for i, s in enumerate(items):
        out.append(s if isinstance(s, Segment) else segment_from_dict(s, i))
    return out


def total_duration(segments) -> float:
    """Sum of segment durations [s]."""
    return float(sum(s.duration for s in segments))


# --- TOML ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Motion:
    """What a motion file holds: segments, an optional start and an optional mount."""

    segments: list
    start: Start | None = None
    mount: object = None


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {v!r} to TOML")


def _toml_table(d):
    return "".join(f"{k} = {_toml_value(v)}\n" for k, v in d.items())


def dump_segments(segments, path, *, start: Start | None = None, mount=None) -> None:
    """Write segments (and optionally the start and the mount) to a TOML file.

    Layout: an optional ``[start]`` table, an optional ``[mount]`` table and one
    ``[[segment]]`` table per segment, all values as unit strings.
    """
    segments = segments_from_list(segments)
    parts = ["# sinslab motion: segments in order; values are unit strings\n"]
    if start is not None:
        parts.append("\n[start]\n" + _toml_table(_as_start(start).to_dict()))
    if mount is not None:
        parts.append("\n[mount]\n" + _toml_table(_as_mount(mount).to_dict()))
    for s in segments:
        parts.append("\n[[segment]]\n" + _toml_table(s.to_dict()))
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text("".join(parts), encoding="utf-8")
    tmp.replace(path)


def load_motion(path) -> Motion:
    """Read a motion TOML file (see :func:`dump_segments`)."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{path}: not valid TOML: {e}") from None
    bad = sorted(set(data) - {"segment", "start", "mount"})
    if bad:
        raise ValueError(f"{path}: unknown table {bad[0]!r}; expected [start], [mount], [[segment]]")
    segs = data.get("segment")
    if not segs:
        raise ValueError(f"{path}: no [[segment]] tables")
    if not isinstance(segs, list):
        raise ValueError(f"{path}: 'segment' must be an array of tables ([[segment]])")
    try:
        return Motion(segments_from_list(segs),
                      Start.from_dict(data["start"]) if "start" in data else None,
                      indexing.mount_from_dict(data["mount"]) if "mount" in data else None)
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None


def load_segments(path) -> list[Segment]:
    """Segments of a motion TOML file."""
    return load_motion(path).segments


# --- compilation of segments into kernel tables -------------------------------------------
NCH = 10
CH_V, CH_PSI, CH_THETA, CH_ROLL, CH_PITCH, CH_YAW, CH_HEAVE, CH_MP, CH_MR, CH_MY = range(NCH)
T_TRAP, T_STEP, T_SINE = 0, 1, 2


def _as_start(start) -> Start:
    if isinstance(start, Start):
        return start
    if isinstance(start, dict):
        return Start.from_dict(start)
    raise ValueError(f"start must be a Start or a table, got {type(start).__name__}")


def _as_mount(mount):
    if mount is None or isinstance(mount, (indexing.RotateStop, indexing.Swing)):
        return mount
    if isinstance(mount, dict):
        return indexing.mount_from_dict(mount)
    raise ValueError(f"mount must be RotateStop, Swing, a table or None, got {type(mount).__name__}")


class _Terms:
    def __init__(self):
        self.rows = []        # (type, ch, ta, params[6], final, internal breakpoints)
        self.coord = []       # coordinated-turn windows

    def trap(self, ch, ta, T, Tr, r):
        self.rows.append((T_TRAP, ch, ta, (r, T, Tr, 0, 0, 0), r * (T - Tr), (ta, ta + Tr, ta + T - Tr, ta + T)))
        return r * (T - Tr)

    def step(self, ch, ta, T, d):
        self.rows.append((T_STEP, ch, ta, (d, T, 0, 0, 0, 0), d, (ta, ta + T)))
        return d

    def sine(self, ch, ta, T, A, w, ph, r_in, r_out):
        final = 0.0 if r_out > 0 else A * math.sin(w * T + ph)
        self.rows.append((T_SINE, ch, ta, (A, w, ph, T, r_in, r_out), final,
                          (ta, ta + r_in, ta + T - r_out, ta + T)))
        return final


def _compile(segments, start: Start, mount, t_end):
    terms = _Terms()
    init = np.zeros(NCH)
    init[CH_V] = start.speed
    init[CH_PSI] = -start.heading
    init[CH_THETA] = start.pitch
    init[CH_ROLL] = start.roll
    cur = init.copy()
    t = 0.0
    for i, s in enumerate(segments):
        T = s.duration
        where = f"segment {i} ({s.kind})"
        if isinstance(s, Static):
            if abs(cur[CH_V]) > 1e-9:
                raise ValueError(f"{where}: speed at its start is {cur[CH_V]:.6g} m/s; "
                                 f"decelerate to 0 first")
        elif isinstance(s, Accelerate):
            if cur[CH_V] + s.speed_change < -1e-9:
                raise ValueError(f"{where}: key 'accel': speed would become "
                                 f"{cur[CH_V] + s.speed_change:.6g} m/s")
            cur[CH_V] += terms.trap(CH_V, t, T, s.ramp, s.accel)
        elif isinstance(s, Turn):
            cur[CH_PSI] += terms.trap(CH_PSI, t, T, s.ramp, -s.rate)
            if s.coordinated:
                terms.coord.append((t, t + T))
        elif isinstance(s, (Climb, Level)):
            target = s.angle if isinstance(s, Climb) else 0.0
            d = target - cur[CH_THETA]
            if d != 0.0 and s.transition > 0:
                cur[CH_THETA] += terms.step(CH_THETA, t, s.transition, d)
            elif d != 0.0:
                raise ValueError(f"{where}: key 'transition' must be > 0 to change the path angle")
        elif isinstance(s, WingRock):
            cur[CH_ROLL] += terms.sine(CH_ROLL, t, T, s.amplitude, 2 * math.pi / s.period, 0.0,
                                       s.ramp, s.ramp)
        elif isinstance(s, Ship):
            if s.speed_amplitude > cur[CH_V] + 1e-9:
                raise ValueError(f"{where}: key 'speed_amplitude' ({s.speed_amplitude:g} m/s) exceeds "
                                 f"the speed at its start ({cur[CH_V]:.6g} m/s)")
            for name, ch in (("pitch", CH_PITCH), ("roll", CH_ROLL), ("yaw", CH_YAW),
                             ("heave", CH_HEAVE), ("speed", CH_V), ("course", CH_PSI)):
                a = getattr(s, f"{name}_amplitude")
                if a != 0.0:
                    if name == "course":
                        a = -a                      # course is clockwise, ψ_v counter-clockwise
                    cur[ch] += terms.sine(ch, t, T, a, 2 * math.pi / getattr(s, f"{name}_period"),
                                          0.0, s.ramp, s.ramp)
        else:
            raise ValueError(f"{where}: not a segment object ({type(s).__name__})")
        t += T
    # mount
    if mount is not None:
        init[CH_MP:CH_MY + 1] = mount.initial
        if isinstance(mount, indexing.Swing):
            terms.sine(CH_MP + indexing.AXES[mount.axis], 0.0, t_end + 10.0, mount.amplitude,
                       2 * math.pi / mount.period, mount.phase, mount.ramp, 0.0)
        else:
            for ts, d, ax, ang in mount.timeline(t_end):
                terms.trap(CH_MP + ax, ts, d, mount.ramp, math.copysign(mount.rate, ang))
    return _tables(terms, init, t_end)


def _tables(terms: _Terms, init, t_end):
    rows = terms.rows
    bp = [0.0]
    for r in rows:
        bp.extend(r[5])
    for a, b in terms.coord:
        bp.extend((a, b))
    bp = np.unique(np.asarray(bp, dtype=float))
    bp = bp[bp >= 0.0]
    keep = np.concatenate([[True], np.diff(bp) > 1e-9])      # merge near-duplicates
    bp = bp[keep]
    P = bp.size
    mids = np.empty(P)
    mids[:-1] = 0.5 * (bp[:-1] + bp[1:])
    mids[-1] = bp[-1] + 1.0
    nt = len(rows)
    ttype = np.array([r[0] for r in rows], dtype=np.int64).reshape(nt)
    tch = np.array([r[1] for r in rows], dtype=np.int64).reshape(nt)
    tta = np.array([r[2] for r in rows], dtype=float).reshape(nt)
    tpar = np.array([r[3] for r in rows], dtype=float).reshape(nt, 6)
    tfin = np.array([r[4] for r in rows], dtype=float).reshape(nt)
    tend = np.array([r[5][-1] for r in rows], dtype=float).reshape(nt)
    # base of each piece: initial values + finals of terms ended before the piece
    base = np.tile(init, (P, 1))
    order = np.argsort(tend, kind="stable")
    cum = np.zeros((nt + 1, NCH))
    for k, ti in enumerate(order):
        cum[k + 1] = cum[k]
        cum[k + 1, tch[ti]] += tfin[ti]
    nend = np.searchsorted(tend[order], mids, side="right")
    base += cum[nend]
    # active terms per piece: ta <= mid < tend
    lo = np.searchsorted(mids, tta, side="left")
    hi = np.searchsorted(mids, tend, side="left")
    counts = np.zeros(P + 1, dtype=np.int64)
    np.add.at(counts, lo, 1)
    np.add.at(counts, hi, -1)
    nact = np.cumsum(counts)[:P]
    plo = np.concatenate([[0], np.cumsum(nact)[:-1]]).astype(np.int64)
    phi = plo + nact
    act = np.empty(int(nact.sum()), dtype=np.int64)
    fill = plo.copy()
    for k in range(nt):
        for p in range(lo[k], hi[k]):
            act[fill[p]] = k
            fill[p] += 1
    flag = np.zeros(P, dtype=np.int64)
    for a, b in terms.coord:
        flag[(mids >= a) & (mids < b)] = 1
    return bp, base, flag, plo, phi, act, ttype, tch, tta, tpar


# --- quadrature rules ----------------------------------------------------------------------
def _rule(quadrature: str, n: int):
    """Nodes c, weights b on [0, 1] and the collocation matrix A_ij = ∫_0^{c_i} ℓ_j."""
    P = np.polynomial.legendre
    if quadrature == "gauss":
        if not 1 <= n <= 8:
            raise ValueError(f"gauss quadrature needs 1..8 nodes, got {n}")
        x, w = P.leggauss(n)
    elif quadrature == "lobatto":
        if not 2 <= n <= 8:
            raise ValueError(f"lobatto quadrature needs 2..8 nodes, got {n}")
        Pn1 = P.Legendre.basis(n - 1)
        x = np.concatenate([[-1.0], np.sort(Pn1.deriv().roots().real), [1.0]])
        w = 2.0 / (n * (n - 1) * Pn1(x) ** 2)
    else:
        raise ValueError(f"quadrature must be 'lobatto' or 'gauss', got {quadrature!r}")
    c, b = (x + 1) / 2, w / 2
    A = np.empty((n, n))
    for j in range(n):
        others = np.delete(c, j)
        poly = (np.polynomial.Polynomial.fromroots(others) / np.prod(c[j] - others)
                if others.size else np.polynomial.Polynomial([1.0]))
        ip = poly.integ()
        A[:, j] = ip(c) - ip(0.0)
    return c, b, A


# --- numba kernel --------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _s5(x):
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))


@njit(cache=True, inline="always")
def _s5d(x):
    y = x * (1.0 - x)
    return 30.0 * y * y


@njit(cache=True, inline="always")
def _s5dd(x):
    return 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x)


@njit(cache=True, inline="always")
def _s5i(x):
    x2 = x * x
    return x2 * x2 * (2.5 + x * (-3.0 + x))


_INV2PI = 1.0 / (2.0 * math.pi)


@njit(cache=True, inline="always")
def _wrap(a):
    """Wrap to (−π, π]. (Multiplying by 1/2π instead of dividing: the same result except
    where the quotient is within an ulp of an integer, fixed by the last test.)"""
    if -math.pi < a <= math.pi:
        return a
    b = a + 2.0 * math.pi * math.floor((math.pi - a) * _INV2PI)
    if b <= -math.pi:
        b += 2.0 * math.pi
    return b


@njit(cache=True, inline="always")
def _term(typ, u, p0, p1, p2, p3, p4, p5):
    """(value, rate, acceleration) of one channel term at u = t − t_a (scalars only, so that
    inlining it into the per-sample loop adds no array reference counting)."""
    if typ == 0:                           # rate trapezoid: r, T, Tr
        r = p0
        T = p1
        Tr = p2
        if Tr > 0.0 and u < Tr:
            x = u / Tr
            return r * Tr * _s5i(x), r * _s5(x), r * _s5d(x) / Tr
        if Tr > 0.0 and u > T - Tr:
            x = (T - u) / Tr
            if x < 0.0:
                x = 0.0
            return r * (T - Tr - Tr * _s5i(x)), r * _s5(x), -(r * _s5d(x) / Tr)
        return r * (0.5 * Tr + (u - Tr)), r, 0.0
    if typ == 1:                           # smooth step: d, T
        dd = p0
        T = p1
        x = u / T
        if x > 1.0:
            x = 1.0
        elif x < 0.0:
            x = 0.0
        return dd * _s5(x), dd * _s5d(x) / T, dd * _s5dd(x) / (T * T)
    arg = p1 * u + p2
    return _sine_term(u, p0, p1, p3, p4, p5, math.sin(arg), math.cos(arg))


@njit(cache=True, inline="always")
def _sine_term(u, A, w, T, ri, ro, s, c):
    """(value, rate, acceleration) of a sine term A·e(u)·sin(w·u + phase) with ramps ri, ro
    over its duration T, given s, c = sin, cos of its argument."""
    e = 1.0
    ed = 0.0
    edd = 0.0
    if ri > 0.0 and u < ri:
        x = u / ri
        e = _s5(x)
        ed = _s5d(x) / ri
        edd = _s5dd(x) / (ri * ri)
    elif ro > 0.0 and u > T - ro:
        x = (T - u) / ro
        if x < 0.0:
            x = 0.0
        e = _s5(x)
        ed = -_s5d(x) / ro
        edd = _s5dd(x) / (ro * ro)
    return A * e * s, A * (ed * s + e * w * c), A * (edd * s + 2.0 * ed * w * c - e * w * w * s)


@njit(cache=True)
def _channels(t, j, base, plo, phi, act, ttype, tch, tta, tpar, val, d1, d2):
    """Values and first two derivatives of all channels at time t (piece j)."""
    for c in range(NCH):
        val[c] = base[j, c]
        d1[c] = 0.0
        d2[c] = 0.0
    for a in range(plo[j], phi[j]):
        k = act[a]
        x0, x1, x2 = _term(ttype[k], t - tta[k], tpar[k, 0], tpar[k, 1], tpar[k, 2], tpar[k, 3],
                           tpar[k, 4], tpar[k, 5])
        ch = tch[k]
        val[ch] += x0
        d1[ch] += x1
        d2[ch] += x2


@njit(cache=True, inline="always")
def _kin(V, Vd, thd, sthv, cthv, spsv, cpsv, psd, hd1, hd2,
         pitch, pitchd, sth, cth, yaw, yawd, sps, cps, roll, rolld, sg, cg,
         has_mount, mp, mr, my, mpd, mrd, myd):
    """Kinematic state from the channels, sines and cosines given (track path angle and yaw:
    sthv..cpsv; body pitch, yaw, roll: sth..cg): the 24-tuple v(3) vdot(3) C_b^n(9)
    w_nb^b(3) att_c(3) mount(3)."""
    s0 = -V * cthv * spsv
    s1 = V * cthv * cpsv
    s2 = V * sthv + hd1
    s3 = -Vd * cthv * spsv + V * sthv * thd * spsv - V * cthv * cpsv * psd
    s4 = Vd * cthv * cpsv - V * sthv * thd * cpsv - V * cthv * spsv * psd
    s5 = Vd * sthv + V * cthv * thd + hd2
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = euler_dcm_sc(sth, cth, sg, cg, sps, cps)
    wx, wy, wz = euler_rates_to_body_sc(sth, cth, sg, cg, pitchd, rolld, yawd)
    if not has_mount:
        return (s0, s1, s2, s3, s4, s5, c00, c01, c02, c10, c11, c12, c20, c21, c22,
                wx, wy, wz, pitch, roll, yaw, 0.0, 0.0, 0.0)
    st = math.sin(mp)
    ct = math.cos(mp)
    sy = math.sin(my)
    cy = math.cos(my)
    sr = math.sin(mr)
    cr = math.cos(mr)
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = euler_dcm_sc(st, ct, sr, cr, sy, cy)  # C_b^c
    # w_nb^b = M^T w_nc^c + w_cb^b
    ux, uy, uz = euler_rates_to_body_sc(st, ct, sr, cr, mpd, mrd, myd)
    # C_b^n = C_c^n M
    return (s0, s1, s2, s3, s4, s5,
            c00 * m00 + c01 * m10 + c02 * m20, c00 * m01 + c01 * m11 + c02 * m21,
            c00 * m02 + c01 * m12 + c02 * m22, c10 * m00 + c11 * m10 + c12 * m20,
            c10 * m01 + c11 * m11 + c12 * m21, c10 * m02 + c11 * m12 + c12 * m22,
            c20 * m00 + c21 * m10 + c22 * m20, c20 * m01 + c21 * m11 + c22 * m21,
            c20 * m02 + c21 * m12 + c22 * m22,
            m00 * wx + m10 * wy + m20 * wz + ux, m01 * wx + m11 * wy + m21 * wz + uy,
            m02 * wx + m12 * wy + m22 * wz + uz,
            pitch, roll, yaw, mp, mr, my)


@njit(cache=True)
def _state(t, j, has_mount, flag, base, plo, phi, act, ttype, tch, tta, tpar, val, d1, d2, S, i):
    """Kinematic state at time t into S[i]: v(3) vdot(3) C_b^n(9) w_nb^b(3) att_c(3) mount(3).
    (The fallback path's evaluation at arbitrary node times; _kinematics does the same for
    whole blocks of epochs, with cached sines and cosines and without the array-argument
    call per epoch.)"""
    _channels(t, j, base, plo, phi, act, ttype, tch, tta, tpar, val, d1, d2)
    V = val[CH_V]
    Vd = d1[CH_V]
    psv = val[CH_PSI]
    psd = d1[CH_PSI]
    thv = val[CH_THETA]
    thd = d1[CH_THETA]
    roll = val[CH_ROLL]
    rolld = d1[CH_ROLL]
    if flag[j] != 0:
        u = -V * psd / G0
        roll += math.atan(u)
        rolld += -(Vd * psd + V * d2[CH_PSI]) / G0 / (1.0 + u * u)
    pitch = thv + val[CH_PITCH]
    yaw = psv + val[CH_YAW]
    out = _kin(V, Vd, thd, math.sin(thv), math.cos(thv), math.sin(psv), math.cos(psv), psd,
               d1[CH_HEAVE], d2[CH_HEAVE], pitch, thd + d1[CH_PITCH], math.sin(pitch),
               math.cos(pitch), yaw, psd + d1[CH_YAW], math.sin(yaw), math.cos(yaw),
               roll, rolld, math.sin(roll), math.cos(roll), has_mount,
               val[CH_MP], val[CH_MR], val[CH_MY], d1[CH_MP], d1[CH_MR], d1[CH_MY])
    for q in range(24):
        S[i, q] = out[q]


@njit(cache=True, inline="always")
def _earth(sl, cl, h, ve, vn, vu, a0, a1, a2, c00, c01, c02, c10, c11, c12, c20, c21, c22,
           w0, w1, w2):
    """ω_ib^b, f^b and the position rates (L̇, λ̇, ḣ) at latitude (sin, cos) and height h, from
    v^n, v̇^n (a), C_b^n and ω_nb^b (w). Radii and gravity: the formulas of earth.radii_s /
    earth.gravity_s, with the four reciprocals (1/√(1−e²sin²L), 1/R_M, 1/R_N, 1/cos L) taken
    from one division (a few ulps)."""
    s = math.sqrt(1.0 - earth.E2 * sl * sl)
    s3 = s * s * s
    P = earth.A * (1.0 - earth.E2) + h * s3          # R_M = P / s³
    Q = earth.A + h * s                              # R_N = Q / s
    sP = s * P
    Qc = Q * cl
    inv = 1.0 / (sP * Qc)
    rsq = inv * P * Qc
    irm = inv * s * Qc * s3
    irn = inv * sP * cl * s
    icl = inv * sP * Q
    g = earth.G_EQ * (1.0 + earth.K_SOM * sl * sl) * rsq - earth.DGDH * h
    wiy = earth.WIE * cl
    wiz = earth.WIE * sl
    ex = -vn * irm
    ey = ve * irn
    ez = ey * sl * icl
    # w_in^n
    nx = ex
    ny = wiy + ey
    nz = wiz + ez
    # f^n = vdot + (2 w_ie + w_en) x v + [0, 0, g]
    ay = 2.0 * wiy + ey
    az = 2.0 * wiz + ez
    fx = a0 + ay * vu - az * vn
    fy = a1 + az * ve - ex * vu
    fz = a2 + ex * vn - ay * ve + g
    return (w0 + c00 * nx + c10 * ny + c20 * nz,
            w1 + c01 * nx + c11 * ny + c21 * nz,
            w2 + c02 * nx + c12 * ny + c22 * nz,
            c00 * fx + c10 * fy + c20 * fz,
            c01 * fx + c11 * fy + c21 * fz,
            c02 * fx + c12 * fy + c22 * fz,
            vn * irm, ey * icl, vu)


@njit(cache=True)
def _earth_call(S, i, sl, cl, h, W, F):
    """Earth terms of S[i] into W[i] (ω_ib^b, f^b) and F[i] (position rates)."""
    out = _earth(sl, cl, h, S[i, 0], S[i, 1], S[i, 2], S[i, 3], S[i, 4], S[i, 5], S[i, 6],
                 S[i, 7], S[i, 8], S[i, 9], S[i, 10], S[i, 11], S[i, 12], S[i, 13], S[i, 14],
                 S[i, 15], S[i, 16], S[i, 17])
    for q in range(6):
        W[i, q] = out[q]
    for q in range(3):
        F[i, q] = out[6 + q]


@njit(cache=True)
def _advance(t, j, bp):
    n = bp.shape[0]
    while j + 1 < n and t >= bp[j + 1]:
        j += 1
    return j


@njit(cache=True, inline="always")
def _asin1(x):
    if x > 1.0:
        x = 1.0
    elif x < -1.0:
        x = -1.0
    return math.asin(x)


_BLOCK = 64        # intervals per block: the vectorised passes run over ~70 epochs at a time
_NB = _BLOCK + 8   # buffer columns: a block and its stencil halo (at most 7 epochs)
_NROW = 35         # buffer rows: kinematics 0..23, Earth terms 24..32, predicted offsets 33, 34
_R = tuple(np.uint64(r * _NB) for r in range(_NROW))     # row offsets in the flat buffer


_ROT_MAX = 0.02      # largest angle step [rad] taken by rotation instead of sin/cos
_ROT_RUN = 64        # rotations before an exact sin/cos again (rounding grows ~1 ulp each)


@njit(cache=True, inline="always")
def _sincos_step(x, a, s, c, n):
    """(x, sin x, cos x, n') from the previous (a, sin a, cos a) and the number n of
    rotations since they were exact: the same values if x == a; for a small step
    d = x − a, (s, c) rotated by d (sin d, cos d by their series, exact to < 1e-18); else,
    or after _ROT_RUN rotations, sin and cos afresh. The epochs' angles change by
    ~1e-4..1e-2 rad per sample, and a rotation costs a third of a sin/cos pair."""
    if x == a:
        return a, s, c, n
    d = x - a
    if n < _ROT_RUN and -_ROT_MAX < d < _ROT_MAX:
        d2 = d * d
        sd = d * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0))))
        cd = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)))
        return x, s * cd + c * sd, c * cd - s * sd, n + 1
    return x, math.sin(x), math.cos(x), 0


@njit(cache=True)
def _kinematics(e0, e1, i0, dt, has_mount, bp, base, flag, plo, phi, act, ttype, tch, tta,
                tpar, K, cache, tc, je):
    """Kinematic state of epochs e0..e1−1 (t_e = e·dt) into columns i0, i0+1, ... of
    K (24, NB): v(3) v̇(3) C_b^n(9) ω_nb^b(3) carrier att(3) mount(3). Returns the piece of
    the last epoch (``je`` is that of the epoch before e0).

    Scalar code. Sines and cosines of the Euler angles and of the sine terms' arguments
    follow their angles by small rotations (:func:`_sincos_step`; exact sin/cos at least
    every _ROT_RUN epochs, so they stay within ~1e-15 of it), and are reused, like the bank
    angle's arctangent, while the argument is unchanged; the caches live in ``cache`` and
    ``tc`` (per term) between calls. An epoch in a piece with no active term copies the
    previous column.
    """
    val = np.empty(NCH)
    d1 = np.empty(NCH)
    d2 = np.empty(NCH)
    nbp = bp.shape[0]
    a_th = cache[0]
    s_th = cache[1]
    c_th = cache[2]
    a_ps = cache[3]
    s_ps = cache[4]
    c_ps = cache[5]
    a_p = cache[6]
    s_p = cache[7]
    c_p = cache[8]
    a_y = cache[9]
    s_y = cache[10]
    c_y = cache[11]
    a_r = cache[12]
    s_r = cache[13]
    c_r = cache[14]
    a_u = cache[15]
    t_u = cache[16]
    n_th = int(cache[17])
    n_ps = int(cache[18])
    n_p = int(cache[19])
    n_y = int(cache[20])
    n_r = int(cache[21])
    for e in range(e0, e1):
        i = i0 + e - e0
        te = e * dt
        jprev = je
        while je + 1 < nbp and te >= bp[je + 1]:
            je += 1
        if e > 0 and je == jprev and plo[je] == phi[je] and flag[je] == 0:
            for q in range(24):
                K[q, i] = K[q, i - 1]
            continue
        for c in range(NCH):
            val[c] = base[je, c]
            d1[c] = 0.0
            d2[c] = 0.0
        for a in range(plo[je], phi[je]):
            kk = act[a]
            u = te - tta[kk]
            if ttype[kk] == T_SINE:
                ag, sg, cg, ng = _sincos_step(tpar[kk, 1] * u + tpar[kk, 2], tc[kk, 0],
                                              tc[kk, 1], tc[kk, 2], int(tc[kk, 3]))
                tc[kk, 0] = ag
                tc[kk, 1] = sg
                tc[kk, 2] = cg
                tc[kk, 3] = ng
                x0, x1, x2 = _sine_term(u, tpar[kk, 0], tpar[kk, 1], tpar[kk, 3], tpar[kk, 4],
                                        tpar[kk, 5], sg, cg)
            else:
                x0, x1, x2 = _term(ttype[kk], u, tpar[kk, 0], tpar[kk, 1], tpar[kk, 2],
                                   tpar[kk, 3], tpar[kk, 4], tpar[kk, 5])
            ch = tch[kk]
            val[ch] += x0
            d1[ch] += x1
            d2[ch] += x2
        V = val[CH_V]
        Vd = d1[CH_V]
        psv = val[CH_PSI]
        psd = d1[CH_PSI]
        thv = val[CH_THETA]
        thd = d1[CH_THETA]
        roll = val[CH_ROLL]
        rolld = d1[CH_ROLL]
        if flag[je] != 0:
            u = -V * psd / G0
            if u != a_u:
                a_u = u
                t_u = math.atan(u)
            roll += t_u
            rolld += -(Vd * psd + V * d2[CH_PSI]) / G0 / (1.0 + u * u)
        a_th, s_th, c_th, n_th = _sincos_step(thv, a_th, s_th, c_th, n_th)
        a_ps, s_ps, c_ps, n_ps = _sincos_step(psv, a_ps, s_ps, c_ps, n_ps)
        pitch = thv + val[CH_PITCH]
        if pitch == thv:                    # no sway: the body pitch is the path angle
            a_p, s_p, c_p, n_p = a_th, s_th, c_th, n_th
        else:
            a_p, s_p, c_p, n_p = _sincos_step(pitch, a_p, s_p, c_p, n_p)
        yaw = psv + val[CH_YAW]
        if yaw == psv:
            a_y, s_y, c_y, n_y = a_ps, s_ps, c_ps, n_ps
        else:
            a_y, s_y, c_y, n_y = _sincos_step(yaw, a_y, s_y, c_y, n_y)
        a_r, s_r, c_r, n_r = _sincos_step(roll, a_r, s_r, c_r, n_r)
        out = _kin(V, Vd, thd, s_th, c_th, s_ps, c_ps, psd, d1[CH_HEAVE], d2[CH_HEAVE],
                   pitch, thd + d1[CH_PITCH], s_p, c_p, yaw, psd + d1[CH_YAW], s_y, c_y,
                   roll, rolld, s_r, c_r, has_mount,
                   val[CH_MP], val[CH_MR], val[CH_MY], d1[CH_MP], d1[CH_MR], d1[CH_MY])
        # one store per element: a loop over the tuple would index it at run time (through
        # a stack copy), a third of this function's time
        K[0, i] = out[0]
        K[1, i] = out[1]
        K[2, i] = out[2]
        K[3, i] = out[3]
        K[4, i] = out[4]
        K[5, i] = out[5]
        K[6, i] = out[6]
        K[7, i] = out[7]
        K[8, i] = out[8]
        K[9, i] = out[9]
        K[10, i] = out[10]
        K[11, i] = out[11]
        K[12, i] = out[12]
        K[13, i] = out[13]
        K[14, i] = out[14]
        K[15, i] = out[15]
        K[16, i] = out[16]
        K[17, i] = out[17]
        K[18, i] = out[18]
        K[19, i] = out[19]
        K[20, i] = out[20]
        K[21, i] = out[21]
        K[22, i] = out[22]
        K[23, i] = out[23]
    cache[0] = a_th
    cache[1] = s_th
    cache[2] = c_th
    cache[3] = a_ps
    cache[4] = s_ps
    cache[5] = c_ps
    cache[6] = a_p
    cache[7] = s_p
    cache[8] = c_p
    cache[9] = a_y
    cache[10] = s_y
    cache[11] = c_y
    cache[12] = a_r
    cache[13] = s_r
    cache[14] = c_r
    cache[15] = a_u
    cache[16] = t_u
    cache[17] = n_th
    cache[18] = n_ps
    cache[19] = n_p
    cache[20] = n_y
    cache[21] = n_r
    return je


@njit(cache=True, error_model="numpy")
def _earth_block(i0, i1, ib, dt, lat, h, Z):
    """Earth terms of columns i0..i1−1 of the kinematics rows of Z into its rows 24..32:
    ω_ib^b, f^b and the position rates (L̇, λ̇, ḣ), at positions predicted from the exact
    position (lat, h) of column ib ≤ i0. ``Z`` is the flat (row-major) view of the block
    buffer of _synth: _NROW rows of _NB columns.

    The prediction integrates the velocities by trapezoids with the Euler–Maclaurin end
    correction (error O(dt⁴)) and turns the north distance into latitude with R_M + h to
    first order in the height and latitude changes. Over one block (~0.7 s at 100 Hz,
    ~7 s at 10 Hz) that is good to well below a micrometre; without the latitude term of
    R_M the ~0.1 mm error of a 50 Hz block showed as 3e-14 m/s in Δv (test_trajectory). The first loop is a running sum; the second has no branch
    and no call, and is vectorised (SIMD) — which is why the synthesis works in blocks. It
    indexes one flat array with unsigned indices and compile-time row offsets: signed
    indices make numba emit a negative-index wraparound, and separate row arrays need more
    run-time alias checks than LLVM allows; either way it would stay scalar.
    """
    sb = math.sin(lat)
    cb = math.cos(lat)
    q = 1.0 - earth.E2 * sb * sb
    rm = earth.A * (1.0 - earth.E2) / q ** 1.5
    irm = 1.0 / (rm + h)
    # d ln(1/(R_M + h))/dL = −kk: the north distance spans a latitude range over the block
    kk = rm * irm * 3.0 * earth.E2 * sb * cb / q
    c6 = dt / 6.0
    dl = 0.0
    dh = 0.0
    one = np.uint64(1)
    ub = np.uint64(ib)
    for j in range(i1 - ib):
        i = ub + np.uint64(j)
        if j > 0:
            dl += Z[_R[1] + i - one] + Z[_R[1] + i]
            dh += Z[_R[2] + i - one] + Z[_R[2] + i]
        Z[_R[33] + i] = dl - c6 * (Z[_R[4] + i] - Z[_R[4] + ub])
        Z[_R[34] + i] = dh - c6 * (Z[_R[5] + i] - Z[_R[5] + ub])
    hdt = 0.5 * dt
    u0 = np.uint64(i0)
    for j in range(i1 - i0):
        i = u0 + np.uint64(j)
        dhp = hdt * Z[_R[34] + i]
        # L − L_b = ∫ v_N/(R_M + h) dt, to first order in Δh and in (L − L_b) of R_M:
        # 1/(R_M + h_b + Δh/2) and ∫ (1 − kk·δL) dδL = d0 − kk·d0²/2
        d0 = hdt * Z[_R[33] + i] * irm * (1.0 - 0.5 * dhp * irm)
        d = d0 * (1.0 - 0.5 * kk * d0)
        d2 = 0.5 * d * d
        d3 = d * (1.0 - d2 * (1.0 / 3.0))
        w = _earth(sb * (1.0 - d2) + cb * d3, cb * (1.0 - d2) - sb * d3, h + dhp,
                   Z[i], Z[_R[1] + i], Z[_R[2] + i], Z[_R[3] + i], Z[_R[4] + i],
                   Z[_R[5] + i], Z[_R[6] + i], Z[_R[7] + i], Z[_R[8] + i], Z[_R[9] + i],
                   Z[_R[10] + i], Z[_R[11] + i], Z[_R[12] + i], Z[_R[13] + i],
                   Z[_R[14] + i], Z[_R[15] + i], Z[_R[16] + i], Z[_R[17] + i])
        Z[_R[24] + i] = w[0]
        Z[_R[25] + i] = w[1]
        Z[_R[26] + i] = w[2]
        Z[_R[27] + i] = w[3]
        Z[_R[28] + i] = w[4]
        Z[_R[29] + i] = w[5]
        Z[_R[30] + i] = w[6]
        Z[_R[31] + i] = w[7]
        Z[_R[32] + i] = w[8]


@njit(cache=True)
def _stencil_block(nk, off, swd, W, S):
    """S[q, k] = Σ_j swd_j·W[q, off + k + j], q = 0..8, k < nk: the stencil integrals of
    ω_ib^b, f^b and the position rates over nk consecutive intervals (symmetric weights
    swd = dt·sw[:m/2], paired; vectorised over k)."""
    mh = swd.shape[0]
    m = 2 * mh
    for q in range(9):
        Sq = S[q]                      # row views: see _earth_block
        Wq = W[q]
        for k in range(nk):
            Sq[k] = 0.0
        for jj in range(mh):
            wq = swd[jj]
            Wa = Wq[off + jj:]
            Wb = Wq[off + m - 1 - jj:]
            for k in range(nk):
                Sq[k] += wq * (Wa[k] + Wb[k])


@njit(cache=True)
def _synth(n, dt, out_every, sw, lo_off, cn, wn, amat, has_mount,
           bp, base, flag, plo, phi, act, ttype, tch, tta, tpar,
           lat, lon, h, t0, dth, dvl, t_imu, olat, olon, oh, t_nav, vel, att, atti, mnt):
    """Increments, position and truth for n IMU intervals of length dt.

    Every epoch t_e = e·dt is evaluated once. With a stencil (``sw`` of length m > 0,
    symmetric, first point at offset ``lo_off``), the increment over [t_k, t_k+1] is
    dt·Σ sw_j·W(t_{k+lo_off+j}) — the exact integral of the interpolating polynomial through
    m epochs — whenever no breakpoint of the profiles lies strictly inside the stencil;
    otherwise (and always when m = 0) the interval is split at the breakpoints and
    integrated with the node rule (cn, wn) and collocation matrix amat.

    The intervals go in blocks of ``_BLOCK``: kinematics of the block's epochs (scalar),
    their Earth terms at predicted positions and the stencil sums (both vectorised), then
    a sequential pass that adds the position increments — or, near breakpoints, does the
    exact node rule from the exact position — and writes the outputs. Columns of the
    buffers K, W hold epochs K0+lo .. K0+B−1+hi of the block starting at interval K0.
    """
    m = sw.shape[0]
    lo = lo_off if (m > 0 and lo_off < 0) else 0
    hi = lo_off + m - 1 if m > 0 else 1
    if hi < 1:
        hi = 1
    B = _BLOCK
    Z = np.zeros((_NROW, _NB))
    Zf = Z.reshape(_NROW * _NB)
    K = Z[:24]
    W = Z[24:33]
    S = np.zeros((9, B))
    cache = np.full(22, math.nan)
    cache[17:] = 0.0
    tc = np.zeros((ttype.shape[0], 4))     # per term: argument, sin, cos, rotations
    tc[:, 0] = math.nan
    ns = cn.shape[0]
    SN = np.zeros((ns, 24))
    WN = np.zeros((ns, 6))
    FN = np.zeros((ns, 3))
    val = np.zeros(NCH)
    d1 = np.zeros(NCH)
    d2 = np.zeros(NCH)
    mh = m // 2
    swd = np.empty(mh)
    for jj in range(mh):
        swd[jj] = sw[jj] * dt
    nbp = bp.shape[0]
    tol = 1e-9 * dt
    je = 0          # piece of the newest evaluated epoch
    jn = 0          # piece of the newest fallback node
    bi = 1          # first breakpoint after the current fallback sub-interval start
    bq = 1          # first breakpoint after the stencil start
    chk = 0.0
    tstep = dt * out_every
    oc = 0          # samples since the last truth epoch
    mo = 0          # index of the last truth epoch
    ib = -lo        # column of the block's first epoch K0
    for K0 in range(0, n, B):
        nk = min(B, n - K0)
        if K0 == 0:
            je = _kinematics(0, nk + hi, ib, dt, has_mount, bp, base, flag, plo, phi, act,
                             ttype, tch, tta, tpar, K, cache, tc, je)
            enew = ib
        else:
            for q in range(24):             # halo: the epochs K0+lo .. K0+hi−1 shift left
                for c in range(hi - lo):
                    K[q, c] = K[q, B + c]
            for q in range(9):
                for c in range(hi - lo):
                    W[q, c] = W[q, B + c]
            je = _kinematics(K0 + hi, K0 + nk + hi, hi - lo, dt, has_mount, bp, base, flag,
                             plo, phi, act, ttype, tch, tta, tpar, K, cache, tc, je)
            enew = hi - lo
        if m > 0:
            _earth_block(enew, ib + nk + hi, ib, dt, lat, h, Zf)
            _stencil_block(nk, lo_off - lo, swd, W, S)
        if K0 == 0:
            t_nav[0] = t0
            olat[0] = lat
            olon[0] = lon
            oh[0] = h
            vel[0, 0] = K[0, ib]
            vel[0, 1] = K[1, ib]
            vel[0, 2] = K[2, ib]
            att[0, 0] = K[18, ib]
            att[0, 1] = _wrap(K[19, ib])
            att[0, 2] = _wrap(K[20, ib])
            if has_mount:
                atti[0, 0] = _asin1(K[13, ib])
                atti[0, 1] = math.atan2(-K[12, ib], K[14, ib])
                atti[0, 2] = math.atan2(-K[7, ib], K[10, ib])
                mnt[0, 0] = K[21, ib]
                mnt[0, 1] = _wrap(K[22, ib])
                mnt[0, 2] = _wrap(K[23, ib])
        for ik in range(nk):
            k = K0 + ik
            c1 = ib + ik + 1                # column of epoch k + 1
            use_stencil = False
            if m > 0:
                t_lo = (k + lo_off) * dt
                t_hi = (k + lo_off + m - 1) * dt
                while bq < nbp and bp[bq] <= t_lo + tol:
                    bq += 1
                # t = 0 is always a breakpoint, so stencils reaching before the start fall back
                use_stencil = k + lo_off >= 0 and not (bq < nbp and bp[bq] < t_hi - tol)
            if use_stencil:
                th0 = S[0, ik]
                th1 = S[1, ik]
                th2 = S[2, ik]
                v0 = S[3, ik]
                v1 = S[4, ik]
                v2 = S[5, ik]
                lat += S[6, ik]
                lon += S[7, ik]
                h += S[8, ik]
            else:
                th0 = 0.0
                th1 = 0.0
                th2 = 0.0
                v0 = 0.0
                v1 = 0.0
                v2 = 0.0
                a = k * dt
                b = (k + 1) * dt
                s0 = a
                while True:
                    while bi < nbp and bp[bi] <= s0 + tol:
                        bi += 1
                    s1 = b
                    hh = b - s0
                    if s0 == a:
                        hh = dt                     # b - a is off by an ulp of t
                    if bi < nbp and bp[bi] < b - tol:
                        s1 = bp[bi]
                        hh = s1 - s0
                    for i in range(ns):
                        tt = s0 + cn[i] * hh
                        jn = _advance(tt, jn, bp)
                        _state(tt, jn, has_mount, flag, base, plo, phi, act, ttype, tch, tta,
                               tpar, val, d1, d2, SN, i)
                    sl0 = math.sin(lat)
                    cl0 = math.cos(lat)
                    rsq = 1.0 / math.sqrt(1.0 - earth.E2 * sl0 * sl0)
                    irm = 1.0 / (earth.A * (1.0 - earth.E2) * rsq * rsq * rsq + h)
                    for i in range(ns):
                        pl = 0.0
                        ph = 0.0
                        for q in range(ns):
                            aa = amat[i, q]
                            pl += aa * SN[q, 1]
                            ph += aa * SN[q, 2]
                        d = hh * pl * irm           # latitude offset of the node
                        d2h = 0.5 * d * d
                        _earth_call(SN, i, sl0 * (1.0 - d2h) + cl0 * d,
                                    cl0 * (1.0 - d2h) - sl0 * d, h + hh * ph, WN, FN)
                    dl = 0.0
                    do = 0.0
                    dh = 0.0
                    for i in range(ns):
                        wq = wn[i] * hh
                        dl += wq * FN[i, 0]
                        do += wq * FN[i, 1]
                        dh += wq * FN[i, 2]
                        th0 += wq * WN[i, 0]
                        th1 += wq * WN[i, 1]
                        th2 += wq * WN[i, 2]
                        v0 += wq * WN[i, 3]
                        v1 += wq * WN[i, 4]
                        v2 += wq * WN[i, 5]
                    lat += dl
                    lon += do
                    h += dh
                    if s1 >= b - tol:
                        break
                    s0 = s1
            dth[k, 0] = th0
            dth[k, 1] = th1
            dth[k, 2] = th2
            dvl[k, 0] = v0
            dvl[k, 1] = v1
            dvl[k, 2] = v2
            if out_every != 1:                  # else t_imu is t_nav[1:], written below
                t_imu[k] = (k + 1) * dt + t0
            chk += th0 + th1 + th2 + v0 + v1 + v2     # NaN/inf stay: one check at the end
            oc += 1
            if oc == out_every:             # (k + 1) % out_every == 0 without a division
                oc = 0
                mo += 1
                t_nav[mo] = mo * tstep + t0
                olat[mo] = lat
                olon[mo] = lon
                oh[mo] = h
                vel[mo, 0] = K[0, c1]
                vel[mo, 1] = K[1, c1]
                vel[mo, 2] = K[2, c1]
                att[mo, 0] = K[18, c1]
                att[mo, 1] = _wrap(K[19, c1])
                att[mo, 2] = _wrap(K[20, c1])
                if has_mount:
                    atti[mo, 0] = _asin1(K[13, c1])
                    atti[mo, 1] = math.atan2(-K[12, c1], K[14, c1])
                    atti[mo, 2] = math.atan2(-K[7, c1], K[10, c1])
            if has_mount:
                mnt[k + 1, 0] = K[21, c1]
                mnt[k + 1, 1] = _wrap(K[22, c1])
                mnt[k + 1, 2] = _wrap(K[23, c1])
    return chk


def _stencil(m: int):
    """Weights of ∫_0^1 p(x) dx for the interpolating polynomial through x = lo..lo+m−1
    (lo = −(m//2 − 1)): a centred m-point rule of order m for one interval. Computed in
    exact rational arithmetic (m = 6: [11, −93, 802, 802, −93, 11]/1440)."""
    from fractions import Fraction
    lo = -(m // 2 - 1)
    x = [Fraction(lo + i) for i in range(m)]
    # solve sum_j w_j x_j^p = ∫_0^1 x^p dx = 1/(p+1), p = 0..m-1 (Gauss-Jordan, exact)
    M = [[x[j] ** p for j in range(m)] + [Fraction(1, p + 1)] for p in range(m)]
    for c in range(m):
        piv = next(r for r in range(c, m) if M[r][c] != 0)
        M[c], M[piv] = M[piv], M[c]
        M[c] = [v / M[c][c] for v in M[c]]
        for r in range(m):
            if r != c and M[r][c] != 0:
                f = M[r][c]
                M[r] = [a - f * b for a, b in zip(M[r], M[c])]
    return np.array([float(M[j][m]) for j in range(m)]), lo


# --- public API ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Generated:
    """Output of :func:`generate`.

    Attributes
    ----------
    truth : NavSeries
        Epochs ``t0, t0 + k·out_every·dt, ...`` (``N + 1`` epochs with ``out_every = 1``):
        position, ENU velocity, carrier attitude ``att`` and, with a mount, the IMU
        attitude ``att_imu``.
    imu : ImuRecord
        The ``N`` exact increments in the IMU frame. With ``out_every = 1`` its time column
        is a view of ``truth.t[1:]`` (same numbers, one array).
    mount : ndarray, shape (N + 1, 3) or None
        Euler angles ``[pitch, roll, yaw]`` of ``C_imu^carrier`` at every IMU epoch
        (regardless of ``out_every``), wrapped to (−π, π].
    segments, start, mount_spec : the inputs, as objects.
    """

    truth: NavSeries
    imu: ImuRecord
    mount: np.ndarray | None
    segments: list
    start: Start
    mount_spec: object = None

    @property
    def dt(self) -> float:
        return self.imu.dt


def generate(segments, start, dt, *, duration=None, mount=None, t0=0.0, out_every=1,
             quadrature="stencil", nodes=8) -> Generated:
    """Synthesize the truth and exact IMU increments of a segment motion.

    Parameters
    ----------
    segments : list of Segment or of config tables
    start : Start or table
        Initial position, speed, heading (clockwise from north), pitch, roll.
    dt : float
        IMU sampling interval [s].
    duration : float, optional
        Length of the run [s]; default: the sum of the segment durations. After the last
        segment the motion continues unchanged.
    mount : indexing.RotateStop, indexing.Swing, table or None
        IMU mount motion relative to the carrier.
    t0 : float
        Time of the first epoch [s].
    out_every : int
        Keep the truth at every ``out_every``-th epoch only (memory for long runs).
    quadrature, nodes : str, int
        Rule for the increments and position. ``"stencil"`` (default, ``nodes`` = 4, 6 or 8
        points): one evaluation per epoch, the increment over an interval is the exact
        integral of the polynomial interpolating ``nodes`` neighbouring epochs (order
        ``nodes``); intervals whose stencil straddles a breakpoint of the profiles are split
        there and integrated with Gauss–Legendre of ``nodes/2`` points. ``"gauss"``
        (1..8 nodes) or ``"lobatto"`` (2..8 nodes): that rule on every interval (slower;
        for checks).

    Returns
    -------
    Generated
    """
    segments = segments_from_list(segments)
    if not segments:
        raise ValueError("no segments")
    start = _as_start(start)
    mount = _as_mount(mount)
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be > 0, got {dt!r}")
    total = total_duration(segments) if duration is None else float(duration)
    if not (math.isfinite(total) and total > 0):
        raise ValueError(f"duration must be > 0, got {total!r}")
    n = int(math.floor(total / dt + 1e-6))
    if n < 1:
        raise ValueError(f"duration {total} s is shorter than one sample ({dt} s)")
    out_every = int(out_every)
    if out_every < 1:
        raise ValueError(f"out_every must be >= 1, got {out_every}")
    if quadrature == "stencil":
        if int(nodes) not in (4, 6, 8):
            raise ValueError(f"stencil quadrature needs 4, 6 or 8 points, got {nodes}")
        sw, lo = _stencil(int(nodes))
        c, b, A = _rule("gauss", int(nodes) // 2)          # fallback near breakpoints, same order
    else:
        c, b, A = _rule(quadrature, int(nodes))
        sw, lo = np.zeros(0), 0
    tabs = _compile(segments, start, mount, n * dt)
    m = n // out_every + 1
    dth = np.empty((n, 3))
    dvl = np.empty((n, 3))
    olat = np.empty(m)
    olon = np.empty(m)
    oh = np.empty(m)
    vel = np.empty((m, 3))
    att = np.empty((m, 3))
    t_nav = np.empty(m)                 # t0 + dt·out_every·k
    # t0 + dt·k, k = 1..n, written by the kernel; with out_every = 1 the same numbers as
    # t_nav[1:] (tstep = dt·1 exactly), so the records share them: one array less to
    # allocate and fault in (neither record writes to its time column)
    t_imu = t_nav[1:] if out_every == 1 else np.empty(n)
    has_mount = mount is not None
    atti = np.empty((m, 3) if has_mount else (1, 3))
    mnt = np.empty((n + 1, 3) if has_mount else (1, 3))
    chk = _synth(n, dt, out_every, sw, lo, c, b, A, has_mount, *tabs,
           start.lat, start.lon, start.h, float(t0), dth, dvl, t_imu, olat, olon, oh, t_nav,
           vel, att, atti, mnt)
    if not math.isfinite(chk):
        raise ValueError("non-finite increments (a pole crossed, or an extreme motion?)")
    truth = NavSeries(t_nav, olat, olon, oh, vel, att,
                      atti if has_mount else None)
    return Generated(truth, _imu_record(t_imu, dth, dvl, dt), mnt if has_mount else None,
                     segments, start, mount)


_RECORD_FIELDS = ("t", "dtheta", "dv", "dt", "rel_tol")
_REL_TOL = {f.name: f.default for f in fields(ImuRecord)}.get("rel_tol")


def _imu_record(t, dth, dv, dt):
    """ImuRecord of arrays valid by construction (uniform increasing times, finite
    increments, checked by the kernel), without the constructor's validation passes, which
    cost a quarter of the synthesis. Falls back to the constructor if ImuRecord ever gains
    fields this does not know."""
    if tuple(f.name for f in fields(ImuRecord)) != _RECORD_FIELDS or t.size < 2:
        return ImuRecord(t, dth, dv, dt)
    rec = object.__new__(ImuRecord)
    dt = (t[-1] - t[0]) / (t.size - 1)                # what the constructor derives
    for name, v in zip(_RECORD_FIELDS, (t, dth, dv, float(dt), _REL_TOL)):
        object.__setattr__(rec, name, v)
    return rec


# --- ready-made motions ------------------------------------------------------------------------
def static(duration: float = 3600.0) -> list[Segment]:
    """A carrier at rest for ``duration`` seconds."""
    return [Static(float(duration))]


def _fill(cycle, duration):
    out, t = [], 0.0
    while True:
        added = False
        for s in cycle:
            if t + s.duration > duration + 1e-9:
                rest = duration - t
                if rest > 1e-9:
                    out.append(Level(rest, transition=min(5.0, rest)))
                return out
            out.append(s)
            t += s.duration
            added = True
        if not added:
            return out


def aircraft_mixed(duration: float = 3600.0, *, turn_rate: float = 1.5 * units.deg,
                   climb_angle: float = 5.0 * units.deg, accel: float = 2.0,
                   wing_rock_amplitude: float = 10.0 * units.deg,
                   wing_rock_period: float = 4.0) -> list[Segment]:
    """Aircraft manoeuvres repeated to fill ``duration`` [s]: level flight, coordinated
    turns (right and left), climb and descent, acceleration and deceleration, wing rock
    (SI arguments).

    One cycle lasts 700 s and returns to the same speed and height; its net heading change
    is +90° (turns of 90°, −180°, +180° at ``turn_rate``, rolled in and out over 5 s). At
    the paper-003 start (32° N, 118° E, 1000 m, heading 0°, 300 m/s) the default turns
    bank by about 39°. A last incomplete cycle is cut and ends with level flight.
    """
    tr = turn_rate
    t90 = (math.pi / 2) / tr + 5.0
    t180 = math.pi / tr + 5.0
    cycle = [
        Level(40.0),
        Accelerate(25.0, accel, ramp=3.0),
        Turn(t90, tr, ramp=5.0),                         # +90° (right)
        Climb(60.0, climb_angle, transition=10.0),
        Level(40.0, transition=10.0),
        WingRock(40.0, wing_rock_amplitude, wing_rock_period, ramp=wing_rock_period),
        Turn(t180, -tr, ramp=5.0),                       # 180° left
        Climb(60.0, -climb_angle, transition=10.0),      # descend
        Level(40.0, transition=10.0),
        Accelerate(25.0, -accel, ramp=3.0),
        Turn(t180, tr, ramp=5.0),                        # 180° right
    ]
    used = sum(s.duration for s in cycle)
    if used < 700.0:
        cycle.append(Level(700.0 - used))
    return _fill(cycle, float(duration))


def ship_manoeuvring(duration: float = 48 * 3600.0, *, static_time: float = 0.0,
                     mean_speed: float = 15.0, speed_amplitude: float = 15.0,
                     speed_period: float = 1200.0, course_amplitude: float = 30.0 * units.deg,
                     course_period: float = 1800.0, roll_amplitude: float = 5.0 * units.deg,
                     roll_period: float = 12.0, pitch_amplitude: float = 2.0 * units.deg,
                     pitch_period: float = 8.0, yaw_amplitude: float = 1.0 * units.deg,
                     yaw_period: float = 15.0, heave_amplitude: float = 0.5,
                     heave_period: float = 10.0, accel: float = 0.1) -> list[Segment]:
    """Continuously manoeuvring ship (paper 004 default): optional rest, acceleration to
    ``mean_speed``, then sinusoidal speed (amplitude 15 m/s: 0–30 m/s), sinusoidal course
    (±30°: with a start heading of 30° the heading stays within 0–60°), roll/pitch/yaw
    sway and heave, for the rest of ``duration`` [s] (SI arguments)."""
    segs: list[Segment] = []
    if static_time > 0:
        segs.append(Static(static_time))
    ta = mean_speed / accel + 10.0
    segs.append(Accelerate(ta, accel, ramp=10.0))
    rest = duration - static_time - ta
    if rest <= 20.0:
        raise ValueError(f"duration {duration} s is too short for the ship manoeuvres")
    segs.append(Ship(rest, pitch_amplitude, pitch_period, roll_amplitude, roll_period,
                     yaw_amplitude, yaw_period, heave_amplitude, heave_period,
                     speed_amplitude, speed_period, course_amplitude, course_period,
                     ramp=min(60.0, rest / 2)))
    return segs
