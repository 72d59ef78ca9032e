"""Readers/writers of recorded data (the sinslab.data formats and front door) and checks of the rtklib-drive facts."""
import math
from pathlib import Path

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab import data
from sinslab.core.records import Fixes
from sinslab.data import frames
from sinslab.data import matlab
from sinslab.data import rtklib
from sinslab.data import tables
from sinslab.fusion import recorded
from sinslab.core import units as u
from sinslab.core.records import ImuRecord

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
DRIVE = DATA / "rtklib-drive"
needs_drive = pytest.mark.skipif(not (DRIVE / "imu_1934.csv").exists(), reason="rtklib-drive not available")
needs_transfer = pytest.mark.skipif(not (DATA / "psins-transfer").exists(), reason="psins-transfer not available")
MOUNT = "rpy:%g,%g,%g" % rtklib.RTKLIB_DRIVE["mount_rpy_frd_deg"]


def _w(tmp_path, text, name="x.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _imu(n=50, dt=0.01):
    rng = np.random.default_rng(0)
    return ImuRecord(dt * np.arange(1, n + 1), rng.normal(0, 1e-4, (n, 3)), rng.normal(0, 1e-2, (n, 3)) + [0, 0, 0.098])


# ----------------------------------------------------------------- generic tables -------
def test_csv_units_in_header(tmp_path):
    p = _w(tmp_path, "time[ms],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g],extra\n"
                     + "".join(f"{10 * k},1,0,-2,0,0.5,1,7\n" for k in range(1, 11)))
    d = data.load_imu(p)
    assert d.imu.dt == pytest.approx(0.01) and len(d.imu) == 10 and d.gaps.shape == (0, 2)
    assert d.imu.dtheta[0] == pytest.approx(np.radians([1, 0, -2]) * 0.01)
    assert d.imu.dv[0] == pytest.approx(np.array([0, 0.5, 1]) * u.g0 * 0.01)
    # units by option, increments, FRD source frame
    p2 = _w(tmp_path, "t,dax,day,daz,dvx,dvy,dvz\n0.1,1e-3,0,0,0,0,-0.98\n0.2,1e-3,0,0,0,0,-0.98\n", "b.csv")
    d2 = tables.read_table_imu(p2, gyro_unit="rad", accel_unit="m/s", frame="frd")
    assert d2.imu.dtheta[0] == pytest.approx([0, 1e-3, 0]) and d2.imu.dv[0] == pytest.approx([0, 0, 0.98])
    # the minimal SI CSV of the alignment reader keeps working
    p3 = _w(tmp_path, "t,dtheta_x,dtheta_y,dtheta_z,dv_x,dv_y,dv_z\n0.1,0,0,1e-6,0,0,0.98\n0.2,0,0,1e-6,0,0,0.98\n", "c.csv")
    assert data.load_imu(p3).imu.dv[1, 2] == pytest.approx(0.98)


@pytest.mark.parametrize("fmt", ["csv", "parquet", "mat"])
def test_write_read_round_trip(tmp_path, fmt):
    imu = _imu()
    p = data.write_imu(tmp_path / f"r.{fmt}", imu)
    d = data.load_imu(p)
    assert np.allclose(d.imu.t, imu.t) and np.allclose(d.imu.dtheta, imu.dtheta, rtol=1e-12, atol=0)
    assert np.allclose(d.imu.dv, imu.dv, rtol=1e-12, atol=0)


def test_fix_csv_round_trip(tmp_path):
    J = 5
    fx = Fixes(np.arange(J, dtype=float), np.radians(np.full(J, 40.0)), np.radians(np.full(J, -105.0)),
                  np.full(J, 1600.0), np.full((J, 3), 0.02), np.ones((J, 3)), np.full((J, 3), 0.05),
                  np.zeros(J, int))
    g = data.read_fixes(data.write_fixes(tmp_path / "f.csv", fx))
    assert np.allclose(g.lat, fx.lat) and np.allclose(g.vel, fx.vel) and np.allclose(g.sigma, 0.02)


@pytest.mark.parametrize("fmt,module", [("csv", "tables"), ("parquet", "tables"), ("mat", "matlab")])
def test_every_imu_writer_round_trips_exactly(tmp_path, fmt, module):
    """write_imu -> load_imu through the front door is lossless (17 significant digits in
    CSV, float64 in Parquet and MATLAB) and picks the format module from the suffix."""
    imu = _imu(n=37, dt=0.005)
    p = data.write_imu(tmp_path / f"r.{fmt}", imu)
    assert data.guess_imu_format(p) == fmt
    d = data.load_imu(p)
    assert d.format == fmt and d.n_raw == len(imu) and d.gaps.shape == (0, 2)
    for a, b in ((d.imu.t, imu.t), (d.imu.dtheta, imu.dtheta), (d.imu.dv, imu.dv)):
        assert np.array_equal(a, b)
    assert getattr(__import__(f"sinslab.data.{module}", fromlist=["x"]), f"read_{'mat' if fmt == 'mat' else 'table'}_imu")


def test_horizontal_lagged_fixes_round_trip(tmp_path):
    """Two-GEO style fixes (no height, arrival after validity) written by write_fixes and
    read back by the CSV reader: the same Fixes (12 significant digits)."""
    J = 4
    t = 10.0 + np.arange(J)
    nan = np.full(J, np.nan)
    fx = Fixes(t, np.radians(32.0 + 1e-4 * np.arange(J)), np.radians(np.full(J, 118.0)), nan,
               np.stack([np.full(J, 40.0), np.full(J, 30.0), nan], -1), t_arrive=t + 1.25)
    p = data.write_fixes(tmp_path / "h.csv", fx)
    head = p.read_text().splitlines()[0]
    assert head == "t[s],t_arrive[s],lat[deg],lon[deg],sd_n[m],sd_e[m]"
    g = data.read_fixes(p)
    assert np.array_equal(g.t, fx.t) and np.array_equal(g.t_arrive, fx.t_arrive)
    assert np.allclose(g.lat, fx.lat, rtol=1e-12, atol=0) and np.all(np.isnan(g.h))
    assert np.array_equal(g.sigma[:, :2], fx.sigma[:, :2]) and np.all(np.isnan(g.sigma[:, 2]))
    assert g.vel is None


def test_two_geo_fix_list(tmp_path):
    """The recorded double-star fix list: degrees -> rad, σ north/east, optional arrival."""
    p = _w(tmp_path, "# two-GEO\n" + ",".join(tables.TWO_GEO_COLUMNS) + ",extra\n"
           "1,2.5,30,110,40,30,9\n2,3.5,30.001,110,41,31,9\n")
    fx = data.read_fixes(p, "two-geo")
    assert np.array_equal(fx.t, [1.0, 2.0]) and np.array_equal(fx.t_arrive, [2.5, 3.5])
    assert np.allclose(fx.lat, np.radians([30.0, 30.001]), rtol=0, atol=1e-16)
    assert np.array_equal(fx.sigma[:, :2], [[40.0, 30.0], [41.0, 31.0]]) and np.all(np.isnan(fx.h))
    p2 = _w(tmp_path, "t_valid_s,lat_deg,lon_deg,sigma_ns_m,sigma_ew_m\n4,30,110,40,30\n", "n.csv")
    assert np.array_equal(data.read_fixes(p2, "two-geo").t_arrive, [4.0])     # no lag by default


@pytest.mark.parametrize("text,msg", [("", "empty"), ("t_valid_s,lat_deg\n1,2\n", "missing column"),
                                      (",".join(tables.TWO_GEO_COLUMNS) + "\n", "no fixes"),
                                      (",".join(tables.TWO_GEO_COLUMNS) + "\n1,2,x,4,5,6\n", "could not convert"),
                                      (",".join(tables.TWO_GEO_COLUMNS) + "\n2,1,30,110,40,30\n", "before")])
def test_bad_two_geo_fix_files(tmp_path, text, msg):
    p = tmp_path / "f.csv"
    p.write_text(text)
    with pytest.raises(ValueError, match=msg):
        data.read_fixes(p, "two-geo")


BAD = [
    ("t,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,2,3,0,0,1\n0.02,nan,2,3,0,0,1\n", r"x\.csv:3: NaN"),
    ("t,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.02,1,2,3,0,0,1\n0.01,1,2,3,0,0,1\n", r"x\.csv:3: time stamps not sorted"),
    ("t,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,2,3,0,0,1\n0.01,1,2,3,0,0,1\n", r"x\.csv:3: duplicated"),
    ("t,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,2,3,0,0,1\n0.02,1,2,3,0,0\n", r"x\.csv:3: 6 columns"),
    ("t,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,2,3,0,0,1\n0.02,1,2,x,0,0,1\n", r"x\.csv:3: not a number"),
    ("t,p,q,r,ax[g],ay[g],az[g]\n0.01,1,2,3,0,0,1\n", r"x\.csv:1: wrong columns"),
    ("t,gx,gy,gz,ax[g],ay[g],az[g]\n0.01,1,2,3,0,0,1\n", r"x\.csv:1: column 'gx' has no unit"),
    ("t,gx[deg/s],gy[rad/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,2,3,0,0,1\n", r"x\.csv:1: mixed units"),
    ("t,gx[deg/s],gy[deg/s],gz[deg/s],dvx[m/s],dvy[m/s],dvz[m/s]\n0.01,1,2,3,0,0,1\n", r"mixed units"),
    ("t,gx[m],gy[m],gz[m],ax[g],ay[g],az[g]\n0.01,1,2,3,0,0,1\n", r"not a gyro unit"),
    ("", r"x\.csv: empty file"),
    ("# only a comment\nt,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n", r"x\.csv:2: header only"),
]


@pytest.mark.parametrize("text,msg", BAD)
def test_bad_tables(tmp_path, text, msg):
    with pytest.raises(ValueError, match=msg):
        data.load_imu(_w(tmp_path, text))


def test_gaps_and_jitter(tmp_path):
    t = 0.01 * np.arange(1, 301)
    t = np.delete(t, np.arange(100, 120))                   # 0.2 s gap
    rows = "".join(f"{x:.4f},0,0,10,0,0,1\n" for x in t)
    p = _w(tmp_path, "t,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n" + rows)
    d = data.load_imu(p)
    assert d.gaps.shape == (1, 2) and d.gaps[0, 1] == pytest.approx(0.21)
    assert d.imu.dt == pytest.approx(0.01) and len(d.imu) == 300
    # bridged at the mean rate: the integrated angle is exact
    assert d.imu.dtheta[:, 2].sum() == pytest.approx(math.radians(10) * 3.0, rel=1e-9)
    with pytest.raises(ValueError, match=r"x\.csv:\d+: gap of 0\.210 s"):
        data.load_imu(p, max_gap=0.1)
    assert data.load_imu(p, max_gap=0.1, allow_gaps=True).gaps.shape == (1, 2)
    # jittery stamps (ms quantisation) -> uniform grid, cumulative angle preserved
    rng = np.random.default_rng(3)
    tj = 0.01 * np.arange(1, 501) + rng.integers(-1, 2, 500) * 1e-3
    pj = _w(tmp_path, "t,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n"
            + "".join(f"{x:.4f},0,0,10,0,0,1\n" for x in tj), "j.csv")
    dj = data.load_imu(pj)
    assert dj.jitter > 0 and np.ptp(np.diff(dj.imu.t)) < 1e-9
    assert dj.imu.dtheta[:, 2].sum() == pytest.approx(math.radians(10) * len(dj.imu) * dj.imu.dt, rel=1e-9)


def test_frames_and_mounts():
    assert frames.frame_matrix("frd") @ [1, 0, 0] == pytest.approx([0, 1, 0])      # forward
    assert frames.frame_matrix("frd") @ [0, 0, 1] == pytest.approx([0, 0, -1])     # down
    assert frames.frame_matrix("flu") @ [0, 1, 0] == pytest.approx([-1, 0, 0])     # left
    # roll 180 + yaw 180 (Groves, FRD): sensor x back, y right, z up
    M = frames.rpy_frd_matrix(np.radians([180, 0, 180]))
    assert M == pytest.approx(np.diag([-1.0, 1.0, -1.0]), abs=1e-12)
    R = frames.sensor_to_body("rpy:180,0,180", "frd")
    assert R @ [0, 0, 1] == pytest.approx([0, 0, 1], abs=1e-12)                # sensor up -> up
    assert R @ [-1, 0, 0] == pytest.approx([0, 1, 0], abs=1e-12)               # sensor -x -> forward
    # Groves' formula is the passive R1 R2 R3 product
    r = np.radians([10.0, -6.79, 5.35])
    assert frames.rpy_frd_matrix(r) == pytest.approx(A.euler_to_dcm(np.zeros(3)) @ np.array(
        __import__("scipy.spatial.transform", fromlist=["Rotation"]).Rotation.from_euler(
            "ZYX", r[::-1]).as_matrix().T), abs=1e-12)
    with pytest.raises(ValueError, match="not a rotation"):
        frames.sensor_to_body(np.diag([1.0, 1.0, 2.0]))
    with pytest.raises(ValueError, match="reflection"):
        frames.sensor_to_body(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="unknown body frame"):
        frames.frame_matrix("xyz")


def test_rtklib_pos_small(tmp_path):
    head = "%  GPST  latitude(deg) longitude(deg) height(m) Q ns sdn sde sdu sdne sdeu sdun age ratio vn ve vu sdvn sdve sdvu sdvne sdveu sdvun\n"
    line = "2025/07/08 19:34:{s:06.3f} 40.0 -105.0 1600.0 1 20 0.01 0.02 0.03 0 0 0 0 0 1.0 2.0 0.5 0.1 0.2 0.3 0 0 0\n"
    p = _w(tmp_path, head + line.format(s=18.5) + line.format(s=18.75), "s.pos")
    fx = rtklib.read_rtklib_pos(p)
    assert fx.t[1] - fx.t[0] == pytest.approx(0.25)
    assert fx.vel[0] == pytest.approx([2.0, 1.0, 0.5])          # vn ve vu -> ENU
    assert fx.sigma[0] == pytest.approx([0.01, 0.02, 0.03]) and fx.sigma_vel[0] == pytest.approx([0.2, 0.1, 0.3])
    with pytest.raises(ValueError, match=r"s\.pos:3: duplicated"):
        rtklib.read_rtklib_pos(_w(tmp_path, head + line.format(s=18.5) + line.format(s=18.5), "s.pos"))
    with pytest.raises(ValueError, match="no solution epochs"):
        rtklib.read_rtklib_pos(_w(tmp_path, head, "e.pos"))
    with pytest.raises(ValueError, match=r"e\.pos:2: .* value columns"):
        rtklib.read_rtklib_pos(_w(tmp_path, head + "2025/07/08 19:34:18.5 40 -105 1600 1\n", "e.pos"))


# ------------------------------------------------------------------- MATLAB data -------
@needs_transfer
def test_psins_transfer_mat():
    p = DATA / "psins-transfer" / "transfer_align_fog_mems.mat"
    d = data.load_imu(p, var="mimu")
    assert d.imu.dt == pytest.approx(0.01) and len(d.imu) == 10001
    T = len(d.imu) * d.imu.dt
    f = np.linalg.norm(d.imu.dv.sum(0) / T)
    assert f == pytest.approx(9.8, rel=0.05)                    # rad, m/s increments: |f| ~ g
    s = matlab.read_mat_avp(p, "fogavp")
    assert math.degrees(s.lat[0]) == pytest.approx(34.43, abs=0.05)
    assert 10 < np.hypot(s.vel[:, 0], s.vel[:, 1]).mean() < 17
    with pytest.raises(ValueError, match="no numeric matrix 'nope'"):
        matlab.read_mat_imu(p, "nope")


# ------------------------------------------------------------------- rtklib-drive ------
@pytest.fixture(scope="module")
def drive():
    im = rtklib.read_rtklib_imu(DRIVE / "imu_1934.csv", mount=MOUNT, frame="frd")
    fx = rtklib.read_rtklib_pos(DRIVE / "gnss_1934_sf.pos")
    return im, fx


def _rest(im, fx):
    sp = np.hypot(fx.vel[:, 0], fx.vel[:, 1])
    k1 = int(np.searchsorted(im.imu.t, fx.t[np.argmax(sp > 0.05)]))
    return 0, k1


@needs_drive
def test_drive_tag_and_units(drive):
    im, fx = drive
    tg = rtklib.read_rtklib_tag(DRIVE / "imu_1934.csv.tag")
    assert tg["header"].startswith("TIMETAG RTKLIB")
    assert tg["end"] - tg["start"] == pytest.approx(548.731)
    assert len(im.imu) in (54859, 54860) and im.gaps.shape == (0, 2) and im.imu.dt == pytest.approx(0.01, rel=1e-3)
    assert im.jitter < 1e-3                                       # ms-quantised ticks
    # gravity: the accelerometer unit is g; |f| at rest is 1.4 % above local gravity (a z error
    # of ~0.14 m/s^2 the filter estimates as bias), not 0 % and not a factor 9.8
    k0, k1 = _rest(im, fx)
    T = (k1 - k0) * im.imu.dt
    f = im.imu.dv[k0:k1].sum(0) / T
    g = float(E.gravity(fx.lat[0], fx.h[0]))
    assert 1.005 < np.linalg.norm(f) / g < 1.02
    # mount: after it the car is level at rest (pitch, roll within 2 deg)
    assert abs(math.degrees(math.atan2(f[1], f[2]))) < 2 and abs(math.degrees(math.atan2(-f[0], f[2]))) < 2
    # Earth rate: |w| at rest is ~40x the Earth rate (MEMS bias): no gyrocompassing, heading
    # must come from the fixes
    w = im.imu.dtheta[k0:k1].sum(0) / T
    assert np.linalg.norm(w) / E.WIE > 20


@needs_drive
def test_drive_velocity_columns_and_lag(drive):
    _, fx = drive
    rm, rn = E.radii(fx.lat, fx.h)
    tm = 0.5 * (fx.t[1:] + fx.t[:-1])
    vn = np.diff(fx.lat) * rm[1:] / np.diff(fx.t)
    ve = np.diff(fx.lon) * rn[1:] * np.cos(fx.lat[1:]) / np.diff(fx.t)
    assert np.corrcoef(np.interp(tm, fx.t, fx.vel[:, 1]), vn)[0, 1] > 0.999     # vn is north
    assert np.corrcoef(np.interp(tm, fx.t, fx.vel[:, 0]), ve)[0, 1] > 0.999

    def rms(sh):
        return np.sqrt(np.mean((np.interp(tm + sh, fx.t, fx.vel[:, 1]) - vn) ** 2))
    shifts = np.arange(-0.2, 0.3, 0.025)
    best = shifts[np.argmin([rms(s) for s in shifts])]
    assert best == pytest.approx(0.125, abs=0.03)           # velocities describe t - 0.125 s
    assert rms(best) < 0.5 * rms(0.0)


@needs_drive
def test_drive_time_base_is_gpst_and_clock(drive):
    im, fx = drive
    fx = rtklib.read_rtklib_pos(DRIVE / "gnss_1934_sf.pos", velocity_lag=0.125)
    est = recorded.estimate_time_offset(im.imu, fx)
    assert all(c > 0.97 for _, _, c in est["windows"])
    assert abs(est["offset"]) < 0.3                         # tag read as GPST: within 0.3 s
    assert 100 < est["ppm"] < 250                           # the IMU ms clock runs fast
    # as UTC the IMU would be 18 s off: no correlation at all there
    sp = np.hypot(fx.vel[:, 0], fx.vel[:, 1])
    cr = -np.gradient(np.unwrap(np.arctan2(fx.vel[:, 0], fx.vel[:, 1])), fx.t)
    cr[sp < 2] = 0
    grid = np.arange(fx.t[0] + 60, fx.t[-1] - 60, 0.02)
    wz = im.imu.dtheta[:, 2] / im.imu.dt
    c0 = np.corrcoef(np.interp(grid + est["offset"], im.imu.t, wz), np.interp(grid, fx.t, cr))[0, 1]
    c18 = np.corrcoef(np.interp(grid + 18.0, im.imu.t, wz), np.interp(grid, fx.t, cr))[0, 1]
    assert c0 > 0.95 and abs(c18) < 0.3
    # deg/s unit and axis sign of the vertical gyro: slope 1 against the course rate
    sl = np.polyfit(np.interp(grid, fx.t, cr), np.interp(grid + est["offset"], im.imu.t, wz), 1)[0]
    assert sl == pytest.approx(1.0, abs=0.03)
    # the source project's tick stretch goes the wrong way: the drift doubles
    st = rtklib.read_rtklib_imu(DRIVE / "imu_1934.csv", mount=MOUNT, frame="frd", stretch=True)
    assert recorded.estimate_time_offset(st.imu, fx)["ppm"] > est["ppm"] + 150


@needs_drive
def test_drive_bad_inputs(tmp_path):
    lines = (DRIVE / "imu_1934.csv").read_text().splitlines()[:200]
    bad = list(lines)
    bad[50] = bad[49]                                       # duplicated tick
    p = _w(tmp_path, "\n".join(bad) + "\n", "imu.csv")
    (tmp_path / "imu.csv.tag").write_bytes((DRIVE / "imu_1934.csv.tag").read_bytes())
    with pytest.raises(ValueError, match=r"imu\.csv:51: duplicated"):
        rtklib.read_rtklib_imu(p)
    gap = lines[:100] + lines[150:]
    p = _w(tmp_path, "\n".join(gap) + "\n", "imu.csv")
    with pytest.raises(ValueError, match=r"imu\.csv:101: gap of 0\.\d+ s"):
        rtklib.read_rtklib_imu(p, max_gap=0.2)
    assert rtklib.read_rtklib_imu(p).gaps.shape == (1, 2)
    with pytest.raises(ValueError, match="no time-tag file"):
        rtklib.read_rtklib_imu(_w(tmp_path, "\n".join(lines) + "\n", "other.csv"))
    with pytest.raises(ValueError, match="not a rotation"):
        rtklib.read_rtklib_imu(p, mount=np.ones((3, 3)))


@pytest.mark.parametrize("reader", ["load_imu", "read_fixes"])
def test_a_directory_is_refused_with_one_clear_error(tmp_path, reader):
    import sinslab.data as D
    with pytest.raises(ValueError, match="is a directory, not a file"):
        getattr(D, reader)(tmp_path)


def test_velocity_lag_applies_to_every_fix_format(tmp_path):
    """A velocity lag re-times CSV fix velocities exactly as it does RTKLIB ones:
    vel(t) = recorded vel(t + lag) by linear interpolation; invalid lags are refused."""
    t = np.arange(0.0, 10.0, 1.0)
    vel = np.column_stack([t ** 2, -t, 0.5 * t])
    fx = Fixes(t, np.full(t.size, 0.5), np.full(t.size, 2.0), np.zeros(t.size), np.ones((t.size, 3)),
               vel, np.full((t.size, 3), 0.1))
    p = data.write_fixes(tmp_path / "f.csv", fx)
    got = data.read_fixes(p, velocity_lag=0.25)
    want = np.column_stack([np.interp(t + 0.25, t, vel[:, i]) for i in range(3)])
    np.testing.assert_allclose(got.vel, want, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(data.read_fixes(p).vel, data.read_fixes(p, velocity_lag=0).vel)
    with pytest.raises(ValueError, match=">= 0"):
        data.read_fixes(p, velocity_lag=-5)
    no_vel = data.write_fixes(tmp_path / "g.csv", Fixes(t, fx.lat, fx.lon, fx.h, fx.sigma))
    with pytest.raises(ValueError, match="no velocities"):
        data.read_fixes(no_vel, velocity_lag=0.1)
