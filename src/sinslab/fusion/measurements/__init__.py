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

The package's public contract is :mod:`.base` (``Grid``, ``NavRow``, ``Epoch``, the
``Measurement`` protocol, ``Stack``), :mod:`.schedule` (arrival epochs, timed and
interval-held items, the innovation gate, robust weighting) and :mod:`.jacobians` (terms placed by block
kind: a mount's rotation, the lever-arm rate term on every block feeding the gyro). Each
sensor family has its own file: :mod:`.fixes` (position/velocity fixes),
:mod:`.vehicle` (non-holonomic constraint, body velocity, odometer), :mod:`.rest`
(ZUPT/ZARU), :mod:`.ins_difference` (two INS compared), :mod:`.barometer` (a barometric
altimeter with a bias state of its own), :mod:`.magnetometer` (the field vector or the
heading of a three-axis magnetometer, with a residual hard-iron state of its own). A new sensor is a file here with a class
following :class:`Measurement` and, when it has states of its own, an error-state block
(:mod:`.barometer` is the worked example).
"""
from sinslab.fusion.measurements.barometer import Barometer
from sinslab.fusion.measurements.base import Epoch, Grid, Measurement, NavRow, Rows, Stack, declared
from sinslab.fusion.measurements.fixes import LeverPositionFix, LeverVelocityFix, PositionFix, VelocityFix
from sinslab.fusion.measurements.ins_difference import InsDifference
from sinslab.fusion.measurements.jacobians import add_rate_H, vehicle_from_body
from sinslab.fusion.measurements.magnetometer import MagneticField, MagneticHeading
from sinslab.fusion.measurements.rest import ZeroRate, ZeroVelocity
from sinslab.fusion.measurements.schedule import InnovationGate, RobustWeighting, RowGate, Timed, arrival_epochs
from sinslab.fusion.measurements.vehicle import BodyVelocity, NonHolonomic, Odometer

__all__ = ["Measurement", "NavRow", "Epoch", "Grid", "Timed", "PositionFix", "VelocityFix", "Stack",
           "InsDifference", "arrival_epochs", "ZeroVelocity", "ZeroRate", "NonHolonomic",
           "BodyVelocity", "Odometer", "LeverPositionFix", "LeverVelocityFix", "vehicle_from_body",
           "InnovationGate", "RobustWeighting", "RowGate", "Rows", "declared", "add_rate_H", "Barometer",
           "MagneticField", "MagneticHeading"]
