"""Time-differenced carrier phase (TDCP) as a measurement of the fusion driver, without a
base station: :class:`TimeDifferencedPhase`.

Between two epochs of one receiver a signal tracked without a slip keeps its ambiguity,
so its phase change is the change of range, of the receiver clock and of the satellite
clock (and the troposphere's, modelled; the ionosphere's, millimetres per second, left
to the noise):

``z = [ρ̂_k(r̂_k) − ρ̂_j(r̂_j)] + [T̂_k − T̂_j] + [b̂_k − b̂_j] − [c δt_s,k − c δt_s,j] − [λφ_k − λφ_j]``

with ``j`` the last epoch the measurement was applied at (any interval up to ``max_gap``,
so a longer interval uses the INS's position change over it). ``r̂_j`` and ``b̂_j`` are
the antenna position and nominal clock bias *recorded* at ``j``; their errors are not in
the present state, so the measurement keeps them as states of its own (stochastic
cloning, Roumeliotis & Burdick 2002): before its rows at each epoch it asks the driver to
copy the present antenna-position error ``J x`` (J (3, n) the antenna Jacobian of
:meth:`sinslab.fusion.gnss.SatelliteMeasurement.antenna`) and clock-bias error into one
of two clone sets (:func:`sinslab.nav.errstate.phase_clones`, used in turn), so that the
rows of the next epoch read ``H = ∂ρ_k/∂r · J + e_b − ∂ρ_j/∂r · [clone xyz] − [clone b]``.
The clones keep what the update of epoch ``j`` learnt about that epoch's position, and
the receiver-clock change ``b_k − b_j`` is the clock block's own (bias integrating the
drift; the clone carries the bias error of epoch j).

Rows are per signal (every carrier with a phase), weighted by
:func:`sinslab.fusion.carrier.signal_variance` at both epochs; slips are found by
:class:`sinslab.fusion.carrier.SlipDetector` (LLI, geometry-free, Doppler) and the
prediction test against the INS's position change (from the corrected position of epoch
``j``, ``r̂_j − x̂_clone``, to the present one with the updates of this epoch so far,
``r̂_k − J x̂``, its variance along each line of sight from ``D P Dᵀ``, ``D = J − [clone]``); rows whose innovation fails ``gate`` σ are rejected.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sinslab.core import earth as E
from sinslab.core import gnss as G
from sinslab.fusion.carrier import SlipDetector, prediction_slips, signal_variance, troposphere
from sinslab.fusion.gnss import SatelliteMeasurement

__all__ = ["TimeDifferencedPhase", "TdcpLog"]


@dataclass
class TdcpLog:
    """Per epoch: ``t`` [s], ``used``, ``rejected`` (rows), ``slips`` (signals restarted),
    ``interval`` (since the epoch compared with [s]), ``innovation`` (array [m] of the rows
    used, before the update), ``slipped`` (the signals ``(satellite, slot)`` cut by a slip
    test)."""

    t: list = field(default_factory=list)
    used: list = field(default_factory=list)
    rejected: list = field(default_factory=list)
    slips: list = field(default_factory=list)
    interval: list = field(default_factory=list)
    innovation: list = field(default_factory=list)
    slipped: list = field(default_factory=list)


class TimeDifferencedPhase(SatelliteMeasurement):
    """Time-differenced carrier phase of every signal (see the module notes).

    Parameters
    ----------
    sv : SatelliteObservations
        With ``signals``.
    sigma : float
        σ₀ of one phase [m] (default 3 mm).
    gate : float or None
        Innovation gate of a row [σ of ``H P Hᵀ + R``] against the prior (None: none).
    gf, doppler_k, prediction_k : float or None
        Slip tests (None: off).
    max_gap : float
        Longest interval compared [s].
    Other parameters as :class:`sinslab.fusion.gnss.SatelliteMeasurement` (lever arm,
    mask, C/N0 reference, at most K satellites over a window, receiver-clock block and its
    nominal, outages, stream).
    """

    kind = "time-differenced phase"

    def __init__(self, sv, sigma=0.003, *, gate=5.0, gf=0.05, doppler_k=5.0, prediction_k=5.0, max_gap=5.0, **kw):
        super().__init__(sv, sigma, gate=None, **kw)
        self.tdcp_gate = None if gate is None else float(gate)
        if sv.signals is None:
            raise ValueError("time-differenced phase needs the signals (carrier phase) of the observations")
        self.detector = SlipDetector(gf=gf, doppler_k=doppler_k, phase_sigma=sigma, cn0_ref=self.cn0_ref,
                                     max_gap=max_gap)
        self.prediction_k = prediction_k
        self.max_gap = float(max_gap)
        self.rec = None                 # what was recorded at the last epoch
        self.tdcp = TdcpLog()
        self._prep = None

    # -- the epoch: signals, slips, the record, the clone copy
    def _prepare(self, ep):
        sv, lay = self.sv, ep.layout
        r, Jr, _, _, (lat, lon, h), _, el, _ = self.antenna(ep)
        rows = sv.rows(ep.item)
        ok = sv.usable[rows] & (el >= self.mask)
        rows, el = rows[ok], el[ok]
        S = sv.signals
        t = float(sv.t_epoch[ep.item])
        for k, a, b in self.limits:          # at most k satellites, highest first (as the pseudoranges)
            if a <= t < b and rows.size > k:
                top = np.sort(np.argsort(-el, kind="stable")[:k])
                rows, el = rows[top], el[top]
        slip, new = self.detector.check(t, sv.sat[rows], S.phase[rows], S.doppler[rows], S.freq[rows], S.lli[rows],
                                        sv.cn0[rows], el)
        use = np.isfinite(S.phase[rows]) & ~slip & ((S.lli[rows] & 2) == 0)
        q, f = np.nonzero(np.isfinite(S.phase[rows]) & ((S.lli[rows] & 2) == 0))
        i = rows[q]
        lam = G.C_LIGHT / S.freq[i, f]
        trop, dtrop, _ = troposphere(r, sv.sat_pos[i])
        now = dict(t=t, r=r, b=self._bias_nominal(t), keys=list(zip(sv.sat[i].tolist(), f.tolist())),
                   L=S.phase[i, f] * lam, sat_clk=sv.sat_clock[i], pos=sv.sat_pos[i], el=el[q],
                   trop=trop, dtrop=dtrop,
                   var=signal_variance(self.sigma, sv.cn0[i], el[q], self.cn0_ref), ok=use[q, f], i=i,
                   n_slip=int((slip & ~new).sum()), dt=ep.t - t,
                   slipped=[(str(sv.sat[rows[a]]), int(b)) for a, b in zip(*np.nonzero(slip & ~new))])
        cl = lay.find("phase_clone")
        if cl is None:
            raise ValueError(f"time-differenced phase needs clone states in the model (blocks {list(lay.names)}): "
                             "add sinslab.nav.errstate.phase_clones")
        ib, idr, _ = self._clock_columns(lay, sv.system[:1])
        prev = self.rec if (self.rec is not None and t - self.rec["t"] <= self.max_gap) else None
        slot = 0 if prev is None else 1 - prev["slot"]
        now["slot"] = slot
        if prev is not None and self.prediction_k is not None:
            self._predicted(ep, now, prev, cl, Jr)
        A = np.eye(ep.n)
        c0 = cl.start + 4 * slot
        A[c0:c0 + 4] = 0.0
        A[c0:c0 + 3] = Jr
        A[c0 + 3, ib] = 1.0                # the bias error at the observation time
        A[c0 + 3, idr] = -now["dt"]
        self._prep = (ep.item, now, prev, cl, (ib, idr), r, Jr, (lat, lon, h))
        self.rec = now
        return A

    def _bias_nominal(self, t):
        b0, d0, t0 = self.nominal
        return b0 + d0 * (t - t0)            # at the observation time

    def _predicted(self, ep, now, prev, cl, Jr):
        """Slips by prediction: the phase change against the range change from the
        corrected antenna position of the last epoch to the present INS one."""
        pk = {k: n for n, k in enumerate(prev["keys"])}
        q = [n for n, k in enumerate(now["keys"]) if now["ok"][n] and k in pk]
        if len(q) < 3:
            return
        q = np.array(q)
        p = np.array([pk[now["keys"][n]] for n in q])
        c0 = cl.start + 4 * prev["slot"]
        # the antenna positions as the filter knows them now: the present one with this
        # epoch's earlier updates, the last one with what its clone has learnt
        D = Jr.copy()
        D[:, c0:c0 + 3] -= np.eye(3)
        if ep.prior is not None:
            x, P = ep.prior
            r1, r0 = now["r"] - Jr @ x, prev["r"] - x[c0:c0 + 3]
            Sd = D @ P @ D.T
        else:
            r1, r0, Sd = now["r"], prev["r"], np.zeros((3, 3))
        rho1, u1 = G.sagnac_range(now["pos"][q], r1)
        rho0 = G.sagnac_range(prev["pos"][p], r0)[0]
        dphi = now["L"][q] - prev["L"][p]
        dpred = (rho1 - rho0) - (now["sat_clk"][q] - prev["sat_clk"][p])
        var = now["var"][q] + prev["var"][p] + np.einsum("ij,jk,ik->i", u1, Sd, u1)
        hit = prediction_slips(dphi, dpred, var, self.prediction_k)
        self.detector.counts["prediction"] += int(hit.sum())
        now["ok"][q[hit]] = False
        now["n_slip"] += int(hit.sum())
        now["slipped"] += [now["keys"][n] for n in q[hit]]

    def transform(self, ep):
        return self._prepare(ep), None

    # -- the rows
    def matrices(self, ep):
        if self._prep is None or self._prep[0] != ep.item:
            self._prepare(ep)              # a check of H: no clone copied
        item, now, prev, cl, ib, r, Jr, (lat, lon, h) = self._prep
        self._prep = None
        log = self.tdcp
        if prev is None:
            self._log(now, 0, 0, np.nan, np.zeros(0))
            return None
        pk = {k: n for n, k in enumerate(prev["keys"])}
        q = np.array([n for n, k in enumerate(now["keys"]) if now["ok"][n] and k in pk], dtype=np.int64)
        if q.size == 0:
            self._log(now, 0, 0, now["t"] - prev["t"], np.zeros(0))
            return None
        p = np.array([pk[now["keys"][n]] for n in q], dtype=np.int64)
        z, H = self._rows(ep, now, prev, q, p, cl, ib, r, Jr, (lat, lon, h))
        R = now["var"][q] + prev["var"][p]
        rej, nu = self._reject(ep, z, H, R)
        self._log(now, int((~rej).sum()), int(rej.sum()), now["t"] - prev["t"], nu[~rej])
        if not np.any(~rej):
            return None
        return z[~rej], H[~rej], R[~rej]

    def _reject(self, ep, z, H, R):
        """Rows whose innovation against the prior exceeds ``gate`` σ of ``H P Hᵀ + R``
        (none without a prior or a gate), and the innovations."""
        if ep.prior is None:
            return np.zeros(z.size, bool), np.full(z.size, np.nan)
        x, P = ep.prior
        nu = z - H @ x
        if self.tdcp_gate is None:
            return np.zeros(z.size, bool), nu
        S = np.einsum("ij,jk,ik->i", H, P, H) + R
        return nu * nu > self.tdcp_gate ** 2 * S, nu

    def _rows(self, ep, now, prev, q, p, cl, ib, r, Jr, llh):
        lay = ep.layout
        lat, lon, h = llh
        rs1, rs0 = now["pos"][q], prev["pos"][p]
        rho1, u1 = G.sagnac_range(rs1, r)
        rho0, u0 = G.sagnac_range(rs0, prev["r"])
        w = E.WIE / G.C_LIGHT
        zero = np.zeros(q.size)
        trop0, dtrop0, _ = troposphere(prev["r"], rs0)        # at the recorded position
        g1 = -u1 + w * np.stack([-rs1[:, 1], rs1[:, 0], zero], -1) + now["dtrop"][q]
        g0 = -u0 + w * np.stack([-rs0[:, 1], rs0[:, 0], zero], -1) + dtrop0
        z = ((rho1 - rho0) + (now["trop"][q] - trop0) + (now["b"] - prev["b"])
             - (now["sat_clk"][q] - prev["sat_clk"][p]) - (now["L"][q] - prev["L"][p]))
        H = g1 @ Jr
        H[:, ib[0]] += 1.0
        H[:, ib[1]] -= now["dt"]           # the bias at the observation time
        c0 = cl.start + 4 * prev["slot"]
        H[:, c0:c0 + 3] -= g0
        H[:, c0 + 3] -= 1.0
        return z, H

    def _log(self, now, used, rejected, interval, nu):
        log = self.tdcp
        log.t.append(now["t"])
        log.used.append(used)
        log.rejected.append(rejected)
        log.slips.append(now["n_slip"])
        log.slipped.append(now["slipped"])
        log.interval.append(interval)
        log.innovation.append(nu)

    def counts(self):
        """Rows used and rejected, slips by cause."""
        return dict(used=int(sum(self.tdcp.used)), rejected=int(sum(self.tdcp.rejected)), **self.detector.counts)
