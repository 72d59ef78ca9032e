"""Atomic writes and run-folder rules."""
import json
import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from sinslab.app import outputs
from sinslab.app.outputs import MARKER, OutputDirError, RunDir
from sinslab.core.atomic import atomic_path, atomic_write


def test_atomic_write_replaces_whole_file(tmp_path):
    p = tmp_path / "f.txt"
    atomic_write(p, "old")
    atomic_write(p, "new content")
    assert p.read_text() == "new content"
    assert [x.name for x in tmp_path.iterdir()] == ["f.txt"]


@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_interrupted_writer_leaves_old_file_and_no_temp(tmp_path, exc):
    p = tmp_path / "f.txt"
    atomic_write(p, "complete old")
    with pytest.raises(exc):
        with atomic_path(p) as tmp:
            tmp.write_text("half writ")
            raise exc()
    assert p.read_text() == "complete old"
    assert [x.name for x in tmp_path.iterdir()] == ["f.txt"]
    q = tmp_path / "g.txt"
    with pytest.raises(exc):
        with atomic_path(q) as tmp:
            tmp.write_text("half")
            raise exc()
    assert not q.exists()


def test_to_jsonable():
    obj = {"a": np.float64(1.5), "b": np.array([1.0, np.nan]), "c": np.int32(3), "d": float("inf"),
           "e": (np.bool_(True),)}
    assert json.loads(outputs.dumps_json(obj)) == {"a": 1.5, "b": [1.0, None], "c": 3, "d": None,
                                                   "e": [True]}


def test_run_dir_rules(tmp_path):
    # new folder and empty existing folder: fine
    RunDir(tmp_path / "new", "x").prepare()
    (tmp_path / "empty").mkdir()
    rd = RunDir(tmp_path / "empty", "x").prepare()
    assert (rd.path / MARKER).is_file()
    rd.finish()
    assert (tmp_path / "empty" / MARKER).is_file()
    # a foreign non-empty folder is refused, without writing anything
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("mine")
    with pytest.raises(OutputDirError, match="not a previous sinslab run.*--force"):
        RunDir(foreign, "x").prepare()
    assert [x.name for x in foreign.iterdir()] == ["thesis.tex"]
    # a file is refused
    f = tmp_path / "afile"
    f.write_text("")
    with pytest.raises(OutputDirError, match="is a file"):
        RunDir(f, "x").check()


def test_run_replaces_previous_run_only_when_finished(tmp_path):
    d = tmp_path / "run"
    rd = RunDir(d, "x").prepare()
    assert not d.exists()                        # written in a staging folder next to it
    rd.write_text("old_only.txt", "stale")
    rd.write_json("summary.json", {"a": 1})
    rd.finish()
    marker = json.loads((d / MARKER).read_text())
    assert marker["status"] == "complete" and marker["experiment"] == "x"
    assert "old_only.txt" in marker["files"]
    (d / ".summary.json.tmp-1-abc").write_text("left by a killed writer")
    before = {p.name: p.read_bytes() for p in d.iterdir()}
    rd2 = RunDir(d, "x").prepare()
    rd2.write_text("summary.json", "{}")
    assert {p.name: p.read_bytes() for p in d.iterdir()} == before    # untouched until finish
    rd2.finish()
    assert sorted(p.name for p in d.iterdir()) == [MARKER, "summary.json"]
    assert [p.name for p in tmp_path.iterdir()] == ["run"]


def test_run_dir_refuses_other_runs_and_foreign_files(tmp_path):
    d = tmp_path / "run"
    rd = RunDir(d, "x").prepare()
    rd.write_text("a.txt", "a")
    rd.finish()
    with pytest.raises(OutputDirError, match="holds a run of `x`, not `y`"):
        RunDir(d, "y").check()
    with pytest.raises(OutputDirError, match="holds a run of `run x`, not `navigate`"):
        RunDir(_remark(d, "run"), "navigate", command="navigate").check()
    (d / "thesis.tex").write_text("mine")
    with pytest.raises(OutputDirError, match="'thesis.tex', not written by sinslab"):
        RunDir(d, "x", command="run").check()
    rd = RunDir(d, "x", force=True).prepare()
    rd.write_text("b.txt", "b")
    rd.finish()
    assert sorted(p.name for p in d.iterdir()) == [MARKER, "b.txt"]
    with pytest.raises(OutputDirError, match="never replaces"):
        RunDir(Path.cwd(), "x", force=True).check()


def _remark(d, command):
    m = json.loads((d / MARKER).read_text())
    m["command"] = command
    (d / MARKER).write_text(json.dumps(m))
    return d


