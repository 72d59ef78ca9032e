"""RTK/INS: the double differences of :mod:`sinslab.fusion.rtk` as a measurement of the
fusion driver (:class:`DoubleDifferences`), and the error model that carries their
ambiguity states (:func:`rtk_model`).

The antenna is the INS point plus ``C_b^n l``, moved back to the observation time, with
its Jacobian ``J`` (3, n) with respect to the error state
(:meth:`sinslab.fusion.gnss.SatelliteMeasurement.antenna`): the engine's rows carry
``∂ρ/∂r · J`` on the INS states (φ through the lever arm, δv through the extrapolation,
δp, the gyro blocks through ω×l) and λ on the ambiguity states. Before its rows at an
epoch the measurement asks the driver for the state transform that restarts the
ambiguities of new and slipped signals (``transform``); the prediction test compares the
phase change with the range change from the position the filter held at the last epoch
to the INS's present one, its σ the INS velocity σ times the interval.

With ``ar="hold"`` the filter is conditioned on the integers (the INS is corrected by the
fixed solution); after an outage the INS's position (and the ambiguities it implies once
the first double differences arrive) is what lets the integers be found again at once.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from sinslab.fusion.gnss import SatelliteMeasurement
from sinslab.fusion.loosely_coupled import LooselyCoupled, loosely_coupled
from sinslab.fusion.rtk import RtkBase, RtkEngine, RtkOptions
from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec
from sinslab.nav import errstate as es

__all__ = ["DoubleDifferences", "rtk_model", "rtk_ins", "RtkIns"]


class DoubleDifferences(SatelliteMeasurement):
    """Double-differenced code and phase of a rover against a base (see the module notes).

    Parameters
    ----------
    rover : sinslab.fusion.gnss.SatelliteObservations
        With ``signals``, on the IMU's time axis.
    base : RtkBase
    options : RtkOptions
    lever_arm : array_like (3,), optional
        IMU -> antenna, body axes [m].
    outages : sequence of (start, length) [s]
    stream : int
    """

    kind = "double difference"

    def __init__(self, rover, base: RtkBase, options: RtkOptions = RtkOptions(), *, lever_arm=None, outages=(),
                 stream=0):
        super().__init__(rover, options.phase_sigma, lever_arm=lever_arm, mask=options.mask, gate=None,
                         outages=outages, stream=stream)
        self.base = base
        self.options = options
        self.engine = None
        self._prepared = None

    def _engine(self, layout, n):
        if self.engine is None:
            sl = layout.find("ambiguity")
            if sl is None:
                raise ValueError(f"RTK needs ambiguity states in the model (blocks {list(layout.names)}): "
                                 "add sinslab.nav.errstate.carrier_ambiguities")
            self.engine = RtkEngine(self.sv, self.base, np.arange(sl.start, sl.stop), n, self.options)
        return self.engine

    def _pos_sigma(self, ep):
        """σ of the INS position change since the engine's last epoch [m]."""
        eng = self.engine
        if ep.prior is None or eng._last is None:
            return 0.0
        P = ep.prior[1]
        sv = ep.layout.slice("dv")
        dt = float(self.sv.t_epoch[ep.item]) - eng._last[0]
        return math.sqrt(max(float(np.trace(P[sv, sv])) / 3.0, 0.0)) * max(dt, 0.0)

    def transform(self, ep):
        eng = self._engine(ep.layout, ep.n)
        r = self.antenna(ep)[0]
        self._prepared = ep.item
        return eng.prepare(ep.item, r, self._pos_sigma(ep))

    def matrices(self, ep):
        eng = self._engine(ep.layout, ep.n)
        r, Jr = self.antenna(ep)[:2]
        if self._prepared != ep.item:       # not asked for the transform (a check of H): no restarts applied
            eng.prepare(ep.item, r, 0.0)
            eng.slots.pending.clear()
        self._prepared = None
        prior = ep.prior if ep.prior is not None else (np.zeros(ep.n), None)
        return eng.rows(r, Jr, prior)

    @property
    def rtk(self):
        """The engine's per-epoch record (:class:`sinslab.fusion.rtk.RtkLog`)."""
        return None if self.engine is None else self.engine.log


