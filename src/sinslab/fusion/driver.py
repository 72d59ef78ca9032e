"""The fusion driver: k INS streams, one error-state Kalman filter, a list of measurements.

This is sinslab's one loop that runs a filter beside strapdown navigation; the loosely
coupled filter (:mod:`sinslab.fusion.loosely_coupled`), paper 003's lag-aware integration
and the two-INS difference filters are compositions of it.

State layout
------------
The error state ``x`` (n,) is the layout of an error model of
:mod:`sinslab.nav.errstate` (named blocks: ``phi`` misalignment [rad, ENU], ``dv``
velocity error [m/s], ``dp = [δL, δλ(, δh)]`` [rad, rad(, m)], sensor blocks ``eps``,
``nabla``, ``kg``, ``ka``, Gauss–Markov states, ...; for a
:class:`~sinslab.nav.errstate.DifferenceModel` the core blocks are differences of two INS).
Errors are computed minus true. The continuous model ``ẋ = F x + G w``,
``E[w wᵀ] = diag(q) δ``, is evaluated with one :class:`~sinslab.nav.errstate.NavPoint` per
stream: ``F, G = model.matrices(nav_1, ..., nav_k)``.

Epochs
------
The filter runs on the grid ``t_k = t_0 + k T`` (``T = kf_dt``, a multiple of
``nsub·dt`` of every live stream), k = 0..K. Between two consecutive *stops* — the
epochs at which some measurement arrives, the end, and at most ``max_block`` apart — each
live stream runs its compiled mechanization (:func:`sinslab.nav.strapdown.step`) in one
call, writing its row ``[q, v, L, λ, h]`` at every epoch of the block together with the
mean compensated rate and specific force of every step. A precomputed stream (a
navigation series computed elsewhere) just reads its rows. The block boundaries are part
of the arithmetic: a held vertical channel takes its vertical rate from the numerical
derivative of each block's height slice (one-sided at the block ends), so the same stops
give the same numbers and other stops differ at the level of that derivative.

Per block ``[e0, e1]``:

1. Streams advance to ``e1``: rows ``r_{e0+1..e1}``, step rates ``ω_{e0..e1−1}``,
   ``f_{e0..e1−1}`` (rates of the step *after* each epoch).
2. Model evaluation. When the block passes the end of the stretch evaluated last, F and
   G are evaluated for all epochs ``e0..e_la−1`` of the next ``model_every`` seconds at
   once, at epoch ``e`` with the row ``r_e`` and the rates of the step ``e -> e+1``; the
   rows beyond ``e1`` come from a look-ahead run of the live streams from their present
   (corrected) state. The linearisation point then differs from the corrected path only
   by the feedback applied within that stretch; ``model_every <= kf_dt`` evaluates it on
   the corrected path exactly. ``Φ_e, Q_e`` follow from
   :func:`sinslab.estimation.kalman.discretize` (``"series"`` or ``"vanloan"``). That
   numpy path is the reference (``model_eval="numpy"``); by default compiled kernels
   equal to it to rounding evaluate F, G and the series (:mod:`sinslab.nav.errstate_kernels`),
   and when the filter keeps no history the model, Φ, Q̄ and step 3 of each epoch run
   in one compiled loop per block (:mod:`sinslab.fusion.propagate`, which the filter
   steps itself with: :meth:`KalmanFilter.propagate_lanes`).
3. Prediction of the filter through the block in one compiled loop
   (:meth:`KalmanFilter.predict_many`; both paths step with
   :func:`sinslab.estimation.kernels.predict_step`); σ and x are recorded at every epoch.
4. Measurements at ``e1``, in measurement order then item order (a measurement that
   owns re-initialised states first asks for a jump of the state, ``transform``, applied
   by :meth:`KalmanFilter.transform` before its rows; it is applied on arrival only, and
   not smoothed). An item valid at
   ``t_v`` (validity epoch ``e_v = ⌈(t_v − t_0)/T⌉``) that arrives at ``e1``:

   * on time (``e_v = e1``) or with a policy that applies on arrival: compared with the
     rows of ``e1`` (before the feedback of ``e1``) at the time ``t_e1`` (a late item
     under the on-arrival policy at its own ``t_v``: no extrapolation), and
     :meth:`KalmanFilter.update`;
   * late (``e_v < e1``): compared with the rows of ``e_v`` — before the feedback of
     ``e_v`` or after it, as the lag policy says — at ``t_ev``, and applied by the lag
     policy (``policy.update``; default :class:`~sinslab.fusion.lag.ExactReprocessing`;
     a policy may also need the continuous model ``F, Qc`` of ``e_v``: the driver then
     keeps ``F`` and ``G`` of every epoch and forms ``Qc = G diag(q) Gᵀ`` at ``e_v``).

5. Feedback. If a measurement arrived at ``e1`` and feedback layouts are given, each
   (stream, :class:`~sinslab.fusion.feedback.FeedbackLayout`) pair takes its states out
   of the filter (which zeroes them and keeps their cumulative sum ``c``), corrects the
   stream's strapdown state and adds the sensor estimates to its compensation; the row
   of ``e1`` is then the corrected one. Without feedback the streams run free
   (feed-forward: ``x`` estimates their errors); precomputed streams cannot be fed back.

Lag and feedback
----------------
The filter's history stores, per epoch, the prior ``(x, P)`` in feedback coordinates, the
cumulative feedback ``c``, the transition to the next epoch and the updates applied. A
lagged item is formed from the INS output of ``e_v`` *as it was* (the rows are kept for
the length of the history), so exact re-processing works in feed-forward coordinates
``x + c`` and its result equals that of a filter that received the item on time; the
feedback of the epochs after ``e_v`` is already in the INS and is not repeated, the
estimate after re-processing is fed back at ``e1`` like any other.
"""
from __future__ import annotations

import bisect
import os
import weakref
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from sinslab.core import attitude as A
from sinslab.core import units
from sinslab.core.blocks import BLOCK_ROWS, is_mapped, release_pages
from sinslab.estimation.filter import KalmanFilter
from sinslab.estimation.kalman import discretize
from sinslab.estimation.linear import discretize_series_many
from sinslab.fusion.lag import ExactReprocessing
from sinslab.fusion.measurements import Epoch, Grid, NavRow, Rows, declared
from sinslab.fusion.observer import Applied, Decisions, Recorder
from sinslab.fusion.propagate import CompiledPropagation
from sinslab.fusion.spec import FilterGrid, InsSpec
from sinslab.nav import errstate as es
from sinslab.nav import errstate_kernels as ek
from sinslab.nav import strapdown as sd

