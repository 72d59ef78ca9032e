"""User errors and interrupts of the command line, in one place below the CLI.

An error the user can fix (an unknown config key, a bad unit, an unreadable file, an
output folder that may not be used, an unknown experiment) is a :class:`UserError` — a
``ValueError`` — or one of :data:`USER_ERRORS`. Inside :func:`user_errors` it becomes one
line ``sinslab: error: ...`` on stderr and exit status 2. Ctrl-C becomes exit 130 and
SIGTERM exit 143; both unwind the stack, the unfinished run is discarded (its staging
folder removed, see :mod:`sinslab.app.outputs`) and the message says what the output
folder holds: the previous run, unchanged, or nothing. A signal that arrives once the
command's run folder has replaced the previous one (while a Dask cluster shuts down, the
summary is printed or the interpreter exits) cannot undo it: the command says the folder
holds the completed run and exits 0. Anything else is a bug and keeps its traceback (exit 1).

Signals are never lost: one that arrives while the run folder is being exchanged waits
for the exchange (:func:`deferred_signals`), and one whose exception a library swallows
(raised inside a garbage-collector callback such as distributed's, a ``__del__`` or a
weakref callback, where Python can only print it as "Exception ignored") is delivered
again at once, outside it (:func:`install_signal_handlers`).

Every command body (``sinslab run``, ``navigate``, ...) runs inside ``user_errors()``::

    from sinslab.app.errors import CliError, user_errors

    with user_errors():
        if not path.exists():
            raise CliError(f"{path}: no such file")
        ...
"""
from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
import threading

import typer

from sinslab.core.errors import InputError
from sinslab.core.units import UnitError

__all__ = ["UserError", "CliError", "USER_ERRORS", "user_errors", "error_line", "cut",
           "Terminated", "on_abort", "published", "deferred_signals", "install_signal_handlers",
           "cli_process", "finish_command", "exit_now", "pause"]

#: What :func:`user_errors` calls when a command fails or is interrupted, each returning
#: one phrase per output folder saying what it holds now (:func:`on_abort`).
_ABORTS: list = []


def on_abort(discard):
    """Register ``discard() -> list[str]``, called when a command body fails or is
    interrupted: it discards that module's unfinished work (the run folders of
    :mod:`sinslab.app.outputs`, which registers itself on import) and says what remains."""
    if discard not in _ABORTS:
        _ABORTS.append(discard)
    return discard


class UserError(ValueError):
    """Base of the errors a user can fix; printed as one line, exit status 2.

    The configuration, output-folder and report errors of :mod:`sinslab.app` and the
    unknown-experiment error derive from it.
    """


class CliError(UserError):
    """A user error raised by a command itself (bad option value, missing file)."""


#: Exceptions :func:`user_errors` turns into one line and exit 2: every :class:`UserError`,
#: the unit-parsing error of :mod:`sinslab.core.units` and the bad-input error of the
#: lower layers (:class:`sinslab.core.errors.InputError`), all ``ValueError``.
USER_ERRORS: tuple = (UserError, UnitError, InputError)


class Terminated(KeyboardInterrupt):
    """SIGTERM, delivered as an exception so that temporary files are cleaned up."""


#: run folders that replaced their previous contents during the current command
#: (:func:`published`, called by :mod:`sinslab.app.outputs` once a run is in place)
_PUBLISHED: list[str] = []
#: the command's work is over (the command line's process only): a signal now ends the
#: process with the status of the work, 0, instead of interrupting what remains of the exit
_FINISHED = False
#: the exit status of the finished command (:func:`finish_command`)
_STATUS = 0
#: depth of :func:`user_errors` blocks (the outermost one starts and ends a command)
_DEPTH = 0
#: this process is the command line (:func:`cli_process`), not a library caller
_IN_CLI = False


