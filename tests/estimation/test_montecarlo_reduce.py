"""Campaign statistics summed where the runs are computed, in a tree fixed by the run
index; finished tasks kept in a store and reused; tasks sized from the measured cost."""
import logging
import os
import sys

import cloudpickle
import numpy as np
import pytest

from sinslab.core.errors import InputError
from sinslab.estimation import montecarlo as mc

cloudpickle.register_pickle_by_value(sys.modules[__name__])   # workers need not import tests/


def draws(seeds, scale=1.0):
    return {"x": np.stack([scale * np.random.default_rng(s).standard_normal((3, 2)) for s in seeds]),
            "k": np.array([s.spawn_key[-1] for s in seeds])}


def moments(out):
    return {"x": out["x"], "x2": out["x"] ** 2, "k": out["k"]}


def pairwise(x):
    """Independent reference of the tree: recursive halving at the largest power of two
    below the length (the same tree as aligned power-of-two blocks, largest first)."""
    n = len(x)
    if n == 1:
        return x[0]
    h = 1 << ((n - 1).bit_length() - 1)
    return pairwise(x[:h]) + pairwise(x[h:])


def leftfold(x):
    out = x[0]
    for v in x[1:]:
        out = out + v
    return out


def test_tree_sum_is_pairwise_over_the_run_index():
    x = np.random.default_rng(5).standard_normal((77, 4)) * 10.0 ** np.arange(4)
    t = mc.tree_sum(x)
    # the remainder blocks are added left to right: 64 + 8 + 4 + 1 runs
    ref = leftfold([pairwise(x[0:64]), pairwise(x[64:72]), pairwise(x[72:76]), x[76]])
    assert np.array_equal(t, ref)
    assert np.array_equal(mc.tree_sum(x[:64]), pairwise(x[:64]))
    np.testing.assert_allclose(t, x.sum(0), rtol=1e-13)


def test_reduced_sums_do_not_depend_on_batches_tasks_or_workers():
    full = mc.run_campaign(draws, 45, 11, batch=4, scheduler="sync", progress=False)
    ref = mc.tree_sum(moments(full))
    assert ref["k"] == sum(range(45))              # every run counted once
    outs = [mc.run_campaign(draws, 45, 11, batch=b, scheduler="sync", progress=False, reduce=moments)
            for b in (1, 7, 45)]
    from distributed import LocalCluster
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=logging.CRITICAL) as cl:
        outs.append(mc.run_campaign(draws, 45, 11, batch=3, scheduler=cl.scheduler_address, progress=False,
                                    reduce=moments, task_seconds=1e-6))
        outs.append(mc.run_campaign(draws, 45, 11, batch=2, scheduler=cl.scheduler_address, progress=False,
                                    reduce=moments, task_seconds=1e3))
    for out in outs:
        assert set(out) == set(ref)
        for k in ref:
            assert np.array_equal(out[k], ref[k]), k


def test_tasks_group_batches_from_the_measured_cost():
    blocks = [(s, 10) for s in range(0, 200, 10)]
    # 0.1 s a run, 5 s a task: 50 runs = 5 batches, within 20 // (2 workers x 2) = 5
    assert [len(g) for g in mc._group_blocks(blocks, 0.1, 2, 2, 5.0)] == [5, 5, 5, 5]
    # a costly run: one batch a task; cheap runs: capped to keep 2 tasks per worker
    assert all(len(g) == 1 for g in mc._group_blocks(blocks, 10.0, 2, 2, 5.0))
    assert [len(g) for g in mc._group_blocks(blocks, 1e-6, 1, 2, 5.0)] == [10, 10]
    # a gap (runs found finished) ends a group
    gap = blocks[:3] + blocks[5:8]
    assert [[b[0] for b in g] for g in mc._group_blocks(gap, 1e-6, 1, 1, 5.0)] == [[0, 10, 20], [50, 60, 70]]


class Failing(Exception):
    pass


def failing_after(seeds, limit, calls):
    calls.append(seeds[0].spawn_key[-1])
    if seeds[0].spawn_key[-1] >= limit:
        raise Failing("stopped")
    return draws(seeds)


