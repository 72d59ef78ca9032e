"""Oracles for the aiding measurements (ZUPT, ZARU, NHC, body velocity, odometer, lever-arm
fixes) and the stationarity detector.

Their H are finite-difference Jacobians of their own z on every error model
(tests/fusion/test_measurements.py, the measurement contract); here: the values of z at
known truth (rest, the true reading, the body-axis velocity of the point), R, schedules
and bad input.
"""
import math

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core.earth import WIE, gravity, radii
from sinslab.core.records import ImuRecord
from sinslab.fusion import stationarity as st
from sinslab.fusion.measurements import (BodyVelocity, Epoch, Grid, LeverPositionFix,
                                         LeverVelocityFix, NavRow, NonHolonomic, Odometer,
                                         ZeroRate, ZeroVelocity, vehicle_from_body)
from sinslab.fusion.spec import FilterGrid
from sinslab.nav import errstate as es
from support import assert_doc_quotes

W = np.array([0.01, -0.02, 0.3])


def _row(lat=0.55, lon=2.0, h=800.0, vel=(12.0, -4.0, 0.3), att=(0.05, -0.1, 0.7)):
    return np.r_[A.euler_to_quat(np.asarray(att)), vel, lat, lon, h]


def _model(*extra):
    return es.ErrorModel("full", [es.gyro_bias(), es.gyro_markov(100.0, 1e-5, axes="xz"),
                                  es.gyro_scale(), es.accel_bias(), *extra])


def _at(meas, lay, row, w=W, t=0.0):
    """``(z, H, R)`` of ``meas`` on one stream at row ``row``, rate ``w``."""
    return meas.matrices(Epoch(t, 1, (NavRow(row, w, np.zeros(3)),), lay, lay.n, 0))


def test_zupt_value():
    lay = _model().layout
    row = _row()
    z, H, R = _at(ZeroVelocity([(0, 10)], 0.02), lay, row)
    np.testing.assert_array_equal(z, row[4:7])
    assert np.allclose(R, 4e-4)


def test_zaru_is_zero_at_rest_and_sees_every_gyro_block():
    lay = _model().layout
    row = _row(vel=(0.0, 0.0, 0.0))
    C = A.quat_to_dcm(row[:4])
    lat = row[7]
    w_true = C.T @ np.array([0.0, WIE * math.cos(lat), WIE * math.sin(lat)])
    z0 = _at(ZeroRate([(0, 10)], 1e-4), lay, row, w_true)[0]
    assert np.abs(z0).max() < 1e-18                       # the Earth rate is removed exactly
    H = _at(ZeroRate([(0, 10)], 1e-4), lay, row, w_true + [0.01, -0.02, 0.03])[1]
    assert np.any(H[:, lay.slice("eps_m")] != 0) and np.any(H[:, lay.slice("kg")] != 0)


@pytest.mark.parametrize("mount", [None, (0.02, -0.01, 0.05), "matrix"])
def test_nhc_is_the_vehicle_axis_velocity(mount):
    if mount == "matrix":
        mount = A.euler_to_dcm(np.array([0.1, 0.0, -0.2]))
    lay = _model(es.lever_arm()).layout
    row = _row()
    lev = np.array([0.3, -1.2, -0.4])
    z, H, R = _at(NonHolonomic((0.1, 0.05), mount=mount, lever_arm=lev, lever_block="lev"), lay, row)
    vb = A.quat_to_dcm(row[:4]).T @ row[4:7] + np.cross(W, lev)
    np.testing.assert_allclose(z, (vehicle_from_body(mount) @ vb)[[0, 2]], rtol=1e-12)
    assert np.allclose(R, [0.01, 0.0025])


def test_body_velocity_shape_and_R():
    lay = _model(es.lever_arm()).layout
    z, H, R = _at(BodyVelocity([0.0], [[0.1, 12.0, 0.0]], 0.1, mount=(0.0, 0.0, 0.03),
                               lever_arm=[0.0, 1.0, -0.5], lever_block="lev"), lay, _row())
    assert z.shape == (3,) and H.shape == (3, lay.n) and np.allclose(R, 0.01)


@pytest.mark.parametrize("nhc", [None, (0.1, 0.1)])
def test_odometer_of_the_true_reading_is_zero(nhc):
    lay = _model(es.lever_arm(), es.odometer_scale()).layout
    row = _row()
    C = A.quat_to_dcm(row[:4])
    row[4:7] = C @ np.array([0.3, 12.0, 0.1])             # driving forward
    lev = np.array([0.7, -1.0, -0.3])
    v_true = (C.T @ row[4:7] + np.cross(W, lev))[1]
    z, H, R = _at(Odometer([-1.0, 0.0, 1.0], np.full(3, v_true), 0.05, lever_arm=lev,
                           lever_block="lev", nhc_sigma=nhc), lay, row)
    assert abs(z[0]) < 1e-12
    assert z.size == (1 if nhc is None else 3)
    assert H[0, lay.slice("kod")][0] == -v_true             # ∂z/∂k = −s̃


