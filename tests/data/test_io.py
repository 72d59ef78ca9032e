"""Readers/writers of recorded data (sinslab.data.io) and checks of the rtklib-drive facts."""
import math
from pathlib import Path

import numpy as np
import pytest

from sinslab.core import attitude as A
from sinslab.core import earth as E
from sinslab.data import io
from sinslab.core import units as u
from sinslab.core.records import ImuRecord

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
DRIVE = DATA / "rtklib-drive"
needs_drive = pytest.mark.skipif(not (DRIVE / "imu_1934.csv").exists(), reason="rtklib-drive not available")
needs_transfer = pytest.mark.skipif(not (DATA / "psins-transfer").exists(), reason="psins-transfer not available")
MOUNT = "rpy:%g,%g,%g" % io.RTKLIB_DRIVE["mount_rpy_frd_deg"]


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
    d = io.load_imu(p)
    assert d.imu.dt == pytest.approx(0.01) and len(d.imu) == 10 and d.gaps.shape == (0, 2)
    assert d.imu.dtheta[0] == pytest.approx(np.radians([1, 0, -2]) * 0.01)
    assert d.imu.dv[0] == pytest.approx(np.array([0, 0.5, 1]) * u.g0 * 0.01)
    # units by option, increments, FRD source frame
    p2 = _w(tmp_path, "t,dax,day,daz,dvx,dvy,dvz\n0.1,1e-3,0,0,0,0,-0.98\n0.2,1e-3,0,0,0,0,-0.98\n", "b.csv")
    d2 = io.read_table_imu(p2, gyro_unit="rad", accel_unit="m/s", frame="frd")
    assert d2.imu.dtheta[0] == pytest.approx([0, 1e-3, 0]) and d2.imu.dv[0] == pytest.approx([0, 0, 0.98])
    # the minimal SI CSV of the alignment reader keeps working
    p3 = _w(tmp_path, "t,dtheta_x,dtheta_y,dtheta_z,dv_x,dv_y,dv_z\n0.1,0,0,1e-6,0,0,0.98\n0.2,0,0,1e-6,0,0,0.98\n", "c.csv")
    assert io.load_imu(p3).imu.dv[1, 2] == pytest.approx(0.98)


@pytest.mark.parametrize("fmt", ["csv", "parquet", "mat"])
def test_write_read_round_trip(tmp_path, fmt):
    imu = _imu()
    p = io.write_imu(tmp_path / f"r.{fmt}", imu)
    d = io.load_imu(p)
    assert np.allclose(d.imu.t, imu.t) and np.allclose(d.imu.dtheta, imu.dtheta, rtol=1e-12, atol=0)
    assert np.allclose(d.imu.dv, imu.dv, rtol=1e-12, atol=0)


def test_fix_csv_round_trip(tmp_path):
    J = 5
    fx = io.Fixes(np.arange(J, dtype=float), np.radians(np.full(J, 40.0)), np.radians(np.full(J, -105.0)),
                  np.full(J, 1600.0), np.full((J, 3), 0.02), np.ones((J, 3)), np.full((J, 3), 0.05),
                  np.zeros(J, int))
    g = io.read_fixes(io.write_fixes(tmp_path / "f.csv", fx))
    assert np.allclose(g.lat, fx.lat) and np.allclose(g.vel, fx.vel) and np.allclose(g.sigma, 0.02)


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
        io.load_imu(_w(tmp_path, text))


