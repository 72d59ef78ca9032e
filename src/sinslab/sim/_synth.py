"""Compiled synthesis kernels of :func:`sinslab.sim.trajectory.generate`.

The segment compiler of :mod:`sinslab.sim.trajectory` turns a motion into channel-term
tables (layout constants below); :func:`_synth` evaluates the channels, the kinematics
and the Earth terms once per epoch and integrates increments and position with the
stencil or quadrature weights of :func:`_stencil` / :func:`_rule` (the model and the
numerics are described in :mod:`sinslab.sim.trajectory`). Private: only the trajectory
module calls these.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sinslab.core import earth, units
from sinslab.core.attitude import euler_dcm_sc, euler_rates_to_body_sc, wrap_pi_s

G0 = units.g0          # gravity used for the coordinated-turn bank angle (a body attitude only)

# channel-term table layout: channels, term types
NCH = 10
CH_V, CH_PSI, CH_THETA, CH_ROLL, CH_PITCH, CH_YAW, CH_HEAVE, CH_MP, CH_MR, CH_MY = range(NCH)
T_TRAP, T_STEP, T_SINE = 0, 1, 2


# --- quadrature rules ----------------------------------------------------------------------
def _rule(quadrature: str, n: int):
    """Nodes c, weights b on [0, 1] and the collocation matrix A_ij = ∫_0^{c_i} ℓ_j."""
    P = np.polynomial.legendre
    if quadrature == "gauss":
        if not 1 <= n <= 8:
            raise ValueError(f"gauss quadrature needs 1..8 nodes, got {n}")
        x, w = P.leggauss(n)
    elif quadrature == "lobatto":
        if not 2 <= n <= 8:
            raise ValueError(f"lobatto quadrature needs 2..8 nodes, got {n}")
        Pn1 = P.Legendre.basis(n - 1)
        x = np.concatenate([[-1.0], np.sort(Pn1.deriv().roots().real), [1.0]])
        w = 2.0 / (n * (n - 1) * Pn1(x) ** 2)
    else:
        raise ValueError(f"quadrature must be 'lobatto' or 'gauss', got {quadrature!r}")
    c, b = (x + 1) / 2, w / 2
    A = np.empty((n, n))
    for j in range(n):
        others = np.delete(c, j)
        poly = (np.polynomial.Polynomial.fromroots(others) / np.prod(c[j] - others)
                if others.size else np.polynomial.Polynomial([1.0]))
        ip = poly.integ()
        A[:, j] = ip(c) - ip(0.0)
    return c, b, A


# --- numba kernel --------------------------------------------------------------------------
# inline="always" inlines at numba-IR level: every copy is typed and lowered again, so
# nested helpers called from several places multiply the compile time of a first run.
# The small helpers are plain functions (LLVM inlines them: same code, same speed); only
# _term, _sine_term and _kin, which LLVM would leave as calls in the per-epoch loop
# (synthesis ~10 % slower), and _earth (compiles faster inlined) are inlined by numba,
# and _term leaves sine terms to its callers so that a kernel holds one _sine_term.
@njit(cache=True)
def _s5(x):
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))


@njit(cache=True)
def _s5d(x):
    y = x * (1.0 - x)
    return 30.0 * y * y


@njit(cache=True)
def _s5dd(x):
    return 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x)


@njit(cache=True)
def _s5i(x):
    x2 = x * x
    return x2 * x2 * (2.5 + x * (-3.0 + x))


@njit(cache=True, inline="always")
def _term(typ, u, p0, p1, p2):
    """(value, rate, acceleration) at u = t − t_a of a rate-trapezoid (typ 0) or smooth-step
    (typ 1) channel term; sine terms go to :func:`_sine_term` (scalars only, so that
    inlining it into the per-sample loop adds no array reference counting)."""
    if typ == 0:                           # rate trapezoid: r, T, Tr
        r = p0
        T = p1
        Tr = p2
        if Tr > 0.0 and u < Tr:
            x = u / Tr
            return r * Tr * _s5i(x), r * _s5(x), r * _s5d(x) / Tr
        if Tr > 0.0 and u > T - Tr:
            x = (T - u) / Tr
            if x < 0.0:
                x = 0.0
            return r * (T - Tr - Tr * _s5i(x)), r * _s5(x), -(r * _s5d(x) / Tr)
        return r * (0.5 * Tr + (u - Tr)), r, 0.0
    dd = p0                                # smooth step: d, T
    T = p1
    x = u / T
    if x > 1.0:
        x = 1.0
    elif x < 0.0:
        x = 0.0
    return dd * _s5(x), dd * _s5d(x) / T, dd * _s5dd(x) / (T * T)


@njit(cache=True, inline="always")
def _sine_term(u, A, w, T, ri, ro, s, c):
    """(value, rate, acceleration) of a sine term A·e(u)·sin(w·u + phase) with ramps ri, ro
    over its duration T, given s, c = sin, cos of its argument."""
    e = 1.0
    ed = 0.0
    edd = 0.0
    if ri > 0.0 and u < ri:
        x = u / ri
        e = _s5(x)
        ed = _s5d(x) / ri
        edd = _s5dd(x) / (ri * ri)
    elif ro > 0.0 and u > T - ro:
        x = (T - u) / ro
        if x < 0.0:
            x = 0.0
        e = _s5(x)
        ed = -_s5d(x) / ro
        edd = _s5dd(x) / (ro * ro)
    return A * e * s, A * (ed * s + e * w * c), A * (edd * s + 2.0 * ed * w * c - e * w * w * s)


@njit(cache=True)
def _channels(t, j, base, plo, phi, act, ttype, tch, tta, tpar, val, d1, d2):
    """Values and first two derivatives of all channels at time t (piece j)."""
    for c in range(NCH):
        val[c] = base[j, c]
        d1[c] = 0.0
        d2[c] = 0.0
    for a in range(plo[j], phi[j]):
        k = act[a]
        u = t - tta[k]
        if ttype[k] == T_SINE:
            arg = tpar[k, 1] * u + tpar[k, 2]
            x0, x1, x2 = _sine_term(u, tpar[k, 0], tpar[k, 1], tpar[k, 3], tpar[k, 4], tpar[k, 5],
                                    math.sin(arg), math.cos(arg))
        else:
            x0, x1, x2 = _term(ttype[k], u, tpar[k, 0], tpar[k, 1], tpar[k, 2])
        ch = tch[k]
        val[ch] += x0
        d1[ch] += x1
        d2[ch] += x2


@njit(cache=True, inline="always")
def _kin(V, Vd, thd, sthv, cthv, spsv, cpsv, psd, hd1, hd2,
         pitch, pitchd, sth, cth, yaw, yawd, sps, cps, roll, rolld, sg, cg,
         has_mount, mnt):
    """Kinematic state from the channels, sines and cosines given (track path angle and yaw:
    sthv..cpsv; body pitch, yaw, roll: sth..cg; ``mnt``: the mount's pitch, roll, yaw,
    their rates and sines and cosines, a 12-tuple: a call of more than 30 arguments
    compiles to a call with ``*args``, which numba cannot inline): the 24-tuple v(3) vdot(3)
    C_b^n(9) w_nb^b(3) att_c(3) mount(3). Arithmetic only (no call, no branch but
    has_mount), so that loops of it vectorise."""
    s0 = -V * cthv * spsv
    s1 = V * cthv * cpsv
    s2 = V * sthv + hd1
    s3 = -Vd * cthv * spsv + V * sthv * thd * spsv - V * cthv * cpsv * psd
    s4 = Vd * cthv * cpsv - V * sthv * thd * cpsv - V * cthv * spsv * psd
    s5 = Vd * sthv + V * cthv * thd + hd2
    c00, c01, c02, c10, c11, c12, c20, c21, c22 = euler_dcm_sc(sth, cth, sg, cg, sps, cps)
    wx, wy, wz = euler_rates_to_body_sc(sth, cth, sg, cg, pitchd, rolld, yawd)
    if not has_mount:
        return (s0, s1, s2, s3, s4, s5, c00, c01, c02, c10, c11, c12, c20, c21, c22,
                wx, wy, wz, pitch, roll, yaw, 0.0, 0.0, 0.0)
    mp, mr, my, mpd, mrd, myd, st, ct, sr, cr, sy, cy = mnt
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = euler_dcm_sc(st, ct, sr, cr, sy, cy)  # C_b^c
    # w_nb^b = M^T w_nc^c + w_cb^b
    ux, uy, uz = euler_rates_to_body_sc(st, ct, sr, cr, mpd, mrd, myd)
    # C_b^n = C_c^n M
    return (s0, s1, s2, s3, s4, s5,
            c00 * m00 + c01 * m10 + c02 * m20, c00 * m01 + c01 * m11 + c02 * m21,
            c00 * m02 + c01 * m12 + c02 * m22, c10 * m00 + c11 * m10 + c12 * m20,
            c10 * m01 + c11 * m11 + c12 * m21, c10 * m02 + c11 * m12 + c12 * m22,
            c20 * m00 + c21 * m10 + c22 * m20, c20 * m01 + c21 * m11 + c22 * m21,
            c20 * m02 + c21 * m12 + c22 * m22,
            m00 * wx + m10 * wy + m20 * wz + ux, m01 * wx + m11 * wy + m21 * wz + uy,
            m02 * wx + m12 * wy + m22 * wz + uz,
            pitch, roll, yaw, mp, mr, my)


@njit(cache=True)
def _state(t, j, has_mount, flag, base, plo, phi, act, ttype, tch, tta, tpar, val, d1, d2, S, i):
    """Kinematic state at time t into S[i]: v(3) vdot(3) C_b^n(9) w_nb^b(3) att_c(3) mount(3).
    (The fallback path's evaluation at arbitrary node times; _kinematics does the same for
    whole blocks of epochs, with cached sines and cosines and without the array-argument
    call per epoch.)"""
    _channels(t, j, base, plo, phi, act, ttype, tch, tta, tpar, val, d1, d2)
    V = val[CH_V]
    Vd = d1[CH_V]
    psv = val[CH_PSI]
    psd = d1[CH_PSI]
    thv = val[CH_THETA]
    thd = d1[CH_THETA]
    roll = val[CH_ROLL]
    rolld = d1[CH_ROLL]
    if flag[j] != 0:
        u = -V * psd / G0
        roll += math.atan(u)
        rolld += -(Vd * psd + V * d2[CH_PSI]) / G0 / (1.0 + u * u)
    pitch = thv + val[CH_PITCH]
    yaw = psv + val[CH_YAW]
    out = _kin(V, Vd, thd, math.sin(thv), math.cos(thv), math.sin(psv), math.cos(psv), psd,
               d1[CH_HEAVE], d2[CH_HEAVE], pitch, thd + d1[CH_PITCH], math.sin(pitch),
               math.cos(pitch), yaw, psd + d1[CH_YAW], math.sin(yaw), math.cos(yaw),
               roll, rolld, math.sin(roll), math.cos(roll), has_mount,
               (val[CH_MP], val[CH_MR], val[CH_MY], d1[CH_MP], d1[CH_MR], d1[CH_MY],
                math.sin(val[CH_MP]), math.cos(val[CH_MP]), math.sin(val[CH_MR]),
                math.cos(val[CH_MR]), math.sin(val[CH_MY]), math.cos(val[CH_MY])))
    for q in range(24):
        S[i, q] = out[q]


@njit(cache=True, inline="always")
def _earth(sl, cl, h, ve, vn, vu, a0, a1, a2, c00, c01, c02, c10, c11, c12, c20, c21, c22,
           w0, w1, w2):
    """ω_ib^b, f^b and the position rates (L̇, λ̇, ḣ) at latitude (sin, cos) and height h, from
    v^n, v̇^n (a), C_b^n and ω_nb^b (w). Radii and gravity: the formulas of earth.radii_s /
    earth.gravity_s, with the four reciprocals (1/√(1−e²sin²L), 1/R_M, 1/R_N, 1/cos L) taken
    from one division (a few ulps)."""
    irm, irn, icl, g = _earth_radii(sl, cl, h)
    return _earth_terms(sl, cl, irm, irn, icl, g, ve, vn, vu, a0, a1, a2, c00, c01, c02, c10,
                        c11, c12, c20, c21, c22, w0, w1, w2)


@njit(cache=True, inline="always")
def _earth_radii(sl, cl, h):
    """1/(R_M + h), 1/(R_N + h), 1/cos L and normal gravity at latitude (sin, cos) and
    height h (the first part of :func:`_earth`)."""
    s = math.sqrt(1.0 - earth.E2 * sl * sl)
    s3 = s * s * s
    P = earth.A * (1.0 - earth.E2) + h * s3          # R_M = P / s³
    Q = earth.A + h * s                              # R_N = Q / s
    sP = s * P
    Qc = Q * cl
    inv = 1.0 / (sP * Qc)
    rsq = inv * P * Qc
    irm = inv * s * Qc * s3
    irn = inv * sP * cl * s
    icl = inv * sP * Q
    g = earth.G_EQ * (1.0 + earth.K_SOM * sl * sl) * rsq - earth.DGDH * h
    return irm, irn, icl, g


@njit(cache=True, inline="always")
def _earth_terms(sl, cl, irm, irn, icl, g, ve, vn, vu, a0, a1, a2, c00, c01, c02, c10, c11,
                 c12, c20, c21, c22, w0, w1, w2):
    """The rest of :func:`_earth`, from :func:`_earth_radii`'s values."""
    wiy = earth.WIE * cl
    wiz = earth.WIE * sl
    ex = -vn * irm
    ey = ve * irn
    ez = ey * sl * icl
    # w_in^n
    nx = ex
    ny = wiy + ey
    nz = wiz + ez
    # f^n = vdot + (2 w_ie + w_en) x v + [0, 0, g]
    ay = 2.0 * wiy + ey
    az = 2.0 * wiz + ez
    fx = a0 + ay * vu - az * vn
    fy = a1 + az * ve - ex * vu
    fz = a2 + ex * vn - ay * ve + g
    return (w0 + c00 * nx + c10 * ny + c20 * nz,
            w1 + c01 * nx + c11 * ny + c21 * nz,
            w2 + c02 * nx + c12 * ny + c22 * nz,
            c00 * fx + c10 * fy + c20 * fz,
            c01 * fx + c11 * fy + c21 * fz,
            c02 * fx + c12 * fy + c22 * fz,
            vn * irm, ey * icl, vu)


