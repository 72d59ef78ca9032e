"""The difference of two INS streams' navigation outputs (:class:`InsDifference`)."""
from __future__ import annotations

import math

import numpy as np

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.fusion.measurements.base import Epoch
from sinslab.fusion.measurements.jacobians import add_rate_H
from sinslab.fusion.measurements.schedule import Timed

__all__ = ["InsDifference"]


class InsDifference(Timed):
    """The difference of two INS streams on one carrier (stream 0 minus stream 1).

    ``z = [L1 − Lk, λ1 − λk, vE1 − vEk, vN1 − vNk]`` [rad, rad, m/s, m/s] against a
    :class:`sinslab.nav.errstate.DifferenceModel` layout: ``H`` picks ``[δL, δλ]_1k`` of the
    ``dp`` block and ``[δvE, δvN]_1k`` of the ``dv`` block (the differences of the two
    INS errors, computed − true, are the differences of their outputs since both see the
    same carrier). A lever arm ``l`` from IMU 1 to IMU k (body axes of IMU 1) is removed:
    the position of IMU k is shifted back by ``C_b1^n l`` and its velocity by
    ``C_b1^n (ω_ib1^b × l)``; the resulting φ terms (first order) go into H on the
    ``phi`` block (``∂z/∂φ_1``, exact for the difference core whose φ block is ``φ_1 − φ_k``
    only when IMU k's attitude error equals IMU 1's; give ``lever_arm=None`` when the
    IMUs are co-located), and ``−C_b1^n (l×) ∂δω_1/∂x`` on the velocity rows of every
    block feeding INS 1's gyro compensation (:func:`add_rate_H`; INS 1's blocks are those
    named with ``suffix``).

    Parameters
    ----------
    t : array_like, shape (J,)
        Times [s] at which the difference is formed (filter epochs, available at once).
    sigma : array_like, shape (4,) or (J, 4)
        Standard deviations [rad, rad, m/s, m/s].
    lever_arm : array_like (3,), optional
        IMU 1 -> IMU k in IMU 1 body axes [m].
    streams : (int, int)
        The two streams (default 0 and 1).
    windows : sequence of (start, end) [s], optional
        Form the difference only at epochs inside these windows.
    suffix : str
        Ending of the names of INS 1's sensor blocks in the layout (the first of
        :class:`sinslab.nav.errstate.DifferenceModel`'s ``suffixes``).
    """

    def __init__(self, t, sigma, *, lever_arm=None, streams=(0, 1), windows=None, suffix="_1"):
        self._init_times(t, None, (), windows)
        J = self.t_valid.size
        self.sigma = np.broadcast_to(np.asarray(sigma, dtype=float), (J, 4))
        lever = None if lever_arm is None else np.asarray(lever_arm, dtype=float).reshape(3)
        self.lever = None if (lever is None or not np.any(lever)) else lever
        self.streams = tuple(int(s) for s in streams)
        self.suffix = str(suffix)

    def matrices(self, ep: Epoch):
        j = ep.item
        lay = ep.layout
        a, b = (ep.streams[i] for i in self.streams)
        z = np.empty(4)
        H = np.zeros((4, ep.n))
        lat_k, lon_k = b.lat, b.lon
        vk = b.vel[:2]
        if self.lever is not None:
            C1 = a.C_bn
            d = C1 @ self.lever                        # IMU 1 -> IMU k, ENU [m]
            rm, rn = E.radii(a.lat, a.h)
            rm, rnc = float(rm), float(rn) * math.cos(a.lat)
            lat_k = lat_k - d[1] / rm
            lon_k = lon_k - d[0] / rnc
            vlev = C1 @ np.cross(a.omega_b, self.lever)
            vk = vk - vlev[:2]
            # the lever is removed with the computed attitude, d' = (I − φ×) d, so z
            # gains −φ×d = (d×) φ (north, east of position; likewise of velocity)
            H[0, lay.slice("phi")] = A.skew(d)[1] / rm
            H[1, lay.slice("phi")] = A.skew(d)[0] / rnc
            H[2:4, lay.slice("phi")] = A.skew(vlev)[0:2]
            add_rate_H(H[2:4], lay, (-C1 @ A.skew(self.lever))[0:2], a.omega_b, self.suffix)
        z[0] = a.lat - lat_k
        z[1] = A.wrap_pi(a.lon - lon_k)
        z[2:4] = a.vel[:2] - vk
        sp, sv = lay.slice("dp"), lay.slice("dv")
        H[0, sp.start] = 1.0
        H[1, sp.start + 1] = 1.0
        H[2, sv.start] = 1.0
        H[3, sv.start + 1] = 1.0
        return z, H, self.sigma[j] ** 2


# ------------------------------------------------------------------ aiding measurements
