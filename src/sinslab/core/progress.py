"""Progress bars for long loops: rich on a terminal, silent otherwise.

Any module with a long loop (mechanization of a long record, a Kalman time loop, a
Monte Carlo campaign) reports progress through this helper, so that the look and the
"quiet when not a TTY" rule live in one place::

    from sinslab.core.progress import progress

    with progress("navigating", total=n_samples, unit="samples") as bar:
        for lo in range(0, n_samples, chunk):
            hi = min(lo + chunk, n_samples)
            step_chunk(state, dtheta[lo:hi], dv[lo:hi], dt)   # compiled hot loop
            bar.advance(hi - lo)

Compiled loops stay compiled: call them on chunks (10^5–10^6 samples) and advance the
bar between chunks. ``track(iterable, "label")`` wraps a Python iterable.

A function whose caller may switch its bar off takes a ``progress`` flag and passes it
on as ``enabled``; a disabled bar is a no-op :class:`Bar` with the same methods, so the
loop needs no second branch::

    def navigate(..., progress=True):
        with progress_bar("navigating", total=n, unit="samples", enabled=progress) as bar:
            ...
            bar.advance(hi - lo)

(import it as ``from sinslab.core.progress import progress as progress_bar`` where the
function's own flag is called ``progress``).

A command announces its stages with :func:`stage` (``with stage("reading imu.csv"):``);
the stage's lines, its timer and its spinner come from here.

The bars go to stderr and are shown only when stderr is a terminal. Off a terminal (a
log file, CI, a pipe) the command line (:func:`set_lines`) turns each bar into lines: one
when the stage starts, one every :data:`HEARTBEAT_S` seconds of a long stage (from a
timer, whether the stage advances or not) and one at its end, each with the elapsed time,
so that long work is visible in a log; a library caller off a terminal (a notebook, a Dask worker, a loop over records)
gets neither. Both are silenced for the whole process by ``SINSLAB_QUIET=1`` or
:func:`set_quiet`; the CLI's ``--quiet`` flag and test runners use that. Nested bars share
one live display.
"""
from __future__ import annotations

import contextlib
import os
import sys
import threading
from typing import Any, Iterable, Iterator, TypeVar

__all__ = ["progress", "stage", "track", "set_quiet", "set_lines", "is_quiet", "Bar", "HEARTBEAT_S"]

#: seconds between the progress lines of a long stage off a terminal
HEARTBEAT_S = 30.0

T = TypeVar("T")

_state = threading.local()
_quiet_override: bool | None = None
_lines = False


def set_quiet(quiet: bool | None) -> None:
    """Force bars off (True), on when on a terminal (False), or back to automatic (None)."""
    global _quiet_override
    _quiet_override = quiet


def is_quiet() -> bool:
    """True when bars are not shown: forced quiet, ``SINSLAB_QUIET`` set, or not a TTY."""
    if _quiet_override is not None:
        return _quiet_override
    if os.environ.get("SINSLAB_QUIET", "") not in ("", "0"):
        return True
    try:
        return not sys.stderr.isatty()
    except (AttributeError, ValueError):
        return True


class Bar:
    """Handle of one progress task; ``advance(n)`` and ``update(completed=...)``.

    A quiet bar accepts the same calls and does nothing.
    """

    def __init__(self, prog: Any = None, task: Any = None) -> None:
        self._p, self._t = prog, task

    def advance(self, n: float = 1) -> None:
        if self._p is not None:
            self._p.advance(self._t, n)

    def update(self, *, completed: float | None = None, total: float | None = None,
               description: str | None = None) -> None:
        if self._p is not None:
            kw = {k: v for k, v in (("completed", completed), ("total", total),
                                    ("description", description)) if v is not None}
            self._p.update(self._t, **kw)


def set_lines(on: bool = True) -> None:
    """Off a terminal, print a line per stage (start, every HEARTBEAT_S, end) instead of
    nothing; the command line turns this on."""
    global _lines
    _lines = bool(on)


def _lines_wanted() -> bool:
    """True off a terminal when lines are on and not silenced: stages print lines."""
    if not _lines or _quiet_override is True or os.environ.get("SINSLAB_QUIET", "") not in ("", "0"):
        return False
    try:
        return not sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