def rtk_model(gyro_arw, accel_vrw, gyro_rrw=0.0, accel_rrw=0.0, *, slots, scale_factors=False, ambiguity_noise=1e-4):
    """The RTK/INS error model: φ, δv, δp, gyro bias, accelerometer bias (and scale factors
    with ``scale_factors=True``), then ``slots`` ambiguity states
    (:func:`sinslab.nav.errstate.carrier_ambiguities`) — no receiver clock: double
    differences have none."""
    sensors = [es.gyro_bias(rrw=gyro_rrw), es.accel_bias(arw=accel_rrw)]
    if scale_factors:
        sensors += [es.gyro_scale(), es.accel_scale()]
    sensors.append(es.carrier_ambiguities(slots, noise=ambiguity_noise))
    return es.ErrorModel("full", sensors, gyro_arw=gyro_arw, accel_vrw=accel_vrw)


@dataclass(frozen=True)
class RtkIns(LooselyCoupled):
    """Output of :func:`rtk_ins`: the fields of
    :class:`sinslab.fusion.loosely_coupled.LooselyCoupled` at the filter epochs (its fix
    records empty) and ``rtk`` the :class:`sinslab.fusion.rtk.RtkLog` of the GNSS epochs
    (status, ratio, integers fixed, float and fixed antenna positions with their
    covariances), ``counts`` (signals skipped by cause) and ``slips`` (restarts by cause)."""

    rtk: object = None
    counts: dict = None
    slips: dict = None


def rtk_ins(imu, init, rover, base: RtkBase, P0, model, options: RtkOptions = RtkOptions(), *,
            ins: InsSpec = InsSpec(), grid: FilterGrid = FilterGrid(), lever_arm=None, outages=(), aiding=(),
            feedback=True, progress=False, label="RTK/INS") -> RtkIns:
    """INS + double-differenced code and phase against a base with integer ambiguities,
    on the fusion driver (closed loop).

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
        On the time axis of ``rover.t_epoch``.
    init : sinslab.core.records.NavState
    rover : sinslab.fusion.gnss.SatelliteObservations
        With ``signals``.
    base : RtkBase
    P0 : array_like (n, n)
        Initial covariance; the ambiguity states' part is ignored (they start when their
        signals do).
    model : sinslab.nav.errstate.ErrorModel
        With a ``carrier_ambiguities`` block (e.g. :func:`rtk_model`).
    options : RtkOptions
    ins, grid, feedback, progress, label
        As :func:`sinslab.fusion.loosely_coupled.loosely_coupled`.
    lever_arm : array_like (3,), optional
        IMU -> antenna, body axes [m].
    outages : sequence of (start, length) [s]
        GNSS epochs not used.
    aiding : sequence of measurements
        Further measurements beside the double differences.

    Returns
    -------
    RtkIns
    """
    lay = model.layout
    sl = lay.find("ambiguity")
    if sl is None:
        raise ValueError(f"the model needs ambiguity states (blocks {list(lay.names)}): see rtk_model")
    P0 = np.array(P0, dtype=float)
    P0[sl, :] = 0.0
    P0[:, sl] = 0.0
    dd = DoubleDifferences(rover, base, options, lever_arm=lever_arm, outages=outages)
    r = loosely_coupled(imu, init, FixSpec(np.zeros(0), np.zeros((0, 3)), np.ones(3)), P0, model, ins=ins,
                        grid=grid, feedback=feedback, aiding=(dd, *aiding), progress=progress, label=label)
    base_f = {f.name: getattr(r, f.name) for f in fields(LooselyCoupled)}
    eng = dd.engine
    return RtkIns(**base_f, rtk=None if eng is None else eng.log,
                  counts=None if eng is None else dict(eng.counts, no_slot=eng.slots.full),
                  slips=None if eng is None else eng.slip_counts)