@njit(cache=True)
def _earth_call(S, i, sl, cl, h, W, F):
    """Earth terms of S[i] into W[i] (ω_ib^b, f^b) and F[i] (position rates)."""
    out = _earth(sl, cl, h, S[i, 0], S[i, 1], S[i, 2], S[i, 3], S[i, 4], S[i, 5], S[i, 6],
                 S[i, 7], S[i, 8], S[i, 9], S[i, 10], S[i, 11], S[i, 12], S[i, 13], S[i, 14],
                 S[i, 15], S[i, 16], S[i, 17])
    for q in range(6):
        W[i, q] = out[q]
    for q in range(3):
        F[i, q] = out[6 + q]


@njit(cache=True)
def _advance(t, j, bp):
    n = bp.shape[0]
    while j + 1 < n and t >= bp[j + 1]:
        j += 1
    return j


@njit(cache=True)
def _asin1(x):
    if x > 1.0:
        x = 1.0
    elif x < -1.0:
        x = -1.0
    return math.asin(x)


_BLOCK = 64        # intervals per block: the vectorised passes run over ~70 epochs at a time
_NB = _BLOCK + 8   # buffer columns: a block and its stencil halo (at most 7 epochs)
_NROW = 74         # buffer rows: kinematics 0..23, Earth terms 24..32, predicted offsets 33, 34,
                   # stencil sums 35..43, channel c's value, rate and acceleration 44 + 3c ..
                   # 46 + 3c