__all__ = ["run", "run_many", "Lane", "DriverResult", "Applied", "LiveStream", "PrecomputedStream"]


@njit(cache=True)
def _scaled_increments(dth, dv, kg, ka, gb, ab, k, T, dth_s, dv_s, ws, fs):
    """Scale-corrected increments and the mean rates of each filter step of a block.

    ``dth_s = dth (1 − kg)``, ``dv_s = dv (1 − ka)`` per axis (rows of one block, k per
    filter step); ``ws``, ``fs`` (m, 3) the per-step sums of those divided by the step
    T [s] minus the biases. Element by element the operations of the numpy expressions
    ``(dth * (1 − kg)).reshape(m, k, 3).sum(1) / T − gb``, in the same order.
    """
    m = ws.shape[0]
    for c in range(3):
        sg = 1.0 - kg[c]
        sa = 1.0 - ka[c]
        for e in range(m):
            i = e * k
            a = dth[i, c] * sg
            b = dv[i, c] * sa
            dth_s[i, c] = a
            dv_s[i, c] = b
            for j in range(1, k):
                u = dth[i + j, c] * sg
                v = dv[i + j, c] * sa
                dth_s[i + j, c] = u
                dv_s[i + j, c] = v
                a += u
                b += v
            ws[e, c] = a / T - gb[c]
            fs[e, c] = b / T - ab[c]


_NONE = np.zeros(1)      # the height arguments of a free vertical channel (unused)


@njit(cache=True)
def _fill_rows(h, a, b, v):
    """``h[a:b] = v``: rows ``a..b−1`` of ``h`` (M, 3) set to ``v`` (3,) (numpy's
    broadcast runs a 3-element inner loop per row)."""
    for i in range(a, b):
        for c in range(3):
            h[i, c] = v[c]


@njit(cache=True)
def _step_sums_kernel(x, k, acc):
    for e in range(acc.shape[0]):
        i = e * k
        for c in range(3):
            a = x[i, c]
            for j in range(1, k):
                a += x[i + j, c]
            acc[e, c] = a


def _step_sums(x, n_ep, k):
    """Sums of ``k`` consecutive rows of ``x`` (n_ep·k, 3) -> (n_ep, 3), added in row order.

    The same additions in the same order as ``x.reshape(n_ep, k, 3).sum(1)`` (numpy adds
    along a non-contiguous axis one slice after another), compiled: numpy's version runs a
    3-element inner loop.
    """
    acc = np.empty((n_ep, 3))
    _step_sums_kernel(np.ascontiguousarray(x), k, acc)
    return acc


#: Step sums of the IMU records in use, by (id of the record, first sample, steps, samples
#: per step); an entry leaves with its record.
_IMU_SUMS = {}


def _imu_step_sums(imu, start, n_ep, k):
    """``(Σ Δθ, Σ Δv)`` (n_ep, 3) each of the filter steps of ``imu`` from sample ``start``.

    Several filters on one IMU record (a Monte Carlo run's competing filters) bind to the
    same steps; the sums are made once per record. Records are values — their arrays are
    not edited in place — so sums made once stay right for the record's life.
    """
    key = (id(imu), int(start), int(n_ep), int(k))
    sums = _IMU_SUMS.get(key)
    if sums is None:
        n_use = n_ep * k
        sums = (_step_sums(imu.dtheta[start:start + n_use], n_ep, k),
                _step_sums(imu.dv[start:start + n_use], n_ep, k))
        for a in sums:
            a.flags.writeable = False
        _IMU_SUMS[key] = sums
        weakref.finalize(imu, _IMU_SUMS.pop, key, None)
    return sums


