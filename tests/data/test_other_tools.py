"""Other tools' files as they ship them, read through the data front door without a format
name: NaveGo's MATLAB structs (``ins_gnss.m``'s documented fields and units), KF-GINS /
OB_GINS's headerless text and binary files (their READMEs' column tables), ROS 1 and ROS 2
bags (sensor_msgs/Imu, NavSatFix, TwistWithCovarianceStamped through ``rosbags``).
Oracle: a record written in the tool's own layout (its axes, units and field names) and
read back equals the original; what the file says about its sensor (σ, lever arm, noise,
start attitude) comes back in sinslab's axes and units."""
import numpy as np
import pytest
import scipy.io

from sinslab import data
from sinslab.app.error_model import load_error_model
from sinslab.core import attitude as A
from sinslab.core.records import Fixes, ImuRecord, NavSeries
from rosbag_files import write_bag as _write_bag
from sinslab.data import kfgins

FRD = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])     # RFU <-> FRD (its own inverse)


def _imu(n=400, dt=0.01, t0=138000.0):
    rng = np.random.default_rng(5)
    return ImuRecord(t0 + dt * np.arange(1, n + 1), rng.normal(0, 1e-3, (n, 3)),
                     rng.normal(0, 1e-2, (n, 3)) + [0, 0, 0.098], dt)


def _fixes(n=10, t0=138000.0, vel=True):
    rng = np.random.default_rng(6)
    t = t0 + 0.2 * np.arange(1, n + 1)
    lat = np.radians(45.06 + 1e-5 * np.arange(n))
    lon = np.radians(7.65 + 1e-5 * np.arange(n))
    v = rng.normal(0, 3, (n, 3)) if vel else None
    sv = np.tile([0.05, 0.06, 0.07], (n, 1)) if vel else None
    return Fixes(t, lat, lon, 300 + rng.normal(0, 1, n), np.tile([1.0, 1.5, 3.0], (n, 1)), v, sv)


# ----------------------------------------------------------------------------- NaveGo ---
def _navego_imu_struct(imu, **extra):
    """The IMU struct NaveGo's ins_gnss reads: rates in forward-right-down axes."""
    s = {"t": imu.t[:, None], "fb": imu.dv @ FRD.T / imu.dt, "wb": imu.dtheta @ FRD.T / imu.dt,
         "freq": 1 / imu.dt}
    s.update(extra)
    return s


def test_navego_structs_round_trip(tmp_path):
    """NaveGo's imu/gnss structs (field names, radians, NED, FRD lever arm, its σ) read back
    as the record written; the noise fields become an error model the filter reads; the
    static biases are removed as NaveGo removes them."""
    imu, fx = _imu(), _fixes()
    gb_sta, ab_sta = np.array([1e-3, -2e-3, 5e-4]), np.array([0.02, -0.01, 0.03])
    st = _navego_imu_struct(imu, arw=np.full((1, 3), 2e-4), vrw=np.full((1, 3), 1e-3),
                            gb_dyn=np.full((1, 3), 5e-5), ab_dyn=np.full((1, 3), 2e-3),
                            gb_corr=np.full((1, 3), 300.0), ab_corr=np.full((1, 3), 300.0),
                            ini_align=np.array([[0.01, -0.02, np.radians(-30)]]),
                            ini_align_err=np.array([[0.02, 0.03, 0.1]]))
    st["wb"] = st["wb"] + gb_sta
    st["fb"] = st["fb"] + ab_sta
    st.update(gb_sta=gb_sta[None], ab_sta=ab_sta[None])
    g = {"t": fx.t[:, None], "lat": fx.lat[:, None], "lon": fx.lon[:, None], "h": fx.h[:, None],
         "vel": A.vec_enu_to_ned(fx.vel), "stdm": np.array([[1.0, 1.5, 3.0]]),
         "stdv": np.array([[0.06, 0.05, 0.07]]), "larm": np.array([[0.5], [-0.2], [-1.1]]), "freq": 5.0}
    pi, pg = tmp_path / "ekinox_imu.mat", tmp_path / "ekinox_gnss.mat"
    scipy.io.savemat(pi, {"ekinox_imu": st})
    scipy.io.savemat(pg, {"ekinox_gnss": g})
    d = data.load_imu(pi)
    assert d.format == "navego" and d.meta["variable"] == "ekinox_imu"
    np.testing.assert_allclose(d.imu.t, imu.t, atol=1e-9)
    np.testing.assert_allclose(d.imu.dtheta, imu.dtheta, atol=1e-15)
    np.testing.assert_allclose(d.imu.dv, imu.dv, atol=1e-15)
    err, extras, _ = load_error_model(d.meta["error_model"])
    np.testing.assert_allclose(err.gyro_arw, 2e-4)
    np.testing.assert_allclose(err.accel_vrw, 1e-3)
    np.testing.assert_allclose(err.gyro_bias_instability, 5e-5)
    np.testing.assert_allclose(err.gyro_corr_time, 300.0)
    np.testing.assert_allclose(extras["initial"]["attitude"], [0.03, 0.02, 0.1])     # pitch, roll, yaw
    C = A.euler_to_dcm(d.meta["initial_attitude"])
    Cn = A.dcm_to_ned(C)                                   # back to NaveGo's frames: yaw −30° clockwise
    np.testing.assert_allclose(np.degrees(np.arctan2(Cn[1, 0], Cn[0, 0])), -30.0, atol=1e-9)
    fx2, meta = data.load_fixes(pg)
    assert meta["format"] == "navego" and meta["sigma_source"] == "ekinox_gnss.stdm"
    np.testing.assert_allclose(fx2.lat, fx.lat, atol=0)
    np.testing.assert_allclose(fx2.vel, fx.vel, atol=1e-12)
    np.testing.assert_allclose(fx2.sigma[0], [1.0, 1.5, 3.0])
    np.testing.assert_allclose(fx2.sigma_vel[0], [0.05, 0.06, 0.07])       # NED σ -> east, north, up
    np.testing.assert_allclose(meta["lever_arm"], [-0.2, 0.5, 1.1])         # FRD -> RFU