_R = tuple(np.uint64(r * _NB) for r in range(_NROW))     # row offsets in the flat buffer
_U = tuple(np.uint64(j) for j in range(8))                # column steps within a row
_ONE = np.int64(1)    # a run of one epoch (typed: a literal 1 would compile _bank_rows again)


_ROT_MAX = 0.02      # largest angle step [rad] taken by rotation instead of sin/cos
_ROT_RUN = 64        # rotations before an exact sin/cos again (rounding grows ~1 ulp each)


@njit(cache=True)
def _sincos_step(x, a, s, c, n):
    """(x, sin x, cos x, n') from the previous (a, sin a, cos a) and the number n of
    rotations since they were exact: the same values if x == a; for a small step
    d = x − a, (s, c) rotated by d (sin d, cos d by their series, exact to < 1e-18); else,
    or after _ROT_RUN rotations, sin and cos afresh. The epochs' angles change by
    ~1e-4..1e-2 rad per sample, and a rotation costs a third of a sin/cos pair."""
    if x == a:
        return a, s, c, n
    d = x - a
    if n < _ROT_RUN and -_ROT_MAX < d < _ROT_MAX:
        d2 = d * d
        sd = d * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0))))
        cd = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)))
        return x, s * cd + c * sd, c * cd - s * sd, n + 1
    return x, math.sin(x), math.cos(x), 0


@njit(cache=True)
def _same(x, y):
    """x and y equal, zeros of the same sign (then every function of them is the same)."""
    return x == y and math.copysign(1.0, x) == math.copysign(1.0, y)


@njit(cache=True, error_model="numpy")
def _channel_rows(e, nr, ui, dt, je, base, plo, phi, act, ttype, tch, tta, tpar, tc, rowb, Z):
    """Values, rates and accelerations of all channels at the nr epochs e, e+1, ... of piece
    je (t = e·dt) into columns ui, ui+1, ... of rows 44 + 3c, 45 + 3c, 46 + 3c of the flat
    block buffer ``Z`` (channel c; layout as in :func:`_earth_block`).

    The same sums as :func:`_channels` — the piece's base value (rates 0), then its active
    terms in order — row by row: every term's parameters are read once per run and its
    values computed in a loop of its own (vectorised for trapezoids and steps, divisions
    included); epoch by epoch, fetching each term's type, channel and parameters and
    dispatching on them cost more than the evaluation. Sines and cosines of the sine terms
    by :func:`_sincos_step` on the per-term cache ``tc``. ``rowb[c]``: the constant that
    fills every column of channel c's rows (rates 0), or NaN.
    """
    nb = np.uint64(_NB)
    active = 0
    for a in range(plo[je], phi[je]):
        active |= 1 << tch[act[a]]
    for c in range(NCH):
        b = base[je, c]
        o = np.uint64((44 + 3 * c) * _NB)
        if active & (1 << c):
            o += ui
            for k in range(nr):
                uk = np.uint64(k)
                Z[o + uk] = b
                Z[o + nb + uk] = 0.0
                Z[o + nb + nb + uk] = 0.0
            rowb[c] = math.nan
        elif not _same(b, rowb[c]):
            # a channel without terms: its rows hold the constant in every column, written
            # once for as long as it stays so (the memory traffic of filling all rows for
            # every run cost more than the evaluation saved)
            for k in range(_NB):
                uk = np.uint64(k)
                Z[o + uk] = b
                Z[o + nb + uk] = 0.0
                Z[o + nb + nb + uk] = 0.0
            rowb[c] = b
    for a in range(plo[je], phi[je]):
        kk = act[a]
        ov = np.uint64((44 + 3 * tch[kk]) * _NB) + ui
        od = ov + nb
        oa = od + nb
        ta = tta[kk]
        typ = ttype[kk]
        if typ == T_SINE:
            amp = tpar[kk, 0]
            w = tpar[kk, 1]
            ph = tpar[kk, 2]
            T = tpar[kk, 3]
            ri = tpar[kk, 4]
            ro = tpar[kk, 5]
            ag = tc[kk, 0]
            sg = tc[kk, 1]
            cg = tc[kk, 2]
            ng = int(tc[kk, 3])
            for k in range(nr):
                u = (e + k) * dt - ta
                ag, sg, cg, ng = _sincos_step(w * u + ph, ag, sg, cg, ng)
                x0, x1, x2 = _sine_term(u, amp, w, T, ri, ro, sg, cg)
                uk = np.uint64(k)
                Z[ov + uk] += x0
                Z[od + uk] += x1
                Z[oa + uk] += x2
            tc[kk, 0] = ag
            tc[kk, 1] = sg
            tc[kk, 2] = cg
            tc[kk, 3] = ng
        else:                               # T_TRAP or T_STEP
            p0 = tpar[kk, 0]
            p1 = tpar[kk, 1]
            p2 = tpar[kk, 2]
            for k in range(nr):
                x0, x1, x2 = _term(typ, (e + k) * dt - ta, p0, p1, p2)
                uk = np.uint64(k)
                Z[ov + uk] += x0
                Z[od + uk] += x1
                Z[oa + uk] += x2


@njit(cache=True, error_model="numpy")
def _bank_rows(ui, nr, Z):
    """The coordinated turn's tan φ = −V·ψ̇/g0 (``u``) and roll rate −(V̇ψ̇ + Vψ̈)/g0/(1 + u²)
    at columns ui .. ui+nr−1 of the flat block buffer ``Z``, from the channel rows, into
    its rows 17 and 21 (free until :func:`_state_rows`): the divisions vectorised, only
    the arctangent's cache stays in the sequential loop."""
    for k in range(nr):
        uk = ui + np.uint64(k)
        V = Z[_R[44] + uk]
        psd = Z[_R[48] + uk]
        u = -V * psd / G0
        Z[_R[17] + uk] = u
        Z[_R[21] + uk] = -(Z[_R[45] + uk] * psd + V * Z[_R[49] + uk]) / G0 / (1.0 + u * u)


@njit(cache=True)
def _fill_run(Z, o0, nrow, ui, nr):
    """Columns ui+1 .. ui+nr−1 of the nrow rows from offset o0 (a row's, see _R) of the
    flat block buffer ``Z`` set to the value in column ui. (Row offsets and counts from the
    tuples _R, _U, not literal ints: numba compiles a function once per literal argument.)"""
    for r in range(nrow):
        o = o0 + np.uint64(r * _NB) + ui
        v = Z[o]
        for k in range(1, nr):
            Z[o + np.uint64(k)] = v


@njit(cache=True)
def _rows_same(Zi, o0, nrow, ui, nr):
    """Whether each of the nrow rows from offset o0 holds the same bits in columns
    ui .. ui+nr−1 (``Zi``: the block buffer viewed as int64)."""
    d = 0
    for r in range(nrow):
        o = o0 + np.uint64(r * _NB) + ui
        v = Zi[o]
        for k in range(nr):
            d |= Zi[o + np.uint64(k)] ^ v
    return d == 0


