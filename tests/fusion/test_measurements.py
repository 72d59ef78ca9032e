"""The measurement contract (sinslab.fusion.measurements): every measurement's H is the
finite-difference Jacobian of its own nonlinear z with respect to the error state, on
every error model it can meet — the 15-state loosely coupled model, Gauss–Markov gyro and
accelerometer blocks beside (or instead of) the random-constant biases, scale factors on
a subset of axes, lever-arm and odometer-scale states the measurement owns, a horizontal
core, the difference core of two INS. The perturbation follows what each block feeds
(tests/support.py: nav_with_errors), never its name, so a term placed on a block found
by name is caught on a model whose block has another name or kind.

A position fix is also taken Δt after its validity time, where z gains −Δt ∂v_ant/∂x (the
fix is moved to the epoch with the INS antenna velocity, which carries δv, φ through the
lever and the gyro errors through ω×l).

A difference model's layout does not say which of the two streams a sensor block feeds:
its cases name the blocks of INS 1 (the stream carrying the error) or perturb none.

The carrier-phase measurements (RTK double differences, time-differenced phase) live
beside the other satellite measurements outside the package and are held to the same
contract on models with their own states: the ambiguities enter through the nominal
ambiguities the measurement keeps, the clock through its nominal clock, the clone states
through the antenna position and clock bias recorded at the epoch before.
"""
import functools
import inspect
import math

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core.earth import radii
from sinslab.fusion.measurements import barometer as B
from sinslab.fusion import measurements as M
from sinslab.fusion.loosely_coupled import lc_model
from sinslab.nav import errstate as es
from support import assert_H_is_jacobian

LEVER = np.array([0.4, 1.5, -0.7])          # IMU -> antenna / wheel point, body axes [m]
W = np.array([0.01, -0.02, 0.3])            # true body rate [rad/s] (a turning car)

MODELS = {
    "15-state": lambda: lc_model(1e-5, 1e-4),
    "gauss-markov": lambda: es.ErrorModel("full", [es.gyro_bias(), es.gyro_markov(100.0, 1e-5, axes="xz"),
                                                   es.accel_bias(), es.accel_markov(300.0, 1e-3)]),
    "scale-factors": lambda: lc_model(1e-5, 1e-4, scale_factors=True),
    # no block named "eps": the gyro errors are a Markov and a two-axis scale block only
    "lever-states": lambda: es.ErrorModel("full", [es.gyro_markov(100.0, 1e-5), es.gyro_scale(axes="xy"),
                                                   es.accel_bias(), es.lever_arm(), es.odometer_scale()]),
    # a barometer bias of its own (Gauss–Markov)
    "barometer": lambda: es.ErrorModel("full", [es.gyro_bias(), es.accel_bias(),
                                                es.barometer_bias(tau=600.0, sigma=2.0)]),
    # a magnetometer's residual hard iron (random constant)
    "magnetometer": lambda: es.ErrorModel("full", [es.gyro_bias(), es.accel_bias(), es.magnetometer_bias()]),
    "horizontal": lambda: es.ErrorModel("horizontal", [es.gyro_bias(), es.accel_bias(axes="xy")]),
    # carrier phase: ambiguity states (RTK), receiver clock and clone states (TDCP), beside
    # the 15 states or beside Gauss–Markov and scale gyro blocks with no block named "eps"
    "rtk": lambda: es.ErrorModel("full", [es.gyro_bias(), es.accel_bias(), es.carrier_ambiguities(60)]),
    "rtk-markov-scale": lambda: es.ErrorModel("full", [es.gyro_markov(100.0, 1e-5), es.gyro_scale(axes="xy"),
                                                       es.accel_bias(), es.carrier_ambiguities(60)]),
    "tdcp": lambda: es.ErrorModel("full", [es.gyro_bias(), es.accel_bias(), es.receiver_clock(("G", "E")),
                                           es.phase_clones()]),
    "tdcp-markov-scale": lambda: es.ErrorModel("full", [es.gyro_markov(100.0, 1e-5), es.gyro_scale(axes="xy"),
                                                        es.accel_bias(), es.receiver_clock(("G", "E")),
                                                        es.phase_clones()]),
    # INS 1 with a gyro scale block beside its bias, INS k with a bias only
    "difference": lambda: es.DifferenceModel("horizontal", [es.gyro_bias(), es.gyro_scale(axes="xz"),
                                                            es.accel_bias(axes="xy")],
                                             [es.gyro_bias(), es.accel_bias(axes="xy")]),
}
SINGLE = ("15-state", "gauss-markov", "scale-factors", "lever-states", "barometer", "magnetometer", "horizontal")
FULL = SINGLE[:-1]                           # measurements that need three velocity errors
RTK = ("rtk", "rtk-markov-scale")
TDCP = ("tdcp", "tdcp-markov-scale")
OWN = ("lever-states",)                      # models with the states a measurement owns
BARO_BIAS = 5.0                              # true barometer bias [m]
#: Earth's field ENU [T] (IGRF-14 at 45.3° N, 93.2° W in 2012: D = 0.6°, I = 72°)
B_N = np.array([0.18e-6, 17.25e-6, -53.23e-6])
MAG_BIAS = np.array([2e-6, -1e-6, 3e-6])     # residual hard iron removed by the measurement [T]


