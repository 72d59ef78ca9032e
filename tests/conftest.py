"""Fixtures shared by the test packages; plain helper functions live in ``support.py``."""

import pytest


@pytest.fixture(autouse=True)
def _progress_state_per_test():
    """The command line sets process-wide progress switches (``--quiet``, stage lines); a
    test that runs it in process must not decide what a later test prints."""
    from sinslab.core import progress

    quiet, lines = progress._quiet_override, progress._lines
    yield
    progress._quiet_override, progress._lines = quiet, lines
