"""sinslab.nav.magnetic: the geomagnetic reference field (IGRF-14 through ppigrf) against an
independent model (the World Magnetic Model 2010 through pygeomag, a development
dependency), and the magnetometer calibrations against a known hard and soft iron."""
import datetime
import math

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.nav import magnetic as M
from support import assert_doc_quotes

#: places (lat, lon [deg], h [m]) over both hemispheres, the equator and a volcano's height
PLACES = [(45.33, -93.23, 250.0), (0.0, 0.0, 0.0), (-33.9, 18.4, 100.0), (60.4, 5.3, 0.0),
          (35.7, 139.7, 40.0), (-45.0, 170.0, 1000.0), (20.0, -155.0, 3000.0)]


def test_igrf_agrees_with_the_world_magnetic_model():
    """IGRF-14 and WMM2010 are two models fitted independently (IAGA; NOAA/BGS) to the same
    main field: in 2012.5 they differ by tens of nT per component, a tenth of a degree in D
    and I (measured: at most 61 nT, 0.12°). Agreement within 100 nT and 0.2° at every place
    checks the frames (ENU, geodetic), the units (nT -> T, m -> km) and the sign of up."""
    GeoMag = pytest.importorskip("pygeomag").GeoMag
    wmm = GeoMag(coefficients_file="wmm/WMM_2010.COF")
    lat, lon, h = (np.array(c) for c in zip(*PLACES))
    rf = M.reference_field(np.radians(lat), np.radians(lon), h, 2012.5)
    assert rf.b_n.shape == (len(PLACES), 3) and rf.model.startswith("IGRF-14")
    worst = np.zeros(3)
    for i, (la, lo, hh) in enumerate(PLACES):
        w = wmm.calculate(glat=la, glon=lo, alt=hh / 1000.0, time=2012.5)
        b_wmm = np.array([w.y, w.x, -w.z]) * 1e-9                 # north, east, down -> ENU [T]
        assert np.all(np.abs(rf.b_n[i] - b_wmm) < 100e-9), (PLACES[i], rf.b_n[i], b_wmm)
        assert abs(math.degrees(rf.declination[i]) - w.d) < 0.2
        assert abs(math.degrees(rf.inclination[i]) - w.i) < 0.2
        assert abs(rf.intensity[i] - w.f * 1e-9) < 100e-9
        worst = np.maximum(worst, [np.max(np.abs(rf.b_n[i] - b_wmm)) * 1e9, abs(math.degrees(rf.declination[i]) - w.d),
                                   abs(math.degrees(rf.inclination[i]) - w.i)])
    assert_doc_quotes("docs/aiding.md", "in 2012.5: the largest differences are 61 nT in a component, 0.12° in "
                      "declination and 0.12° in inclination", [2012.5, *worst])


def test_dates_and_the_models_span():
    assert M.decimal_year("2012-07-02") == pytest.approx(2012.5, abs=2e-3)
    assert M.decimal_year(datetime.date(2000, 1, 1)) == 2000.0
    assert M.decimal_year(2012.25) == 2012.25
    with pytest.raises(ValueError, match="outside the IGRF-14 span"):
        M.reference_field(0.8, -1.6, 0.0, "2035-01-01")
    with pytest.raises(ValueError, match="not a date"):
        M.decimal_year("yesterday")
    # the secular variation is applied: the field of 1990 is not that of 2020 (Minnesota's
    # declination moved east by about 5° in those 30 years)
    d = [float(np.degrees(M.reference_field(0.79, -1.63, 0.0, y).declination)) for y in (1990.0, 2020.0)]
    assert 2.0 < d[0] - d[1] or 2.0 < d[1] - d[0]


def _sphere(n, rng):
    u = rng.normal(size=(n, 3))
    return u / np.linalg.norm(u, axis=1, keepdims=True)


