"""Dask faults end in one line, never in a wait without end (the battery's "hang" class):
a live scheduler without workers, a cluster whose every worker is gone. Each is bounded
here by a short :data:`~sinslab.estimation.montecarlo.NO_WORKERS_S`."""
import re
import sys
import time

import numpy as np
import pytest

from sinslab.estimation import montecarlo as mc


@pytest.fixture
def short_waits(monkeypatch):
    monkeypatch.setattr(mc, "NO_WORKERS_S", 1.0)
    monkeypatch.setattr(mc, "WATCH_POLL_S", 0.2)


@pytest.fixture
def scheduler_without_workers():
    """The address of a live scheduler (in this process) that has no workers."""
    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=0, processes=False, protocol="tcp://", host="127.0.0.1",
                           dashboard_address=None)
    try:
        yield cluster.scheduler_address
    finally:
        cluster.close()


def slow_draws(seeds):
    time.sleep(0.05)
    return np.array([np.random.default_rng(s).normal() for s in seeds])


def test_a_scheduler_without_workers_is_a_timeout_naming_it_and_what_to_start(
        short_waits, scheduler_without_workers, capsys):
    addr = scheduler_without_workers
    t0 = time.monotonic()
    with pytest.raises(mc.ClusterError) as e:
        mc.run_campaign(slow_draws, 4, 0, scheduler=addr, progress=False)
    msg = str(e.value)
    assert time.monotonic() - t0 < 20
    assert "\n" not in msg
    assert f"the Dask scheduler at {addr} has no workers" in msg and f"`dask worker {addr}`" in msg, msg
    assert msg.endswith("0 of 4 runs had finished"), msg
    assert f"waiting up to 1 s for some to join (start them with `dask worker {addr}`)" in capsys.readouterr().err


_KILL_AFTER = 2


def draws_then_the_worker_leaves(seeds):
    """Two batches go through; the third closes the worker computing it (and any other)."""
    from distributed import get_worker

    out = np.array([np.random.default_rng(s).normal() for s in seeds])
    w = get_worker()
    w.sinslab_done = getattr(w, "sinslab_done", 0) + 1
    if w.sinslab_done > _KILL_AFTER:
        w.loop.add_callback(w.close)
        time.sleep(5)
    return out


def test_every_worker_gone_says_what_finished_and_where_it_is_kept(short_waits, tmp_path):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cl, \
            Client(cl) as client:
        t0 = time.monotonic()
        with pytest.raises(mc.ClusterError) as e:
            mc.run_campaign(draws_then_the_worker_leaves, 6, 0, batch=1, scheduler=client, progress=False,
                            store=tmp_path / "mc", store_key="k")
        assert time.monotonic() - t0 < 30
    msg = str(e.value)
    assert "\n" not in msg
    assert "every worker of the local Dask cluster is gone" in msg, msg
    # the worker may leave before the scheduler has collected the last batch it
    # computed: what the message counts is what the store kept, at most the two batches
    m = re.search(r"(\d) of 6 runs had finished; they are kept in (\S+), where", msg)
    assert m and 1 <= int(m[1]) <= _KILL_AFTER and m[2] == str(tmp_path / "mc"), msg
    # the rerun on a working cluster computes only the others, with the same numbers
    ref = mc.run_campaign(slow_draws, 6, 0, batch=1, scheduler="sync", progress=False)
    again = mc.run_campaign(slow_draws, 6, 0, batch=1, scheduler="sync", progress=False,
                            store=tmp_path / "mc", store_key="k")
    assert np.array_equal(again, ref)


def test_the_command_line_says_it_in_one_line(short_waits, scheduler_without_workers, tmp_path):
    """`sinslab run ... --scheduler ADDR` of a scheduler without workers: exit 2, one line
    with the address and what to start, nothing written."""
    from typer.testing import CliRunner

    import sinslab.experiments as E
    from sinslab.cli import app

    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parents[1] / "app"))
    import test_interrupts

    E.register(test_interrupts.Signals)
    addr = scheduler_without_workers
    r = CliRunner().invoke(app, ["-q", "run", "signals", "--runs", "3", "--scheduler", addr,
                                 "--out", str(tmp_path / "out")])
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sinslab: error: signals: Monte Carlo: the Dask scheduler at"), lines
    assert f"`dask worker {addr}`" in lines[0] and "check the values given" not in lines[0]
    assert not (tmp_path / "out").exists()


def test_workers_beyond_the_machine_are_refused():
    from sinslab.app.errors import CliError
    from sinslab.app.validate import WORKER_MEMORY, check_workers, usable_cores

    n = usable_cores()
    check_workers(n, available=n * WORKER_MEMORY)
    with pytest.raises(CliError, match=rf"--workers {n + 1}: this machine gives this process {n} core"):
        check_workers(n + 1)
    with pytest.raises(CliError, match=r"--workers 1: each worker process needs about 300 MiB.*give at most 0"):
        check_workers(1, available=WORKER_MEMORY // 2)
