"""Validation of the record containers: every bad input is a ValueError naming the problem."""
import math

import numpy as np
import pytest

from sinslab.core.records import Fixes, ImuRecord, NavSeries, NavState, check_times


def imu(n=10, dt=0.01, t0=0.0):
    t = t0 + dt * np.arange(1, n + 1)
    return t, np.zeros((n, 3)), np.zeros((n, 3))


def test_valid_record():
    t, a, b = imu(100)
    r = ImuRecord(t, a, b)
    assert len(r) == 100 and r.dt == pytest.approx(0.01) and r.t0 == pytest.approx(0.0)
    assert r.dtheta.dtype == np.float64 and r.dtheta.flags.c_contiguous
    r2 = ImuRecord(t, a.tolist(), b, dt=0.01)
    assert r2.dt == pytest.approx(0.01)


@pytest.mark.parametrize("where", ["dtheta", "dv"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_increments(where, bad):
    t, a, b = imu()
    (a if where == "dtheta" else b)[4, 1] = bad
    with pytest.raises(ValueError, match=rf"{where} has a NaN/inf value at sample 4"):
        ImuRecord(t, a, b)


def test_time_problems():
    t, a, b = imu()
    t2 = t.copy()
    t2[5] = t2[4]
    with pytest.raises(ValueError, match="duplicated stamp.*index 5"):
        ImuRecord(t2, a, b)
    t2 = t.copy()
    t2[[5, 6]] = t2[[6, 5]]
    with pytest.raises(ValueError, match="not sorted.*index 6"):
        ImuRecord(t2, a, b)
    t2 = t.copy()
    t2[3] += 0.004
    with pytest.raises(ValueError, match="not uniformly sampled") as e:
        ImuRecord(t2, a, b)
    assert "np.float64" not in str(e.value)          # the numbers as a user writes them
    t2 = t.copy()
    t2[3] = np.nan
    with pytest.raises(ValueError, match="non-finite value at index 3"):
        ImuRecord(t2, a, b)
    # a gap is non-uniform sampling
    t2 = np.concatenate([t[:5], t[5:] + 1.0])
    with pytest.raises(ValueError, match="not uniformly sampled"):
        ImuRecord(t2, a, b)
    # jitter within tolerance is accepted
    t2 = t + np.random.default_rng(0).uniform(-1e-6, 1e-6, t.size)
    ImuRecord(t2, a, b)


def test_shapes_and_empty():
    t, a, b = imu()
    with pytest.raises(ValueError, match=r"dtheta must have shape \(10, 3\), got \(10, 2\)"):
        ImuRecord(t, a[:, :2], b)
    with pytest.raises(ValueError, match=r"dv must have shape \(10, 3\), got \(9, 3\)"):
        ImuRecord(t, a, b[:9])
    with pytest.raises(ValueError, match=r"dtheta must have shape"):
        ImuRecord(t, a.T, b)
    with pytest.raises(ValueError, match="empty"):
        ImuRecord(np.array([]), np.zeros((0, 3)), np.zeros((0, 3)))
    with pytest.raises(ValueError, match="1-D"):
        ImuRecord(t.reshape(2, 5), a, b)
    with pytest.raises(ValueError, match="explicit dt"):
        ImuRecord([0.01], np.zeros((1, 3)), np.zeros((1, 3)))
    one = ImuRecord([0.01], np.zeros((1, 3)), np.zeros((1, 3)), dt=0.01)
    assert len(one) == 1 and one.t0 == pytest.approx(0.0)
    with pytest.raises(ValueError, match="disagrees"):
        ImuRecord(t, a, b, dt=0.02)


def test_from_rates_and_slice():
    n, dt = 50, 0.02
    t = dt * np.arange(1, n + 1)
    w = np.tile([0.1, -0.2, 0.3], (n, 1))
    f = np.tile([0.0, 0.0, 9.8], (n, 1))
    r = ImuRecord.from_rates(t, w, f)
    assert np.allclose(r.dtheta, w * dt) and np.allclose(r.dv, f * dt) and r.dt == pytest.approx(dt)
    s = r.slice(0.1, 0.3)
    assert s.t[0] > 0.1 and s.t[-1] <= 0.3 + 1e-12 and len(s) == 10
    with pytest.raises(ValueError, match="no IMU samples"):
        r.slice(5.0, 6.0)
    with pytest.raises(ValueError, match="NaN/inf"):
        ImuRecord.from_rates(t, np.full((n, 3), np.nan), f)


def test_check_times_direct():
    assert check_times([1.0, 2.0, 3.0]) == pytest.approx(1.0)
    assert math.isnan(check_times([1.0]))
    assert check_times([0.0, 1.0, 3.0], uniform=False) == pytest.approx(1.5)
    with pytest.raises(ValueError, match="gnss time is empty"):
        check_times([], "gnss time")
    with pytest.raises(ValueError, match="one-dimensional"):
        check_times(np.zeros((2, 2)))


def navseries(m=5):
    return dict(t=np.arange(m, dtype=float), lat=np.full(m, 0.5), lon=np.full(m, 2.0), h=np.zeros(m),
                vel=np.zeros((m, 3)), att=np.zeros((m, 3)))


def test_navseries():
    s = NavSeries(**navseries())
    assert len(s) == 5 and s.pos.shape == (5, 3) and s.att_imu is None
    sub = s.at(slice(1, 3))
    assert len(sub) == 2 and sub.t[0] == 1.0
    for name, bad in (("vel", np.zeros((5, 2))), ("att", np.zeros((4, 3))), ("lat", np.zeros(4)),
                      ("att_imu", np.zeros((5, 4)))):
        kw = navseries()
        kw[name] = bad
        with pytest.raises(ValueError, match=rf"{name} must have shape"):
            NavSeries(**kw)
    s = NavSeries(**navseries(), att_imu=np.ones((5, 3)))
    st = NavState.from_series(s, 2)
    assert np.all(st.att == 1.0) and st.t == 2.0
    assert np.all(NavState.from_series(s, 2, imu_frame=False).att == 0.0)


def test_navstate_validation():
    st = NavState(0.5, 2.0, 100.0, [1, 2, 3], [0.1, 0.2, 0.3])
    assert st.vel.shape == (3,) and st.t == 0.0
    with pytest.raises(ValueError, match="latitude 95 deg is beyond"):
        NavState(math.radians(95), 0.0, 0.0, [0, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="latitude -90.1 deg"):
        NavState(math.radians(-90.1), 0.0, 0.0, [0, 0, 0], [0, 0, 0])
    NavState(math.pi / 2, 0.0, 0.0, [0, 0, 0], [0, 0, 0])           # the pole itself is fine
    with pytest.raises(ValueError, match="initial h is not finite"):
        NavState(0.5, 0.0, np.nan, [0, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="initial lat is not finite"):
        NavState(np.inf, 0.0, 0.0, [0, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="initial vel must be 3 finite numbers"):
        NavState(0.5, 0.0, 0.0, [0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="initial att must be 3 finite numbers"):
        NavState(0.5, 0.0, 0.0, [0, 0, 0], [0, np.nan, 0])


def _fixes(J=4, **kw):
    t = np.arange(J, dtype=float)
    return dict(t=t, lat=np.full(J, 0.5), lon=np.full(J, 1.0), h=np.full(J, 10.0),
                sigma=np.full((J, 3), 2.0), **kw)


def test_fixes_defaults_and_select():
    """One Fixes for GNSS solutions and two-GEO fixes: arrival defaults to validity, the
    quality flag to 0, and select keeps every optional column aligned."""
    f = Fixes(**_fixes())
    assert np.array_equal(f.t_arrive, f.t) and f.t_arrive is not f.t
    assert np.array_equal(f.quality, [0, 0, 0, 0]) and f.vel is None and f.err is None
    g = Fixes(**_fixes(vel=np.ones((4, 3)), sigma_vel=np.full((4, 3), 0.1), t_arrive=np.arange(4) + 0.5,
                       err=np.arange(12.0).reshape(4, 3)))
    s = g.select(np.array([False, True, False, True]))
    assert len(s) == 2 and np.array_equal(s.t, [1.0, 3.0]) and np.array_equal(s.t_arrive, [1.5, 3.5])
    assert np.array_equal(s.err, [[3, 4, 5], [9, 10, 11]]) and s.vel.shape == (2, 3)
    h = Fixes(**{**_fixes(), "h": np.full(4, np.nan), "sigma": np.stack([np.full(4, 1.0)] * 2 + [np.full(4, np.nan)], -1)})
    assert np.all(np.isnan(h.h))           # a horizontal fix: height and its σ not measured
    assert len(Fixes([], [], [], [], np.zeros((0, 3)))) == 0


@pytest.mark.parametrize("change,msg", [
    ({"t_arrive": np.arange(4) - 0.5}, "arrives before"),
    ({"t": np.array([0.0, 1.0, 1.0, 2.0])}, "strictly increasing"),
    ({"sigma": np.zeros((4, 3))}, "sigmas must be > 0"),
    ({"lat": np.array([0.5, np.nan, 0.5, 0.5])}, "lat has NaN"),
    ({"sigma": np.ones((4, 2))}, r"sigma must have shape \(4, 3\)"),
    ({"lon": np.ones(3)}, r"lon must have shape \(4,\)"),
    ({"quality": np.zeros(3)}, "quality has 3 values"),
])
def test_fixes_validation(change, msg):
    with pytest.raises(ValueError, match=msg):
        Fixes(**{**_fixes(), **change})


def test_imu_record_to_pandas_round_trip():
    rng = np.random.default_rng(0)
    t = 0.005 * np.arange(1, 201)
    r = ImuRecord(t, rng.normal(size=(200, 3)) * 1e-5, rng.normal(size=(200, 3)) * 1e-3)
    df = r.to_pandas()
    assert list(df.columns) == ["t_s", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad",
                                "dv_x_mps", "dv_y_mps", "dv_z_mps"]
    back = ImuRecord(df["t_s"], df.filter(like="dtheta_"), df.filter(like="dv_"))
    assert np.array_equal(back.t, r.t) and np.array_equal(back.dtheta, r.dtheta) and np.array_equal(back.dv, r.dv)


def test_nav_series_to_pandas_degrees_and_heading():
    """Columns of navigate's solution.csv; heading = −yaw in [0, 360) deg (README conventions)."""
    m = 5
    yaw = np.radians([0.0, 90.0, -90.0, 180.0, -30.0])
    att = np.c_[np.radians(np.arange(m)), np.radians(-np.arange(m)), yaw]
    s = NavSeries(np.arange(m, dtype=float), np.full(m, 0.5), np.full(m, -1.0), np.full(m, 100.0),
                  np.tile([1.0, 2.0, 3.0], (m, 1)), att, att_imu=att[::-1])
    df = s.to_pandas()
    assert list(df.columns)[:10] == ["t_s", "lat_deg", "lon_deg", "h_m", "vE_mps", "vN_mps", "vU_mps",
                                     "pitch_deg", "roll_deg", "heading_deg"]
    assert list(df.columns)[10:] == ["imu_pitch_deg", "imu_roll_deg", "imu_heading_deg"]
    np.testing.assert_allclose(df["heading_deg"], [0.0, 270.0, 90.0, 180.0, 30.0], atol=1e-12)
    np.testing.assert_allclose(df["lat_deg"], math.degrees(0.5))
    np.testing.assert_allclose(df["pitch_deg"], np.arange(m), atol=1e-12)
    np.testing.assert_allclose(df["imu_heading_deg"], [30.0, 180.0, 90.0, 270.0, 0.0], atol=1e-12)
    assert df["vN_mps"].eq(2.0).all()
    assert "imu_pitch_deg" not in NavSeries(s.t, s.lat, s.lon, s.h, s.vel, s.att).to_pandas()
