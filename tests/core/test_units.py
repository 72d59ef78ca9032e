"""Independent checks of sinslab.core.units against hand-computed SI values."""
import math

import numpy as np
import pytest

from sinslab.core import units as u

D = math.pi / 180


@pytest.mark.parametrize("text,kind,si", [
    ("0.01 deg/h", "angular_rate", 0.01 * D / 3600),
    ("100 ug", "acceleration", 100e-6 * 9.80665),
    ("0.001 deg/sqrt(h)", "angle_random_walk", 0.001 * D / 60),
    ("10 ug/sqrt(Hz)", "velocity_random_walk", 10e-6 * 9.80665),
    ("10 arcmin", "angle", 10 * D / 60),
    ("2.1 arcsec", "angle", 2.1 * D / 3600),
    ("42.2 min", "time", 42.2 * 60),
    ("9.8 m/s^2", "acceleration", 9.8),
    ("9.8 m/s/s", "acceleration", 9.8),
    ("1e-4 g", "acceleration", 1e-4 * 9.80665),
    ("-6.9 arcmin", "angle", -6.9 * D / 60),
    ("5e-5 g/sqrt(Hz)", "velocity_random_walk", 5e-5 * 9.80665),
    ("0.001 deg/h/sqrt(Hz)", "angle_random_walk", 0.001 * D / 3600),
    ("0.0001 deg/h/sqrt(h)", "rate_random_walk", 1e-4 * D / 3600 / 60),
    ("1 m/s/sqrt(h)", "velocity_random_walk", 1 / 60),
    ("200 ppm", "dimensionless", 2e-4),
    ("300 s", "time", 300.0),
    ("24 h", "time", 86400.0),
    ("100 Hz", "frequency", 100.0),
    ("34.246 deg", "angle", 34.246 * D),
    ("15 m/s", "velocity", 15.0),
    ("1000 m", "length", 1000.0),
    ("1 NM", "length", 1852.0),
    (".5 deg", "angle", 0.5 * D),
    ("  60 ' ", "angle", D),
    ("10 µg", "acceleration", 10e-6 * 9.80665),
    ("1 °/h", "angular_rate", D / 3600),
])
def test_parse_known_values(text, kind, si):
    assert u.parse(text, kind) == pytest.approx(si, rel=1e-13)
    assert u.parse(text) == pytest.approx(si, rel=1e-13)        # no kind: no check


def test_constants():
    assert u.dph == pytest.approx(D / 3600, rel=1e-15)
    assert u.dpsh == pytest.approx(D / 60, rel=1e-15)
    assert u.ug == pytest.approx(9.80665e-6, rel=1e-15)
    assert u.arcsec * 3600 == pytest.approx(D, rel=1e-15)
    assert u.ugpsHz == u.ug
    assert u.dphpsh == pytest.approx(D / 3600 / 60, rel=1e-15)
    # datasheet identity: 1 deg/h/sqrt(Hz) == 1/60 deg/sqrt(h)
    assert u.parse("1 deg/h/sqrt(Hz)", "angle_random_walk") == pytest.approx(u.dpsh / 60, rel=1e-14)


def test_parse_vector_forms():
    exp = np.array([0.003, -0.002, 0.0005]) * u.dph
    assert np.allclose(u.parse_vector("[0.003, -0.002, 0.0005] deg/h", "angular_rate"), exp, rtol=1e-14)
    assert np.allclose(u.parse_vector(["0.003 deg/h", "-0.002 deg/h", "0.0005 deg/h"], "angular_rate"),
                       exp, rtol=1e-14)
    assert np.allclose(u.parse_vector("[0.003 -0.002 0.0005] deg/h", "angular_rate"), exp, rtol=1e-14)
    one = u.parse_vector("0.01 deg/h", "angular_rate")
    assert one.shape == (3,) and np.all(one == 0.01 * u.dph)
    assert np.array_equal(u.parse_vector(["10 arcmin"], "angle"), np.full(3, 10 * u.arcmin))
    assert u.parse_vector("[1, 2] ug", "acceleration", n=2).shape == (2,)
    with pytest.raises(ValueError, match="expected 3 values, got 2"):
        u.parse_vector("[2e-5, -4e-5] g", "acceleration")
    with pytest.raises(ValueError):
        u.parse_vector(["1 deg", "2 m", "3 deg"], "angle")


