"""Publishing a run is a transaction under every signal: SIGINT, SIGTERM or SIGKILL at any
point from the start of a run to the exit of its process leaves ``--out`` holding either
the previous run, byte for byte, or the complete new one, and the message says which.

Each case is one ``sinslab run`` stopped at a known point (the ``SINSLAB_PAUSE_AT`` hook
of :func:`sinslab.app.errors.pause`, or the experiment's own sleep for "during
computation") and sent a signal. The cases run concurrently, each in a process forked
from one launcher that has imported sinslab once (a case then costs its run, not the
imports); the Dask cases start a one-worker local cluster of their own.

Before the exchange of the folders the previous run must survive (exit 130/143, "still
holds the previous run, unchanged"); from the exchange on the new run is in place and the
command reports success (exit 0, "holds the completed run"). A signal raised inside a
garbage-collector callback (where distributed hooks one in) must not be swallowed.
"""
import contextlib
import gc
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import sinslab.experiments as E
from sinslab.app.errors import pause
from sinslab.cli import app
from sinslab.experiments.base import (Claim, ExperimentConfig, Field, Figure, Metric, Result,
                                      Section, Table)

HERE = Path(__file__).resolve().parent
SRC = HERE.parents[1] / "src"


# ------------------------------------------------------------ the experiment stopped ----
class _Scenario(Section):
    rows: int = Field(40, ge=2)
    sleep_s: float = Field(0.0, ge=0)


class _Config(ExperimentConfig):
    scenario: _Scenario = _Scenario()


def _campaign(seeds):
    return np.array([np.random.default_rng(s).normal() for s in seeds])


#: set by the run just before its garbage collection: the test's collector callback pauses then
_ARMED = []


def _run(cfg, ctx):
    from sinslab.app import plotting as P
    from sinslab.estimation.montecarlo import run_campaign

    t = np.linspace(0.0, 10.0, cfg.scenario.rows)
    x = np.sin(t) + ctx.rng(1).normal(size=t.size) * 1e-3
    time.sleep(cfg.scenario.sleep_s)
    _ARMED.append(True)
    gc.collect()
    mc = None
    if cfg.runs > 1:                       # a campaign on the Dask cluster of --workers
        mc = run_campaign(_campaign, cfg.runs, cfg.seed, scheduler=ctx.scheduler, progress=False)
        pause("campaign")
    figs = [Figure(n, P.error_figure(t, [("x [m]", np.c_[x, -x], ["x", "-x"])]), n) for n in ("wave", "neg")]
    return Result(metrics={"final_x_m": float(x[-1]), "mc_mean": None if mc is None else float(mc.mean())},
                  claims=[Claim.at_most("small", "|x| stays below 2 m", float(np.abs(x).max()), 2.0, "m")],
                  series={"wave": {"t_s": t, "x_m": x}, "wave2": {"t_s": t, "y_m": -x}},
                  figures=figs, tables=[Table("stats", {"stat": ["mean"], "value": [float(x.mean())]}, "stats")])


class Signals:
    """The experiment of these tests: tables, two figures, a campaign with runs > 1."""

    NAME = "signals"
    PURPOSE = "test experiment for interrupts"
    Config = _Config
    METRICS = {"final_x_m": Metric("m", "last x"), "mc_mean": Metric("-", "campaign mean")}
    run = staticmethod(_run)


# ------------------------------------------------------------ the launcher --------------
_LAUNCHER = """
import json, os, signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)    # as under a terminal
sys.path[:0] = [{here!r}]
import test_interrupts as T
T.preload()
cases = json.loads(sys.argv[1])
sys.stdout.flush()
pids = {{}}
for c in cases:
    pid = os.fork()
    if pid == 0:
        try:
            T.child(c)
        finally:                   # never back into this loop: a child must not fork or report
            os._exit(3)
    pids[pid] = c["id"]
print(json.dumps({{i: p for p, i in pids.items()}}), flush=True)
status = {{}}
while pids:
    pid, st = os.wait()
    status[pids.pop(pid)] = os.waitstatus_to_exitcode(st)
print(json.dumps(status), flush=True)
"""


