"""Oracles for sinslab.estimation.smoother (Rauch–Tung–Striebel backward pass).

* batch least squares over the whole record (the smoothed estimate is the
  conditional mean of all states given all measurements; the RTS recursion, Rauch,
  Tung & Striebel 1965, is one way of computing it);
* the two-filter smoother (forward filter combined with a backward information
  filter, Fraser & Potter 1969), an independent algorithm;
* Monte Carlo: smoothed RMS / smoothed σ inside the chi-square band;
* closed-loop (feedback) form equal to the open-loop form on a linear system.
"""
from pathlib import Path

import numpy as np
import pytest
from scipy import linalg as sla
from scipy import stats

from sinslab.estimation import kalman as kf
from sinslab.core.blocks import release_pages
from sinslab.estimation.smoother import rts_smooth, storage_bytes


# ----------------------------------------------------------------------------------------
# a linear time-varying system and its forward filter
# ----------------------------------------------------------------------------------------
def _ltv(n=4, m=2, K=30, seed=0, q_zero=(), p0_zero=(), missing=0.3):
    """Random stable LTV system: Phi_k = expm(F_k), Q_k, H_k, R_k per step, and a mask
    of available measurements (epochs 0..K). States in ``q_zero`` are random constants
    (no process noise); states in ``p0_zero`` are also known exactly at the start."""
    rng = np.random.default_rng(seed)
    Phi, Q, H, R = [], [], [], []
    for _ in range(K):
        F = rng.normal(scale=0.3, size=(n, n)) - 0.3 * np.eye(n)
        Phi.append(sla.expm(F))
        G = rng.normal(scale=0.3, size=(n, n))
        Qk = G @ G.T + 0.01 * np.eye(n)
        for j in q_zero:
            Qk[j, :] = 0.0
            Qk[:, j] = 0.0
        for j in q_zero:
            Phi[-1][j, :] = 0.0
            Phi[-1][j, j] = 1.0          # random constant: x_j(k+1) = x_j(k)
        Q.append(Qk)
    for _ in range(K + 1):
        H.append(rng.normal(size=(m, n)))
        R.append(np.diag(rng.uniform(0.05, 0.5, m)))
    avail = rng.random(K + 1) > missing
    avail[-1] = True
    B = rng.normal(scale=0.5, size=(n, n))
    P0 = B @ B.T + 0.5 * np.eye(n)
    for j in p0_zero:
        P0[j, :] = 0.0
        P0[:, j] = 0.0
    return dict(Phi=np.array(Phi), Q=np.array(Q), H=np.array(H), R=np.array(R), avail=avail,
                P0=P0, m0=np.zeros(n), rng=rng, n=n, K=K)


def _factor(C):
    """G with G G^T = C for a positive semi-definite C (columns for the nonzero modes)."""
    w, V = np.linalg.eigh(0.5 * (C + C.T))
    keep = w > 1e-14 * max(w.max(), 1e-300)
    return V[:, keep] * np.sqrt(w[keep])


def _simulate(s, rng):
    n, K = s["n"], s["K"]
    x = np.empty((K + 1, n))
    x[0] = s["m0"] + _factor(s["P0"]) @ rng.normal(size=_factor(s["P0"]).shape[1])
    for k in range(K):
        G = _factor(s["Q"][k])
        x[k + 1] = s["Phi"][k] @ x[k] + G @ rng.normal(size=G.shape[1])
    z = np.full((K + 1, s["H"].shape[1]), np.nan)
    for k in range(K + 1):
        if s["avail"][k]:
            z[k] = s["H"][k] @ x[k] + np.sqrt(np.diag(s["R"][k])) * rng.normal(size=z.shape[1])
    return x, z


