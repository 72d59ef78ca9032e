"""Run specs of :func:`sinslab.fusion.recorded.navigate_recorded`: four cohesive frozen
values, each checked once when it is made (SI units), bundled in :class:`NavOptions`.

- :class:`ErrorSpec`: the IMU's error model and noise (bias, Gauss–Markov and scale-factor
  states, and whether the initial rest calibrates the bias and the white noise).
- :class:`FixHandling`: how the GNSS enters the filter: lever arm, outages, and for fixes
  latency, lag policy, σ overrides and floors.
- :class:`StartSpec`: the initial attitude and its σ (levelling, heading from the course,
  in-motion alignment) and the platform kind.
- :class:`GridSpec`: the filter step, subsamples, and the recorded/smoothed pass.

The aids (their settings, states and measurements) and the GNSS source are plug-ins of
the run, not fields here (:mod:`sinslab.fusion.aids`).

The app assembles them at its edge (from its option and unit-string machinery) and
builds each once; nothing below re-parses them. Derive another value with
:func:`dataclasses.replace` on the spec concerned, or :meth:`NavOptions.replace` by field
name.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import units
from sinslab.fusion.lag import ExactReprocessing

__all__ = ["ErrorSpec", "FixHandling", "StartSpec", "GridSpec", "NavOptions", "PLATFORMS", "FIX_NOISE"]

#: platform kinds of :attr:`StartSpec.platform`
PLATFORMS = ("auto", "land", "aircraft", "marine")
#: how the fixes' σ are taken (:attr:`FixHandling.fix_noise`)
FIX_NOISE = ("stated", "innovations")


def _check_positive(spec, *names):
    for nm in names:
        v = getattr(spec, nm)
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{nm} must be > 0, got {v}")


def _check_sigmas(spec, *pairs):
    for nm, n in pairs:
        v = getattr(spec, nm)
        if v is not None:
            try:
                a = np.broadcast_to(np.asarray(v, dtype=float), (n,))
            except ValueError:
                a = np.full(n, np.nan)
            if not np.all(np.isfinite(a) & (a > 0)):
                raise ValueError(f"{nm} must be {n} finite values > 0, got {v!r}")


def _lever(name, v):
    la = np.asarray(v, dtype=float)
    if la.shape != (3,) or not np.all(np.isfinite(la)):
        raise ValueError(f"{name} must be 3 finite numbers [m], got {v!r}")
    return tuple(float(x) for x in la)


@dataclass(frozen=True, eq=False)
class ErrorSpec:
    """The IMU's error model: white noise, bias and scale-factor states and their initial σ."""

    gyro_arw: float = 0.0038 * units.deg    #: [rad/sqrt(s)] (0.0038 deg/s/sqrt(Hz))
    accel_vrw: float = 70 * units.ug        #: [m/s/sqrt(s)]
    gyro_rrw: float = 3.8e-5 * units.deg * 2   #: gyro bias random walk [rad/s/sqrt(s)]
    accel_rrw: float = 7 * units.ug * 4     #: accel bias random walk [m/s^2/sqrt(s)]
    gyro_bias_sigma: float = 0.05 * units.deg   #: initial 1σ [rad/s] (after rest calibration)
    accel_bias_sigma: float = 0.2           #: initial 1σ [m/s^2]
    scale_factors: bool = False
    scale_sigma: float = 0.01               #: initial 1σ of scale-factor states [-]
    rest_bias: bool = True                  #: initial gyro bias from the initial rest
    rest_noise: bool = True                 #: white noise per axis from the initial rest
    #: (sample scatter at rest × sqrt(dt), floored at gyro_arw/accel_vrw: engine vibration
    #: in a car is far above a datasheet's noise density); False: gyro_arw/accel_vrw as given
    gyro_markov: tuple | None = None        #: (σ [rad/s], τ [s]) Gauss–Markov gyro bias block
    accel_markov: tuple | None = None       #: (σ [m/s²], τ [s]) Gauss–Markov accelerometer bias
    gyro_scale_sigma: float | None = None   #: initial σ of gyro scale factors [-] (default scale_sigma)
    accel_scale_sigma: float | None = None  #: likewise for the accelerometers
    scale_rw: tuple = (0.0, 0.0)            #: gyro, accel scale-factor random walk [1/√s]
    scale_tau: tuple = (None, None)         #: gyro, accel scale-factor Gauss–Markov τ [s] (σ: the scale σ)

    def __post_init__(self):
        for nm in ("gyro_arw", "accel_vrw"):
            a = np.asarray(getattr(self, nm), dtype=float)
            if not (np.all(np.isfinite(a)) and np.all(a >= 0)):
                raise ValueError(f"{nm} must be finite values >= 0, got {getattr(self, nm)!r}")
        object.__setattr__(self, "scale_rw", tuple(self.scale_rw))
        object.__setattr__(self, "scale_tau", tuple(self.scale_tau))
        if len(self.scale_rw) != 2 or len(self.scale_tau) != 2:
            raise ValueError("scale_rw and scale_tau are (gyro, accel) pairs")


