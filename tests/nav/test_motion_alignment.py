"""In-motion alignment from GNSS velocity (nav.motion_alignment): Davenport's q-method
against the SVD solution of Wahba's problem, its covariance against Monte Carlo, and the
whole alignment on simulated motion against the truth."""
import math

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.nav import motion_alignment as M
from sinslab.sim import trajectory as tr


def _svd_wahba(alpha, beta):
    """Markley's SVD solution of min Σ |α − Cβ|² (Markley 1988), the independent oracle."""
    U, _, Vt = np.linalg.svd(alpha.T @ beta)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U) * np.linalg.det(Vt)]) @ Vt


def test_davenport_recovers_a_rotation_and_matches_the_svd_solution():
    rng = np.random.default_rng(3)
    C = A.euler_to_dcm(np.array([0.3, -1.1, 2.5]))
    beta = rng.normal(0, 10, (12, 3))
    np.testing.assert_allclose(M.davenport(beta @ C.T, beta), C, atol=1e-12)
    alpha = beta @ C.T + rng.normal(0, 0.5, beta.shape)
    np.testing.assert_allclose(M.davenport(alpha, beta), _svd_wahba(alpha, beta), atol=1e-10)


def test_wahba_covariance_against_monte_carlo():
    """The covariance of φ (``Ĉ = (I − φ×) C``) from the Fisher information, with σ
    estimated from the residuals, against the scatter of 2000 noisy fits (within the 95 %
    range of a sample variance of 2000 draws, ±7 %, plus the σ estimate's own scatter)."""
    rng = np.random.default_rng(7)
    C = A.euler_to_dcm(np.array([0.1, 0.2, -0.7]))
    g = np.array([0.0, 0.0, 9.8])
    beta = np.array([(k + 1) * g + [3.0 * math.sin(k), 2.0 * math.cos(0.7 * k), 0.0] for k in range(10)]) @ C
    phis, covs = [], []
    for _ in range(2000):
        alpha = beta @ C.T + rng.normal(0, 0.3, beta.shape)
        Ch = M.davenport(alpha, beta)
        phis.append(A.misalignment(C, Ch))
        covs.append(M.wahba_covariance(Ch, alpha, beta)[0])
    emp = np.cov(np.array(phis).T)
    pred = np.mean(covs, axis=0)
    np.testing.assert_allclose(np.diag(emp), np.diag(pred), rtol=0.12)


@pytest.fixture(scope="module")
def flight():
    segs = [tr.Level(duration=3.0), tr.Accelerate(duration=4.0, accel=2.0),
            tr.Turn(duration=6.0, rate=8 * u.deg), tr.Climb(duration=5.0, angle=5 * u.deg)]
    g = tr.generate(segs, tr.Start(lat=math.radians(44.9), lon=math.radians(-93.2), h=280.0, speed=15.0,
                                   heading=math.radians(60), pitch=0.0), 0.01)
    return g.imu, g.truth


def test_alignment_of_error_free_motion_against_the_truth(flight):
    """Error-free increments and the true velocity at 1 Hz: pitch, roll and heading at the
    end of the window (and at its start) within 0.01° of the truth (the trapezoid rule of the
    velocity integrals is the only approximation); the fit's σ says so."""
    imu, tru = flight
    tf = np.arange(1.0, 18.01, 1.0)
    vel = np.stack([np.interp(tf, tru.t, tru.vel[:, i]) for i in range(3)], -1)
    lat, h = np.interp(tf, tru.t, tru.lat), np.interp(tf, tru.t, tru.h)
    k0, k1 = int(np.searchsorted(imu.t, 1.0)), int(np.searchsorted(imu.t, 18.0 - 1e-9)) + 1
    m = M.align_in_motion(imu, tf, vel, lat, h, k0, k1)
    assert m.t_ref == pytest.approx(18.0) and m.n_vectors == 18
    for C, t in ((m.C_bn, m.t_ref), (m.C_bn_start, m.t_first)):
        i = int(round((t - tru.t[0]) / 0.01))
        err = A.misalignment(A.euler_to_dcm(tru.att[i]), C)
        assert np.all(np.abs(np.degrees(err)) < 0.01), np.degrees(err)
    assert np.all(np.degrees(m.sigma) < 0.02)


def test_alignment_sigma_covers_noisy_velocity(flight):
    """Velocity noise 0.1 m/s: the errors at the end of the window are within 3σ of the fit
    in every axis over 20 noise draws (all 60 below 3.5σ: a 3σ bound fails once in 60
    draws with probability 0.15), and the heading, seen through the
    acceleration and the turn, within 3°."""
    imu, tru = flight
    tf = np.arange(1.0, 18.01, 1.0)
    v0 = np.stack([np.interp(tf, tru.t, tru.vel[:, i]) for i in range(3)], -1)
    lat, h = np.interp(tf, tru.t, tru.lat), np.interp(tf, tru.t, tru.h)
    k0, k1 = int(np.searchsorted(imu.t, 1.0)), int(np.searchsorted(imu.t, 18.0 - 1e-9)) + 1
    i = int(round((18.0 - tru.t[0]) / 0.01))
    Ct = A.euler_to_dcm(tru.att[i])
    rng = np.random.default_rng(11)
    z = []
    for _ in range(20):
        m = M.align_in_motion(imu, tf, v0 + rng.normal(0, 0.1, v0.shape), lat, h, k0, k1)
        err = A.misalignment(Ct, m.C_bn)
        z.append(np.abs(err) / m.sigma)
        assert abs(math.degrees(err[2])) < 3.0
    assert np.max(z) < 3.5 and np.mean(np.array(z) < 1.0) > 0.5, np.max(z, 0)


def test_too_few_fixes_give_none(flight):
    """Fewer than four usable fixes in the span (a fix without a vertical velocity is not
    usable): no alignment."""
    imu, tru = flight
    tf = np.array([1.0, 2.0])
    assert M.align_in_motion(imu, tf, np.zeros((2, 3)), np.full(2, 0.7), np.zeros(2), 100, 200) is None
    tf = np.arange(1.0, 6.01, 1.0)
    vel = np.stack([np.interp(tf, tru.t, tru.vel[:, i]) for i in range(3)], -1)
    lat, h = np.interp(tf, tru.t, tru.lat), np.interp(tf, tru.t, tru.h)
    k0, k1 = int(np.searchsorted(imu.t, 1.0)), int(np.searchsorted(imu.t, 6.0 - 1e-9)) + 1
    assert M.align_in_motion(imu, tf, vel, lat, h, k0, k1).n_vectors == 6
    vel[1:4, 2] = np.nan
    assert M.align_in_motion(imu, tf, vel, lat, h, k0, k1) is None
