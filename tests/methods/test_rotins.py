"""Oracles for sinslab.methods.rotins (Wang, Wu et al. 2018: joint rotation-modulated INS,
online evaluation).

- windowed_std (eq 21): against a direct per-window numpy evaluation, and against the
  closed form of a linear ramp (N samples spaced dt: slope·dt·sqrt((N²−1)/12), → the
  continuous slope·window/√12);
"""
from __future__ import annotations

import numpy as np
import pytest

from sinslab.methods import rotins


def test_windowed_std_matches_direct_evaluation():
    rng = np.random.default_rng(7)
    t = 10.0 + 0.5 * np.arange(2001)                      # 10 … 1010 s
    x = np.cumsum(rng.standard_normal((t.size, 2)), axis=0)
    start, window = 100.0, 150.0
    te, s = rotins.windowed_std(t, x, start, window)
    J = int((t[-1] - start) // window)
    assert te.size == J == 6
    for j in range(J):
        a, b = start + j * window, start + (j + 1) * window
        seg = x[(t >= a) & (t < b)]
        np.testing.assert_allclose(s[j], np.std(seg, axis=0), rtol=1e-13)
        assert te[j] == b
    _, s1 = rotins.windowed_std(t, x[:, 0], start, window)
    np.testing.assert_allclose(s1, s[:, 0], rtol=1e-13)


def test_windowed_std_linear_ramp_closed_form():
    """Ramp x = a t: std over N samples spaced dt is a·dt·sqrt((N²−1)/12) → a·window/√12."""
    dt, a = 1.0, 3e-9
    t = np.arange(0.0, 144 * 3600.0 + dt, dt)
    start, window = 16 * 3600.0, 4 * 3600.0
    te, s = rotins.windowed_std(t, a * t, start, window)
    N = window / dt
    assert te.size == 32
    np.testing.assert_allclose(s, a * dt * np.sqrt((N ** 2 - 1) / 12), rtol=1e-9)
    np.testing.assert_allclose(s, a * window / np.sqrt(12), rtol=1e-7)


@pytest.mark.parametrize("start, window, msg", [
    (0.0, 0.0, "window must be > 0"), (0.0, -1.0, "window must be > 0"),
    (100.0, 10.0, "start 100.0 s is not before"), (120.0, 10.0, "not before"),
    (50.0, 60.0, "longer than the 50.0 s"), (-100.0, 101.0, "longer than"),
])
def test_windowed_std_bad_input(start, window, msg):
    t = np.arange(101.0)
    with pytest.raises(ValueError, match=msg):
        rotins.windowed_std(t, t, start, window)
