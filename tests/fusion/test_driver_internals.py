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


def test_streams_on_one_imu_record_share_its_step_sums_while_it_lives():
    """Filters on one IMU record (a run's competing filters) bind to the sums made once:
    numpy's sums of that record from the stream's first sample, read-only; another record,
    another start or another step gets its own, and the entry leaves with its record."""
    import gc

    from sinslab.core.records import ImuRecord
    from sinslab.fusion import driver

    rng = np.random.default_rng(3)
    N, dt = 1000, 0.01
    imu = ImuRecord(dt * np.arange(1, N + 1), rng.standard_normal((N, 3)) * 1e-4,
                    rng.standard_normal((N, 3)) * 1e-2, dt)
    a = driver._imu_step_sums(imu, 0, 49, 20)
    b = driver._imu_step_sums(imu, 0, 49, 20)
    assert a[0] is b[0] and a[1] is b[1]
    assert np.array_equal(a[0], imu.dtheta[:980].reshape(49, 20, 3).sum(1))
    assert np.array_equal(a[1], imu.dv[:980].reshape(49, 20, 3).sum(1))
    assert not a[0].flags.writeable
    c = driver._imu_step_sums(imu, 10, 49, 20)
    assert np.array_equal(c[0], imu.dtheta[10:990].reshape(49, 20, 3).sum(1))
    other = ImuRecord(imu.t, imu.dtheta * 2.0, imu.dv, dt)
    assert np.array_equal(driver._imu_step_sums(other, 0, 49, 20)[0], 2.0 * a[0])
    keys = [k for k in driver._IMU_SUMS if k[0] in (id(imu), id(other))]
    assert len(keys) == 3
    del imu, other, a, b, c
    gc.collect()
    assert not any(k in driver._IMU_SUMS for k in keys)


def test_scale_record_is_one_array_whose_halves_are_the_scale_factors(tmp_path):
    """The (M, 6) scale record of a result is the array the driver wrote the gyro and
    accelerometer scale factors into (no copy), in memory and spilled to disk; two
    unrelated (M, 3) arrays are joined into a new one."""
    from sinslab.fusion.driver import _joined, _LaneRun, _Record
    from sinslab.nav import errstate as es

    for folder in (None, tmp_path / "spill"):
        rec = _LaneRun._comp_record(_Record(folder), es.COMPENSATIONS, 0, 5)
        rec["gyro_scale"][:] = 1.0
        rec["accel_scale"][:] = 2.0
        both = _joined(rec["gyro_scale"], rec["accel_scale"])
        assert np.shares_memory(both, rec["gyro_scale"]) and both.shape == (5, 6)
        assert both[:, :3].tolist() == [[1.0] * 3] * 5 and both[:, 3:].tolist() == [[2.0] * 3] * 5
    a, b = np.ones((4, 3)), np.zeros((4, 3))
    j = _joined(a, b)
    assert not np.shares_memory(j, a) and j.tolist() == [[1.0] * 3 + [0.0] * 3] * 4
    w = np.arange(24.0).reshape(4, 6)
    assert not np.shares_memory(_joined(w[:, 3:], w[:, :3]), w)          # halves swapped: a copy



@pytest.mark.parametrize("comp_rows", [4096, 7])
def test_compensation_record_holds_the_compensation_in_use_after_each_epoch(monkeypatch, comp_rows):
    """The compensation record (written when feedback is about to change it, every
    ``COMP_ROWS`` rows and at the end) holds at every epoch the compensation the stream used
    after that epoch: the initial one up to the first feedback, then the one each feedback
    left, bit for bit with the stream's own arrays (scale factors too); a run without
    feedback keeps its initial compensation in every row."""
    from sinslab.core import units as u
    from sinslab.core.records import NavState
    from sinslab.fusion import driver
    from sinslab.fusion.feedback import FeedbackLayout
    from sinslab.fusion.loosely_coupled import lc_model
    from sinslab.fusion.measurements import PositionFix
    from sinslab.fusion.spec import FilterGrid
    from support import static_imu

    monkeypatch.setattr(driver, "COMP_ROWS", comp_rows)
    dt, n = 0.01, 1200
    imu = static_imu(0.6, np.array([0.01, -0.02, 0.5]), dt, n, gyro_err=(2e-5, -1e-5, 3e-5),
                     accel_err=(3e-3, -2e-3, 1e-3))
    init = NavState(0.6, 1.0, 0.0, np.zeros(3), np.array([0.01, -0.02, 0.5]), imu.t0)
    model = lc_model(0.02 * u.dpsh, 20 * u.ugpsHz, scale_factors=True)
    P0 = np.diag(np.r_[[1e-6] * 3, [0.01] * 3, 1e-12, 1e-12, 1.0, [1e-9] * 3, [1e-5] * 3, [1e-8] * 6])
    tf = imu.t0 + np.arange(1, 12) * 1.0
    fix = PositionFix(tf, np.tile([0.6, 1.0, 0.0], (tf.size, 1)), [1.0, 1.0, 2.0])
    after = []
    feedback = driver.LiveStream.feedback

    def recorded(self, filt, layout):
        d = feedback(self, filt, layout)
        after.append({k: v.copy() for k, v in self.compensation.items()})
        return d
    monkeypatch.setattr(driver.LiveStream, "feedback", recorded)
    grid = FilterGrid(0.05)
    stream = driver.LiveStream(imu, init, nsub=1, scaled=True)
    res = driver.run([stream], model, P0, [fix], grid=grid, feedback=FeedbackLayout.from_model(model.layout))
    comp, M = res.compensation[0], res.t.size
    epochs = np.searchsorted(res.t, res.applied.t_applied).tolist()
    assert len(after) == len(epochs) > 3 and M > 10 * comp_rows or comp_rows > M
    assert set(comp) == {"gyro_bias", "accel_bias", "gyro_scale", "accel_scale"}
    for key in comp:
        want = np.empty((M, 3))
        want[:epochs[0]] = 0.0
        for e, nxt, c in zip(epochs, epochs[1:] + [M], after):
            want[e:nxt] = c[key]
        assert np.array_equal(comp[key], want), key
        assert np.any(want != 0.0), key
    ab = np.array([1e-3, -2e-3, 3e-3])
    free = driver.run([driver.LiveStream(imu, init, nsub=1, accel_bias=ab)], model, P0, [fix], grid=grid)
    assert np.array_equal(free.compensation[0]["accel_bias"], np.broadcast_to(ab, (M, 3)))
