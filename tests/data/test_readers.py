"""IMU tables as real logs come: extra columns of any kind, indexed names, column maps
with units, headerless text with positional maps, quaternion/matrix mounts, and one clear
line for every malformed table. Oracles: a record written in sensor axes through a known
rotation and read back equals the original (round trip through mount and map); the
same samples read from CSV, Parquet and a vendor log agree."""
import numpy as np
import pytest

import foreign_unit as fu
from sinslab import data
from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.core.records import ImuRecord
from sinslab.data import columns, frames


def _imu(n=200, dt=0.01):
    rng = np.random.default_rng(3)
    return ImuRecord(100.0 + dt * np.arange(1, n + 1), rng.normal(0, 1e-3, (n, 3)),
                     rng.normal(0, 1e-2, (n, 3)) + [0, 0, 0.098], dt)


def _rates_csv(tmp_path, extra_head="", extra_val="", name="r.csv", n=20, sep=","):
    head = sep.join(["t[s]", "gx[deg/s]", "gy[deg/s]", "gz[deg/s]", "ax[g]", "ay[g]", "az[g]"])
    rows = "".join(sep.join(f"{v:g}" for v in (0.01 * k, 1, 0, -2, 0, 0.5, 1)) + extra_val + "\n"
                   for k in range(1, n + 1))
    p = tmp_path / name
    p.write_text(head + extra_head + "\n" + rows)
    return p


def test_extra_columns_of_any_kind_are_ignored(tmp_path):
    ref = data.load_imu(_rates_csv(tmp_path))
    p = _rates_csv(tmp_path, ",status,Temperature (degC),note", ",OK,21.5,", name="x.csv")
    d = data.load_imu(p)
    np.testing.assert_array_equal(d.imu.dtheta, ref.imu.dtheta)
    np.testing.assert_array_equal(d.imu.dv, ref.imu.dv)
    # semicolon- and tab-delimited text too
    for sep, nm in ((";", "s.csv"), ("\t", "t.tsv")):
        d = data.load_imu(_rates_csv(tmp_path, f"{sep}status", f"{sep}OK", name=nm, sep=sep), "csv")
        np.testing.assert_array_equal(d.imu.dtheta, ref.imu.dtheta)


def test_whitespace_text_read_in_c_equals_the_line_reader(tmp_path):
    """Whitespace-delimited text (KF-GINS and PSINS style: runs of spaces, comment
    and blank lines between samples) goes through numpy's C parser; the samples equal
    those of the line-by-line reader, and a malformed line still gets its line number."""
    from sinslab.data.tables import _TextSource

    imu = _imu()
    body = ["  " + "   ".join(f"{v:.17g}" for v in (imu.t[k], *imu.dtheta[k], *imu.dv[k])) for k in range(len(imu))]
    body[5:5] = ["# a comment", "", "% another"]
    p = tmp_path / "w.txt"
    p.write_text("\n".join(body) + "\n")
    cmap = "t=1[s],dtheta_x=2[rad],dtheta_y=3[rad],dtheta_z=4[rad],dv_x=5[m/s],dv_y=6[m/s],dv_z=7[m/s]"
    d = data.load_imu(p, "csv", columns=cmap)
    np.testing.assert_array_equal(d.imu.dtheta, imu.dtheta)
    np.testing.assert_array_equal(d.imu.dv, imu.dv)
    src = _TextSource(p, headerless=True)
    np.testing.assert_array_equal(src.fetch([0, 3, 6]), src._slow([0, 3, 6]))
    for bad, what in (("1e9 1 2 3 4 5", "6 columns"), ("1e9 1 2 x 4 5 6", "not a number: 'x'"),
                      ("1e9 1 2 3 4 5 6 7", "8 columns")):
        q = tmp_path / "bad.txt"
        q.write_text("\n".join(body) + "\n" + bad + "\n")
        with pytest.raises(ValueError, match=f"bad.txt:{len(body) + 1}: {what}"):
            data.load_imu(q, "csv", columns=cmap)


def test_indexed_names_are_names_not_units():
    assert columns.parse_header_cell("DeltaTheta[0]") == ("deltatheta[0]", None, True)
    assert columns.parse_header_cell("DeltaTheta[2][rad]") == ("deltatheta[2]", "rad", True)
    assert columns.parse_header_cell("gx [deg/s]") == ("gx", "deg/s", True)
    assert columns.parse_header_cell("Gyro X (deg/s)")[2] is False        # kept as a raw name


