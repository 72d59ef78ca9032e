"""Strapdown mechanization in the ENU frame (compiled hot loop).

Frames and conventions (docs/architecture.md): navigation frame n = ENU, body frame b = RFU,
attitude quaternion ``q`` = scalar-first Hamilton quaternion of ``C_b^n``. SI units:
rad, m, s. IMU input is body-frame increments Δθ [rad] and Δv [m/s] per sample.

Algorithm (one *update* consumes ``nsub`` samples, update interval ``T = nsub·dt``)
-----------------------------------------------------------------------------------
1. Sensor compensation: ``Δθ_i -= gyro_bias·dt``, ``Δv_i -= accel_bias·dt``.
2. Coning and sculling, optimal polynomial form for N = ``nsub`` subsamples::

       φ   = Σθ_i + (Σ_{i<N} c_i θ_i) × θ_N                         (coning)
       Δv' = ΣΔv_i + ½ Σθ×ΣΔv + ⅙ Σθ×(Σθ×ΣΔv)                      (rotation)
             + (Σ_{i<N} c_i θ_i) × Δv_N + (Σ_{i<N} c_i Δv_i) × θ_N     (sculling)

   with ``c`` from :data:`CONING_COEFFS` (N = 2: 2/3; N = 3: 9/20, 27/20; ...). For
   N = 1 the "one-plus-previous-sample" algorithm is used: coning ``θ_{k-1}×θ_k/12``,
   sculling ``(θ_{k-1}×Δv_k + Δv_{k-1}×θ_k)/12``. The coefficients make the coning term
   exact through order (ΩT)^(2N+1) for classic coning motion (Ignagni, "Efficient class of
   optimized coning compensation algorithms", J. Guid. Control Dyn. 19(2), 1996; in the
   "Σ c_i θ_i × θ_N" form of Yan Gongmin, *Strapdown Inertial Navigation Algorithm and
   Integrated Navigation Principles* (2019), §2.3, and PSINS ``cnscl.m``); the sculling
   coefficients equal the coning ones by the coning/sculling equivalence (Savage,
   "Strapdown inertial navigation integration algorithm design, part 2: velocity and
   position algorithms", JGCD 21(2), 1998; Roscoe, "Equivalency between strapdown
   inertial navigation coning and sculling integrals/algorithms", JGCD 24(2), 2001).
   ``tests/test_strapdown.py`` re-derives every coefficient with exact fractions. The
   ⅙ term completes the rotation compensation to third order for constant rates
   (it is the next term of ``∫exp(ωt×)f dt``).

   Manoeuvres: the coefficients are optimised for coning, not for changing rates. All N
   are exact for a linearly varying rate (``ω0×α T³/12``), but only N = 2 also for a
   quadratically varying one: N = 3, 4, 5 leave ``m_N·h⁴·ω0×β`` per update
   (``ω = ω0 + αt + βt²``, sample interval h; m_N = 27/20, 204/35, 2075/126). Through
   manoeuvre onsets (roll-in of a turn, rate ramps) nsub = 3..5 are therefore *less*
   accurate than nsub = 2: in a 1.5 °/s coordinated-turn roll-in the attitude error
   grows 3.2× (N = 4) and 7.2× (N = 5) over N = 3, as (m_N/N)/(m_3/3) predicts, and
   N = 2 is 30× better than N = 3 (tests/test_strapdown.py). Prefer nsub = 2 unless the
   motion is dominated by vibration-induced coning.
3. Mid-interval extrapolation (PSINS-like, but using this update's own specific force):
   ``v_½ = v + ½(C_b^n Δv' + g_cc,prev T)``, ``pos_½ = pos + M_pv (v + v_½)/2 · T/2``;
   the Earth model (radii, normal gravity, ω_ie, ω_en) is evaluated once, at (pos_½, v_½).
4. Velocity: ``v⁺ = v + C_b^n Δv' − ½ (ω_in T)×(C_b^n Δv') + g_cc T`` with
   ``g_cc = [0, 0, −g] − (2ω_ie + ω_en)×v_½``.
5. Position by the trapezoid: ``lat⁺ = lat + ½(v_N + v_N⁺)T/(R_M+h)``,
   ``lon⁺ = lon + ½(v_E + v_E⁺)T/((R_N+h)cos L)``, ``h⁺ = h + ½(v_U + v_U⁺)T`` (radii at
   mid-interval).
6. Attitude: ``q⁺ = q(−ω_in T) ⊗ q ⊗ q(φ)`` (exact rotation-vector quaternions), normalised.

Vertical channel: ``"free"`` (pure inertial, unstable), ``"hold"`` (``h`` and ``v_U`` set to an
external height series and its derivative; the mid-interval ``v_U`` used in the Coriolis
term is the height difference over the update divided by T), ``"damped"`` (baro-style
loop to an external reference height, second or third order; see :class:`VerticalDamping`).

Public API
----------
:func:`navigate` runs a whole :class:`~sinslab.core.records.ImuRecord` and returns a
:class:`~sinslab.core.records.NavSeries`. The low-level steppable API for filters is
:func:`initial_state_array`, :func:`step` (advance a state array in place over a chunk,
compiled, no per-sample Python), :func:`correct` (feedback correction) and
:func:`state_to_navstate`.

State array layout (float64, length :data:`NSTATE`)::

    [q0, q1, q2, q3, vE, vN, vU, lat, lon, h,  gccE, gccN, gccU, inv_rm, inv_rnc,
     damp_int, pθx, pθy, pθz, pΔvx, pΔvy, pΔvz, has_prev, ωE, ωN, ωU]

The first ten entries are the navigation state (units rad, m/s, m). The rest is auxiliary
memory of the integrator (last gravity+Coriolis acceleration [m/s^2], last 1/(R_M+h) and
1/((R_N+h)cos L) [1/m], damping-loop integrator [m/s^2], previous sample for N = 1, last
ω_in^n [rad/s]); a
length-10 array is also accepted by :func:`step` (auxiliaries are then rebuilt).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from sinslab.core.attitude import (euler2q_s, euler_to_quat, q2dcm_s, q2euler_s, qmul_s, quat_mul, rotvec_to_quat,
                                   rv2q_s)
from sinslab.core.earth import (WIE, check_latitude, gravity, gravity_s, gravity_sin_s, radii, radii_s,
                                radii_sin_s)
from sinslab.core.records import ImuRecord, NavSeries, NavState
from sinslab.core.errors import InputError

__all__ = [
    "navigate", "initial_state_array", "step", "correct", "correct_rows", "with_errors",
    "state_to_navstate", "rows_to_series",
    "VerticalDamping", "HeldHeight", "CONING_COEFFS", "NSTATE", "NAV", "VERTICAL_MODES", "step_chunk",
]

#: Length of the full state array.
NSTATE = 26
#: Number of navigation entries at the front of the state array.
NAV = 10
_I_GCC, _I_IRM, _I_IRN, _I_DINT, _I_PREV, _I_HASPREV = 10, 13, 14, 15, 16, 22

#: Vertical channel modes accepted by :func:`navigate` and :func:`step`.
VERTICAL_MODES = ("free", "hold", "damped")
_VMODE = {"free": 0, "hold": 1, "damped": 2}

#: Coning/sculling coefficients c_i of ``(Σ_{i<N} c_i θ_i) × θ_N`` (row N−1 for N = 2..5;
#: row 0 holds the 1/12 of the one-plus-previous algorithm used for N = 1).
CONING_COEFFS = np.array([
    [1.0 / 12.0, 0.0, 0.0, 0.0],
    [2.0 / 3.0, 0.0, 0.0, 0.0],
    [9.0 / 20.0, 27.0 / 20.0, 0.0, 0.0],
    [54.0 / 105.0, 92.0 / 105.0, 214.0 / 105.0, 0.0],
    [250.0 / 504.0, 525.0 / 504.0, 650.0 / 504.0, 1375.0 / 504.0],
])


@dataclass(frozen=True)
class VerticalDamping:
    """Gains of the baro-style vertical damping loop.

    With ``δh = h − h_ref`` the loop is::

        ḣ   = v_U − k1·δh
        v̇_U = a_U − k2·δh − a_d
        ȧ_d = k3·δh                      (k3 = 0: second order)

    The closed-loop characteristic polynomial of the height error is
    ``s³ + k1 s² + (k2 − 2ω_s²) s + k3`` (the ``2ω_s² = 2g/R`` is the free channel's
    instability). :meth:`gains` places the poles from ``tau`` [s]: third order at a triple
    pole ``−1/tau`` (k1 = 3/τ, k2 = 3/τ² + 2ω_s², k3 = 1/τ³); second order at
    ``s² + 2ζ s/τ + 1/τ²`` (k1 = 2ζ/τ, k2 = 1/τ² + 2ω_s²). Explicit ``k1, k2, k3`` [1/s,
    1/s², 1/s³] override that.

    Attributes
    ----------
    order : int
        2 or 3.
    tau : float
        Time constant [s] (default 100 s).
    zeta : float
        Damping ratio of the second-order loop.
    k : tuple of 3 floats or None
        Explicit gains ``(k1, k2, k3)``; ``tau``/``zeta``/``order`` are then ignored.
    """

    order: int = 3
    tau: float = 100.0
    zeta: float = 0.7071067811865476
    k: tuple | None = None

    def __post_init__(self):
        if self.k is None:
            if self.order not in (2, 3):
                raise ValueError(f"vertical damping order must be 2 or 3, got {self.order!r}")
            if not (np.isfinite(self.tau) and self.tau > 0):
                raise ValueError(f"vertical damping tau must be > 0 s, got {self.tau!r}")
            if not (np.isfinite(self.zeta) and self.zeta > 0):
                raise ValueError(f"vertical damping zeta must be > 0, got {self.zeta!r}")
        else:
            k = tuple(float(x) for x in self.k)
            if len(k) != 3 or not all(np.isfinite(k)):
                raise ValueError(f"vertical damping gains k must be 3 finite numbers, got {self.k!r}")
            object.__setattr__(self, "k", k)

    def gains(self, lat: float = 0.0, h: float = 0.0) -> tuple[float, float, float]:
        """``(k1, k2, k3)`` for a latitude [rad] and height [m] (for ω_s)."""
        if self.k is not None:
            return self.k
        rm, rn = radii(lat, h)
        ws2 = float(gravity(lat, h)) / float(np.sqrt(rm * rn))
        t = float(self.tau)
        if self.order == 3:
            return 3.0 / t, 3.0 / t ** 2 + 2.0 * ws2, 1.0 / t ** 3
        return 2.0 * self.zeta / t, 1.0 / t ** 2 + 2.0 * ws2, 0.0

    @classmethod
    def coerce(cls, d: "VerticalDamping | dict | None") -> "VerticalDamping":
        """From None (defaults), a VerticalDamping, or a dict of its fields."""
        if d is None:
            return cls()
        if isinstance(d, cls):
            return d
        if isinstance(d, dict):
            unknown = set(d) - {"order", "tau", "zeta", "k"}
            if unknown:
                raise ValueError(f"unknown vertical damping key(s): {sorted(unknown)}")
            return cls(**d)
        raise ValueError(f"damping must be None, a dict or a VerticalDamping, got {type(d).__name__}")


# ------------------------------------------------------------------------------------------
# compiled kernel
# ------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(cache=True, inline="always")
def _sincos_near(x, a, sa, ca):
    """sin x, cos x from ``sa``, ``ca`` = sin a, cos a of a nearby angle: the Taylor series
    of the rotation by d = x − a to third order where that is exact in double precision
    (|d| < 1e-5 rad: the dropped d⁴ terms are < 5e-22), sin and cos of x themselves
    otherwise.

    The mid-interval latitude lies v·T/(2R) from the update's start (2e-6 rad at 300 m/s
    over T = 0.1 s): its sine and cosine then come from those of the start latitude, which
    is known when the update begins, instead of from a sin/cos that waits for this
    update's specific force — the longest chain of dependent operations of an update."""
    d = x - a
    if -1e-5 < d < 1e-5:
        h = 0.5 * d * d
        e = d * (1.0 - h * (1.0 / 3.0))       # d − d³/6
        return sa * (1.0 - h) + ca * e, ca * (1.0 - h) - sa * e
    return math.sin(x), math.cos(x)


