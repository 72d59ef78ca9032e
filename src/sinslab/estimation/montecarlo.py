"""Monte Carlo campaigns on Dask, and their statistics.

A campaign is ``n_runs`` independent runs. Run ``i`` always gets the ``i``-th child of
``numpy.random.SeedSequence(seed).spawn(n_runs)``, whatever the partition into batches
and whatever the number of workers, so the same seed gives the same runs with 1, 2 or 4
workers and after a worker is lost and its tasks re-run. The bytes are the same too when
the batches are (``batch=``), or when ``fn``'s arithmetic per run does not depend on how
many runs it stacks (the default batch size follows the number of workers; stacked
matrix products may round differently for one run than for several, ~1e-13 relative).

The user supplies ``fn(seeds, *args, **kwargs)``: given a list of ``SeedSequence``
(one per run of the batch) it returns either an array whose first axis is the run, or a
dict of such arrays. Small filters should be vectorised across the runs of a batch
(see :func:`linear_batch`). ``fn`` must be pure: its output depends only on its inputs.

Batches are Dask tasks (``dask.distributed``): by default a ``LocalCluster`` of worker
processes on this machine (one thread each); ``scheduler=ADDRESS`` sends the same
campaign to an existing cluster, ``scheduler=client`` reuses a ``distributed.Client``,
and ``scheduler="sync"`` runs in this process without Dask (debugging).

:func:`summarize` turns error histories into mean, RMS and σ versus time, the filter σ,
and NEES / NIS with their chi-square acceptance bounds.
"""
from __future__ import annotations

import contextlib
import logging
import math
import os
import sys
import time
from dataclasses import dataclass

import numpy as np
from scipy import stats

from sinslab.core.errors import InputError

__all__ = ["spawn_seeds", "run_campaign", "dask_client", "map_tasks", "summarize", "Summary", "chi2_bounds",
           "mean_ci95", "wilson_ci95", "linear_batch"]


def spawn_seeds(seed, n_runs):
    """The per-run seed sequences of a campaign: ``SeedSequence(seed).spawn(n_runs)``.

    Parameters
    ----------
    seed : int or numpy.random.SeedSequence
        Campaign seed.
    n_runs : int
        Number of runs.

    Returns
    -------
    list of numpy.random.SeedSequence, length n_runs
        Child ``i`` belongs to run ``i``.
    """
    if not isinstance(n_runs, (int, np.integer)) or n_runs < 1:
        raise ValueError(f"n_runs must be a positive integer, got {n_runs!r}")
    ss = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    return ss.spawn(int(n_runs))


def _run_batch(fn, first, seeds, args, kwargs):
    out = fn(seeds, *args, **kwargs)
    b = len(seeds)
    if isinstance(out, dict):
        for k, v in out.items():
            v = np.asarray(v)
            if v.ndim == 0 or v.shape[0] != b:
                raise ValueError(f"campaign function returned {k!r} with shape {v.shape}; its first "
                                 f"axis must be the {b} runs of the batch")
        return first, {k: np.asarray(v) for k, v in out.items()}
    out = np.asarray(out)
    if out.ndim == 0 or out.shape[0] != b:
        raise ValueError(f"campaign function returned shape {out.shape}; first axis must be the "
                         f"{b} runs of the batch")
    return first, out