class LiveStream:
    """An INS navigated by the driver: IMU increments + initial state + mechanization
    options + the sensor compensation that feedback updates.

    Parameters
    ----------
    imu : sinslab.core.records.ImuRecord
        Increments (with errors), N samples at ``dt``.
    init : sinslab.core.records.NavState
        Initial navigation state (IMU attitude) at the end of sample ``start − 1``
        (``imu.t0`` for ``start = 0``).
    nsub : int
        Mechanization subsamples (coning/sculling).
    vertical : {"free", "hold"}
        ``"hold"``: the vertical channel held to ``height`` (N+1,) or float [m] at the IMU
        epochs, or to a :class:`sinslab.nav.strapdown.HeldHeight` shared with other streams
        (its vertical rate per block computed once for all of them).
    gyro_bias, accel_bias : array_like (3,), optional
        Initial bias compensation [rad/s], [m/s²].
    scaled : bool
        Keep scale-factor compensation (``kg``, ``ka`` [-]) applied as
        ``Δθ (1 − kg)``, ``Δv (1 − ka)``.
    start : int
        First IMU sample used.
    t_start : float, optional
        Start time [s] if not the end of sample ``start − 1``.
    """

    precomputed = False

    def __init__(self, imu, init, *, nsub=2, vertical="free", height=None, gyro_bias=None,
                 accel_bias=None, scaled=False, start=0, t_start=None):
        self._setup(imu, init, InsSpec(nsub=nsub, vertical=vertical, height=height, gyro_bias=gyro_bias,
                                       accel_bias=accel_bias, start=start, t_start=t_start), scaled)

    @classmethod
    def of(cls, imu, init, spec: InsSpec, *, scaled=False) -> "LiveStream":
        """The stream of an INS spec (:class:`sinslab.fusion.spec.InsSpec`, checked when
        it was made)."""
        self = cls.__new__(cls)
        self._setup(imu, init, spec, scaled)
        return self

    def _setup(self, imu, init, spec: InsSpec, scaled):
        self.imu = imu
        self.nsub = int(spec.nsub)
        self.start = int(spec.start)
        self.t0 = (float(spec.t_start) if spec.t_start is not None
                   else (float(imu.t[self.start - 1]) if self.start > 0 else imu.t0))
        height = spec.height
        if spec.vertical == "hold" and isinstance(height, sd.HeldHeight):
            if len(height) != len(imu) + 1 or abs(height.dt - imu.dt) > 1e-9 * imu.dt:
                raise ValueError(f"the shared held height has {len(height)} epochs at {height.dt} s, "
                                 f"the IMU record {len(imu) + 1} at {imu.dt} s")
            self._held = height
        elif spec.vertical == "hold":
            hgt = np.asarray(height, dtype=float)
            if hgt.ndim == 0:
                hgt = np.full(len(imu) + 1, float(hgt))
            if hgt.shape != (len(imu) + 1,):
                raise ValueError(f"height must have {len(imu) + 1} values (IMU epochs), got {hgt.shape}")
            if not np.all(np.isfinite(hgt)):
                raise ValueError(f"held height has a NaN/inf value at epoch {int(np.argmax(~np.isfinite(hgt)))}")
            self._held = sd.HeldHeight(hgt, float(imu.dt), shared=False)
        else:
            self._held = None
        self.dt = float(imu.dt)
        self.state = sd.initial_state_array(init)
        # what feedback may correct, keyed by what a block feeds (es.COMPENSATIONS)
        self.compensation = dict(zip(es.COMPENSATIONS, (
            np.zeros(3) if spec.gyro_bias is None else spec.gyro_bias.copy(),
            np.zeros(3) if spec.accel_bias is None else spec.accel_bias.copy(),
            np.zeros(3), np.zeros(3))))
        self.scaled = bool(scaled)

    gb = property(lambda self: self.compensation["gyro_bias"], doc="Gyro bias compensation [rad/s] (3,).")
    ab = property(lambda self: self.compensation["accel_bias"], doc="Accelerometer bias compensation [m/s²].")
    kg = property(lambda self: self.compensation["gyro_scale"], doc="Gyro scale compensation [-] (3,).")
    ka = property(lambda self: self.compensation["accel_scale"], doc="Accelerometer scale compensation [-].")

    def bind(self, kf_dt):
        """Put the stream on the filter grid; returns ``(t0, number of filter steps)``."""
        dt = self.imu.dt
        k_kf = int(round(kf_dt / dt))
        if k_kf < 1 or abs(k_kf * dt - kf_dt) > 1e-6 * kf_dt or k_kf % self.nsub:
            raise ValueError(f"kf_dt={kf_dt} s must be a multiple of nsub*dt = {self.nsub * dt} s")
        self.k_kf = k_kf
        self.T = k_kf * dt
        self.per = k_kf // self.nsub
        n_ep = (len(self.imu) - self.start) // k_kf
        if n_ep < 1:
            raise ValueError(f"the IMU record ({len(self.imu) - self.start} samples) is shorter "
                             "than one filter step")
        self.n_ep = n_ep
        # a record mapped from files is read a block at a time: its step sums are made
        # per block (the same sums), not held for the whole record
        self._mapped = is_mapped(self.imu.dtheta)
        self._read = 0                  # samples read since the pages were last let go
        if not self.scaled and not self._mapped:
            self._dth_sum, self._dv_sum = _imu_step_sums(self.imu, self.start, n_ep, k_kf)
        return self.T, self.t0, n_ep

    def row0(self):
        """Row of epoch 0 and the rates of its first step."""
        s = self.start
        w0 = self.imu.dtheta[s:s + self.k_kf].sum(0) / self.T - self.gb
        f0 = self.imu.dv[s:s + self.k_kf].sum(0) / self.T - self.ab
        return self.state[:10].copy(), w0, f0

    def row(self):
        """Current row (10,)."""
        return self.state[:10]

    def _increments(self, e_a, e_b):
        k_kf, T = self.k_kf, self.T
        a, b = self.start + e_a * k_kf, self.start + e_b * k_kf
        dth, dvb = self.imu.dtheta[a:b], self.imu.dv[a:b]
        if self._mapped:
            dth, dvb = np.asarray(dth), np.asarray(dvb)
        if self.scaled:
            m = e_b - e_a
            dth_s, dv_s = np.empty((b - a, 3)), np.empty((b - a, 3))
            ws, fs = np.empty((m, 3)), np.empty((m, 3))
            _scaled_increments(dth, dvb, self.kg, self.ka, self.gb, self.ab, k_kf, T, dth_s, dv_s, ws, fs)
            dth, dvb = dth_s, dv_s
        elif self._mapped:
            ws = _step_sums(dth, e_b - e_a, k_kf) / T - self.gb
            fs = _step_sums(dvb, e_b - e_a, k_kf) / T - self.ab
        else:
            ws = self._dth_sum[e_a:e_b] / T - self.gb
            fs = self._dv_sum[e_a:e_b] / T - self.ab
        if self._mapped:
            self._read += b - a
            if self._read >= BLOCK_ROWS:
                release_pages(self.imu.t, self.imu.dtheta, self.imu.dv)
                self._read = 0
        return dth, dvb, ws, fs, a, b

    def _run(self, st, e_a, e_b):
        dth, dvb, ws, fs, a, b = self._increments(e_a, e_b)
        out = np.empty((e_b - e_a, 10))
        # inputs were checked when the stream was made: the compiled loop directly
        if self._held is None:
            mode, href, vref = 0, _NONE, _NONE
        else:
            mode, (href, vref) = 1, self._held.slice(a, b)
        sd.advance(st, dth, dvb, self.dt, self.nsub, mode, href, vref, (0.0, 0.0, 0.0), self.gb, self.ab,
                   out, self.per)
        return out, ws, fs

    def advance(self, e0, e1):
        """Navigate epochs e0 -> e1: rows of e0+1..e1 and the rates of steps e0..e1−1."""
        return self._run(self.state, e0, e1)

    def lookahead(self, e1, e2):
        """Rows and rates of e1 -> e2 from a copy of the present state (the stream is not
        advanced)."""
        return self._run(self.state.copy(), e1, e2)

    def feedback(self, filt, layout):
        """Feed the filter's states of ``layout`` back into this INS."""
        self.compensation, d = layout.apply(filt, self.state, self.compensation)
        return d


