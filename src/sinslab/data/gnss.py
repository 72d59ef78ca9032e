"""Raw GNSS observations and broadcast ephemerides: u-blox binary logs and RINEX 2/3.

Decoding is RTKLIB's (the demo5 branch, through its Python binding ``pyrtklib5``): UBX
RXM-RAWX (pseudorange, carrier phase, Doppler, C/N0 per signal) and RXM-SFRBX (the
broadcast subframes of GPS, Galileo I/NAV and F/NAV, BeiDou D1/D2, GLONASS strings,
QZSS), and RINEX observation and navigation files. The demo5 branch is chosen over
RTKLIB 2.4.3 (``pyrtklib``) because on a current u-blox log 2.4.3 decodes no Galileo
ephemeris and drops the BeiDou B1C/B2a signals. The receiver's own solution (UBX
NAV-PVT), which RTKLIB ignores, is read with ``pyubx2``.

One row per satellite and epoch. Its pseudorange, Doppler, C/N0 and carrier frequency
are those of the first carrier slot that has a pseudorange (GPS/QZSS L1, Galileo E1,
BeiDou B1, GLONASS G1); every signal of the row — pseudorange, carrier phase [cycles],
Doppler, C/N0, loss-of-lock and half-cycle flags, by RTKLIB's frequency slot — is kept
beside it in :class:`Signals`. Times are GPS time: reception epochs by the receiver's clock and ephemeris
reference times are seconds relative to ``t_ref``, the start of the GPS week of the first
epoch, given in seconds since 1970-01-01 counted without leap seconds (the convention of
RTKLIB's time-tag files and ``.pos`` readers here, so ``t_ref + t`` is on the time axis of
the IMU of a tagged log).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sinslab.core.errors import InputError
from sinslab.core.gnss import GPS_EPOCH_UNIX, Ephemerides, GlonassEphemerides, Signals
from sinslab.core.records import Fixes

__all__ = ["GnssObservations", "Signals", "read_gnss_raw", "read_ubx_pvt", "rinex_version"]

_SYS = {1: "G", 4: "R", 8: "E", 32: "C", 16: "J", 2: "S", 64: "I"}
_SNR_UNIT = 1.0             # the demo5 binding gives C/N0 in dB-Hz (RTKLIB 2.4.3: 0.001 dB-Hz)
_WEEK = 604800
_EMPTY_SLOT = ("", np.nan, np.nan, np.nan, np.nan, np.nan, 0)


@dataclass(frozen=True)
class GnssObservations:
    """Raw observations of one receiver with the ephemerides to use them.

    Attributes
    ----------
    t_ref : int
        Reference of the times below: GPS time [s] since 1970-01-01 (no leap seconds) of
        the start of the GPS week of the first epoch.
    epoch_t : ndarray (E,)
        Reception time of each epoch by the receiver clock [s], relative to ``t_ref``.
    epoch : int ndarray (M,)
        Epoch of each observation (one per satellite and epoch).
    sat : str ndarray (M,)
        Satellite ("G10", "E07", "C21", "R03", "J02", "S35").
    code : str ndarray (M,)
        RINEX signal code of the observation ("1C", "1X", "2I", ...).
    pseudorange : ndarray (M,)
        [m].
    doppler : ndarray (M,)
        [Hz] (positive when the satellite approaches: range rate = −λ · doppler); NaN
        where the receiver gave none.
    freq : ndarray (M,)
        Carrier frequency [Hz].
    cn0 : ndarray (M,)
        Carrier-to-noise density [dB-Hz].
    eph, geph : Ephemerides, GlonassEphemerides
    eph_decoded, geph_decoded : ndarray
        Time each ephemeris became complete in the log [s rel. ``t_ref``] (−inf from a
        navigation file).
    iono : ndarray (8,)
        Klobuchar α0..α3, β0..β3 broadcast in the log (zeros: none broadcast).
    source : str
        The file(s) read.
    signals : Signals
        Every signal of each row (carrier phase and its flags among them).
    """

    t_ref: int
    epoch_t: np.ndarray
    epoch: np.ndarray
    sat: np.ndarray
    code: np.ndarray
    pseudorange: np.ndarray
    doppler: np.ndarray
    freq: np.ndarray
    cn0: np.ndarray
    eph: Ephemerides
    geph: GlonassEphemerides
    eph_decoded: np.ndarray
    geph_decoded: np.ndarray
    iono: np.ndarray
    source: str
    signals: Signals = None

    def __len__(self):
        return int(self.sat.size)

    @property
    def t_abs(self):
        """Epoch times as GPS seconds since 1970 (the IMU's time axis of a tagged log)."""
        return self.t_ref + self.epoch_t

    @property
    def systems(self):
        """The systems observed, as letters."""
        return sorted({s[0] for s in self.sat})

    def select(self, mask):
        """The observations ``mask`` (bool (M,)); epochs are kept."""
        m = np.asarray(mask, dtype=bool)
        return GnssObservations(self.t_ref, self.epoch_t, self.epoch[m], self.sat[m], self.code[m],
                                self.pseudorange[m], self.doppler[m], self.freq[m], self.cn0[m],
                                self.eph, self.geph, self.eph_decoded, self.geph_decoded, self.iono,
                                self.source, None if self.signals is None else self.signals[m])

    @property
    def has_phase(self):
        """Whether any signal carries a carrier phase."""
        return self.signals is not None and bool(np.isfinite(self.signals.phase).any())


def _lib():
    try:
        import pyrtklib5 as rtk
    except ImportError as e:          # declared in pyproject; a broken install says so
        raise InputError(f"raw GNSS needs the RTKLIB binding pyrtklib5 ({e})") from None
    return rtk


def _satid(rtk, sat):
    prn = rtk.Arr1Dint(1)
    sys = rtk.satsys(sat, prn)
    s = _SYS.get(sys)
    if s is None:
        return None
    p = prn[0]
    if s == "J":
        p -= 192
    elif s == "S":
        p -= 100
    return f"{s}{p:02d}"


def _gt(g):
    """gtime_t -> (int seconds, fraction)."""
    return int(g.time), float(g.sec)


class _Collector:
    """Observations and ephemerides gathered from RTKLIB structures."""

    def __init__(self, rtk):
        self.rtk = rtk
        self.t_int, self.t_frac = [], []
        self.rows = []                      # (epoch, sat, code, P, D, f, cn0)
        self.sig = []                       # per row, per slot: (code, P, L, D, cn0, f, lli)
        self.code_freq = {}
        self.n_slots = rtk.NFREQ + rtk.NEXOBS
        self.eph = {}                       # (sat, toe, set) -> (fields, decoded at)
        self.geph = {}
        self.nav = None

    def epoch(self, obs, n, nav):
        rtk = self.rtk
        e = len(self.t_int)
        ti, tf = _gt(obs.data[0].time)
        self.t_int.append(ti)
        self.t_frac.append(tf)
        for i in range(n):
            d = obs.data[i]
            sid = _satid(rtk, d.sat)
            if sid is None:
                continue
            for j in range(rtk.NFREQ):
                P = d.P[j]
                if P != 0.0:
                    break
            else:
                continue
            code = int(d.code[j])
            f = rtk.sat2freq(d.sat, code, nav)
            D = float(d.D[j])
            self.rows.append((e, sid, rtk.code2obs(code), float(P), D if D != 0.0 else np.nan, f,
                              float(d.SNR[j]) * _SNR_UNIT))
            self.sig.append(self._signals(d, nav))

    def _signals(self, d, nav):
        """(code, P, L, D, C/N0, f, LLI) of every slot of one satellite's record."""
        rtk, out = self.rtk, []
        codes, Ps, Ls, Ds, snr, lli = d.code, d.P, d.L, d.D, d.SNR, d.LLI
        for j in range(self.n_slots):
            c = int(codes[j])
            if c == 0:
                out.append(_EMPTY_SLOT)
                continue
            key = (d.sat, c)
            cf = self.code_freq.get(key)
            if cf is None:
                cf = (rtk.code2obs(c), rtk.sat2freq(d.sat, c, nav))
                if cf[1] > 0 and _satid(rtk, d.sat)[0] != "R":   # a GLONASS channel may come later
                    self.code_freq[key] = cf
            P, L, D = float(Ps[j]), float(Ls[j]), float(Ds[j])
            out.append((cf[0], P if P != 0.0 else np.nan, L if L != 0.0 else np.nan,
                        D if D != 0.0 else np.nan, float(snr[j]) * _SNR_UNIT, cf[1], int(lli[j])))
        return out

    def ephemeris(self, e, t_dec, eset=0):
        sid = _satid(self.rtk, e.sat)
        if sid is None or e.sat <= 0 or e.A <= 0:
            return
        key = (sid, _gt(e.toe), eset)
        if key in self.eph:
            return
        self.eph[key] = (dict(
            sat=sid, iode=int(e.iode), toe=_gt(e.toe), toc=_gt(e.toc), toes=float(e.toes), A=e.A, e=e.e,
            i0=e.i0, OMG0=e.OMG0, omg=e.omg, M0=e.M0, deln=e.deln, OMGd=e.OMGd, idot=e.idot,
            crc=e.crc, crs=e.crs, cuc=e.cuc, cus=e.cus, cic=e.cic, cis=e.cis, f0=e.f0, f1=e.f1,
            f2=e.f2, tgd=(e.tgd[0], e.tgd[1]), svh=int(e.svh)), t_dec)

    def glonass(self, g, t_dec):
        sid = _satid(self.rtk, g.sat)
        if sid is None or g.sat <= 0:
            return
        key = (sid, _gt(g.toe))
        if key in self.geph:
            return
        self.geph[key] = (dict(sat=sid, iode=int(g.iode), toe=_gt(g.toe), pos=tuple(g.pos[k] for k in range(3)),
                               vel=tuple(g.vel[k] for k in range(3)), acc=tuple(g.acc[k] for k in range(3)),
                               taun=g.taun, gamn=g.gamn, frq=int(g.frq), svh=int(g.svh)), t_dec)

    def finish(self, iono, source, path_for_errors):
        if not self.t_int:
            raise InputError(f"{path_for_errors}: no raw measurements (no RXM-RAWX epoch or RINEX "
                             "observation record)")
        if not self.rows:
            raise InputError(f"{path_for_errors}: {len(self.t_int)} epochs of raw observations without a single "
                             "pseudorange (every code observation empty or zero): the receiver reported no range")
        week0 = (self.t_int[0] - GPS_EPOCH_UNIX) // _WEEK
        t_ref = int(GPS_EPOCH_UNIX + week0 * _WEEK)
        rel = lambda ti_tf: (ti_tf[0] - t_ref) + ti_tf[1]  # noqa: E731
        epoch_t = np.array([rel(x) for x in zip(self.t_int, self.t_frac)])
        if np.any(np.diff(epoch_t) <= 0):
            k = int(np.argmax(np.diff(epoch_t) <= 0)) + 1
            raise InputError(f"{path_for_errors}: epoch {k} is not after the one before it "
                             "(unsorted or duplicated observation times)")
        cols = list(zip(*self.rows))
        # Galileo: one ephemeris per (satellite, toe), I/NAV (set 0) before F/NAV
        chosen = {}
        for (sid, toe, eset), v in sorted(self.eph.items(), key=lambda kv: kv[0][2]):
            chosen.setdefault((sid, toe), v)
        ev = list(chosen.values())
        if ev:
            f = {k: [d[0][k] for d in ev] for k in ev[0][0]}
            eph = Ephemerides(
                t_ref, np.array(f["sat"]), np.array(f["iode"], np.int64),
                np.array([rel(x) for x in f["toe"]]), np.array([rel(x) for x in f["toc"]]),
                *(np.array(f[k], float) for k in ("toes", "A", "e", "i0", "OMG0", "omg", "M0", "deln",
                                                 "OMGd", "idot", "crc", "crs", "cuc", "cus", "cic",
                                                 "cis", "f0", "f1", "f2")),
                np.array(f["tgd"], float).reshape(-1, 2), np.array(f["svh"], np.int64))
            dec = np.array([d[1] - t_ref for d in ev])
        else:
            eph, dec = Ephemerides.empty(t_ref), np.zeros(0)
        gv = list(self.geph.values())
        if gv:
            g = {k: [d[0][k] for d in gv] for k in gv[0][0]}
            geph = GlonassEphemerides(
                t_ref, np.array(g["sat"]), np.array(g["iode"], np.int64), np.array([rel(x) for x in g["toe"]]),
                np.array(g["pos"], float), np.array(g["vel"], float), np.array(g["acc"], float),
                np.array(g["taun"], float), np.array(g["gamn"], float), np.array(g["frq"], np.int64),
                np.array(g["svh"], np.int64))
            gdec = np.array([d[1] - t_ref for d in gv])
        else:
            geph, gdec = GlonassEphemerides.empty(t_ref), np.zeros(0)
        return GnssObservations(
            t_ref, epoch_t, np.array(cols[0], np.int64), np.array(cols[1]), np.array(cols[2]),
            np.array(cols[3], float), np.array(cols[4], float), np.array(cols[5], float),
            np.array(cols[6], float), eph, geph, dec, gdec, np.asarray(iono, float), source,
            self._signal_arrays())

    def _signal_arrays(self):
        sig = self.sig
        return Signals(np.array([[x[0] for x in r] for r in sig], dtype="<U3"),
                       *(np.array([[x[k] for x in r] for r in sig], float) for k in range(1, 6)),
                       np.array([[x[6] for x in r] for r in sig], np.uint8))


def rinex_version(path) -> tuple:
    """``(version, type letter)`` from the first header line of a RINEX file."""
    with open(path, "r", encoding="ascii", errors="replace") as fh:
        line = fh.readline()
    if "RINEX VERSION / TYPE" not in line:
        raise InputError(f"{path}:1: not a RINEX file (no 'RINEX VERSION / TYPE' header line)")
    try:
        ver = float(line[:9])
    except ValueError:
        raise InputError(f"{path}:1: unreadable RINEX version {line[:9].strip()!r}") from None
    return ver, line[20:21].upper()


def _is_rinex(path):
    with open(path, "rb") as fh:
        head = fh.read(80)
    return b"RINEX VERSION / TYPE" in head


def _read_ubx(rtk, path, col):
    raw = rtk.raw_t()
    rtk.init_raw(raw, rtk.STRFMT_UBX)
    fw = rtk.FileWrapper(str(path), "rb")
    n_eph = 0
    while True:
        r = rtk.input_ubxf(raw, fw)
        if r == -2:
            break
        if r == 1 and raw.obs.n > 0:
            col.epoch(raw.obs, raw.obs.n, raw.nav)
        elif r == 2:
            t_dec = raw.time.time + raw.time.sec
            s = raw.ephsat
            sid = _satid(rtk, s)
            if sid is not None and sid[0] == "R":
                prn = int(sid[1:])
                col.glonass(raw.nav.geph[prn - 1], t_dec)
            elif sid is not None:
                col.ephemeris(raw.nav.eph[s - 1 + rtk.MAXSAT * raw.ephset], t_dec, raw.ephset)
            n_eph += 1
    iono = [raw.nav.ion_gps[k] for k in range(8)]
    rtk.free_raw(raw)
    return iono


#: lines a RINEX header may take before its END OF HEADER label (real ones take tens)
MAX_HEADER_LINES = 2000


def _check_header_end(path) -> None:
    """A RINEX header ends with the label END OF HEADER (columns 61-80); without it the
    reader finds no record and said so, not what is wrong."""
    with open(path, "r", encoding="ascii", errors="replace") as fh:
        for n, line in enumerate(fh, 1):
            if "END OF HEADER" in line[60:]:
                return
            if n >= MAX_HEADER_LINES:
                break
    raise InputError(f"{path}: the RINEX header has no END OF HEADER line (label in columns 61-80) in its "
                     f"first {min(n, MAX_HEADER_LINES)} lines: the header is cut or damaged")


def _read_rinex_nav(rtk, path, col):
    ver, kind = rinex_version(path)
    if not (2.0 <= ver < 4.0):
        raise InputError(f"{path}: RINEX version {ver:g} (this reader takes versions 2 and 3)")
    if kind not in ("N", "G", "M", "L", "C", "E"):
        raise InputError(f"{path}: RINEX type {kind!r} is not a navigation file")
    _check_header_end(path)
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    if rtk.readrnx(str(path), 1, "", obs, nav, sta) <= 0 or (nav.n + nav.ng) == 0:
        raise InputError(f"{path}: no ephemeris could be read (RINEX {ver:g} navigation)")
    for i in range(nav.n):
        col.ephemeris(nav.eph[i], -np.inf)
    for i in range(nav.ng):
        col.glonass(nav.geph[i], -np.inf)
    return [nav.ion_gps[k] for k in range(8)]


def _read_rinex_obs(rtk, path, col):
    ver, kind = rinex_version(path)
    if not (2.0 <= ver < 4.0):
        raise InputError(f"{path}: RINEX version {ver:g} (this reader takes versions 2 and 3)")
    if kind != "O":
        raise InputError(f"{path}: RINEX type {kind!r} is not an observation file")
    _check_header_end(path)
    obs, nav, sta = rtk.obs_t(), rtk.nav_t(), rtk.sta_t()
    if rtk.readrnx(str(path), 1, "", obs, nav, sta) <= 0 or obs.n == 0:
        raise InputError(f"{path}: no raw measurements (RINEX {ver:g} observation file without records)")
    # epochs: consecutive records with one time stamp
    i = 0
    while i < obs.n:
        t = obs.data[i].time
        j = i
        while j < obs.n and abs((obs.data[j].time.time - t.time) + (obs.data[j].time.sec - t.sec)) < 1e-9:
            j += 1
        sub = rtk.obs_t()
        sub.data = obs.data[i:j]
        col.epoch(sub, j - i, nav)
        i = j


def read_gnss_raw(path, nav=None) -> GnssObservations:
    """Raw observations and ephemerides from a u-blox log or a RINEX observation file.

    Parameters
    ----------
    path : str or Path
        A u-blox binary log (RXM-RAWX, RXM-SFRBX) or a RINEX 2/3 observation file.
    nav : str or Path, optional
        A RINEX 2/3 navigation file whose ephemerides are added to those in the log
        (a RINEX observation file carries none: give one).

    Returns
    -------
    GnssObservations

    Raises
    ------
    InputError
        One line naming the file and the cause: missing or empty file, no raw
        measurements, a RINEX version other than 2 or 3, no ephemeris at all.
    """
    rtk = _lib()
    path = Path(path)
    for p in (path, nav):
        if p is None:
            continue
        if not Path(p).exists():
            raise InputError(f"{p}: no such file")
        if Path(p).is_dir():
            raise InputError(f"{p}: is a folder, not a file (give the log or RINEX file in it)")
        if Path(p).stat().st_size == 0:
            raise InputError(f"{p}: empty file")
    col = _Collector(rtk)
    if _is_rinex(path):
        _read_rinex_obs(rtk, path, col)
        iono = np.zeros(8)
    else:
        iono = _read_ubx(rtk, path, col)
    if nav is not None:
        io2 = _read_rinex_nav(rtk, Path(nav), col)
        if not np.any(iono):
            iono = io2
    src = str(path) + (f" + {nav}" if nav is not None else "")
    g = col.finish(iono, src, path)
    if not np.isfinite(g.pseudorange).any():
        raise InputError(f"{path}: every pseudorange is NaN ({len(g)} observations in {len(g.epoch_t)} epochs): "
                         "the receiver reported no range")
    if len(g.eph) + len(g.geph) == 0:
        raise InputError(f"{path}: no broadcast ephemeris in the log"
                         + ("" if nav is not None else "; give a RINEX navigation file (--gnss-nav)"))
    if nav is not None:
        _check_nav_dates(g, path, nav)
    return g


#: a broadcast ephemeris describes its satellite for a few hours around its reference time
#: (GPS: a 4 h fit interval); a navigation file none of whose ephemerides comes this close
#: to the observations [s] is of another day
NAV_REACH_S = 4 * 3600.0


def _check_nav_dates(g, path, nav) -> None:
    """Refuse a navigation file whose ephemerides are all far from the observations' time,
    naming both files and their dates (else the error said 'no satellite has an ephemeris'
    of the observation file)."""
    import datetime as dt

    toe = np.concatenate([np.asarray(g.eph.toe, float)[np.isneginf(g.eph_decoded)],
                          np.asarray(g.geph.toe, float)[np.isneginf(g.geph_decoded)]])
    if toe.size == 0:
        return
    t = np.asarray(g.epoch_t, float)
    near = np.min(np.abs(toe[:, None] - t[[0, -1]][None, :]))
    inside = np.any((toe >= t[0] - NAV_REACH_S) & (toe <= t[-1] + NAV_REACH_S))
    if inside:
        return
    day = lambda x: dt.datetime.fromtimestamp(g.t_ref + float(x), dt.timezone.utc).strftime("%Y-%m-%d %H:%M")  # noqa: E731
    raise InputError(f"{nav}: its ephemerides are for {day(toe.min())} to {day(toe.max())} (GPS time), the "
                     f"observations of {path} for {day(t[0])} to {day(t[-1])}: {near / 3600:.3g} h apart, beyond "
                     f"the {NAV_REACH_S / 3600:g} h an ephemeris holds — a navigation file of another day?")


def read_ubx_pvt(path, *, week_of=None) -> Fixes:
    """The receiver's own solutions (UBX NAV-PVT) of a u-blox log as fixes.

    Times are GPS seconds since 1970 (``iTOW`` of the week of the first RAWX epoch, or
    ``week_of`` [GPS s since 1970] if given): the time axis of :func:`read_gnss_raw`.
    σ north = σ east = hAcc/√2, σ up = vAcc; velocities ENU with σ sAcc; only solutions
    with ``gnssFixOk`` and a 3-D fix (fixType 3 or 4) are kept.
    """
    from pyubx2 import UBXReader

    path = Path(path)
    if not path.exists():
        raise InputError(f"{path}: no such file")
    rows = []
    week_t = week_of
    with open(path, "rb") as fh:
        for _raw, msg in UBXReader(fh, protfilter=2, quitonerror=0):
            if msg is None:
                continue
            ident = msg.identity
            if ident == "RXM-RAWX" and week_t is None:
                week_t = GPS_EPOCH_UNIX + int(msg.week) * _WEEK
            elif ident == "NAV-PVT":
                rows.append((msg.iTOW * 1e-3, msg.fixType, msg.gnssFixOk, msg.lat, msg.lon,
                             msg.height * 1e-3, msg.hAcc * 1e-3, msg.vAcc * 1e-3, msg.velE * 1e-3,
                             msg.velN * 1e-3, -msg.velD * 1e-3, msg.sAcc * 1e-3, msg.numSV))
    if not rows:
        raise InputError(f"{path}: no UBX NAV-PVT message")
    if week_t is None:
        raise InputError(f"{path}: no RXM-RAWX epoch to date the NAV-PVT time of week")
    a = np.array(rows, float)
    keep = (a[:, 2] > 0) & np.isin(a[:, 1], (3, 4))
    a = a[keep]
    if not a.size:
        raise InputError(f"{path}: no NAV-PVT solution with a valid 3-D fix")
    t = week_t + a[:, 0]
    sh = np.maximum(a[:, 6], 1e-3) / np.sqrt(2.0)
    sig = np.stack([sh, sh, np.maximum(a[:, 7], 1e-3)], -1)
    sv = np.maximum(a[:, 11], 1e-3)
    return Fixes(t, np.radians(a[:, 3]), np.radians(a[:, 4]), a[:, 5], sig, vel=a[:, 8:11],
                 sigma_vel=np.stack([sv, sv, sv], -1), quality=np.full(len(t), 5),
                 path=f"{path} (NAV-PVT)")
