"""Independent checks of sinslab.core.earth against WGS-84 closed forms and published values."""
import math

import numpy as np
import pytest

from sinslab.core import earth

A, F = 6378137.0, 1 / 298.257223563
E2 = F * (2 - F)
D = math.pi / 180


def test_constants():
    assert earth.A == A and earth.F == F
    assert earth.E2 == pytest.approx(0.00669437999014, rel=1e-12)
    assert earth.B == pytest.approx(6356752.314245, abs=1e-6)
    assert earth.WIE == 7.2921151467e-5


def test_radii_closed_forms():
    rm, rn = earth.radii(0.0)
    assert rn == pytest.approx(A, rel=1e-15)                       # R_N(0) = a
    assert rm == pytest.approx(A * (1 - E2), rel=1e-15)            # R_M(0) = a(1-e²)
    rm, rn = earth.radii(math.pi / 2)
    assert rn == pytest.approx(A / math.sqrt(1 - E2), rel=1e-14)   # R_N(90°) = a/sqrt(1-e²)
    assert rm == pytest.approx(A / math.sqrt(1 - E2), rel=1e-14)   # R_M = R_N at the pole = a²/b
    assert rm == pytest.approx(A * A / earth.B, rel=1e-12)
    # known values at 45°: R_M = 6367381.8 m, R_N = 6388838.3 m
    rm, rn = earth.radii(45 * D)
    assert rm == pytest.approx(6367381.816, abs=0.01)
    assert rn == pytest.approx(6388838.290, abs=0.01)
    # height adds to both
    rm_h, rn_h = earth.radii(45 * D, 1000.0)
    assert rm_h - rm == pytest.approx(1000.0) and rn_h - rn == pytest.approx(1000.0)
    # broadcasting, symmetry in latitude
    lat = np.linspace(-1.5, 1.5, 7)
    rm, rn = earth.radii(lat, 0.0)
    assert rm.shape == (7,) and np.allclose(rm, rm[::-1]) and np.allclose(rn, rn[::-1])


def test_meridian_radius_is_curvature_of_the_ellipse():
    """R_M = ds/dL: meridian arc length by finite difference of the ellipse parametrisation."""
    for L in (0.1, 0.7, 1.3):
        def xz(lat):
            rn = A / math.sqrt(1 - E2 * math.sin(lat) ** 2)
            return rn * math.cos(lat), rn * (1 - E2) * math.sin(lat)
        h = 1e-6
        (x1, z1), (x2, z2) = xz(L - h), xz(L + h)
        ds = math.hypot(x2 - x1, z2 - z1) / (2 * h)
        assert float(earth.radii(L)[0]) == pytest.approx(ds, rel=1e-8)


def test_numba_scalars_match_numpy():
    for lat in (-1.2, -0.3, 0.0, 0.5972, 1.4):
        for h in (0.0, 1000.0, -50.0):
            rm, rn = earth.radii(lat, h)
            rm_s, rn_s = earth.radii_s(lat, h)
            assert rm_s == pytest.approx(float(rm), rel=1e-15)
            assert rn_s == pytest.approx(float(rn), rel=1e-15)
            assert earth.gravity_s(lat, h) == pytest.approx(float(earth.gravity(lat, h)), rel=1e-15)


def test_gravity_somigliana_values():
    assert float(earth.gravity(0.0)) == pytest.approx(9.7803267714, abs=1e-10)
    assert float(earth.gravity(math.pi / 2)) == pytest.approx(9.8321863685, abs=1e-9)
    assert float(earth.gravity(-math.pi / 2)) == pytest.approx(9.8321863685, abs=1e-9)
    # 45°: 9.806199203 m/s² (WGS-84 normal gravity)
    assert float(earth.gravity(45 * D)) == pytest.approx(9.806199203, abs=1e-8)
    # free-air gradient: 3.086e-6 /s² (≈ 0.3086 mGal/m)
    g0, g1 = earth.gravity(0.6, 0.0), earth.gravity(0.6, 1000.0)
    assert float(g0 - g1) == pytest.approx(3.086e-3, rel=1e-9)
    gv = earth.gravity_vector(np.array([0.1, 0.2]), 0.0)
    assert gv.shape == (2, 3) and np.all(gv[:, :2] == 0) and np.all(gv[:, 2] < -9.7)


