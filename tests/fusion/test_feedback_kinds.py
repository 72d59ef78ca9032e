"""Closed-loop feedback follows what a sensor block is (its ``feeds``), not its name."""
import numpy as np
import pytest

from sinslab.estimation.filter import KalmanFilter
from sinslab.fusion.feedback import FeedbackLayout
from sinslab.nav import errstate as es
from sinslab.nav import strapdown as sd
from sinslab.core.records import NavState

KINDS = {
    "gyro_bias": es.gyro_bias(), "accel_bias": es.accel_bias(),
    "gyro_markov": es.gyro_markov(300.0, 1e-5), "accel_markov": es.accel_markov(300.0, 1e-3),
    "gyro_scale": es.gyro_scale(), "accel_scale": es.accel_scale(),
}


def _state():
    return sd.initial_state_array(NavState(0.7, 0.2, 100.0, np.zeros(3), np.zeros(3)))


def _filter(model, x):
    f = KalmanFilter(np.asarray(x, float), np.eye(model.n))
    return f


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_every_sensor_kind_reaches_the_ins(kind):
    block = KINDS[kind]
    model = es.ErrorModel("full", [block])
    lay = model.layout
    fb = FeedbackLayout.from_model(lay)
    x = np.zeros(model.n)
    sl = lay.slice(block.name)
    est = np.array([1e-5, -2e-5, 3e-5])
    x[sl] = est
    filt = _filter(model, x)
    state = _state()
    base = {k: (i + 1.0) * np.ones(3) for i, k in enumerate(es.COMPENSATIONS)}
    comp, d = fb.apply(filt, state, base)
    assert np.all(filt.x[sl] == 0.0)                    # the block is zeroed
    np.testing.assert_array_equal(d[sl], est)
    assert [k for k, _ in fb.compensation] == [block.feeds]
    for k, v in comp.items():                             # its compensation alone moves
        np.testing.assert_allclose(v - base[k], est if k == block.feeds else 0.0, rtol=1e-9)


def test_bias_and_markov_add_and_axis_subsets():
    model = es.ErrorModel("full", [es.gyro_bias(), es.gyro_markov(100.0, 1e-5, axes="z"),
                                   es.accel_bias("xy"), es.accel_markov(50.0, 1e-3)])
    lay = model.layout
    fb = FeedbackLayout.from_model(lay)
    x = np.zeros(model.n)
    x[lay.slice("eps")] = [1.0, 2.0, 3.0]
    x[lay.slice("eps_m")] = [10.0]
    x[lay.slice("nabla")] = [4.0, 5.0]
    x[lay.slice("nabla_m")] = [0.1, 0.2, 0.3]
    filt = KalmanFilter(x.copy() * 1e-6, np.eye(model.n))
    state = _state()
    comp, d = fb.apply(filt, state, {"gyro_bias": np.zeros(3), "accel_bias": np.zeros(3)})
    gb, ab = comp["gyro_bias"], comp["accel_bias"]
    np.testing.assert_allclose(gb, np.array([1.0, 2.0, 13.0]) * 1e-6, rtol=0, atol=1e-20)
    np.testing.assert_allclose(ab, np.array([4.1, 5.2, 0.3]) * 1e-6, rtol=0, atol=1e-20)
    assert not np.any(filt.x[9:])
    assert set(fb.indices(model.n).tolist()) == set(range(model.n))


def test_explicit_names_still_override():
    model = es.ErrorModel("full", [es.gyro_bias(name="eps_b"), es.gyro_markov(100.0, 1e-5), es.accel_bias()])
    fb = FeedbackLayout.from_model(model.layout, gyro="eps_b", accel=None)
    assert fb.gyro == model.layout.slice("eps_b") and fb.accel is None
    # the legacy single-block case stays a slice (bit-identical arithmetic)
    fb2 = FeedbackLayout.from_model(es.ErrorModel("full", [es.gyro_bias(), es.accel_bias()]).layout)
    assert fb2.gyro == slice(9, 12) and fb2.accel == slice(12, 15)


def test_nav_frame_and_installation_do_not_feed():
    model = es.ErrorModel("full", [es.gyro_bias(frame="nav"), es.installation()])
    fb = FeedbackLayout.from_model(model.layout)
    assert fb.gyro is None and fb.accel is None


def test_scale_blocks_add_up_per_axis():
    """Two gyro scale blocks on axis subsets feed the one scale compensation, each its axes."""
    model = es.ErrorModel("full", [es.gyro_scale("z", name="kz"), es.gyro_scale("xy", name="kxy")])
    fb = FeedbackLayout.from_model(model.layout)
    filt = KalmanFilter(np.r_[np.zeros(9), 3e-6, 1e-6, 2e-6], np.eye(12))   # kz, then kxy
    comp, _ = fb.apply(filt, _state(), {"gyro_scale": np.zeros(3)})
    np.testing.assert_array_equal(comp["gyro_scale"], [1e-6, 2e-6, 3e-6])


def test_a_compensation_the_ins_lacks_is_refused():
    fb = FeedbackLayout.from_model(es.ErrorModel("full", [es.gyro_scale()]).layout)
    with pytest.raises(ValueError, match="no gyro_scale compensation"):
        fb.apply(KalmanFilter(np.zeros(12), np.eye(12)), _state(), {"gyro_bias": np.zeros(3)})
