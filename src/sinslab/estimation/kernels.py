"""The compiled Kalman kernels: covariance and state prediction, the series
discretisation of an error model, scalar and vector Joseph updates, the fixed-gain update.

Every compiled filter loop of the package steps with these kernels — the stepped
:class:`sinslab.estimation.filter.KalmanFilter` (:func:`cov_predict`,
:func:`predict_steps`, :func:`sequential_update`, also when it re-processes a lagged
measurement), the linear time loops of :mod:`sinslab.estimation.linear` (their covariance
recursion gives the gains of the filters whose covariance does not depend on the data, and
:func:`~sinslab.estimation.linear.fixed_gain_runs` runs those filters), the fused model +
discretisation + prediction of :mod:`sinslab.fusion.propagate` and the recording prediction
of :mod:`sinslab.fusion.smoothing` (:func:`predict_step`), and the methods' own loops over
many runs: transfer alignment's common-gain lanes and per-lane EKFs
(:func:`state_predict_dense`, :func:`innovation`, :func:`gain_correct`,
:func:`predict_lanes`, :func:`sequential_update_lanes`), the rotation-evaluation campaign, double-star's
stored-state update and the Monte Carlo of a linear system — so one epoch of prediction or
update has one arithmetic wherever it runs. Scalar style, no array temporaries inside a
time loop; the work arrays are the caller's.

Shapes: ``n`` states, ``P`` (n, n) C-contiguous float64, stepped in place; ``Φ`` (n, n);
row lists ``nzc`` (n, ≥1) int with counts ``nnz`` (n,) name the non-zero columns of each
row of Φ (:func:`row_nonzeros`).

Block-diagonal tail
-------------------
In the error models of an INS the sensor states come last and, without navigation
coupling among themselves, evolve each by its own scalar: a random constant (Φ_ii = 1)
or a first-order Gauss–Markov process (Φ_ii = 1 − T/τ + ...). With the rows ``r..n−1``
of Φ diagonal, ``Φ P Φᵀ`` splits into ``Φ[:r] P Φ[:r]ᵀ`` (the one dense part, r × r),
``(Φ[:r] P)[i, j] Φ_jj`` (i < r <= j) and ``Φ_ii P_ij Φ_jj`` (i, j >= r): for KF-GINS'
21-state model r = 9 and the products cost 5.7 k multiply-adds instead of 18.5 k.
:func:`diagonal_tail` finds r from a pattern; r = n is the general case.

Unsigned indices
----------------
numba lets an array be indexed from its end with a negative index, so every access with
a signed index that it cannot prove non-negative tests the sign and adds the dimension.
An index read from a table of places (``nzc``, ``fcol``, ``grow``, ``R``, ...) is never
negative, and neither is a loop counter from 0: the loops of the prediction cast them to
``np.uint64``, which indexes without the test. The arithmetic is the same, so are the
numbers; the fused prediction of KF-GINS' 21-state model
(:mod:`sinslab.fusion.propagate`) runs ~20 % faster for it.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sinslab.core.jitnotice import install as _compile_notice

_compile_notice()   # a status line while the kernels below compile (first run)

__all__ = ["cov_predict", "state_predict", "predict_step", "predict_step_sparse_x", "predict_steps", "predict_steps_dense",
           "predict_lanes", "scalar_update", "sequential_update", "sequential_update_lanes", "vector_update",
           "predicted_dense", "state_predict_dense", "innovation", "gain_correct", "innovation_cov", "row_nonzeros", "copy2",
           "diagonal_tail", "series_structure", "series_phi", "series_qbar", "series_qk",
           "series_step", "add_half_qbar"]


# ----------------------------------------------------------------------------------------
# prediction
# ----------------------------------------------------------------------------------------
@njit(cache=True)
def cov_predict(P, Phi, Q, r, T1, W):
    """``P <- Φ P Φᵀ + Q`` in place, exactly symmetric, for a Φ whose rows ``r..n−1`` are
    diagonal (``r = n``: any Φ; see the module notes).

    Parameters
    ----------
    P : ndarray (n, n)
        Covariance, stepped in place.
    Phi, Q : ndarray (n, n)
        Transition and process noise (Q symmetric to rounding; its two halves averaged).
    r : int
        Rows ``r..n−1`` of Φ hold only their diagonal entry.
    T1 : ndarray (n, n)
        Work array.
    W : ndarray (r, r)
        Work array.

    Two BLAS products on the dense rows, called from compiled code (no Python per step):
    measured faster than scalar loops over the zeros of Φ for every n from 2 to 40, and
    with r = n the arithmetic of a dense ``Φ P Φᵀ``."""
    n = P.shape[0]
    if r > 0:
        A = Phi[:r]
        T1r = T1[:r]
        np.dot(A, P, T1r)
        np.dot(T1r, A.T, W)
    ur, un = np.uint64(r), np.uint64(n)        # unsigned: see the module notes
    for i in range(ur):
        for j in range(i, ur):
            v = 0.5 * (W[i, j] + W[j, i] + Q[i, j] + Q[j, i])
            P[i, j] = v
            P[j, i] = v
        for j in range(ur, un):
            v = T1[i, j] * Phi[j, j] + 0.5 * (Q[i, j] + Q[j, i])
            P[i, j] = v
            P[j, i] = v
    for i in range(ur, un):
        di = Phi[i, i]
        for j in range(i, un):
            v = di * P[i, j] * Phi[j, j] + 0.5 * (Q[i, j] + Q[j, i])
            P[i, j] = v
            P[j, i] = v


@njit(cache=True)
def state_predict(x, Phi, nzc, nnz, tmp):
    """x <- Φ x in place over the non-zero columns ``nzc[i, :nnz[i]]`` of each row;
    ``tmp`` (n,) work array."""
    n = np.uint64(x.shape[0])
    for i in range(n):
        s = 0.0
        for a in range(nnz[i]):
            k = np.uint64(nzc[i, a])
            s += Phi[i, k] * x[k]
        tmp[i] = s
    for i in range(n):
        x[i] = tmp[i]


@njit(cache=True, inline="always")
def predicted_dense(x, Phi, out):
    """``out <- Φ x`` over every column of Φ (n, n), each sum in column order (``out`` not
    ``x``). The same numbers as :func:`state_predict` wherever x is finite (a product with
    a zero of Φ adds ±0), for the per-run loops where Φ's rows are mostly full and the row
    lists would cost more than they skip."""
    n = x.shape[0]
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += Phi[i, j] * x[j]
        out[i] = s


@njit(cache=True, inline="always")
def state_predict_dense(x, Phi, tmp):
    """``x <- Φ x`` in place by :func:`predicted_dense`; ``tmp`` (n,) a work array."""
    predicted_dense(x, Phi, tmp)
    for i in range(x.shape[0]):
        x[i] = tmp[i]


@njit(cache=True, inline="always")
def _predict_xc(x, c, P, Phi, Q, r, nzc, nnz, T1, W, tmp):
    """``P`` by :func:`cov_predict`, then ``x`` and ``c`` by :func:`state_predict`; returns
    whether x is zero (then left as +0.0 everywhere, the product skipped)."""
    n = x.shape[0]
    cov_predict(P, Phi, Q, r, T1, W)
    # closed loop: the estimate is zero from one update's feedback to the next update, and
    # Φ·0 is +0.0 in every component (Φ finite): the product is skipped, the same numbers
    zero = True
    for j in range(n):
        if x[j] != 0.0:
            zero = False
            break
    if zero:
        for j in range(n):
            x[j] = 0.0
    else:
        state_predict(x, Phi, nzc, nnz, tmp)
    state_predict(c, Phi, nzc, nnz, tmp)
    return zero


@njit(cache=True)
def predict_step(x, c, P, Phi, Q, r, nzc, nnz, T1, W, tmp, sig, xo):
    """One filter prediction: ``P`` by :func:`cov_predict`, then the estimate ``x`` and the
    cumulative feedback ``c`` (n,) by :func:`state_predict`, in that order; σ = sqrt(diag P)
    and x after the step into the rows ``sig``, ``xo`` (n,)."""
    _predict_xc(x, c, P, Phi, Q, r, nzc, nnz, T1, W, tmp)
    for j in range(x.shape[0]):
        sig[j] = math.sqrt(max(P[j, j], 0.0))
        xo[j] = x[j]


@njit(cache=True)
def predict_step_sparse_x(x, c, P, Phi, Q, r, nzc, nnz, T1, W, tmp, sig, xo):
    """:func:`predict_step` into an ``xo`` row that holds zeros on entry, written only where
    x is not zero: the record of a closed-loop filter, whose estimate is zero at every epoch
    without an update, stays untouched memory (never faulted in) but for those epochs."""
    zero = _predict_xc(x, c, P, Phi, Q, r, nzc, nnz, T1, W, tmp)
    n = np.uint64(x.shape[0])
    for j in range(n):
        sig[j] = math.sqrt(max(P[j, j], 0.0))
    if not zero:
        for j in range(n):
            xo[j] = x[j]


@njit(cache=True)
def predict_lanes(X, Ps, Phi, Q, r, nzc, nnz, T1, W, tmp):
    """One prediction of L filters (lanes) with a common ``Φ``, ``Q``: each covariance
    ``Ps[l]`` (n, n) by :func:`cov_predict`, each estimate ``X[l]`` (n,) by
    :func:`state_predict`, in place (``r``, ``nzc``, ``nnz``, work arrays as there)."""
    for l in range(X.shape[0]):
        cov_predict(Ps[l], Phi, Q, r, T1, W)
        state_predict(X[l], Phi, nzc, nnz, tmp)


@njit(cache=True)
def predict_steps(x, c, P, Phis, Qs, nzc, nnz, T1, T2, tmp, sig_out, x_out):
    """``m`` :func:`predict_step` steps with ``Phis``, ``Qs`` (m, n, n) and their row lists
    ``nzc`` (m, n, n), ``nnz`` (m, n); σ and x after step i into row i of ``sig_out``,
    ``x_out`` (m, n)."""
    n = x.shape[0]
    for i in range(Phis.shape[0]):
        predict_step(x, c, P, Phis[i], Qs[i], n, nzc[i], nnz[i], T1, T2, tmp, sig_out[i], x_out[i])


@njit(cache=True)
def predict_steps_dense(x, c, P, Phis, Qs, m, T1, T2, sig_out, x_out):
    """The first ``m`` steps of :meth:`~sinslab.estimation.filter.KalmanFilter.predict`'s arithmetic in one compiled
    loop: ``P`` by :func:`cov_predict`, ``x`` and ``c`` by the BLAS product ``Φ @ x``
    that numpy uses (same bits); σ and x after each step into ``sig_out``, ``x_out``."""
    n = x.shape[0]
    for i in range(m):
        cov_predict(P, Phis[i], Qs[i], n, T1, T2)
        # element loops rather than x[:] = ...: the slice assignment alone costs numba
        # ~2.5 s more to compile
        y = Phis[i] @ x
        for j in range(n):
            x[j] = y[j]
        y = Phis[i] @ c
        for j in range(n):
            c[j] = y[j]
        for j in range(n):
            sig_out[i, j] = math.sqrt(max(P[j, j], 0.0))
            x_out[i, j] = x[j]


@njit(cache=True)
def add_half_qbar(P, Qb, h, R, nr, qbr, qbn, Qh):
    """``Qh[R[a], R[b]] = h Q̄[a, b]`` over the pattern of Q̄ (``Qb`` in the places of
    :func:`series_structure`; ``Qh`` (n, n) zero elsewhere) and ``P += Qh``.

    With ``h = T/2``, then :func:`predict_step` with ``Q = Qh`` steps
    ``P <- Φ (P + h Q̄) Φᵀ + h Q̄``: the series ``Φ P Φᵀ + Q_k`` with ``Q_k = T (Q̄ + Φ Q̄ Φᵀ)/2``
    (:func:`series_qk`) without forming ``Φ Q̄ Φᵀ`` (equal to rounding)."""
    for b in range(nr):
        rb = np.uint64(R[b])
        for a_ in range(qbn[b]):
            a = np.uint64(qbr[b, a_])
            v = h * Qb[a, b]
            ra = np.uint64(R[a])
            Qh[ra, rb] = v
            P[ra, rb] += v


@njit(cache=True)
def diagonal_tail(nzc, nnz):
    """The smallest r such that every row ``i >= r`` of a pattern (row lists ``nzc`` (n, ·),
    counts ``nnz`` (n,)) holds at most its diagonal entry (n when the last row does not)."""
    n = nnz.shape[0]
    r = n
    while r > 0 and (nnz[r - 1] == 0 or (nnz[r - 1] == 1 and nzc[r - 1, 0] == r - 1)):
        r -= 1
    return r


@njit(cache=True)
def row_nonzeros(Phi_t, nzc, nnz):
    """Per matrix of ``Phi_t`` (L, n, n) and row, its non-zero columns ascending into
    ``nzc`` (L, n, ≥n) and their count into ``nnz`` (L, n)."""
    L, n, _ = Phi_t.shape
    for l in range(L):
        for i in range(n):
            c = 0
            for k in range(n):
                if Phi_t[l, i, k] != 0.0:
                    nzc[l, i, c] = k
                    c += 1
            nnz[l, i] = c


@njit(cache=True)
def copy2(dst, src):
    """dst[:, :] = src by elements (a slice assignment from an array compiles numba's
    shape-error message formatting: seconds on a first run)."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


