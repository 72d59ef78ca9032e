"""Measurement objects of the fusion driver: what is measured, when it is available, and its
linearisation ``(z, H, R)`` against the navigation rows of the streams.

A measurement is any object with the methods of :class:`Measurement`. It owns its time
stamps: each of its records (an *item*) is valid at ``t_valid`` and arrives (can be
processed) at ``t_arrive >= t_valid``. The driver (:mod:`sinslab.fusion.driver`) asks
:meth:`Measurement.epochs` once for the filter epochs at which items arrive, stops its
compiled blocks there, and calls :meth:`Measurement.matrices` with an :class:`Epoch` that
names the item and carries the navigation rows the item is to be compared with (those of
its validity epoch for a lag-aware update, those of the arrival epoch otherwise).

Conventions (those of :mod:`sinslab.nav.errstate`): errors are computed minus true;
``φ`` is the misalignment of the computed frame, ``C_b^{n'} = (I − φ×) C_b^n``;
``δv`` ENU [m/s]; ``δp = [δL, δλ, δh]`` [rad, rad, m] (``[δL, δλ]`` for a horizontal
model). Position measurements are metres north, east[, up].
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E

__all__ = ["Measurement", "NavRow", "Epoch", "Grid", "Timed", "PositionFix", "VelocityFix", "Stack",
           "InsDifference", "arrival_epochs", "ZeroVelocity", "ZeroRate", "NonHolonomic",
           "BodyVelocity", "Odometer", "LeverPositionFix", "LeverVelocityFix", "vehicle_from_body",
           "InnovationGate", "add_rate_H"]


@dataclass(frozen=True)
class Grid:
    """The filter epochs ``t_k = t0 + k T``, k = 0..n.

    Attributes
    ----------
    t0 : float
        First epoch [s].
    T : float
        Filter step [s].
    n : int
        Number of steps.
    """

    t0: float
    T: float
    n: int

    @property
    def t(self):
        """Epoch times [s], shape (n + 1,)."""
        return self.t0 + self.T * np.arange(self.n + 1)

    def epoch_at_or_after(self, t):
        """Index of the first epoch at or after ``t`` [s] (array or float; 1e-6 T slack)."""
        return np.ceil((np.asarray(t, dtype=float) - self.t0) / self.T - 1e-6).astype(np.int64)


@dataclass(frozen=True)
class NavRow:
    """Named accessors of one stream's navigation row at one epoch.

    Attributes
    ----------
    row : ndarray, shape (10,)
        The raw row ``[q0..q3, vE, vN, vU, lat, lon, h]`` (quaternion of C_b^n).
    omega_b : ndarray, shape (3,)
        Compensated body rate ω_ib^b of the last step to this epoch [rad/s].
    f_b : ndarray, shape (3,)
        Compensated specific force of that step in body axes [m/s²].
    """

    row: np.ndarray
    omega_b: np.ndarray
    f_b: np.ndarray

    @property
    def quat(self):
        """Quaternion of C_b^n (4,)."""
        return self.row[:4]

    @property
    def C_bn(self):
        """Attitude C_b^n, body -> ENU (3, 3)."""
        return A.quat_to_dcm(self.row[:4])

    @property
    def vel(self):
        """Velocity ENU [m/s] (3,)."""
        return self.row[4:7]

    @property
    def lat(self):
        """Latitude [rad]."""
        return self.row[7]

    @property
    def lon(self):
        """Longitude [rad]."""
        return self.row[8]

    @property
    def h(self):
        """Height [m]."""
        return self.row[9]

    @property
    def pos(self):
        """``[lat, lon, h]`` [rad, rad, m] (3,)."""
        return self.row[7:10]


@dataclass(frozen=True)
class Epoch:
    """What a measurement sees when the driver asks for its matrices.

    Attributes
    ----------
    t : float
        Absolute time [s] the navigation rows are taken as valid at.
    k : int
        Filter epoch index of those rows.
    streams : tuple of NavRow
        One row per stream, in the driver's stream order.
    layout : sinslab.nav.errstate.StateLayout
        Error-state layout of the filter.
    n : int
        Number of states.
    item : int
        The measurement record to apply (one of those :meth:`Measurement.epochs` returned).
    prior : (x (n,), P (n, n)) or None
        The filter's estimate before this update, for measurements that gate their rows
        on the innovation (given for items applied on arrival; None for lagged items).
    """

    t: float
    k: int
    streams: tuple
    layout: object
    n: int
    item: int = 0
    prior: tuple | None = None


class Measurement(Protocol):
    """Protocol of a measurement the driver applies."""

    def epochs(self, grid: Grid) -> dict:
        """``{arrival epoch index: [items, in processing order]}`` on the filter epochs
        ``grid``; items that do not arrive inside the run are left out."""

    def times(self, item) -> tuple:
        """``(t_valid, t_arrive)`` [s] of an item."""

    def matrices(self, ep: Epoch):
        """``(z (m,), H (m, n), R (m,) variances or (m, m))``, or None (nothing to apply)."""


def arrival_epochs(t_valid, t_arrive, grid, *, outages=(), windows=None):
    """Arrival epochs of time-stamped records: the first filter epoch at or after each
    arrival; records arriving after the run, valid inside an outage ``(start, length)``
    [s], or processed outside every window ``(start, end)`` [s] are dropped.

    Returns
    -------
    dict
        ``{epoch index: [record indices]}``.
    """
    t_valid = np.asarray(t_valid, dtype=float)
    n_ep = grid.n
    t_ep = grid.t
    e_arr = grid.epoch_at_or_after(t_arrive)
    keep = e_arr <= n_ep
    for s, ln in outages:
        keep &= ~((t_valid >= s) & (t_valid < s + ln))
    if windows is not None:
        w = np.asarray(windows, dtype=float).reshape(-1, 2)
        te = t_ep[np.minimum(e_arr, n_ep)]
        keep &= ((te[:, None] >= w[:, 0] - 1e-9) & (te[:, None] <= w[:, 1] + 1e-9)).any(1)
    out = {}
    for j in np.flatnonzero(keep):
        out.setdefault(int(e_arr[j]), []).append(int(j))
    return out


class Timed:
    """Time stamps and schedule shared by the fix measurements (``t_valid``, ``t_arrive``,
    outages and windows: :func:`arrival_epochs`); a measurement of time-stamped records
    subclasses it and calls ``_init_times``."""

    def _init_times(self, t_valid, t_arrive, outages, windows):
        self.t_valid = np.atleast_1d(np.asarray(t_valid, dtype=float))
        self.t_arrive = (self.t_valid.copy() if t_arrive is None
                         else np.atleast_1d(np.asarray(t_arrive, dtype=float)))
        if self.t_arrive.shape != self.t_valid.shape:
            raise ValueError(f"{len(self.t_arrive)} arrival times for {len(self.t_valid)} fixes")
        self.outages = tuple(outages)
        self.windows = windows

    def __len__(self):
        return self.t_valid.size

    def epochs(self, grid):
        return arrival_epochs(self.t_valid, self.t_arrive, grid, outages=self.outages,
                              windows=self.windows)

    def times(self, item):
        return float(self.t_valid[item]), float(self.t_arrive[item])


class PositionFix(Timed):
    """Position fixes of an antenna (2-D or 3-D) against one stream.

    ``z = [(L − L_fix)(R_M+h), (λ − λ_fix)(R_N+h)cosL, h − h_fix] − v_ant·Δt``
    (north, east, up [m]; the fix extrapolated from its validity time to the epoch with
    the antenna velocity, Δt = t_epoch − t_valid), with the lever arm ``l`` (IMU ->
    antenna, body axes) added as ``+ C_b^n l`` and in H as ``(C_b^n l)×`` on φ (rows
    reordered north, east, up). The antenna velocity is ``v + C_b^n (ω_ib^b × l)``.

    Parameters
    ----------
    t_valid : array_like, shape (J,)
        Validity times [s].
    pos : array_like, shape (J, 3) or (J, 2)
        ``[lat, lon, h]`` [rad, rad, m]; ``(J, 2)`` only for a 2-state position block.
    sigma : array_like, shape (J, m) or (m,)
        Standard deviations north, east[, up] [m].
    t_arrive : array_like, shape (J,), optional
        Arrival times [s] (default: the validity times).
    lever_arm : array_like (3,), optional
        IMU -> antenna in body axes [m].
    outages, windows
        See :func:`arrival_epochs`.
    stream : int
        Index of the stream the fix is compared with.
    """

    def __init__(self, t_valid, pos, sigma, *, t_arrive=None, lever_arm=None, outages=(),
                 windows=None, stream=0):
        self._init_times(t_valid, t_arrive, outages, windows)
        self.pos = np.asarray(pos, dtype=float)
        J = self.t_valid.size
        if self.pos.ndim != 2 or self.pos.shape[0] != J or self.pos.shape[1] not in (2, 3):
            raise ValueError(f"fix positions must have shape ({J}, 3) or ({J}, 2), got {self.pos.shape}")
        sigma = np.asarray(sigma, dtype=float)
        self.sigma = np.broadcast_to(sigma, (J, sigma.shape[-1]))
        lever = None if lever_arm is None else np.asarray(lever_arm, dtype=float).reshape(3)
        self.lever = None if (lever is None or not np.any(lever)) else lever
        self.stream = int(stream)

    def size(self, layout):
        return 3 if layout.slice("dp").stop - layout.slice("dp").start == 3 else 2

    def antenna(self, nr: NavRow):
        """``(C_b^n, C_b^n l, v_ant, C_b^n (ω×l))`` of a row (lever terms None without a lever arm)."""
        if self.lever is None:
            return None, None, nr.vel, None
        C = nr.C_bn
        Cl = C @ self.lever
        vlev = C @ np.cross(nr.omega_b, self.lever)
        return C, Cl, nr.vel + vlev, vlev

    def matrices(self, ep: Epoch):
        j = ep.item
        lay = ep.layout
        nr = ep.streams[self.stream]
        s_pos = lay.slice("dp")
        n_z = self.size(lay)
        lat, lon, h = nr.lat, nr.lon, nr.h
        rm, rn = E.radii(lat, h)
        rm, rnc = float(rm), float(rn) * math.cos(lat)
        C, Cl, v_ant, _ = self.antenna(nr)
        z = np.empty(n_z)
        H = np.zeros((n_z, ep.n))
        if Cl is not None:
            H[0:3, lay.slice("phi")] = A.skew(Cl)[[1, 0, 2]][:n_z]
        dtf = ep.t - self.t_valid[j]                 # fix extrapolated to the epoch
        dlon = float(A.wrap_pi(lon - self.pos[j, 1]))
        z[0] = (lat - self.pos[j, 0]) * rm - v_ant[1] * dtf
        z[1] = dlon * rnc - v_ant[0] * dtf
        H[0, s_pos.start] = rm
        H[1, s_pos.start + 1] = rnc
        if n_z == 3:
            z[2] = (h - self.pos[j, 2]) - v_ant[2] * dtf
            H[2, s_pos.start + 2] = 1.0
        if Cl is not None:
            z[0:n_z] += Cl[[1, 0, 2]][:n_z]
        return z, H, self.sigma[j, :n_z] ** 2


class VelocityFix(Timed):
    """Velocity fixes of an antenna (ENU, 3 components) against one stream.

    ``z = v + C_b^n (ω_ib^b × l) − v_fix`` [m/s]; ``H`` has ``I`` on δv and, with a lever
    arm, ``(C_b^n (ω×l))×`` on φ and ``−C_b^n (l×) ∂δω/∂x`` on every block feeding the
    gyro compensation (bias, Gauss–Markov, scale factors: :func:`add_rate_H`).

    Parameters
    ----------
    t_valid : array_like, shape (J,)
    vel : array_like, shape (J, 3)
        ENU [m/s].
    sigma : array_like, shape (J, 3) or (3,)
        [m/s].
    t_arrive, lever_arm, outages, windows, stream
        As in :class:`PositionFix`.
    """

    def __init__(self, t_valid, vel, sigma, *, t_arrive=None, lever_arm=None, outages=(),
                 windows=None, stream=0):
        self._init_times(t_valid, t_arrive, outages, windows)
        J = self.t_valid.size
        self.vel = np.asarray(vel, dtype=float).reshape(J, 3)
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (J, 3))
        lever = None if lever_arm is None else np.asarray(lever_arm, dtype=float).reshape(3)
        self.lever = None if (lever is None or not np.any(lever)) else lever
        self.stream = int(stream)

    def matrices(self, ep: Epoch):
        j = ep.item
        lay = ep.layout
        nr = ep.streams[self.stream]
        v_ant = nr.vel
        H = np.zeros((3, ep.n))
        H[:, lay.slice("dv")] = np.eye(3)
        if self.lever is not None:
            C = nr.C_bn
            vlev = C @ np.cross(nr.omega_b, self.lever)
            v_ant = v_ant + vlev
            H[:, lay.slice("phi")] = A.skew(vlev)
            add_rate_H(H, lay, -C @ A.skew(self.lever), nr.omega_b)
        return v_ant - self.vel[j], H, self.sigma[j] ** 2


class Stack:
    """Several measurements on the same schedule applied as one update (components in
    the order given); the schedule and time stamps are those of the first."""

    def __init__(self, *parts):
        if not parts:
            raise ValueError("Stack needs at least one measurement")
        self.parts = parts

    def epochs(self, grid):
        return self.parts[0].epochs(grid)

    def times(self, item):
        return self.parts[0].times(item)

    def matrices(self, ep: Epoch):
        zs, Hs, Rs = [], [], []
        for p in self.parts:
            r = p.matrices(ep)
            if r is None:
                continue
            z, H, R = r
            R = np.asarray(R, dtype=float)
            if R.ndim == 2:
                R = np.diag(R)
            zs.append(z)
            Hs.append(H)
            Rs.append(R)
        if not zs:
            return None
        return np.concatenate(zs), np.vstack(Hs), np.concatenate(Rs)


class InsDifference(Timed):
    """The difference of two INS streams on one carrier (stream 0 minus stream 1).

    ``z = [L1 − Lk, λ1 − λk, vE1 − vEk, vN1 − vNk]`` [rad, rad, m/s, m/s] against a
    :class:`sinslab.nav.errstate.DifferenceModel` layout: ``H`` picks ``[δL, δλ]_1k`` of the
    ``dp`` block and ``[δvE, δvN]_1k`` of the ``dv`` block (the differences of the two
    INS errors, computed − true, are the differences of their outputs since both see the
    same carrier). A lever arm ``l`` from IMU 1 to IMU k (body axes of IMU 1) is removed:
    the position of IMU k is shifted back by ``C_b1^n l`` and its velocity by
    ``C_b1^n (ω_ib1^b × l)``; the resulting φ terms (first order) go into H on the
    ``phi`` block (``∂z/∂φ_1``, exact for the difference core whose φ block is ``φ_1 − φ_k``
    only when IMU k's attitude error equals IMU 1's; give ``lever_arm=None`` when the
    IMUs are co-located).

    Parameters
    ----------
    t : array_like, shape (J,)
        Times [s] at which the difference is formed (filter epochs, available at once).
    sigma : array_like, shape (4,) or (J, 4)
        Standard deviations [rad, rad, m/s, m/s].
    lever_arm : array_like (3,), optional
        IMU 1 -> IMU k in IMU 1 body axes [m].
    streams : (int, int)
        The two streams (default 0 and 1).
    windows : sequence of (start, end) [s], optional
        Form the difference only at epochs inside these windows.
    """

    def __init__(self, t, sigma, *, lever_arm=None, streams=(0, 1), windows=None):
        self._init_times(t, None, (), windows)
        J = self.t_valid.size
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (J, 4))
        lever = None if lever_arm is None else np.asarray(lever_arm, dtype=float).reshape(3)
        self.lever = None if (lever is None or not np.any(lever)) else lever
        self.streams = tuple(int(s) for s in streams)

    def matrices(self, ep: Epoch):
        j = ep.item
        lay = ep.layout
        a, b = (ep.streams[i] for i in self.streams)
        z = np.empty(4)
        H = np.zeros((4, ep.n))
        lat_k, lon_k = b.lat, b.lon
        vk = b.vel[:2]
        if self.lever is not None:
            C1 = a.C_bn
            d = C1 @ self.lever                        # IMU 1 -> IMU k, ENU [m]
            rm, rn = E.radii(a.lat, a.h)
            rm, rnc = float(rm), float(rn) * math.cos(a.lat)
            lat_k = lat_k - d[1] / rm
            lon_k = lon_k - d[0] / rnc
            vlev = C1 @ np.cross(a.omega_b, self.lever)
            vk = vk - vlev[:2]
            # the lever is removed with the computed attitude, d' = (I − φ×) d, so z
            # gains −φ×d = (d×) φ (north, east of position; likewise of velocity)
            H[0, lay.slice("phi")] = A.skew(d)[1] / rm
            H[1, lay.slice("phi")] = A.skew(d)[0] / rnc
            H[2:4, lay.slice("phi")] = A.skew(vlev)[0:2]
        z[0] = a.lat - lat_k
        z[1] = A.wrap_pi(a.lon - lon_k)
        z[2:4] = a.vel[:2] - vk
        sp, sv = lay.slice("dp"), lay.slice("dv")
        H[0, sp.start] = 1.0
        H[1, sp.start + 1] = 1.0
        H[2, sv.start] = 1.0
        H[3, sv.start + 1] = 1.0
        return z, H, self.sigma[j] ** 2


# ------------------------------------------------------------------ aiding measurements
def vehicle_from_body(mount):
    """The vehicle-from-body mount ``C_b^v`` (3, 3): IMU body axes -> vehicle axes (both
    RFU: x right, y forward, z up) of the wheel constraints (the sensor-to-body mount of
    recorded data is :func:`sinslab.data.frames.sensor_to_body`).

    ``mount`` is None (aligned), a (3, 3) rotation matrix ``C_b^v`` or Euler angles
    ``[pitch, roll, yaw]`` [rad] of the IMU body frame in the vehicle frame (the
    :func:`sinslab.core.attitude.euler_to_dcm` convention with v in place of n).
    """
    if mount is None:
        return np.eye(3)
    m = np.asarray(mount, dtype=float)
    if m.shape == (3,):
        return A.euler_to_dcm(m)
    if m.shape == (3, 3):
        if not np.allclose(m @ m.T, np.eye(3), atol=1e-9) or np.linalg.det(m) < 0:
            raise ValueError("mount matrix C_b^v must be a proper rotation")
        return m
    raise ValueError(f"mount must be 3 Euler angles or a 3x3 matrix, got shape {m.shape}")


def add_rate_H(H, lay, M, omega_b):
    """Add ``M ∂δω_ib^b/∂x`` to ``H`` for every block that feeds the gyro compensation
    (:attr:`sinslab.nav.errstate.Block.feeds`): a bias or Gauss–Markov block enters the
    compensated rate as ``δω = x``, a scale block as ``δω = diag(ω) x``."""
    for b in lay.blocks:
        feeds = getattr(b, "feeds", None)
        if feeds not in ("gyro_bias", "gyro_scale"):
            continue
        sl = lay.slice(b.name)
        for i, a in enumerate(b.axes):
            ax = "xyz".index(a)
            H[:, sl.start + i] += M[:, ax] * (omega_b[ax] if feeds == "gyro_scale" else 1.0)


def _intervals(intervals):
    if intervals is None:
        return None
    w = np.asarray(intervals, dtype=float).reshape(-1, 2)
    if not np.all(np.isfinite(w)) or np.any(w[:, 1] < w[:, 0]):
        raise ValueError("intervals must be finite (start, end) pairs [s] with end >= start")
    return w


class InnovationGate:
    """Reject an update whose innovation the filter's own covariance cannot explain.

    An aiding measurement is an assumption (the vehicle is at rest, does not slide
    sideways); where it is false its innovation ``ν = z − H x`` is far outside
    ``S = H P Hᵀ + R``. The update is applied only when ``νᵀ S⁻¹ ν`` is at most the
    ``1 − p`` quantile of χ² with ``m`` degrees of freedom (``m`` = rows of ``z``);
    a consistent measurement is rejected with probability ``p``.

    Attributes
    ----------
    p : float
        False-rejection probability per update.
    rejected : list of float
        Times [s] of the rejected updates.
    passed : int
        Number of updates let through.
    """

    def __init__(self, p=1e-6):
        if not (0 < p < 1):
            raise ValueError(f"gate probability must be in (0, 1), got {p}")
        self.p = float(p)
        self.rejected = []
        self.passed = 0
        self._limit = {}

    def limit(self, m):
        """χ² threshold for ``m`` rows."""
        if m not in self._limit:
            from scipy.stats import chi2
            self._limit[m] = float(chi2.isf(self.p, m))
        return self._limit[m]

    def passes(self, x, P, z, H, R, t):
        """True when the update ``(z, H, R)`` against the prior ``x, P`` lies inside the
        gate; a rejection is recorded at ``t``."""
        z = np.atleast_1d(np.asarray(z, dtype=float))
        H = np.atleast_2d(H)
        R = np.asarray(R, dtype=float)
        nu = z - H @ x
        S = H @ P @ H.T + (np.diag(np.broadcast_to(R, z.shape)) if R.ndim < 2 else R)
        try:
            nis = float(nu @ np.linalg.solve(S, nu))
        except np.linalg.LinAlgError:
            nis = math.inf
        if nis <= self.limit(z.size):
            self.passed += 1
            return True
        self.rejected.append(float(t))
        return False


class _OnEpochs:
    """Items are filter epochs (the item is the epoch index), optionally restricted to
    time intervals and thinned to every ``every``-th epoch; available at once. ``gate``:
    an :class:`InnovationGate` (or its false-rejection probability) the driver applies
    before each update (None: every update applied)."""

    def _init_sched(self, intervals, every, stream, gate=None):
        self.intervals = _intervals(intervals)
        self.every = int(every)
        if self.every < 1:
            raise ValueError(f"every must be >= 1, got {every}")
        self.stream = int(stream)
        self._t = None
        self.gate = gate if (gate is None or isinstance(gate, InnovationGate)) else InnovationGate(gate)

    def _keep(self, t):
        keep = np.ones(t.size, dtype=bool)
        keep[0] = False                                   # no step rate before epoch 0
        if self.intervals is not None:
            w = self.intervals
            keep &= ((t[:, None] >= w[:, 0] - 1e-9) & (t[:, None] <= w[:, 1] + 1e-9)).any(1)
        return keep

    def epochs(self, grid):
        t = grid.t
        self._t = t
        idx = np.flatnonzero(self._keep(t))[::self.every]
        return {int(k): [int(k)] for k in idx}

    def times(self, item):
        t = float(self._t[item])
        return t, t


def _sigma(sigma, m, what):
    s = np.broadcast_to(np.asarray(sigma, dtype=float), (m,)).copy()
    if not np.all(s > 0) or not np.all(np.isfinite(s)):
        raise ValueError(f"{what} sigma must be finite and > 0, got {sigma}")
    return s


class ZeroVelocity(_OnEpochs):
    """Zero-velocity update (ZUPT): the carrier is at rest on the Earth.

    ``z = ṽ^n`` (ENU [m/s]; east, north for a 2-state velocity block), ``H = I`` on δv.

    Parameters
    ----------
    intervals : sequence of (start, end) [s]
        Stationary intervals (e.g. :func:`sinslab.fusion.stationarity.detect`).
    sigma : float or array_like (3,)
        [m/s].
    every : int
        Apply at every ``every``-th filter epoch inside the intervals.
    stream : int
    gate : InnovationGate or float, optional
        Innovation gate (or its false-rejection probability): an update the filter's
        covariance cannot explain (a "rest" in motion) is skipped.
    """

    def __init__(self, intervals, sigma=0.01, *, every=1, stream=0, gate=None):
        self._init_sched(intervals, every, stream, gate)
        self.sigma = _sigma(sigma, 3, "ZUPT")

    def matrices(self, ep: Epoch):
        lay = ep.layout
        sv = lay.slice("dv")
        k = sv.stop - sv.start
        H = np.zeros((k, ep.n))
        H[:, sv] = np.eye(k)
        return ep.streams[self.stream].vel[:k].copy(), H, self.sigma[:k] ** 2


class ZeroRate(_OnEpochs):
    """Zero angular-rate update (ZARU): at rest the body turns with the Earth only.

    ``z = ω̃_ib^b − C̃_n^b ω_ie^n(L̃)`` [rad/s] with the compensated rate of the last
    filter step. With ``C̃_b^n = (I − φ×) C_b^n`` and ``ω̃ = ω + δω``:
    ``z = δω + C_n^b (ω_ie^n×) φ − C_n^b (∂ω_ie^n/∂L) δL``; ``δω`` is expressed through
    every block feeding the gyro compensation (bias, Gauss–Markov: ``x``; scale:
    ``diag(ω) x``), so the heading error is observable through the gyro bias only as far
    as ``ω_ie`` allows, and the bias itself (hence the heading drift) is held.

    Parameters
    ----------
    intervals : sequence of (start, end) [s]
    sigma : float or array_like (3,)
        [rad/s] (of the mean rate over one filter step: ARW / √T plus vibration).
    every, stream, gate
        As in :class:`ZeroVelocity`.
    """

    def __init__(self, intervals, sigma, *, every=1, stream=0, gate=None):
        self._init_sched(intervals, every, stream, gate)
        self.sigma = _sigma(sigma, 3, "ZARU")

    def matrices(self, ep: Epoch):
        lay = ep.layout
        nr = ep.streams[self.stream]
        Cnb = nr.C_bn.T
        lat = nr.lat
        wie = np.array([0.0, E.WIE * math.cos(lat), E.WIE * math.sin(lat)])
        dwie = np.array([0.0, -E.WIE * math.sin(lat), E.WIE * math.cos(lat)])
        z = nr.omega_b - Cnb @ wie
        H = np.zeros((3, ep.n))
        H[:, lay.slice("phi")] = Cnb @ A.skew(wie)
        H[:, lay.slice("dp").start] = -Cnb @ dwie
        add_rate_H(H, lay, np.eye(3), nr.omega_b)
        return z, H, self.sigma ** 2


def _vehicle_velocity(nr, lay, n, Cvb, lever, lever_block=None, mount_block=None):
    """Velocity of a vehicle point in vehicle axes and its Jacobian.

    ``v^v = C_b^v (C̃_n^b ṽ^n + ω̃_ib^b × l)`` [m/s] (l: IMU -> point, body axes [m]);
    ``∂/∂φ = −C_b^v C_n^b (v^n×)``, ``∂/∂δv = C_b^v C_n^b``, ``∂/∂δω = −C_b^v (l×)``,
    ``∂/∂δl = C_b^v (ω×)`` (lever error state, computed − true, when ``lever_block``),
    ``∂/∂ψ = (v^v×)`` (``mount_block``: small angles ψ [rad] of the mount in use, vehicle
    axes, ``C̃_b^v = (I − ψ×) C_b^v``; the true mount is ``(I + ψ×) C̃_b^v``).
    """
    Cnb = nr.C_bn.T
    w = nr.omega_b
    vb = Cnb @ nr.vel + np.cross(w, lever)
    H = np.zeros((3, n))
    sv = lay.slice("dv")
    k = sv.stop - sv.start
    H[:, sv] = (Cvb @ Cnb)[:, :k]
    H[:, lay.slice("phi")] = -Cvb @ Cnb @ A.skew(nr.vel)
    add_rate_H(H, lay, -Cvb @ A.skew(lever), w)
    if lever_block is not None:
        H[:, lay.find("lever_arm", lever_block)] = Cvb @ A.skew(w)
    vv = Cvb @ vb
    if mount_block is not None:
        sl = lay.find("installation", mount_block)
        H[:, sl] = A.skew(vv)[:, ["xyz".index(a) for a in lay.blocks[lay.names.index(mount_block)].axes]]
    return vv, H


def _lever(lever_arm):
    return np.zeros(3) if lever_arm is None else np.asarray(lever_arm, dtype=float).reshape(3)


class NonHolonomic(_OnEpochs):
    """Non-holonomic constraint of a wheeled vehicle: no lateral and no vertical velocity
    of the wheel contact point in vehicle axes (RFU: x right, z up).

    ``z = [v^v_x, v^v_z]`` of :func:`_vehicle_velocity` [m/s].

    Parameters
    ----------
    sigma : float or array_like (2,)
        Lateral, vertical [m/s] (the constraint is violated by skid and suspension).
    mount : see :func:`vehicle_from_body`
        IMU body -> vehicle axes.
    lever_arm : array_like (3,), optional
        IMU -> constraint point (e.g. rear-axle centre), body axes [m].
    intervals : sequence of (start, end) [s], optional
        Where the constraint holds (default: every epoch).
    lever_block : str, optional
        Name of a :func:`sinslab.nav.errstate.lever_arm` block estimating the lever error.
    mount_block : str, optional
        Name of a :func:`sinslab.nav.errstate.installation` block (axes ``"xz"``: pitch and
        yaw; roll is unobservable) estimating the mount's small-angle error.
    every, stream, gate
        As in :class:`ZeroVelocity`.
    pitch_gradient : float, optional
        Pitch of the body on its suspension per longitudinal acceleration [rad per m/s²]
        (a car dips its nose when braking). The vertical velocity it gives the constraint
        point, ``e = v_y k a_y`` (vehicle axes, ``a = C_b^n f^b + g^n``), is not modelled
        but systematic over a manoeuvre: its variance is added to the vertical row's,
        multiplied by the number of updates in ``correlation_time`` (it does not average
        out like white noise over them). 0: the fixed σ alone.
    correlation_time : float, optional
        [s] over which that error stays the same (a braking or accelerating manoeuvre).
    dt : float, optional
        Filter epoch [s]; the updates come every ``every * dt``.
    """

    rows = (0, 2)

    def __init__(self, sigma=0.1, *, mount=None, lever_arm=None, intervals=None, lever_block=None,
                 every=1, stream=0, gate=None, mount_block=None, pitch_gradient=0.0,
                 correlation_time=1.0, dt=None):
        self._init_sched(intervals, every, stream, gate)
        self.sigma = _sigma(sigma, 2, "NHC")
        self.Cvb = vehicle_from_body(mount)
        self.lever = _lever(lever_arm)
        self.lever_block = lever_block
        self.mount_block = mount_block
        self.pitch_gradient = float(pitch_gradient)
        if not (math.isfinite(self.pitch_gradient) and self.pitch_gradient >= 0):
            raise ValueError(f"NHC pitch gradient must be finite and >= 0, got {pitch_gradient}")
        if self.pitch_gradient > 0 and not (dt is not None and dt > 0 and correlation_time > 0):
            raise ValueError("an NHC pitch gradient needs the filter epoch dt > 0 and a correlation time > 0")
        self.n_corr = max(1.0, correlation_time / (self.every * dt)) if self.pitch_gradient > 0 else 1.0

    def matrices(self, ep: Epoch):
        nr = ep.streams[self.stream]
        vv, H = _vehicle_velocity(nr, ep.layout, ep.n, self.Cvb, self.lever,
                                  self.lever_block, self.mount_block)
        r = list(self.rows)
        R = self.sigma ** 2
        if self.pitch_gradient > 0:
            Cbn = nr.C_bn
            acc = Cbn @ nr.f_b + E.gravity_vector(nr.lat, nr.h)
            av = self.Cvb @ (Cbn.T @ acc)                   # vehicle axes: y forward
            e = self.pitch_gradient * (vv[1] * av[1])
            R = R + np.array([0.0, self.n_corr * e * e])
        return vv[r], H[r], R


class BodyVelocity(Timed):
    """A measured 3-D velocity of a vehicle point in vehicle axes (e.g. a Doppler
    velocity log, or wheel speed with the non-holonomic zeros).

    ``z = v^v(computed) − v_meas`` [m/s], linearised by :func:`_vehicle_velocity`.

    Parameters
    ----------
    t : array_like (J,)
        Validity times [s].
    vel : array_like (J, 3)
        Vehicle-axis velocity [m/s].
    sigma : array_like (3,) or (J, 3)
        [m/s].
    mount, lever_arm, lever_block, stream
        As in :class:`NonHolonomic`.
    t_arrive, outages, windows
        As in :class:`PositionFix`.
    """

    def __init__(self, t, vel, sigma, *, mount=None, lever_arm=None, lever_block=None,
                 t_arrive=None, outages=(), windows=None, stream=0):
        self._init_times(t, t_arrive, outages, windows)
        J = self.t_valid.size
        self.vel = np.asarray(vel, dtype=float).reshape(J, 3)
        if not np.all(np.isfinite(self.vel)):
            raise ValueError("body velocities contain NaN/inf")
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (J, 3))
        if not np.all(self.sigma > 0):
            raise ValueError("body velocity sigma must be > 0")
        self.Cvb = vehicle_from_body(mount)
        self.lever = _lever(lever_arm)
        self.lever_block = lever_block
        self.stream = int(stream)

    def matrices(self, ep: Epoch):
        vv, H = _vehicle_velocity(ep.streams[self.stream], ep.layout, ep.n, self.Cvb, self.lever,
                                  self.lever_block)
        return vv - self.vel[ep.item], H, self.sigma[ep.item] ** 2


class Odometer(_OnEpochs):
    """Wheel speed: the forward velocity ``v^v_y`` of the wheel point, from a time series
    with its own time stamps, linearly interpolated to the filter epochs it spans.

    The scale-factor state ``k`` (an :func:`sinslab.nav.errstate.odometer_scale` block,
    when ``scale_block`` names one) is defined by ``v^v_y = (1 − k) s̃`` for the reading
    ``s̃``: then ``z = v^v_y(computed) − s̃ = δv^v_y − k s̃`` holds exactly, ``∂z/∂k = −s̃``.
    A reading ``s̃ = (1 + k_s) v^v_y`` corresponds to ``k = k_s / (1 + k_s)`` (equal to
    first order; compare estimates with that, not with ``k_s``). With
    ``nhc_sigma`` the non-holonomic zeros ``v^v_x, v^v_z`` are stacked as rows 2, 3.

    Parameters
    ----------
    t : array_like (J,)
        Odometer time stamps [s], strictly increasing.
    speed : array_like (J,)
        Forward speed [m/s], finite and >= 0.
    sigma : float
        Speed noise [m/s] at one filter epoch (include quantisation: step/√12).
    mount, lever_arm, lever_block, intervals, every, stream, gate
        As in :class:`NonHolonomic` (``lever_arm``: IMU -> wheel point).
    scale_block : str or None
        Name of the odometer scale-factor block (None: no scale state).
    nhc_sigma : float or array_like (2,), optional
        Also constrain lateral and vertical velocity [m/s].
    """

    def __init__(self, t, speed, sigma, *, mount=None, lever_arm=None, lever_block=None,
                 scale_block="kod", nhc_sigma=None, intervals=None, every=1, stream=0, gate=None):
        self._init_sched(intervals, every, stream, gate)
        self.t_odo = np.asarray(t, dtype=float).ravel()
        self.speed = np.asarray(speed, dtype=float).ravel()
        if self.t_odo.size < 2 or self.speed.shape != self.t_odo.shape:
            raise ValueError(f"odometer: {self.t_odo.size} times and {self.speed.size} speeds "
                             "(need >= 2 of each, equal numbers)")
        if not (np.all(np.isfinite(self.t_odo)) and np.all(np.diff(self.t_odo) > 0)):
            raise ValueError("odometer times must be finite and strictly increasing")
        if not np.all(np.isfinite(self.speed)) or np.any(self.speed < 0):
            raise ValueError("odometer speeds must be finite and >= 0")
        self.sigma = _sigma(sigma, 1, "odometer")
        self.nhc_sigma = None if nhc_sigma is None else _sigma(nhc_sigma, 2, "NHC")
        self.Cvb = vehicle_from_body(mount)
        self.lever = _lever(lever_arm)
        self.lever_block = lever_block
        self.scale_block = scale_block

    def _keep(self, t):
        keep = super()._keep(t)
        keep &= (t >= self.t_odo[0] - 1e-9) & (t <= self.t_odo[-1] + 1e-9)
        return keep

    def epochs(self, grid):
        t = grid.t
        if self.t_odo[-1] < t[0] or self.t_odo[0] > t[-1]:
            raise ValueError(f"odometer times {self.t_odo[0]:.3f}..{self.t_odo[-1]:.3f} s do not "
                             f"overlap the filter epochs {t[0]:.3f}..{t[-1]:.3f} s")
        return super().epochs(grid)

    def reading(self, t):
        """Wheel speed [m/s] interpolated at ``t`` [s]."""
        return float(np.interp(t, self.t_odo, self.speed))

    def matrices(self, ep: Epoch):
        vv, H = _vehicle_velocity(ep.streams[self.stream], ep.layout, ep.n, self.Cvb, self.lever,
                                  self.lever_block)
        s = self.reading(ep.t)
        rows = [1] if self.nhc_sigma is None else [1, 0, 2]
        z = vv[rows]
        z[0] -= s
        H = H[rows]
        if self.scale_block is not None:
            H[0, ep.layout.find("odometer_scale", self.scale_block)] = -s
        R = self.sigma ** 2 if self.nhc_sigma is None else np.r_[self.sigma, self.nhc_sigma] ** 2
        return z, H, R


class LeverPositionFix(PositionFix):
    """:class:`PositionFix` with the antenna lever arm estimated: the block ``lever_block``
    (:func:`sinslab.nav.errstate.lever_arm`) holds ``δl = l_used − l_true`` and
    ``∂z/∂δl = C_b^n`` (rows north, east, up) ``− C_b^n (ω×) Δt`` (extrapolation).
    ``lever_arm`` is the lever used (default zero, an unknown antenna offset)."""

    def __init__(self, t_valid, pos, sigma, *, lever_block="lev", lever_arm=None, **kw):
        super().__init__(t_valid, pos, sigma, lever_arm=lever_arm, **kw)
        self.lever_block = lever_block

    def matrices(self, ep: Epoch):
        z, H, R = super().matrices(ep)
        nr = ep.streams[self.stream]
        C = nr.C_bn
        dtf = ep.t - self.t_valid[ep.item]
        n_z = z.size
        H[:, ep.layout.find("lever_arm", self.lever_block)] = (C - dtf * C @ A.skew(nr.omega_b))[[1, 0, 2]][:n_z]
        return z, H, R


class LeverVelocityFix(VelocityFix):
    """:class:`VelocityFix` with the antenna lever arm estimated (``∂z/∂δl = C_b^n (ω×)``)."""

    def __init__(self, t_valid, vel, sigma, *, lever_block="lev", lever_arm=None, **kw):
        super().__init__(t_valid, vel, sigma, lever_arm=lever_arm, **kw)
        self.lever_block = lever_block

    def matrices(self, ep: Epoch):
        z, H, R = super().matrices(ep)
        nr = ep.streams[self.stream]
        H[:, ep.layout.find("lever_arm", self.lever_block)] = nr.C_bn @ A.skew(nr.omega_b)
        return z, H, R
