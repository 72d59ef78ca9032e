"""A barometer with a Gauss–Markov bias state of its own (sinslab.fusion.measurements.barometer) bounds
the vertical channel of an INS at rest, through the fusion driver with closed-loop
feedback: the model gains one block, nothing else changes.

Oracle: covariance versus Monte Carlo. Runs with their own IMU biases, white noise,
initial height and vertical-velocity errors, a first-order Gauss–Markov barometer bias
(discretised exactly) and reading noise, all drawn from the filter's own model; position
fixes for the first 150 s make the bias observable, the barometer alone holds the height
after. The sum over runs of (error / filter σ)² of the height and of the estimated bias
must lie in the two-sided 99.9 % interval of χ² with one degree of freedom per run.
"""
import math

import numpy as np
import pytest
from scipy.stats import chi2

from sinslab.core import units as u
from sinslab.core.records import ImuRecord, NavState
from sinslab.fusion import driver
from sinslab.fusion.measurements import Barometer
from sinslab.fusion.feedback import FeedbackLayout
from sinslab.fusion.measurements import PositionFix
from sinslab.fusion.spec import FilterGrid
from sinslab.nav import errstate as es
from support import static_imu

LAT, LON, H0 = 0.6, 2.0, 300.0
DT, KF_DT, T_END, T_FIX = 0.1, 0.2, 400.0, 150.0
ARW, VRW = 0.05 * u.deg / 60, 50 * u.ug          # [rad/√s], [m/s/√s]
GYRO_BIAS, ACCEL_BIAS = 0.05 * u.dph, 300 * u.ug  # 1σ of the random constants
TAU, SIGMA_B, SIGMA_V = 300.0, 2.0, 0.5           # barometer bias τ [s], σ [m]; reading σ [m]
SIGMA_H0, SIGMA_VU0 = 1.0, 0.05                   # initial height [m], vertical velocity [m/s]
RUNS = 20


def _model(baro=True):
    blocks = [es.gyro_bias(), es.accel_bias()] + ([es.barometer_bias(tau=TAU, sigma=SIGMA_B)] if baro else [])
    return es.ErrorModel("full", blocks, gyro_arw=ARW, accel_vrw=VRW)


def _P0(lay):
    d = np.zeros(lay.n)
    d[lay.slice("phi")] = (1e-5) ** 2
    d[lay.slice("dv")] = [1e-4, 1e-4, SIGMA_VU0 ** 2]
    d[lay.slice("dp")] = [1e-14, 1e-14, SIGMA_H0 ** 2]
    d[lay.slice("eps")] = GYRO_BIAS ** 2
    d[lay.slice("nabla")] = ACCEL_BIAS ** 2
    sb = lay.find("baro_bias")
    if sb is not None:
        d[sb] = SIGMA_B ** 2
    return np.diag(d)


def _run(seed, baro=True, history=None):
    """One run: ``(t, height error, estimated − true bias, σ_h, σ_b)`` at the filter epochs
    (and the driver's result, the true bias at the readings)."""
    rng = np.random.default_rng(seed)
    n = int(round(T_END / DT))
    imu = static_imu(LAT, np.zeros(3), DT, n, h=H0, gyro_err=rng.normal(0, GYRO_BIAS, 3),
                     accel_err=rng.normal(0, ACCEL_BIAS, 3))
    imu = ImuRecord(imu.t, imu.dtheta + rng.normal(0, ARW * math.sqrt(DT), (n, 3)),
                    imu.dv + rng.normal(0, VRW * math.sqrt(DT), (n, 3)), DT)
    init = NavState(LAT, LON, H0 + rng.normal(0, SIGMA_H0), np.array([0.0, 0.0, rng.normal(0, SIGMA_VU0)]),
                    np.zeros(3), 0.0)
    tb = np.arange(1.0, T_END + 0.5)                      # readings at 1 Hz
    a = math.exp(-1.0 / TAU)
    b = np.empty(tb.size)
    b[0] = rng.normal(0, SIGMA_B) * a + rng.normal(0, SIGMA_B * math.sqrt(1 - a * a))
    for k in range(1, tb.size):
        b[k] = a * b[k - 1] + rng.normal(0, SIGMA_B * math.sqrt(1 - a * a))
    tf = tb[tb <= (T_FIX if baro else 0.0)]          # the free INS: no fixes either
    rm, rn = 6.36e6, 6.39e6                                # fix noise in radians: any radius of the right size
    pos = np.column_stack([LAT + rng.normal(0, 0.5, tf.size) / rm,
                           LON + rng.normal(0, 0.5, tf.size) / (rn * math.cos(LAT)),
                           H0 + rng.normal(0, 0.5, tf.size)])
    meas = [PositionFix(tf, pos, [0.5, 0.5, 0.5])]
    if baro:
        meas.append(Barometer(tb, H0 + b + rng.normal(0, SIGMA_V, tb.size), SIGMA_V))
    model = _model(baro)
    lay = model.layout
    r = driver.run([driver.LiveStream(imu, init, nsub=2)], model, _P0(lay), meas, grid=FilterGrid(KF_DT),
                   feedback=FeedbackLayout.from_model(lay), history=history)
    dh = r.nav[0][:, 9] - H0
    sp = lay.slice("dp").start + 2
    out = dict(t=r.t, dh=dh, sigma_h=r.sigma[:, sp], result=r, bias=b)
    sb = lay.find("baro_bias")
    if sb is not None:
        # the bias state is b_used − b_true with b_used = 0; b_true at the readings
        k = np.rint(r.t).astype(int) - 1
        ok = (np.abs(r.t - np.rint(r.t)) < 1e-9) & (k >= 0)
        eb = np.full(r.t.size, np.nan)
        eb[ok] = (0.0 - r.x[ok, sb.start]) - b[k[ok]]
        out.update(eb=eb, sigma_b=r.sigma[:, sb.start])
    return out