def test_column_map_string_toml_and_positions(tmp_path):
    imu = _imu()
    body = "".join(",".join(f"{v:.17g}" for v in (imu.t[k], *imu.dtheta[k], *imu.dv[k], k % 3)) + "\n"
                   for k in range(len(imu)))
    p = tmp_path / "v.csv"
    p.write_text("Time,DeltaTheta[0],DeltaTheta[1],DeltaTheta[2],DeltaVel[0],DeltaVel[1],DeltaVel[2],mode\n"
                 + body.replace(",", ",", 1))
    # without a map: the indexed names are not mistaken for units, the error says what to do
    with pytest.raises(ValueError, match="wrong columns.*column map"):
        data.load_imu(p)
    m = ("t=Time[s],dtheta_x=DeltaTheta[0][rad],dtheta_y=DeltaTheta[1][rad],dtheta_z=DeltaTheta[2][rad],"
         "dv_x=DeltaVel[0][m/s],dv_y=DeltaVel[1][m/s],dv_z=DeltaVel[2][m/s]")
    d = data.load_imu(p, columns=m)
    np.testing.assert_allclose(d.imu.dtheta, imu.dtheta, rtol=1e-15)
    np.testing.assert_allclose(d.imu.dv, imu.dv, rtol=1e-15)
    # units in the map rescale: the same columns declared in mrad, mm/s
    m2 = m.replace("[rad]", "[mrad]").replace("[m/s]", "[mm/s]")
    d2 = data.load_imu(p, columns=m2)
    np.testing.assert_allclose(d2.imu.dtheta, imu.dtheta * 1e-3, rtol=1e-14)
    # the same map as a TOML table (strings and inline tables)
    tm = tmp_path / "cols.toml"
    tm.write_text("[columns]\nt = \"Time [s]\"\n" + "".join(
        f"dtheta_{a} = {{name = \"DeltaTheta[{i}]\", unit = \"rad\"}}\n"
        f"dv_{a} = \"DeltaVel[{i}] [m/s]\"\n" for i, a in enumerate("xyz")))
    d3 = data.load_imu(p, columns=tm)
    np.testing.assert_array_equal(d3.imu.dtheta, d.imu.dtheta)
    # a file without a header, read by 1-based positions
    q = tmp_path / "nohead.txt"
    q.write_text(body.replace(",", " "))
    pos = "t=1[s],dtheta_x=2[rad],dtheta_y=3[rad],dtheta_z=4[rad],dv_x=5[m/s],dv_y=6[m/s],dv_z=7[m/s]"
    d4 = data.load_imu(q, "csv", columns=pos)
    np.testing.assert_allclose(d4.imu.dtheta, imu.dtheta, rtol=1e-15)
    with pytest.raises(ValueError, match="no header line"):
        data.load_imu(q, "csv")


@pytest.mark.parametrize("bad, msg", [
    ("dtheta_x=DeltaTheta[0][rad]", "lacks t"),
    ("t=Time,gx=a[deg/s],gy=b[deg/s],gz=c[deg/s],ax=d[g],ay=e[g],az=f[g],dv_x=x[m/s]", "mixes"),
    ("t=Time,speed=v", "unknown column key 'speed'"),
    ("t=Time,t=Time2", "given twice"),
    ("t", "use key=COLUMN"),
])
def test_column_map_errors(bad, msg):
    with pytest.raises(ValueError, match=msg):
        columns.parse_column_map(bad)