class PrecomputedStream:
    """A navigation solution computed elsewhere, read at the filter epochs (feed-forward
    filtering of INS outputs; no feedback possible).

    Parameters
    ----------
    t : array_like, shape (M,)
        Epochs [s], spaced by the filter step.
    rows : array_like, shape (M, 10)
        ``[q0..q3, vE, vN, vU, lat, lon, h]`` at the epochs.
    omega_b, f_b : array_like, shape (M − 1, 3)
        Mean compensated body rate [rad/s] and specific force [m/s²] of each step
        ``k -> k+1``.
    """

    precomputed = True

    def __init__(self, t, rows, omega_b, f_b):
        self.t = np.asarray(t, dtype=float)
        self.rows = np.ascontiguousarray(rows, dtype=float)
        self.omega = np.asarray(omega_b, dtype=float)
        self.f = np.asarray(f_b, dtype=float)
        M = self.t.size
        if self.rows.shape != (M, 10) or self.omega.shape != (M - 1, 3) or self.f.shape != (M - 1, 3):
            raise ValueError(f"precomputed stream: rows must be ({M}, 10) and rates ({M - 1}, 3), got "
                             f"{self.rows.shape}, {self.omega.shape}, {self.f.shape}")
        self._k = 0

    @classmethod
    def from_series(cls, series, imu, *, every, start=0, gyro_bias=None, accel_bias=None):
        """From a :class:`~sinslab.core.records.NavSeries` whose epochs are every
        ``every`` IMU samples from the end of sample ``start − 1``; the step rates are the
        mean IMU rates over those samples minus the given biases."""
        att = series.att_imu if series.att_imu is not None else series.att
        rows = np.concatenate([A.euler_to_quat(att), series.vel, series.lat[:, None],
                               series.lon[:, None], series.h[:, None]], 1)
        M = series.t.size
        n = (M - 1) * every
        T = every * imu.dt
        gb = units.vec3(gyro_bias, "gyro_bias", default=0.0)
        ab = units.vec3(accel_bias, "accel_bias", default=0.0)
        w = imu.dtheta[start:start + n].reshape(M - 1, every, 3).sum(1) / T - gb
        f = imu.dv[start:start + n].reshape(M - 1, every, 3).sum(1) / T - ab
        return cls(series.t, rows, w, f)

    def bind(self, kf_dt):
        T = float(self.t[1] - self.t[0]) if self.t.size > 1 else float(kf_dt)
        if abs(T - kf_dt) > 1e-6 * kf_dt:
            raise ValueError(f"precomputed stream epochs are {T} s apart, the filter step is {kf_dt} s")
        return float(kf_dt), float(self.t[0]), self.t.size - 1

    def row0(self):
        return self.rows[0].copy(), self.omega[0], self.f[0]

    def row(self):
        return self.rows[self._k]

    def advance(self, e0, e1):
        self._k = e1
        return self.rows[e0 + 1:e1 + 1], self.omega[e0:e1], self.f[e0:e1]

    def lookahead(self, e1, e2):
        return self.rows[e1 + 1:e2 + 1], self.omega[e1:e2], self.f[e1:e2]

    def feedback(self, filt, layout):
        raise ValueError("a precomputed navigation stream cannot be fed back")


@dataclass(frozen=True)
class DriverResult:
    """Output of :func:`run` at the filter epochs (M = K + 1 rows, row 0 = start).

    Attributes
    ----------
    t : ndarray (M,)
        Epoch times [s].
    nav : tuple of ndarray (M, 10)
        Per stream, the row after any feedback at that epoch.
    x, sigma : ndarray (M, n)
        Estimate after the epoch (after its updates and feedback) and filter σ.
    compensation : tuple of dict or None
        Per stream, the compensation in use after each epoch keyed as the stream keeps it
        (:data:`sinslab.nav.errstate.COMPENSATIONS`), ``{key: ndarray (M, 3)}``: the
        biases, and the scale factors when some feedback layout has scale blocks (None for
        a precomputed stream). Viewed as ``gyro_bias``, ``accel_bias`` and ``scale``
        (``[kg, ka]`` (M, 6) or None), tuples over the streams.
    applied : Applied
        The updates applied (:mod:`sinslab.fusion.observer`).
    layout : StateLayout
    history : sinslab.fusion.smoothing.History or None
        The forward pass recorded for smoothing (``history=`` of :func:`run`).
    decisions : Decisions
        What each measurement's gate and row gate decided, by measurement index (none
        recorded for a result made elsewhere, e.g. the factor graph's).
    """

    t: np.ndarray
    nav: tuple
    x: np.ndarray
    sigma: np.ndarray
    compensation: tuple
    applied: Applied
    layout: object
    history: object = None
    decisions: Decisions = field(default_factory=lambda: Decisions({}, {}))

    def _key(self, key):
        return tuple(None if c is None else c[key] for c in self.compensation)

    gyro_bias = property(lambda self: self._key("gyro_bias"))
    accel_bias = property(lambda self: self._key("accel_bias"))

    @property
    def scale(self):
        if not any(c is not None and "gyro_scale" in c for c in self.compensation):
            return None
        return tuple(None if c is None else _joined(c["gyro_scale"], c["accel_scale"]) for c in self.compensation)


def _joined(a, b):
    """``[a, b]`` (M, 6) of two (M, 3) arrays: their common array when they are its two
    halves (the driver's record), else a new one."""
    base = a.base
    if (base is not None and b.base is base and base.ndim == 2 and base.shape == (a.shape[0], 6)
            and a.strides == b.strides == base.strides and a.ctypes.data == base.ctypes.data
            and b.ctypes.data == base.ctypes.data + 3 * base.itemsize):
        return base
    return np.concatenate([a, b], 1)


#: rows of a spilled record written between two releases of its pages
SPILL_ROWS = 4096
#: rows of the compensation record left to write at most (the record of a run without
#: feedback is written as the run passes, as a spilled record's pages are let go)
COMP_ROWS = 4096


class _Record:
    """The per-epoch arrays of one run: in memory, or (``folder`` given) memory-mapped
    ``.npy`` files in ``folder`` whose resident pages are let go as the run passes them
    (:func:`sinslab.core.blocks.release_pages`), so the process holds a few
    thousand rows of each, not the whole run. The arrays are the same either way."""

    def __init__(self, folder):
        self.folder = folder
        self.arrays = []
        self._released = 0

    def alloc(self, name, shape, zero=False):
        if self.folder is None:
            return (np.zeros if zero else np.empty)(shape)
        os.makedirs(self.folder, exist_ok=True)
        a = np.lib.format.open_memmap(os.path.join(os.fspath(self.folder), name + ".npy"), mode="w+",
                                      dtype=np.float64, shape=shape)       # a new file reads zeros
        self.arrays.append(a)
        return a

    def passed(self, e):
        """The run will not read rows before ``e`` again (None: the run is over)."""
        if self.folder is None or (e is not None and e - self._released < SPILL_ROWS):
            return
        release_pages(*self.arrays)
        self._released = e if e is not None else self._released


