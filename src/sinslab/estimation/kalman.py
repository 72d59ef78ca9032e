"""Kalman filter core on plain arrays: the equations every filter in sinslab uses.

:func:`predict`, :func:`update` (Joseph form, optional sequential scalar updates,
measurement masks), :func:`check_covariance`, :func:`discretize` (the one discretisation
of ``ẋ = F x + G w``, exact by Van Loan's method or by the second-order series, one epoch
or many), :func:`van_loan` and :func:`steady_state`.

The compiled time loops of linear systems (covariance analysis, error budgets) are in
:mod:`sinslab.estimation.linear`; the stepped filter that runs beside an INS (feedback,
lagged measurements) is :class:`sinslab.estimation.filter.KalmanFilter`.

Conventions
-----------
``n`` states, ``m`` measurement components. Units are whatever the model uses (SI in
sinslab: rad, m/s, m or rad for positions). This module knows nothing about navigation.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from sinslab.core.errors import InputError

__all__ = [
    "check_covariance", "predict", "update", "UpdateResult", "discretize", "van_loan",
    "steady_state", "SteadyState",
]


# ----------------------------------------------------------------------------------------
# validation
# ----------------------------------------------------------------------------------------
def _as_square(M: ArrayLike, n: int, name: str) -> np.ndarray:
    M = np.asarray(M, dtype=float)
    if M.ndim != 2 or M.shape != (n, n):
        raise ValueError(f"{name} must have shape ({n}, {n}), got {M.shape}")
    return M


def check_covariance(M: ArrayLike, name: str = "P", *, definite: bool = False, rtol: float = 1e-9) -> np.ndarray:
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
    # a diagonal matrix (a typical R or Q) has its diagonal as eigenvalues: no LAPACK call
    w = np.sort(Ms.diagonal()) if _is_diag(Ms) else np.linalg.eigvalsh(Ms)
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
def predict(x: ArrayLike, P: ArrayLike, Phi: ArrayLike, Qk: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
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


def _check_update_args(x: ArrayLike, P: ArrayLike, z: ArrayLike, H: ArrayLike, R: ArrayLike,
                       mask: ArrayLike | None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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
        use = np.isfinite(z)
    else:
        use = np.asarray(mask, dtype=bool)
        if use.shape != (m,):
            raise ValueError(f"mask must have shape ({m},), got {use.shape}")
        if np.any(~np.isfinite(z[use])):
            raise ValueError("z has NaN/inf in a component the mask marks as available")
    if not np.all(np.isfinite(H)):
        raise ValueError("H has NaN/inf elements")
    return x, P, z, H, R, use


def update(x: ArrayLike, P: ArrayLike, z: ArrayLike, H: ArrayLike, R: ArrayLike, *,
           mask: ArrayLike | None = None, sequential: bool | None = None) -> UpdateResult:
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
    xv, Pv, z, H, R, mask = _check_update_args(x, P, z, H, R, mask)
    m = z.size
    idx = np.flatnonzero(mask)
    innov = np.full(m, np.nan)
    S_full = np.full((m, m), np.nan)
    if idx.size == 0:
        return UpdateResult(xv.copy(), Pv.copy(), innov, S_full, 0.0, mask)
    Ru = check_covariance(R[np.ix_(idx, idx)], "R (used components)", definite=True)
    Hu, zu = H[idx], z[idx]
    S = Hu @ Pv @ Hu.T + Ru
    nu = zu - Hu @ xv
    innov[idx] = nu
    S_full[np.ix_(idx, idx)] = S
    diag = _is_diag(Ru)
    if sequential is None:
        sequential = diag
    if sequential and not diag:
        raise ValueError("sequential updates need a diagonal R (the used components are correlated)")
    if sequential:
        xv = xv.copy()
        Pv = Pv.copy()
        nis = 0.0
        for i in range(idx.size):
            h, r = Hu[i], Ru[i, i]
            pht = Pv @ h
            s = float(h @ pht + r)
            if not s > 0:
                # Non-finite or negative: the covariance has lost its meaning, which in
                # practice comes from initial errors or noise levels far outside what
                # the linearised model can carry.
                raise InputError(f"innovation variance of component {idx[i]} is {s:.3g} "
                                 "(not > 0): the filter covariance diverged; check the "
                                 "initial errors and noise levels")
            nu_i = zu[i] - h @ xv
            k = pht / s
            xv = xv + k * nu_i
            A = np.eye(xv.size) - np.outer(k, h)
            Pv = A @ Pv @ A.T + r * np.outer(k, k)
            Pv = 0.5 * (Pv + Pv.T)
            nis += nu_i * nu_i / s
    else:
        from scipy import linalg as sla   # here: scipy.linalg costs a whole-process run ~0.2 s to import

        try:
            cf = sla.cho_factor(S)
        except np.linalg.LinAlgError as e:
            raise ValueError(f"innovation covariance is not positive definite: {e}") from None
        K = sla.cho_solve(cf, Hu @ Pv).T
        xv = xv + K @ nu
        A = np.eye(xv.size) - K @ Hu
        Pv = A @ Pv @ A.T + K @ Ru @ K.T
        Pv = 0.5 * (Pv + Pv.T)
        nis = float(nu @ sla.cho_solve(cf, nu))
    if not np.all(np.isfinite(Pv)):
        raise ValueError("update produced a non-finite covariance")
    return UpdateResult(xv, Pv, innov, S_full, float(nis), mask)


def van_loan(F: ArrayLike, Qc: ArrayLike, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact ``(Φ, Q_k)`` of ``ẋ = F x + w``, ``E[w wᵀ] = Qc δ(t)``, over T (Van Loan 1978).

    ``Φ = expm(F T)``, ``Q_k = ∫₀ᵀ Φ(s) Qc Φ(s)ᵀ ds`` from one block exponential
    ``expm([[−F, Qc], [0, Fᵀ]] T)``. F ``(..., n, n)``, Qc ``(..., n, n)`` (any symmetric
    density, correlated or not), T [s]; leading dimensions broadcast (many epochs).
    """
    F = np.asarray(F, dtype=float)
    Qc = np.asarray(Qc, dtype=float)
    n = F.shape[-1]
    T = float(T)
    S = np.broadcast_shapes(F.shape[:-2], Qc.shape[:-2])
    M = np.zeros(S + (2 * n, 2 * n))
    M[..., :n, :n] = -F * T
    M[..., :n, n:] = Qc * T
    M[..., n:, n:] = np.swapaxes(F, -1, -2) * T
    from scipy.linalg import expm

    E = expm(M)
    Phi = np.swapaxes(E[..., n:, n:], -1, -2)
    Qk = Phi @ E[..., :n, n:]
    return Phi, 0.5 * (Qk + np.swapaxes(Qk, -1, -2))