@njit(cache=True)
def _init_aux(s):
    """Fill the auxiliary entries from the navigation entries (start of a run)."""
    lat = s[7]
    h = s[9]
    ve, vn, vu = s[4], s[5], s[6]
    sl = math.sin(lat)
    cl = math.cos(lat)
    rm, rn = radii_s(lat, h)
    g = gravity_s(lat, h)
    wx = -vn / rm
    wy = 2.0 * WIE * cl + ve / rn
    wz = 2.0 * WIE * sl + ve * sl / (cl * rn)
    cx, cy, cz = _cross(wx, wy, wz, ve, vn, vu)
    s[10] = -cx
    s[11] = -cy
    s[12] = -g - cz
    s[13] = 1.0 / rm
    s[14] = 1.0 / (rn * cl)
    s[23] = -vn / rm
    s[24] = WIE * cl + ve / rn
    s[25] = WIE * sl + ve * sl / (cl * rn)


@njit(cache=True, inline="always")
def _correct_s(s, px, py, pz, dve, dvn, dvu, dlat, dlon, dh):
    """Feedback correction in place: q <- q(φ) ⊗ q, v -= δv, pos -= δpos."""
    e0, e1, e2, e3 = rv2q_s(px, py, pz)
    a0, a1, a2, a3 = qmul_s(e0, e1, e2, e3, s[0], s[1], s[2], s[3])
    nq = 1.0 / math.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
    s[0] = a0 * nq
    s[1] = a1 * nq
    s[2] = a2 * nq
    s[3] = a3 * nq
    s[4] -= dve
    s[5] -= dvn
    s[6] -= dvu
    s[7] -= dlat
    s[8] -= dlon
    s[9] -= dh


