"""Every bad input is one line and exit status 2, and loses nothing.

Table-driven, in process (typer's CliRunner): each case runs a command with one bad
value into an ``--out`` folder that holds a previous run of the same command, and
asserts exit status 2, exactly one stderr line ``sinslab: error: ...`` that names the
culprit (option, config key or file), and the previous run unchanged byte for byte.
Inputs found bad only while computing (a diverging navigation) may follow the command's
progress lines: there the error must be the last line and the only error line.
"""
import hashlib
import json
import math
import socket
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import sinslab.experiments as E
from sinslab.app.outputs import MARKER, RunDir
from sinslab.cli import app

HERE = Path(__file__).resolve().parent
DRIVE = HERE.parents[2] / "shared" / "data" / "rtklib-drive"
runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def snapshot(d):
    """{relative path: sha1} of every file under ``d`` (None if ``d`` does not exist)."""
    d = Path(d)
    if not d.exists():
        return None
    if d.is_file():
        return hashlib.sha1(d.read_bytes()).hexdigest()
    return {p.relative_to(d).as_posix(): hashlib.sha1(p.read_bytes()).hexdigest()
            for p in sorted(d.rglob("*")) if p.is_file()}


# ------------------------------------------------------------------ inputs --------------
def _psins_text(n, dt_ms=10.0, lat_deg=34.0):
    """A PSINS .imu log of an IMU at rest (x right, y north, z up): earth rate and gravity
    as integer counts, with gyro scale 1e-3 arcsec/count and accel scale 1 ug·s/count."""
    wie, g = 7.292115e-5, 9.7946
    dt = dt_ms * 1e-3
    gyro = np.array([0.0, wie * math.cos(math.radians(lat_deg)), wie * math.sin(math.radians(lat_deg))])
    gc = np.round(gyro * dt / (1e-3 * math.pi / 180 / 3600))
    ac = np.round(np.array([0.0, 0.0, dt / 1e-6]))
    rng = np.random.default_rng(1)
    rows = np.c_[gc + rng.integers(-20, 21, (n, 3)), ac + rng.integers(-3, 4, (n, 3))]
    head = ("% PSINS-format SIMU log file (synthetic)\n0 0 0 0 0 0\n"
            f"{lat_deg} 108.9 380 0 {dt_ms} {g}\n0.001 0.001 0.001 1 1 1\n")
    return head + "\n".join(" ".join(str(int(v)) for v in r) for r in rows) + "\n"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("inputs")
    f = {"dir": d / "folder", "random": d / "random.imu", "random_csv": d / "random.csv",
         "rest": d / "rest.imu", "trunc": d / "trunc.imu", "units_csv": d / "units.csv",
         "afile": d / "afile.txt", "missing": d / "missing.imu"}
    f["dir"].mkdir()
    raw = np.random.default_rng(2).integers(0, 256, 4000, dtype=np.uint8).tobytes()
    f["random"].write_bytes(raw)
    f["random_csv"].write_bytes(raw)
    text = _psins_text(6000)
    f["rest"].write_text(text)
    f["trunc"].write_text(text[: len(text) // 2])
    f["units_csv"].write_text("t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n"
                              + "".join(f"{0.01 * (k + 1):.2f},0,0,0,0,0,1\n" for k in range(500)))
    f["afile"].write_text("a file\n")
    return {k: str(v) for k, v in f.items()}


def _previous_run(path, command, experiment=None):
    """A completed run of ``command`` in ``path`` (what a user's last run left there)."""
    rd = RunDir(path, experiment or command, command=command).prepare()
    rd.write_text("config.toml", f"# previous {command}\n")
    rd.write_json("summary.json", {"experiment": experiment or command, "previous": True})
    rd.finish()


@pytest.fixture(scope="module")
def dummy():
    import test_cli

    E.register(test_cli.Dummy)
    return test_cli.Dummy


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# (id, command line with {placeholders}, what holds --out beforehand, text the line must contain)
# {out} is the output folder; {port} a closed local port; file names from `files`.
FI = ["run", "free-inertial", "--quick"]
NAV = ["navigate", "--imu", "{rest}", "--fixes", "{rest}"]
ALIGN = ["align", "--imu", "{rest}"]
CASES = [
    # -- run: configuration and options
    ("unknown-experiment", ["run", "no-such-experiment"], "run", "unknown experiment 'no-such-experiment'"),
    ("unknown-key", ["run", "dummy", "--set", "imu.gyro_bais=1 deg/h"], "run", "imu.gyro_bais"),
    ("no-unit", ["run", "dummy", "--set", "scenario.latitude=45"], "run", "scenario.latitude"),
    ("config-is-folder", ["run", "dummy", "--config", "{dir}"], "run", "is a folder"),
    ("config-binary", ["run", "dummy", "--config", "{random}"], "run", "not UTF-8"),
    ("seed-not-int", ["run", "dummy", "--seed", "abc"], "run", "'--seed'"),
    ("runs-zero", ["run", "dummy", "--runs", "0"], "run", "'--runs'"),
    ("memory", FI + ["--set", "scenario.sample_interval=1e-9 s"], "run:free-inertial",
     "scenario.sample_interval: 1e-9 s over"),
    ("diverging-navigation", FI + ["--set", "scenario.duration=1 min", "--set", "init.vel_err=1e9 m/s"],
     "run:free-inertial", "init.vel_err=1e9 m/s"),
    # -- run: Dask scheduler (each refused within seconds, no Dask traceback)
    ("scheduler-malformed", FI + ["--runs", "4", "--scheduler", "not an address"], "run:free-inertial",
     "--scheduler 'not an address'"),
    ("scheduler-unreachable", FI + ["--runs", "4", "--scheduler", "tcp://127.0.0.1:{port}"],
     "run:free-inertial", "no scheduler answers at 127.0.0.1"),
    ("scheduler-unresolvable", FI + ["--runs", "4", "--scheduler", "tcp://no-such-host.invalid:8786"],
     "run:free-inertial", "'no-such-host.invalid'"),
    ("scheduler-without-monte-carlo", ["run", "dummy", "--scheduler", "tcp://127.0.0.1:8786"], "run",
     "runs no Monte Carlo"),
    ("scheduler-one-run", FI + ["--runs", "1", "--scheduler", "sync"], "run:free-inertial", "runs >= 2 (runs = 1)"),
    # -- output folders
    ("out-under-a-file", ["run", "dummy", "--out", "{afile}/run"], None, "is a file"),
    ("out-is-a-file", ["run", "dummy", "--out", "{afile}"], None, "is a file"),
    ("out-unwritable", ["run", "dummy", "--out", "/proc/sinslab-run"], None, "/proc"),
    ("out-foreign-files", ["run", "dummy"], "foreign", "'thesis.tex'"),
    ("out-other-experiment", ["run", "dummy"], "run:free-inertial", "`run free-inertial`"),
    ("out-other-command", ["run", "dummy"], "navigate", "`navigate`"),
    ("demo-user-index", ["demo", "--quick", "--only", "dummy"], "user-index", "index.html"),
    # -- navigate: option values (checked before any file is read)
    ("nav-max-gap-negative", NAV + ["--max-gap", "-1"], "navigate", "--max-gap"),
    ("nav-fix-latency-nan", NAV + ["--fix-latency", "nan"], "navigate", "--fix-latency"),
    ("nav-velocity-lag-negative", NAV + ["--velocity-lag", "-5"], "navigate", "--velocity-lag"),
    ("nav-lag-choice", NAV + ["--lag", "sometimes"], "navigate", "--lag"),
    ("nav-time-sync-choice", NAV + ["--time-sync", "maybe"], "navigate", "--time-sync"),
    ("nav-init-no-unit", NAV + ["--init", "heading=30"], "navigate", "--init heading"),
    ("nav-init-out-of-range", NAV + ["--init", "heading=400 deg"], "navigate", "--init heading"),
    ("nav-init-unknown", NAV + ["--init", "pitch=3 deg"], "navigate", "--init"),
    ("nav-imu-folder", ["navigate", "--imu", "{dir}", "--fixes", "{rest}"], "navigate", "folder"),
    ("nav-missing-option", ["navigate", "--fixes", "{rest}"], "navigate", "'--imu'"),
    # -- align
    ("align-lat-no-unit", ALIGN + ["--lat", "34"], "align", "--lat '34'"),
    ("align-lat-range", ALIGN + ["--lat", "100 deg"], "align", "--lat"),
    ("align-height", ALIGN + ["--height", "abc"], "align", "--height 'abc'"),
    ("align-window-text", ALIGN + ["--window", "abc"], "align", "--window 'abc'"),
    ("align-window-reversed", ALIGN + ["--window", "50:20"], "align", "--window"),
    ("align-window-outside", ALIGN + ["--window", "1e6:2e6"], "align", "outside the record"),
    ("align-period", ALIGN + ["--period", "0 s"], "align", "--period"),
    ("align-model", ALIGN + ["--model", "best"], "align", "--model"),
    ("align-gyro-bias-no-unit", ALIGN + ["--gyro-bias", "5"], "align", "--gyro-bias"),
    ("align-random-bytes", ["align", "--imu", "{random}"], "align", "binary data"),
    ("align-truncated", ["align", "--imu", "{trunc}"], "align", "truncated"),
    ("align-missing-file", ["align", "--imu", "{missing}"], "align", "missing.imu"),
    ("align-out-other-command", ALIGN, "allan", "`allan`"),
    # -- allan
    ("allan-window-text", ["allan", "{rest}", "--window", "abc"], "allan", "--window 'abc'"),
    ("allan-window-outside", ["allan", "{rest}", "--window", "1e6:2e6"], "allan", "outside the record"),
    ("allan-gyro-unit-psins", ["allan", "{rest}", "--gyro-unit", "deg/h"], "allan", "--gyro-unit"),
    ("allan-gyro-unit-header", ["allan", "{units_csv}", "--gyro-unit", "deg/h"], "allan", "states the column units"),
    ("allan-accel-unit-kind", ["allan", "{units_csv}", "--accel-unit", "deg"], "allan", "--accel-unit"),
    ("allan-random-bytes", ["allan", "{random}"], "allan", "random.imu"),
    ("allan-folder", ["allan", "{dir}"], "allan", "folder"),
    ("allan-out-foreign", ["allan", "{rest}"], "foreign", "'thesis.tex'"),
    # -- transfer-align
    ("transfer-method", ["transfer-align", "--slave", "{rest}", "--master", "{rest}", "--method", "magic"],
     "transfer-align", "--method 'magic'"),
    ("transfer-window", ["transfer-align", "--slave", "{rest}", "--master", "{rest}", "--window", "abc"],
     "transfer-align", "--window 'abc'"),
]


@pytest.mark.parametrize("cid, argv, before, needle", CASES, ids=[c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_and_loses_nothing(tmp_path, files, dummy, cid, argv, before, needle):
    out = tmp_path / "out"
    if before == "foreign":
        out.mkdir()
        (out / "thesis.tex").write_text("precious")
    elif before == "user-index":
        out.mkdir()
        (out / "index.html").write_text("<html>my own page</html>")
    elif before is not None:
        cmd, _, exp = before.partition(":")
        _previous_run(out, cmd, exp or ("dummy" if cmd == "run" else cmd))
    subs = dict(files, out=str(out), port=str(_free_port()))
    args = [a.format(**subs) for a in argv]
    if "--out" not in args and argv[0] != "demo":
        args += ["--out", str(out)]
    if argv[0] == "demo":
        args += ["--out", str(out)]
    sib = sorted(p.name for p in tmp_path.iterdir())
    old = snapshot(out)
    r = invoke("-q", *args)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.exit_code == 2, (r.exit_code, r.stderr, r.stdout)
    assert "Traceback" not in r.stderr + r.stdout
    errors = [ln for ln in lines if ln.startswith("sinslab: error:")]
    assert len(errors) == 1 and lines[-1] == errors[0], lines
    if cid != "diverging-navigation":           # found while computing: after progress lines
        assert len(lines) == 1, lines
    assert needle in errors[0], errors[0]
    assert snapshot(out) == old                 # the previous run (or the user's files) intact
    assert sorted(p.name for p in tmp_path.iterdir()) == sib     # no staging folder left


def test_accepted_with_a_warning_short_alignment_window(tmp_path, files):
    """A 2 s window cannot determine heading: the run completes but says so, with the σ."""
    r = invoke("-q", "align", "--imu", files["rest"], "--window", "0:2", "--out", tmp_path / "a")
    assert r.exit_code == 0, r.stderr
    line = [ln for ln in r.stdout.splitlines() if "warning" in ln and "heading" in ln]
    assert line and "σ" in line[0] and "2 s window" in line[0]
    r = invoke("-q", "align", "--imu", files["rest"], "--window", "0:40", "--out", tmp_path / "b")
    assert r.exit_code == 0 and "window is too short" not in r.stdout


@pytest.mark.skipif(not (DRIVE / "imu_1934.csv").exists(), reason="rtklib-drive not available")
def test_outages_beyond_the_record(tmp_path):
    _previous_run(tmp_path / "out", "navigate")
    old = snapshot(tmp_path / "out")
    r = invoke("-q", "navigate", "--imu", DRIVE / "imu_1934.csv", "--fixes", DRIVE / "gnss_1934_sf.pos",
               "--outages", "5000:30", "--out", tmp_path / "out")
    assert r.exit_code == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "--outages '5000:30'" in r.stderr and "outside the record" in r.stderr
    assert snapshot(tmp_path / "out") == old


def test_demo_rewrites_its_own_index(tmp_path, dummy):
    """The index a previous demo wrote is replaced (a user's own page is refused: CASES)."""
    from sinslab.app import report

    report.index(tmp_path, [])
    old = (tmp_path / "index.html").read_text()
    r = invoke("-q", "demo", "--quick", "--only", "dummy", "--out", tmp_path)
    assert r.exit_code == 0, r.stderr
    new = (tmp_path / "index.html").read_text()
    assert new != old and "dummy" in new
    assert json.loads((tmp_path / "dummy" / MARKER).read_text())["status"] == "complete"
