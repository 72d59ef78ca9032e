"""Monte Carlo on Dask: determinism across workers and batches, worker loss, statistics."""
import logging
import os
import signal
import sys
import threading
import time

import cloudpickle
import numpy as np
import pytest

from sinslab.estimation import kalman as kf
from sinslab.estimation import linear as lin
from sinslab.estimation import montecarlo as mc

cloudpickle.register_pickle_by_value(sys.modules[__name__])   # workers need not import tests/


def _model():
    F = np.array([[0.0, 1.0], [0.0, -0.05]])
    Phi, Q = kf.discretize(F, np.diag([0.0, 0.02]), 1.0)
    H = np.array([[1.0, 0.0]])
    R = np.array([[0.5]])
    P0 = np.diag([4.0, 1.0])
    return Phi, Q, H, R, P0


def slow_batch(seeds, delay):
    """Pure per-run draws, slowed down so a worker can be killed mid-campaign."""
    time.sleep(delay)
    return np.stack([np.random.default_rng(s).standard_normal(5) for s in seeds])


def test_seeds_belong_to_runs_whatever_the_batching():
    a = mc.run_campaign(slow_batch, 10, 42, batch=3, scheduler="sync", kwargs=dict(delay=0))
    b = mc.run_campaign(slow_batch, 10, 42, batch=10, scheduler="sync", kwargs=dict(delay=0))
    c = np.stack([np.random.default_rng(s).standard_normal(5) for s in mc.spawn_seeds(42, 10)])
    assert np.array_equal(a, b) and np.array_equal(a, c)


def test_tasks_per_worker_sets_the_default_batch():
    """Without ``batch``: about ``tasks_per_worker`` tasks per worker (here one worker), the
    same runs in the same order either way."""
    sizes = []

    def counted(seeds):
        sizes.append(len(seeds))
        return slow_batch(seeds, 0)

    a = mc.run_campaign(counted, 10, 42, scheduler="sync", progress=False)
    assert sizes == [3, 3, 3, 1]
    sizes.clear()
    b = mc.run_campaign(counted, 10, 42, scheduler="sync", progress=False, tasks_per_worker=1)
    assert sizes == [10] and np.array_equal(a, b)


def test_same_seed_identical_for_1_2_4_workers():
    Phi, Q, H, R, P0 = _model()
    kw = dict(Phi=Phi, Q=Q, H=H, R=R, P0=P0, n_steps=50)
    ref = mc.run_campaign(mc.linear_batch, 24, 7, batch=5, scheduler="sync", kwargs=kw)
    for nw in (1, 2, 4):
        if nw == 2:
            # an existing cluster reached by its address (the --scheduler ADDRESS path)
            from distributed import LocalCluster
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                              dashboard_address=None, silence_logs=logging.CRITICAL) as cl:
                out = mc.run_campaign(mc.linear_batch, 24, 7, batch=5, progress=False,
                                      scheduler=cl.scheduler_address, kwargs=kw)
        else:
            out = mc.run_campaign(mc.linear_batch, 24, 7, batch=3 + nw, n_workers=nw,
                                  progress=False, kwargs=kw, auto_serial=False)
        for k in ref:
            assert np.array_equal(out[k], ref[k]), (nw, k)


def test_killed_worker_campaign_completes_identically():
    from distributed import Client, LocalCluster
    ref = mc.run_campaign(slow_batch, 16, 3, batch=2, scheduler="sync", kwargs=dict(delay=0))
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=logging.CRITICAL)
    client = Client(cluster)
    killed = []

    def kill():
        # wait until a worker is busy with a batch, then SIGKILL that worker's process
        deadline = time.time() + 20
        while time.time() < deadline:
            busy = {w: k for w, k in client.processing().items() if k}
            for nanny in cluster.workers.values():
                if nanny.worker_address in busy:
                    killed.append((nanny.process.process.pid, len(busy[nanny.worker_address])))
                    os.kill(nanny.process.process.pid, signal.SIGKILL)
                    return
            time.sleep(0.02)

    try:
        client.wait_for_workers(2, timeout=30)
        th = threading.Thread(target=kill)
        th.start()
        out = mc.run_campaign(slow_batch, 16, 3, batch=2, scheduler=client, progress=False,
                              kwargs=dict(delay=0.4))
        th.join()
    finally:
        client.close()
        cluster.close()
    assert killed and killed[0][1] > 0, "no busy worker was killed mid-campaign"
    assert np.array_equal(out, ref)


