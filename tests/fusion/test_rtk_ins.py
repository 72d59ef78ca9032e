"""RTK/INS (sinslab.fusion.rtk_ins) on a simulated car drive with a base station and a
10 s outage of every satellite (tests/support.py:phase_drive): the integers fixed are the
simulator's, the fixed antenna positions are centimetre-level, the integers are found
again at the first epoch after the outage (the INS carries the position through it); the
driver refuses to smooth or lag a measurement that restarts states."""
import math

import numpy as np
import pytest
from support import phase_drive, true_double_differences

from sinslab.core import earth as E
from sinslab.fusion.carrier import max_signals, slot_count
from sinslab.fusion.rtk import STATUS, RtkOptions
from sinslab.fusion.rtk_ins import DoubleDifferences, rtk_ins, rtk_model
from sinslab.fusion.spec import FilterGrid

OPT = RtkOptions(mask=math.radians(10.0), ar_mask=math.radians(10.0), iono="broadcast")


@pytest.fixture(scope="module")
def drive():
    d = phase_drive(1, canyon=((0, 80.0, 10.0),), duration=110.0)
    model = rtk_model(d["arw"], d["vrw"], slots=slot_count(max_signals(d["rover"])))
    P0 = np.zeros((model.n, model.n))
    P0[:15, :15] = np.diag(d["sigma0"] ** 2)
    r = rtk_ins(d["imu"], d["init"], d["rover"], d["base"], P0, model, OPT, grid=FilterGrid(0.1))
    return d, r


def _truth_ecef(tru, t):
    k = np.searchsorted(tru.t, t - 1e-9)
    return E.geodetic_to_ecef(tru.lat[k], tru.lon[k], tru.h[k])


def test_integers_and_fixed_position(drive):
    """Every double-difference integer fixed is the truth; fixed at ≥ 95 % of the epochs
    with satellites, horizontal RMS of the fixed antenna ≤ 2 cm, vertical ≤ 3 cm."""
    d, r = drive
    a = r.rtk.arrays()
    dd = true_double_differences(d["sim"])
    e_of = {float(t): e for e, t in enumerate(d["rover"].t_epoch)}
    n = 0
    for t, (pairs, ints) in zip(a["t"], a["fixed_dd"]):
        for (s, q, k), v in zip(pairs, ints):
            assert v == dd(e_of[float(t)], s, q, k)
            n += 1
    assert n > 1500
    seen = a["status"] > STATUS["none"]
    fx = a["status"] == STATUS["fixed"]
    assert fx[seen].mean() >= 0.95
    tru = d["truth"]
    err = (a["fixed_pos"][fx] - _truth_ecef(tru, a["t"][fx])) @ E.enu_to_ecef_matrix(tru.lat[0], tru.lon[0])
    assert np.sqrt(np.mean(np.sum(err[:, :2] ** 2, 1))) <= 0.02 and np.sqrt(np.mean(err[:, 2] ** 2)) <= 0.03


def test_fixed_again_when_the_signals_return(drive):
    """No satellite 80–90 s (the INS drifts by about 8 cm); at 90 s every signal is a new
    lock (flagged), its ambiguity restarted; the first epoch back is fixed (part of its
    ambiguities), the next with all of them."""
    d, r = drive
    a = r.rtk.arrays()
    t = a["t"]
    assert np.all(a["status"][(t >= 80) & (t < 90)] == STATUS["none"])
    back = int(np.flatnonzero(t >= 90.0)[0])
    assert a["n_slip"][back] >= 20 and a["status"][back] == STATUS["fixed"]
    assert a["n_fixed"][back] >= 4 and a["n_fixed"][back + 1] == a["n_amb"][back + 1] >= 16


def test_measurement_is_refused_where_it_cannot_be_exact(drive):
    """A measurement that restarts states cannot be smoothed (the RTS pass would miss the
    restarts) and a model without ambiguity states is refused with its blocks named."""
    from sinslab.fusion.driver import LiveStream, run
    from sinslab.fusion.loosely_coupled import lc_model
    from sinslab.fusion.smoothing import History
    from sinslab.fusion.spec import InsSpec
    d, _ = drive
    model = rtk_model(d["arw"], d["vrw"], slots=40)
    dd = DoubleDifferences(d["rover"], d["base"], OPT)
    stream = LiveStream.of(d["imu"], d["init"], InsSpec())
    with pytest.raises(ValueError, match="smoothing a run whose measurements re-initialise"):
        run([stream], model, np.eye(model.n), [dd], grid=FilterGrid(0.1), history=History())
    with pytest.raises(ValueError, match="needs ambiguity states"):
        rtk_ins(d["imu"], d["init"], d["rover"], d["base"], np.eye(15), lc_model(d["arw"], d["vrw"]), OPT)
