"""Run folders as transactions, and atomic file output.

A run never writes into its output folder directly. :meth:`RunDir.prepare` creates a
hidden staging folder next to it (``.NAME.sinslab-staging-PID-XXXXXX``), every file of
the run is written there (each one atomically, through :func:`atomic_write` /
:func:`atomic_path`), and :meth:`RunDir.finish` replaces the folder's previous contents
in one step: ``renameat2(RENAME_EXCHANGE)`` swaps the complete new folder with the old
one (two renames where the platform lacks it), then the old contents are deleted. So a
run that fails, is interrupted (SIGINT/SIGTERM) or killed (SIGKILL) at any moment leaves
the previous run in its folder complete and byte-for-byte unchanged, and nothing of its
own under a final name. Staging folders of killed processes are removed by the next run
next to them; those of failed or interrupted runs at once (:func:`abort_all`, called by
:func:`sinslab.app.errors.user_errors` and at interpreter exit).

A run folder is marked by a ``.sinslab-run`` file (JSON: command, experiment, status, the
files the run wrote). :meth:`RunDir.check` enforces the folder rules, before any work:

- a folder that does not exist, or exists and is empty, is used;
- a folder holding a previous run of the same command and experiment, and nothing else,
  is replaced when the new run completes;
- a folder holding another command's or experiment's run, files the run did not write,
  or no marker at all is refused (:class:`OutputDirError`) unless ``force=True``
  (``--force``), which replaces whatever it holds — except the current directory, one
  of its parents, the home folder or a git work tree, never replaced;
- a path under a file, or where a folder cannot be created, is refused.

The default output folder ``runs/NAME-YYYYmmdd-HHMMSS`` is created atomically by
:func:`default_out_dir` (``-2``, ``-3``, ... appended when runs start in the same second).

Time series: tables of up to ``LARGE_ROWS`` rows are written as CSV; larger ones as
Parquet (full resolution) plus a CSV of every k-th row (the summary records ``k``).
Figures are written as PNG and SVG.
"""
from __future__ import annotations

import contextlib
import contextvars
import datetime as _dt
import json
import math
import os
import atexit
import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from sinslab.app import report
from sinslab.app.errors import UserError, deferred_signals, on_abort, published, raise_pending_interrupt
from sinslab.core.atomic import atomic_path, atomic_write

__all__ = ["MARKER", "LARGE_ROWS", "OutputDirError", "abort_run", "atomic_write", "atomic_path",
           "to_jsonable", "dumps_json", "RunDir", "Figure", "default_out_dir", "is_run_dir",
           "abort_all", "completed_elsewhere", "completed_since", "forcing"]

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


_STAGING = ".sinslab-staging-"
#: commands whose runs carry their own name as experiment, for markers written before the
#: marker recorded the command
_OLD_COMMANDS = frozenset({"navigate", "allan", "align", "transfer-align"})
_FORCE = contextvars.ContextVar("sinslab_force", default=False)


@contextlib.contextmanager
def forcing(force: bool = True) -> Iterator[None]:
    """Within the block, :class:`RunDir` objects created without ``force`` take this value
    (how the CLI's ``--force`` reaches the command functions)."""
    tok = _FORCE.set(bool(force))
    try:
        yield
    finally:
        _FORCE.reset(tok)
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def default_out_dir(name: str, root: str | os.PathLike = "runs") -> Path:
    """Create and return ``runs/NAME-YYYYmmdd-HHMMSS`` (local time), unique.

    The folder is created with an exclusive ``mkdir``: a run started in the same second
    gets ``...-2``, ``...-3``; two processes can never share one. A run that then fails
    removes it again if it is still empty.
    """
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    root = Path(root)
    _check_parent(root / f"{name}-{stamp}")
    _check_not_in_run(root / f"{name}-{stamp}")
    made = [a for a in (root, *root.parents) if not a.exists()]
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputDirError(f"output folder {root}: cannot create it ({e.strerror or e})") from None
    for i in range(1, 10_000):
        p = root / (f"{name}-{stamp}" if i == 1 else f"{name}-{stamp}-{i}")
        try:
            p.mkdir()
        except FileExistsError:
            continue
        except OSError as e:
            raise OutputDirError(f"output folder {p}: cannot create it ({e.strerror or e})") from None
        _CREATED[p.absolute()] = made          # a failed run removes them again if still empty
        return p
    raise OutputDirError(f"output folder {root}: no free name {name}-{stamp}-N")


