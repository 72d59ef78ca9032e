"""Barometric altimeter as a measurement of the fusion driver, with a bias state of its own.

A barometer reads the height ``h̃ = h + b + v`` [m] (pressure height referred to the
ellipsoid: the reference pressure and the offset of the local geoid are in ``b``), with a
bias ``b`` that drifts with weather and temperature and white noise ``v``.
:class:`Barometer` removes the bias it is given (``b_used``) and compares the rest with the
INS height of one stream:

``z = ĥ − (h̃ − b_used) − v̂_U Δt = δh + δb − v``,  ``H = [1 on δh, 1 on δb]``,

with ``δh`` the INS height error and ``δb = b_used − b_true`` the bias error, computed
minus true as every error of :mod:`sinslab.nav.errstate`; ``Δt = t_epoch − t_valid`` moves
a reading to a later epoch with the INS vertical velocity. The bias state is a
:func:`sinslab.nav.errstate.barometer_bias` block (Gauss–Markov or random walk): it feeds
nothing back to the INS, and is found in the layout by what it is
(:meth:`~sinslab.nav.errstate.StateLayout.find`), so the estimated bias is
``b_used − x_b``. Without such a block the bias is taken as known.

This module is the recipe for a sensor with a state of its own: the measurement (this
file) and its block (one builder in :mod:`sinslab.nav.errstate`); the driver, the feedback
layout and the smoother follow from the model.
"""
from __future__ import annotations

import numpy as np

from sinslab.fusion.measurements.base import Epoch
from sinslab.fusion.measurements.schedule import InnovationGate, Timed

__all__ = ["Barometer"]


class Barometer(Timed):
    """Barometric heights against one stream (see the module notes).

    Parameters
    ----------
    t_valid : array_like, shape (J,)
        Validity times [s].
    height : array_like, shape (J,)
        Barometric heights above the ellipsoid [m], bias included.
    sigma : float or array_like (J,)
        White noise of a reading [m].
    bias : float
        The bias ``b_used`` removed from every reading [m] (nominal value of the bias
        state).
    bias_block : str, optional
        Name of the :func:`~sinslab.nav.errstate.barometer_bias` block, when a layout has
        several; by default the layout's one block of that quantity (or none).
    gate : InnovationGate or float, optional
        Innovation gate (or its false-rejection probability): a pressure jump, ground
        effect at take-off.
    t_arrive, outages, windows, stream
        As in :class:`sinslab.fusion.measurements.PositionFix`.
    """

    def __init__(self, t_valid, height, sigma, *, bias=0.0, bias_block=None, t_arrive=None,
                 outages=(), windows=None, stream=0, gate=None):
        self._init_times(t_valid, t_arrive, outages, windows)
        J = self.t_valid.size
        self.height = np.asarray(height, dtype=float).reshape(-1)
        if self.height.shape != (J,):
            raise ValueError(f"{self.height.size} barometric heights for {J} times")
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (J,))
        if not np.all(self.sigma > 0) or not np.all(np.isfinite(self.sigma)):
            raise ValueError("barometer sigma must be finite and > 0")
        self.bias = float(bias)
        self.bias_block = bias_block
        self.stream = int(stream)
        self.gate = gate if (gate is None or isinstance(gate, InnovationGate)) else InnovationGate(gate)

    def matrices(self, ep: Epoch):
        j = ep.item
        lay = ep.layout
        nr = ep.streams[self.stream]
        sp = lay.slice("dp")
        if sp.stop - sp.start != 3:
            raise ValueError("a barometer needs a model with a height error state (a full core)")
        H = np.zeros((1, ep.n))
        H[0, sp.start + 2] = 1.0
        sb = lay.find("baro_bias", self.bias_block)
        if sb is not None:
            H[0, sb] = 1.0
        dt = ep.t - self.t_valid[j]
        z = np.array([nr.h - (self.height[j] - self.bias) - nr.vel[2] * dt])
        return z, H, self.sigma[j:j + 1] ** 2
