"""The checks of time stamps and values screen by reductions (a sum, an extreme) before
looking element by element: they must decide as the element-wise tests do, at the
tolerance's edge and where a sum of finite values overflows."""
import numpy as np
import pytest

from sinslab.core.records import ImuRecord, check_times
from sinslab.data.increments import check_stamps, uniform_increments
from sinslab.data.tables import read_table_imu

COLS = "t=1[s],dtheta_x=2[rad],dtheta_y=3[rad],dtheta_z=4[rad],dv_x=5[m/s],dv_y=6[m/s],dv_z=7[m/s]"


def _stamps(rng, n, rel):
    """n stamps 5 ms apart moved by up to ±rel of an interval."""
    return 0.005 * np.arange(1, n + 1) + rng.uniform(-1, 1, n) * 0.005 * rel


def test_uniformity_screens_decide_as_the_elementwise_tests():
    """check_times: 'not uniformly sampled' iff some |d − mean| > 1e-3·mean; uniform_increments:
    the stamps kept iff every |d − median| <= 1e-4·median (else resampled), and its jitter
    sqrt(mean((d − median)²)) bit for bit — on stamps scattered about both bounds."""
    rng = np.random.default_rng(21)
    seen = set()
    for rel in np.repeat([2e-5, 5e-5, 1e-4, 4e-4, 5e-4, 1e-3], 40):
        t = _stamps(rng, int(rng.integers(3, 40)), rel)
        d = np.diff(t)
        mean = (t[-1] - t[0]) / (t.size - 1)
        bad = bool(np.any(np.abs(d - mean) > 1e-3 * mean))
        if bad:
            with pytest.raises(ValueError, match="not uniformly sampled"):
                check_times(t, "IMU time")
        else:
            assert check_times(t, "IMU time") == float(mean)
        med = float(np.median(d))
        keep = bool(np.all(np.abs(d - med) <= 1e-4 * med)) and \
            abs(t[-1] - t[0] - (t.size - 1) * med) <= 1e-9 * max(1.0, abs(t[-1]))
        z = np.zeros((t.size, 3))
        if keep and bad:
            continue                     # kept stamps that ImuRecord itself refuses: not a case here
        rec, gaps, jit = uniform_increments(t, z, z)
        assert jit == float(np.sqrt(np.mean((d - med) ** 2)))
        assert (rec.t.size == t.size and np.array_equal(rec.t, t)) == keep
        seen.add((bad, keep))
    assert {(False, True), (False, False), (True, False)} <= seen


def test_one_short_interval_is_found_by_the_minimum():
    """An interval short by 3e-4 of the median, four long by 0.75e-4 (the span kept):
    uniform_increments resamples; one short by 2e-3 of the mean among exact ones:
    check_times refuses — the deviation below is seen as well as the one above."""
    dt = 0.005
    dev = np.zeros(20)
    dev[5], dev[8:12] = -3e-4, 0.75e-4
    t = dt * np.arange(1, 22) + np.concatenate([[0.0], np.cumsum(dev * dt)])
    z = np.zeros((t.size, 3))
    rec, _, jit = uniform_increments(t, z, z)
    assert not np.array_equal(rec.t, t)
    assert jit == float(np.sqrt(np.mean((np.diff(t) - np.median(np.diff(t))) ** 2)))
    t = dt * np.arange(1, 101)
    t[50:] -= 2e-3 * dt
    with pytest.raises(ValueError, match="not uniformly sampled: interval 0.00498.* at index 50"):
        check_times(t, "IMU time")


def test_huge_finite_values_pass_and_nan_is_found(tmp_path):
    """Values near the largest double (their sums would overflow) pass without a warning;
    a NaN or an infinity among them is found at its line."""
    big = np.finfo(float).max / 2
    t = 0.005 * np.arange(1, 11)
    dth = np.full((10, 3), big)
    rec = ImuRecord(t, dth, -dth)
    assert np.array_equal(rec.dtheta, dth)
    check_stamps(np.array([-big, 0.0, big]), "x", [1, 2, 3])
    assert check_times(np.array([-big, 0.0, big]), uniform=False) == big
    rows = [[f"{x:.3f}"] + [repr(float(big))] * 6 for x in t]
    p = tmp_path / "big.txt"
    p.write_text("".join(" ".join(r) + "\n" for r in rows))
    imu = read_table_imu(p, columns=COLS).imu
    assert np.array_equal(imu.dtheta, dth) and np.array_equal(imu.dv, dth)
    rows[6][3] = "nan"
    p.write_text("".join(" ".join(r) + "\n" for r in rows))
    with pytest.raises(ValueError, match=r"big\.txt:7: NaN/inf or empty value in column '#4'"):
        read_table_imu(p, columns=COLS)
    rows[6][3] = rows[6][2]
    rows[4][0] = "inf"
    p.write_text("".join(" ".join(r) + "\n" for r in rows))
    with pytest.raises(ValueError, match=r"big\.txt:5: NaN/inf or empty value in column '#1'"):
        read_table_imu(p, columns=COLS)