def test_odometer_interpolates_and_refuses_bad_input():
    o = Odometer([0.0, 2.0], [10.0, 12.0], 0.1, scale_block=None)
    assert o.reading(0.5) == pytest.approx(10.5)
    ep = o.epochs(Grid(0.0, 0.5, 8))
    assert sorted(ep) == [1, 2, 3, 4]
    with pytest.raises(ValueError, match="do not overlap"):
        Odometer([100.0, 200.0], [1.0, 1.0], 0.1).epochs(Grid(0.0, 0.5, 8))
    with pytest.raises(ValueError, match=">= 0"):
        Odometer([0.0, 1.0], [1.0, -1.0], 0.1)
    with pytest.raises(ValueError, match="finite"):
        Odometer([0.0, 1.0], [1.0, np.nan], 0.1)


def test_lever_position_fix_of_the_true_antenna_is_zero():
    lay = _model(es.lever_arm()).layout
    row = _row()
    d = A.quat_to_dcm(row[:4]) @ np.array([0.5, 1.0, 1.5])      # the true antenna
    rm, rn = radii(row[7], row[9])
    fix = np.array([[row[7] + d[1] / rm, row[8] + d[0] / (rn * math.cos(row[7])), row[9] + d[2]]])
    z, H, R = _at(LeverPositionFix([0.0], fix, [3.0, 3.0, 5.0], lever_arm=[0.5, 1.0, 1.5]), lay, row)
    assert np.allclose(z, 0.0, atol=1e-6)


def test_lever_velocity_fix_couples_every_gyro_block():
    lay = _model(es.lever_arm()).layout
    row = _row()
    z, H, R = _at(LeverVelocityFix([0.0], [row[4:7]], 0.1, lever_arm=[0.5, 1.0, 1.5]), lay, row)
    assert all(np.any(H[:, lay.slice(b)] != 0) for b in ("eps", "eps_m", "kg", "lev"))


def test_stationarity_detector_finds_a_stop():
    dt = 0.01
    N = 3000
    rng = np.random.default_rng(1)
    lat = 0.6
    g = float(gravity(lat, 0.0))
    f = np.tile([0.0, 0.0, g], (N, 1)) + 0.01 * rng.standard_normal((N, 3))
    w = 1e-4 * rng.standard_normal((N, 3))
    moving = np.r_[np.ones(1000, bool), np.zeros(1200, bool), np.ones(800, bool)]
    f[moving] += 0.5 * rng.standard_normal((moving.sum(), 3))      # road vibration
    w[moving] += 0.05
    t = dt * np.arange(1, N + 1)
    imu = ImuRecord(t, w * dt, f * dt, dt)
    iv = st.detect(imu, lat, window=1.0)
    assert iv.shape == (1, 2)
    assert iv[0, 0] == pytest.approx(10.0, abs=1e-9) and iv[0, 1] == pytest.approx(22.0, abs=1e-9)
    fl = st.from_flags(t, ~moving)
    assert fl.shape == (1, 2) and fl[0, 0] == pytest.approx(10.01) and fl[0, 1] == pytest.approx(22.01)
    with pytest.raises(ValueError):
        st.from_flags(t, np.full(N, 2))


# ------------------------------------------------------------------ simulated drives
def _drive(segs, seed=1):
    from sinslab.core import units as u
    from sinslab.core.records import NavState
    from sinslab.sim import imu as imu_mod
    from sinslab.sim import trajectory as tr
    start = tr.Start(lat=32 * u.deg, lon=118 * u.deg, h=50.0, speed=0.0, heading=45 * u.deg)
    gen = tr.generate(segs, start, 0.01)
    err = imu_mod.ImuErrors.from_datasheet(gyro_bias="10 deg/h", gyro_arw="0.3 deg/sqrt(h)",
                                           accel_bias="500 ug", accel_vrw="100 ug/sqrt(Hz)")
    meas = imu_mod.apply(gen.imu, err, seed)
    tru = gen.truth
    init = NavState(tru.lat[0], tru.lon[0], tru.h[0], tru.vel[0] + [0.05, -0.05, 0.0],
                    tru.att[0] + np.array([0.1, 0.1, 1.0]) * u.deg, tru.t[0])
    return gen, meas, tru, init