@dataclass(frozen=True, eq=False)
class FixHandling:
    """How the GNSS enters the filter: the antenna and the outages (any source), and how
    position/velocity fixes are applied (latency, lag policy, σ); the σ floors also bound
    the start's position and velocity σ from whatever fixes start the run."""

    lever_arm: tuple = (0.0, 0.0, 0.0)      #: IMU -> antenna, vehicle RFU axes [m]
    outages: tuple = ()                     #: ((start, length), ...) absolute times [s]
    fix_latency: float = 0.0                #: [s]
    lag: object = ExactReprocessing()       #: lag policy (sinslab.fusion.lag)
    use_velocity: bool = True
    fix_sigma: tuple | None = None          #: replaces every fix's σ north, east, up [m]
    fix_vel_sigma: tuple | None = None      #: replaces every fix velocity σ east, north, up [m/s]
    pos_sigma_floor: float = 0.05           #: fix σ floor [m] (timing, antenna phase centre)
    vel_sigma_floor: float = 0.05           #: [m/s]
    #: the fixes' time-correlated position error as Gauss-Markov states: None (white fixes),
    #: "auto" (measured from the record, sinslab.fusion.fix_noise; used where metre-level), or
    #: given: a FixErrorModel, (tau [s], (σE, σN, σU) correlated [m], (σE, σN, σU) white [m]),
    #: or that with the velocity error's (σE, σN, σU) [m/s] and correlation time [s] appended
    #: (sinslab.fusion.fix_noise.given_fix_error); fixes only
    fix_error: object = None
    #: inflate a fix's R where its innovation is beyond the 1 − robust χ² quantile (Chang 2014;
    #: sinslab.fusion.measurements.schedule.robust_R); None: every fix as stated
    robust: float | None = None
    #: the fixes' σ: "stated" (as the file gives them, floored) or "innovations" (floored at the
    #: long-run variance of the filter's own innovations, the run repeated until they agree:
    #: optimistic σ and errors that last; sinslab.fusion.fix_noise.innovation_noise)
    fix_noise: str = "stated"
    #: check each velocity fix against the position fixes over this trailing window [s] and
    #: raise its σ by the lasting velocity error they contradict
    #: (sinslab.fusion.fix_noise.velocity_check); None: no check
    velocity_check: float | None = None

    def __post_init__(self):
        object.__setattr__(self, "lever_arm", _lever("lever arm", self.lever_arm))
        if self.fix_noise not in FIX_NOISE:
            raise ValueError(f"fix_noise must be one of {', '.join(FIX_NOISE)}, got {self.fix_noise!r}")
        object.__setattr__(self, "outages", tuple(self.outages))
        for o in self.outages:
            s, ln = (o[2], o[1]) if o[0] == "periodic" else o
            if not (ln > 0 and math.isfinite(s)):
                raise ValueError(f"outage {s}:{ln}: length must be > 0")
        lat = float(self.fix_latency)
        if not (math.isfinite(lat) and lat >= 0):
            raise ValueError(f"fix latency must be >= 0 s, got {self.fix_latency}")
        _check_sigmas(self, ("fix_sigma", 3), ("fix_vel_sigma", 3))
        if self.fix_error is not None and not (isinstance(self.fix_error, str) and self.fix_error == "auto"):
            from sinslab.fusion.fix_noise import given_fix_error
            given_fix_error(self.fix_error)                 # a clear error now, not at the first fix
        if self.velocity_check is not None and not (math.isfinite(self.velocity_check) and self.velocity_check > 0):
            raise ValueError(f"velocity check window must be > 0 s, got {self.velocity_check}")


