"""Robust weighting of fixes (:class:`sinslab.fusion.measurements.schedule.RobustWeighting`,
shared by the filter and the factor graph) and the graph's frame conversions (no GTSAM needed).

* Huber and IGG-III row weights are their closed forms (Yang, Song & Xu 2002); Chang's rule
  through the weighting is :func:`robust_R` (Chang 2014).
* The frame conversions of :mod:`sinslab.fusion.graph.frame` are exact round trips; normal
  gravity 10 km east of the origin is tilted by d/R.
"""
import math

import numpy as np
import pytest

from sinslab.core import earth as E
from sinslab.fusion.measurements.base import Epoch
from sinslab.fusion.measurements.schedule import RobustWeighting, robust_R, robust_weighting
from sinslab.fusion.spec import FixSpec


# ------------------------------------------------------------------ robust weighting
def test_huber_and_igg3_row_weights_are_their_closed_forms():
    h = RobustWeighting("huber", k0=1.5)
    v = np.array([0.3, -1.5, 3.0, -6.0])
    assert np.allclose(h.row_weights(v), [1, 1, 0.5, 0.25])
    g = RobustWeighting("igg3", k0=1.0, k1=4.0)
    w = g.row_weights(np.array([0.5, 2.0, -3.0, 4.5]))
    assert w[0] == 1.0
    assert w[1] == pytest.approx(0.5 * (2.0 / 3.0) ** 2) and w[2] == pytest.approx((1 / 3) * (1 / 3) ** 2)
    assert w[3] < 1e-9                                                  # rejected past k1
    # weigh(): standardised by √S_ii of the prior, rows inflated by 1/w
    P = np.diag([1.0, 1.0])
    ep = Epoch(0.0, 0, (), None, 2, 0, (np.zeros(2), P))
    R, f = h.weigh(ep, np.array([0.5, 6.0]), np.eye(2), np.array([1.0, 1.0]))     # ṽ = 0.35, 4.24
    assert R[0] == 1.0 and R[1] == pytest.approx(6.0 / math.sqrt(2) / 1.5) and f == pytest.approx(R[1])
    assert h.weigh(Epoch(0.0, 0, (), None, 2, 0, None), np.array([9.0, 9.0]), np.eye(2), [1.0, 1.0])[1] == 1.0
    c = robust_weighting(0.01)
    z = np.array([4.0, 3.0])
    Hc = np.eye(2)
    Pc = np.diag([0.5, 0.5])
    epc = Epoch(0.0, 0, (), None, 2, 0, (np.zeros(2), Pc))
    assert c.kind == "chang" and np.allclose(c.weigh(epc, z, Hc, [0.5, 0.5])[0], robust_R(epc, z, Hc, [0.5, 0.5], 0.01)[0])


def test_robust_weighting_text_and_refusals():
    assert robust_weighting("huber:2") == RobustWeighting("huber", 0.01, 2.0)
    assert robust_weighting("igg3:1.5:4") == RobustWeighting("igg3", 0.01, 1.5, 4.0)
    assert robust_weighting(None) is None
    fx = FixSpec([1.0], [[0.7, 0.2, 10.0]], [1.0, 1.0, 2.0], robust="igg3")
    assert fx.robust.kind == "igg3"
    for bad in ("tukey", "huber:x", "igg3:3:1"):
        with pytest.raises(ValueError):
            robust_weighting(bad)


# ------------------------------------------------------------------ frame and translation
def test_local_frame_round_trip_and_gravity_tilt():
    from sinslab.fusion.graph.frame import LocalFrame
    fr = LocalFrame(math.radians(32), math.radians(118), 50.0)
    rng = np.random.default_rng(3)
    q = rng.normal(size=(5, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    rows = np.column_stack([q, rng.normal(0, 10, (5, 3)), math.radians(32) + rng.normal(0, 1e-3, 5),
                            math.radians(118) + rng.normal(0, 1e-3, 5), 50 + rng.normal(0, 30, 5)])
    back = fr.rows_from_w(*fr.rows_to_w(rows))
    qs = np.sign(np.sum(back[:, :4] * rows[:, :4], 1))[:, None]
    assert np.allclose(back[:, :4] * qs, rows[:, :4], atol=1e-12)
    assert np.allclose(back[:, 4:7], rows[:, 4:7], atol=1e-10) and np.allclose(back[:, 9], rows[:, 9], atol=1e-6)
    assert np.allclose(back[:, 7:9], rows[:, 7:9], atol=1e-13)
    g0 = fr.gravity_w()
    g10 = fr.gravity_w(np.array([10e3, 0.0, 0.0]))
    tilt = math.acos(g0 @ g10 / np.linalg.norm(g0) / np.linalg.norm(g10))
    rn = float(E.radii(math.radians(32), 50.0)[1])
    assert tilt == pytest.approx(10e3 / rn, rel=1e-3)
