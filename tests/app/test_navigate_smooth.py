"""`sinslab navigate --smooth --odometer` on a simulated car drive written to files.

Oracles: the truth of the simulation (held-out fixes inside the outages are truth plus
1 cm noise): the smoothed solution is several times closer to them than the forward
filter; a wheel odometer (2 % scale error, noise, 2 cm/s quantisation) shrinks the
outage-end error; an odometer given as a column of the IMU table and as a separate file
with the same samples reads the same series. Bad input: one line, exit 2, nothing written.
"""
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from sinslab.core import attitude as A
from sinslab.core import units as u
from sinslab.data import write_fixes
from sinslab.sim import trajectory as tr
from support import simulated_car_drive


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("drive")
    segs = [tr.Static(duration=30.0), tr.Accelerate(duration=5.0, accel=2.0), tr.Level(duration=20.0),
            tr.Turn(duration=10.0, rate=9 * u.deg, coordinated=False), tr.Level(duration=20.0),
            tr.Turn(duration=20.0, rate=-9 * u.deg, coordinated=False), tr.Level(duration=30.0),
            tr.Turn(duration=10.0, rate=9 * u.deg, coordinated=False), tr.Level(duration=40.0)]
    imu, fx, tru, _, rng = simulated_car_drive(segs)
    write_fixes(d / "fixes.csv", fx)
    # wheel speed of the IMU point at the IMU samples: +2 %, noise, 2 cm/s steps
    C = A.euler_to_dcm(tru.att[1:])
    vf = np.einsum("kji,kj->ki", C, tru.vel[1:])[:, 1]
    spd = np.round(np.maximum(0.0, 1.02 * vf + 0.03 * rng.standard_normal(vf.size)) / 0.02) * 0.02
    a = np.column_stack([imu.t, imu.dtheta, imu.dv, spd])
    np.savetxt(d / "imu.csv", a, delimiter=",", comments="", fmt="%.17g",
               header="t[s],dtheta_x[rad],dtheta_y[rad],dtheta_z[rad],dv_x[m/s],dv_y[m/s],dv_z[m/s],odo[m/s]")
    np.savetxt(d / "odo.csv", np.column_stack([imu.t, spd * 3.6]), delimiter=",", comments="",
               fmt="%.17g", header="t[s],speed[km/h]")
    return d


def _nav(d, out, *extra):
    from sinslab.cli import app
    return CliRunner().invoke(app, ["-q", "navigate", "--imu", str(d / "imu.csv"), "--fixes",
                                    str(d / "fixes.csv"), "--outages", "60:25,120:25",
                                    "--out", str(out), *extra])


def test_smooth_and_odometer_cli(files, tmp_path):
    runs = {}
    for name, extra in (("plain", ["--smooth"]), ("file", ["--smooth", "--odometer", str(files / "odo.csv")])):
        res = _nav(files, tmp_path / name, *extra)
        assert res.exit_code == 0, res.output
        summary = json.loads((tmp_path / name / "summary.json").read_text())
        runs[name] = summary["metrics"]
        # the report describes every metric the run wrote, smoothing and odometer ones too
        info = summary["metric_info"]
        assert [m for m in runs[name] if not (info.get(m) or {}).get("description")] == []
    p = runs["plain"]
    assert p["n_outages"] == 2 and len(p["outage_mid_hz_err_smoothed_m"]) == 2
    assert p["smoothed_hz_err_rms_m"] < 0.25 * p["forward_hz_err_rms_m"], p
    assert max(p["outage_mid_hz_err_smoothed_m"]) < 0.25 * max(p["outage_end_hz_err_m"])
    for f in ("smoothed.csv", "smoothed.png", "solution.csv"):
        assert (tmp_path / "plain" / f).is_file()
    hdr = (tmp_path / "plain" / "smoothed.csv").read_text().splitlines()[0].split(",")
    assert "fwd_lat_deg" in hdr and "smo_lat_deg" in hdr and "smo_sigma_dL_arcsec" in hdr
    f = runs["file"]
    # wheel speed alone bounds the along-track error only (the lateral drift from heading
    # and tilt errors needs the non-holonomic constraint): a clear but not a large gain
    assert f["outage_end_hz_err_median_m"] < 0.7 * p["outage_end_hz_err_median_m"], (f, p)
    assert f["odometer_scale_final_ppm"] == pytest.approx(0.02 / 1.02 * 1e6, abs=4 * f["odometer_scale_sigma_ppm"])