def test_gaps_and_jitter(tmp_path):
    t = 0.01 * np.arange(1, 301)
    t = np.delete(t, np.arange(100, 120))                   # 0.2 s gap
    rows = "".join(f"{x:.4f},0,0,10,0,0,1\n" for x in t)
    p = _w(tmp_path, "t,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n" + rows)
    d = io.load_imu(p)
    assert d.gaps.shape == (1, 2) and d.gaps[0, 1] == pytest.approx(0.21)
    assert d.imu.dt == pytest.approx(0.01) and len(d.imu) == 300
    # bridged at the mean rate: the integrated angle is exact
    assert d.imu.dtheta[:, 2].sum() == pytest.approx(math.radians(10) * 3.0, rel=1e-9)
    with pytest.raises(ValueError, match=r"x\.csv:\d+: gap of 0\.210 s"):
        io.load_imu(p, max_gap=0.1)
    assert io.load_imu(p, max_gap=0.1, allow_gaps=True).gaps.shape == (1, 2)
    # jittery stamps (ms quantisation) -> uniform grid, cumulative angle preserved
    rng = np.random.default_rng(3)
    tj = 0.01 * np.arange(1, 501) + rng.integers(-1, 2, 500) * 1e-3
    pj = _w(tmp_path, "t,gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n"
            + "".join(f"{x:.4f},0,0,10,0,0,1\n" for x in tj), "j.csv")
    dj = io.load_imu(pj)
    assert dj.jitter > 0 and np.ptp(np.diff(dj.imu.t)) < 1e-9
    assert dj.imu.dtheta[:, 2].sum() == pytest.approx(math.radians(10) * len(dj.imu) * dj.imu.dt, rel=1e-9)


def test_frames_and_mounts():
    assert io.frame_matrix("frd") @ [1, 0, 0] == pytest.approx([0, 1, 0])      # forward
    assert io.frame_matrix("frd") @ [0, 0, 1] == pytest.approx([0, 0, -1])     # down
    assert io.frame_matrix("flu") @ [0, 1, 0] == pytest.approx([-1, 0, 0])     # left
    # roll 180 + yaw 180 (Groves, FRD): sensor x back, y right, z up
    M = io.rpy_frd_matrix(np.radians([180, 0, 180]))
    assert M == pytest.approx(np.diag([-1.0, 1.0, -1.0]), abs=1e-12)
    R = io.mount_matrix("rpy:180,0,180", "frd")
    assert R @ [0, 0, 1] == pytest.approx([0, 0, 1], abs=1e-12)                # sensor up -> up
    assert R @ [-1, 0, 0] == pytest.approx([0, 1, 0], abs=1e-12)               # sensor -x -> forward
    # Groves' formula is the passive R1 R2 R3 product
    r = np.radians([10.0, -6.79, 5.35])
    assert io.rpy_frd_matrix(r) == pytest.approx(A.euler_to_dcm(np.zeros(3)) @ np.array(
        __import__("scipy.spatial.transform", fromlist=["Rotation"]).Rotation.from_euler(
            "ZYX", r[::-1]).as_matrix().T), abs=1e-12)
    with pytest.raises(ValueError, match="not a rotation"):
        io.mount_matrix(np.diag([1.0, 1.0, 2.0]))
    with pytest.raises(ValueError, match="reflection"):
        io.mount_matrix(np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="unknown body frame"):
        io.frame_matrix("xyz")


def test_rtklib_pos_small(tmp_path):
    head = "%  GPST  latitude(deg) longitude(deg) height(m) Q ns sdn sde sdu sdne sdeu sdun age ratio vn ve vu sdvn sdve sdvu sdvne sdveu sdvun\n"
    line = "2025/07/08 19:34:{s:06.3f} 40.0 -105.0 1600.0 1 20 0.01 0.02 0.03 0 0 0 0 0 1.0 2.0 0.5 0.1 0.2 0.3 0 0 0\n"
    p = _w(tmp_path, head + line.format(s=18.5) + line.format(s=18.75), "s.pos")
    fx = io.read_rtklib_pos(p)
    assert fx.t[1] - fx.t[0] == pytest.approx(0.25)
    assert fx.vel[0] == pytest.approx([2.0, 1.0, 0.5])          # vn ve vu -> ENU
    assert fx.sigma[0] == pytest.approx([0.01, 0.02, 0.03]) and fx.sigma_vel[0] == pytest.approx([0.2, 0.1, 0.3])
    with pytest.raises(ValueError, match=r"s\.pos:3: duplicated"):
        io.read_rtklib_pos(_w(tmp_path, head + line.format(s=18.5) + line.format(s=18.5), "s.pos"))
    with pytest.raises(ValueError, match="no solution epochs"):
        io.read_rtklib_pos(_w(tmp_path, head, "e.pos"))
    with pytest.raises(ValueError, match=r"e\.pos:2: .* value columns"):
        io.read_rtklib_pos(_w(tmp_path, head + "2025/07/08 19:34:18.5 40 -105 1600 1\n", "e.pos"))