def _forward(s, z, fb_idx=None, fb_every=1):
    """Forward Kalman filter (sinslab.estimation.kalman.predict/update). With
    ``fb_idx`` it runs closed loop: the estimate of those states is fed back at every
    ``fb_every``-th epoch, the measurement is that of the corrected system
    (``z - H C``), and the history is stored as rts_smooth expects."""
    n, K = s["n"], s["K"]
    xpost, Ppost = np.empty((K + 1, n)), np.empty((K + 1, n, n))
    xprior, Pprior = np.empty((K, n)), np.empty((K, n, n))
    d = np.zeros((K + 1, n))
    C = np.zeros((K + 1, n))          # accumulated correction before feedback at k (eq. 8)
    x, P = s["m0"].copy(), s["P0"].copy()
    c = np.zeros(n)
    for k in range(K + 1):
        if k > 0:
            x, P = kf.predict(x, P, s["Phi"][k - 1], s["Q"][k - 1])
            c = s["Phi"][k - 1] @ c
            xprior[k - 1], Pprior[k - 1] = x, P
        C[k] = c
        if s["avail"][k]:
            x, P, _, _ = kf.update(x, P, z[k] - s["H"][k] @ c, s["H"][k], s["R"][k])
        xpost[k], Ppost[k] = x, P
        if fb_idx is not None and k % fb_every == 0:
            d[k, fb_idx] = x[fb_idx]
            x = x - d[k]
            c = c + d[k]
    return dict(xpost=xpost, Ppost=Ppost, xprior=xprior, Pprior=Pprior, d=d, C=C)


# ----------------------------------------------------------------------------------------
# independent smoothers
# ----------------------------------------------------------------------------------------
def _batch(s, z):
    """Batch least squares over the whole record in information form.

    Unknowns ξ = (u, w_0..w_{K-1}) ~ N(0, I) with x_0 = m0 + L0 u and
    x_{k+1} = Phi_k x_k + G_k w_k (L0 L0^T = P0, G_k G_k^T = Q_k, so singular P0 and Q
    are allowed); x_k = m_k + T_k ξ. The posterior of ξ given every measurement has
    information J = I + Σ (H_k T_k)^T R_k^-1 H_k T_k; mean and covariance of x_k follow."""
    n, K = s["n"], s["K"]
    L0 = _factor(s["P0"])
    Gs = [_factor(Qk) for Qk in s["Q"]]
    dims = [L0.shape[1]] + [G.shape[1] for G in Gs]
    off = np.concatenate([[0], np.cumsum(dims)])
    N = off[-1]
    T = np.zeros((K + 1, n, N))
    mk = np.zeros((K + 1, n))
    T[0][:, off[0]:off[1]] = L0
    mk[0] = s["m0"]
    for k in range(K):
        T[k + 1] = s["Phi"][k] @ T[k]
        T[k + 1][:, off[k + 1]:off[k + 2]] += Gs[k]
        mk[k + 1] = s["Phi"][k] @ mk[k]
    J = np.eye(N)
    b = np.zeros(N)
    for k in range(K + 1):
        if s["avail"][k]:
            HT = s["H"][k] @ T[k]
            Ri = np.linalg.inv(s["R"][k])
            J += HT.T @ Ri @ HT
            b += HT.T @ Ri @ (z[k] - s["H"][k] @ mk[k])
    cf = sla.cho_factor(J)
    xi = sla.cho_solve(cf, b)
    Jinv = sla.cho_solve(cf, np.eye(N))
    x = mk + np.einsum("kin,n->ki", T, xi)
    P = np.einsum("kin,nm,kjm->kij", T, Jinv, T)
    return x, P


def _two_filter(s, z, fwd):
    """Two-filter smoother: the forward filter's x_{k|k}, P_{k|k} combined with a
    backward information filter of the measurements after epoch k.

    Backward filter (information Y, vector y about x_k from z_{k+1..K}):
    update Y <- Y + H^T R^-1 H, y <- y + H^T R^-1 z; step back through
    x_{k+1} = Phi x_k + w: Y <- Phi^T (I + Y Q)^-1 Y Phi, y <- Phi^T (I + Y Q)^-1 y
    (no inverse of Q, Phi or Y needed). Combination with the forward filter:
    P_s = (I + P Y)^-1 P, x_s = (I + P Y)^-1 (x + P y)."""
    n, K = s["n"], s["K"]
    I = np.eye(n)
    Y = np.zeros((n, n))
    y = np.zeros(n)
    xs, Ps = np.empty((K + 1, n)), np.empty((K + 1, n, n))
    for k in range(K, -1, -1):
        P, x = fwd["Ppost"][k], fwd["xpost"][k]
        W = np.linalg.solve(I + P @ Y, np.column_stack([P, x + P @ y]))
        Ps[k], xs[k] = W[:, :n], W[:, n]
        if k == 0:
            break
        if s["avail"][k]:
            Ri = np.linalg.inv(s["R"][k])
            Y = Y + s["H"][k].T @ Ri @ s["H"][k]
            y = y + s["H"][k].T @ Ri @ z[k]
        Phi, Qk = s["Phi"][k - 1], s["Q"][k - 1]
        E = np.linalg.solve(I + Y @ Qk, np.column_stack([Y, y]))
        Y = Phi.T @ E[:, :n] @ Phi
        Y = 0.5 * (Y + Y.T)
        y = Phi.T @ E[:, n]
    return xs, Ps


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def _smooth(f, **kw):
    return rts_smooth(f["xpost"], f["Ppost"], f["xprior"], f["Pprior"], kw.pop("Phi"), **kw)


