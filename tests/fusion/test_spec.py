"""The run specs of the fusion compositions (sinslab.fusion.spec) and the one lag
vocabulary (sinslab.fusion.lag): each value is checked once, when it is made, with one
clear error naming what is wrong; a made spec cannot be changed."""
import dataclasses

import numpy as np
import pytest

from sinslab.fusion import lag as L
from sinslab.fusion.spec import FilterGrid, FixSpec, InsSpec
from sinslab.methods import doublestar as ds


def _fix(**kw):
    t = np.array([1.0, 2.0, 3.0])
    return FixSpec(t, np.zeros((3, 3)), [3.0, 3.0, 5.0], **kw)


def test_fix_spec_converts_once_and_is_frozen():
    f = _fix(latency=0.5, lever_arm=[0.1, 0.2, 0.3], outages=[(1.5, 1.0)])
    assert f.sigma.shape == (3, 3) and np.array_equal(f.arrive, f.t + 0.5)
    assert np.array_equal(f.lever_arm, [0.1, 0.2, 0.3]) and f.outages == ((1.5, 1.0),)
    with pytest.raises(ValueError):
        f.lever_arm[0] = 1.0                          # read-only arrays
    with pytest.raises(dataclasses.FrozenInstanceError):
        f.latency = 1.0
    assert len(f) == 3 and f.n_pos == 3


@pytest.mark.parametrize("kw, msg", [
    (dict(latency=-1.0), "latency"),
    (dict(lever_arm=[1.0, 2.0]), "lever arm"),
    (dict(lever_arm=[1.0, np.nan, 0.0]), "lever arm"),
    (dict(arrive=[1.0, 1.5, 3.0]), "arrival"),
    (dict(outages=[(2.0, 0.0)]), "outage"),
    (dict(vel=np.zeros((3, 3)), vel_sigma=0.0), "vel_sigma"),
])
def test_fix_spec_refuses_bad_values(kw, msg):
    with pytest.raises(ValueError, match=msg):
        _fix(**kw)


def test_fix_spec_refuses_bad_fixes():
    with pytest.raises(ValueError, match="increasing"):
        FixSpec([1.0, 1.0], np.zeros((2, 3)), 1.0 * np.ones(3))
    with pytest.raises(ValueError, match="NaN"):
        FixSpec([1.0, 2.0], [[0, 0, 0], [np.nan, 0, 0]], np.ones(3))
    with pytest.raises(ValueError, match="shape"):
        FixSpec([1.0, 2.0], np.zeros((2, 4)), np.ones(3))
    with pytest.raises(ValueError, match="sigma"):
        FixSpec([1.0, 2.0], np.zeros((2, 3)), [1.0, 0.0, 1.0])


def test_ins_spec_and_grid_check_themselves():
    s = InsSpec(nsub=2.0, gyro_bias=1e-5, start=3)
    assert s.nsub == 2 and isinstance(s.nsub, int) and np.array_equal(s.gyro_bias, [1e-5] * 3)
    for kw, msg in ((dict(nsub=6), "nsub"), (dict(nsub=1.5), "nsub"), (dict(vertical="up"), "vertical"),
                    (dict(vertical="hold"), "height"), (dict(start=-1), "start"),
                    (dict(gyro_bias=[np.nan, 0, 0]), "gyro_bias")):
        with pytest.raises(ValueError, match=msg):
            InsSpec(**kw)
    for kw, msg in ((dict(kf_dt=0.0), "kf_dt"), (dict(max_block=np.inf), "max_block"),
                    (dict(model_every=-1.0), "model_every"), (dict(discretization="euler"), "discretization")):
        with pytest.raises(ValueError, match=msg):
            FilterGrid(**kw)


def test_one_lag_vocabulary():
    """A lag is a policy object; its name, on the command line or in a config file, is
    read once. The double-star method's own policy joins the same vocabulary."""
    assert L.lag_policy("exact") == L.ExactReprocessing()
    assert L.lag_policy("on-arrival") == L.OnArrival()
    p = L.OnArrival()
    assert L.lag_policy(p) is p
    with pytest.raises(ValueError, match="unknown lag policy 'paper003'"):
        L.lag_policy("paper003")
    assert ds.lag_policy("paper003") == ds.StoredStateUpdate()
    assert ds.lag_policy("exact") == L.ExactReprocessing()
    assert ds.mode_policy("lag-ignore", ds.StoredStateUpdate()) == L.OnArrival()
    assert ds.mode_policy("zero-lag", ds.StoredStateUpdate()) == ds.StoredStateUpdate()
    for pol in (L.ExactReprocessing(), L.OnArrival(), ds.StoredStateUpdate()):
        assert {pol.name, pol.on_arrival, pol.corrected_nav, pol.needs_model} and callable(pol.update)


# --- the specs of navigate_recorded: each checked when made, fields routed by name ---------
def test_navoptions_is_four_specs_each_checked_when_made():
    from sinslab.fusion import recorded_spec as RS
    o = RS.NavOptions.of(lever_arm=[1, 2, 3], platform="land", kf_dt=0.1, heading=0.5, gyro_arw=1e-4)
    assert o.fix.lever_arm == (1.0, 2.0, 3.0) and o.start.platform == "land" and o.grid.kf_dt == 0.1
    assert o.start.heading == 0.5 and o.errors.gyro_arw == 1e-4
    # a replace remakes only the spec concerned
    o2 = o.replace(motion_alignment=False)
    assert not o2.start.motion_alignment and o2.fix is o.fix and o2.errors is o.errors
    # every field has exactly one home; the aids' settings are theirs (sinslab.fusion.aids)
    names = [f.name for cls in (RS.ErrorSpec, RS.FixHandling, RS.StartSpec, RS.GridSpec)
             for f in dataclasses.fields(cls)]
    assert len(names) == len(set(names)) == len(RS.FIELD_GROUP)
    for bad, msg in ((dict(lever_arm=(1.0, 2.0)), "lever arm"), (dict(platform="boat"), "platform"),
                     (dict(fix_sigma=(1.0, 0.0, 1.0)), "fix_sigma"), (dict(nsub=7), "nsub"),
                     (dict(fix_latency=-0.1), "latency"), (dict(att_sigma=(1.0, 1.0)), "att_sigma")):
        with pytest.raises(ValueError, match=msg):
            RS.NavOptions.of(**bad)
    with pytest.raises(TypeError, match="no field 'zupt'"):
        RS.NavOptions.of(zupt="auto")
    with pytest.raises(TypeError, match="FixHandling"):
        RS.NavOptions(fix=RS.StartSpec())
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.fix.fix_latency = 1.0