# ----------------------------------------------------------------------------------------
# update
# ----------------------------------------------------------------------------------------
@njit(cache=True)
def _times_h(A, h, out):
    """out <- A h over the non-zeros of the row h (its zeros skipped, sums in column order)."""
    for i in range(A.shape[0]):
        t = 0.0
        for k in range(A.shape[1]):
            if h[k] != 0.0:
                t += A[i, k] * h[k]
        out[i] = t


@njit(cache=True)
def _scalar_gain(P, h, r, pht, kk):
    """pht <- P h and kk <- the gain P h / s of a scalar update; returns s = h P h + r."""
    n = P.shape[0]
    _times_h(P, h, pht)
    s = r
    for k in range(n):
        s += h[k] * pht[k]
    for i in range(n):
        kk[i] = pht[i] / s
    return s


@njit(cache=True)
def _joseph_scalar(P, h, r, pht, kk, bh, B):
    """P <- (I − k h) P (I − k h)^T + r k k^T in place (symmetrised), from pht = P h and
    the gain k of :func:`_scalar_gain`; B is a work array (n, n)."""
    n = P.shape[0]
    # B = (I - k h) P = P - k pht^T
    for i in range(n):
        for j in range(n):
            B[i, j] = P[i, j] - kk[i] * pht[j]
    _times_h(B, h, bh)
    # P = B (I - k h)^T + r k k^T = B - bh k^T + r k k^T
    for i in range(n):
        for j in range(n):
            P[i, j] = B[i, j] - bh[i] * kk[j] + r * kk[i] * kk[j]
    for i in range(n):
        for j in range(i + 1, n):
            t = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = t
            P[j, i] = t


