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

Batches are grouped into Dask tasks (``dask.distributed``) of a few seconds each, sized
from the measured cost of the first batch: by default on a ``LocalCluster`` of worker
processes on this machine (one thread each); ``scheduler=ADDRESS`` sends the same
campaign to an existing cluster, ``scheduler=client`` reuses a ``distributed.Client``,
and ``scheduler="sync"`` runs in this process without Dask (debugging).

Statistics need not travel as runs: with ``reduce=`` each task sums what the statistics
need over its runs, in a binary tree fixed by the run index (:func:`tree_sum`), and only
the tree's nodes reach this process, where they are merged as they arrive; the sums are
the same bytes whatever the batches, tasks or workers. With ``store=`` every finished
task is written to a folder as it ends, and a campaign started again on that folder
computes only the runs not found there.

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
import warnings
from dataclasses import dataclass

import numpy as np

from sinslab.core.atomic import atomic_path, atomic_write
from sinslab.core.errors import InputError

__all__ = ["spawn_seeds", "run_campaign", "tree_sum", "TASK_SECONDS", "dask_client", "map_tasks", "summarize", "Summary", "chi2_bounds",
           "ClusterError", "NO_WORKERS_S",
           "mean_ci95", "mean_ci95_sums", "wilson_ci95", "linear_batch", "summarize_sums"]


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
                 auto_serial=True, reduce=None, store=None, store_key="", task_seconds=None, gather=None):
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
        Runs per call of ``fn`` (default: about ``tasks_per_worker`` calls per worker, at
        most 64 runs). A task makes one or more consecutive calls (see ``task_seconds``).
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
        Extra arguments passed to every ``fn`` call (sent to the workers once, as the result
        of a task the scheduler can recompute when a worker holding them is lost).
    retries : int
        Re-run a task this many times if *it* raises (worker loss is handled by the
        scheduler regardless, since tasks are pure).
    tasks_per_worker : int
        Calls of ``fn`` per worker when ``batch`` is not given: several balance the load; 1
        suits a task function whose cost hardly depends on the number of runs it stacks.
    auto_serial : bool
        With ``scheduler=None``: run the first batch in this process, timed, and run the
        rest serially too when that is expected to take no longer than starting a local
        cluster (:data:`CLUSTER_START_S`) and sharing the rest among its workers; the
        decision is printed (stderr, not under ``SINSLAB_QUIET``). The batches are those
        the cluster would get, so the bytes are the same either way.
    reduce : callable, optional
        ``reduce(out)`` maps one call's output to a dict of per-run arrays (runs first) to
        be summed over the runs. The sums are formed where the runs were computed and
        merged in the fixed binary tree of :func:`tree_sum` over the run index, so only
        the tree's nodes travel to this process (a few per task) and the bytes depend
        neither on the batches, the tasks, the workers nor the order in which tasks end.
        Without it every run's output is gathered here.
    gather : callable, optional
        With ``reduce``: ``gather(out)`` maps one call's output to a dict of arrays whose
        rows are some of its runs, in run order, gathered here whole beside the sums — what
        is not a sum but stays small: a few runs drawn in a figure, a scalar per run for a
        median.
    store : path-like, optional
        Folder keeping each finished task's result (its tree nodes, or its runs' outputs
        without ``reduce``), written atomically as the task ends. A campaign started with
        the same ``store``, ``store_key``, runs, seed and batch takes the runs found there
        as done and computes only the others: a lost cluster or an interrupt loses only the
        tasks under way.
    store_key : str
        What else the stored results depend on (e.g. a digest of the configuration); a
        store written under another key is not reused.
    task_seconds : float, optional
        Aim of a task's duration [s] (default :data:`TASK_SECONDS`): from the measured
        cost of the first batch, a task takes as many consecutive batches as fit (at
        least one, and no more than would leave fewer than ``tasks_per_worker`` tasks per
        worker).

    Returns
    -------
    ndarray or dict of ndarray
        Without ``reduce``: the outputs of all runs concatenated along the first axis in
        run order. With ``reduce``: the sum over all runs of each of its arrays; with
        ``gather`` too, the pair ``(sums, gathered rows concatenated in run order)``.
    """
    kwargs = dict(kwargs or {})
    seeds = spawn_seeds(seed, n_runs)
    n = len(seeds)
    if reduce is not None and gather is not None:
        reduce = _Gathering(reduce, gather)
    acc = _Collected(n, reduce)
    per_run = None
    nw = int(n_workers or os.cpu_count() or 1)
    if scheduler is None:
        batch = _default_batch(n, nw, tasks_per_worker) if batch is None else batch
        _check_batch(batch)
    st = None

    def open_store(batch):
        nonlocal st
        if store is None or st is not None:
            return
        st = _Store(store, dict(n_runs=n, seed=_seed_words(seed), batch=int(batch), reduce=reduce is not None,
                                gather=gather is not None, key=str(store_key)))
        for first, count, payload in st.load():
            acc.add(first, count, payload)
        if acc.done:
            _say(f"Monte Carlo: {acc.done} of {n} runs found finished in {st.path}")

    if scheduler is None:
        open_store(batch)
    if scheduler is None and auto_serial and acc.done < n:
        # a cluster of our own: the batches it would get, and whether it pays for its
        # start-up, judged from the first batch run here (the same batches either way)
        b0 = _first_missing(acc, n, int(batch))
        blk = (b0, min(int(batch), n - b0))
        t0 = time.perf_counter()
        payload = _run_task(fn, [blk], seeds[blk[0]:blk[0] + blk[1]], args, kwargs, reduce)
        per_run = (time.perf_counter() - t0) / blk[1]
        acc.add(b0, blk[1], payload)
        if st is not None:
            st.save(b0, blk[1], payload)
        rest = n - acc.done
        serial_s, cluster_s = rest * per_run, CLUSTER_START_S + rest * per_run / nw
        if rest and serial_s <= cluster_s:
            scheduler = "sync"
        if rest:
            _say(f"Monte Carlo: {n} runs at {per_run * 1e3:.3g} ms each: "
                 + (f"serial in this process (~{serial_s:.3g} s; a {nw}-worker local cluster "
                    f"~{cluster_s:.3g} s with its start-up)" if scheduler == "sync" else
                    f"on a {nw}-worker local cluster (~{cluster_s:.3g} s with its start-up; serial "
                    f"~{serial_s:.3g} s)"))
    with dask_client(scheduler if (scheduler is not None or acc.done < n) else "sync", n_workers) as client:
        nw = 1 if client is None else max(1, len(client.scheduler_info().get("workers", {})) or 1)
        if batch is None:
            batch = _default_batch(n, nw, tasks_per_worker)
        _check_batch(batch)
        batch = int(batch)
        open_store(batch)
        from sinslab.core.progress import progress as _progress
        ctx = _progress("Monte Carlo", total=n, unit="runs") if progress else contextlib.nullcontext()
        with ctx as bar:
            if bar is not None and acc.done:
                bar.advance(acc.done)

            def finished(first, count, payload):
                acc.add(first, count, payload)
                if st is not None:
                    st.save(first, count, payload)
                if bar is not None:
                    bar.advance(count)

            blocks = [(s, min(batch, n - s)) for s in range(0, n, batch) if not acc.has(s)]
            if client is None:
                for blk in blocks:
                    finished(*blk, _run_task(fn, [blk], seeds[blk[0]:blk[0] + blk[1]], args, kwargs, reduce))
            elif blocks:
                # the shared inputs as the result of a task, not scattered data: a worker
                # that leaves with its copy costs a recomputation, not the campaign
                # (in the graph on purpose, so Dask's warning about a large graph is moot)
                with warnings.catch_warnings():
                    warnings.filterwarnings("ignore", message="Sending large graph")
                    a_f = client.submit(_inputs, args, kwargs, pure=False)

                def submit(group):
                    a, z = group[0][0], group[-1][0] + group[-1][1]
                    return client.submit(_run_task_timed, fn, group, seeds[a:z], a_f, reduce,
                                         pure=False, retries=retries)

                futs = {}

                def go(group):
                    f = submit(group)
                    futs[f] = (group[0][0], sum(c for _, c in group))

                def grouped(pending):
                    return _group_blocks(pending, per_run, nw, tasks_per_worker,
                                         TASK_SECONDS if task_seconds is None else task_seconds)

                try:
                    if per_run is None:
                        # a first wave of one batch per worker; the first to end, timed on
                        # its worker, sizes the tasks of the rest
                        pending = blocks[nw:]
                        for blk in blocks[:nw]:
                            go([blk])
                    else:
                        pending = []
                        for g in grouped(blocks):
                            go(g)
                    watch = _Watch(client, lambda: _finished_text(acc.done, n, st))
                    while futs:
                        for fut in watch.done(list(futs)):
                            first, count = futs.pop(fut)
                            payload, elapsed = watch.result(fut)
                            fut.release()
                            finished(first, count, payload)
                            if pending:
                                per_run = elapsed / count
                                for g in grouped(pending):
                                    go(g)
                                pending = []
                except Exception as e:                       # noqa: BLE001 - sorted below
                    if not _lost_cluster(e):
                        raise
                    raise ClusterError(f"Monte Carlo: the Dask cluster lost its workers ({type(e).__name__}); "
                                       f"{_finished_text(acc.done, n, st)}") from None
    return acc.result()


def _finished_text(done, n, store) -> str:
    """What a failed campaign leaves: the runs finished and where they are kept."""
    kept = (f"; they are kept in {store.path}, where a rerun of the same campaign resumes"
            if store is not None and done else "")
    return f"{done} of {n} runs had finished{kept}"


class ClusterError(InputError):
    """A Dask cluster that cannot run the work: no workers at its scheduler, every worker
    lost, the scheduler gone. One line saying what happened, what had finished and what
    to do."""


#: How long a campaign waits for a worker when its cluster has none [s]: workers started
#: beside the scheduler join within seconds; none in this time means none are coming.
NO_WORKERS_S = 30.0
#: How often a waiting campaign checks that its cluster still has workers [s].
WATCH_POLL_S = 2.0


class _Watch:
    """Waits for a cluster's futures, never forever: every :data:`WATCH_POLL_S` without a
    finished one it asks the scheduler for its workers, and with none for
    :data:`NO_WORKERS_S` (or the scheduler gone) raises :class:`ClusterError` naming the
    cluster, what to start and ``status()`` (what had finished)."""

    def __init__(self, client, status, work: str = "Monte Carlo"):
        self.client, self.status, self.work = client, status, work
        self.since = None
        self.had_workers = False
        self.gone = None

    def done(self, futs):
        """The finished futures among ``futs`` (at least one)."""
        from distributed import wait

        while True:
            try:
                finished, _ = wait(futs, timeout=WATCH_POLL_S, return_when="FIRST_COMPLETED")
                if finished:
                    return finished
            except TimeoutError:
                pass
            self.check()

    def result(self, fut):
        """``fut``'s result, waited for as :meth:`done` waits: a future the scheduler
        reports as lost (its worker left between computing and handing it over) is
        recomputed, and with no worker left to do it that is a :class:`ClusterError`,
        not a wait without end."""
        while True:
            try:
                return fut.result(timeout=WATCH_POLL_S)
            except TimeoutError:
                self.check()

    def workers(self) -> int:
        try:
            n = len(self.client.scheduler_info().get("workers", {}))
            self.gone = None
            return n
        except Exception as e:                               # noqa: BLE001 - the scheduler is gone
            self.gone = e
            return 0

    def check(self) -> None:
        now = time.monotonic()
        if self.workers():
            self.had_workers, self.since = True, None
            return
        self.since = now if self.since is None else self.since
        if now - self.since >= NO_WORKERS_S:
            raise ClusterError(f"{self.what()} (for {now - self.since:.0f} s); {self.status()}")

    def what(self) -> str:
        addr = _address(self.client)
        local = getattr(self.client, "cluster", None) is not None
        if self.gone is not None:
            return f"{self.work}: the Dask scheduler at {addr} no longer answers"
        if local:
            return (f"{self.work}: every worker of the local Dask cluster is gone (killed, or out of "
                    "memory?) and none came back")
        if self.had_workers:
            return (f"{self.work}: every worker of the Dask scheduler at {addr} has left; start workers "
                    f"with `dask worker {addr}` and run the same command again")
        return (f"{self.work}: the Dask scheduler at {addr} has no workers; start some with "
                f"`dask worker {addr}` (or run without a scheduler address, on a local cluster)")


def _address(client) -> str:
    try:
        return str(client.scheduler.address)
    except Exception:                                        # noqa: BLE001
        return "?"


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


#: Aim of a task's duration [s] when a campaign's batches are grouped into tasks from the
#: measured cost of its first batch: long enough that Dask's per-task cost (scheduling,
#: transfer of the result) is small beside it, short enough that a lost worker costs little.
TASK_SECONDS = 5.0


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


def _identity(x):
    return x


def _run_task(fn, blocks, seeds, args, kwargs, reduce):
    """One task: ``fn`` on each ``(first, count)`` block in turn (``seeds`` those of the
    blocks' whole range); without ``reduce`` their outputs concatenated, with it the tree
    nodes of the sums over the task's runs."""
    a = blocks[0][0]
    outs = [_run_batch(fn, s, seeds[s - a:s - a + c], args, kwargs)[1] for s, c in blocks]
    if reduce is None:
        return outs[0] if len(outs) == 1 else _concat(outs)
    tree = _TreeSum()
    for (s, c), out in zip(blocks, outs):
        for level, index, node in _dyadic_nodes(s, _contributions(reduce(out), c)):
            tree.add(level, index, node)
    nodes = tree.nodes
    if isinstance(reduce, _Gathering):
        for (s, c), out in zip(blocks, outs):
            nodes[(_GATHERED, s)] = reduce.rows(out)
    return nodes


#: Level of the entries of a task's tree nodes that carry rows gathered whole (``gather``),
#: keyed by the first run of their call, instead of sums.
_GATHERED = -1


class _Gathering:
    """A campaign's ``reduce`` with its ``gather``."""

    def __init__(self, reduce, gather):
        self.reduce, self.gather = reduce, gather

    def __call__(self, out):
        return self.reduce(out)

    def rows(self, out):
        d = self.gather(out)
        if not isinstance(d, dict) or not d:
            raise ValueError("a campaign's gather function must return a non-empty dict of arrays")
        return {k: np.asarray(v) for k, v in d.items()}


def _run_task_timed(fn, blocks, seeds, packed, reduce):
    t0 = time.perf_counter()
    payload = _run_task(fn, blocks, seeds, packed[0], packed[1], reduce)
    return payload, time.perf_counter() - t0


def _contributions(d, count):
    if not isinstance(d, dict) or not d:
        raise ValueError("a campaign's reduce function must return a non-empty dict of per-run arrays")
    out = {}
    for k, v in d.items():
        v = np.asarray(v, dtype=float)
        if v.ndim == 0 or v.shape[0] != count:
            raise ValueError(f"campaign reduce function returned {k!r} with shape {v.shape}; its first "
                             f"axis must be the {count} runs of the batch")
        out[k] = v
    return out


def _concat(outs):
    if isinstance(outs[0], dict):
        return {k: np.concatenate([o[k] for o in outs], axis=0) for k in outs[0]}
    return np.concatenate(outs, axis=0)


def _first_missing(acc, n, batch):
    return next(s for s in range(0, n, batch) if not acc.has(s))


def _group_blocks(blocks, per_run, nw, tasks_per_worker, seconds):
    """Consecutive ``(first, count)`` blocks grouped into tasks of about ``seconds`` at
    ``per_run`` seconds a run: at least one block each, at most as many as leave
    ``tasks_per_worker`` tasks to each of ``nw`` workers; a gap (runs already done) ends
    a group."""
    if not blocks:
        return []
    runs = max(1.0, float(seconds) / max(float(per_run), 1e-9))
    g = max(1, int(runs // blocks[0][1]))
    g = max(1, min(g, len(blocks) // max(1, nw * max(1, int(tasks_per_worker)))))
    groups, cur = [], []
    for blk in blocks:
        if cur and (len(cur) == g or cur[-1][0] + cur[-1][1] != blk[0]):
            groups.append(cur)
            cur = []
        cur.append(blk)
    return groups + [cur]


class _Collected:
    """The finished runs of a campaign: their outputs by first run, or the tree of sums."""

    def __init__(self, n, reduce):
        self.n, self.reduce = n, reduce
        self.parts, self.tree = {}, _TreeSum()
        self.mask = np.zeros(n, dtype=bool)

    @property
    def done(self):
        return int(self.mask.sum())

    def has(self, first):
        return bool(self.mask[first])

    def add(self, first, count, payload):
        if self.reduce is None:
            self.parts[first] = payload
        else:
            for (level, index), node in payload.items():
                if level == _GATHERED:
                    self.parts[index] = node
                else:
                    self.tree.add(level, index, node)
        self.mask[first:first + count] = True

    def result(self):
        if self.reduce is None:
            return _concat([self.parts[s] for s in sorted(self.parts)])
        sums = self.tree.total(self.n)
        if not isinstance(self.reduce, _Gathering):
            return sums
        return sums, _concat([self.parts[s] for s in sorted(self.parts)])


def _seed_words(seed):
    if isinstance(seed, np.random.SeedSequence):
        return [repr(seed.entropy), list(seed.spawn_key)]
    return int(seed)


class _Store:
    """A folder of finished tasks: ``campaign.json`` (what the results belong to) and one
    ``runs-<first>-<count>.npz`` per task, each written to a temporary name and renamed."""

    def __init__(self, path, manifest):
        import json
        from pathlib import Path

        self.path = Path(path)
        self.path.mkdir(parents=True, exist_ok=True)
        m = self.path / "campaign.json"
        text = json.dumps(manifest, sort_keys=True)
        old = m.read_text() if m.exists() else None
        if old != text:
            for f in self.path.glob("runs-*.npz"):
                f.unlink()
            atomic_write(m, text)

    def load(self):
        for f in sorted(self.path.glob("runs-*.npz")):
            try:
                first, count = (int(x) for x in f.stem.split("-")[1:3])
                with np.load(f) as z:
                    yield first, count, _unpack(dict(z))
            except (ValueError, OSError, KeyError):
                continue                       # unreadable: its runs are computed again

    def save(self, first, count, payload):
        f = self.path / f"runs-{first:09d}-{count}.npz"
        with atomic_path(f) as tmp, open(tmp, "wb") as fh:
            np.savez(fh, **_pack(payload))


def _pack(payload):
    if isinstance(payload, np.ndarray):
        return {"array": payload}
    if payload and isinstance(next(iter(payload)), tuple):
        return {f"node-{'rows' if lv == _GATHERED else lv}-{ix}-{k}": v for (lv, ix), d in payload.items()
                for k, v in d.items()}
    return {f"out-{k}": v for k, v in payload.items()}


def _unpack(z):
    if "array" in z:
        return z["array"]
    if any(k.startswith("node-") for k in z):
        nodes = {}
        for k, v in z.items():
            _, lv, ix, name = k.split("-", 3)
            nodes.setdefault((_GATHERED if lv == "rows" else int(lv), int(ix)), {})[name] = v
        return nodes
    return {k[4:]: v for k, v in z.items()}


# ----------------------------------------------------------------------------------------
# sums over runs in a fixed tree
# ----------------------------------------------------------------------------------------
class _TreeSum:
    """Nodes ``(level, index)`` of the binary tree over run indices: node (l, i) is the sum
    of runs ``[i 2^l, (i+1) 2^l)``, always formed as (left child) + (right child), with the
    single runs as leaves. Two siblings present are merged into their parent at once."""

    def __init__(self):
        self.nodes = {}

    def add(self, level, index, node):
        while (level, index ^ 1) in self.nodes:
            other = self.nodes.pop((level, index ^ 1))
            left, right = (other, node) if index & 1 else (node, other)
            node = {k: left[k] + right[k] for k in left}
            level, index = level + 1, index >> 1
        self.nodes[(level, index)] = node

    def total(self, n):
        """The sum over runs ``[0, n)``: its aligned nodes, largest (leftmost) first, added
        left to right."""
        out, pos = None, 0
        for level in range(int(n).bit_length() - 1, -1, -1):
            if n >> level & 1:
                node = self.nodes[(level, pos >> level)]
                out = dict(node) if out is None else {k: out[k] + node[k] for k in out}
                pos += 1 << level
        return out


def _dyadic_nodes(first, x):
    """The aligned tree nodes covering runs ``[first, first + len)`` of the per-run arrays
    ``x`` (dict of (count, ...)), each summed pairwise level by level."""
    count = len(next(iter(x.values())))
    pos, end = first, first + count
    while pos < end:
        level = (pos & -pos).bit_length() - 1 if pos else (end - pos).bit_length()
        while (1 << level) > end - pos:
            level -= 1
        blk = {k: v[pos - first:pos - first + (1 << level)] for k, v in x.items()}
        for _ in range(level):
            blk = {k: v[0::2] + v[1::2] for k, v in blk.items()}
        yield level, pos >> level, {k: v[0] for k, v in blk.items()}
        pos += 1 << level


def tree_sum(x):
    """Sum over the first axis of ``x`` (array or dict of arrays, runs first) in the fixed
    tree of :func:`run_campaign`'s ``reduce``: the same bytes as a campaign's sums however
    its runs were split into batches, tasks and workers.

    The tree pairs runs (0, 1), (2, 3), ... then those pairs, and so on (pairwise
    summation over aligned power-of-two blocks); the blocks left over at the end, largest
    first, are added left to right. Numpy's ``x.sum(0)`` adds the runs one after another,
    so the two differ in the last bits (a few units in the last place; the tree's rounding
    error grows as log2 of the runs instead of their number).

    Returns
    -------
    ndarray or dict of ndarray
    """
    d = x if isinstance(x, dict) else {"x": x}
    d = {k: np.asarray(v, dtype=float) for k, v in d.items()}
    n = len(next(iter(d.values())))
    tree = _TreeSum()
    for level, index, node in _dyadic_nodes(0, d):
        tree.add(level, index, node)
    out = tree.total(n)
    return out if isinstance(x, dict) else out["x"]


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
        if not _Watch(client, str).workers():
            _say(f"Monte Carlo: no workers at the Dask scheduler {_address(client)} yet; waiting up to "
                 f"{NO_WORKERS_S:g} s for some to join (start them with `dask worker {_address(client)}`)")
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
        with dask_client(scheduler or None, int(workers)) as client:
            # each input as the result of a task of its own (one object, its parts sharing
            # their arrays): unlike scattered data, the scheduler can make it again when the
            # worker holding it is lost
            with warnings.catch_warnings():
                warnings.filterwarnings("ignore", message="Sending large graph")
                sent = [client.submit(_identity, _Sent(x), pure=False) for x in items]
            futs = {client.submit(_call_sent, fn, f, pure=False, **kwargs): i for i, f in enumerate(sent)}
            n = len(futs)
            watch = _Watch(client, lambda: f"{n - len(futs)} of {n} tasks had finished", work="tasks")
            while futs:
                for fut in watch.done(list(futs)):
                    i = futs.pop(fut)
                    results[i] = fut.result()
                    if on_done is not None:
                        on_done(i, results[i])
    return results


# ----------------------------------------------------------------------------------------
# statistics
# ----------------------------------------------------------------------------------------
# Quantiles from scipy.special, the functions scipy.stats' t and chi2 evaluate (the same
# bits): scipy.stats takes ~35 MB to import, in every process and Dask worker that
# merely imports this module.
def _t975(df):
    """Student's t 0.975 quantile with ``df`` degrees of freedom."""
    from scipy.special import stdtrit

    return stdtrit(df, 0.975)


def _chi2_ppf(q, df):
    """χ² quantile ``q`` with ``df`` degrees of freedom (NaN where ``df`` <= 0)."""
    from scipy.special import gammaincinv

    df = np.asarray(df, dtype=float)
    return np.where(df > 0, 2 * gammaincinv(df / 2, q), np.nan)


def mean_ci95(x):
    """Mean of ``x`` over seeds and its 95 % confidence interval (Student t)."""
    x = np.asarray(x, float)
    m = float(x.mean())
    if x.size < 2:
        return m, [float("nan"), float("nan")]
    h = float(_t975(x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return m, [m - h, m + h]


def mean_ci95_sums(n, s1, s2, shift=0.0):
    """:func:`mean_ci95` of ``n`` values from the sums of ``x − shift`` (``s1``) and of its
    squares (``s2``); a shift near the mean keeps the spread's digits."""
    n = int(n)
    m = float(shift + s1 / n)
    if n < 2:
        return m, [float("nan"), float("nan")]
    sd = math.sqrt(max(float(s2 - s1 * s1 / n), 0.0) / (n - 1))
    h = float(_t975(n - 1) * sd / math.sqrt(n))
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
        lo = _chi2_ppf(alpha / 2, N * dof) / N
        hi = _chi2_ppf(1 - alpha / 2, N * dof) / N
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


def summarize_sums(n_runs, s1, s2, sigma=None):
    """:class:`Summary` (mean, RMS, σ; no NEES/NIS) from the sums over ``n_runs`` runs of
    the errors ``s1`` and of their squares ``s2`` (each (T, n), e.g. a campaign's
    ``reduce`` sums), with the filter σ ``sigma`` (T, n) if given.

    The mean is ``s1 / N`` and the RMS ``sqrt(s2 / N)``, as :func:`summarize` forms them
    from all runs (up to the order of the sums); the standard deviation (ddof=1) is
    ``sqrt((s2 - s1²/N) / (N - 1))``, which loses digits where the mean is far larger than
    the spread (:func:`summarize` subtracts the mean from each run first).
    """
    N = int(n_runs)
    if N < 2:
        raise ValueError("need at least 2 runs for Monte Carlo statistics")
    s1, s2 = np.asarray(s1, dtype=float), np.asarray(s2, dtype=float)
    mean = s1 / N
    std = np.sqrt(np.maximum(s2 - s1 * mean, 0.0) / (N - 1))
    sig = None if sigma is None else np.asarray(sigma, dtype=float)
    return Summary(N, mean, np.sqrt(s2 / N), std, sig, None, None, None, None, None, None)


# ----------------------------------------------------------------------------------------
# a linear-system campaign function
# ----------------------------------------------------------------------------------------
def linear_batch(seeds, Phi, Q, H, R, P0, n_steps, mask=None, x0_bias=None):
    """Simulate and filter a linear system for a batch of runs.

    Truth: ``x_0 ~ N(0, P0)`` (plus ``x0_bias``), ``x_{k+1} = Phi x_k + w_k``,
    ``w_k ~ N(0, Q)``; measurement ``z_k = H x_{k+1} + v_k``, ``v_k ~ N(0, R)`` where
    ``mask[k]``, vectorised across runs. The filter starts from ``x̂_0 = 0``, ``P0``.
    Because the gains of a linear filter do not depend on the data, the covariance is
    propagated once for the batch (:func:`sinslab.estimation.linear.propagate_covariance`
    with ``keep_gain``) and every run is filtered with those gains in one compiled loop
    (:func:`sinslab.estimation.linear.fixed_gain_runs`): the arithmetic of
    :mod:`sinslab.estimation.kernels`, as in every filter of the package.

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
    from sinslab.estimation import linear

    Phi, Q, H, R, P0 = (np.asarray(a, dtype=float) for a in (Phi, Q, H, R, P0))
    n, m, K, B = Phi.shape[0], H.shape[0], int(n_steps), len(seeds)
    mask = np.ones(K, dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    # gains and covariances (shared by the batch), stepped with the estimation kernels
    cov = linear.propagate_covariance(P0, Phi, Q, H, R, n_steps=K, mask=mask, save_at=np.arange(K + 1),
                                      keep_gain=True)
    Ps = cov.P_saved
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
    # the truth and its measurements
    xt = np.empty((B, K + 1, n))
    xt[:, 0] = x0
    z = np.zeros((B, K, m))
    for k in range(K):
        xt[:, k + 1] = xt[:, k] @ Phi.T + W[:, k]
        if mask[k]:
            z[:, k] = xt[:, k + 1] @ H.T + V[:, k]
    # the filter of every run from x̂_0 = 0 with the common gains
    xe, nu = linear.fixed_gain_runs(np.zeros((B, n)), Phi, H, cov.gain, z, mask=mask)
    err = xe - xt
    nis = np.zeros((B, K))
    for k in np.flatnonzero(mask):
        nis[:, k] = np.einsum("bi,ij,bj->b", nu[:, k], np.linalg.inv(cov.S[k]), nu[:, k])
    Pinv = np.linalg.pinv(Ps, hermitian=True)
    nees = np.einsum("bti,tij,btj->bt", err, Pinv, err)
    sigma = np.broadcast_to(np.sqrt(np.diagonal(Ps, axis1=1, axis2=2)), (B, K + 1, n)).copy()
    return {"err": err, "sigma": sigma, "nees": nees, "nis": nis}