@dataclass(frozen=True, eq=False)
class StartSpec:
    """The initial attitude: levelling at rest or in motion, heading given or from the
    course, the in-motion alignment, and the attitude σ; the platform kind."""

    heading: float | None = None            #: initial heading, clockwise from north [rad]
    att_sigma: tuple = (1.0 * units.deg, 1.0 * units.deg, 5.0 * units.deg)  #: φE φN φU
    static_speed: float = 0.05              #: [m/s] below it the vehicle is at rest
    move_speed: float = 2.0                 #: [m/s] heading from the fix course above it
    heading_window: float = 1.0             #: [s] of motion above move_speed for the heading
    heading_straight: float = 2.0 * units.deg   #: largest spread of course − gyro heading in it [rad]
    heading_sigma_floor: float = 1.0 * units.deg  #: added (in quadrature) to the σ of that heading
    level_window: float = 10.0              #: [s] of fixes for levelling in motion (no initial rest)
    #: in-motion alignment over ``level_window`` s before the start where the gyros would
    #: carry the levelling there too long (``CARRY_LIMIT``); False: always carried
    motion_alignment: bool = True
    #: "auto" | "land" | "aircraft" | "marine" ("auto": from the fixes); an aircraft's heading
    #: is taken from its course only when flying, and aids of a wheeled vehicle need land
    platform: str = "auto"
    #: initial pitch and roll [rad] given (None: levelled at the rest or in motion)
    pitch: float | None = None
    roll: float | None = None
    #: the IMU point's initial position (lat [rad], lon [rad], h [m]) and ENU velocity [m/s]
    #: given (None: the fixes' at the start, the position moved from the antenna by the lever arm)
    init_position: tuple | None = None
    init_velocity: tuple | None = None
    #: their 1σ, east, north, up [m] and [m/s] (None: twice the σ of the fix nearest the start)
    init_position_sigma: tuple | None = None
    init_velocity_sigma: tuple | None = None
    #: the time [s] (the IMU's time base) a fully given attitude holds at (None: the first fix)
    init_time: float | None = None

    def __post_init__(self):
        if self.platform not in PLATFORMS:
            raise ValueError(f"platform must be one of {', '.join(PLATFORMS)}, got {self.platform!r}")
        for nm in ("heading", "pitch", "roll", "init_time"):
            v = getattr(self, nm)
            if v is not None and not math.isfinite(v):
                raise ValueError(f"{nm} must be finite, got {v}")
        for nm, n in (("init_position", 3), ("init_velocity", 3)):
            v = getattr(self, nm)
            if v is not None:
                a = np.asarray(v, dtype=float)
                if a.shape != (n,) or not np.all(np.isfinite(a)):
                    raise ValueError(f"{nm} must be {n} finite numbers, got {v!r}")
                object.__setattr__(self, nm, tuple(float(x) for x in a))
        _check_sigmas(self, ("init_position_sigma", 3), ("init_velocity_sigma", 3))
        if self.init_time is not None and not self.attitude_given:
            raise ValueError("a start time needs the whole attitude given (pitch, roll and heading): the "
                             "attitude found in the data holds where the data shows it")
        _check_positive(self, "heading_window", "heading_straight")
        _check_sigmas(self, ("att_sigma", 3))

    @property
    def attitude_given(self) -> bool:
        """Pitch, roll and heading all given: nothing of the attitude is found in the data."""
        return self.heading is not None and self.pitch is not None and self.roll is not None


@dataclass(frozen=True, eq=False)
class GridSpec:
    """The filter step and the pass: subsamples, and the recorded forward pass smoothed."""

    kf_dt: float = 0.02                     #: filter step [s]
    nsub: int = 2                           #: mechanization subsamples per update
    smooth: bool = False                    #: record the forward pass and smooth it (RTS)
    smooth_spill: str | None = None         #: folder for the smoother's record on disk (None: memory)
    spill: str | None = None                #: folder for the filter's per-epoch record on disk (None: memory)

    def __post_init__(self):
        _check_positive(self, "kf_dt")
        if isinstance(self.nsub, bool) or int(self.nsub) != self.nsub or not 1 <= self.nsub <= 5:
            raise ValueError(f"nsub (samples per update) must be an integer in 1..5, got {self.nsub!r}")


_GROUPS = {"errors": ErrorSpec, "fix": FixHandling, "start": StartSpec, "grid": GridSpec}
#: spec field name -> the :class:`NavOptions` group holding it
FIELD_GROUP = {f.name: g for g, cls in _GROUPS.items() for f in dataclasses.fields(cls)}


@dataclass(frozen=True, eq=False)
class NavOptions:
    """The run spec of :func:`sinslab.fusion.recorded.navigate_recorded`: its four specs,
    each already checked."""

    errors: ErrorSpec = ErrorSpec()
    fix: FixHandling = FixHandling()
    start: StartSpec = StartSpec()
    grid: GridSpec = GridSpec()

    def __post_init__(self):
        for g, cls in _GROUPS.items():
            if not isinstance(getattr(self, g), cls):
                raise TypeError(f"NavOptions.{g} must be a {cls.__name__}, got {type(getattr(self, g)).__name__}")

    @classmethod
    def of(cls, **fields):
        """The options with the named spec fields set (each spec made once)."""
        return cls().replace(**fields)

    def replace(self, **fields):
        """Another value with the named spec fields changed (only those specs remade)."""
        by = {}
        for k, v in fields.items():
            if k not in FIELD_GROUP:
                raise TypeError(f"NavOptions has no field {k!r}")
            by.setdefault(FIELD_GROUP[k], {})[k] = v
        return dataclasses.replace(self, **{g: dataclasses.replace(getattr(self, g), **kv)
                                            for g, kv in by.items()})

    def field(self, name):
        """The value of spec field ``name`` (whichever spec holds it)."""
        if name not in FIELD_GROUP:
            raise AttributeError(f"NavOptions has no field {name!r}")
        return getattr(getattr(self, FIELD_GROUP[name]), name)