@njit(cache=True)
def scalar_update(x, P, h, r, zi, with_x, pht, kk, bh, B):
    """Joseph-form scalar update in place. Returns (innovation, s).

    Callers pass ``with_x`` as a constant or not, and numba compiles this function once
    for each (``Literal[bool](True)``, ``Literal[bool](False)``, ``bool``): the covariance
    work lives in :func:`_scalar_gain` and :func:`_joseph_scalar`, compiled once, so
    only this small shell is compiled three times."""
    n = P.shape[0]
    s = _scalar_gain(P, h, r, pht, kk)
    nu = 0.0
    if with_x:
        hx = 0.0
        for k in range(n):
            hx += h[k] * x[k]
        nu = zi - hx
        for i in range(n):
            x[i] += kk[i] * nu
    _joseph_scalar(P, h, r, pht, kk, bh, B)
    return nu, s


@njit(cache=True)
def _sequential(x, P, z, H, r, innov, sdiag, pht, kk, tmp, B):
    """:func:`sequential_update` with the caller's work arrays ``pht``, ``kk`` (n,)."""
    for c in range(z.shape[0]):
        if not (math.isfinite(z[c]) and r[c] > 0.0):
            return -1.0
    nis = 0.0
    for c in range(z.shape[0]):
        nu, s = scalar_update(x, P, H[c], r[c], z[c], True, pht, kk, tmp, B)
        innov[c] = nu
        sdiag[c] = s
        nis += nu * nu / s
    return nis