def _P0(m):
    from sinslab.core import units as u
    lay = m.layout
    d = np.zeros(m.n)
    d[lay.slice("phi")] = [(0.2 * u.deg) ** 2] * 2 + [(2 * u.deg) ** 2]
    d[lay.slice("dv")] = 0.01
    d[lay.slice("dp")] = [(3 / 6.4e6) ** 2, (3 / 5.4e6) ** 2, 9.0]
    for b in lay.blocks:
        if b.feeds == "gyro_bias":
            d[lay.slice(b.name)] = (20 * u.dph) ** 2
        if b.feeds == "accel_bias":
            d[lay.slice(b.name)] = (1000 * u.ug) ** 2
    for name, v in (("kod", 0.05 ** 2), ("lev", 1.0)):
        if name in lay.names:
            d[lay.slice(name)] = v
    return np.diag(d)


def _fixes(tru, skip=()):
    t = np.arange(tru.t[0] + 1.0, tru.t[-1] - 1, 1.0)
    for a, b in skip:
        t = t[~((t >= a) & (t < b))]
    i = np.rint((t - tru.t[0]) / 0.01).astype(int)
    from sinslab.fusion.measurements import PositionFix, Stack, VelocityFix
    return Stack(PositionFix(t, np.stack([tru.lat[i], tru.lon[i], tru.h[i]], -1), [1.0, 1.0, 2.0]),
                 VelocityFix(t, tru.vel[i], 0.05))


def _horiz(r, tru, t):
    k = int(np.argmin(np.abs(r.t - t)))
    i = int(round((r.t[k] - tru.t[0]) / 0.01))
    rm, rn = radii(tru.lat[i], tru.h[i])
    row = r.nav[0][k]
    return math.hypot((row[7] - tru.lat[i]) * rm, (row[8] - tru.lon[i]) * rn * math.cos(tru.lat[i]))


def _car(u, tr):
    return [tr.Accelerate(duration=11.0, accel=2.0), tr.Level(duration=40.0),
            tr.Turn(duration=20.0, rate=4.5 * u.deg, coordinated=False), tr.Level(duration=30.0)]


def test_stop_heading_held_by_zaru():
    """A 2-min stop without GNSS: the heading drifts with the residual z gyro bias unless
    ZARU observes it (the drift rate is the slope of the yaw error while stopped)."""
    from sinslab.core import units as u
    from sinslab.fusion import driver
    from sinslab.fusion.feedback import FeedbackLayout
    from sinslab.sim import trajectory as tr
    segs = _car(u, tr) + [tr.Accelerate(duration=11.0, accel=-2.0), tr.Static(duration=120.0),
                          tr.Accelerate(duration=11.0, accel=2.0)]
    gen, meas, tru, init = _drive(segs)
    spd = np.linalg.norm(tru.vel, axis=1)
    iv = [(a + 1.0, b - 1.0) for a, b in st.from_flags(tru.t, spd < 1e-6, min_duration=5.0) if a > 5]
    assert len(iv) == 1 and iv[0][1] - iv[0][0] > 110
    s0, s1 = iv[0]
    m = es.ErrorModel("full", [es.gyro_bias(), es.accel_bias()], gyro_arw=0.3 * u.deg / 60,
                      accel_vrw=100 * u.ug)
    arw_T = 0.3 * u.deg / 60 / math.sqrt(0.1)
    rates = {}
    for name, extra in (("none", []), ("zaru", [ZeroVelocity(iv, 0.01), ZeroRate(iv, 2 * arw_T)])):
        r = driver.run([driver.LiveStream(meas, init, nsub=2)], m, _P0(m), [_fixes(tru, [(s0 - 1, s1 + 1)])] + extra,
                       grid=FilterGrid(0.1), feedback=FeedbackLayout.from_model(m.layout))
        ks = np.flatnonzero((r.t > s0 + 5) & (r.t < s1 - 5))
        i = np.rint((r.t[ks] - tru.t[0]) / 0.01).astype(int)
        y = A.wrap_pi(A.quat_to_euler(r.nav[0][ks, :4])[:, 2] - tru.att[i, 2])
        rates[name] = abs(np.polyfit(r.t[ks], y, 1)[0]) / u.dph
    assert rates["none"] > 1.0 and rates["zaru"] < 0.3, rates
    assert_doc_quotes("docs/recorded-data.md", "with a 2-min stop and a less settled bias: 3.05 °/h without, "
                      "0.05 °/h with ZUPT + ZARU", [2, rates["none"], rates["zaru"]])


def test_markov_blocks_fed_back_through_an_outage():
    """Gauss–Markov bias blocks under their default names are fed back: a 60 s outage ends
    several times closer than with the name-based layout that left them in the filter."""
    from sinslab.core import units as u
    from sinslab.fusion import driver
    from sinslab.fusion.feedback import FeedbackLayout
    from sinslab.sim import trajectory as tr
    gen, meas, tru, init = _drive(_car(u, tr) + [tr.Level(duration=80.0)])
    m = es.ErrorModel("full", [es.gyro_markov(600.0, 10 * u.dph), es.accel_markov(600.0, 500 * u.ug)],
                      gyro_arw=0.3 * u.deg / 60, accel_vrw=100 * u.ug)
    fx = [_fixes(tru, [(110.0, 170.0)])]
    err = {}
    for name, fb in (("kind", FeedbackLayout.from_model(m.layout)),
                     ("names", FeedbackLayout.from_model(m.layout, gyro="eps", accel="nabla"))):
        r = driver.run([driver.LiveStream(meas, init, nsub=2)], m, _P0(m), fx, grid=FilterGrid(0.1), feedback=fb)
        err[name] = _horiz(r, tru, 170.0 - 0.1)
    assert err["kind"] < 0.4 * err["names"], err


