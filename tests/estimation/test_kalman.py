"""Oracles for sinslab.estimation (kalman, linear, filter): textbook equations, on-time vs
lagged filters, budgets; the estimation layer imports nothing from the INS."""
import numpy as np
import pytest
from scipy import linalg as sla

from sinslab.estimation import kalman as kf
from sinslab.estimation import linear as lin
from sinslab.estimation.filter import KalmanFilter


def _model(n=6, m=2, seed=0, dt=1.0):
    """A random stable-ish linear model: Phi = expm(F dt), Q by Van Loan."""
    rng = np.random.default_rng(seed)
    F = rng.normal(scale=0.2, size=(n, n)) - 0.1 * np.eye(n)
    G = rng.normal(size=(n, 2))
    Phi, Q = kf.discretize(F, np.diag([0.01, 0.02]), dt, G=G)
    H = rng.normal(size=(m, n))
    R = np.diag(rng.uniform(0.1, 0.5, m))
    P0 = np.eye(n) + 0.1 * np.ones((n, n))
    return F, G, Phi, Q, H, R, P0, rng


def _textbook(x, P, z, H, R):
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (z - H @ x), (np.eye(len(x)) - K @ H) @ P, z - H @ x, S


# --- plain functions ------------------------------------------------------------------
def test_update_matches_textbook_and_sequential_equals_vector():
    _, _, Phi, Q, H, R, P0, rng = _model()
    x = rng.normal(size=6)
    z = rng.normal(size=2)
    xt, Pt, nut, St = _textbook(x, P0, z, H, R)
    for seq in (True, False):
        x1, P1, nu, S = kf.update(x, P0, z, H, R, sequential=seq)
        np.testing.assert_allclose(x1, xt, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(P1, Pt, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(nu, nut)
        np.testing.assert_allclose(S, St)
        assert np.array_equal(P1, P1.T)
    res = kf.update(x, P0, z, H, R)
    assert res.nis == pytest.approx(nut @ np.linalg.solve(St, nut), rel=1e-10)


def test_update_mask_and_nan_use_only_available_components():
    _, _, _, _, H, R, P0, rng = _model()
    x = rng.normal(size=6)
    z = np.array([0.3, np.nan])
    res = kf.update(x, P0, z, H, R)
    xt, Pt, _, _ = _textbook(x, P0, z[:1], H[:1], R[:1, :1])
    np.testing.assert_allclose(res.x, xt, rtol=1e-12)
    np.testing.assert_allclose(res.P, Pt, rtol=1e-10, atol=1e-13)
    assert np.isnan(res.innovation[1]) and res.used.tolist() == [True, False]
    res2 = kf.update(x, P0, [0.3, 7.0], H, R, mask=[True, False])
    np.testing.assert_allclose(res2.x, res.x)


def test_predict_matches_formula():
    _, _, Phi, Q, _, _, P0, rng = _model()
    x = rng.normal(size=6)
    x1, P1 = kf.predict(x, P0, Phi, Q)
    np.testing.assert_allclose(x1, Phi @ x)
    np.testing.assert_allclose(P1, Phi @ P0 @ Phi.T + Q, rtol=1e-12)


def test_discretize_matches_series_for_small_step():
    F, G, *_ = _model()
    Qc = G @ np.diag([0.01, 0.02]) @ G.T
    T = 1e-3
    Phi, Qk = kf.discretize(F, Qc, T)
    np.testing.assert_allclose(Phi, sla.expm(F * T), rtol=1e-12)
    series = Qc * T + (F @ Qc + Qc @ F.T) * T**2 / 2
    np.testing.assert_allclose(Qk, series, rtol=1e-5, atol=1e-16)


@pytest.mark.parametrize("bad", ["P0", "Q", "R", "shape_H", "shape_z", "nan_P", "asym"])
def test_bad_input_is_a_clear_error(bad):
    _, _, Phi, Q, H, R, P0, rng = _model()
    x = np.zeros(6)
    z = np.zeros(2)
    notpsd = np.diag([1, 1, 1, 1, 1, -1.0])
    with pytest.raises(ValueError) as ei:
        if bad == "P0":
            lin.run_linear(x, notpsd, Phi, Q, H, R, np.zeros((3, 2)))
        elif bad == "Q":
            kf.predict(x, P0, Phi, notpsd)
        elif bad == "R":
            kf.update(x, P0, z, H, np.diag([1.0, 0.0]))
        elif bad == "shape_H":
            kf.update(x, P0, z, H[:, :5], R)
        elif bad == "shape_z":
            lin.run_linear(x, P0, Phi, Q, H, R, np.zeros((3, 3)))
        elif bad == "nan_P":
            P = P0.copy()
            P[0, 1] = np.nan
            KalmanFilter(x, P)
        elif bad == "asym":
            P = P0.copy()
            P[0, 1] += 0.1
            lin.propagate_covariance(P, Phi, Q, n_steps=3)
    msg = str(ei.value)
    assert any(w in msg for w in ("P0", "Q", "R", "H", "z", "P")), msg


@pytest.mark.parametrize("d", [[1.0, 2.0], [1.0, 0.0], [1.0, -1e-12], [1.0, -1.0], [4.0, 1e-12, 3.0],
                               [0.0, 0.0], [2.0, -1e-10, 1.0]])
@pytest.mark.parametrize("definite", [False, True])
def test_check_covariance_of_a_diagonal_decides_as_its_eigenvalues(d, definite):
    """A diagonal matrix is checked from its diagonal (its eigenvalues) without LAPACK:
    the same accept/refuse decision as for the same matrix in a rotated basis, whose
    eigenvalues come from eigvalsh, and the same returned matrix."""
    from sinslab.estimation.kalman import check_covariance

    D = np.diag(d)
    th = 0.3
    U = np.eye(len(d))
    U[:2, :2] = [[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]]
    M = U @ D @ U.T
    M = 0.5 * (M + M.T)

    def decision(A):
        try:
            return check_covariance(A, definite=definite)
        except ValueError:
            return None

    a, b = decision(D), decision(M)
    assert (a is None) == (b is None)
    if a is not None:
        assert np.array_equal(a, D)


# --- compiled loops -------------------------------------------------------------------
def _python_loop(x0, P0, Phis, Qs, H, R, z, mask):
    x, P = x0.copy(), P0.copy()
    xs, pd = [x.copy()], [np.diag(P).copy()]
    for k in range(len(z)):
        x, P = kf.predict(x, P, Phis[k], Qs[k])
        if mask[k].any():
            x, P, _, _ = kf.update(x, P, z[k], H, R, mask=mask[k])
        xs.append(x.copy())
        pd.append(np.diag(P).copy())
    return np.array(xs), np.array(pd), P


@pytest.mark.parametrize("correlated", [False, True])
def test_compiled_loop_equals_python_loop(correlated):
    _, _, Phi, Q, H, R, P0, rng = _model()
    K = 40
    Phis = np.array([Phi * (1 + 0.01 * np.sin(k)) for k in range(K)])
    Qs = np.array([Q] * K)
    if correlated:
        R = R + 0.05 * np.ones((2, 2))
    z = rng.normal(size=(K, 2))
    mask = rng.uniform(size=(K, 2)) < 0.6
    if correlated:
        mask[:] = mask[:, :1]
    x0 = rng.normal(size=6)
    run = lin.run_linear(x0, P0, Phis, Q, H, R, z, mask=mask, save_at=[0, 10, -1])
    xs, pd, P = _python_loop(x0, P0, Phis, Qs, H, R, z, mask)
    np.testing.assert_allclose(run.x, xs, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(run.P_diag, pd, rtol=1e-9)
    np.testing.assert_allclose(run.P_saved[-1], P, rtol=1e-9, atol=1e-13)
    np.testing.assert_allclose(run.P_saved[0], P0)
    cov = lin.propagate_covariance(P0, Phis, Q, H, R, mask=mask)
    np.testing.assert_allclose(cov.P_diag, run.P_diag, rtol=1e-12)
    assert np.isnan(run.innovation[~mask]).all() and np.isfinite(run.innovation[mask]).all()


def test_table_index_and_windows():
    _, _, Phi, Q, H, R, P0, _ = _model()
    K = 30
    t = np.arange(K + 1) * 1.0
    tab = np.array([Phi, Phi.T @ Phi * 0.5])
    idx = np.arange(K) % 2
    a = lin.propagate_covariance(P0, tab, Q, H, R, Phi_index=idx, windows=[(5, 9), (20, 22)], t=t)
    mask = ((t[1:] >= 5) & (t[1:] <= 9)) | ((t[1:] >= 20) & (t[1:] <= 22))
    b = lin.propagate_covariance(P0, tab[idx], Q, H, R, mask=mask)
    np.testing.assert_allclose(a.P_diag, b.P_diag, rtol=1e-13)
    with pytest.raises(ValueError, match="outside"):
        lin.propagate_covariance(P0, Phi, Q, H, R, n_steps=K, windows=[(100, 200)], t=t)


@pytest.mark.parametrize("correlated", [False, True])
def test_kept_gains_are_the_batch_gain_and_rerun_the_filter(correlated):
    """The gain kept by the covariance run (sequential scalar updates, composed; with a
    correlated R the vector update's) is the batch gain ``P⁻Hᵀ(HP⁻Hᵀ + R)⁻¹`` of the
    textbook recursion (kalman.predict/update) at every step, zero where nothing is
    measured, the kept S is ``HP⁻Hᵀ + R``, and the fixed-gain recursion
    ``x⁺ = Φx + G(z − HΦx)`` (written out here, and compiled over several records by
    fixed_gain_runs) reproduces the filter run on data."""
    _, _, Phi, Q, H, R, P0, rng = _model()
    if correlated:
        R = R + 0.05
    K = 40
    Phis = np.array([Phi * (1 + 0.01 * np.sin(k)) for k in range(K)])
    z = rng.normal(size=(K, 2))
    mask = rng.uniform(size=(K, 2)) < 0.6
    x0 = rng.normal(size=6)
    cov = lin.propagate_covariance(P0, Phis, Q, H, R, mask=mask, keep_gain=True)
    assert cov.gain.shape == (K, 6, 2) and cov.S.shape == (K, 2, 2)
    P = P0.copy()
    for k in range(K):
        _, P = kf.predict(np.zeros(6), P, Phis[k], Q)
        np.testing.assert_allclose(cov.S[k], H @ P @ H.T + R, rtol=1e-12)
        on = mask[k]
        G = np.zeros((6, 2))
        if on.any():
            Hu, Ru = H[on], R[np.ix_(on, on)]
            G[:, on] = np.linalg.solve(Hu @ P @ Hu.T + Ru, Hu @ P).T
            _, P, _, _ = kf.update(np.zeros(6), P, z[k], H, R, mask=on)
        np.testing.assert_allclose(cov.gain[k], G, rtol=1e-10, atol=1e-14)
    run = lin.run_linear(x0, P0, Phis, Q, H, R, z, mask=mask)
    x = x0.copy()
    prior_nu = np.empty((K, 2))
    for k in range(K):
        x = Phis[k] @ x
        prior_nu[k] = z[k] - H @ x
        x = x + cov.gain[k] @ np.where(mask[k], prior_nu[k], 0.0)
        np.testing.assert_allclose(x, run.x[k + 1], rtol=1e-10, atol=1e-13)
    # three records: the second is the run above; a record's numbers do not depend on the others
    zs = np.stack([rng.normal(size=(K, 2)), np.where(mask, z, np.nan), rng.normal(size=(K, 2))])
    x0s = np.stack([rng.normal(size=6), x0, rng.normal(size=6)])
    xs, nu = lin.fixed_gain_runs(x0s, Phis, H, cov.gain, zs, mask=mask)
    np.testing.assert_allclose(xs[1], run.x, rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(nu[1][mask], prior_nu[mask], rtol=1e-10, atol=1e-13)
    assert np.isnan(nu[1][~mask]).all()
    one, _ = lin.fixed_gain_runs(x0s[2:], Phis, H, cov.gain, zs[2:], mask=mask)
    np.testing.assert_array_equal(one[0], xs[2])


def test_error_budget_sums_to_total_and_scales_linearly():
    F, G, Phi, _, H, R, P0, rng = _model()
    T = 1.0
    q = [0.01, 0.02]
    Qparts = np.array([kf.discretize(F, np.array([[q[j]]]), T, G=G[:, [j]])[1] for j in range(2)])
    P0parts = np.array([np.diag(np.r_[np.diag(P0)[:3], 0, 0, 0]), np.diag(np.r_[0, 0, 0, np.diag(P0)[3:]])])
    r = np.diag(R)
    Rparts = np.array([[r[0], 0], [0, r[1]]])
    K = 200
    mask = (np.arange(K) % 5 == 0)
    b = lin.error_budget(P0parts, Phi, Qparts, H, Rparts, n_steps=K, mask=mask, history_every=50)
    full = lin.propagate_covariance(P0parts.sum(0), Phi, Qparts.sum(0), H, R, mask=mask)
    np.testing.assert_allclose(b.total, full.P_diag[-1], rtol=1e-12)
    np.testing.assert_allclose(b.variance.sum(0), b.total, rtol=1e-10)
    assert b.history.shape == (4, 6, 6)
    assert (b.variance > -1e-15).all()
    assert np.allclose(b.fraction().sum(0), 1.0)
    # independent oracle: propagate the second Q source alone through the gains of the
    # full filter (computed here in plain numpy, one scalar component at a time)
    P = P0parts.sum(0).copy()
    C = np.zeros((6, 6))
    Qtot = Qparts.sum(0)
    for k in range(K):
        P = Phi @ P @ Phi.T + Qtot
        C = Phi @ C @ Phi.T + Qparts[1]
        if mask[k]:
            for c in range(2):
                h = H[c]
                kg = P @ h / (h @ P @ h + r[c])
                A = np.eye(6) - np.outer(kg, h)
                P = A @ P @ A.T + r[c] * np.outer(kg, kg)
                C = A @ C @ A.T
    np.testing.assert_allclose(b.variance[3], np.diag(C), rtol=1e-9)


def test_steady_state_matches_long_run():
    _, _, Phi, Q, H, R, P0, _ = _model()
    ss = kf.steady_state(Phi, Q, H, R)
    run = lin.propagate_covariance(P0, Phi, Q, H, R, n_steps=2000)
    np.testing.assert_allclose(run.P_final, ss.P_post, rtol=1e-8)


def test_covariance_stays_symmetric_psd_over_144h():
    """1 Hz for 144 h (518 400 steps), tiny R as in paper 001: a Schuler-like loop
    (position, velocity, tilt) plus a random-constant drift, position measured."""
    wS = np.sqrt(9.8 / 6.4e6)
    g = 9.8
    F = np.zeros((4, 4))
    F[0, 1] = 1.0            # dp = v
    F[1, 2] = -g             # dv = -g phi
    F[2, 1] = 1 / 6.4e6      # dphi = v/R - eps
    F[2, 3] = -1.0
    Qc = np.diag([0, (10e-6 * g) ** 2, (1e-3 * np.pi / 180 / 60) ** 2, 0])
    Phi, Q = kf.discretize(F, Qc, 1.0)
    H = np.array([[1.0, 0, 0, 0]])
    R = np.array([[1e-6]])            # 1 mm
    K = 144 * 3600
    P0 = np.diag([1.0, 0.01, (1e-4) ** 2, (0.01 * np.pi / 180 / 3600) ** 2])
    run = lin.propagate_covariance(P0, Phi, Q, H, R, n_steps=K,
                                  save_at=np.linspace(0, K, 13).astype(int))
    assert wS > 0
    assert np.all(np.isfinite(run.P_diag)) and (run.P_diag >= 0).all()
    for P in run.P_saved:
        assert np.array_equal(P, P.T)
        w = np.linalg.eigvalsh(P / np.sqrt(np.outer(np.diag(P), np.diag(P))))
        assert w.min() > -1e-9


# --- lagged measurements --------------------------------------------------------------
def _lag_scenario(feedback, method="exact", seed=3):
    """Run an on-time filter and a lagged filter on the same linear truth; return the
    feed-forward-equivalent estimates and covariances at the end."""
    F, G, Phi, Q, H, R, P0, rng = _model(seed=seed, dt=0.5)
    Qc = G @ np.diag([0.01, 0.02]) @ G.T
    n, K = 6, 30
    truth = rng.multivariate_normal(np.zeros(n), P0)
    xs_true = [truth.copy()]
    zs = []
    for k in range(K):
        truth = Phi @ truth + rng.multivariate_normal(np.zeros(n), Q)
        xs_true.append(truth.copy())
        zs.append(H @ truth + rng.normal(size=2) * np.sqrt(np.diag(R)))
    j_lag, lag = 12, 6           # fix valid at epoch 12 arrives at epoch 18
    other = {5, 14, 16, 25} if method != "paper003" else {5, 25}  # on-time fixes
    out = []
    for lagged in (False, True):
        f = KalmanFilter(np.zeros(n), P0, history=10 if lagged else 0)
        corr = np.zeros(n)       # corrections applied to the "INS" (feedback)
        for k in range(K):
            f.predict(Phi, Q, 0.5, aux=corr.copy())
            corr = Phi @ corr
            e = k + 1
            if e in other or (e == j_lag and not lagged):
                f.update(zs[k] - H @ corr, H, R)
            if lagged and e == j_lag + lag:
                corr_then = f.aux_at(j_lag * 0.5)
                zm = zs[j_lag - 1] - H @ (Phi @ corr_then)
                if method == "naive":
                    f.update(zm, H, R)
                elif method == "paper003":
                    from sinslab.methods.doublestar import StoredStateUpdate
                    StoredStateUpdate().update(f, zm, H, R, j_lag * 0.5, F=F, Qc=Qc)
                else:
                    f.update_lagged(zm, H, R, j_lag * 0.5)
            if feedback:
                corr = corr + f.feedback()
        out.append((f.x + corr if feedback else f.x, f.P, f.x_total))
    return out


@pytest.mark.parametrize("feedback", [False, True])
def test_lagged_exact_equals_on_time_filter(feedback):
    (x0, P0, xt0), (x1, P1, xt1) = _lag_scenario(feedback)
    np.testing.assert_allclose(x1, x0, rtol=1e-9, atol=1e-12 * np.abs(x0).max())
    np.testing.assert_allclose(P1, P0, rtol=1e-9, atol=1e-12 * np.abs(P0).max())
    np.testing.assert_allclose(xt1, xt0, rtol=1e-9, atol=1e-12 * np.abs(xt0).max())
    rel = np.abs(x1 - x0).max() / np.abs(x0).max()
    assert rel < 1e-9


def test_ignoring_the_lag_changes_the_estimate():
    """Sanity: the scenario is sensitive to the lag (applying the old fix as if current
    gives a clearly different estimate), so the 1e-9 agreement above means something."""
    (x0, _, _), (x1, _, _) = _lag_scenario(False, method="naive")
    assert np.abs(x1 - x0).max() / np.abs(x0).max() > 1e-3


@pytest.mark.parametrize("feedback", [False, True])
def test_lagged_paper003_equals_on_time_for_time_invariant_system(feedback):
    (x0, P0, _), (x1, P1, _) = _lag_scenario(feedback, method="paper003")
    np.testing.assert_allclose(x1, x0, rtol=1e-9, atol=1e-10 * np.abs(x0).max())
    np.testing.assert_allclose(P1, P0, rtol=1e-9, atol=1e-10 * np.abs(P0).max())


def test_lagged_errors():
    _, _, Phi, Q, H, R, P0, _ = _model()
    f = KalmanFilter(None, P0, history=3)
    for _ in range(5):
        f.predict(Phi, Q, 1.0)
    with pytest.raises(ValueError, match="older than the stored history"):
        f.update_lagged([0, 0], H, R, 1.0)
    with pytest.raises(ValueError, match="future"):
        f.update_lagged([0, 0], H, R, 9.0)
    with pytest.raises(ValueError, match="not a stored epoch"):
        f.update_lagged([0, 0], H, R, 4.5)
    with pytest.raises(ValueError, match="history"):
        KalmanFilter(None, P0).update_lagged([0, 0], H, R, 0.0)


def test_stateful_filter_fast_paths_agree_and_results_are_not_aliased():
    _, _, Phi, Q, H, R, P0, rng = _model()
    z = rng.normal(size=(5, 2))
    slow = KalmanFilter(np.zeros(6), P0)                 # checked path
    fast = KalmanFilter(np.zeros(6), P0, check=False)    # compiled path
    for k in range(5):
        slow.predict(Phi, Q, 1.0)
        fast.predict_many(Phi[None], Q[None], 1.0)
        r1 = slow.update(z[k], H, R)
        r2 = fast.update(z[k], H, R)
        np.testing.assert_allclose(r2.x, r1.x, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(r2.P, r1.P, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(r2.innovation, r1.innovation, rtol=1e-12, atol=1e-14)
        assert r2.nis == pytest.approx(r1.nis, rel=1e-10)
    # a missing component or an R entry <= 0 leaves the compiled path untouched: the general
    # update drops the NaN component, and refuses the non-positive R
    zn = np.array([np.nan, z[0, 1]])
    x_b, P_b = fast.x.copy(), fast.P.copy()
    r3, r4 = fast.update(zn, H, R), slow.update(zn, H, R)
    assert np.isnan(r3.innovation[0]) and r3.used.tolist() == [False, True]
    np.testing.assert_allclose(r3.x, r4.x, rtol=1e-10, atol=1e-14)
    assert not np.array_equal(r3.P, P_b) and not np.array_equal(r3.x, x_b)
    x_b, P_b = fast.x.copy(), fast.P.copy()
    with pytest.raises(ValueError, match="R"):
        fast.update(z[0], H, np.array([R[0, 0], -1.0]))
    assert np.array_equal(fast.x, x_b) and np.array_equal(fast.P, P_b)
    r2 = fast.update(z[2], H, R)
    P_keep, x_keep = r2.P.copy(), r2.x.copy()
    fast.predict_many(np.array([Phi, Phi]), np.array([Q, Q]), 1.0)
    fast.feedback()
    assert np.array_equal(r2.P, P_keep) and np.array_equal(r2.x, x_keep)
    assert fast.t == pytest.approx(7.0)


def test_a_callers_propagation_steps_the_fast_filter_and_its_lanes():
    """KalmanFilter.propagate / propagate_lanes: a caller's kernel steps x, c, P in place
    (one filter where it is, several stacked) and the filters' time advances as by
    predict; a filter with a history or checks is refused (its steps would go unrecorded)."""
    propagate_lanes = KalmanFilter.propagate_lanes
    _, _, Phi, Q, H, R, P0, rng = _model()
    x0 = rng.normal(size=6)

    def step(x, c, P, *work):                  # two steps of x <- Φx, P <- ΦPΦ' + Q
        for _ in range(2):
            x[...] = x @ Phi.T
            c[...] = c @ Phi.T
            P[...] = Phi @ P @ Phi.T + Q

    ref = KalmanFilter(x0, P0)
    for _ in range(2):
        ref.predict(Phi, Q, 0.5)
    one = KalmanFilter(x0, P0, check=False)
    one.propagate(step, 2, 0.5)
    lanes = [KalmanFilter(x0, P0, check=False) for _ in range(3)]
    propagate_lanes(lanes, step, 2, 0.5)
    for k in [one] + lanes:
        np.testing.assert_allclose(k.x, ref.x, rtol=1e-12)
        np.testing.assert_allclose(k.P, ref.P, rtol=1e-12)
        assert k.t == ref.t == 1.0
    with pytest.raises(ValueError, match="without history and checks"):
        KalmanFilter(x0, P0, history=3, check=False).propagate(step, 2, 0.5)
    with pytest.raises(ValueError, match="without history and checks"):
        propagate_lanes([KalmanFilter(x0, P0)], step, 2, 0.5)


def test_compiled_update_of_given_arrays_equals_the_numpy_update():
    """compiled_update (sequential scalar Joseph updates, compiled) against kalman.update for
    R given as a matrix, a vector and a scalar; where it does not apply (correlated R, a
    NaN in z, r <= 0) it returns None and leaves x, P as they were."""
    from sinslab.estimation.filter import compiled_update

    _, _, _, _, H, R, P0, rng = _model()
    x0 = rng.normal(size=6)
    z = rng.normal(size=2)
    ref = kf.update(x0, P0, z, H, R)
    for r in (R, np.diag(R).copy()):
        x, P = x0.copy(), P0.copy()
        res = compiled_update(x, P, z, H, r)
        np.testing.assert_allclose(res.x, ref.x, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(res.P, ref.P, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(res.innovation, ref.innovation, rtol=1e-12)
        np.testing.assert_allclose(res.S, ref.S, rtol=1e-12)
        assert res.nis == pytest.approx(ref.nis, rel=1e-10)
        assert np.array_equal(x, res.x) and x is not res.x          # in place, result a copy
    ref1 = kf.update(x0, P0, z, H, 0.3)
    res1 = compiled_update(x0.copy(), P0.copy(), z, H, 0.3)
    np.testing.assert_allclose(res1.P, ref1.P, rtol=1e-10, atol=1e-14)
    for zz, rr in ((z, R + 0.01 * np.ones((2, 2))), (np.array([np.nan, 1.0]), R),
                   (z, np.array([R[0, 0], 0.0]))):
        x, P = x0.copy(), P0.copy()
        assert compiled_update(x, P, zz, H, rr) is None
        assert np.array_equal(x, x0) and np.array_equal(P, P0)


@pytest.mark.parametrize("m", [1, 3, 4, 9])
def test_predict_many_with_history_is_predict_step_by_step(m):
    """A filter with a lag history stepped by predict_many keeps exactly what m single
    predict calls keep (x, P, c, time, σ out, and every stored epoch bit for bit), also
    when most of the stretch leaves the history before the call returns."""
    _, _, Phi, Q, H, R, P0, rng = _model()
    hist = 4
    Phis = np.array([Phi + 1e-3 * rng.normal(size=Phi.shape) for _ in range(m)])
    Qs = np.array([Q * (1 + k) for k in range(m)])
    one = KalmanFilter(rng.normal(size=6), P0, history=hist, check=False)
    many = KalmanFilter(one.x.copy(), P0, history=hist, check=False)
    for f in (one, many):          # a stored epoch with an update and a feedback (c ≠ 0)
        f.predict(Phi, Q, 1.0)
        f.update(np.full(2, 0.1), H, R)
        f.feedback([0, 1])
    sig_one, x_one = np.empty((m, 6)), np.empty((m, 6))
    for k in range(m):
        one.predict(Phis[k], Qs[k], 1.0)
        sig_one[k], x_one[k] = one.sigma, one.x
    sig_many, x_many = np.empty((m, 6)), np.empty((m, 6))
    many.predict_many(Phis, Qs, 1.0, sigma_out=sig_many, x_out=x_many)
    assert np.array_equal(one.x, many.x) and np.array_equal(one.P, many.P) and np.array_equal(one.c, many.c)
    assert np.any(many.c != 0)
    assert one.t == many.t and np.array_equal(sig_one, sig_many) and np.array_equal(x_one, x_many)
    assert len(one._buf) == len(many._buf)
    for a, b in zip(one._buf, many._buf):
        assert a.t == b.t
        for name in ("x", "P", "c", "Phi", "Q", "x_post", "P_post", "c_post"):
            va, vb = getattr(a, name, None), getattr(b, name, None)
            assert (va is None and vb is None) or np.array_equal(va, vb), name
    z = rng.normal(size=2)                                # a lagged update sees the same past
    ra = one.update_lagged(z, H, R, one.t - 2.0)
    rb = many.update_lagged(z, H, R, many.t - 2.0)
    assert np.array_equal(ra.x, rb.x) and np.array_equal(ra.P, rb.P)


def test_estimation_imports_nothing_from_the_ins():
    """Layering: the estimation modules know no INS (no import of sinslab.nav, fusion,
    methods or anything above, module level or function local)."""
    import ast
    import pathlib

    import sinslab.estimation as est
    allowed = ("sinslab.core", "sinslab.estimation")
    for path in sorted(pathlib.Path(est.__file__).parent.glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                mods = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                mods = [node.module]
            else:
                continue
            for mod in mods:
                if mod == "sinslab" or mod.startswith("sinslab."):
                    assert mod.startswith(allowed), f"{path.name} imports {mod}"


def test_transform_restarts_and_copies_states():
    """KalmanFilter.transform: a restart (row of A zero, its variance in Q) leaves the
    state uncorrelated with the others; a copy (a row of A forming a linear combination)
    carries the combination's covariance exactly, P <- A P Aᵀ + Q; a filter with a history
    for lagged updates refuses a transform."""
    from sinslab.estimation.filter import KalmanFilter
    rng = np.random.default_rng(3)
    A0 = rng.normal(size=(5, 5))
    P0 = A0 @ A0.T + np.eye(5)
    x0 = rng.normal(size=5)
    kf = KalmanFilter(x0, P0)
    A = np.eye(5)
    A[4] = 0.0
    A[4, :2] = [1.0, -2.0]                   # state 4 <- x0 − 2 x1
    A[3, 3] = 0.0                            # state 3 restarted
    Q = np.zeros((5, 5))
    Q[3, 3] = 100.0
    kf.transform(A, Q)
    assert np.allclose(kf.x, A @ x0) and np.allclose(kf.P, A @ P0 @ A.T + Q)
    assert np.allclose(kf.P[3, [0, 1, 2, 4]], 0.0) and kf.P[3, 3] == 100.0
    v = np.array([1.0, -2.0, 0, 0, 0])
    assert np.isclose(kf.P[4, 4], v @ P0 @ v) and np.allclose(kf.P[4, :3], (P0 @ v)[:3])
    with pytest.raises(ValueError, match="lagged updates"):
        KalmanFilter(x0, P0, history=3).transform(A, Q)


def test_feedback_of_every_state_equals_the_indexed_feedback_bit_for_bit():
    """``feedback()`` (every state) returns, zeroes and accumulates in ``c`` exactly what
    the indexed form does with all the indices, and what a caller's subset leaves alone
    stays (the amounts are zero outside it)."""
    rng = np.random.default_rng(7)
    x0 = np.r_[rng.normal(size=7), -0.0, np.nan]
    P0 = np.eye(9)
    a, b = KalmanFilter(x0, P0), KalmanFilter(x0, P0)
    for f in (a, b):
        f._c[:] = rng.normal(size=9) if f is a else a._c       # the same cumulative feedback
    da, db = a.feedback(), b.feedback(np.arange(9))
    for u, v in ((da, db), (a.x, b.x), (a.c, b.c)):
        assert np.array_equal(u.view(np.int64), v.view(np.int64))
    assert np.array_equal(da.view(np.int64), x0.view(np.int64)) and not np.any(a.x)
    c = KalmanFilter(x0, P0)
    d = c.feedback(np.array([0, 3]))
    assert d[1] == 0.0 and c.x[1] == x0[1] and c.x[0] == 0.0 and d[3] == x0[3]