def preload():
    """What every case needs, imported once in the launcher before it forks."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot  # noqa: F401

    import sinslab.app.plotting  # noqa: F401
    import sinslab.app.report  # noqa: F401
    import sinslab.estimation.montecarlo  # noqa: F401
    E.register(Signals)


def child(case):
    """One case in a forked process: its stdio in files, its pause point, the CLI's main."""
    d = Path(case["dir"])
    for fd, name in ((1, "stdout"), (2, "stderr")):
        f = os.open(d / name, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        os.dup2(f, fd)
        os.close(f)
    if case["point"] == "gc":
        def stop_in_collector(phase, info):
            if phase == "start" and _ARMED:
                _ARMED.clear()
                pause("gc")
        gc.callbacks.append(stop_in_collector)
    os.environ["SINSLAB_PAUSE_AT"] = case["point"] if case["point"] != "compute" else ""
    from sinslab.cli import main

    sys.argv = ["sinslab", "-q", *case["argv"]]
    code = 3
    try:
        main()
    except SystemExit as e:
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


# ------------------------------------------------------------ the cases -----------------
OLD, NEW = "previous run", "new run"
#: (point, signals, folder afterwards) in the order a run reaches them; "dask:" points run
#: a 3-run campaign on a one-worker local cluster
POINTS = [
    ("checked", "INT TERM KILL", OLD),          # folder checked, nothing staged
    ("compute", "INT TERM KILL", OLD),          # computing (the experiment sleeps)
    ("gc", "INT TERM", OLD),                    # inside a garbage-collector callback
    ("dask:campaign", "TERM", OLD),             # just after the Monte Carlo campaign
    ("write:3", "INT TERM KILL", OLD),          # tables being written
    ("figures", "INT TERM KILL", OLD),          # figures being drawn by the worker processes
    ("swap", "INT TERM KILL", OLD),             # complete in staging, before the exchange
    ("exchange", "INT TERM KILL", NEW),         # folders exchanged, signals held
    ("published", "INT TERM KILL", NEW),        # in place, the previous run not yet deleted
    ("dask:published", "INT", NEW),             # in place, the Dask cluster still up
    ("summary", "INT TERM KILL", NEW),          # before the summary is printed
    ("exit", "INT TERM KILL", NEW),             # the interpreter exiting
]
CASES = [(p, s, want) for p, sigs, want in POINTS for s in sigs.split()]


def snapshot(d):
    return {p.relative_to(d).as_posix(): hashlib.sha1(p.read_bytes()).hexdigest()
            for p in sorted(Path(d).rglob("*")) if p.is_file()}


def _complete_new_run(out, before):
    marker = json.loads((out / ".sinslab-run").read_text())
    names = {p.name for p in out.iterdir()}
    return (marker["status"] == "complete" and names == set(marker["files"]) | {".sinslab-run"}
            and "summary.json" in names and snapshot(out) != before)


def _wait_for(path, text, proc, deadline):
    while text not in (path.read_text() if path.exists() else ""):
        if proc.poll() is not None or time.time() > deadline:
            return False
        time.sleep(0.02)
    return True


def test_signals_at_every_point_leave_the_old_or_the_complete_new_run(tmp_path):
    E.register(Signals)
    base = tmp_path / "base"
    r = CliRunner().invoke(app, ["-q", "run", "signals", "--out", str(base)])
    assert r.exit_code == 0, r.stderr
    before = snapshot(base)
    cases = []
    for i, (point, sig, want) in enumerate(CASES):
        d = tmp_path / f"case{i}"
        d.mkdir()
        shutil.copytree(base, d / "out")
        argv = ["run", "signals", "--out", str(d / "out"), "--seed", "7"]
        if point == "compute":
            argv += ["--set", "scenario.sleep_s=60"]
        if point.startswith("dask:"):
            argv += ["--runs", "3", "--workers", "1"]
        cases.append({"id": str(i), "dir": str(d), "point": point.removeprefix("dask:"), "argv": argv})
    env = dict(os.environ, MPLBACKEND="Agg", OPENBLAS_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(SRC), str(HERE), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-c", _LAUNCHER.format(here=str(HERE)), json.dumps(cases)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, text=True)
    try:
        pids = json.loads(proc.stdout.readline() or "{}")
        assert len(pids) == len(cases), proc.communicate(timeout=30)[1][-3000:]
        assert all(isinstance(p, int) and p > 1 for p in pids.values()), pids     # never kill(0)
        deadline = time.time() + 240
        for c, (point, sig, want) in zip(cases, CASES):
            d = Path(c["dir"])
            if point == "compute":          # staged its config: computing, asleep
                while not list(d.glob(".out.sinslab-staging-*/config.toml")):
                    assert time.time() < deadline, f"{point}: never started computing"
                    time.sleep(0.05)
            else:
                ok = _wait_for(d / "stderr", f"paused at {c['point']}", proc, deadline)
                assert ok, f"{point}: never paused: {(d / 'stderr').read_text()[-2000:]}"
            os.kill(pids[c["id"]], getattr(signal, f"SIG{sig}"))
        out, err = proc.communicate(timeout=120)
        status = json.loads(out.strip() or "{}")
    finally:
        if proc.poll() is None:
            for pid in pids.values():
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
            proc.kill()
    table = []
    for c, (point, sig, want) in zip(cases, CASES):
        d, out = Path(c["dir"]), Path(c["dir"]) / "out"
        err = (d / "stderr").read_text()
        lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("sinslab: paused")]
        case = f"{point} SIG{sig}: exit {status.get(c['id'])}; {lines[-1:] or ''}"
        table.append(case)
        assert "Traceback" not in err and "Exception ignored" not in err, case + err[-2000:]
        if want == OLD:
            assert snapshot(out) == before, case
        else:
            assert _complete_new_run(out, before), case
        if sig == "KILL":
            assert status[c["id"]] == -signal.SIGKILL, case
            continue
        word = "interrupted" if sig == "INT" else "terminated"
        if want == OLD:
            assert status[c["id"]] == (130 if sig == "INT" else 143), case
            assert lines[-1] == f"sinslab: error: {word}; {out} still holds the previous run, unchanged", case
        elif point == "exit":                       # done and said so: the exit is quick and quiet
            assert status[c["id"]] == 0 and lines == [], case
            assert "claims passed" in (d / "stdout").read_text(), case
        else:
            assert status[c["id"]] == 0, case
            assert lines[-1] == f"sinslab: {word} after the run was complete; {out} holds the completed run", case
        # cleaned on the way out: no staging folder, no replaced run, no kept campaign
        assert sorted(p.name for p in d.iterdir()) == ["out", "stderr", "stdout"], case
    print("\n".join(table))


def test_a_killed_runs_leftovers_do_not_block_the_next_run(tmp_path):
    """A staging folder and a replaced run left by a SIGKILLed process (here made by hand
    under a dead process id) are removed by the next run next to them."""
    E.register(Signals)
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["-q", "run", "signals", "--out", str(out)])
    assert r.exit_code == 0, r.stderr
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    for name in (f".out.sinslab-staging-{dead}-abc123", f".out.sinslab-staging-old-{dead}-abc123"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "summary.json").write_text("{}")
    r = CliRunner().invoke(app, ["-q", "run", "signals", "--out", str(out), "--seed", "5"])
    assert r.exit_code == 0, r.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["out"]


