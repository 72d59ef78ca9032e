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


_HEAD = "t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n"


def _table_text(n=3000, dt=0.01, gyro=(0.0, 0.0, 0.0), accel=(0.0, 0.0, 1.0), noise=(1e-3, 1e-4),
                gap=None, head=_HEAD, seed=3, spike=None):
    """A CSV IMU table of rates at rest (deg/s, g) with white noise; ``gap=(t, length)``
    drops the samples in that interval; ``spike=(i, rate)`` puts gyro x = rate at row i."""
    rng = np.random.default_rng(seed)
    t = dt * np.arange(1, n + 1)
    if gap is not None:
        t = t[(t <= gap[0]) | (t > gap[0] + gap[1])]
    w = np.asarray(gyro) + noise[0] * rng.standard_normal((t.size, 3))
    if spike is not None:
        w[spike[0], 0] = spike[1]
    f = np.asarray(accel) + noise[1] * rng.standard_normal((t.size, 3))
    return head + "".join(f"{a:.3f}," + ",".join(f"{x:.7g}" for x in (*b, *c)) + "\n"
                          for a, b, c in zip(t, w, f))


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
    # garbage that reads well: each one a confident answer before the plausibility checks
    for name, text in {
        "zeros": _HEAD + "".join(f"{0.01 * (k + 1):.2f},0,0,0,0,0,0\n" for k in range(3000)),
        "two": _HEAD + "0.01,0,0,0.001,0,0,1\n0.02,0,0,0.001,0,0,1\n",
        "no_accel": _table_text(accel=(0, 0, 0), noise=(1e-3, 0.0)),
        "spike": _table_text(spike=(300, 9e4)),
        "mps2_as_g": _table_text(accel=(0, 0, 9.81 / 9.81 / 9.81)),        # m/s² values under [g]
        "scale_10pct": _table_text(accel=(0, 0, 1.1)),                     # warning: 1.1 g
        "dead_gyro": _table_text(noise=(0.0, 1e-4)),                       # warning: constant gyros
        "gap": _table_text(n=6000, gyro=(0, 0, 20.0), gap=(30.0, 0.5)),    # warning: turning across it
        "bom": "\ufeff" + _table_text(),
        "wide": ",".join([f"extra_column_with_a_long_name_{i}" for i in range(3000)]) + "\n1,2\n",
        "binary_toml": None,
        "fixes_csv": "t[s],lat[deg],lon[deg],h[m]\n" + "".join(f"{k}.0,30,110,10\n" for k in range(1, 20)),
        "table": _table_text(),
        # increments stamped in ms under a [s] header (it read as 'a wrong accelerometer unit')
        "ms_inc": "t[s],dtheta_x[rad],dtheta_y[rad],dtheta_z[rad],dv_x[m/s],dv_y[m/s],dv_z[m/s]\n"
                  + "".join(f"{10 * (k + 1)},0,0,1e-6,0,0,0.0981\n" for k in range(500)),
        # a fix at 95° (it ended in 'latitude 95 deg is beyond ±90 deg' naming no file)
        "lat95": "t[s],lat[deg],lon[deg],h[m]\n" + "".join(f"{k}.0,{95 if k == 4 else 30 + 1e-5 * k},110,10\n"
                                                         for k in range(1, 20)),
        "late_fixes": "t[s],lat[deg],lon[deg],h[m]\n" + "".join(f"{1000 + k}.0,{30 + 1e-5 * k},110,10\n"
                                                              for k in range(1, 20)),
    }.items():
        f[name] = d / (name + (".toml" if "toml" in name else ".csv"))
        if text is None:
            f[name].write_bytes(bytes(range(256)) * 8)
        else:
            f[name].write_text(text, encoding="utf-8")
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
    ("diverging-navigation", FI + ["--set", "scenario.duration=1 min", "--set", "init.pos_err=[0, 9000, 0] km"],
     "run:free-inertial", "latitude 113.151 deg is beyond ±90 deg; check the values given"),
    ("config-velocity-beyond-physical", FI + ["--set", "init.vel_err=1e9 m/s"], "run:free-inertial",
     "init.vel_err=1e9 m/s): '1e9 m/s' (component 0) is beyond any physical velocity"),
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
    ("nav-init-unknown", NAV + ["--init", "yaw=3 deg"], "navigate", "--init"),
    ("nav-imu-folder", ["navigate", "--imu", "{dir}", "--fixes", "{rest}"], "navigate", "folder"),
    ("nav-missing-option", ["navigate", "--fixes", "{rest}"], "navigate", "give the IMU log: --imu FILE"),
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
    # -- garbage in: data that cannot be an IMU on the Earth, refused before an answer
    ("align-all-zero", ["align", "--imu", "{zeros}", "--lat", "30 deg"], "align", "every gyro and accelerometer sample is zero"),
    ("allan-all-zero", ["allan", "{zeros}"], "allan", "every gyro and accelerometer sample is zero"),
    ("nav-all-zero", ["navigate", "--imu", "{zeros}", "--fixes", "{rest}"], "navigate", "zeros.csv: every gyro"),
    ("align-two-samples", ["align", "--imu", "{two}", "--lat", "30 deg"], "align", "two.csv: only 2 samples"),
    ("nav-two-samples", ["navigate", "--imu", "{two}", "--fixes", "{rest}"], "navigate", "two.csv: only 2 samples"),
    ("align-no-accel", ["align", "--imu", "{no_accel}", "--lat", "30 deg"], "align", "every accelerometer sample is zero"),
    ("align-beyond-range", ["align", "--imu", "{spike}", "--lat", "30 deg"], "align", "beyond any IMU's range"),
    ("align-wrong-accel-unit", ["align", "--imu", "{mps2_as_g}", "--lat", "30 deg"], "align",
     "wrong accelerometer unit"),
    ("align-window-beyond-end", ALIGN + ["--window", "10:100"], "align", "END 100 s is outside the record"),
    ("allan-window-beyond-end", ["allan", "{rest}", "--window", "0:1000"], "allan", "END 1000 s is outside the record"),
    ("allan-too-few-clusters", ["allan", "{rest}", "--window", "0:1"], "allan", "too short for an Allan fit"),
    ("align-accel-bias-huge", ALIGN + ["--accel-bias", "1e30 ug"], "align", "--accel-bias '1e30 ug': out of range"),
    ("config-gyro-bias-huge", ["run", "dummy", "--set", "imu.gyro_bias=1e300 deg/h"], "run",
     "imu.gyro_bias=1e300 deg/h): '1e300 deg/h' (component 0) is beyond any physical angular rate"),
    ("config-latitude-pole", ["run", "static-alignment", "--quick", "--set", "scenario.latitude=90 deg"],
     "run:static-alignment", "within 1 deg of a pole"),
    # -- --strict: every warning refused
    ("align-strict-scale", ["align", "--imu", "{scale_10pct}", "--lat", "30 deg", "--strict"], "align",
     "refused because of --strict"),
    ("allan-strict-dead", ["allan", "{dead_gyro}", "--strict"], "allan", "constant over all"),
    # -- messages that name their cause and source
    ("nav-lever-arm-huge", NAV + ["--lever-arm", "[1e9, 0, 0] m"], "navigate", "--lever-arm '[1e9, 0, 0] m' (component 0) is out of range: must be <= 200 m"),
    ("nav-mount-overflow", NAV + ["--mount", "rpy:1e400,0,0"], "navigate", "--mount: mount 'rpy:1e400,0,0': angle inf deg"),
    ("nav-mount-nan", NAV + ["--mount", "matrix:nan,0,0,0,1,0,0,0,1"], "navigate", "element (1, 1) is nan"),
    ("nav-frame-unknown", NAV + ["--frame", "ned"], "navigate", "--frame 'ned': choose one of auto, rfu, frd, flu, rbd"),
    ("nav-imu-errors-binary", NAV + ["--imu-errors", "{binary_toml}"], "navigate", "--imu-errors"),
    ("nav-fix-format-wrong", ["navigate", "--imu", "{bom}", "--fixes", "{fixes_csv}", "--fix-format", "rtklib-pos"],
     "navigate", "fixes_csv.csv:1: cannot read the time stamp"),
    ("nav-rest-unknown", NAV + ["--aid", "zupt", "--rest", "bogus"], "navigate", "--rest 'bogus': choose one of either, auto, flags"),
    ("nav-rest-without-zupt", NAV + ["--rest", "auto"], "navigate", "add --aid zupt"),
    ("nav-fix-latency-huge", NAV + ["--fix-latency", "1e9"], "navigate", "--fix-latency '1000000000.0 s' is out of range: must be <= 60 s"),
    ("align-long-header", ["align", "--imu", "{wide}", "--lat", "30 deg"], "align", "characters cut"),
    # -- the real cause, named with its file
    ("nav-time-in-ms", ["navigate", "--imu", "{ms_inc}", "--fixes", "{fixes_csv}"], "navigate",
     "ms_inc.csv: sample interval 10 s (0.1 Hz): no strapdown IMU logs slower than every 1 s; a time column in "
     "milliseconds read as seconds? (then 100 Hz; declare it t[ms])"),
    ("align-time-in-ms", ["align", "--imu", "{ms_inc}", "--lat", "30 deg"], "align", "milliseconds read as seconds"),
    ("nav-fix-latitude-95", ["navigate", "--imu", "{table}", "--fixes", "{lat95}"], "navigate",
     "lat95.csv:5: latitude 95 deg (column 'lat') is beyond ±90 deg"),
    ("nav-fixes-one-epoch", ["navigate", "--imu", "{table}", "--fixes", "{fixes_csv}"], "navigate",
     "fixes_csv.csv: only one receiver epoch: a run needs fixes at two times at least"),
    ("nav-fixes-other-time-base", ["navigate", "--imu", "{table}", "--fixes", "{late_fixes}"], "navigate",
     "late_fixes.csv: the fix times (1001.000..1019.000 s) do not overlap the IMU record"),
    ("nav-gnss-raw-folder", ["navigate", "--imu", "{table}", "--gnss-raw", "{dir}"], "navigate",
     "folder: is a folder, not a file"),
    ("nav-gnss-nav-with-fixes", NAV + ["--gnss-nav", "{afile}"], "navigate",
     "config key gnss.raw.nav (--gnss-nav"),
    # -- no run inside another run's folder
    ("run-out-inside-a-run", ["run", "dummy", "--out", "{out}/sub"], "run", "inside the run folder"),
    ("demo-out-is-a-run", ["demo", "--quick", "--only", "dummy"], "run", "is a run folder"),
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
    assert len(errors[0]) < 600, len(errors[0])   # long values are cut
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