def test_foreign_unit_log_round_trip(tmp_path):
    """The vendor log (sensor axes, FRD vehicle frame, quaternion mount, seconds of week,
    text status column, flag column) read back through the map equals the record written."""
    imu = _imu()
    flags = (np.arange(len(imu)) // 50) % 2 == 0
    p = fu.write_foreign_log(tmp_path / "acme.csv", imu, flags)
    d = data.load_imu(p, columns=fu.COLUMNS, mount=fu.MOUNT, frame=fu.FRAME)
    np.testing.assert_allclose(d.imu.t, imu.t + 345600.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(d.imu.dtheta, imu.dtheta, rtol=0, atol=1e-15)
    np.testing.assert_allclose(d.imu.dv, imu.dv, rtol=0, atol=1e-15)
    ts, fl = d.meta["stationary"]
    np.testing.assert_array_equal(fl, flags)
    assert d.meta["columns"]["dtheta_x"] == "deltatheta[0][rad]"


def test_mount_quaternion_matrix_and_angles_agree():
    C = A.euler_to_dcm(np.radians([3.0, -20.0, 75.0]))
    q = A.dcm_to_quat(C)
    M_e = frames.sensor_to_body("euler:3,-20,75")
    M_q = frames.sensor_to_body("quat:" + ",".join(map(repr, q.tolist())))
    M_m = frames.sensor_to_body("matrix:" + str(C.tolist()))
    M_a = frames.sensor_to_body(q)
    for M in (M_q, M_m, M_a):
        np.testing.assert_allclose(M, M_e, atol=1e-12)
    with pytest.raises(ValueError, match="norm"):
        frames.sensor_to_body("quat:1,0.1,0,0")
    with pytest.raises(ValueError, match="9 numbers"):
        frames.sensor_to_body("matrix:1,0,0,0,1,0")
    with pytest.raises(ValueError, match="reflection"):
        frames.sensor_to_body("matrix:[[1,0,0],[0,1,0],[0,0,-1]]")
    with pytest.raises(ValueError, match="quat:W,X,Y,Z"):
        frames.sensor_to_body("1,2,3")


@pytest.mark.parametrize("content, msg", [
    (bytes(np.random.default_rng(7).integers(0, 256, 3000, dtype=np.uint8)), "not a text table"),
    (b"t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,0,0,0,0,1\n0.02,1,0\n",
     r"x.csv:3: 3 columns, the header has 7"),
    (b"t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,0,0,0,0,1\n0.02,1,0,zz,0,0,1\n",
     r"x.csv:3: not a number: 'zz' in column 'gz\[deg/s\]'"),
    (b"t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,0,0,0,0,1\n0.02,1,0,,0,0,1\n",
     r"x.csv:3: empty value in column"),
    (b"t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n", "header only"),
    (b"t[s],gx[deg/s],gx[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,0,0,0,0,1\n", "wrong columns"),
    (b"t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g],gx\n0.01,1,0,0,0,0,1,2\n", "2 columns are named 'gx'"),
    (b"t[fortnight],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,0,0,0,0,1\n", "not a time unit"),
    (b"t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,0,0,0,0,1\n0.01,1,0,0,0,0,1\n",
     "x.csv:3: duplicated time stamp"),
])
def test_malformed_tables_are_one_clear_line(tmp_path, content, msg):
    p = tmp_path / "x.csv"
    p.write_bytes(content)
    with pytest.raises(ValueError, match=msg) as e:
        data.load_imu(p)
    assert "\n" not in str(e.value)


def test_comment_lines_between_samples_keep_line_numbers(tmp_path):
    p = tmp_path / "c.csv"
    p.write_text("# unit ACME\nt[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n0.01,1,0,0,0,0,1\n"
                 "# resync\n0.02,1,0,0,0,0,1\n0.02,1,0,0,0,0,1\n")
    with pytest.raises(ValueError, match="c.csv:6: duplicated"):
        data.load_imu(p)


def test_parquet_with_map_and_extra_columns(tmp_path):
    import pandas as pd
    imu = _imu()
    df = pd.DataFrame({"Time": imu.t, **{f"DeltaTheta[{i}]": imu.dtheta[:, i] for i in range(3)},
                       **{f"DeltaVel[{i}]": imu.dv[:, i] for i in range(3)}, "status": ["OK"] * len(imu)})
    p = tmp_path / "v.parquet"
    df.to_parquet(p)
    d = data.load_imu(p, columns={"t": "Time[s]", **{f"dtheta_{a}": f"DeltaTheta[{i}][rad]" for i, a in enumerate("xyz")},
                                  **{f"dv_{a}": f"DeltaVel[{i}][m/s]" for i, a in enumerate("xyz")}})
    np.testing.assert_array_equal(d.imu.dv, imu.dv)
    assert u.unit_scale("mrad", "angle") == pytest.approx(1e-3)
