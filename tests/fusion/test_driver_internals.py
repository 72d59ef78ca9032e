"""Internals of the fusion driver that must not move numbers."""
import numpy as np
import pytest

from sinslab.fusion.driver import _step_sums


@pytest.mark.parametrize("k", [1, 2, 3, 20, 100, 200])
def test_step_sums_are_numpys_sums_bit_for_bit(k):
    """The per-step increment sums equal ``reshape(n, k, 3).sum(1)`` exactly (same
    additions, same order), so filter inputs do not change in the last bit."""
    rng = np.random.default_rng(k)
    x = rng.standard_normal((57 * k, 3)) * 10.0 ** rng.integers(-8, 2, (57 * k, 3))
    assert np.array_equal(_step_sums(x, 57, k), x.reshape(57, k, 3).sum(1))


@pytest.mark.parametrize("k", [1, 2, 20])
def test_scaled_increments_are_the_numpy_expressions_bit_for_bit(k):
    """The compiled scale-corrected increments and step rates equal the numpy expressions
    ``(dth * (1 − kg)).reshape(m, k, 3).sum(1) / T − gb`` exactly (no reordering, no fused
    multiply-add), so a run with scale-factor states keeps its numbers."""
    from sinslab.fusion.driver import _scaled_increments

    rng = np.random.default_rng(k + 10)
    m = 13
    dth = rng.standard_normal((m * k, 3)) * 1e-3
    dv = rng.standard_normal((m * k, 3)) * 1e-2 + [0.0, 0.0, 0.049]
    kg, ka = rng.standard_normal(3) * 1e-4, rng.standard_normal(3) * 1e-4
    gb, ab = rng.standard_normal(3) * 1e-6, rng.standard_normal(3) * 1e-3
    T = k * 0.005
    out = [np.empty((m * k, 3)), np.empty((m * k, 3)), np.empty((m, 3)), np.empty((m, 3))]
    _scaled_increments(dth, dv, kg, ka, gb, ab, k, T, *out)
    dth_s, dv_s = dth * (1.0 - kg), dv * (1.0 - ka)
    ref = [dth_s, dv_s, dth_s.reshape(m, k, 3).sum(1) / T - gb, dv_s.reshape(m, k, 3).sum(1) / T - ab]
    for got, want in zip(out, ref):
        assert np.array_equal(got, want)
