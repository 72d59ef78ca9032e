"""Fixtures shared by the test packages; plain helper functions live in ``support.py``."""

import pytest


@pytest.fixture(autouse=True)
def _progress_state_per_test():
    """The command line sets process-wide progress switches (``--quiet``, stage lines); a
    test, or a module fixture, that runs it in process must not decide what a later test
    prints: every test starts and ends with them automatic."""
    from sinslab.core import progress

    progress._quiet_override, progress._lines = None, False
    yield
    progress._quiet_override, progress._lines = None, False
