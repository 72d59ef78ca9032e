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
    gb, ab, d = fb.apply(filt, state, np.ones(3), 2 * np.ones(3))
    assert np.all(filt.x[sl] == 0.0)                    # the block is zeroed
    np.testing.assert_array_equal(d[sl], est)
    comp = {"gyro_bias": gb - 1, "accel_bias": ab - 2}
    if block.feeds in comp:
        np.testing.assert_allclose(comp[block.feeds], est, rtol=1e-9)
        other = "accel_bias" if block.feeds == "gyro_bias" else "gyro_bias"
        np.testing.assert_array_equal(comp[other], 0.0)
    else:                                                  # scale: the stream adds d[slice]
        assert getattr(fb, block.feeds) == sl
        np.testing.assert_array_equal(d[getattr(fb, block.feeds)], est)


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
    gb, ab, d = fb.apply(filt, state)
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


def test_partial_scale_refused():
    with pytest.raises(ValueError, match="gyro_scale"):
        FeedbackLayout.from_model(es.ErrorModel("full", [es.gyro_scale("z")]).layout)
