"""The in-kernel normal generator bit for bit against a plain-Python implementation.

xoshiro256++ as in Blackman & Vigna, "Scrambled linear pseudorandom number generators"
(2021; the reference C code ``xoshiro256plusplus.c``), and the 256-layer ziggurat of
Marsaglia & Tsang (2000) in numpy's 64-bit layout (``random_standard_normal``: layer from
bits 0-7, sign from bit 8, abscissa from bits 9-60; Marsaglia's exact tail beyond r and
the wedge test against exp(-x²/2)), written out here with Python integers and floats from
the module's layer tables. Generator states are built so that the rare cases (the tail,
with and without a rejection in its loop, a wedge accepted and rejected in the first and
last layers, a signed zero) are among the first draws.
"""
import math
import random

import numpy as np
import pytest

from sinslab.sim import _rng
from sinslab.sim import imu as imu_mod

M64 = (1 << 64) - 1
KI = [int(v) for v in _rng._ZIG_KI]
WI = [float(v) for v in _rng._ZIG_WI]
FI = [float(v) for v in _rng._ZIG_FI]


def rotl(x, k):
    return ((x << k) | (x >> (64 - k))) & M64


class Xoshiro:
    """xoshiro256++ with Python integers."""

    def __init__(self, s):
        self.s = [int(v) for v in s]

    def next(self):
        s = self.s
        r = (rotl((s[0] + s[3]) & M64, 23) + s[0]) & M64
        t = (s[1] << 17) & M64
        s[2] ^= s[0]
        s[3] ^= s[1]
        s[1] ^= s[2]
        s[0] ^= s[3]
        s[2] ^= t
        s[3] = rotl(s[3], 45)
        return r


def uniform(g):
    return (g.next() >> 11) * (1.0 / 9007199254740992.0)


def normal(g, paths):
    """One standard normal (numpy's ziggurat on the words of ``g``); ``paths`` counts the
    rare cases taken."""
    while True:
        r = g.next()
        idx = r & 0xFF
        sign = (r >> 8) & 1
        rabs = (r >> 9) & 0x000FFFFFFFFFFFFF
        x = rabs * WI[idx]
        if sign:
            x = -x
        if rabs < KI[idx]:
            return x
        if idx == 0:                       # tail beyond r: Marsaglia (1964)
            while True:
                xx = -math.log1p(-uniform(g)) / _rng._ZIG_R
                yy = -math.log1p(-uniform(g))
                if yy + yy > xx * xx:
                    paths["tail"] += 1
                    return -(_rng._ZIG_R + xx) if (rabs >> 8) & 1 else _rng._ZIG_R + xx
                paths["tail_retry"] += 1
        if (FI[idx - 1] - FI[idx]) * uniform(g) + FI[idx] < math.exp(-0.5 * x * x):
            paths[f"wedge_in_{'last' if idx == 255 else 'first' if idx == 1 else 'mid'}"] += 1
            return x
        paths["wedge_out"] += 1


def normals(state, n, paths):
    g = Xoshiro(state)
    z = np.array([normal(g, paths) for _ in range(n)])
    return z, np.array(g.s, dtype=np.uint64)


def state_with_first_word(word, rnd):
    """A state (four uint64) whose first xoshiro256++ output is ``word``: s0, s1, s2 drawn,
    s3 solved from r = rotl(s0 + s3, 23) + s0."""
    s0, s1, s2 = (rnd.getrandbits(64) for _ in range(3))
    s3 = (rotl((word - s0) & M64, 64 - 23) - s0) & M64
    g = Xoshiro([s0, s1, s2, s3])
    assert g.next() == word
    return [s0, s1, s2, s3]


def word(idx, sign, rabs, top=0):
    return (top << 61) | (rabs << 9) | (sign << 8) | idx


