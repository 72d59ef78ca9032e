"""Carrier phase for the measurements of :mod:`sinslab.fusion.rtk` and
:mod:`sinslab.fusion.tdcp`: the weight of a phase or code observation, cycle-slip
detection per receiver, and the ambiguity states handed from signal to signal.

Weights
-------
``σ² = σ₀² 10^{max(0, C/N0_ref − C/N0)/10} / sin² el`` (:func:`signal_variance`), the form
of the pseudorange and Doppler rows of :mod:`sinslab.fusion.gnss` and of the simulator;
σ₀ defaults to 3 mm for phase and 0.3 m for code (RTKLIB's ``err`` 0.003 m and code/phase
ratio 100).

Cycle slips
-----------
A signal's ambiguity is restarted when, between two epochs of one receiver, any of these
says so (:class:`SlipDetector`, counts per cause kept):

* **LLI**: the receiver's loss-of-lock bit (``Signals.slip``), on the rover or the base;
* **geometry-free**: ``λ₁φ₁ − λ₂φ₂`` of a satellite with two carriers changes by more than
  ``gf`` (0.05 m) and k = 5 standard deviations of the change by the phase noise model
  (low satellites are noisy): the ionosphere moves it by millimetres per second, a slip by
  ``n₁λ₁ − n₂λ₂`` (L1/L2: 0.19 m for one L1 cycle, 0.24 m for one L2 cycle, 0.054 m for one
  on both); slips with ``n₁λ₁ ≈ n₂λ₂`` (77 and 60 cycles) it cannot see, the others do;
* **Doppler**: the phase change differs from the Doppler integrated over the interval
  (trapezoid), after the median over the signals of the epoch is removed (the receiver
  clock's white frequency noise moves every phase alike between two Doppler readings),
  by more than ``k`` standard deviations of both (k = 5);
* **prediction**: the phase change minus the range change predicted by the navigation
  (the INS, or the motion model of a GNSS-only filter) and the satellite clock, after
  the median over all signals of the epoch is removed (the receiver clock's change,
  common to all), exceeds ``k`` standard deviations of phase noise and predicted range
  change (:func:`prediction_slips`).

A signal with an unresolved half cycle (``Signals.half_cycle``) is not used for phase.

Ambiguity states
----------------
A filter carries a fixed number of ambiguity states (:func:`sinslab.nav.errstate.carrier_ambiguities`).
:class:`AmbiguitySlots` hands one to each tracked signal (a key such as ``("G05", 1)``),
keeps the nominal ambiguity the state is the error of (``N = N₀ − x``), restarts it after a
slip or a loss of lock longer than ``max_gap``, and frees it when the signal has been
gone for that long. A restart is the state transform ``x_j ← 0``, ``P_j· ← 0``,
``P_jj ← σ₀²`` (:meth:`AmbiguitySlots.transform`).
"""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import earth as E
from sinslab.core import gnss as G

__all__ = ["signal_variance", "SlipDetector", "prediction_slips", "AmbiguitySlots", "SLIP_CAUSES", "slot_count",
           "max_signals", "troposphere"]

#: The causes a slip is counted under.
SLIP_CAUSES = ("lli", "geometry_free", "doppler", "prediction", "gate")


def signal_variance(sigma0, cn0, el, cn0_ref=45.0):
    """``σ₀² 10^{max(0, C/N0_ref − C/N0)/10} / sin² el`` [m²] (elevation floor 0.05 rad)."""
    c = np.maximum(cn0_ref - np.asarray(cn0, float), 0.0)
    c = np.where(np.isfinite(c), c, 0.0)
    return sigma0 ** 2 * 10.0 ** (c / 10.0) / np.maximum(np.sin(np.asarray(el, float)), 0.05) ** 2