def test_linear_campaign_statistics_agree_with_covariance():
    Phi, Q, H, R, P0 = _model()
    K = 60
    mask = np.arange(K) % 3 == 0
    out = mc.run_campaign(mc.linear_batch, 400, 11, batch=100, scheduler="sync",
                          kwargs=dict(Phi=Phi, Q=Q, H=H, R=R, P0=P0, n_steps=K, mask=mask))
    cov = lin.propagate_covariance(P0, Phi, Q, H, R, mask=mask)
    # one covariance recursion (estimation's): the campaign's σ is the covariance run's, bit for bit
    np.testing.assert_array_equal(out["sigma"][0], cov.sigma)
    s = mc.summarize(out["err"], sigma=out["sigma"], nees=out["nees"], nis=out["nis"],
                     nis_dof=mask.astype(int))
    ratio = s.rms_over_sigma()
    assert 0.8 < ratio.min() and ratio.max() < 1.2, ratio
    assert s.nees_inside > 0.85 and s.nis_inside > 0.85
    lo, hi = mc.chi2_bounds(2, 400)
    assert lo < 2 < hi
    # a biased truth is caught by the NEES
    bad = mc.run_campaign(mc.linear_batch, 100, 11, batch=100, scheduler="sync",
                          kwargs=dict(Phi=Phi, Q=Q, H=H, R=R, P0=P0, n_steps=K, mask=mask,
                                      x0_bias=[10.0, 0.0]))
    sb = mc.summarize(bad["err"], nees=bad["nees"])
    assert sb.nees[0] > sb.nees_bounds[1][0]


def test_bad_campaign_output_is_an_error():
    with pytest.raises(ValueError, match="first axis"):
        mc.run_campaign(lambda seeds: np.zeros(3), 2, 0, batch=2, scheduler="sync")
    with pytest.raises(ValueError, match="n_runs"):
        mc.spawn_seeds(0, 0)


def _square_or_fail(x, stop=None, fail_on=None, seen=None):
    if x == fail_on:
        raise RuntimeError(f"task {x} failed")
    if stop is not None and seen is not None:
        # a long task checks ``stop`` between its steps: wait for the failure to be seen
        for _ in range(200):
            if stop.is_set():
                seen.append(x)
                return None
            time.sleep(0.01)
    return x * x


@pytest.mark.parametrize("mode", ["serial", "threads"])
def test_map_tasks_keeps_item_order(mode):
    """map_tasks: results in the order of the items whatever the completion order, and
    on_done sees every task once."""
    done = []
    got = mc.map_tasks(_square_or_fail, [5, 1, 4, 2, 3], mode=mode, workers=3,
                       on_done=lambda i, r: done.append((i, r)))
    assert got == [25, 1, 16, 4, 9]
    assert sorted(done) == [(0, 25), (1, 1), (2, 16), (3, 4), (4, 9)]


def test_map_tasks_failure_stops_the_others():
    """threads: a failing task's error reaches the caller and the tasks still running see
    ``stop`` set (they give up at their next check)."""
    seen = []
    with pytest.raises(RuntimeError, match="task 0 failed"):
        mc.map_tasks(_square_or_fail, [1, 0], mode="threads", workers=2, kwargs=dict(fail_on=0, seen=seen))
    assert seen == [1]


def test_quantiles_equal_scipy_stats_to_the_bit():
    """The Student-t and χ² quantiles of the confidence intervals and NEES/NIS bounds come
    from scipy.special (scipy.stats is not imported by a worker); they are the functions
    scipy.stats.t.ppf / chi2.ppf evaluate, so the bits agree, degrees of freedom from 1
    to 10⁶ and dof 0 (no state) bounded at 0."""
    from scipy import stats

    bits = lambda a: np.asarray(a, dtype=float).view(np.int64)
    df = np.r_[np.arange(1, 400), np.random.default_rng(3).uniform(0.5, 1e6, 400)]
    for q in (0.025, 0.975, 0.005, 0.995):
        assert np.array_equal(bits(mc._chi2_ppf(q, df)), bits(stats.chi2.ppf(q, df)))
    n = np.arange(1, 2000)
    assert np.array_equal(bits(mc._t975(n)), bits(stats.t.ppf(0.975, n)))
    lo, hi = mc.chi2_bounds(np.array([0.0, 1.0, 6.0, 21.0]), 200)
    assert lo[0] == hi[0] == 0.0
    assert np.array_equal(bits(hi[1:]), bits(stats.chi2.ppf(0.975, 200 * np.array([1.0, 6.0, 21.0])) / 200))