def test_odometer_bounds_an_outage():
    """Wheel speed with a 2 % scale error, noise and 2 cm/s quantisation through a 60 s
    GNSS outage: the outage-end error shrinks and the scale factor is estimated."""
    from sinslab.core import units as u
    from sinslab.fusion import driver
    from sinslab.fusion.feedback import FeedbackLayout
    from sinslab.sim import trajectory as tr
    gen, meas, tru, init = _drive(_car(u, tr) + [tr.Level(duration=60.0)])
    C = A.euler_to_dcm(tru.att)
    vf = np.einsum("kji,kj->ki", C, tru.vel)[:, 1]
    rng = np.random.default_rng(5)
    t_odo = tru.t[::5]
    s = np.round(np.maximum(0, 1.02 * vf[::5] + 0.05 * rng.standard_normal(t_odo.size)) / 0.02) * 0.02
    fx = [_fixes(tru, [(90.0, 150.0)])]
    out = {}
    for name, extra, blocks in (("gnss", [], []),
                                ("odo", [Odometer(t_odo, s, 0.1, nhc_sigma=(0.1, 0.1))], [es.odometer_scale()])):
        m = es.ErrorModel("full", [es.gyro_bias(), es.accel_bias(), *blocks], gyro_arw=0.3 * u.deg / 60,
                          accel_vrw=100 * u.ug)
        r = driver.run([driver.LiveStream(meas, init, nsub=2)], m, _P0(m), fx + extra, grid=FilterGrid(0.1),
                       feedback=FeedbackLayout.from_model(m.layout))
        out[name] = _horiz(r, tru, 150.0 - 0.1)
        if blocks:
            sl = m.layout.slice("kod")
            assert abs(r.x[-1, sl][0] - 0.02) < 3 * r.sigma[-1, sl][0] + 1e-3
    assert out["odo"] < 0.3 * out["gnss"], out


def test_lever_arm_estimated_within_sigma():
    """GNSS antenna lever arm (0.4, 1.2, 1.6) m estimated from position and velocity fixes
    with the lever used set to zero: within 3σ on every axis, horizontal σ below 0.1 m
    (the vertical lever is weakly observable on a level car drive)."""
    from sinslab.core import units as u
    from sinslab.fusion import driver
    from sinslab.fusion.feedback import FeedbackLayout
    from sinslab.sim import trajectory as tr
    segs = _car(u, tr) + [tr.Turn(duration=20.0, rate=-9 * u.deg, coordinated=False), tr.Level(duration=30.0)]
    gen, meas, tru, init = _drive(segs)
    lev = np.array([0.4, 1.2, 1.6])
    t = np.arange(1.0, tru.t[-1] - 1, 1.0)
    i = np.rint((t - tru.t[0]) / 0.01).astype(int)
    C = A.euler_to_dcm(tru.att[i])
    d = C @ lev
    rm, rn = radii(tru.lat[i], tru.h[i])
    pos = np.stack([tru.lat[i] + d[:, 1] / rm, tru.lon[i] + d[:, 0] / (rn * np.cos(tru.lat[i])),
                    tru.h[i] + d[:, 2]], -1)
    omega = gen.imu.dtheta[i - 1] / 0.01
    vel = tru.vel[i] + np.einsum("kij,kj->ki", C, np.cross(omega, lev))
    from sinslab.fusion.measurements import Stack
    m = es.ErrorModel("full", [es.gyro_bias(), es.accel_bias(), es.lever_arm()],
                      gyro_arw=0.3 * u.deg / 60, accel_vrw=100 * u.ug)
    ms = [Stack(LeverPositionFix(t, pos, [0.05, 0.05, 0.1]), LeverVelocityFix(t, vel, 0.02))]
    r = driver.run([driver.LiveStream(meas, init, nsub=2)], m, _P0(m), ms, grid=FilterGrid(0.1),
                   feedback=FeedbackLayout.from_model(m.layout))
    sl = m.layout.slice("lev")
    est, sig = -r.x[-1, sl], r.sigma[-1, sl]           # δl = l_used − l_true, l_used = 0
    assert np.all(np.abs(est - lev) < 3 * sig), (est, sig)
    assert np.all(sig[:2] < 0.1)
