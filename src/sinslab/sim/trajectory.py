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
kernel (:mod:`sinslab.sim._synth`); segments are first compiled here into parameter arrays
(channel terms and pieces). Ready-made motions built of these segments live in
:mod:`sinslab.sim.presets`.

Units: SI inside (rad, m, s). Configs/TOML give unit strings (``"3 deg/s"``); heading in
:class:`Start` is clockwise from north, the Euler yaw in the outputs is ``−heading``.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, fields
from pathlib import Path
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from sinslab.core import units
from sinslab.core.errors import InputError
from sinslab.core.atomic import atomic_write
from sinslab.core.toml import dump_toml
from sinslab.sim import indexing
from sinslab.sim._synth import (CH_HEAVE, CH_MP, CH_MY, CH_PITCH, CH_PSI, CH_ROLL, CH_THETA, CH_V,
                                CH_YAW, NCH, T_SINE, T_STEP, T_TRAP, _rule, _stencil, _synth)
from sinslab.core.records import ImuRecord, NavSeries

__all__ = [
    "Start", "Segment", "Static", "Accelerate", "Turn", "Climb", "Level", "WingRock", "Ship",
    "SEGMENT_KINDS", "segment_from_dict", "segments_from_list", "load_segments", "load_motion",
    "dump_segments", "Motion", "Generated", "generate", "total_duration",
]

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
    out: dict[str, Any] = {}
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
    if TYPE_CHECKING:                   # every kind declares it, first (a field of the kinds only)
        duration: float

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
        if getattr(self, "transition") is None:
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


SEGMENT_KINDS: dict[str, type[Segment]] = {c.kind: c for c in
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


def segments_from_list(items: Iterable[Segment | dict]) -> list[Segment]:
    """Segments from a list of tables or :class:`Segment` objects."""
    out = []
    for i, s in enumerate(items):
        out.append(s if isinstance(s, Segment) else segment_from_dict(s, i))
    return out


def total_duration(segments: Iterable[Segment]) -> float:
    """Sum of segment durations [s]."""
    return float(sum(s.duration for s in segments))


# --- TOML ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Motion:
    """What a motion file holds: segments, an optional start and an optional mount."""

    segments: list
    start: Start | None = None
    mount: object = None


def dump_segments(segments: Iterable[Segment | dict], path: str | Path, *, start: Start | dict | None = None,
                  mount: object = None) -> None:
    """Write segments (and optionally the start and the mount) to a TOML file, atomically.

    Layout: an optional ``[start]`` table, an optional ``[mount]`` table and one
    ``[[segment]]`` table per segment, all values as unit strings.
    """
    segments = segments_from_list(segments)
    doc = {"start": None if start is None else _as_start(start).to_dict(),
           "mount": None if mount is None else _as_mount(mount).to_dict(),
           "segment": [s.to_dict() for s in segments]}
    atomic_write(path, "# sinslab motion: segments in order; values are unit strings\n\n"
                 + dump_toml(doc, array_tables=True))


def load_motion(path: str | Path) -> Motion:
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


def load_segments(path: str | Path) -> list[Segment]:
    """Segments of a motion TOML file."""
    return load_motion(path).segments


# --- compilation of segments into kernel tables -------------------------------------------


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
            assert s.transition is not None         # set by __post_init__
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
    points = [0.0]
    for r in rows:
        points.extend(r[5])
    for a, b in terms.coord:
        points.extend((a, b))
    bp = np.unique(np.asarray(points, dtype=float))
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


def generate(segments: Iterable[Segment | dict], start: Start | dict, dt: float, *, duration: float | None = None,
             mount: object = None, t0: float = 0.0, out_every: int = 1, quadrature: str = "stencil",
             nodes: int = 8) -> Generated:
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
    bp, base, flag, plo, phi, act, ttype, tch, tta, tpar = _compile(segments, start, mount, n * dt)
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
    chk = _synth(n, dt, out_every, sw, lo, c, b, A, has_mount, bp, base, flag, plo, phi, act, ttype, tch, tta, tpar,
           start.lat, start.lon, start.h, float(t0), dth, dvl, t_imu, olat, olon, oh, t_nav,
           vel, att, atti, mnt)
    if not math.isfinite(chk):
        raise InputError("non-finite increments (a pole crossed, or an extreme motion?)")
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
