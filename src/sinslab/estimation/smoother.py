"""Rauch–Tung–Striebel fixed-interval smoother over a stored forward Kalman pass.

The backward pass knows nothing of an INS: it takes, for the filter epochs
``k = 0..K``, what a forward filter stored and returns the smoothed estimates
``x_{k|K}`` and covariances ``P_{k|K}`` (every measurement of the record used).

Forward pass (stored)
---------------------
Step ``k`` predicts from epoch ``k`` to ``k+1`` with the transition ``Phi_k``::

    x_{k|k}     updated state at epoch k (after its measurements, if any;
                *before* any feedback applied at k)                      (1)
    d_k         correction fed back at epoch k (zero in open loop): the
                state is ``x_{k|k} - d_k`` after the feedback              (2)
    x_{k+1|k} = Phi_k (x_{k|k} - d_k)                                     (3)
    P_{k+1|k} = Phi_k P_{k|k} Phi_k^T + Q_k                               (4)

Feedback does not change the covariance: ``d_k`` is a deterministic function of the
data already used, so ``P_{k|k}`` is the covariance of the error of ``x_{k|k}`` and
also of ``x_{k|k} - d_k`` as an estimate of the fed-back error.

Backward pass (RTS, open loop)
------------------------------
Rauch, Tung & Striebel (1965), "Maximum likelihood estimates of linear dynamic
systems", AIAA J. 3(8); in the notation of Gelb (1974), *Applied Optimal Estimation*,
sec. 5.3::

    A_k     = P_{k|k} Phi_k^T P_{k+1|k}^{-1}                              (5)
    x_{k|K} = x_{k|k} + A_k (x_{k+1|K} - x_{k+1|k})                       (6)
    P_{k|K} = P_{k|k} + A_k (P_{k+1|K} - P_{k+1|k}) A_k^T                 (7)

started from ``x_{K|K}``, ``P_{K|K}`` of the forward pass.

Closed-loop (feedback) form
---------------------------
With feedback the stored states do not describe one fixed quantity: after the
correction ``d_k`` the navigation solution — and so the error the filter estimates —
has changed by ``d_k``. Let ``C_k`` be the correction accumulated up to epoch ``k``
(before the feedback at ``k``), carried by the error dynamics::

    C_0 = 0,   C_{k+1} = Phi_k (C_k + d_k)                                (8)

In the *accumulated-correction coordinates* ``y = x + C`` the filter is the open-loop
(feed-forward) filter of the uncorrected errors: ``y_{k|k} = x_{k|k} + C_k`` is the
same before and after the feedback (``x`` loses ``d_k``, ``C`` gains it) and
``y_{k+1|k} = Phi_k y_{k|k} = x_{k+1|k} + C_{k+1}`` by (3) and (8); the covariances
are those of ``x``. Equations (5)–(7) hold for ``y``. Subtracting ``C_k`` from (6)
written in ``y``, and using ``y_{k+1|K} - y_{k+1|k} = x_{k+1|K} - x_{k+1|k}`` (both
carry the same ``C_{k+1}``)::

    x_{k|K} = x_{k|k} + A_k (x_{k+1|K} - x_{k+1|k})                       (9)

with ``x_{k|K} = y_{k|K} - C_k`` the smoothed error of the solution *as it was
before the feedback at k*; the error of the solution after that feedback is::

    x^+_{k|K} = x_{k|K} - d_k                                             (10)

So (9) is (6) applied to the stored values, provided ``x_{k|k}`` is the
*pre-feedback* state and ``x_{k+1|k}`` the prediction from the *post-feedback* state
(3). ``C`` itself is never formed: it is not needed, and propagating it through (8)
over an hour would carry large, growing numbers (position corrections) whose
difference is the small quantity wanted. Mixing the two coordinates — e.g. running
(6) with the zeroed post-feedback states as ``x_{k|k}`` and ``x^+_{k+1|K}`` as the
smoothed successor — drops ``d_{k+1}`` from every step and is wrong.

Numerics
--------
* The gain (5) is solved, never inverted: ``P_{k+1|k} A_k^T = Phi_k P_{k|k}`` with a
  Cholesky factor of the *equilibrated* prediction ``S^-1 P_{k+1|k} S^-1``
  (``S = diag(sqrt(P_{k+1|k,ii}))``, a correlation matrix), so states in rad, m and
  rad/s do not spoil the factorisation.
* Singular predictions (a state with zero variance and zero process noise, a
  combination measured with R -> 0, random constants with Q = 0 once P is singular)
  are guarded: states with zero predicted variance, and Cholesky pivots of the
  correlation matrix at or below ``null_tol`` (default 1e-12: the state's predicted
  variance not explained by the states before it is < 1e-12 of its variance), are
  dropped from the solve and get zero gain columns. This is the gain with a
  generalised inverse of ``P_{k+1|k}``; since the columns of ``Phi_k P_{k|k}`` and the
  differences in (6), (7) lie in the range of ``P_{k+1|k}``, it gives the same
  smoothed estimate and covariance as the Moore–Penrose form.
* (7) is symmetrised at every step.
* The loop is one compiled kernel (scalar Cholesky and triangular solves, BLAS
  products); the record is processed backwards in chunks, so the inputs may be
  ``numpy.memmap`` arrays on disk and only a chunk is held in memory (the pages of a
  chunk are let go once it is processed, :func:`release_pages`).

Storage: per epoch ``2 n^2 + n^2 + 3 n`` float64 (two covariances, Phi, three vectors).
For n = 21 states at 10 Hz for 1 h (36 001 epochs) that is 36 001 x 1 386 x 8 B =
399 MB in float64. Inputs are converted to float64 chunk by chunk, so they may be
stored in float32: on a 21-state INS error model over 1 h that changed the smoothed
estimate by at most 2e-3 σ and σ by at most 6e-3 relative. float64 is the default;
``numpy.memmap`` inputs bound the memory instead.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from numba import njit

from sinslab.core.blocks import release_pages

__all__ = ["rts_smooth", "Smoothed", "storage_bytes"]


@dataclass(frozen=True)
class Smoothed:
    """Result of :func:`rts_smooth`.

    Attributes
    ----------
    x : ndarray, shape (K+1, n)
        Smoothed ``x_{k|K}`` in the coordinates of the given ``x_post`` (before any
        feedback at epoch k), eq. (9).
    x_corrected : ndarray, shape (K+1, n)
        Smoothed error of the solution after the feedback at epoch k, ``x - d_k``
        (eq. 10); equal to ``x`` without feedback.
    sigma : ndarray, shape (K+1, n)
        Smoothed standard deviations sqrt(diag P_{k|K}).
    P : ndarray, shape (K+1, n, n), or None
        Smoothed covariances (``covariance="full"``), else None.
    dropped : ndarray of int, shape (K,)
        Number of directions of ``P_{k+1|k}`` treated as singular at step k.
    """

    x: np.ndarray
    x_corrected: np.ndarray
    sigma: np.ndarray
    P: np.ndarray | None
    dropped: np.ndarray


def storage_bytes(n_states, n_epochs, itemsize=8):
    """Bytes of forward history the backward pass reads: per epoch two (n, n)
    covariances, Phi (n, n) and the vectors x_post, x_prior, d (n each)."""
    return int(n_epochs) * (3 * n_states * n_states + 3 * n_states) * int(itemsize)


@njit(cache=True)
def _rts_chunk(xpost, Ppost, xprior, Pprior, Phi, xs1, Ps1, xs_out, P_out, sig_out, full,
               null_tol, dropped, M, W, At, T1, T2, act, s, keep, v):
    """Steps i = m-1 .. 0 of eqs. (5)-(7) for one chunk.

    ``xs1``, ``Ps1`` hold the smoothed state/covariance of the epoch after the chunk
    and are overwritten with those of its first epoch. Row i of the outputs is the
    epoch of ``xpost[i]``."""
    m = xpost.shape[0]
    n = xpost.shape[1]
    for i in range(m - 1, -1, -1):
        Pp = Pprior[i]
        # equilibrate: active states have positive predicted variance
        r = 0
        for j in range(n):
            d = Pp[j, j]
            if d > 0.0:
                act[r] = j
                s[r] = math.sqrt(d)
                r += 1
        for a in range(r):
            ja = act[a]
            for b in range(a + 1):
                M[a, b] = Pp[ja, act[b]] / (s[a] * s[b])
        # Cholesky M = L L^T in the lower triangle of M, skipping null pivots
        nd = n - r
        for j in range(r):
            d = M[j, j]
            for k in range(j):
                d -= M[j, k] * M[j, k]
            if d <= null_tol:
                keep[j] = False
                nd += 1
                for a in range(j, r):
                    M[a, j] = 0.0
                continue
            keep[j] = True
            ljj = math.sqrt(d)
            M[j, j] = ljj
            for a in range(j + 1, r):
                t = M[a, j]
                for k in range(j):
                    t -= M[a, k] * M[j, k]
                M[a, j] = t / ljj
        dropped[i] = nd
        # A^T solves P_{k+1|k} A^T = Phi P_{k|k} =: B. With P_{k+1|k} = S M S and
        # M = L L^T over the kept pivots: A^T = S^-1 L^-T L^-1 S^-1 B, done as row
        # operations on B (inner loops run along contiguous rows)
        np.dot(Phi[i], Ppost[i], T1)
        for j in range(n):
            for c in range(n):
                At[j, c] = 0.0
        for a in range(r):
            if not keep[a]:
                continue
            ja = act[a]
            inv_s = 1.0 / s[a]
            for c in range(n):
                W[a, c] = T1[ja, c] * inv_s
            for k in range(a):
                lk = M[a, k]
                if lk != 0.0:
                    for c in range(n):
                        W[a, c] -= lk * W[k, c]
            inv_l = 1.0 / M[a, a]
            for c in range(n):
                W[a, c] *= inv_l
        for a in range(r - 1, -1, -1):
            if not keep[a]:
                continue
            for k in range(a + 1, r):
                lk = M[k, a]
                if lk != 0.0 and keep[k]:
                    for c in range(n):
                        W[a, c] -= lk * W[k, c]
            inv_l = 1.0 / M[a, a]
            for c in range(n):
                W[a, c] *= inv_l
        for a in range(r):
            if keep[a]:
                ja = act[a]
                inv_s = 1.0 / s[a]
                for c in range(n):
                    At[ja, c] = W[a, c] * inv_s
        # (9): x_s = x_post + A (x_s1 - x_prior)
        for j in range(n):
            v[j] = xs1[j] - xprior[i, j]
        for c in range(n):
            xs_out[i, c] = xpost[i, c]
        for j in range(n):
            vj = v[j]
            for c in range(n):
                xs_out[i, c] += At[j, c] * vj
        for c in range(n):
            xs1[c] = xs_out[i, c]
        # (7): P_s = P_post + A (P_s1 - P_prior) A^T
        for a in range(n):
            for b in range(n):
                T2[a, b] = Ps1[a, b] - Pp[a, b]
        np.dot(At.T, T2, T1)
        np.dot(T1, At, T2)
        Pq = Ppost[i]
        for a in range(n):
            for b in range(a, n):
                t = Pq[a, b] + 0.5 * (T2[a, b] + T2[b, a])
                Ps1[a, b] = t
                Ps1[b, a] = t
        for a in range(n):
            sig_out[i, a] = math.sqrt(max(Ps1[a, a], 0.0))
        if full:
            for a in range(n):
                for b in range(n):
                    P_out[i, a, b] = Ps1[a, b]


def _shape_error(name, got, want):
    raise ValueError(f"{name} must have shape {want}, got {got}")


def rts_smooth(x_post, P_post, x_prior, P_prior, Phi, *, feedback=None, covariance="full",
               null_tol=1e-12, check=True, chunk=4096):
    """Smooth a stored forward Kalman pass (Rauch–Tung–Striebel), open or closed loop.

    Parameters
    ----------
    x_post : array_like, shape (K+1, n)
        Updated states ``x_{k|k}`` at the filter epochs, *before* any feedback at the
        epoch (eq. 1 of the module notes). Units those of the error-state model.
    P_post : array_like, shape (K+1, n, n)
        Their covariances ``P_{k|k}``.
    x_prior : array_like, shape (K, n), or None
        Row k is the prediction ``x_{k+1|k} = Phi_k (x_{k|k} - d_k)`` (eq. 3); None
        computes it from ``x_post``, ``feedback`` and ``Phi``.
    P_prior : array_like, shape (K, n, n)
        Row k is ``P_{k+1|k}`` (eq. 4).
    Phi : array_like, shape (K, n, n)
        Row k is the transition from epoch k to k+1.
    feedback : array_like, shape (K+1, n), optional
        Corrections ``d_k`` fed back at epoch k (the amount removed from the state;
        zero where nothing was fed back). None: open loop.
    covariance : {"full", "diag"}
        Return the smoothed covariances, or only their σ (saves K n^2 floats).
    null_tol : float
        Pivot threshold of the equilibrated Cholesky factor below which a direction of
        ``P_{k+1|k}`` is treated as singular (see the module notes).
    check : bool
        Check finiteness, shapes and that ``x_prior`` is eq. (3) of the given
        ``x_post``/``feedback`` (catches a history stored after instead of before
        feedback, or corrections left out): a mismatch larger than 1e-6 of the
        predicted σ (plus 1e-9 relative) raises.
    chunk : int
        Epochs per backward chunk; inputs may be ``numpy.memmap`` arrays, of which only
        a chunk is copied into memory at a time.

    Returns
    -------
    Smoothed

    Raises
    ------
    ValueError
        Shape mismatch, NaN/inf, an unknown ``covariance`` option, or (``check``) a
        prediction that does not follow from the stored state and feedback.
    """
    x_post = np.asarray(x_post) if not isinstance(x_post, np.memmap) else x_post
    if x_post.ndim != 2:
        raise ValueError(f"x_post must have shape (K+1, n), got {x_post.shape}")
    K1, n = x_post.shape
    K = K1 - 1
    if K < 0:
        raise ValueError("x_post is empty: nothing to smooth")
    if covariance not in ("full", "diag"):
        raise ValueError(f"covariance must be 'full' or 'diag', got {covariance!r}")
    if not (chunk >= 1):
        raise ValueError(f"chunk must be >= 1, got {chunk}")
    if np.shape(P_post) != (K1, n, n):
        _shape_error("P_post", np.shape(P_post), (K1, n, n))
    if np.shape(P_prior) != (K, n, n):
        _shape_error("P_prior", np.shape(P_prior), (K, n, n))
    if np.shape(Phi) != (K, n, n):
        _shape_error("Phi", np.shape(Phi), (K, n, n))
    if feedback is not None and np.shape(feedback) != (K1, n):
        _shape_error("feedback", np.shape(feedback), (K1, n))
    if x_prior is not None and np.shape(x_prior) != (K, n):
        _shape_error("x_prior", np.shape(x_prior), (K, n))

    full = covariance == "full"
    xs = np.empty((K1, n))
    sig = np.empty((K1, n))
    Ps = np.empty((K1, n, n)) if full else np.empty((1, n, n))
    dropped = np.zeros(max(K, 0), dtype=np.int64)

    xs1 = np.array(x_post[K], dtype=float)
    Ps1 = np.array(P_post[K], dtype=float)
    if check:
        _check_finite("x_post", xs1, K)
        _check_finite("P_post", Ps1, K)
    Ps1 = 0.5 * (Ps1 + Ps1.T)
    xs[K] = xs1
    sig[K] = np.sqrt(np.maximum(np.diag(Ps1), 0.0))
    if full:
        Ps[K] = Ps1

    M = np.zeros((n, n))
    At = np.empty((n, n))     # A^T
    W = np.empty((n, n))
    T1 = np.empty((n, n))
    T2 = np.empty((n, n))
    act = np.empty(n, dtype=np.int64)
    s = np.empty(n)
    keep = np.empty(n, dtype=np.bool_)
    v = np.empty(n)
    P_dummy = np.empty((1, n, n))
    b = K
    while b > 0:
        a = max(0, b - int(chunk))
        xq = np.ascontiguousarray(x_post[a:b], dtype=float)
        Pq = np.ascontiguousarray(P_post[a:b], dtype=float)
        Pp = np.ascontiguousarray(P_prior[a:b], dtype=float)
        Fq = np.ascontiguousarray(Phi[a:b], dtype=float)
        dq = None if feedback is None else np.ascontiguousarray(feedback[a:b], dtype=float)
        if x_prior is None:
            xp = np.einsum("kij,kj->ki", Fq, xq if dq is None else xq - dq)
        else:
            xp = np.ascontiguousarray(x_prior[a:b], dtype=float)
        if check:
            for name, arr in (("x_post", xq), ("P_post", Pq), ("P_prior", Pp), ("Phi", Fq),
                              ("x_prior", xp)) + ((("feedback", dq),) if dq is not None else ()):
                _check_finite(name, arr, a)
            if x_prior is not None:
                _check_prediction(xq, dq, xp, Pp, Fq, a)
        _rts_chunk(xq, Pq, xp, Pp, Fq, xs1, Ps1, xs[a:b], Ps[a:b] if full else P_dummy,
                   sig[a:b], full, float(null_tol), dropped[a:b], M, W, At, T1, T2, act, s, keep, v)
        release_pages(x_post, P_post, x_prior, P_prior, Phi, feedback)
        b = a
    xc = xs if feedback is None else xs - np.asarray(feedback, dtype=float)
    return Smoothed(xs, xc, sig, Ps if full else None, dropped)


def _check_finite(name, arr, offset):
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        k = int(bad[0]) + offset if arr.ndim > 1 else offset
        raise ValueError(f"{name} has a NaN/inf element at epoch {k}")


def _check_prediction(xq, dq, xp, Pp, Fq, offset):
    base = xq if dq is None else xq - dq
    pred = np.einsum("kij,kj->ki", Fq, base)
    scale = np.einsum("kij,kj->ki", np.abs(Fq), np.abs(base))
    sd = np.sqrt(np.maximum(np.einsum("kii->ki", Pp), 0.0))
    bad = np.abs(xp - pred) > 1e-6 * sd + 1e-9 * scale + 1e-300
    if np.any(bad):
        k, j = np.argwhere(bad)[0]
        raise ValueError(
            f"x_prior[{k + offset}] is not Phi[{k + offset}] @ (x_post - feedback)[{k + offset}] "
            f"(state {j}: {xp[k, j]:.6g} vs {pred[k, j]:.6g}); store x_post before the "
            f"feedback of each epoch and pass the fed-back corrections as feedback=")