def _epoch_times(grid, spill):
    """``grid.t`` (n + 1,), written a chunk at a time into a memory-mapped file in
    ``spill`` (or made in memory when None); the same values."""
    if spill is None:
        return grid.t
    os.makedirs(spill, exist_ok=True)
    t = np.lib.format.open_memmap(os.path.join(os.fspath(spill), "t.npy"), mode="w+", dtype=np.float64,
                                  shape=(grid.n + 1,))
    for a in range(0, grid.n + 1, 1 << 16):
        b = min(grid.n + 1, a + (1 << 16))
        t[a:b] = grid.t0 + grid.T * np.arange(a, b)
    release_pages(t)
    return t


class _FilterClock:
    """Epoch index -> time since the first epoch [s] (``T·k``, as ``T * np.arange``
    gives it), without an array of every epoch."""

    def __init__(self, T):
        self.T = T

    def __getitem__(self, k):
        return np.float64(self.T * float(k))


def _model_stretch(model, prog, pts, q, T, discretization):
    """F, G, Φ, Q_k of a stretch of epochs; ``pts`` holds per stream the rows (S, 10)
    and the step rates ω, f (S, 3) at those epochs. ``prog`` (a compiled program of the
    model) or None (numpy reference)."""
    if prog is None:
        navs = [es.NavPoint(r[:, 7], r[:, 9], r[:, 4:7], A.quat_to_dcm(r[:, :4]), f, w)
                for r, w, f in pts]
        F, G = model.matrices(*navs)
    else:
        F, G = ek.matrices_rows(prog, np.stack([p[0] for p in pts]),
                                np.stack([p[1] for p in pts]), np.stack([p[2] for p in pts]))
    if prog is not None and discretization == "series":
        Phi, Qk = discretize_series_many(F, G, q, T)
    else:
        Phi, Qk = discretize(F, q, T, G=G, method=discretization)
    return F, G, Phi, Qk


def _model_lanes(model, prog, pts_lanes, q, T, discretization):
    """:func:`_model_stretch` of several lanes' stretches of equal length: with the compiled
    program and the series, all lanes' points go through one call (the kernels work point
    by point; the series skips only zeros of the model's structure, whose terms add exact
    zeros); otherwise lane by lane."""
    if prog is None or discretization != "series" or len(pts_lanes) == 1:
        return [_model_stretch(model, prog, p, q, T, discretization) for p in pts_lanes]
    ns = len(pts_lanes[0])
    cat = [tuple(np.concatenate([p[i][c] for p in pts_lanes]) for c in range(3)) for i in range(ns)]
    F, G, Phi, Qk = _model_stretch(model, prog, cat, q, T, discretization)
    S = pts_lanes[0][0][0].shape[0]
    return [(F[a:a + S], G[a:a + S], Phi[a:a + S], Qk[a:a + S])
            for a in range(0, S * len(pts_lanes), S)]


def _feedback_pairs(feedback):
    if feedback is None or feedback is False:
        return []
    if hasattr(feedback, "apply"):
        return [(0, feedback)]
    return [(int(i), fb) for i, fb in feedback]


@dataclass(frozen=True)
class Lane:
    """One run of :func:`run_many`: its navigation streams, its measurements and its
    initial estimate (the model, ``P0`` and the options are shared by all lanes).

    Attributes
    ----------
    streams : sequence of LiveStream / PrecomputedStream
    measurements : sequence of Measurement
    x0 : array_like (n,), optional
        Initial estimate (default zero).
    """

    streams: tuple
    measurements: tuple
    x0: object = None