@njit(cache=True)
def _add_copy_rows(Z, rx, rd, ra, rs0, rs, ui, nr):
    """Columns ui .. ui+nr−1: row ra = row rx + row rd, rows rs, rs + 1 = rows rs0,
    rs0 + 1 (row offsets, see _R)."""
    one = np.uint64(_NB)
    for k in range(nr):
        uk = ui + np.uint64(k)
        Z[ra + uk] = Z[rx + uk] + Z[rd + uk]
        Z[rs + uk] = Z[rs0 + uk]
        Z[rs + one + uk] = Z[rs0 + one + uk]


@njit(cache=True)
def _sines_run(Z, rx, rs, rn, ui, nr, a, s, c, n):
    """:func:`_sincos_step` along the angles in row rx of the flat block buffer ``Z``,
    columns ui .. ui+nr−1, from the cache (a, s, c, n): sines into row rs, cosines into
    the next row, rotation counts into row rn (rows given by their offsets, see _R).
    Returns the cache after the last column."""
    ox = rx + ui
    os = rs + ui
    oc = os + np.uint64(_NB)
    on = rn + ui
    for k in range(nr):
        uk = np.uint64(k)
        a, s, c, n = _sincos_step(Z[ox + uk], a, s, c, n)
        Z[os + uk] = s
        Z[oc + uk] = c
        Z[on + uk] = n
    return a, s, c, n


@njit(cache=True)
def _offset_sines_run(Z, rx, rd, rs0, rn0, rs, ra, ui, nr, a, s, c, n):
    """As :func:`_sines_run` for the body angle x = (row rx) + (row rd), written to row ra:
    where x equals the path angle (row rx) the cache becomes the path angle's (its sines in
    rows rs0 and the next, its rotation count in row rn0), as in the epoch-by-epoch loop."""
    ox = rx + ui
    od = rd + ui
    os0 = rs0 + ui
    on0 = rn0 + ui
    os = rs + ui
    oa = ra + ui
    one = np.uint64(_NB)
    for k in range(nr):
        uk = np.uint64(k)
        x0 = Z[ox + uk]
        x = x0 + Z[od + uk]
        if x == x0:
            a = x0
            s = Z[os0 + uk]
            c = Z[os0 + one + uk]
            n = int(Z[on0 + uk])
        else:
            a, s, c, n = _sincos_step(x, a, s, c, n)
        Z[os + uk] = s
        Z[os + one + uk] = c
        Z[oa + uk] = x
    return a, s, c, n


@njit(cache=True)
def _state_rows(ui, nr, has_mount, Z):
    """Kinematic state (:func:`_kin`) of columns ui .. ui+nr−1 of the flat block buffer
    ``Z`` into its rows 0..23, from the channel rows (44..) and the rows of sines,
    cosines and angles that :func:`_kinematics` fills (0..20; each is read before its
    column is overwritten). Arithmetic only: vectorised (SIMD); in the scalar loop of the
    sines, the same arithmetic and stores made the kinematics of the benchmark case 18 ns
    per epoch instead of 13."""
    for k in range(nr):
        uk = ui + np.uint64(k)
        thd = Z[_R[51] + uk]
        psd = Z[_R[48] + uk]
        out = _kin(Z[_R[44] + uk], Z[_R[45] + uk], thd, Z[_R[6] + uk], Z[_R[7] + uk],
                   Z[_R[8] + uk], Z[_R[9] + uk], psd, Z[_R[63] + uk], Z[_R[64] + uk],
                   Z[_R[18] + uk], thd + Z[_R[57] + uk], Z[_R[10] + uk], Z[_R[11] + uk],
                   Z[_R[20] + uk], psd + Z[_R[60] + uk], Z[_R[12] + uk], Z[_R[13] + uk],
                   Z[_R[19] + uk], Z[_R[16] + uk], Z[_R[14] + uk], Z[_R[15] + uk], has_mount,
                   (Z[_R[65] + uk], Z[_R[68] + uk], Z[_R[71] + uk], Z[_R[66] + uk],
                    Z[_R[69] + uk], Z[_R[72] + uk], Z[uk], Z[_R[1] + uk], Z[_R[2] + uk],
                    Z[_R[3] + uk], Z[_R[4] + uk], Z[_R[5] + uk]))
        # one store per element: a loop over the tuple would index it at run time (through
        # a stack copy)
        Z[uk] = out[0]
        Z[_R[1] + uk] = out[1]
        Z[_R[2] + uk] = out[2]
        Z[_R[3] + uk] = out[3]
        Z[_R[4] + uk] = out[4]
        Z[_R[5] + uk] = out[5]
        Z[_R[6] + uk] = out[6]
        Z[_R[7] + uk] = out[7]
        Z[_R[8] + uk] = out[8]
        Z[_R[9] + uk] = out[9]
        Z[_R[10] + uk] = out[10]
        Z[_R[11] + uk] = out[11]
        Z[_R[12] + uk] = out[12]
        Z[_R[13] + uk] = out[13]
        Z[_R[14] + uk] = out[14]
        Z[_R[15] + uk] = out[15]
        Z[_R[16] + uk] = out[16]
        Z[_R[17] + uk] = out[17]
        Z[_R[18] + uk] = out[18]
        Z[_R[19] + uk] = out[19]
        Z[_R[20] + uk] = out[20]
        Z[_R[21] + uk] = out[21]
        Z[_R[22] + uk] = out[22]
        Z[_R[23] + uk] = out[23]


@njit(cache=True)
def _path_angles_run(Z, ui, nr, v_th, v_ps, v_p, v_y, rowb, cache):
    """Sines and cosines of the path angles θ, ψ and of the body pitch and yaw over the run
    of ``nr`` columns from ``ui`` of the flat block buffer ``Z`` (see :func:`_kinematics`),
    each angle's :func:`_sincos_step` cache (angle, sine, cosine) in ``cache[0:12]`` (θ, ψ,
    pitch, yaw) and its rotation count in ``cache[17:21]``, read here and written back. An
    angle whose channel has no term over the run (``v_*``) is stepped at its first column
    only and filled into the others."""
    a_th, s_th, c_th, n_th = cache[0], cache[1], cache[2], int(cache[17])
    a_ps, s_ps, c_ps, n_ps = cache[3], cache[4], cache[5], int(cache[18])
    a_p, s_p, c_p, n_p = cache[6], cache[7], cache[8], int(cache[19])
    a_y, s_y, c_y, n_y = cache[9], cache[10], cache[11], int(cache[20])
    # sequential: the sines' and the arctangent's caches, one loop per angle (into rows
    # the state pass reads: sines and cosines 6..15, mount 0..5, roll rate 16, the
    # carrier's Euler angles 18..20; rotation counts of θ and ψ 22, 23 for the body
    # pitch and yaw, which take their path's sines where they equal it)
    n1 = nr if v_th else 1
    a_th, s_th, c_th, n_th = _sines_run(Z, _R[50], _R[6], _R[22], ui, n1,
                                        a_th, s_th, c_th, n_th)
    _fill_run(Z, _R[6], _U[2], ui, nr - n1 + 1)
    _fill_run(Z, _R[22], _U[1], ui, nr - n1 + 1)
    n1 = nr if v_ps else 1
    a_ps, s_ps, c_ps, n_ps = _sines_run(Z, _R[47], _R[8], _R[23], ui, n1,
                                        a_ps, s_ps, c_ps, n_ps)
    _fill_run(Z, _R[8], _U[2], ui, nr - n1 + 1)
    _fill_run(Z, _R[23], _U[1], ui, nr - n1 + 1)
    # a body pitch or yaw offset that is 0 over the run: x + 0 == x, so the body angle
    # takes its path angle's sines and cache at every epoch (rows copied, vectorised)
    if v_p and rowb[CH_PITCH] == 0.0:
        _add_copy_rows(Z, _R[50], _R[56], _R[18], _R[6], _R[10], ui, nr)
        a_p, s_p, c_p, n_p = a_th, s_th, c_th, n_th
    else:
        n1 = nr if v_p else 1
        a_p, s_p, c_p, n_p = _offset_sines_run(Z, _R[50], _R[56], _R[6], _R[22], _R[10],
                                               _R[18], ui, n1, a_p, s_p, c_p, n_p)
        _fill_run(Z, _R[10], _U[2], ui, nr - n1 + 1)
        _fill_run(Z, _R[18], _U[1], ui, nr - n1 + 1)
    if v_y and rowb[CH_YAW] == 0.0:
        _add_copy_rows(Z, _R[47], _R[59], _R[20], _R[8], _R[12], ui, nr)
        a_y, s_y, c_y, n_y = a_ps, s_ps, c_ps, n_ps
    else:
        n1 = nr if v_y else 1
        a_y, s_y, c_y, n_y = _offset_sines_run(Z, _R[47], _R[59], _R[8], _R[23], _R[12],
                                               _R[20], ui, n1, a_y, s_y, c_y, n_y)
        _fill_run(Z, _R[12], _U[2], ui, nr - n1 + 1)
        _fill_run(Z, _R[20], _U[1], ui, nr - n1 + 1)
    cache[0], cache[1], cache[2], cache[17] = a_th, s_th, c_th, n_th
    cache[3], cache[4], cache[5], cache[18] = a_ps, s_ps, c_ps, n_ps
    cache[6], cache[7], cache[8], cache[19] = a_p, s_p, c_p, n_p
    cache[9], cache[10], cache[11], cache[20] = a_y, s_y, c_y, n_y


