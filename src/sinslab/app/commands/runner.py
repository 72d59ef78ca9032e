"""The run contract of the recorded-data commands (``navigate``, ``allan``, ``align``).

The commands' counterpart of :func:`sinslab.experiments.execute`. A command is a
:class:`Command` (name, purpose, the method it applies) and a compute function that reads
the input files, runs the method, prints its lines and returns an :class:`Output`
(configuration, metrics, tables, figures, extra text files, notes) — it never writes a
file. :func:`run_command` does the rest, always in the same order:

1. check the output folder (``--out``, default ``runs/NAME-<timestamp>``) before any
   work, so an unusable folder fails in a second (:class:`~sinslab.app.outputs.OutputDirError`);
2. call the compute function;
3. claim the folder, write ``config.toml``, the extra text files, the tables (CSV, or
   Parquet + thinned CSV), the figures (PNG + SVG), ``summary.json``
   (:func:`command_summary`) and ``report.html``, each atomically, then mark the run
   complete.

:func:`cli_call` is the typer side: it runs a command inside
:func:`sinslab.app.errors.user_errors`, with a bad value or a missing file becoming the
one line ``sinslab: error: ...`` and exit status 2::

    ALLAN = Command("allan", "Allan deviation of a recorded IMU file")

    def allan_file(path, *, out=None, echo=print):
        def compute():
            ...
            return Output(config={...}, metrics={...}, tables=[Series(...)], figures=[...])
        summary, _ = run_command(ALLAN, out, compute, echo=echo)
        return summary

    @app.command()
    def allan(file: Path, out: Optional[Path] = None):
        cli_call(allan_file, file, out=out, echo=typer.echo)
"""
from __future__ import annotations

import contextvars
import datetime as _dt
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from sinslab import __version__
from sinslab.app.errors import CliError, user_errors
from sinslab.app.outputs import Figure, RunDir, default_out_dir, forcing
from sinslab.app.publish import complete_timed, write_figures
from sinslab.core.blocks import release_free_memory
from sinslab.core.progress import stage
from sinslab.core.toml import dump_toml

__all__ = ["Command", "Output", "Series", "Figure", "run_command", "command_summary", "cli_call",
           "scratch_dir"]


@dataclass(frozen=True)
class Command:
    """A recorded-data command: its CLI name, one-line purpose, and the method it applies
    (bibliographic reference, printed in the report; empty when none)."""

    name: str
    purpose: str
    paper: str = ""


@dataclass
class Series:
    """A table to write as ``name.csv`` (Parquet + every k-th row as CSV when large).

    ``data`` is a pandas DataFrame or a dict of equal-length 1-D arrays. ``csv_every``:
    always write the full table as Parquet and every ``csv_every``-th row as CSV (the
    same files whatever the length).
    """

    name: str
    data: Any
    description: str = ""
    csv_every: int | None = None


@dataclass
class Output:
    """What a command's compute function returns; :func:`run_command` writes it.

    config : the command's inputs as a flat TOML-able dict (``config.toml``, and the
        ``config`` of ``summary.json``).
    metrics : ``{name: number | list | None}`` for ``summary.json``.
    tables : :class:`Series` to write, in order.
    figures : :class:`~sinslab.app.outputs.Figure` to write, in order.
    files : ``{file name: text}`` extra text files (e.g. an ``imu_errors.toml`` block).
    notes : lines for the report.
    value : anything the Python function returns besides the summary (the estimates).
    """

    config: dict
    metrics: dict
    tables: list = field(default_factory=list)
    figures: list = field(default_factory=list)
    files: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    value: Any = None
    #: :class:`sinslab.experiments.base.Claim` s the command checked (none: no claims section)
    claims: list = field(default_factory=list)
    #: plausibility warnings about the data or the run (:mod:`sinslab.app.plausibility`),
    #: already printed; ``summary.json`` ``warnings`` and a flagged list in the report
    warnings: list = field(default_factory=list)
    #: ``(regex, description)`` of metrics the command's plug-ins describe themselves
    descriptions: list = field(default_factory=list)
    #: what this run did, under the report's title (empty: the command's purpose)
    purpose: str = ""


