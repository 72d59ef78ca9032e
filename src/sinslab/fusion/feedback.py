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

__all__ = ["FeedbackLayout", "AUTO"]

#: Default of :meth:`FeedbackLayout.from_model`: pick the blocks by what they feed.
AUTO = "auto"


def _states(s, n):
    """State indices of a layout entry (slice, index array, or (k, 3) padded rows)."""
    if isinstance(s, np.ndarray) and s.ndim == 2:
        v = s.ravel()
        return v[v < n].tolist()
    return np.arange(n)[s].tolist()


def _sum3(d, s):
    """Compensation change (3,) of an entry: its states, or the padded rows summed."""
    if isinstance(s, np.ndarray) and s.ndim == 2:
        return np.r_[d, 0.0][s].sum(0)
    return d[s]


@dataclass(frozen=True)
class FeedbackLayout:
    """Where the feedback-able blocks sit in an error-state vector.

    Each attribute is a slice or index array into the state vector, or None if the
    model has no such block; ``gyro`` and ``accel`` may also be an int array (k, 3) of
    k blocks whose column a holds the state of body axis a (n: the block has no such
    axis), their estimates adding up. Used by callers of
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
        """All fed-back state indices, sorted, as a read-only int array."""
        cache = self.__dict__.setdefault("_indices", {})   # asked at every feedback
        if n not in cache:
            out = []
            for s in (self.att, self.vel, self.pos, self.gyro, self.accel, self.gyro_scale,
                      self.accel_scale, *self.other):
                if s is not None:
                    out.extend(_states(s, n))
            idx = np.array(sorted(set(out)), dtype=np.int64)
            idx.setflags(write=False)
            cache[n] = idx
        return cache[n]

    def nav_errors(self, x):
        """``(φ, δv, δp)`` of an error state ``x`` (..., n): the blocks that correct the
        navigation state (2-state horizontal blocks as they are, None where the layout has
        none), the arguments of :func:`sinslab.nav.strapdown.correct` and
        :func:`~sinslab.nav.strapdown.correct_rows`."""
        x = np.asarray(x)
        return tuple(None if s is None else x[..., s] for s in (self.att, self.vel, self.pos))

    def split(self, x):
        """Dict of the blocks of ``x`` (absent blocks omitted)."""
        x = np.asarray(x)
        return {k: (_sum3(x, getattr(self, k)) if k in ("gyro", "accel") else x[getattr(self, k)])
                for k in ("att", "vel", "pos", "gyro", "accel") if getattr(self, k) is not None}

    @classmethod
    def from_model(cls, layout, *, att="phi", vel="dv", pos="dp", gyro=AUTO, accel=AUTO,
                   gyro_scale=AUTO, accel_scale=AUTO, other=()):
        """From a :class:`sinslab.nav.errstate.StateLayout`.

        The sensor targets follow what a block *is* (its :attr:`Block.feeds`), not its
        name: by default (``AUTO``) every body-axis gyro bias or Gauss–Markov block feeds
        the gyro bias compensation (several blocks add up, an axis subset feeds only its
        axes), likewise accelerometer biases and the scale-factor blocks. A block name
        (str) picks that one block instead (missing: none), None feeds nothing.

        Raises
        ------
        ValueError
            For scale-factor feedback from several blocks or from an axis subset (the
            scale compensation of the streams takes one 3-axis block).
        """
        names = [b.name for b in layout.blocks]
        get = lambda b: layout.slice(b) if (b is not None and b in names) else None  # noqa: E731

        def kind(target, arg, scale):
            if arg is not AUTO:
                return get(arg)
            blocks = [b for b in layout.blocks if getattr(b, "feeds", None) == target]
            if not blocks:
                return None
            if len(blocks) == 1 and blocks[0].axes == "xyz":
                return layout.slice(blocks[0].name)
            if scale:
                raise ValueError(f"{target} feedback needs one 3-axis block, the layout has "
                                 f"{[(b.name, b.axes) for b in blocks]}")
            # rows: one per block; column a holds the state of axis a, or n (a zero pad)
            idx = np.full((len(blocks), 3), layout.n, dtype=np.int64)
            for r, b in enumerate(blocks):
                sl = layout.slice(b.name)
                for i, a in enumerate(b.axes):
                    idx[r, "xyz".index(a)] = sl.start + i
            return idx

        return cls(get(att), get(vel), get(pos), kind("gyro_bias", gyro, False),
                   kind("accel_bias", accel, False),
                   tuple(layout.slice(o) for o in other),
                   kind("gyro_scale", gyro_scale, True), kind("accel_scale", accel_scale, True))

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
        sd.correct(state, *self.nav_errors(d))
        gb = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, dtype=float).copy()
        ab = np.zeros(3) if accel_bias is None else np.asarray(accel_bias, dtype=float).copy()
        if self.gyro is not None:
            gb = gb + _sum3(d, self.gyro)
        if self.accel is not None:
            ab = ab + _sum3(d, self.accel)
        return gb, ab, d
