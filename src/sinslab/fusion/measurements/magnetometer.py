"""A three-axis magnetometer as a measurement of the fusion driver: the whole field vector
(:class:`MagneticField`) or the heading it gives (:class:`MagneticHeading`), with a residual
hard-iron state of its own.

A reading, calibrated (:class:`sinslab.nav.magnetic.MagCalibration`: ``W (m̃ − h)``), is
``u = b + β + v`` [T], body axes: the Earth's field ``b = C_n^b B^n`` (``B^n`` ENU from a
geomagnetic model, :func:`sinslab.nav.magnetic.reference_field`), a residual hard iron
``β`` the calibration left and noise ``v``. The measurement removes the ``β_used`` it is
given; the state of a :func:`sinslab.nav.errstate.magnetometer_bias` block is
``δβ = β_used − β_true`` (computed minus true, as every error of
:mod:`sinslab.nav.errstate`), so the estimate of β is ``β_used − x_β``.

Field vector (3 rows, body axes [T]): with ``C̃_n^b = C_n^b (I + φ×)``,

``z = C̃_n^b B^n − (u − β_used) = −C_n^b (B^n×) φ + δβ − v``,
``H = [−C_n^b (B^n×) on φ, I on δβ]``.

It sees all three attitude angles (the dip makes the vertical part large: at I = 72° it
is three times the horizontal one), so a field disturbance moves pitch and roll too.

Heading (1 row [rad]): the calibrated reading turned to ENU with the INS attitude,
``m' = C̃_b^n (u − β_used)``, has the azimuth ``atan2(m'_E, m'_N)``; the model's is the
declination D:

``z = atan2(m'_E, m'_N) − D``, with ``∂m'/∂φ = (m'×)`` (``C̃_b^n = (I − φ×) C_b^n``),
``∂m'/∂δβ = −C_b^n`` and ``∂z/∂m' = [m'_N, −m'_E, 0] / H²`` (``H²`` the squared
horizontal part). The tilt used to level the reading is the INS's own, so a tilt error
enters the heading through the dip (``H`` has φ_E and φ_N terms); the row is skipped
where the horizontal part is under :data:`MIN_HORIZONTAL` of the reading (near a
magnetic pole, or a reading swamped by a disturbance).

Both take an innovation gate (:class:`~sinslab.fusion.measurements.InnovationGate`): a
local disturbance (a hangar, a car beside the antenna mast, motor currents) is a field the
model does not have; the filter's own covariance says so and the reading is refused and
counted, not fatal.

The reference field is treated as known at each reading (its gradient, a few nT per km,
is not a state); readings are applied at the first filter epoch at or after their time,
the INS attitude of that epoch used (``Δt`` below one filter step: the rotation in it is
in the noise).
"""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import attitude as A
from sinslab.fusion.measurements.base import Epoch
from sinslab.fusion.measurements.schedule import InnovationGate, Timed

__all__ = ["MagneticField", "MagneticHeading", "MIN_HORIZONTAL"]

#: Least horizontal part of a levelled reading, relative to its magnitude, for a heading.
MIN_HORIZONTAL = 0.05


class _Magnetometer(Timed):
    """Readings, calibration, reference field and residual hard iron shared by both forms."""

    def _init_readings(self, t_valid, field, reference, *, calibration, bias, bias_block, t_arrive,
                       outages, windows, stream, gate):
        self._init_times(t_valid, t_arrive, outages, windows)
        J = self.t_valid.size
        field = np.asarray(field, dtype=float)
        if field.shape != (J, 3):
            raise ValueError(f"magnetometer readings must have shape ({J}, 3), got {field.shape}")
        self.field = field if calibration is None else calibration.apply(field)
        ref = np.asarray(reference, dtype=float)
        if ref.shape not in ((3,), (J, 3)):
            raise ValueError(f"reference field must have shape (3,) or ({J}, 3), got {ref.shape}")
        self.reference = np.broadcast_to(ref, (J, 3))
        self.bias = np.broadcast_to(np.asarray(bias, dtype=float), (3,)).copy()
        self.bias_block = bias_block
        self.stream = int(stream)
        self.gate = gate if (gate is None or isinstance(gate, InnovationGate)) else InnovationGate(gate)

    def _reading(self, j):
        """Calibrated reading of item j with the residual hard iron removed, body axes [T]."""
        return self.field[j] - self.bias

    def _bias_slice(self, lay):
        return lay.find("mag_hard_iron", self.bias_block)


