"""A carrier at rest (a moored ship) carrying an IMU on an indexing mount.

With the carrier at rest the true IMU increments repeat exactly with the mount's cycle,
so a long run needs one synthesised cycle (:func:`one_cycle`) tiled over the run
(:func:`tile`, chunk by chunk, without index arrays). :func:`truth_rows` gives the
error-free navigation output at chosen epochs and the true rates per step, the
linearisation points of an error model along the schedule. Axes: navigation frame ENU,
carrier frame = ENU (heading north, level), height 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core.errors import InputError
from sinslab.sim import indexing as ix

__all__ = ["Cycle", "one_cycle", "tile", "truth_rows", "remove_block_means"]


@dataclass
class Cycle:
    """One cycle of exact increments of a carrier at rest on an indexing mount.

    Attributes
    ----------
    dth, dv : ndarray (N, 3)
        Angle [rad] and velocity [m/s] increments per IMU sample, body axes.
    att0 : ndarray (3,)
        IMU attitude at t = 0, Euler ``[pitch, roll, yaw]`` [rad].
    period : float
        The mount's cycle [s] (N samples).
    """

    dth: np.ndarray
    dv: np.ndarray
    att0: np.ndarray
    period: float


def one_cycle(mount, lat, lon, dt):
    """Exact increments over one cycle of ``mount`` at rest at ``lat``, ``lon`` [rad],
    height 0, sampled every ``dt`` [s] (they repeat: the carrier is at rest).

    Raises :class:`~sinslab.core.errors.InputError` when the cycle is not a whole number
    of samples."""
    from sinslab.sim import trajectory as tj

    Tc = float(mount.cycle_time)
    n = int(round(Tc / dt))
    if abs(n * dt - Tc) > 1e-6:
        raise InputError(f"rotation: the cycle of {mount.name} ({Tc:g} s) is not a whole number of IMU samples "
                         f"of {dt:g} s; choose rate, ramp and dwell so that it is")
    gen = tj.generate([tj.Static(Tc)], tj.Start(lat=lat, lon=lon, h=0.0), dt, duration=Tc, mount=mount,
                      out_every=n)
    return Cycle(np.ascontiguousarray(gen.imu.dtheta), np.ascontiguousarray(gen.imu.dv),
                 np.asarray(gen.truth.att_imu[0], float), Tc)


def tile(a, i0, L, out=None):
    """Rows ``i0 .. i0+L−1`` of the periodic repetition of ``a`` (slices, no index array):
    a view when they do not wrap, else copied into ``out`` (rows ≥ L) or a new array."""
    N = a.shape[0]
    j = i0 % N
    if j + L <= N:
        return a[j:j + L]
    res = np.empty((L,) + a.shape[1:], a.dtype) if out is None else out[:L]
    k = min(L, N - j)
    res[:k] = a[j:j + k]
    while k < L:
        m = min(N, L - k)
        res[k:k + m] = a[:m]
        k += m
    return res


def truth_rows(mount, t, lat, lon):
    """Error-free INS output of a carrier at rest on ``mount`` at the epochs ``t`` (S,) [s].

    Returns
    -------
    rows : ndarray (S, 10)
        Navigation rows (quaternion C_b^n, velocity ENU [m/s] = 0, lat, lon [rad], h = 0).
    w : ndarray (S-1, 3)
        Earth rate in body axes at each step's start epoch [rad/s].
    f : ndarray (S-1, 3)
        Specific force (normal gravity, up) in body axes at each step's start epoch [m/s²].
    """
    from sinslab.core import attitude as A
    from sinslab.core import earth

    ang, _ = ix.mount_angles(mount, t)
    C = A.euler_to_dcm(ang)
    rows = np.zeros((t.size, 10))
    rows[:, :4] = A.euler_to_quat(ang)
    rows[:, 7] = lat
    rows[:, 8] = lon
    wie = earth.WIE * np.array([0.0, math.cos(lat), math.sin(lat)])
    g = float(earth.gravity(lat, 0.0))
    w = np.einsum("kji,j->ki", C, wie)[:-1]
    f = np.einsum("kji,j->ki", C, np.array([0.0, 0.0, g]))[:-1]
    return rows, w, f


def remove_block_means(x, nb, keep=0.0):
    """Remove from ``x`` (L, 3), in place, its mean over consecutive blocks of ``nb`` rows
    (a last, shorter block over its own rows) and add ``keep`` (3,) back: with ``x`` the
    error of the increments, bias·dt + noise, and ``keep`` = bias·dt, the noise loses its
    block means and the bias stays."""
    L = x.shape[0]
    full = (L // nb) * nb
    if full:
        v = x[:full].reshape(-1, nb, x.shape[1])
        v -= v.mean(1, keepdims=True) - keep
    if full < L:
        x[full:] -= x[full:].mean(0) - keep
    return x