def _row():
    """True navigation row of a car driving forward (body velocity [0.3, 12, 0.1] m/s)."""
    q = A.euler_to_quat(np.array([0.05, -0.1, 0.7]))
    return np.r_[q, A.quat_to_dcm(q) @ [0.3, 12.0, 0.1], 0.55, 2.0, 800.0]


def _owned(lay, x, name, base):
    """A parameter that is a state of the layout when it has the block, else fixed."""
    return (base + x[lay.slice(name)], name) if name in lay.names else (base, None)


def _fix_pos(lay, row):
    return row[7:10][None, :3 if lay.slice("dp").stop - lay.slice("dp").start == 3 else 2]


# one entry per measurement class: (models, [(case id, make(lay, row) -> make(x), epoch kw)])
CASES = {
    "PositionFix": (SINGLE, [
        ("no-lever", lambda lay, row: lambda x: M.PositionFix([0.0], _fix_pos(lay, row), [3.0, 3.0, 5.0]),
         {}),
        ("lever", lambda lay, row: lambda x: M.PositionFix([0.0], _fix_pos(lay, row), [3.0, 3.0, 5.0],
                                                           lever_arm=LEVER), {}),
        # the fix moved to a later epoch with the antenna velocity: −Δt ∂v_ant/∂x in H
        ("extrapolated", lambda lay, row: lambda x: M.PositionFix([0.0], _fix_pos(lay, row), [3.0, 3.0, 5.0],
                                                                  lever_arm=LEVER), {"t": 0.5}),
    ]),
    "VelocityFix": (FULL, [
        ("no-lever", lambda lay, row: lambda x: M.VelocityFix([0.0], [row[4:7]], 0.1), {}),
        ("lever", lambda lay, row: lambda x: M.VelocityFix([0.0], [row[4:7]], 0.1, lever_arm=LEVER), {}),
    ]),
    "Stack": (FULL, [
        ("position+velocity", lambda lay, row: lambda x: M.Stack(
            M.PositionFix([0.0], [row[7:10]], [3.0, 3.0, 5.0], lever_arm=LEVER),
            M.VelocityFix([0.0], [row[4:7]], 0.1, lever_arm=LEVER)), {}),
    ]),
    "InsDifference": (("difference",), [
        ("co-located", lambda lay, row: lambda x: M.InsDifference([0.0], [1e-7, 1e-7, 0.01, 0.01]),
         {"sensor_errors": False}),
        # INS 1 carries its own sensor errors: ω_1 enters through the lever's C_b1^n (ω_1×l)
        ("lever+sensors-1", lambda lay, row: lambda x: M.InsDifference([0.0], [1e-7, 1e-7, 0.01, 0.01],
                                                                       lever_arm=LEVER),
         {"sensor_errors": ("eps_1", "nabla_1", "kg_1")}),
    ]),
    "ZeroVelocity": (SINGLE, [
        ("zupt", lambda lay, row: lambda x: M.ZeroVelocity([(0.0, 10.0)], 0.02), {}),
    ]),
    "ZeroRate": (SINGLE, [
        ("zaru", lambda lay, row: lambda x: M.ZeroRate([(0.0, 10.0)], 1e-4), {}),
    ]),
    "NonHolonomic": (SINGLE, [
        ("mount+lever", lambda lay, row: lambda x: M.NonHolonomic(
            (0.1, 0.05), mount=(0.02, -0.01, 0.05), **dict(zip(("lever_arm", "lever_block"),
                                                               _owned(lay, x, "lev", LEVER)))), {}),
    ]),
    "BodyVelocity": (SINGLE, [
        ("mount+lever", lambda lay, row: lambda x: M.BodyVelocity(
            [0.0], [[0.1, 12.0, 0.0]], 0.1, mount=A.euler_to_dcm(np.array([0.1, 0.0, -0.2])),
            **dict(zip(("lever_arm", "lever_block"), _owned(lay, x, "lev", LEVER)))), {}),
    ]),
    "Odometer": (SINGLE, [
        ("speed", lambda lay, row: _odometer(lay, row, None), {}),
        ("speed+nhc", lambda lay, row: _odometer(lay, row, (0.1, 0.1)), {}),
    ]),
    "LeverPositionFix": (OWN, [
        ("extrapolated", lambda lay, row: lambda x: M.LeverPositionFix([0.0], [row[7:10]], [3.0, 3.0, 5.0],
                                                                       lever_arm=LEVER + x[lay.slice("lev")]),
         {"t": 0.5}),
    ]),
    "LeverVelocityFix": (OWN, [
        ("lever", lambda lay, row: lambda x: M.LeverVelocityFix([0.0], [row[4:7]], 0.1,
                                                                lever_arm=LEVER + x[lay.slice("lev")]), {}),
    ]),
    "Barometer": (FULL, [
        ("own-bias", lambda lay, row: _barometer(lay, row), {}),
    ]),
    "MagneticField": (SINGLE, [
        ("hard-iron", lambda lay, row: _magnetometer(lay, row, M.MagneticField, 0.3e-6), {}),
    ]),
    "MagneticHeading": (SINGLE, [
        ("hard-iron", lambda lay, row: _magnetometer(lay, row, M.MagneticHeading, 0.05), {}),
    ]),
    # fusion.rtk_ins and fusion.tdcp: the satellites of a simulated sky over the row
    "DoubleDifferences": (RTK, [
        ("lever", lambda lay, row: _double_differences(lay, row, 100.0), {"t": 100.0}),
        ("extrapolated", lambda lay, row: _double_differences(lay, row, 100.4), {"t": 100.4}),
    ]),
    "TimeDifferencedPhase": (TDCP, [
        ("lever", lambda lay, row: _tdcp(lay, row, 101.0), {"t": 101.0, "item": 1}),
        ("extrapolated", lambda lay, row: _tdcp(lay, row, 101.3), {"t": 101.3, "item": 1}),
    ]),
}
#: modules of satellite measurements outside the package held to the same contract
CARRIER_MODULES = ("sinslab.fusion.rtk_ins", "sinslab.fusion.tdcp")
F_TRUE = np.array([0.3, -0.2, 9.8])         # the specific force of assert_H_is_jacobian


