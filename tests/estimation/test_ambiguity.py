"""Integer ambiguity resolution (sinslab.estimation.ambiguity): RTKLIB's LAMBDA against a
brute-force enumeration of the integer least-squares problem (the best and second-best
vectors and their norms), the ratio test and partial fixing on a set with one poorly
determined ambiguity, the fixed solution against the Kalman update it is the limit of, and
known integers recovered from noisy floats at the rate the covariance promises."""
import itertools

import numpy as np
import pytest

from sinslab.estimation import ambiguity as AM
from sinslab.estimation.kalman import update


def _cov(rng, n, scale):
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T + 0.3 * np.eye(n))


def _brute(a, Q, width=3):
    """The two smallest (â − z)ᵀ Q⁻¹ (â − z) over the integer box round(â) ± width."""
    Qi = np.linalg.inv(Q)
    c = np.round(a)
    best = []
    for off in itertools.product(range(-width, width + 1), repeat=a.size):
        z = c + np.array(off)
        d = a - z
        best.append((float(d @ Qi @ d), tuple(z)))
    best.sort()
    return best[:2]


@pytest.mark.parametrize("seed", range(6))
def test_lambda_is_the_integer_least_squares_solution(seed):
    """Correlated 4-dim floats (σ ≈ 0.3–1 cycle, large integers): LAMBDA's best and
    second-best vectors and norms are those of the exhaustive search (Teunissen 1995)."""
    rng = np.random.default_rng(seed)
    Q = _cov(rng, 4, 0.05)
    a = rng.integers(-10 ** 6, 10 ** 6, 4) + rng.normal(0, 0.4, 4)
    F, s = AM.lambda_search(a, Q)
    (s0, z0), (s1, z1) = _brute(a, Q)
    assert np.array_equal(F[0], z0) and np.array_equal(F[1], z1)
    assert np.allclose(s, [s0, s1], rtol=1e-8)


def test_ratio_and_partial_fixing():
    """Five precise ambiguities (σ 0.02 cycles) and one at σ 0.6 cycles with its float
    half-way between integers: the full set fails the ratio test (the poor one has two
    nearly equal candidates); dropping it (the largest variance first) fixes the other
    five to their true integers with a large ratio."""
    rng = np.random.default_rng(3)
    true = rng.integers(-1000, 1000, 6).astype(float)
    Q = np.diag([0.02 ** 2] * 5 + [0.6 ** 2])
    a = true + np.r_[rng.normal(0, 0.02, 5), 0.5]
    fix = AM.resolve(a, Q, ratio=3.0, min_fixed=4)
    assert fix.fixed and fix.tried == 2 and fix.n_fixed == 5 and not fix.used[5]
    assert np.array_equal(fix.integers[:5], true[:5]) and fix.ratio > 100
    only = AM.resolve(a[5:], Q[5:, 5:], min_fixed=1)
    assert not only.fixed and only.ratio < 3.0
    assert not AM.resolve(a[:3], Q[:3, :3], min_fixed=4).fixed       # too few


def test_condition_is_the_limit_of_a_kalman_update():
    """The fixed solution x − P Dᵀ (D P Dᵀ)⁻¹ (D x − d) equals the Kalman update by the
    constraint rows with R → 0 (1e-14), and its covariance is zero along D."""
    rng = np.random.default_rng(1)
    n = 7
    P = _cov(rng, n, 1.0)
    x = rng.normal(size=n)
    D = np.zeros((2, n))
    D[0, 4], D[0, 5] = 1.0, -1.0
    D[1, 6], D[1, 5] = 1.0, -1.0
    d = np.array([3.0, -2.0])
    xf, Pf = AM.condition(x, P, D, d)
    r = update(x, P, d, D, np.full(2, 1e-14), sequential=False)
    # z − H x is the innovation: the update's "z" is d, H is D
    assert np.allclose(xf, r.x, atol=1e-7) and np.allclose(Pf, r.P, atol=1e-7)
    assert np.allclose(D @ xf, d) and np.allclose(D @ Pf @ D.T, 0, atol=1e-10)


def test_known_integers_recovered_at_the_promised_rate():
    """200 draws of floats about known integers with a correlated covariance of
    σ ≈ 0.05–0.1 cycles (8 ambiguities): every accepted fix (ratio ≥ 3) holds the true
    integers, and at least 95 % of the draws are fixed."""
    rng = np.random.default_rng(7)
    Q = _cov(rng, 8, 0.002)
    L = np.linalg.cholesky(Q)
    true = rng.integers(-10 ** 5, 10 ** 5, 8).astype(float)
    fixed = wrong = 0
    for _ in range(200):
        a = true + L @ rng.normal(size=8)
        f = AM.resolve(a, Q)
        if f.fixed:
            fixed += 1
            wrong += not np.array_equal(f.integers[f.used], true[f.used])
    assert wrong == 0 and fixed >= 190


def test_success_rate():
    """The bootstrapped success rate: one ambiguity of σ = 0.2 cycles, 2Φ(1/(2σ)) − 1 =
    erf(1/(2√2 σ)); correlated floats: a lower bound of the integer least-squares success
    rate measured over 1000 draws (Teunissen 1998), and close to it (within 0.1)."""
    import math
    assert np.isclose(AM.success_rate(np.array([[0.04]])), math.erf(1 / (2 * math.sqrt(2) * 0.2)))
    rng = np.random.default_rng(11)
    Q = _cov(rng, 5, 0.01)
    L = np.linalg.cholesky(Q)
    p = AM.success_rate(Q)
    assert 0.5 < p < 0.99
    hits = 0
    for _ in range(1000):
        a = L @ rng.normal(size=5)
        hits += np.array_equal(AM.lambda_search(a, Q)[0][0], np.zeros(5))
    measured = hits / 1000
    assert p - 3 * math.sqrt(p * (1 - p) / 1000) <= measured <= p + 0.1, (p, measured)


def test_bad_covariance():
    with pytest.raises(ValueError, match="needs Q"):
        AM.lambda_search([1.2, 3.4], np.eye(3))
    with pytest.raises(ValueError, match="not positive definite"):
        AM.lambda_search([1.2, 3.4], np.array([[1.0, 2.0], [2.0, 1.0]]))
