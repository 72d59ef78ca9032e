"""The fixes' σ measured from the filter's own innovations (``fix_noise="innovations"``:
:func:`sinslab.fusion.fix_noise.innovation_noise` iterated by
:func:`sinslab.fusion.recorded.navigate_recorded`).

Oracles:

- batch means of innovations: for white innovations of covariance ``S = HPHᵀ + R`` the
  estimate is R; for a first-order autoregressive error ``e_k = ρ e_{k−1} + w_k`` of
  variance σ² the expectation of ``n ē²`` over a batch of ``n`` is the closed form
  ``σ² [(1+ρ)/(1−ρ) − 2ρ(1−ρⁿ)/(n(1−ρ)²)]`` (the variance of the mean of an AR(1) series);
- a simulated car whose receiver states σ 5–7× too small (position 0.2 m against a 1 m
  Gauss–Markov error of 30 s plus 0.3 m white; velocity 0.03 m/s against a 0.2 m/s
  Gauss–Markov error of 2 s plus 0.05 m/s white): with the σ as stated the filter enters
  its outages off and their ends are several times those of a filter tuned on the truth
  (the best of a small grid of σ); measured from the innovations they are bounded like the
  tuned filter's.
"""
import math

import numpy as np
import pytest

from sinslab.core import units as u
from sinslab.core.earth import radii
from sinslab.core.records import Fixes
from sinslab.fusion.fix_noise import innovation_noise
from sinslab.fusion.recorded import NavOptions, navigate_recorded
from sinslab.sim import imu as IM
from sinslab.sim import trajectory as tr


def _ar1(rng, n, sigma, rho):
    """``x_k = ρ x_{k−1} + w_k`` of steady-state σ (x_0 drawn from it)."""
    from scipy.signal import lfilter
    w = rng.normal(0, sigma * math.sqrt(1 - rho * rho), n)
    w[0] = rng.normal(0, sigma)
    return lfilter([1.0], [1.0, -rho], w)


def test_white_innovations_give_back_R():
    rng = np.random.default_rng(1)
    n, h = 20000, 0.2
    t = h * np.arange(n)
    R, hph = np.array([0.5, 0.02]), np.array([0.3, 0.01])         # σ² of the fix and of the prior
    nu = rng.normal(0, np.sqrt(R + hph), (n, 2))
    sd = np.tile(np.sqrt(R + hph), (n, 1))
    est, nb = innovation_noise(t, nu, sd, np.tile(np.sqrt(R), (n, 1)))
    assert nb == 400
    # 400 batches: the variance estimate within ±3·√(2/400) of its value
    assert np.allclose(est ** 2, R, rtol=0, atol=3 * math.sqrt(2 / 400) * (R + hph)), est ** 2


def test_correlated_innovations_give_the_batch_mean_variance():
    rng = np.random.default_rng(2)
    n, h, rho, sigma = 40000, 0.2, 0.8, 0.1
    t = h * np.arange(n)
    nu = _ar1(rng, n, sigma, rho)[:, None]
    est, nb = innovation_noise(t, nu, np.full((n, 1), 0.03), np.full((n, 1), 0.03))     # HPHᵀ = 0
    m = 50                                                                                 # fixes per 10 s batch
    closed = sigma ** 2 * ((1 + rho) / (1 - rho) - 2 * rho * (1 - rho ** m) / (m * (1 - rho) ** 2))
    assert nb == 800
    assert est[0] ** 2 == pytest.approx(closed, rel=0.15), (est[0] ** 2, closed)
    assert est[0] > 2.5 * sigma                   # ≈ 2.9σ: the white σ carrying what the fixes carry


def test_batches_that_straddle_a_gap_are_not_used_and_a_bias_counts_whole():
    # 57 s of fixes, a gap, 57 s: the two batches cut by the gap hold 35 of 50 fixes
    t = np.r_[0.2 * np.arange(285), 203 + 0.2 * np.arange(285)]
    nu = np.ones((t.size, 1))                                       # a bias of 1 σ, HPHᵀ = 0
    est = innovation_noise(t, nu, np.ones_like(nu), np.ones_like(nu))
    assert est is not None and est[1] == 10
    assert est[0][0] == pytest.approx(math.sqrt(50))                # n ν̄² = n: it never averages away
    assert innovation_noise(t, nu, np.ones_like(nu), np.ones_like(nu), min_batches=11) is None


def _gm(rng, n, dt, sigma, tau):
    return _ar1(rng, n, sigma, math.exp(-dt / tau))


