"""Oracles for the fusion driver (sinslab.fusion.driver), its measurement objects
(sinslab.fusion.measurements) and the feedback layout (sinslab.fusion.feedback).

- a 2-D position fix on a horizontal model, its extrapolation to the epoch, and Stack
  (the H of every measurement is the finite-difference Jacobian of its z: the measurement
  contract, tests/fusion/test_measurements.py);
- the INS-difference measurement on two streams selects the difference states of a
  DifferenceModel, and a two-stream filter on it estimates the output difference;
- feed-forward filtering of a precomputed navigation series equals that of the live
  stream it came from.
"""
import math

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.core.earth import radii
from sinslab.estimation.filter import KalmanFilter
from sinslab.fusion import driver
from sinslab.fusion.feedback import FeedbackLayout
from sinslab.fusion.loosely_coupled import lc_model
from sinslab.fusion.measurements import (Epoch, Grid, InsDifference, NavRow, PositionFix, Stack,
                                         VelocityFix, arrival_epochs)
from sinslab.methods.rotins import joint_rotation_model
from sinslab.fusion.spec import FilterGrid
from sinslab.nav import errstate as es
from support import assert_H_is_jacobian


def _row(lat=0.55, lon=2.0, h=800.0, vel=(120.0, -40.0, 2.0), att=(0.05, -0.1, 0.7)):
    return np.r_[A.euler_to_quat(np.asarray(att)), vel, lat, lon, h]


def test_position_fix_2d_on_a_horizontal_model_and_extrapolation():
    m16 = es.ErrorModel("horizontal", [es.gyro_bias(name="eps")])
    lay = m16.layout
    row = _row()
    fix = np.array([[row[7], row[8]]])
    m = PositionFix([10.0], fix, [2.0, 2.0], lever_arm=(0.3, 0.2, 0.1))
    z, H, R = m.matrices(Epoch(10.0, 0, (NavRow(row, np.zeros(3), np.zeros(3)),), lay, lay.n, 0))
    assert z.shape == (2,) and H.shape == (2, lay.n) and R.shape == (2,)
    # a fix valid 0.1 s before the epoch is moved along the (antenna) velocity
    m0 = PositionFix([9.9], fix, [2.0, 2.0])
    rs = (NavRow(row, np.zeros(3), np.zeros(3)),)
    z0 = m0.matrices(Epoch(10.0, 0, rs, lay, lay.n, 0))[0]
    assert z0 == pytest.approx([-row[5] * 0.1, -row[4] * 0.1], rel=1e-12)


def test_stack_concatenates_its_parts():
    lay = lc_model(1e-5, 1e-4).layout
    row = _row()
    w = np.array([0.01, -0.02, 0.05])
    ep = Epoch(0.0, 0, (NavRow(row, w, np.zeros(3)),), lay, lay.n, 0)
    m = VelocityFix([0.0], [row[4:7]], 0.1, lever_arm=(0.4, 1.5, -0.7))
    z, H, R = m.matrices(ep)
    st = Stack(PositionFix([0.0], [row[7:10]], [3.0, 3.0, 5.0]), m)
    z2, H2, R2 = st.matrices(ep)
    assert z2.shape == (6,) and np.array_equal(z2[3:], z) and np.array_equal(H2[3:], H)
    assert np.allclose(R2, [9.0, 9.0, 25.0, 0.01, 0.01, 0.01])


@pytest.mark.parametrize("lever", [None, (0.5, 2.0, 0.3)])
def test_ins_difference_selects_the_difference_states(lever):
    """z = [L1 − Lk, λ1 − λk, vE1 − vEk, vN1 − vNk] on paper 001's joint model: H picks
    [δL δλ δvE δvN]_1k; with a lever arm between the IMUs its φ and INS-1 gyro-bias columns
    are the Jacobian of the lever removal (stream 1 and its sensor errors perturbed,
    stream k exact)."""
    m = joint_rotation_model()
    lay = m.layout
    row1 = _row()
    w = np.array([0.003, 0.001, 0.04])
    rowk = row1.copy()
    if lever is not None:
        C = A.quat_to_dcm(row1[:4])
        d = C @ np.asarray(lever)
        rm, rn = radii(row1[7], row1[9])
        rowk[7] += d[1] / rm
        rowk[8] += d[0] / (rn * math.cos(row1[7]))
        rowk[4:7] += C @ np.cross(w, lever)
    meas = InsDifference([0.0], [1e-7, 1e-7, 0.01, 0.01], lever_arm=lever)
    z, H, R = assert_H_is_jacobian(lambda x: meas, lay, [row1, rowk], [w, w], k=0,
                                   sensor_errors=("eps_1", "nabla_1"))
    assert np.allclose(z, 0.0, atol=1e-9)
    sel = lay.selector(["dL_1k", "dlam_1k", "dvE_1k", "dvN_1k"])
    rest = np.ones(lay.n, bool)
    rest[lay.slice("phi")] = rest[lay.slice("eps_1")] = False
    assert np.array_equal(H[:, rest], sel[:, rest])


