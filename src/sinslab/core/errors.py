"""The bad-input error of the layers below the application.

:class:`InputError` is raised by code below :mod:`sinslab.app` when what it was given
cannot be used — a Monte Carlo scheduler that cannot be reached, a navigation run that
becomes non-finite from its initial errors — and the message says which input and why
in one line. The command line prints it as ``sinslab: error: ...`` with exit status 2
(:data:`sinslab.app.errors.USER_ERRORS`); Python callers get a ``ValueError``.
"""
from __future__ import annotations

__all__ = ["InputError"]


class InputError(ValueError):
    """An input that cannot be used; ``str(err)`` is one line naming it."""
