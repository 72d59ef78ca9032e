"""Run specs of :func:`sinslab.fusion.recorded.navigate_recorded`: five cohesive frozen
values, each checked once when it is made (SI units), bundled in :class:`NavOptions`.

- :class:`ErrorSpec`: the IMU's error model and noise (bias, Gauss–Markov and scale-factor
  states, and whether the initial rest calibrates the bias and the white noise).
- :class:`FixHandling`: how the position/velocity fixes (or raw GNSS) enter the filter:
  lever arm, outages, latency, lag policy, σ overrides and floors, lever states.
- :class:`AidingSpec`: ZUPT/ZARU, the non-holonomic constraint and the vehicle frame, the
  odometer, the platform kind and the innovation gate.
- :class:`StartSpec`: the initial attitude and its σ (levelling, heading from the course,
  in-motion alignment).
- :class:`GridSpec`: the filter step, subsamples, and the recorded/smoothed pass.

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

__all__ = ["ErrorSpec", "FixHandling", "AidingSpec", "StartSpec", "GridSpec", "NavOptions", "PLATFORMS"]

#: platform kinds of :attr:`AidingSpec.platform`
PLATFORMS = ("auto", "land", "aircraft", "marine")


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
    """How the fixes (or the raw GNSS) enter the filter."""

    lever_arm: tuple = (0.0, 0.0, 0.0)      #: IMU -> antenna, vehicle RFU axes [m]
    outages: tuple = ()                     #: ((start, length), ...) absolute times [s]
    fix_latency: float = 0.0                #: [s]
    lag: object = ExactReprocessing()       #: lag policy (sinslab.fusion.lag)
    use_velocity: bool = True
    fix_sigma: tuple | None = None          #: replaces every fix's σ north, east, up [m]
    fix_vel_sigma: tuple | None = None      #: replaces every fix velocity σ east, north, up [m/s]
    pos_sigma_floor: float = 0.05           #: fix σ floor [m] (timing, antenna phase centre)
    vel_sigma_floor: float = 0.05           #: [m/s]
    estimate_lever: bool = False            #: estimate the antenna lever arm (3 states)
    lever_sigma: float = 1.0                #: its initial σ per axis [m]
    #: the fixes' time-correlated position error as Gauss-Markov states: None (white fixes),
    #: "auto" (measured from the record, sinslab.fusion.fix_noise; used where metre-level), or
    #: (tau [s], (σE, σN, σU) correlated [m], (σE, σN, σU) white [m])
    fix_error: object = None
    #: inflate a fix's R where its innovation is beyond the 1 − robust χ² quantile (Chang 2014;
    #: sinslab.fusion.measurements.schedule.robust_R); None: every fix as stated
    robust: float | None = None
    #: raw GNSS (sinslab.fusion.tightly_coupled.RawGnss): its pseudoranges and range rates
    #: replace the fixes in the filter (tightly coupled); the fixes then only start it
    gnss_raw: object = None

    def __post_init__(self):
        object.__setattr__(self, "lever_arm", _lever("lever arm", self.lever_arm))
        object.__setattr__(self, "outages", tuple(self.outages))
        for o in self.outages:
            s, ln = (o[2], o[1]) if o[0] == "periodic" else o
            if not (ln > 0 and math.isfinite(s)):
                raise ValueError(f"outage {s}:{ln}: length must be > 0")
        lat = float(self.fix_latency)
        if not (math.isfinite(lat) and lat >= 0):
            raise ValueError(f"fix latency must be >= 0 s, got {self.fix_latency}")
        _check_positive(self, "lever_sigma")
        _check_sigmas(self, ("fix_sigma", 3), ("fix_vel_sigma", 3))


@dataclass(frozen=True, eq=False)
class AidingSpec:
    """Aiding beyond the fixes: rest (ZUPT/ZARU), the wheeled vehicle (NHC, its frame, the
    odometer) and the innovation gate of every such update."""

    zupt: str | None = None                 #: None | "auto" (IMU detector) | "flags" (rest_flags)
    zupt_sigma: float = 0.02                #: [m/s]
    zaru: bool = False                      #: zero angular rate on the same intervals
    zaru_sigma: float | None = None         #: [rad/s]; default 2 × gyro white noise / √kf_dt
    rest_flags: tuple | None = None         #: (t (N,), flags (N,) bool) of a log's rest column
    rest_min: float = 2.0                   #: shortest rest interval used [s]
    nhc_sigma: tuple | None = None          #: (lateral, vertical) [m/s]: non-holonomic constraint
    nhc_lever_arm: tuple = (0.0, 0.0, 0.0)  #: IMU -> rear-axle centre, vehicle RFU [m]
    #: body pitch on the suspension per longitudinal acceleration [rad per m/s²]: the vertical
    #: NHC row's σ grows with it (0.30°/(m/s²): measured on a car against its RTK fixes,
    #: docs/recorded-data.md); 0: the fixed σ alone
    nhc_pitch_gradient: float = 0.3 * units.deg
    nhc_correlation_time: float = 1.0       #: [s] that suspension pitch lasts (a manoeuvre)
    vehicle_mount: tuple | None = None      #: IMU body in the vehicle frame [pitch, roll, yaw] [rad]
    #: (what is left after the reader's mount: a case bolted 1-2° off the car's axes)
    estimate_vehicle: bool = False          #: states for the mount's pitch and yaw and the NHC lever
    vehicle_mount_sigma: float = 2.0 * units.deg   #: their initial σ [rad]
    nhc_lever_sigma: float = 0.5            #: [m] per axis
    platform: str = "auto"                  #: "auto" | "land" | "aircraft" | "marine": NHC and the
    #: odometer assume a wheeled land vehicle and are refused otherwise ("auto": from the fixes)
    aiding_dt: float = 0.1                  #: ZUPT/NHC applied every this [s] (ZARU: every epoch)
    aid_gate: float | None = 1e-6           #: false-rejection probability of the innovation gate of
    #: every ZUPT/ZARU/NHC/odometer update (:class:`~sinslab.fusion.measurements.InnovationGate`); None: no gate
    odometer: object = None                 #: wheel speeds (sinslab.data.odometer.OdometerSeries)
    odometer_sigma: float = 0.1             #: [m/s] per update (noise and quantisation)
    odometer_lever: tuple = (0.0, 0.0, 0.0)  #: IMU -> wheel point, vehicle RFU [m]
    odometer_scale_sigma: float = 0.02      #: initial 1σ of the odometer scale factor [-]
    odometer_rate: float = 10.0             #: odometer updates per second [Hz]

    def __post_init__(self):
        if self.zupt not in (None, "auto", "flags"):
            raise ValueError(f"zupt must be None, 'auto' or 'flags', got {self.zupt!r}")
        if self.zupt == "flags" and self.rest_flags is None:
            raise ValueError("zupt='flags' needs a rest-flag column (column map key 'stationary')")
        if self.zaru and self.zupt is None:
            raise ValueError("ZARU runs on the rest intervals of ZUPT: choose zupt='auto' or 'flags'")
        if self.platform not in PLATFORMS:
            raise ValueError(f"platform must be one of {', '.join(PLATFORMS)}, got {self.platform!r}")
        if self.estimate_vehicle and self.nhc_sigma is None:
            raise ValueError("the vehicle mount and NHC lever states need the NHC (nhc_sigma)")
        if self.aid_gate is not None and not (0 < self.aid_gate < 1):
            raise ValueError(f"aid_gate must be a probability in (0, 1) or None, got {self.aid_gate}")
        if not (math.isfinite(self.nhc_pitch_gradient) and self.nhc_pitch_gradient >= 0):
            raise ValueError(f"nhc_pitch_gradient must be >= 0, got {self.nhc_pitch_gradient}")
        _check_positive(self, "zupt_sigma", "aiding_dt", "nhc_correlation_time")
        _check_sigmas(self, ("nhc_sigma", 2))
        object.__setattr__(self, "nhc_lever_arm", _lever("NHC lever arm", self.nhc_lever_arm))
        object.__setattr__(self, "odometer_lever", _lever("odometer lever arm", self.odometer_lever))
        if not (self.odometer_sigma > 0 and self.odometer_rate > 0):
            raise ValueError("odometer σ and rate must be > 0")


@dataclass(frozen=True, eq=False)
class StartSpec:
    """The initial attitude: levelling at rest or in motion, heading given or from the
    course, the in-motion alignment, and the attitude σ."""

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

    def __post_init__(self):
        if self.heading is not None and not math.isfinite(self.heading):
            raise ValueError(f"heading must be finite, got {self.heading}")
        _check_positive(self, "heading_window", "heading_straight")
        _check_sigmas(self, ("att_sigma", 3))


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


_GROUPS = {"errors": ErrorSpec, "fix": FixHandling, "aiding": AidingSpec, "start": StartSpec, "grid": GridSpec}
#: spec field name -> the :class:`NavOptions` group holding it
FIELD_GROUP = {f.name: g for g, cls in _GROUPS.items() for f in dataclasses.fields(cls)}


@dataclass(frozen=True, eq=False)
class NavOptions:
    """The run spec of :func:`sinslab.fusion.recorded.navigate_recorded`: its five specs,
    each already checked."""

    errors: ErrorSpec = ErrorSpec()
    fix: FixHandling = FixHandling()
    aiding: AidingSpec = AidingSpec()
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