def run_campaign(fn, n_runs, seed, *, batch=None, scheduler=None, n_workers=None,
                 progress=True, args=(), kwargs=None, retries=0, tasks_per_worker=4,
                 auto_serial=True):
    """Run ``n_runs`` independent runs of ``fn`` in batches on Dask.

    Parameters
    ----------
    fn : callable
        ``fn(seeds, *args, **kwargs)`` with ``seeds`` a list of SeedSequence (one per run
        in the batch); returns an array (runs first) or a dict of such arrays. Must be
        importable or picklable by cloudpickle, and pure.
    n_runs : int
        Number of runs.
    seed : int or SeedSequence
        Campaign seed; run ``i`` uses ``spawn_seeds(seed, n_runs)[i]``.
    batch : int, optional
        Runs per task (default: about ``tasks_per_worker`` tasks per worker, at most 64
        runs).
    scheduler : None, str or distributed.Client
        None: start a LocalCluster of ``n_workers`` processes (1 thread each) for this
        campaign and close it after; an address string (``"tcp://host:8786"``): connect to
        that cluster; a Client: use it; ``"sync"``: run serially in this process.
    n_workers : int, optional
        Workers of the local cluster (default: number of CPUs, at least 1).
    progress : bool
        Show a progress bar (via :mod:`sinslab.core.progress`: only on a terminal, silenced by
        ``SINSLAB_QUIET=1``).
    args, kwargs
        Extra arguments passed to every ``fn`` call (sent to the workers once).
    retries : int
        Re-run a task this many times if *it* raises (worker loss is handled by the
        scheduler regardless, since tasks are pure).
    tasks_per_worker : int
        Tasks per worker when ``batch`` is not given: several balance the load; 1 suits a
        task function whose cost hardly depends on the number of runs it stacks.
    auto_serial : bool
        With ``scheduler=None``: run the first batch in this process, timed, and run the
        rest serially too when that is expected to take no longer than starting a local
        cluster (:data:`CLUSTER_START_S`) and sharing the rest among its workers; the
        decision is printed (stderr, not under ``SINSLAB_QUIET``). The batches are those
        the cluster would get, so the bytes are the same either way.

    Returns
    -------
    ndarray or dict of ndarray
        The outputs of all runs concatenated along the first axis in run order.
    """
    kwargs = dict(kwargs or {})
    seeds = spawn_seeds(seed, n_runs)
    n = len(seeds)
    parts = {}
    if scheduler is None and auto_serial:
        # a cluster of our own: the batches it would get, and whether it pays for its
        # start-up, judged from the first batch run here (the same batches either way)
        nw = int(n_workers or os.cpu_count() or 1)
        batch = _default_batch(n, nw, tasks_per_worker) if batch is None else batch
        _check_batch(batch)
        b0 = min(int(batch), n)
        t0 = time.perf_counter()
        parts[0] = _run_batch(fn, 0, seeds[:b0], args, kwargs)[1]
        per_run = (time.perf_counter() - t0) / b0
        rest = n - b0
        serial_s, cluster_s = rest * per_run, CLUSTER_START_S + rest * per_run / nw
        if rest and serial_s <= cluster_s:
            scheduler = "sync"
        if rest:
            _say(f"Monte Carlo: {n} runs at {per_run * 1e3:.3g} ms each: "
                 + (f"serial in this process (~{serial_s:.3g} s; a {nw}-worker local cluster "
                    f"~{cluster_s:.3g} s with its start-up)" if scheduler == "sync" else
                    f"on a {nw}-worker local cluster (~{cluster_s:.3g} s with its start-up; serial "
                    f"~{serial_s:.3g} s)"))
    with dask_client(scheduler if (scheduler is not None or len(parts) < n) else "sync", n_workers) as client:
        nw = 1 if client is None else max(1, len(client.scheduler_info().get("workers", {})) or 1)
        if batch is None:
            batch = _default_batch(n, nw, tasks_per_worker)
        _check_batch(batch)
        batch = int(batch)
        starts = list(range(0, n, batch))
        from sinslab.core.progress import progress as _progress
        ctx = _progress("Monte Carlo", total=n, unit="runs") if progress else contextlib.nullcontext()
        with ctx as bar:
            if bar is not None and 0 in parts:
                bar.advance(min(batch, n))
            if client is None:
                for s in starts:
                    if s not in parts:
                        parts[s] = _run_batch(fn, s, seeds[s:s + batch], args, kwargs)[1]
                        if bar is not None:
                            bar.advance(len(seeds[s:s + batch]))
            else:
                from distributed import as_completed
                # the shared inputs as the result of a task, not scattered data: a worker
                # that leaves with its copy costs a recomputation, not the campaign
                a_f = client.submit(_inputs, args, kwargs, pure=False)
                futs = [client.submit(_run_packed, fn, s, seeds[s:s + batch], a_f,
                                      pure=False, retries=retries) for s in starts if s not in parts]
                try:
                    for fut in as_completed(futs):
                        s, out = fut.result()
                        parts[s] = out
                        if bar is not None:
                            bar.advance(len(seeds[s:s + batch]))
                except Exception as e:                       # noqa: BLE001 - sorted below
                    if not _lost_cluster(e):
                        raise
                    done = sum(len(seeds[s:s + batch]) for s in parts)
                    raise InputError(f"Monte Carlo: the Dask cluster lost its workers "
                                     f"({type(e).__name__}); {done} of {n} runs had finished") from None
    ordered = [parts[s] for s in starts]
    if isinstance(ordered[0], dict):
        keys = ordered[0].keys()
        return {k: np.concatenate([o[k] for o in ordered], axis=0) for k in keys}
    return np.concatenate(ordered, axis=0)


