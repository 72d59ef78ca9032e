"""Docs that cannot go stale: every ``sinslab`` command shown in README.md and docs/**.md runs.

Commands are discovered, not listed: every line of a fenced code block that starts with
``sinslab`` (or ``$ sinslab``; ``\\`` continuations joined, ``# comments`` dropped), and every
inline code span ``sinslab COMMAND ARG...`` with at least one argument. A line with a
placeholder (an upper-case word such as ``NAME``, ``FILE``, ``DIR``, ``ADDRESS``, or ``...``)
is a synopsis and is not run; an optional part written with a concrete value
(``[--window 600:1200]``) is left out (the command as shown without it).

Each command runs in one scratch folder per document (in order, so ``sinslab report runs/fi``
finds the ``--out runs/fi`` of the line before it), in process, with exit status 0 — or, where
the document shows the error line that follows it (``$ sinslab ...`` then ``sinslab: error:
...``), exit status 2 and that very line. Data files are found by name in the shared data
folder (``psins-lasergyro/``, ``rtklib-drive/``, ``psins-transfer/``). Substitutions that keep
the test within a minute or two of CPU (the documented commands run at full scale):

- ``sinslab run NAME ...`` gets ``--quick`` (a bare ``sinslab run NAME`` of the experiments in
  :data:`FULL_SCALE`, a few seconds each, runs as shown); ``--runs N`` becomes
  ``--runs 4 --scheduler sync``;
- ``sinslab demo ...`` becomes ``sinslab demo --quick --only static-alignment``;
- identical command lines (after substitution) in one document run once.

Files named in a command that exist nowhere are an error, unless listed in
:data:`ILLUSTRATIONS` (a made-up vendor log the text explains).

The example at the end of every command's ``--help`` (``sinslab.cli.EXAMPLES``) runs too.

Numbers quoted in the docs from these runs are checked against the run's ``summary.json``
with a stated tolerance (:data:`QUOTED`): a run that moves them fails here until the
document is updated.
"""
import json
import re
import shlex
from pathlib import Path

import pytest
from typer.testing import CliRunner

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data"
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
#: file names in commands that illustrate a format and exist nowhere
ILLUSTRATIONS = {"acme.csv", "fixes.csv"}
#: experiments whose full-scale run takes seconds: ``sinslab run NAME`` alone runs as shown
FULL_SCALE = {"static-alignment", "free-inertial"}
#: summary.json of every run made here, by its (substituted) command line
_SUMMARIES: dict[str, dict] = {}
_PLACEHOLDER = re.compile(r"(?<![\w./-])(?:[A-Z][A-Z_]{1,}(?:\.[a-z]+)?)(?![\w/-])|\.\.\.")
_DATA_SUFFIX = (".imu", ".csv", ".pos", ".mat", ".parquet", ".ubx", ".zip", ".gz")
#: recordings of the public ``onavdata`` package (a car drive of a commercial MEMS INS/GNSS
#: unit, a small aircraft's flight) that docs/recorded-data.md shows for a user who has it;
#: they are not in the data folder, so their commands are not run here
EXTERNAL = {"n380-imu-nav.csv.zip", "n380-gnss-pvt.csv.zip", "accel_data.txt.zip", "gyro_data.txt.zip",
            "gps_traj_data.txt.zip", "gps_velocity_data.txt.zip"}


def _commands(path: Path):
    """``[(command line, expected error line or None)]`` shown in one document."""
    text = path.read_text(encoding="utf-8")
    found = []
    for m in re.finditer(r"```[a-z]*\n(.*?)```", text, re.S):
        lines = re.sub(r"\\\n\s*", " ", m.group(1)).splitlines()
        for i, ln in enumerate(lines):
            s = ln.strip()
            if s.startswith("$ "):
                s = s[2:]
            if not re.match(r"(?:\.venv/bin/)?sinslab\s", s):
                continue
            s = re.sub(r"\s+#\s.*$", "", s).strip()
            s = re.split(r"\s{3,}", s)[0]          # a synopsis' description column
            if s.startswith("sinslab: "):
                continue
            nxt = lines[i + 1].strip() if i + 1 < len(lines) else ""
            found.append((s, nxt if nxt.startswith("sinslab: error:") else None))
    prose = re.sub(r"```.*?```", "", text, flags=re.S)
    for m in re.finditer(r"`((?:\.venv/bin/)?sinslab [^`]+)`", prose):
        if len(m.group(1).split()) >= 3:
            found.append((m.group(1), None))
    out = []
    for cmd, err in found:
        body = re.sub(r"\s*\[--[^\[\]]*\]", "", cmd)    # optional parts ([--window 600:1200]) left out
        if _PLACEHOLDER.search(body.replace("sinslab -q", "sinslab")) or "[--" in body:
            continue
        out.append((body, err))
    return out


