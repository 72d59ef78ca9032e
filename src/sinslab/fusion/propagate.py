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

from sinslab.estimation.linear import _cov_predict, _state_predict, series_step, series_structure
from sinslab.nav import errstate_kernels as ek

__all__ = ["CompiledPropagation"]


@njit(cache=True)
def _predict_model(rows, w, f, e_a, e_b, rd, F0, G0, core_k, core_r, f_row, f_col, f_ins, f_k,
                   f_j, f_src, f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, q, T, fcol, fcnt,
                   grow, gcnt, R, pos, nr, qr, nq, phic, phin, x, c, P, sig_out, x_out):
    n, m = F0.shape[0], G0.shape[1]
    C = np.empty((rows.shape[0], 3, 3))
    Fc = np.empty((9, 9))
    Fe = np.empty((n, n))
    Ge = np.empty((n, m))
    Pe = np.empty((n, n))
    Qe = np.empty((n, n))
    nr1 = max(nr, 1)
    Qb = np.empty((nr1, nr1))
    PR = np.empty((n, nr1))
    W = np.empty((n, nr1))
    T1 = np.empty((n, n))
    T2 = np.empty((n, n))
    tmp = np.empty(n)
    for e in range(e_a, e_b):
        if not ek.fill_one(rows, w, f, e, rd, F0, G0, core_k, core_r, f_row, f_col, f_ins, f_k,
                           f_j, f_src, f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, C, Fc,
                           Fe, Ge):
            return e
        series_step(Fe, Ge, q, T, fcol, fcnt, grow, gcnt, R, pos, nr, qr, nq, Qb, PR, W, Pe, Qe)
        _cov_predict(P, Pe, Qe, T1, T2)
        _state_predict(x, Pe, phic, phin, tmp)
        _state_predict(c, Pe, phic, phin, tmp)
        i = e - e_a
        for j in range(n):
            sig_out[i, j] = math.sqrt(max(P[j, j], 0.0))
            x_out[i, j] = x[j]
    return -1


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

    def predict(self, filt, stretch, a, b, T, sigma_out, x_out):
        """Predict ``filt`` through epochs ``a..b−1`` of a stretch.

        Parameters
        ----------
        filt : KalmanFilter
            Without history and checks (its fast path); x, c, P are updated in place and
            its time advances by ``(b − a) T``.
        stretch : tuple of ndarray
            ``rows`` (k, S, 10), ``w``, ``f`` (k, S, 3), contiguous: the linearisation
            points of the stretch (see :func:`sinslab.nav.errstate_kernels.matrices_rows`).
        a, b : int
            Epochs of the stretch to step from (``a <= b <= S``).
        T : float
            Step [s].
        sigma_out, x_out : ndarray, shape (b − a, n)
            Receive σ and x after each step.
        """
        rows, w, f = stretch
        fcol, fcnt, grow, gcnt, R, pos, nr, phic, phin, qr, nq = self.structure
        bad = _predict_model(rows, w, f, a, b, *self._tables, self.q, float(T), fcol, fcnt, grow,
                             gcnt, R, pos, nr, qr, nq, phic, phin, filt.x, filt.c, filt.P,
                             sigma_out, x_out)
        if bad >= 0:
            ek.matrices_rows(self.prog, rows[:, bad:bad + 1], w[:, bad:bad + 1], f[:, bad:bad + 1])
            raise ValueError(f"navigation point {bad} of the stretch is invalid")  # not reached
        filt.t += (b - a) * float(T)
