"""The compiled prediction kernels against the dense formulas they replace.

``cov_predict`` with the diagonal rows of the sensor states (Φ P Φᵀ split into its dense
r × r part and scalar products) and the fused series step (``Φ (P + T Q̄/2) Φᵀ + T Q̄/2``,
Q_k never formed) are checked against the dense oracle ``Φ P Φᵀ + Q_k`` with the series
``Q_k = T (Q̄ + Φ Q̄ Φᵀ)/2`` (numpy products) on random SPD covariances and the Φ of KF-GINS'
21-state model (Gauss–Markov biases and scale factors, 18 noise inputs) and of the 15-state
default; with r = n the kernel is the dense product itself. The lane forms (many filters in
one call) are the one-filter kernels lane by lane, and the sequential scalar update, the
fixed-gain update and the innovation covariance equal their textbook numpy forms."""
import numpy as np
import pytest

from sinslab.core import units as u
from sinslab.estimation import kernels as K
from sinslab.nav import errstate as es
from sinslab.nav import errstate_kernels as ek

KFGINS = [es.gyro_markov(3600.0, 1 * u.dph), es.accel_markov(3600.0, 500 * u.ug),
          es.gyro_scale(tau=3600.0, sigma=300 * u.ppm), es.accel_scale(tau=3600.0, sigma=300 * u.ppm)]
DEFAULT = [es.gyro_bias(), es.accel_bias()]
T = 0.005


def _model_epochs(blocks, S=4, seed=5):
    """Φ, Q̄ (places of series_structure), Q_k, Q̄ (n, n) of ``S`` random navigation points."""
    m = es.ErrorModel("full", blocks, gyro_arw=0.05 * u.dpsh, accel_vrw=50 * u.ugpsHz)
    prog = ek.program(m)
    rng = np.random.default_rng(seed)
    rows = np.zeros((1, S, 10))
    rows[0, :, :4] = rng.normal(size=(S, 4))
    rows[0, :, 4:7] = rng.normal(scale=80.0, size=(S, 3))
    rows[0, :, 7] = rng.uniform(-1.2, 1.2, S)
    rows[0, :, 9] = rng.uniform(0, 3000, S)
    F, G = ek.matrices_rows(prog, rows, rng.normal(scale=0.1, size=(1, S, 3)),
                            rng.normal(size=(1, S, 3)) + [0, 0, 9.8])
    q = np.asarray(m.q, float)
    fnz, gnz = ek.pattern(prog)
    st = K.series_structure(fnz, gnz, q)
    fcol, fcnt, grow, gcnt, R, pos, nr, phic, phin, qr, nq, qbr, qbn, prc, prn = st
    n = m.n
    out = []
    for e in range(S):
        Phi, Qk = np.empty((n, n)), np.empty((n, n))
        Qb = np.zeros((max(nr, 1), max(nr, 1)))
        K.series_step(F[e], G[e], q, T, fcol, fcnt, grow, gcnt, R, pos, nr, qr, nq, Qb,
                      np.empty((n, max(nr, 1))), np.empty((n, max(nr, 1))), Phi, Qk, qbr, qbn, prc, prn)
        Qbar = (G[e] * q) @ G[e].T
        out.append((Phi, Qb.copy(), Qk, 0.5 * (Qbar + Qbar.T)))
    return st, out


def _spd(n, rng):
    A = rng.normal(size=(n, n)) * np.logspace(-6, 1, n)
    return A @ A.T + 1e-12 * np.eye(n)


def _rel(a, b):
    """Largest difference relative to sqrt(P_ii P_jj) of the oracle."""
    d = np.sqrt(np.diag(b))
    return float(np.max(np.abs(a - b) / np.outer(d, d)))


@pytest.mark.parametrize("blocks,r_expected", [(KFGINS, 9), (DEFAULT, 9)])
def test_diagonal_rows_of_the_sensor_states(blocks, r_expected):
    st, eps = _model_epochs(blocks)
    phic, phin = st[7], st[8]
    r = K.diagonal_tail(phic, phin)
    assert r == r_expected
    for Phi, *_ in eps:                       # the pattern holds for every epoch's Φ
        assert not (Phi - np.diag(np.diag(Phi)))[r:].any()
        assert (Phi - np.diag(np.diag(Phi)))[r - 1].any()