@functools.lru_cache(maxsize=1)
def _sky():
    """Rover (two epochs, 1 s apart) and base 3 km away under GPS + Galileo on two
    carriers, at the row's position."""
    from sinslab.core import earth as E
    from sinslab.fusion.gnss import SatelliteObservations
    from sinslab.fusion.rtk import RtkBase
    from sinslab.sim import gnss as SG
    lat, lon, h = _row()[7:10]
    t = np.array([100.0, 101.0])
    rb = E.geodetic_to_ecef(lat, lon, h) + np.array([2000.0, -1500.0, 1500.0])
    sim = SG.simulate_observations(t, np.full(2, lat), np.full(2, lon), np.full(2, h), np.zeros((2, 3)),
                                   [SG.Walker(), SG.Walker(planes=3, per_plane=8, system="E", raan0=0.4)],
                                   seed=3, phase=SG.PhaseErrors(), base=SG.BaseStation(position=tuple(rb)))
    return SatelliteObservations(**sim.fields), RtkBase(SatelliteObservations(**sim.base.fields), rb)


def _double_differences(lay, row, t):
    """Double differences prepared once at the true navigation (signals and their nominal
    ambiguities); ``x`` moves the nominal ambiguities (``N₀ = N + δN``, the states the
    measurement owns)."""
    import copy

    from sinslab.fusion.rtk import RtkOptions
    from sinslab.fusion.rtk_ins import DoubleDifferences
    sv, base = _sky()
    m0 = DoubleDifferences(sv, base, RtkOptions(mask=0.2), lever_arm=LEVER)
    m0.transform(M.Epoch(t, 1, (M.NavRow(row, W, F_TRUE),), lay, lay.n, 0))
    sl = lay.find("ambiguity")

    def make(x):
        m = copy.deepcopy(m0)
        m.engine.slots.n0 += x[sl]
        return m
    return make