def test_interrupt_into_a_new_folder_leaves_nothing(tmp_path):
    out = tmp_path / "new" / "out"
    env = dict(os.environ, MPLBACKEND="Agg", SINSLAB_PAUSE_AT="write:3",
               PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
    child = ("import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
             f"sys.path.insert(0, {str(HERE)!r}); import sinslab.experiments as E, test_interrupts as T; "
             "E.register(T.Signals); from sinslab.cli import main; sys.argv = ['sinslab'] + sys.argv[1:]; main()")
    p = subprocess.Popen([sys.executable, "-c", child, "-q", "run", "signals", "--out", str(out)],
                         stderr=subprocess.PIPE, env=env, text=True)
    assert "paused at write:3" in p.stderr.readline()
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130
    assert err.strip().splitlines()[-1] == f"sinslab: error: interrupted; nothing was written to {out}"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("out", [".", ""])
def test_the_current_folder_is_refused_before_any_work(tmp_path, monkeypatch, out):
    """``--out .`` (or ``''``) in an empty folder: a run is put in place by exchanging
    whole folders, which the current folder cannot be; refused at once, not after the run."""
    E.register(Signals)
    monkeypatch.chdir(tmp_path)
    r = CliRunner().invoke(app, ["-q", "run", "signals", "--out", out])
    assert r.exit_code == 2, r.output
    assert r.stderr.startswith("sinslab: error: output folder . is the current folder") \
        and r.stderr.count("\n") == 1, r.stderr
    assert list(tmp_path.iterdir()) == []


def _library_that_swallows_everything(signum):
    """Stands in for C code that clears any error (a dict lookup calling ``__eq__``, an
    extension's callback): the interrupt's exception is raised inside it and lost."""
    try:
        signal.raise_signal(signum)
    except BaseException:
        pass


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["INT", "TERM"])
def test_an_interrupt_whose_exception_was_lost_still_stops_the_commit(tmp_path, sig, code):
    """The handler's exception dies in a library and the run goes on to its end: the commit
    raises the interrupt instead of replacing the previous run; the next command is not
    interrupted by it."""
    import typer

    from sinslab.app.errors import user_errors
    from sinslab.app.outputs import RunDir

    out = tmp_path / "out"
    # the dispositions of a command started from a terminal: what this test process
    # inherited, or an earlier test left, may be another (an ignored SIGINT, which sinslab
    # leaves ignored on purpose, as in a background job)
    start = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        with user_errors():
            rd = RunDir(out, "x").prepare()
            rd.write_text("a.txt", "old\n")
            rd.finish()
        before = snapshot(out)
        seen = []
        try:
            with user_errors():
                rd = RunDir(out, "x").prepare()
                rd.write_text("a.txt", "new\n")
                seen.append(signal.getsignal(sig))
                _library_that_swallows_everything(sig)
                rd.finish()
        except typer.Exit as e:
            exit_code = e.exit_code
        else:
            pytest.fail(f"the run was committed; handler in the block {seen}, at the test's start {start}")
    finally:
        for s, h in start.items():
            signal.signal(s, h)
    assert exit_code == code
    assert snapshot(out) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    with user_errors():
        rd = RunDir(out, "x").prepare()
        rd.write_text("a.txt", "newer\n")
        rd.finish()
    assert (out / "a.txt").read_text() == "newer\n"
