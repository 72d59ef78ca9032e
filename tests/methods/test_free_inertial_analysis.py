"""Oracles of the free-inertial analysis library: the Schuler-period fit against a
synthetic Foucault-split oscillation, the batch matrix exponential against scipy."""
import numpy as np
import pytest
import scipy.linalg

from sinslab.core import earth, units
from sinslab.methods import free_inertial as fi


def test_fit_schuler_period_recovers_a_foucault_split_oscillation():
    lat = 40 * units.deg
    ws = 2 * np.pi / earth.schuler_period(lat)
    wf = earth.WIE * np.sin(lat)
    t = np.arange(0.0, 2 * 3600.0, 1.0)
    z = np.exp(-1j * wf * t) * (0.3 * np.exp(1j * ws * t) + 0.2j * np.exp(-1j * ws * t)) + 0.05 + 1e-6 * t
    v = np.column_stack([z.real, z.imag]) + np.random.default_rng(0).normal(0, 1e-3, (t.size, 2))
    p = fi.fit_schuler_period(t, v)
    assert p == pytest.approx(2 * np.pi / ws, rel=1e-3)


def test_expm_batch_matches_scipy():
    A = np.random.default_rng(1).normal(size=(4, 9, 9)) * np.array([0.01, 1, 10, 30])[:, None, None]
    ref = np.stack([scipy.linalg.expm(a) for a in A])
    got = fi._expm_batch(A)
    assert np.allclose(got, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())
