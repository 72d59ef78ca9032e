"""Integer ambiguity resolution: the LAMBDA search of a maintained library, the ratio
test, partial fixing, and the fixed (conditional) solution.

Given float ambiguities ``â`` (n,) [cycles] with covariance ``Q_â`` from a Kalman filter,
the integer least-squares problem ``min_a (â − a)ᵀ Q_â⁻¹ (â − a)`` over integers is solved
by the LAMBDA method (Teunissen 1995: decorrelation by integer Gauss transformations,
then a search in the transformed space; de Jonge & Tiberius 1996, Chang et al. 2005
"MLAMBDA"). The search is RTKLIB's ``lambda`` (through its Python binding ``pyrtklib5``,
the library the GNSS readers use), which returns the best and second-best integer
vectors with their squared norms.

The fix is accepted when the second-best norm is at least ``ratio`` times the best (the
ratio test, RTKLIB's default threshold 3) and the float is precise enough for integers to
be found at all: the success rate of integer bootstrapping in LAMBDA's decorrelated space
(Teunissen 1998, a sharp lower bound of the integer least-squares success rate),
``P_s = Π (2Φ(1/(2√d_i)) − 1)`` with ``d_i`` the conditional variances, is at least
``success`` (:func:`success_rate`). The ratio alone passes wrong integers of a weak float
(a single epoch of code after an outage); the success rate refuses them. When the full
set fails, *partial fixing*
drops ambiguities one at a time in a caller-given order (the least reliable first, e.g.
lowest elevation or shortest lock) and searches the rest again, while at least
``min_fixed`` remain. With the fixed integers ``ǎ`` of a subset ``D â`` (rows of ``D``
pick or difference the filter's ambiguity states), the fixed solution of every state is
the conditional estimate ``x̌ = x̂ − P Dᵀ (D P Dᵀ)⁻¹ (D x̂ − ǎ)`` with covariance
``P − P Dᵀ (D P Dᵀ)⁻¹ D P`` (:func:`condition`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sinslab.core.errors import InputError

__all__ = ["lambda_search", "resolve", "IntegerFix", "condition", "success_rate"]


def _lib():
    try:
        import pyrtklib5 as rtk
    except ImportError as e:          # declared in pyproject; a broken install says so
        raise InputError(f"integer ambiguity resolution needs the RTKLIB binding pyrtklib5 ({e})") from None
    return rtk


def lambda_search(a, Q, candidates=2):
    """The ``candidates`` best integer vectors of ``min (â − a)ᵀ Q⁻¹ (â − a)`` (LAMBDA,
    RTKLIB's ``lambda``).

    Parameters
    ----------
    a : array_like (n,)
        Float ambiguities [cycles].
    Q : array_like (n, n)
        Their covariance [cycles²], positive definite.
    candidates : int
        How many integer vectors to return (2 for the ratio test).

    Returns
    -------
    F : ndarray (candidates, n)
        Integer vectors (as floats), best first.
    s : ndarray (candidates,)
        Their squared norms ``(â − a)ᵀ Q⁻¹ (â − a)``, ascending.

    Raises
    ------
    ValueError
        ``Q`` not positive definite, or the search failed.
    """
    rtk = _lib()
    a = np.asarray(a, float).ravel()
    Q = np.asarray(Q, float)
    n, m = a.size, int(candidates)
    if Q.shape != (n, n) or n == 0:
        raise ValueError(f"lambda_search: a ({n},) needs Q ({n}, {n}), got {Q.shape}")
    # the search works on the fractional parts; the integer offset is added back, which keeps
    # the library's arithmetic near zero whatever the size of the ambiguities
    base = np.round(a)
    aa, QQ = rtk.Arr1Ddouble(n), rtk.Arr1Ddouble(n * n)
    for i, v in enumerate((a - base).tolist()):
        aa[i] = v
    for i, v in enumerate(Q.ravel(order="F").tolist()):
        QQ[i] = v
    F, s = rtk.Arr1Ddouble(n * m), rtk.Arr1Ddouble(m)
    info = getattr(rtk, "lambda")(n, m, aa, QQ, F, s)
    if info != 0:
        raise ValueError(f"LAMBDA failed (RTKLIB lambda returned {info}): the float ambiguity covariance "
                         "is not positive definite")
    # the back-transformed candidates are integers to rounding
    cand = np.round(np.array([F[i] for i in range(n * m)]).reshape(m, n)) + base
    return cand, np.array([s[i] for i in range(m)])


def success_rate(Q):
    """Success rate of integer bootstrapping of float ambiguities with covariance ``Q``
    (n, n) [cycles²], after LAMBDA's decorrelation (RTKLIB's ``lambda_reduction``):
    ``Π (2Φ(1/(2√d_i)) − 1)`` over the conditional variances ``d_i`` in the order the
    search conditions them (the last transformed ambiguity first)."""
    Q = np.asarray(Q, float)
    return max(_bootstrap(Q), _bootstrap_decorrelated(Q))


def _bootstrap(Q):
    """Bootstrapped success rate of ``Q`` as it stands (the last component conditioned
    first): a lower bound, the decorrelated one is sharper."""
    try:
        L = np.linalg.cholesky(Q[::-1, ::-1])
    except np.linalg.LinAlgError:
        return 0.0
    d = np.diag(L) ** 2
    return float(np.prod([math.erf(1.0 / (2.0 * math.sqrt(2.0 * v))) for v in d]))


def _bootstrap_decorrelated(Q):
    rtk = _lib()
    n = Q.shape[0]
    QQ, Z = rtk.Arr1Ddouble(n * n), rtk.Arr1Ddouble(n * n)
    for i, v in enumerate(Q.ravel(order="F").tolist()):
        QQ[i] = v
    if rtk.lambda_reduction(n, QQ, Z) != 0:
        return 0.0
    Zm = np.array([Z[i] for i in range(n * n)]).reshape(n, n, order="F")
    return _bootstrap(Zm.T @ Q @ Zm)


def _success_at_least(Q, p):
    """``success_rate(Q) >= p``, the decorrelation skipped when the plain bound passes."""
    return _bootstrap(Q) >= p or _bootstrap_decorrelated(Q) >= p


@dataclass(frozen=True)
class IntegerFix:
    """Outcome of :func:`resolve`.

    Attributes
    ----------
    used : bool ndarray (n,)
        The ambiguities fixed (all False when not fixed).
    integers : ndarray (n,)
        The fixed integers where ``used`` (NaN elsewhere).
    ratio : float
        Second-best over best squared norm of the accepted subset, or of the last subset
        tried when none passed (inf when the best norm is 0).
    fixed : bool
        A subset of at least ``min_fixed`` ambiguities passed the ratio test.
    tried : int
        Subsets searched.
    """

    used: np.ndarray
    integers: np.ndarray
    ratio: float
    fixed: bool
    tried: int

    @property
    def n_fixed(self):
        return int(self.used.sum())


def _ratio(s):
    return float(s[1] / s[0]) if s[0] > 0 else float("inf")


def resolve(a, Q, *, ratio=3.0, min_fixed=4, drop_order=None, max_tries=None, success=0.0) -> IntegerFix:
    """Fix the float ambiguities ``a`` (n,) [cycles] with covariance ``Q`` by LAMBDA and the
    ratio test, partially when the full set fails.

    Parameters
    ----------
    a, Q : array_like
        Float ambiguities (n,) and covariance (n, n) [cycles, cycles²].
    ratio : float
        Threshold of the ratio test (second-best over best squared norm).
    min_fixed : int
        Fewest ambiguities a fix may hold.
    drop_order : sequence of int or of index lists, optional
        The ambiguities in the order they are given up when a set fails (least reliable
        first), one index or a list of indices given up together (the carriers of one
        satellite); default: one at a time, largest float variance first.
    max_tries : int, optional
        Most subsets searched (default: until ``min_fixed`` remain).
    success : float
        Least bootstrapped success rate of a subset fixed (:func:`success_rate`; 0: the
        ratio test alone).

    Returns
    -------
    IntegerFix
    """
    a = np.asarray(a, float).ravel()
    Q = np.asarray(Q, float)
    n = a.size
    none = IntegerFix(np.zeros(n, bool), np.full(n, np.nan), float("nan"), False, 0)
    if n < max(int(min_fixed), 1):
        return none
    order = [[int(i)] for i in np.argsort(-np.diag(Q), kind="stable")] if drop_order is None else \
        [[int(i)] if np.ndim(i) == 0 else [int(j) for j in i] for i in drop_order]
    keep = np.ones(n, bool)
    tries, last = 0, float("nan")
    limit = n if max_tries is None else int(max_tries)
    k = 0
    while keep.sum() >= max(int(min_fixed), 1) and tries < limit:
        idx = np.flatnonzero(keep)
        try:
            F, s = lambda_search(a[idx], Q[np.ix_(idx, idx)])
        except ValueError:
            return IntegerFix(none.used, none.integers, last, False, tries)
        tries += 1
        last = _ratio(s)
        if last >= ratio and (success <= 0.0 or _success_at_least(Q[np.ix_(idx, idx)], success)):
            ints = np.full(n, np.nan)
            ints[idx] = F[0]
            return IntegerFix(keep.copy(), ints, last, True, tries)
        while k < len(order) and not keep[order[k]].any():
            k += 1
        if k >= len(order):
            break
        keep[order[k]] = False
    return IntegerFix(none.used, none.integers, last, False, tries)


def condition(x, P, D, d, R=None):
    """The estimate of every state given ``D x = d`` (exactly, or with noise covariance
    ``R``): ``x − K (D x − d)``, ``P − K D P`` with ``K = P Dᵀ (D P Dᵀ + R)⁻¹``.

    With the fixed integers as ``d`` (and the rows of ``D`` on the ambiguity states) this is
    the fixed solution and its covariance, given that the integers are right.

    Parameters
    ----------
    x : (n,), P : (n, n)
    D : (k, n)
    d : (k,)
    R : (k, k), optional

    Returns
    -------
    x_fixed : ndarray (n,)
    P_fixed : ndarray (n, n)
    """
    x = np.asarray(x, float)
    P = np.asarray(P, float)
    D = np.atleast_2d(np.asarray(D, float))
    S = D @ P @ D.T
    if R is not None:
        S = S + np.asarray(R, float)
    PD = P @ D.T
    K = np.linalg.solve(S, PD.T).T
    xf = x - K @ (D @ x - np.asarray(d, float))
    Pf = P - K @ PD.T
    return xf, 0.5 * (Pf + Pf.T)
