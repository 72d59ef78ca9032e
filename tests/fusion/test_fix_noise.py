"""The fixes' correlated errors measured from the record (:mod:`sinslab.fusion.fix_noise`)
and the robust weighting of an inconsistent fix (:func:`robust_R`, Chang 2014).

Oracles: fixes of a simulated drive with a known first-order Gauss–Markov position error
(σ 2 m, τ 60 s) plus white noise (0.3 m) — the structure function fit returns the white
part to 0.08 m and the correlated one within a factor of two (one 10-minute record holds
ten correlation times; over lags up to 2τ the velocity-walk term takes part of it); Chang's rule leaves a consistent innovation alone and
scales R by d/χ² for one beyond the quantile (the closed form)."""
import math

import numpy as np
import pytest

from sinslab.core.earth import radii
from sinslab.core.records import Fixes
from sinslab.fusion.fix_noise import fix_error_model
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