def _tdcp(lay, row, t):
    """Time-differenced phase of epoch 1 against the record of epoch 0 made at the true
    navigation (0.7 m and 0.1 s behind); ``x`` moves the nominal clock (the clock
    states, errors of it) and the recorded antenna position and bias (the clone states of
    the set the record was copied into)."""
    import copy

    from sinslab.fusion.tdcp import TimeDifferencedPhase
    sv, _ = _sky()
    b0, d0, t0 = 3.0e4, -50.0, 100.0
    # the slip tests off: the row's INS moves, the simulated antenna does not
    m0 = TimeDifferencedPhase(sv, lever_arm=LEVER, clock_nominal=(b0, d0, t0), mask=0.2, gf=None, doppler_k=None,
                              prediction_k=None)
    before = row.copy()
    before[7] -= 1e-7
    m0.transform(M.Epoch(t - 1.0, 1, (M.NavRow(before, W, F_TRUE),), lay, lay.n, 0))
    sc, cl = lay.find("receiver_clock"), lay.find("phase_clone")
    c0 = cl.start + 4 * m0.rec["slot"]

    def make(x):
        m = copy.deepcopy(m0)
        xb, xd = x[sc.start], x[sc.start + 1]
        m.nominal = (b0 + xb + xd * (t0 - t), d0 + xd, t0)
        m.rec["r"] = m0.rec["r"] + x[c0:c0 + 3]
        m.rec["b"] = m0.rec["b"] + x[c0 + 3]
        return m
    return make


def _barometer(lay, row):
    """A barometer reading the true height plus its bias, removing ``BARO_BIAS + δb``
    (``δb = b_used − b_true``: the bias state, when the model has it)."""
    sb = lay.find("baro_bias")
    return lambda x: B.Barometer([0.0], [row[9] + BARO_BIAS], 0.5,
                                 bias=BARO_BIAS + (x[sb][0] if sb is not None else 0.0))


def _magnetometer(lay, row, cls, sigma):
    """A magnetometer reading the true body field through a soft and hard iron the
    calibration removes, plus a residual hard iron ``MAG_BIAS``; the measurement removes
    ``MAG_BIAS + δβ`` (``δβ = β_used − β_true``: the state, when the model has it)."""
    from sinslab.nav.magnetic import MagCalibration
    cal = MagCalibration([[1.05, 0.02, -0.01], [0.02, 0.97, 0.03], [-0.01, 0.03, 1.02]], [4e-6, -7e-6, 2e-6])
    raw = cal.distort(A.quat_to_dcm(row[:4]).T @ B_N + MAG_BIAS)
    sb = lay.find("mag_hard_iron")
    return lambda x: cls([0.0], raw[None], B_N, sigma, calibration=cal,
                         bias=MAG_BIAS + (x[sb] if sb is not None else 0.0))


