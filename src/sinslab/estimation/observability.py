"""Observability of linear (piecewise-constant) error-state systems.

For ``ẋ = F x``, ``z = H x`` (n states, p measurements) this module computes

- the observability matrix ``O = [H; H F; …; H F^{n−1}]`` and its rank;
- for piecewise-constant systems (segments j = 1..m with (F_j, H_j, T_j)), the rank after
  each segment of the *stripped* observability matrix (SOM, simple stacking
  ``[O_1; O_2; …; O_m]``, paper 001 eq 15) and of the *total* observability matrix
  (TOM, Goshen-Meskin & Bar-Itzhack 1992: ``[O_1; O_2 Φ_1; O_3 Φ_2 Φ_1; …]``,
  ``Φ_j = expm(F_j T_j)``). The SOM equals the TOM's rank when ``null(O_j) ⊂ null(F_j)``
  for every segment (G-M's condition, true e.g. for stationary segments whose unobservable
  directions are steady states); the TOM is always the exact answer;
- the unobservable subspace (orthonormal basis of the null space);
- a per-state SVD degree of observability and the covariance-based degrees.

Numerics (stated, because ranks of navigation models are ill-conditioned in SI units):

1. **state scaling** ``x = D x'``: ``scale`` gives D (e.g. 1σ of each state, so that
   ``sqrt(diag(P0))`` makes the analysis unit-free); by default D is chosen automatically
   by equilibrating the columns of O (two passes) — rank and null space do not depend on
   D in exact arithmetic, only their numerical detection does;
2. **time scaling**: the powers use ``F'/s`` with ``s = ‖F'‖₂`` (row space unchanged);
3. **row normalisation**: every row of the stacked matrix is scaled to unit norm; rows
   below ``1e-13`` of the largest (numerically zero) are dropped;
4. **rank** = number of singular values above ``rtol · σ_max`` (default ``rtol = 1e-9``).

Degree of observability (per state): ``d_j = min ‖O' x'‖ subject to x'_j = 1`` divided
by σ_max (O' = the scaled, normalised matrix): the smallest measurement response a unit
(1σ with ``scale`` = P0 σ) change of state j can produce when all other states may
conspire to hide it. It is 0 exactly for states with a component in the unobservable
subspace and 1/σ_max·σ_i for a state aligned with one singular direction; it equals
``1 / sqrt([(O'ᵀO')⁻¹]_jj)`` — the Cramér–Rao bound of state j from noise-free outputs —
which is why it is preferred here to "largest component of each singular vector"
(Goshen-Meskin), also returned for reference (:attr:`ObservabilityResult.dominant`).
The covariance degrees (Ham & Brown 1983) are :func:`covariance_degree` and
:func:`covariance_eigen_degree`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike

__all__ = [
    "observability_matrix", "ObservabilityResult", "analyze", "rank", "unobservable_subspace",
    "PiecewiseResult", "piecewise", "covariance_degree", "covariance_eigen_degree",
    "DEFAULT_RTOL",
]

DEFAULT_RTOL = 1e-9          #: relative singular-value tolerance for ranks
_ROW_DROP = 1e-13            #: rows below this fraction of the largest are numerical zeros


def _check(F: ArrayLike, H: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    F = np.asarray(F, dtype=float)
    H = np.atleast_2d(np.asarray(H, dtype=float))
    n = F.shape[0]
    if F.shape != (n, n):
        raise ValueError(f"F must be square, got {F.shape}")
    if H.shape[1] != n:
        raise ValueError(f"H must have {n} columns, got {H.shape}")
    if not (np.all(np.isfinite(F)) and np.all(np.isfinite(H))):
        raise ValueError("F and H must be finite")
    return F, H


def observability_matrix(F: ArrayLike, H: ArrayLike, k: int | None = None, time_scale: float = 1.0) -> np.ndarray:
    """Observability matrix ``[H; H A; …; H A^{k−1}]`` with ``A = F · time_scale``.

    Parameters
    ----------
    F : array (n, n)
    H : array (p, n)
    k : int, optional
        Number of blocks (default n).
    time_scale : float
        Multiplies F (a unit of time; any positive value leaves the row space unchanged).

    Returns
    -------
    O : ndarray (k·p, n)
    """
    F, H = _check(F, H)
    k = F.shape[0] if k is None else int(k)
    A = F * time_scale
    blocks = [H]
    for _ in range(k - 1):
        blocks.append(blocks[-1] @ A)
    return np.vstack(blocks)


def _normalised_O(F, H, D):
    """Stripped O of the state-scaled system (F' = D⁻¹FD, H' = HD), time-scaled."""
    Fp = F * D[None, :] / D[:, None]
    Hp = H * D[None, :]
    s = float(np.linalg.norm(Fp, 2))
    return observability_matrix(Fp, Hp, time_scale=1.0 / s if s > 0 else 1.0)


def _rownorm(O):
    r = np.linalg.norm(O, axis=1)
    if r.size == 0 or r.max() == 0:
        return O[:0]
    keep = r > _ROW_DROP * r.max()
    return O[keep] / r[keep, None]


def _balance(F, H):
    """Diagonal D from balancing the augmented matrix [[F, 0], [H, 0]] (similarity on F,
    column scaling of H): makes the scaled F' and H' entries comparable before any power."""
    n, p = F.shape[0], H.shape[0]
    M = np.zeros((n + p, n + p))
    M[:n, :n] = F
    M[n:, :n] = H
    if not np.any(M):
        return np.ones(n)
    _, (sc, _) = scipy.linalg.matrix_balance(M, permute=False, separate=True)
    return sc[:n].astype(float)


def _auto_scale(blocks_fn, n, D0=None):
    """Column equilibration: D_j = 1/‖column j‖ of the normalised matrix (three passes from
    the balancing scale D0)."""
    D = np.ones(n) if D0 is None else D0.copy()
    for _ in range(3):
        O = _rownorm(blocks_fn(D))
        c = np.linalg.norm(O, axis=0)
        c[c == 0] = 1.0
        D = D / c
    return D


@dataclass(frozen=True)
class ObservabilityResult:
    """Result of :func:`analyze`.

    Attributes
    ----------
    rank : int
        Numerical rank of the observability matrix.
    n : int
        Number of states.
    singular_values : ndarray
        Of the scaled, row-normalised observability matrix, descending, divided by the
        largest (so the first is 1).
    null_space : ndarray (n, n − rank)
        Basis of the unobservable subspace in the original (SI) coordinates: ``D·V₀``
        with V₀ orthonormal in the scaled coordinates, each column then normalised to unit
        length (it is not re-orthogonalised in SI, where states of different units would
        lose their small components to round-off).
    degree : ndarray (n,)
        Per-state degree of observability in [0, 1] (see module docstring); 0 means the
        state has a component in the unobservable subspace.
    observable_fraction : ndarray (n,)
        ``‖P_row e_j‖`` in the scaled coordinates: the share of state j (unit vector) lying
        in the observable subspace (1 = fully observable direction, 0 = unobservable).
        Useful where every state mixes with an unobservable direction (paper 000 at
        mid-latitudes: all 8 strict degrees are 0, yet εN is 99.99 % observable).
    dominant : ndarray (r,)
        For each singular value σ_i > 0 the index of the state with the largest component
        of the right singular vector (Goshen-Meskin's association), for reference.
    scale : ndarray (n,)
        The state scaling D used.
    rtol : float
    """

    rank: int
    n: int
    singular_values: np.ndarray
    null_space: np.ndarray
    degree: np.ndarray
    observable_fraction: np.ndarray
    dominant: np.ndarray
    scale: np.ndarray
    rtol: float

    @property
    def observable(self) -> bool:
        return self.rank == self.n

    def table(self, labels: Sequence[str] | None = None) -> str:
        """Per-state degree as text."""
        labels = labels or [f"x{i}" for i in range(self.n)]
        return "\n".join(f"{l:>10s} {d:.3e}" for l, d in zip(labels, self.degree))


def _result_from(O_scaled, D, rtol):
    n = D.size
    O = _rownorm(O_scaled)
    if O.shape[0] == 0:
        sv = np.zeros(n)
        V = np.eye(n)
    else:
        _, sv, Vt = np.linalg.svd(O, full_matrices=True)
        V = Vt.T
        sv = np.concatenate([sv, np.zeros(n - sv.size)]) if sv.size < n else sv
    smax = sv[0] if sv[0] > 0 else 1.0
    svn = sv / smax
    r = int(np.sum(svn > rtol))
    Nsc = V[:, r:]                                 # null space, scaled coordinates
    N = D[:, None] * Nsc                          # not re-orthogonalised in SI: the units mix
    if N.shape[1]:
        N = N / np.linalg.norm(N, axis=0)
    # degree: 1/sqrt(diag((OᵀO)^+)) restricted to the observable part; 0 if e_j ∉ row space
    deg = np.zeros(n)
    if r:
        Vr, sr = V[:, :r], svn[:r]
        inrow = np.linalg.norm(Nsc, axis=1) < 1e-6 if Nsc.shape[1] else np.ones(n, bool)
        ginv_diag = np.sum((Vr / sr[None, :]) ** 2, axis=1)
        with np.errstate(divide="ignore"):
            deg = np.where(inrow & (ginv_diag > 0), 1.0 / np.sqrt(ginv_diag), 0.0)
    frac = np.linalg.norm(V[:, :r], axis=1)
    dom = np.argmax(np.abs(V[:, :r]), axis=0) if r else np.zeros(0, int)
    return ObservabilityResult(r, n, svn, N, deg, frac, dom, D, rtol)


def analyze(F: ArrayLike, H: ArrayLike, scale: ArrayLike | None = None, rtol: float = DEFAULT_RTOL) -> ObservabilityResult:
    """Rank, unobservable subspace and per-state degree of a time-invariant (F, H).

    Parameters
    ----------
    F : array (n, n)
        System matrix (SI units, e.g. from :mod:`sinslab.nav.errstate`).
    H : array (p, n)
        Measurement matrix.
    scale : array (n,), optional
        State magnitudes (e.g. ``sqrt(diag(P0))``); default automatic column equilibration.
    rtol : float
        Relative singular-value tolerance for the rank (default 1e-9).
    """
    F, H = _check(F, H)
    n = F.shape[0]
    fn = lambda D: _normalised_O(F, H, D)
    D = _auto_scale(fn, n, _balance(F, H)) if scale is None else _check_scale(scale, n)
    return _result_from(fn(D), D, rtol)


def _check_scale(scale: ArrayLike, n: int) -> np.ndarray:
    D = np.broadcast_to(np.asarray(scale, dtype=float), (n,)).copy()
    if not (np.all(np.isfinite(D)) and np.all(D > 0)):
        raise ValueError("scale must be finite and > 0 for every state")
    return D


def rank(F: ArrayLike, H: ArrayLike, scale: ArrayLike | None = None, rtol: float = DEFAULT_RTOL) -> int:
    """Numerical rank of the observability matrix of (F, H) (see :func:`analyze`)."""
    return analyze(F, H, scale, rtol).rank


def unobservable_subspace(F: ArrayLike, H: ArrayLike, scale: ArrayLike | None = None,
                          rtol: float = DEFAULT_RTOL) -> np.ndarray:
    """Basis (n, n − rank) of the unobservable subspace of (F, H), SI coordinates (see
    :attr:`ObservabilityResult.null_space`)."""
    return analyze(F, H, scale, rtol).null_space


@dataclass(frozen=True)
class PiecewiseResult:
    """Result of :func:`piecewise`.

    Attributes
    ----------
    ranks : list of int
        Rank of the stacked matrix after segments 1, 2, …, m.
    result : ObservabilityResult
        Full analysis (degree, null space) of all m segments.
    method : str
        ``"som"`` or ``"tom"``.
    """

    ranks: list
    result: ObservabilityResult
    method: str


def piecewise(segments: Sequence, method: str = "som", scale: ArrayLike | None = None,
              rtol: float = DEFAULT_RTOL) -> PiecewiseResult:
    """Observability of a piecewise-constant system, rank after each segment.

    Parameters
    ----------
    segments : sequence of (F_j, H_j) or (F_j, H_j, T_j)
        Segment matrices; ``T_j`` [s] (duration) is needed by ``method="tom"``.
    method : {"som", "tom"}
        ``"som"``: stripped observability matrix ``[O_1; …; O_m]`` (paper 001 eq 15);
        ``"tom"``: total observability matrix ``[O_1; O_2 Φ_1; O_3 Φ_2 Φ_1; …]``
        (Goshen-Meskin & Bar-Itzhack), exact for any segments.
    scale, rtol :
        As in :func:`analyze`; the automatic scale is computed once over all segments.
    """
    if method not in ("som", "tom"):
        raise ValueError(f"unknown method {method!r} (som|tom)")
    segs = []
    for s in segments:
        F, H = _check(s[0], s[1])
        T = float(s[2]) if len(s) > 2 else None
        if method == "tom" and T is None:
            raise ValueError("method='tom' needs segment durations (F, H, T)")
        segs.append((F, H, T))
    if not segs:
        raise ValueError("no segments")
    n = segs[0][0].shape[0]
    if any(F.shape[0] != n for F, _, _ in segs):
        raise ValueError("all segments must have the same number of states")

    def blocks(D, upto):
        out = []
        Pacc = np.eye(n)                           # Φ_{j−1}…Φ_1 of the scaled system
        for j, (F, H, T) in enumerate(segs[:upto]):
            O = _rownorm(_normalised_O(F, H, D))
            out.append(O @ Pacc if method == "tom" else O)
            if method == "tom":
                Fp = F * D[None, :] / D[:, None]
                Pacc = scipy.linalg.expm(Fp * T) @ Pacc
        return np.vstack(out)

    if scale is None:
        D0 = np.exp(np.mean([np.log(_balance(F, H)) for F, H, _ in segs], axis=0))
        D = _auto_scale(lambda D: blocks(D, len(segs)), n, D0)
    else:
        D = _check_scale(scale, n)
    ranks = [_result_from(blocks(D, j), D, rtol).rank for j in range(1, len(segs) + 1)]
    return PiecewiseResult(ranks, _result_from(blocks(D, len(segs)), D, rtol), method)


def covariance_degree(P0: ArrayLike, P: ArrayLike) -> np.ndarray:
    """Covariance-based degree of observability ``sqrt(P0_jj / P_jj)`` per state.

    Parameters
    ----------
    P0 : array (n, n) or (n,)
        Initial covariance, or its diagonal.
    P : array (..., n, n) or (..., n)
        Covariance history, e.g. (M, n, n) over M epochs — matrices when P0 is a matrix,
        diagonals (..., n) when P0 is a diagonal.

    Returns
    -------
    ndarray (..., n)
        1 = no information gained; large = well estimated (σ reduced by that factor).
    """
    P0 = np.asarray(P0, dtype=float)
    P = np.asarray(P, dtype=float)
    d0 = np.diagonal(P0) if P0.ndim == 2 else P0
    n = d0.size
    if P0.ndim == 2:
        if P.shape[-2:] != (n, n):
            raise ValueError(f"P must have shape (..., {n}, {n}), got {P.shape}")
        d = np.diagonal(P, axis1=-2, axis2=-1)
    else:
        if P.shape[-1:] != (n,):
            raise ValueError(f"P must have shape (..., {n}) (diagonals), got {P.shape}")
        d = P
    if np.any(d0 <= 0) or np.any(d <= 0):
        raise ValueError("covariance diagonals must be > 0")
    return np.sqrt(d0 / d)


def covariance_eigen_degree(P0: ArrayLike, P: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Ham & Brown's eigen-analysis of the normalised covariance ``P' = D⁻¹ P D⁻¹``, D = sqrt(diag P0).

    Returns eigenvalues (ascending; small = well-observable direction) and eigenvectors
    (columns, in the normalised coordinates) of P'.
    """
    P0 = np.asarray(P0, dtype=float)
    d0 = np.sqrt(np.diagonal(P0) if P0.ndim == 2 else P0)
    Pn = np.asarray(P, dtype=float) / d0[:, None] / d0[None, :]
    w, V = np.linalg.eigh(0.5 * (Pn + np.swapaxes(Pn, -1, -2)))
    return w, V
