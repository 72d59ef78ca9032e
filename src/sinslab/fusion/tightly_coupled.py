"""Tightly coupled INS/GNSS: the fusion driver with pseudoranges and range rates of each
satellite in place of position/velocity fixes (:func:`tightly_coupled`).

The composition is that of :func:`sinslab.fusion.loosely_coupled.loosely_coupled` with
no fixes: one live INS stream, the error model of :func:`tc_model` (the loosely coupled
states plus the receiver clock of :func:`sinslab.nav.errstate.receiver_clock`), and the
measurements :class:`sinslab.fusion.gnss.Pseudoranges` and
:class:`~sinslab.fusion.gnss.RangeRates` applied at every observation epoch. The clock
states are errors of a nominal clock taken from the first single-point solution (bias,
drift and inter-system biases at the first epoch that has one): the clock estimate is
``nominal − x``. :class:`RawGnss` holds the settings, builds the clock block and the
measurements, and is what :func:`sinslab.fusion.recorded.navigate_recorded` takes for
recorded data.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from sinslab.fusion.gnss import Pseudoranges, RangeRates, SatelliteObservations, single_point
from sinslab.fusion.loosely_coupled import LooselyCoupled, loosely_coupled
from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec
from sinslab.nav import errstate as es

__all__ = ["RawGnss", "tightly_coupled", "TightlyCoupled", "tc_model"]


@dataclass
class RawGnss:
    """Raw GNSS aiding: the prepared observations and how they are used.

    Attributes
    ----------
    sv : SatelliteObservations
    pseudorange_sigma : float
        σ₀ [m] (zenith, strong signal).
    doppler_sigma : float
        σ₀ [m/s]; ``use_doppler=False`` leaves the range rates out.
    mask : float
        Elevation mask [rad].
    cn0_ref : float
        [dB-Hz].
    gate : float or None
        Innovation gate [σ].
    max_satellites : tuple of (K, start, duration)
        Satellite limits (times on the IMU axis [s]).
    outages : tuple of (start, length)
        No GNSS epoch is used inside [s].
    clock_noise : (bias [m/√s], drift [m/s/√s], inter-system [m/√s])
    clock_sigma0 : (bias [m], drift [m/s], inter-system [m])
        Initial σ of the clock states about the nominal clock.
    nominal : tuple, optional
        ``(b0, d0, t0, {system: isb})``; default from the first single-point solution.
    """

    sv: SatelliteObservations
    pseudorange_sigma: float = 1.0
    doppler_sigma: float = 0.05
    use_doppler: bool = True
    mask: float = math.radians(10.0)
    cn0_ref: float = 45.0
    gate: float | None = 5.0
    max_satellites: tuple = ()
    outages: tuple = ()
    clock_noise: tuple = (0.5, 0.5, 1e-3)
    clock_sigma0: tuple = (30.0, 5.0, 10.0)
    nominal: tuple | None = None
    spp: object = field(default=None, repr=False)
    measurements: tuple = field(default=(), repr=False)

    @property
    def systems(self):
        return self.sv.systems

    def single_point(self):
        """The GNSS-only solution of the observations (computed once)."""
        if self.spp is None:
            self.spp = single_point(self.sv, mask=self.mask, sigma=self.pseudorange_sigma,
                                    sigma_rate=self.doppler_sigma, cn0_ref=self.cn0_ref)
        return self.spp

    def fixes(self):
        """The single-point solutions as :class:`~sinslab.core.records.Fixes` (quality 5,
        RTKLIB's 'single'), for what needs fixes: the start (levelling, heading from the
        course) and the GNSS-only reference."""
        from sinslab.core.records import Fixes
        sp = self.single_point()
        ok = np.isfinite(sp.lat) & np.all(np.isfinite(sp.vel), 1)
        if ok.sum() < 2:
            raise ValueError(f"{int(ok.sum())} single-point solution(s) in the GNSS log: at least 2 "
                             "epochs with 4 or more satellites above the mask are needed to start")
        return Fixes(sp.t[ok], sp.lat[ok], sp.lon[ok], sp.h[ok], sp.sigma[ok], sp.vel[ok], sp.sigma_vel[ok],
                     np.full(int(ok.sum()), 5), "single-point solution")

    def clock_nominal(self, t_start=None):
        """``(b0, d0, t0, {system: isb0})`` from the first single-point solution at or
        after ``t_start`` (the inter-system biases: the median residual of each system's
        satellites there); kept once made."""
        if self.nominal is not None:
            return self.nominal
        sp = self.single_point()
        ok = np.flatnonzero(np.isfinite(sp.clock) & np.isfinite(sp.drift)
                            & (sp.t >= (-np.inf if t_start is None else t_start - 1e-9)))
        if not ok.size:
            raise ValueError("no single-point solution in the GNSS log: the clock cannot be started "
                             "(fewer than 4 satellites with ephemeris at every epoch)")
        e = int(ok[0])
        isb = _isb_at(self.sv, sp, e)
        self.nominal = (float(sp.clock[e]), float(sp.drift[e]), float(sp.t[e]), isb)
        return self.nominal

    def clock_block(self):
        bn, dn, isn = self.clock_noise
        return es.receiver_clock(self.systems, bias_noise=bn, drift_noise=dn, isb_noise=isn)

    def clock_sigmas(self):
        b, d, i = self.clock_sigma0
        return np.r_[b, d, np.full(len(self.systems) - 1, i)]

    def make(self, lever_arm=None, outages=None, t_start=None):
        """The measurements (pseudoranges, then range rates), kept in ``measurements``;
        the nominal clock from the first single-point solution at or after ``t_start``."""
        kw = dict(lever_arm=lever_arm, mask=self.mask, cn0_ref=self.cn0_ref, gate=self.gate,
                  max_satellites=self.max_satellites, clock_nominal=self.clock_nominal(t_start),
                  outages=tuple(self.outages) if outages is None else tuple(outages), shared={})
        ms = [Pseudoranges(self.sv, self.pseudorange_sigma, **kw)]
        if self.use_doppler:
            ms.append(RangeRates(self.sv, self.doppler_sigma, **kw))
        self.measurements = tuple(ms)
        return self.measurements

    def clock_estimate(self, t, x, layout):
        """Receiver clock bias [m], drift [m/s] and inter-system biases [m] (M, k) at the
        epochs ``t`` from the filter's clock states ``x`` (M, n): nominal minus error."""
        b0, d0, t0, isb = self.clock_nominal()
        sl = layout.find("receiver_clock")
        xc = x[:, sl]
        out = np.empty_like(xc)
        out[:, 0] = b0 + d0 * (t - t0) - xc[:, 0]
        out[:, 1] = d0 - xc[:, 1]
        for j, s in enumerate(self.systems[1:]):
            out[:, 2 + j] = isb.get(s, 0.0) - xc[:, 2 + j]
        return out