@njit(cache=True)
def sequential_update(x, P, z, H, r, innov, sdiag, tmp, B):
    """Sequential scalar updates in place; NIS. Returns −1 and leaves x, P alone when some
    z is not finite or some r not > 0 (the caller takes the general path)."""
    n = x.shape[0]
    return _sequential(x, P, z, H, r, innov, sdiag, np.empty(n), np.empty(n), tmp, B)


@njit(cache=True)
def sequential_update_lanes(X, Ps, Z, H, r, nis):
    """:func:`sequential_update` of L filters (lanes) at once, each with its own estimate
    ``X[l]`` (n,), covariance ``Ps[l]`` (n, n), measurement ``Z[l]`` (m,) and rows ``H[l]``
    (m, n), the variances ``r`` (m,) common; in place. NIS of each lane into ``nis`` (L,),
    −1 for a lane left alone (some z not finite: a stopped lane)."""
    L, n = X.shape
    m = Z.shape[1]
    innov = np.empty(m)
    sdiag = np.empty(m)
    pht = np.empty(n)
    kk = np.empty(n)
    tmp = np.empty(n)
    B = np.empty((n, n))
    for l in range(L):
        nis[l] = _sequential(X[l], Ps[l], Z[l], H[l], r, innov, sdiag, pht, kk, tmp, B)