class _LaneRun:
    """The state of one lane while the loop of :func:`run_many` runs: its streams, filter,
    measurement schedule and the histories it returns."""

    def __init__(self, lane, model, P0, lag, fbs, kf_dt, history, spill=None):
        streams = list(lane.streams)
        if not streams:
            raise ValueError("the driver needs at least one navigation stream")
        for si, _ in fbs:
            if streams[si].precomputed:
                raise ValueError(f"stream {si} is a precomputed navigation series: it cannot be fed back")
        self.streams = streams
        self.measurements = list(lane.measurements)
        self.history = history
        self.gates = [declared(m) for m in self.measurements]
        if history is not None and any(g.transform is not None for g in self.gates):
            raise ValueError("smoothing a run whose measurements re-initialise filter states (carrier-phase "
                             "ambiguities, time-differenced phase) is not supported")
        n = model.n
        # --- filter grid (stream 0 sets t0; all share the step)
        grids = [s.bind(kf_dt) for s in streams]
        T, t0, _ = grids[0]
        n_ep = min(g[2] for g in grids)
        self.grid = Grid(t0, T, n_ep)
        # --- schedule of every measurement: one row per item, in the order the items are
        # processed (by arrival epoch; within an epoch by measurement, then as the
        # measurement lists them). Arrays, not a dict of tuples: a long log has an item
        # per fix, and Python objects would cost ~0.4 kB each for the whole run.
        cols = ([], [], [], [], [], [])               # arrival epoch, measurement, item, validity epoch, time, late
        for mi, m in enumerate(self.measurements):
            for e, items in m.epochs(self.grid).items():
                for j in items:
                    tv, ta = m.times(j)
                    for c, v in zip(cols, (int(e), mi, int(j), int(self.grid.epoch_at_or_after(tv)), tv, ta > tv)):
                        c.append(v)
        order = np.argsort(np.asarray(cols[0], dtype=np.int64), kind="stable")
        self.s_e, self.s_m, self.s_j, self.s_ev = (np.asarray(c, dtype=np.int64)[order] for c in cols[:4])
        self.s_tv = np.asarray(cols[4], dtype=float)[order]
        self.s_late = np.asarray(cols[5], dtype=bool)[order]
        # the schedule read item by item as Python numbers (arriving, measure)
        self._s_e, self._s_m, self._s_j, self._s_ev, self._s_tv, self._s_late = (
            memoryview(a) for a in (self.s_e, self.s_m, self.s_j, self.s_ev, self.s_tv, self.s_late))
        self._next = 0
        del cols, order
        lagged = self.s_ev < self.s_e
        hist = 0 if lag.on_arrival or not lagged.any() else int((self.s_e - self.s_ev)[lagged].max()) + 3
        self.hist = hist
        self.keep_F = lag.needs_model and hist > 0
        if history is not None and hist > 0 and not isinstance(lag, ExactReprocessing):
            raise ValueError(f"smoothing a run with lagged measurements needs exact re-processing or "
                             f"on-arrival updates, not {type(lag).__name__}")
        # --- filter and histories
        self.ns = ns = len(streams)
        self.filt = filt = KalmanFilter(np.zeros(n) if lane.x0 is None else lane.x0, P0, t0=0.0,
                                        history=hist, check=False)
        self.store = store = _Record(spill)
        M = n_ep + 1
        self.nav_h = [store.alloc(f"nav{i}", (M, 10)) for i in range(len(streams))]
        self.nav_pre = [store.alloc(f"nav_pre{i}", (M, 10)) for i in range(len(streams))] if hist else self.nav_h
        # the step rates are read back only by lagged items (None: nothing lags)
        self.w_h = [store.alloc(f"omega{i}", (M, 3)) for i in range(len(streams))] if hist else None
        self.f_h = [store.alloc(f"f{i}", (M, 3)) for i in range(len(streams))] if hist else None
        self.x_h = store.alloc("x", (M, n), zero=True)
        self.sig_h = store.alloc("sigma", (M, n))
        self.live = live = [not s.precomputed for s in streams]
        self.scaled = scaled = any(fb.gyro_scale is not None or fb.accel_scale is not None for _, fb in fbs)
        keys = es.COMPENSATIONS if scaled else es.COMPENSATIONS[:2]      # the biases always
        self.comp_h = [self._comp_record(store, keys, i, M) if lv else None for i, lv in enumerate(live)]
        self.F_h = store.alloc("F", (n_ep, n, n)) if self.keep_F else None
        self.G_h = store.alloc("G", (n_ep, n, model.q.size)) if self.keep_F else None
        for i, s in enumerate(streams):
            r0, w0, f0 = s.row0()
            self.nav_h[i][0] = r0
            self.nav_pre[i][0] = r0
            if hist:
                self.w_h[i][0] = w0
                self.f_h[i][0] = f0
        # rows of comp_h before comp_next[i] hold stream i's compensation (see _comp)
        self.comp_next = [0] * len(streams)
        self.sig_h[0] = filt.sigma
        if history is not None:
            history.begin(filt, n_ep, T, set(np.union1d(self.s_e, self.s_ev).tolist()))
        self.rec = Recorder()
        self.streak = [0] * len(self.measurements)          # epochs whose every row was refused
        self.nav_lag = self.nav_h if lag.corrected_nav else self.nav_pre
        self.Phi_la = self.Q_la = self.stretch = None
        self.blk = self.rows = None

    @staticmethod
    def _comp_record(store, keys, i, M):
        """Stream i's compensation record ``{key: (M, 3)}``; the two scale factors are the
        halves of one (M, 6) array, the ``scale`` of the result without a copy."""
        rec = {k: store.alloc(f"{k}{i}", (M, 3)) for k in keys if not k.endswith("_scale")}
        if "gyro_scale" in keys:
            both = store.alloc(f"scale{i}", (M, 6))
            rec["gyro_scale"], rec["accel_scale"] = both[:, :3], both[:, 3:]
        return rec

    def arrival_epochs(self) -> list:
        """The epochs at which items arrive, ascending, once each."""
        return np.unique(self.s_e).tolist()

    def arriving(self, e):
        """Rows of the schedule of the items arriving at epoch ``e`` (a range)."""
        # the loop asks epoch after epoch: the items from where the last answer ended,
        # found without a search while one item arrives per epoch
        s_e, a = self._s_e, self._next
        if not (a < len(s_e) and s_e[a] == e and (a == 0 or s_e[a - 1] < e)):
            a = bisect.bisect_left(s_e, e)
        b = a
        while b < len(s_e) and s_e[b] == e:
            b += 1
        self._next = b
        return range(a, b)

    def fusable(self, cprop, discretization):
        """Model, Φ, Q_k and prediction in the one compiled loop, unless Φ, Q_k or F must
        be kept (a history for lagged items or smoothing records every Φ)."""
        f = self.filt
        return (cprop is not None and discretization == "series" and f.fast
                and not self.keep_F and self.history is None)

    def advance(self, e0, e1):
        """Streams to ``e1``: rows of ``e0..e1`` and the step rates of the block."""
        m = e1 - e0
        self.blk = [s.advance(e0, e1) for s in self.streams]
        self.rows = []
        for i in range(self.ns):
            r = np.empty((m + 1, 10))
            r[0] = self.nav_h[i][e0]
            r[1:] = self.blk[i][0]
            self.rows.append(r)

    def points(self, e1, la_end):
        """Per stream the linearisation points of the stretch from the block start to
        ``la_end``: the block's rows, then a look-ahead run of the streams."""
        pts = []
        for i, s in enumerate(self.streams):
            out, ws, fs = self.blk[i]
            if la_end > e1:
                la_out, lws, lfs = s.lookahead(e1, la_end)
                la_rows = np.vstack([self.rows[i], la_out[:-1]])       # epochs e0..la_end-1
                w_la, f_la = np.vstack([ws, lws]), np.vstack([fs, lfs])
            else:
                la_rows, w_la, f_la = self.rows[i][:-1], ws, fs
            pts.append((la_rows, w_la, f_la))
        return pts

    def predict(self, e0, e1, la0, T):
        """Prediction through the block from the kept Φ, Q_k of the stretch."""
        sl = slice(e0 - la0, e1 - la0)
        if self.history is None:
            self.filt.predict_many(self.Phi_la[sl], self.Q_la[sl], T, sigma_out=self.sig_h[e0 + 1:e1 + 1],
                                   x_out=self.x_h[e0 + 1:e1 + 1])
        else:
            self.history.predict(self.filt, self.Phi_la[sl], self.Q_la[sl], T, e0, self.sig_h[e0 + 1:e1 + 1],
                                 self.x_h[e0 + 1:e1 + 1])

    def record(self, e0, e1):
        """The block's rows, rates and compensation into the histories."""
        for i, s in enumerate(self.streams):
            _, ws, fs = self.blk[i]
            self.nav_h[i][e0 + 1:e1 + 1] = self.rows[i][1:]
            if self.hist:
                self.nav_pre[i][e0 + 1:e1 + 1] = self.rows[i][1:]
                self.w_h[i][e0 + 1:e1 + 1] = ws
                self.f_h[i][e0 + 1:e1 + 1] = fs
            if self.live[i] and e1 - self.comp_next[i] >= COMP_ROWS:
                self._comp(i, e1)
        # rows up to a few lagged epochs back are read again (the validity epoch of a late
        # item): the pages before those are let go
        self.store.passed(e1 - self.hist - 1)

    def _comp(self, i, end):
        """Stream i's compensation into its history up to row ``end`` (exclusive).

        The compensation changes only by feedback, so its rows are written when it is
        about to change (and every :data:`COMP_ROWS` rows, and at the end): one write per
        fix instead of one per block and one per feedback; the rows are the same."""
        a = self.comp_next[i]
        if end > a:
            c = self.streams[i].compensation
            for k, h in self.comp_h[i].items():
                _fill_rows(h, a, end, c[k])
            self.comp_next[i] = end

    def _epoch_rows(self, rows_list, k):
        return tuple(NavRow(rows_list[i][k], self.w_h[i][k], self.f_h[i][k]) for i in range(self.ns))

    def measure(self, e1, here, lag, lay, n, q, lag_tol, t_ep, t_rel, fbs):
        """The measurements arriving at ``e1`` (see the module notes, step 4), then the
        feedback (step 5)."""
        filt = self.filt
        now = None
        ev_min = None
        for k in here:
            mi, j, ev, tv, late = self._s_m[k], self._s_j[k], self._s_ev[k], self._s_tv[k], self._s_late[k]
            meas = self.measurements[mi]
            gate, row_gate, transform = self.gates[mi]
            if ev < e1 and not lag.on_arrival:
                if transform is not None:
                    raise ValueError(f"{type(meas).__name__} arrives late and re-initialises filter states: it "
                                     "must be applied on arrival (a lag policy with on_arrival)")
                ep = Epoch(t_ep[ev], ev, self._epoch_rows(self.nav_lag, ev), lay, n, j)
                r = self._rows(mi, tv, meas.matrices(ep), row_gate, None)
                if r is None:
                    continue
                if self.keep_F:
                    # Qc = G diag(q) Gᵀ of the validity epoch only (a one-matrix stack:
                    # the arithmetic of forming it for the whole stretch)
                    g = self.G_h[ev:ev + 1]
                    kw = dict(F=self.F_h[ev], Qc=((g * q) @ np.swapaxes(g, -1, -2))[0])
                else:
                    kw = {}
                res = lag.update(filt, *r, t_rel[ev], tol=lag_tol, **kw)
                ev_min = ev if ev_min is None else min(ev_min, ev)
            else:
                # on time, or the lag ignored: a late item taken as valid now
                t_at = tv if (lag.on_arrival and late) else t_ep[e1]
                if now is None:
                    now = tuple(NavRow(self.rows[i][-1], self.blk[i][1][-1], self.blk[i][2][-1])
                                for i in range(self.ns))
                ep = Epoch(t_at, e1, now, lay, n, j, (filt.x, filt.P))
                jump = transform(ep) if transform is not None else None
                if jump is not None:            # states the measurement re-initialises or copies
                    filt.transform(*jump)
                    ep = Epoch(t_at, e1, now, lay, n, j, (filt.x, filt.P))
                r = self._rows(mi, tv, meas.matrices(ep), row_gate, ep.prior)
                if r is None:
                    continue
                if gate is not None:
                    passed, _ = gate.test(filt.x, filt.P, *r)
                    self.rec.gated(mi, t_at, passed)
                    if not passed:
                        continue
                res = filt.update(*r)
            self.rec.applied(mi, j, tv, t_ep[e1], res)
        if not here:
            return
        history = self.history
        if history is not None:
            history.updated(e1, filt, ev_min)
        for si_, fb in fbs:
            s = self.streams[si_]
            self._comp(si_, e1)                 # the rows before e1 hold the compensation before
            d = s.feedback(filt, fb)
            if history is not None:
                history.fed_back(e1, d)
            self.nav_h[si_][e1] = s.row()
        self.x_h[e1] = filt.x
        self.sig_h[e1] = filt.sigma

    def _rows(self, mi, tv, r, row_gate, prior):
        """A measurement's answer as an update: ``(z, H, R)`` as given, or the rows of a
        :class:`Rows` answer its row gate keeps against ``prior`` (all rows, none gated,
        for a lagged update: ``prior`` None), the decisions recorded; None: nothing to apply."""
        if not isinstance(r, Rows):
            return r
        if row_gate is None:
            raise ValueError(f"measurement {mi} answered rows to gate but declares no row_gate")
        rej, nu, nis, self.streak[mi] = row_gate.decide(r, prior, self.streak[mi])
        self.rec.row_decisions(mi, tv, r, rej, nu, nis)
        if not np.any(~rej):
            return None
        return r.z[~rej], r.H[~rej], r.R[~rej]

    def result(self, t_ep, lay):
        for i, lv in enumerate(self.live):
            if lv:
                self._comp(i, self.x_h.shape[0])
        self.store.passed(None)
        applied, decisions = self.rec.result()
        return DriverResult(t_ep, tuple(self.nav_h), self.x_h, self.sig_h, tuple(self.comp_h), applied, lay,
                            self.history, decisions)


