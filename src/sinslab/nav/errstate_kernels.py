"""Compiled evaluation of the error-state models of :mod:`sinslab.nav.errstate`.

:class:`~sinslab.nav.errstate.ErrorModel` and
:class:`~sinslab.nav.errstate.DifferenceModel` assemble ``F`` and ``G`` with readable
vectorised numpy; that code is the reference. Inside a filter loop the same matrices are
needed for every epoch, so :func:`program` turns a model into index tables once (where
each core entry, each ``C_b^n`` entry and each sensor coupling lands, with its sign) and
:func:`matrices_rows` fills ``F`` and ``G`` for many epochs in one compiled scalar loop
(no array temporaries per epoch). The tables are read off the model's own layout and
sensor blocks with the placement rules of ``ErrorModel._assemble``; the core entries are
the scalar form of :func:`~sinslab.nav.errstate.core_matrices`. Both are checked entry by
entry against the numpy model for every core, sensor kind, frame and the difference
model (tests/nav/test_errstate_kernels.py).

Inputs are the rows the fusion driver keeps per navigation stream: ``[q0..q3, vE, vN,
vU, lat, lon, h]`` (scalar-first quaternion of ``C_b^n``, ENU velocity [m/s], latitude
and longitude [rad], height [m]) with the step's mean body rate ``ω_ib^b`` [rad/s] and
specific force ``f^b`` [m/s²].
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from sinslab.core.earth import A, DGDH, E2, G_EQ, K_SOM, WIE
from sinslab.nav import errstate as es

__all__ = ["ModelProgram", "program", "matrices_rows", "fill_one", "tables", "pattern"]

# source of a sensor coupling entry: 0 the unit map (bias, Gauss-Markov), 1 ω_ib^b, 2 f^b
_SRC = {"bias": 0, "markov": 0, "scale": None}


@dataclass(frozen=True)
class ModelProgram:
    """Index tables of one error model (see :func:`program`).

    Attributes
    ----------
    n, m : int
        States and noise columns.
    n_ins : int
        Navigation points the model takes (1, or 2 for a difference model).
    radius_derivatives : bool
    F0, G0 : ndarray (n, n), (n, m)
        Constant entries (sensor dynamics, unit noise inputs); zero elsewhere.
    core_k, core_r : int arrays
        Full-core index (0..8) and model row of each kept core state.
    f_row, f_col, f_ins, f_k, f_j, f_src : int arrays
        Sensor-coupling entries ``F[row, col] = sign · C_ins[k, j] · s`` with ``s = 1``
        (``src`` 0), ``ω_ib^b[j]`` (1) or ``f^b[j]`` (2) of navigation point ``ins``.
    f_sign : float array
    g_row, g_col, g_ins, g_k, g_j : int arrays
        White-noise inputs ``G[row, col] = sign · C_ins[k, j]``.
    g_sign : float array
    """

    n: int
    m: int
    n_ins: int
    radius_derivatives: bool
    F0: np.ndarray
    G0: np.ndarray
    core_k: np.ndarray
    core_r: np.ndarray
    f_row: np.ndarray
    f_col: np.ndarray
    f_ins: np.ndarray
    f_k: np.ndarray
    f_j: np.ndarray
    f_src: np.ndarray
    f_sign: np.ndarray
    g_row: np.ndarray
    g_col: np.ndarray
    g_ins: np.ndarray
    g_k: np.ndarray
    g_j: np.ndarray
    g_sign: np.ndarray


def program(model) -> ModelProgram | None:
    """Index tables that let :func:`matrices_rows` evaluate ``model``'s F and G.

    Parameters
    ----------
    model : ErrorModel or DifferenceModel
        A model of :mod:`sinslab.nav.errstate` whose ``matrices`` (and the assembly
        behind it) is the one defined there; anything else returns None (the caller
        keeps the numpy path).

    Returns
    -------
    ModelProgram or None
    """
    cls = type(model)
    if cls.matrices not in (es.ErrorModel.matrices, es.DifferenceModel.matrices) or \
            cls._assemble is not es.ErrorModel._assemble or cls._rows is not es.ErrorModel._rows:
        return None
    n, m = model.n, len(model.q)
    rows = model._rows()
    ki = list(rows.keys())
    att_k = [k for k in ki if k < 3]
    vel_k = [k for k in ki if 3 <= k < 6]
    att_r = [rows[k] for k in att_k]
    vel_r = [rows[k] for k in vel_k]
    F0 = np.zeros((n, n))
    G0 = np.zeros((n, m))
    fr, fc, fi, fk, fj, fs, fsg = [], [], [], [], [], [], []
    gr, gc, gi_, gk, gj, gsg = [], [], [], [], [], []
    col = 0
    for ii, ins in enumerate(model._ins):
        sg = ins["sign"]
        gax = [es._AXES[a] for a in ins["gaxes"]]
        for c, j in enumerate(gax):
            for a, k in enumerate(att_k):
                gr.append(att_r[a]), gc.append(col + c), gi_.append(ii), gk.append(k), gj.append(j)
                gsg.append(-sg)
        col += len(gax)
        aax = [es._AXES[a] for a in ins["aaxes"]]
        if vel_r:
            for c, j in enumerate(aax):
                for a, k in enumerate(vel_k):
                    gr.append(vel_r[a]), gc.append(col + c), gi_.append(ii), gk.append(k - 3)
                    gj.append(j), gsg.append(sg)
        col += len(aax)
        for s in ins["sensors"]:
            if s.sensor is None:
                continue
            sl = model.layout.slice(s.name + ins["suffix"])
            if s.sensor == "gyro":
                tgt_r, tgt_k, sign = att_r, att_k, -sg
            elif vel_r:
                tgt_r, tgt_k, sign = vel_r, [k - 3 for k in vel_k], sg
            else:
                continue
            src = _SRC.get(s.kind, -1)
            if src is None:
                src = 1 if s.sensor == "gyro" else 2
            if src < 0:
                raise ValueError(f"sensor block {s.name!r}: unknown kind {s.kind!r}")
            for c, a_ in enumerate(s.axes):
                j = es._AXES[a_]
                for r, k in zip(tgt_r, tgt_k):
                    if s.frame == "body":
                        fr.append(r), fc.append(sl.start + c), fi.append(ii), fk.append(k)
                        fj.append(j), fs.append(src), fsg.append(sign)
                    elif k == j:
                        # n-frame states enter without C_b^n: a unit (or source) entry
                        if src != 0:
                            raise ValueError(f"sensor block {s.name!r}: an n-frame scale factor "
                                             "has no compiled form")
                        F0[r, sl.start + c] = sign
    for ins in model._ins:
        for s in ins["sensors"]:
            sl = model.layout.slice(s.name + ins["suffix"])
            d = s.dynamics()
            if d.ndim == 2:
                F0[sl, sl] = d
            else:
                F0[np.arange(sl.start, sl.stop), np.arange(sl.start, sl.stop)] = d
            if np.any(s.q > 0):
                G0[np.arange(sl.start, sl.stop), col + np.arange(s.size)] = 1.0
                col += s.size
    ia = lambda v: np.array(v, dtype=np.int64)  # noqa: E731
    fa = lambda v: np.array(v, dtype=float)  # noqa: E731
    return ModelProgram(n, m, len(model._ins), bool(model.radius_derivatives), F0, G0,
                        ia(ki), ia([rows[k] for k in ki]), ia(fr), ia(fc), ia(fi), ia(fk),
                        ia(fj), ia(fs), fa(fsg), ia(gr), ia(gc), ia(gi_), ia(gk), ia(gj),
                        fa(gsg))


@njit(cache=True)
def _quat_dcm(q0, q1, q2, q3, C):
    """C_b^n of a scalar-first quaternion, normalised first (as attitude.quat_to_dcm)."""
    nq = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
    w, x, y, z = q0 / nq, q1 / nq, q2 / nq, q3 / nq
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    C[0, 0] = x2 - y2 - z2 + w2
    C[1, 0] = 2.0 * (xy + zw)
    C[2, 0] = 2.0 * (xz - yw)
    C[0, 1] = 2.0 * (xy - zw)
    C[1, 1] = -x2 + y2 - z2 + w2
    C[2, 1] = 2.0 * (yz + xw)
    C[0, 2] = 2.0 * (xz + yw)
    C[1, 2] = 2.0 * (yz - xw)
    C[2, 2] = -x2 - y2 + z2 + w2


@njit(cache=True)
def _core(L, h, vE, vN, vU, fE, fN, fU, rd, Fc):
    """The 9×9 core matrix of errstate.core_matrices at one point, into Fc (all entries)."""
    for i in range(9):
        for j in range(9):
            Fc[i, j] = 0.0
    sL, cL = math.sin(L), math.cos(L)
    tL = sL / cL
    q = 1.0 - E2 * sL * sL
    RM0 = A * (1.0 - E2) / q ** 1.5
    RN0 = A / math.sqrt(q)
    RMh, RNh = RM0 + h, RN0 + h
    if rd:
        dRM = RM0 * 3.0 * E2 * sL * cL / q
        dRN = RN0 * E2 * sL * cL / q
        dgdL = G_EQ * (2.0 * K_SOM * sL * cL / math.sqrt(q)
                       + (1.0 + K_SOM * sL * sL) * E2 * sL * cL / q ** 1.5)
    else:
        dRM = dRN = dgdL = 0.0
    wie1, wie2 = WIE * cL, WIE * sL
    wen0, wen1, wen2 = -vN / RMh, vE / RNh, vE * tL / RNh
    w0, w1, w2 = wen0, wie1 + wen1, wie2 + wen2                 # ω_in
    # φ rows: −(ω_in×), Mav, M1 + M2
    Fc[0, 1], Fc[0, 2] = w2, -w1
    Fc[1, 0], Fc[1, 2] = -w2, w0
    Fc[2, 0], Fc[2, 1] = w1, -w0
    mav01, mav10, mav20 = -1.0 / RMh, 1.0 / RNh, tL / RNh
    Fc[0, 4], Fc[1, 3], Fc[2, 3] = mav01, mav10, mav20
    RMh2, RNh2 = RMh ** 2, RNh ** 2
    m2_00 = vN * dRM / RMh2
    m2_02 = vN / RMh2
    m2_10 = -vE * dRN / RNh2
    m2_12 = -vE / RNh2
    m2_20 = vE / (cL * cL * RNh) - vE * tL * dRN / RNh2
    m2_22 = -vE * tL / RNh2
    m1_10, m1_20 = -WIE * sL, WIE * cL
    Fc[0, 6], Fc[0, 8] = m2_00, m2_02
    Fc[1, 6], Fc[1, 8] = m1_10 + m2_10, m2_12
    Fc[2, 6], Fc[2, 8] = m1_20 + m2_20, m2_22
    # δv rows: (f^n×), (v×) Mav − ((2ω_ie + ω_en)×), (v×)(2 M1 + M2), gravity
    Fc[3, 1], Fc[3, 2] = -fU, fN
    Fc[4, 0], Fc[4, 2] = fU, -fE
    Fc[5, 0], Fc[5, 1] = -fN, fE
    # v× = [[0, −vU, vN], [vU, 0, −vE], [−vN, vE, 0]]; Mav has columns 0 (rows 1, 2), 1 (row 0)
    u0, u1, u2 = wen0, 2.0 * wie1 + wen1, 2.0 * wie2 + wen2
    Fc[3, 3] = -vU * mav10 + vN * mav20
    Fc[3, 4] = u2
    Fc[3, 5] = -u1
    Fc[4, 3] = -vE * mav20 - u2
    Fc[4, 4] = vU * mav01
    Fc[4, 5] = u0
    Fc[5, 3] = vE * mav10 + u1
    Fc[5, 4] = -vN * mav01 - u0
    n00, n02 = m2_00, m2_02
    n10, n12 = 2.0 * m1_10 + m2_10, m2_12
    n20, n22 = 2.0 * m1_20 + m2_20, m2_22
    Fc[3, 6] = -vU * n10 + vN * n20
    Fc[3, 8] = -vU * n12 + vN * n22
    Fc[4, 6] = vU * n00 - vE * n20
    Fc[4, 8] = vU * n02 - vE * n22
    Fc[5, 6] = -vN * n00 + vE * n10 - dgdL
    Fc[5, 8] = -vN * n02 + vE * n12 + DGDH
    # position rows
    Fc[6, 4] = 1.0 / RMh
    Fc[6, 6] = -vN * dRM / RMh2
    Fc[6, 8] = -vN / RMh2
    Fc[7, 3] = 1.0 / (RNh * cL)
    Fc[7, 6] = vE * tL / (RNh * cL) - vE * dRN / (RNh2 * cL)
    Fc[7, 8] = -vE / (RNh2 * cL)
    Fc[8, 5] = 1.0


@njit(cache=True)
def fill_one(rows, w, f, e, rd, F0, G0, core_k, core_r, f_row, f_col, f_ins, f_k, f_j, f_src,
             f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, C, Fc, Fe, Ge):
    """F and G of epoch ``e`` into ``Fe`` (n, n), ``Ge`` (n, m); ``C`` (k, 3, 3) and
    ``Fc`` (9, 9) are work arrays. Returns False for a non-finite input or a latitude beyond ±90°."""
    n, m = F0.shape[0], G0.shape[1]
    for i in range(n):
        for j in range(n):
            Fe[i, j] = F0[i, j]
        for j in range(m):
            Ge[i, j] = G0[i, j]
    return fill_varying(rows, w, f, e, rd, core_k, core_r, f_row, f_col, f_ins, f_k, f_j, f_src,
                        f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, C, Fc, Fe, Ge)


@njit(cache=True)
def fill_varying(rows, w, f, e, rd, core_k, core_r, f_row, f_col, f_ins, f_k, f_j, f_src,
                 f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, C, Fc, Fe, Ge):
    """The entries of F and G that vary with the navigation point (those :func:`fill_one`
    writes after the constant ``F0``, ``G0``; the two sets do not overlap), for a caller
    that keeps ``Fe``, ``Ge`` from one epoch to the next and copied the constants once.
    Returns False for a non-finite input or a latitude beyond ±90°."""
    n_ins = rows.shape[0]
    for i in range(n_ins):
        for c in range(10):
            if not math.isfinite(rows[i, e, c]):
                return False
        for c in range(3):
            if not (math.isfinite(w[i, e, c]) and math.isfinite(f[i, e, c])):
                return False
        _quat_dcm(rows[i, e, 0], rows[i, e, 1], rows[i, e, 2], rows[i, e, 3], C[i])
    L = rows[0, e, 7]
    if not abs(L) < 0.5 * math.pi:
        return False
    f0, f1, f2 = f[0, e, 0], f[0, e, 1], f[0, e, 2]
    fE = C[0, 0, 0] * f0 + C[0, 0, 1] * f1 + C[0, 0, 2] * f2
    fN = C[0, 1, 0] * f0 + C[0, 1, 1] * f1 + C[0, 1, 2] * f2
    fU = C[0, 2, 0] * f0 + C[0, 2, 1] * f1 + C[0, 2, 2] * f2
    _core(L, rows[0, e, 9], rows[0, e, 4], rows[0, e, 5], rows[0, e, 6], fE, fN, fU, rd, Fc)
    # the tables hold places, never negative: as unsigned integers they index without
    # numba's test for an index counted from the end (see sinslab.estimation.kernels)
    nk = core_k.shape[0]
    for a in range(nk):
        ra, ka = np.uint64(core_r[a]), np.uint64(core_k[a])
        for b in range(nk):
            Fe[ra, np.uint64(core_r[b])] = Fc[ka, np.uint64(core_k[b])]
    for t in range(f_row.shape[0]):
        ii, j = np.uint64(f_ins[t]), np.uint64(f_j[t])
        v = f_sign[t] * C[ii, np.uint64(f_k[t]), j]
        if f_src[t] == 1:
            v *= w[ii, e, j]
        elif f_src[t] == 2:
            v *= f[ii, e, j]
        Fe[np.uint64(f_row[t]), np.uint64(f_col[t])] = v
    for t in range(g_row.shape[0]):
        Ge[np.uint64(g_row[t]), np.uint64(g_col[t])] = g_sign[t] * C[np.uint64(g_ins[t]), np.uint64(g_k[t]),
                                                                      np.uint64(g_j[t])]
    return True


@njit(cache=True)
def _fill(rows, w, f, rd, F0, G0, core_k, core_r, f_row, f_col, f_ins, f_k, f_j, f_src,
          f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, F, G):
    """F[e], G[e] for every epoch e; returns the first bad epoch or -1."""
    C = np.empty((rows.shape[0], 3, 3))
    Fc = np.empty((9, 9))
    for e in range(rows.shape[1]):
        if not fill_one(rows, w, f, e, rd, F0, G0, core_k, core_r, f_row, f_col, f_ins, f_k,
                        f_j, f_src, f_sign, g_row, g_col, g_ins, g_k, g_j, g_sign, C, Fc,
                        F[e], G[e]):
            return e
    return -1


def tables(prog: ModelProgram):
    """The arguments of :func:`fill_one` that come from the program, in order (from
    ``rd`` to ``g_sign``)."""
    return (prog.radius_derivatives, prog.F0, prog.G0, prog.core_k, prog.core_r, prog.f_row,
            prog.f_col, prog.f_ins, prog.f_k, prog.f_j, prog.f_src, prog.f_sign, prog.g_row,
            prog.g_col, prog.g_ins, prog.g_k, prog.g_j, prog.g_sign)


def pattern(prog: ModelProgram):
    """Entries of F (n, n) and G (n, m) that can be non-zero (bool arrays).

    Every entry is an analytic function of the navigation point, so one that vanishes at
    two random generic points vanishes everywhere; the entries the tables write are
    added whatever their value."""
    rng = np.random.default_rng(20240601)
    k = prog.n_ins
    fnz = prog.F0 != 0
    gnz = prog.G0 != 0
    for _ in range(2):
        rows = np.zeros((k, 1, 10))
        rows[:, 0, :4] = rng.normal(size=(k, 4))
        rows[:, 0, 4:7] = rng.normal(scale=50.0, size=(k, 3))
        rows[:, 0, 7] = rng.uniform(-1.2, 1.2)
        rows[:, 0, 9] = rng.uniform(0.0, 3000.0)
        F, G = matrices_rows(prog, rows, rng.normal(size=(k, 1, 3)), rng.normal(size=(k, 1, 3)))
        fnz = fnz | (F[0] != 0)
        gnz = gnz | (G[0] != 0)
    fnz[prog.f_row, prog.f_col] = True
    gnz[prog.g_row, prog.g_col] = True
    return fnz, gnz


def matrices_rows(prog: ModelProgram, rows, w, f, F=None, G=None):
    """F and G of the model at many epochs, from navigation rows.

    Parameters
    ----------
    prog : ModelProgram
        From :func:`program`.
    rows : ndarray, shape (k, S, 10)
        Per navigation point (k = ``prog.n_ins``) and epoch: ``[q0..q3, vE, vN, vU, lat,
        lon, h]`` [-, m/s, rad, m].
    w, f : ndarray, shape (k, S, 3)
        Body rate ω_ib^b [rad/s] and specific force f^b [m/s²].
    F, G : ndarray, shape (≥S, n, n), (≥S, n, m), optional
        Output buffers (reused by a caller that evaluates stretch after stretch).

    Returns
    -------
    F, G : ndarray, shape (S, n, n), (S, n, m)
        Views of the buffers, equal to ``model.matrices(*navpoints)`` to rounding.

    Raises
    ------
    ValueError
        Non-finite navigation values or a latitude outside (−90°, 90°), as NavPoint.
    """
    rows = np.ascontiguousarray(rows, dtype=float)
    w = np.ascontiguousarray(w, dtype=float)
    f = np.ascontiguousarray(f, dtype=float)
    k, S = rows.shape[:2]
    if k != prog.n_ins or rows.shape[2] != 10 or w.shape != (k, S, 3) or f.shape != (k, S, 3):
        raise ValueError(f"rows must be ({prog.n_ins}, S, 10) and rates ({prog.n_ins}, S, 3), got "
                         f"{rows.shape}, {w.shape}, {f.shape}")
    n, m = prog.n, prog.m
    F = np.empty((S, n, n)) if F is None or F.shape[0] < S else F
    G = np.empty((S, n, m)) if G is None or G.shape[0] < S else G
    F, G = F[:S], G[:S]
    bad = _fill(rows, w, f, *tables(prog), F, G)
    if bad >= 0:
        for i in range(k):
            if not (np.all(np.isfinite(rows[i, bad])) and np.all(np.isfinite(w[i, bad]))
                    and np.all(np.isfinite(f[i, bad]))):
                raise ValueError(f"NavPoint of stream {i} has non-finite values at epoch {bad}")
        raise ValueError("NavPoint latitude must be inside (-90, 90) deg")
    return F, G
