"""Oscillation-component analysis: known synthetic amplitudes, the closed-form Schuler loop,
the static error model (Foucault splitting), spectra and bad input."""
import math

import numpy as np
import pytest
from scipy.linalg import expm

from sinslab.core import earth
from sinslab.methods import oscillation as osc

LAT = math.radians(45.75)
W = osc.known_frequencies(LAT)


def test_known_frequencies_match_earth_model():
    ws = float(earth.schuler_frequency(LAT))
    wf = earth.WIE * math.sin(LAT)
    assert W["schuler"] == pytest.approx(ws)
    assert W["schuler_plus"] - W["schuler"] == pytest.approx(wf)
    assert W["schuler"] - W["schuler_minus"] == pytest.approx(wf)
    assert W["earth"] == earth.WIE
    assert 2 * math.pi / ws / 60 == pytest.approx(84.4, abs=0.2)     # ≈ 84.4 min


def test_fit_recovers_known_lines_bias_trend_and_noise():
    t = np.arange(0.0, 48 * 3600.0, 10.0)
    rng = np.random.default_rng(3)
    x = (0.30 * np.cos(W["schuler"] * t + 0.4) + 0.20 * np.sin(W["schuler_plus"] * t)
         + 0.10 * np.cos(W["schuler_minus"] * t + 1.0) + 0.50 * np.sin(W["earth"] * t + 0.3)
         + 1.0 + 2e-5 * t + rng.normal(0, 0.05, t.size))
    c = osc.fit_components(t, x, lat=LAT)
    assert c.foucault_fitted and c.earth_fitted
    assert c.lines["schuler"][1] == pytest.approx(0.30, abs=0.005)
    assert c.lines["schuler_plus"][1] == pytest.approx(0.20, abs=0.005)
    assert c.lines["schuler_minus"][1] == pytest.approx(0.10, abs=0.005)
    assert c.earth == pytest.approx(0.50, abs=0.01)
    assert c.lines["schuler"][2] == pytest.approx(-0.4, abs=0.03)        # A cos(ωt − phase)
    assert c.bias == pytest.approx(1.0, abs=0.02)
    assert c.trend == pytest.approx(2e-5 * t[-1], rel=0.02)
    assert c.residual_rms == pytest.approx(0.05, rel=0.05)
    # the equivalent amplitude is √2·RMS of the fitted band
    band = c.band("schuler")
    assert c.schuler == pytest.approx(math.sqrt(2 * np.mean(band ** 2)))


def test_pure_sinusoid_equivalent_amplitude_is_its_amplitude():
    t = np.arange(0.0, 24 * 3600.0, 5.0)
    c = osc.fit_components(t, 0.7 * np.sin(W["schuler"] * t + 1.1), lat=LAT)
    assert c.schuler == pytest.approx(0.7, rel=0.01)
    assert c.earth == pytest.approx(0.0, abs=1e-6)


def test_modulated_schuler_gives_side_lines_and_a_over_sqrt2():
    """z = A cos(ω_f t) sin(ω_s t) (paper eq 11) = two side lines of A/2."""
    wf = W["schuler_plus"] - W["schuler"]
    T = 2 * math.pi / wf * 2                   # two Foucault periods
    t = np.arange(0.0, T, 10.0)
    A = 0.8
    c = osc.fit_components(t, A * np.cos(wf * t) * np.sin(W["schuler"] * t), lat=LAT)
    assert c.lines["schuler_plus"][1] == pytest.approx(A / 2, rel=0.01)
    assert c.lines["schuler_minus"][1] == pytest.approx(A / 2, rel=0.01)
    assert c.lines["schuler"][1] == pytest.approx(0.0, abs=0.01 * A)
    assert c.schuler == pytest.approx(A / math.sqrt(2), rel=0.01)
    assert c.foucault == pytest.approx(A / math.sqrt(2), rel=0.01)


