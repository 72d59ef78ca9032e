"""The contract between the fusion driver and its measurements: the filter grid
(:class:`Grid`), the navigation row of a stream at an epoch (:class:`NavRow`), what the
driver hands a measurement (:class:`Epoch`), the protocol every measurement follows
(:class:`Measurement`) and the stack of several measurements applied as one
(:class:`Stack`). See the package notes for the conventions."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from sinslab.core import attitude as A

__all__ = ["Grid", "NavRow", "Epoch", "Measurement", "Stack"]


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

    # Optional: ``transform(ep) -> (A (n, n), Q (n, n)) | None``, a jump of the filter's
    # state asked for before ``matrices`` of an item applied on arrival (states the
    # measurement re-initialises, as carrier-phase ambiguities after a slip, or copies);
    # the driver applies it with ``KalmanFilter.transform`` and hands ``matrices`` the
    # prior after it. Such a measurement cannot be lagged or smoothed.


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