def test_navego_reference_struct_is_truth(tmp_path):
    """NaveGo's reference struct (roll, pitch, yaw clockwise, NED velocity) read as a
    NavSeries in sinslab's frames: the attitude matrix is the same rotation."""
    n = 5
    rpy = np.column_stack([np.full(n, 0.02), np.full(n, -0.05), np.linspace(-3, 3, n)])
    ref = {"t": np.arange(n)[:, None], "lat": np.full((n, 1), 0.78), "lon": np.full((n, 1), 0.13),
           "h": np.full((n, 1), 300.0), "vel": np.tile([1.0, 2.0, -0.1], (n, 1)),
           "roll": rpy[:, :1], "pitch": rpy[:, 1:2], "yaw": rpy[:, 2:3], "pos_std": np.zeros((n + 3, 3))}
    p = tmp_path / "ref.mat"
    scipy.io.savemat(p, {"ref": ref})
    s = data.read_truth(p)
    np.testing.assert_allclose(s.vel[0], [2.0, 1.0, 0.1])
    from scipy.spatial.transform import Rotation
    for k in range(n):
        Cned = Rotation.from_euler("ZYX", rpy[k, ::-1]).as_matrix()
        np.testing.assert_allclose(A.euler_to_dcm(s.att[k]), A.dcm_from_ned(Cned), atol=1e-12)


def test_navego_struct_errors_name_the_field(tmp_path):
    imu = _imu(20)
    st = _navego_imu_struct(imu)
    st["fb"] = st["fb"][:-1]
    p = tmp_path / "imu.mat"
    scipy.io.savemat(p, {"imu": st})
    with pytest.raises(ValueError, match=r"imu\.fb has 19 rows but imu\.t has 20"):
        data.load_imu(p)
    g = {"t": np.arange(3.0)[:, None], "lat": np.full((3, 1), 45.0), "lon": np.full((3, 1), 7.0),
         "h": np.zeros((3, 1))}
    q = tmp_path / "gnss.mat"
    scipy.io.savemat(q, {"gnss": g})
    with pytest.raises(ValueError, match="in radians"):
        data.load_fixes(q)


# --------------------------------------------------------------------- KF-GINS / OB_GINS ---
def test_kfgins_imu_text_binary_and_odometer_round_trip(tmp_path):
    """The IMU file KF-GINS reads (seconds of week, Δθ rad, Δv m/s, forward-right-down),
    as text and as .bin doubles, and OB_GINS's 8-column text with the odometer speed."""
    imu = _imu()
    a = np.column_stack([imu.t, imu.dtheta @ FRD.T, imu.dv @ FRD.T])
    txt, b, o = tmp_path / "ADIS16465.txt", tmp_path / "ADIS16465.bin", tmp_path / "odo.txt"
    np.savetxt(txt, a, fmt="%.6f" + " %.17g" * 6)
    a.astype("<f8").tofile(b)
    speed = np.linspace(0, 10, len(imu))
    np.savetxt(o, np.column_stack([a, speed]), fmt="%.6f" + " %.17g" * 7)
    for p in (txt, b, o):
        assert data.guess_imu_format(p) == "kf-gins"
        d = data.load_imu(p)
        assert d.format == "kf-gins"
        np.testing.assert_allclose(d.imu.dtheta, imu.dtheta, atol=1e-15)
        np.testing.assert_allclose(d.imu.dv, imu.dv, atol=1e-15)
    np.testing.assert_allclose(data.load_imu(o).meta["odometer"][1], speed, atol=1e-12)
    w = kfgins.write_kfgins_imu(tmp_path / "w.txt", imu)
    np.testing.assert_allclose(data.load_imu(w).imu.dtheta, imu.dtheta, atol=1e-15)