def test_short_record_leaves_out_unresolvable_lines():
    t = np.arange(0.0, 5 * 3600.0, 10.0)
    c = osc.fit_components(t, np.sin(W["schuler"] * t), lat=LAT)
    assert not c.foucault_fitted and not c.earth_fitted
    assert math.isnan(c.foucault) and math.isnan(c.earth)
    assert len(c.notes) == 2
    assert c.schuler == pytest.approx(1.0, rel=0.01)


def _schuler_loop(t, phi0, dv0, nabla, eps, R, g):
    """Closed form of the single-axis Schuler loop (no Earth rate):
    δv̇ = g φ + ∇,  φ̇ = −δv/R − ε  (east tilt φ, north velocity δv)."""
    ws = math.sqrt(g / R)
    s, c = np.sin(ws * t), np.cos(ws * t)
    dv = dv0 * c + (g * phi0 + nabla) / ws * s - R * eps * (1 - c)
    phi = phi0 * c - dv0 / (R * ws) * s - nabla / g * (1 - c) - eps / ws * s
    return dv, phi, ws


def test_closed_form_schuler_loop_amplitudes():
    R, g = 6.371e6, 9.8
    phi0, dv0, nabla, eps = 1e-4, 0.1, 5e-4, 5e-8
    ws = math.sqrt(g / R)
    t = np.arange(0.0, 12 * 3600.0, 5.0)
    dv, phi, _ = _schuler_loop(t, phi0, dv0, nabla, eps, R, g)
    # the closed form solves the ODE
    F = np.array([[0.0, g], [-1 / R, 0.0]])
    x = expm(F * 1000.0) @ [dv0, phi0] + np.linalg.solve(F, (expm(F * 1000.0) - np.eye(2)) @ [nabla, -eps])
    k = int(1000 / 5)
    assert dv[k] == pytest.approx(x[0], rel=1e-9) and phi[k] == pytest.approx(x[1], rel=1e-9)
    amp_v = math.hypot(dv0 + R * eps, (g * phi0 + nabla) / ws)
    amp_p = math.hypot(phi0 + nabla / g, dv0 / (R * ws) + eps / ws)
    cv = osc.fit_components(t, dv, lat=0.0, omega_s=ws, earth=False, foucault=False)
    cp = osc.fit_components(t, phi, lat=0.0, omega_s=ws, earth=False, foucault=False)
    assert cv.schuler == pytest.approx(amp_v, rel=3e-3)
    assert cp.schuler == pytest.approx(amp_p, rel=3e-3)
    assert cv.bias == pytest.approx(-R * eps, rel=1e-3)              # the −Rε(1 − cos) offset


def _modal_closed_form(F, x0, t):
    """Closed form of ẋ = F x (F diagonalisable): x(t) = Σ_i c_i e^{λ_i t} v_i, and the
    amplitude of every oscillation frequency |Im λ| in every state (2|c_i v_ji| per pair)."""
    lam, V = np.linalg.eig(F)
    c = np.linalg.solve(V, x0)
    x = (V[None, :, :] * (c * np.exp(np.outer(t, lam)))[:, None, :]).sum(-1).real
    amps = {}
    for i, l in enumerate(lam):
        if l.imag > 1e-9:
            amps[round(l.imag, 10)] = 2 * np.abs(c[i] * V[:, i])
    return x, amps


