"""Bad recorded-unit options of ``sinslab navigate`` are one line and exit status 2,
before anything is computed or written."""
import numpy as np
import pytest
from typer.testing import CliRunner

from sinslab.cli import app


@pytest.fixture
def files(tmp_path):
    imu = tmp_path / "imu.csv"
    imu.write_text("t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g],flag\n"
                   + "".join(f"{0.01 * k:.2f},0,0,0,0,0,1,1\n" for k in range(1, 301)))
    fx = tmp_path / "fx.csv"
    fx.write_text("t[s],lat[deg],lon[deg],h[m]\n" + "".join(f"{k}.0,30,110,10\n" for k in range(1, 3)))
    return imu, fx, tmp_path


@pytest.mark.parametrize("args, msg", [
    (["--aid", "zupt,odo"], "unknown odo"),
    (["--csv-rate", "0"], "--csv-rate"),
    (["--aid", "zupt", "--rest", "flags"], "no rest-flag column"),
    (["--aid", "zupt", "--rest", "sometimes"], "--rest 'sometimes': choose one of either, auto, flags"),
    (["--imu-errors", "platinum"], "neither a file nor a grade"),
    (["--columns", "t=time[s],speed=v"], "unknown column key 'speed'"),
    (["--mount", "quat:1,1,0,0"], "norm"),
])
def test_bad_options(files, args, msg):
    imu, fx, tmp = files
    out = tmp / "run"
    res = CliRunner().invoke(app, ["navigate", "--imu", str(imu), "--fixes", str(fx), "--out", str(out), *args])
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert any("sinslab: error:" in ln and msg in ln for ln in lines), res.output
    assert not (out / "summary.json").exists()


def test_options_are_short_forms_of_the_configuration_parsed_once():
    """The CLI edge: the options become keys of one configuration, unit strings parsed to
    SI once (lever arm, --init), --aid resolved to the registered aids (an alias sets its
    aid's key), the files made absolute; a bad one refused there, before any file is read."""
    import math
    from pathlib import Path

    from sinslab.app.commands.navigate import navigate_config
    from sinslab.app.commands.navigate_config import aids_of
    from sinslab.app.errors import UserError

    c = navigate_config(imu=[Path("imu.csv")], fixes=[Path("fix.pos")], lever_arm="[10, -20, 30] cm",
                        aid="zaru, NHC", init="heading=90 deg,course_speed=3 km/h", lag="ignore")
    assert c.gnss.lever_arm == pytest.approx((0.1, -0.2, 0.3))
    assert c.aid == ["zupt", "nhc"] and c.zupt.zaru                 # zaru: ZUPT's intervals, and ZARU
    assert c.start.heading == pytest.approx(math.pi / 2) and c.start.course_speed == pytest.approx(3 / 3.6)
    assert c.gnss.fixes.lag == "ignore" and c.gnss.source == "fixes"
    assert Path(c.imu.file).is_absolute() and c.imu.file.endswith("imu.csv")
    assert c.start.heading.text == "90 deg"                         # the text kept for config.toml
    assert [type(a).__name__ for a in aids_of(c)] == ["Zupt", "Nhc"]
    for bad in (dict(aid="zupt,wings"), dict(init="yaw=3 deg"), dict(init="pitch=3"), dict(lag="late"),
                dict(lever_arm="[1, 2] m"), dict(fix_latency=-1.0), dict(gnss_raw=Path("x.ubx"))):
        with pytest.raises((ValueError, UserError)):
            navigate_config(imu=[Path("imu.csv")], fixes=[Path("fix.pos")], **bad)