class MagneticField(_Magnetometer):
    """The field vector in body axes against one stream (see the module notes).

    Parameters
    ----------
    t_valid : array_like, shape (J,)
        Reading times [s].
    field : array_like, shape (J, 3)
        Raw readings [T], body axes of the IMU (the sensor's axes turned into them).
    reference : array_like, shape (3,) or (J, 3)
        Model field ENU [T] at the readings.
    sigma : float or array_like (3,)
        White noise of a calibrated reading per axis [T].
    calibration : sinslab.nav.magnetic.MagCalibration, optional
        Hard and soft iron applied to every reading (default: none).
    bias : array_like (3,)
        Residual hard iron ``β_used`` removed [T] (the nominal value of the bias state).
    bias_block : str, optional
        Name of the :func:`~sinslab.nav.errstate.magnetometer_bias` block when a layout has
        several; by default the layout's one block of that quantity (or none: β known).
    gate : InnovationGate or float, optional
        Innovation gate (or its false-rejection probability).
    t_arrive, outages, windows, stream
        As in :class:`sinslab.fusion.measurements.PositionFix`.
    """

    def __init__(self, t_valid, field, reference, sigma, *, calibration=None, bias=0.0, bias_block=None,
                 t_arrive=None, outages=(), windows=None, stream=0, gate=None):
        self._init_readings(t_valid, field, reference, calibration=calibration, bias=bias,
                            bias_block=bias_block, t_arrive=t_arrive, outages=outages, windows=windows,
                            stream=stream, gate=gate)
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (3,)).copy()
        if not np.all(self.sigma > 0) or not np.all(np.isfinite(self.sigma)):
            raise ValueError("magnetometer sigma must be finite and > 0")

    def matrices(self, ep: Epoch):
        j = ep.item
        lay = ep.layout
        Cnb = ep.streams[self.stream].C_bn.T
        bn = self.reference[j]
        H = np.zeros((3, ep.n))
        H[:, lay.slice("phi")] = -Cnb @ A.skew(bn)
        sb = self._bias_slice(lay)
        if sb is not None:
            H[:, sb] = np.eye(3)
        return Cnb @ bn - self._reading(j), H, self.sigma ** 2


class MagneticHeading(_Magnetometer):
    """The heading of the levelled field against the declination, one row [rad] (see the
    module notes).

    Parameters
    ----------
    sigma : float
        White noise of the magnetic heading [rad].
    t_valid, field, reference, calibration, bias, bias_block, gate, t_arrive, outages, windows, stream
        As in :class:`MagneticField`.
    """

    def __init__(self, t_valid, field, reference, sigma, *, calibration=None, bias=0.0, bias_block=None,
                 t_arrive=None, outages=(), windows=None, stream=0, gate=None):
        self._init_readings(t_valid, field, reference, calibration=calibration, bias=bias,
                            bias_block=bias_block, t_arrive=t_arrive, outages=outages, windows=windows,
                            stream=stream, gate=gate)
        self.sigma = float(sigma)
        if not (self.sigma > 0 and math.isfinite(self.sigma)):
            raise ValueError("magnetic heading sigma must be finite and > 0")
        ref = self.reference
        self.declination = np.arctan2(ref[:, 0], ref[:, 1])

    def matrices(self, ep: Epoch):
        j = ep.item
        lay = ep.layout
        C = ep.streams[self.stream].C_bn
        m = C @ self._reading(j)
        h2 = m[0] ** 2 + m[1] ** 2
        if h2 < (MIN_HORIZONTAL ** 2) * float(m @ m):
            return None
        g = np.array([m[1], -m[0], 0.0]) / h2
        H = np.zeros((1, ep.n))
        H[0, lay.slice("phi")] = g @ A.skew(m)
        sb = self._bias_slice(lay)
        if sb is not None:
            H[0, sb] = -g @ C
        z = A.wrap_pi(math.atan2(m[0], m[1]) - self.declination[j])
        return np.array([z]), H, np.array([self.sigma ** 2])