def test_static_error_model_lines_match_modal_closed_form():
    """Static-base error model of sinslab.nav.errstate (horizontal core, 45.75°): its modes are
    the 24 h line and the Schuler line split by Foucault (ω_s ± ω_ie sinL); the fitted
    amplitudes of a 72 h response match the modal closed form."""
    from sinslab.nav import errstate

    g = float(earth.gravity(LAT))
    F = errstate.ErrorModel("horizontal").F(errstate.NavPoint(
        lat=LAT, h=0.0, vel=np.zeros(3), Cbn=np.eye(3), fb=np.array([0.0, 0.0, g])))
    lam = np.sort(np.abs(np.linalg.eigvals(F).imag))
    wf = W["schuler_plus"] - W["schuler"]
    # eigenfrequencies: 0, ω_ie, ≈ ω_s ± ω_f (to 1e-6 rad/s)
    assert lam[2] == pytest.approx(earth.WIE, rel=1e-9)
    assert lam[4] == pytest.approx(W["schuler_minus"], abs=2e-6)
    assert lam[6] == pytest.approx(W["schuler_plus"], abs=2e-6)
    assert lam[6] - lam[4] == pytest.approx(2 * wf, rel=0.01)
    t = np.arange(0.0, 72 * 3600.0, 60.0)
    # states: φE φN φU δvE δvN δL δλ ; initial tilt, heading error, velocity error
    x0 = np.array([1e-4, -5e-5, 1e-3, 0.05, 0.1, 0.0, 0.0])
    x, amps = _modal_closed_form(F, x0, t)
    # the closed form solves the ODE (expm oracle)
    assert np.allclose(x[600], expm(F * t[600]) @ x0, rtol=1e-8, atol=1e-12)
    keys = sorted(amps)
    w_e, w_m, w_p = keys
    for j, scale in ((0, 1e-4), (1, 1e-4), (3, 0.1), (4, 0.1)):
        c = osc.fit_components(t, x[:, j], lat=LAT)
        assert c.lines["schuler_minus"][1] == pytest.approx(amps[w_m][j], rel=0.05, abs=0.02 * scale)
        assert c.lines["schuler_plus"][1] == pytest.approx(amps[w_p][j], rel=0.05, abs=0.02 * scale)
        assert c.lines["schuler"][1] < 0.05 * max(amps[w_m][j], amps[w_p][j]) + 0.02 * scale
        assert c.earth == pytest.approx(amps[w_e][j], rel=0.05, abs=0.02 * scale)


@pytest.mark.parametrize("method", ["periodogram", "lombscargle"])
def test_spectrum_peak_height_is_amplitude(method):
    t = np.arange(0.0, 48 * 3600.0, 20.0)
    f0 = W["schuler"] / (2 * math.pi)
    x = 0.4 * np.sin(2 * math.pi * f0 * t + 0.3) + 0.001 * t / 3600
    f, a = osc.amplitude_spectrum(t, x, method=method, fmax=3 * f0)
    fp, ap = osc.band_peak(f, a, 0.9 * f0, 1.1 * f0)
    assert fp == pytest.approx(f0, rel=2e-3)
    assert ap == pytest.approx(0.4, rel=0.02)


def test_lombscargle_with_gaps():
    t = np.arange(0.0, 24 * 3600.0, 20.0)
    keep = (t < 6 * 3600) | (t > 8 * 3600)
    f0 = W["schuler"] / (2 * math.pi)
    x = 0.25 * np.cos(2 * math.pi * f0 * t)
    with pytest.raises(ValueError, match="uniform"):
        osc.amplitude_spectrum(t[keep], x[keep])
    f, a = osc.amplitude_spectrum(t[keep], x[keep], method="lombscargle", fmax=3 * f0)
    assert osc.band_peak(f, a, 0.9 * f0, 1.1 * f0)[1] == pytest.approx(0.25, rel=0.1)
    c = osc.fit_components(t[keep], x[keep], lat=LAT)
    assert c.lines["schuler"][1] == pytest.approx(0.25, rel=0.01)


def test_bad_input():
    t = np.arange(0.0, 100.0)
    with pytest.raises(ValueError, match="same length"):
        osc.fit_components(t, t[:-1], lat=LAT)
    with pytest.raises(ValueError, match="increasing"):
        osc.fit_components(t[::-1], t, lat=LAT)
    with pytest.raises(ValueError, match="at least 8"):
        osc.fit_components(t[:5], t[:5], lat=LAT)
    with pytest.raises(ValueError, match="method"):
        osc.amplitude_spectrum(t, t, method="welch2")
    with pytest.raises(ValueError, match="no spectrum bins"):
        osc.band_peak(np.arange(5.0), np.ones(5), 10, 20)
    # NaN samples are dropped, not propagated
    x = np.sin(W["schuler"] * np.arange(0, 20000.0, 10))
    x[100] = np.nan
    c = osc.fit_components(np.arange(0, 20000.0, 10), x, lat=LAT)
    assert c.schuler == pytest.approx(1.0, rel=0.02)