def _isb_at(sv, sp, e):
    """Inter-system biases [m] at epoch ``e``: the mean pseudorange residual of each
    system's satellites at the single-point position, minus the reference system's."""
    from sinslab.core import earth as E
    from sinslab.core import gnss as G
    rows = sv.rows(e)
    rows = rows[sv.usable[rows] & np.isfinite(sv.pseudorange[rows])]
    r = E.geodetic_to_ecef(sp.lat[e], sp.lon[e], sp.h[e])
    rho, _ = G.sagnac_range(sv.sat_pos[rows], r)
    el, az = E.elevation_azimuth(sv.sat_pos[rows], sp.lat[e], sp.lon[e], sp.h[e])
    from sinslab.fusion.gnss import F_L1
    corr = (G.klobuchar(sv.t_epoch[e] - sv.t_ref, sp.lat[e], sp.lon[e], az, el, sv.iono)
            * (F_L1 / sv.freq[rows]) ** 2 + G.saastamoinen(sp.lat[e], sp.h[e], el))
    res = sv.pseudorange[rows] - (rho - sv.sat_clock[rows] + corr + sp.clock[e])
    out = {}
    for s in sv.systems[1:]:
        m = (sv.system[rows] == s) & (el > 0)
        out[s] = float(np.median(res[m])) if m.any() else 0.0
    return out


