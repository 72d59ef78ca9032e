"""Oracles for the run axis of the fusion driver (sinslab.fusion.driver.run_many and the
compositions on it): the runs of a campaign stepped in lockstep give, lane by lane, the
bytes of :func:`sinslab.fusion.driver.run` on that run alone — closed loop or feed-forward,
one stream or two, with the fused compiled prediction, with a history for lagged fixes
(exact re-processing, paper 003's stored-state update), with scale-factor feedback.
"""
import numpy as np
import pytest

from sinslab.core import units as u
from sinslab.core.records import NavState
from sinslab.fusion import driver
from sinslab.fusion.feedback import FeedbackLayout
from sinslab.fusion.lag import ExactReprocessing, OnArrival
from sinslab.fusion.loosely_coupled import lc_model, loosely_coupled, loosely_coupled_many
from sinslab.fusion.measurements import InsDifference, PositionFix
from sinslab.fusion.spec import FilterGrid, FixSpec
from sinslab.methods.rotins import joint_rotation_model


def _flight(duration=90.0, rate=50.0):
    from sinslab.sim import trajectory as tr
    segs = [tr.Level(duration=20.0), tr.Turn(duration=40.0, rate=2 * u.deg), tr.Level(duration=30.0)]
    start = tr.Start(lat=32 * u.deg, lon=118 * u.deg, h=500.0, speed=100.0, heading=30.0)
    return tr.generate(segs, start, 1.0 / rate, duration=duration)


def _run_data(gen, seed):
    """One run's IMU record (own noise and biases) and initial state (own errors)."""
    from sinslab.sim import imu as imu_mod
    rng = np.random.default_rng(seed)
    err = imu_mod.ImuErrors(gyro_bias=rng.normal(0, 0.3 * u.dph, 3), gyro_arw=0.02 * u.dpsh,
                            accel_bias=rng.normal(0, 100 * u.ug, 3), accel_vrw=20 * u.ugpsHz)
    meas = imu_mod.apply(gen.imu, err, rng)
    tru = gen.truth
    d = rng.normal(0, 1, 5)
    init = NavState(tru.lat[0] + d[0] * 1e-6, tru.lon[0] + d[1] * 1e-6, tru.h[0],
                    tru.vel[0] + [0.1 * d[2], -0.1 * d[3], 0.0],
                    tru.att[0] + np.array([1, 1, 5]) * d[4] * u.arcmin, tru.t[0])
    return meas, init


def _fixes(tru, seed, every=50, latency=1.0):
    """Position fixes on one request plan (same times for every run), own noise."""
    rng = np.random.default_rng(100 + seed)
    idx = np.arange(every, tru.t.size - every, every)
    pos = np.stack([tru.lat[idx] + rng.normal(0, 3e-7, idx.size),
                    tru.lon[idx] + rng.normal(0, 3e-7, idx.size), tru.h[idx] + rng.normal(0, 3, idx.size)], -1)
    return PositionFix(tru.t[idx], pos, [3.0, 3.0, 5.0], t_arrive=tru.t[idx] + latency)


def _P0(n):
    sd = np.r_[[2 * u.arcmin] * 2, 10 * u.arcmin, [0.2] * 3, 5 / 6.4e6, 5 / 5.4e6, 5.0,
               [1 * u.dph] * 3, [200 * u.ug] * 3, [1e-4] * (n - 15)]
    return np.diag(sd ** 2)


def _same(a, b):
    """Every array of two DriverResults equal, bit for bit."""
    assert np.array_equal(a.t, b.t)
    for x, y in zip(a.nav, b.nav):
        assert np.array_equal(x, y)
    assert np.array_equal(a.x, b.x) and np.array_equal(a.sigma, b.sigma)
    for xs, ys in ((a.gyro_bias, b.gyro_bias), (a.accel_bias, b.accel_bias)):
        for x, y in zip(xs, ys):
            assert (x is None and y is None) or np.array_equal(x, y)
    assert (a.scale is None) == (b.scale is None)
    if a.scale is not None:
        for x, y in zip(a.scale, b.scale):
            assert np.array_equal(x, y)
    for f in ("measurement", "item", "t_valid", "t_applied", "nis"):
        assert np.array_equal(getattr(a.applied, f), getattr(b.applied, f)), f
    for x, y in zip(a.applied.innovation, b.applied.innovation):
        assert np.array_equal(x, y, equal_nan=True)


@pytest.mark.parametrize("case", ["on-arrival, fused", "exact lag, history", "scale factors",
                                  "feed-forward, numpy model"])
