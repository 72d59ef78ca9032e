"""The one optional-progress helper: a disabled or quiet bar is a no-op with the same API."""
import pytest

from sinslab.core import progress as P


@pytest.fixture
def loud():
    P.set_quiet(False)                  # bars on even though stderr is not a terminal
    yield
    P.set_quiet(None)


def test_disabled_bar_is_a_noop_even_when_bars_are_on(loud, capsys):
    with P.progress("work", total=3, unit="steps", enabled=False) as bar:
        assert bar._p is None
        bar.advance(2)
        bar.update(completed=3, description="done")
    assert capsys.readouterr().err == ""


def test_enabled_bar_drives_a_live_task(loud):
    with P.progress("work", total=3) as bar:
        assert bar._p is not None
        bar.advance(3)
        assert bar._p.tasks[0].completed == 3


def test_quiet_wins_over_enabled():
    P.set_quiet(True)
    try:
        with P.progress("work", total=3, enabled=True) as bar:
            assert bar._p is None
    finally:
        P.set_quiet(None)


def test_track_disabled_yields_every_item(loud):
    assert list(P.track(range(5), "items", enabled=False)) == [0, 1, 2, 3, 4]
