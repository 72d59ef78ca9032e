"""Lane-stacked mechanization against the one-INS compiled step (sinslab.nav.strapdown):
the same update on every lane, the lanes independent of each other, the sensor
compensation applied as the fusion driver's live streams apply it, and a lane that
leaves the valid latitudes stopped instead of raising."""
import numpy as np
import pytest

from sinslab.core.records import NavState
from sinslab.nav import strapdown as sd
from sinslab.nav.lanes import LaneBank


def _data(rng, nrec=2, n=400, dt=0.01):
    dth = rng.normal(0, 1e-3, (nrec, n, 3)) + np.array([0.0, 0.0, 1e-4])
    dv = rng.normal(0, 1e-3, (nrec, n, 3)) + np.array([0.0, 0.0, 9.8 * dt])
    return dth, dv


def _init(L):
    s = sd.initial_state_array(NavState(0.6, 1.9, 300.0, np.array([50.0, 120.0, 1.0]), np.array([0.02, -0.3, 0.8]), 0.0))
    return np.tile(s, (L, 1))


def test_every_lane_is_the_one_ins_step():
    rng = np.random.default_rng(1)
    dth, dv = _data(rng)
    comp = rng.normal(0, 1e-4, (3, 12))
    bank = LaneBank(_init(3), dth, dv, [0, 1, 0], 0.01, nsub=2)
    bank.comp[:] = comp
    for _ in range(4):                       # four blocks of 100 samples = one step over 400
        bank.advance(100)
    for lane, rec in enumerate([0, 1, 0]):
        s = _init(1)[0]
        c = comp[lane]
        sd.step(s, dth[rec] * (1.0 - c[6:9]), dv[rec] * (1.0 - c[9:12]), 0.01, 2, gyro_bias=c[0:3], accel_bias=c[3:6])
        np.testing.assert_array_equal(bank.state[lane], s)


def test_lanes_are_independent_and_corrections_follow_correct():
    rng = np.random.default_rng(2)
    dth, dv = _data(rng)
    one = LaneBank(_init(1), dth[:1], dv[:1], [0], 0.01)
    three = LaneBank(_init(3), dth, dv, [1, 0, 1], 0.01)
    phi = np.array([[1e-3, -2e-3, 5e-3]])
    dvel = np.array([[0.1, -0.2, 0.05]])
    for b, k in ((one, 0), (three, 1)):
        b.advance(200)
        p, d = np.zeros((b.lanes, 3)), np.zeros((b.lanes, 3))
        p[k], d[k] = phi[0], dvel[0]
        b.correct(p, d)
        b.compensate(gyro_bias=np.full((b.lanes, 3), 1e-5))
        b.advance(200)
    np.testing.assert_array_equal(three.state[1], one.state[0])
    s = _init(1)[0]
    sd.step(s, dth[0, :200], dv[0, :200], 0.01, 2)
    sd.correct(s, phi=phi[0], dvel=dvel[0])
    sd.step(s, dth[0, 200:], dv[0, 200:], 0.01, 2, gyro_bias=np.full(3, 1e-5))
    np.testing.assert_allclose(one.state[0, :10], s[:10], rtol=0, atol=1e-9)


def test_a_lane_leaving_the_latitudes_is_stopped_not_raised():
    rng = np.random.default_rng(3)
    dth, dv = _data(rng, nrec=1)
    init = _init(2)
    init[1, 7] = np.radians(88.99999)
    init[1, 5] = 5000.0                      # flying north fast across 89°
    bank = LaneBank(init, dth, dv, [0, 0], 0.01)
    bank.advance(400)
    assert bank.active.tolist() == [True, False]
    frozen = bank.state[1].copy()
    bank.correct(np.ones((2, 3)) * 1e-3, np.zeros((2, 3)))
    np.testing.assert_array_equal(bank.state[1], frozen)
    with pytest.raises(ValueError, match="cannot advance"):
        bank.advance(2)
