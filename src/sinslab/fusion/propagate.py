"""Filter prediction with the error model evaluated inside one compiled loop.

Per epoch: ``F``, ``G`` from the navigation rows (``fill_varying`` of :mod:`sinslab.nav.errstate_kernels`),
the series ``Φ = I + F T + (F T)²/2`` and ``Q̄ = G diag(q) Gᵀ``
(:func:`sinslab.estimation.kernels.series_phi`, :func:`~sinslab.estimation.kernels.series_qbar`),
then the filter's own prediction step
(:func:`sinslab.estimation.kernels.predict_step_sparse_x`: ``P``, ``x ← Φ x``, ``c ← Φ c``;
x recorded where it is not zero). The series ``Q_k = T (Q̄ + Φ Q̄ Φᵀ)/2`` is never formed:
``P ← Φ P Φᵀ + Q_k = Φ (P + T Q̄/2) Φᵀ + T Q̄/2``
(:func:`~sinslab.estimation.kernels.add_half_qbar`), and ``Φ P Φᵀ`` uses the diagonal rows
of the sensor states (the module notes of :mod:`sinslab.estimation.kernels`). The
matrices live in small work arrays that stay in cache, instead of stretches of
``(S, n, n)`` arrays written and read back. The numbers equal those of the unfused path
(Φ and Q_k formed, then ``KalmanFilter.predict_many``) to rounding.

Used by :func:`sinslab.fusion.driver.run` when the filter keeps no history (no lagged
measurements) and the discretisation is the series; the filter steps itself with the
loop (:meth:`sinslab.estimation.filter.KalmanFilter.propagate_lanes`).
"""
from __future__ import annotations


import numpy as np
from numba import njit

from sinslab.estimation.filter import KalmanFilter
from sinslab.estimation.kernels import (add_half_qbar, diagonal_tail, predict_step_sparse_x, series_phi,
                                         series_qbar, series_structure)
from sinslab.nav import errstate_kernels as ek

__all__ = ["CompiledPropagation"]


@njit(cache=True)
def _predict_model(rows, w, f, e_a, e_b, rd, F0, G0, core_k, core_r, f_row, f_col, f_ins, f_k,
                   f_j, f_src, f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, q, T, fcol, fcnt,
                   grow, gcnt, R, pos, nr, qbr, qbn, phic, phin, r, x, c, P, sig_out, x_out):
    """Epochs ``e_a..e_b−1`` of L lanes, one lane after the other with the same work arrays:
    ``rows`` (L, k, S, 10), ``w``, ``f`` (L, k, S, 3); ``x``, ``c`` (L, n), ``P`` (L, n, n)
    stepped in place; ``sig_out``, ``x_out`` (L, e_b − e_a, n), ``x_out`` zero on entry
    (written where x is not); rows ``r..n−1`` of Φ diagonal. Returns ``(lane, epoch)`` of
    the first invalid navigation point, or ``(−1, −1)``."""
    n = F0.shape[0]
    C = np.empty((rows.shape[1], 3, 3))
    Fc = np.empty((9, 9))
    Fe = np.empty((n, n))
    Ge = np.empty((n, G0.shape[1]))
    Pe = np.empty((n, n))
    Qh = np.zeros((n, n))
    Qb = np.zeros((max(nr, 1), max(nr, 1)))
    T1 = np.empty((n, n))
    W = np.empty((r, r))
    tmp = np.empty(n)
    h = 0.5 * T
    # the constant entries once; each epoch writes the varying ones over the same places
    Fe[:, :] = F0
    Ge[:, :] = G0
    for ln in range(rows.shape[0]):
        rl, wl, fl = rows[ln], w[ln], f[ln]
        xl, cl, Pl = x[ln], c[ln], P[ln]
        for e in range(e_a, e_b):
            if not ek.fill_varying(rl, wl, fl, e, rd, core_k, core_r, f_row, f_col, f_ins, f_k,
                                   f_j, f_src, f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, C,
                                   Fc, Fe, Ge):
                return ln, e
            series_phi(Fe, T, fcol, fcnt, Pe)
            series_qbar(Ge, q, grow, gcnt, pos, nr, qbr, qbn, Qb)
            add_half_qbar(Pl, Qb, h, R, nr, qbr, qbn, Qh)
            i = e - e_a
            predict_step_sparse_x(xl, cl, Pl, Pe, Qh, r, phic, phin, T1, W, tmp, sig_out[ln, i], x_out[ln, i])
    return -1, -1