def forced_states():
    """States whose first draw takes each rare path (found by trying states with that
    first word until the words after it decide the case)."""
    rnd = random.Random(2000)
    want = {"tail": 2, "tail_retry": 1, "wedge_in_first": 1, "wedge_in_last": 1, "wedge_in_mid": 1,
            "wedge_out": 2}
    # tail words with bits 7 and 8 of the abscissa unequal (bit 8 signs the tail's value)
    firsts = [word(0, 0, ((1 << 52) - 1) ^ 0x100), word(0, 1, ((KI[0] + 0x1000) | 0x100) & ~0x80), word(1, 0, KI[1]), word(1, 1, (1 << 52) - 7),
              word(255, 0, KI[255] + 99), word(255, 1, (1 << 52) - 1), word(128, 1, KI[128] + 5)]
    states = []
    for w in firsts:
        for _ in range(400):
            st = state_with_first_word(w, rnd)
            p = dict.fromkeys(want, 0)
            normal(Xoshiro(st), p)
            hit = [k for k in want if p[k] and want[k]]
            if hit:
                for k in hit:
                    want[k] -= 1
                states.append(st)
            if not any(want[k] for k in want if k.startswith("tail" if w & 0xFF == 0 else "wedge")):
                break
    assert not any(want.values()), want
    # a zero abscissa under the sign bit: -0.0 (0.0 · w negated)
    states.append(state_with_first_word(word(7, 1, 0), rnd))
    states.append(state_with_first_word(word(7, 0, 0, top=5), rnd))
    return states


STATES = forced_states()


@pytest.mark.parametrize("k", range(len(STATES)))
def test_forced_rare_cases_bit_for_bit(k):
    paths = dict.fromkeys(["tail", "tail_retry", "wedge_in_first", "wedge_in_last", "wedge_in_mid", "wedge_out"], 0)
    ref, after = normals(STATES[k], 40, paths)
    st = np.array(STATES[k], dtype=np.uint64)
    got = _rng._standard_normals(st, 40)
    assert got.tobytes() == ref.tobytes()
    assert st.tobytes() == after.tobytes()          # the state advanced by the words used


def test_forced_states_cover_every_rare_path():
    paths = dict.fromkeys(["tail", "tail_retry", "wedge_in_first", "wedge_in_last", "wedge_in_mid", "wedge_out"], 0)
    z = [normals(st, 1, paths)[0][0] for st in STATES]
    assert all(paths.values()), paths
    assert math.copysign(1.0, z[-2]) == -1.0 and z[-2] == 0.0 and math.copysign(1.0, z[-1]) == 1.0


def test_stream_of_seeded_states_bit_for_bit():
    """A few hundred ordinary draws from seeded states (about 1 % of them wedges)."""
    paths = dict.fromkeys(["tail", "tail_retry", "wedge_in_first", "wedge_in_last", "wedge_in_mid", "wedge_out"], 0)
    for seed in (0, 5, 2**40 + 3):
        st = _rng._kernel_state(np.random.default_rng(seed))
        ref, after = normals(st, 300, paths)
        assert _rng._standard_normals(st, 300).tobytes() == ref.tobytes()
        assert st.tobytes() == after.tobytes()
    assert paths["wedge_out"] + paths["wedge_in_mid"] > 0


def test_kernels_draw_the_oracles_normals():
    """Every kernel of sinslab.sim.imu compiles its own copy of the draw: the white-noise
    kernels from forced states give x + (b + σ·z) with the oracle's z in the kernels' order
    (sample by sample, gyro x, y, z, accel x, y, z)."""
    n = 12
    rng = np.random.default_rng(3)
    dth, dv = rng.standard_normal((n, 3)) * 1e-4, rng.standard_normal((n, 3)) * 1e-2
    b, w = rng.standard_normal(6) * 1e-6, rng.random(6) * 1e-5 + 1e-6
    K = np.broadcast_to(np.eye(3), (2, 3, 3)).copy()
    for st in STATES[::2]:
        z, _ = normals(st, 6 * n, dict.fromkeys(["tail", "tail_retry", "wedge_in_first", "wedge_in_last",
                                                     "wedge_in_mid", "wedge_out"], 0))
        z = z.reshape(n, 6)
        x = np.hstack([dth, dv])
        ref = np.array([[x[k, c] + (b[c] + w[c] * z[k, c]) for c in range(6)] for k in range(n)])
        runs = {
            "white_all": lambda o1, o2: imu_mod._kernel_white_all(dth, dv, np.array(st, np.uint64), b, w, o1, o2),
            "white": lambda o1, o2: imu_mod._kernel_white(dth, dv, np.array(st, np.uint64), K, False, b, w,
                                                          np.ones(6, bool), o1, o2),
            "shared": lambda o1, o2: imu_mod._kernel_white_all_shared(dth, dv, np.array(st, np.uint64), b[None],
                                                                      w[None], o1[None], o2[None]),
        }
        for name, run in runs.items():
            o1, o2 = np.empty((n, 3)), np.empty((n, 3))
            run(o1, o2)
            assert np.hstack([o1, o2]).tobytes() == ref.tobytes(), name