@pytest.fixture(scope="module")
def runs():
    return [_run(s) for s in range(RUNS)]


def test_the_barometer_block_feeds_nothing_back():
    lay = _model().layout
    fb = FeedbackLayout.from_model(lay)
    sb = lay.find("baro_bias")
    assert sb.start not in fb.indices(lay.n) and [k for k, _ in fb.compensation] == ["gyro_bias", "accel_bias"]


@pytest.mark.parametrize("t_check", [T_FIX, T_END])
def test_height_and_bias_errors_match_the_filter_sigma(runs, t_check):
    lo, hi = chi2.ppf([0.0005, 0.9995], RUNS)
    k = int(np.argmin(np.abs(runs[0]["t"] - t_check)))
    for err, sig in (("dh", "sigma_h"), ("eb", "sigma_b")):
        s = sum((r[err][k] / r[sig][k]) ** 2 for r in runs)
        assert lo < s < hi, (err, t_check, s, (lo, hi))


def test_the_bias_converges_under_fixes_and_the_barometer_holds_the_height(runs):
    """Under the fixes the bias σ falls well below its prior σ (it is observed); after them
    the height error stays within a few metres, where the free vertical channel of the
    same IMUs (no aiding at all) leaves by tens of metres."""
    k_fix = int(np.argmin(np.abs(runs[0]["t"] - T_FIX)))
    assert max(r["sigma_b"][k_fix] for r in runs) < 0.5 * SIGMA_B
    assert max(r["sigma_h"][-1] for r in runs) < 1.5 * SIGMA_B
    rms = math.sqrt(np.mean([r["dh"][-1] ** 2 for r in runs]))
    free = math.sqrt(np.mean([_run(s, baro=False)["dh"][-1] ** 2 for s in range(4)]))
    assert rms < 3.0 and free > 10 * rms, (rms, free)


def test_the_smoother_follows_the_model():
    """The RTS smoother of the same run, with no edit for the new block: the smoothed bias
    σ is at most the forward one and smaller inside the barometer-only stretch, and the
    smoothed bias errors at the readings stay within 4σ."""
    from sinslab.fusion.smoothing import History, smooth
    out = _run(100, history=History(1.0))
    r = out["result"]
    s = smooth(r)
    sb = r.layout.find("baro_bias").start
    assert np.all(s.sigma[:, sb] <= r.sigma[:, sb] * (1 + 1e-9))
    mid = np.abs(r.t - 0.5 * (T_FIX + T_END)) < 1e-9
    assert s.sigma[mid, sb][0] < 0.9 * r.sigma[mid, sb][0]
    k = np.flatnonzero(np.abs(r.t - np.rint(r.t)) < 1e-9)[1:]
    err = (0.0 - s.x[k, sb]) - out["bias"][np.rint(r.t[k]).astype(int) - 1]
    assert np.all(np.abs(err) < 4 * s.sigma[k, sb])