def run(streams, model, P0, measurements, *, grid: FilterGrid, feedback=None, lag=None, x0=None,
        progress=False, label="fusion", history=None) -> DriverResult:
    """Run the filter beside the streams and apply the measurements (see the module notes).

    Parameters
    ----------
    streams : sequence of LiveStream / PrecomputedStream
        k >= 1 navigation streams on one filter grid (``t0`` and step of stream 0).
    model : sinslab.nav.errstate.ErrorModel or DifferenceModel
        ``model.matrices(*navpoints)`` with one NavPoint per stream gives F, G; ``model.q``
        the noise densities; ``model.layout`` the state layout.
    P0 : array_like (n, n)
        Initial covariance.
    measurements : sequence of Measurement
        See :mod:`sinslab.fusion.measurements`.
    grid : sinslab.fusion.spec.FilterGrid
        The filter step, the longest compiled stretch, the model look-ahead (the model is
        evaluated for that stretch at once), the discretisation, the tolerance matching a
        lagged item to a stored epoch, and how the model is evaluated
        (``model_eval``: ``"compiled"`` kernels or the readable ``"numpy"`` reference).
    feedback : FeedbackLayout or sequence of (stream index, FeedbackLayout), optional
        Closed loop for those streams after every epoch with a measurement; None: feed
        forward.
    lag : lag policy, optional
        Default :class:`sinslab.fusion.lag.ExactReprocessing`.
    x0 : array_like (n,), optional
        Initial estimate (default zero).
    progress : bool
        Show a progress bar on a terminal.
    label : str
        The progress bar's label.
    history : sinslab.fusion.smoothing.History, optional
        Record the forward pass for :func:`sinslab.fusion.smoothing.smooth` (it is
        called after each prediction, after the measurements of an epoch and after
        its feedback; lagged items need :class:`~sinslab.fusion.lag.ExactReprocessing`
        or :class:`~sinslab.fusion.lag.OnArrival`).

    Returns
    -------
    DriverResult
    """
    return _run_lanes([Lane(tuple(streams), tuple(measurements), x0)], [history], model, P0, grid,
                      feedback=feedback, lag=lag, progress=progress, label=label)[0]


