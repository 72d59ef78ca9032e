"""Fixtures shared by the test packages; plain helper functions live in ``support.py``."""

import os

import pytest

#: ``SINSLAB_QUIET`` as the session started, before test modules (some import benchmark
#: scripts that set it) are collected
_SESSION_QUIET = os.environ.get("SINSLAB_QUIET")


@pytest.fixture(autouse=True)
def _progress_state_per_test():
    """The command line sets process-wide progress switches (``--quiet``, stage lines) and
    benchmark scripts set ``SINSLAB_QUIET`` when imported; a test, or a module fixture, that
    runs either in process must not decide what a later test prints: every test starts and
    ends with the switches automatic and the variable as the session found it."""
    from sinslab.core import progress

    def automatic():
        progress._quiet_override, progress._lines = None, False
        if _SESSION_QUIET is None:
            os.environ.pop("SINSLAB_QUIET", None)
        else:
            os.environ["SINSLAB_QUIET"] = _SESSION_QUIET

    automatic()
    yield
    automatic()