# ----------------------------------------------------------------------------------------
# tests
# ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_equals_batch_least_squares_and_two_filter(seed):
    s = _ltv(seed=seed)
    _, z = _simulate(s, s["rng"])
    f = _forward(s, z)
    r = _smooth(f, Phi=s["Phi"])
    xb, Pb = _batch(s, z)
    assert _rel(r.x, xb) < 1e-9
    assert _rel(r.P, Pb) < 1e-9
    x2, P2 = _two_filter(s, z, f)
    assert _rel(r.x, x2) < 1e-9
    assert _rel(r.P, P2) < 1e-9
    np.testing.assert_allclose(r.sigma, np.sqrt(np.einsum("kii->ki", Pb)), rtol=1e-9)
    assert not r.dropped.any()
    # every measurement adds information: smoothed σ <= forward σ at every epoch
    sf = np.sqrt(np.einsum("kii->ki", f["Ppost"]))
    assert np.all(r.sigma <= sf * (1 + 1e-12))
    assert np.all(r.sigma[:-5] < sf[:-5])       # strictly, away from the record end
    np.testing.assert_array_equal(r.x[-1], f["xpost"][-1])


def test_singular_prediction_random_constants_and_exactly_known_state():
    """State 2 is a random constant (Q = 0), state 3 a constant known exactly
    (P0 = 0, Q = 0): P_{k+1|k} is singular at every step; the guarded gain (the
    generalised-inverse form) still gives the batch solution."""
    s = _ltv(n=4, K=40, seed=3, q_zero=(2, 3), p0_zero=(3,))
    _, z = _simulate(s, s["rng"])
    f = _forward(s, z)
    assert np.all(f["Pprior"][:, 3, 3] == 0.0)
    r = _smooth(f, Phi=s["Phi"])
    assert np.all(r.dropped >= 1)
    xb, Pb = _batch(s, z)
    assert _rel(r.x, xb) < 1e-9
    assert _rel(r.P, Pb) < 1e-9
    assert np.all(r.P[:, 3, :] == 0.0)
    # the random constant is one value over the whole record, smoothed from all data
    assert np.ptp(r.x[:, 2]) < 1e-9 * np.max(np.abs(r.x[:, 2]))
    np.testing.assert_allclose(r.sigma[:, 2], r.sigma[-1, 2], rtol=1e-9)


def test_rank_deficient_prediction_from_perfectly_correlated_states():
    """Two states driven by the same noise and starting from one common value stay
    identical: P_{k+1|k} has an exact null direction (x0 - x1) that is not a single
    state; the pivot guard drops it and the result still matches batch LS."""
    s = _ltv(n=3, K=25, seed=4, missing=0.2)
    n = 3
    for k in range(s["K"]):
        Phi = s["Phi"][k]
        Phi[1] = Phi[0]                 # x1(k+1) = x0(k+1) whenever x0 = x1
        Phi[:, 0] += Phi[:, 1]
        Phi[:, 1] = 0.0
        G = np.zeros((n, 2))
        G[0, 0] = G[1, 0] = 0.4
        G[2, 1] = 0.3
        s["Q"][k] = G @ G.T
    J = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    s["P0"] = J @ np.array([[1.0, 0.3], [0.3, 0.8]]) @ J.T
    _, z = _simulate(s, s["rng"])
    f = _forward(s, z)
    r = _smooth(f, Phi=s["Phi"])
    assert np.all(r.dropped == 1)
    xb, Pb = _batch(s, z)
    assert _rel(r.x, xb) < 1e-9
    assert _rel(r.P, Pb) < 1e-9


