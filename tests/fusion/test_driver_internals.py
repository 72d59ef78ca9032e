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