def test_diagonal_tail_of_patterns():
    n = 5
    full = np.tile(np.arange(n), (n, 1))
    assert K.diagonal_tail(full, np.full(n, n)) == n
    eye = np.arange(n)[:, None] * np.ones((n, n), dtype=np.int64)
    assert K.diagonal_tail(eye, np.ones(n, dtype=np.int64)) == 0
    # a single off-diagonal entry in the last row keeps every row dense
    nzc = eye.copy()
    nzc[4, :2] = [0, 4]
    cnt = np.ones(n, dtype=np.int64)
    cnt[4] = 2
    assert K.diagonal_tail(nzc, cnt) == n


@pytest.mark.parametrize("blocks", [KFGINS, DEFAULT])
def test_cov_predict_with_diagonal_rows_is_the_dense_product(blocks):
    st, eps = _model_epochs(blocks)
    r = K.diagonal_tail(st[7], st[8])
    rng = np.random.default_rng(11)
    for Phi, _, Qk, _ in eps:
        n = Phi.shape[0]
        P0 = _spd(n, rng)
        ref = Phi @ P0 @ Phi.T + Qk
        for rr in (r, n):
            P = P0.copy()
            K.cov_predict(P, Phi, Qk, rr, np.empty((n, n)), np.empty((rr, rr)))
            assert np.array_equal(P, P.T)
            assert _rel(P, ref) < 1e-13


@pytest.mark.parametrize("blocks", [KFGINS, DEFAULT])
def test_fused_series_step_is_phi_p_phit_plus_qk(blocks):
    """P ← Φ (P + T Q̄/2) Φᵀ + T Q̄/2 (add_half_qbar, then predict_step with Q = T Q̄/2)
    against Φ P Φᵀ + Q_k with the series Q_k, over a run of steps; x and c by Φ."""
    st, eps = _model_epochs(blocks, S=6)
    R, nr, phic, phin, qbr, qbn = st[4], st[6], st[7], st[8], st[11], st[12]
    r = K.diagonal_tail(phic, phin)
    rng = np.random.default_rng(3)
    n = eps[0][0].shape[0]
    P = _spd(n, rng)
    x, c = rng.normal(size=n), rng.normal(size=n)
    Pr, xr, cr = P.copy(), x.copy(), c.copy()
    Qh = np.zeros((n, n))
    sig, xo = np.empty(n), np.empty(n)
    for Phi, Qb, Qk, Qbar in eps:
        K.add_half_qbar(P, Qb, 0.5 * T, R, nr, qbr, qbn, Qh)
        np.testing.assert_allclose(Qh, 0.5 * T * Qbar, rtol=1e-14, atol=1e-14 * np.abs(Qh).max())
        K.predict_step(x, c, P, Phi, Qh, r, phic, phin, np.empty((n, n)), np.empty((r, r)),
                       np.empty(n), sig, xo)
        Pr = Phi @ Pr @ Phi.T + Qk
        xr, cr = Phi @ xr, Phi @ cr
        assert _rel(P, Pr) < 1e-12
        np.testing.assert_allclose(x, xr, rtol=1e-13, atol=1e-13 * np.abs(xr).max())
        np.testing.assert_allclose(c, cr, rtol=1e-13, atol=1e-13 * np.abs(cr).max())
        np.testing.assert_array_equal(sig, np.sqrt(np.diag(P)))
        np.testing.assert_array_equal(xo, x)


