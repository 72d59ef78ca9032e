"""Kalman filter core shared by every method in sinslab.

Three layers, from small to large:

1. Plain functions on arrays: :func:`predict`, :func:`update` (Joseph form, optional
   sequential scalar updates, measurement masks), :func:`check_covariance`,
   :func:`discretize` and :func:`steady_state`.
2. Compiled (numba) time loops for linear systems: :func:`run_linear` (state and
   covariance with data) and :func:`propagate_covariance` (no data, covariance analysis),
   plus :func:`error_budget`, which splits the variance into the contributions of P0,
   each process-noise source and each measurement-noise source. Time-varying systems are
   given as *tables* of matrices plus per-step *index* arrays, so a piecewise-constant
   or periodically varying system costs no memory per step.
3. :class:`KalmanFilter`, a stateful filter for running beside a nonlinear INS: step
   by step predict/update, feedback (correct the INS, zero the states) or feed-forward
   (open loop), and lagged measurements from a ring-buffer history (exact re-processing
   or the one-step form of paper 003); :class:`FeedbackLayout` routes the fed-back
   states to the INS and its sensor compensation.

The INS + fix application that runs this filter beside the mechanization (chunked
strapdown stepping between filter epochs, lagged fixes, feedback) is
:func:`sinslab.fusion.loosely_coupled.loosely_coupled`; it is the only such driver in sinslab.

Conventions
-----------
``n`` states, ``m`` measurement components, ``K`` steps. Step ``k`` (0-based) of a time
loop predicts from epoch ``k`` to epoch ``k+1`` with ``Phi_k``, ``Q_k`` and then applies
the measurement ``z[k]`` (valid at epoch ``k+1``) where ``mask[k]`` is true. Histories
have ``K+1`` rows: row 0 is the initial condition. Units are whatever the model uses
(SI in sinslab: rad, m/s, m or rad for positions — see :mod:`sinslab.nav.errstate`).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from numba import njit
from scipy import linalg as sla

from sinslab.nav.errstate import van_loan

__all__ = [
    "check_covariance", "predict", "update", "UpdateResult", "discretize",
    "steady_state", "SteadyState", "run_linear", "LinearRun", "propagate_covariance",
    "error_budget", "Budget", "KalmanFilter", "FeedbackLayout",
]


# ----------------------------------------------------------------------------------------
# validation
# ----------------------------------------------------------------------------------------
def _as_square(M, n, name):
    M = np.asarray(M, dtype=float)
    if M.ndim != 2 or M.shape != (n, n):
        raise ValueError(f"{name} must have shape ({n}, {n}), got {M.shape}")
    return M


def check_covariance(M, name="P", *, definite=False, rtol=1e-9):
    """Check that ``M`` is a finite, symmetric, positive (semi-)definite matrix.

    Parameters
    ----------
    M : array_like, shape (n, n)
        Covariance matrix.
    name : str
        Name used in error messages (``"P0"``, ``"Q"``, ``"R"``...).
    definite : bool
        Require positive definite (all eigenvalues > 0), e.g. for R; otherwise positive
        semi-definite is enough (zero-variance states and singular Q are allowed).
    rtol : float
        Tolerance on asymmetry and on negative eigenvalues, relative to the largest
        absolute element / eigenvalue.

    Returns
    -------
    ndarray, shape (n, n)
        The symmetrised matrix ``(M + M^T)/2``.

    Raises
    ------
    ValueError
        Not square, not finite, not symmetric, or not positive (semi-)definite; the
        message names the matrix and the offending eigenvalue or element.
    """
    M = np.asarray(M, dtype=float)
    if M.ndim != 2 or M.shape[0] != M.shape[1]:
        raise ValueError(f"{name} must be a square matrix, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        i, j = np.argwhere(~np.isfinite(M))[0]
        raise ValueError(f"{name} has a NaN/inf element at ({i}, {j})")
    scale = float(np.max(np.abs(M))) if M.size else 0.0
    asym = float(np.max(np.abs(M - M.T))) if M.size else 0.0
    if asym > rtol * max(scale, 1e-300) and asym > 0:
        i, j = np.unravel_index(np.argmax(np.abs(M - M.T)), M.shape)
        raise ValueError(f"{name} is not symmetric: element ({i}, {j}) differs from ({j}, {i}) "
                         f"by {asym:.3g}")
    Ms = 0.5 * (M + M.T)
    if M.size == 0:
        return Ms
    w = np.linalg.eigvalsh(Ms)
    wmax = max(float(np.max(np.abs(w))), 1e-300)
    if definite:
        if w[0] <= rtol * wmax or scale == 0.0:
            raise ValueError(f"{name} must be positive definite; smallest eigenvalue {w[0]:.3g} "
                             f"(largest {w[-1]:.3g})")
    elif w[0] < -rtol * wmax * max(1, M.shape[0]):
        raise ValueError(f"{name} must be positive semi-definite; smallest eigenvalue "
                         f"{w[0]:.3g} (largest {w[-1]:.3g})")
    return Ms


def _is_diag(R):
    return not np.any(R - np.diag(np.diag(R)))


# ----------------------------------------------------------------------------------------
# plain functions
# ----------------------------------------------------------------------------------------
def predict(x, P, Phi, Qk):
    """One Kalman time update ``x <- Phi x``, ``P <- Phi P Phi^T + Q_k`` (symmetrised).

    Parameters
    ----------
    x : array_like, shape (n,)
        State estimate.
    P : array_like, shape (n, n)
        Its covariance.
    Phi : array_like, shape (n, n)
        State transition matrix over the step.
    Qk : array_like, shape (n, n)
        Discrete process-noise covariance of the step (positive semi-definite).

    Returns
    -------
    x, P : ndarray
        Predicted state (n,) and covariance (n, n), new arrays.
    """
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"x must be a vector, got shape {x.shape}")
    n = x.size
    P = _as_square(P, n, "P")
    Phi = _as_square(Phi, n, "Phi")
    Qk = check_covariance(_as_square(Qk, n, "Q"), "Q")
    if not np.all(np.isfinite(Phi)):
        raise ValueError("Phi has NaN/inf elements")
    Pn = Phi @ P @ Phi.T + Qk
    return Phi @ x, 0.5 * (Pn + Pn.T)


@dataclass(frozen=True)
class UpdateResult:
    """Result of a measurement update.

    Attributes
    ----------
    x : ndarray, shape (n,)
        Updated state.
    P : ndarray, shape (n, n)
        Updated covariance (Joseph form, symmetrised).
    innovation : ndarray, shape (m,)
        ``z - H x_prior``; NaN where the component was masked out.
    S : ndarray, shape (m, m)
        Innovation covariance ``H P H^T + R`` of the prior; NaN rows/columns where masked.
    nis : float
        Normalised innovation squared ``nu^T S^-1 nu`` over the used components.
    used : ndarray of bool, shape (m,)
        Components actually applied.
    """

    x: np.ndarray
    P: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    nis: float
    used: np.ndarray

    def __iter__(self):           # x, P, innovation, S = update(...)
        return iter((self.x, self.P, self.innovation, self.S))


def _check_update_args(x, P, z, H, R, mask):
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"x must be a vector, got shape {x.shape}")
    n = x.size
    P = _as_square(P, n, "P")
    z = np.atleast_1d(np.asarray(z, dtype=float))
    if z.ndim != 1:
        raise ValueError(f"z must be a vector, got shape {z.shape}")
    m = z.size
    H = np.asarray(H, dtype=float)
    if H.ndim == 1 and m == 1:
        H = H[None, :]
    if H.shape != (m, n):
        raise ValueError(f"H must have shape ({m}, {n}) for {m} measurements and {n} states, "
                         f"got {H.shape}")
    R = np.asarray(R, dtype=float)
    if R.ndim == 0 or (R.ndim == 1 and R.size == m):
        R = np.diag(np.broadcast_to(R, (m,)).astype(float))
    R = _as_square(R, m, "R")
    if mask is None:
        mask = np.isfinite(z)
    else:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != (m,):
            raise ValueError(f"mask must have shape ({m},), got {mask.shape}")
        if np.any(~np.isfinite(z[mask])):
            raise ValueError("z has NaN/inf in a component the mask marks as available")
    if not np.all(np.isfinite(H)):
        raise ValueError("H has NaN/inf elements")
    return x, P, z, H, R, mask


def update(x, P, z, H, R, *, mask=None, sequential=None):
    """Kalman measurement update in Joseph form.

    ``K = P H^T S^-1``, ``x <- x + K (z - H x)``,
    ``P <- (I - K H) P (I - K H)^T + K R K^T`` (then symmetrised).

    Parameters
    ----------
    x : array_like, shape (n,)
        Prior state.
    P : array_like, shape (n, n)
        Prior covariance.
    z : array_like, shape (m,)
        Measurement. NaN components are treated as unavailable unless ``mask`` is given.
    H : array_like, shape (m, n)
        Measurement matrix.
    R : array_like, shape (m, m), (m,) or scalar
        Measurement-noise covariance (a vector or scalar means diagonal); the used
        sub-block must be positive definite.
    mask : array_like of bool, shape (m,), optional
        Components to apply (default: the finite components of ``z``).
    sequential : bool, optional
        Process the components one scalar at a time (requires diagonal R). Default: when R
        is diagonal. Mathematically identical to the vector update.

    Returns
    -------
    UpdateResult
        Unpacks as ``x, P, innovation, S``; also has ``nis`` and ``used``.
    """
    x, P, z, H, R, mask = _check_update_args(x, P, z, H, R, mask)
    m = z.size
    idx = np.flatnonzero(mask)
    innov = np.full(m, np.nan)
    S_full = np.full((m, m), np.nan)
    if idx.size == 0:
        return UpdateResult(x.copy(), P.copy(), innov, S_full, 0.0, mask)
    Ru = check_covariance(R[np.ix_(idx, idx)], "R (used components)", definite=True)
    Hu, zu = H[idx], z[idx]
    S = Hu @ P @ Hu.T + Ru
    nu = zu - Hu @ x
    innov[idx] = nu
    S_full[np.ix_(idx, idx)] = S
    diag = _is_diag(Ru)
    if sequential is None:
        sequential = diag
    if sequential and not diag:
        raise ValueError("sequential updates need a diagonal R (the used components are correlated)")
    if sequential:
        x = x.copy()
        P = P.copy()
        nis = 0.0
        for i in range(idx.size):
            h, r = Hu[i], Ru[i, i]
            pht = P @ h
            s = float(h @ pht + r)
            if not s > 0:
                raise ValueError(f"innovation variance of component {idx[i]} is {s:.3g} (not > 0)")
            nu_i = zu[i] - h @ x
            k = pht / s
            x = x + k * nu_i
            A = np.eye(x.size) - np.outer(k, h)
            P = A @ P @ A.T + r * np.outer(k, k)
            P = 0.5 * (P + P.T)
            nis += nu_i * nu_i / s
    else:
        try:
            cf = sla.cho_factor(S)
        except np.linalg.LinAlgError as e:
            raise ValueError(f"innovation covariance is not positive definite: {e}") from None
        K = sla.cho_solve(cf, Hu @ P).T
        x = x + K @ nu
        A = np.eye(x.size) - K @ Hu
        P = A @ P @ A.T + K @ Ru @ K.T
        P = 0.5 * (P + P.T)
        nis = float(nu @ sla.cho_solve(cf, nu))
    if not np.all(np.isfinite(P)):
        raise ValueError("update produced a non-finite covariance")
    return UpdateResult(x, P, innov, S_full, float(nis), mask)


def discretize(F, Qc, T, *, G=None):
    """Exact discretisation by Van Loan's method.

    Parameters
    ----------
    F : array_like, shape (n, n)
        Continuous system matrix (held constant over the step).
    Qc : array_like, shape (n, n) or (p, p)
        Continuous white-noise spectral density; with ``G`` given it is the density of
        the driving noise ``w`` (p,) and the state density is ``G Qc G^T``.
    T : float
        Step [s], >= 0.
    G : array_like, shape (n, p), optional
        Noise input matrix.

    Returns
    -------
    Phi, Qk : ndarray, shape (n, n)
        ``expm(F T)`` and ``∫_0^T expm(F s) G Qc G^T expm(F s)^T ds``.
    """
    F = np.asarray(F, dtype=float)
    n = F.shape[0]
    F = _as_square(F, n, "F")
    Qc = np.asarray(Qc, dtype=float)
    if G is not None:
        G = np.asarray(G, dtype=float)
        Qc = G @ Qc @ G.T
    Qc = check_covariance(_as_square(Qc, n, "Qc"), "Qc")
    if not T >= 0:
        raise ValueError(f"step T must be >= 0, got {T}")
    return van_loan(F, Qc, T)


@dataclass(frozen=True)
class SteadyState:
    """Steady-state Kalman filter of a time-invariant system.

    Attributes
    ----------
    P_prior : ndarray, shape (n, n)
        Steady predicted covariance (solution of the discrete algebraic Riccati equation).
    P_post : ndarray, shape (n, n)
        Steady updated covariance.
    K : ndarray, shape (n, m)
        Steady gain.
    """

    P_prior: np.ndarray
    P_post: np.ndarray
    K: np.ndarray


def steady_state(Phi, Qk, H, R):
    """Steady-state covariance and gain of a time-invariant filter (predict, then update).

    Solves ``P = Phi (P - P H^T (H P H^T + R)^-1 H P) Phi^T + Q`` with
    :func:`scipy.linalg.solve_discrete_are`. Raises ValueError when no stabilising
    solution exists (e.g. an unobservable unstable or undamped mode without noise).
    """
    Phi = np.asarray(Phi, dtype=float)
    n = Phi.shape[0]
    Phi = _as_square(Phi, n, "Phi")
    Qk = check_covariance(_as_square(Qk, n, "Q"), "Q")
    H = np.atleast_2d(np.asarray(H, dtype=float))
    if H.shape[1] != n:
        raise ValueError(f"H must have {n} columns, got shape {H.shape}")
    m = H.shape[0]
    R = np.asarray(R, dtype=float)
    if R.ndim < 2:
        R = np.diag(np.broadcast_to(R, (m,)).astype(float))
    R = check_covariance(_as_square(R, m, "R"), "R", definite=True)
    try:
        Pp = sla.solve_discrete_are(Phi.T, H.T, Qk, R)
    except (np.linalg.LinAlgError, ValueError) as e:
        raise ValueError(f"no steady-state solution: {e}") from None
    Pp = 0.5 * (Pp + Pp.T)
    S = H @ Pp @ H.T + R
    K = np.linalg.solve(S, H @ Pp).T
    A = np.eye(n) - K @ H
    Pu = A @ Pp @ A.T + K @ R @ K.T
    return SteadyState(Pp, 0.5 * (Pu + Pu.T), K)


# ----------------------------------------------------------------------------------------
# compiled kernels (scalar style, no temporaries inside the time loop)
# ----------------------------------------------------------------------------------------
@njit(cache=True)
def _cov_predict(P, Phi, Q, T1, T2):
    """P <- Phi P Phi^T + Q in place, exactly symmetric. T1, T2 are (n, n) work arrays.

    Two BLAS products called from compiled code (no Python per step): measured faster
    than scalar loops exploiting the zeros of Phi for every n from 2 to 40."""
    n = P.shape[0]
    np.dot(Phi, P, T1)
    np.dot(T1, Phi.T, T2)
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (T2[i, j] + T2[j, i] + Q[i, j] + Q[j, i])
            P[i, j] = v
            P[j, i] = v


@njit(cache=True)
def _state_predict(x, Phi, nzc, nnz, tmp):
    n = x.shape[0]
    for i in range(n):
        s = 0.0
        for a in range(nnz[i]):
            k = nzc[i, a]
            s += Phi[i, k] * x[k]
        tmp[i] = s
    for i in range(n):
        x[i] = tmp[i]


@njit(cache=True)
def _scalar_update(x, P, h, r, zi, with_x, pht, kk, bh, B):
    """Joseph-form scalar update in place. Returns (innovation, s)."""
    n = P.shape[0]
    for i in range(n):
        s = 0.0
        for k in range(n):
            if h[k] != 0.0:
                s += P[i, k] * h[k]
        pht[i] = s
    s = r
    for k in range(n):
        s += h[k] * pht[k]
    nu = 0.0
    if with_x:
        hx = 0.0
        for k in range(n):
            hx += h[k] * x[k]
        nu = zi - hx
    for i in range(n):
        kk[i] = pht[i] / s
    if with_x:
        for i in range(n):
            x[i] += kk[i] * nu
    # B = (I - k h) P = P - k pht^T
    for i in range(n):
        for j in range(n):
            B[i, j] = P[i, j] - kk[i] * pht[j]
    # bh = B h
    for i in range(n):
        t = 0.0
        for k in range(n):
            if h[k] != 0.0:
                t += B[i, k] * h[k]
        bh[i] = t
    # P = B (I - k h)^T + r k k^T = B - bh k^T + r k k^T
    for i in range(n):
        for j in range(n):
            P[i, j] = B[i, j] - bh[i] * kk[j] + r * kk[i] * kk[j]
    for i in range(n):
        for j in range(i + 1, n):
            t = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = t
            P[j, i] = t
    return nu, s


@njit(cache=True)
def _vector_update(x, P, H, R, z, used, with_x):
    """Joseph-form vector update over the used rows (correlated R). Returns (nu, S, nis)."""
    n = P.shape[0]
    mu = used.shape[0]
    Hu = np.empty((mu, n))
    Ru = np.empty((mu, mu))
    for a in range(mu):
        for j in range(n):
            Hu[a, j] = H[used[a], j]
        for b in range(mu):
            Ru[a, b] = R[used[a], used[b]]
    PHt = P @ Hu.T
    S = Hu @ PHt + Ru
    np.linalg.cholesky(S)            # raises if S is not positive definite
    Sinv = np.linalg.inv(S)
    K = PHt @ Sinv
    nu = np.zeros(mu)
    nis = 0.0
    if with_x:
        for a in range(mu):
            nu[a] = z[used[a]] - Hu[a] @ x
        x += K @ nu
        nis = nu @ (Sinv @ nu)
    A = np.eye(n) - K @ Hu
    Pn = A @ P @ A.T + K @ Ru @ K.T
    for i in range(n):
        for j in range(n):
            P[i, j] = 0.5 * (Pn[i, j] + Pn[j, i])
    return nu, S, nis


@njit(cache=True)
def _linear_loop(x, P, Phi_t, phi_i, Q_t, q_i, H_t, h_i, R_t, r_i, z, mask, diagR, with_x,
                 nzc_t, nnz_t, save_flag, x_hist, pd_hist, P_save, innov, sdiag, nis):
    n = P.shape[0]
    K = phi_i.shape[0]
    m = mask.shape[1]
    T1 = np.empty((n, n))
    T2 = np.empty((n, n))
    tmp = np.empty(n)
    pht = np.empty(n)
    kk = np.empty(n)
    bh = np.empty(n)
    used = np.empty(m, dtype=np.int64)
    ns = 0
    if with_x:
        for j in range(n):
            x_hist[0, j] = x[j]
    for j in range(n):
        pd_hist[0, j] = P[j, j]
    if save_flag[0]:
        P_save[ns] = P
        ns += 1
    for k in range(K):
        ip = phi_i[k]
        _cov_predict(P, Phi_t[ip], Q_t[q_i[k]], T1, T2)
        if with_x:
            _state_predict(x, Phi_t[ip], nzc_t[ip], nnz_t[ip], tmp)
        nu_tot = 0.0
        nm = 0
        for c in range(m):
            if mask[k, c]:
                used[nm] = c
                nm += 1
        if nm > 0:
            Hk = H_t[h_i[k]]
            Rk = R_t[r_i[k]]
            if diagR:
                for a in range(nm):
                    c = used[a]
                    zc = 0.0
                    if with_x:
                        zc = z[k, c]
                    nu, s = _scalar_update(x, P, Hk[c], Rk[c, c], zc, with_x, pht, kk, bh, T1)
                    innov[k, c] = nu
                    sdiag[k, c] = s
                    nu_tot += nu * nu / s
            else:
                nuv, S, nisv = _vector_update(x, P, Hk, Rk, z[k], used[:nm], with_x)
                for a in range(nm):
                    innov[k, used[a]] = nuv[a]
                    sdiag[k, used[a]] = S[a, a]
                nu_tot = nisv
        nis[k] = nu_tot
        if with_x:
            for j in range(n):
                x_hist[k + 1, j] = x[j]
        for j in range(n):
            pd_hist[k + 1, j] = P[j, j]
        if save_flag[k + 1]:
            P_save[ns] = P
            ns += 1
        if not (P[0, 0] == P[0, 0]):
            return k + 1
    return -1


@njit(cache=True)
def _budget_loop(Ptot, C, Phi_t, phi_i, Qparts_t, q_i, H_t, h_i, Rparts_t, r_i, mask,
                 nzc_t, nnz_t, src_q, src_r, hist_every, Chist):
    """Propagate total covariance Ptot and the contributions C[s] of each source with the
    gains of the full filter. src_q[s] = index of the Q part driving source s (-1: none);
    src_r[s] = index of the R part (-1: none)."""
    n = Ptot.shape[0]
    K = phi_i.shape[0]
    m = mask.shape[1]
    S = C.shape[0]
    nq = Qparts_t.shape[0]
    nr = Rparts_t.shape[0]
    T1 = np.empty((n, n))
    T2 = np.empty((n, n))
    Qtot = np.zeros((n, n))
    Zero = np.zeros((n, n))
    pht = np.empty(n)
    kk = np.empty(n)
    bh = np.empty(n)
    ch = np.empty(n)
    dummy = np.zeros(n)
    nh = 0
    for k in range(K):
        ip = phi_i[k]
        iq = q_i[k]
        for i in range(n):
            for j in range(n):
                t = 0.0
                for p in range(nq):
                    t += Qparts_t[p, iq, i, j]
                Qtot[i, j] = t
        _cov_predict(Ptot, Phi_t[ip], Qtot, T1, T2)
        for s in range(S):
            if src_q[s] >= 0:
                _cov_predict(C[s], Phi_t[ip], Qparts_t[src_q[s], iq], T1, T2)
            else:
                _cov_predict(C[s], Phi_t[ip], Zero, T1, T2)
        Hk = H_t[h_i[k]]
        for c in range(m):
            if not mask[k, c]:
                continue
            h = Hk[c]
            r = 0.0
            for p in range(nr):
                r += Rparts_t[p, r_i[k], c]
            # gain from the total covariance (before its update)
            for i in range(n):
                t = 0.0
                for j in range(n):
                    t += Ptot[i, j] * h[j]
                pht[i] = t
            sv = r
            for i in range(n):
                sv += h[i] * pht[i]
            for i in range(n):
                kk[i] = pht[i] / sv
            # contributions: C <- A C A^T + r_s k k^T,  A = I - k h
            for s in range(S):
                Cs = C[s]
                for i in range(n):
                    t = 0.0
                    for j in range(n):
                        t += Cs[i, j] * h[j]
                    ch[i] = t
                hch = 0.0
                for i in range(n):
                    hch += h[i] * ch[i]
                rs = 0.0
                if src_r[s] >= 0:
                    rs = Rparts_t[src_r[s], r_i[k], c]
                for i in range(n):
                    for j in range(n):
                        Cs[i, j] += (-kk[i] * ch[j] - ch[i] * kk[j]
                                     + (hch + rs) * kk[i] * kk[j])
            _scalar_update(dummy, Ptot, h, r, 0.0, False, pht, kk, bh, T1)
        if hist_every > 0 and (k + 1) % hist_every == 0:
            for s in range(S):
                for i in range(n):
                    Chist[nh, s, i] = C[s, i, i]
            nh += 1


# ----------------------------------------------------------------------------------------
# compiled time loops: Python wrappers
# ----------------------------------------------------------------------------------------
def _table(A, idx, K, shape, name):
    """Normalise a constant / per-step / table-with-index argument.

    Returns (table (L,)+shape, index (K,) int64)."""
    A = np.asarray(A, dtype=float)
    if A.shape == shape:
        tab = A[None]
        if idx is not None:
            raise ValueError(f"{name}_index given but {name} is a single matrix")
        return np.ascontiguousarray(tab), np.zeros(K, dtype=np.int64)
    if A.ndim != len(shape) + 1 or A.shape[1:] != shape:
        raise ValueError(f"{name} must have shape {shape}, (K, *{shape}) or (L, *{shape}) with "
                         f"{name}_index; got {A.shape}")
    if idx is None:
        if A.shape[0] != K:
            raise ValueError(f"{name} has {A.shape[0]} matrices but there are {K} steps "
                             f"(give {name}_index to use a table)")
        idx = np.arange(K, dtype=np.int64)
    else:
        idx = np.asarray(idx, dtype=np.int64)
        if idx.shape != (K,):
            raise ValueError(f"{name}_index must have shape ({K},), got {idx.shape}")
        if idx.size and (idx.min() < 0 or idx.max() >= A.shape[0]):
            raise ValueError(f"{name}_index out of range [0, {A.shape[0]})")
    if not np.all(np.isfinite(A)):
        raise ValueError(f"{name} has NaN/inf elements")
    return np.ascontiguousarray(A), idx


@njit(cache=True)
def _sparsity_nb(Phi_t, nzc, nnz):
    L, n, _ = Phi_t.shape
    for l in range(L):
        for i in range(n):
            c = 0
            for k in range(n):
                if Phi_t[l, i, k] != 0.0:
                    nzc[l, i, c] = k
                    c += 1
            nnz[l, i] = c


def _sparsity(Phi_t):
    """Per row, the columns where Phi is non-zero (zero entries are skipped in products)."""
    L, n, _ = Phi_t.shape
    nnz = np.zeros((L, n), dtype=np.int64)
    nzc = np.zeros((L, n, max(1, n)), dtype=np.int64)
    _sparsity_nb(Phi_t, nzc, nnz)
    return nzc, nnz


def _check_tables_psd(Q_t, name):
    # cheap: check each distinct matrix of the table (tables are small or per-step; for
    # long per-step tables check a few and the diagonals of all)
    L = Q_t.shape[0]
    if np.any(np.diagonal(Q_t, axis1=1, axis2=2) < 0):
        l = int(np.argwhere(np.diagonal(Q_t, axis1=1, axis2=2) < 0)[0, 0])
        raise ValueError(f"{name}[{l}] has a negative diagonal element (not a covariance)")
    for l in (range(L) if L <= 64 else np.unique(np.linspace(0, L - 1, 64).astype(int))):
        check_covariance(Q_t[l], f"{name}[{l}]" if L > 1 else name)


@dataclass(frozen=True)
class LinearRun:
    """Output of :func:`run_linear` / :func:`propagate_covariance`.

    Attributes
    ----------
    x : ndarray, shape (K+1, n) or None
        State estimate history (row 0 = x0); None for covariance-only runs.
    P_diag : ndarray, shape (K+1, n)
        Diagonal of P at every epoch (variances).
    P_saved : ndarray, shape (len(save_at), n, n)
        Full P at the requested epochs ``save_at``.
    save_at : ndarray of int
        Epoch indices of ``P_saved`` (0..K).
    innovation : ndarray, shape (K, m)
        Innovations (NaN where not measured; zero in covariance-only runs).
    S_diag : ndarray, shape (K, m)
        Diagonal of the innovation covariance (for sequential updates: the variance of
        each scalar innovation at its turn), NaN where not measured.
    nis : ndarray, shape (K,)
        Normalised innovation squared per step (0 where nothing was measured).
    x_final, P_final : ndarray
        State (n,) and covariance (n, n) after the last step, to continue a run in chunks.
    """

    x: np.ndarray | None
    P_diag: np.ndarray
    P_saved: np.ndarray
    save_at: np.ndarray
    innovation: np.ndarray
    S_diag: np.ndarray
    nis: np.ndarray
    x_final: np.ndarray | None
    P_final: np.ndarray

    @property
    def sigma(self):
        """Standard deviations, shape (K+1, n)."""
        return np.sqrt(np.maximum(self.P_diag, 0.0))


def _prepare(x0, P0, Phi, Q, H, R, z, mask, windows, t, n_steps, Phi_index, Q_index,
             H_index, R_index, with_x, check=True):
    P0 = np.asarray(P0, dtype=float)
    n = P0.shape[0]
    if check:
        P0 = check_covariance(_as_square(P0, n, "P0"), "P0")
    if with_x:
        x0 = np.asarray(x0, dtype=float).copy()
        if x0.shape != (n,):
            raise ValueError(f"x0 must have shape ({n},) to match P0, got {x0.shape}")
    else:
        x0 = np.zeros(n)
    # number of steps
    Phi = np.asarray(Phi, dtype=float)
    if n_steps is None:
        if z is not None:
            n_steps = np.asarray(z).shape[0]
        elif mask is not None:
            n_steps = np.asarray(mask).shape[0]
        elif Phi_index is not None:
            n_steps = len(Phi_index)
        elif Phi.ndim == 3:
            n_steps = Phi.shape[0]
        else:
            raise ValueError("cannot tell the number of steps: give n_steps, z, mask or a per-step Phi")
    K = int(n_steps)
    Phi_t, phi_i = _table(Phi, Phi_index, K, (n, n), "Phi")
    Q_t, q_i = _table(Q, Q_index, K, (n, n), "Q")
    if check:
        _check_tables_psd(Q_t, "Q")
    if H is None:
        m = 0
        H_t, h_i = np.zeros((1, 0, n)), np.zeros(K, dtype=np.int64)
        R_t, r_i = np.ones((1, 0, 0)), np.zeros(K, dtype=np.int64)
    else:
        H = np.asarray(H, dtype=float)
        if H.ndim == 1:
            H = H[None, :]
        m = H.shape[-2]
        if H.shape[-1] != n:
            raise ValueError(f"H must have {n} columns (states), got shape {H.shape}")
        H_t, h_i = _table(H, H_index, K, (m, n), "H")
        if R is None:
            raise ValueError("R is required with H")
        R = np.asarray(R, dtype=float)
        if R.ndim == 0 or (R.ndim == 1 and R.shape == (m,)):
            R = np.diag(np.broadcast_to(R, (m,)).astype(float))
        R_t, r_i = _table(R, R_index, K, (m, m), "R")
        if check:
            for l in range(min(R_t.shape[0], 64)):
                check_covariance(R_t[l], f"R[{l}]" if R_t.shape[0] > 1 else "R", definite=True)
    # mask
    if m == 0:
        mk = np.zeros((K, 0), dtype=bool)
    elif mask is not None:
        mk = np.asarray(mask, dtype=bool)
        if mk.ndim == 1 and m == 1 and mk.shape == (K,):
            mk = mk[:, None]
        if mk.ndim == 1 and mk.shape == (K,):
            mk = np.repeat(mk[:, None], m, axis=1)
        if mk.shape != (K, m):
            raise ValueError(f"mask must have shape ({K}, {m}) or ({K},), got {mk.shape}")
    elif windows is not None:
        if t is None:
            raise ValueError("windows need the epoch times t (shape (K+1,))")
        t = np.asarray(t, dtype=float)
        if t.shape != (K + 1,):
            raise ValueError(f"t must have shape ({K + 1},) (epochs incl. t0), got {t.shape}")
        te = t[1:]
        on = np.zeros(K, dtype=bool)
        for a, b in windows:
            if b < a:
                raise ValueError(f"window ({a}, {b}) ends before it starts")
            if b < t[0] or a > t[-1]:
                raise ValueError(f"window ({a}, {b}) s lies outside the run [{t[0]}, {t[-1]}] s")
            on |= (te >= a) & (te <= b)
        mk = np.repeat(on[:, None], m, axis=1)
    elif z is not None:
        mk = np.isfinite(np.asarray(z, dtype=float))
        if mk.ndim == 1:
            mk = mk[:, None]
    else:
        mk = np.ones((K, m), dtype=bool)
    if with_x and m > 0:
        if z is None:
            raise ValueError("z is required to run the filter with data (use propagate_covariance for no data)")
        z = np.asarray(z, dtype=float)
        if z.ndim == 1 and m == 1:
            z = z[:, None]
        if z.shape != (K, m):
            raise ValueError(f"z must have shape ({K}, {m}), got {z.shape}")
        if np.any(~np.isfinite(z[mk])):
            k, c = np.argwhere(~np.isfinite(z) & mk)[0]
            raise ValueError(f"z[{k}, {c}] is NaN/inf but the mask marks it available")
        z = np.where(mk, z, 0.0)
    else:
        z = np.zeros((K, m))
    diagR = bool(all(_is_diag(R_t[l]) for l in range(R_t.shape[0])))
    return dict(x0=x0, P0=P0, n=n, m=m, K=K, Phi_t=Phi_t, phi_i=phi_i, Q_t=Q_t, q_i=q_i,
                H_t=np.ascontiguousarray(H_t), h_i=h_i, R_t=np.ascontiguousarray(R_t), r_i=r_i,
                z=np.ascontiguousarray(z), mask=np.ascontiguousarray(mk), diagR=diagR)


def _run(prep, with_x, save_at):
    n, m, K = prep["n"], prep["m"], prep["K"]
    x = prep["x0"].copy()
    P = np.ascontiguousarray(prep["P0"].copy())
    save_flag = np.zeros(K + 1, dtype=np.bool_)
    if save_at is None:
        save_at = np.array([K], dtype=np.int64)
    save_at = np.atleast_1d(np.asarray(save_at, dtype=np.int64))
    save_at = np.where(save_at < 0, save_at + K + 1, save_at)
    if save_at.size and (save_at.min() < 0 or save_at.max() > K):
        raise ValueError(f"save_at epochs must be within 0..{K}")
    save_at = np.unique(save_at)
    save_flag[save_at] = True
    x_hist = np.empty((K + 1, n) if with_x else (1, n))
    pd = np.empty((K + 1, n))
    P_save = np.empty((save_at.size, n, n))
    innov = np.full((K, m), np.nan)
    sdiag = np.full((K, m), np.nan)
    nis = np.zeros(K)
    nzc, nnz = _sparsity(prep["Phi_t"])
    bad = _linear_loop(x, P, prep["Phi_t"], prep["phi_i"], prep["Q_t"], prep["q_i"],
                       prep["H_t"], prep["h_i"], prep["R_t"], prep["r_i"], prep["z"],
                       prep["mask"], prep["diagR"], with_x, nzc, nnz, save_flag, x_hist, pd,
                       P_save, innov, sdiag, nis)
    if bad >= 0:
        raise ValueError(f"covariance became NaN at step {bad}: check Phi, Q, R for extreme values")
    return LinearRun(x_hist if with_x else None, pd, P_save, save_at, innov, sdiag, nis,
                     x if with_x else None, P)


def run_linear(x0, P0, Phi, Q, H, R, z, *, mask=None, windows=None, t=None,
               Phi_index=None, Q_index=None, H_index=None, R_index=None, save_at=None,
               check=True):
    """Run a linear Kalman filter over K steps in a compiled loop.

    Parameters
    ----------
    x0 : array_like, shape (n,)
        Initial estimate.
    P0 : array_like, shape (n, n)
        Initial covariance (symmetric positive semi-definite).
    Phi : array_like, shape (n, n), (K, n, n) or (L, n, n) with ``Phi_index``
        Transition matrices: constant, per step, or a table indexed per step.
    Q : array_like, same forms as ``Phi``
        Discrete process-noise covariances.
    H : array_like, shape (m, n), (K, m, n) or (L, m, n) with ``H_index``
        Measurement matrices.
    R : array_like, scalar, (m,), (m, m), (K, m, m) or (L, m, m) with ``R_index``
        Measurement-noise covariances (diagonal R -> sequential scalar updates, correlated
        R -> vector update).
    z : array_like, shape (K, m)
        Measurements; ``z[k]`` is valid at epoch ``k+1``. NaN = unavailable (when no mask).
    mask : array_like of bool, shape (K, m) or (K,), optional
        Components available at each step.
    windows : sequence of (t_start, t_end), optional
        Alternatively to ``mask``: measure (all components) only at epochs within these
        closed time windows [s]; needs ``t``.
    t : array_like, shape (K+1,), optional
        Epoch times [s], for ``windows``.
    Phi_index, Q_index, H_index, R_index : array_like of int, shape (K,), optional
        Which table entry each step uses.
    save_at : array_like of int, optional
        Epochs (0..K, negative counts from the end) at which the full P is kept; default
        the last epoch.
    check : bool
        Validate P0, Q, R (positive (semi-)definite, finite, shapes). Shapes are always
        checked.

    Returns
    -------
    LinearRun
    """
    prep = _prepare(x0, P0, Phi, Q, H, R, z, mask, windows, t, None, Phi_index, Q_index,
                    H_index, R_index, True, check)
    return _run(prep, True, save_at)


def propagate_covariance(P0, Phi, Q, H=None, R=None, *, n_steps=None, mask=None,
                         windows=None, t=None, Phi_index=None, Q_index=None, H_index=None,
                         R_index=None, save_at=None, check=True):
    """Covariance analysis: propagate P (no data) with an optional measurement schedule.

    Same conventions as :func:`run_linear`; measurements are applied where ``mask`` (or
    ``windows``) says so, or at every step if neither is given and ``H`` is. Give
    ``n_steps`` when all of Phi, Q, H, R are constant.

    Returns
    -------
    LinearRun
        with ``x`` None; ``sigma`` gives the σ of every state versus epoch.
    """
    prep = _prepare(None, P0, Phi, Q, H, R, None, mask, windows, t, n_steps, Phi_index,
                    Q_index, H_index, R_index, False, check)
    return _run(prep, False, save_at)


@dataclass(frozen=True)
class Budget:
    """Error budget of a covariance analysis.

    Attributes
    ----------
    names : list of str
        Source names: the P0 parts, then the process-noise parts, then the
        measurement-noise parts.
    variance : ndarray, shape (S, n)
        Contribution of each source to the final variance of each state.
    total : ndarray, shape (n,)
        Final variance of the full filter (equals ``variance.sum(0)`` up to rounding).
    history : ndarray, shape (H, S, n) or None
        Contributions every ``history_every`` steps.
    """

    names: list
    variance: np.ndarray
    total: np.ndarray
    history: np.ndarray | None

    def fraction(self):
        """Share of each source in the final variance, shape (S, n)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.variance / self.total


