"""Measurements at rest: zero velocity (:class:`ZeroVelocity`, ZUPT) and zero angular
rate (:class:`ZeroRate`, ZARU) on stationary intervals."""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.fusion.measurements.base import Epoch
from sinslab.fusion.measurements.jacobians import add_rate_H
from sinslab.fusion.measurements.schedule import _OnEpochs, _sigma

__all__ = ["ZeroVelocity", "ZeroRate"]


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