@pytest.mark.parametrize("fb_every", [1, 3])
def test_closed_loop_equals_open_loop(fb_every):
    """Feedback of states 0, 1, 3 (not 2): x_{k|K} + C_k (eq. 8, accumulated
    correction) equals the open-loop smoothed estimate, and x_corrected = x - d_k."""
    s = _ltv(n=4, K=30, seed=5)
    _, z = _simulate(s, s["rng"])
    fo = _forward(s, z)
    fc = _forward(s, z, fb_idx=[0, 1, 3], fb_every=fb_every)
    np.testing.assert_allclose(fc["xpost"] + fc["C"], fo["xpost"], rtol=0, atol=1e-12)
    ro = _smooth(fo, Phi=s["Phi"])
    rc = _smooth(fc, Phi=s["Phi"], feedback=fc["d"])
    assert _rel(rc.x + fc["C"], ro.x) < 1e-10
    assert _rel(rc.x_corrected + fc["C"] + fc["d"], ro.x) < 1e-10
    assert _rel(rc.P, ro.P) < 1e-12
    # x_prior may be left for the smoother to form from x_post, feedback and Phi
    rn = rts_smooth(fc["xpost"], fc["Ppost"], None, fc["Pprior"], s["Phi"], feedback=fc["d"])
    assert _rel(rn.x, rc.x) < 1e-12
    # the history of a closed-loop run without its corrections is refused
    with pytest.raises(ValueError, match="feedback"):
        _smooth(fc, Phi=s["Phi"])
    # the tempting mix: the zeroed post-feedback states as x_{k|k} (consistent with eq. 3
    # without feedback, so accepted) drop d_{k+1} at every step
    mix = rts_smooth(fc["xpost"] - fc["d"], fc["Ppost"], fc["xprior"], fc["Pprior"], s["Phi"])
    off = _rel(mix.x, rc.x_corrected)
    assert off > 0.1
    if fb_every == 1:
        from support import assert_doc_quotes

        assert_doc_quotes("docs/methods/smoother.md", "test system with feedback at every epoch it is off by 33 % of "
                          "the smoothed estimate", [100 * off])