def test_earth_rate():
    w = earth.wie_n(0.6)
    assert np.allclose(w, [0, earth.WIE * math.cos(0.6), earth.WIE * math.sin(0.6)], rtol=1e-15)
    assert np.linalg.norm(w) == pytest.approx(earth.WIE)
    assert earth.wie_n(np.zeros(4)).shape == (4, 3)


def test_transport_rate():
    lat, h = 0.6, 1000.0
    vE, vN = 200.0, -150.0
    rm, rn = earth.radii(lat, h)
    w = earth.wen_n(lat, h, [vE, vN, 3.0])
    assert np.allclose(w, [-vN / rm, vE / rn, vE * math.tan(lat) / rn], rtol=1e-15)
    # physical check: flying north at v, the n frame turns about west (−E) at v/(R_M+h)
    w = earth.wen_n(0.0, 0.0, [0.0, 100.0, 0.0])
    assert w[0] == pytest.approx(-100.0 / (A * (1 - E2))) and w[1] == 0 and w[2] == 0
    # rates of change of position: dL/dt = vN/(R_M+h), dλ/dt = vE/((R_N+h) cos L)
    mL, ml = earth.metres_per_rad(lat, h)
    assert float(mL) == pytest.approx(float(rm)) and float(ml) == pytest.approx(float(rn) * math.cos(lat))
    assert np.allclose(earth.win_n(lat, h, [vE, vN, 0]), earth.wie_n(lat) + earth.wen_n(lat, h, [vE, vN, 0]))
    # broadcasting over arrays of states
    v = np.tile([10.0, 20.0, 0.0], (5, 1))
    assert earth.wen_n(np.linspace(0, 1, 5), 0.0, v).shape == (5, 3)


def test_schuler_and_foucault():
    T = float(earth.schuler_period(0.0)) / 60
    assert T == pytest.approx(84.4, abs=0.2)
    # independent: 2π sqrt(R/g) with the local Gaussian mean radius
    L = 34.246 * D
    rm, rn = earth.radii(L)
    Tl = 2 * math.pi * math.sqrt(math.sqrt(rm * rn) / earth.gravity(L))
    assert float(earth.schuler_period(L)) == pytest.approx(Tl, rel=1e-12)
    assert 84.0 < float(earth.schuler_period(L)) / 60 < 84.6
    assert float(earth.schuler_frequency(L)) == pytest.approx(2 * math.pi / Tl, rel=1e-12)
    # half a Schuler period ≈ 42.2 min (paper 004)
    assert float(earth.schuler_period(L)) / 120 == pytest.approx(42.2, abs=0.1)
    # Foucault: ω_ie sin L, period 2π/(ω_ie sin L): ≈ 33.9 h at 45°
    assert float(earth.foucault_frequency(L)) == pytest.approx(earth.WIE * math.sin(L))
    assert 2 * math.pi / float(earth.foucault_frequency(45 * D)) / 3600 == pytest.approx(33.85, abs=0.05)
    assert float(earth.foucault_frequency(-L)) < 0


@pytest.mark.parametrize("lat", [math.pi / 2 + 1e-9, -2.0, np.nan, np.inf, [0.1, 1.7]])
def test_latitude_errors(lat):
    with pytest.raises(ValueError, match="latitude"):
        earth.check_latitude(lat)


def test_latitude_message_names_the_value():
    with pytest.raises(ValueError, match="100 deg"):
        earth.check_latitude(100 * D)
    with pytest.raises(ValueError, match="-95 deg"):
        earth.check_latitude(np.array([0.0, -95 * D]))
    earth.check_latitude(np.array([-math.pi / 2, 0.0, math.pi / 2]))    # the poles are fine


def test_latitude_check_on_2d_arrays():
    with pytest.raises(ValueError, match="110 deg"):
        earth.check_latitude(np.array([[0.1, 0.2], [0.3, 110 * D]]))