# ------------------------------------------------------------------- MATLAB data -------
@needs_transfer
def test_psins_transfer_mat():
    p = DATA / "psins-transfer" / "transfer_align_fog_mems.mat"
    d = io.load_imu(p, var="mimu")
    assert d.imu.dt == pytest.approx(0.01) and len(d.imu) == 10001
    T = len(d.imu) * d.imu.dt
    f = np.linalg.norm(d.imu.dv.sum(0) / T)
    assert f == pytest.approx(9.8, rel=0.05)                    # rad, m/s increments: |f| ~ g
    s = io.read_mat_avp(p, "fogavp")
    assert math.degrees(s.lat[0]) == pytest.approx(34.43, abs=0.05)
    assert 10 < np.hypot(s.vel[:, 0], s.vel[:, 1]).mean() < 17
    with pytest.raises(ValueError, match="no numeric matrix 'nope'"):
        io.read_mat_imu(p, "nope")


# ------------------------------------------------------------------- rtklib-drive ------
@pytest.fixture(scope="module")
def drive():
    im = io.read_rtklib_imu(DRIVE / "imu_1934.csv", mount=MOUNT, frame="frd")
    fx = io.read_rtklib_pos(DRIVE / "gnss_1934_sf.pos")
    return im, fx


def _rest(im, fx):
    sp = np.hypot(fx.vel[:, 0], fx.vel[:, 1])
    k1 = int(np.searchsorted(im.imu.t, fx.t[np.argmax(sp > 0.05)]))
    return 0, k1


@needs_drive
def test_drive_tag_and_units(drive):
    im, fx = drive
    tg = io.read_rtklib_tag(DRIVE / "imu_1934.csv.tag")
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
    fx = io.read_rtklib_pos(DRIVE / "gnss_1934_sf.pos", velocity_lag=0.125)
    est = io.estimate_time_offset(im.imu, fx)
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
    st = io.read_rtklib_imu(DRIVE / "imu_1934.csv", mount=MOUNT, frame="frd", stretch=True)
    assert io.estimate_time_offset(st.imu, fx)["ppm"] > est["ppm"] + 150


@needs_drive
def test_drive_bad_inputs(tmp_path):
    lines = (DRIVE / "imu_1934.csv").read_text().splitlines()[:200]
    bad = list(lines)
    bad[50] = bad[49]                                       # duplicated tick
    p = _w(tmp_path, "\n".join(bad) + "\n", "imu.csv")
    (tmp_path / "imu.csv.tag").write_bytes((DRIVE / "imu_1934.csv.tag").read_bytes())
    with pytest.raises(ValueError, match=r"imu\.csv:51: duplicated"):
        io.read_rtklib_imu(p)
    gap = lines[:100] + lines[150:]
    p = _w(tmp_path, "\n".join(gap) + "\n", "imu.csv")
    with pytest.raises(ValueError, match=r"imu\.csv:101: gap of 0\.\d+ s"):
        io.read_rtklib_imu(p, max_gap=0.2)
    assert io.read_rtklib_imu(p).gaps.shape == (1, 2)
    with pytest.raises(ValueError, match="no time-tag file"):
        io.read_rtklib_imu(_w(tmp_path, "\n".join(lines) + "\n", "other.csv"))
    with pytest.raises(ValueError, match="not a rotation"):
        io.read_rtklib_imu(p, mount=np.ones((3, 3)))