# The fixed-gain kernels below (and the dense state prediction) are inlined into their callers: a
# run of a fixed-gain filter is a few hundred multiply-adds per step, and a call per step
# (its array views counted in and out) cost the per-run loops of paper 002's campaign a
# third of their time.
@njit(cache=True, inline="always")
def innovation(x, H, z, nu):
    """``nu <- z − H x``: the innovation (m,) of the rows ``H`` (m, n) against the estimate
    ``x`` (n,); each product summed in column order."""
    n = x.shape[0]
    for i in range(H.shape[0]):
        acc = 0.0
        for j in range(n):
            acc += H[i, j] * x[j]
        nu[i] = z[i] - acc


@njit(cache=True, inline="always")
def gain_correct(x, G, nu):
    """``x <- x + G nu`` in place: the update of a filter whose gain ``G`` (n, m) does not
    depend on the data (made once by a covariance recursion:
    :func:`sinslab.estimation.linear.propagate_covariance` with ``keep_gain``), from the
    innovation ``nu`` (m,) of :func:`innovation`."""
    m = nu.shape[0]
    for i in range(G.shape[0]):
        acc = 0.0
        for j in range(m):
            acc += G[i, j] * nu[j]
        x[i] = x[i] + acc


@njit(cache=True)
def innovation_cov(H, P, R, PHt, S):
    """``S <- H P Hᵀ + R`` (m, m), exactly symmetric: the covariance of the innovation of the
    rows ``H`` (m, n) against the prior ``P`` (n, n) with measurement noise ``R`` (m, m);
    ``PHt`` (n, m) a work array (receives ``P Hᵀ``)."""
    m, n = H.shape
    for i in range(n):
        for b in range(m):
            t = 0.0
            for j in range(n):
                t += P[i, j] * H[b, j]
            PHt[i, b] = t
    for a in range(m):
        for b in range(a, m):
            s = 0.0
            for i in range(n):
                s += H[a, i] * PHt[i, b]
            v = s + 0.5 * (R[a, b] + R[b, a])
            S[a, b] = v
            S[b, a] = v


@njit(cache=True)
def _matmul(A, B, C):
    """C <- A B by scalar loops, each sum in the order of the inner index."""
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            s = 0.0
            for k in range(A.shape[1]):
                s += A[i, k] * B[k, j]
            C[i, j] = s