# ------------------------------------------------ accepted, with a warning (and --strict) ---
# (id, command line, text the warning line must contain); each run completes (exit 0) with
# the warning on stdout, in summary.json and flagged in the report; with --strict the same
# command is refused with exit 2 and writes nothing.
WARNED = [
    ("align-accel-scale", ["align", "--imu", "{scale_10pct}", "--lat", "30 deg"], "1.1 × local gravity"),
    ("align-dead-gyros", ["align", "--imu", "{dead_gyro}", "--lat", "30 deg"], "constant over all 3000 samples: gyro x"),
    ("allan-gap", ["allan", "{gap}"], "turn rates up to 20 deg/s, so up to 10.2 deg of rotation"),
    ("allan-short-record", ["allan", "{rest}"], "bias instability there is an upper bound"),
    ("align-bom-header", ["align", "--imu", "{bom}", "--lat", "30 deg", "--window", "0:2"], "2 s window"),
]


@pytest.mark.parametrize("cid, argv, needle", WARNED, ids=[c[0] for c in WARNED])
def test_warned_then_refused_with_strict(tmp_path, files, cid, argv, needle):
    args = [a.format(**files) for a in argv]
    r = invoke("-q", *args, "--out", tmp_path / "a")
    assert r.exit_code == 0, r.stderr
    warn = [ln for ln in r.stdout.splitlines() if ln.strip().startswith("warning:") and needle in ln]
    assert warn, r.stdout
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert any(needle in w for w in s["warnings"])
    assert "id='warnings'" in (tmp_path / "a" / "report.html").read_text()
    r = invoke("-q", *args, "--strict", "--out", tmp_path / "b")
    assert r.exit_code == 2 and "refused because of --strict" in r.stderr, r.stderr
    assert not (tmp_path / "b").exists()


