"""IMU mount motion relative to the carrier: rotate-stop indexing and swinging tables.

The IMU body frame b sits on a mechanism in the carrier frame c. The mechanism's
attitude is given by Euler angles ``m = [pitch, roll, yaw]`` in sinslab's convention,
``C_b^c = R_z(yaw) R_x(pitch) R_y(roll)``: the azimuth gimbal (yaw, about the carrier's
up axis) is the outer one, the roll gimbal (about the IMU's forward axis) the inner one,
which is the usual dual-axis (azimuth + roll) indexing layout.

Two kinds of mount:

- :class:`RotateStop` — a rotate-stop schedule: dwell, rotate by a given angle about the
  azimuth or roll axis, dwell, next move, ... repeated cyclically. Each rotation has a
  smooth rate profile (rate rises to ``rate`` along a quintic smooth step of length
  ``ramp``, holds, falls back), so the rotation takes ``|angle|/rate + ramp`` seconds and
  the angular rate is continuous. Ready-made schemes (data in :data:`SCHEMES`):

  * ``single_axis_4pos`` — azimuth stops at 0°, 180°, 270°, 90° (moves +180°, +90°, −180°,
    −90°, so the cable never winds up): the single-axis 4-position scheme of paper 001.
  * ``dual_axis_16`` — the 16-step azimuth/roll sequence with stops at 0°/180° about both
    axes (after Yuan, Liao, Han 2012, ref. [5] of paper 001): each group of four moves is
    mirrored in order and sign by the following ones so that, over a cycle, every move is
    cancelled by an opposite one.
  * ``azimuth_flip``, ``roll_flip`` — stops at 0° and 180° about one axis only.

  :func:`scheme` builds the mount of any of them by name.

- :class:`Swing` — a swinging table: sinusoidal swing about one Euler axis
  (e.g. ±5°, 40 s about pitch: the laboratory variant of paper 004).

:func:`mount_angles` evaluates a mount (angles and Euler-angle rates) at given times; the
trajectory generator (:mod:`sinslab.sim.trajectory`) compiles the same schedule into its own
kernel and the two are tested against each other. Times are seconds since the start of
the motion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import units

__all__ = ["common_stops", "AXES", "SINGLE_AXIS_4POS", "DUAL_AXIS_16", "AZIMUTH_FLIP", "ROLL_FLIP", "SCHEMES",
           "RotateStop", "Swing", "short_number", "single_axis_4pos", "dual_axis_16", "scheme", "mount_angles",
           "mount_from_dict", "Mount"]

#: Mount Euler-angle components: index into ``[pitch, roll, yaw]``; "azimuth" = yaw.
AXES = {"pitch": 0, "roll": 1, "yaw": 2, "azimuth": 2}

#: Single-axis 4-position rotate-stop moves (axis, angle in degrees): stops 0°, 180°, 270°, 90°.
SINGLE_AXIS_4POS: tuple[tuple[str, float], ...] = (
    ("yaw", 180.0), ("yaw", 90.0), ("yaw", -180.0), ("yaw", -90.0))

#: Dual-axis 16-step rotate-stop moves (axis, angle in degrees): stops at 0°/180° on both axes.
DUAL_AXIS_16: tuple[tuple[str, float], ...] = (
    ("yaw", 180.0), ("roll", 180.0), ("yaw", -180.0), ("roll", -180.0),
    ("roll", -180.0), ("yaw", -180.0), ("roll", 180.0), ("yaw", 180.0),
    ("yaw", -180.0), ("roll", -180.0), ("yaw", 180.0), ("roll", 180.0),
    ("roll", 180.0), ("yaw", 180.0), ("roll", -180.0), ("yaw", -180.0))

#: One-axis flips (axis, angle in degrees): stops at 0° and 180° about the azimuth or the roll
#: axis only, schedules on which to check what a dual-axis scheme adds.
AZIMUTH_FLIP: tuple[tuple[str, float], ...] = (("yaw", 180.0), ("yaw", -180.0))
ROLL_FLIP: tuple[tuple[str, float], ...] = (("roll", 180.0), ("roll", -180.0))

#: Named schemes: move lists in degrees.
SCHEMES = {"single_axis_4pos": SINGLE_AXIS_4POS, "dual_axis_16": DUAL_AXIS_16, "azimuth_flip": AZIMUTH_FLIP,
           "roll_flip": ROLL_FLIP}


# --- smooth step (quintic) and its derivatives, numpy ------------------------------------
def _s5(x):
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))


def _s5d(x):
    y = x * (1.0 - x)
    return 30.0 * y * y


def _s5i(x):          # ∫_0^x s5
    x2 = x * x
    return x2 * x2 * (2.5 + x * (-3.0 + x))


def _axis_index(axis, allowed=("pitch", "roll", "yaw", "azimuth")):
    if axis not in allowed:
        raise ValueError(f"mount axis {axis!r} is not one of {', '.join(allowed)}")
    return AXES[axis]


@dataclass(frozen=True)
class RotateStop:
    """Rotate-stop indexing schedule (SI units).

    Attributes
    ----------
    moves : tuple of (axis, angle)
        Rotations in order; axis ``"yaw"``/``"azimuth"`` or ``"roll"`` (or ``"pitch"``),
        angle [rad], signed.
    rate : float
        Peak rotation rate [rad/s] (> 0).
    ramp : float
        Time for the rate to rise from 0 to ``rate`` (and to fall back) [s]; needs
        ``|angle|/rate >= ramp`` for every move.
    dwell : float
        Stop time before each move [s] (the schedule starts with a stop).
    initial : tuple of 3 floats
        Mount angles ``[pitch, roll, yaw]`` at the start [rad].
    repeat : bool
        Repeat the move list cyclically (otherwise stop after the last move).
    name : str
        Label (the scheme name for the ready-made ones).
    """

    moves: tuple
    rate: float = 9.0 * units.deg
    ramp: float = 1.0
    dwell: float = 300.0
    initial: tuple = (0.0, 0.0, 0.0)
    repeat: bool = True
    name: str = "custom"
    kind = "rotate_stop"

    def __post_init__(self):
        moves = tuple((str(a), float(x)) for a, x in self.moves)
        if not moves:
            raise ValueError("rotate-stop schedule has no moves")
        for i, (a, x) in enumerate(moves):
            _axis_index(a)
            if not math.isfinite(x) or x == 0.0:
                raise ValueError(f"move {i}: angle must be finite and non-zero, got {x!r}")
        if not (self.rate > 0 and math.isfinite(self.rate)):
            raise ValueError(f"rate must be > 0, got {self.rate!r}")
        if not (self.ramp >= 0 and math.isfinite(self.ramp)):
            raise ValueError(f"ramp must be >= 0, got {self.ramp!r}")
        if not (self.dwell >= 0 and math.isfinite(self.dwell)):
            raise ValueError(f"dwell must be >= 0, got {self.dwell!r}")
        for i, (a, x) in enumerate(moves):
            if abs(x) / self.rate < self.ramp * (1 - 1e-12):
                raise ValueError(f"move {i}: angle {math.degrees(x):g} deg is too small for rate "
                                 f"{math.degrees(self.rate):g} deg/s with ramp {self.ramp:g} s")
        ini = tuple(float(v) for v in self.initial)
        if len(ini) != 3:
            raise ValueError("initial mount angles must be 3 numbers [pitch, roll, yaw]")
        object.__setattr__(self, "moves", moves)
        object.__setattr__(self, "initial", ini)

    def move_time(self, angle: float) -> float:
        """Duration of a rotation by ``angle`` [s]."""
        return abs(angle) / self.rate + self.ramp

    @property
    def cycle_time(self) -> float:
        """Duration of one pass through the move list, dwells included [s]."""
        return sum(self.dwell + self.move_time(x) for _, x in self.moves)

    def timeline(self, t_end: float):
        """Moves starting before ``t_end`` [s]: list of ``(t_start, duration, axis_index, angle)``."""
        out, t = [], 0.0
        while True:
            for a, x in self.moves:
                t += self.dwell
                if t >= t_end:
                    return out
                d = self.move_time(x)
                out.append((t, d, AXES[a], x))
                t += d
            if not self.repeat:
                return out

    def to_dict(self) -> dict:
        d = {"kind": "rotate_stop"}
        if self.name in SCHEMES and _same_moves(self.moves, SCHEMES[self.name]):
            d["scheme"] = self.name
        else:
            d["moves"] = [[a, _deg(x)] for a, x in self.moves]
        d.update(rate=f"{short_number(self.rate, units.deg)} deg/s", ramp=f"{self.ramp!r} s",
                 dwell=f"{self.dwell!r} s", initial=[_deg(v) for v in self.initial],
                 repeat=self.repeat)
        return d


def short_number(v_si: float, scale: float) -> str:
    """``v_si / scale`` as the shortest decimal (≤ 15 digits) that parses back to exactly
    ``v_si`` when multiplied by ``scale`` (else the full repr): ``118 deg`` not
    ``118.00000000000001 deg``."""
    x = v_si / scale
    for digits in range(1, 16):
        y = float(f"{x:.{digits}g}")
        if y * scale == v_si:
            return repr(y)
    return repr(x)


def _deg(v):
    return f"{short_number(v, units.deg)} deg"


def _same_moves(a, b):
    return len(a) == len(b) and all(x[0] == y[0] and abs(x[1] - math.radians(y[1])) < 1e-12
                                    for x, y in zip(a, b))


@dataclass(frozen=True)
class Swing:
    """Swinging table: ``m[axis] = initial[axis] + amplitude·E(t)·sin(2π t/period + phase)``.

    ``E`` rises from 0 to 1 along a quintic smooth step of length ``ramp`` (``ramp = 0``:
    the swing is in full motion from t = 0, with a non-zero rate at the start).
    """

    axis: str = "pitch"
    amplitude: float = 5.0 * units.deg
    period: float = 40.0
    phase: float = 0.0
    ramp: float = 0.0
    initial: tuple = (0.0, 0.0, 0.0)
    kind = "swing"

    def __post_init__(self):
        _axis_index(self.axis)
        for name in ("amplitude", "period", "phase", "ramp"):
            v = getattr(self, name)
            if not math.isfinite(v):
                raise ValueError(f"swing {name} is not finite")
        if self.period <= 0:
            raise ValueError(f"swing period must be > 0, got {self.period!r}")
        if self.ramp < 0:
            raise ValueError(f"swing ramp must be >= 0, got {self.ramp!r}")
        ini = tuple(float(v) for v in self.initial)
        if len(ini) != 3:
            raise ValueError("initial mount angles must be 3 numbers [pitch, roll, yaw]")
        object.__setattr__(self, "initial", ini)

    def to_dict(self) -> dict:
        return {"kind": "swing", "axis": self.axis, "amplitude": _deg(self.amplitude),
                "period": f"{self.period!r} s", "phase": _deg(self.phase),
                "ramp": f"{self.ramp!r} s", "initial": [_deg(v) for v in self.initial]}


Mount = RotateStop | Swing


def single_axis_4pos(rate=9.0 * units.deg, dwell=300.0, ramp=1.0, initial=(0.0, 0.0, 0.0),
                     repeat=True) -> RotateStop:
    """Single-axis (azimuth) 4-position rotate-stop: stops at 0°, 180°, 270°, 90° (SI arguments)."""
    return RotateStop(tuple((a, math.radians(x)) for a, x in SINGLE_AXIS_4POS), rate, ramp, dwell,
                      initial, repeat, "single_axis_4pos")


def dual_axis_16(rate=9.0 * units.deg, dwell=300.0, ramp=1.0, initial=(0.0, 0.0, 0.0),
                 repeat=True) -> RotateStop:
    """Dual-axis (azimuth + roll) 16-step rotate-stop, stops at 0°/180° (SI arguments)."""
    return RotateStop(tuple((a, math.radians(x)) for a, x in DUAL_AXIS_16), rate, ramp, dwell,
                      initial, repeat, "dual_axis_16")


def scheme(name, rate=9.0 * units.deg, dwell=300.0, ramp=1.0, initial=(0.0, 0.0, 0.0),
           repeat=True) -> RotateStop:
    """The rotate-stop mount of a named scheme of :data:`SCHEMES` (SI arguments)."""
    return RotateStop(tuple((a, math.radians(x)) for a, x in SCHEMES[name]), rate, ramp, dwell, initial, repeat,
                      name)


def mount_angles(mount: Mount | None, t):
    """Mount Euler angles ``[pitch, roll, yaw]`` of ``C_imu^carrier`` and their rates.

    Parameters
    ----------
    mount : RotateStop, Swing or None
    t : array_like
        Times since the start of the motion [s] (>= 0).

    Returns
    -------
    angles, rates : ndarray, shape ``t.shape + (3,)``
        Angles [rad] (not wrapped: a 360° rotation shows as 2π) and Euler-angle rates [rad/s].
    """
    t = np.asarray(t, dtype=float)
    ang = np.zeros(t.shape + (3,)) + np.asarray(getattr(mount, "initial", (0.0, 0.0, 0.0)))
    rate = np.zeros(t.shape + (3,))
    if mount is None:
        return ang, rate
    if isinstance(mount, Swing):
        k = AXES[mount.axis]
        w = 2 * math.pi / mount.period
        s, c = np.sin(w * t + mount.phase), np.cos(w * t + mount.phase)
        if mount.ramp > 0:
            x = np.clip(t / mount.ramp, 0.0, 1.0)
            e, ed = _s5(x), np.where(t < mount.ramp, _s5d(x) / mount.ramp, 0.0)
        else:
            e, ed = np.ones_like(t), np.zeros_like(t)
        ang[..., k] += mount.amplitude * e * s
        rate[..., k] = mount.amplitude * (ed * s + e * w * c)
        return ang, rate
    if not isinstance(mount, RotateStop):
        raise TypeError(f"unknown mount type {type(mount).__name__}")
    tl = mount.timeline(float(np.max(t)) + 1.0 if t.size else 0.0)
    if not tl:
        return ang, rate
    starts = np.array([m[0] for m in tl])
    durs = np.array([m[1] for m in tl])
    axes = np.array([m[2] for m in tl])
    dang = np.array([m[3] for m in tl])
    cum = np.zeros((len(tl) + 1, 3))
    for i in range(len(tl)):
        cum[i + 1] = cum[i]
        cum[i + 1, axes[i]] += dang[i]
    idx = np.searchsorted(starts, t, side="right") - 1          # last move started
    has = idx >= 0
    i = np.where(has, idx, 0)
    ang += np.where(has[..., None], cum[i + 1], 0.0)     # full angles of moves started so far
    u = t - starts[i]
    T, Tr = durs[i], mount.ramp
    r = np.sign(dang[i]) * mount.rate
    inside = has & (u < T)
    # integral of the trapezoidal rate profile and the rate itself
    if Tr > 0:
        xa = np.clip(u / Tr, 0.0, 1.0)
        xb = np.clip((T - u) / Tr, 0.0, 1.0)
        up, down = u < Tr, u > T - Tr
        val = np.where(up, Tr * _s5i(xa), np.where(down, T - Tr - Tr * _s5i(xb), Tr / 2 + (u - Tr)))
        rt = np.where(up, _s5(xa), np.where(down, _s5(xb), 1.0))
    else:
        val, rt = u, np.ones_like(u)
    val = r * val - dang[i]              # progress minus the full angle (already in cum)
    rt = r * rt
    ax = axes[i]
    for k in range(3):
        sel = inside & (ax == k)
        ang[..., k] += np.where(sel, val, 0.0)
        rate[..., k] = np.where(sel, rt, 0.0)
    return ang, rate


def _q(value, kind, key, where):
    try:
        return units.parse(value, kind)
    except ValueError as e:
        raise ValueError(f"{where}: key {key!r}: {e}") from None


def mount_from_dict(d: dict, where: str = "mount") -> Mount:
    """Build a mount from a config table (unit strings), e.g.
    ``{kind="rotate_stop", scheme="dual_axis_16", rate="9 deg/s", dwell="5 min"}`` or
    ``{kind="swing", axis="pitch", amplitude="5 deg", period="40 s"}``."""
    d = dict(d)
    kind = d.pop("kind", None)
    if kind == "swing":
        allowed = {"axis", "amplitude", "period", "phase", "ramp", "initial"}
    elif kind == "rotate_stop":
        allowed = {"scheme", "moves", "rate", "ramp", "dwell", "initial", "repeat"}
    else:
        raise ValueError(f"{where}: key 'kind' must be 'rotate_stop' or 'swing', got {kind!r}")
    bad = sorted(set(d) - allowed)
    if bad:
        raise ValueError(f"{where} ({kind}): unknown key {bad[0]!r}; allowed: {', '.join(sorted(allowed))}")
    kw = {}
    if "initial" in d:
        v = d["initial"]
        if not isinstance(v, (list, tuple)) or len(v) != 3:
            raise ValueError(f"{where}: key 'initial' must be 3 angles [pitch, roll, yaw]")
        kw["initial"] = tuple(_q(x, "angle", "initial", where) for x in v)
    try:
        if kind == "swing":
            if "axis" in d:
                kw["axis"] = str(d["axis"])
            for key, q in (("amplitude", "angle"), ("period", "time"), ("phase", "angle"),
                           ("ramp", "time")):
                if key in d:
                    kw[key] = _q(d[key], q, key, where)
            return Swing(**kw)
        if ("scheme" in d) == ("moves" in d):
            raise ValueError(f"{where}: give exactly one of 'scheme' or 'moves'")
        if "scheme" in d:
            if d["scheme"] not in SCHEMES:
                raise ValueError(f"{where}: key 'scheme': unknown {d['scheme']!r}; "
                                 f"known: {', '.join(SCHEMES)}")
            kw["moves"] = tuple((a, math.radians(x)) for a, x in SCHEMES[d["scheme"]])
            kw["name"] = d["scheme"]
        else:
            mv = []
            for i, m in enumerate(d["moves"]):
                if not isinstance(m, (list, tuple)) or len(m) != 2:
                    raise ValueError(f"{where}: key 'moves': item {i} must be [axis, angle]")
                mv.append((str(m[0]), _q(m[1], "angle", f"moves[{i}]", where)))
            kw["moves"] = tuple(mv)
        for key, q in (("rate", "angular_rate"), ("ramp", "time"), ("dwell", "time")):
            if key in d:
                kw[key] = _q(d[key], q, key, where)
        if "repeat" in d:
            if not isinstance(d["repeat"], bool):
                raise ValueError(f"{where}: key 'repeat' must be true or false")
            kw["repeat"] = d["repeat"]
        return RotateStop(**kw)
    except ValueError as e:
        msg = str(e)
        raise ValueError(msg if msg.startswith(where) else f"{where} ({kind}): {msg}") from None


def common_stops(m1: Mount | None, mk: Mount | None, t_end: float, dt: float = 0.5):
    """The intervals in which two indexing mechanisms both stand still, in time order.

    Both mounts are sampled every ``dt`` seconds over ``[0, t_end)``; consecutive samples
    with zero rates and the same pair of mount angles form one stop. This is the piecewise
    constant segmentation of the relative attitude of two rotating IMUs on one carrier.

    Parameters
    ----------
    m1, mk : Mount or None
        The two mechanisms (None: fixed mount).
    t_end : float
        End of the examined span [s].
    dt : float
        Sampling step [s]; a stop is resolved to this step.

    Returns
    -------
    C1c, Ckc : ndarray (m, 3, 3)
        IMU-to-carrier DCMs ``C_b1^c``, ``C_bk^c`` of the m stops.
    durations : ndarray (m,)
        Length of each stop [s] (a multiple of ``dt``).
    """
    # here, not at the top: the mount definitions (an experiment's configuration) need no numba or scipy
    from sinslab.core.attitude import euler_to_dcm

    t = np.arange(0.0, t_end, dt)
    a1, r1 = mount_angles(m1, t)
    ak, rk = mount_angles(mk, t)
    still = np.all(r1 == 0, -1) & np.all(rk == 0, -1)
    key = np.round(np.hstack([a1, ak]), 9)
    segs = []
    for i in np.flatnonzero(still):
        if segs and segs[-1][2] == i - 1 and np.array_equal(segs[-1][0], key[i]):
            segs[-1][1] += dt
            segs[-1][2] = i
        else:
            segs.append([key[i], dt, i])
    ang = np.array([s[0] for s in segs])
    return euler_to_dcm(ang[:, :3]), euler_to_dcm(ang[:, 3:]), np.array([s[1] for s in segs])