@njit(cache=True)
def vector_update(x, P, H, R, z, used, with_x):
    """Joseph-form vector update over the used rows (correlated R). Returns (nu, S, nis, K),
    K (n, len(used)) the gain of the used rows.

    Scalar loops with a Cholesky factor of S (no LAPACK/BLAS bindings: they and their
    error formatting cost seconds of compilation on a first run)."""
    n = P.shape[0]
    mu = used.shape[0]
    Hu = np.empty((mu, n))
    Ru = np.empty((mu, mu))
    for a in range(mu):
        for j in range(n):
            Hu[a, j] = H[used[a], j]
        for b in range(mu):
            Ru[a, b] = R[used[a], used[b]]
    PHt = np.empty((n, mu))                  # P Huᵀ
    _matmul(P, Hu.T, PHt)
    S = np.empty((mu, mu))
    for a in range(mu):
        for b in range(mu):
            s = Ru[a, b]
            for j in range(n):
                s += Hu[a, j] * PHt[j, b]
            S[a, b] = s
    # S = L Lᵀ, then Sinv = L⁻ᵀ L⁻¹
    L = np.zeros((mu, mu))
    for a in range(mu):
        for b in range(a + 1):
            s = 0.5 * (S[a, b] + S[b, a])
            for c in range(b):
                s -= L[a, c] * L[b, c]
            if a == b:
                if not s > 0.0:
                    raise ValueError("innovation covariance is not positive definite")
                L[a, a] = math.sqrt(s)
            else:
                L[a, b] = s / L[b, b]
    Li = np.zeros((mu, mu))                  # L⁻¹
    for a in range(mu):
        Li[a, a] = 1.0 / L[a, a]
        for b in range(a):
            s = 0.0
            for c in range(b, a):
                s -= L[a, c] * Li[c, b]
            Li[a, b] = s / L[a, a]
    Sinv = np.zeros((mu, mu))
    for a in range(mu):
        for b in range(mu):
            s = 0.0
            for c in range(max(a, b), mu):
                s += Li[c, a] * Li[c, b]
            Sinv[a, b] = s
    K = np.empty((n, mu))
    _matmul(PHt, Sinv, K)
    nu = np.zeros(mu)
    nis = 0.0
    if with_x:
        for a in range(mu):
            s = z[used[a]]
            for j in range(n):
                s -= Hu[a, j] * x[j]
            nu[a] = s
        for i in range(n):
            s = 0.0
            for a in range(mu):
                s += K[i, a] * nu[a]
            x[i] += s
        for a in range(mu):
            for b in range(mu):
                nis += nu[a] * Sinv[a, b] * nu[b]
    # P <- (I − K H) P (I − K H)ᵀ + K R Kᵀ
    Am = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            s = 1.0 if i == j else 0.0
            for a in range(mu):
                s -= K[i, a] * Hu[a, j]
            Am[i, j] = s
    AP = np.empty((n, n))
    _matmul(Am, P, AP)
    KR = np.empty((n, mu))
    _matmul(K, Ru, KR)
    Pn = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                s += AP[i, k] * Am[j, k]
            for a in range(mu):
                s += KR[i, a] * K[j, a]
            Pn[i, j] = s
    for i in range(n):
        for j in range(n):
            P[i, j] = 0.5 * (Pn[i, j] + Pn[j, i])
    return nu, S, nis, K


# ----------------------------------------------------------------------------------------
# series discretisation (the "series" method of kalman.discretize, compiled)
# ----------------------------------------------------------------------------------------
@njit(cache=True)
def _row_lists(mask, width):
    """Per row of ``mask`` (r, c) the columns of its True entries, ascending (r, width),
    and their counts (r,)."""
    r, c = mask.shape
    idx = np.zeros((r, width), dtype=np.int64)
    cnt = np.zeros(r, dtype=np.int64)
    for i in range(r):
        for j in range(c):
            if mask[i, j]:
                idx[i, cnt[i]] = j
                cnt[i] += 1
    return idx, cnt


