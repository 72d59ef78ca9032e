"""The Earth's magnetic field where and when a magnetometer reads it, and the calibration of
a three-axis magnetometer (hard and soft iron).

Reference field: the International Geomagnetic Reference Field, 14th generation (IGRF-14,
IAGA Working Group V-MOD), evaluated by the ``ppigrf`` package from the coefficient file
its wheel ships (no network, no coefficients typed here); valid 1900–2030. The field is
returned in ENU [T] on the WGS-84 ellipsoid (geodetic north and up), with the declination
D (east of true north) and the inclination I (positive down) it implies::

    D = atan2(B_E, B_N),   I = atan2(−B_U, √(B_E² + B_N²)),   F = |B|.

Calibration (the usual model of a strapdown magnetometer): a reading is

    m̃ = S b + h + v,

with ``b = C_n^b B^n`` the Earth's field in body axes, ``S`` the soft-iron matrix (scale
factors, misalignment and the induced field of the airframe's soft iron), ``h`` the
hard-iron offset (permanent magnetisation, constant currents) and ``v`` noise.
:class:`MagCalibration` holds the inverse map ``b ≈ W (m̃ − h)`` (``W = S⁻¹``).
:func:`ellipsoid_fit` finds ``W`` and ``h`` from the readings alone (they lie on an
ellipsoid; its sphere has the model's radius F) — possible only when the readings cover
enough directions (a calibration swing, a tumbling rig): it says how well they do.
:func:`attitude_fit` finds ``S`` and ``h`` from readings whose attitude is known (a
reference or an aided INS) by linear least squares.
"""
from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ReferenceField", "reference_field", "decimal_year", "MagCalibration", "EllipsoidFit",
           "ellipsoid_fit", "attitude_fit", "IGRF_SPAN", "likely_field_unit", "FIELD_UNITS"]

#: Years the IGRF-14 coefficients cover (definitive and predictive).
IGRF_SPAN = (1900.0, 2030.0)
#: Units a magnetometer log may be in, with their value in tesla.
FIELD_UNITS = {"T": 1.0, "mT": 1e-3, "uT": 1e-6, "nT": 1e-9, "G": 1e-4, "mG": 1e-7}


@dataclass(frozen=True)
class ReferenceField:
    """The main field of a geomagnetic model at some places.

    Attributes
    ----------
    b_n : ndarray, shape S + (3,)
        Field in ENU [T] (east, north, up of the WGS-84 ellipsoid).
    model : str
        Which model and package gave it (for reports).
    """

    b_n: np.ndarray
    model: str

    @property
    def declination(self):
        """Declination D [rad], east of true north, shape S."""
        return np.arctan2(self.b_n[..., 0], self.b_n[..., 1])

    @property
    def inclination(self):
        """Inclination (dip) I [rad], positive below the horizontal, shape S."""
        return np.arctan2(-self.b_n[..., 2], np.hypot(self.b_n[..., 0], self.b_n[..., 1]))

    @property
    def intensity(self):
        """Total intensity F [T], shape S."""
        return np.linalg.norm(self.b_n, axis=-1)


def decimal_year(date) -> float:
    """A date as a decimal year: a float (taken as is), a ``datetime.date``/``datetime``, or
    an ISO string (``"2012-08-07"``, ``"2012-08-07T15:00"``)."""
    if isinstance(date, (int, float)) and not isinstance(date, bool):
        return float(date)
    if isinstance(date, str):
        try:
            date = _dt.datetime.fromisoformat(date.strip())
        except ValueError:
            raise ValueError(f"not a date: {date!r} (give YYYY-MM-DD or a decimal year)") from None
    if isinstance(date, _dt.datetime):
        start = _dt.datetime(date.year, 1, 1, tzinfo=date.tzinfo)
        end = _dt.datetime(date.year + 1, 1, 1, tzinfo=date.tzinfo)
        return date.year + (date - start) / (end - start)
    if isinstance(date, _dt.date):
        return decimal_year(_dt.datetime(date.year, date.month, date.day))
    raise ValueError(f"not a date: {date!r} (give YYYY-MM-DD or a decimal year)")


