"""`transfer-align` gets the input checks and option ranges `navigate` has, and checks its own
estimates: the battery's cases on the PSINS car record (docs/cli.md, transfer-align).

Refused in one line with exit 2 and nothing written: a slave scaled by 1000, a master
attitude in degrees read as radians, a slave gyro in degrees read as radians (the two
rotation rates 180/π apart), a master in reverse time order, an all-zero slave, options
beyond any IMU. Warned about (refused with --strict): a master clock 0.5 s late — found
by lining the rotation rates up — and the σ it makes implausibly tight (NIS)."""
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from sinslab.cli import app

DATA = Path(__file__).resolve().parents[3] / "shared" / "data" / "psins-transfer" / "transfer_align_fog_mems.mat"
pytestmark = pytest.mark.skipif(not DATA.exists(), reason="recorded transfer-alignment data not present")


def _cli(*args):
    return CliRunner().invoke(app, ["-q", "transfer-align", *map(str, args)])


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    import scipy.io

    d = tmp_path_factory.mktemp("ta")
    m = scipy.io.loadmat(DATA)
    base = {k: m[k] for k in ("mimu", "fogavp", "eb0", "db0", "mu0")}

    def save(name, **over):
        scipy.io.savemat(d / name, {**base, **over})
        return d / name

    slave = m["mimu"].copy()
    slave[:, :6] *= 1000
    gyro_deg = m["mimu"].copy()
    gyro_deg[:, :3] = np.degrees(gyro_deg[:, :3])
    zero = m["mimu"].copy()
    zero[:, :6] = 0
    att_deg = m["fogavp"].copy()
    att_deg[:, :3] = np.degrees(att_deg[:, :3])
    late = m["fogavp"].copy()
    late[:, 9] += 0.5
    return {"slave1000": save("slave1000.mat", mimu=slave), "gyro_deg": save("gyro_deg.mat", mimu=gyro_deg),
            "zero": save("zero.mat", mimu=zero), "att_deg": save("att_deg.mat", fogavp=att_deg),
            "reversed": save("reversed.mat", fogavp=m["fogavp"][::-1].copy()), "late": save("late.mat", fogavp=late)}


REFUSED = [  # (id, slave, master, extra options, text of the one error line)
    ("slave-x1000", "slave1000", None, [], "is beyond any IMU's range (±500 g): a wrong unit"),
    ("master-degrees", None, "att_deg", [], "master pitch -261.35 deg at t = 62.3 s is beyond ±90 deg — degrees read as radians?"),
    ("slave-gyro-degrees", "gyro_deg", None, [],
     "gyro_deg.mat), where both measure the same rotation: a unit slip (180/π = 57.3): "
     "the slave's gyro data in degrees read as radians"),
    ("master-reversed", None, "reversed", [], "reversed.mat:row 2: time stamps decrease throughout: the record is in reverse order"),
    ("slave-all-zero", "zero", None, [], "zero.mat: every gyro and accelerometer sample is zero"),
    ("gyro-arw-1e9", None, None, ["--gyro-arw", "1e9 deg/sqrt(h)"], "--gyro-arw '1e9 deg/sqrt(h)': out of range, must be <= 100 deg/sqrt(h)"),
    ("mount-400", None, None, ["--mount", "[400, 0, 0] deg"], "--mount '[400, 0, 0] deg': pitch 400 deg is out of range"),
    ("accel-vrw", None, None, ["--accel-vrw", "10 m/s/sqrt(s)"], "--accel-vrw '10 m/s/sqrt(s)': out of range"),
]


@pytest.mark.parametrize("cid, slave, master, extra, needle", REFUSED, ids=[c[0] for c in REFUSED])
def test_refused_in_one_line(tmp_path, files, cid, slave, master, extra, needle):
    r = _cli("--slave", files[slave] if slave else DATA, "--master", files[master] if master else DATA,
             *extra, "--out", tmp_path / "o")
    lines = r.stderr.strip().splitlines()
    assert r.exit_code == 2 and len(lines) == 1 and "Traceback" not in r.output, r.output
    assert needle in lines[0], lines[0]
    assert not (tmp_path / "o").exists()


@pytest.fixture(scope="module")
def runs(tmp_path_factory, files):
    d = tmp_path_factory.mktemp("runs")
    out = {}
    for name, master in (("ok", DATA), ("late", files["late"])):
        r = _cli("--slave", DATA, "--master", master, "--out", d / name)
        assert r.exit_code == 0, r.output
        out[name] = (r.stdout, json.loads((d / name / "summary.json").read_text()))
    return out


def test_a_late_master_clock_is_found_and_warned_about(runs, files, tmp_path):
    from support import assert_doc_quotes

    text, s = runs["late"]
    warn = [w for w in s["warnings"] if "line up best" in w]
    assert len(warn) == 1 and "master's clock 0.516 s late" in warn[0], s["warnings"]
    tight = [w for w in s["warnings"] if "implausibly tight" in w]
    assert len(tight) == 1 and "warning: slave and master" in text
    ok_text, ok = runs["ok"]
    assert ok["warnings"] == [] and "warning" not in ok_text
    from sinslab.app.commands.transfer_align import read_master
    from sinslab.data import load_imu
    from sinslab.methods import transfer as tm

    lag_ok = tm.rate_lag(load_imu(DATA).imu, tm.MasterRecord(*read_master(DATA)[:3]))[0]
    roll = lambda s: (s["metrics"]["mounting_arcmin_optimal_all"][1],                     # noqa: E731
                      s["metrics"]["mounting_sigma_arcmin_optimal_all"][1])
    moved = abs(roll(s)[0] - roll(ok)[0]) / roll(s)[1]
    ratio = float(tight[0].split("innovations are ")[1].split(" times")[0])
    ok_ratio = _innovation_ratio()
    assert_doc_quotes("docs/cli.md", "a master 0.5 s late is found 0.52 s late (the record itself lines up at 0.02 s)",
                      [0.5, float(warn[0].split("clock ")[1].split(" s")[0]), lag_ok])
    assert_doc_quotes("docs/cli.md", "it moves the roll mounting by 8.6σ", [moved])
    assert_doc_quotes("docs/cli.md", "on the car record the innovations are 0.51 σ, with the master 0.5 s late 9.2 σ",
                      [ok_ratio, 0.5, ratio])
    r = _cli("--slave", DATA, "--master", files["late"], "--strict", "--out", tmp_path / "strict")
    assert r.exit_code == 2 and "refused because of --strict" in r.stderr and not (tmp_path / "strict").exists()


def _innovation_ratio():
    """√(NIS per component) of the car record's own alignment (no warning: below 1)."""
    from sinslab.app.commands.transfer_align import _process_noise, read_master
    from sinslab.core import units
    from sinslab.data import load_imu
    from sinslab.methods import transfer as tm

    mt, att, vel, pos = read_master(DATA)
    pn = _process_noise(None)
    r = tm.align_recorded(load_imu(DATA).imu, tm.MasterRecord(mt, att, vel), pos, "optimal",
                          att_sigma=units.arcmin, gyro_arw=pn["gyro_arw"][0], accel_vrw=pn["accel_vrw"][0])
    dof = sum(int(np.isfinite(np.asarray(v)).sum()) for v in r.applied.innovation)
    return float(np.sqrt(np.nansum(r.applied.nis) / dof))