def is_run_dir(path: str | os.PathLike) -> bool:
    """True if ``path`` is a folder carrying a ``.sinslab-run`` marker."""
    return (Path(path) / MARKER).is_file()


def _read_marker(path: Path) -> dict:
    try:
        m = json.loads((path / MARKER).read_text(encoding="utf-8"))
        return m if isinstance(m, dict) else {}
    except (OSError, ValueError):
        return {}


def _check_parent(p: Path) -> None:
    """Refuse a folder path under a file or in a place where it cannot be created."""
    anc = p.parent
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        raise OutputDirError(f"output folder {p}: {anc} is a file, not a folder")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise OutputDirError(f"output folder {p}: cannot write in {anc} (permission denied)")


def _check_not_in_run(p: Path) -> None:
    """Refuse a folder inside another run's folder: the later run's files would sit among
    the first run's, and replacing either would take the other with it."""
    for anc in Path(os.path.abspath(p)).parents:
        if is_run_dir(anc):
            raise OutputDirError(f"output folder {p} is inside the run folder {anc} "
                                 f"(it holds a {MARKER} marker); choose an --out outside it")


def _check_replaceable(p: Path) -> None:
    """Refuse a folder that a completed run cannot take the place of: the current folder
    or one of its parents (``--out .`` or ``--out ''``), the root, a mount point."""
    if not p.exists():
        return
    rp, cwd = p.resolve(), Path.cwd().resolve()
    what = ("the current folder" if rp == cwd else "a parent of the current folder" if rp in cwd.parents
            else "a mount point" if os.path.ismount(rp) else None)
    if what:
        raise OutputDirError(f"output folder {str(p) or '.'} is {what}: a run is put in place as a whole "
                             f"folder when it completes, which this one cannot be replaced by; give a "
                             f"folder inside it, e.g. --out {Path(str(p) or '.') / 'run1'}")


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _remove_tree(p: Path) -> None:
    import shutil

    shutil.rmtree(p, ignore_errors=True)


def _clean_stale(target: Path) -> None:
    """Remove staging folders next to ``target`` left by processes that no longer run."""
    parent = target.parent
    if not parent.is_dir():
        return
    for st in parent.glob(f".{target.name}{_STAGING}*"):
        pid = st.name[len(f".{target.name}{_STAGING}"):].removeprefix("old-").split("-", 1)[0]
        if pid.isdigit() and not _pid_alive(int(pid)) and st.is_dir():
            _remove_tree(st)