@njit(cache=True)
def _roll_run(Z, ui, nr, coord, v_r, cache):
    """The roll over the run (see :func:`_path_angles_run`): the channel's roll plus, in a
    coordinated turn, the bank angle's arctangent (cached on its argument in
    ``cache[15:17]``), stepped from its cache ``cache[12:15]``, ``cache[21]``."""
    a_r, s_r, c_r, n_r = cache[12], cache[13], cache[14], int(cache[21])
    a_u, t_u = cache[15], cache[16]
    n1 = nr if v_r else 1
    for k in range(n1):
        uk = ui + np.uint64(k)
        roll = Z[_R[53] + uk]
        rolld = Z[_R[54] + uk]
        if coord:
            u = Z[_R[17] + uk]
            if u != a_u:
                a_u = u
                t_u = math.atan(u)
            roll += t_u
            rolld += Z[_R[21] + uk]
        a_r, s_r, c_r, n_r = _sincos_step(roll, a_r, s_r, c_r, n_r)
        Z[_R[14] + uk] = s_r
        Z[_R[15] + uk] = c_r
        Z[_R[16] + uk] = rolld
        Z[_R[19] + uk] = roll
    _fill_run(Z, _R[14], _U[3], ui, nr - n1 + 1)
    _fill_run(Z, _R[19], _U[1], ui, nr - n1 + 1)
    cache[12], cache[13], cache[14], cache[21] = a_r, s_r, c_r, n_r
    cache[15], cache[16] = a_u, t_u


@njit(cache=True)
def _mount_run(Z, ui, nr, v_m, cache):
    """Exact sines and cosines of the mount angles over the run, each reused while its
    angle keeps its bits (caches in ``cache[22:31]``)."""
    a_mp, s_mp, c_mp = cache[22], cache[23], cache[24]
    a_mr, s_mr, c_mr = cache[25], cache[26], cache[27]
    a_my, s_my, c_my = cache[28], cache[29], cache[30]
    n1 = nr if v_m else 1
    for k in range(n1):
        # exact sines of the mount angles, reused while an angle stays the same
        uk = ui + np.uint64(k)
        mp = Z[_R[65] + uk]
        if not _same(mp, a_mp):
            a_mp = mp
            s_mp = math.sin(mp)
            c_mp = math.cos(mp)
        mr = Z[_R[68] + uk]
        if not _same(mr, a_mr):
            a_mr = mr
            s_mr = math.sin(mr)
            c_mr = math.cos(mr)
        my = Z[_R[71] + uk]
        if not _same(my, a_my):
            a_my = my
            s_my = math.sin(my)
            c_my = math.cos(my)
        Z[uk] = s_mp
        Z[_R[1] + uk] = c_mp
        Z[_R[2] + uk] = s_mr
        Z[_R[3] + uk] = c_mr
        Z[_R[4] + uk] = s_my
        Z[_R[5] + uk] = c_my
    _fill_run(Z, _R[0], _U[6], ui, nr - n1 + 1)
    cache[22], cache[23], cache[24] = a_mp, s_mp, c_mp
    cache[25], cache[26], cache[27] = a_mr, s_mr, c_mr
    cache[28], cache[29], cache[30] = a_my, s_my, c_my


@njit(cache=True)
def _kinematics(e0, e1, i0, dt, has_mount, bp, base, flag, plo, phi, act, ttype, tch, tta,
                tpar, Z, cache, tc, rowb, je):
    """Kinematic state of epochs e0..e1−1 (t_e = e·dt) into columns i0, i0+1, ... of
    rows 0..23 of the flat block buffer ``Z`` (see :func:`_earth_block`): v(3) v̇(3)
    C_b^n(9) ω_nb^b(3) carrier att(3) mount(3). Returns the piece of the last epoch (``je``
    is that of the epoch before e0).

    The epochs go in runs within one piece: the channels of a run by :func:`_channel_rows`
    (rows 44.. of ``Z``), then epoch by epoch in scalar code the bank angle and the sines
    and cosines, then the state of the whole run by :func:`_state_rows`. Sines and cosines
    of the Euler angles and of the sine terms' arguments follow their angles by small
    rotations (:func:`_sincos_step`; exact sin/cos at least every _ROT_RUN epochs, so they
    stay within ~1e-15 of it), and are reused, like the bank angle's arctangent and the
    mount angles' sines, while the argument is unchanged; the caches live in ``cache``,
    ``tc`` (per term) and ``rowb`` between calls (the angles' slots of ``cache``: see
    :func:`_path_angles_run`, :func:`_roll_run`, :func:`_mount_run`). The epochs of a piece with no
    active term repeat the previous column: one vectorised fill per row for the whole run
    (copied epoch by epoch and column by column, such epochs cost half as much as computed
    ones). The stores go to unsigned flat indices with compile-time row offsets: through a
    2-D array, each needed a row pointer kept on the stack and a negative-index wraparound.
    """
    nbp = bp.shape[0]
    kfrom = int(cache[31])
    Zi = Z.view(np.int64)
    e = e0
    while e < e1:
        i = i0 + e - e0
        ui = np.uint64(i)
        te = e * dt
        jprev = je
        while je + 1 < nbp and te >= bp[je + 1]:
            je += 1
        const = plo[je] == phi[je] and flag[je] == 0
        er = e1                             # the run: epochs e .. er−1 of piece je
        if je + 1 < nbp and (e1 - 1) * dt >= bp[je + 1]:
            # (else all the epochs left lie before the next breakpoint: k·dt grows with k)
            er = e + 1
            while er < e1 and er * dt < bp[je + 1]:
                er += 1
        if const and e > 0 and je == jprev:
            # a piece with no active term: its epochs repeat the previous column, filled
            # row by row (vectorised) to the end of the rows (columns after the run are
            # written again by later runs, if any). Columns kfrom.. hold one state in
            # every row (_synth's shift of the halo keeps that: it copies columns of that
            # range, or to columns before it), so the next blocks of the same piece find
            # them filled already (the fill is store-bound: 3.6 ns per epoch)
            if kfrom > i - 1:
                for q in range(24):
                    rq = _R[q] + ui
                    v = Z[rq - np.uint64(1)]
                    for c in range(np.uint64(_NB - i)):
                        Z[rq + c] = v
                kfrom = i - 1
            e = er
            continue
        if const:
            er = e + 1                      # the first epoch of such a piece; the next ones copy it
        nr = er - e
        kfrom = _NB
        _channel_rows(e, nr, ui, dt, je, base, plo, phi, act, ttype, tch, tta, tpar, tc, rowb, Z)
        coord = flag[je] != 0
        # the angles whose channels have no term keep their value over the run: their
        # sines are those of its first epoch, filled into the other columns after the loop
        v_th = math.isnan(rowb[CH_THETA])
        v_ps = math.isnan(rowb[CH_PSI])
        v_p = v_th or math.isnan(rowb[CH_PITCH])
        v_y = v_ps or math.isnan(rowb[CH_YAW])
        v_r = coord or math.isnan(rowb[CH_ROLL])
        v_m = has_mount and (math.isnan(rowb[CH_MP]) or math.isnan(rowb[CH_MR])
                             or math.isnan(rowb[CH_MY]))
        if coord:
            if _rows_same(Zi, _R[44], _U[2], ui, nr) and _rows_same(Zi, _R[48], _U[2], ui, nr):
                # V, V̇, ψ̇, ψ̈ the same bits over the run (a steady turn): so are the bank
                # angle and its rate term, and the roll too if its channel has no term
                _bank_rows(ui, _ONE, Z)
                _fill_run(Z, _R[17], _U[1], ui, nr)
                _fill_run(Z, _R[21], _U[1], ui, nr)
                v_r = math.isnan(rowb[CH_ROLL])
            else:
                _bank_rows(ui, nr, Z)
        # sequential, one loop per angle, each from and back to its cache slots
        _path_angles_run(Z, ui, nr, v_th, v_ps, v_p, v_y, rowb, cache)
        _roll_run(Z, ui, nr, coord, v_r, cache)
        if has_mount:
            _mount_run(Z, ui, nr, v_m, cache)
        _state_rows(ui, nr, has_mount, Z)
        e = er
    cache[31] = kfrom
    return je