def test_lane_forms_are_the_one_filter_kernels():
    """predict_lanes and sequential_update_lanes step each lane exactly as cov_predict +
    state_predict and sequential_update step one filter (bit for bit), a lane with a
    non-finite z is left alone (NIS −1); the sequential update equals the textbook
    vector Joseph update (Joseph 1968 form, numpy) to rounding."""
    rng = np.random.default_rng(21)
    n, m, L = 7, 3, 4
    Phi = rng.normal(size=(n, n)) * (rng.uniform(size=(n, n)) < 0.5) + np.eye(n)
    Q = _spd(n, rng) * 1e-3
    X = rng.normal(size=(L, n))
    Ps = np.stack([_spd(n, rng) for _ in range(L)])
    nzc = np.zeros((1, n, n), dtype=np.int64)
    nnz = np.zeros((1, n), dtype=np.int64)
    K.row_nonzeros(Phi[None], nzc, nnz)
    X1, P1 = X.copy(), Ps.copy()
    K.predict_lanes(X1, P1, Phi, Q, n, nzc[0], nnz[0], np.empty((n, n)), np.empty((n, n)), np.empty(n))
    for l in range(L):
        x, P = X[l].copy(), Ps[l].copy()
        K.cov_predict(P, Phi, Q, n, np.empty((n, n)), np.empty((n, n)))
        K.state_predict(x, Phi, nzc[0], nnz[0], np.empty(n))
        np.testing.assert_array_equal(P1[l], P)
        np.testing.assert_array_equal(X1[l], x)
    Z = rng.normal(size=(L, m))
    Z[2, 1] = np.nan
    H = rng.normal(size=(L, m, n))
    r = rng.uniform(0.1, 1.0, m)
    nis = np.empty(L)
    X2, P2 = X1.copy(), P1.copy()
    K.sequential_update_lanes(X2, P2, Z, H, r, nis)
    assert nis[2] == -1.0 and np.array_equal(X2[2], X1[2]) and np.array_equal(P2[2], P1[2])
    for l in (0, 1, 3):
        x, P = X1[l].copy(), P1[l].copy()
        nis1 = K.sequential_update(x, P, Z[l], H[l], r, np.empty(m), np.empty(m), np.empty(n), np.empty((n, n)))
        assert nis1 == nis[l]
        np.testing.assert_array_equal(X2[l], x)
        np.testing.assert_array_equal(P2[l], P)
        # the textbook vector Joseph update
        S = H[l] @ P1[l] @ H[l].T + np.diag(r)
        G = np.linalg.solve(S, H[l] @ P1[l]).T
        A = np.eye(n) - G @ H[l]
        nu = Z[l] - H[l] @ X1[l]
        np.testing.assert_allclose(X2[l], X1[l] + G @ nu, rtol=1e-10, atol=1e-12)
        assert _rel(P2[l], A @ P1[l] @ A.T + G @ np.diag(r) @ G.T) < 1e-10
        assert nis[l] == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-10)


def test_sparse_x_record_step_is_predict_step():
    """predict_step_sparse_x steps P, x and c and writes σ exactly as predict_step (bit for
    bit); its x row is left as it was (zero) when the estimate is zero — the closed-loop
    epochs without an update — and written otherwise."""
    rng = np.random.default_rng(8)
    n = 7
    Phi = rng.normal(size=(n, n)) * (rng.uniform(size=(n, n)) < 0.5) + np.eye(n)
    Q = _spd(n, rng) * 1e-3
    nzc = np.zeros((1, n, n), dtype=np.int64)
    nnz = np.zeros((1, n), dtype=np.int64)
    K.row_nonzeros(Phi[None], nzc, nnz)
    for x0 in (np.zeros(n), rng.normal(size=n)):
        outs = []
        for step in (K.predict_step, K.predict_step_sparse_x):
            x, c, P = x0.copy(), np.ones(n), _spd(n, np.random.default_rng(3))
            sig, xo = np.empty(n), np.zeros(n)
            step(x, c, P, Phi, Q, n, nzc[0], nnz[0], np.empty((n, n)), np.empty((n, n)), np.empty(n), sig, xo)
            outs.append((x, c, P, sig, xo))
        for a, b in zip(*outs):
            np.testing.assert_array_equal(a, b)
        assert np.any(outs[1][4] != 0.0) == np.any(x0 != 0.0)


def test_fixed_gain_update_and_innovation_covariance():
    """innovation, gain_correct and innovation_cov against numpy's z − H x, x + G ν and
    H P Hᵀ + R (to rounding; S exactly symmetric, R's halves averaged)."""
    rng = np.random.default_rng(22)
    n, m = 9, 4
    x, z = rng.normal(size=n), rng.normal(size=m)
    H = rng.normal(size=(m, n)) * (rng.uniform(size=(m, n)) < 0.6)
    G = rng.normal(size=(n, m))
    nu = np.empty(m)
    K.innovation(x, H, z, nu)
    np.testing.assert_allclose(nu, z - H @ x, rtol=1e-14, atol=1e-14)
    y = x.copy()
    K.gain_correct(y, G, nu)
    np.testing.assert_allclose(y, x + G @ nu, rtol=1e-14, atol=1e-14)
    P = _spd(n, rng)
    R = _spd(m, rng)
    S = np.empty((m, m))
    K.innovation_cov(H, P, R, np.empty((n, m)), S)
    assert np.array_equal(S, S.T)
    np.testing.assert_allclose(S, H @ P @ H.T + R, rtol=1e-13, atol=1e-13 * np.abs(S).max())
