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

__all__ = ["Measurement", "NavRow", "Epoch", "Grid", "PositionFix", "VelocityFix", "Stack",
           "InsDifference", "arrival_epochs"]


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
    """

    t: float
    k: int
    streams: tuple
    layout: object
    n: int
    item: int = 0


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


def _names(layout):
    return [b.name for b in layout.blocks]


class _Timed:
    """Time stamps and schedule shared by the fix measurements."""

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


class PositionFix(_Timed):
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
        dlon = (lon - self.pos[j, 1] + math.pi) % (2 * math.pi) - math.pi
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


class VelocityFix(_Timed):
    """Velocity fixes of an antenna (ENU, 3 components) against one stream.

    ``z = v + C_b^n (ω_ib^b × l) − v_fix`` [m/s]; ``H`` has ``I`` on δv and, with a lever
    arm, ``(C_b^n (ω×l))×`` on φ and ``−C_b^n l×`` on the gyro bias block ``eps`` (when the
    layout has one).

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
            if "eps" in _names(lay):
                H[:, lay.slice("eps")] = -C @ A.skew(self.lever)
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


class InsDifference(_Timed):
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
        z[1] = (a.lon - lon_k + math.pi) % (2 * math.pi) - math.pi
        z[2:4] = a.vel[:2] - vk
        sp, sv = lay.slice("dp"), lay.slice("dv")
        H[0, sp.start] = 1.0
        H[1, sp.start + 1] = 1.0
        H[2, sv.start] = 1.0
        H[3, sv.start + 1] = 1.0
        return z, H, self.sigma[j] ** 2
