"""The in-kernel random number generator of :mod:`sinslab.sim.imu` (private).

Normals come from a generator inside the compiled kernels: xoshiro256++ (Blackman & Vigna)
for the bits and the ziggurat of Marsaglia & Tsang (2000) in numpy's 64-bit layout (8 bits
of layer, 1 sign bit, 52 bits of abscissa; exact tail and wedge rejections). At ~2 ns per
normal it is ~4x faster than ``Generator.standard_normal`` and needs no buffer of normals
between passes, so the whole error model is one pass over the record. The generator's
state (four uint64) is drawn from a numpy Generator (:func:`_kernel_state`), so a seed
fixes every bit.

:func:`_normal` is inlined into the kernels of :mod:`sinslab.sim.imu`; their cached machine
code is stamped with this file's source too (:func:`sinslab.core.jitcache.dependency_digest`),
so a change here compiles them again.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sinslab.core.jitnotice import install as _compile_notice

_compile_notice()   # a status line while the kernels below compile (first run)


def _ziggurat_tables():
    """Layer tables of the 256-layer normal ziggurat (r = 3.6541528853610088, v = 4.928673e-3)."""
    m1 = 2.0 ** 52
    dn = tn = _ZIG_R
    vn = 4.92867323399e-3
    ki = np.zeros(256, dtype=np.uint64)
    wi = np.zeros(256)
    fi = np.zeros(256)
    q = vn / math.exp(-0.5 * dn * dn)
    ki[0] = int(dn / q * m1)
    wi[0] = q / m1
    wi[255] = dn / m1
    fi[0] = 1.0
    fi[255] = math.exp(-0.5 * dn * dn)
    for i in range(254, 0, -1):
        dn = math.sqrt(-2.0 * math.log(vn / dn + math.exp(-0.5 * dn * dn)))
        ki[i + 1] = int(dn / tn * m1)
        tn = dn
        fi[i] = math.exp(-0.5 * dn * dn)
        wi[i] = dn / m1
    return ki, wi, fi


_ZIG_R = 3.6541528853610088
_ZIG_KI, _ZIG_WI, _ZIG_FI = _ziggurat_tables()
# The same tables indexed by the draw's low 9 bits (layer and sign): the sign folded into the
# abscissa's factor. float(rabs) * -w is -(float(rabs) * w) bit for bit (IEEE rounding is
# symmetric), so one load and one multiply replace the test of the sign bit, which is a coin
# toss: compiled for the baseline CPU it is a branch mispredicted half the time.
_ZIG_KI2 = np.concatenate([_ZIG_KI, _ZIG_KI])
_ZIG_WS = np.concatenate([_ZIG_WI, -_ZIG_WI])
_U1 = np.uint64(1)
_INV53 = 1.0 / 9007199254740992.0


@njit(cache=True, inline="always")
def _xoshiro(s0, s1, s2, s3):
    """xoshiro256++: next 64 random bits and the new state."""
    r = s0 + s3
    r = ((r << np.uint64(23)) | (r >> np.uint64(41))) + s0
    t = s1 << np.uint64(17)
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    s3 = (s3 << np.uint64(45)) | (s3 >> np.uint64(19))
    return r, s0, s1, s2, s3


@njit(cache=True)
def _normal_reject(idx, rabs, x, s0, s1, s2, s3):
    """The rare ziggurat cases (~1 %): the tail beyond r (layer 0) or a wedge test.
    Returns (value, accepted, state)."""
    if idx == 0:
        while True:
            r, s0, s1, s2, s3 = _xoshiro(s0, s1, s2, s3)
            u1 = float(r >> np.uint64(11)) * _INV53
            r, s0, s1, s2, s3 = _xoshiro(s0, s1, s2, s3)
            u2 = float(r >> np.uint64(11)) * _INV53
            xx = -math.log1p(-u1) / _ZIG_R
            yy = -math.log1p(-u2)
            if yy + yy > xx * xx:
                y = -(_ZIG_R + xx) if (rabs >> np.uint64(8)) & _U1 else _ZIG_R + xx
                return y, True, s0, s1, s2, s3
    r, s0, s1, s2, s3 = _xoshiro(s0, s1, s2, s3)
    u = float(r >> np.uint64(11)) * _INV53
    ok = (_ZIG_FI[idx - 1] - _ZIG_FI[idx]) * u + _ZIG_FI[idx] < math.exp(-0.5 * x * x)
    return x, ok, s0, s1, s2, s3


@njit(cache=True, inline="always")
def _normal(s0, s1, s2, s3):
    """One standard normal and the new generator state.

    Inlined into each caller by numba (LLVM did not inline it): called, it returned its
    value and state through memory, half of a kernel's time. The rare cases stay out of
    line in :func:`_normal_reject`."""
    while True:
        r, s0, s1, s2, s3 = _xoshiro(s0, s1, s2, s3)
        j = r & np.uint64(0x1FF)                 # layer (bits 0-7) and sign (bit 8)
        rabs = (r >> np.uint64(9)) & np.uint64(0x000FFFFFFFFFFFFF)
        x = float(rabs) * _ZIG_WS[j]
        if rabs < _ZIG_KI2[j]:
            return x, s0, s1, s2, s3
        y, ok, s0, s1, s2, s3 = _normal_reject(j & np.uint64(0xFF), rabs, x, s0, s1, s2, s3)
        if ok:
            return y, s0, s1, s2, s3


@njit(cache=True)
def _standard_normals(state, n):
    """n standard normals from the kernel's generator; ``state`` (4 uint64) is advanced."""
    out = np.empty(n)
    s0, s1, s2, s3 = state[0], state[1], state[2], state[3]
    for i in range(n):
        out[i], s0, s1, s2, s3 = _normal(s0, s1, s2, s3)
    state[0], state[1], state[2], state[3] = s0, s1, s2, s3
    return out


def _rng(seed):
    if isinstance(seed, np.random.Generator):
        return seed
    if isinstance(seed, (bool, float)):
        raise ValueError(f"seed must be an int or a numpy Generator, got {seed!r}")
    return np.random.default_rng(seed)


def _kernel_state(rng):
    """The kernel generator's state (4 uint64), drawn from a numpy Generator (advancing it)."""
    st = rng.integers(0, 2**64, size=4, dtype=np.uint64)
    if not st.any():                       # xoshiro's one forbidden state (probability 2^-256)
        st[0] = 0x9E3779B97F4A7C15
    return st