#: a symmetric soft iron (scale 0.9..1.15, cross-coupling a few per cent) and a hard iron
#: of a fifth of the field [T]
SOFT = np.array([[1.10, 0.03, -0.02], [0.03, 0.92, 0.04], [-0.02, 0.04, 1.05]])
HARD = np.array([8e-6, -5e-6, 12e-6])
F = 55e-6


def test_ellipsoid_fit_recovers_a_known_hard_and_soft_iron():
    """Readings of a 55 µT field over the whole sphere through a known symmetric soft iron
    and hard iron, 0.1 µT noise: the fit gives the hard iron within 0.05 µT, the inverse
    soft iron within 0.5 %, the calibrated magnitude at F within 0.3 %, full coverage."""
    rng = np.random.default_rng(4)
    b = F * _sphere(4000, rng)
    cal_true = M.MagCalibration(np.linalg.inv(SOFT), HARD)
    raw = cal_true.distort(b) + rng.normal(scale=0.1e-6, size=b.shape)
    cal, fit = M.ellipsoid_fit(raw, F)
    np.testing.assert_allclose(cal.hard, HARD, atol=0.05e-6)
    np.testing.assert_allclose(cal.soft, np.linalg.inv(SOFT), atol=5e-3)
    assert fit.residual < 3e-3 and np.all(fit.coverage > 0.5)


def test_ellipsoid_fit_refuses_readings_on_a_cone():
    """A vehicle turning level sees the field on a cone (the vertical part constant): the
    ellipsoid is not determined and the fit says so instead of returning a calibration."""
    psi = np.linspace(0.0, 4 * np.pi, 2000)
    inc = math.radians(72.0)
    b = F * np.column_stack([math.cos(inc) * np.cos(psi), math.cos(inc) * np.sin(psi),
                             np.full_like(psi, -math.sin(inc))])
    with pytest.raises(ValueError, match="turn too little"):
        M.ellipsoid_fit(M.MagCalibration(np.linalg.inv(SOFT), HARD).distort(b), F)


def test_attitude_fit_recovers_a_general_soft_iron():
    """With the attitude known the twelve parameters of ``m = S b + h`` are linear: a
    non-symmetric S (a rotated sensor) and h are recovered to the noise."""
    rng = np.random.default_rng(5)
    att = np.column_stack([rng.uniform(-0.5, 0.5, 500), rng.uniform(-0.8, 0.8, 500), rng.uniform(-np.pi, np.pi, 500)])
    C = A.euler_to_dcm(att)
    bn = np.array([0.2e-6, 17.2e-6, -53.2e-6])
    S = SOFT @ A.euler_to_dcm(np.array([0.02, -0.03, 0.05]))
    raw = np.einsum("ij,kj->ki", S, np.einsum("kji,j->ki", C, bn)) + HARD + rng.normal(scale=0.05e-6, size=(500, 3))
    cal = M.attitude_fit(raw, C, bn)
    np.testing.assert_allclose(np.linalg.inv(cal.soft), S, atol=3e-3)
    np.testing.assert_allclose(cal.hard, HARD, atol=0.05e-6)


def test_calibration_round_trip_and_refusals():
    cal = M.MagCalibration(np.linalg.inv(SOFT), HARD)
    b = F * _sphere(10, np.random.default_rng(1))
    np.testing.assert_allclose(cal.apply(cal.distort(b)), b, atol=1e-18)
    with pytest.raises(ValueError, match="singular"):
        M.MagCalibration(np.zeros((3, 3)), HARD)


@pytest.mark.parametrize("unit", ["G", "uT", "nT", "mG", "T"])
def test_the_unit_a_log_is_in_is_told_by_its_magnitude(unit):
    """A field of 56 µT written in any unit, with hard iron moving the magnitude by 20 %,
    is recognised as that unit (a µT file declared as gauss reads 100× the model)."""
    rng = np.random.default_rng(2)
    raw = (1.2 * 56e-6 * _sphere(100, rng)) / M.FIELD_UNITS[unit]
    assert M.likely_field_unit(raw, 56e-6) == unit