def test_monte_carlo_smoothed_rms_matches_sigma():
    """500 runs of one LTV system (same matrices, new noise): per state and epoch the
    sum of (x_{k|K} - x_k)^2 / σ_{k|K}^2 is chi-square with 500 degrees of freedom;
    RMS/σ inside the two-sided band at 1e-3 overall (Bonferroni over states x epochs)."""
    s = _ltv(n=3, m=1, K=40, seed=6)
    N = 500
    rng = np.random.default_rng(60)
    q = np.zeros((s["K"] + 1, s["n"]))
    qf = np.zeros_like(q)
    sig = None
    for _ in range(N):
        x, z = _simulate(s, rng)
        f = _forward(s, z)
        r = rts_smooth(f["xpost"], f["Ppost"], f["xprior"], f["Pprior"], s["Phi"],
                       covariance="diag")
        sig = r.sigma
        q += ((r.x - x) / r.sigma) ** 2
        qf += ((f["xpost"] - x) / r.sigma) ** 2
    ntest = q.size
    alpha = 1e-3 / ntest
    lo = np.sqrt(stats.chi2.ppf(alpha / 2, N) / N)
    hi = np.sqrt(stats.chi2.ppf(1 - alpha / 2, N) / N)
    ratio = np.sqrt(q / N)
    assert np.all((ratio > lo) & (ratio < hi)), (ratio.min(), ratio.max(), lo, hi)
    # the test has power: the forward errors measured against the smoothed σ are out
    # of the band in the middle of the record
    assert np.max(np.sqrt(qf[: s["K"] // 2] / N)) > hi
    assert sig.shape == (s["K"] + 1, s["n"])


def test_chunked_memmap_input_gives_identical_numbers(tmp_path):
    s = _ltv(seed=7, K=50)
    _, z = _simulate(s, s["rng"])
    f = _forward(s, z)
    r1 = _smooth(f, Phi=s["Phi"])
    mm = {}
    for key in ("xpost", "Ppost", "xprior", "Pprior"):
        a = np.lib.format.open_memmap(tmp_path / f"{key}.npy", mode="w+", shape=f[key].shape)
        a[:] = f[key]
        mm[key] = a
    r2 = rts_smooth(mm["xpost"], mm["Ppost"], mm["xprior"], mm["Pprior"], s["Phi"], chunk=7)
    np.testing.assert_array_equal(r1.x, r2.x)
    np.testing.assert_array_equal(r1.P, r2.P)
    r3 = _smooth(f, Phi=s["Phi"], covariance="diag")
    assert r3.P is None
    np.testing.assert_array_equal(r3.sigma, r1.sigma)


def test_bad_input_one_clear_error():
    s = _ltv(seed=8, K=10)
    _, z = _simulate(s, s["rng"])
    f = _forward(s, z)
    with pytest.raises(ValueError, match="P_prior must have shape"):
        rts_smooth(f["xpost"], f["Ppost"], f["xprior"], f["Pprior"][:-1], s["Phi"])
    bad = f["Ppost"].copy()
    bad[4, 1, 2] = np.nan
    with pytest.raises(ValueError, match="P_post has a NaN/inf element at epoch 4"):
        rts_smooth(f["xpost"], bad, f["xprior"], f["Pprior"], s["Phi"])
    with pytest.raises(ValueError, match="covariance must be"):
        _smooth(f, Phi=s["Phi"], covariance="upper")


def test_storage_size_of_one_hour():
    # 21 states, 10 Hz for 1 h: 36 001 epochs of 3 n^2 + 3 n float64
    assert storage_bytes(21, 36001) == 36001 * (3 * 441 + 63) * 8



def _mapped_kb(folder):
    """Resident pages [kB] of this process' mappings of files in ``folder``."""
    kb, ours = 0, False
    with open("/proc/self/smaps") as fh:
        for ln in fh:
            head = ln.split()
            if head and "-" in head[0] and len(head) >= 5:           # a mapping's first line
                ours = len(head) >= 6 and head[5].startswith(str(folder))
            elif ours and ln.startswith("Rss:"):
                kb += int(head[1])
    return kb


class _Watched:
    """An array-like over a memory map that notes the resident pages of the record each
    time the smoother reads a chunk (their peak over the backward pass)."""

    def __init__(self, a, peak, folder):
        self.a, self.peak, self.folder, self.shape = a, peak, folder, a.shape

    def __getitem__(self, key):
        out = self.a[key]
        self.peak[0] = max(self.peak[0], _mapped_kb(self.folder))
        return out

    def release_pages(self):
        release_pages(self.a)


@pytest.mark.skipif(not Path("/proc/self/smaps").exists(), reason="reads /proc/self/smaps")
def test_spilled_record_holds_one_chunk_whatever_its_length(tmp_path):
    """A record memory-mapped on disk is walked backwards a chunk at a time and each chunk's
    pages are let go: the record's resident memory at its peak is the same for a record 8
    times longer (without the release it is the whole record: all of it is read)."""
    n, chunk = 15, 256
    chunk_kb = chunk * 3 * n * n * 8 / 1024
    peaks = []
    for K in (1000, 8000):
        folder = tmp_path / str(K)
        folder.mkdir()
        arrs = {}
        for name, shape in (("xpo", (K + 1, n)), ("Ppo", (K + 1, n, n)), ("Ppr", (K, n, n)),
                            ("Phi", (K, n, n))):
            arrs[name] = np.lib.format.open_memmap(folder / f"{name}.npy", mode="w+",
                                                   dtype=float, shape=shape)
        arrs["xpo"][:] = 0.0
        arrs["Ppo"][:] = np.eye(n)
        arrs["Ppr"][:] = 2.0 * np.eye(n)
        arrs["Phi"][:] = np.eye(n)
        release_pages(*arrs.values())            # written by the forward pass, let go
        peak = [0]
        s = rts_smooth(arrs["xpo"], _Watched(arrs["Ppo"], peak, folder), None,
                       _Watched(arrs["Ppr"], peak, folder), _Watched(arrs["Phi"], peak, folder),
                       covariance="diag", check=False, chunk=chunk)
        # Φ = I, P_post = I, P_prior = 2 I: gain I/2, P_s = I + (P_s' − 2 I)/4 -> 2/3 I far from the end
        assert np.allclose(s.sigma[0], np.sqrt(2 / 3)) and np.allclose(s.sigma[-1], 1.0)
        peaks.append(peak[0])
        del arrs
    assert peaks[1] < 3 * chunk_kb                       # a chunk or two, not the record
    assert peaks[1] - peaks[0] < chunk_kb                # the same for a record 8 times longer
