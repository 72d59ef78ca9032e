"""Run specs of the fusion compositions: frozen values, each checked once when it is made.

A composition (:func:`sinslab.fusion.loosely_coupled.loosely_coupled`, the driver) takes
these instead of long keyword lists; what they hold is already in SI units and of the
right shape, so nothing below re-parses or re-validates it. The app builds them at its
edge from its option and unit-string machinery.

- :class:`FilterGrid`: the filter step and how the driver walks the grid.
- :class:`InsSpec`: how one INS stream runs (subsamples, vertical channel, initial sensor
  compensation, start).
- :class:`FixSpec`: position (and velocity) fixes, their σ, arrivals, the antenna lever arm
  and the outages/windows that drop some of them.

The lag policy (:mod:`sinslab.fusion.lag`) is passed beside them as an object.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sinslab.core import units
from sinslab.fusion.measurements.schedule import robust_weighting

__all__ = ["FilterGrid", "InsSpec", "FixSpec", "DISCRETIZATIONS", "VERTICAL"]

#: discretisations of the continuous error model per filter step
DISCRETIZATIONS = ("series", "vanloan")
#: vertical channel of a fused INS stream
VERTICAL = ("free", "hold")


def _positive(name, v, *, zero=False):
    v = float(v)
    if not (math.isfinite(v) and (v >= 0 if zero else v > 0)):
        raise ValueError(f"{name} must be {'>= 0' if zero else '> 0'} s, got {v}")
    return v


def _vec3_or_none(name, v):
    return None if v is None else units.vec3(v, name, finite=True, readonly=True)


@dataclass(frozen=True)
class FilterGrid:
    """How the fusion driver walks the filter grid.

    Attributes
    ----------
    kf_dt : float
        Filter step [s]; a multiple of the stream's ``nsub * imu.dt``.
    max_block : float
        Longest stretch [s] the streams run in one compiled call.
    model_every : float
        Length [s] of the stretch the error model is evaluated for at once, along a
        look-ahead run of the streams (``<= kf_dt``: on the corrected path, every step).
    discretization : {"series", "vanloan"}
        Φ, Q_k of each step from F, G frozen at the epoch.
    lag_tol : float
        Tolerance [s] matching a lagged item to a stored epoch.
    model_eval : {"compiled", "numpy"}
        ``"compiled"``: F, G (and the series Φ, Q_k) from the compiled kernels of
        :mod:`sinslab.nav.errstate_kernels` and
        :func:`sinslab.estimation.linear.discretize_series_many` (models of
        :mod:`sinslab.nav.errstate`; other models use numpy); ``"numpy"``: the readable
        reference, ``model.matrices`` on :class:`~sinslab.nav.errstate.NavPoint` and
        :func:`~sinslab.estimation.kalman.discretize`. Equal to rounding.
    spill : str or path-like, optional
        A folder for the per-epoch record of the run (rows, estimates, σ, compensation,
        epoch times): memory-mapped ``.npy`` files there whose pages are let go as the
        run moves on, so a long run does not hold its record in memory (the same numbers
        either way). None: in memory.
    """

    kf_dt: float = 0.1
    max_block: float = 10.0
    model_every: float = 10.0
    discretization: str = "series"
    lag_tol: float = 1e-6
    model_eval: str = "compiled"
    spill: object = None

    def __post_init__(self):
        object.__setattr__(self, "kf_dt", _positive("kf_dt", self.kf_dt))
        object.__setattr__(self, "max_block", _positive("max_block", self.max_block))
        object.__setattr__(self, "model_every", _positive("model_every", self.model_every, zero=True))
        if self.discretization not in DISCRETIZATIONS:
            raise ValueError(f"discretization must be one of {DISCRETIZATIONS}, got {self.discretization!r}")
        object.__setattr__(self, "lag_tol", _positive("lag_tol", self.lag_tol))
        if self.model_eval not in ("compiled", "numpy"):
            raise ValueError(f"model_eval must be 'compiled' or 'numpy', got {self.model_eval!r}")


@dataclass(frozen=True)
class InsSpec:
    """How one live INS stream runs (:class:`sinslab.fusion.driver.LiveStream`).

    Attributes
    ----------
    nsub : int
        Mechanization subsamples per update (coning/sculling), 1..5.
    vertical : {"free", "hold"}
        ``"hold"``: the vertical channel is held to ``height`` at the IMU epochs.
    height : float, array_like (N+1,) or sinslab.nav.strapdown.HeldHeight, optional
        The held height [m] (``vertical="hold"``); its length is checked against the IMU
        record by the stream.
    gyro_bias, accel_bias : ndarray (3,), optional
        Initial sensor compensation [rad/s], [m/s²] (read-only arrays).
    start : int
        First IMU sample used (the stream starts at the end of sample ``start - 1``).
    t_start : float, optional
        Start time [s] if not that end time.
    """

    nsub: int = 2
    vertical: str = "free"
    height: object = None
    gyro_bias: np.ndarray | None = None
    accel_bias: np.ndarray | None = None
    start: int = 0
    t_start: float | None = None

    def __post_init__(self):
        if _whole(self.nsub) is None or not 1 <= self.nsub <= 5:
            raise ValueError(f"nsub (samples per update) must be an integer in 1..5, got {self.nsub!r}")
        object.__setattr__(self, "nsub", _whole(self.nsub))
        if self.vertical not in VERTICAL:
            raise ValueError(f"vertical must be 'free' or 'hold', got {self.vertical!r}")
        if self.vertical == "hold" and self.height is None:
            raise ValueError("vertical='hold' needs the height to hold")
        object.__setattr__(self, "gyro_bias", _vec3_or_none("gyro_bias", self.gyro_bias))
        object.__setattr__(self, "accel_bias", _vec3_or_none("accel_bias", self.accel_bias))
        if _whole(self.start) is None or self.start < 0:
            raise ValueError(f"start must be a sample index >= 0, got {self.start!r}")
        object.__setattr__(self, "start", _whole(self.start))
        if self.t_start is not None and not math.isfinite(self.t_start):
            raise ValueError(f"t_start must be finite, got {self.t_start}")


def _whole(v):
    """``v`` as an int when it is a whole number (not a bool), else None."""
    try:
        return None if isinstance(v, bool) or int(v) != v else int(v)
    except (TypeError, ValueError, OverflowError):
        return None


def _frozen(a):
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class FixSpec:
    """Position (and velocity) fixes of an antenna, checked once.

    Attributes
    ----------
    t : ndarray (J,)
        Validity times [s], finite and strictly increasing.
    pos : ndarray (J, 3) or (J, 2)
        Antenna positions ``[lat, lon, h]`` [rad, rad, m] (no height: a model with a
        2-state horizontal position block).
    sigma : ndarray (J, 3) or (J, 2)
        σ north, east[, up] [m] > 0 (a (3,)/(2,) value is broadcast to every fix).
    vel, vel_sigma : ndarray (J, 3), optional
        Antenna velocities ENU [m/s] and their σ (> 0; (3,) broadcast).
    arrive : ndarray (J,)
        Arrival times [s], never before the validity times (default ``t + latency``).
    latency : float
        Constant arrival delay [s] >= 0 when ``arrive`` is not given.
    lever_arm : ndarray (3,)
        IMU -> antenna in IMU body axes [m]; converted here once and held by the fix
        measurements.
    outages : tuple of (start, length)
        Fixes valid inside are dropped [s].
    windows : tuple of (start, end), optional
        Fixes are processed only at epochs inside these windows [s].
    lever_block : str, optional
        Name of a :func:`sinslab.nav.errstate.lever_arm` block of the model that estimates
        the antenna lever arm (``lever_arm`` is then the value its states are errors of);
        None: the lever arm is known.
    robust : RobustWeighting, float or str, optional
        Down-weight a fix whose innovation the filter cannot explain
        (:class:`sinslab.fusion.measurements.schedule.RobustWeighting`: a probability is
        Chang's whole-fix rule, ``robust_R`` of the measurement schedule;
        ``"huber[:k0]"``, ``"igg3[:k0:k1]"`` row weights); held as a ``RobustWeighting``.
    """

    t: np.ndarray
    pos: np.ndarray
    sigma: np.ndarray
    vel: np.ndarray | None = None
    vel_sigma: np.ndarray | None = None
    arrive: np.ndarray | None = None
    latency: float = 0.0
    lever_arm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    outages: tuple = ()
    windows: tuple | None = None
    lever_block: str | None = None
    robust: object = None

    def __post_init__(self):
        t = np.atleast_1d(np.array(self.t, dtype=float))
        J = t.size
        pos = np.array(self.pos, dtype=float).reshape(J, -1) if J else \
            np.array(self.pos, dtype=float).reshape(0, np.shape(self.pos)[-1] if np.ndim(self.pos) == 2 else 3)
        if pos.ndim != 2 or pos.shape[0] != J or pos.shape[1] not in (2, 3):
            raise ValueError(f"fix positions must have shape ({J}, 3) or ({J}, 2) for {J} fix times, "
                             f"got {np.shape(self.pos)}")
        sig = np.asarray(self.sigma, dtype=float)
        sig = np.array(np.broadcast_to(sig, (J, sig.shape[-1]))[:, :pos.shape[1]])
        lat = float(self.latency)
        if not (math.isfinite(lat) and lat >= 0):
            raise ValueError(f"fix latency must be >= 0 s, got {self.latency}")
        arrive = t + lat if self.arrive is None else np.array(self.arrive, dtype=float)
        vel = vsig = None
        if self.vel is not None:
            vel = np.array(self.vel, dtype=float).reshape(J, 3)
            vsig = np.array(np.broadcast_to(np.asarray(self.vel_sigma, dtype=float), (J, 3)))
        if J:
            if not (np.all(np.isfinite(t)) and np.all(np.isfinite(pos))):
                raise ValueError("fix times/positions contain NaN/inf")
            if np.any(np.diff(t) <= 0):
                raise ValueError("fix times must be strictly increasing")
            if np.any(~(sig > 0)) or (vel is not None and np.any(~(vsig > 0))):
                raise ValueError("fix_sigma and vel_sigma must be > 0")
            if arrive.shape != (J,) or np.any(~(arrive >= t)):
                raise ValueError("fix arrival times must not precede the validity times (fix_lag >= 0)")
        lever = np.array(self.lever_arm, dtype=float).reshape(-1)
        if lever.shape != (3,) or not np.all(np.isfinite(lever)):
            raise ValueError(f"lever arm must be 3 finite numbers [m], got {self.lever_arm!r}")
        outs = tuple((float(s), float(ln)) for s, ln in self.outages)
        for s, ln in outs:
            if not (ln > 0 and math.isfinite(s)):
                raise ValueError(f"outage {s}:{ln}: length must be > 0")
        win = None if self.windows is None else tuple((float(a), float(b)) for a, b in self.windows)
        for name, v in (("t", t), ("pos", pos), ("sigma", sig), ("vel", vel), ("vel_sigma", vsig),
                        ("arrive", arrive), ("lever_arm", lever)):
            object.__setattr__(self, name, None if v is None else _frozen(v))
        object.__setattr__(self, "latency", lat)
        object.__setattr__(self, "robust", robust_weighting(self.robust))
        object.__setattr__(self, "outages", outs)
        object.__setattr__(self, "windows", win)

    def __len__(self):
        return self.t.size

    @property
    def n_pos(self) -> int:
        """Components of a position fix (3, or 2 without height)."""
        return self.pos.shape[1]