@pytest.mark.parametrize("text,kind,match", [
    ("0.01 deg/h", "angle", "expected angle"),
    ("100 ug", "angular_rate", "acceleration.*expected angular rate"),
    ("0.1 deg/h", "angle_random_walk", "expected angle random walk"),
    ("10 ug", "velocity_random_walk", "expected velocity random walk"),
    ("10 m", "angle", "length.*expected angle"),
    ("10", "angle", "no unit"),
    ("deg", "angle", "does not start with a number"),
    ("", "angle", "does not start with a number"),
    ("ten deg", "angle", "does not start with a number"),
    ("10 furlong", "length", "unknown unit 'furlong'"),
    ("10 deg/", "angular_rate", "cannot read unit"),
    ("10 sqrt(h", "time", "cannot read unit"),
    ("10 deg)", "angle", "cannot read unit"),
    ("10 deg$", "angle", "cannot read unit"),
    ("1e999 deg", "angle", "not finite"),
])
def test_parse_errors(text, kind, match):
    with pytest.raises(ValueError, match=match):
        u.parse(text, kind)


def test_bare_numbers():
    with pytest.raises(ValueError, match="no unit"):
        u.parse(0.01, "angular_rate")
    with pytest.raises(ValueError, match="no unit"):
        u.parse(np.float64(3.0), "time")
    assert u.parse(0.5, "dimensionless") == 0.5
    assert u.parse("0.5", "dimensionless") == 0.5
    assert u.parse(2) == 2.0
    with pytest.raises(ValueError):
        u.parse(True, "dimensionless")
    with pytest.raises(ValueError):
        u.parse(None, "angle")
    with pytest.raises(ValueError, match="unknown quantity kind"):
        u.parse("1 deg", "angel")


def test_unit_error_is_value_error():
    assert issubclass(u.UnitError, ValueError)


def test_format_quantity_round_trip():
    s = u.format_quantity(0.01 * u.dph, "deg/h")
    assert s == "0.01 deg/h"
    assert u.parse(s, "angular_rate") == pytest.approx(0.01 * u.dph, rel=1e-12)
    assert u.parse(u.format_quantity(7.3e-4, "ug/sqrt(Hz)"), "velocity_random_walk") == pytest.approx(
        7.3e-4, rel=1e-6)


@pytest.mark.parametrize("text,kind,si", [
    ("0.001 °/√h", "angle_random_walk", 0.001 * D / 60),
    ("10 µg/√Hz", "velocity_random_walk", 10e-6 * 9.80665),
    ("0.001 deg/√(h)", "angle_random_walk", 0.001 * D / 60),
    ("9.8 m/s²", "acceleration", 9.8),
    ("0.001 deg/h²", None, 0.001 * D / 3600 ** 2),
])
def test_paper_notation(text, kind, si):
    """Units as the papers print them (√, superscript exponents)."""
    assert u.parse(text, kind) == pytest.approx(si, rel=1e-13)


def test_vec3_forms_and_errors():
    """The one per-axis validator: scalar, 1 or 3 values, default for None, read-only option,
    and one clear error for each bad input."""
    assert np.array_equal(u.vec3(2.0, "b"), [2.0, 2.0, 2.0])
    assert np.array_equal(u.vec3([5], "b"), [5.0, 5.0, 5.0])
    src = [1.0, -2.0, 3.0]
    a = u.vec3(src, "b")
    a[0] = 9.0
    assert src[0] == 1.0                                   # a copy, never a view
    assert np.array_equal(u.vec3(None, "lever", default=0.0), np.zeros(3))
    assert not u.vec3(1.0, "b", readonly=True).flags.writeable
    assert np.isinf(u.vec3(math.inf, "tau")).all()         # inf allowed unless finite=True
    for v, kw, msg in [([1, 2], {}, r"b must be 1 or 3 values, got shape \(2,\)"),
                       ([1, math.nan, 2], {}, "b is NaN"),
                       ([1, -1, 2], {"nonneg": True}, r"b must be >= 0, got \[1.0, -1.0, 2.0\]"),
                       (math.inf, {"finite": True}, "b must be finite"),
                       (None, {}, "b is missing")]:
        with pytest.raises(ValueError, match=msg):
            u.vec3(v, "b", **kw)


def test_magnetic_field_units():
    """A magnetometer's units: tesla and gauss (1 G = 1e-4 T) and their parts, a kind of
    their own (a field is never a length or an acceleration, "G" is not "g")."""
    from sinslab.core import units as u
    assert u.parse("0.55 G", "magnetic_field") == pytest.approx(55e-6)
    assert u.parse("55 µT", "magnetic_field") == pytest.approx(55e-6)
    assert u.parse("55000 nT", "magnetic_field") == pytest.approx(55e-6)
    assert u.parse("550 mG", "magnetic_field") == pytest.approx(55e-6)
    with pytest.raises(u.UnitError, match="magnetic_field, expected acceleration"):
        u.parse("1 G", "acceleration")
    assert u.parse("1 g", "acceleration") == u.g0