class SlipDetector:
    """Cycle-slip tests between consecutive epochs of one receiver (see the module notes).

    Parameters
    ----------
    gf : float or None
        Geometry-free threshold [m] (None: no test).
    doppler_k : float or None
        Doppler test threshold in σ (None: no test).
    phase_sigma, doppler_sigma : float
        σ₀ of phase [m] and range rate [m/s] for the Doppler test.
    max_gap : float
        Longest interval [s] between two epochs of a signal that keeps its lock.
    """

    def __init__(self, *, gf=0.05, doppler_k=5.0, phase_sigma=0.003, doppler_sigma=0.05, cn0_ref=45.0,
                 max_gap=5.0):
        self.gf = gf
        self.doppler_k = doppler_k
        self.k_gf = 5.0
        self.phase_sigma = float(phase_sigma)
        self.doppler_sigma = float(doppler_sigma)
        self.cn0_ref = float(cn0_ref)
        self.max_gap = float(max_gap)
        self.slot_of = {}              # satellite -> its row of the arrays of the last epoch seen
        self._t = np.zeros(0)
        self._ph = self._d = np.zeros(0)
        self._gf = self._gfv = np.zeros(0)
        self.counts = dict.fromkeys(SLIP_CAUSES, 0)

    def _index(self, sats, nf):
        """Rows of ``sats`` in the arrays of the last epoch seen (new satellites get rows
        that have seen nothing)."""
        idx = np.empty(len(sats), dtype=np.int64)
        for q, s in enumerate(sats.tolist()):
            k = self.slot_of.get(s)
            if k is None:
                k = self.slot_of[s] = len(self.slot_of)
            idx[q] = k
        K = len(self.slot_of)
        if K > self._t.size:                 # room for the new satellites, doubled as it grows
            n_new = max(K, 2 * self._t.size) - self._t.size
            self._t = np.r_[self._t, np.full(n_new, -np.inf)]
            self._gf = np.r_[self._gf, np.full(n_new, np.nan)]
            self._gfv = np.r_[self._gfv, np.full(n_new, np.nan)]
            self._ph = np.vstack([self._ph.reshape(-1, nf), np.full((n_new, nf), np.nan)])
            self._d = np.vstack([self._d.reshape(-1, nf), np.full((n_new, nf), np.nan)])
        return idx

    def check(self, t, sats, phase, doppler, freq, lli, cn0, el):
        """Slips of the signals of one epoch.

        Parameters
        ----------
        t : float
            Epoch [s].
        sats : str array (m,)
        phase, doppler, freq : arrays (m, F)
            [cycles], [Hz], [Hz] (NaN: no signal).
        lli : uint8 array (m, F)
        cn0, el : arrays (m,)
            [dB-Hz], [rad].

        Returns
        -------
        slip : bool ndarray (m, F)
            The signal lost its lock (any test), or has no earlier epoch within
            ``max_gap`` (new).
        new : bool ndarray (m, F)
            No earlier epoch of the signal within ``max_gap``.
        """
        m, nf = phase.shape
        lam = G.C_LIGHT / freq
        have = np.isfinite(phase)
        slip = (lli & 1).astype(bool) & have
        self.counts["lli"] += int(slip.sum())
        var = signal_variance(self.phase_sigma, cn0, el, self.cn0_ref)
        gf_now, gfv = _geometry_free(phase, lam, var)
        # the previous epoch of each row's satellite (arrays indexed by satellite)
        idx = self._index(sats, nf)
        t0, ph0, d0 = self._t[idx], self._ph[idx], self._d[idx]
        gf0, gfv0 = self._gf[idx], self._gfv[idx]
        dt = t - t0
        kept = dt <= self.max_gap
        new = have & ~(kept[:, None] & np.isfinite(ph0))
        ok = have & ~new
        if self.gf is not None:
            thr = np.maximum(self.gf, self.k_gf * np.sqrt(gfv0 + gfv))
            jump = kept & (np.abs(gf_now - gf0) > thr)          # NaN compares False
            hit = jump[:, None] & ok
            self.counts["geometry_free"] += int(np.any(hit & ~slip, 1).sum())
            slip |= hit
        if self.doppler_k is not None:
            dop = ok & np.isfinite(doppler) & np.isfinite(d0) & ~slip
            if dop.sum() >= 3:
                # phase change minus the Doppler integrated (trapezoid) [m]; the median over
                # the signals (the receiver clock's white frequency noise, which the Doppler
                # of the epoch does not carry) removed
                dtc = np.where(kept, dt, 0.0)[:, None]
                dev = ((phase - ph0) + 0.5 * (doppler + d0) * dtc) * lam
                dev = dev - np.median(dev[dop])
                var_d = signal_variance(self.doppler_sigma, cn0, el, self.cn0_ref)[:, None]
                sd = np.sqrt(2 * var[:, None] + 0.5 * var_d * dtc * dtc)
                hit = dop & (np.abs(dev) > self.doppler_k * sd)
                self.counts["doppler"] += int(hit.sum())
                slip |= hit
        self._t[idx], self._ph[idx], self._d[idx], self._gf[idx], self._gfv[idx] = t, phase, doppler, gf_now, gfv
        return slip | new, new


