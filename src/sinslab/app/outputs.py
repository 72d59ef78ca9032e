"""Run folders and atomic file output.

Every file sinslab writes goes through :func:`atomic_write` (or :func:`atomic_path`):
the content is written to a hidden temporary name in the same folder, flushed, fsynced
and renamed over the final name with ``os.replace``. A run interrupted by Ctrl-C or
``kill`` therefore never leaves a half-written file under its final name (at worst a
hidden ``.NAME.tmp-*`` file, removed on a clean interrupt).

A run folder is marked by a ``.sinslab-run`` file (JSON: experiment, status, the list
of files the run wrote). :class:`RunDir` enforces the folder rules of every run folder:

- a folder that does not exist, or exists and is empty, is used as is;
- a folder holding a ``.sinslab-run`` marker is a previous run: the files listed in its
  marker are deleted and the new run is written in their place (files the user added
  are left alone);
- any other existing path is refused with :class:`OutputDirError`.

Time series: tables of up to ``LARGE_ROWS`` rows are written as CSV; larger ones as
Parquet (full resolution) plus a CSV of every k-th row (the summary records ``k``).
Figures are written as PNG and SVG.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import json
import math
import os
import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from sinslab.app import report
from sinslab.app.errors import UserError
from sinslab.core.atomic import atomic_path, atomic_write

__all__ = ["MARKER", "LARGE_ROWS", "OutputDirError", "atomic_write", "atomic_path",
           "to_jsonable", "dumps_json", "RunDir", "Figure", "default_out_dir", "is_run_dir"]

MARKER = ".sinslab-run"
LARGE_ROWS = 100_000


class OutputDirError(UserError):
    """An output folder that cannot be used (exists and is not a previous sinslab run)."""


# ---------------------------------------------------------------- JSON ------------------

def to_jsonable(obj: Any) -> Any:
    """Numpy scalars/arrays -> Python; non-finite floats -> None; paths -> str."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        f = float(obj)
        return f if math.isfinite(f) else None
    if isinstance(obj, Path):
        return str(obj)
    if obj is None or isinstance(obj, str):
        return obj
    if hasattr(obj, "model_dump"):
        return to_jsonable(obj.model_dump(mode="json"))
    return str(obj)


def dumps_json(obj: Any) -> str:
    return json.dumps(to_jsonable(obj), indent=2, ensure_ascii=False, allow_nan=False) + "\n"


# ---------------------------------------------------------------- run folders -----------

@dataclass
class Figure:
    """A matplotlib figure to save as ``name.png`` + ``name.svg`` and show in the report."""

    name: str
    fig: object
    caption: str = ""


def default_out_dir(name: str, root: str | os.PathLike = "runs") -> Path:
    """``runs/NAME-YYYYmmdd-HHMMSS`` (local time)."""
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    return Path(root) / f"{name}-{stamp}"


def is_run_dir(path: str | os.PathLike) -> bool:
    """True if ``path`` is a folder carrying a ``.sinslab-run`` marker."""
    return (Path(path) / MARKER).is_file()


def _read_marker(path: Path) -> dict:
    try:
        return json.loads((path / MARKER).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}


