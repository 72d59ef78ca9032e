"""The compiled pass of :class:`sinslab.experiments.rotation_evaluation.ChunkTrends` (its own
module: the experiment's configuration is read without importing numba)."""
from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True)
def add_trend(dth, s, k_of, ramp, ea, decay, sa, wave, dt):
    """``dth[:, a] += (ramp[k]·s + (ea[k]·decay[:, k] if ea[k] ≠ 0 else 0) + sa[k]·wave[:, k])·dt``
    for the axes ``a`` with a trend term (``k = k_of[a] ≥ 0``), ``+= 0`` for the others: the
    operations of :meth:`sinslab.sim.imu.Trend.evaluate` in its order, sample by sample
    (no fused multiply-add: the same bits). ``wave`` of one row: the same at every sample."""
    step = 1 if wave.shape[0] > 1 else 0
    for i in range(dth.shape[0]):
        for a in range(3):
            k = k_of[a]
            if k < 0:
                dth[i, a] += 0.0
            else:
                e = ea[k] * decay[i, k] if ea[k] != 0 else 0.0
                dth[i, a] += (ramp[k] * s[i] + e + sa[k] * wave[i * step, k]) * dt