def _geometry_free(phase, lam, var):
    """λ₀φ₀ − λ_jφ_j with the first further carrier j that has a phase, per row (NaN: one
    carrier), and its variance from the phase variance ``var`` (m,) of one carrier."""
    out = np.full(phase.shape[0], np.nan)
    L = phase * lam
    for j in range(1, phase.shape[1]):
        ok = np.isfinite(L[:, 0]) & np.isfinite(L[:, j]) & np.isnan(out)
        out[ok] = L[ok, 0] - L[ok, j]
    return out, 2.0 * np.asarray(var, float)


def prediction_slips(dphase, dpred, var, k=5.0):
    """Slips by prediction: ``dphase`` (m,) the phase changes [m], ``dpred`` (m,) the range
    and satellite-clock changes the navigation predicts [m], ``var`` (m,) the variance of
    their difference without the receiver clock [m²]. The median of ``dphase − dpred``
    (the receiver clock's change) is removed; a row deviating by more than ``k σ`` is a slip.
    Needs 3 rows (fewer: none flagged)."""
    d = np.asarray(dphase, float) - np.asarray(dpred, float)
    out = np.zeros(d.size, bool)
    ok = np.isfinite(d)
    if ok.sum() < 3:
        return out
    dev = np.abs(d - np.median(d[ok]))
    out[ok] = dev[ok] > k * np.sqrt(np.asarray(var, float)[ok])
    return out