def _data_file(word: str):
    name = Path(word).name
    hits = sorted(DATA.glob(f"*/{name}")) if DATA.is_dir() else []
    return str(hits[0]) if hits else None


def _substitute(argv: list[str]) -> list[str]:
    argv = list(argv)
    if argv[:1] == ["run"] and not (len(argv) == 2 and argv[1] in FULL_SCALE):
        if "--quick" not in argv:
            argv.append("--quick")
        if "--runs" in argv:
            i = argv.index("--runs")
            argv[i + 1] = str(min(int(argv[i + 1]), 4))
            argv += ["--scheduler", "sync"] if "--scheduler" not in argv else []
    if argv[:1] == ["demo"]:
        argv = ["demo", "--quick", "--only", "static-alignment"] + (
            argv[argv.index("--out"):argv.index("--out") + 2] if "--out" in argv else [])
    out = []
    for w in argv:
        if w.lower().endswith(_DATA_SUFFIX) and not Path(w).exists():
            w = _data_file(w) or w
        out.append(w)
    return out


CASES = [(p, cmd, err) for p in DOCS for cmd, err in _commands(p)]


def test_the_docs_show_commands():
    assert len(CASES) >= 15
    docs = {p.name for p, _, _ in CASES}
    assert {"README.md", "cli.md", "recorded-data.md"} <= docs


#: (document, quoted text, command line of the run (as the docs show it), metrics, tolerance):
#: the text must appear in the document and equal the metrics of that run's summary.json,
#: (or claims' measured values, ``claim:ID``) number by number, within the quoted rounding
#: (half a unit of the last digit shown) plus the tolerance (absolute, in the text's units)
DRIVE = ("navigate --imu rtklib-drive/imu_1934.csv --fixes rtklib-drive/gnss_1934_sf.pos "
         "--mount rpy:180,-6.79,185.35 --frame frd --lever-arm '[-0.05, 0, 0] m' --time-sync auto "
         "--velocity-lag 0.125 --outages 15/60@40 --out runs/drive")
WALK = ('navigate --imu imu_1730.csv --format rtklib-imu --mount "rpy:180,0,-90" --frame frd '
        '--gnss-raw gnss_1730.ubx --init "course_speed=1 m/s,course_spread=10 deg" --out runs/walk-tc')
QUOTED = [
    ("raw-gnss.md", "461 of 461 epochs used, median 16 satellites, 7376 pseudoranges used and 0 rejected "
     "by the gate, 7373 range rates used and 3 rejected; 3439 observations without ephemeris", WALK,
     ["gnss_epochs_used", "gnss_epochs", "satellites_used_median", "pseudoranges_used",
      "pseudoranges_rejected", "doppler_used", "doppler_rejected", "observations_without_ephemeris"], 0.0),
    ("raw-gnss.md", "the means are 0.21 for the 7376 pseudoranges and 0.45 for the 7373 range rates", WALK,
     ["pseudorange_nis_mean", "pseudoranges_used", "doppler_nis_mean", "doppler_used"], 0.0),
    ("recorded-data.md", "pitch 0.15°, roll −0.28°, heading 61.70° (σ 0.23°)", DRIVE,
     ["final_pitch_deg", "final_roll_deg", "final_heading_deg", "final_sigma_heading_deg"], 0.0),
    ("recorded-data.md", "accelerometer bias [2153, 7695, 13470] µg", DRIVE, ["accel_bias_final_ug"], 0.0),
    ("recorded-data.md", "gyro bias [−251, 96, 591] °/h", DRIVE, ["gyro_bias_final_dph"], 0.0),
    ("recorded-data.md", "NIS 1.78 of 6", DRIVE, ["nis_mean", "nis_dof"], 0.0),
    ("README.md", "residual − limit φE 0.10′, φU 0.13′, εN 0.002 °/h", "run static-alignment",
     ["claim:margin_phiE", "claim:margin_phiU", "claim:margin_epsN"], 0.0),
    ("README.md", "reduced filter 1890 vs 7104 flops per step", "run static-alignment",
     ["flops_per_step_reduced", "flops_per_step_full"], 0.0),
    ("README.md", "initial-velocity response 84.35 min (theory 84.47)", "run free-inertial",
     ["schuler_period_min", "schuler_period_theory_min"], 0.0),
]