def test_consistency_monitors_find_long_inconsistent_stretches():
    """Oracle: a consistent filter's innovations are white N(0, S) (Mehra & Peschon 1971):
    600 s of 4 Hz fixes drawn so, with a σ changing from fix to fix and a masked component,
    raise nothing; the same fixes scaled by 2 over 200 s are overconfident there (NIS), a
    0.6σ bias of one component over 200 s (the NIS up by only 0.36 of 6) is reported as
    biased in that component, and a pessimistic run (innovations a third of their σ) is no
    warning (the whole-run NIS verdict says so)."""
    from sinslab.app.plausibility import consistency_findings

    rng = np.random.default_rng(0)
    t = np.arange(0.0, 600.0, 0.25)
    sd = rng.uniform(0.5, 3.0, (t.size, 6))
    nu = rng.standard_normal((t.size, 6)) * sd
    nu[::7, 5] = sd[::7, 5] = np.nan                            # a component not used

    def nis(v):
        return np.nansum((v / sd) ** 2, axis=1)

    labels = ["pos N", "pos E", "pos U", "vel E", "vel N", "vel U"]
    assert consistency_findings(t, nu, sd, nis(nu), labels) == []
    assert consistency_findings(t, nu / 3, sd, nis(nu / 3), labels) == []
    bad = nu.copy()
    bad[800:1600] *= 2.0
    (fd,) = consistency_findings(t, bad, sd, nis(bad), labels)
    assert "overconfident for 2" in fd.text and "window's" in fd.text, fd.text
    bias = nu.copy()
    bias[800:1600, 1] += 0.6 * sd[800:1600, 1]
    (fd,) = consistency_findings(t, bias, sd, nis(bias), labels)
    assert "biased for" in fd.text and "in pos E:" in fd.text, fd.text
    assert 170 < float(fd.text.split("biased for ")[1].split(" s")[0]) < 240, fd.text


