"""The fixes' correlated errors measured from the record (:mod:`sinslab.fusion.fix_noise`)
and the robust weighting of an inconsistent fix (:func:`robust_R`, Chang 2014).

Oracles: fixes of a simulated drive with a known first-order Gauss–Markov position error
(σ 2 m, τ 60 s) plus white noise (0.3 m) — the structure function fit returns the white
part to 0.08 m and the correlated one within a factor of two (one 10-minute record holds
ten correlation times; over lags up to 2τ the velocity-walk term takes part of it); a
receiver-like record (white 0.05 m, Gauss–Markov 0.9 m over 25 s, a Doppler velocity error
of 0.066 m/s lasting 6 s) — the fit recovers every part within the scatter of 20 such
records (the random walk alone fitted no position error there); stops where the receiver
holds its solution — the model is the one of the same record with the stops cut out
(time at rest does not count); Chang's rule leaves a consistent innovation alone and
scales R by d/χ² for one beyond the quantile (the closed form)."""
import math

import numpy as np
import pytest

from sinslab.core.earth import radii
from sinslab.core.records import Fixes
from sinslab.fusion.fix_noise import at_rest, fix_error_model
from sinslab.fusion.measurements.base import Epoch
from sinslab.fusion.measurements.schedule import robust_R


def _gm(rng, n, dt, sigma, tau):
    a = math.exp(-dt / tau)
    x = np.empty(n)
    x[0] = rng.normal(0, sigma)
    w = rng.normal(0, sigma * math.sqrt(1 - a * a), n)
    for k in range(1, n):
        x[k] = a * x[k - 1] + w[k]
    return x


def test_structure_function_recovers_a_gauss_markov_fix_error():
    rng = np.random.default_rng(11)
    dt, n = 0.2, 3000                                   # 10 min at 5 Hz
    t = dt * np.arange(n)
    # a car at 10 m/s turning slowly: the truth integrates the velocity exactly
    psi = 0.02 * t
    vel = np.column_stack([10 * np.sin(psi), 10 * np.cos(psi), np.zeros(n)])
    e_true = np.cumsum(np.vstack([np.zeros((1, 3)), 0.5 * (vel[1:] + vel[:-1]) * dt]), 0)
    lat0 = math.radians(45.0)
    rm, rn = (float(x) for x in radii(lat0, 100.0))
    err = np.column_stack([_gm(rng, n, dt, 2.0, 60.0) for _ in range(3)]) + rng.normal(0, 0.3, (n, 3))
    p = e_true + err
    fx = Fixes(t, lat0 + p[:, 1] / rm, p[:, 0] / (rn * math.cos(lat0)), 100 + p[:, 2], np.ones((n, 3)),
               vel + rng.normal(0, 0.02, (n, 3)), np.full((n, 3), 0.02))
    m = fix_error_model(fx)
    assert np.all(np.abs(m.white - 0.3) < 0.08), m.describe()
    assert np.all((m.correlated > 1.0) & (m.correlated < 4.0)), m.describe()
    assert 15 < m.tau < 150, m.describe()


def _receiver_drive(seed, n, white, corr, tau, vel_sigma, vel_tau, stops=()):
    """Fixes of a car at 10 m/s turning slowly, the truth the trapezoid integral of its
    velocity: position error white + Gauss–Markov (σ, τ) per axis, velocity error
    Gauss–Markov (σ_v, T). In ``stops`` ((start, end) [s]) the car stands, the receiver
    holds its solution (the error frozen, no white noise) and its velocity reads zero."""
    rng = np.random.default_rng(seed)
    dt = 0.2
    t = dt * np.arange(n)
    moving = np.ones(n, bool)
    for a, b in stops:
        moving[(t >= a) & (t < b)] = False
    psi = 0.02 * t
    vel = 10.0 * moving[:, None] * np.column_stack([np.sin(psi), np.cos(psi), np.zeros(n)])
    truth = np.cumsum(np.vstack([np.zeros((1, 3)), 0.5 * (vel[1:] + vel[:-1]) * dt]), 0)
    a = math.exp(-dt / tau)
    gm = np.empty((n, 3))
    gm[0] = rng.normal(0, corr, 3)
    drive = rng.normal(0, corr * math.sqrt(1 - a * a), (n, 3))
    for k in range(1, n):
        gm[k] = a * gm[k - 1] + drive[k] if moving[k] else gm[k - 1]
    wn = rng.normal(0, white, (n, 3)) * moving[:, None]
    ev = np.column_stack([_gm(rng, n, dt, vel_sigma, vel_tau) for _ in range(3)]) * moving[:, None]
    p = truth + gm + wn
    lat0 = math.radians(45.0)
    rm, rn = (float(x) for x in radii(lat0, 100.0))
    return Fixes(t, lat0 + p[:, 1] / rm, p[:, 0] / (rn * math.cos(lat0)), 100 + p[:, 2], np.ones((n, 3)),
                 vel + ev, np.full((n, 3), 0.05))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_structure_function_recovers_a_receiver_whose_velocity_errors_last(seed):
    """One hour at 5 Hz of a receiver-like error: white 0.05 m, Gauss–Markov 0.9 m over 25 s
    on the positions, a velocity error of 0.066 m/s lasting 6 s (q_v = 2σ_v²T =
    0.052 m²/s). The integrated velocity error bends the structure function up over its
    first seconds (``σ_v² Δ²``); a random walk ``q_v Δ`` alone cannot and the fit took the
    concave Gauss–Markov part out instead (no correlated error on an axis, white 0–0.04 m).
    Tolerances: the range of 20 such records (seeds 1–20: white 0.033–0.059 m, σ_c
    0.57–1.41 m, τ 11–60 s, T 3.8–10.3 s, q_v 0.023–0.085 m²/s, the Gauss–Markov part's
    initial slope 2σ_c²/τ 0.058–0.074 m²/s against 0.065): σ_c and τ trade off against the
    walk over two-minute lags, their slope is sharp."""
    m = fix_error_model(_receiver_drive(seed, 18000, 0.05, 0.9, 25.0, 0.066, 6.0))
    assert np.all(np.abs(m.white - 0.05) < 0.02), m.describe()
    assert np.all((m.correlated > 0.9 / 1.7) & (m.correlated < 0.9 * 1.7)), m.describe()
    assert 25.0 / 3 < m.tau < 25.0 * 3, m.describe()
    assert 6.0 / 2 < m.velocity_tau < 6.0 * 2, m.velocity_tau
    q = 2 * 0.066 ** 2 * 6.0
    assert np.all((m.velocity_walk ** 2 > q / 2.5) & (m.velocity_walk ** 2 < q * 2.5)), m.velocity_walk
    slope = 2 * m.correlated ** 2 / m.tau
    assert np.all(np.abs(slope / (2 * 0.9 ** 2 / 25.0) - 1) < 0.2), slope