@njit(cache=True, error_model="numpy")
def _earth_block(i0, i1, ib, dt, lat, h, Z):
    """Earth terms of columns i0..i1−1 of the kinematics rows of Z into its rows 24..32:
    ω_ib^b, f^b and the position rates (L̇, λ̇, ḣ), at positions predicted from the exact
    position (lat, h) of column ib ≤ i0. ``Z`` is the flat (row-major) view of the block
    buffer of _synth: _NROW rows of _NB columns.

    The prediction integrates the velocities by trapezoids with the Euler–Maclaurin end
    correction (error O(dt⁴)) and turns the north distance into latitude with R_M + h to
    first order in the height and latitude changes. Over one block (~0.7 s at 100 Hz,
    ~7 s at 10 Hz) that is good to well below a micrometre; without the latitude term of
    R_M the ~0.1 mm error of a 50 Hz block showed as 3e-14 m/s in Δv (test_trajectory).
    The first loop is a running sum; the others have no branch and no call, and are
    vectorised (SIMD) — which is why the synthesis works in blocks. They are three (the
    predicted position into rows 33, 34, 24; :func:`_earth_radii` into rows 25..28;
    :func:`_earth_terms`, each reading a column before writing it): in one loop, the chain
    of the prediction, the square root, the division and the terms made it wait on latency,
    7.4 ns per epoch instead of 5.4. They index one flat array with unsigned indices and
    compile-time row offsets: signed indices make numba emit a negative-index wraparound,
    and separate row arrays need more run-time alias checks than LLVM allows; either way
    they would stay scalar.
    """
    sb = math.sin(lat)
    cb = math.cos(lat)
    q = 1.0 - earth.E2 * sb * sb
    rm = earth.A * (1.0 - earth.E2) / q ** 1.5
    irm = 1.0 / (rm + h)
    # d ln(1/(R_M + h))/dL = −kk: the north distance spans a latitude range over the block
    kk = rm * irm * 3.0 * earth.E2 * sb * cb / q
    c6 = dt / 6.0
    dl = 0.0
    dh = 0.0
    one = np.uint64(1)
    ub = np.uint64(ib)
    for j in range(i1 - ib):
        i = ub + np.uint64(j)
        if j > 0:
            dl += Z[_R[1] + i - one] + Z[_R[1] + i]
            dh += Z[_R[2] + i - one] + Z[_R[2] + i]
        Z[_R[33] + i] = dl - c6 * (Z[_R[4] + i] - Z[_R[4] + ub])
        Z[_R[34] + i] = dh - c6 * (Z[_R[5] + i] - Z[_R[5] + ub])
    hdt = 0.5 * dt
    u0 = np.uint64(i0)
    for j in range(i1 - i0):
        i = u0 + np.uint64(j)
        dhp = hdt * Z[_R[34] + i]
        # L − L_b = ∫ v_N/(R_M + h) dt, to first order in Δh and in (L − L_b) of R_M:
        # 1/(R_M + h_b + Δh/2) and ∫ (1 − kk·δL) dδL = d0 − kk·d0²/2
        d0 = hdt * Z[_R[33] + i] * irm * (1.0 - 0.5 * dhp * irm)
        d = d0 * (1.0 - 0.5 * kk * d0)
        d2 = 0.5 * d * d
        d3 = d * (1.0 - d2 * (1.0 / 3.0))
        Z[_R[33] + i] = sb * (1.0 - d2) + cb * d3
        Z[_R[34] + i] = cb * (1.0 - d2) - sb * d3
        Z[_R[24] + i] = h + dhp
    for j in range(i1 - i0):
        i = u0 + np.uint64(j)
        rm_, rn_, rc_, g_ = _earth_radii(Z[_R[33] + i], Z[_R[34] + i], Z[_R[24] + i])
        Z[_R[25] + i] = rm_
        Z[_R[26] + i] = rn_
        Z[_R[27] + i] = rc_
        Z[_R[28] + i] = g_
    for j in range(i1 - i0):
        i = u0 + np.uint64(j)
        w = _earth_terms(Z[_R[33] + i], Z[_R[34] + i], Z[_R[25] + i], Z[_R[26] + i],
                         Z[_R[27] + i], Z[_R[28] + i], Z[i], Z[_R[1] + i], Z[_R[2] + i],
                         Z[_R[3] + i], Z[_R[4] + i], Z[_R[5] + i], Z[_R[6] + i],
                         Z[_R[7] + i], Z[_R[8] + i], Z[_R[9] + i], Z[_R[10] + i],
                         Z[_R[11] + i], Z[_R[12] + i], Z[_R[13] + i], Z[_R[14] + i],
                         Z[_R[15] + i], Z[_R[16] + i], Z[_R[17] + i])
        Z[_R[24] + i] = w[0]
        Z[_R[25] + i] = w[1]
        Z[_R[26] + i] = w[2]
        Z[_R[27] + i] = w[3]
        Z[_R[28] + i] = w[4]
        Z[_R[29] + i] = w[5]
        Z[_R[30] + i] = w[6]
        Z[_R[31] + i] = w[7]
        Z[_R[32] + i] = w[8]


