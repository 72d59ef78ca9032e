"""Recorded static noise: the gyro channel of a record taken at rest, as noise to add to
a simulated IMU (the record's mean removed, checked against the run that uses it).

Any IMU file :func:`sinslab.data.load.load_imu` reads will do (unit headers honoured).
"""
from __future__ import annotations

import numpy as np

from sinslab.core.errors import InputError

__all__ = ["load_recorded_gyro"]


def load_recorded_gyro(path, n_needed, dt, what):
    """Gyro noise of a recorded static file, checked for a run.

    Parameters
    ----------
    path : str or Path
        The record (any format of :func:`sinslab.data.load.load_imu`).
    n_needed : int
        Samples the run needs; the record must hold at least as many.
    dt : float
        The run's IMU interval [s]; the record must be sampled at it.
    what : str
        The option that named the file, put at the head of every error line.

    Returns
    -------
    ndarray (n_needed, 3)
        Gyro rate noise [rad/s], body axes, the mean of these samples removed.

    Raises
    ------
    InputError
        One line naming the option, the file and the problem: unreadable, a gap in the
        stamps, another sampling interval, NaN/inf, too short, or a std far above any
        static navigation-grade record (wrong units in the header).
    """
    from sinslab.data import load as dload

    try:
        d = dload.load_imu(path)
    except (OSError, ValueError) as e:
        msg = str(e)
        raise InputError(f"{what}: {msg}" if str(path) in msg else f"{what} {path}: {msg}") from None
    if np.asarray(d.gaps).size:
        g0 = np.asarray(d.gaps)[0]
        raise InputError(f"{what} {path}: gap of {g0[1]:g} s at t = {g0[0]:g} s in the time stamps")
    rec = d.imu
    step = float(rec.dt)
    if abs(step - dt) > 1e-6 * dt:
        raise InputError(f"{what} {path}: sampled every {step:g} s, the run uses {dt:g} s")
    g = np.asarray(rec.dtheta, float) / step
    if not np.all(np.isfinite(g)):
        k = int(np.flatnonzero(~np.all(np.isfinite(g), 1))[0])
        raise InputError(f"{what} {path}: NaN or infinite value at sample {k}")
    if g.shape[0] < n_needed:
        raise InputError(f"{what} {path}: {g.shape[0]} samples ({g.shape[0] * step / 3600:.3g} h), "
                         f"the run needs {n_needed} ({n_needed * dt / 3600:.3g} h)")
    g = g[:n_needed] - g[:n_needed].mean(0)
    s = float(np.max(np.std(g, 0)))
    if s > 0.01:
        raise InputError(f"{what} {path}: gyro noise std {s:.3g} rad/s is far above any static "
                         "navigation-grade record (wrong units in the header?)")
    return g
