"""The series discretisation skips the structural zeros of Q̄ and Φ[:, R]; only exact
zeros are skipped, in the order of the dense sums, so Φ and Q_k equal, bit for bit, the
dense loops (written out here in plain Python: Φ = I + FT + (FT)²/2, Q̄ = G diag(q) Gᵀ,
Q_k = T (Q̄ + Φ Q̄ Φᵀ)/2 over the reached states) for KF-GINS' 21-state model with 18
noise inputs and for the 15-state default."""
import numpy as np
import pytest

from sinslab.core import units as u
from sinslab.estimation.linear import discretize_series_many
from sinslab.nav import errstate as es
from sinslab.nav import errstate_kernels as ek


def _dense(F, G, q, T):
    n, m = G.shape
    Phi = [[1.0 if i == j else 0.0 for j in range(n)] for i in range(n)]
    for i in range(n):
        for k in range(n):
            if F[i, k] == 0.0:
                continue
            fik = F[i, k] * T
            Phi[i][k] += fik
            h = 0.5 * fik
            for j in range(n):
                if F[k, j] != 0.0:
                    Phi[i][j] += h * (F[k, j] * T)
    R = [i for i in range(n) if any(G[i, c] != 0.0 and q[c] != 0.0 for c in range(m))]
    pos = {s: a for a, s in enumerate(R)}
    nr = len(R)
    Qb = [[0.0] * nr for _ in range(nr)]
    for c in range(m):
        if q[c] == 0.0:
            continue
        rows = [i for i in range(n) if G[i, c] != 0.0]
        for i in rows:
            gi = G[i, c] * q[c]
            for j in rows:
                Qb[pos[i]][pos[j]] += gi * G[j, c]
    for a in range(nr):
        for b in range(a + 1, nr):
            v = 0.5 * (Qb[a][b] + Qb[b][a])
            Qb[a][b] = Qb[b][a] = v
    Q = np.zeros((n, n))
    W = [[sum(Phi[i][R[a]] * Qb[a][b] for a in range(nr)) for b in range(nr)] for i in range(n)]
    for i in range(n):
        for l in range(i, n):
            s = 0.0
            for b in range(nr):
                s += W[i][b] * Phi[l][R[b]]
            if i in pos and l in pos:
                s += Qb[pos[i]][pos[l]]
            Q[i, l] = Q[l, i] = 0.5 * T * s
    return np.array(Phi), Q


@pytest.mark.parametrize("blocks", [
    [es.gyro_markov(3600.0, 1 * u.dph), es.accel_markov(3600.0, 500 * u.ug),
     es.gyro_scale(tau=3600.0, sigma=300 * u.ppm), es.accel_scale(tau=3600.0, sigma=300 * u.ppm)],
    [es.gyro_bias(), es.accel_bias()]])
def test_bit_for_bit_the_dense_loops(blocks):
    m = es.ErrorModel("full", blocks, gyro_arw=0.05 * u.dpsh, accel_vrw=50 * u.ugpsHz)
    prog = ek.program(m)
    rng = np.random.default_rng(5)
    rows = np.zeros((1, 4, 10))
    rows[0, :, :4] = rng.normal(size=(4, 4))
    rows[0, :, 4:7] = rng.normal(scale=80.0, size=(4, 3))
    rows[0, :, 7] = rng.uniform(-1.2, 1.2, 4)
    rows[0, :, 9] = rng.uniform(0, 3000, 4)
    F, G = ek.matrices_rows(prog, rows, rng.normal(scale=0.1, size=(1, 4, 3)), rng.normal(size=(1, 4, 3)) + [0, 0, 9.8])
    q = np.asarray(m.q, float)
    Phi, Q = discretize_series_many(F, G, q, 0.005)
    for e in range(4):
        P_ref, Q_ref = _dense(F[e], G[e], q, 0.005)
        np.testing.assert_array_equal(Phi[e], P_ref)
        np.testing.assert_array_equal(Q[e], Q_ref)
