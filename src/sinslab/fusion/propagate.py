"""Filter prediction with the error model evaluated inside one compiled loop.

Per epoch: ``F``, ``G`` from the navigation rows (:func:`sinslab.nav.errstate_kernels.fill_one`),
the series ``Φ``, ``Q_k`` (:func:`sinslab.estimation.linear.series_step`), then the
filter's own prediction steps (``P ← Φ P Φᵀ + Q_k``, ``x ← Φ x``, ``c ← Φ c``: the kernels
of :meth:`sinslab.estimation.filter.KalmanFilter.predict_many`). The matrices live in
small work arrays that stay in cache, instead of stretches of ``(S, n, n)`` arrays
written and read back. The arithmetic of each step is that of the unfused path: the
zeros skipped are those of the model's structure, whose terms add exact zeros.

Used by :func:`sinslab.fusion.driver.run` when the filter keeps no history (no lagged
measurements) and the discretisation is the series.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sinslab.estimation.filter import propagate_lanes
from sinslab.estimation.linear import _cov_predict, _state_predict, series_step, series_structure
from sinslab.nav import errstate_kernels as ek

__all__ = ["CompiledPropagation"]


@njit(cache=True)
def _predict_model(rows, w, f, e_a, e_b, rd, F0, G0, core_k, core_r, f_row, f_col, f_ins, f_k,
                   f_j, f_src, f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, q, T, fcol, fcnt,
                   grow, gcnt, R, pos, nr, qr, nq, phic, phin, qbr, qbn, prc, prn, x, c, P,
                   sig_out, x_out):
    """Epochs ``e_a..e_b−1`` of L lanes, one lane after the other with the same work arrays:
    ``rows`` (L, k, S, 10), ``w``, ``f`` (L, k, S, 3); ``x``, ``c`` (L, n), ``P`` (L, n, n)
    stepped in place; ``sig_out``, ``x_out`` (L, e_b − e_a, n). Returns ``(lane, epoch)``
    of the first invalid navigation point, or ``(−1, −1)``."""
    n, m = F0.shape[0], G0.shape[1]
    C = np.empty((rows.shape[1], 3, 3))
    Fc = np.empty((9, 9))
    Fe = np.empty((n, n))
    Ge = np.empty((n, m))
    Pe = np.empty((n, n))
    Qe = np.empty((n, n))
    nr1 = max(nr, 1)
    Qb = np.zeros((nr1, nr1))
    PR = np.empty((n, nr1))
    W = np.empty((n, nr1))
    T1 = np.empty((n, n))
    T2 = np.empty((n, n))
    tmp = np.empty(n)
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
            series_step(Fe, Ge, q, T, fcol, fcnt, grow, gcnt, R, pos, nr, qr, nq, Qb, PR, W, Pe, Qe,
                        qbr, qbn, prc, prn)
            _cov_predict(Pl, Pe, Qe, T1, T2)
            _state_predict(xl, Pe, phic, phin, tmp)
            _state_predict(cl, Pe, phic, phin, tmp)
            i = e - e_a
            for j in range(n):
                sig_out[ln, i, j] = math.sqrt(max(Pl[j, j], 0.0))
                x_out[ln, i, j] = xl[j]
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
            Per lane, receive σ and x after each step.
        """
        rows, w, f = stretch
        fcol, fcnt, grow, gcnt, R, pos, nr, phic, phin, qr, nq, qbr, qbn, prc, prn = self.structure
        L = len(filts)
        if L == 1:
            so, xo = sigma_out[0][None], x_out[0][None]
        else:
            n = filts[0].n
            so, xo = np.empty((L, b - a, n)), np.empty((L, b - a, n))

        def step(x, c, P):
            return _predict_model(rows, w, f, a, b, *self._tables, self.q, float(T), fcol, fcnt, grow,
                                  gcnt, R, pos, nr, qr, nq, phic, phin, qbr, qbn, prc, prn, x, c, P,
                                  so, xo)

        bad, e = propagate_lanes(filts, step, b - a, T)
        if bad >= 0:
            ek.matrices_rows(self.prog, rows[bad][:, e:e + 1], w[bad][:, e:e + 1], f[bad][:, e:e + 1])
            raise ValueError(f"navigation point {e} of the stretch is invalid")  # not reached
        if L > 1:
            for ln in range(L):
                sigma_out[ln][:] = so[ln]
                x_out[ln][:] = xo[ln]
