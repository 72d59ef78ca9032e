"""RTK: double-differenced code and carrier phase against a base station, float
ambiguities per signal, integer resolution and the fixed solution.

Observation model
-----------------
For a signal (satellite s, carrier f, wavelength λ) seen by the rover r and the base b,
each receiver's undifferenced model is
``λφ = ρ + T − c δt_s + c δt_rcv + λ N + ε`` and ``P = ρ + T − c δt_s + c δt_rcv + ε``
(ρ with the Sagnac term from the satellite position at that receiver's own transmission
time, T Saastamoinen at that receiver, the broadcast satellite clock at its own time).
The base position is known, so the base's part ``y_b = λφ_b − (ρ_b + T_b − c δt_s)`` is a
number; the single difference ``λφ_r − λφ_b`` is predicted by
``ρ̂_r + T̂_r − c δt_s,r − (ρ_b + T_b − c δt_s,b) + λ Ñ_s`` plus the difference of the
receiver clocks, which the double difference between the satellite s and the reference
satellite q of its system and carrier removes:

``z = [ŜD_s − ŜD_q] − [(λφ_r − λφ_b)_s − (λφ_r − λφ_b)_q]`` (computed − measured)

and the same without ambiguity for code. The residual troposphere of a short baseline is
left to the noise, and so is the ionosphere unless ``iono="broadcast"`` applies the
Klobuchar delay at each receiver (``γ I`` on code, ``−γ I`` on phase). The states are the *single-difference* ambiguities
``Ñ_s`` [cycles] (RTKLIB's choice): integer plus fractional receiver biases per carrier
that cancel between satellites, so that a change of reference satellite changes nothing
in the filter. Each is the error of a nominal ``N₀`` (``Ñ = N₀ − x``) set to phase minus
code when the signal is (re)acquired; ``H`` holds ``λ`` on its state and the antenna
Jacobian ``∂ρ/∂r · J`` on the others. The rows of a (system, carrier) group are correlated
through their common reference: ``R = diag(σ²_s) + σ²_q 1 1ᵀ`` with ``σ² = σ²_r + σ²_b``
per signal (:func:`sinslab.fusion.carrier.signal_variance`); they are whitened with the
Cholesky factor of ``R`` so that the filter applies them as scalar rows.

Integer resolution
------------------
After the float update (computed here from the prior, the filter's update in vector
form), the double-difference ambiguities ``D (N₀ − x̂)`` of signals above
``ar_mask`` locked for ``min_lock`` seconds with their covariance ``D P Dᵀ`` go to LAMBDA
with the ratio test and partial fixing (:func:`sinslab.estimation.ambiguity.resolve`,
the satellite with the least precise float ambiguities given up first). The fixed solution (:func:`~sinslab.estimation.ambiguity.condition`)
is validated: every phase double difference's residual at it must be within
``4σ`` (RTKLIB's check of a fixed solution); otherwise the epoch stays float. With
``ar="hold"`` the accepted integers are applied to the filter as rows of σ
``hold_sigma`` [cycles] beside the observations, once (an integer the filter already holds
gets no row again; fix and hold: the INS is corrected by the fixed solution); with ``ar="continuous"`` the fixed solution is reported and the filter
stays float; ``ar="off"`` reports the float solution only.

Cycle slips (:class:`sinslab.fusion.carrier.SlipDetector` on both receivers: LLI,
geometry-free, Doppler; the prediction test on the rover's phase change against the
range change from the position the filter held at the last epoch to the present prior,
and on the base against its known position) restart the signal's ambiguity through the
filter's state transform before the rows; a phase double difference whose innovation
fails the gate is dropped and its ambiguity restarted (most of a group failing: the
reference's).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_triangular

from sinslab.core import earth as E
from sinslab.core import gnss as G
from sinslab.core.errors import InputError
from sinslab.estimation.ambiguity import condition, resolve
from sinslab.fusion.carrier import AmbiguitySlots, SlipDetector, prediction_slips, signal_variance, troposphere
from sinslab.fusion.gnss import F_L1

__all__ = ["RtkOptions", "RtkBase", "RtkEngine", "RtkLog", "STATUS", "check_pair", "check_phase"]

#: Solution status per epoch: no rows, float, fixed.
STATUS = {"none": 0, "float": 1, "fixed": 2}


@dataclass(frozen=True)
class RtkOptions:
    """Settings of the RTK rows and integer resolution (SI; angles in rad).

    Attributes
    ----------
    phase_sigma, code_sigma : float
        σ₀ of one undifferenced phase / code observation [m] at zenith and C/N0 ≥ ``cn0_ref``.
    cn0_ref : float
        [dB-Hz].
    mask : float
        Elevation mask of the rows [rad].
    ar : {"hold", "continuous", "off"}
        Integer resolution: fix and hold, fixed solution reported only, none.
    ar_mask : float
        Elevation mask of the ambiguities fixed [rad].
    ratio : float
        Ratio-test threshold.
    success : float
        Least bootstrapped success rate of the float ambiguities fixed
        (:func:`sinslab.estimation.ambiguity.success_rate`; 0: the ratio test alone).
    min_fixed : int
        Fewest double-difference ambiguities in a fix.
    min_lock : float
        A signal's ambiguity is fixed after this long since its (re)start [s].
    hold_sigma : float
        σ of the held integers [cycles].
    gate : float
        Innovation gate of a double difference [σ of H P Hᵀ + R].
    gf, doppler_k, prediction_k : float or None
        Slip tests (see :mod:`sinslab.fusion.carrier`); None turns one off.
    max_gap : float
        A signal unseen for longer restarts its ambiguity [s].
    max_age : float
        Oldest base epoch used with a rover epoch [s].
    sigma0 : float
        σ of a restarted single-difference ambiguity [cycles].
    iono : {"off", "broadcast"}
        The difference of the ionospheric delays at rover and base: left to the noise (a
        short baseline), or the broadcast (Klobuchar) model's at each receiver.
    systems : str
        Systems used (GLONASS FDMA phase is not double-differenced).
    """

    phase_sigma: float = 0.003
    code_sigma: float = 0.3
    cn0_ref: float = 45.0
    mask: float = math.radians(15.0)
    ar: str = "hold"
    ar_mask: float = math.radians(15.0)
    ratio: float = 3.0
    success: float = 0.999
    min_fixed: int = 4
    min_lock: float = 0.0
    hold_sigma: float = 0.001
    gate: float = 5.0
    gf: float | None = 0.05
    doppler_k: float | None = 5.0
    prediction_k: float | None = 5.0
    max_gap: float = 5.0
    max_age: float = 30.0
    sigma0: float = 150.0
    iono: str = "off"
    systems: str = "GECJ"

    def __post_init__(self):
        if self.ar not in ("hold", "continuous", "off"):
            raise ValueError(f"ar must be 'hold', 'continuous' or 'off', got {self.ar!r}")
        if self.iono not in ("off", "broadcast"):
            raise ValueError(f"iono must be 'off' or 'broadcast', got {self.iono!r}")
        for k in ("phase_sigma", "code_sigma", "ratio", "hold_sigma", "gate", "max_gap", "max_age", "sigma0"):
            v = getattr(self, k)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{k} must be > 0, got {v!r}")


@dataclass(frozen=True)
class RtkBase:
    """A base station: its prepared observations (with ``signals``) and known position.

    Attributes
    ----------
    sv : sinslab.fusion.gnss.SatelliteObservations
        On the rover's time axis.
    position : ndarray (3,)
        ECEF [m] (the antenna reference point the phase refers to).
    source : str
        Name for messages (the file).
    """

    sv: object
    position: np.ndarray
    source: str = "base"


@dataclass
class RtkLog:
    """Per epoch of the rover (lists, one entry per epoch asked for): ``t`` [s], ``status``
    (:data:`STATUS`), ``ratio``, ``n_fixed`` (double-difference ambiguities fixed),
    ``n_amb`` (formed), ``n_phase``, ``n_code`` (double differences used), ``n_slip``
    (ambiguities restarted), ``age`` (of the base epoch [s]), ``float_pos``, ``fixed_pos``
    (ECEF antenna [m], NaN when none), ``float_cov``, ``fixed_cov`` (3×3 ECEF [m²]) and
    ``fixed_dd``: the integers fixed, ``([(satellite, reference satellite, carrier slot),
    ...], integers)``; ``restarted``: the signals ``(satellite, slot)`` whose ambiguity was
    (re)started (new, slipped, gated)."""

    t: list = field(default_factory=list)
    status: list = field(default_factory=list)
    ratio: list = field(default_factory=list)
    n_fixed: list = field(default_factory=list)
    n_amb: list = field(default_factory=list)
    n_phase: list = field(default_factory=list)
    n_code: list = field(default_factory=list)
    n_slip: list = field(default_factory=list)
    age: list = field(default_factory=list)
    float_pos: list = field(default_factory=list)
    fixed_pos: list = field(default_factory=list)
    float_cov: list = field(default_factory=list)
    fixed_cov: list = field(default_factory=list)
    fixed_dd: list = field(default_factory=list)
    restarted: list = field(default_factory=list)

    def arrays(self):
        """The lists as arrays (``fixed_dd`` and ``restarted`` stay lists)."""
        return {k: (v if k in ("fixed_dd", "restarted") else np.asarray(v)) for k, v in self.__dict__.items()}


_NAN3 = np.full(3, np.nan)


class RtkEngine:
    """The RTK rows of one rover against one base, epoch by epoch, for any filter whose
    state holds the antenna position error through a Jacobian ``J`` (3, n) and the
    ambiguity states ``columns`` (the INS measurement :class:`sinslab.fusion.rtk_ins.DoubleDifferences`
    and the GNSS-only filter :func:`sinslab.fusion.gnss_alone.rtk_solve`).

    Parameters
    ----------
    rover : SatelliteObservations
        With ``signals``.
    base : RtkBase
    columns : int array
        Filter columns of the ambiguity states.
    n : int
        Number of filter states.
    options : RtkOptions
    """

    def __init__(self, rover, base: RtkBase, columns, n, options: RtkOptions = RtkOptions()):
        if rover.signals is None or base.sv.signals is None:
            raise ValueError("RTK needs the signals (carrier phase) of rover and base")
        self.rover, self.base, self.opt = rover, base, options
        self.slots = AmbiguitySlots(columns, sigma0=options.sigma0, max_gap=options.max_gap)
        kw = dict(gf=options.gf, doppler_k=options.doppler_k, phase_sigma=options.phase_sigma,
                  cn0_ref=options.cn0_ref, max_gap=options.max_gap)
        self.det_r, self.det_b = SlipDetector(**kw), SlipDetector(**kw)
        self.log = RtkLog()
        self.counts = dict(no_base_epoch=0, no_base_signal=0, half_cycle=0, no_slot=0, code_rejected=0,
                           phase_rejected=0, fix_rejected=0)
        self._pair = _pair_epochs(rover.t_epoch, base.sv.t_epoch, options.max_age)
        self._base_terms()
        self._cur = None
        self._last = None                   # (t, pos, {key: (λφ [m], sat clock [m], sat pos)})
        self._base_seen = -1
        self._base_slip = {}
        self._b_prev = None
        self._gated = set()                 # slots whose double difference failed the gate
        self.n = int(n)
        #: ν²/(H P Hᵀ + R) of the rows used, one row at a time: [sum, rows] per kind
        self.nis = {"ph": [0.0, 0], "code": [0.0, 0]}

    # -- set-up
    def _base_terms(self):
        """``ρ_b + T_b − c δt_s`` [m] and the elevation of every base row."""
        b = self.base.sv
        rb = np.asarray(self.base.position, float)
        lat, lon, h = (float(v) for v in E.ecef_to_geodetic(rb))
        rho, _ = G.sagnac_range(b.sat_pos, rb)
        el, az = E.elevation_azimuth(b.sat_pos, lat, lon, h)
        self._b_el = el
        self._b_pred = rho + G.saastamoinen(lat, h, el) - b.sat_clock
        self._b_iono = np.zeros(el.size)
        if self.opt.iono == "broadcast":
            self._b_iono = G.klobuchar(b.t_epoch[b.epoch] - b.t_ref, lat, lon, az, el, b.iono)
        self._b_rows = {}

    def _base_rows(self, eb):
        d = self._b_rows.get(eb)
        if d is None:
            rows = self.base.sv.rows(eb)
            d = {s: int(i) for s, i in zip(self.base.sv.sat[rows], rows)}
            self._b_rows = {eb: d}
        return d

    # -- step 1: signals, slips and restarts (before the filter's update)
    def prepare(self, e, r, prior_pos_sigma=0.0):
        """Select the signals of rover epoch ``e`` seen from the antenna at ``r`` (ECEF),
        detect slips and restart ambiguities. Returns the filter's state transform
        ``(A, Q)`` or None; ``prior_pos_sigma`` [m] is the σ of the predicted position change
        since the last epoch (the prediction test's)."""
        rv, opt = self.rover, self.opt
        t = float(rv.t_epoch[e])
        self.slots.free_stale(t)
        eb = self._pair[e]
        cur = dict(e=e, t=t, eb=eb, n_slip=0)
        self._cur = cur
        if eb < 0:
            self.counts["no_base_epoch"] += 1
            cur["sig"] = None
            return self.slots.transform(self.n)
        rows = rv.rows(e)
        rows = rows[rv.usable[rows] & np.array([s[0] in opt.systems and s[0] != "R" for s in rv.sat[rows]], bool)]
        lat, lon, h = (float(v) for v in E.ecef_to_geodetic(r))
        el, _ = E.elevation_azimuth(rv.sat_pos[rows], lat, lon, h)
        up = el >= opt.mask
        rows, el = rows[up], el[up]
        sig = self._signals(e, eb, rows, el)
        cur["sig"] = sig
        if sig is None:
            return self.slots.transform(self.n)
        slip = self._slips(t, eb, rows, el, sig, r, prior_pos_sigma)
        cur["n_slip"] = self._restart(sig, slip, t)
        return self.slots.transform(self.n)

    def _signals(self, e, eb, rows, el):
        """The (rover row, carrier) pairs with phase and code on both receivers at one
        frequency, as flat arrays; None when there are none."""
        rS, bS = self.rover.signals, self.base.sv.signals
        brow = self._base_rows(eb)
        j_of = np.array([brow.get(s, -1) for s in self.rover.sat[rows].tolist()], dtype=np.int64)
        mine = np.isfinite(rS.phase[rows]) & np.isfinite(rS.pseudorange[rows])
        half = mine & ((rS.lli[rows] & 2) != 0)
        self.counts["half_cycle"] += int(half.sum())
        mine &= ~half
        jj = np.maximum(j_of, 0)
        theirs = ((j_of >= 0)[:, None] & np.isfinite(bS.phase[jj]) & np.isfinite(bS.pseudorange[jj])
                  & (np.abs(bS.freq[jj] - rS.freq[rows]) < 1e3) & ((bS.lli[jj] & 2) == 0))
        self.counts["no_base_signal"] += int((mine & ~theirs).sum())
        k, f = np.nonzero(mine & theirs)
        if not k.size:
            return None
        i, j = rows[k], j_of[k]
        lam = G.C_LIGHT / rS.freq[i, f]
        sat = self.rover.sat[i]
        return dict(k=k, i=i, f=f, j=j, el=el[k], lam=lam, sat=sat, keys=list(zip(sat.tolist(), f.tolist())),
                    sys=sat.astype("U1"), Lr=rS.phase[i, f] * lam, Pr=rS.pseudorange[i, f], Lb=bS.phase[j, f] * lam,
                    Pb=bS.pseudorange[j, f], cn0_r=rS.cn0[i, f], cn0_b=bS.cn0[j, f])

    def _slips(self, t, eb, rows, el, sig, r, pos_sigma):
        """Slip flags of the signals (both receivers' tests, the prediction tests)."""
        rv, b, opt = self.rover, self.base.sv, self.opt
        S = rv.signals
        s_r, _ = self.det_r.check(t, rv.sat[rows], S.phase[rows], S.doppler[rows], S.freq[rows], S.lli[rows],
                                  rv.cn0[rows], el)
        slip = s_r[sig["k"], sig["f"]]
        if eb != self._base_seen:                    # the base's tests once per base epoch
            brows = b.rows(eb)
            s_b, _ = self.det_b.check(float(b.t_epoch[eb]), b.sat[brows], b.signals.phase[brows],
                                      b.signals.doppler[brows], b.signals.freq[brows], b.signals.lli[brows],
                                      b.cn0[brows], self._b_el[brows])
            self._base_slip = {(s, f): bool(s_b[q, f]) for q, s in enumerate(b.sat[brows])
                               for f in range(s_b.shape[1])}
            self._base_predicted(eb, brows)
            self._base_seen = eb
        slip = slip | np.array([self._base_slip.get(k_, True) for k_ in sig["keys"]], bool)
        if opt.prediction_k is not None and self._last is not None:
            slip |= self._predicted(t, sig, r, pos_sigma)
        return slip

    def _base_predicted(self, eb, brows):
        """The prediction test on the base (known position): restarts counted in the base's
        slip flags."""
        opt, b = self.opt, self.base.sv
        S = b.signals
        q, f = np.nonzero(np.isfinite(S.phase[brows]))
        i = brows[q]
        var = signal_variance(opt.phase_sigma, b.cn0[i], self._b_el[i], opt.cn0_ref)
        now = dict(keys=list(zip(b.sat[i].tolist(), f.tolist())), L=S.phase[i, f] * G.C_LIGHT / S.freq[i, f],
                   pred=self._b_pred[i], var=var)
        prev, self._b_prev = self._b_prev, now
        if prev is None or opt.prediction_k is None:
            return
        pk = {k: n for n, k in enumerate(prev["keys"])}
        a = [n for n, k in enumerate(now["keys"]) if k in pk and not self._base_slip.get(k, False)]
        if len(a) < 3:
            return
        a = np.array(a)
        p = np.array([pk[now["keys"][n]] for n in a])
        hit = prediction_slips(now["L"][a] - prev["L"][p], now["pred"][a] - prev["pred"][p],
                               now["var"][a] + prev["var"][p], opt.prediction_k)
        self.det_b.counts["prediction"] += int(hit.sum())
        for n in a[hit]:
            self._base_slip[now["keys"][n]] = True

    def _predicted(self, t, sig, r, pos_sigma):
        """The prediction test on the rover: phase change against the range change from the
        last epoch's filtered antenna position to ``r``."""
        opt, rv = self.opt, self.rover
        t0, r0, prev = self._last
        if t - t0 > opt.max_gap:
            return np.zeros(len(sig["keys"]), bool)
        rho, _ = G.sagnac_range(rv.sat_pos[sig["i"]], r)
        sclk = rv.sat_clock[sig["i"]]
        out = np.zeros(len(sig["keys"]), bool)
        q = [n for n, k in enumerate(sig["keys"]) if k in prev]
        if len(q) < 3:
            return out
        q = np.array(q)
        pv = [prev[sig["keys"][n]] for n in q]
        rho0 = G.sagnac_range(np.array([p[2] for p in pv]), r0)[0]
        dphi = sig["Lr"][q] - np.array([p[0] for p in pv])
        dpred = (rho[q] - rho0) - (sclk[q] - np.array([p[1] for p in pv]))
        var = 2 * signal_variance(opt.phase_sigma, sig["cn0_r"][q], sig["el"][q], opt.cn0_ref) + pos_sigma ** 2
        hit = prediction_slips(dphi, dpred, var, opt.prediction_k)
        self.det_r.counts["prediction"] += int(hit.sum())
        out[q] = hit
        return out

    def _restart(self, sig, slip, t):
        """Ambiguities of slipped, new or gated signals restarted at phase minus code;
        signals left without a state are dropped."""
        slots = self.slots.lookup(sig["keys"])
        again = np.array([s in self._gated for s in slots.tolist()], bool)
        self._gated = set()
        need = slip | (slots < 0) | again
        self._cur["restarted"] = [sig["keys"][q] for q in np.flatnonzero(need)]
        if need.any():
            idx = np.flatnonzero(need)
            n0 = ((sig["Lr"] - sig["Lb"]) - (sig["Pr"] - sig["Pb"]))[idx] / sig["lam"][idx]
            slots[idx] = self.slots.restart([sig["keys"][q] for q in idx], n0, t)
        have = slots >= 0
        self.counts["no_slot"] += int((~have).sum())
        for k in list(sig):
            if isinstance(sig[k], np.ndarray) and sig[k].shape[:1] == (slots.size,):
                sig[k] = sig[k][have]
        sig["keys"] = [k for k, hv in zip(sig["keys"], have) if hv]
        sig["slot"] = slots[have]
        sig["fresh"] = need[have]
        self.slots.touch(sig["slot"], t)
        return int(need.sum())

    # -- step 2: the rows, the float solution and the fix
    def rows(self, r, J, prior):
        """Double differences of the epoch :meth:`prepare` selected, at the antenna ``r``
        (ECEF [m]) whose error is ``J x`` (J (3, n)), against the filter prior
        ``(x, P)`` (P None: the rows only, without gate, integers or record). Returns
        ``(z, H, R)`` (whitened rows and held integers, R a vector) or None."""
        cur, opt = self._cur, self.opt
        sig = cur.get("sig")
        if sig is None or sig["slot"].size < 2:
            self._log_none(cur)
            return None
        x, P = prior
        rv = self.rover
        i = sig["i"]
        rs = rv.sat_pos[i]
        rho, u = G.sagnac_range(rs, r)
        trop, dtrop, el = troposphere(r, rs)
        g = -u + (E.WIE / G.C_LIGHT) * np.stack([-rs[:, 1], rs[:, 0], np.zeros(i.size)], -1) + dtrop
        pred = rho + trop - rv.sat_clock[i] - self._b_pred[sig["j"]]
        gJ = g @ J
        lam = sig["lam"]
        cols = self.slots.columns[sig["slot"]]
        m = i.size
        if opt.iono == "broadcast":      # code delayed, phase advanced by γ I (γ = (f_L1/f)²)
            t_gps = float(rv.t_epoch[cur["e"]] - rv.t_ref)
            lat, lon, h = (float(v) for v in E.ecef_to_geodetic(r))
            _, az = E.elevation_azimuth(rs, lat, lon, h)
            I_r = G.klobuchar(t_gps, lat, lon, az, el, rv.iono)
            dI = (I_r - self._b_iono[sig["j"]]) * (F_L1 * lam / G.C_LIGHT) ** 2
        else:
            dI = 0.0
        zph = pred - dI + lam * self.slots.n0[sig["slot"]] - (sig["Lr"] - sig["Lb"])
        Hph = gJ.copy()
        Hph[np.arange(m), cols] += lam
        zc = pred + dI - (sig["Pr"] - sig["Pb"])
        # both receivers' weights at the base's elevation (the same within 0.1° over tens of
        # kilometres): R, and so the whitened rows, do not move with the rover's state
        el_b = self._b_el[sig["j"]]
        vph = (signal_variance(opt.phase_sigma, sig["cn0_r"], el_b, opt.cn0_ref)
               + signal_variance(opt.phase_sigma, sig["cn0_b"], el_b, opt.cn0_ref))
        vc = (signal_variance(opt.code_sigma, sig["cn0_r"], el_b, opt.cn0_ref)
              + signal_variance(opt.code_sigma, sig["cn0_b"], el_b, opt.cn0_ref))
        groups = self._groups(sig, el)
        dd = _double_differences(groups, (zph, Hph, vph), (zc, gJ, vc))
        if dd is None:
            self._log_none(cur)
            return None
        if P is None:                       # no prior (a check of H): the rows alone
            return (*_whiten(dd), np.ones(sum(b[2].size for k in dd for b in dd[k])))
        dd = self._gate(dd, groups, sig, x, P)
        if dd is None:
            self._log_none(cur)
            return None
        zw, Hw = _whiten(dd)
        return self._solve(zw, Hw, dd, groups, sig, el, x, P, r, J)

    def _groups(self, sig, el):
        """(system, carrier) groups of two or more signals: (reference index, other indices),
        the reference the highest of the signals not restarted now (of all, if none)."""
        out = []
        key = np.array([ord(c) for c in sig["sys"].tolist()]) * 8 + sig["f"]
        for gk in np.unique(key):
            idx = np.flatnonzero(key == gk)
            if idx.size < 2:
                continue
            locked = idx[~sig["fresh"][idx]]
            pool = locked if locked.size else idx
            ref = int(pool[np.argmax(el[pool])])
            out.append((ref, idx[idx != ref]))
        return out

    def _gate(self, dd, groups, sig, x, P):
        """Rows whose innovation ``z − H x`` exceeds ``gate`` σ of ``H P Hᵀ + R`` dropped;
        their ambiguities restarted at the next epoch (most of a phase group failing: its
        reference's, the whole group dropped)."""
        g2 = self.opt.gate ** 2
        blocks = dd["ph"] + dd["code"]
        Hs = np.vstack([b[3] for b in blocks])
        nu_all = np.concatenate([b[2] for b in blocks]) - Hs @ x
        s_all = np.einsum("ij,ij->i", Hs @ P, Hs)
        out = {"ph": [], "code": []}
        at = 0
        for j, (ref, oth, z, H, R) in enumerate(blocks):
            kind = "ph" if j < len(dd["ph"]) else "code"
            m = z.size
            nu, S = nu_all[at:at + m], s_all[at:at + m] + np.diag(R)
            at += m
            bad = nu * nu > g2 * S
            if kind == "code":
                self.counts["code_rejected"] += int(bad.sum())
            elif bad.sum() * 2 > bad.size and bad.size >= 2:
                self._gated.add(int(sig["slot"][ref]))
                self.counts["phase_rejected"] += int(bad.size)
                continue
            elif bad.any():
                self._gated.update(int(s_) for s_ in sig["slot"][oth[bad]])
                self.counts["phase_rejected"] += int(bad.sum())
            keep = ~bad
            self.nis[kind][0] += float(np.sum(nu[keep] ** 2 / S[keep]))
            self.nis[kind][1] += int(keep.sum())
            if not bad.any():
                out[kind].append((ref, oth, z, H, R))
            elif not bad.all():
                ok = ~bad
                out[kind].append((ref, oth[ok], z[ok], H[ok], R[np.ix_(ok, ok)]))
        return out if (out["ph"] or out["code"]) else None

    def _solve(self, zw, Hw, dd, groups, sig, el, x, P, r, J):
        """Float update, integer resolution, validation; the rows for the filter and the log."""
        opt, cur = self.opt, self._cur
        xf, Pf = _float_update(x, P, zw, Hw)
        fix_rows = None
        x_fix = P_fix = None
        ratio, n_fixed, n_amb = np.nan, 0, 0
        if opt.ar != "off" and dd["ph"]:
            Dx, d, sats = self._dd_ambiguities(dd["ph"], sig, el)
            n_amb = d.size
            if n_amb:
                a_hat = d - Dx @ xf
                Qa = Dx @ Pf @ Dx.T
                fix = resolve(a_hat, Qa, ratio=opt.ratio, min_fixed=opt.min_fixed, success=opt.success,
                              drop_order=_by_satellite(sats, Qa))
                ratio = fix.ratio
                if fix.fixed:
                    sel = fix.used
                    dsel = d[sel] - fix.integers[sel]
                    x_fix, P_fix = condition(xf, Pf, Dx[sel], dsel)
                    if self._valid(dd["ph"], x_fix):
                        n_fixed = int(sel.sum())
                        # an integer already held (float within 3 hold σ of it, variance below
                        # (3 hold σ)²) needs no row again: the filter carries it
                        h = opt.hold_sigma
                        new = sel & ((np.diag(Qa) > 9 * h * h) | (np.abs(a_hat - np.nan_to_num(fix.integers)) > 3 * h))
                        fix_rows = (Dx[new], d[new] - fix.integers[new])
                        cur["fixed"] = ([p for p, u in zip(cur["pairs"], sel) if u], fix.integers[sel])
                    else:
                        self.counts["fix_rejected"] += 1
                        x_fix = P_fix = None
        status = STATUS["fixed"] if fix_rows is not None else STATUS["float"]
        self._record(cur, status, ratio, n_fixed, n_amb, dd, r, J, xf, Pf, x_fix, P_fix, sig)
        if fix_rows is not None and opt.ar == "hold" and fix_rows[1].size:
            k = fix_rows[1].size
            return (np.concatenate([zw, fix_rows[1]]), np.vstack([Hw, fix_rows[0]]),
                    np.concatenate([np.ones(zw.size), np.full(k, opt.hold_sigma ** 2)]))
        return zw, Hw, np.ones(zw.size)

    def _dd_ambiguities(self, ph, sig, el):
        """Rows ``D`` (k, n) on the ambiguity states and ``d = D N₀`` (k,) of the
        double-difference ambiguities that may be fixed (``â = d − D x``), and the
        satellite of each."""
        opt = self.opt
        cols = self.slots.columns[sig["slot"]]
        lock = self.slots.lock_time(sig["slot"], self._cur["t"])
        n0 = self.slots.n0[sig["slot"]]
        rows, d, sats, pairs = [], [], [], []
        for ref, oth, *_ in ph:
            if el[ref] < opt.ar_mask or lock[ref] < opt.min_lock:
                continue
            for q in oth:
                if el[q] < opt.ar_mask or lock[q] < opt.min_lock:
                    continue
                row = np.zeros(self.n)
                row[cols[q]] += 1.0
                row[cols[ref]] -= 1.0
                rows.append(row)
                d.append(n0[q] - n0[ref])
                sats.append(sig["sat"][q])
                pairs.append((sig["sat"][q], sig["sat"][ref], int(sig["f"][q])))
        self._cur["pairs"] = pairs
        if not rows:
            return np.zeros((0, self.n)), np.zeros(0), np.zeros(0, "U3")
        return np.array(rows), np.array(d), np.array(sats)

    def _valid(self, ph, x_fix):
        """Every phase double difference within 4σ of its noise at the fixed solution."""
        for _, _, z, H, R in ph:
            v = z - H @ x_fix
            if np.any(v * v > 16.0 * np.diag(R)):
                return False
        return True

    def _record(self, cur, status, ratio, n_fixed, n_amb, dd, r, J, xf, Pf, x_fix, P_fix, sig):
        log = self.log
        pos_f = r - J @ xf
        log.t.append(cur["t"])
        log.status.append(status)
        log.ratio.append(float(ratio))
        log.n_fixed.append(n_fixed)
        log.n_amb.append(n_amb)
        log.n_phase.append(int(sum(b[2].size for b in dd["ph"])))
        log.n_code.append(int(sum(b[2].size for b in dd["code"])))
        log.n_slip.append(cur["n_slip"])
        log.restarted.append(cur.get("restarted", []))
        log.age.append(float(self.rover.t_epoch[cur["e"]] - self.base.sv.t_epoch[cur["eb"]]))
        log.float_pos.append(pos_f)
        log.float_cov.append(J @ Pf @ J.T)
        if x_fix is not None:
            log.fixed_pos.append(r - J @ x_fix)
            log.fixed_cov.append(J @ P_fix @ J.T)
        else:
            log.fixed_pos.append(_NAN3)
            log.fixed_cov.append(np.full((3, 3), np.nan))
        log.fixed_dd.append(cur.get("fixed", ([], np.zeros(0))))
        best = log.fixed_pos[-1] if x_fix is not None else pos_f
        self._last = (cur["t"], best, {k: (L, c, p) for k, L, c, p in zip(
            sig["keys"], sig["Lr"], self.rover.sat_clock[sig["i"]], self.rover.sat_pos[sig["i"]])})

    def _log_none(self, cur):
        log = self.log
        log.t.append(cur["t"])
        log.status.append(STATUS["none"])
        for k in ("ratio",):
            getattr(log, k).append(np.nan)
        for k in ("n_fixed", "n_amb", "n_phase", "n_code"):
            getattr(log, k).append(0)
        log.n_slip.append(cur.get("n_slip", 0))
        log.restarted.append(cur.get("restarted", []))
        eb = cur.get("eb", -1)
        log.age.append(float(self.rover.t_epoch[cur["e"]] - self.base.sv.t_epoch[eb]) if eb >= 0 else np.nan)
        for k in ("float_pos", "fixed_pos"):
            getattr(log, k).append(_NAN3)
        for k in ("float_cov", "fixed_cov"):
            getattr(log, k).append(np.full((3, 3), np.nan))
        log.fixed_dd.append(([], np.zeros(0)))

    @property
    def slip_counts(self):
        """Restarts by cause on the rover and the base (LLI, geometry-free, Doppler,
        prediction) and by the gate."""
        out = {f"rover_{k}": v for k, v in self.det_r.counts.items() if k != "gate"}
        out.update({f"base_{k}": v for k, v in self.det_b.counts.items() if k != "gate"})
        out["gate"] = self.counts["phase_rejected"]
        return out


def _by_satellite(sats, Qa):
    """Partial fixing's order: a satellite's double differences given up together, the
    satellite with the least precise float ambiguity first."""
    var = np.diag(Qa)
    worst = {}
    for k, s_ in enumerate(sats):
        worst.setdefault(s_, []).append(k)
    return sorted(worst.values(), key=lambda ks: -max(var[k] for k in ks))


def _double_differences(groups, phase, code):
    """Per group, the double differences of single-difference rows ``(z, H, var)``:
    ``(ref, others, z (k,), H (k, n), R (k, k))`` for phase and code."""
    out = {"ph": [], "code": []}
    for kind, (z, H, v) in (("ph", phase), ("code", code)):
        for ref, oth in groups:
            zz = z[oth] - z[ref]
            HH = H[oth] - H[ref]
            R = np.diag(v[oth]) + v[ref]
            out[kind].append((ref, oth, zz, HH, R))
    return out if groups else None


def _float_update(x, P, z, H):
    """The posterior of unit-variance rows ``(z, H)`` on the prior ``(x, P)`` in vector
    form: ``W = L⁻¹ H P`` with ``L Lᵀ = H P Hᵀ + I``, ``x + Wᵀ L⁻¹ (z − H x)``, ``P − Wᵀ W``
    (what the filter's update gives, to rounding; used for the integer search and the
    solutions reported)."""
    HP = H @ P
    S = HP @ H.T
    S.flat[::S.shape[0] + 1] += 1.0
    L = np.linalg.cholesky(S)
    Wv = solve_triangular(L, np.column_stack([HP, z - H @ x]), lower=True, check_finite=False)
    W, v = Wv[:, :-1], Wv[:, -1]
    Pf = P - W.T @ W
    return x + W.T @ v, 0.5 * (Pf + Pf.T)


def _whiten(dd):
    """Every block's rows times the inverse Cholesky factor of its R (one block-diagonal
    factor for all): uncorrelated rows of unit variance (the filter applies them one at a
    time)."""
    blocks = dd["ph"] + dd["code"]
    z = np.concatenate([b[2] for b in blocks])
    H = np.vstack([b[3] for b in blocks])
    R = np.zeros((z.size, z.size))
    at = 0
    for b in blocks:
        m = b[2].size
        R[at:at + m, at:at + m] = b[4]
        at += m
    L = np.linalg.cholesky(R)
    zH = solve_triangular(L, np.column_stack([z, H]), lower=True, check_finite=False)
    return zH[:, 0], zH[:, 1:]


def _pair_epochs(t_rover, t_base, max_age):
    """For each rover epoch the latest base epoch at or before it (1 ms slack) within
    ``max_age`` [s], −1 where none."""
    j = np.searchsorted(t_base, np.asarray(t_rover) + 1e-3, side="right") - 1
    ok = (j >= 0)
    age = np.where(ok, np.asarray(t_rover) - t_base[np.maximum(j, 0)], np.inf)
    return np.where(ok & (age <= max_age), j, -1)


def _carriers(sv):
    """{(system, rounded carrier frequency [MHz])} with a carrier phase."""
    S = sv.signals
    i, f = np.nonzero(np.isfinite(S.phase))
    return {(s[0], int(round(fr / 1e6))) for s, fr in zip(sv.sat[i], S.freq[i, f])}


def _gps_time(t):
    """GPS seconds since 1970 (no leap seconds) as a date and time of GPS time."""
    import datetime as dt
    return dt.datetime.fromtimestamp(float(t), dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S") + " GPST"


def check_phase(sv, name):
    """One-line errors of observations that cannot carry phase measurements: no carrier
    phase at all, or every phase flagged as a loss of lock."""
    if sv.signals is None or not np.isfinite(sv.signals.phase).any():
        raise InputError(f"{name}: no carrier phase in the observations (RTK and time-differenced phase need it)")
    S = sv.signals
    have = np.isfinite(S.phase)
    if have.sum() > 0 and np.all(S.slip[have]):
        raise InputError(f"{name}: every carrier-phase observation is flagged as a cycle slip (loss of lock): "
                         "no ambiguity lasts two epochs")


def check_pair(rover, base: RtkBase, rover_name="rover", options: RtkOptions = RtkOptions(), *,
               position_tolerance=100.0, baseline_warning=50e3):
    """Refuse a rover/base pair RTK cannot use, with one line naming the file and the cause
    (:class:`~sinslab.core.errors.InputError`): either without phase or with every phase
    flagged, a base whose epochs do not overlap the rover's (another day) or come further
    apart than ``options.max_age``, no carrier in common, a base position more than
    ``position_tolerance`` [m] from the base observations' own single-point solution.
    Returns warnings (a baseline longer than ``baseline_warning`` [m])."""
    from sinslab.fusion.gnss import single_point
    bname = base.source
    check_phase(rover, rover_name)
    check_phase(base.sv, bname)
    tr, tb = rover.t_epoch, base.sv.t_epoch
    if tb[0] > tr[-1] or tb[-1] + options.max_age < tr[0]:
        raise InputError(f"{bname}: its epochs ({_gps_time(tb[0])} .. {_gps_time(tb[-1])}) do not overlap the "
                         f"rover's ({_gps_time(tr[0])} .. {_gps_time(tr[-1])}): a base file of another day or time")
    step = float(np.median(np.diff(tb))) if tb.size > 1 else 0.0
    if step > options.max_age:
        raise InputError(f"{bname}: base epochs every {step:g} s, further apart than the {options.max_age:g} s a "
                         "base epoch may be used for (RTK needs a base at 1–30 s)")
    common = _carriers(rover) & _carriers(base.sv)
    if not common:
        fmt = lambda c: ", ".join(f"{s} {f} MHz" for s, f in sorted(c))  # noqa: E731
        raise InputError(f"{bname}: no carrier in common with the rover ({rover_name}: {fmt(_carriers(rover))}; "
                         f"base: {fmt(_carriers(base.sv))})")
    sp = single_point(base.sv)
    ok = np.isfinite(sp.lat)
    if ok.any():
        r = E.geodetic_to_ecef(np.median(sp.lat[ok]), np.median(sp.lon[ok]), np.median(sp.h[ok]))
        off = float(np.linalg.norm(r - np.asarray(base.position, float)))
        if off > position_tolerance:
            raise InputError(f"{bname}: the base position given is {off / 1e3:.3g} km from the base observations' own "
                             f"single-point solution ({r[0]:.1f}, {r[1]:.1f}, {r[2]:.1f} m): check the base position")
    warnings = []
    spr = single_point(rover)
    okr = np.isfinite(spr.lat)
    if okr.any():
        rr = E.geodetic_to_ecef(spr.lat[okr][0], spr.lon[okr][0], spr.h[okr][0])
        dist = float(np.linalg.norm(rr - np.asarray(base.position, float)))
        if dist > baseline_warning:
            warnings.append(f"baseline {dist / 1e3:.0f} km: beyond {baseline_warning / 1e3:.0f} km the ionosphere and "
                            "troposphere no longer cancel in double differences; integers may not be found")
    return warnings
