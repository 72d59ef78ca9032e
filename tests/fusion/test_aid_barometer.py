"""The barometer aid (sinslab.fusion.aids.barometer) on THOR flight 75 of onavdata: the
height through 60 s GNSS outages against the unit's own solution with and without it, and
a barometer table on another clock refused in one line with nothing written."""
import json

import numpy as np
import pytest

from support import assert_doc_quotes
from test_aid_magnetometer import _flight, _navigate, _table


def _baro(d, path, shift=0.0):
    b = _table(d / "baroalt_data.txt.zip")
    b[:, 0] += shift
    np.savetxt(path, b, delimiter=",", header="time,baro_alt", comments="", fmt="%.4f")
    return ["--aid", "barometer", "--set", f"barometer.file={path}", "--set",
            "barometer.columns=t=time[s], h=baro_alt[m]"]


def _height_at_outage_ends(run, d):
    """|height − the unit's own| [m] at the last epoch of each outage (the fixes the run left
    out, from its fix table)."""
    import pandas as pd
    sol = pd.read_parquet(run / "solution.parquet", columns=["t_s", "t_abs_s", "h_m"])
    t = sol["t_abs_s"].to_numpy()
    fe = np.genfromtxt(run / "fix_errors.csv", delimiter=",", names=True)
    tf = fe["t_s"] + t[0] - sol["t_s"].iloc[0]
    inn = fe["in_outage"] > 0.5
    back = tf[1:][inn[:-1] & ~inn[1:]]                 # the first fix after each outage
    pos = _table(d / "nav_traj_data.txt.zip")
    dh = sol["h_m"].to_numpy() - np.interp(t, pos[:, 0], pos[:, 3])
    return np.array([abs(dh[np.flatnonzero(t < b)[-1]]) for b in back])


def test_barometer_holds_the_height_through_outages(tmp_path):
    """Two 60 s outages (160 s and 280 s after the first fix): without the barometer the
    height is 20–62 m off the unit's own solution at their end (measured 61.8, 20.3 m: the
    vertical channel of a consumer IMU), with it within 10 m (measured 4.3, 5.2 m); the
    bias found at the start and estimated is reported."""
    d = _flight()
    free = _navigate(d, tmp_path / "free", "--outages", "60/120@160")
    assert free.exit_code == 0, free.output
    res = _navigate(d, tmp_path / "baro", "--outages", "60/120@160", *_baro(d, tmp_path / "baro.csv"))
    assert res.exit_code == 0, res.output
    e_free, e_baro = _height_at_outage_ends(tmp_path / "free", d), _height_at_outage_ends(tmp_path / "baro", d)
    assert e_free.size == e_baro.size == 2
    assert np.all(e_free > 15.0) and np.all(e_baro < 10.0), (e_free, e_baro)
    m = json.loads((tmp_path / "baro" / "summary.json").read_text())["metrics"]
    assert m["barometer_bias_sigma_m"] < 1.0 and m["barometer_updates_rejected"] < 10
    assert_doc_quotes("docs/aiding.md", "on THOR flight 75 with two 60 s outages the gate refuses 4 of 369 updates, "
                      "and the bias found at the start, −5.94 m, ends at −6.49 ± 0.40 m",
                      [75, 60, m["barometer_updates_rejected"],
                       m["barometer_updates_rejected"] + m["barometer_updates_applied"], m["barometer_bias_start_m"],
                       m["barometer_bias_m"], m["barometer_bias_sigma_m"]])
    assert "barometer bias" in res.output and (tmp_path / "baro" / "barometer.png").is_file()


def test_a_barometer_on_another_clock_is_refused(tmp_path):
    """The barometer's stamps in seconds of the GPS week (the IMU's since power-on): one line
    naming the file and both spans, exit 2, nothing written."""
    d = _flight()
    res = _navigate(d, tmp_path / "run", *_baro(d, tmp_path / "baro.csv", shift=345600.0))
    assert res.exit_code == 2, res.output
    err = [ln for ln in res.output.splitlines() if "error" in ln]
    said = ("baro.csv: its times 345600.000..346076.180 s do not overlap the IMU record -0.020..476.180 s (covered "
            "0%): a different time base?")
    assert len(err) == 1 and said in err[0], res.output
    assert_doc_quotes("docs/aiding.md", said, [345600.0, 346076.18, -0.02, 476.18, 0])
    assert not (tmp_path / "run").exists()
