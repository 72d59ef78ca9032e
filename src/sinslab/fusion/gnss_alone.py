"""GNSS alone: the RTK filter without an INS (:func:`rtk_solve`), the same double
differences, ambiguity states and integer resolution as RTK/INS
(:class:`sinslab.fusion.rtk.RtkEngine`) with a motion model in place of the inertial
navigation.

States: the antenna position error (ECEF [m]), for a moving antenna its velocity error,
then the ambiguity states. ``dynamics="static"``: the position is a constant (a static
survey: every epoch adds to one position); ``"kinematic"``: constant velocity driven by
white acceleration noise of density ``accel_noise`` [m/s²/√s] on each ECEF axis
(``Q = q [[dt³/3, dt²/2], [dt²/2, dt]]``). The filter starts from the rover's
single-point solution (:func:`sinslab.fusion.gnss.single_point`) with σ ``pos_sigma0``;
the nominal position (and velocity) take the estimate after every epoch (closed loop),
so the states stay small. The filter is :class:`sinslab.estimation.filter.KalmanFilter`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core import earth as E
from sinslab.estimation.filter import KalmanFilter
from sinslab.fusion.carrier import max_signals, slot_count
from sinslab.fusion.gnss import single_point
from sinslab.fusion.rtk import STATUS, RtkBase, RtkEngine, RtkOptions

__all__ = ["rtk_solve", "RtkSolution", "solution_of"]


@dataclass(frozen=True)
class RtkSolution:
    """Per rover epoch (E,): ``t`` [s], ``status`` (:data:`sinslab.fusion.rtk.STATUS`:
    0 none, 1 float, 2 fixed), ``ratio``, ``n_fixed``, ``n_amb``, ``n_phase``, ``n_code``,
    ``n_slip``; ``pos`` (E, 3) the solution (fixed where fixed, else float; NaN none),
    ``float_pos``, ``fixed_pos`` (E, 3) and ``float_cov``, ``fixed_cov`` (E, 3, 3) ECEF
    [m, m²]; ``counts`` (signals skipped by cause), ``slips`` (restarts by cause);
    ``fixed_dd`` per epoch the double-difference integers fixed and ``restarted`` the signals
    whose ambiguity was (re)started (see :class:`sinslab.fusion.rtk.RtkLog`); ``nis``
    ``{"ph" | "code": (mean ν²/(H P Hᵀ + R) of the double differences used, one row at a
    time, rows)}``."""

    t: np.ndarray
    status: np.ndarray
    ratio: np.ndarray
    n_fixed: np.ndarray
    n_amb: np.ndarray
    n_phase: np.ndarray
    n_code: np.ndarray
    n_slip: np.ndarray
    pos: np.ndarray
    float_pos: np.ndarray
    fixed_pos: np.ndarray
    float_cov: np.ndarray
    fixed_cov: np.ndarray
    counts: dict
    slips: dict
    fixed_dd: list = None
    restarted: list = None
    nis: dict = None

    @property
    def fixed(self):
        return self.status == STATUS["fixed"]

    def time_to_first_fix(self):
        """Epochs and seconds from the first epoch with a solution to the first fixed one
        (counting both: fixed at the first epoch is 1), or (None, None)."""
        have = np.flatnonzero(self.status > 0)
        fx = np.flatnonzero(self.fixed)
        if not fx.size:
            return None, None
        return int(fx[0] - have[0] + 1), float(self.t[fx[0]] - self.t[have[0]])

    def summary(self):
        """Metrics of the run: epochs with a solution, fixed (share), time to the first
        fix [epochs, s], median and least ratio of the fixed epochs, integers fixed (median per fixed
        epoch), ambiguity restarts by cause and receiver, signals left out by cause, rows
        rejected by the gate, fixes refused by the validation."""
        seen = self.status > 0
        n_fix = int(self.fixed.sum())
        ep, sec = self.time_to_first_fix()
        fr = self.ratio[self.fixed]
        fr = fr[np.isfinite(fr)]
        out = dict(rtk_epochs=int(self.t.size), rtk_epochs_solved=int(seen.sum()), rtk_epochs_fixed=n_fix,
                   rtk_fixed_fraction=float(n_fix / max(int(seen.sum()), 1)), rtk_first_fix_epochs=ep,
                   rtk_first_fix_s=sec, rtk_ratio_median=float(np.median(fr)) if fr.size else None,
                   rtk_ratio_min=float(np.min(fr)) if fr.size else None,
                   rtk_integers_fixed_median=float(np.median(self.n_fixed[self.fixed])) if n_fix else 0.0)
        out.update({f"restarts_{k}": int(v) for k, v in self.slips.items()})
        c = self.counts
        out.update(epochs_without_base=c["no_base_epoch"], signals_without_base_signal=c["no_base_signal"],
                   signals_half_cycle=c["half_cycle"], signals_without_state=c["no_slot"],
                   code_rows_rejected=c["code_rejected"], phase_rows_rejected=c["phase_rejected"],
                   fixes_refused_by_validation=c["fix_rejected"])
        if self.nis:
            out.update(phase_nis_mean=self.nis["ph"][0], phase_rows=self.nis["ph"][1],
                       code_nis_mean=self.nis["code"][0], code_rows=self.nis["code"][1])
        return out

    def table(self):
        """Per epoch: t [s], status, ratio, integers fixed and formed, double differences
        of phase and code, restarts, and the solution (fixed where fixed, else float) as
        latitude, longitude [deg], height [m] with its σ east, north, up [m]."""
        ok = np.all(np.isfinite(self.pos), 1)
        lat = np.full(self.t.size, np.nan)
        lon, h = lat.copy(), lat.copy()
        if ok.any():
            lat[ok], lon[ok], h[ok] = E.ecef_to_geodetic(self.pos[ok])
        cov = np.where(self.fixed[:, None, None], self.fixed_cov, self.float_cov)
        sig = np.full((self.t.size, 3), np.nan)
        for i in np.flatnonzero(ok):
            C = E.enu_to_ecef_matrix(lat[i], lon[i])
            sig[i] = np.sqrt(np.maximum(np.diag(C.T @ cov[i] @ C), 0.0))
        return dict(t_s=self.t, status=self.status, ratio=self.ratio, n_fixed=self.n_fixed, n_amb=self.n_amb,
                    n_phase=self.n_phase, n_code=self.n_code, n_slip=self.n_slip, lat_deg=np.degrees(lat),
                    lon_deg=np.degrees(lon), h_m=h, sigma_e_m=sig[:, 0], sigma_n_m=sig[:, 1], sigma_u_m=sig[:, 2])

    def enu_errors(self, reference, which="pos"):
        """East, north, up errors (E, 3) [m] of ``pos`` (or ``float_pos``, ``fixed_pos``)
        against the ECEF ``reference`` (3,)."""
        ref = np.asarray(reference, float)
        lat, lon, _ = E.ecef_to_geodetic(ref)
        C = E.enu_to_ecef_matrix(lat, lon)
        return (getattr(self, which) - ref) @ C


def rtk_solve(rover, base: RtkBase, options: RtkOptions = RtkOptions(), *, dynamics="static", accel_noise=1.0,
              pos_sigma0=30.0, vel_sigma0=10.0, slots=None, start_position=None, outages=()) -> RtkSolution:
    """RTK without an INS on the epochs of ``rover`` (see the module notes).

    Parameters
    ----------
    rover : sinslab.fusion.gnss.SatelliteObservations
        With ``signals``.
    base : RtkBase
    options : RtkOptions
    dynamics : {"static", "kinematic"}
    accel_noise : float
        [m/s²/√s] (kinematic).
    pos_sigma0, vel_sigma0 : float
        Initial σ [m], [m/s] about the single-point solution.
    slots : int, optional
        Ambiguity states (default from the most satellites of an epoch and the carriers).
    start_position : array_like (3,), optional
        ECEF start [m] instead of the single-point solution.
    outages : sequence of (start, length) [s]
        Rover epochs not used (``start <= t < start + length``): the motion model carries
        the solution over them (status 0 there).

    Returns
    -------
    RtkSolution
    """
    if dynamics not in ("static", "kinematic"):
        raise ValueError(f"dynamics must be 'static' or 'kinematic', got {dynamics!r}")
    nm = 3 if dynamics == "static" else 6
    if slots is None:
        slots = slot_count(max_signals(rover))
    n = nm + int(slots)
    eng = RtkEngine(rover, base, np.arange(nm, n), n, options)
    e0, r_nom, v_nom = _start(rover, start_position)
    P0 = np.zeros((n, n))
    P0[:3, :3] = np.eye(3) * pos_sigma0 ** 2
    if nm == 6:
        P0[3:6, 3:6] = np.eye(3) * vel_sigma0 ** 2
    filt = KalmanFilter(np.zeros(n), P0, t0=float(rover.t_epoch[e0]), check=False)
    J = np.zeros((3, n))
    J[:, :3] = np.eye(3)
    q_amb = np.zeros(n)
    q_amb[nm:] = 1e-8                    # the ambiguity states' random walk (RTKLIB's 1e-4 cycles/√s)
    t_prev = float(rover.t_epoch[e0])
    fb = np.arange(nm)
    for e in range(e0, rover.t_epoch.size):
        t = float(rover.t_epoch[e])
        if any(a <= t < a + ln for a, ln in outages):
            continue
        dt = t - t_prev
        if dt > 0:
            Phi, Q = _motion(n, nm, dt, accel_noise, q_amb)
            filt.predict(Phi, Q, dt)
            r_nom = r_nom + v_nom * dt
        t_prev = t
        pos_sigma = 0.0 if nm == 3 else float(math.sqrt(np.trace(filt.P[3:6, 3:6]) / 3.0)) * max(dt, 0.0)
        jump = eng.prepare(e, r_nom, pos_sigma)
        if jump is not None:
            filt.transform(*jump)
        rows = eng.rows(r_nom, J, (filt.x, filt.P))
        if rows is not None:
            filt.update(*rows)
            d = filt.feedback(fb)
            r_nom = r_nom - d[:3]
            if nm == 6:
                v_nom = v_nom - d[3:6]
    return solution_of(eng, rover.t_epoch)


def _start(rover, start_position):
    sp = single_point(rover)
    ok = np.flatnonzero(np.isfinite(sp.lat))
    if start_position is not None:
        e0 = int(ok[0]) if ok.size else 0
        return e0, np.asarray(start_position, float).reshape(3), np.zeros(3)
    if not ok.size:
        raise ValueError("no single-point solution of the rover: RTK has no start (fewer than 4 satellites "
                         "with ephemeris at every epoch)")
    e0 = int(ok[0])
    r = E.geodetic_to_ecef(sp.lat[e0], sp.lon[e0], sp.h[e0])
    v = E.enu_to_ecef_matrix(sp.lat[e0], sp.lon[e0]) @ np.nan_to_num(sp.vel[e0])
    return e0, r, v


def _motion(n, nm, dt, q, q_amb):
    Phi = np.eye(n)
    Q = np.diag(q_amb * dt)
    if nm == 6:
        Phi[:3, 3:6] = np.eye(3) * dt
        q2 = q * q
        Q[:3, :3] = np.eye(3) * q2 * dt ** 3 / 3
        Q[:3, 3:6] = Q[3:6, :3] = np.eye(3) * q2 * dt ** 2 / 2
        Q[3:6, 3:6] = np.eye(3) * q2 * dt
    return Phi, Q


def solution_of(eng, t=None) -> RtkSolution:
    """The :class:`RtkSolution` of a run of the RTK engine ``eng``
    (:class:`sinslab.fusion.rtk.RtkEngine`, with an INS or without): per epoch ``t`` [s]
    (default: the epochs the engine was asked for, from its record); the epochs of ``t``
    the engine was not asked for (before the start, in an outage) without a solution."""
    a = eng.log.arrays()
    ta = np.asarray(a["t"], float)
    t = ta if t is None else np.asarray(t, float)
    E_ = t.size
    m = np.searchsorted(t, ta)

    def full(v, fill, shape=()):
        out = np.full((E_,) + shape, fill, dtype=float)
        if m.size:
            out[m] = v
        return out

    st = np.zeros(E_, np.int64)
    st[m] = a["status"]
    fixed = st == STATUS["fixed"]
    fpos = full(a["float_pos"], np.nan, (3,))
    xpos = full(a["fixed_pos"], np.nan, (3,))
    pos = np.where(fixed[:, None], xpos, fpos)
    ints = {k: np.zeros(E_, np.int64) for k in ("n_fixed", "n_amb", "n_phase", "n_code", "n_slip")}
    for k in ints:
        ints[k][m] = a[k]
    fixed_dd, restarted = [([], np.zeros(0))] * E_, [[]] * E_
    for j, k in enumerate(m):
        fixed_dd[k], restarted[k] = a["fixed_dd"][j], a["restarted"][j]
    return RtkSolution(t.copy(), st, full(a["ratio"], np.nan), *ints.values(), pos, fpos, xpos,
                       full(a["float_cov"], np.nan, (3, 3)), full(a["fixed_cov"], np.nan, (3, 3)),
                       dict(eng.counts, no_slot=eng.slots.full), eng.slip_counts, fixed_dd, restarted,
                       {k: (v[0] / v[1] if v[1] else None, v[1]) for k, v in eng.nis.items()})