@pytest.fixture(scope="module")
def optimistic_receiver():
    segs = [tr.Static(duration=5.0), tr.Accelerate(duration=5.0, accel=2.0)]
    for k in range(30):
        segs += [tr.Turn(duration=6.0, rate=(-1) ** k * 12 * u.deg, coordinated=False), tr.Level(duration=6.0, transition=2.0)]
        if k % 4 == 1:
            segs.append(tr.Accelerate(duration=4.0, accel=(-1) ** (k // 4) * 1.0))
    g = tr.generate(segs, tr.Start(lat=math.radians(45.07), lon=math.radians(7.66), h=300.0,
                                   heading=math.radians(70)), 0.01)
    err = IM.ImuErrors.from_datasheet(gyro_bias="[2, -1.5, 2.5] deg/h", gyro_arw="0.15 deg/sqrt(h)",
                                      accel_bias="[200, -150, 100] ug", accel_vrw="50 ug/sqrt(Hz)")
    imu = IM.apply(g.imu, err, 13)
    tru = g.truth
    rng = np.random.default_rng(3)
    t = np.arange(0.2, tru.t[-1] - 0.1, 0.2)
    i = np.rint(t / 0.01).astype(int)
    n = t.size
    ve = np.stack([_gm(rng, n, 0.2, 0.2, 2.0) + rng.normal(0, 0.05, n) for _ in range(3)], -1)
    pe = np.stack([_gm(rng, n, 0.2, 1.0, 30.0) + rng.normal(0, 0.3, n) for _ in range(3)], -1)
    rm, rn = radii(tru.lat[i], tru.h[i])
    fx = Fixes(t, tru.lat[i] + pe[:, 1] / rm, tru.lon[i] + pe[:, 0] / (rn * np.cos(tru.lat[i])), tru.h[i] + pe[:, 2],
               np.tile([0.2, 0.2, 0.4], (n, 1)), tru.vel[i] + ve, np.full((n, 3), 0.03), np.ones(n, int))
    return imu, fx, tru


OUTAGES = ((150.0, 30.0), (300.0, 30.0))
FILTER = dict(rest_noise=False, gyro_arw=0.15 * u.deg / 60, accel_vrw=50 * u.ug, gyro_bias_sigma=5 * u.dph,
              accel_bias_sigma=500 * u.ug, outages=OUTAGES)


def _ends(res, tru):
    k = np.rint((res.t - tru.t[0]) / 0.01).astype(int)
    rm, rn = radii(tru.lat[k], tru.h[k])
    hz = np.hypot((res.nav[:, 7] - tru.lat[k]) * rm, (res.nav[:, 8] - tru.lon[k]) * rn * np.cos(tru.lat[k]))
    return np.array([hz[int(np.searchsorted(res.t, s + ln)) - 1] for s, ln in OUTAGES])


def test_optimistic_receiver_sigma_measured_from_the_innovations(optimistic_receiver):
    imu, fx, tru = optimistic_receiver
    run = lambda **kw: navigate_recorded(imu, fx, NavOptions.of(**FILTER, **kw))
    tuned = min((_ends(run(fix_sigma=(p, p, 2 * p), fix_vel_sigma=(v, v, v)), tru) for p, v in
                 ((1.0, 0.3), (1.0, 0.9), (3.0, 1.0))), key=np.mean)
    stated = _ends(run(), tru)
    res = run(fix_noise="innovations")
    measured = _ends(res, tru)
    assert np.mean(stated) > 2.5 * np.mean(tuned), (stated, tuned)          # the defect
    assert np.mean(measured) < 1.5 * np.mean(tuned), (measured, tuned)
    assert np.max(measured) < 1.5 * np.max(tuned), (measured, tuned)
    m = res.source.metrics
    assert m["fix_noise_sigma_stated"] == pytest.approx([0.2, 0.2, 0.4, 0.05, 0.05, 0.05])   # floored at 0.05 m/s
    used = np.array(m["fix_noise_sigma_used"])
    assert np.all(used[:3] > 1.0) and np.all(used[3:] > 0.3), used           # raised 5–20×, where the errors are
    assert 2 <= m["fix_noise_runs"] <= 6
    assert any(nt.startswith("Fix σ from the innovations") for nt in res.source.notes)


def test_the_configuration_key_reaches_the_run(optimistic_receiver):
    """``--set gnss.fixes.noise=innovations`` (the one option) becomes ``fix_noise`` of the
    run's options; a value it does not know is refused."""
    from pathlib import Path

    from sinslab.app.commands.navigate import _options, navigate_config
    from sinslab.app.errors import UserError

    imu, fx, _ = optimistic_receiver
    c = navigate_config(imu=[Path("imu.csv")], fixes=[Path("fix.pos")], sets=["gnss.fixes.noise=innovations"])
    assert _options(c, None, imu, fx, None).fix.fix_noise == "innovations"
    c = navigate_config(imu=[Path("imu.csv")], fixes=[Path("fix.pos")])
    assert _options(c, None, imu, fx, None).fix.fix_noise == "stated"
    with pytest.raises((ValueError, UserError)):
        navigate_config(imu=[Path("imu.csv")], fixes=[Path("fix.pos")], sets=["gnss.fixes.noise=adaptive"])
    with pytest.raises(ValueError, match="fix_noise"):
        NavOptions.of(fix_noise="adaptive")


def test_fixes_another_sigma_governs_are_left_out_of_the_estimate():
    """Velocity fixes the velocity check de-weighted keep their whole lasting error in the
    innovations (the filter does not follow them): white innovations of σ 0.3 with a bias
    of 2 in 10 % of the batches give back 0.3 when those fixes are marked as not governed
    (the estimate of the other 360 batches, within 3·√(2/360)), and ≈ √(0.09 + 0.1·50·4)
    (the bias counted over every fix) when they are not marked."""
    rng = np.random.default_rng(11)
    n, h, sig = 20000, 0.2, 0.3
    t = h * np.arange(n)
    nu = rng.normal(0, sig, (n, 2))
    b = np.floor(t / 10.0).astype(int)
    biased = b % 10 == 3                                            # 40 of 400 batches
    nu[biased, 1] += 2.0
    sd = np.full((n, 2), sig)                                       # HPHᵀ = 0
    governed = np.ones((n, 2), bool)
    governed[biased, 1] = False
    plain, nb = innovation_noise(t, nu, sd, sd)
    est, nb2 = innovation_noise(t, nu, sd, sd, governed=governed)
    assert nb == nb2 == 400
    assert plain[1] == pytest.approx(math.sqrt(sig ** 2 + 0.1 * 50 * 4.0), rel=0.05)    # the defect
    assert est[1] ** 2 == pytest.approx(sig ** 2, abs=3 * math.sqrt(2 / 360) * sig ** 2)
    assert est[0] == plain[0]                                       # a fully governed component: unchanged
    # fewer clean batches than the minimum: the component falls back to all its batches
    few = np.ones((n, 2), bool)
    few[b % 40 != 0, 1] = False                                     # 10 clean batches of 400
    assert innovation_noise(t, nu, sd, sd, governed=few, min_batches=11)[0][1] == plain[1]
    assert innovation_noise(t, nu, sd, sd, governed=few, min_batches=10)[0][1] < 1.5 * sig


def test_the_velocity_check_marks_the_fixes_it_raised():
    """:func:`sinslab.fusion.recorded._governed` (the mask the innovation passes use): the
    velocity columns of the fixes whose σ the velocity check raised above the floor the
    others are taken with are not governed; every other entry is (a fix raised less is taken
    with the floor); without the check there is no mask."""
    import dataclasses

    from sinslab.fusion.fix_noise import velocity_check
    from sinslab.fusion.loosely_coupled import FixSource
    from sinslab.fusion.recorded import _governed
    from sinslab.fusion.recorded_spec import FixHandling

    rng = np.random.default_rng(5)
    t = 0.2 * np.arange(1500)
    psi = 0.01 * t
    vel = np.column_stack([12 * np.sin(psi), 12 * np.cos(psi), np.zeros_like(t)])
    pos = np.vstack([np.zeros((1, 3)), np.cumsum(0.5 * (vel[1:] + vel[:-1]) * np.diff(t)[:, None], 0)])
    pos += rng.normal(0, 0.3, pos.shape)
    vf = vel + rng.normal(0, 0.02, vel.shape)
    vf[(t >= 150.0) & (t < 180.0), 1] += 0.3
    rm, rn = (float(x) for x in radii(math.radians(45.07), 300.0))
    n = t.size
    fx = Fixes(t, math.radians(45.07) + pos[:, 1] / rm, pos[:, 0] / (rn * math.cos(math.radians(45.07))),
               300.0 + pos[:, 2], np.full((n, 3), 1.0), vf, np.full((n, 3), 0.05), np.ones(n, int))
    src = FixSource(fx, FixHandling(velocity_check=10.0, fix_noise="innovations"))
    checked = velocity_check(fx, 10.0)[0]
    floor = 0.2
    above = checked > floor
    assert above[:, 1].sum() > 50                                   # the check found the stretch
    assert np.any((checked[:, 1] > 0.05 * (1 + 1e-9)) & ~above[:, 1])   # and raised some fixes less
    applied = np.arange(0, n, 2)                                    # the fixes the filter applied
    used = np.hstack([np.ones((applied.size, 3)), np.maximum(checked[applied], floor)])
    g = _governed(src, t[applied], used)
    assert g.shape == (applied.size, 6) and g[:, :3].all()
    assert np.array_equal(~g[:, 3:], above[applied])
    assert _governed(dataclasses.replace(src, handling=FixHandling(fix_noise="innovations")), t, used) is None