@njit(cache=True)
def series_structure(fnz, gnz, q):
    """Index lists of the zeros :func:`series_step` skips, from the possible non-zeros.

    Parameters
    ----------
    fnz : bool ndarray (n, n)
        Entries of F that may be non-zero.
    gnz : bool ndarray (n, p)
        Entries of G that may be non-zero.
    q : ndarray (p,)
        Noise densities (columns with q = 0 are skipped).

    Returns
    -------
    fcol, fcnt : (n, n), (n,) int
        Non-zero columns of each row of F.
    grow, gcnt : (p, n), (p,) int
        Non-zero rows of each column of G.
    R, pos : (n,), (n,) int
        The states reached by Q̄ (first ``nr`` entries of R); ``pos[i]`` the place of
        state i in R or −1.
    nr : int
    phic, phin : (n, n), (n,) int
        Non-zero columns of each row of Φ = I + FT + (FT)²/2.
    qr, nq : (n,) int, int
        The rows of Φ that reach R (first ``nq`` entries): Q_k is zero elsewhere.
    qbr, qbn : (max(nr, 1), max(nr, 1)), (max(nr, 1),) int
        Per column b of Q̄ (places in R) the rows a where it can be non-zero: the pairs of
        states that share a noise column.
    prc, prn : (n, max(nr, 1)), (n,) int
        Per row u of ``Φ[qr, R]`` (in ``qr`` order) the places b in R where it can be
        non-zero.
    """
    n, m = gnz.shape
    fcol, fcnt = _row_lists(fnz, n)
    grow = np.zeros((m, n), dtype=np.int64)
    gcnt = np.zeros(m, dtype=np.int64)
    pos = np.full(n, -1, dtype=np.int64)
    for c in range(m):
        if q[c] == 0.0:
            continue
        for i in range(n):
            if gnz[i, c]:
                grow[c, gcnt[c]] = i
                gcnt[c] += 1
                pos[i] = 0
    R = np.zeros(n, dtype=np.int64)
    nr = 0
    for i in range(n):
        if pos[i] == 0:
            R[nr] = i
            pos[i] = nr
            nr += 1
    pnz = np.zeros((n, n), dtype=np.bool_)
    for i in range(n):
        pnz[i, i] = True
        for a in range(fcnt[i]):
            k = fcol[i, a]
            pnz[i, k] = True
            for b in range(fcnt[k]):
                pnz[i, fcol[k, b]] = True
    phic, phin = _row_lists(pnz, n)
    qr = np.zeros(n, dtype=np.int64)
    nq = 0
    for i in range(n):
        for a in range(nr):
            if pnz[i, R[a]]:
                qr[nq] = i
                nq += 1
                break
    nr1 = max(nr, 1)
    # Q̄'s pattern is symmetric: the rows of column b are the columns of row b
    qnz = np.zeros((nr1, nr1), dtype=np.bool_)
    for c in range(m):
        for a in range(gcnt[c]):
            for b in range(gcnt[c]):
                qnz[pos[grow[c, a]], pos[grow[c, b]]] = True
    qbr, qbn = _row_lists(qnz, nr1)
    prz = np.zeros((n, nr1), dtype=np.bool_)
    for u in range(nq):
        for b in range(nr):
            prz[u, b] = pnz[qr[u], R[b]]
    prc, prn = _row_lists(prz, nr1)
    return fcol, fcnt, grow, gcnt, R, pos, nr, phic, phin, qr, nq, qbr, qbn, prc, prn


@njit(cache=True)
def series_phi(Fe, T, fcol, fcnt, Pe):
    """``Pe <- Φ = I + F T + (F T)²/2`` over the non-zeros ``fcol``, ``fcnt`` of F."""
    n = np.uint64(Fe.shape[0])
    # Φ = I + FT + (FT)²/2
    for i in range(n):
        for j in range(n):
            Pe[i, j] = 0.0
        Pe[i, i] = 1.0
        for a in range(fcnt[i]):
            k = np.uint64(fcol[i, a])
            fik = Fe[i, k] * T
            Pe[i, k] += fik
            h = 0.5 * fik
            for b in range(fcnt[k]):
                j = np.uint64(fcol[k, b])
                Pe[i, j] += h * (Fe[k, j] * T)