def tc_model(gyro_arw, accel_vrw, gyro_rrw=0.0, accel_rrw=0.0, *, systems=("G",), clock_noise=(0.1, 0.1, 1e-4),
             scale_factors=False):
    """The tightly coupled error model: φ, δv, δp, gyro bias ε, accelerometer bias ∇ (and
    scale factors with ``scale_factors=True``) as :func:`~sinslab.fusion.loosely_coupled.lc_model`,
    plus the receiver clock block ``clk`` (bias, drift, one inter-system bias per system
    after the first)."""
    sensors = [es.gyro_bias(rrw=gyro_rrw), es.accel_bias(arw=accel_rrw)]
    if scale_factors:
        sensors += [es.gyro_scale(), es.accel_scale()]
    bn, dn, isn = clock_noise
    sensors.append(es.receiver_clock(tuple(systems), bias_noise=bn, drift_noise=dn, isb_noise=isn))
    return es.ErrorModel("full", sensors, gyro_arw=gyro_arw, accel_vrw=accel_vrw)


@dataclass(frozen=True)
class TightlyCoupled(LooselyCoupled):
    """Output of :func:`tightly_coupled` at the filter epochs (every ``kf_dt``): the fields
    of :class:`sinslab.fusion.loosely_coupled.LooselyCoupled` (its fix records empty) and
    ``clock`` (M, k) the receiver clock estimate (bias [m], drift [m/s], inter-system
    biases [m]); ``pseudoranges`` and ``range_rates`` the measurement objects, whose
    ``log`` holds per epoch the satellites, their elevation, azimuth, C/N0, innovation,
    σ, ν²/S and whether they were used or rejected.
    """

    clock: np.ndarray = None
    pseudoranges: object = None
    range_rates: object = None


def tightly_coupled(imu, init, raw: RawGnss, P0, model, *, ins: InsSpec = InsSpec(),
                    grid: FilterGrid = FilterGrid(), lever_arm=None, feedback=True, aiding=(),
                    history=None, progress=False, label="tightly coupled") -> TightlyCoupled:
    """INS + pseudoranges and range rates of each satellite with an error-state Kalman
    filter on the fusion driver.

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
        IMU increments on the time axis of the observations (``raw.sv.t_epoch``).
    init : sinslab.core.records.NavState
        Initial navigation state (IMU point) at the start.
    raw : RawGnss
        Observations and settings.
    P0 : array_like (n, n)
        Initial covariance; the clock block's part is replaced by ``raw.clock_sigmas()²``
        when left zero.
    model : sinslab.nav.errstate.ErrorModel
        With a ``clk`` block for ``raw.systems`` (e.g. :func:`tc_model`).
    ins : InsSpec
        How the INS stream runs (subsamples, initial compensation, start).
    grid : FilterGrid
        The filter step and how the driver walks the grid.
    lever_arm : array_like (3,), optional
        IMU -> antenna, body axes [m].
    feedback, aiding, progress, history
        As in :func:`sinslab.fusion.loosely_coupled.loosely_coupled`.

    Returns
    -------
    TightlyCoupled
    """
    lay = model.layout
    sl = lay.find("receiver_clock")
    if sl is None:
        raise ValueError(f"the model needs a receiver-clock block (has {list(lay.names)})")
    P0 = np.array(P0, dtype=float)
    if not np.any(P0[sl, sl]):
        P0[sl, sl] = np.diag(raw.clock_sigmas() ** 2)
    ms = raw.make(lever_arm=lever_arm, t_start=ins.t_start if ins.t_start is not None else (
        float(imu.t[ins.start - 1]) if ins.start > 0 else imu.t0))
    r = loosely_coupled(imu, init, FixSpec(np.zeros(0), np.zeros((0, 3)), np.ones(3)), P0, model,
                        ins=ins, grid=grid, feedback=feedback, aiding=(*ms, *aiding), progress=progress, label=label,
                        history=history)
    base = {f.name: getattr(r, f.name) for f in fields(LooselyCoupled)}
    return TightlyCoupled(**base, clock=raw.clock_estimate(r.t, r.x, lay), pseudoranges=ms[0],
                          range_rates=ms[1] if len(ms) > 1 else None)