def reference_field(lat, lon, h, date) -> ReferenceField:
    """IGRF-14 main field at geodetic places and one date.

    Parameters
    ----------
    lat, lon : array_like, shape S
        Geodetic latitude and longitude [rad].
    h : array_like, shape S
        Height above the WGS-84 ellipsoid [m].
    date : float, str, datetime.date or datetime.datetime
        When (see :func:`decimal_year`); inside :data:`IGRF_SPAN`.

    Returns
    -------
    ReferenceField
        ``b_n`` of shape S + (3,).

    Raises
    ------
    ValueError
        A date outside the model's span (the package would extrapolate silently).
    """
    import ppigrf                                   # imports pandas: only when a field is asked for

    year = decimal_year(date)
    if not (IGRF_SPAN[0] <= year <= IGRF_SPAN[1]):
        raise ValueError(f"date {year:.2f} is outside the IGRF-14 span {IGRF_SPAN[0]:.0f}–{IGRF_SPAN[1]:.0f}")
    lat, lon, h = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (lat, lon, h)))
    y = int(math.floor(year))
    start = _dt.datetime(y, 1, 1)
    when = start + (_dt.datetime(y + 1, 1, 1) - start) * (year - y)
    be, bn, bu = ppigrf.igrf(np.degrees(lon), np.degrees(lat), h / 1000.0, when)
    b = np.stack([be[0], bn[0], bu[0]], -1).reshape(lat.shape + (3,)) * 1e-9
    return ReferenceField(b, f"IGRF-14 (ppigrf {_version('ppigrf')})")


def _version(package):
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version(package)
    except PackageNotFoundError:                   # a copy of the module, not installed
        return "unknown version"


def likely_field_unit(values, intensity) -> str:
    """The unit of :data:`FIELD_UNITS` in which readings of median magnitude ``values`` come
    closest to a field of ``intensity`` [T] (a factor of ten or more apart is another unit:
    hard iron and airframe fields change the magnitude by tens of per cent, not by 10×)."""
    med = float(np.median(np.linalg.norm(np.asarray(values, dtype=float), axis=-1)))
    if not (med > 0 and math.isfinite(med)):
        raise ValueError("the readings have no magnitude")
    return min(FIELD_UNITS, key=lambda u: abs(math.log(med * FIELD_UNITS[u] / intensity)))


@dataclass(frozen=True)
class MagCalibration:
    """Hard- and soft-iron calibration of a three-axis magnetometer (see the module notes).

    Attributes
    ----------
    soft : ndarray, shape (3, 3)
        ``W``: the calibrated reading is ``W (m̃ − h)`` (the inverse of the soft-iron matrix).
    hard : ndarray, shape (3,)
        Hard-iron offset ``h`` in the units of the readings.
    """

    soft: np.ndarray
    hard: np.ndarray

    def __post_init__(self):
        soft = np.asarray(self.soft, dtype=float).reshape(3, 3)
        hard = np.asarray(self.hard, dtype=float).reshape(3)
        if not (np.all(np.isfinite(soft)) and np.all(np.isfinite(hard))):
            raise ValueError("magnetometer calibration has non-finite values")
        if not np.linalg.cond(soft) < 1e8:
            raise ValueError("soft-iron matrix is singular")
        object.__setattr__(self, "soft", soft)
        object.__setattr__(self, "hard", hard)

    @classmethod
    def identity(cls):
        """No correction."""
        return cls(np.eye(3), np.zeros(3))

    def apply(self, m):
        """Calibrated readings ``W (m̃ − h)``, shape (..., 3)."""
        return (np.asarray(m, dtype=float) - self.hard) @ self.soft.T

    def distort(self, b):
        """Readings a calibrated field ``b`` produces, ``W⁻¹ b + h`` (the inverse of :meth:`apply`)."""
        return np.linalg.solve(self.soft, np.asarray(b, dtype=float).reshape(-1, 3).T).T.reshape(
            np.shape(b)) + self.hard


@dataclass(frozen=True)
class EllipsoidFit:
    """How well an ellipsoid fit is determined.

    Attributes
    ----------
    residual : float
        RMS of ``|W (m̃ − h)| − F`` over the readings, relative to F.
    coverage : ndarray, shape (3,)
        Standard deviations of the calibrated field's direction (unit vector) along its
        principal axes, largest first: about 0.58 each for readings spread over the whole
        sphere, near 0 along an axis the readings never turn (a level flight turns the field
        on a cone: the vertical is not seen).
    """

    residual: float
    coverage: np.ndarray


