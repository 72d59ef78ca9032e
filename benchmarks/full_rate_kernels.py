"""The compiled stages of one full-rate filter epoch, each alone, for the profile of
``benchmarks/full_rate.py``.

A module of their own so that numba's on-disk cache (``cache=True``) keys them by this
module's name: ``full_rate.py`` runs as ``__main__`` and, in the tests, under another
module name, and a cache written under one name cannot be reloaded under the other.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from sinslab.estimation.kernels import cov_predict, series_phi, series_qbar, state_predict
from sinslab.nav import errstate_kernels as ek


@njit(cache=True)
def k_fill(rows, w, f, n_ep, rd, F0, G0, core_k, core_r, f_row, f_col, f_ins, f_k, f_j, f_src,
            f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, Fs, Gs):
    C = np.empty((1, 3, 3))
    Fc = np.empty((9, 9))
    for e in range(n_ep):
        ek.fill_one(rows, w, f, e, rd, F0, G0, core_k, core_r, f_row, f_col, f_ins, f_k, f_j, f_src,
                    f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, C, Fc, Fs[e], Gs[e])


@njit(cache=True)
def k_phi_qbar(F, G, q, T, fcol, fcnt, grow, gcnt, pos, nr, qbr, qbn, Phi):
    Qb = np.zeros((max(nr, 1), max(nr, 1)))
    for e in range(F.shape[0]):
        series_phi(F[e], T, fcol, fcnt, Phi[e])
        series_qbar(G[e], q, grow, gcnt, pos, nr, qbr, qbn, Qb)


@njit(cache=True)
def k_cov(P, Phi, Q, r):
    n = P.shape[0]
    T1, W = np.empty((n, n)), np.empty((r, r))
    for e in range(Phi.shape[0]):
        cov_predict(P, Phi[e], Q[e], r, T1, W)


@njit(cache=True)
def k_state(x, Phi, phic, phin):
    tmp = np.empty(x.shape[0])
    for e in range(Phi.shape[0]):
        state_predict(x, Phi[e], phic, phin, tmp)
