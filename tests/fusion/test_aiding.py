"""Oracles for the aiding measurements (ZUPT, ZARU, NHC, body velocity, odometer, lever-arm
fixes) and the stationarity detector.

Every H is checked against central finite differences of the class's own nonlinear z
with respect to the error state (computed − true, sinslab.nav.errstate conventions:
C_b^n' = (I − φ×) C_b^n, δv, δp, compensated rate ω + δω with δω = x of each
gyro bias / Gauss–Markov block and diag(ω) x of a scale block; a lever-arm state is the
error of the lever used, an odometer scale error k makes the reading (1 + k) v).
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
                                         ZeroRate, ZeroVelocity, mount_matrix)
from sinslab.nav import errstate as es


def _row(lat=0.55, lon=2.0, h=800.0, vel=(12.0, -4.0, 0.3), att=(0.05, -0.1, 0.7)):
    return np.r_[A.euler_to_quat(np.asarray(att)), vel, lat, lon, h]


def _model(*extra):
    return es.ErrorModel("full", [es.gyro_bias(), es.gyro_markov(100.0, 1e-5, axes="xz"),
                                  es.gyro_scale(), es.accel_bias(), *extra])


def _perturb(row, omega, lay, x):
    r = row.copy()
    C = A.quat_to_dcm(row[:4])
    r[:4] = A.dcm_to_quat(A.apply_misalignment(C, x[lay.slice("phi")]))
    r[4:7] += x[lay.slice("dv")]
    r[7:10] += x[lay.slice("dp")]
    w = omega.copy()
    for b in lay.blocks:
        sl = lay.slice(b.name)
        for i, a in enumerate(b.axes):
            ax = "xyz".index(a)
            if b.feeds == "gyro_bias":
                w[ax] += x[sl.start + i]
            elif b.feeds == "gyro_scale":
                w[ax] += omega[ax] * x[sl.start + i]
    return r, w


def _steps(lay):
    s = np.full(lay.n, 1e-6)
    s[lay.slice("dv")] = 1e-4
    sp = lay.slice("dp")
    s[sp.start:sp.start + 2] = 1e-8
    s[sp.start + 2] = 1e-3
    for name in ("lev", "kod"):
        if name in lay.names:
            s[lay.slice(name)] = 1e-4
    return s


def _check(make, lay, row, w, t=0.0, item=0):
    """FD Jacobian of z(x) = make(x).matrices(rows perturbed by x) against the H at x = 0."""
    n = lay.n
    steps = _steps(lay)

    def z(x):
        r, ww = _perturb(row, w, lay, x)
        return make(x).matrices(Epoch(t, 1, (NavRow(r, ww, np.zeros(3)),), lay, n, item))[0]

    J = np.empty((z(np.zeros(n)).size, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = steps[i]
        J[:, i] = (z(e) - z(-e)) / (2 * steps[i])
    z0, H, R = make(np.zeros(n)).matrices(Epoch(t, 1, (NavRow(row, w, np.zeros(3)),), lay, n, item))
    err = np.abs(H - J).max() / np.abs(H).max()
    assert err < 1e-6, f"relative error {err:.2e}\nH={H}\nJ={J}"
    return z0, H, R


def test_zupt_H_and_value():
    lay = _model().layout
    row = _row()
    z, H, R = _check(lambda x: ZeroVelocity([(0, 10)], 0.02), lay, row, np.array([0.01, 0.0, 0.02]))
    np.testing.assert_array_equal(z, row[4:7])
    assert np.allclose(R, 4e-4)


def test_zaru_H_is_the_jacobian_and_zero_at_rest():
    lay = _model().layout
    row = _row(vel=(0.0, 0.0, 0.0))
    C = A.quat_to_dcm(row[:4])
    lat = row[7]
    w_true = C.T @ np.array([0.0, WIE * math.cos(lat), WIE * math.sin(lat)])
    z, H, R = _check(lambda x: ZeroRate([(0, 10)], 1e-4), lay, row, w_true + [0.01, -0.02, 0.03])
    z0 = ZeroRate([(0, 10)], 1e-4).matrices(
        Epoch(0.0, 1, (NavRow(row, w_true, np.zeros(3)),), lay, lay.n, 0))[0]
    assert np.abs(z0).max() < 1e-18                       # the Earth rate is removed exactly
    assert np.any(H[:, lay.slice("eps_m")] != 0) and np.any(H[:, lay.slice("kg")] != 0)


@pytest.mark.parametrize("mount", [None, (0.02, -0.01, 0.05), "matrix"])
def test_nhc_H(mount):
    if mount == "matrix":
        mount = A.euler_to_dcm(np.array([0.1, 0.0, -0.2]))
    lay = _model(es.lever_arm()).layout
    row = _row()
    make = lambda x: NonHolonomic((0.1, 0.05), mount=mount, lever_arm=np.array([0.3, -1.2, -0.4])  # noqa: E731
                                  + x[lay.slice("lev")], lever_block="lev")
    z, H, R = _check(make, lay, row, np.array([0.01, -0.02, 0.3]))
    Cvb = mount_matrix(mount)
    vb = A.quat_to_dcm(row[:4]).T @ row[4:7] + np.cross([0.01, -0.02, 0.3], [0.3, -1.2, -0.4])
    np.testing.assert_allclose(z, (Cvb @ vb)[[0, 2]], rtol=1e-12)


def test_body_velocity_H():
    lay = _model(es.lever_arm()).layout
    row = _row()
    make = lambda x: BodyVelocity([0.0], [[0.1, 12.0, 0.0]], 0.1, mount=(0.0, 0.0, 0.03),  # noqa: E731
                                  lever_arm=np.array([0.0, 1.0, -0.5]) + x[lay.slice("lev")],
                                  lever_block="lev")
    z, H, R = _check(make, lay, row, np.array([0.01, -0.02, 0.3]))
    assert z.shape == (3,) and np.allclose(R, 0.01)


@pytest.mark.parametrize("nhc", [None, (0.1, 0.1)])
def test_odometer_H_with_scale_and_lever(nhc):
    lay = _model(es.lever_arm(), es.odometer_scale()).layout
    row = _row()
    C = A.quat_to_dcm(row[:4])
    row[4:7] = C @ np.array([0.3, 12.0, 0.1])             # driving forward
    w = np.array([0.01, -0.02, 0.3])
    lev = np.array([0.7, -1.0, -0.3])
    v_true = (C.T @ row[4:7] + np.cross(w, lev))[1]
    t_odo = np.array([-1.0, 0.0, 1.0])

    def make(x):
        k = x[lay.slice("kod")][0]
        return Odometer(t_odo, np.full(3, (1 + k) * v_true), 0.05, lever_arm=lev + x[lay.slice("lev")],
                        lever_block="lev", nhc_sigma=nhc)

    z, H, R = _check(make, lay, row, w)
    assert abs(z[0]) < 1e-12                               # the true reading
    assert z.size == (1 if nhc is None else 3)


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


@pytest.mark.parametrize("t_epoch", [0.0, 0.3])
def test_lever_position_fix_H(t_epoch):
    lay = _model(es.lever_arm()).layout
    row = _row()
    d = A.quat_to_dcm(row[:4]) @ np.array([0.5, 1.0, 1.5])      # the true antenna
    rm, rn = radii(row[7], row[9])
    fix = np.array([[row[7] + d[1] / rm, row[8] + d[0] / (rn * math.cos(row[7])), row[9] + d[2]]])
    make = lambda x: LeverPositionFix([0.0], fix, [3.0, 3.0, 5.0],  # noqa: E731
                                      lever_arm=np.array([0.5, 1.0, 1.5]) + x[lay.slice("lev")])
    _check(make, lay, row, np.array([0.01, -0.02, 0.3]), t=t_epoch)


def test_lever_velocity_fix_H():
    lay = _model(es.lever_arm()).layout
    row = _row()
    make = lambda x: LeverVelocityFix([0.0], [row[4:7]], 0.1,  # noqa: E731
                                      lever_arm=np.array([0.5, 1.0, 1.5]) + x[lay.slice("lev")])
    z, H, R = _check(make, lay, row, np.array([0.01, -0.02, 0.3]))
    assert np.any(H[:, lay.slice("eps_m")] != 0)


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