def run_many(lanes, model, P0, *, grid: FilterGrid, feedback=None, lag=None, progress=False,
             label="fusion") -> list:
    """The runs of a Monte Carlo campaign in lockstep: :func:`run` for every lane, on a run
    axis.

    All lanes step through the same blocks: per block every lane's streams advance, the
    error model of all lanes is evaluated and their filters predicted in one compiled call
    (the fused loop of :mod:`sinslab.fusion.propagate` over the lanes; with a history, the
    model and its discretisation for all lanes at once), then each lane applies its own
    measurements, lag policy and feedback. Each lane's numbers are those of :func:`run` on
    that lane alone, bit for bit.

    Parameters
    ----------
    lanes : sequence of Lane
        The runs: their own streams (own IMU records and initial states), measurements
        (own data) and initial estimates. They must share the filter grid and the epochs
        at which measurements arrive (for instance fixes requested on one plan), because
        the block boundaries are part of the arithmetic.
    model, P0, grid, feedback, lag, progress, label
        As in :func:`run`, shared by all lanes (lag policies and feedback layouts hold no
        run state).

    Returns
    -------
    list of DriverResult
        One per lane, in order.

    Raises
    ------
    ValueError
        No lanes, or lanes on different filter grids or measurement schedules.
    """
    lanes = list(lanes)
    if not lanes:
        raise ValueError("run_many needs at least one lane")
    return _run_lanes(lanes, [None] * len(lanes), model, P0, grid, feedback=feedback, lag=lag,
                      progress=progress, label=label)


def _run_lanes(lanes, histories, model, P0, spec: FilterGrid, *, feedback, lag, progress, label):
    """The loop of :func:`run` and :func:`run_many` (see the module notes)."""
    from sinslab.core.progress import progress as _progress

    kf_dt, max_block, model_every = spec.kf_dt, spec.max_block, spec.model_every
    discretization, lag_tol, model_eval = spec.discretization, spec.lag_tol, spec.model_eval
    lag = ExactReprocessing() if lag is None else lag
    lay = model.layout
    n = model.n
    fbs = _feedback_pairs(feedback)
    runs = [_LaneRun(ln, model, P0, lag, fbs, kf_dt, h,
                     None if spec.spill is None else os.path.join(os.fspath(spec.spill), f"lane{k}"))
            for k, (ln, h) in enumerate(zip(lanes, histories))]
    grid = runs[0].grid
    stops = sorted(set(runs[0].arrival_epochs()) | {grid.n})
    for k, r in enumerate(runs[1:], 1):
        g = r.grid
        if (g.t0, g.T, g.n) != (grid.t0, grid.T, grid.n):
            raise ValueError(f"lane {k} is on the filter grid t0={g.t0} s, step {g.T} s, {g.n} steps; "
                             f"lane 0 on t0={grid.t0} s, step {grid.T} s, {grid.n} steps")
        if sorted(set(r.arrival_epochs()) | {g.n}) != stops:
            raise ValueError(f"lane {k} receives measurements at other epochs than lane 0: lanes "
                             "in lockstep need one measurement schedule")
    T, n_ep = grid.T, grid.n
    t_ep = _epoch_times(grid, spec.spill)
    if spec.spill is not None:
        runs[0].store.arrays.append(t_ep)          # its pages let go with the first lane's
    t_rel = _FilterClock(T)                      # filter clock (absolute stamps lose digits)
    max_ep = max(1, int(round(max_block / T)))
    la_ep = max(1, int(round(model_every / T)))
    la_end = -1
    la0 = 0
    q = model.q
    cprop = CompiledPropagation.of(model) if model_eval == "compiled" else None
    prog = cprop.prog if cprop is not None else None
    fused = [r for r in runs if r.fusable(cprop, discretization)]
    kept = [r for r in runs if not r.fusable(cprop, discretization)]
    stretch = None

    with _progress(label, total=n_ep, unit="steps", enabled=bool(progress)) as bar:
        e0 = 0
        si = 0
        while e0 < n_ep:
            while stops[si] <= e0:
                si += 1
            e1 = min(stops[si], e0 + max_ep)
            for r in runs:
                r.advance(e0, e1)
            if e1 > la_end:
                # error model for the next stretch, from a look-ahead run of the streams
                la0 = e0
                la_end = max(e1, min(n_ep, e0 + la_ep))
                pts = {id(r): r.points(e1, la_end) for r in runs}
                if fused:
                    # (L, k, S, ·) per quantity; one lane with one stream: a view, no copy
                    ns = fused[0].ns
                    if len(fused) == 1 and ns == 1:
                        p = pts[id(fused[0])][0]
                        stretch = tuple(np.ascontiguousarray(p[c][None, None]) for c in range(3))
                    else:
                        stretch = tuple(np.ascontiguousarray(np.stack([np.stack([p[c] for p in pts[id(r)]])
                                                                       for r in fused]))
                                        for c in range(3))
                if kept:
                    for r, (F, G, r.Phi_la, r.Q_la) in zip(kept, _model_lanes(
                            model, prog, [pts[id(r)] for r in kept], q, T, discretization)):
                        if r.keep_F:
                            r.F_h[la0:la_end] = F
                            r.G_h[la0:la_end] = G
            if fused:
                cprop.predict([r.filt for r in fused], stretch, e0 - la0, e1 - la0, T,
                              [r.sig_h[e0 + 1:e1 + 1] for r in fused], [r.x_h[e0 + 1:e1 + 1] for r in fused])
            for r in kept:
                r.predict(e0, e1, la0, T)
            at_stop = e1 == stops[si]
            for r in runs:
                r.record(e0, e1)
                r.measure(e1, r.arriving(e1) if at_stop else (), lag, lay, n, q, lag_tol,
                          t_ep, t_rel, fbs)
            bar.advance(e1 - e0)
            e0 = e1
    return [r.result(t_ep, lay) for r in runs]