def test_default_out_dir_unique_within_a_second(tmp_path):
    from sinslab.app.outputs import default_out_dir

    made = {default_out_dir("x", tmp_path) for _ in range(5)}
    assert len(made) == 5 and all(p.is_dir() for p in made)


def test_aborted_run_leaves_nothing(tmp_path):
    from sinslab.app.outputs import abort_all

    abort_all()                                  # runs other tests left open
    d = tmp_path / "a" / "b" / "run"
    rd = RunDir(d, "x").prepare()
    rd.write_text("a.txt", "a")
    assert abort_all() == [f"nothing was written to {d}"]
    assert list(tmp_path.iterdir()) == []


def test_abort_run_discards_that_run_alone(tmp_path):
    """Two runs being written by one process (a demo worker's threads): the one aborted by
    :func:`outputs.abort_run` is discarded, its folder as before; the other goes on and
    completes."""
    from sinslab.app.outputs import abort_all, abort_run

    abort_all()                                  # runs other tests left open
    failed, going = tmp_path / "failed", tmp_path / "going"
    a = RunDir(failed, "x").prepare()
    b = RunDir(going, "x").prepare()
    a.write_text("a.txt", "a")
    b.write_text("b.txt", "b")
    assert abort_run(failed) == f"nothing was written to {failed}"
    assert abort_run(tmp_path / "never") is None
    b.write_text("c.txt", "c")
    b.finish()
    assert not failed.exists()
    assert sorted(p.name for p in going.iterdir() if not p.name.startswith(".")) == ["b.txt", "c.txt"]
    assert abort_all() == []


def test_completed_since_tells_a_run_put_in_place_after_a_moment(tmp_path):
    """:func:`outputs.completed_since`: a complete run whose marker was written at or after
    the moment (whole seconds, as the marker keeps them) is new; one written before, a run
    still being written and a folder without a run are not."""
    import datetime as dt

    from sinslab.app.outputs import abort_all, completed_since

    abort_all()                                  # runs other tests left open
    before = dt.datetime.now()
    done = tmp_path / "done"
    RunDir(done, "x").prepare().finish()
    assert completed_since(done, before)
    assert not completed_since(done, dt.datetime.now() + dt.timedelta(seconds=2))
    writing = RunDir(tmp_path / "writing", "x").prepare()
    assert not completed_since(writing.path, before)
    assert not completed_since(tmp_path / "none", before)
    abort_all()


def test_abort_removes_staging_of_processes_gone_and_forgets_runs_completed_elsewhere(tmp_path):
    """An abort also removes the staging folders next to its folders that processes which
    no longer run left (a demo's Dask workers, stopped with the demo); a live process's is
    kept. A folder another process completed (:func:`outputs.completed_elsewhere`) is not
    reported as holding the previous run."""
    import subprocess
    import sys

    from sinslab.app.outputs import abort_all, completed_elsewhere

    abort_all()                                  # runs other tests left open
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    run, done = tmp_path / "run", tmp_path / "done"
    for d in (run, done):
        RunDir(d, "x").prepare().finish()
    dead = tmp_path / f".run.sinslab-staging-{gone}-abc123"
    alive = tmp_path / f".run.sinslab-staging-{os.getppid()}-def456"
    for st in (dead, alive):
        st.mkdir()
        (st / "config.toml").write_text("x")
    RunDir(run, "x").check()
    RunDir(done, "x").check()
    completed_elsewhere(done)
    assert abort_all() == [f"{run} still holds the previous run, unchanged"]
    assert not dead.exists() and alive.is_dir()


def test_tables_csv_and_parquet(tmp_path):
    rd = RunDir(tmp_path / "r", "x").prepare()
    small = rd.write_table("small", {"t_s": np.arange(10.0), "x": np.arange(10) ** 2})
    assert small["parquet"] is None and small["csv_every"] == 1
    assert pd.read_csv(rd.path / "small.csv")["x"].tolist() == [i * i for i in range(10)]
    big = rd.write_table("big", pd.DataFrame({"t_s": np.arange(2500.0)}), large_rows=1000)
    assert big["parquet"] == "big.parquet" and big["csv_every"] == 3
    assert len(pd.read_parquet(rd.path / "big.parquet")) == 2500
    assert len(pd.read_csv(rd.path / "big.csv")) == 834


def test_figures_png_and_svg(tmp_path):
    from matplotlib.figure import Figure

    rd = RunDir(tmp_path / "r", "x").prepare()
    fig = Figure()
    fig.subplots().plot([0, 1], [1, 0])
    info = rd.write_figure("f", fig, "cap")
    assert (rd.path / "f.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert b"<svg" in (rd.path / "f.svg").read_bytes()[:500]
    assert info["caption"] == "cap"
