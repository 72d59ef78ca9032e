"""Tightly coupled INS/GNSS: the fusion driver with pseudoranges and range rates of each
satellite in place of position/velocity fixes (:func:`tightly_coupled`).

The composition is the INS core of the loosely coupled filter
(:func:`sinslab.fusion.loosely_coupled.ins_core`: one live INS stream on the filter grid)
with other measurements: the error model of :func:`tc_model` (the loosely coupled states
plus the receiver clock of :func:`sinslab.nav.errstate.receiver_clock`), and
:class:`sinslab.fusion.gnss.Pseudoranges` and :class:`~sinslab.fusion.gnss.RangeRates`
applied at every observation epoch. The clock states are errors of a nominal clock taken
from the first single-point solution at or after the start (bias, drift and
inter-system biases at the first epoch that has one): the clock estimate is
``nominal − x``. :class:`RawGnss` holds the observations and the settings, builds the
clock block and the measurements; :class:`RawSource` is the raw observations as the
GNSS source of a recorded run (:func:`sinslab.fusion.recorded.navigate_recorded`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from sinslab.fusion.gnss import Pseudoranges, RangeRates, SatelliteObservations, single_point
from sinslab.fusion.lag import ExactReprocessing
from sinslab.fusion.loosely_coupled import ins_core
from sinslab.fusion.spec import FilterGrid, InsSpec
from sinslab.nav import errstate as es

__all__ = ["RawGnss", "RawSource", "tightly_coupled", "TightlyCoupled", "tc_model"]


@dataclass(frozen=True, eq=False)
class RawGnss:
    """Raw GNSS aiding: the prepared observations and how they are used. The single-point
    solution of the observations is computed once (:attr:`spp`).

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
        ``(b0, d0, t0, {system: isb})``; default from the first single-point solution at
        or after the start (:meth:`clock_nominal`).
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

    @property
    def systems(self):
        return self.sv.systems

    @cached_property
    def spp(self):
        """The GNSS-only solution of the observations (:func:`~sinslab.fusion.gnss.single_point`)."""
        return single_point(self.sv, mask=self.mask, sigma=self.pseudorange_sigma,
                            sigma_rate=self.doppler_sigma, cn0_ref=self.cn0_ref)

    def single_point(self):
        """The GNSS-only solution of the observations (computed once)."""
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
        """``(b0, d0, t0, {system: isb0})``: the one given, or from the first single-point
        solution at or after ``t_start`` (the inter-system biases: the median residual of
        each system's satellites there)."""
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
        return float(sp.clock[e]), float(sp.drift[e]), float(sp.t[e]), isb

    def clock_block(self):
        bn, dn, isn = self.clock_noise
        return es.receiver_clock(self.systems, bias_noise=bn, drift_noise=dn, isb_noise=isn)

    def clock_sigmas(self):
        b, d, i = self.clock_sigma0
        return np.r_[b, d, np.full(len(self.systems) - 1, i)]

    def make(self, nominal, lever_arm=None, outages=None):
        """The measurements (pseudoranges, then range rates) about the nominal clock
        ``nominal`` (:meth:`clock_nominal`)."""
        kw = dict(lever_arm=lever_arm, mask=self.mask, cn0_ref=self.cn0_ref, gate=self.gate,
                  max_satellites=self.max_satellites, clock_nominal=nominal,
                  outages=tuple(self.outages) if outages is None else tuple(outages), shared={})
        ms = [Pseudoranges(self.sv, self.pseudorange_sigma, **kw)]
        if self.use_doppler:
            ms.append(RangeRates(self.sv, self.doppler_sigma, **kw))
        return tuple(ms)

    def clock_estimate(self, t, x, layout, nominal):
        """Receiver clock bias [m], drift [m/s] and inter-system biases [m] (M, k) at the
        epochs ``t`` from the filter's clock states ``x`` (M, n): ``nominal`` minus error."""
        b0, d0, t0, isb = nominal
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
class TightlyCoupled:
    """Output of :func:`tightly_coupled` at the filter epochs (every ``kf_dt``).

    ``t`` (M,), ``nav`` (M, 10), ``x``, ``sigma`` (M, n), ``gyro_bias``, ``accel_bias``
    (M, 3), ``scale`` (M, 6) or None, ``layout``, ``history`` as in
    :class:`sinslab.fusion.loosely_coupled.LooselyCoupled`; ``clock`` (M, k) the receiver
    clock estimate (bias [m], drift [m/s], inter-system biases [m]); ``pseudoranges`` and
    ``range_rates`` the driver's record of every satellite's row per epoch
    (:class:`sinslab.fusion.observer.RowLog`: the satellites, their elevation, azimuth,
    C/N0, innovation, σ, ν²/S and whether they were used or rejected).
    """

    t: np.ndarray
    nav: np.ndarray
    x: np.ndarray
    sigma: np.ndarray
    gyro_bias: np.ndarray
    accel_bias: np.ndarray
    scale: np.ndarray | None
    layout: object
    history: object
    clock: np.ndarray
    pseudoranges: object
    range_rates: object = None