@pytest.mark.parametrize("reduce", [None, moments])
def test_store_keeps_finished_tasks_and_a_rerun_reuses_them(tmp_path, reduce):
    ref = mc.run_campaign(draws, 20, 4, batch=3, scheduler="sync", progress=False, reduce=reduce)
    calls = []
    with pytest.raises(Failing):
        mc.run_campaign(failing_after, 20, 4, batch=3, scheduler="sync", progress=False, reduce=reduce,
                        store=tmp_path, args=(9, calls))
    assert calls == [0, 3, 6, 9]
    assert sorted(f.name for f in tmp_path.glob("runs-*")) == [f"runs-{s:09d}-3.npz" for s in (0, 3, 6)]
    calls.clear()
    out = mc.run_campaign(failing_after, 20, 4, batch=3, scheduler="sync", progress=False, reduce=reduce,
                          store=tmp_path, args=(99, calls))
    assert calls == [9, 12, 15, 18]                   # only the runs not kept
    for k in ref:
        assert np.array_equal(out[k], ref[k]), k
    # another key (another configuration) or another batch: nothing reused
    calls.clear()
    mc.run_campaign(failing_after, 20, 4, batch=3, scheduler="sync", progress=False, reduce=reduce,
                    store=tmp_path, store_key="other", args=(99, calls))
    assert calls == list(range(0, 20, 3))


def dying_after(seeds, marker):
    if os.path.exists(marker) and seeds[0].spawn_key[-1] >= 4:
        os._exit(1)
    return draws(seeds)


def test_every_worker_lost_keeps_the_finished_runs(tmp_path):
    import dask
    import distributed  # noqa: F401 - its configuration must exist before it is overridden

    marker = tmp_path / "die"
    marker.touch()
    store = tmp_path / "store"
    ref = mc.run_campaign(draws, 12, 2, batch=2, scheduler="sync", progress=False, reduce=moments)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        with pytest.raises(InputError) as e:
            mc.run_campaign(dying_after, 12, 2, batch=2, n_workers=1, args=(str(marker),), progress=False,
                            auto_serial=False, reduce=moments, store=store)
    msg = str(e.value)
    assert "\n" not in msg and "lost its workers" in msg and f"kept in {store}" in msg
    kept = sorted(f.name for f in store.glob("runs-*"))
    assert "runs-000000000-2.npz" in kept and "runs-000000004-2.npz" not in kept
    marker.unlink()
    out = mc.run_campaign(dying_after, 12, 2, batch=2, scheduler="sync", args=(str(marker),), progress=False,
                          reduce=moments, store=store)
    for k in ref:
        assert np.array_equal(out[k], ref[k]), k


def square_dying_once(x, marker, stop=None):
    """Kills its worker the first time it runs (the marker file says so), then squares."""
    if os.path.exists(marker):
        os.unlink(marker)
        os._exit(1)
    return x * x


def test_map_tasks_inputs_survive_a_lost_worker(tmp_path):
    """The inputs of map_tasks on Dask are task results, not scattered data: when the only
    worker dies holding them, its restarted successor makes them again and every task
    completes (scattered data would be lost with it and the tasks fail)."""
    marker = tmp_path / "die"
    marker.touch()
    got = mc.map_tasks(square_dying_once, [np.arange(3.0), np.arange(4.0)], mode="processes", workers=1,
                       kwargs=dict(marker=str(marker)))
    assert not marker.exists()                        # a worker did die
    assert [g.tolist() for g in got] == [[0.0, 1.0, 4.0], [0.0, 1.0, 4.0, 9.0]]


def first_six_and_a_scalar(out):
    return {"x": out["x"][out["k"] < 6], "k": out["k"][out["k"] < 6]}


def test_rows_gathered_whole_beside_the_sums(tmp_path):
    """gather brings rows of some runs as they are, beside the tree sums: the same bytes as
    those runs of the gathered campaign in run order, the same sums whatever the batches,
    and a store written with them is read back whole."""
    full = mc.run_campaign(draws, 23, 3, batch=5, scheduler="sync", progress=False)
    ref = mc.tree_sum(moments(full))
    for b in (1, 4, 23):
        sums, rows = mc.run_campaign(draws, 23, 3, batch=b, scheduler="sync", progress=False, reduce=moments,
                                     gather=first_six_and_a_scalar, store=tmp_path / f"s{b}")
        assert all(np.array_equal(sums[k], ref[k]) for k in ref)
        assert np.array_equal(rows["x"], full["x"][:6]) and rows["k"].tolist() == list(range(6))
        again = mc.run_campaign(draws, 23, 3, batch=b, scheduler="sync", progress=False, reduce=moments,
                                gather=first_six_and_a_scalar, store=tmp_path / f"s{b}")
        assert np.array_equal(again[1]["x"], rows["x"]) and np.array_equal(again[0]["x"], sums["x"])