@njit(cache=True)
def _stencil_block(nk, off, swd, Z):
    """Z[35 + q, k] = Σ_j swd_j·Z[24 + q, off + k + j], q = 0..8, k < nk: the stencil
    integrals of ω_ib^b, f^b and the position rates (rows 24..32 of the flat block buffer
    ``Z``, see :func:`_earth_block`) over nk consecutive intervals (symmetric weights swd =
    dt·sw[:m/2], paired; vectorised over k).

    Each sum is one expression in the order of adding the pairs one after another to a
    zero (the leading 0 turns a −0 sum into +0, as such a loop does), for the 4-, 6- and
    8-point stencils written out; flat indices as in :func:`_earth_block`: with row arrays
    and a store and reload of each sum per pair, this took twice the time.
    """
    mh = swd.shape[0]
    m = 2 * mh
    uo = np.uint64(off)
    one = np.uint64(1)
    for q in range(9):
        rw = _R[24] + np.uint64(q * _NB) + uo
        rs = _R[35] + np.uint64(q * _NB)
        if mh == 2:
            w0 = swd[0]
            w1 = swd[1]
            for k in range(nk):
                uk = np.uint64(k)
                i = rw + uk
                Z[rs + uk] = (0.0 + w0 * (Z[i] + Z[i + _U[3]])) + w1 * (Z[i + one] + Z[i + _U[2]])
        elif mh == 3:
            w0 = swd[0]
            w1 = swd[1]
            w2 = swd[2]
            for k in range(nk):
                uk = np.uint64(k)
                i = rw + uk
                Z[rs + uk] = (((0.0 + w0 * (Z[i] + Z[i + _U[5]])) + w1 * (Z[i + one] + Z[i + _U[4]]))
                              + w2 * (Z[i + _U[2]] + Z[i + _U[3]]))
        elif mh == 4:
            w0 = swd[0]
            w1 = swd[1]
            w2 = swd[2]
            w3 = swd[3]
            for k in range(nk):
                uk = np.uint64(k)
                i = rw + uk
                Z[rs + uk] = (((((0.0 + w0 * (Z[i] + Z[i + _U[7]])) + w1 * (Z[i + one] + Z[i + _U[6]]))
                                + w2 * (Z[i + _U[2]] + Z[i + _U[5]])) + w3 * (Z[i + _U[3]] + Z[i + _U[4]])))
        else:
            for k in range(nk):
                uk = np.uint64(k)
                i = rw + uk
                acc = 0.0
                for jj in range(mh):
                    acc += swd[jj] * (Z[i + np.uint64(jj)] + Z[i + np.uint64(m - 1 - jj)])
                Z[rs + uk] = acc