def published(folder) -> None:
    """Record that ``folder`` now holds the completed run of the current command: an
    interrupt from now on cannot take it back, and says so."""
    text = str(folder)
    if text not in _PUBLISHED:
        _PUBLISHED.append(text)


#: interrupts this process received that no command has reported yet. The exception a
#: handler raises can still be lost: C code that clears every error (a dictionary lookup
#: calling ``__eq__``, some extension modules) swallows it when it lands in Python code
#: called from there. A run's commit looks here (:func:`raise_pending_interrupt`), so
#: that an interrupt received before it never lets the run replace the folder.
_PENDING: list[int] = []


def _interrupt(signum: int) -> BaseException:
    if signum not in _PENDING:
        _PENDING.append(signum)
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def raise_pending_interrupt() -> None:
    """Raise the interrupt this process received and that was not handled (its exception
    lost on the way up, or a redelivery still waiting), as the handler would have."""
    if _PENDING:
        raise _interrupt(_PENDING[0])


def _on_sigterm(signum, frame):
    if _FINISHED:
        _exit_quietly()
    if _swallowing(frame):
        _redeliver(signum)
        return
    raise _interrupt(signum)


def _on_sigint(signum, frame):
    if _FINISHED:
        _exit_quietly()
    if _swallowing(frame):
        _redeliver(signum)
        return
    raise _interrupt(signum)


def _exit_quietly() -> None:
    """End the process with the command's status: the command is done and has said so;
    what remains (the interpreter's exit) has nothing to keep."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(_STATUS)


def _swallowing(frame) -> bool:
    """True if an exception raised in ``frame`` may never reach the command: the main
    thread is inside an import (a compiled module's initialisation may discard errors of
    the Python code it calls), a garbage-collector callback or a finalizer (whose
    exceptions Python only prints)."""
    callbacks = set()
    for cb in list(gc.callbacks):
        code = getattr(getattr(cb, "__func__", cb), "__code__", None)
        if code is not None:
            callbacks.add(code)
    while frame is not None:
        code = frame.f_code
        if code.co_filename.startswith("<frozen importlib") or code.co_name == "__del__" or code in callbacks:
            return True
        frame = frame.f_back
    return False


#: signals waiting for :func:`_redeliver` to trip their handler again
_REDELIVERING: list[int] = []


def _redeliver(signum: int) -> None:
    """Trip ``signum``'s Python handler again as soon as the main thread has left the
    place where its exception could be lost (:func:`_swallowing`), from a helper thread
    that looks every 10 ms; the handler then runs in the main thread and raises."""
    import _thread
    import time

    main = threading.main_thread().ident
    _REDELIVERING.append(signum)
    if signum not in _PENDING:
        _PENDING.append(signum)

    def later():
        while True:
            time.sleep(0.01)
            frame = sys._current_frames().get(main)
            if frame is None or not _swallowing(frame):
                break
            del frame
        with contextlib.suppress(ValueError):
            _REDELIVERING.remove(signum)
        with contextlib.suppress(Exception):
            _thread.interrupt_main(signum)

    threading.Thread(target=later, name="sinslab-redeliver", daemon=True).start()


def _unraisable(unraisable) -> None:
    """``sys.unraisablehook``: an interrupt raised where Python cannot propagate it (a
    garbage-collector callback, ``__del__``, a weakref callback) is delivered again rather
    than printed and lost; anything else goes to the previous hook."""
    exc = unraisable.exc_type
    if isinstance(exc, type) and issubclass(exc, KeyboardInterrupt):
        _redeliver(signal.SIGTERM if issubclass(exc, Terminated) else signal.SIGINT)
        return
    _PREVIOUS_HOOK(unraisable)


_PREVIOUS_HOOK = sys.unraisablehook


def install_signal_handlers() -> None:
    """Handle SIGTERM (as :class:`Terminated`) and SIGINT (as ``KeyboardInterrupt``, unless
    it is ignored, e.g. in a background job) in the main thread, and re-deliver interrupts
    swallowed by library callbacks (:func:`_unraisable`). The command line calls it once
    at start; :func:`user_errors` for the duration of its block."""
    global _PREVIOUS_HOOK
    if threading.current_thread() is not threading.main_thread():
        return
    signal.signal(signal.SIGTERM, _on_sigterm)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _on_sigint)
    if sys.unraisablehook is not _unraisable:
        _PREVIOUS_HOOK = sys.unraisablehook
        sys.unraisablehook = _unraisable


def finish_command(status: int | None = 0) -> None:
    """The command line's process has done its work and said so (its last line is
    printed): a signal arriving during the interpreter's exit ends it at once with the
    command's exit ``status``."""
    global _FINISHED, _STATUS
    _FINISHED = True
    _STATUS = int(status) if isinstance(status, int) else (0 if status is None else 1)