def _odometer(lay, row, nhc):
    """An odometer reading the true forward speed of the wheel point through its scale
    error k (``v = (1 − k) s̃``, the definition of :class:`Odometer`)."""
    v_fwd = (A.quat_to_dcm(row[:4]).T @ row[4:7] + np.cross(W, LEVER))[1]

    def make(x):
        k = x[lay.slice("kod")][0] if "kod" in lay.names else 0.0
        lever, block = _owned(lay, x, "lev", LEVER)
        return M.Odometer([-1.0, 0.0, 1.0], np.full(3, v_fwd / (1.0 - k)), 0.05, lever_arm=lever,
                          lever_block=block, scale_block="kod" if "kod" in lay.names else None,
                          nhc_sigma=nhc)
    return make


def _params():
    for cls, (models, cases) in CASES.items():
        for case, build, kw in cases:
            for model in models:
                yield pytest.param(cls, build, kw, model, id=f"{cls}-{case}-{model}")


@pytest.mark.parametrize("cls, build, kw, model", list(_params()))
def test_H_is_the_jacobian_of_z(cls, build, kw, model):
    lay = MODELS[model]().layout
    row = _row()
    rows, omegas = [row], [W]
    if model == "difference":
        rows, omegas = [row, row.copy()], [W, W]     # stream 0 carries the (difference) error
    assert_H_is_jacobian(build(lay, row), lay, rows, omegas, **kw)


def test_every_measurement_class_is_under_the_contract():
    """Every public class with ``matrices`` in every file of the measurement package (a new
    sensor family's file included) and in the carrier-phase modules has a case in CASES."""
    import importlib
    import pkgutil

    mods = [importlib.import_module(f"{M.__name__}.{m.name}") for m in pkgutil.iter_modules(M.__path__)]
    mods += [importlib.import_module(m) for m in CARRIER_MODULES]
    classes = {name for mod in mods for name, c in inspect.getmembers(mod, inspect.isclass)
               if c.__module__ == mod.__name__ and hasattr(c, "matrices") and c is not M.Measurement
               and not name.startswith("_")}
    assert classes == set(CASES), f"not under the contract: {sorted(classes - set(CASES))}"


def test_the_contract_sees_a_term_placed_on_a_block_by_name():
    """A velocity fix whose lever-arm rate term sits on the block named "eps" alone (as the
    class once had it) fails the contract on a Gauss–Markov model: the check can fail."""
    class ByName(M.VelocityFix):
        def matrices(self, ep):
            z, H, R = super().matrices(ep)
            for b in ep.layout.blocks:
                if b.feeds == "gyro_bias" and b.name != "eps":
                    H[:, ep.layout.slice(b.name)] = 0.0
            return z, H, R

    lay = MODELS["gauss-markov"]().layout
    row = _row()
    with pytest.raises(AssertionError, match="eps_m"):
        assert_H_is_jacobian(lambda x: ByName([0.0], [row[4:7]], 0.1, lever_arm=LEVER), lay, [row], [W])


def test_the_contract_sees_a_magnetic_heading_without_its_tilt_terms():
    """A magnetic heading whose H had φ_U alone (the heading of a level compass) fails the
    contract: with the dip of 72° a tilt error of the INS moves the levelled field's azimuth
    by about three times itself, and the contract sees the missing terms."""
    class Level(M.MagneticHeading):
        def matrices(self, ep):
            z, H, R = super().matrices(ep)
            s = ep.layout.slice("phi")
            H[:, s.start:s.start + 2] = 0.0
            return z, H, R

    lay = MODELS["magnetometer"]().layout
    row = _row()
    with pytest.raises(AssertionError, match="phi[EN]"):
        assert_H_is_jacobian(_magnetometer(lay, row, Level, 0.05), lay, [row], [W])


def test_position_fix_of_the_true_antenna_is_zero():
    lay = lc_model(1e-5, 1e-4).layout
    row = _row()
    d = A.quat_to_dcm(row[:4]) @ LEVER
    rm, rn = radii(row[7], row[9])
    fix = np.array([[row[7] + d[1] / rm, row[8] + d[0] / (rn * math.cos(row[7])), row[9] + d[2]]])
    z, H, R = assert_H_is_jacobian(lambda x: M.PositionFix([0.0], fix, [3.0, 3.0, 5.0], lever_arm=LEVER),
                                   lay, [row], [W])
    assert np.allclose(z, 0.0, atol=1e-6) and np.allclose(R, [9.0, 9.0, 25.0])