@njit(cache=True, nogil=True, error_model="numpy")
def _kernel(s, dth, dvl, dt, nsub, nupd, vmode, href, vref, k1, k2, k3,
            gbx, gby, gbz, abx, aby, abz, cs, out, out_every):
    """Advance state ``s`` (length NSTATE) by ``nupd`` updates of ``nsub`` samples.

    ``href``/``vref``: height and vertical-rate series at the sample epochs (length
    nupd·nsub + 1, epoch 0 = start of the chunk) for vmode 1 (hold) and 2 (damped; vref
    unused). ``out`` (rows >= nupd // out_every, >= 10 columns) receives s[:10] after every
    ``out_every``-th update. Returns nothing; everything is in place.

    Compiled with IEEE division (numba's numpy error model): no divisor of an update is zero
    off the poles, which the callers check, so the test numba adds before every division to
    raise ZeroDivisionError would only cost instructions; the samples are read with unsigned
    indices, which spares a negative-index wraparound per load. Neither changes a value.
    """
    if s[13] == 0.0:
        _init_aux(s)
    q0, q1, q2, q3 = s[0], s[1], s[2], s[3]
    ve, vn, vu = s[4], s[5], s[6]
    lat, lon, h = s[7], s[8], s[9]
    gcx, gcy, gcz = s[10], s[11], s[12]
    irm, irn = s[13], s[14]
    dint = s[15]
    p1x, p1y, p1z = s[16], s[17], s[18]
    p2x, p2y, p2z = s[19], s[20], s[21]
    has_prev = s[22] != 0.0
    wnx, wny, wnz = s[23], s[24], s[25]
    T = nsub * dt
    hT = 0.5 * T
    gdx, gdy, gdz = gbx * dt, gby * dt, gbz * dt
    adx, ady, adz = abx * dt, aby * dt, abz * dt
    iout = 0
    since = 0                      # updates since the last output row
    c2 = cs[1, 0]
    one = np.uint64(1)
    for k in range(nupd):
        i0 = k * nsub
        u0 = np.uint64(i0)         # unsigned sample index: no negative-index wraparound per load
        # --- coning / sculling -----------------------------------------------------
        if nsub == 1:
            wx = dth[u0, 0] - gdx
            wy = dth[u0, 1] - gdy
            wz = dth[u0, 2] - gdz
            ux = dvl[u0, 0] - adx
            uy = dvl[u0, 1] - ady
            uz = dvl[u0, 2] - adz
            if has_prev:
                c = cs[0, 0]
                cnx, cny, cnz = _cross(p1x, p1y, p1z, wx, wy, wz)
                s1x, s1y, s1z = _cross(p1x, p1y, p1z, ux, uy, uz)
                s2x, s2y, s2z = _cross(p2x, p2y, p2z, wx, wy, wz)
                cnx *= c
                cny *= c
                cnz *= c
                scx = c * (s1x + s2x)
                scy = c * (s1y + s2y)
                scz = c * (s1z + s2z)
            else:
                cnx = cny = cnz = 0.0
                scx = scy = scz = 0.0
            p1x, p1y, p1z = wx, wy, wz
            p2x, p2y, p2z = ux, uy, uz
            has_prev = True
            tx, ty, tz = wx, wy, wz
            sx, sy, sz = ux, uy, uz
        elif nsub == 2:
            # the general branch below for N = 2, written out: the same operations in the
            # same order (the zeros they start from included), without its loop and table
            w1x = dth[u0, 0] - gdx
            w1y = dth[u0, 1] - gdy
            w1z = dth[u0, 2] - gdz
            u1x = dvl[u0, 0] - adx
            u1y = dvl[u0, 1] - ady
            u1z = dvl[u0, 2] - adz
            wx = dth[u0 + one, 0] - gdx
            wy = dth[u0 + one, 1] - gdy
            wz = dth[u0 + one, 2] - gdz
            ux = dvl[u0 + one, 0] - adx
            uy = dvl[u0 + one, 1] - ady
            uz = dvl[u0 + one, 2] - adz
            awx = 0.0 + c2 * w1x
            awy = 0.0 + c2 * w1y
            awz = 0.0 + c2 * w1z
            avx = 0.0 + c2 * u1x
            avy = 0.0 + c2 * u1y
            avz = 0.0 + c2 * u1z
            tx = (0.0 + w1x) + wx
            ty = (0.0 + w1y) + wy
            tz = (0.0 + w1z) + wz
            sx = (0.0 + u1x) + ux
            sy = (0.0 + u1y) + uy
            sz = (0.0 + u1z) + uz
            cnx, cny, cnz = _cross(awx, awy, awz, wx, wy, wz)
            s1x, s1y, s1z = _cross(awx, awy, awz, ux, uy, uz)
            s2x, s2y, s2z = _cross(avx, avy, avz, wx, wy, wz)
            scx = s1x + s2x
            scy = s1y + s2y
            scz = s1z + s2z
        else:
            tx = ty = tz = 0.0
            sx = sy = sz = 0.0
            awx = awy = awz = 0.0
            avx = avy = avz = 0.0
            for i in range(nsub - 1):
                ui = u0 + np.uint64(i)
                wx = dth[ui, 0] - gdx
                wy = dth[ui, 1] - gdy
                wz = dth[ui, 2] - gdz
                ux = dvl[ui, 0] - adx
                uy = dvl[ui, 1] - ady
                uz = dvl[ui, 2] - adz
                c = cs[nsub - 1, i]
                awx += c * wx
                awy += c * wy
                awz += c * wz
                avx += c * ux
                avy += c * uy
                avz += c * uz
                tx += wx
                ty += wy
                tz += wz
                sx += ux
                sy += uy
                sz += uz
            j = u0 + np.uint64(nsub - 1)
            wx = dth[j, 0] - gdx
            wy = dth[j, 1] - gdy
            wz = dth[j, 2] - gdz
            ux = dvl[j, 0] - adx
            uy = dvl[j, 1] - ady
            uz = dvl[j, 2] - adz
            tx += wx
            ty += wy
            tz += wz
            sx += ux
            sy += uy
            sz += uz
            cnx, cny, cnz = _cross(awx, awy, awz, wx, wy, wz)
            s1x, s1y, s1z = _cross(awx, awy, awz, ux, uy, uz)
            s2x, s2y, s2z = _cross(avx, avy, avz, wx, wy, wz)
            scx = s1x + s2x
            scy = s1y + s2y
            scz = s1z + s2z
        phx = tx + cnx
        phy = ty + cny
        phz = tz + cnz
        r1x, r1y, r1z = _cross(tx, ty, tz, sx, sy, sz)
        r2x, r2y, r2z = _cross(tx, ty, tz, r1x, r1y, r1z)
        dbx = sx + 0.5 * r1x + r2x / 6.0 + scx
        dby = sy + 0.5 * r1y + r2y / 6.0 + scy
        dbz = sz + 0.5 * r1z + r2z / 6.0 + scz
        # --- specific-force velocity increment in n (start attitude) ---------------
        c00, c01, c02, c10, c11, c12, c20, c21, c22 = q2dcm_s(q0, q1, q2, q3)
        fx = c00 * dbx + c01 * dby + c02 * dbz
        fy = c10 * dbx + c11 * dby + c12 * dbz
        fz = c20 * dbx + c21 * dby + c22 * dbz
        # --- mid-interval extrapolation (last ω_in, g_cc; this update's f) ----------
        rx, ry, rz = _cross(wnx, wny, wnz, fx, fy, fz)
        vme = ve + 0.5 * (fx - 0.5 * rx * T + gcx * T)
        vmn = vn + 0.5 * (fy - 0.5 * ry * T + gcy * T)
        if vmode == 1:
            h0r = href[i0]
            h1r = href[i0 + nsub]
            vmu = (h1r - h0r) / T
            hm = 0.5 * (href[i0 + nsub // 2] + href[i0 + (nsub + 1) // 2])
        else:
            vmu = vu + 0.5 * (fz - 0.5 * rz * T + gcz * T)
            hm = h + 0.5 * hT * (vu + vmu)
        latm = lat + 0.5 * hT * (vn + vmn) * irm
        # --- Earth model at mid-interval -------------------------------------------
        sl, cl = _sincos_near(latm, lat, math.sin(lat), math.cos(lat))
        rm, rn = radii_sin_s(sl, hm)
        g = gravity_sin_s(sl, hm)
        wiey = WIE * cl
        wiez = WIE * sl
        wex = -vmn / rm
        wey = vme / rn
        wez = vme * sl / (cl * rn)
        cx, cy, cz = _cross(wex, 2.0 * wiey + wey, 2.0 * wiez + wez, vme, vmn, vmu)
        gcx = -cx
        gcy = -cy
        gcz = -g - cz
        wnx = wex
        wny = wiey + wey
        wnz = wiez + wez
        zx = wnx * T
        zy = wny * T
        zz = wnz * T
        rx, ry, rz = _cross(zx, zy, zz, fx, fy, fz)
        nve = ve + fx - 0.5 * rx + gcx * T
        nvn = vn + fy - 0.5 * ry + gcy * T
        irm = 1.0 / rm
        irn = 1.0 / (rn * cl)
        lat += 0.5 * (vn + nvn) * T * irm
        lon += 0.5 * (ve + nve) * T * irn
        ve = nve
        vn = nvn
        if vmode == 1:
            h = href[i0 + nsub]
            vu = vref[i0 + nsub]
        elif vmode == 2:
            dhh = h - href[i0]
            nvu = vu + fz - 0.5 * rz + (gcz - k2 * dhh - dint) * T
            h += (0.5 * (vu + nvu) - k1 * dhh) * T
            dint += k3 * dhh * T
            vu = nvu
        else:
            nvu = vu + fz - 0.5 * rz + gcz * T
            h += 0.5 * (vu + nvu) * T
            vu = nvu
        # --- attitude ---------------------------------------------------------------
        b0, b1, b2, b3 = rv2q_s(phx, phy, phz)
        e0, e1, e2, e3 = rv2q_s(-zx, -zy, -zz)
        a0, a1, a2, a3 = qmul_s(q0, q1, q2, q3, b0, b1, b2, b3)
        q0, q1, q2, q3 = qmul_s(e0, e1, e2, e3, a0, a1, a2, a3)
        nq = 1.0 / math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        q0 *= nq
        q1 *= nq
        q2 *= nq
        q3 *= nq
        since += 1
        if since == out_every:     # (k + 1) % out_every == 0 without a division
            since = 0
            out[iout, 0] = q0
            out[iout, 1] = q1
            out[iout, 2] = q2
            out[iout, 3] = q3
            out[iout, 4] = ve
            out[iout, 5] = vn
            out[iout, 6] = vu
            out[iout, 7] = lat
            out[iout, 8] = lon
            out[iout, 9] = h
            iout += 1
    s[0], s[1], s[2], s[3] = q0, q1, q2, q3
    s[4], s[5], s[6] = ve, vn, vu
    s[7], s[8], s[9] = lat, lon, h
    s[10], s[11], s[12] = gcx, gcy, gcz
    s[13], s[14] = irm, irn
    s[15] = dint
    s[16], s[17], s[18] = p1x, p1y, p1z
    s[19], s[20], s[21] = p2x, p2y, p2z
    s[22] = 1.0 if has_prev else 0.0
    s[23], s[24], s[25] = wnx, wny, wnz


@njit(cache=True)
def _split_rows(rows, mq, lat, lon, h, vel, att, att_imu):
    """Split state rows into output columns and Euler angles (one pass; serial so that it
    is safe to call from several threads, e.g. Dask workers).

    ``mq`` (M, 4): quaternions of C_imu^carrier, or shape (0, 4) for a fixed IMU (then
    ``att_imu`` is not written). Carrier: C_c^n = C_b^n (C_b^c)^T, q_c = q_b ⊗ conj(q_m).
    """
    m = rows.shape[0]
    has_mount = mq.shape[0] > 0
    for k in range(m):
        q0, q1, q2, q3 = rows[k, 0], rows[k, 1], rows[k, 2], rows[k, 3]
        vel[k, 0] = rows[k, 4]
        vel[k, 1] = rows[k, 5]
        vel[k, 2] = rows[k, 6]
        lat[k] = rows[k, 7]
        lon[k] = rows[k, 8]
        h[k] = rows[k, 9]
        if has_mount:
            p, r, y = q2euler_s(q0, q1, q2, q3)
            att_imu[k, 0] = p
            att_imu[k, 1] = r
            att_imu[k, 2] = y
            c0, c1, c2, c3 = qmul_s(q0, q1, q2, q3, mq[k, 0], -mq[k, 1], -mq[k, 2], -mq[k, 3])
            p, r, y = q2euler_s(c0, c1, c2, c3)
        else:
            p, r, y = q2euler_s(q0, q1, q2, q3)
        att[k, 0] = p
        att[k, 1] = r
        att[k, 2] = y


@njit(cache=True)
def _mount_quats(mount, idx):
    m = idx.shape[0]
    out = np.empty((m, 4))
    for k in range(m):
        j = idx[k]
        a0, a1, a2, a3 = euler2q_s(mount[j, 0], mount[j, 1], mount[j, 2])
        out[k, 0] = a0
        out[k, 1] = a1
        out[k, 2] = a2
        out[k, 3] = a3
    return out


# ------------------------------------------------------------------------------------------
# Python API
# ------------------------------------------------------------------------------------------
def _check_nsub(nsub) -> int:
    if isinstance(nsub, bool) or not isinstance(nsub, (int, np.integer)) or not 1 <= nsub <= 5:
        raise ValueError(f"nsub (samples per update) must be an integer in 1..5, got {nsub!r}")
    return int(nsub)


def _bias3(b, name) -> np.ndarray:
    if b is None:
        return np.zeros(3)
    if type(b) is np.ndarray and b.shape == (3,) and b.dtype == np.float64 and \
            math.isfinite(b[0]) and math.isfinite(b[1]) and math.isfinite(b[2]):
        return b
    a = np.asarray(b, dtype=float).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers (body frame), got {b!r}")
    return a


def _check_not_pole(lat):
    if abs(float(lat)) > math.pi / 2 - 1e-9:
        raise ValueError(f"latitude {math.degrees(float(lat)):.9g} deg is at a pole, where the "
                         "ENU mechanization (longitude, transport rate) is singular")


def initial_state_array(init: NavState) -> np.ndarray:
    """Full state array (length :data:`NSTATE`) for an initial :class:`NavState`.

    ``init.att`` is the IMU body attitude ``[pitch, roll, yaw]`` [rad]. Entries 0..9 are
    ``[q0, q1, q2, q3, vE, vN, vU, lat, lon, h]`` (quaternion of C_b^n, m/s, rad, m).
    """
    check_latitude(init.lat)
    _check_not_pole(init.lat)
    s = np.zeros(NSTATE)
    s[:4] = euler_to_quat(np.asarray(init.att, dtype=float))
    s[4:7] = init.vel
    s[7:10] = (init.lat, init.lon, init.h)
    _init_aux(s)
    return s


def state_to_navstate(state: np.ndarray, t: float = 0.0) -> NavState:
    """A :class:`NavState` (IMU attitude) from a state array and an epoch ``t`` [s]."""
    s = np.asarray(state, dtype=float)
    q = s[:4] / np.linalg.norm(s[:4])
    att = np.array(q2euler_s(q[0], q[1], q[2], q[3]))
    return NavState(s[7], s[8], s[9], s[4:7].copy(), att, t)


def correct(state: np.ndarray, phi: ArrayLike | None = None, dvel: ArrayLike | None = None,
            dpos: ArrayLike | None = None) -> np.ndarray:
    """Apply a feedback correction to a state array in place (and return it): the compiled
    form of :func:`correct_rows` on one state (equal to rounding).

    Parameters
    ----------
    state : ndarray, shape (NSTATE,) or (10,)
        State array (modified in place).
    phi : array_like, shape (k,), k <= 3, optional
        Estimated misalignment [rad] in n (ENU) with the convention
        ``C_b^{n'} = (I − φ×) C_b^n``; the corrected attitude is ``exp(φ×) C_b^{n'}``
        (≈ ``(I + φ×) C'``), i.e. ``q <- q(φ) ⊗ q``.
    dvel : array_like, shape (k,), k <= 3, optional
        Estimated velocity error ``v' − v`` [m/s] (ENU); subtracted.
    dpos : array_like, shape (k,), k <= 3, optional
        Estimated position error ``[δlat, δlon, δh]`` [rad, rad, m]; subtracted.
        Fewer than 3 components (a horizontal block) leave the rest alone.
    """
    s = np.asarray(state)
    if s.dtype != np.float64 or s.ndim != 1 or s.size < NAV:
        raise ValueError(f"state must be a float64 array of length >= {NAV}, got {s.dtype} {s.shape}")
    p = _bias3(_pad3(phi), "phi")
    v = _bias3(_pad3(dvel), "dvel")
    d = _bias3(_pad3(dpos), "dpos")
    _correct_s(s, p[0], p[1], p[2], v[0], v[1], v[2], d[0], d[1], d[2])
    if abs(s[7]) > math.pi / 2:
        raise ValueError(f"corrected latitude {math.degrees(s[7]):.6g} deg is beyond ±90 deg")
    if s.size >= NSTATE:
        # the cached radii follow the corrected position (gravity/Coriolis memory is kept)
        rm, rn = radii(s[7], s[9])
        s[_I_IRM] = 1.0 / float(rm)
        s[_I_IRN] = 1.0 / (float(rn) * math.cos(s[7]))
    return s


def _pad3(e: ArrayLike | None) -> np.ndarray | None:
    """Errors (..., k), k <= 3, padded with zeros to (..., 3) (a horizontal block leaves the
    vertical alone), or None."""
    if e is None:
        return None
    e = np.asarray(e, dtype=float)
    if e.shape[-1] == 3:
        return e
    return np.concatenate([e, np.zeros(e.shape[:-1] + (3 - e.shape[-1],))], -1)


def correct_rows(rows: ArrayLike, phi: ArrayLike | None = None, dvel: ArrayLike | None = None,
                 dpos: ArrayLike | None = None) -> np.ndarray:
    """Navigation rows corrected by an error state, as a feedback corrects the INS.

    The definition of the correction (the errors are computed minus true, the conventions
    of :mod:`sinslab.nav.errstate`): ``q ← q(φ) ⊗ q`` (normalised), ``v ← v − δv``,
    ``[lat, lon, h] ← [lat, lon, h] − δp``. :func:`correct` is its compiled in-place form
    on one state array (the feedback of a running INS); :func:`with_errors` its inverse.

    Parameters
    ----------
    rows : array_like, shape (M, 10) or (10,)
        ``[q0..q3, vE, vN, vU, lat, lon, h]``.
    phi, dvel, dpos : array_like, shape (M, k) or (k,), k <= 3, optional
        Misalignment [rad] (ENU), velocity error [m/s] (ENU), position error
        ``[δlat, δlon, δh]`` [rad, rad, m]; fewer than 3 columns leave the rest alone (a
        horizontal block); None leaves that part alone.

    Returns
    -------
    ndarray, the shape of ``rows``
        A new array.
    """
    out = np.array(rows, dtype=float, copy=True)
    phi, dvel, dpos = _pad3(phi), _pad3(dvel), _pad3(dpos)
    if phi is not None:
        q = quat_mul(rotvec_to_quat(phi), out[..., :4])
        out[..., :4] = q / np.linalg.norm(q, axis=-1, keepdims=True)
    if dvel is not None:
        out[..., 4:7] -= dvel
    if dpos is not None:
        out[..., 7:10] -= dpos
    return out


def with_errors(rows: ArrayLike, phi: ArrayLike | None = None, dvel: ArrayLike | None = None,
                dpos: ArrayLike | None = None) -> np.ndarray:
    """Navigation rows an INS carrying an error state shows: the inverse of
    :func:`correct_rows` (``q ← q(−φ) ⊗ q``, ``v ← v + δv``, ``p ← p + δp``; to first
    order ``C_b^{n'} = (I − φ×) C_b^n``). Arguments and result as in :func:`correct_rows`."""
    out = np.array(rows, dtype=float, copy=True)
    phi, dvel, dpos = _pad3(phi), _pad3(dvel), _pad3(dpos)
    if phi is not None:
        q = quat_mul(rotvec_to_quat(-phi), out[..., :4])
        out[..., :4] = q / np.linalg.norm(q, axis=-1, keepdims=True)
    if dvel is not None:
        out[..., 4:7] += dvel
    if dpos is not None:
        out[..., 7:10] += dpos
    return out


def _height_series(height, n_epochs, what):
    if isinstance(height, NavSeries):
        height = height.h
    a = np.asarray(height, dtype=float)
    if a.ndim == 0:
        a = np.full(n_epochs, float(a))
    if a.ndim != 1 or a.size != n_epochs:
        raise ValueError(f"{what} height series must have {n_epochs} epochs (samples + 1), "
                         f"got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} height series has a NaN/inf value at epoch "
                         f"{int(np.argmax(~np.isfinite(a)))}")
    return np.ascontiguousarray(a)


def held_vup(href: np.ndarray, dt: float) -> np.ndarray:
    """Vertical velocity [m/s] of a held height series ``href`` [m] at interval ``dt`` [s]:
    second-order finite differences (one-sided at the ends), contiguous."""
    n_epochs = href.shape[0]
    if n_epochs >= 3:
        vref = np.gradient(href, dt, edge_order=2)
    elif n_epochs == 2:
        vref = np.full(2, (href[1] - href[0]) / dt)
    else:
        vref = np.zeros(1)
    return np.ascontiguousarray(vref)


class HeldHeight:
    """A height series that several INS hold their vertical channel to, with the vertical
    rate of every slice they ask for computed once for all of them.

    The rate of a slice is :func:`held_vup` of that slice (one-sided differences at its
    ends), so a stream that runs in blocks gets exactly the numbers it would compute
    itself; Monte Carlo runs and filter variants on one trajectory ask for the same blocks.

    Parameters
    ----------
    height : array_like (N + 1,)
        Height [m] at the IMU epochs (finite).
    dt : float
        IMU sampling interval [s].
    shared : bool
        Keep each slice's rate for the next stream that asks; False: compute it on every
        call and keep nothing (the height of one stream).
    """

    def __init__(self, height: ArrayLike, dt: float, *, shared: bool = True):
        h = np.asarray(height, dtype=float)
        if h.ndim != 1 or h.size < 2:
            raise ValueError(f"held height must be a series of >= 2 epochs, got shape {h.shape}")
        self.h = _height_series(h, h.size, "held")
        self.dt = float(dt)
        self._vup: dict[tuple[int, int], np.ndarray] | None = {} if shared else None

    def __len__(self):
        return self.h.size

    def slice(self, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        """Heights and vertical rates [m/s] of epochs ``a..b`` (inclusive), contiguous."""
        if self._vup is None:
            return self.h[a:b + 1], held_vup(self.h[a:b + 1], self.dt)
        v = self._vup.get((a, b))
        if v is None:
            v = self._vup[(a, b)] = held_vup(self.h[a:b + 1], self.dt)
        return self.h[a:b + 1], v


def advance(full: np.ndarray, dth: np.ndarray, dvl: np.ndarray, dt: float, nsub: int, mode: int,
            href: np.ndarray, vref: np.ndarray, gains: tuple[float, float, float], gb: np.ndarray,
            ab: np.ndarray, out: np.ndarray, out_every: int) -> int:
    """The compiled update loop on inputs already checked (what :func:`step` runs after
    its checks; the fusion driver's streams call it per block with inputs checked once).

    ``full`` the state array of length :data:`NSTATE` (in place); ``dth``, ``dvl``
    contiguous float64 (n, 3); ``mode`` 0/1/2 (free/hold/damped) with ``href``, ``vref``
    (n + 1,) and the damping ``gains`` (k1, k2, k3); ``gb``, ``ab`` float64 (3,) biases;
    ``out`` float64 (>= updates // out_every, >= 10) or a (1, 10) dummy with
    ``out_every = 0``. Returns the number of updates.
    """
    nupd = dth.shape[0] // nsub
    if nupd > 0:
        k1, k2, k3 = gains
        _kernel(full, dth, dvl, dt, nsub, nupd, mode, href, vref, k1, k2, k3,
                gb[0], gb[1], gb[2], ab[0], ab[1], ab[2], CONING_COEFFS, out, out_every)
    return nupd


def _vertical(vertical, height, damping, n_epochs, dt, lat, h, vup=None):
    if vertical not in _VMODE:
        raise ValueError(f"vertical must be one of {VERTICAL_MODES}, got {vertical!r}")
    mode = _VMODE[vertical]
    empty = np.zeros(1)
    if mode != 1 and vup is not None:
        raise ValueError("a held vertical velocity (vup) is only used with vertical='hold'")
    if mode == 0:
        if height is not None:
            raise ValueError("a height series is only used with vertical='hold' or 'damped'")
        return mode, empty, empty, (0.0, 0.0, 0.0)
    if height is None:
        raise ValueError(f"vertical={vertical!r} needs a height series (samples + 1 epochs)")
    href = _height_series(height, n_epochs, "reference" if mode == 2 else "held")
    if mode == 1:
        vref = held_vup(href, dt) if vup is None else _height_series(vup, n_epochs, "held vertical-velocity")
        return mode, href, vref, (0.0, 0.0, 0.0)
    gains = VerticalDamping.coerce(damping).gains(lat, h)
    return mode, href, empty, gains


def step(state: np.ndarray, dtheta: np.ndarray, dv: np.ndarray, dt: float, nsub: int = 2, *,
         vertical: str = "free", height: ArrayLike | None = None, vup: ArrayLike | None = None,
         damping: VerticalDamping | dict | None = None, gyro_bias: ArrayLike | None = None,
         accel_bias: ArrayLike | None = None, out: np.ndarray | None = None, out_every: int = 1) -> int:
    """Advance a state array in place over a chunk of IMU samples (compiled loop).

    Parameters
    ----------
    state : ndarray, shape (NSTATE,) or (10,)
        From :func:`initial_state_array` (or a previous ``step``); modified in place.
    dtheta, dv : ndarray, shape (n, 3)
        Body-frame (RFU) angle [rad] and velocity [m/s] increments of the chunk.
    dt : float
        Sampling interval [s].
    nsub : int
        Samples per update, 1..5 (coning/sculling order). Only ``n // nsub`` updates are
        made; trailing samples that do not fill an update are not consumed (pass them
        again at the head of the next chunk).
    vertical : {"free", "hold", "damped"}
        Vertical channel mode.
    height : ndarray, shape (n + 1,), optional
        Held or reference height [m] at the chunk's epochs (epoch 0 = chunk start).
    vup : ndarray, shape (n + 1,), optional
        Held vertical velocity [m/s] at the epochs ("hold"); default: derivative of
        ``height`` (second-order finite differences).
    damping : VerticalDamping or dict, optional
        Loop gains for "damped" (default third order, τ = 100 s).
    gyro_bias, accel_bias : array_like, shape (3,), optional
        Constant body-frame biases [rad/s], [m/s^2] subtracted from the increments.
    out : ndarray, shape (>= n_updates // out_every, >= 10), optional
        Receives ``state[:10]`` after every ``out_every``-th update.

    Returns
    -------
    int
        Number of updates made (samples consumed = updates · nsub).
    """
    nsub = _check_nsub(nsub)
    s = np.asarray(state)
    if s.dtype != np.float64 or s.ndim != 1 or s.size not in (NAV, NSTATE):
        raise ValueError(f"state must be a float64 array of length {NAV} or {NSTATE}, "
                         f"got {s.dtype} {s.shape}")
    check_latitude(s[7])
    _check_not_pole(s[7])
    dth = np.ascontiguousarray(dtheta, dtype=float)
    dvl = np.ascontiguousarray(dv, dtype=float)
    if dth.ndim != 2 or dth.shape[1] != 3 or dvl.shape != dth.shape:
        raise ValueError(f"dtheta and dv must both have shape (n, 3), got {dth.shape} and {dvl.shape}")
    dt = float(dt)
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite number > 0 s, got {dt!r}")
    n = dth.shape[0]
    nupd = n // nsub
    if not isinstance(out_every, (int, np.integer)) or out_every < 1:
        raise ValueError(f"out_every must be a positive integer, got {out_every!r}")
    mode, href, vref, (k1, k2, k3) = _vertical(vertical, height, damping, n + 1, dt, s[7], s[9], vup)
    if out is None:
        o = np.zeros((1, NAV))
        oe = 0
    else:
        if out.dtype != np.float64 or out.ndim != 2 or out.shape[1] < NAV or \
                out.shape[0] < nupd // out_every:
            raise ValueError(f"out must be float64 with shape (>= {nupd // out_every}, >= {NAV}), "
                             f"got {out.dtype} {out.shape}")
        o = out
        oe = int(out_every)
    gb = _bias3(gyro_bias, "gyro_bias")
    ab = _bias3(accel_bias, "accel_bias")
    full = s if s.size == NSTATE else np.concatenate([s, np.zeros(NSTATE - NAV)])
    advance(full, dth, dvl, dt, nsub, mode, href, vref, (k1, k2, k3), gb, ab, o, oe)
    if full is not s:
        s[:] = full[:NAV]
    return nupd


#: Name used in docs/INTERFACES.md for :func:`step`.
step_chunk = step


def _progress_ctx(progress, total):
    """A context manager yielding ``advance(n)``; see :func:`navigate` ``progress``."""
    import contextlib

    if progress is False:
        return contextlib.nullcontext(lambda n: None)
    if callable(progress):
        done = [0]

        def adv(n):
            done[0] += n
            progress(done[0], total)
        return contextlib.nullcontext(adv)
    try:
        from sinslab.core.progress import progress as bar
    except ImportError:  # pragma: no cover - progress helper not available
        return contextlib.nullcontext(lambda n: None)

    @contextlib.contextmanager
    def ctx():
        with bar("navigating", total=total, unit="samples") as b:
            yield b.advance
    return ctx()


def navigate(imu: ImuRecord, init: NavState, *, nsub: int = 2, vertical: str = "free",
             height: ArrayLike | NavSeries | None = None, vup: ArrayLike | None = None,
             damping: VerticalDamping | dict | None = None, mount: ArrayLike | None = None,
             out_every: int = 1, gyro_bias: ArrayLike | None = None, accel_bias: ArrayLike | None = None,
             progress: bool | Callable | None = None,
             chunk: int = 1 << 20) -> NavSeries:
    """Strapdown navigation of an IMU record (ENU frame, compiled loop).

    Parameters
    ----------
    imu : ImuRecord
        N body-frame increments (IMU frame, RFU) at interval ``imu.dt``; sample k covers
        ``(t[k] − dt, t[k]]``.
    init : NavState
        State at ``imu.t0``; ``init.att`` is the attitude of the IMU body frame.
    nsub : int
        Samples per update, 1..5 (coning/sculling order; see module docstring: 3..5 are
        less accurate than 2 through manoeuvres). If N is not a multiple of ``nsub`` the
        trailing ``N mod nsub`` samples are not used.
    vertical : {"free", "hold", "damped"}
        Vertical channel: pure inertial, held to ``height`` (v_U = its derivative; the
        run then starts on ``height[0]`` whatever ``init.h``), or damped towards ``height``
        by the loop of :class:`VerticalDamping`.
    height : array_like (N + 1,), float, or NavSeries, optional
        Height [m] at the N + 1 epochs ``t0, t[0], ..., t[N−1]`` (a scalar means constant;
        a NavSeries gives its ``h``). Required for "hold" and "damped".
    vup : array_like (N + 1,), optional
        Held vertical velocity [m/s] at the same epochs ("hold"); default
        :func:`held_vup` of ``height``. Runs that hold to one height series pass it once
        computed.
    damping : VerticalDamping or dict, optional
        Damping-loop gains (default third order, τ = 100 s).
    mount : array_like (N + 1, 3), optional
        Euler angles ``[pitch, roll, yaw]`` [rad] of C_imu^carrier at the epochs (rotating or
        swinging IMU). Then ``att`` is the carrier attitude ``C_c^n = C_b^n (C_b^c)^T`` and
        ``att_imu`` the IMU's. ``init.att`` is still the IMU attitude.
    out_every : int
        Output every ``out_every``-th update (plus the initial epoch).
    gyro_bias, accel_bias : array_like (3,), optional
        Constant body-frame biases [rad/s], [m/s^2] compensated (subtracted).
    progress : None, False or callable
        None: a progress bar on a terminal (quiet otherwise); False: none; a callable is
        called as ``progress(samples_done, samples_total)`` between chunks.
    chunk : int
        Samples per compiled call (progress granularity).

    Returns
    -------
    NavSeries
        Epochs ``t0`` and the end of every ``out_every``-th update (sample index
        ``(j+1)·nsub − 1``), M = 1 + (N // nsub) // out_every rows; ``att_imu`` is None
        without a mount.
    """
    if not isinstance(imu, ImuRecord):
        raise ValueError(f"imu must be an ImuRecord, got {type(imu).__name__}")
    if not isinstance(init, NavState):
        raise ValueError(f"init must be a NavState, got {type(init).__name__}")
    nsub = _check_nsub(nsub)
    check_latitude(init.lat)
    n_all = len(imu)
    if n_all < nsub:
        raise ValueError(f"IMU record has {n_all} samples, fewer than nsub = {nsub}")
    if not isinstance(out_every, (int, np.integer)) or out_every < 1:
        raise ValueError(f"out_every must be a positive integer, got {out_every!r}")
    nupd = n_all // nsub
    n = nupd * nsub
    dt = imu.dt
    mode, href, vref, gains = _vertical(vertical, height, damping, n_all + 1, dt, init.lat, init.h, vup)
    if mount is not None:
        mount = np.ascontiguousarray(mount, dtype=float)
        if mount.shape != (n_all + 1, 3):
            raise ValueError(f"mount must have shape ({n_all + 1}, 3) (one row per epoch), "
                             f"got {mount.shape}")
        if not np.all(np.isfinite(mount)):
            raise ValueError("mount angles contain NaN/inf")
    gb = _bias3(gyro_bias, "gyro_bias")
    ab = _bias3(accel_bias, "accel_bias")
    s = initial_state_array(init)
    if mode == 1:                       # held channel: start on the held values
        s[9], s[6] = href[0], vref[0]
        _init_aux(s)
    m_out = nupd // out_every
    rows = np.empty((m_out + 1, NAV))
    rows[0] = s[:NAV]
    # chunks hold a whole number of output periods so the output grid stays regular
    per = nsub * out_every
    csz = max(per, (int(chunk) // per) * per)
    k1, k2, k3 = gains
    with _progress_ctx(progress, n) as advance:
        lo = 0
        r = 1
        while lo < n:
            hi = min(lo + csz, n)
            cu = (hi - lo) // nsub
            hs = href[lo:hi + 1] if mode != 0 else href
            vs = vref[lo:hi + 1] if mode == 1 else vref
            _kernel(s, imu.dtheta[lo:hi], imu.dv[lo:hi], dt, nsub, cu, mode, hs, vs, k1, k2, k3,
                    gb[0], gb[1], gb[2], ab[0], ab[1], ab[2], CONING_COEFFS, rows[r:], out_every)
            r += cu // out_every
            if not np.all(np.isfinite(s[:NAV])):
                raise InputError(f"navigation became non-finite by t = {imu.t[hi - 1]:.6g} s "
                                 "(a pole crossed, or diverging input)")
            lo = hi
            advance(cu * nsub)
    upd_idx = np.arange(1, m_out + 1) * out_every * nsub      # epoch index (0 = t0)
    ep = np.concatenate([[0], upd_idx])
    t_all = np.concatenate([[imu.t0], imu.t[upd_idx - 1]])
    return rows_to_series(t_all, rows, None if mount is None else mount[ep])


def rows_to_series(t: ArrayLike, rows: np.ndarray, mount: ArrayLike | None = None) -> NavSeries:
    """A :class:`~sinslab.core.records.NavSeries` from state rows of :func:`step`.

    Parameters
    ----------
    t : array_like, shape (M,)
        Epochs of the rows [s].
    rows : ndarray, shape (M, >= 10)
        State rows ``[q0, q1, q2, q3, vE, vN, vU, lat, lon, h, ...]`` (q of C_b^n).
    mount : array_like, shape (M, 3), optional
        Euler angles ``[pitch, roll, yaw]`` of C_imu^carrier at the same epochs; then
        ``att`` is the carrier attitude C_c^n = C_b^n (C_b^c)^T and ``att_imu`` the IMU's.
    """
    rows = np.ascontiguousarray(rows, dtype=float)
    m = rows.shape[0]
    if rows.ndim != 2 or rows.shape[1] < NAV or np.shape(t) != (m,):
        raise ValueError(f"rows must have shape (M, >= {NAV}) matching t (M,), got "
                         f"{rows.shape} and {np.shape(t)}")
    lat, lon, h = np.empty(m), np.empty(m), np.empty(m)
    vel, att = np.empty((m, 3)), np.empty((m, 3))
    if mount is None:
        att_imu, mq = np.empty((0, 3)), np.zeros((0, 4))
    else:
        mount = np.ascontiguousarray(mount, dtype=float)
        if mount.shape != (m, 3):
            raise ValueError(f"mount must have shape ({m}, 3), got {mount.shape}")
        att_imu, mq = np.empty((m, 3)), _mount_quats(mount, np.arange(m))
    _split_rows(rows, mq, lat, lon, h, vel, att, att_imu)
    return NavSeries(np.asarray(t, dtype=float), lat, lon, h, vel, att,
                     att_imu if mount is not None else None)