def discretize(F: ArrayLike, Qc: ArrayLike, T: float, *, G: ArrayLike | None = None,
               method: str = "vanloan") -> tuple[np.ndarray, np.ndarray]:
    """Discrete transition and process-noise matrices of ``ẋ = F x + G w`` over a step T.

    Parameters
    ----------
    F : array_like, shape (..., n, n)
        Continuous system matrix, held constant over the step; leading dimensions are
        many epochs (each discretised on its own).
    Qc : array_like, shape (..., n, n), (p, p) or (p,)
        Continuous white-noise spectral density. Without ``G`` it is the state density
        (n, n). With ``G``: a matrix (p, p) is the density of ``w`` and the state
        density is ``G Qc Gᵀ``; a vector (p,) holds the densities of independent noises
        (``E[w wᵀ] = diag(Qc) δ``, SI, e.g. rad²/s) and the state density is
        ``G diag(Qc) Gᵀ``.
    T : float
        Step [s], >= 0.
    G : array_like, shape (..., n, p), optional
        Noise input matrix.
    method : {"vanloan", "series"}
        ``"vanloan"``: ``Φ = expm(F T)`` and ``Q_k = ∫₀ᵀ Φ(s) Q̄ Φ(s)ᵀ ds`` exactly
        (:func:`van_loan`). ``"series"``: ``Φ ≈ I + F T + (F T)²/2`` and the trapezoid
        ``Q_k ≈ (Q̄ T + Φ Q̄ Φᵀ T)/2``; both err by O(T³).

    Returns
    -------
    Phi, Qk : ndarray, shape (..., n, n)

    Raises
    ------
    ValueError
        Shapes that do not match, negative densities, a density that is not a
        covariance, a negative step or an unknown method.
    """
    F = np.asarray(F, dtype=float)
    Qc = np.asarray(Qc, dtype=float)
    n = F.shape[-1]
    if G is not None and Qc.ndim == 1:
        # independent noises: Q̄ = G diag(q) Gᵀ, symmetrised (one epoch or many)
        G = np.asarray(G, dtype=float)
        q = Qc
        if F.ndim < 2 or F.shape[-2] != n or G.shape[-2] != n or G.shape[-1] != q.shape[-1]:
            raise ValueError(f"shape mismatch: F {F.shape}, G {G.shape}, q {q.shape}")
        if np.any(q < 0):
            raise ValueError("noise spectral densities must be >= 0")
        Qbar = (G * q[..., None, :]) @ np.swapaxes(G, -1, -2)
        Qbar = 0.5 * (Qbar + np.swapaxes(Qbar, -1, -2))
    elif F.ndim == 2:
        F = _as_square(F, n, "F")
        if G is not None:
            G = np.asarray(G, dtype=float)
            Qc = G @ Qc @ G.T
        Qbar = check_covariance(_as_square(Qc, n, "Qc"), "Qc")
    else:
        Qs = Qc if G is None else np.asarray(G, dtype=float) @ Qc @ np.swapaxes(np.asarray(G, dtype=float), -1, -2)
        if F.shape[-2] != n or Qs.shape[-2:] != (n, n):
            raise ValueError(f"shape mismatch: F {F.shape}, Qc {Qs.shape}")
        Qbar = 0.5 * (Qs + np.swapaxes(Qs, -1, -2))
    if not T >= 0:
        raise ValueError(f"step T must be >= 0, got {T}")
    T = float(T)
    if method == "vanloan":
        return van_loan(F, Qbar, T)
    if method != "series":
        raise ValueError(f"unknown discretisation method {method!r} (vanloan|series)")
    FT = F * T
    Phi = np.eye(n) + FT + 0.5 * FT @ FT
    Qk = 0.5 * T * (Qbar + Phi @ Qbar @ np.swapaxes(Phi, -1, -2))
    return Phi, 0.5 * (Qk + np.swapaxes(Qk, -1, -2))


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


def steady_state(Phi: ArrayLike, Qk: ArrayLike, H: ArrayLike, R: ArrayLike) -> SteadyState:
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
    from scipy import linalg as sla

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
