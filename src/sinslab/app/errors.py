"""User errors and interrupts of the command line, in one place below the CLI.

An error the user can fix (an unknown config key, a bad unit, an unreadable file, an
output folder that may not be used, an unknown experiment) is a :class:`UserError` — a
``ValueError`` — or one of :data:`USER_ERRORS`. Inside :func:`user_errors` it becomes one
line ``sinslab: error: ...`` on stderr and exit status 2. Ctrl-C becomes exit 130 and
SIGTERM exit 143; both unwind the stack, the unfinished run is discarded (its staging
folder removed, see :mod:`sinslab.app.outputs`) and the message says what the output
folder holds: the previous run, unchanged, or nothing. Anything else is a bug and keeps its traceback (exit 1).

Every command body (``sinslab run``, ``navigate``, ...) runs inside ``user_errors()``::

    from sinslab.app.errors import CliError, user_errors

    with user_errors():
        if not path.exists():
            raise CliError(f"{path}: no such file")
        ...
"""
from __future__ import annotations

import contextlib
import signal

import typer

from sinslab.core.errors import InputError
from sinslab.core.units import UnitError

__all__ = ["UserError", "CliError", "USER_ERRORS", "user_errors", "error_line", "cut",
           "Terminated", "on_abort"]

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


def _on_sigterm(signum, frame):
    raise Terminated()


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


def _abort() -> str:
    """Discard the unfinished run folders of this process; say what they hold now."""
    said = []
    for discard in _ABORTS:
        said += [s for s in discard() if s not in said]
    return "; ".join(said) if said else "nothing was written"


@contextlib.contextmanager
def user_errors():
    """Turn user errors into one stderr line + exit 2, interrupts into exit 130/143.

    Installs a SIGTERM handler for the duration of the block (main thread only) and
    restores the previous one afterwards.
    """
    old = None
    with contextlib.suppress(ValueError):          # not in the main thread: leave it
        old = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        yield
    except USER_ERRORS as e:
        _abort()
        _err(error_line(e))
        raise typer.Exit(2) from None
    except Terminated:
        _err(f"terminated; {_abort()}")
        raise typer.Exit(143) from None
    except KeyboardInterrupt:
        _err(f"interrupted; {_abort()}")
        raise typer.Exit(130) from None
    except BaseException:
        _abort()
        raise
    finally:
        if old is not None:
            signal.signal(signal.SIGTERM, old)
