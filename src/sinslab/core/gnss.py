"""GNSS satellite geometry from broadcast ephemerides: orbits, clocks, signal path.

Satellite positions, velocities and clock offsets at the time of transmission from the
broadcast navigation message (Keplerian elements of GPS, Galileo, BeiDou and QZSS with
their harmonic corrections, IS-GPS-200 §20.3.3.4.3, Galileo OS SIS ICD §5.1.1, BDS SIS ICD
§5.2.4 including the rotation of BeiDou's geostationary orbits; GLONASS state vectors
integrated with the PZ-90 equations of motion, GLONASS ICD A.3.1.2), the receiver-side
signal path (Sagnac term, Klobuchar ionosphere, Saastamoinen troposphere), and the
constants each system defines. The formulas are those of the system documents in the form
RTKLIB uses (tests/core/test_gnss.py checks positions, clocks and both path models against
RTKLIB's own functions to millimetres).

Times are GPS time in seconds relative to a reference ``t_ref`` that the caller chooses
(an integer second, e.g. the start of the GPS week of a log): absolute seconds since
1970 keep only a quarter of a microsecond, 1 mm of satellite motion.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from sinslab.core.earth import WIE, ecef_to_geodetic, elevation_azimuth

__all__ = ["C_LIGHT", "GPS_EPOCH_UNIX", "SYSTEMS", "Ephemerides", "GlonassEphemerides",
           "kepler_states", "glonass_states", "transmit_states", "sagnac_range",
           "klobuchar", "KLOBUCHAR_DEFAULT", "saastamoinen", "MAX_AGE", "Signals"]

C_LIGHT = 299792458.0                 #: speed of light [m/s]
GPS_EPOCH_UNIX = 315964800            #: 1980-01-06 00:00:00 in seconds since 1970 (GPST)

#: System letters (RINEX): G GPS, R GLONASS, E Galileo, C BeiDou, J QZSS, S SBAS.
SYSTEMS = ("G", "R", "E", "C", "J", "S")

# gravitational constant and Earth rate each system's orbit formulas are defined with
_MU = {"G": 3.9860050e14, "J": 3.9860050e14, "E": 3.986004418e14, "C": 3.986004418e14}
_OMGE = {"G": 7.2921151467e-5, "J": 7.2921151467e-5, "E": 7.2921151467e-5, "C": 7.292115e-5}
_MU_GLO, _J2_GLO, _RE_GLO, _OMGE_GLO = 3.9860044e14, 1.0826257e-3, 6378136.0, 7.292115e-5
_SIN5, _COS5 = math.sin(math.radians(-5.0)), math.cos(math.radians(-5.0))

#: Longest use of an ephemeris away from its reference time [s], per system.
MAX_AGE = {"G": 7200.0, "J": 7200.0, "E": 14400.0, "C": 21600.0, "R": 1800.0}

#: Klobuchar coefficients α0..α3, β0..β3 used when a log carries none (RTKLIB's default,
#: broadcast on 2004-01-01): the ionosphere of a mid-latitude day, not of the day of a log.
KLOBUCHAR_DEFAULT = (0.1118e-07, -0.7451e-08, -0.5961e-07, 0.1192e-06,
                     0.1167e+06, -0.2294e+06, -0.1311e+06, 0.1049e+07)


def _arr(v, dtype=float):
    return np.asarray(v, dtype=dtype)


@dataclass(frozen=True)
class Ephemerides:
    """Keplerian broadcast ephemerides (GPS, Galileo, BeiDou, QZSS), one row each.

    Times (``toe``, ``toc``) are GPS time in seconds relative to ``t_ref``; ``toes`` is
    the reference time as broadcast (seconds of the system's week), which the longitude of
    the ascending node is counted from. Angles in rad, rates in rad/s, ``A`` the semi-major
    axis [m], clock polynomial ``f0`` [s], ``f1`` [s/s], ``f2`` [s/s²], group delays
    ``tgd`` (K, 2) [s] (GPS TGD; Galileo BGD E1/E5a, E1/E5b; BeiDou TGD1, TGD2).
    """

    t_ref: int
    sat: np.ndarray          # "G10", "E07", ... (K,)
    iode: np.ndarray
    toe: np.ndarray
    toc: np.ndarray
    toes: np.ndarray
    A: np.ndarray
    e: np.ndarray
    i0: np.ndarray
    OMG0: np.ndarray
    omg: np.ndarray
    M0: np.ndarray
    deln: np.ndarray
    OMGd: np.ndarray
    idot: np.ndarray
    crc: np.ndarray
    crs: np.ndarray
    cuc: np.ndarray
    cus: np.ndarray
    cic: np.ndarray
    cis: np.ndarray
    f0: np.ndarray
    f1: np.ndarray
    f2: np.ndarray
    tgd: np.ndarray
    svh: np.ndarray

    def __len__(self):
        return int(self.sat.size)

    @classmethod
    def empty(cls, t_ref: int = 0) -> Ephemerides:
        z = np.zeros(0)
        columns = [np.zeros(0, "U3"), np.zeros(0, np.int64), *([z] * 21), np.zeros((0, 2)), np.zeros(0, np.int64)]
        return cls(int(t_ref), *columns)

    def take(self, idx: np.ndarray) -> Ephemerides:
        """The ephemerides ``idx`` (int array) as a new table."""
        kw = {f: getattr(self, f)[idx] for f in self.__dataclass_fields__ if f != "t_ref"}
        return Ephemerides(self.t_ref, **kw)


@dataclass(frozen=True)
class GlonassEphemerides:
    """GLONASS broadcast ephemerides: PZ-90 state at ``toe`` (GPS time relative to
    ``t_ref`` [s]) — ``pos`` [m], ``vel`` [m/s], luni-solar ``acc`` [m/s²] (K, 3) — clock
    ``-taun + gamn (t - toe)`` [s], frequency channel ``frq``."""

    t_ref: int
    sat: np.ndarray
    iode: np.ndarray
    toe: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    taun: np.ndarray
    gamn: np.ndarray
    frq: np.ndarray
    svh: np.ndarray | None = None

    def __len__(self):
        return int(self.sat.size)

    @classmethod
    def empty(cls, t_ref: int = 0) -> GlonassEphemerides:
        z3 = np.zeros((0, 3))
        return cls(int(t_ref), np.zeros(0, "U3"), np.zeros(0, np.int64), np.zeros(0), z3, z3, z3,
                   np.zeros(0), np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int64))

    def take(self, idx: np.ndarray) -> GlonassEphemerides:
        kw = {f: getattr(self, f)[idx] for f in self.__dataclass_fields__ if f != "t_ref"}
        return GlonassEphemerides(self.t_ref, **kw)


# ---------------------------------------------------------------------------- signals
@dataclass(frozen=True)
class Signals:
    """Every signal of each observation row, by RTKLIB's frequency slot (F slots).

    Slot 0 is L1/E1/B1/G1; slots 1 and 2 are the second and third carriers in RTKLIB's
    order for the system (GPS/QZSS L2, L5; Galileo E5b, E5a; BeiDou B2, B3 or B2a;
    GLONASS G2, G3). Missing values are NaN (empty code).

    Attributes
    ----------
    code : str ndarray (M, F)
        RINEX signal code ("1C", "2W", "5Q", ...; "" where the slot is empty).
    pseudorange : ndarray (M, F)
        [m].
    phase : ndarray (M, F)
        Carrier phase [cycles], RINEX sign: ``λ φ`` follows the range (its rate is minus
        the Doppler), up to an integer ambiguity and the clocks.
    doppler : ndarray (M, F)
        [Hz] (positive when the satellite approaches).
    cn0 : ndarray (M, F)
        [dB-Hz].
    freq : ndarray (M, F)
        Carrier frequency [Hz].
    lli : uint8 ndarray (M, F)
        RTKLIB's loss-of-lock indicator: bit 0 a possible cycle slip since the last
        epoch, bit 1 the half-cycle ambiguity unresolved, bits 6/7 a half cycle added /
        subtracted by the receiver.
    """

    code: np.ndarray
    pseudorange: np.ndarray
    phase: np.ndarray
    doppler: np.ndarray
    cn0: np.ndarray
    freq: np.ndarray
    lli: np.ndarray

    @property
    def slip(self) -> np.ndarray:
        """Loss of lock (a possible cycle slip) since the previous epoch, bool (M, F)."""
        return (self.lli & 1) != 0

    @property
    def half_cycle(self) -> np.ndarray:
        """Half-cycle ambiguity unresolved, bool (M, F): the phase may be off by ½ cycle."""
        return (self.lli & 2) != 0

    def __getitem__(self, m):
        return Signals(*(a[m] for a in (self.code, self.pseudorange, self.phase, self.doppler,
                                          self.cn0, self.freq, self.lli)))


# ----------------------------------------------------------------------------- orbits
def _kepler_pos(eph, rows, t):
    """Positions (M, 3) [m] and clock offsets with the relativistic term (M,) [s] of the
    ephemeris rows ``rows`` at GPS times ``t`` (M,) (relative to ``eph.t_ref``)."""
    sysl = np.array([s[0] for s in eph.sat[rows]]) if rows.size else np.zeros(0, "U1")
    prn = np.array([int(s[1:]) for s in eph.sat[rows]], dtype=np.int64) if rows.size else np.zeros(0, np.int64)
    mu = np.array([_MU.get(s, _MU["G"]) for s in sysl])
    omge = np.array([_OMGE.get(s, _OMGE["G"]) for s in sysl])
    g = lambda f: getattr(eph, f)[rows]  # noqa: E731
    A_, e = g("A"), g("e")
    tk = t - g("toe")
    M = g("M0") + (np.sqrt(mu / A_ ** 3) + g("deln")) * tk
    E = M.copy()
    for _ in range(30):
        dE = (E - e * np.sin(E) - M) / (1.0 - e * np.cos(E))
        E = E - dE
        if np.all(np.abs(dE) < 1e-14):
            break
    sinE, cosE = np.sin(E), np.cos(E)
    u = np.arctan2(np.sqrt(1.0 - e * e) * sinE, cosE - e) + g("omg")
    r = A_ * (1.0 - e * cosE)
    i = g("i0") + g("idot") * tk
    s2u, c2u = np.sin(2.0 * u), np.cos(2.0 * u)
    u = u + g("cus") * s2u + g("cuc") * c2u
    r = r + g("crs") * s2u + g("crc") * c2u
    i = i + g("cis") * s2u + g("cic") * c2u
    x, y, ci, si = r * np.cos(u), r * np.sin(u), np.cos(i), np.sin(i)
    geo = (sysl == "C") & ((prn <= 5) | (prn >= 59))
    # BeiDou GEO: the orbit in an inertial-like frame rotated by -5° about x, then by the
    # Earth's rotation since toe (BDS SIS ICD table 5-11)
    O = np.where(geo, g("OMG0") + g("OMGd") * tk - omge * g("toes"),
                 g("OMG0") + (g("OMGd") - omge) * tk - omge * g("toes"))
    sO, cO = np.sin(O), np.cos(O)
    xg, yg, zg = x * cO - y * ci * sO, x * sO + y * ci * cO, y * si
    pos = np.stack([xg, yg, zg], -1)
    if np.any(geo):
        so, co = np.sin(omge * tk), np.cos(omge * tk)
        pg = np.stack([xg * co + yg * so * _COS5 + zg * so * _SIN5,
                       -xg * so + yg * co * _COS5 + zg * co * _SIN5,
                       -yg * _SIN5 + zg * _COS5], -1)
        pos = np.where(geo[:, None], pg, pos)
    tc = t - g("toc")
    dts = g("f0") + g("f1") * tc + g("f2") * tc * tc - 2.0 * np.sqrt(mu * A_) * e * sinE / C_LIGHT ** 2
    return pos, dts


def kepler_states(eph: Ephemerides, rows: np.ndarray, t: ArrayLike, *,
                  step: float = 1e-3) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Satellite position, velocity, clock offset and drift from Keplerian ephemerides.

    Parameters
    ----------
    eph : Ephemerides
    rows : int array (M,)
        Ephemeris row of each request.
    t : array (M,)
        GPS time of transmission [s], relative to ``eph.t_ref``.
    step : float
        Half-width [s] of the central difference giving velocity and clock drift (1 ms:
        exact to 1e-6 m/s, far below what Doppler resolves).

    Returns
    -------
    pos, vel : ndarray (M, 3)
        ECEF at ``t`` [m], [m/s] (the frame of the transmission time).
    dts : ndarray (M,)
        Satellite clock offset [s] with the relativistic correction ``−2 √(μA) e sinE / c²``
        (no group delay).
    ddts : ndarray (M,)
        Clock drift [s/s].
    """
    rows = np.asarray(rows, dtype=np.int64)
    t = np.asarray(t, dtype=float)
    p, d = _kepler_pos(eph, rows, t)
    pa, da = _kepler_pos(eph, rows, t + step)
    pb, db = _kepler_pos(eph, rows, t - step)
    return p, (pa - pb) / (2 * step), d, (da - db) / (2 * step)


def _glo_deq(x, acc):
    r2 = np.sum(x[:, :3] ** 2, 1)
    r3 = r2 * np.sqrt(r2)
    a = 1.5 * _J2_GLO * _MU_GLO * _RE_GLO ** 2 / r2 / r3
    b = 5.0 * x[:, 2] ** 2 / r2
    c = -_MU_GLO / r3 - a * (1.0 - b)
    w2 = _OMGE_GLO ** 2
    out = np.empty_like(x)
    out[:, :3] = x[:, 3:]
    out[:, 3] = (c + w2) * x[:, 0] + 2.0 * _OMGE_GLO * x[:, 4] + acc[:, 0]
    out[:, 4] = (c + w2) * x[:, 1] - 2.0 * _OMGE_GLO * x[:, 3] + acc[:, 1]
    out[:, 5] = (c - 2.0 * a) * x[:, 2] + acc[:, 2]
    return out


def _glo_pos(geph, rows, t, tstep=60.0):
    """GLONASS states (M, 6) and clock offsets (M,) at ``t``: fourth-order Runge–Kutta
    from ``toe`` in steps of at most ``tstep`` s, the last one shortened."""
    x = np.concatenate([geph.pos[rows], geph.vel[rows]], 1)
    acc = geph.acc[rows]
    left = t - geph.toe[rows]
    dts = -geph.taun[rows] + geph.gamn[rows] * left
    while np.any(np.abs(left) > 1e-9):
        h = np.clip(left, -tstep, tstep)
        h = np.where(np.abs(left) > 1e-9, h, 0.0)[:, None]
        k1 = _glo_deq(x, acc)
        k2 = _glo_deq(x + k1 * h / 2, acc)
        k3 = _glo_deq(x + k2 * h / 2, acc)
        k4 = _glo_deq(x + k3 * h, acc)
        x = x + (k1 + 2 * k2 + 2 * k3 + k4) * h / 6
        left = left - h[:, 0]
    return x, dts


def glonass_states(geph: GlonassEphemerides, rows: np.ndarray,
                   t: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`kepler_states` for GLONASS (position and velocity from the integration,
    clock drift ``gamn``)."""
    rows = np.asarray(rows, dtype=np.int64)
    x, dts = _glo_pos(geph, rows, np.asarray(t, dtype=float))
    return x[:, :3], x[:, 3:], dts, geph.gamn[rows].copy()


def _select(sat_e, toe_e, svh_e, sats, t):
    """Row of the healthy ephemeris nearest in time for each (satellite, time), -1 where
    none is within :data:`MAX_AGE`."""
    out = np.full(len(sats), -1, dtype=np.int64)
    for s in np.unique(sats):
        cand = np.flatnonzero((sat_e == s) & (svh_e == 0))
        if not cand.size:
            continue
        m = np.flatnonzero(sats == s)
        d = np.abs(t[m, None] - toe_e[cand][None, :])
        j = np.argmin(d, 1)
        ok = d[np.arange(m.size), j] <= MAX_AGE.get(s[0], 7200.0)
        out[m[ok]] = cand[j[ok]]
    return out


def transmit_states(eph: Ephemerides, geph: GlonassEphemerides | None, sats: np.ndarray, t_rx: ArrayLike,
                    pseudorange: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Satellite states at the transmission time of each observation.

    ``t_tx = t_rx − P/c − dts(t_tx)``: the signal left ``P/c`` before its reception by the
    receiver's clock, corrected by the satellite clock polynomial (one fixed-point step
    from ``t_rx − P/c``, as RTKLIB's ``satposs``); the receiver clock error shifts ``t_tx``
    by at most its offset (about a millisecond: 3 m of orbit, removed by the filter's
    clock states together with the range).

    Parameters
    ----------
    eph, geph : Ephemerides, GlonassEphemerides or None
    sats : array of str (M,)
        Satellite of each observation ("G10", "R03", ...).
    t_rx : array (M,)
        Reception time by the receiver clock, GPS time relative to ``eph.t_ref`` [s].
    pseudorange : array (M,)
        [m].

    Returns
    -------
    pos, vel : ndarray (M, 3)
        ECEF at the transmission time [m], [m/s] (NaN without ephemeris).
    dts, ddts : ndarray (M,)
        Satellite clock offset (relativistic term included) [s] and drift [s/s].
    eph_row : int array (M,)
        Row in ``eph`` (Keplerian) or in ``geph`` (GLONASS) used; −1 where no healthy
        ephemeris lies within :data:`MAX_AGE`.
    """
    sats = np.asarray(sats)
    t_rx = np.asarray(t_rx, dtype=float)
    P = np.asarray(pseudorange, dtype=float)
    M = sats.size
    pos, vel = np.full((M, 3), np.nan), np.full((M, 3), np.nan)
    dts, ddts = np.full(M, np.nan), np.full(M, np.nan)
    rows = np.full(M, -1, dtype=np.int64)
    t0 = t_rx - P / C_LIGHT
    glo = np.array([s[:1] == "R" for s in sats], dtype=bool)
    kep = ~glo
    if np.any(kep) and len(eph):
        k = np.flatnonzero(kep)
        r = _select(eph.sat, eph.toe, eph.svh, sats[k], t0[k])
        ok = r >= 0
        k, r = k[ok], r[ok]
        tc = t0[k] - eph.toc[r]
        for _ in range(2):
            tc = t0[k] - eph.toc[r] - (eph.f0[r] + eph.f1[r] * tc + eph.f2[r] * tc * tc)
        ttx = t0[k] - (eph.f0[r] + eph.f1[r] * tc + eph.f2[r] * tc * tc)
        pos[k], vel[k], dts[k], ddts[k] = kepler_states(eph, r, ttx)
        rows[k] = r
    if np.any(glo) and geph is not None and len(geph):
        k = np.flatnonzero(glo)
        r = _select(geph.sat, geph.toe, geph.svh if geph.svh is not None else np.zeros(len(geph), np.int64),
                    sats[k], t0[k])
        ok = r >= 0
        k, r = k[ok], r[ok]
        tg = t0[k] - geph.toe[r]
        for _ in range(2):
            tg = t0[k] - geph.toe[r] - (-geph.taun[r] + geph.gamn[r] * tg)
        ttx = t0[k] - (-geph.taun[r] + geph.gamn[r] * tg)
        pos[k], vel[k], dts[k], ddts[k] = glonass_states(geph, r, ttx)
        rows[k] = r
    return pos, vel, dts, ddts, rows


# ----------------------------------------------------------------------- signal path
def sagnac_range(r_sat: ArrayLike, r_rcv: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Geometric range [m] from the receiver ``r_rcv`` (ECEF at reception) to the
    satellite ``r_sat`` (ECEF at transmission), with the Earth's rotation during the flight
    (Sagnac term ``ω_e (x_s y_r − y_s x_r) / c``), and the unit line of sight (receiver to
    satellite, ECEF). Shapes (..., 3) -> (...), (..., 3)."""
    d = np.asarray(r_sat, dtype=float) - np.asarray(r_rcv, dtype=float)
    rho = np.linalg.norm(d, axis=-1)
    rs, rr = np.asarray(r_sat, dtype=float), np.asarray(r_rcv, dtype=float)
    sag = WIE * (rs[..., 0] * rr[..., 1] - rs[..., 1] * rr[..., 0]) / C_LIGHT
    return rho + sag, d / rho[..., None]


def klobuchar(t_gps_s: ArrayLike, lat: ArrayLike, lon: ArrayLike, az: ArrayLike, el: ArrayLike,
              coeffs: ArrayLike | None = None) -> np.ndarray:
    """Klobuchar ionospheric delay on GPS L1 [m] (IS-GPS-200 §20.3.3.5.2.5).

    Parameters
    ----------
    t_gps_s : array
        GPS time [s] (of the week, or since the GPS epoch: only the time of day is used).
    lat, lon : float or array
        Receiver geodetic latitude and longitude [rad].
    az, el : array
        Azimuth (clockwise from north) and elevation [rad] of the satellite.
    coeffs : sequence of 8, optional
        α0..α3, β0..β3 as broadcast (semicircle units); None or all zero:
        :data:`KLOBUCHAR_DEFAULT`.

    Returns
    -------
    ndarray
        Slant delay on L1 [m] (scale by ``(f_L1 / f)²`` for another frequency); 0 for
        satellites at or below the horizon.
    """
    c = np.asarray(KLOBUCHAR_DEFAULT if coeffs is None or not np.any(coeffs) else coeffs, dtype=float)
    el = np.asarray(el, dtype=float)
    az = np.asarray(az, dtype=float)
    pi = math.pi
    psi = 0.0137 / (el / pi + 0.11) - 0.022
    phi = np.clip(np.asarray(lat) / pi + psi * np.cos(az), -0.416, 0.416)
    lam = np.asarray(lon) / pi + psi * np.sin(az) / np.cos(phi * pi)
    phi = phi + 0.064 * np.cos((lam - 1.617) * pi)
    tt = 43200.0 * lam + np.mod(np.asarray(t_gps_s, dtype=float), 604800.0)
    tt = tt - np.floor(tt / 86400.0) * 86400.0
    f = 1.0 + 16.0 * (0.53 - el / pi) ** 3
    amp = np.maximum(c[0] + phi * (c[1] + phi * (c[2] + phi * c[3])), 0.0)
    per = np.maximum(c[4] + phi * (c[5] + phi * (c[6] + phi * c[7])), 72000.0)
    x = 2.0 * pi * (tt - 50400.0) / per
    d = C_LIGHT * f * np.where(np.abs(x) < 1.57, 5e-9 + amp * (1.0 + x * x * (-0.5 + x * x / 24.0)), 5e-9)
    return np.where(el > 0, d, 0.0)


def saastamoinen(lat: ArrayLike, h: ArrayLike, el: ArrayLike, humidity: float = 0.7) -> np.ndarray:
    """Saastamoinen tropospheric delay [m] in a standard atmosphere (pressure and
    temperature from the height, relative ``humidity`` [0..1]), mapped with 1/cos z.

    ``lat`` [rad], ellipsoidal height ``h`` [m] (taken as the height above sea level:
    a geoid height of tens of metres changes the delay by millimetres), elevation ``el``
    [rad]; 0 at or below the horizon and outside −100 m..10 km."""
    h = np.asarray(h, dtype=float)
    el = np.asarray(el, dtype=float)
    hgt = np.clip(h, 0.0, 1e4)
    pres = 1013.25 * (1.0 - 2.2557e-5 * hgt) ** 5.2568
    temp = 15.0 - 6.5e-3 * hgt + 273.16
    e = 6.108 * humidity * np.exp((17.15 * temp - 4684.0) / (temp - 38.45))
    cz = np.cos(math.pi / 2 - el)
    trph = 0.0022768 * pres / (1.0 - 0.00266 * np.cos(2.0 * np.asarray(lat)) - 0.00028 * hgt / 1e3) / cz
    trpw = 0.002277 * (1255.0 / temp + 0.05) * e / cz
    ok = (el > 0) & (h >= -100.0) & (h <= 1e4)
    return np.where(ok, trph + trpw, 0.0)


def sky(r_sat: ArrayLike, r_rcv: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Elevation and azimuth [rad] of ECEF satellites seen from an ECEF receiver."""
    lat, lon, h = ecef_to_geodetic(r_rcv)
    return elevation_azimuth(r_sat, lat, lon, h)