class _LineBar(Bar):
    """A bar off a terminal: a line at the start, one every HEARTBEAT_S while the stage
    runs (from a timer thread, so that a stage that never advances — one long compiled
    call, figures being drawn — still shows it is alive) and one at the end.

    The timer prints between two Python steps of the working thread: a compiled call
    that holds the interpreter lock delays its line until the call returns (the loops of
    sinslab's long stages return to Python between blocks).

    Stages nest (a command's computation, the filter inside it): only the innermost open
    stage of a thread prints its 30 s lines, and the one around it counts its next 30 s
    from the end of the inner one, so a log gets one line per interval, from the work
    that is running."""

    def __init__(self, description: str, total, unit: str):
        import time

        super().__init__()
        self.description, self.total, self.unit = description, total, unit
        self.done = 0.0
        self.t0 = self.last = time.monotonic()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        stack = getattr(_state, "lines", None)
        if stack is None:
            stack = _state.lines = []
        self._stack: list = stack           # this thread's open line stages, innermost last
        stack.append(self)
        self._say("started")
        self._timer = threading.Thread(target=self._run, name="sinslab-progress", daemon=True)
        self._timer.start()

    def _say(self, what: str) -> None:
        print(f"sinslab: {self.description}: {what}", file=sys.stderr, flush=True)

    def _run(self) -> None:
        import time

        while not self._stop.wait(max(0.05, self.last + HEARTBEAT_S - time.monotonic())):
            self._beat()

    def _beat(self) -> None:
        import time

        with self._lock:
            now = time.monotonic()
            if now - self.last < HEARTBEAT_S or self._stop.is_set() or self._stack[-1:] != [self]:
                return
            self.last = now
            u = f" {self.unit}" if self.unit else ""
            if self.total:
                part = f"{100.0 * self.done / self.total:.0f} % of {self.total:g}{u}"
            elif self.done:
                part = f"{self.done:g}{u}"
            else:
                part = "still running"
            self._say(f"{part} after {now - self.t0:.0f} s")

    def advance(self, n: float = 1) -> None:
        self.done += n
        self._beat()

    def update(self, *, completed: float | None = None, total: float | None = None,
               description: str | None = None) -> None:
        if completed is not None:
            self.done = completed
        if total is not None:
            self.total = total
        self._beat()

    def stop(self) -> None:
        """End the timer without a line (the stage failed: its error says why)."""
        import time

        with self._lock:
            self._stop.set()
        self._timer.join()
        if self in self._stack:
            self._stack.remove(self)
        if self._stack:                     # the stage around this one: 30 s from now
            self._stack[-1].last = max(self._stack[-1].last, time.monotonic())

    def end(self) -> None:
        import time

        self.stop()
        self._say(f"done in {time.monotonic() - self.t0:.1f} s")


@contextlib.contextmanager
def progress(description: str, total: float | None = None, unit: str = "", *,
             enabled: bool = True) -> Iterator[Bar]:
    """Context manager yielding a :class:`Bar` for a loop of ``total`` steps.

    ``total=None`` shows an indeterminate spinner. The bar is a no-op (no output at all)
    when ``enabled`` is false or :func:`set_quiet` / ``SINSLAB_QUIET`` silence it; off a
    terminal it prints lines with the elapsed time instead (module notes).
    """
    if not enabled or is_quiet():
        if enabled and _lines_wanted():
            bar = _LineBar(description, total, unit)
            try:
                yield bar
            except BaseException:
                bar.stop()
                raise
            bar.end()
            return
        yield Bar()
        return
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, SpinnerColumn,
                               TextColumn, TimeElapsedColumn, TimeRemainingColumn)

    outer = getattr(_state, "progress", None)
    if outer is not None:                      # nested: add a task to the live display
        task = outer.add_task(description, total=total)
        try:
            yield Bar(outer, task)
        finally:
            outer.remove_task(task)
        return
    cols = [SpinnerColumn(), TextColumn("[bold]{task.description}"), BarColumn(),
            MofNCompleteColumn(), TextColumn(unit) if unit else TextColumn(""),
            TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn()]
    prog = Progress(*cols, console=Console(stderr=True), transient=True)
    _state.progress = prog
    try:
        with prog:
            task = prog.add_task(description, total=total)
            yield Bar(prog, task)
    finally:
        _state.progress = None


def stage(description: str, total: float | None = None, unit: str = "") -> contextlib.AbstractContextManager:
    """One stage of a command — reading a log, the filter, drawing the figures — announced
    by the command: :func:`progress` under the stage's name. Off a terminal (with the
    command line's lines on) it prints ``sinslab: <description>: started``, a line every
    :data:`HEARTBEAT_S` while it runs and ``sinslab: <description>: done in <t> s``; on a
    terminal a spinner (a bar with ``total``); nothing when quiet. A stage's bars (the
    filter's own) nest inside it."""
    return progress(description, total, unit)


def track(iterable: Iterable[T], description: str, total: float | None = None, *,
          enabled: bool = True) -> Iterator[T]:
    """Iterate ``iterable`` with a progress bar (``total`` defaults to ``len(iterable)``;
    no bar when ``enabled`` is false)."""
    if total is None:
        try:
            total = len(iterable)  # type: ignore[arg-type]
        except TypeError:
            total = None
    with progress(description, total, enabled=enabled) as bar:
        for item in iterable:
            yield item
            bar.advance(1)