def test_stops_do_not_count_as_time_for_the_fix_error():
    """A receiver that holds its solution while the car stands: a third of the record in
    five stops. Its fixes at rest (:func:`at_rest`: speed within the 99 % χ² of the stated
    σ) are left out and the moving stretches joined, so the model is the one of the same
    record with the stops cut out and the time closed up (the same position changes and
    integrated velocities over every pair). Counted, the stops add zeros at every lag and
    lags the error did not evolve over: the structure function came out a quarter low
    (white 0.17–0.18 m, correlated 0.69–0.77 m against 0.19–0.21 and 0.85–0.93 m cut)."""
    stops = ((0.0, 150.0), (300.0, 330.0), (500.0, 540.0), (700.0, 740.0), (900.0, 930.0))
    fx = _receiver_drive(4, 6000, 0.2, 1.0, 20.0, 0.03, 2.0, stops)
    rest = at_rest(fx.vel, fx.sigma_vel)
    assert 0.2 < rest.mean() < 0.3
    n = int((~rest).sum())
    cut = Fixes(0.2 * np.arange(n), fx.lat[~rest], fx.lon[~rest], fx.h[~rest], fx.sigma[~rest], fx.vel[~rest],
                fx.sigma_vel[~rest])
    m, ref = fix_error_model(fx), fix_error_model(cut)
    assert m.rest_fraction == pytest.approx(rest.mean()) and ref.rest_fraction == 0.0
    # the same up to the local projection's east scale, taken at each record's first fix: 1e-8
    # of kilometres of travel is 1e-5 m in a difference of metres
    assert np.allclose(m.structure, ref.structure, rtol=1e-4, atol=0.0)
    assert np.allclose(m.white, ref.white, rtol=1e-5) and np.allclose(m.correlated, ref.correlated, rtol=1e-5)
    assert m.tau == pytest.approx(ref.tau, rel=1e-9) and m.velocity_tau == pytest.approx(ref.velocity_tau, rel=1e-9)
    assert np.all(np.abs(m.white - 0.2) < 0.04) and np.all(m.correlated > 0.5), m.describe()


def test_at_rest_is_the_chi_square_of_the_horizontal_speed():
    """χ²₂ 99 % quantile −2 ln 0.01 = 9.21: 3.0σ in one axis is below it, 3.1σ above; the
    vertical velocity does not count; a fix without a positive σ is never at rest."""
    v = np.array([[0.15, 0.0, 5.0], [0.155, 0.0, 0.0], [0.1, 0.1, 0.0], [0.11, 0.11, 0.0], [0.0, 0.0, 0.0]])
    s = np.array([[0.05, 0.05, 0.05]] * 4 + [[0.0, 0.05, 0.05]])
    assert at_rest(v, s).tolist() == [True, False, True, False, False]


def test_robust_R_is_chang_scaling():
    H = np.eye(2)
    P = np.diag([0.5, 0.5])
    R = np.array([0.5, 0.5])
    ep = Epoch(0.0, 0, (), None, 2, 0, (np.zeros(2), P))
    R1, f = robust_R(ep, np.array([0.3, -0.2]), H, R, 0.01)
    assert f == 1.0 and np.array_equal(R1, R)
    z = np.array([4.0, 3.0])                              # d = 25 / 1 = 25 against χ²₂(0.99) = 9.21
    R2, f2 = robust_R(ep, z, H, R, 0.01)
    lim = -2 * math.log(0.01)                             # χ²₂ quantile in closed form
    assert f2 == pytest.approx(25.0 / lim) and np.allclose(R2, R * 25.0 / lim)
    assert robust_R(Epoch(0.0, 0, (), None, 2, 0, None), z, H, R, 0.01)[1] == 1.0     # a lagged item: no prior