def _short_flight(duration=120.0, rate=50.0, seed=3):
    from sinslab.core.records import NavState
    from sinslab.sim import imu as imu_mod
    from sinslab.sim import trajectory as tr
    segs = [tr.Level(duration=30.0), tr.Turn(duration=40.0, rate=2 * u.deg), tr.Level(duration=50.0)]
    start = tr.Start(lat=32 * u.deg, lon=118 * u.deg, h=500.0, speed=100.0, heading=30.0)
    gen = tr.generate(segs, start, 1.0 / rate, duration=duration)
    err = imu_mod.ImuErrors.from_datasheet(gyro_bias="0.3 deg/h", gyro_arw="0.02 deg/sqrt(h)",
                                           accel_bias="100 ug", accel_vrw="20 ug/sqrt(Hz)")
    meas = imu_mod.apply(gen.imu, err, seed)
    tru = gen.truth
    att0 = tru.att_imu[0] if tru.att_imu is not None else tru.att[0]
    init = NavState(tru.lat[0], tru.lon[0], tru.h[0], tru.vel[0] + [0.1, -0.1, 0.0],
                    att0 + np.array([1, 1, 5]) * u.arcmin, tru.t[0])
    return meas, init, tru


def test_precomputed_stream_feed_forward_equals_live_stream():
    """Feed-forward filtering of a navigation series computed beforehand gives the same
    estimate and covariance as the live stream it came from (same rows, same rates)."""
    meas, init, tru = _short_flight()
    model = lc_model(0.02 * u.dpsh, 20 * u.ugpsHz)
    P0 = np.diag(np.r_[[(2 * u.arcmin) ** 2] * 2, (10 * u.arcmin) ** 2, [0.2 ** 2] * 3,
                       (5 / 6.4e6) ** 2, (5 / 5.4e6) ** 2, 25.0, [(1 * u.dph) ** 2] * 3,
                       [(200 * u.ug) ** 2] * 3])
    idx = np.arange(50, tru.t.size, 50)
    fix = PositionFix(tru.t[idx], np.stack([tru.lat[idx], tru.lon[idx], tru.h[idx]], -1),
                      [3.0, 3.0, 5.0], t_arrive=tru.t[idx] + 1.0)
    live = driver.LiveStream(meas, init, nsub=2)
    r1 = driver.run([live], model, P0, [fix], grid=FilterGrid(0.2))
    T = 0.2
    k_kf = int(round(T / meas.dt))
    n_ep = r1.t.size - 1
    w = meas.dtheta[:n_ep * k_kf].reshape(n_ep, k_kf, 3).sum(1) / T - np.zeros(3)
    f = meas.dv[:n_ep * k_kf].reshape(n_ep, k_kf, 3).sum(1) / T - np.zeros(3)
    pre = driver.PrecomputedStream(r1.t, r1.nav[0], w, f)
    r2 = driver.run([pre], model, P0, [fix], grid=FilterGrid(0.2))
    assert r1.applied.item.size == idx.size - 1              # the last fix arrives after the end
    assert np.array_equal(r2.x, r1.x) and np.array_equal(r2.sigma, r1.sigma)
    with pytest.raises(ValueError, match="cannot be fed back"):
        driver.run([pre], model, P0, [fix], grid=FilterGrid(0.2), feedback=FeedbackLayout.from_model(model.layout))


def test_two_stream_difference_filter_estimates_the_output_difference():
    """Two INS on one IMU record with different initial errors, run as two live streams
    with the joint (difference) model: the filter's δL_1k, δλ_1k, δv_1k follow the
    difference of the two outputs that the measurement shows, within 3σ."""
    meas, init, tru = _short_flight(duration=100.0)
    from sinslab.core.records import NavState
    init2 = NavState(init.lat + 2e-6, init.lon - 1e-6, init.h, init.vel + [0.3, -0.2, 0.0],
                     init.att + np.array([-2, 1, 3]) * u.arcmin, init.t)
    h = np.full(len(meas) + 1, init.h)
    s1 = driver.LiveStream(meas, init, vertical="hold", height=h)
    s2 = driver.LiveStream(meas, init2, vertical="hold", height=h)
    m = joint_rotation_model(1e-6, 1e-6, 1e-5, 1e-5)
    lay = m.layout
    sd = np.r_[[1e-5] * 2, [1.0] * 2, [10 * u.arcmin] * 3, [1 * u.dph] * 6, [300 * u.ug] * 4]
    P0 = np.diag(sd ** 2)
    t = 1.0 + np.arange(99)
    dif = InsDifference(t, [1e-8, 1e-8, 0.01, 0.01])
    r = driver.run([s1, s2], m, P0, [dif], grid=FilterGrid(1.0, model_every=0.0))
    assert r.applied.item.size == t.size
    sel = lay.index(["dL_1k", "dlam_1k", "dvE_1k", "dvN_1k"])
    d = np.stack([r.nav[0][:, 7] - r.nav[1][:, 7], r.nav[0][:, 8] - r.nav[1][:, 8],
                  r.nav[0][:, 4] - r.nav[1][:, 4], r.nav[0][:, 5] - r.nav[1][:, 5]], -1)
    err = r.x[:, sel] - d
    assert np.all(np.abs(err[10:]) < 3 * r.sigma[10:, sel] + 1e-12)
    assert np.all(r.sigma[-1, sel] < 0.1 * sd[sel])


