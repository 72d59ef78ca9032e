"""Stamp intervals and held streams (sinslab.core.stamps)."""
import numpy as np
import pytest

from sinslab.core import stamps as S


def test_step_and_tolerance_from_the_stamps_own_jitter():
    t = np.arange(100) * 1.000019
    dt, tol = S.stamp_step(t)
    assert dt == pytest.approx(1.000019, abs=1e-12) and tol == pytest.approx(1.000019e-6)
    # ±0.2 ms uniform jitter on 10 ms stamps: the intervals scatter by 0.16 ms (1σ), the
    # tolerance is 6 of those; ±2 ms jitter: capped at a quarter interval
    rng = np.random.default_rng(0)
    dt, tol = S.stamp_step(np.arange(2000) * 0.01 + rng.uniform(-2e-4, 2e-4, 2000))
    assert dt == pytest.approx(0.01, abs=2e-5) and 0.6e-3 < tol < 1.4e-3
    dt, tol = S.stamp_step(np.arange(2000) * 0.01 + rng.uniform(-2e-3, 2e-3, 2000))
    assert tol == pytest.approx(0.25 * dt)
    n, dt, tol = S.whole_intervals(np.arange(10) * 0.25, 1.0)
    assert n == 4
    with pytest.raises(ValueError, match="at least 2"):
        S.stamp_step([1.0])


def test_held_runs_first_row_of_each_epoch():
    fix = np.arange(12, dtype=float).reshape(4, 3)            # 4 receiver epochs
    rows = np.repeat(fix, 50, axis=0)                         # held at 50 rows per epoch
    rows[60:, 2] = np.where(np.arange(140) >= 0, rows[60:, 2], 0)
    idx = S.held_runs(rows)
    assert idx.tolist() == [0, 50, 100, 150]
    rows[10, 0] = np.nan
    rows[11, 0] = np.nan                                      # equal NaNs are a repeat
    assert S.held_runs(rows).tolist() == [0, 10, 12, 50, 100, 150]
    assert S.held_runs(fix) is None                           # no repeats: not held