def exit_now(status: int) -> None:
    """End the command line's process with ``status`` once its work is done: its other
    threads joined and its exit handlers run here, under the command's signal handlers
    (a signal now ends it with ``status``), then the process exits without the
    interpreter's own finalisation, during which Python puts back the default handlers
    and a SIGTERM would kill the process after it has reported success."""
    import atexit

    finish_command(status)
    for t in threading.enumerate():
        if t is not threading.current_thread() and not t.daemon:
            t.join()
    atexit._run_exitfuncs()
    _exit_quietly()


def cli_process() -> None:
    """This process is the ``sinslab`` command line: install the signal handlers for its
    whole life; the end of its command (:func:`user_errors`) is the end of its work."""
    global _IN_CLI
    _IN_CLI = True
    install_signal_handlers()


#: the signals held by each open :func:`deferred_signals` block
_HELD: list[list[int]] = []


@contextlib.contextmanager
def deferred_signals():
    """Hold SIGINT and SIGTERM for the block (main thread only; elsewhere signals are not
    handled anyway): one arriving meanwhile is delivered, with the handler that was in
    place, when the block ends. For steps that must not be cut in two (the exchange of a
    run folder), whichever thread the kernel delivers the signal to."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    _HELD.append(pending)

    def hold(signum, frame):
        if signum not in pending:
            pending.append(signum)

    old = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        old[sig] = signal.signal(sig, hold)
    try:
        yield
    finally:
        _HELD.remove(pending)
        for sig, h in old.items():
            signal.signal(sig, h)
        for sig in pending:
            if old[sig] not in (signal.SIG_IGN, None):
                signal.raise_signal(sig)


#: longest error line printed [characters]; a longer one keeps its head and its tail (the
#: file and line at the start, the hint at the end) and says how much was cut
MAX_LINE = 400
#: longest single word (a value, a header cell) kept whole in an error line
MAX_WORD = 80


def cut(text: str, max_line: int = MAX_LINE, max_word: int = MAX_WORD) -> str:
    """``text`` shortened for one terminal line: words longer than ``max_word`` and lines
    longer than ``max_line`` lose their middle, replaced by ``…(N characters)…``."""
    import re

    def word(m):
        w = m.group(0)
        return f"{w[:max_word // 2]}…({len(w)} characters)…{w[-max_word // 4:]}"

    text = re.sub(r"\S{%d,}" % (max_word + 1), word, text)
    if len(text) > max_line:
        head, tail = text[: max_line * 2 // 3], text[-max_line // 4:]
        text = f"{head} …({len(text) - len(head) - len(tail)} characters cut)… {tail}"
    return text


def error_line(exc: BaseException) -> str:
    """The one line printed for a user error: the first line of its message (or its type),
    cut to :data:`MAX_LINE` characters (a long value is shown by its ends and its length)."""
    text = str(exc)
    return cut(text.splitlines()[0]) if text.strip() else type(exc).__name__


def _err(msg: str) -> None:
    typer.echo(f"sinslab: error: {msg}", err=True)


def _interrupted(word: str, code: int):
    """The line and exit status of an interrupt: the unfinished runs are discarded; if
    every folder the command touched holds its completed run, that is the outcome (exit 0)."""
    kept = _abort()
    done = [f"{p} holds the completed run" for p in _PUBLISHED]
    if done and not kept:
        typer.echo(f"sinslab: {word} after the run was complete; {'; '.join(done)}", err=True)
        return typer.Exit(0)
    _err(f"{word}; {'; '.join(done + kept) if done or kept else 'nothing was written'}")
    return typer.Exit(code)


def _abort() -> list[str]:
    """Discard the unfinished run folders of this process; say what they hold now."""
    said: list[str] = []
    for discard in _ABORTS:
        said += [s for s in discard() if s not in said]
    return said


@contextlib.contextmanager
def user_errors():
    """Turn user errors into one stderr line + exit 2, interrupts into exit 130/143.

    Installs the signal handlers (:func:`install_signal_handlers`) for the duration of the
    block (main thread only) and restores the previous ones afterwards. The outermost
    block is one command: the run folders it publishes (:func:`published`) are what an
    interrupt after them reports as complete, and in the command line's process its end
    is the end of the command's work (:func:`finish_command`).
    """
    global _DEPTH
    old = None
    if threading.current_thread() is threading.main_thread():
        old = (signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT), sys.unraisablehook)
        install_signal_handlers()
    if _DEPTH == 0:
        _PUBLISHED.clear()
    _DEPTH += 1
    status = 1
    try:
        yield
        status = 0
    except USER_ERRORS as e:
        status = 2
        _abort()
        _err(error_line(e))
        raise typer.Exit(2) from None
    except KeyboardInterrupt as e:
        _PENDING.clear()
        code = 143 if isinstance(e, Terminated) else 130
        held = _hold_signals()
        try:
            ex = _interrupted("terminated" if code == 143 else "interrupted", code)
        finally:
            _release_signals(held)
        status = ex.exit_code
        raise ex from None
    except (typer.Exit, SystemExit) as e:
        _abort()
        status = getattr(e, "exit_code", getattr(e, "code", 1))
        raise
    except BaseException:
        _abort()
        raise
    finally:
        _DEPTH -= 1
        if old is not None:
            signal.signal(signal.SIGTERM, old[0])
            signal.signal(signal.SIGINT, old[1])
            sys.unraisablehook = old[2]
        if _DEPTH == 0 and _IN_CLI:
            finish_command(status)


def _hold_signals():
    """Ignore SIGINT/SIGTERM while an interrupt is being handled: a second Ctrl-C must not
    cut the clean-up and its message in two. Returns what to restore."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return {sig: signal.signal(sig, signal.SIG_IGN) for sig in (signal.SIGINT, signal.SIGTERM)}


def _release_signals(held) -> None:
    for sig, h in (held or {}).items():
        signal.signal(sig, h)


def pause(point: str, count: int = 0, hold_s: float | None = None) -> None:
    """Test hook: with ``SINSLAB_PAUSE_AT=point`` (or ``point:count``) the process stops
    here, says ``sinslab: paused at POINT`` on stderr and waits for a signal (where
    signals are held, until one is held or for ``hold_s`` seconds), so that the interrupt
    tests hit that moment.
    Points besides those of :mod:`sinslab.app.outputs`: ``summary`` (the command's run in
    place, its summary not yet printed) and ``exit`` (the command finished, the
    interpreter exiting); an experiment may add its own."""
    want = os.environ.get("SINSLAB_PAUSE_AT")
    if not want or want not in (point, f"{point}:{count}"):
        return
    import time

    print(f"sinslab: paused at {want}", file=sys.stderr, flush=True)
    end = None if hold_s is None else time.monotonic() + hold_s
    while (end is None or time.monotonic() < end) and not any(_HELD) and not _REDELIVERING:
        time.sleep(0.02)