def test_arrival_epochs_outages_windows_and_grid():
    g = Grid(100.0, 0.5, 10)
    assert np.allclose(g.t, 100.0 + 0.5 * np.arange(11))
    tv = np.array([100.5, 101.0, 101.2, 102.0, 104.0])
    ta = tv + np.array([0.0, 1.0, 0.1, 0.0, 2.0])
    assert arrival_epochs(tv, ta, g) == {1: [0], 3: [2], 4: [1, 3]}
    assert arrival_epochs(tv, ta, g, outages=[(101.0, 0.5)]) == {1: [0], 4: [3]}
    assert arrival_epochs(tv, ta, g, windows=[(101.0, 101.6)]) == {3: [2]}
def test_feedback_layout_corrects_ins_and_compensation():
    from sinslab.nav import strapdown as sd
    from sinslab.core.records import NavState

    model = lc_model(1e-5, 1e-4)
    lay = FeedbackLayout.from_model(model.layout)
    assert lay.indices(15).tolist() == list(range(15))
    state = sd.initial_state_array(NavState(0.5, 1.0, 100.0, np.array([10.0, 5.0, 0.0]),
                                            np.array([0.01, 0.02, 0.3]), 0.0))
    x = np.r_[[1e-4, -2e-4, 3e-4], [0.1, 0.2, -0.1], [1e-6, -1e-6, 2.0], [1e-6] * 3, [1e-3] * 3]
    f = KalmanFilter(x, np.eye(15) * 1e-6)
    ref = state.copy()
    sd.correct(ref, phi=x[0:3], dvel=x[3:6], dpos=x[6:9])
    comp = {"gyro_bias": np.ones(3), "accel_bias": np.zeros(3)}
    out, d = lay.apply(f, state, comp)
    np.testing.assert_allclose(state[:10], ref[:10])
    np.testing.assert_allclose(out["gyro_bias"], 1 + x[9:12])
    np.testing.assert_allclose(out["accel_bias"], x[12:15])
    assert np.all(comp["gyro_bias"] == 1.0)                     # the INS's arrays are not changed
    assert np.all(f.x == 0) and np.allclose(f.x_total, x)


def test_feedback_layout_horizontal_blocks_and_scale_factors():
    """A 2-state (horizontal) velocity/position block leaves the vertical alone; scale-factor
    blocks are fed back (zeroed) and returned for the caller's compensation."""
    from sinslab.methods import doublestar as ds
    from sinslab.nav import strapdown as sd

    from sinslab.core.records import NavState
    m = ds.horizontal_model(1e-7, 1e-7, 3600.0, 1e-4, 1800.0)
    lay = FeedbackLayout.from_model(m.layout, gyro="eps_b", accel=None)
    assert lay.indices(16).tolist() == list(range(10))        # the Markov states stay
    state = sd.initial_state_array(NavState(0.5, 1.0, 100.0, np.array([10.0, 5.0, 1.0]),
                                            np.array([0.01, 0.02, 0.3]), 0.0))
    x = np.r_[[1e-4, -2e-4, 3e-4], [0.1, 0.2], [1e-6, -1e-6], [1e-6] * 3, [2e-6] * 3, [1e-3] * 3]
    f = KalmanFilter(x, np.eye(16) * 1e-6)
    ref = state.copy()
    sd.correct(ref, phi=x[0:3], dvel=[x[3], x[4], 0.0], dpos=[x[5], x[6], 0.0])
    out, d = lay.apply(f, state, {"gyro_bias": np.zeros(3), "accel_bias": np.zeros(3)})
    np.testing.assert_allclose(state[:10], ref[:10])
    np.testing.assert_allclose(out["gyro_bias"], x[7:10])
    assert np.all(out["accel_bias"] == 0) and np.all(f.x[:10] == 0) and np.array_equal(f.x[10:], x[10:])
    m21 = lc_model(1e-5, 1e-4, scale_factors=True)
    lay21 = FeedbackLayout.from_model(m21.layout)
    assert lay21.indices(21).tolist() == list(range(21))
    assert lay21.gyro_scale == m21.layout.slice("kg") and lay21.accel_scale == m21.layout.slice("ka")