@njit(cache=True)
def series_qbar(Ge, q, grow, gcnt, pos, nr, qbr, qbn, Qb):
    """``Qb <- Q̄ = G diag(q) Gᵀ`` on the states reached (the places of
    :func:`series_structure`), exactly symmetric."""
    m = Ge.shape[1]
    # Q̄ = G diag(q) Gᵀ on the reached states, exactly symmetric (entries outside the
    # pattern stay zero from the caller's allocation)
    for b in range(nr):
        for a_ in range(qbn[b]):
            Qb[np.uint64(qbr[b, a_]), b] = 0.0
    for c in range(m):
        qc = q[c]
        for a in range(gcnt[c]):
            i = np.uint64(grow[c, a])
            gi = Ge[i, c] * qc
            pa = np.uint64(pos[i])
            for b in range(gcnt[c]):
                g = np.uint64(grow[c, b])
                Qb[pa, np.uint64(pos[g])] += gi * Ge[g, c]
    for b in range(nr):
        for a_ in range(qbn[b]):
            a = qbr[b, a_]
            if a < b:
                u = np.uint64(a)
                v = 0.5 * (Qb[u, b] + Qb[b, u])
                Qb[u, b] = v
                Qb[b, u] = v


@njit(cache=True)
def series_qk(Pe, Qb, T, R, pos, nr, qr, nq, PR, W, Qe, qbr, qbn, prc, prn):
    """``Qe <- Q_k = T (Q̄ + Φ Q̄ Φᵀ)/2`` from ``Pe`` (Φ) and ``Qb`` (Q̄), exactly symmetric."""
    n = Pe.shape[0]
    # Q_k = T (Q̄ + Φ Q̄ Φᵀ)/2 with Φ Q̄ Φᵀ = (Φ[:, R] Q̄) Φ[:, R]ᵀ; when every row of Φ
    # reaches R the loop below writes all of Q_k
    if nq < n:
        for i in range(n):
            for j in range(n):
                Qe[i, j] = 0.0
    for u in range(nq):
        i = qr[u]
        for a in range(nr):
            PR[u, a] = Pe[i, R[a]]
    # W = Φ[:, R] Q̄, row by row over the non-zeros of both (each W[u, b] sums its terms
    # in the order of a)
    for u in range(nq):
        for b in range(nr):
            W[u, b] = 0.0
        for a_ in range(prn[u]):
            a = prc[u, a_]
            pa = PR[u, a]
            for b_ in range(qbn[a]):
                b = qbr[a, b_]
                W[u, b] += pa * Qb[a, b]
    for u in range(nq):
        i = qr[u]
        pi = pos[i]
        for t in range(u, nq):
            l = qr[t]
            s = 0.0
            for b_ in range(prn[t]):
                b = prc[t, b_]
                s += W[u, b] * PR[t, b]
            pl = pos[l]
            if pi >= 0 and pl >= 0:
                s += Qb[pi, pl]
            v = 0.5 * T * s
            Qe[i, l] = v
            Qe[l, i] = v


@njit(cache=True)
def series_step(Fe, Ge, q, T, fcol, fcnt, grow, gcnt, R, pos, nr, qr, nq, Qb, PR, W, Pe, Qe,
                qbr, qbn, prc, prn):
    """One epoch of the series discretisation into ``Pe`` (Φ) and ``Qe`` (Q_k), skipping
    the zeros listed by :func:`series_structure`; ``Qb``, ``PR``, ``W`` are work arrays
    (max(nr, 1) columns), ``Qb`` holding zeros on the first call (``np.zeros``).

    Only exact zeros are skipped, in an order that keeps every sum's other terms in place:
    a product with a structural zero adds ±0, which leaves a finite sum unchanged, so the
    result equals the dense loops bit for bit."""
    series_phi(Fe, T, fcol, fcnt, Pe)
    series_qbar(Ge, q, grow, gcnt, pos, nr, qbr, qbn, Qb)
    series_qk(Pe, Qb, T, R, pos, nr, qr, nq, PR, W, Qe, qbr, qbn, prc, prn)
