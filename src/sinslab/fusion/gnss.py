"""Raw GNSS measurements of the fusion driver: pseudorange and range rate (Doppler) per
satellite, with the receiver clock of :func:`sinslab.nav.errstate.receiver_clock`, and the
GNSS-only single-point solution from the same observations.

Preparation (:func:`prepare`) computes once, for every observation, what does not depend
on the receiver: the satellite position, velocity, clock offset and drift at the
transmission time (:func:`sinslab.core.gnss.transmit_states`), the group-delay
correction and the wavelength. The measurements then compare each epoch's observations
with the antenna of the INS stream:

``ρ̂ = |r_s − r_a| + ω_e (x_s y_a − y_s x_a)/c + b + b_sys − c δt_s + I + T``

(Sagnac term, receiver clock bias ``b`` [m] and the inter-system bias of the satellite's
system, satellite clock with the relativistic term and the group delay, Klobuchar
ionosphere ``I`` scaled by ``(f_L1/f)²``, Saastamoinen troposphere ``T``), and the range
rate ``ρ̇̂ = (v_s − v_a)·e + ω_e (v_sy x_a + y_s v_ax − v_sx y_a − x_s v_ay)/c + d − c δṫ_s``
with ``e`` the unit line of sight and ``d`` the clock drift [m/s]. The antenna is the IMU
point plus ``C_b^n l`` (lever arm ``l``, body axes), moved back to the observation time
with its velocity when the filter epoch is later. ``z`` is predicted minus measured, so
that ``z = H x + noise`` for the error state ``x`` (computed minus true) of
:mod:`sinslab.nav.errstate`; the clock states are errors of a nominal clock
``b₀ + d₀ (t − t₀)`` the measurement keeps (not fed back: they are the receiver's).

Each satellite is one row, weighted by elevation and C/N0
(``σ² = σ₀² 10^{max(0, C/N0_ref − C/N0)/10} / sin² el``); satellites below the elevation
mask, without ephemeris or beyond the ``max_satellites`` windows are left out, and an
innovation gate rejects single rows whose ``ν²/(H P Hᵀ + R)`` exceeds ``gate²`` against
the filter's prior: the measurement declares it (``row_gate``, a
:class:`~sinslab.fusion.measurements.RowGate`) and answers each epoch with its candidate
rows (:class:`~sinslab.fusion.measurements.Rows`: every satellite of the epoch, the ones
it formed a row for, their name, elevation, azimuth and C/N0, and the ones left out by
cause); the driver gates the rows and records, epoch by epoch, what was used and refused
(:class:`sinslab.fusion.observer.RowLog`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import attitude as Att
from sinslab.core import earth as E
from sinslab.core import gnss as G
from sinslab.fusion.measurements import Epoch, RowGate, Rows, add_rate_H, arrival_epochs

__all__ = ["SatelliteObservations", "SatelliteMeasurement", "prepare", "Pseudoranges", "RangeRates",
           "single_point", "SinglePoint", "F_L1"]

F_L1 = 1575.42e6           #: GPS L1 / Galileo E1 carrier [Hz] (the Klobuchar delay is for it)


@dataclass(frozen=True)
class SatelliteObservations:
    """Observations made ready for the measurements: one row per satellite and epoch.

    Attributes
    ----------
    t_ref : int
        GPS seconds since 1970 of the relative times of the source (for the ionosphere's
        time of day); ``t`` below is absolute.
    t_epoch : ndarray (E,)
        Epoch times on the IMU's time axis [s] (``t_ref`` + reception time + ``t_offset``).
    epoch : int ndarray (M,)
    sat : str ndarray (M,)
    system : str ndarray (M,)
        The satellite's system letter.
    pseudorange : ndarray (M,)
        [m], with the satellite's group delay removed.
    range_rate : ndarray (M,)
        ``−λ · Doppler`` [m/s] (NaN without Doppler).
    freq : ndarray (M,)
        [Hz].
    cn0 : ndarray (M,)
        [dB-Hz].
    sat_pos, sat_vel : ndarray (M, 3)
        ECEF at transmission [m], [m/s].
    sat_clock, sat_drift : ndarray (M,)
        ``c δt_s`` [m] and ``c δṫ_s`` [m/s].
    iono : ndarray (8,)
        Klobuchar coefficients (zeros: the default set).
    usable : bool ndarray (M,)
        An ephemeris was found (the others are skipped and counted).
    signals : sinslab.core.gnss.Signals, optional
        Every signal of each row (carrier phase among them), as read.
    """

    t_ref: int
    t_epoch: np.ndarray
    epoch: np.ndarray
    sat: np.ndarray
    system: np.ndarray
    pseudorange: np.ndarray
    range_rate: np.ndarray
    freq: np.ndarray
    cn0: np.ndarray
    sat_pos: np.ndarray
    sat_vel: np.ndarray
    sat_clock: np.ndarray
    sat_drift: np.ndarray
    iono: np.ndarray
    usable: np.ndarray
    signals: object = None

    @property
    def systems(self):
        """Systems with usable observations, GPS first, then E, C, R, J."""
        order = "GECRJ"
        have = set(self.system[self.usable].tolist())
        return tuple(s for s in order if s in have)

    def rows(self, e):
        """Observation rows of epoch ``e``."""
        idx = self.__dict__.setdefault("_rows", None)
        if idx is None:
            b = np.searchsorted(self.epoch, np.arange(self.t_epoch.size + 1))
            idx = b
            object.__setattr__(self, "_rows", b)
        return np.arange(idx[e], idx[e + 1])


def _group_delay(obs, rows):
    """Group-delay correction [m] to subtract from each pseudorange: GPS/QZSS TGD on L1,
    Galileo BGD(E1,E5b) on E1 (I/NAV), BeiDou TGD1 on B1; other signals and systems 0."""
    out = np.zeros(rows.size)
    eph = obs.eph
    for i, (s, r, c) in enumerate(zip(obs.sat, rows, obs.code)):
        if r < 0 or s[0] == "R" or c[0] != "1" and not (s[0] == "C" and c[0] == "2"):
            continue
        tg = eph.tgd[r]
        k = 1 if s[0] == "E" and tg[1] != 0 else 0
        out[i] = G.C_LIGHT * tg[k]
    return out


def prepare(obs, *, t_offset=0.0, systems=None) -> SatelliteObservations:
    """Satellite states and corrected observables of every observation of ``obs``.

    Parameters
    ----------
    obs : sinslab.data.gnss.GnssObservations (or an object with its attributes)
    t_offset : float
        Added to the epoch times to put them on the IMU's time axis [s].
    systems : str, optional
        Letters of the systems to use (default all but SBAS, which broadcasts no orbit).

    Returns
    -------
    SatelliteObservations
    """
    keep = np.array([s[0] in (systems or "GRECJ") for s in obs.sat], dtype=bool)
    sat = obs.sat[keep]
    ep = obs.epoch[keep]
    P = obs.pseudorange[keep]
    t_rx = obs.epoch_t[ep]
    pos, vel, dts, ddts, rows = G.transmit_states(obs.eph, obs.geph, sat, t_rx, P)
    sub = type("Sub", (), {})()
    sub.sat, sub.code, sub.eph = sat, obs.code[keep], obs.eph
    glo = np.array([s[0] == "R" for s in sat], dtype=bool)
    tgd = _group_delay(sub, np.where(glo, -1, rows))
    lam = G.C_LIGHT / obs.freq[keep]
    return SatelliteObservations(
        int(obs.t_ref), obs.t_ref + obs.epoch_t + float(t_offset), ep, sat,
        np.array([s[0] for s in sat]), P - tgd, -lam * obs.doppler[keep], obs.freq[keep],
        obs.cn0[keep], pos, vel, G.C_LIGHT * dts, G.C_LIGHT * ddts, np.asarray(obs.iono, float),
        rows >= 0, None if getattr(obs, "signals", None) is None else obs.signals[keep])


def _enu_derivatives(lat, lon):
    """``C_n^e`` and its derivatives with respect to latitude and longitude."""
    sL, cL, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    C = np.array([[-so, -sL * co, cL * co], [co, -sL * so, cL * so], [0.0, cL, sL]])
    dL = np.array([[0.0, -cL * co, -sL * co], [0.0, -cL * so, -sL * so], [0.0, -sL, cL]])
    dl = np.array([[-co, sL * so, -cL * so], [-so, -sL * co, cL * co], [0.0, 0.0, 0.0]])
    return C, dL, dl


def _limits(max_satellites):
    out = []
    for item in max_satellites or ():
        k, s, d = item
        if int(k) < 0 or not (d > 0):
            raise ValueError(f"max_satellites: K >= 0 and a duration > 0 s, got {item!r}")
        out.append((int(k), float(s), float(s) + float(d)))
    return tuple(out)


class SatelliteMeasurement:
    """Base of :class:`Pseudoranges` and :class:`RangeRates`: the schedule (one item per
    epoch), the antenna, the satellite selection and the row gate (see the module notes).

    Parameters
    ----------
    sv : SatelliteObservations
    sigma : float
        σ₀ of one observation at zenith and C/N0 at or above ``cn0_ref`` [m or m/s].
    lever_arm : array_like (3,), optional
        IMU -> antenna, body axes [m].
    mask : float
        Elevation mask [rad].
    cn0_ref : float
        [dB-Hz].
    gate : float or None
        Innovation gate in σ of ``H P Hᵀ + R`` (None: none).
    gate_reset : int
        After this many consecutive epochs whose every row was rejected the gate opens
        for one epoch (the filter, not all satellites, is then wrong).
    max_satellites : sequence of (K, start, duration)
        Inside ``[start, start + duration)`` [s, IMU time axis] at most K satellites,
        highest elevation first.
    clock : str, optional
        Name of the receiver-clock block, when a layout has several; by default the
        layout's one block of that quantity (:meth:`~sinslab.nav.errstate.StateLayout.find`).
    clock_nominal : (b0 [m], d0 [m/s], t0 [s]) or (b0, d0, t0, {system: isb [m]})
        Nominal clock the clock states are errors of (and nominal inter-system biases).
    outages : sequence of (start, length) [s]
        Epochs inside are not used.
    stream : int
    shared : dict, optional
        A cache of the epoch's antenna geometry shared by the measurements of one
        receiver (pseudoranges and range rates of the same observations).
    """

    kind = ""
    gate = None                 # no gate of the whole update: the rows are gated one by one

    def __init__(self, sv: SatelliteObservations, sigma, *, lever_arm=None, mask=math.radians(10.0),
                 cn0_ref=45.0, gate=5.0, gate_reset=10, max_satellites=(), clock=None,
                 clock_nominal=(0.0, 0.0, 0.0), outages=(), stream=0, shared=None):
        self.sv = sv
        self.sigma = float(sigma)
        if not (self.sigma > 0 and math.isfinite(self.sigma)):
            raise ValueError(f"{self.kind} sigma must be > 0, got {sigma!r}")
        lever = np.zeros(3) if lever_arm is None else np.asarray(lever_arm, float).reshape(3)
        self.lever = lever
        self.mask = float(mask)
        self.cn0_ref = float(cn0_ref)
        #: the gate of single rows the driver applies (``sigmas`` None: none)
        self.row_gate = RowGate(gate, gate_reset)
        self.limits = _limits(max_satellites)
        self.clock = clock
        self.nominal = tuple(float(v) for v in clock_nominal[:3])
        #: nominal inter-system biases [m] by system letter (default 0)
        self.isb_nominal = dict(clock_nominal[3]) if len(clock_nominal) > 3 else {}
        self.outages = tuple(outages)
        self.stream = int(stream)
        self.shared = {} if shared is None else shared

    # -- schedule
    def epochs(self, grid):
        return arrival_epochs(self.sv.t_epoch, self.sv.t_epoch, grid, outages=self.outages)

    def times(self, item):
        t = float(self.sv.t_epoch[item])
        return t, t

    # -- antenna
    def antenna(self, ep: Epoch):
        """Antenna ECEF position and velocity at the observation time, with their
        Jacobians (3, n) with respect to the error state; the geometry of the epoch
        (with the satellites' elevation and azimuth) is shared with the other measurement
        made by the same :class:`RawGnss`-like owner (``shared``), which asks for the same
        rows at the same epoch."""
        nr = ep.streams[self.stream]
        key = (ep.item, ep.t, nr.row.tobytes(), nr.omega_b.tobytes(), self.lever.tobytes(), ep.layout)
        if self.shared.get("key") == key:
            return self.shared["antenna"]
        out = self._antenna(ep, nr)
        rows = self.sv.rows(ep.item)
        lat, lon, h = out[4]
        el, az = E.elevation_azimuth(self.sv.sat_pos[rows], lat, lon, h)
        self.shared.clear()
        self.shared.update(key=key, antenna=(*out, el, az))
        return self.shared["antenna"]

    def _antenna(self, ep, nr):
        lay, n = ep.layout, ep.n
        lat, lon, h = float(nr.lat), float(nr.lon), float(nr.h)
        C = nr.C_bn
        Cl = C @ self.lever
        w, l_ = nr.omega_b, self.lever
        wl = np.array([w[1] * l_[2] - w[2] * l_[1], w[2] * l_[0] - w[0] * l_[2], w[0] * l_[1] - w[1] * l_[0]])
        v_ant = nr.vel + C @ wl                     # ENU
        Jv = np.zeros((3, n))
        Jv[:, lay.slice("dv")] = np.eye(3)
        Jv[:, lay.slice("phi")] = Att.skew(C @ wl)
        add_rate_H(Jv, lay, -C @ Att.skew(self.lever), w)   # every block feeding the gyro
        dt = ep.t - float(self.sv.t_epoch[ep.item])
        Cne, dCL, dCl = _enu_derivatives(lat, lon)
        rm, rn = E.radii_s(lat, h)
        off = Cl - v_ant * dt
        cL = math.cos(lat)
        r = np.array([rn * cL * math.cos(lon), rn * cL * math.sin(lon),
                      (rn - h) * (1.0 - E.E2) * math.sin(lat) + h * math.sin(lat)]) + Cne @ off
        sp = lay.slice("dp")
        Jr = -dt * Cne @ Jv
        Jr[:, lay.slice("phi")] += Cne @ Att.skew(Cl)
        Jr[:, sp.start] += rm * Cne[:, 1] + dCL @ off
        Jr[:, sp.start + 1] += rn * math.cos(lat) * Cne[:, 0] + dCl @ off
        Jr[:, sp.start + 2] += Cne[:, 2]
        v = Cne @ v_ant
        Jve = Cne @ Jv
        Jve[:, sp.start] += dCL @ v_ant
        Jve[:, sp.start + 1] += dCl @ v_ant
        return r, Jr, v, Jve, (lat, lon, h), dt

    # -- selection and gate
    def _select(self, ep, rows, el):
        sv = self.sv
        ok = sv.usable[rows] & np.isfinite(self._observable(rows))
        no_eph = int(np.sum(~sv.usable[rows]))
        above = ok & (el >= self.mask)
        below = int(np.sum(ok & (el < self.mask)))
        keep = above.copy()
        over = 0
        t = float(sv.t_epoch[ep.item])
        for k, a, b in self.limits:
            if a <= t < b and np.sum(keep) > k:
                idx = np.flatnonzero(keep)
                drop = idx[np.argsort(-el[idx], kind="stable")[k:]]
                keep[drop] = False
                over = int(drop.size)
        return keep, below, over, no_eph

    def _weights(self, rows, el):
        c = np.maximum(self.cn0_ref - self.sv.cn0[rows], 0.0)
        return self.sigma ** 2 * 10.0 ** (c / 10.0) / np.maximum(np.sin(el), 0.05) ** 2

    def matrices(self, ep: Epoch) -> Rows:
        sv = self.sv
        rows = sv.rows(ep.item)
        r, Jr, v, Jv, (lat, lon, h), dt, el, az = self.antenna(ep)
        keep, below, over, no_eph = self._select(ep, rows, el)
        k = rows[keep]
        z, H = self._model(ep, k, r, Jr, v, Jv, el[keep], az[keep], (lat, lon, h), dt)
        return Rows(z, H, self._weights(k, el[keep]), keep,
                    dict(sat=sv.sat[rows], el=el, az=az, cn0=sv.cn0[rows]),
                    dict(below_mask=below, over_limit=over, no_ephemeris=no_eph))

    def _clock_columns(self, lay, systems):
        """Columns of the clock bias, drift and of each row's inter-system bias (−1: none)."""
        sl = lay.find("receiver_clock", self.clock)
        if sl is None:
            raise ValueError(f"the layout has no receiver-clock block (blocks {list(lay.names)})")
        labels = lay.labels[sl]
        isb = {lab.rsplit("_", 1)[1]: sl.start + i for i, lab in enumerate(labels) if "_isb_" in lab}
        cols = np.array([isb.get(s, -1) for s in systems], dtype=np.int64)
        return sl.start, sl.start + 1, cols


class Pseudoranges(SatelliteMeasurement):
    """Pseudorange per satellite (see the module notes); rows ``ρ̂ − P`` [m].

    ``sigma`` (σ₀) defaults to 1 m (code noise and multipath of a current consumer receiver
    under open sky)."""

    kind = "pseudorange"

    def __init__(self, sv, sigma=1.0, **kw):
        super().__init__(sv, sigma, **kw)

    def _observable(self, rows):
        return self.sv.pseudorange[rows]

    def _model(self, ep, k, r, Jr, v, Jv, el, az, llh, dt):
        sv = self.sv
        lay = ep.layout
        rs = sv.sat_pos[k]
        rho, u = G.sagnac_range(rs, r)
        lat, lon, h = llh
        t_gps = sv.t_epoch[ep.item] - sv.t_ref
        iono = G.klobuchar(t_gps, lat, lon, az, el, sv.iono) * (F_L1 / sv.freq[k]) ** 2
        trop = G.saastamoinen(lat, h, el)
        dtrop_dh = G.saastamoinen(lat, h + 1.0, el) - trop
        ib, idr, isb_cols = self._clock_columns(lay, sv.system[k])
        b0, d0, t0 = self.nominal
        t_obs = float(sv.t_epoch[ep.item])
        clock = b0 + d0 * (t_obs - t0)
        isb0 = np.array([self.isb_nominal.get(s_, 0.0) for s_ in sv.system[k]])
        z = rho + clock + isb0 - sv.sat_clock[k] + iono + trop - sv.pseudorange[k]
        # ∂ρ/∂r_a: −e, and the Sagnac term's ω_e/c [−y_s, x_s, 0]
        g = -u + (E.WIE / G.C_LIGHT) * np.stack([-rs[:, 1], rs[:, 0], np.zeros(k.size)], -1)
        H = g @ Jr
        # the troposphere is taken at the IMU's height (elevation and pierce-point
        # changes of the models, below 1e-5 m per metre, are left out)
        H[:, lay.slice("dp").start + 2] += dtrop_dh
        H[:, ib] = 1.0
        H[:, idr] = -dt                    # the clock at the observation time
        has = isb_cols >= 0
        H[np.flatnonzero(has), isb_cols[has]] = 1.0
        return z, H


class RangeRates(SatelliteMeasurement):
    """Range rate from Doppler per satellite (see the module notes); rows ``ρ̇̂ − ρ̇`` [m/s].

    ``sigma`` (σ₀) defaults to 0.05 m/s."""

    kind = "Doppler"

    def __init__(self, sv, sigma=0.05, **kw):
        super().__init__(sv, sigma, **kw)

    def _observable(self, rows):
        return self.sv.range_rate[rows]

    def _model(self, ep, k, r, Jr, v, Jv, el, az, llh, dt):
        sv = self.sv
        lay = ep.layout
        rs, vs = sv.sat_pos[k], sv.sat_vel[k]
        d = rs - r
        rho = np.linalg.norm(d, axis=1)
        e = d / rho[:, None]
        w = E.WIE / G.C_LIGHT
        dv = vs - v
        rate = np.sum(dv * e, 1) + w * (vs[:, 1] * r[0] + rs[:, 1] * v[0] - vs[:, 0] * r[1] - rs[:, 0] * v[1])
        ib, idr, _ = self._clock_columns(lay, sv.system[k])
        z = rate + self.nominal[1] - sv.sat_drift[k] - sv.range_rate[k]
        # ∂/∂r_a: −(v_s − v_a)ᵀ(I − e eᵀ)/ρ + ω_e/c [v_sy, −v_sx, 0]
        proj = dv - np.sum(dv * e, 1)[:, None] * e
        gr = -proj / rho[:, None] + w * np.stack([vs[:, 1], -vs[:, 0], np.zeros(k.size)], -1)
        gv = -e + w * np.stack([rs[:, 1], -rs[:, 0], np.zeros(k.size)], -1)
        H = gr @ Jr + gv @ Jv
        H[:, idr] = 1.0
        return z, H


# ------------------------------------------------------------- single-point solution
@dataclass(frozen=True)
class SinglePoint:
    """GNSS-only least-squares solution per epoch (NaN where fewer satellites than
    unknowns).

    Attributes
    ----------
    t : ndarray (E,)
        Epoch times (IMU time axis) [s].
    lat, lon, h : ndarray (E,)
        [rad, rad, m].
    vel : ndarray (E, 3)
        ENU [m/s] from the range rates.
    sigma : ndarray (E, 3)
        Position σ north, east, up [m] from the weights (formal).
    sigma_vel : ndarray (E, 3)
        [m/s].
    clock : ndarray (E,)
        Receiver clock bias of the first system [m].
    drift : ndarray (E,)
        [m/s].
    n_sat : int ndarray (E,)
        Satellites used.
    """

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    vel: np.ndarray
    sigma: np.ndarray
    sigma_vel: np.ndarray
    clock: np.ndarray
    drift: np.ndarray
    n_sat: np.ndarray


def single_point(sv: SatelliteObservations, *, mask=math.radians(10.0), sigma=3.0, sigma_rate=0.1,
                 cn0_ref=45.0, reject=5.0, iterations=10) -> SinglePoint:
    """Iterated weighted least squares per epoch: position and a clock bias per system
    (a constellation's own bias: the inter-system biases are their differences), then
    velocity and drift from the range rates at that position. The corrections and
    weights are those of the measurements; while more rows than unknowns remain, the row
    with the largest normalised post-fit residual above ``reject`` is dropped and the
    epoch solved again. Each epoch starts from the previous solution (the first from the
    Earth's centre, where no elevation is known: the mask then applies from the second
    iteration)."""
    E_ = sv.t_epoch.size
    out = dict(lat=np.full(E_, np.nan), lon=np.full(E_, np.nan), h=np.full(E_, np.nan),
               vel=np.full((E_, 3), np.nan), sigma=np.full((E_, 3), np.nan),
               sigma_vel=np.full((E_, 3), np.nan), clock=np.full(E_, np.nan),
               drift=np.full(E_, np.nan), n_sat=np.zeros(E_, np.int64))
    systems = sv.systems
    r0 = np.zeros(3)
    cb0 = np.zeros(len(systems))
    for e in range(E_):
        rows = sv.rows(e)
        rows = rows[sv.usable[rows] & np.isfinite(sv.pseudorange[rows])]
        if rows.size < 4:
            continue
        sysi = np.array([systems.index(s) for s in sv.system[rows]])
        r, cb = r0.copy(), cb0.copy()
        good = np.ones(rows.size, bool)
        ok = False
        for _ in range(iterations):
            known = bool(np.any(r))
            if known:
                lat, lon, h = (float(v) for v in E.ecef_to_geodetic(r))
                el, az = E.elevation_azimuth(sv.sat_pos[rows], lat, lon, h)
                use = good & (el >= mask)
            else:
                el, use = np.full(rows.size, math.pi / 2), good.copy()
            used_sys = sorted(set(sysi[use].tolist()))
            nx = 3 + len(used_sys)
            if use.sum() < nx:
                break
            ru = rows[use]
            rho, u = G.sagnac_range(sv.sat_pos[ru], r)
            pred = rho + cb[sysi[use]] - sv.sat_clock[ru]
            if known:
                pred = pred + (G.klobuchar(sv.t_epoch[e] - sv.t_ref, lat, lon, az[use], el[use], sv.iono)
                               * (F_L1 / sv.freq[ru]) ** 2 + G.saastamoinen(lat, h, el[use]))
            resid = sv.pseudorange[ru] - pred
            A_ = np.zeros((ru.size, nx))
            A_[:, :3] = -u
            for j, s in enumerate(used_sys):
                A_[sysi[use] == s, 3 + j] = 1.0
            wgt = (1.0 / (sigma ** 2 * 10.0 ** (np.maximum(cn0_ref - sv.cn0[ru], 0) / 10)
                          / np.maximum(np.sin(el[use]), 0.05) ** 2))
            N = A_.T @ (A_ * wgt[:, None])
            dx = np.linalg.solve(N, A_.T @ (wgt * resid))
            r = r + dx[:3]
            cb[used_sys] += dx[3:]
            if known and np.linalg.norm(dx[:3]) < 1e-3:
                nres = np.abs(resid - A_ @ dx) * np.sqrt(wgt)
                if nres.max() > reject and ru.size > nx + 1:
                    good[np.flatnonzero(use)[np.argmax(nres)]] = False
                    continue
                ok = True
                break
        if not ok:
            continue
        r0, cb0 = r, cb
        lat, lon, h = (float(v) for v in E.ecef_to_geodetic(r))
        Cne = E.enu_to_ecef_matrix(lat, lon)
        Pe = Cne.T @ np.linalg.inv(N)[:3, :3] @ Cne
        out["lat"][e], out["lon"][e], out["h"][e] = lat, lon, h
        out["sigma"][e] = np.sqrt(np.diag(Pe))[[1, 0, 2]]
        out["clock"][e] = cb[0] if 0 in used_sys else np.nan
        out["n_sat"][e] = int(use.sum())
        ur = use & np.isfinite(sv.range_rate[rows])
        if ur.sum() >= 4:
            rr = rows[ur]
            d = sv.sat_pos[rr] - r
            ee = d / np.linalg.norm(d, axis=1)[:, None]
            w = E.WIE / G.C_LIGHT
            vs, ps = sv.sat_vel[rr], sv.sat_pos[rr]
            A_ = np.c_[-ee + w * np.stack([ps[:, 1], -ps[:, 0], np.zeros(rr.size)], -1), np.ones(rr.size)]
            y = sv.range_rate[rr] - (np.sum(vs * ee, 1) + w * (vs[:, 1] * r[0] - vs[:, 0] * r[1])
                                     - sv.sat_drift[rr])
            wv = np.maximum(np.sin(el[ur]), 0.05) ** 2 / sigma_rate ** 2
            Nv = A_.T @ (A_ * wv[:, None])
            sol = np.linalg.solve(Nv, A_.T @ (wv * y))
            out["vel"][e] = Cne.T @ sol[:3]
            out["drift"][e] = sol[3]
            out["sigma_vel"][e] = np.sqrt(np.diag(Cne.T @ np.linalg.inv(Nv)[:3, :3] @ Cne))
    return SinglePoint(sv.t_epoch.copy(), **out)