def test_kfgins_gnss_pos_is_told_from_rtklib_by_content(tmp_path):
    """A KF-GINS / OB_GINS GNSS file under its own ``.pos`` name (7 columns: no RTKLIB
    header, degrees, σ north-east-down) and its 13-column form with NED velocity; an
    RTKLIB .pos stays RTKLIB's."""
    fx = _fixes()
    p7 = tmp_path / "GNSS_RTK.pos"
    rows = np.column_stack([fx.t, np.degrees(fx.lat), np.degrees(fx.lon), fx.h, fx.sigma])
    np.savetxt(p7, rows, fmt="%.3f    %.10f   %.10f     %.3f    %.3f    %.3f    %.3f ")
    assert data.guess_fix_format(p7) == "kf-gins"
    f7, m = data.load_fixes(p7)
    assert m["format"] == "kf-gins" and f7.vel is None
    np.testing.assert_allclose(np.degrees(f7.lat), np.degrees(fx.lat), atol=1e-10)
    np.testing.assert_allclose(f7.sigma, fx.sigma)
    p13 = kfgins.write_kfgins_gnss(tmp_path / "gnss13.txt", fx)
    f13, _ = data.load_fixes(p13)
    np.testing.assert_allclose(f13.vel, fx.vel, atol=1e-4)
    np.testing.assert_allclose(f13.sigma_vel, fx.sigma_vel, atol=1e-4)
    rtk = tmp_path / "rtk.pos"
    rtk.write_text("% program   : RTKLIB\n%  GPST   latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)"
                   "   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n"
                   "2021/03/19 00:00:00.000   45.060000000    7.650000000   300.0000   1   8   0.0100   "
                   "0.0100   0.0200   0.0000   0.0000   0.0000   0.00    0.0\n")
    assert data.guess_fix_format(rtk) == "rtklib-pos"


def test_kfgins_truth_nav_round_trip(tmp_path):
    n = 6
    att = np.column_stack([np.full(n, 0.01), np.full(n, -0.02), np.linspace(-3, 3, n)])
    s = NavSeries(456300.0 + np.arange(n), np.full(n, 0.53), np.full(n, 1.99), np.full(n, 20.0),
                  np.tile([1.0, 2.0, 0.1], (n, 1)), att)
    p = kfgins.write_kfgins_nav(tmp_path / "truth.nav", s, week=2200)
    assert kfgins.sniff(p) == "kf-gins-nav"
    r = data.read_truth(p)
    np.testing.assert_allclose(r.t, s.t)
    np.testing.assert_allclose(r.vel, s.vel, atol=1e-6)
    for k in range(n):
        np.testing.assert_allclose(A.euler_to_dcm(r.att[k]), A.euler_to_dcm(s.att[k]), atol=1e-7)


# ----------------------------------------------------------------------------- ROS bags ---
@pytest.mark.parametrize("ros1", [False, True], ids=["ros2", "ros1"])
def test_rosbag_imu_fix_and_velocity_round_trip(tmp_path, ros1):
    """A ROS 1 and a ROS 2 bag with sensor_msgs/Imu (REP 103 x-forward y-left z-up),
    NavSatFix (ENU covariance) and TwistWithCovarianceStamped (ENU velocity) read back as
    the record, fixes, σ and velocities written."""
    pytest.importorskip("rosbags")
    imu, fx = _imu(200), _fixes()
    p = tmp_path / ("run.bag" if ros1 else "run")
    _write_bag(p, imu, fx, ros1)
    assert data.guess_imu_format(p) == "rosbag" and data.guess_fix_format(p) == "rosbag"
    d = data.load_imu(p)
    assert d.format == "rosbag" and d.meta["topic"] == "/imu/data"
    np.testing.assert_allclose(d.imu.t, imu.t, atol=1e-8)
    np.testing.assert_allclose(d.imu.dtheta, imu.dtheta, atol=1e-12)
    np.testing.assert_allclose(d.imu.dv, imu.dv, atol=1e-12)
    f2, meta = data.load_fixes(p)
    assert meta["topic"] == "/gnss/fix" and meta["velocity_topic"] == "/gnss/vel"
    np.testing.assert_allclose(f2.lat, fx.lat, atol=1e-15)
    np.testing.assert_allclose(f2.sigma, fx.sigma, atol=1e-12)
    np.testing.assert_allclose(f2.vel, fx.vel, atol=1e-12)
    np.testing.assert_allclose(f2.sigma_vel, fx.sigma_vel, atol=1e-12)


def test_rosbag_without_imu_names_what_it_holds(tmp_path):
    pytest.importorskip("rosbags")
    fx = _fixes()
    p = tmp_path / "run"
    _write_bag(p, _imu(5), fx)
    with pytest.raises(ValueError, match="no sensor_msgs/Imu topic '/x'.*/imu/data"):
        data.load_imu(p, topic="/x")
