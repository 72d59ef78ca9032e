"""A run folder is a transaction: interrupted or killed at any point, a run leaves the
previous run in its ``--out`` folder byte for byte, and nothing of its own under a final
name; the message says what the folder holds.

Each case starts ``sinslab run dummy`` in a subprocess into a copy of a completed run,
stops it at a known point (the ``SINSLAB_PAUSE_AT`` hook of :mod:`sinslab.app.outputs`,
or the experiment's own sleep for "during computation") and sends SIGINT, SIGTERM or
SIGKILL. The children run concurrently to keep the test short.
"""
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

import sinslab.experiments as E
from sinslab.cli import app

HERE = Path(__file__).resolve().parent
SRC = HERE.parents[1] / "src"

_CHILD = """
import signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)   # as under a terminal, even if
sys.path.insert(0, {here!r})                               # started with SIGINT ignored
import sinslab.experiments as E, test_cli
E.register(test_cli.Dummy)
from sinslab.cli import main
sys.argv = ["sinslab"] + sys.argv[1:]
main()
"""

# (where the run is stopped, signal): before any staging, during computation, with three
# files staged, with the complete run staged just before the swap
POINTS = [("checked", signal.SIGINT), ("compute", signal.SIGTERM), ("compute", signal.SIGKILL),
          ("write:3", signal.SIGINT), ("write:3", signal.SIGKILL), ("swap", signal.SIGTERM),
          ("swap", signal.SIGINT), ("swap", signal.SIGKILL)]


def snapshot(d):
    return {p.relative_to(d).as_posix(): hashlib.sha1(p.read_bytes()).hexdigest()
            for p in sorted(Path(d).rglob("*")) if p.is_file()}


def _start(out, point):
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONPATH=os.pathsep.join(
        [str(SRC), os.environ.get("PYTHONPATH", "")]))
    args = ["run", "dummy", "--out", str(out), "--set", "scenario.rows=40"]
    if point == "compute":
        args += ["--set", "scenario.sleep_s=60"]
    else:
        env["SINSLAB_PAUSE_AT"] = point
    return subprocess.Popen([sys.executable, "-c", _CHILD.format(here=str(HERE)), "-q", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True)


def _reached(p, out, point):
    """True once the child stands at ``point``."""
    if point == "compute":
        return any((s / "config.toml").is_file() for s in out.parent.glob(f".{out.name}.sinslab-staging-*"))
    return False


def test_interrupted_or_killed_runs_leave_the_previous_run_intact(tmp_path):
    import test_cli

    E.register(test_cli.Dummy)
    base = tmp_path / "base"
    r = CliRunner().invoke(app, ["-q", "run", "dummy", "--quick", "--out", str(base)])
    assert r.exit_code == 0, r.stderr
    before = snapshot(base)
    assert ".sinslab-run" in before and "summary.json" in before

    kids = []
    for i, (point, sig) in enumerate(POINTS):
        d = tmp_path / f"case{i}"
        d.mkdir()
        shutil.copytree(base, d / "out")
        kids.append((point, sig, d / "out", _start(d / "out", point)))
    for point, sig, out, p in kids:
        deadline = time.time() + 120
        if point == "compute":
            while not _reached(p, out, point):
                assert p.poll() is None, p.communicate(timeout=30)
                assert time.time() < deadline, f"never reached {point}"
                time.sleep(0.05)
        else:
            line = p.stderr.readline()                   # "sinslab: paused at POINT"
            if f"paused at {point}" not in line:
                p.kill()
                pytest.fail(f"{point}: {line}{p.communicate(timeout=30)[1]}")
        p.send_signal(sig)
    for point, sig, out, p in kids:
        _, err = p.communicate(timeout=120)
        case = f"{point} {signal.Signals(sig).name}: {err[-500:]}"
        assert snapshot(out) == before, case             # the previous run, byte for byte
        staging = list(out.parent.glob(".out.sinslab-staging-*"))
        if sig == signal.SIGKILL:
            assert p.returncode == -signal.SIGKILL, case
        else:
            assert p.returncode == (130 if sig == signal.SIGINT else 143), case
            lines = [ln for ln in err.splitlines() if ln.strip()]
            word = "interrupted" if sig == signal.SIGINT else "terminated"
            assert lines[-1] == f"sinslab: error: {word}; {out} still holds the previous run, unchanged", case
            assert "Traceback" not in err, case
            assert staging == [], case                   # cleaned on the way out
    # a killed run's staging folder does not block, nor survive, the next run
    point, sig, out, p = kids[-1]
    r = CliRunner().invoke(app, ["-q", "run", "dummy", "--quick", "--out", str(out), "--seed", "5"])
    assert r.exit_code == 0, r.stderr
    assert sorted(x.name for x in out.parent.iterdir()) == ["out"]
    assert snapshot(out) != before and (out / "summary.json").is_file()


@pytest.mark.parametrize("sig", [signal.SIGINT])
def test_interrupt_into_a_new_folder_leaves_nothing(tmp_path, sig):
    out = tmp_path / "new" / "out"
    p = _start(out, "write:3")
    assert "paused at write:3" in p.stderr.readline()
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130
    assert err.strip().splitlines()[-1] == f"sinslab: error: interrupted; nothing was written to {out}"
    assert list(tmp_path.iterdir()) == []
