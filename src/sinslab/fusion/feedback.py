"""Closed-loop correction of an INS from an error-state filter: which states are fed back
and how they correct the strapdown state and the sensor compensation.

:class:`FeedbackLayout` routes the fed-back blocks of an error state (named as in
:mod:`sinslab.nav.errstate`) to the navigation state (:func:`sinslab.nav.strapdown.correct`)
and to the INS compensation each sensor block declares it feeds (gyro/accelerometer
bias and scale factors); blocks that feed nothing stay with their measurements. The
filter itself (:class:`sinslab.estimation.filter.KalmanFilter`) only zeroes the fed-back
states and keeps their cumulative sum.
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


#: ``from_model`` keywords naming a compensation (:data:`sinslab.nav.errstate.COMPENSATIONS`)
_KEYWORDS = {"gyro": "gyro_bias", "accel": "accel_bias", "gyro_scale": "gyro_scale",
             "accel_scale": "accel_scale"}


@dataclass(frozen=True)
class FeedbackLayout:
    """Where the feedback-able blocks sit in an error-state vector.

    ``att``, ``vel``, ``pos`` are slices into the state vector, or None if the model has
    no such block: ``att`` (φ, rad, ENU), ``vel`` (δv, m/s, ENU; 2 states = east, north of
    a horizontal model), ``pos`` (δL, δλ [rad], δh [m]; 2 states = δL, δλ).
    ``compensation`` holds ``(key, entry)`` pairs, one per INS compensation some block
    feeds (its :attr:`sinslab.nav.errstate.Block.feeds`, e.g. ``"gyro_bias"`` [rad/s],
    ``"accel_bias"`` [m/s²], ``"gyro_scale"``, ``"accel_scale"`` [-]); an entry is a
    slice of one 3-axis block or an int array (k, 3) of k blocks whose column a holds the
    state of body axis a (n: the block has no such axis), their estimates adding up.
    ``other`` blocks are zeroed on feedback. Blocks that feed nothing (a receiver clock,
    a barometer bias, a lever arm) stay in the filter, read by their measurements.
    Used by callers of :meth:`sinslab.estimation.filter.KalmanFilter.feedback` to route
    the estimate.
    """

    att: object = None
    vel: object = None
    pos: object = None
    compensation: tuple = ()
    other: tuple = ()

    def target(self, key):
        """The entry of compensation ``key`` (None: no block feeds it)."""
        return dict(self.compensation).get(key)

    # the four compensations of a strapdown INS, by their short names
    gyro = property(lambda self: self.target("gyro_bias"))
    accel = property(lambda self: self.target("accel_bias"))
    gyro_scale = property(lambda self: self.target("gyro_scale"))
    accel_scale = property(lambda self: self.target("accel_scale"))

    def indices(self, n):
        """All fed-back state indices, sorted, as a read-only int array."""
        cache = self.__dict__.setdefault("_indices", {})   # asked at every feedback
        if n not in cache:
            out = []
            for s in (self.att, self.vel, self.pos, *(e for _, e in self.compensation), *self.other):
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

    @classmethod
    def from_model(cls, layout, *, att="phi", vel="dv", pos="dp", gyro=AUTO, accel=AUTO,
                   gyro_scale=AUTO, accel_scale=AUTO, other=()):
        """From a :class:`sinslab.nav.errstate.StateLayout`: the layout follows the model.

        Every compensation some block feeds gets an entry, found by what the blocks *are*
        (their :attr:`Block.feeds`), not by name: every body-axis gyro bias or Gauss–Markov
        block feeds the gyro bias compensation (several blocks add up, an axis subset
        feeds only its axes), likewise accelerometer biases and the scale-factor blocks.
        ``gyro``, ``accel``, ``gyro_scale``, ``accel_scale``: ``AUTO`` (that default), a
        block name (str) to feed from that one block instead (missing: none), or None to
        feed nothing.
        """
        names = [b.name for b in layout.blocks]
        get = lambda b: layout.slice(b) if (b is not None and b in names) else None  # noqa: E731
        choice = {_KEYWORDS[k]: v for k, v in (("gyro", gyro), ("accel", accel),
                                               ("gyro_scale", gyro_scale), ("accel_scale", accel_scale))}
        comp = []
        keys = [b.feeds for b in layout.blocks if getattr(b, "feeds", None)]
        keys += [k for k, v in choice.items() if isinstance(v, str)]      # a block named outright
        for key in dict.fromkeys(keys):
            arg = choice.get(key, AUTO)
            entry = get(arg) if arg is not AUTO else _entry(layout, [b for b in layout.blocks
                                                                     if b.feeds == key])
            if entry is not None:
                comp.append((key, entry))
        return cls(get(att), get(vel), get(pos), tuple(comp), tuple(layout.slice(o) for o in other))

    def apply(self, filt, state, compensation):
        """Closed-loop correction: feed the filter's estimate back into the INS.

        Takes the fed-back states out of ``filt`` (:meth:`KalmanFilter.feedback`, which
        zeroes them), corrects the strapdown state array in place with
        :func:`sinslab.nav.strapdown.correct` (φ [rad], δv [m/s], δp = [δL, δλ, δh]; the
        vertical of a 2-state horizontal block is left alone) and adds each compensation
        estimate to the INS's compensation of that key.

        Parameters
        ----------
        filt : sinslab.estimation.filter.KalmanFilter
        state : ndarray, shape (NSTATE,) or (10,)
            Strapdown state array (modified in place).
        compensation : dict
            The INS's compensation in use, ``{key: ndarray (3,)}`` (bias [rad/s], [m/s²],
            scale factors [-]); it must hold every key of the layout.

        Returns
        -------
        compensation : dict
            The new compensation (a new dict of new arrays; keys the layout does not feed
            are passed on as they are).
        d : ndarray, shape (n,)
            The fed-back amounts.

        Raises
        ------
        ValueError
            The INS has no compensation a block of the layout feeds.
        """
        missing = [k for k, _ in self.compensation if k not in compensation]
        if missing:
            raise ValueError(f"the INS has no {missing[0]} compensation for the blocks that feed it "
                             f"(it has {sorted(compensation)})")
        idx = self.indices(filt.n)
        d = filt.feedback(None if idx.size == filt.n else idx)       # sorted, once each: all states
        sd.correct(state, *self.nav_errors(d))
        out = dict(compensation)
        for key, entry in self.compensation:
            out[key] = np.asarray(compensation[key], dtype=float) + _sum3(d, entry)
        return out, d


def _entry(layout, blocks):
    """The compensation entry of the blocks feeding one compensation: the slice of a lone
    3-axis block (plain arithmetic), else padded rows (one per block; column a holds the
    state of axis a, or n, a zero pad)."""
    if not blocks:
        return None
    if len(blocks) == 1 and blocks[0].axes == "xyz":
        return layout.slice(blocks[0].name)
    idx = np.full((len(blocks), 3), layout.n, dtype=np.int64)
    for r, b in enumerate(blocks):
        sl = layout.slice(b.name)
        for i, a in enumerate(b.axes):
            idx[r, "xyz".index(a)] = sl.start + i
    return idx
