"""Closed-loop correction of an INS from an error-state filter: which states are fed back
and how they correct the strapdown state and the sensor compensation.

:class:`FeedbackLayout` routes the fed-back blocks of an error state (named as in
:mod:`sinslab.nav.errstate`) to the navigation state (:func:`sinslab.nav.strapdown.correct`)
and to the gyro/accelerometer bias and scale-factor compensation. The filter itself
(:class:`sinslab.estimation.filter.KalmanFilter`) only zeroes the fed-back states and
keeps their cumulative sum.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sinslab.nav import strapdown as sd

__all__ = ["FeedbackLayout"]


@dataclass(frozen=True)
class FeedbackLayout:
    """Where the feedback-able blocks sit in an error-state vector.

    Each attribute is a slice or index array into the state vector, or None if the
    model has no such block. Used by callers of
    :meth:`sinslab.estimation.filter.KalmanFilter.feedback` to route the
    estimate: ``att`` (φ, rad, ENU), ``vel`` (δv, m/s, ENU; 2 states = east, north of a
    horizontal model), ``pos`` (δL, δλ [rad], δh [m]; 2 states = δL, δλ), ``gyro``
    (rad/s), ``accel`` (m/s²), ``gyro_scale``, ``accel_scale`` (scale-factor errors [-],
    added to the scale compensation by the caller) and ``other`` blocks that are zeroed
    on feedback.
    """

    att: object = None
    vel: object = None
    pos: object = None
    gyro: object = None
    accel: object = None
    other: tuple = ()
    gyro_scale: object = None
    accel_scale: object = None

    def indices(self, n):
        """All fed-back state indices, sorted, as an int array."""
        out = []
        for s in (self.att, self.vel, self.pos, self.gyro, self.accel, self.gyro_scale,
                  self.accel_scale, *self.other):
            if s is not None:
                out.extend(np.arange(n)[s].tolist())
        return np.array(sorted(set(out)), dtype=np.int64)

    def split(self, x):
        """Dict of the blocks of ``x`` (absent blocks omitted)."""
        return {k: np.asarray(x)[getattr(self, k)] for k in ("att", "vel", "pos", "gyro", "accel")
                if getattr(self, k) is not None}

    @classmethod
    def from_model(cls, layout, *, att="phi", vel="dv", pos="dp", gyro="eps", accel="nabla",
                   gyro_scale="kg", accel_scale="ka", other=()):
        """From a :class:`sinslab.nav.errstate.StateLayout` (block names as in errstate's
        builders; missing blocks, or a name given as None, become None)."""
        names = [b.name for b in layout.blocks]
        get = lambda b: layout.slice(b) if (b is not None and b in names) else None  # noqa: E731
        return cls(get(att), get(vel), get(pos), get(gyro), get(accel),
                   tuple(layout.slice(o) for o in other), get(gyro_scale), get(accel_scale))

    def apply(self, filt, state, gyro_bias=None, accel_bias=None):
        """Closed-loop correction: feed the filter's estimate back into the INS.

        Takes the fed-back states out of ``filt`` (:meth:`KalmanFilter.feedback`, which
        zeroes them), corrects the strapdown state array in place with
        :func:`sinslab.nav.strapdown.correct` (φ [rad], δv [m/s], δp = [δL, δλ, δh]; the
        vertical of a 2-state horizontal block is left alone) and adds the bias estimates
        to the compensation in use (scale factors: ``d[gyro_scale]``, ``d[accel_scale]``
        are for the caller).

        Parameters
        ----------
        filt : sinslab.estimation.filter.KalmanFilter
        state : ndarray, shape (NSTATE,) or (10,)
            Strapdown state array (modified in place).
        gyro_bias, accel_bias : array_like, shape (3,), optional
            Current compensation [rad/s], [m/s²] (default zero).

        Returns
        -------
        gyro_bias, accel_bias : ndarray, shape (3,)
            The new compensation to pass to :func:`sinslab.nav.strapdown.step`.
        d : ndarray, shape (n,)
            The fed-back amounts.
        """
        d = filt.feedback(self.indices(filt.n))

        def three(s):
            if s is None:
                return None
            v = d[s]
            return v if v.size == 3 else np.r_[v, 0.0]

        sd.correct(state, phi=three(self.att), dvel=three(self.vel), dpos=three(self.pos))
        gb = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, dtype=float).copy()
        ab = np.zeros(3) if accel_bias is None else np.asarray(accel_bias, dtype=float).copy()
        if self.gyro is not None:
            gb = gb + d[self.gyro]
        if self.accel is not None:
            ab = ab + d[self.accel]
        return gb, ab, d
