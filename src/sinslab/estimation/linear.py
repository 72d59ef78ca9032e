"""Compiled (numba) time loops of linear Kalman filters: data runs, covariance analysis and
error budgets.

:func:`run_linear` (state and covariance with data), :func:`propagate_covariance` (no
data: covariance analysis, and the gains of a filter whose covariance does not depend on
the data), :func:`fixed_gain_runs` (that filter over many data records) and
:func:`error_budget`, which splits the variance into the contributions of P0, each
process-noise source and each measurement-noise source.
Time-varying systems are given as *tables* of matrices plus per-step *index* arrays, so
a piecewise-constant or periodically varying system costs no memory per step. Their
steps are the kernels of :mod:`sinslab.estimation.kernels` (covariance prediction, sparse
state prediction, Joseph scalar and vector updates, the fixed-gain update), those of every
compiled filter loop.

Conventions of the loops
------------------------
``n`` states, ``m`` measurement components, ``K`` steps. Step ``k`` (0-based) predicts
from epoch ``k`` to epoch ``k+1`` with ``Phi_k``, ``Q_k`` and then applies the measurement
``z[k]`` (valid at epoch ``k+1``) where ``mask[k]`` is true. Histories have ``K+1`` rows:
row 0 is the initial condition.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from sinslab.estimation.kalman import _as_square, _is_diag, check_covariance
from sinslab.estimation.kernels import (copy2, cov_predict, gain_correct, innovation, innovation_cov, row_nonzeros,
                                         predicted_dense, scalar_update, series_step, series_structure,
                                         state_predict, vector_update)

from sinslab.core.jitnotice import install as _compile_notice

_compile_notice()   # a status line while the kernels below compile (first run)

__all__ = ["run_linear", "LinearRun", "propagate_covariance", "fixed_gain_runs", "error_budget", "Budget",
           "sparsity", "discretize_series_many"]


# ----------------------------------------------------------------------------------------
# compiled time loops (scalar style, no temporaries inside the loop)
# ----------------------------------------------------------------------------------------
@njit(cache=True)
def _compose_gain(G, h, kk, c, hg):
    """``G ← (I − k hᵀ) G``, then ``G[:, c] += k``: the gain (n, m) of the updates so far
    followed by a scalar update of component ``c`` (gain ``kk``, row ``h``). ``hg`` (m,)
    is a work array."""
    n, m = G.shape
    for a in range(m):
        t = 0.0
        for j in range(n):
            if h[j] != 0.0:
                t += h[j] * G[j, a]
        hg[a] = t
    for i in range(n):
        for a in range(m):
            G[i, a] -= kk[i] * hg[a]
        G[i, c] += kk[i]


@njit(cache=True)
def _linear_loop(x, P, Phi_t, phi_i, Q_t, q_i, H_t, h_i, R_t, r_i, z, mask, R_corr, with_x,
                 nzc_t, nnz_t, save_flag, x_hist, pd_hist, P_save, innov, sdiag, nis, gain, S_prior):
    """The time loop of :func:`_run`. ``R_corr`` is None when every R of the table is
    diagonal (scalar updates), else the table itself (vector updates with the full R): a
    None argument prunes the vector branch at compile time, so a run with diagonal R
    does not compile :func:`vector_update` (a second of a first run).

    ``gain`` (K, n, m) and ``S_prior`` (K, m, m), or (0, …) not to keep them: each step's
    gain G (``x⁺ = x⁻ + G (z − H x⁻)``, zero columns where nothing is measured; the scalar
    updates compose to it, each mapping ``G ← (I − k h) G`` and adding ``k`` to its own
    column, a vector update gives it whole) and innovation covariance ``H P⁻ Hᵀ + R``.
    Empty arrays rather than None: runs with and without them share one compiled loop (a
    compilation costs ~2 s of a fresh clone's first run, and one more in every Dask worker
    of a campaign that runs both)."""
    n = P.shape[0]
    K = phi_i.shape[0]
    m = mask.shape[1]
    T1, T2 = np.empty((n, n)), np.empty((n, n))
    tmp, pht, kk, bh = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    used = np.empty(m, dtype=np.int64)
    hg = np.empty(m)
    PHt = np.empty((n, m))
    ns = 0
    if with_x:
        for j in range(n):
            x_hist[0, j] = x[j]
    for j in range(n):
        pd_hist[0, j] = P[j, j]
    if save_flag[0]:
        copy2(P_save[ns], P)
        ns += 1
    for k in range(K):
        ip = phi_i[k]
        cov_predict(P, Phi_t[ip], Q_t[q_i[k]], n, T1, T2)
        if with_x:
            state_predict(x, Phi_t[ip], nzc_t[ip], nnz_t[ip], tmp)
        nu_tot = 0.0
        nm = 0
        for c in range(m):
            if mask[k, c]:
                used[nm] = c
                nm += 1
        if S_prior.shape[0] > 0:
            innovation_cov(H_t[h_i[k]], P, R_t[r_i[k]], PHt, S_prior[k])
        if nm > 0:
            Hk = H_t[h_i[k]]
            if R_corr is None:
                Rk = R_t[r_i[k]]
                for a in range(nm):
                    c = used[a]
                    zc = 0.0
                    if with_x:
                        zc = z[k, c]
                    nu, s = scalar_update(x, P, Hk[c], Rk[c, c], zc, with_x, pht, kk, bh, T1)
                    innov[k, c] = nu
                    sdiag[k, c] = s
                    nu_tot += nu * nu / s
                    if gain.shape[0] > 0:
                        _compose_gain(gain[k], Hk[c], kk, c, hg)
            else:
                nuv, S, nisv, Kv = vector_update(x, P, Hk, R_corr[r_i[k]], z[k], used[:nm], with_x)
                for a in range(nm):
                    innov[k, used[a]] = nuv[a]
                    sdiag[k, used[a]] = S[a, a]
                    if gain.shape[0] > 0:
                        for i in range(n):
                            gain[k, i, used[a]] = Kv[i, a]
                nu_tot = nisv
        nis[k] = nu_tot
        if with_x:
            for j in range(n):
                x_hist[k + 1, j] = x[j]
        for j in range(n):
            pd_hist[k + 1, j] = P[j, j]
        if save_flag[k + 1]:
            copy2(P_save[ns], P)
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
        cov_predict(Ptot, Phi_t[ip], Qtot, n, T1, T2)
        for s in range(S):
            if src_q[s] >= 0:
                cov_predict(C[s], Phi_t[ip], Qparts_t[src_q[s], iq], n, T1, T2)
            else:
                cov_predict(C[s], Phi_t[ip], Zero, n, T1, T2)
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
            scalar_update(dummy, Ptot, h, r, 0.0, False, pht, kk, bh, T1)
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


def _sparsity(Phi_t):
    """Per row, the columns where Phi is non-zero (zero entries are skipped in products)."""
    L, n, _ = Phi_t.shape
    nnz = np.zeros((L, n), dtype=np.int64)
    nzc = np.zeros((L, n, max(1, n)), dtype=np.int64)
    row_nonzeros(Phi_t, nzc, nnz)
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
    gain : ndarray, shape (K, n, m) or None
        With ``keep_gain``: each step's gain, ``x⁺ = x⁻ + gain[k] (z[k] − H x⁻)`` (zero
        columns where nothing was measured) — the filter to run on other data with fixed gains.
    S : ndarray, shape (K, m, m) or None
        With ``keep_gain``: each step's innovation covariance ``H P⁻ Hᵀ + R`` of all m
        components (the NIS of that fixed-gain filter is ``νᵀ S⁻¹ ν``).
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
    gain: np.ndarray | None = None
    S: np.ndarray | None = None

    @property
    def sigma(self) -> np.ndarray:
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


def _run(prep, with_x, save_at, keep_gain=False):
    n, m, K = prep["n"], prep["m"], prep["K"]
    gain = np.zeros((K if keep_gain else 0, n, m))
    S_prior = np.empty((K if keep_gain else 0, m, m))
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
                       prep["mask"], None if prep["diagR"] else prep["R_t"], with_x, nzc, nnz,
                       save_flag, x_hist, pd, P_save, innov, sdiag, nis, gain, S_prior)
    if bad >= 0:
        raise ValueError(f"covariance became NaN at step {bad}: check Phi, Q, R for extreme values")
    return LinearRun(x_hist if with_x else None, pd, P_save, save_at, innov, sdiag, nis,
                     x if with_x else None, P, gain if keep_gain else None, S_prior if keep_gain else None)


def run_linear(x0: ArrayLike, P0: ArrayLike, Phi: ArrayLike, Q: ArrayLike, H: ArrayLike, R: ArrayLike,
               z: ArrayLike, *, mask: ArrayLike | None = None, windows: Sequence[tuple[float, float]] | None = None,
               t: ArrayLike | None = None, Phi_index: ArrayLike | None = None, Q_index: ArrayLike | None = None,
               H_index: ArrayLike | None = None, R_index: ArrayLike | None = None, save_at: ArrayLike | None = None,
               check: bool = True) -> LinearRun:
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


def propagate_covariance(P0: ArrayLike, Phi: ArrayLike, Q: ArrayLike, H: ArrayLike | None = None,
                         R: ArrayLike | None = None, *, n_steps: int | None = None, mask: ArrayLike | None = None,
                         windows: Sequence[tuple[float, float]] | None = None, t: ArrayLike | None = None,
                         Phi_index: ArrayLike | None = None, Q_index: ArrayLike | None = None,
                         H_index: ArrayLike | None = None, R_index: ArrayLike | None = None,
                         save_at: ArrayLike | None = None, check: bool = True, keep_gain: bool = False) -> LinearRun:
    """Covariance analysis: propagate P (no data) with an optional measurement schedule.

    Same conventions as :func:`run_linear`; measurements are applied where ``mask`` (or
    ``windows``) says so, or at every step if neither is given and ``H`` is. Give
    ``n_steps`` when all of Phi, Q, H, R are constant. ``keep_gain`` keeps every step's
    gain and innovation covariance (``LinearRun.gain``, ``LinearRun.S``): the covariance
    does not depend on the data, so these gains run the same filter on any number of data
    records as a fixed-gain recursion ``x⁺ = Φ x + G (z − H Φ x)``
    (:func:`fixed_gain_runs`).

    Returns
    -------
    LinearRun
        with ``x`` None; ``sigma`` gives the σ of every state versus epoch.
    """
    prep = _prepare(None, P0, Phi, Q, H, R, None, mask, windows, t, n_steps, Phi_index,
                    Q_index, H_index, R_index, False, check)
    return _run(prep, False, save_at, keep_gain)


@njit(cache=True)
def _gain_runs(X, Phi_t, phi_i, H_t, h_i, gain, z, mask, x_hist, nu_hist):
    """The time loop of :func:`fixed_gain_runs`, record by record (a record's numbers do not
    depend on the records beside it); each step's estimate is stepped in its row of
    ``x_hist``."""
    B, n = X.shape
    K, m = mask.shape
    for b in range(B):
        for j in range(n):
            x_hist[b, 0, j] = X[b, j]
        for k in range(K):
            x = x_hist[b, k + 1]
            predicted_dense(x_hist[b, k], Phi_t[phi_i[k]], x)
            nu = nu_hist[b, k]
            on = False
            for c in range(m):
                on = on or mask[k, c]
            if not on:
                for c in range(m):
                    nu[c] = np.nan
                continue
            innovation(x, H_t[h_i[k]], z[b, k], nu)
            for c in range(m):
                if not mask[k, c]:
                    nu[c] = 0.0
            gain_correct(x, gain[k], nu)
            for c in range(m):
                if not mask[k, c]:
                    nu[c] = np.nan


def fixed_gain_runs(x0: ArrayLike, Phi: ArrayLike, H: ArrayLike, gain: ArrayLike, z: ArrayLike, *,
                    mask: ArrayLike | None = None, Phi_index: ArrayLike | None = None,
                    H_index: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A filter with fixed gains (those of :func:`propagate_covariance` with ``keep_gain``)
    over many data records, compiled, record by record.

    Same conventions as :func:`run_linear`: step k predicts ``x ← Φ_k x`` and, where
    measured, updates ``x ← x + gain[k] (z[k] − H_k x)``.

    Parameters
    ----------
    x0 : array_like, shape (B, n)
        Initial estimate of each record.
    Phi : array_like, shape (n, n), (K, n, n) or (L, n, n) with ``Phi_index``
    H : array_like, shape (m, n), (K, m, n) or (L, m, n) with ``H_index``
    gain : array_like, shape (K, n, m)
        Each step's gain (``LinearRun.gain``).
    z : array_like, shape (B, K, m)
        Measurements of each record; ``z[:, k]`` is valid at epoch ``k+1``.
    mask : array_like of bool, shape (K, m) or (K,), optional
        Components measured at each step (default all).

    Returns
    -------
    x : ndarray, shape (B, K+1, n)
        Estimates (row 0 = x0).
    innovation : ndarray, shape (B, K, m)
        Innovations against the prediction (NaN where not measured).
    """
    X = np.array(x0, dtype=float, ndmin=2, order="C")
    z = np.ascontiguousarray(z, dtype=float)
    gain = np.ascontiguousarray(gain, dtype=float)
    B, n = X.shape
    if z.ndim != 3 or z.shape[0] != B:
        raise ValueError(f"z must have shape ({B}, K, m) for {B} records, got {z.shape}")
    K, m = z.shape[1], z.shape[2]
    if gain.shape != (K, n, m):
        raise ValueError(f"gain must have shape ({K}, {n}, {m}), got {gain.shape}")
    Phi_t, phi_i = _table(Phi, Phi_index, K, (n, n), "Phi")
    H_t, h_i = _table(H, H_index, K, (m, n), "H")
    mk = np.ones((K, m), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    if mk.shape == (K,):
        mk = np.repeat(mk[:, None], m, axis=1)
    if mk.shape != (K, m):
        raise ValueError(f"mask must have shape ({K}, {m}) or ({K},), got {mk.shape}")
    xs = np.empty((B, K + 1, n))
    nu = np.empty((B, K, m))
    _gain_runs(X, Phi_t, phi_i, H_t, h_i, gain, z, np.ascontiguousarray(mk), xs, nu)
    return xs, nu


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

    def fraction(self) -> np.ndarray:
        """Share of each source in the final variance, shape (S, n)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return self.variance / self.total


def error_budget(P0_parts: ArrayLike, Phi: ArrayLike, Q_parts: ArrayLike, H: ArrayLike, R_parts: ArrayLike, *,
                 n_steps: int | None = None, mask: ArrayLike | None = None,
                 windows: Sequence[tuple[float, float]] | None = None, t: ArrayLike | None = None,
                 Phi_index: ArrayLike | None = None, Q_index: ArrayLike | None = None,
                 H_index: ArrayLike | None = None, R_index: ArrayLike | None = None,
                 names: Sequence[str] | None = None, history_every: int = 0) -> Budget:
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



def sparsity(Phi_t: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Per row, the columns where Φ is non-zero (zero entries are skipped in products).

    Parameters
    ----------
    Phi_t : ndarray, shape (L, n, n)

    Returns
    -------
    nzc : ndarray of int64, shape (L, n, max(n, 1))
        Column indices of the non-zeros of each row (first ``nnz`` entries valid).
    nnz : ndarray of int64, shape (L, n)
        Number of non-zeros per row.
    """
    return _sparsity(np.ascontiguousarray(Phi_t, dtype=float))


# ----------------------------------------------------------------------------------------
# series discretisation of many epochs (the "series" method of kalman.discretize, compiled)
# ----------------------------------------------------------------------------------------
@njit(cache=True)
def _series_many(F, G, q, T, Phi, Q):
    S, n, m = F.shape[0], F.shape[1], G.shape[2]
    # possible non-zeros: those of any epoch
    fnz = np.zeros((n, n), dtype=np.bool_)
    gnz = np.zeros((n, m), dtype=np.bool_)
    for e in range(S):
        for i in range(n):
            for j in range(n):
                if F[e, i, j] != 0.0:
                    fnz[i, j] = True
            for c in range(m):
                if G[e, i, c] != 0.0:
                    gnz[i, c] = True
    fcol, fcnt, grow, gcnt, R, pos, nr, phic, phin, qr, nq, qbr, qbn, prc, prn = \
        series_structure(fnz, gnz, q)
    nr1 = max(nr, 1)
    Qb = np.zeros((nr1, nr1))
    PR = np.zeros((n, nr1))
    W = np.zeros((n, nr1))
    for e in range(S):
        series_step(F[e], G[e], q, T, fcol, fcnt, grow, gcnt, R, pos, nr, qr, nq, Qb, PR, W,
                    Phi[e], Q[e], qbr, qbn, prc, prn)


def discretize_series_many(F: ArrayLike, G: ArrayLike, q: ArrayLike, T: float, Phi: np.ndarray | None = None,
                           Q: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``"series"`` discretisation of :func:`sinslab.estimation.kalman.discretize`
    for many epochs, compiled and using the zeros of F and G.

    Parameters
    ----------
    F : ndarray, shape (S, n, n)
        Continuous system matrices, one per epoch.
    G : ndarray, shape (S, n, p)
        Noise input matrices.
    q : ndarray, shape (p,)
        Spectral densities of the independent noises (>= 0).
    T : float
        Step [s].
    Phi, Q : ndarray, shape (≥S, n, n), optional
        Output buffers.

    Returns
    -------
    Phi, Qk : ndarray, shape (S, n, n)
        ``Φ = I + F T + (F T)²/2``, ``Q_k = T (Q̄ + Φ Q̄ Φᵀ)/2`` with ``Q̄ = G diag(q) Gᵀ``
        (exactly symmetric); equal to ``discretize(F, q, T, G=G, method="series")`` to
        rounding.
    """
    F = np.ascontiguousarray(F, dtype=float)
    G = np.ascontiguousarray(G, dtype=float)
    q = np.ascontiguousarray(q, dtype=float)
    S, n = F.shape[0], F.shape[-1]
    if F.ndim != 3 or F.shape[1] != n or G.ndim != 3 or G.shape[:2] != (S, n) or q.shape != G.shape[2:]:
        raise ValueError(f"shape mismatch: F {F.shape}, G {G.shape}, q {q.shape}")
    if np.any(q < 0):
        raise ValueError("noise spectral densities must be >= 0")
    if not T >= 0:
        raise ValueError(f"step T must be >= 0, got {T}")
    Phi = np.empty((S, n, n)) if Phi is None or Phi.shape[0] < S else Phi
    Q = np.empty((S, n, n)) if Q is None or Q.shape[0] < S else Q
    Phi, Q = Phi[:S], Q[:S]
    _series_many(F, G, q, float(T), Phi, Q)
    return Phi, Q