@pytest.mark.parametrize("argv", [["align", "--imu", "{two}", "--lat", "30 deg"], ["allan", "{zeros}"],
                                  ["navigate", "--imu", "{zeros}", "--fixes", "{rest}"]],
                         ids=["align", "allan", "navigate"])
def test_refused_without_out_writes_no_runs_folder(tmp_path, files, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    r = invoke("-q", *[a.format(**files) for a in argv])
    assert r.exit_code == 2, r.stderr
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------ the command line itself ---
def test_bare_sinslab_is_help_with_status_0():
    r = invoke()
    assert r.exit_code == 0 and "Usage:" in r.stdout and "navigate" in r.stdout


@pytest.mark.parametrize("cmd", ["list", "run", "config", "report", "demo", "navigate", "allan",
                                 "align", "transfer-align"])
def test_every_help_has_an_example(cmd):
    r = invoke(cmd, "--help")
    assert r.exit_code == 0 and "Example:" in r.stdout and f"sinslab {cmd}" in r.stdout


def test_frame_help_lists_every_frame():
    from sinslab.data.frames import _FRAMES

    text = " ".join(invoke("navigate", "--help").stdout.split())
    assert all(f in text for f in _FRAMES)


def test_summary_shows_measured_against_expected_and_stages_off_a_terminal(tmp_path, dummy):
    """Off a terminal (the runner's stderr is no TTY) each stage prints its start and end with
    the elapsed time; each claim line shows the measured value and the expectation."""
    import sinslab.core.progress as P

    P.set_quiet(None)
    try:
        r = invoke("run", "dummy", "--quick", "--out", tmp_path / "r")
    finally:
        P.set_quiet(None)
    assert r.exit_code == 0, r.stderr
    claims = [ln for ln in r.stdout.splitlines() if ln.lstrip().startswith("[")]
    assert claims and all("(expected " in ln for ln in claims), claims


def test_stage_lines_with_elapsed_time_off_a_terminal(capsys):
    import sinslab.core.progress as P

    P.set_quiet(None)
    P.set_lines(False)                          # a library caller: nothing
    with P.progress("crunching", total=10) as bar:
        bar.advance(10)
    assert capsys.readouterr().err == ""
    P.set_lines(True)                           # the command line
    with P.progress("crunching", total=10, unit="steps") as bar:
        bar.advance(10)
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "sinslab: crunching: started" and err[-1].startswith("sinslab: crunching: done in ")
    P.set_quiet(True)
    with P.progress("crunching", total=10) as bar:
        bar.advance(10)
    assert capsys.readouterr().err == ""
    P.set_quiet(None)
    P.set_lines(False)


def test_recorded_data_commands_announce_their_stages_off_a_terminal(tmp_path, files):
    """align and allan (like navigate and transfer-align) print a line as each stage starts
    and ends, with its time, reading included; the run folder's writing is a stage too."""
    import sinslab.core.progress as P

    P.set_quiet(None)
    try:
        for args, work in ((["align", "--imu", files["rest"]], "alignment over 60 s"),
                           (["allan", files["rest"]], "Allan deviation of 60 s")):
            r = invoke(*args, "--out", tmp_path / args[0])
            assert r.exit_code == 0, r.stderr
            lines = [ln for ln in r.stderr.splitlines() if ln.startswith("sinslab: ")]
            stages = [ln.split(": ")[1] for ln in lines if ln.endswith(": started")]
            assert stages == [f"{args[0]}, computing", "reading rest.imu", work,
                              f"writing {tmp_path / args[0]}"], lines
            assert sum(": done in " in ln for ln in lines) == 4, lines
    finally:
        P.set_quiet(None)


def test_config_overriding_quick_says_so(tmp_path, dummy):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[scenario]\nduration = "30 s"\n')
    r = invoke("-q", "run", "dummy", "--quick", "--config", cfg, "--out", tmp_path / "r")
    assert r.exit_code == 0, r.stderr
    assert "note: --config" in r.stderr and "scenario.duration (10 s -> 30 s)" in r.stderr


# ------------------------------------------------------------------ the checks themselves ---
def _rest_record(n=6000, dt=0.01, tilt_step_deg=0.0, f_scale=1.0, seed=5):
    """An ImuRecord at rest, level, g = 9.78 m/s² (equator), white noise of 0.01 m/s² and
    0.001 rad/s per sample; the second half pitched up by ``tilt_step_deg``."""
    from sinslab.core.records import ImuRecord

    rng = np.random.default_rng(seed)
    g = 9.780325 * f_scale
    f = np.tile([0.0, 0.0, g], (n, 1))
    th = math.radians(tilt_step_deg)
    f[n // 2:] = [0.0, g * math.sin(th), g * math.cos(th)]     # RFU: pitch up tilts +y
    f += 0.01 * rng.standard_normal((n, 3))
    w = 1e-3 * rng.standard_normal((n, 3))
    return ImuRecord(dt * np.arange(1, n + 1), w * dt, f * dt, dt)


PLAUSIBLE = [  # (id, record keywords, refuse?, text of the one finding or None)
    ("at-rest", {}, False, None),
    ("tilt-step-0.1deg", {"tilt_step_deg": 0.1}, False, "pitch from the mean specific force changes by 0.1"),
    ("scale-10pct", {"f_scale": 1.1}, False, "1.1 × local gravity"),
    ("g-read-as-m/s2", {"f_scale": 1 / 9.80665}, True, "wrong accelerometer unit"),
]


@pytest.mark.parametrize("cid, kw, refuse, text", PLAUSIBLE, ids=[c[0] for c in PLAUSIBLE])
def test_rest_and_record_checks(cid, kw, refuse, text):
    """Oracles: a level record at rest with white noise raises nothing; a 0.1° pitch step
    (the motion the README's laser-gyro window holds) is far above the noise of a 30-s mean
    (0.01 m/s² / √3000 / g ≈ 0.001°); |f| = 1.1 g is a 10 % scale error; 0.1 g a unit slip."""
    from sinslab.app.plausibility import imu_findings, rest_findings

    imu = _rest_record(**kw)
    found = imu_findings(imu, "rec") + rest_findings(imu, "rec")
    if text is None:
        assert found == []
        return
    assert any(text in fd.text for fd in found), found
    assert any(fd.refuse for fd in found) == refuse


def test_a_header_wider_than_the_first_read_is_read_whole(tmp_path):
    """A valid table with 12 007 columns (a 180 kB header line): it was refused with
    'the header has N' where N was the columns within the first 64 KiB."""
    from sinslab.data import load_imu

    extra = [f"vendor_status_word_{i:05d}" for i in range(12000)]
    head = "t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]," + ",".join(extra) + "\n"
    tail = "," + ",".join("0" * len(extra)) + "\n"
    p = tmp_path / "wide.csv"
    p.write_text(head + "".join(f"{0.01 * k:.2f},0,0,0.001,0,0,1{tail}" for k in range(1, 201)))
    assert len(head) > 1 << 17
    d = load_imu(p)
    assert len(d.imu) == 200 and np.allclose(d.imu.dv[:, 2] / d.imu.dt, 9.80665)