class AmbiguitySlots:
    """The ambiguity states of a filter handed to the signals tracked (module notes).

    Parameters
    ----------
    columns : int array (K,)
        The filter columns of the K ambiguity states.
    sigma0 : float
        σ of a restarted ambiguity [cycles].
    max_gap : float
        A signal gone longer than this [s] loses its state.
    """

    def __init__(self, columns, *, sigma0=150.0, max_gap=5.0):
        self.columns = np.asarray(columns, dtype=np.int64)
        K = self.columns.size
        self.sigma0 = float(sigma0)
        self.max_gap = float(max_gap)
        self.key = [None] * K                  # signal of each slot
        self.slot_of = {}
        self.n0 = np.zeros(K)                  # nominal ambiguity [cycles]
        self.last = np.full(K, -np.inf)        # last time used [s]
        self.since = np.full(K, np.nan)        # time of the last restart [s]
        self.pending = set()                   # slots restarted by the caller's transform next
        self.full = 0                          # signals left out for want of a free slot

    def lookup(self, keys):
        """Slot of each key (−1: none)."""
        return np.array([self.slot_of.get(k, -1) for k in keys], dtype=np.int64)

    def free_stale(self, t):
        """Free the slots of signals gone longer than ``max_gap`` at time ``t``."""
        for j, k in enumerate(self.key):
            if k is not None and t - self.last[j] > self.max_gap:
                del self.slot_of[k]
                self.key[j] = None

    def restart(self, keys, n0, t):
        """(Re)start the ambiguity of each key at the nominal ``n0`` [cycles]: its own slot,
        or a free one. Returns the slots (−1: no free slot, counted in ``full``)."""
        out = np.full(len(keys), -1, dtype=np.int64)
        for i, (k, v) in enumerate(zip(keys, n0)):
            j = self.slot_of.get(k, -1)
            if j < 0:
                free = [q for q, kk in enumerate(self.key) if kk is None]
                if not free:
                    self.full += 1
                    continue
                j = free[0]
                self.key[j] = k
                self.slot_of[k] = j
            self.n0[j] = float(v)
            self.since[j] = t
            self.last[j] = t
            self.pending.add(j)
            out[i] = j
        return out

    def touch(self, slots, t):
        self.last[np.asarray(slots, dtype=np.int64)] = t

    def transform(self, n):
        """``(A, Q)`` restarting the pending slots in a filter of ``n`` states, or None;
        the pending list is emptied."""
        if not self.pending:
            return None
        cols = self.columns[sorted(self.pending)]
        self.pending.clear()
        A = np.eye(n)
        A[cols, cols] = 0.0
        Q = np.zeros((n, n))
        Q[cols, cols] = self.sigma0 ** 2
        return A, Q

    def lock_time(self, slots, t):
        """Time [s] since each slot's last restart."""
        return t - self.since[np.asarray(slots, dtype=np.int64)]

    def __len__(self):
        return int(self.columns.size)


def slot_count(signals):
    """Ambiguity states for at most ``signals`` tracked at once, with room for 8 more that
    rise while the states of setting ones wait out ``max_gap``."""
    return int(signals) + 8


def max_signals(sv):
    """Most phase signals of one epoch of the observations ``sv`` (with ``signals``)."""
    have = np.isfinite(sv.signals.phase).sum(1)
    return int(np.bincount(sv.epoch, weights=have, minlength=sv.t_epoch.size).max()) if have.size else 0


def troposphere(r, sat_pos):
    """Saastamoinen delay [m] (m,) of the satellites ``sat_pos`` (m, 3) seen from the
    antenna ``r`` (ECEF [m]), its gradient with respect to ``r`` (m, 3) and the
    elevations [rad].

    The gradient holds the height term and the elevation term — the line of sight turns
    by 1/ρ per metre and the local vertical by 1/(R + h): at 15° elevation about 2e-5 m
    per metre, which a centimetre-level row must carry."""
    lat, lon, h = (float(v) for v in E.ecef_to_geodetic(r))
    d = np.asarray(sat_pos, float) - r
    rho = np.linalg.norm(d, axis=1)
    e = d / rho[:, None]
    C = E.enu_to_ecef_matrix(lat, lon)
    east, north, up = C[:, 0], C[:, 1], C[:, 2]
    s_el = e @ up
    el = np.arcsin(np.clip(s_el, -1.0, 1.0))
    T = G.saastamoinen(lat, h, el)
    step = 1e-6
    dT_del = (G.saastamoinen(lat, h, el + step) - G.saastamoinen(lat, h, el - step)) / (2 * step)
    dT_dh = (G.saastamoinen(lat, h + 0.5, el) - G.saastamoinen(lat, h - 0.5, el))
    rm, rn = E.radii_s(lat, h)
    ds = (-(up[None, :] - s_el[:, None] * e) / rho[:, None]
          + (e @ north)[:, None] * north[None, :] / rm + (e @ east)[:, None] * east[None, :] / rn)
    d_el = ds / np.maximum(np.cos(el), 1e-9)[:, None]
    return T, dT_del[:, None] * d_el + dT_dh[:, None] * up[None, :], el