def _clock_prior(P0, raw, lay):
    """``P0`` with the clock block's part ``raw.clock_sigmas()²`` where it was left zero."""
    sl = lay.find("receiver_clock")
    if sl is None:
        raise ValueError(f"the model needs a receiver-clock block (has {list(lay.names)})")
    P0 = np.array(P0, dtype=float)
    if not np.any(P0[sl, sl]):
        P0[sl, sl] = np.diag(raw.clock_sigmas() ** 2)
    return P0


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
        As in :func:`sinslab.fusion.loosely_coupled.loosely_coupled` (the satellites'
        measurements come first, then ``aiding``).

    Returns
    -------
    TightlyCoupled
    """
    lay = model.layout
    P0 = _clock_prior(P0, raw, lay)
    nominal = raw.clock_nominal(ins.t_start if ins.t_start is not None else (
        float(imu.t[ins.start - 1]) if ins.start > 0 else imu.t0))
    ms = raw.make(nominal, lever_arm=lever_arm)
    core = ins_core(imu, init, model, ins, grid, ExactReprocessing(), feedback)
    r = core.run(P0, [*ms, *aiding], grid=grid, progress=progress, label=label, history=history)
    return TightlyCoupled(r.t, r.nav[0], r.x, r.sigma, r.gyro_bias[0], r.accel_bias[0],
                          r.scale[0] if r.scale is not None else None, r.layout, r.history,
                          raw.clock_estimate(r.t, r.x, lay, nominal), r.decisions.rows_of(0),
                          r.decisions.rows_of(1) if len(ms) > 1 else None)


#: the labels of the raw source's measurements, by kind
_LABELS = {"pseudorange": "pseudoranges", "Doppler": "range_rates"}


@dataclass(frozen=True, eq=False)
class RawSource:
    """Raw GNSS observations as the GNSS source of a recorded run
    (:class:`sinslab.fusion.aids.base.GnssSource`; tightly coupled): the single-point
    solutions start the filter (and are what the solution is compared with), the
    pseudoranges and range rates of every satellite are its measurements, the receiver
    clock its states."""

    raw: RawGnss
    name = "raw"

    def start_fixes(self):
        return self.raw.fixes()

    def prepare(self, fixes):
        return fixes, self

    def states(self):
        from sinslab.fusion.aids.base import State
        return (State(self.raw.clock_block(), self.raw.clock_sigmas()),)

    def plan(self, setup, fixes, lever_block):
        from sinslab.fusion.aids.base import Plan
        if lever_block is not None:
            raise ValueError("the antenna lever-arm states (--aid lever) are estimated from position and "
                             "velocity fixes; with raw GNSS the lever arm given (--lever-arm) is used")
        nominal = self.raw.clock_nominal(setup.t_start)
        ms = self.raw.make(nominal, lever_arm=setup.lever_arm, outages=setup.outages)
        return Plan(tuple((_LABELS[m.kind], m) for m in ms), {"nominal": nominal})

    def report(self, plan, run):
        from sinslab.fusion.aids.base import SourceReport, Table
        from sinslab.fusion.observer import RowLog
        rows = {label: run.rows.get(label) or RowLog() for label, _ in plan.measurements}
        clock = self.raw.clock_estimate(run.t, run.x, run.layout, plan.facts["nominal"])
        sigma = run.sigma[:, run.layout.find("receiver_clock")]
        metrics, lines = _satellite_metrics(rows, self.raw)
        tables = (Table("gnss_satellites", _satellite_table(rows, float(run.t[0])),
                        "per epoch and satellite: elevation, azimuth, C/N0, pseudorange and Doppler innovations "
                        "(before the update), σ, used/rejected"),
                  Table("gnss_clock", _clock_table(run.t, clock, sigma, self.raw.systems),
                        "receiver clock estimate (bias, drift, inter-system biases against the first system) "
                        "and σ at every filter epoch"))
        note = (f"Tightly coupled: pseudoranges{' and Doppler' if 'range_rates' in rows else ''} of "
                f"{metrics['gnss_systems']} satellites above {metrics['elevation_mask_deg']:g} deg; the filter "
                "starts from the single-point solution (GNSS-only least squares) and the fix tables compare "
                "with it. t_abs_s is GPS time (seconds since 1970 without leap seconds).")
        return SourceReport(self.name, "raw GNSS: pseudoranges and Doppler per satellite", metrics=metrics,
                            tables=tables, notes=(note,), lines=lines, coupling="tightly coupled", rows=rows,
                            reference="the single-point solution", clock=(clock, sigma))


def _satellite_metrics(rows, raw):
    """Counts of the satellites' rows (epochs used, rows used and refused, left out by
    cause, satellites per epoch) and the terminal line."""
    pr, dp = rows["pseudoranges"], rows.get("range_rates")
    c = pr.counts()
    n_used = pr.used_per_epoch()
    m = dict(gnss_epochs_used=int(np.sum(n_used > 0)), gnss_epochs=len(pr.t),
             pseudoranges_used=c["used"], pseudoranges_rejected=c["rejected"],
             doppler_used=dp.counts()["used"] if dp else 0,
             doppler_rejected=dp.counts()["rejected"] if dp else 0,
             satellites_below_mask=c.get("below_mask", 0), satellites_over_limit=c.get("over_limit", 0),
             observations_without_ephemeris=c.get("no_ephemeris", 0),
             satellites_used_median=float(np.median(n_used)) if n_used.size else 0.0,
             satellites_used_min=int(n_used.min()) if n_used.size else 0,
             gnss_systems="".join(raw.systems), elevation_mask_deg=math.degrees(raw.mask))
    line = (f"  raw GNSS: {m['gnss_epochs_used']} of {m['gnss_epochs']} epochs used, {c['used']} pseudoranges "
            f"({c['rejected']} rejected by the gate), median {m['satellites_used_median']:.0f} satellites "
            f"({m['gnss_systems']})")
    return m, (line,)


def _satellite_table(rows, t0):
    """``gnss_satellites``: one row per epoch and candidate satellite (times from ``t0``)."""
    pr, dp = rows["pseudoranges"], rows.get("range_rates")
    cols = {"t_s": [], "sat": [], "elevation_deg": [], "azimuth_deg": [], "cn0_dbhz": [],
            "pr_innovation_m": [], "pr_sigma_m": [], "pr_used": [], "pr_rejected": [],
            "doppler_innovation_mps": [], "doppler_used": [], "doppler_rejected": []}
    meta = pr.meta
    for k, t in enumerate(pr.t):
        n = meta["sat"][k].size
        cols["t_s"].append(np.full(n, t - t0))
        cols["sat"].append(meta["sat"][k])
        cols["elevation_deg"].append(np.degrees(meta["el"][k]))
        cols["azimuth_deg"].append(np.degrees(meta["az"][k]))
        cols["cn0_dbhz"].append(meta["cn0"][k])
        cols["pr_innovation_m"].append(pr.innovation[k])
        cols["pr_sigma_m"].append(pr.sigma[k])
        cols["pr_used"].append(pr.used[k].astype(int))
        cols["pr_rejected"].append(pr.rejected[k].astype(int))
        if dp is not None and k < len(dp.t):
            cols["doppler_innovation_mps"].append(dp.innovation[k])
            cols["doppler_used"].append(dp.used[k].astype(int))
            cols["doppler_rejected"].append(dp.rejected[k].astype(int))
        else:
            cols["doppler_innovation_mps"].append(np.full(n, np.nan))
            cols["doppler_used"].append(np.zeros(n, int))
            cols["doppler_rejected"].append(np.zeros(n, int))
    return {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in cols.items()}


def _clock_table(t, clock, sigma, systems):
    """``gnss_clock``: the clock estimate and σ at every filter epoch (times from the first)."""
    ck = {"t_s": t - float(t[0]), "bias_m": clock[:, 0], "drift_mps": clock[:, 1],
          "sigma_bias_m": sigma[:, 0], "sigma_drift_mps": sigma[:, 1]}
    for j, s in enumerate(systems[1:]):
        ck[f"isb_{s}_m"] = clock[:, 2 + j]
    return ck