def test_lanes_equal_runs_alone_bit_for_bit(case):
    """run_many over three runs = run on each run alone (the fused compiled loop over lanes,
    the model of all lanes evaluated in one call when a history is kept, the numpy
    reference path)."""
    gen = _flight()
    scale = case == "scale factors"
    model = lc_model(0.02 * u.dpsh, 20 * u.ugpsHz, scale_factors=scale)
    P0 = _P0(model.n)
    fb = None if case.startswith("feed-forward") else FeedbackLayout.from_model(model.layout)
    lag = OnArrival() if case in ("on-arrival, fused", "scale factors") else None
    kw = dict(grid=FilterGrid(0.2, max_block=7.0, model_every=3.0,
                              model_eval="numpy" if "numpy" in case else "compiled"), feedback=fb, lag=lag)
    data = [_run_data(gen, s) for s in range(3)]

    def lane(s):
        meas, init = data[s]
        return driver.Lane((driver.LiveStream(meas, init, nsub=2, scaled=scale),), (_fixes(gen.truth, s),),
                           None)

    many = driver.run_many([lane(s) for s in range(3)], model, P0, **kw)
    for s in range(3):
        ln = lane(s)
        alone = driver.run(list(ln.streams), model, P0, list(ln.measurements), **kw)
        assert alone.applied.item.size > 10
        _same(many[s], alone)
    # the runs differ: the lanes did not share a filter
    assert not np.array_equal(many[0].nav[0], many[1].nav[0])


def test_two_stream_lanes_equal_runs_alone():
    """Lanes of two streams each (the joint difference model of paper 001, feed-forward,
    on-time INS-difference measurements): the fused loop with k = 2 streams per lane."""
    gen = _flight(duration=40.0)
    m = joint_rotation_model(1e-6, 1e-6, 1e-5, 1e-5)
    sd = np.r_[[1e-5] * 2, [1.0] * 2, [10 * u.arcmin] * 3, [1 * u.dph] * 6, [300 * u.ug] * 4]
    P0 = np.diag(sd ** 2)
    h = np.full(len(gen.imu) + 1, gen.truth.h[0])
    t = 1.0 + np.arange(38)

    def lane(s):
        meas, init = _run_data(gen, s)
        init2 = NavState(init.lat + 2e-6, init.lon - 1e-6, init.h, init.vel + [0.3, -0.2, 0.0],
                         init.att + np.array([-2, 1, 3]) * u.arcmin, init.t)
        return driver.Lane((driver.LiveStream(meas, init, vertical="hold", height=h),
                            driver.LiveStream(meas, init2, vertical="hold", height=h)),
                           (InsDifference(t, [1e-8, 1e-8, 0.01, 0.01]),))

    many = driver.run_many([lane(s) for s in range(2)], m, P0, grid=FilterGrid(1.0, model_every=0.0))
    for s in range(2):
        ln = lane(s)
        _same(many[s], driver.run(list(ln.streams), m, P0, list(ln.measurements),
                                  grid=FilterGrid(1.0, model_every=0.0)))


def test_loosely_coupled_many_equals_loosely_coupled():
    """The composition on the run axis: each run's LooselyCoupled equals the one-run call."""
    gen = _flight(duration=60.0)
    tru = gen.truth
    model = lc_model(0.02 * u.dpsh, 20 * u.ugpsHz)
    idx = np.arange(50, tru.t.size - 100, 50)
    runs = []
    for s in range(3):
        meas, init = _run_data(gen, s)
        rng = np.random.default_rng(s)
        pos = np.stack([tru.lat[idx], tru.lon[idx], tru.h[idx]], -1) + rng.normal(0, 1, (idx.size, 3)) * [3e-7, 3e-7, 3]
        runs.append((meas, init, FixSpec(tru.t[idx], pos, [3.0, 3.0, 5.0], latency=0.6)))
    shared = dict(lag=ExactReprocessing(), grid=FilterGrid(0.2, max_block=5.0))
    many = loosely_coupled_many(runs, _P0(15), model, **shared)
    for r, got in zip(runs, many):
        one = loosely_coupled(*r, _P0(15), model, progress=False, **shared)
        for f in ("t", "nav", "x", "sigma", "gyro_bias", "accel_bias", "fix_t", "t_applied", "innovation", "nis"):
            assert np.array_equal(getattr(got, f), getattr(one, f)), f
    with pytest.raises(ValueError, match="give \\(imu, init, fixes\\)"):
        loosely_coupled_many([runs[0][:2]], _P0(15), model, **shared)


def test_lanes_need_one_schedule_and_one_grid():
    """Lockstep needs the same block boundaries in every lane: other fix epochs or another
    grid are refused with the lane named."""
    gen = _flight(duration=40.0)
    model = lc_model(0.02 * u.dpsh, 20 * u.ugpsHz)
    meas, init = _run_data(gen, 0)
    a = driver.Lane((driver.LiveStream(meas, init),), (_fixes(gen.truth, 0, every=50),))
    b = driver.Lane((driver.LiveStream(meas, init),), (_fixes(gen.truth, 1, every=75),))
    with pytest.raises(ValueError, match="lane 1 receives measurements at other epochs"):
        driver.run_many([a, b], model, _P0(15), grid=FilterGrid(0.2))
    c = driver.Lane((driver.LiveStream(meas, init, start=10),), (_fixes(gen.truth, 0, every=50),))
    with pytest.raises(ValueError, match="lane 1 is on the filter grid"):
        driver.run_many([a, c], model, _P0(15), grid=FilterGrid(0.2))
    with pytest.raises(ValueError, match="at least one lane"):
        driver.run_many([], model, _P0(15), grid=FilterGrid(0.2))