def command_summary(rd: RunDir, command: str, purpose: str, config: dict, metrics: dict,
                    notes=(), claims=(), paper: str = "", timing: dict | None = None,
                    warnings=(), descriptions=()) -> dict:
    """The ``summary.json`` of a command: the keys of every run folder (``experiment``,
    ``sinslab_version``, ``config``, ``metrics``, ``claims``) plus what the report needs
    (units and descriptions of the metrics, the command line that re-runs it)."""
    from sinslab.app.described import invocation, metric_info

    return {"experiment": command, "kind": "command", "sinslab_version": __version__,
            "config": config, "metrics": metrics,
            "claims": [c.as_dict() if hasattr(c, "as_dict") else c for c in claims],
            "purpose": purpose, "paper": paper,
            "quick": False, "started": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
            "metric_info": metric_info(command, metrics, descriptions), "figures": rd.figure_files,
            "series": rd.series_info, "tables": [], "notes": list(notes),
            "warnings": list(warnings),
            "rerun": invocation(), "timing": timing or {}}


def _close(figures) -> None:
    import matplotlib.pyplot as plt

    for f in figures:
        if getattr(f.fig.canvas, "manager", None) is not None:
            plt.close(f.fig)


def run_command(command: Command, out: str | os.PathLike | None, compute: Callable[[], Output],
                *, echo: Callable[[str], None] = print) -> tuple[dict, Output]:
    """Check ``out``, run ``compute()``, write the run folder; return ``(summary, output)``.

    ``out=None`` writes into ``runs/NAME-<timestamp>``. Raises
    :class:`~sinslab.app.outputs.OutputDirError` before computing anything if the folder
    may not be used; whatever ``compute`` raises propagates with nothing written.
    """
    out = Path(out) if out is not None else default_out_dir(command.name)
    rd = RunDir(out, command.name)
    rd.check()
    t0 = time.perf_counter()
    token = _SCRATCH.set(rd.scratch_path())
    try:
        # the whole computation is a stage: off a terminal a log shows the command alive
        # every 30 s even where no stage of its own runs (the stages inside it nest)
        with stage(f"{command.name}, computing"):
            res = compute()
    finally:
        _remove_scratch(_SCRATCH.get())
        _SCRATCH.reset(token)
    timing = {"compute_s": time.perf_counter() - t0}
    if not isinstance(res, Output):
        raise TypeError(f"the compute function of {command.name!r} must return an Output, "
                        f"got {type(res).__name__}")
    written = 0
    try:
        with stage(f"writing {out}"):
            rd.prepare()
            rd.write_text("config.toml", f"# sinslab {__version__} — {command.name}\n"
                          + dump_toml(res.config))
            for name, text in res.files.items():
                rd.write_text(name, text)
            t1 = time.perf_counter()
            release_free_memory()        # the compute's working set is gone: start the tables afresh
            for t in res.tables:
                if t.csv_every is None:
                    rd.write_table(t.name, t.data, t.description)
                else:
                    rd.write_table(t.name, t.data, t.description, csv_every=t.csv_every)
                release_free_memory()
            t2 = time.perf_counter()
            write_figures(rd, res.figures)
            written = len(res.figures)
            timing.update(series_s=t2 - t1, figures_s=time.perf_counter() - t2)
    finally:
        _close(res.figures[written:])
    summary = complete_timed(rd, command_summary(rd, command.name, res.purpose or command.purpose, res.config,
                                                 res.metrics, res.notes, res.claims,
                                                 paper=command.paper, timing=timing,
                                                 warnings=res.warnings, descriptions=res.descriptions))
    if summary.get("claims"):
        from sinslab.app.report import claim_texts

        for c in summary["claims"]:
            measured, expected = claim_texts(c)
            echo(f"  [{'pass' if c['passed'] else 'FAIL'}] {c['id']}: {measured} (expected {expected})")
    echo(f"  -> {out}")
    return summary, res


#: the scratch folder of the command computing in this context (:func:`scratch_dir`)
_SCRATCH: contextvars.ContextVar = contextvars.ContextVar("sinslab_scratch", default=None)


def scratch_dir() -> Path | None:
    """Where the command computing now may put temporary files (a record spilled to disk):
    a folder next to its run folder, on the disk the run is written to (not a RAM-backed
    ``/tmp``), created by whoever uses it first and removed, with whatever it holds, when
    the compute function returns or fails. None outside :func:`run_command`."""
    return _SCRATCH.get()


def _remove_scratch(path) -> None:
    import shutil

    if path is not None and os.path.isdir(path):
        shutil.rmtree(path, ignore_errors=True)


def cli_call(fn: Callable[..., Any], *args, force: bool = False, **kwargs) -> Any:
    """Call a command function for the CLI: user errors, bad values (``ValueError``) and
    missing files become one line and exit 2; Ctrl-C / SIGTERM exit 130 / 143.
    ``force``: the output folder may replace what it holds (``--force``)."""
    with user_errors(), forcing(force):
        try:
            return fn(*args, **kwargs)
        except (ValueError, FileNotFoundError) as e:
            raise CliError(str(e)) from None