def error_budget(P0_parts, Phi, Q_parts, H, R_parts, *, n_steps=None, mask=None,
                 windows=None, t=None, Phi_index=None, Q_index=None, H_index=None,
                 R_index=None, names=None, history_every=0):
    """Split the variance of a covariance analysis into contributions of its sources.

    For fixed gains the covariance is linear in (P0, Q, R). The full filter (P0 = ΣP0_i,
    Q = ΣQ_j, R = ΣR_l) is propagated to obtain the gain sequence; each source is then
    propagated alone through the same gains: ``C <- Phi C Phi^T + Q_j`` and
    ``C <- (I-KH) C (I-KH)^T + K R_l K^T``. The contributions sum to the total
    (like PSINS ``kfstat``).

    Parameters
    ----------
    P0_parts : array_like, shape (S0, n, n) or (n, n)
        Initial-covariance parts (e.g. one per state group).
    Phi : array_like
        As in :func:`run_linear`.
    Q_parts : array_like, shape (SQ, n, n) or (SQ, L, n, n) with ``Q_index`` or (SQ, K, n, n)
        Process-noise parts, e.g. ``discretize(F, q_j, T, G=G[:, cols_j])`` per group of
        columns of G.
    H : array_like, shape (m, n) or table as in :func:`run_linear`
    R_parts : array_like, shape (SR, m) or (SR, L, m) with ``R_index``
        Diagonal measurement-noise variances per source (R must be diagonal), e.g.
        ``np.diag(r)`` split one component per source.
    names : list of str, optional
        Names for the S0 + SQ + SR sources.
    history_every : int
        Also return the contributions every that many steps.

    Returns
    -------
    Budget
    """
    P0_parts = np.asarray(P0_parts, dtype=float)
    if P0_parts.ndim == 2:
        P0_parts = P0_parts[None]
    n = P0_parts.shape[-1]
    for i, Pp in enumerate(P0_parts):
        check_covariance(_as_square(Pp, n, f"P0_parts[{i}]"), f"P0_parts[{i}]")
    Q_parts = np.asarray(Q_parts, dtype=float)
    if Q_parts.ndim == 2:
        Q_parts = Q_parts[None]
    R_parts = np.asarray(R_parts, dtype=float)
    if R_parts.ndim == 1:
        R_parts = R_parts[None]
    P0 = P0_parts.sum(0)
    Qsum = Q_parts.sum(0)
    Rsum = R_parts.sum(0)
    Rmat = np.apply_along_axis(np.diag, -1, Rsum) if Rsum.ndim == 2 else np.diag(Rsum)
    prep = _prepare(None, P0, Phi, Qsum, H, Rmat, None, mask, windows, t, n_steps, Phi_index,
                    Q_index, H_index, R_index, False, True)
    K = prep["K"]
    q_shape = Qsum.shape
    Qp_t = np.stack([_table(q, Q_index if q_shape != (n, n) else None, K, (n, n), "Q_parts")[0]
                     for q in Q_parts])
    for j in range(Qp_t.shape[0]):
        _check_tables_psd(Qp_t[j], f"Q_parts[{j}]")
    if Rsum.ndim == 1:
        Rp_t = R_parts[:, None, :]
    else:
        Rp_t = R_parts
    if np.any(Rp_t < 0):
        raise ValueError("R_parts must be non-negative variances")
    S0, SQ, SR = P0_parts.shape[0], Qp_t.shape[0], Rp_t.shape[0]
    S = S0 + SQ + SR
    if names is None:
        names = ([f"P0[{i}]" for i in range(S0)] + [f"Q[{j}]" for j in range(SQ)]
                 + [f"R[{l}]" for l in range(SR)])
    if len(names) != S:
        raise ValueError(f"names has {len(names)} entries for {S} sources")
    C = np.zeros((S, n, n))
    C[:S0] = P0_parts
    src_q = np.full(S, -1, dtype=np.int64)
    src_q[S0:S0 + SQ] = np.arange(SQ)
    src_r = np.full(S, -1, dtype=np.int64)
    src_r[S0 + SQ:] = np.arange(SR)
    hist_every = int(history_every)
    Chist = np.zeros(((K // hist_every) if hist_every > 0 else 0, S, n))
    nzc, nnz = _sparsity(prep["Phi_t"])
    Ptot = np.ascontiguousarray(P0.copy())
    _budget_loop(Ptot, C, prep["Phi_t"], prep["phi_i"], np.ascontiguousarray(Qp_t), prep["q_i"],
                 prep["H_t"], prep["h_i"], np.ascontiguousarray(Rp_t), prep["r_i"], prep["mask"],
                 nzc, nnz, src_q, src_r, hist_every, Chist)
    var = np.diagonal(C, axis1=1, axis2=2).copy()
    return Budget(list(names), var, np.diag(Ptot).copy(), Chist if hist_every > 0 else None)


@njit(cache=True)
def _predict_many(x, c, P, Phis, Qs, nzc, nnz, T1, T2, tmp, sig_out, x_out):
    m = Phis.shape[0]
    n = x.shape[0]
    for i in range(m):
        _cov_predict(P, Phis[i], Qs[i], T1, T2)
        _state_predict(x, Phis[i], nzc[i], nnz[i], tmp)
        _state_predict(c, Phis[i], nzc[i], nnz[i], tmp)
        for j in range(n):
            sig_out[i, j] = math.sqrt(max(P[j, j], 0.0))
            x_out[i, j] = x[j]


@njit(cache=True)
def _seq_update(x, P, z, H, r, innov, sdiag, tmp, B):
    n = x.shape[0]
    pht = np.empty(n)
    kk = np.empty(n)
    nis = 0.0
    for c in range(z.shape[0]):
        nu, s = _scalar_update(x, P, H[c], r[c], z[c], True, pht, kk, tmp, B)
        innov[c] = nu
        sdiag[c] = s
        nis += nu * nu / s
    return nis


# ----------------------------------------------------------------------------------------
# stateful filter: feedback / feed-forward, lagged measurements
# ----------------------------------------------------------------------------------------
@dataclass
class _Epoch:
    t: float
    x_prior: np.ndarray          # feedback coordinates, before updates at this epoch
    P_prior: np.ndarray
    c_prior: np.ndarray          # cumulative feedback at the prior
    updates: list = field(default_factory=list)   # (z_ff, H, R, mask, sequential)
    aux: object = None
    Phi: np.ndarray | None = None  # to the next epoch (set by the next predict)
    Q: np.ndarray | None = None
    x_post: np.ndarray | None = None
    P_post: np.ndarray | None = None
    c_post: np.ndarray | None = None


@dataclass(frozen=True)
class FeedbackLayout:
    """Where the feedback-able blocks sit in an error-state vector.

    Each attribute is a slice or index array into the state vector, or None if the
    model has no such block. Used by :meth:`KalmanFilter.feedback` callers to route the
    estimate: ``att`` (φ, rad, ENU), ``vel`` (δv, m/s, ENU; 2 states = east, north of a
    horizontal model), ``pos`` (δL, δλ [rad], δh [m]; 2 states = δL, δλ), ``gyro``
    (rad/s), ``accel`` (m/s²), ``gyro_scale``, ``accel_scale`` (scale-factor errors [-],
    added to the scale compensation by the caller) and ``other`` blocks that are zeroed
    on feedback.
    """

    att: object = None
    vel: object = None
    pos: object = None
    gyro: object = None
    accel: object = None
    other: tuple = ()
    gyro_scale: object = None
    accel_scale: object = None

    def indices(self, n):
        """All fed-back state indices, sorted, as an int array."""
        out = []
        for s in (self.att, self.vel, self.pos, self.gyro, self.accel, self.gyro_scale,
                  self.accel_scale, *self.other):
            if s is not None:
                out.extend(np.arange(n)[s].tolist())
        return np.array(sorted(set(out)), dtype=np.int64)

    def split(self, x):
        """Dict of the blocks of ``x`` (absent blocks omitted)."""
        return {k: np.asarray(x)[getattr(self, k)] for k in ("att", "vel", "pos", "gyro", "accel")
                if getattr(self, k) is not None}

    @classmethod
    def from_model(cls, layout, *, att="phi", vel="dv", pos="dp", gyro="eps", accel="nabla",
                   gyro_scale="kg", accel_scale="ka", other=()):
        """From a :class:`sinslab.nav.errstate.StateLayout` (block names as in errstate's
        builders; missing blocks, or a name given as None, become None)."""
        names = [b.name for b in layout.blocks]
        get = lambda b: layout.slice(b) if (b is not None and b in names) else None  # noqa: E731
        return cls(get(att), get(vel), get(pos), get(gyro), get(accel),
                   tuple(layout.slice(o) for o in other), get(gyro_scale), get(accel_scale))

    def apply(self, filt, state, gyro_bias=None, accel_bias=None):
        """Closed-loop correction: feed the filter's estimate back into the INS.

        Takes the fed-back states out of ``filt`` (:meth:`KalmanFilter.feedback`, which
        zeroes them), corrects the strapdown state array in place with
        :func:`sinslab.nav.strapdown.correct` (φ [rad], δv [m/s], δp = [δL, δλ, δh]; the
        vertical of a 2-state horizontal block is left alone) and adds the bias estimates
        to the compensation in use (scale factors: ``d[gyro_scale]``, ``d[accel_scale]``
        are for the caller).

        Parameters
        ----------
        filt : KalmanFilter
        state : ndarray, shape (NSTATE,) or (10,)
            Strapdown state array (modified in place).
        gyro_bias, accel_bias : array_like, shape (3,), optional
            Current compensation [rad/s], [m/s²] (default zero).

        Returns
        -------
        gyro_bias, accel_bias : ndarray, shape (3,)
            The new compensation to pass to :func:`sinslab.nav.strapdown.step`.
        d : ndarray, shape (n,)
            The fed-back amounts.
        """
        from sinslab.nav import strapdown as sd
        d = filt.feedback(self.indices(filt.n))

        def three(s):
            if s is None:
                return None
            v = d[s]
            return v if v.size == 3 else np.r_[v, 0.0]

        sd.correct(state, phi=three(self.att), dvel=three(self.vel), dpos=three(self.pos))
        gb = np.zeros(3) if gyro_bias is None else np.asarray(gyro_bias, dtype=float).copy()
        ab = np.zeros(3) if accel_bias is None else np.asarray(accel_bias, dtype=float).copy()
        if self.gyro is not None:
            gb = gb + d[self.gyro]
        if self.accel is not None:
            ab = ab + d[self.accel]
        return gb, ab, d


class KalmanFilter:
    """A Kalman filter stepped by the caller, for use beside a nonlinear INS.

    The filter works on an error state ``x`` (n,) with covariance ``P`` (n, n) at time
    ``t``. The caller predicts with the Φ and Q_k of each step (e.g. from
    :mod:`sinslab.nav.errstate`) and applies measurements as they arrive.

    Feedback and feed-forward
    -------------------------
    Feed-forward (open loop): never call :meth:`feedback`; ``x`` estimates the errors of
    the free-running INS and the user subtracts it from the output. Feedback (closed
    loop): after an update, ``d = kf.feedback(indices)`` returns the estimate of those
    states and zeroes them in ``x``; the caller corrects the navigation state (e.g.
    ``strapdown.correct``) and the sensor compensation by ``d``. The filter keeps the
    cumulative correction ``c`` propagated by Φ, so that ``x + c`` (:attr:`x_total`)
    is the feed-forward-equivalent estimate and lagged measurements stay exact.

    Lagged measurements
    -------------------
    With ``history > 0`` the filter keeps a ring buffer of the last ``history`` epochs:
    prior state and covariance, the transition to the next epoch, applied measurements,
    the cumulative feedback, and an optional ``aux`` payload (e.g. a copy of the
    navigation state, to form the lagged measurement from the INS output of that time).
    :meth:`update_lagged` applies a measurement valid at an earlier epoch:

    * ``method="exact"``: inserts it at its epoch and re-processes the stored steps and
      measurements up to now. For a linear system the result equals that of a filter that
      received it on time (to rounding), in feedback or feed-forward mode.
    * ``method="paper003"``: Liu et al. 2004 (eqs 4–10): from the stored posterior at the
      last epoch at or before ``t_m`` predict to ``t_m`` with ``expm(F τ)`` and the
      integrated Q, update, then predict to the current time in one step with
      ``Φ = expm(F ΔT)`` and integrated Q (F constant, measurements in between ignored).

    Parameters
    ----------
    x0 : array_like, shape (n,)
        Initial error-state estimate.
    P0 : array_like, shape (n, n)
        Initial covariance, symmetric positive semi-definite.
    t0 : float
        Initial time [s].
    history : int
        Number of epochs kept for lagged measurements (0: none).
    check : bool
        Validate Q and R at every call (cheap for small n; turn off in hot loops once the
        model is trusted).
    """

    def __init__(self, x0, P0, *, t0=0.0, history=0, check=True):
        P0 = np.asarray(P0, dtype=float)
        n = P0.shape[0] if P0.ndim == 2 else -1
        self.P = check_covariance(_as_square(P0, n, "P0"), "P0").copy()
        self.n = n
        x0 = np.zeros(n) if x0 is None else np.asarray(x0, dtype=float).copy()
        if x0.shape != (n,):
            raise ValueError(f"x0 must have shape ({n},) to match P0, got {x0.shape}")
        self.x = x0
        self.t = float(t0)
        self.c = np.zeros(n)
        self.check = bool(check)
        self.history = int(history)
        self._buf = deque(maxlen=self.history) if self.history > 0 else None
        self._new_epoch()
        # numba work arrays for the fast path
        self._T1 = np.empty((n, n))
        self._T2 = np.empty((n, n))
        self._tmp = np.empty(n)

    # -- history -----------------------------------------------------------------------
    def _new_epoch(self, aux=None):
        if self._buf is not None:
            self._buf.append(_Epoch(self.t, self.x.copy(), self.P.copy(), self.c.copy(), aux=aux))

    def _close_epoch(self, Phi, Q):
        if self._buf is not None and self._buf:
            e = self._buf[-1]
            e.Phi, e.Q = Phi.copy(), Q.copy()
            e.x_post, e.P_post, e.c_post = self.x.copy(), self.P.copy(), self.c.copy()

    def set_aux(self, aux):
        """Attach a payload (e.g. a copy of the navigation state) to the current epoch."""
        if self._buf is not None:
            self._buf[-1].aux = aux

    def epochs(self):
        """Times [s] of the stored epochs, oldest first (shape (≤history,))."""
        return np.array([e.t for e in self._buf]) if self._buf is not None else np.empty(0)

    def aux_at(self, t_m, tol=1e-9):
        """The payload stored at the epoch ``t_m`` (within ``tol`` s)."""
        return self._buf[self._find(t_m, tol, exact=True)].aux

    def _find(self, t_m, tol, exact):
        if self._buf is None:
            raise ValueError("no history kept: create the filter with history > 0 for lagged measurements")
        ts = self.epochs()
        if t_m > self.t + tol:
            raise ValueError(f"measurement time {t_m} s is in the future (filter time {self.t} s)")
        if t_m < ts[0] - tol:
            raise ValueError(f"lagged measurement at {t_m} s is older than the stored history "
                             f"({ts[0]} .. {ts[-1]} s, {len(ts)} epochs); increase history")
        j = int(np.searchsorted(ts, t_m + tol, side="right")) - 1
        if exact and abs(ts[j] - t_m) > tol:
            raise ValueError(f"measurement time {t_m} s is not a stored epoch (nearest "
                             f"{ts[j]} s); predict to the measurement epoch or use method='paper003'")
        return j

    # -- basic steps -------------------------------------------------------------------
    @property
    def x_total(self):
        """Feed-forward-equivalent estimate ``x + c`` (n,): estimate of the errors of the
        INS as if no feedback had been applied."""
        return self.x + self.c

    @property
    def sigma(self):
        """Standard deviations sqrt(diag P), shape (n,)."""
        return np.sqrt(np.maximum(np.diag(self.P), 0.0))

    def predict(self, Phi, Q, dt, *, aux=None):
        """Advance by ``dt`` [s]: ``x <- Phi x``, ``P <- Phi P Phi^T + Q``.

        Parameters
        ----------
        Phi : array_like, shape (n, n)
        Q : array_like, shape (n, n)
        dt : float
            Step length [s] (> 0); the filter time advances by it.
        aux : object, optional
            Payload for the new epoch (see :meth:`set_aux`).
        """
        n = self.n
        Phi = np.ascontiguousarray(Phi, dtype=float)
        Q = np.ascontiguousarray(Q, dtype=float)
        if Phi.shape != (n, n) or Q.shape != (n, n):
            raise ValueError(f"Phi and Q must have shape ({n}, {n}), got {Phi.shape} and {Q.shape}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        if self.check:
            check_covariance(Q, "Q")
            if not np.all(np.isfinite(Phi)):
                raise ValueError("Phi has NaN/inf elements")
        self._close_epoch(Phi, Q)
        _cov_predict(self.P, Phi, Q, self._T1, self._T2)
        self.x = Phi @ self.x
        self.c = Phi @ self.c
        self.t += float(dt)
        self._new_epoch(aux)

    def predict_many(self, Phis, Qs, dt, *, aux=None, sigma_out=None, x_out=None):
        """Several :meth:`predict` steps in one compiled loop.

        Parameters
        ----------
        Phis, Qs : ndarray, shape (m, n, n)
            Transition and process-noise matrices of the m steps.
        dt : float
            Step length [s].
        aux : sequence of length m, optional
            Payloads of the new epochs (history only).
        sigma_out, x_out : ndarray, shape (m, n), optional
            Receive σ and x after each step.
        """
        Phis = np.ascontiguousarray(Phis, dtype=float)
        Qs = np.ascontiguousarray(Qs, dtype=float)
        m = Phis.shape[0]
        if self._buf is not None or self.check:
            for i in range(m):
                self.predict(Phis[i], Qs[i], dt, aux=None if aux is None else aux[i])
                if sigma_out is not None:
                    sigma_out[i] = self.sigma
                if x_out is not None:
                    x_out[i] = self.x
            return
        n = self.n
        if Phis.shape != (m, n, n) or Qs.shape != (m, n, n):
            raise ValueError(f"Phis and Qs must have shape (m, {n}, {n}), got {Phis.shape}, {Qs.shape}")
        nzc = np.zeros((m, n, max(n, 1)), dtype=np.int64)
        nnz = np.zeros((m, n), dtype=np.int64)
        _sparsity_nb(Phis, nzc, nnz)
        so = np.empty((m, n)) if sigma_out is None else sigma_out
        xo = np.empty((m, n)) if x_out is None else x_out
        _predict_many(self.x, self.c, self.P, Phis, Qs, nzc, nnz, self._T1, self._T2, self._tmp,
                      so, xo)
        self.t += m * float(dt)

    def update(self, z, H, R, *, mask=None, sequential=None):
        """Apply a measurement valid now (see :func:`update`). Returns :class:`UpdateResult`."""
        if not self.check and self._buf is None and mask is None and sequential is not False:
            fast = self._fast_update(z, H, R)
            if fast is not None:
                return fast
        res = update(self.x, self.P, z, H, R, mask=mask, sequential=sequential)
        if self._buf is not None:
            z = np.atleast_1d(np.asarray(z, dtype=float))
            Hm = np.atleast_2d(np.asarray(H, dtype=float))
            self._buf[-1].updates.append((z + Hm @ self.c, Hm, R, res.used.copy(), sequential))
        # own copies: predict() and feedback() work in place
        self.x, self.P = res.x.copy(), res.P.copy()
        return res

    def _fast_update(self, z, H, R):
        """Sequential scalar Joseph updates in compiled code (diagonal R, finite z)."""
        z = np.atleast_1d(np.asarray(z, dtype=float))
        H = np.ascontiguousarray(np.atleast_2d(H), dtype=float)
        R = np.asarray(R, dtype=float)
        m = z.size
        if R.ndim == 2:
            if R.shape != (m, m) or not _is_diag(R):
                return None
            r = np.diag(R).copy()
        else:
            r = np.broadcast_to(R, (m,)).astype(float)
        if H.shape != (m, self.n) or not np.all(np.isfinite(z)) or not np.all(r > 0):
            return None
        S = H @ self.P @ H.T + np.diag(r)
        innov = np.empty(m)
        sdiag = np.empty(m)
        nis = _seq_update(self.x, self.P, z, H, r, innov, sdiag, self._tmp, self._T1)
        return UpdateResult(self.x.copy(), self.P.copy(), innov, S, float(nis),
                            np.ones(m, dtype=bool))

    def feedback(self, indices=None):
        """Return the estimate of the given states and zero them (closed-loop correction).

        Parameters
        ----------
        indices : array_like of int or slice, optional
            States to feed back (default all), e.g. ``FeedbackLayout.indices(n)``.

        Returns
        -------
        ndarray, shape (n,)
            The fed-back amounts (zero outside ``indices``); the caller subtracts them
            from the navigation state / adds them to the sensor compensation.
        """
        d = np.zeros(self.n)
        idx = np.arange(self.n) if indices is None else np.arange(self.n)[indices]
        d[idx] = self.x[idx]
        self.x[idx] = 0.0
        self.c += d
        return d

    # -- lagged measurements -----------------------------------------------------------
    def update_lagged(self, z, H, R, t_m, *, method="exact", F=None, Qc=None, mask=None,
                      sequential=None, tol=1e-9):
        """Apply a measurement valid at ``t_m`` <= now, arriving now.

        Parameters
        ----------
        z, H, R, mask, sequential
            As in :func:`update`; ``z`` must be formed from the navigation state of
            ``t_m`` as it was then (:meth:`aux_at` returns what was stored). With
            feedback: for ``"exact"`` that is the INS output at epoch ``t_m`` *before*
            any feedback applied at that epoch (the payload given to :meth:`predict`);
            for ``"paper003"`` it is the output *after* the feedback at the last stored
            epoch at or before ``t_m`` (propagated to ``t_m``), as in the paper.
        t_m : float
            Validity time of the measurement [s].
        method : {"exact", "paper003"}
            See the class notes. ``"paper003"`` needs ``F`` (n, n) and ``Qc`` (n, n), the
            continuous system matrix and process-noise density used for the
            ``expm(F ΔT)`` / Van Loan predictions.
        tol : float
            Time tolerance [s] for matching ``t_m`` to a stored epoch.

        Returns
        -------
        UpdateResult
            Of the update at ``t_m`` (innovation, S, NIS there); the filter's ``x``, ``P``
            are then those of the current time.

        Raises
        ------
        ValueError
            ``t_m`` older than the stored history, in the future, or (exact) not a stored
            epoch.
        """
        if method == "exact":
            return self._lagged_exact(z, H, R, t_m, mask, sequential, tol)
        if method == "paper003":
            if F is None or Qc is None:
                raise ValueError("method='paper003' needs F and Qc (continuous model at t_m)")
            return self._lagged_paper003(z, H, R, t_m, F, Qc, mask, sequential, tol)
        raise ValueError(f"unknown lag method {method!r}; use 'exact' or 'paper003'")

    def _lagged_exact(self, z, H, R, t_m, mask, sequential, tol):
        j = self._find(t_m, tol, exact=True)
        buf = self._buf
        z = np.atleast_1d(np.asarray(z, dtype=float))
        Hm = np.atleast_2d(np.asarray(H, dtype=float))
        e = buf[j]
        z_ff = z + Hm @ e.c_prior
        # re-run in feed-forward coordinates from the prior at epoch j
        xff = e.x_prior + e.c_prior
        P = e.P_prior.copy()
        first = None
        last = len(buf) - 1
        for i in range(j, last + 1):
            ei = buf[i]
            if i > j:
                prev = buf[i - 1]
                xff = prev.Phi @ xff
                P = prev.Phi @ P @ prev.Phi.T + prev.Q
                P = 0.5 * (P + P.T)
                ei.x_prior = xff - ei.c_prior
                ei.P_prior = P.copy()
            ups = ei.updates
            if i == j:
                res = update(xff, P, z_ff, Hm, R, mask=mask, sequential=sequential)
                first = res
                xff, P = res.x, res.P
            for (zf, Hs, Rs, ms, sq) in ups:
                r2 = update(xff, P, zf, Hs, Rs, mask=ms, sequential=sq)
                xff, P = r2.x, r2.P
            if i < last:
                ei.x_post = xff - ei.c_post
                ei.P_post = P.copy()
        buf[j].updates.insert(0, (z_ff, Hm, R, first.used.copy(), sequential))
        self.x = xff - self.c
        self.P = np.array(P, dtype=float, order="C", copy=True)
        return UpdateResult(first.x - e.c_prior, first.P, first.innovation, first.S, first.nis, first.used)

    def _lagged_paper003(self, z, H, R, t_m, F, Qc, mask, sequential, tol):
        j = self._find(t_m, tol, exact=False)
        buf = self._buf
        e = buf[j]
        last = len(buf) - 1
        if j == last:
            x_post, P_post, c_post = self.x, self.P, self.c
        else:
            x_post, P_post, c_post = e.x_post, e.P_post, e.c_post
        z = np.atleast_1d(np.asarray(z, dtype=float))
        Hm = np.atleast_2d(np.asarray(H, dtype=float))
        xff = x_post + c_post
        tau = max(t_m - e.t, 0.0)
        if tau > 0:
            Phi1, Q1 = discretize(F, Qc, tau)
            xff = Phi1 @ xff
            P = Phi1 @ P_post @ Phi1.T + Q1
        else:
            P = P_post.copy()
        # the measurement was formed from the navigation state at t_m, which carried the
        # cumulative feedback of epoch j propagated to t_m
        c_m = (discretize(F, np.zeros_like(F), tau)[0] @ c_post) if tau > 0 else c_post
        res = update(xff, 0.5 * (P + P.T), z + Hm @ c_m, Hm, R, mask=mask, sequential=sequential)
        dT = self.t - t_m
        if dT > 0:
            Phi2, Q2 = discretize(F, Qc, dT)
            xff = Phi2 @ res.x
            P = Phi2 @ res.P @ Phi2.T + Q2
        else:
            xff, P = res.x, res.P
        self.x = xff - self.c
        self.P = 0.5 * (P + P.T)
        # the stored history no longer matches this one-step form: restart it from now
        cur = buf[-1]
        buf.clear()
        cur.x_prior, cur.P_prior, cur.c_prior = self.x.copy(), self.P.copy(), self.c.copy()
        cur.updates = []
        buf.append(cur)
        return res