@njit(cache=True)
def _synth(n, dt, out_every, sw, lo_off, cn, wn, amat, has_mount,
           bp, base, flag, plo, phi, act, ttype, tch, tta, tpar,
           lat, lon, h, t0, dth, dvl, t_imu, olat, olon, oh, t_nav, vel, att, atti, mnt):
    """Increments, position and truth for n IMU intervals of length dt.

    Every epoch t_e = e·dt is evaluated once. With a stencil (``sw`` of length m > 0,
    symmetric, first point at offset ``lo_off``), the increment over [t_k, t_k+1] is
    dt·Σ sw_j·W(t_{k+lo_off+j}) — the exact integral of the interpolating polynomial through
    m epochs — whenever no breakpoint of the profiles lies strictly inside the stencil;
    otherwise (and always when m = 0) the interval is split at the breakpoints and
    integrated with the node rule (cn, wn) and collocation matrix amat.

    The intervals go in blocks of ``_BLOCK``: kinematics of the block's epochs (scalar),
    their Earth terms at predicted positions and the stencil sums (both vectorised), then
    a sequential pass that adds the position increments — or, near breakpoints, does the
    exact node rule from the exact position — and writes the outputs. Columns of the
    buffers K, W hold epochs K0+lo .. K0+B−1+hi of the block starting at interval K0.
    """
    m = sw.shape[0]
    lo = lo_off if (m > 0 and lo_off < 0) else 0
    hi = lo_off + m - 1 if m > 0 else 1
    if hi < 1:
        hi = 1
    B = _BLOCK
    Z = np.zeros((_NROW, _NB))
    Zf = Z.reshape(_NROW * _NB)
    K = Z[:24]
    W = Z[24:33]
    S = Z[35:44]                           # the stencil sums of the block's intervals
    cache = np.full(32, math.nan)
    cache[17:22] = 0.0
    cache[31] = _NB
    tc = np.zeros((ttype.shape[0], 4))     # per term: argument, sin, cos, rotations
    tc[:, 0] = math.nan
    rowb = np.full(NCH, math.nan)          # see _channel_rows
    ns = cn.shape[0]
    SN = np.zeros((ns, 24))
    WN = np.zeros((ns, 6))
    FN = np.zeros((ns, 3))
    val = np.zeros(NCH)
    d1 = np.zeros(NCH)
    d2 = np.zeros(NCH)
    mh = m // 2
    swd = np.empty(mh)
    for jj in range(mh):
        swd[jj] = sw[jj] * dt
    nbp = bp.shape[0]
    tol = 1e-9 * dt
    je = np.int64(0)  # piece of the newest evaluated epoch (typed, not a literal: one compiled _kinematics)
    jn = np.int64(0)  # piece of the newest fallback node
    bi = 1          # first breakpoint after the current fallback sub-interval start
    bq = 1          # first breakpoint after the stencil start
    chk = 0.0
    tstep = dt * out_every
    oc = 0          # samples since the last truth epoch
    mo = 0          # index of the last truth epoch
    ib = -lo        # column of the block's first epoch K0
    for K0 in range(0, n, B):
        nk = min(B, n - K0)
        if K0 == 0:
            je = _kinematics(K0, nk + hi, ib, dt, has_mount, bp, base, flag, plo, phi, act,
                             ttype, tch, tta, tpar, Zf, cache, tc, rowb, je)
            enew = ib
        else:
            for q in range(24):             # halo: the epochs K0+lo .. K0+hi−1 shift left
                for c in range(hi - lo):
                    K[q, c] = K[q, B + c]
            for q in range(9):
                for c in range(hi - lo):
                    W[q, c] = W[q, B + c]
            je = _kinematics(K0 + hi, K0 + nk + hi, hi - lo, dt, has_mount, bp, base, flag,
                             plo, phi, act, ttype, tch, tta, tpar, Zf, cache, tc, rowb, je)
            enew = hi - lo
        if m > 0:
            _earth_block(enew, ib + nk + hi, ib, dt, lat, h, Zf)
            _stencil_block(nk, lo_off - lo, swd, Zf)
        if K0 == 0:
            t_nav[0] = t0
            olat[0] = lat
            olon[0] = lon
            oh[0] = h
            vel[0, 0] = K[0, ib]
            vel[0, 1] = K[1, ib]
            vel[0, 2] = K[2, ib]
            att[0, 0] = K[18, ib]
            att[0, 1] = wrap_pi_s(K[19, ib])
            att[0, 2] = wrap_pi_s(K[20, ib])
            if has_mount:
                atti[0, 0] = _asin1(K[13, ib])
                atti[0, 1] = math.atan2(-K[12, ib], K[14, ib])
                atti[0, 2] = math.atan2(-K[7, ib], K[10, ib])
                mnt[0, 0] = K[21, ib]
                mnt[0, 1] = wrap_pi_s(K[22, ib])
                mnt[0, 2] = wrap_pi_s(K[23, ib])
        # the whole block by stencils when the first breakpoint after its first stencil's
        # start lies beyond its last stencil's end: then the test below would find the same
        # breakpoint and pass for every interval of the block, so it is made once
        clear = False
        if m > 0 and K0 + lo_off >= 0:
            t_lo = (K0 + lo_off) * dt
            while bq < nbp and bp[bq] <= t_lo + tol:
                bq += 1
            clear = not (bq < nbp and bp[bq] < (K0 + nk - 1 + lo_off + m - 1) * dt - tol)
        if clear and out_every == 1 and not has_mount:
            # the common case (every interval by its stencil, the truth at every epoch, no
            # mount) as the loop below does it, in three passes without its per-interval
            # tests: the position sums, the increments, the rest of the truth
            for ik in range(nk):
                k = K0 + ik
                lat += S[6, ik]
                lon += S[7, ik]
                h += S[8, ik]
                olat[k + 1] = lat
                olon[k + 1] = lon
                oh[k + 1] = h
            for ik in range(nk):
                k = K0 + ik
                th0 = S[0, ik]
                th1 = S[1, ik]
                th2 = S[2, ik]
                v0 = S[3, ik]
                v1 = S[4, ik]
                v2 = S[5, ik]
                dth[k, 0] = th0
                dth[k, 1] = th1
                dth[k, 2] = th2
                dvl[k, 0] = v0
                dvl[k, 1] = v1
                dvl[k, 2] = v2
                chk += th0 + th1 + th2 + v0 + v1 + v2
            for ik in range(nk):
                k = K0 + ik
                c1 = ib + ik + 1
                t_nav[k + 1] = (k + 1) * tstep + t0
                vel[k + 1, 0] = K[0, c1]
                vel[k + 1, 1] = K[1, c1]
                vel[k + 1, 2] = K[2, c1]
                att[k + 1, 0] = K[18, c1]
                att[k + 1, 1] = wrap_pi_s(K[19, c1])
                att[k + 1, 2] = wrap_pi_s(K[20, c1])
            mo += nk                        # oc stays 0: out_every is 1
            continue
        for ik in range(nk):
            k = K0 + ik
            c1 = ib + ik + 1                # column of epoch k + 1
            use_stencil = clear
            if m > 0 and not clear:
                t_lo = (k + lo_off) * dt
                t_hi = (k + lo_off + m - 1) * dt
                while bq < nbp and bp[bq] <= t_lo + tol:
                    bq += 1
                # t = 0 is always a breakpoint, so stencils reaching before the start fall back
                use_stencil = k + lo_off >= 0 and not (bq < nbp and bp[bq] < t_hi - tol)
            if use_stencil:
                th0 = S[0, ik]
                th1 = S[1, ik]
                th2 = S[2, ik]
                v0 = S[3, ik]
                v1 = S[4, ik]
                v2 = S[5, ik]
                lat += S[6, ik]
                lon += S[7, ik]
                h += S[8, ik]
            else:
                th0 = 0.0
                th1 = 0.0
                th2 = 0.0
                v0 = 0.0
                v1 = 0.0
                v2 = 0.0
                a = k * dt
                b = (k + 1) * dt
                s0 = a
                while True:
                    while bi < nbp and bp[bi] <= s0 + tol:
                        bi += 1
                    s1 = b
                    hh = b - s0
                    if s0 == a:
                        hh = dt                     # b - a is off by an ulp of t
                    if bi < nbp and bp[bi] < b - tol:
                        s1 = bp[bi]
                        hh = s1 - s0
                    for i in range(ns):
                        tt = s0 + cn[i] * hh
                        jn = _advance(tt, jn, bp)
                        _state(tt, jn, has_mount, flag, base, plo, phi, act, ttype, tch, tta,
                               tpar, val, d1, d2, SN, i)
                    sl0 = math.sin(lat)
                    cl0 = math.cos(lat)
                    rsq = 1.0 / math.sqrt(1.0 - earth.E2 * sl0 * sl0)
                    irm = 1.0 / (earth.A * (1.0 - earth.E2) * rsq * rsq * rsq + h)
                    for i in range(ns):
                        pl = 0.0
                        ph = 0.0
                        for q in range(ns):
                            aa = amat[i, q]
                            pl += aa * SN[q, 1]
                            ph += aa * SN[q, 2]
                        d = hh * pl * irm           # latitude offset of the node
                        d2h = 0.5 * d * d
                        _earth_call(SN, i, sl0 * (1.0 - d2h) + cl0 * d,
                                    cl0 * (1.0 - d2h) - sl0 * d, h + hh * ph, WN, FN)
                    dl = 0.0
                    do = 0.0
                    dh = 0.0
                    for i in range(ns):
                        wq = wn[i] * hh
                        dl += wq * FN[i, 0]
                        do += wq * FN[i, 1]
                        dh += wq * FN[i, 2]
                        th0 += wq * WN[i, 0]
                        th1 += wq * WN[i, 1]
                        th2 += wq * WN[i, 2]
                        v0 += wq * WN[i, 3]
                        v1 += wq * WN[i, 4]
                        v2 += wq * WN[i, 5]
                    lat += dl
                    lon += do
                    h += dh
                    if s1 >= b - tol:
                        break
                    s0 = s1
            dth[k, 0] = th0
            dth[k, 1] = th1
            dth[k, 2] = th2
            dvl[k, 0] = v0
            dvl[k, 1] = v1
            dvl[k, 2] = v2
            if out_every != 1:                  # else t_imu is t_nav[1:], written below
                t_imu[k] = (k + 1) * dt + t0
            chk += th0 + th1 + th2 + v0 + v1 + v2     # NaN/inf stay: one check at the end
            oc += 1
            if oc == out_every:             # (k + 1) % out_every == 0 without a division
                oc = 0
                mo += 1
                t_nav[mo] = mo * tstep + t0
                olat[mo] = lat
                olon[mo] = lon
                oh[mo] = h
                vel[mo, 0] = K[0, c1]
                vel[mo, 1] = K[1, c1]
                vel[mo, 2] = K[2, c1]
                att[mo, 0] = K[18, c1]
                att[mo, 1] = wrap_pi_s(K[19, c1])
                att[mo, 2] = wrap_pi_s(K[20, c1])
                if has_mount:
                    atti[mo, 0] = _asin1(K[13, c1])
                    atti[mo, 1] = math.atan2(-K[12, c1], K[14, c1])
                    atti[mo, 2] = math.atan2(-K[7, c1], K[10, c1])
            if has_mount:
                mnt[k + 1, 0] = K[21, c1]
                mnt[k + 1, 1] = wrap_pi_s(K[22, c1])
                mnt[k + 1, 2] = wrap_pi_s(K[23, c1])
    return chk


def _stencil(m: int):
    """Weights of ∫_0^1 p(x) dx for the interpolating polynomial through x = lo..lo+m−1
    (lo = −(m//2 − 1)): a centred m-point rule of order m for one interval. Computed in
    exact rational arithmetic (m = 6: [11, −93, 802, 802, −93, 11]/1440)."""
    from fractions import Fraction
    lo = -(m // 2 - 1)
    x = [Fraction(lo + i) for i in range(m)]
    # solve sum_j w_j x_j^p = ∫_0^1 x^p dx = 1/(p+1), p = 0..m-1 (Gauss-Jordan, exact)
    M = [[x[j] ** p for j in range(m)] + [Fraction(1, p + 1)] for p in range(m)]
    for c in range(m):
        piv = next(r for r in range(c, m) if M[r][c] != 0)
        M[c], M[piv] = M[piv], M[c]
        M[c] = [v / M[c][c] for v in M[c]]
        for r in range(m):
            if r != c and M[r][c] != 0:
                f = M[r][c]
                M[r] = [a - f * b for a, b in zip(M[r], M[c])]
    return np.array([float(M[j][m]) for j in range(m)]), lo
