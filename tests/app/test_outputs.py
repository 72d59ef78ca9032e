"""Atomic writes and run-folder rules."""
import json

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
    # a foreign non-empty folder is refused, without writing anything
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "thesis.tex").write_text("mine")
    with pytest.raises(OutputDirError, match="not a previous sinslab run"):
        RunDir(foreign, "x").prepare()
    assert [x.name for x in foreign.iterdir()] == ["thesis.tex"]
    # a file is refused
    f = tmp_path / "afile"
    f.write_text("")
    with pytest.raises(OutputDirError, match="is a file"):
        RunDir(f, "x").check()


def test_previous_run_is_overwritten_but_user_files_kept(tmp_path):
    d = tmp_path / "run"
    rd = RunDir(d, "x").prepare()
    rd.write_text("old_only.txt", "stale")
    rd.write_json("summary.json", {"a": 1})
    rd.finish()
    (d / "notes_by_user.txt").write_text("keep me")
    (d / ".summary.json.tmp-1-abc").write_text("left by a killed run")
    marker = json.loads((d / MARKER).read_text())
    assert marker["status"] == "complete" and "old_only.txt" in marker["files"]
    rd2 = RunDir(d, "x").prepare()
    names = sorted(x.name for x in d.iterdir())
    assert names == sorted([MARKER, "notes_by_user.txt"])
    assert json.loads((d / MARKER).read_text())["status"] == "running"
    rd2.write_text("summary.json", "{}")
    rd2.finish()


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
