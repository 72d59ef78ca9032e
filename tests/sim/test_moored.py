"""sim.moored: a carrier at rest on an indexing mount — the tiling of one cycle, the
error-free rows along the schedule, the block means of a noise record."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core import earth
from sinslab.sim import indexing as ix
from sinslab.sim import moored


@pytest.mark.parametrize("i0, L", [(0, 7), (3, 4), (5, 9), (12, 30), (6, 1)])
def test_tile_is_the_periodic_repetition(i0, L):
    """Rows i0 .. i0+L−1 of the periodic repetition equal a[(i0 + k) mod N], with and
    without a buffer for the wrapped case."""
    a = np.arange(21.0).reshape(7, 3)
    want = a[(i0 + np.arange(L)) % 7]
    np.testing.assert_array_equal(moored.tile(a, i0, L), want)
    np.testing.assert_array_equal(moored.tile(a, i0, L, out=np.empty((40, 3))), want)


def test_truth_rows_at_rest():
    """Error-free rows of a moored carrier: the attitude is the mount's, the velocity zero,
    the position fixed; the body rates are the Earth rate (norm Ω) and the specific force
    is normal gravity (norm g), rotated into the body by the mount (their dot product
    g Ω sin L is the same at every stop)."""
    lat, lon = math.radians(28.222), math.radians(112.993)
    m = ix.scheme("dual_axis_16", rate=math.radians(9.0), dwell=30.0, ramp=1.0)
    t = np.linspace(0.0, m.cycle_time, 301)
    rows, w, f = moored.truth_rows(m, t, lat, lon)
    ang, _ = ix.mount_angles(m, t)
    np.testing.assert_allclose(rows[:, :4], A.euler_to_quat(ang), atol=0)
    assert np.all(rows[:, 4:7] == 0.0) and np.all(rows[:, 7] == lat) and np.all(rows[:, 8] == lon)
    g = float(earth.gravity(lat, 0.0))
    np.testing.assert_allclose(np.linalg.norm(w, axis=1), earth.WIE, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), g, rtol=1e-12)
    np.testing.assert_allclose(np.einsum("ki,ki->k", w, f), g * earth.WIE * math.sin(lat), rtol=1e-12)


def test_scheme_builds_the_named_moves():
    """ix.scheme gives the same mount as the ready-made builders, and the one-axis flips."""
    r = math.radians(9.0)
    assert ix.scheme("single_axis_4pos", rate=r, dwell=60.0) == ix.single_axis_4pos(rate=r, dwell=60.0)
    m = ix.scheme("roll_flip", rate=r, dwell=60.0, ramp=1.0)
    assert m.moves == (("roll", math.pi), ("roll", -math.pi)) and m.name == "roll_flip"


def test_block_means_removed():
    """INS #1's noise as paper 001 prepares it: the mean over every block is gone, the bias
    (kept) stays, a last short block has its own mean removed."""
    rng = np.random.default_rng(3)
    bias = np.array([1.0, -2.0, 3.0])
    x = bias + rng.standard_normal((25, 3))
    y = moored.remove_block_means(x.copy(), 10, bias)
    for a, b in ((0, 10), (10, 20), (20, 25)):
        np.testing.assert_allclose(y[a:b].mean(0), bias, atol=1e-12)
        np.testing.assert_allclose(y[a:b] - y[a:b].mean(0), x[a:b] - x[a:b].mean(0), atol=1e-12)