def test_odometer_column_and_file_read_the_same(files):
    """The same samples as a column of the IMU table (m/s) and as a file (km/h)."""
    from sinslab.data.odometer import read_odometer
    col = read_odometer("odo", files / "imu.csv")
    fil = read_odometer(files / "odo.csv")
    assert np.array_equal(col.t, fil.t) and np.allclose(col.speed, fil.speed, rtol=1e-15, atol=1e-12)
    assert read_odometer("ODO", files / "imu.csv").source.endswith(":ODO")
    mph = read_odometer(files / "odo.csv", speed_unit="m/s")          # the option overrides the header
    assert np.allclose(mph.speed, fil.speed * 3.6)


@pytest.mark.parametrize("case, args, text", [
    ("late", "shift", "do not overlap"),
    ("neg", "neg", "negative wheel speed"),
    ("nan", "nan", "non-finite"),
    ("units", ["--odometer-units", "furlong/h"], "furlong"),
    ("angle", ["--odometer-units", "deg/s"], "not a velocity unit"),
    ("lever", ["--odometer-lever", "[0, 1, 0] m"], "the odometer aid is not enabled: add --aid odometer"),
    ("column", ["--odometer", "wheel"], "no column 'wheel'"),
])
def test_odometer_bad_input(files, tmp_path, case, args, text):
    from sinslab.cli import app
    odo = np.loadtxt(files / "odo.csv", delimiter=",", skiprows=1)
    if isinstance(args, str):
        if args == "shift":
            odo[:, 0] += 1e5
        elif args == "neg":
            odo[500, 1] = -1.0
        else:
            odo[500, 1] = np.nan
        p = tmp_path / "odo.csv"
        np.savetxt(p, odo, delimiter=",", comments="", fmt="%.17g", header="t[s],speed[km/h]")
        args = ["--odometer", str(p)]
    elif args[0] != "--odometer" and case != "lever":
        args = ["--odometer", str(files / "odo.csv"), *args]
    out = tmp_path / "run"
    res = CliRunner().invoke(app, ["navigate", "--imu", str(files / "imu.csv"), "--fixes",
                                   str(files / "fixes.csv"), "--smooth", "--out", str(out), *args])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    err = [ln for ln in lines if "error" in ln]
    assert len(err) == 1 and text in err[0], res.output
    assert not out.exists()


def test_spilled_smoother_record_gives_the_same_files(files, tmp_path, monkeypatch):
    """With the smoother's record on disk (any size spills when the threshold is 0) the
    solution and smoothed tables are the same bytes, and the scratch folder is gone."""
    from sinslab.app.commands import navigate as nav

    assert _nav(files, tmp_path / "mem", "--smooth").exit_code == 0
    spilled = []
    orig = nav._spill_smoother

    def spy(opt, imu, fx):
        orig(opt, imu, fx)
        spilled.append(opt.smooth_spill)

    monkeypatch.setattr(nav, "SMOOTH_SPILL_ABOVE", 0)
    monkeypatch.setattr(nav, "_spill_smoother", spy)
    res = _nav(files, tmp_path / "disk", "--smooth")
    assert res.exit_code == 0, res.output
    assert spilled and spilled[0] is not None and str(tmp_path) in spilled[0]
    for f in ("solution.csv", "smoothed.csv", "fix_errors.csv"):
        assert (tmp_path / "mem" / f).read_bytes() == (tmp_path / "disk" / f).read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["disk", "mem"]      # no scratch left