def ellipsoid_fit(m, intensity, *, min_coverage=0.25):
    """Hard and soft iron from readings alone: the ellipsoid they lie on, mapped to the sphere
    of radius ``intensity``.

    Fits the quadric ``xᵀ M x − 2 xᵀ M h = 1 − hᵀ M h`` by linear least squares (nine
    parameters), the hard iron ``h`` as its centre and ``W`` as the symmetric square root of
    ``M`` scaled to ``intensity`` (the soft iron's rotation is not observable from the
    readings alone: a symmetric ``W`` is the choice that adds none).

    Parameters
    ----------
    m : array_like, shape (N, 3)
        Raw readings (any unit), N ≥ 9.
    intensity : float
        Field magnitude in the same unit (the reference model's F).
    min_coverage : float
        Least acceptable smallest value of :attr:`EllipsoidFit.coverage`.

    Returns
    -------
    (MagCalibration, EllipsoidFit)

    Raises
    ------
    ValueError
        Too few readings, readings that turn too little (smallest coverage below
        ``min_coverage``, measured on the readings centred on their mean and again on the
        calibrated ones), or a fit that is no ellipsoid.
    """
    m = np.asarray(m, dtype=float).reshape(-1, 3)
    m = m[np.all(np.isfinite(m), axis=1)]
    if len(m) < 9:
        raise ValueError(f"an ellipsoid fit needs at least 9 readings, got {len(m)}")
    pre = _coverage(m - m.mean(0))
    if pre[-1] < min_coverage:
        raise ValueError(_coverage_message(pre, min_coverage))
    sc = float(np.median(np.linalg.norm(m - m.mean(0), axis=1)))
    x = (m - m.mean(0)) / sc                             # conditioned: centred, unit radius
    D = np.column_stack([x[:, 0] ** 2, x[:, 1] ** 2, x[:, 2] ** 2, 2 * x[:, 0] * x[:, 1], 2 * x[:, 0] * x[:, 2],
                         2 * x[:, 1] * x[:, 2], 2 * x[:, 0], 2 * x[:, 1], 2 * x[:, 2]])
    p = np.linalg.lstsq(D, np.ones(len(x)), rcond=None)[0]
    M = np.array([[p[0], p[3], p[4]], [p[3], p[1], p[5]], [p[4], p[5], p[2]]])
    c = -np.linalg.solve(M, p[6:])
    k = 1.0 + c @ M @ c
    ev, V = np.linalg.eigh(M / k)
    if not np.all(ev > 0):
        raise ValueError("the readings do not lie on an ellipsoid (a disturbed or saturated record?)")
    W = (V * np.sqrt(ev)) @ V.T * (intensity / sc)
    cal = MagCalibration(W, m.mean(0) + sc * c)
    b = cal.apply(m)
    res = float(np.sqrt(np.mean((np.linalg.norm(b, axis=1) / intensity - 1.0) ** 2)))
    cov = _coverage(b)
    if cov[-1] < min_coverage:
        raise ValueError(_coverage_message(cov, min_coverage))
    return cal, EllipsoidFit(res, cov)


def _coverage(u):
    """Standard deviations of directions ``u`` (N, 3) along their principal axes, largest first."""
    u = u / np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-300)
    return np.sqrt(np.maximum(np.linalg.eigvalsh(np.cov(u.T)), 0.0))[::-1]


def _coverage_message(cov, limit):
    return (f"the readings turn too little for an ellipsoid fit (their direction's spread along its "
            f"principal axes {cov[0]:.2f}, {cov[1]:.2f}, {cov[2]:.2f}; at least {limit:g} along each is "
            f"needed, 0.58 for the whole sphere): give the calibration, or let the filter estimate it")


def attitude_fit(m, C_bn, b_n) -> MagCalibration:
    """Hard and soft iron from readings whose attitude is known: ``m̃ = S b + h`` with
    ``b = C_n^b B^n`` fitted by linear least squares (twelve parameters), ``W = S⁻¹``.

    Parameters
    ----------
    m : array_like, shape (N, 3)
        Raw readings.
    C_bn : array_like, shape (N, 3, 3)
        Attitude ``C_b^n`` (body -> ENU) of each reading.
    b_n : array_like, shape (3,) or (N, 3)
        Reference field ENU, in the unit of the readings.
    """
    m = np.asarray(m, dtype=float).reshape(-1, 3)
    b = np.einsum("kji,kj->ki", np.asarray(C_bn, dtype=float), np.broadcast_to(b_n, m.shape))
    ok = np.all(np.isfinite(m), axis=1) & np.all(np.isfinite(b), axis=1)
    if ok.sum() < 12:
        raise ValueError(f"an attitude fit needs at least 12 readings, got {int(ok.sum())}")
    X = np.column_stack([b[ok], np.ones(ok.sum())])
    coef = np.linalg.lstsq(X, m[ok], rcond=None)[0]
    return MagCalibration(np.linalg.inv(coef[:3].T), coef[3])