def _numbers(text: str) -> list[tuple[float, float]]:
    """The numbers of a quoted text with half a unit of their last digit (their rounding)."""
    out = []
    for x in re.findall(r"[−-]?\d+(?:\.\d+)?", text):
        dec = len(x.split(".")[1]) if "." in x else 0
        out.append((float(x.replace("−", "-")), 0.5 * 10.0 ** -dec))
    return out


def _run_doc(doc: Path, tmp_path, monkeypatch, commands=None):
    from sinslab.cli import app

    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    done = set()
    for cmd, err in (commands if commands is not None else _commands(doc)):
        words = shlex.split(cmd)
        words = words[1:]
        redirect = None
        if ">" in words:
            i = words.index(">")
            words, redirect = words[:i], words[i + 1]
        argv = _substitute(words)
        key = " ".join(argv)
        if key in done:
            continue
        done.add(key)
        missing = [w for w in argv if w.lower().endswith(_DATA_SUFFIX) and not Path(w).exists()]
        if missing:
            assert all(Path(w).name in ILLUSTRATIONS | EXTERNAL for w in missing), (
                f"{doc.name}: `{cmd}` names {missing}: no such file in the repository or the data folder")
            continue
        before = set(Path("runs").glob("*")) if Path("runs").is_dir() else set()
        r = runner.invoke(app, ["-q", *argv])
        if err is not None:
            assert r.exit_code == 2 and r.stderr.strip() == err, (doc.name, cmd, r.stderr)
            continue
        assert r.exit_code == 0, (doc.name, cmd, r.exit_code, r.stderr[-2000:], r.stdout[-2000:])
        if redirect:
            Path(redirect).write_text(r.stdout)
        out = argv[argv.index("--out") + 1] if "--out" in argv else None
        new = sorted(set(Path("runs").glob("*")) - before) if Path("runs").is_dir() else []
        folder = Path(out) if out else (new[-1] if new else None)
        if folder is not None and (folder / "summary.json").is_file():
            _SUMMARIES[key] = json.loads((folder / "summary.json").read_text())


@pytest.mark.parametrize("doc", sorted({p for p, _, _ in CASES}), ids=lambda p: p.name)
def test_every_command_in_the_docs_runs(doc, tmp_path, monkeypatch):
    if not DATA.is_dir():
        pytest.skip("shared data folder not available")
    _run_doc(doc, tmp_path, monkeypatch)


def test_every_help_example_runs(tmp_path, monkeypatch):
    """The example at the end of each command's ``--help`` (``sinslab.cli.EXAMPLES``) runs."""
    if not DATA.is_dir():
        pytest.skip("shared data folder not available")
    from sinslab.cli import EXAMPLES

    assert list(EXAMPLES).index("run") < list(EXAMPLES).index("report")   # report reads runs/fi
    _run_doc(ROOT / "src" / "sinslab" / "cli.py", tmp_path, monkeypatch,
             commands=[(c, None) for c in EXAMPLES.values()])


@pytest.mark.parametrize("name, quoted, run, keys, tol", QUOTED, ids=[f"{q[0]}:{q[1][:24]}" for q in QUOTED])
def test_numbers_quoted_from_runs(name, quoted, run, keys, tol, tmp_path, monkeypatch):
    """A number a document quotes from a run equals that run's summary.json."""
    doc = next(p for p in DOCS if p.name == name)
    text = " ".join(doc.read_text(encoding="utf-8").split())
    assert " ".join(quoted.split()) in text, f"{name} no longer quotes {quoted!r}: update QUOTED"
    key = " ".join(_substitute(shlex.split(run)))
    if key not in _SUMMARIES:                   # not run by the test above (run alone)
        if not DATA.is_dir():
            pytest.skip("shared data folder not available")
        _run_doc(doc, tmp_path, monkeypatch, commands=[("sinslab " + run, None)])
    s = _SUMMARIES[key]
    got = []
    for k in keys:                              # a metric, or claim:ID (its measured value)
        v = (next(c for c in s["claims"] if c["id"] == k[6:])["measured"]["value"]
             if k.startswith("claim:") else s["metrics"][k])
        got += v if isinstance(v, list) else [v]
    want = _numbers(quoted)
    assert len(want) == len(got), (quoted, got)
    bad = [(w, g) for (w, r), g in zip(want, got) if abs(w - g) > tol + r + 1e-12]
    assert not bad, f"{name}: {quoted!r} against the run: {got} (tolerance {tol})"