#: Allocator settings of the local cluster's worker processes, beside Dask's own
#: ``MALLOC_TRIM_THRESHOLD_`` (set before each worker starts, when glibc reads them). That
#: one alone switches off glibc's dynamic mmap threshold, leaving it at 128 KiB, so each
#: numpy temporary above it is mapped and unmapped afresh (page faults on every
#: allocation); fixing the threshold at glibc's own dynamic maximum (32 MiB) keeps them on
#: the heap. Same bytes; ``benchmarks/workers.py`` measures the worker CPU with and without.
WORKER_ENVIRON = {"MALLOC_MMAP_THRESHOLD_": 32 * 2 ** 20}


#: Seconds a local Dask cluster takes to start and load its workers' imports and kernels
#: on the 2-core development machine (a campaign's first task on fresh workers included):
#: :func:`run_campaign` runs a campaign serially when that outweighs what the workers save.
CLUSTER_START_S = 10.0


def _default_batch(n, nw, tasks_per_worker):
    return int(min(64, max(1, -(-n // (max(1, int(tasks_per_worker)) * nw)))))


def _check_batch(batch):
    if int(batch) < 1:
        raise ValueError(f"batch must be >= 1, got {batch}")


def _say(text):
    """A status line on stderr (not under ``SINSLAB_QUIET`` or the command line's --quiet)."""
    from sinslab.core import progress

    if os.environ.get("SINSLAB_QUIET", "") in ("", "0") and not getattr(progress, "_quiet_override", False):
        print(f"sinslab: {text}", file=sys.stderr, flush=True)


def _inputs(args, kwargs):
    return args, kwargs


def _run_packed(fn, first, seeds, packed):
    return _run_batch(fn, first, seeds, packed[0], packed[1])


def _lost_cluster(e) -> bool:
    """True for the errors of a cluster that lost its workers or its scheduler (not of the
    task function, whose own exceptions Dask re-raises as they are)."""
    try:
        from distributed import KilledWorker
        from distributed.comm.core import CommClosedError
    except ImportError:          # pragma: no cover
        return False
    import asyncio
    return isinstance(e, (KilledWorker, CommClosedError, asyncio.CancelledError, TimeoutError))


@contextlib.contextmanager
def dask_client(scheduler=None, n_workers=None):
    """The Dask client of a campaign, closed (quietly if the work failed) on exit.

    Parameters
    ----------
    scheduler : None, str or distributed.Client
        None: a ``LocalCluster`` of ``n_workers`` processes (one thread each, no
        dashboard) started for the ``with`` block; an address string: connect to that
        scheduler (one-line :class:`InputError` if it cannot be reached); a Client: used
        as it is and left open; ``"sync"``: no Dask, yields None.
    n_workers : int, optional
        Workers of the local cluster (default: number of CPUs).

    Yields
    ------
    distributed.Client or None
    """
    if scheduler == "sync":
        yield None
        return
    from distributed import Client, LocalCluster

    own = None
    if scheduler is None:
        nw = int(n_workers or os.cpu_count() or 1)
        import dask

        env = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}), **WORKER_ENVIRON}
        with _interrupts_to_this_process(), dask.config.set({"distributed.nanny.pre-spawn-environ": env}):
            # no dashboard; the scheduler's own HTTP routes on a free local port, not on the
            # dashboard's 8787 (taken by another cluster: a warning on every start)
            cluster = LocalCluster(n_workers=nw, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.CRITICAL,
                                   scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
            client = Client(cluster)
        own = (client, cluster)
    elif isinstance(scheduler, str):
        client = _connect(scheduler)
        own = (client, None)
    else:
        client = scheduler
    failed = False
    try:
        yield client
    except BaseException:
        failed = True
        raise
    finally:
        if own is not None:
            log = logging.getLogger("distributed")
            level = log.level
            if failed:                      # interrupted or failed: shut down quietly
                log.setLevel(logging.CRITICAL)
            try:
                own[0].close()
                if own[1] is not None:
                    own[1].close()
            finally:
                log.setLevel(level)


#: seconds to wait for a Dask scheduler given by address
CONNECT_TIMEOUT_S = 10.0


def _connect(address: str):
    """A ``distributed.Client`` of the scheduler at ``address``; InputError (one line)
    if it cannot be reached within :data:`CONNECT_TIMEOUT_S` or the address is malformed."""
    from distributed import Client

    try:
        return Client(address, timeout=f"{CONNECT_TIMEOUT_S:g}s")
    except (OSError, TimeoutError, ValueError) as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise InputError(f"Dask scheduler {address!r}: cannot connect ({msg})") from None


@contextlib.contextmanager
def _interrupts_to_this_process():
    """Ignore SIGINT while worker processes are started, so that they inherit the ignored
    disposition (kept across ``exec``): Ctrl-C, which the terminal sends to the whole
    process group, then stops only this process, which shuts the cluster down without
    worker tracebacks. A Ctrl-C during the start-up itself is ignored."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


# ----------------------------------------------------------------------------------------
# independent tasks of unequal size
# ----------------------------------------------------------------------------------------
@dataclass
class _Sent:
    """One task's input shipped to a worker as one object (its parts keep sharing the
    arrays they share here)."""

    item: object


def _call_sent(fn, sent, **kwargs):
    return fn(sent.item, **kwargs)


def map_tasks(fn, items, *, mode="threads", workers=2, scheduler=None, kwargs=None, on_done=None):
    """``fn(item, **kwargs)`` for independent items, concurrently; results in item order.

    Unlike :func:`run_campaign` (many equal runs from seeds), the tasks here are few and
    of unequal size: they are handed out in the order of ``items`` (put the long ones
    first), each to the next free worker. ``fn``'s result must not depend on where or
    beside which other tasks it runs, so the results do not depend on the mode or the
    number of workers.

    Parameters
    ----------
    fn : callable
        ``fn(item, stop=None, **kwargs)``; in this process (``"threads"``, ``"serial"``)
        it is given ``stop``, a :class:`threading.Event` set when another task has failed
        or the main thread was interrupted, so that a long task can give up between two
        of its steps. Module level (picklable) for ``"processes"``.
    items : sequence
        One input per task.
    mode : {"threads", "processes", "serial"}
        A pool of threads in this process (for compiled kernels that release the GIL), a
        Dask local cluster of worker processes (or ``scheduler``), or one after another.
        With a single item every mode runs it in this process.
    workers : int
        Threads or local worker processes.
    scheduler : str, optional
        Dask scheduler address for ``mode="processes"``.
    kwargs : dict, optional
        Further keyword arguments of every call (sent once per task to a process).
    on_done : callable, optional
        ``on_done(i, result)`` as task ``i`` completes (in any order; in the main thread
        except in ``"serial"`` and ``"threads"`` mode, where it runs beside the task).

    Returns
    -------
    list
        ``fn``'s results in the order of ``items``.
    """
    import threading

    items = list(items)
    kwargs = dict(kwargs or {})
    stop = threading.Event()
    results = [None] * len(items)

    def one(i):
        r = fn(items[i], stop=stop, **kwargs)
        if on_done is not None:
            on_done(i, r)
        return i, r

    if mode == "serial" or len(items) == 1:
        for i in range(len(items)):
            results[i] = one(i)[1]
    elif mode == "threads":
        from concurrent.futures import ThreadPoolExecutor, as_completed

        pool = ThreadPoolExecutor(max_workers=int(workers))
        try:
            for fut in as_completed([pool.submit(one, i) for i in range(len(items))]):
                i, r = fut.result()
                results[i] = r
        except BaseException:
            # an interrupt reaches the main thread only, a failed task only its future:
            # either way the other tasks end at their next check of ``stop``
            stop.set()
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
    else:
        from distributed import as_completed

        with dask_client(scheduler or None, int(workers)) as client:
            # large inputs are sent once rather than inside the task graph, each as one object
            sent = client.scatter([_Sent(x) for x in items], hash=False)
            futs = {client.submit(_call_sent, fn, f, pure=False, **kwargs): i for i, f in enumerate(sent)}
            for fut in as_completed(futs):
                i = futs[fut]
                results[i] = fut.result()
                if on_done is not None:
                    on_done(i, results[i])
    return results


# ----------------------------------------------------------------------------------------
# statistics
# ----------------------------------------------------------------------------------------
def mean_ci95(x):
    """Mean of ``x`` over seeds and its 95 % confidence interval (Student t)."""
    x = np.asarray(x, float)
    m = float(x.mean())
    if x.size < 2:
        return m, [float("nan"), float("nan")]
    h = float(stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return m, [m - h, m + h]


def wilson_ci95(k, n):
    """95 % Wilson score interval of a probability from ``k`` successes in ``n`` trials."""
    z = 1.959963984540054
    p = k / n
    c = (p + z * z / (2 * n)) / (1 + z * z / n)
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return [max(0.0, c - h), min(1.0, c + h)]


def chi2_bounds(dof, n_runs, alpha=0.05):
    """Two-sided acceptance bounds of the run-averaged NEES or NIS.

    Under consistency ``n_runs * mean`` is chi-square with ``n_runs * dof`` degrees of
    freedom; the bounds are ``chi2.ppf([alpha/2, 1-alpha/2], n_runs*dof) / n_runs``.

    Returns
    -------
    lo, hi : ndarray (broadcast of ``dof``)
    """
    dof = np.asarray(dof, dtype=float)
    N = float(n_runs)
    with np.errstate(invalid="ignore"):
        lo = stats.chi2.ppf(alpha / 2, N * dof) / N
        hi = stats.chi2.ppf(1 - alpha / 2, N * dof) / N
    lo = np.where(dof > 0, lo, 0.0)
    hi = np.where(dof > 0, hi, 0.0)
    return lo, hi


@dataclass(frozen=True)
class Summary:
    """Statistics of a Monte Carlo campaign versus time.

    Attributes
    ----------
    n_runs : int
    mean, rms, std : ndarray, shape (T, n)
        Across-run mean, root-mean-square and standard deviation (ddof=1) of each error.
    sigma : ndarray, shape (T, n) or None
        Filter σ (RMS across runs of each run's σ when given per run).
    nees, nees_bounds : ndarray (T,), tuple of (T,) or None
        Run-averaged NEES and its chi-square bounds (dof = n).
    nees_inside : float or None
        Fraction of epochs whose averaged NEES is within the bounds.
    nis, nis_bounds, nis_inside : likewise for the NIS (dof = measured components).
    """

    n_runs: int
    mean: np.ndarray
    rms: np.ndarray
    std: np.ndarray
    sigma: np.ndarray | None
    nees: np.ndarray | None
    nees_bounds: tuple | None
    nees_inside: float | None
    nis: np.ndarray | None
    nis_bounds: tuple | None
    nis_inside: float | None

    def rms_over_sigma(self):
        """Ratio RMS / filter σ, shape (T, n) (NaN where σ = 0)."""
        if self.sigma is None:
            raise ValueError("no filter sigma in this summary")
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.sigma > 0, self.rms / self.sigma, np.nan)


def summarize(err, *, sigma=None, P=None, nees=None, nis=None, nis_dof=None, alpha=0.05):
    """Monte Carlo statistics of estimation errors.

    Parameters
    ----------
    err : array_like, shape (N, T, n)
        Estimation error (estimate − truth) of N runs at T epochs, n states.
    sigma : array_like, shape (T, n) or (N, T, n), optional
        Filter standard deviations.
    P : array_like, shape (T, n, n) or (N, T, n, n), optional
        Filter covariances; if given and ``nees`` is not, the NEES is computed.
    nees : array_like, shape (N, T), optional
        Per-run NEES ``e^T P^-1 e``.
    nis : array_like, shape (N, K), optional
        Per-run NIS (0 or NaN where nothing was measured).
    nis_dof : int or array_like, shape (K,), optional
        Measured components per step (default: the measurement size is unknown, so the
        NIS is summarised only when given).
    alpha : float
        Significance of the two-sided chi-square bounds.

    Returns
    -------
    Summary
    """
    err = np.asarray(err, dtype=float)
    if err.ndim != 3:
        raise ValueError(f"err must have shape (runs, epochs, states), got {err.shape}")
    N, T, n = err.shape
    if N < 2:
        raise ValueError("need at least 2 runs for Monte Carlo statistics")
    mean = err.mean(0)
    rms = np.sqrt((err ** 2).mean(0))
    std = err.std(0, ddof=1)
    sig = None
    if sigma is not None:
        sigma = np.asarray(sigma, dtype=float)
        if sigma.shape == (N, T, n):
            sig = np.sqrt((sigma ** 2).mean(0))
        elif sigma.shape == (T, n):
            sig = sigma
        else:
            raise ValueError(f"sigma must have shape ({T}, {n}) or ({N}, {T}, {n}), got {sigma.shape}")
    if nees is None and P is not None:
        P = np.asarray(P, dtype=float)
        if P.shape == (T, n, n):
            Pinv = np.linalg.pinv(P, hermitian=True)
            nees = np.einsum("nti,tij,ntj->nt", err, Pinv, err)
        elif P.shape == (N, T, n, n):
            Pinv = np.linalg.pinv(P, hermitian=True)
            nees = np.einsum("nti,ntij,ntj->nt", err, Pinv, err)
        else:
            raise ValueError(f"P must have shape ({T}, {n}, {n}) or ({N}, {T}, {n}, {n}), got {P.shape}")
    nees_m = nees_b = nees_in = None
    if nees is not None:
        nees = np.asarray(nees, dtype=float)
        if nees.shape != (N, T):
            raise ValueError(f"nees must have shape ({N}, {T}), got {nees.shape}")
        nees_m = nees.mean(0)
        nees_b = chi2_bounds(n, N, alpha)
        nees_b = (np.full(T, nees_b[0]), np.full(T, nees_b[1]))
        nees_in = float(np.mean((nees_m >= nees_b[0]) & (nees_m <= nees_b[1])))
    nis_m = nis_b = nis_in = None
    if nis is not None and nis_dof is not None:
        nis = np.asarray(nis, dtype=float)
        if nis.ndim != 2 or nis.shape[0] != N:
            raise ValueError(f"nis must have shape ({N}, K), got {nis.shape}")
        dof = np.broadcast_to(np.asarray(nis_dof, dtype=float), (nis.shape[1],))
        nis_m = np.zeros(nis.shape[1])
        on = dof > 0
        nis_m[on] = nis[:, on].mean(0)
        lo, hi = chi2_bounds(dof, N, alpha)
        nis_b = (lo, hi)
        nis_in = float(np.mean((nis_m[on] >= lo[on]) & (nis_m[on] <= hi[on]))) if on.any() else None
    return Summary(N, mean, rms, std, sig, nees_m, nees_b, nees_in, nis_m, nis_b, nis_in)


# ----------------------------------------------------------------------------------------
# a vectorised linear-system campaign function
# ----------------------------------------------------------------------------------------
def linear_batch(seeds, Phi, Q, H, R, P0, n_steps, mask=None, x0_bias=None):
    """Simulate and filter a linear system for a batch of runs, vectorised across runs.

    Truth: ``x_0 ~ N(0, P0)`` (plus ``x0_bias``), ``x_{k+1} = Phi x_k + w_k``,
    ``w_k ~ N(0, Q)``; measurement ``z_k = H x_{k+1} + v_k``, ``v_k ~ N(0, R)`` where
    ``mask[k]``. The filter starts from ``x̂_0 = 0``, ``P0``. Because the gains of a
    linear filter do not depend on the data, the covariance is propagated once for the
    batch and the estimates of all runs are updated together.

    Each run draws its numbers from its own ``default_rng(seed)`` in a fixed order, so
    the outputs of a run do not depend on the batch it was in.

    Parameters
    ----------
    seeds : list of SeedSequence
    Phi, Q : array_like, shape (n, n)
    H : array_like, shape (m, n)
    R : array_like, shape (m, m)
    P0 : array_like, shape (n, n)
    n_steps : int
    mask : array_like of bool, shape (n_steps,), optional
        Steps with a measurement (default all).
    x0_bias : array_like, shape (n,), optional
        Mean of the true initial state (to test for biased filters).

    Returns
    -------
    dict
        ``err`` (B, K+1, n) estimate − truth; ``sigma`` (B, K+1, n) filter σ (identical
        rows); ``nees`` (B, K+1); ``nis`` (B, K) (0 where not measured).
    """
    Phi, Q, H, R, P0 = (np.asarray(a, dtype=float) for a in (Phi, Q, H, R, P0))
    n, m, K, B = Phi.shape[0], H.shape[0], int(n_steps), len(seeds)
    mask = np.ones(K, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    # gains and covariances (shared by the batch)
    P = P0.copy()
    Ps = np.empty((K + 1, n, n))
    Ps[0] = P
    gains = np.zeros((K, n, m))
    Sinv = np.zeros((K, m, m))
    for k in range(K):
        P = Phi @ P @ Phi.T + Q
        if mask[k]:
            S = H @ P @ H.T + R
            Si = np.linalg.inv(S)
            Kg = P @ H.T @ Si
            A = np.eye(n) - Kg @ H
            P = A @ P @ A.T + Kg @ R @ Kg.T
            gains[k], Sinv[k] = Kg, Si
        P = 0.5 * (P + P.T)
        Ps[k + 1] = P
    # per-run random draws, in a fixed order per run
    Lp = np.linalg.cholesky(P0) if np.all(np.linalg.eigvalsh(P0) > 0) else None
    x0 = np.empty((B, n))
    W = np.empty((B, K, n))
    V = np.empty((B, K, m))
    for b, s in enumerate(seeds):
        rng = np.random.default_rng(s)
        x0[b] = rng.multivariate_normal(np.zeros(n), P0) if Lp is None else Lp @ rng.standard_normal(n)
        W[b] = rng.multivariate_normal(np.zeros(n), Q, size=K, method="eigh")
        V[b] = rng.multivariate_normal(np.zeros(m), R, size=K)
    if x0_bias is not None:
        x0 += np.asarray(x0_bias, dtype=float)
    xt = x0
    xe = np.zeros((B, n))
    err = np.empty((B, K + 1, n))
    nis = np.zeros((B, K))
    err[:, 0] = xe - xt
    for k in range(K):
        xt = xt @ Phi.T + W[:, k]
        xe = xe @ Phi.T
        if mask[k]:
            z = xt @ H.T + V[:, k]
            nu = z - xe @ H.T
            xe = xe + nu @ gains[k].T
            nis[:, k] = np.einsum("bi,ij,bj->b", nu, Sinv[k], nu)
        err[:, k + 1] = xe - xt
    Pinv = np.linalg.pinv(Ps, hermitian=True)
    nees = np.einsum("bti,tij,btj->bt", err, Pinv, err)
    sigma = np.broadcast_to(np.sqrt(np.diagonal(Ps, axis1=1, axis2=2)), (B, K + 1, n)).copy()
    return {"err": err, "sigma": sigma, "nees": nees, "nis": nis}