_libc = None


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2(RENAME_EXCHANGE)``); False if unsupported."""
    global _libc
    import ctypes
    import sys

    if not sys.platform.startswith("linux"):
        return False
    if _libc is None:
        _libc = ctypes.CDLL(None, use_errno=True)
    fn = getattr(_libc, "renameat2", None)
    if fn is None:
        return False
    r = fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if r == 0:
        return True
    err = ctypes.get_errno()
    if err in (22, 38, 95):                     # EINVAL, ENOSYS, EOPNOTSUPP: fall back
        return False
    raise OSError(err, os.strerror(err), str(b))


#: default folders created by :func:`default_out_dir`, with the parents it created for them
#: (all removed again if a run leaves them empty)
_CREATED: dict[Path, list[Path]] = {}
#: run folders checked or being written in this process, in order
_ACTIVE: list["RunDir"] = []


def completed_elsewhere(path: str | os.PathLike) -> None:
    """Another process (a Dask worker of ``sinslab demo``) completed its run in ``path``,
    checked here: an abort of this process has nothing of it to discard or report."""
    t = Path(path).absolute()
    _ACTIVE[:] = [r for r in _ACTIVE if r.target.absolute() != t]
    published(path)


def completed_since(path: str | os.PathLike, since: _dt.datetime) -> bool:
    """True if ``path`` holds a complete run whose marker was written at or after
    ``since`` (local time; the marker keeps whole seconds): a run another process put in
    place after that moment, as opposed to the run the folder held before."""
    m = _read_marker(Path(path))
    try:
        return m.get("status") == "complete" and \
            _dt.datetime.fromisoformat(m["updated"]) >= since.replace(microsecond=0)
    except (KeyError, TypeError, ValueError):
        return False


@on_abort
def abort_all() -> list[str]:
    """Discard every unfinished run of this process; return one phrase per run folder
    saying what it holds now (for the interrupt/error message)."""
    said: list[str] = []
    _remove_leftovers()
    while _ACTIVE:
        s = _ACTIVE.pop(0).abort()
        if s and s not in said:
            said.append(s)
    return said


def abort_run(path: str | os.PathLike) -> str | None:
    """Discard this process's unfinished run in ``path`` alone; return what the folder
    holds now (None: no run of this process was being written there). Runs of the
    process in other folders go on: a demo's worker computing runs in several threads
    discards only the one that failed."""
    t = Path(path).absolute()
    said = None
    for r in [r for r in _ACTIVE if r.target.absolute() == t]:
        said = r.abort()
    return said


def _pause(point: str, count: int = 0, hold_s: float | None = None) -> None:
    """Test hook: ``SINSLAB_PAUSE_AT=point`` stops the process there, announced on stderr,
    until a signal arrives (for ``hold_s`` seconds where signals are held), so that
    interrupt tests hit that exact moment. Points of a run folder: ``checked`` (folder
    checked, nothing staged), ``write:N`` (N files staged), ``figures`` (figures being
    drawn), ``swap`` (run complete in staging, before the exchange), ``exchange`` (run
    exchanged, signals held), ``published`` (run in place, the previous one not yet
    deleted); :func:`sinslab.app.errors.pause` names the others."""
    from sinslab.app.errors import pause

    pause(point, count, hold_s)


#: run folders in place whose replaced run (and obsolete folders) are still to delete
#: (by :meth:`RunDir._commit`, or by an abort should a signal come between)
_LEFTOVERS: list["RunDir"] = []


def _remove_leftovers() -> None:
    for rd in list(_LEFTOVERS):
        rd._remove_leftovers()

class RunDir:
    """The output folder of one run, written as a transaction.

    ``RunDir(path, experiment).prepare()`` checks the folder and opens a staging folder;
    ``write_text``/``write_json``/``write_table``/``write_figure`` add files to it
    (``rd.path`` is the staging folder while the run is open), and ``finish()`` (or
    ``complete(summary)``) marks the run complete and swaps it into place.

    Parameters
    ----------
    path : path-like
        The output folder (``--out``).
    experiment : str
        Experiment or command name recorded in the marker.
    command : str, optional
        The CLI command that writes the run (``run`` for experiments); default: ``experiment``.
    force : bool, optional
        Replace whatever the folder holds (``--force``); default: the value set by
        :func:`forcing` (False).
    """

    def __init__(self, path: str | os.PathLike, experiment: str, command: str | None = None,
                 force: bool | None = None):
        self.target = Path(path)
        self.path = self.target
        self.experiment = experiment
        self.command = command or experiment
        self.force = _FORCE.get() if force is None else bool(force)
        self.files: list[str] = []
        self.series_info: list[dict] = []
        self.figure_files: list[dict] = []
        self._staging: Path | None = None
        self._had_run = False
        self._done = False
        self._made: list[Path] = []
        self._obsolete: list[Path] = []
        self._leftovers: list[Path] = []

    # -- folder rules
    def _describe(self, m: dict) -> str:
        cmd, exp = m.get("command", "run"), m.get("experiment", "?")
        return f"`{cmd}`" if cmd == exp else f"`{cmd} {exp}`"

    def check(self) -> None:
        """Raise :class:`OutputDirError` if the folder may not be used (writes nothing)."""
        p = self.target
        if p.exists() and not p.is_dir():
            raise OutputDirError(f"output folder {p} exists and is a file, not a folder")
        _check_parent(p)
        _check_not_in_run(p)
        self._had_run = False
        if p.is_dir():
            names = [x.name for x in p.iterdir()
                     if not (x.name.startswith(".") and ".tmp-" in x.name)]
            if names and MARKER not in names:
                if not self.force:
                    first = sorted(names)[0]
                    more = f" and {len(names) - 1} more" if len(names) > 1 else ""
                    raise OutputDirError(
                        f"output folder {p} holds {first!r}{more} and is not a previous sinslab "
                        f"run (no {MARKER} marker); choose another --out, empty it, or add --force")
            elif names:
                m = _read_marker(p)
                mine = {"command": self.command, "experiment": self.experiment}
                exp = m.get("experiment")
                cmd = m.get("command") or (exp if exp in _OLD_COMMANDS else "run")
                theirs = {"command": cmd, "experiment": exp}
                if theirs != mine and not self.force:
                    raise OutputDirError(
                        f"output folder {p} holds a run of {self._describe(theirs)}, not "
                        f"{self._describe(mine)}; choose another --out or add --force to replace it")
                listed = set(m.get("files", [])) | {MARKER}
                foreign = sorted(set(names) - listed)
                if foreign and not self.force:
                    more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
                    raise OutputDirError(
                        f"output folder {p} holds {foreign[0]!r}{more}, not written by sinslab; "
                        f"choose another --out, move it away, or add --force to replace it")
                self._had_run = True
            if self.force and names:
                self._check_force_target(p)
                self._had_run = True
        _check_replaceable(p)
        if self not in _ACTIVE:
            _ACTIVE.append(self)
        _pause("checked")

    @staticmethod
    def _check_force_target(p: Path) -> None:
        rp = p.resolve()
        cwd = Path.cwd().resolve()
        if rp == cwd or rp in cwd.parents or rp == Path.home().resolve() or rp == rp.parent \
                or (rp / ".git").exists():
            raise OutputDirError(f"output folder {p} is the current folder, one of its parents, "
                                 f"the home folder or a git work tree; --force never replaces it")

    def prepare(self) -> "RunDir":
        """Check the folder and open the staging folder the run is written into."""
        self.check()
        _clean_stale(self.target)
        name = f".{self.target.name}{_STAGING}{os.getpid()}-{secrets.token_hex(3)}"
        st = self.target.parent / name
        anc = self.target.parent
        while not anc.exists() and anc != anc.parent:
            self._made.append(anc)
            anc = anc.parent
        try:
            st.mkdir(parents=True)
        except OSError as e:
            raise OutputDirError(f"output folder {self.target}: cannot create it "
                                 f"({e.strerror or e})") from None
        self._staging = st
        self.path = st
        self._write_marker("running")
        return self

    def obsolete_when_complete(self, path: str | os.PathLike) -> None:
        """Delete ``path`` (a folder beside the run) once the run is in place, not before:
        e.g. the finished tasks of its Monte Carlo campaigns, kept for a rerun until then."""
        self._obsolete.append(Path(path))

    def scratch_path(self) -> Path:
        """A folder name next to the run folder for a run's temporary files (a record
        spilled to disk while it computes); not created here. Named like a staging
        folder, so the next run next to it removes it if this process is killed."""
        return self.target.parent / f".{self.target.name}{_STAGING}{os.getpid()}-scratch-{secrets.token_hex(3)}"

    def _write_marker(self, status: str) -> None:
        marker = {"sinslab_run": 2, "command": self.command, "experiment": self.experiment,
                  "status": status, "updated": _dt.datetime.now().isoformat(timespec="seconds"),
                  "files": sorted(set(self.files))}
        atomic_write(self.path / MARKER, json.dumps(marker, indent=2) + "\n")

    def finish(self) -> None:
        """Mark the run complete and put it in place of the folder's previous contents."""
        self._write_marker("complete")
        self._commit()

    def _commit(self) -> None:
        st, target = self._staging, self.target
        if st is None:
            raise RuntimeError("RunDir.finish() before prepare()")
        _pause("swap")
        raise_pending_interrupt()
        # from the exchange to the bookkeeping that says the run is in place, a signal
        # waits: cut in between, an abort would take the new run for an unfinished one
        with deferred_signals():
            old = None
            try:
                if target.is_dir() and not target.is_symlink():
                    if _exchange(st, target):
                        old = st                       # the staging name now holds the old run
                    else:
                        old = st.with_name(st.name.replace(_STAGING, _STAGING + "old-"))
                        os.rename(target, old)
                        os.rename(st, target)
                else:
                    os.rename(st, target)
            except OSError as e:
                raise OutputDirError(f"output folder {target}: cannot put the completed run in place "
                                     f"({e.strerror or e}); it keeps what it held") from None
            self._leftovers = ([old] if old is not None else []) + self._obsolete
            _LEFTOVERS.append(self)
            self._done = True
            self.path = target
            self._staging = None
            _ACTIVE[:] = [r for r in _ACTIVE if r.target.absolute() != target.absolute()]
            published(target)
            _pause("exchange", hold_s=60.0)
        _pause("published")
        self._remove_leftovers()

    def _remove_leftovers(self) -> None:
        """Delete the replaced run and the obsolete folders of this (committed) run."""
        while True:
            try:                                   # an abort in another thread may take one first
                path = self._leftovers.pop(0)
            except IndexError:
                break
            _remove_tree(path)
        with contextlib.suppress(ValueError):
            _LEFTOVERS.remove(self)

    def abort(self) -> str:
        """Discard the unfinished run (staging folder, an empty default folder); return
        what the output folder holds now."""
        if self in _ACTIVE:
            _ACTIVE.remove(self)
        if self._done:
            return f"{self.target} holds the completed run"
        if self._staging is not None:
            _remove_tree(self._staging)
            self._staging = None
            self.path = self.target
        _clean_stale(self.target)          # e.g. of the Dask workers a demo's cluster had
        created = self.target.absolute() in _CREATED
        if created:
            with contextlib.suppress(OSError):
                self.target.rmdir()                    # only if still empty
        for d in self._made + (_CREATED.get(self.target.absolute(), []) if created else []):
            with contextlib.suppress(OSError):
                d.rmdir()
        if self._had_run:
            return f"{self.target} still holds the previous run, unchanged"
        if created and not self.target.exists():
            return f"nothing was written (no {self.target} created)"
        return f"nothing was written to {self.target}"

    # -- writers
    def _record(self, name: str) -> Path:
        if "/" in name or name.startswith("."):
            raise ValueError(f"bad output file name {name!r}")
        _pause("write", len(self.files))
        self.files.append(name)
        return self.path / name

    def write_text(self, name: str, text: str) -> Path:
        return atomic_write(self._record(name), text)

    def write_bytes(self, name: str, data: bytes) -> Path:
        return atomic_write(self._record(name), data)

    def move_in(self, name: str, path: str | os.PathLike) -> Path:
        """Record ``name`` and rename the finished file ``path`` (in this folder, written
        by another process) to it: the file appears whole or not at all."""
        dest = self._record(name)
        os.replace(path, dest)
        return dest

    def write_json(self, name: str, obj: Any) -> Path:
        return self.write_text(name, dumps_json(obj))

    def write_table(self, name: str, table, description: str = "",
                    large_rows: int = LARGE_ROWS, csv_every: int | None = None) -> dict:
        """Write a table (DataFrame, dict of 1-D arrays or
        :class:`~sinslab.app.tablefile.ChunkedTable`) as CSV, or Parquet + thinned CSV.

        ``csv_every``: always Parquet (full) + every ``csv_every``-th row as CSV, whatever
        the length. Returns (and records) ``{"name", "description", "rows", "columns",
        "csv", "parquet", "csv_every"}``. A dict of float columns is written a chunk of
        rows at a time (:class:`sinslab.app.tablefile.TableWriter`, the same CSV bytes as
        pandas writes, no DataFrame); anything else through pandas.
        """
        from sinslab.app.tablefile import ChunkedTable, float_columns

        if isinstance(table, ChunkedTable):
            with self.table_writer(name, table.columns, rows=table.n_rows, large_rows=large_rows,
                                   csv_every=csv_every) as w:
                for chunk in table.chunks():
                    w.write(chunk)
            return self.series_written(w, description)
        cols = float_columns(table)
        if cols is not None:
            return self.write_columns(name, cols, description, large_rows, csv_every)
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

    def table_writer(self, name: str, columns, *, rows: int | None = None,
                     large_rows: int = LARGE_ROWS, csv_every: int | None = None):
        """A :class:`sinslab.app.tablefile.TableWriter` of ``name`` in this run folder: CSV
        only, or Parquet + every k-th row as CSV when ``csv_every`` is given or ``rows``
        (the expected length) exceeds ``large_rows`` — the files :meth:`write_table` writes."""
        from sinslab.app.tablefile import TableWriter

        large = csv_every is not None or (rows is not None and rows > large_rows)
        every = (1 if not large else max(1, int(csv_every)) if csv_every is not None
                 else int(math.ceil(rows / large_rows)))
        w = TableWriter(self.path, name, columns, csv_every=every, parquet=large)
        for f in reversed(w.files):
            self._record(f)
        return w

    def series_written(self, writer, description: str = "") -> dict:
        """Record a closed :meth:`table_writer` table in the summary's series list."""
        info = {"name": writer.name, "description": description, "rows": int(writer.rows),
                "columns": list(writer.columns), "csv": f"{writer.name}.csv",
                "parquet": f"{writer.name}.parquet" if len(writer.files) > 1 else None,
                "csv_every": writer.every}
        self.series_info.append(info)
        return info

    def write_columns(self, name: str, cols: dict, description: str = "",
                      large_rows: int = LARGE_ROWS, csv_every: int | None = None,
                      chunk_rows: int = 1 << 16) -> dict:
        """:meth:`write_table` of a dict of equal-length float arrays, ``chunk_rows`` rows
        at a time."""
        n = len(next(iter(cols.values())))
        with self.table_writer(name, cols, rows=n, large_rows=large_rows, csv_every=csv_every) as w:
            for a in range(0, n, chunk_rows):
                w.write({k: v[a:a + chunk_rows] for k, v in cols.items()})
        return self.series_written(w, description)

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


atexit.register(abort_all)