class CompiledPropagation:
    """The compiled model + series discretisation + prediction of one error model.

    Parameters
    ----------
    model : ErrorModel or DifferenceModel
        A model of :mod:`sinslab.nav.errstate` (see :func:`sinslab.nav.errstate_kernels.program`).
    prog : ModelProgram
        Its program.
    """

    def __init__(self, model, prog):
        cr = prog.core_r
        if (prog.F0[np.ix_(cr, cr)].any() or prog.F0[prog.f_row, prog.f_col].any()
                or prog.G0[prog.g_row, prog.g_col].any()):
            # the loop copies the constant entries once and writes the varying ones over them
            raise AssertionError("constant and navigation-dependent entries of the model overlap")
        self.prog = prog
        self.q = np.ascontiguousarray(model.q, dtype=float)
        fnz, gnz = ek.pattern(prog)
        self.structure = series_structure(fnz, gnz, self.q)
        #: rows r..n−1 of Φ hold only their diagonal (the sensor states' own dynamics)
        self.r = int(diagonal_tail(self.structure[7], self.structure[8]))
        self._tables = ek.tables(prog)

    @classmethod
    def of(cls, model):
        """The propagation of ``model``, or None when it has no compiled program."""
        prog = ek.program(model)
        return None if prog is None else cls(model, prog)

    def predict(self, filts, stretch, a, b, T, sigma_out, x_out):
        """Predict the filters of L lanes through epochs ``a..b−1`` of a stretch, in one
        compiled call (each lane's arithmetic is that of a call for it alone).

        Parameters
        ----------
        filts : sequence of KalmanFilter
            One per lane, without history and checks (their fast path); x, c, P are
            updated in place and their time advances by ``(b − a) T``.
        stretch : tuple of ndarray
            ``rows`` (L, k, S, 10), ``w``, ``f`` (L, k, S, 3), contiguous: per lane the
            linearisation points of the stretch (see
            :func:`sinslab.nav.errstate_kernels.matrices_rows`).
        a, b : int
            Epochs of the stretch to step from (``a <= b <= S``).
        T : float
            Step [s].
        sigma_out, x_out : sequence of ndarray, shape (b − a, n)
            Per lane, receive σ and x after each step; ``x_out`` holds zeros on entry and
            is written where x is not zero (a closed-loop record stays untouched memory
            between updates).
        """
        rows, w, f = stretch
        fcol, fcnt, grow, gcnt, R, pos, nr, phic, phin, qr, nq, qbr, qbn, prc, prn = self.structure
        r = self.r
        L = len(filts)
        if L == 1:
            so, xo = sigma_out[0][None], x_out[0][None]
        else:
            n = filts[0].n
            so, xo = np.empty((L, b - a, n)), np.zeros((L, b - a, n))

        def step(x, c, P):
            return _predict_model(rows, w, f, a, b, *self._tables, self.q, float(T), fcol, fcnt, grow,
                                  gcnt, R, pos, nr, qbr, qbn, phic, phin, r, x, c, P, so, xo)

        bad, e = KalmanFilter.propagate_lanes(filts, step, b - a, T)
        if bad >= 0:
            ek.matrices_rows(self.prog, rows[bad][:, e:e + 1], w[bad][:, e:e + 1], f[bad][:, e:e + 1])
            raise ValueError(f"navigation point {e} of the stretch is invalid")  # not reached
        if L > 1:
            for ln in range(L):
                sigma_out[ln][:] = so[ln]
                x_out[ln][:] = xo[ln]
