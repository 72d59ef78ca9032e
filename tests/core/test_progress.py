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


def test_stage_prints_a_line_per_heartbeat_without_advancing(monkeypatch, capsys):
    """Off a terminal a stage that never advances (one long call) still shows it runs: the
    timer prints every HEARTBEAT_S, then the end line with the elapsed time."""
    import time

    monkeypatch.setattr(P, "HEARTBEAT_S", 0.05)
    P.set_quiet(None)
    P.set_lines(True)
    try:
        with P.stage("one long call"):
            time.sleep(0.18)
    finally:
        P.set_lines(False)
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "sinslab: one long call: started"
    beats = [ln for ln in err[1:-1] if ln.startswith("sinslab: one long call: still running after ")]
    assert len(beats) >= 2 and len(beats) == len(err) - 2, err
    assert err[-1].startswith("sinslab: one long call: done in ")


def test_failed_stage_stops_its_timer_without_an_end_line(monkeypatch, capsys):
    import threading
    import time

    monkeypatch.setattr(P, "HEARTBEAT_S", 0.05)
    P.set_quiet(None)
    P.set_lines(True)
    try:
        with pytest.raises(ValueError):
            with P.stage("failing"):
                time.sleep(0.02)
                raise ValueError("bad input")
    finally:
        P.set_lines(False)
    time.sleep(0.12)                    # a timer left running would print here
    err = capsys.readouterr().err.splitlines()
    assert err == ["sinslab: failing: started"]
    assert not [t for t in threading.enumerate() if t.name == "sinslab-progress"]


def test_nested_stages_print_the_innermost_heartbeat(monkeypatch, capsys):
    """A command's computation around the filter's stage: while the inner stage runs only
    it prints the periodic lines; the outer one counts its next interval from the inner
    one's end (one line per interval in the log, from the work that runs)."""
    import time

    monkeypatch.setattr(P, "HEARTBEAT_S", 0.06)
    P.set_quiet(None)
    P.set_lines(True)
    try:
        with P.stage("outer"):
            with P.stage("inner", total=4, unit="steps") as bar:
                for _ in range(4):
                    time.sleep(0.05)
                    bar.advance(1)
            time.sleep(0.03)                # shorter than an interval: no outer line yet
    finally:
        P.set_lines(False)
    err = capsys.readouterr().err.splitlines()
    assert err[:2] == ["sinslab: outer: started", "sinslab: inner: started"], err
    assert err[-1].startswith("sinslab: outer: done in ") and err[-2].startswith("sinslab: inner: done in ")
    middle = err[2:-2]
    assert middle and all(ln.startswith("sinslab: inner: ") and " % of 4 steps after " in ln
                          for ln in middle), err