class RunDir:
    """The output folder of one run; all writes are atomic and recorded in the marker.

    ``RunDir(path, experiment).prepare()`` checks and claims the folder; then
    ``write_text``/``write_json``/``write_table``/``write_figure`` add files, and
    ``finish()`` marks the run complete.
    """

    def __init__(self, path: str | os.PathLike, experiment: str):
        self.path = Path(path)
        self.experiment = experiment
        self.files: list[str] = []
        self.series_info: list[dict] = []
        self.figure_files: list[dict] = []

    # -- folder rules
    def check(self) -> None:
        """Raise :class:`OutputDirError` if the folder may not be used (writes nothing)."""
        p = self.path
        if p.exists() and not p.is_dir():
            raise OutputDirError(f"output folder {p} exists and is a file, not a folder")
        if p.is_dir() and not is_run_dir(p) and any(p.iterdir()):
            raise OutputDirError(
                f"output folder {p} exists and is not a previous sinslab run "
                f"(no {MARKER} marker); choose another --out or empty it")

    def prepare(self) -> "RunDir":
        """Check the folder, delete a previous run's files, write the marker (status running)."""
        self.check()
        self.path.mkdir(parents=True, exist_ok=True)
        old = _read_marker(self.path) if is_run_dir(self.path) else {}
        for name in old.get("files", []):
            f = self.path / name
            if f.parent == self.path and f.is_file() and name != MARKER:
                f.unlink()
        for stale in self.path.glob(".*.tmp-*"):       # left by a killed run
            with contextlib.suppress(OSError):
                stale.unlink()
        self._write_marker("running")
        return self

    def _write_marker(self, status: str) -> None:
        marker = {"sinslab_run": 1, "experiment": self.experiment, "status": status,
                  "updated": _dt.datetime.now().isoformat(timespec="seconds"),
                  "files": sorted(set(self.files))}
        atomic_write(self.path / MARKER, json.dumps(marker, indent=2) + "\n")

    def finish(self) -> None:
        self._write_marker("complete")

    # -- writers
    def _record(self, name: str) -> Path:
        if "/" in name or name.startswith("."):
            raise ValueError(f"bad output file name {name!r}")
        self.files.append(name)
        return self.path / name

    def write_text(self, name: str, text: str) -> Path:
        return atomic_write(self._record(name), text)

    def write_bytes(self, name: str, data: bytes) -> Path:
        return atomic_write(self._record(name), data)

    def write_json(self, name: str, obj: Any) -> Path:
        return self.write_text(name, dumps_json(obj))

    def write_table(self, name: str, table, description: str = "",
                    large_rows: int = LARGE_ROWS, csv_every: int | None = None) -> dict:
        """Write a table (DataFrame or dict of 1-D arrays) as CSV, or Parquet + thinned CSV.

        ``csv_every``: always Parquet (full) + every ``csv_every``-th row as CSV, whatever
        the length. Returns (and records) ``{"name", "description", "rows", "columns",
        "csv", "parquet", "csv_every"}``.
        """
        import pandas as pd

        df = table if isinstance(table, pd.DataFrame) else pd.DataFrame(dict(table))
        info = {"name": name, "description": description, "rows": int(len(df)),
                "columns": [str(c) for c in df.columns], "csv": f"{name}.csv",
                "parquet": None, "csv_every": 1}
        if len(df) > large_rows or csv_every is not None:
            every = int(math.ceil(len(df) / large_rows)) if csv_every is None else max(1, int(csv_every))
            with atomic_path(self._record(f"{name}.parquet")) as tmp:
                df.to_parquet(tmp, index=False)
            info["parquet"] = f"{name}.parquet"
            info["csv_every"] = every
            df = df.iloc[::every]
        with atomic_path(self._record(f"{name}.csv")) as tmp:
            df.to_csv(tmp, index=False, float_format="%.10g")
        self.series_info.append(info)
        return info

    def write_figure(self, name: str, fig, caption: str = "", dpi: int = 110) -> dict:
        """Save a matplotlib figure as ``name.png`` and ``name.svg`` (and close it if pyplot owns it)."""
        info = {"name": name, "caption": caption, "png": f"{name}.png", "svg": f"{name}.svg"}
        try:
            with atomic_path(self._record(info["png"])) as tmp:
                fig.savefig(tmp, format="png", dpi=dpi, bbox_inches="tight")
            with atomic_path(self._record(info["svg"])) as tmp:
                fig.savefig(tmp, format="svg", bbox_inches="tight")
        finally:
            if getattr(fig.canvas, "manager", None) is not None:
                import matplotlib.pyplot as plt
                plt.close(fig)
        self.figure_files.append(info)
        return info

    def complete(self, summary: dict) -> dict:
        """Write ``summary.json`` and ``report.html`` and mark the run complete (the last
        step of every run: experiments and the ``align``/``allan``/``navigate`` commands)."""
        self.write_json("summary.json", summary)
        self.write_text("report.html", report.render(self.path))
        self.finish()
        return summary
