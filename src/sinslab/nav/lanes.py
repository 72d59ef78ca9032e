"""Lane-stacked strapdown mechanization: many INS ("lanes") advanced in one compiled call.

A Monte Carlo campaign of closed-loop filters runs hundreds of slave INS over one
trajectory, each with its own IMU errors and its own feedback. Per filter step every lane
advances a few IMU samples and is then corrected; one Python call per lane and step would
cost more than the navigation itself. :class:`LaneBank` holds the strapdown state arrays
of all lanes (rows of :data:`sinslab.nav.strapdown.NSTATE` entries) and advances them
through the same compiled update as :func:`sinslab.nav.strapdown.step` (the one
mechanization: ENU, coning/sculling over ``nsub`` samples, free vertical channel), lane by
lane inside one compiled loop.

Each lane reads the raw increments of one IMU record (``source[lane]``: several lanes may
share a record, e.g. the same slave IMU under different filters) and applies its own
sensor compensation, as the fusion driver's live streams do::

    Δθ_c = Δθ (1 − k_g) − ε dt,      Δv_c = Δv (1 − k_a) − ∇ dt     (per axis)

Lanes can be stopped (``active`` false): a diverged lane keeps its last state and is not
advanced or corrected again, so one run that blows up never raises inside the loop of
the others.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sinslab.core.attitude import quat_to_dcm
from sinslab.nav import strapdown as sd

__all__ = ["LaneBank"]

_LAT_LIMIT = math.radians(89.0)


@njit(cache=True)
def _advance_lanes(S, dth, dvl, src, a, b, dt, nsub, comp, active, coeffs, bufth, bufv, dummy, out1, free):
    """Advance every active lane over the samples ``a..b−1`` of its record.

    ``S`` (L, NSTATE) in place; ``dth``, ``dvl`` (nrec, N, 3); ``src`` (L,) record of each
    lane; ``comp`` (L, 12) = [ε (3) rad/s, ∇ (3) m/s², k_g (3), k_a (3)]. A lane whose
    latitude leaves ±89° or whose state turns non-finite is made inactive. ``free`` is 0
    (the free vertical channel, no output rows), an argument rather than a literal: a
    literal 0 would compile the mechanization once more for its own signature.
    """
    nupd = (b - a) // nsub
    for l in range(S.shape[0]):
        if not active[l]:
            continue
        r = src[l]
        for i in range(b - a):
            for c in range(3):
                bufth[i, c] = dth[r, a + i, c] * (1.0 - comp[l, 6 + c])
                bufv[i, c] = dvl[r, a + i, c] * (1.0 - comp[l, 9 + c])
        s = S[l]
        sd._kernel(s, bufth, bufv, dt, nsub, nupd, free, dummy, dummy, 0.0, 0.0, 0.0,
                   comp[l, 0], comp[l, 1], comp[l, 2], comp[l, 3], comp[l, 4], comp[l, 5], coeffs, out1, free)
        ok = abs(s[7]) < _LAT_LIMIT
        for j in range(sd.NAV):
            if not math.isfinite(s[j]):
                ok = False
        if not ok:
            active[l] = False


@njit(cache=True)
def _correct_lanes(S, phi, dvel, active):
    """Feedback of φ [rad] and δv [m/s] (rows per lane) into the active lanes."""
    for l in range(S.shape[0]):
        if active[l]:
            sd._correct_s(S[l], phi[l, 0], phi[l, 1], phi[l, 2], dvel[l, 0], dvel[l, 1], dvel[l, 2],
                          0.0, 0.0, 0.0)


class LaneBank:
    """The strapdown states of L lanes over shared IMU records.

    Parameters
    ----------
    init : (L, NSTATE) ndarray
        Initial state arrays (:func:`sinslab.nav.strapdown.initial_state_array` per lane).
    dtheta, dv : (nrec, N, 3) ndarray
        Raw IMU increments [rad], [m/s] (body axes) of the records, sample ``i`` covering
        ``[t0 + i dt, t0 + (i+1) dt]``.
    source : (L,) int array
        Record read by each lane.
    dt : float
        IMU interval [s].
    nsub : int
        Samples per mechanization update (1..5).

    Attributes
    ----------
    state : (L, NSTATE) ndarray
    comp : (L, 12) ndarray
        Sensor compensation [ε, ∇, k_g, k_a] in use (SI).
    active : (L,) bool ndarray
        False for a lane stopped (by :meth:`stop` or because it left the valid latitudes or
        turned non-finite).
    sample : int
        Next raw sample to be read.
    """

    def __init__(self, init, dtheta, dv, source, dt, nsub=2):
        self.state = np.ascontiguousarray(np.array(init, dtype=float))
        L = self.state.shape[0]
        if self.state.ndim != 2 or self.state.shape[1] != sd.NSTATE:
            raise ValueError(f"init must be (L, {sd.NSTATE}) state arrays, got {self.state.shape}")
        self.dtheta = np.ascontiguousarray(dtheta, dtype=float)
        self.dv = np.ascontiguousarray(dv, dtype=float)
        if self.dtheta.ndim != 3 or self.dtheta.shape[2] != 3 or self.dv.shape != self.dtheta.shape:
            raise ValueError(f"dtheta, dv must be (records, samples, 3), got {self.dtheta.shape}, {self.dv.shape}")
        self.source = np.ascontiguousarray(source, dtype=np.int64)
        if self.source.shape != (L,) or self.source.min() < 0 or self.source.max() >= self.dtheta.shape[0]:
            raise ValueError(f"source must be {L} record indices in 0..{self.dtheta.shape[0] - 1}")
        if not 1 <= int(nsub) <= 5:
            raise ValueError(f"nsub must be in 1..5, got {nsub!r}")
        self.dt, self.nsub = float(dt), int(nsub)
        self.comp = np.zeros((L, 12))
        self.active = np.ones(L, dtype=np.bool_)
        self.sample = 0
        self._dummy = np.zeros(1)
        self._out1 = np.zeros((1, sd.NSTATE))

    @property
    def lanes(self) -> int:
        return self.state.shape[0]

    def advance(self, n):
        """Advance every active lane by ``n`` samples (a multiple of ``nsub``)."""
        n = int(n)
        if n % self.nsub or self.sample + n > self.dtheta.shape[1]:
            raise ValueError(f"cannot advance {n} samples from sample {self.sample} of "
                             f"{self.dtheta.shape[1]} in updates of {self.nsub}")
        buf = np.empty((n, 3))
        _advance_lanes(self.state, self.dtheta, self.dv, self.source, self.sample, self.sample + n, self.dt,
                       self.nsub, self.comp, self.active, sd.CONING_COEFFS, buf, np.empty((n, 3)),
                       self._dummy, self._out1, 0)
        self.sample += n

    def correct(self, phi, dvel):
        """Closed-loop correction of the active lanes: ``q <- q(φ) ⊗ q``, ``v -= δv``.

        ``phi`` (L, 3) [rad] in n (ENU), ``dvel`` (L, 3) [m/s]; the convention of
        :func:`sinslab.nav.strapdown.correct`.
        """
        _correct_lanes(self.state, np.ascontiguousarray(phi, dtype=float),
                       np.ascontiguousarray(dvel, dtype=float), self.active)

    def compensate(self, gyro_bias=None, accel_bias=None, gyro_scale=None, accel_scale=None):
        """Add estimates (L, 3) each, SI) to the sensor compensation of the active lanes."""
        on = self.active[:, None]
        for k, v in enumerate((gyro_bias, accel_bias, gyro_scale, accel_scale)):
            if v is not None:
                self.comp[:, 3 * k:3 * k + 3] += np.where(on, np.asarray(v, float), 0.0)

    def stop(self, mask):
        """Stop the lanes of the boolean ``mask`` (L,)."""
        self.active &= ~np.asarray(mask, dtype=bool)

    def attitude(self):
        """``C_b^n`` (L, 3, 3) of every lane (body -> ENU)."""
        q = self.state[:, :4]
        return quat_to_dcm(q / np.linalg.norm(q, axis=1, keepdims=True))

    def velocity(self):
        """``[vE, vN, vU]`` (L, 3) [m/s]."""
        return self.state[:, 4:7].copy()
