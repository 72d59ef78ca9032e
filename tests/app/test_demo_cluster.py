"""`sinslab demo` starts one Dask cluster when a run has a Monte Carlo campaign, computes
its costliest run itself and hands every other run to that cluster's workers, one per free
worker, longest first."""
import contextlib
import json
import sys
import types

import pytest
from typer.testing import CliRunner

import sinslab.experiments as E
from sinslab.cli import app
from sinslab.experiments.base import Claim, ExperimentConfig, Metric, Result

SEEN = []


class _Config(ExperimentConfig):
    pass


def _run(cfg, ctx):
    # what a campaign experiment does with the scheduler it is given
    SEEN.append((cfg.runs, ctx.scheduler))
    return Result(metrics={"runs": cfg.runs},
                  claims=[Claim.at_most("ok", "runs are few", float(cfg.runs), 10.0)])


def _module():
    m = types.ModuleType("campaign_dummy")
    m.NAME = "campaign-dummy"
    m.PURPOSE = "test experiment with a Monte Carlo campaign"
    m.Config = _Config
    m.QUICK = {"runs": 3}
    m.METRICS = {"runs": Metric("-", "runs")}
    m.CAMPAIGN_MIN_RUNS = 2
    m.DEMO_VARIANTS = {"single": ["runs=1"], "more": ["runs=4"]}
    m.run = _run
    return m


@pytest.fixture(autouse=True)
def _registered_only_here():
    yield
    E.registry().pop("campaign-dummy", None)


def _demo(tmp_path, monkeypatch, client, **declared):
    """``sinslab demo --quick`` of the campaign dummy with ``montecarlo.dask_client``
    replaced by ``client`` and the module's names ``declared`` set; the command's result
    (its exit code checked)."""
    from sinslab.estimation import montecarlo as mc

    mod = _module()
    for k, v in declared.items():
        setattr(mod, k, v)
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    monkeypatch.setattr(mc, "dask_client", client)
    E.register(mod)
    SEEN.clear()
    r = CliRunner().invoke(app, ["demo", "--quick", "--only", "campaign-dummy", "--out", str(tmp_path / "runs")])
    assert r.exit_code == 0, r.output
    return r


def test_demo_shares_one_cluster_among_its_campaigns(tmp_path, monkeypatch):
    """The cluster is started once, when the first run with a campaign comes, and every
    campaign of the demo gets that same client; a run below CAMPAIGN_MIN_RUNS gets none."""
    starts = []

    @contextlib.contextmanager
    def fake_client(scheduler=None, n_workers=None):
        if scheduler is None:
            starts.append(n_workers)
            yield "the shared client"
        else:
            yield scheduler

    _demo(tmp_path, monkeypatch, fake_client)
    assert starts == [None]
    assert SEEN == [(3, "the shared client"), (1, None), (4, "the shared client")]
    assert (tmp_path / "runs" / "campaign-dummy-more" / "summary.json").is_file()


def test_demo_runs_the_longest_campaign_first_and_prints_in_run_order(tmp_path, monkeypatch):
    """Beside the shared cluster the runs go longest first by their declared CPU cost
    (LPT: the short ones fill the CPUs at the end); a run without a declared cost goes
    last; the summaries still come in the order of the runs."""
    @contextlib.contextmanager
    def fake_client(scheduler=None, n_workers=None):
        yield "the shared client" if scheduler is None else scheduler

    r = _demo(tmp_path, monkeypatch, fake_client, DEMO_COST_S={"more": 30.0, "single": 2.0})
    assert SEEN == [(4, "the shared client"), (1, None), (3, "the shared client")]
    lines = [ln.split(":")[0] for ln in r.stdout.splitlines() if "claims passed" in ln]
    assert lines == ["campaign-dummy", "campaign-dummy-single", "campaign-dummy-more"]


def test_demo_without_campaigns_starts_no_cluster(tmp_path, monkeypatch):
    def no_cluster(*a, **k):
        raise AssertionError("a cluster was started")

    _demo(tmp_path, monkeypatch, no_cluster, DEMO_VARIANTS={}, QUICK={"runs": 1})
    assert SEEN == [(1, None)]


# ------------------------------------------------- runs without a campaign on the workers
PLACES = {}
SCHEDULERS = {}


def _where(label):
    """Where this run computes: 'worker' inside a Dask task, 'command' otherwise."""
    try:
        from distributed import get_worker

        get_worker()
        return "worker"
    except ValueError:
        return "command"


def _run_beside(cfg, ctx):
    PLACES[(cfg.runs, cfg.seed)] = _where(ctx.name)
    SCHEDULERS[(cfg.runs, cfg.seed)] = ctx.scheduler if ctx.scheduler in (None, "sync") else "client"
    if cfg.seed == 13:
        raise RuntimeError("a broken run")
    return Result(metrics={"runs": cfg.runs},
                  claims=[Claim.at_most("ok", "runs are few", float(cfg.runs), 10.0)])


@pytest.fixture
def threads_cluster(monkeypatch):
    """``montecarlo.dask_client`` replaced by a Dask cluster of two worker threads in this
    process (the dummy experiment's module is importable there, unlike in a worker process)."""
    from distributed import Client, LocalCluster

    from sinslab.estimation import montecarlo as mc

    starts = []

    @contextlib.contextmanager
    def client(scheduler=None, n_workers=None):
        if scheduler is not None:
            yield scheduler
            return
        starts.append(n_workers)
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                          dashboard_address=None) as cl, Client(cl) as c:
            yield c

    monkeypatch.setattr(mc, "dask_client", client)
    return starts


def _demo_beside(tmp_path, monkeypatch, variants, **declared):
    mod = _module()
    mod.run = _run_beside
    mod.DEMO_VARIANTS = variants
    for k, v in declared.items():
        setattr(mod, k, v)
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    E.register(mod)
    PLACES.clear()
    SCHEDULERS.clear()
    return CliRunner().invoke(app, ["demo", "--quick", "--only", "campaign-dummy", "--out", str(tmp_path / "runs")])


def test_demo_computes_its_costliest_run_and_hands_the_others_to_the_workers(tmp_path, monkeypatch,
                                                                           threads_cluster):
    """Beside a cluster, the run with the highest declared cost computes in the command and
    every other run is a task on the workers, a campaign there computed serially (its
    scheduler ``"sync"``: a worker starts no cluster); the summaries come in the order of
    the runs whatever order the runs end in, and every folder holds its completed run."""
    r = _demo_beside(tmp_path, monkeypatch, {"single": ["runs=1"], "more": ["runs=4"], "one": ["runs=1", "seed=5"]},
                     DEMO_COST_S={"": 1.0, "single": 1.0, "more": 5.0, "one": 1.0})
    assert r.exit_code == 0, r.output
    assert threads_cluster == [None]
    assert PLACES == {(3, 0): "worker", (1, 0): "worker", (4, 0): "command", (1, 5): "worker"}
    assert SCHEDULERS == {(3, 0): "sync", (1, 0): None, (4, 0): "sync", (1, 5): None}
    lines = [ln.split(":")[0] for ln in r.stdout.splitlines() if "claims passed" in ln]
    assert lines == ["campaign-dummy", "campaign-dummy-single", "campaign-dummy-more", "campaign-dummy-one"]
    for label in ("campaign-dummy-single", "campaign-dummy-one"):
        s = json.loads((tmp_path / "runs" / label / "summary.json").read_text())
        assert s["name"] == label and s["metrics"]["runs"] == 1
    assert not [p for p in (tmp_path / "runs").iterdir() if p.name.startswith(".")]


class _Future:
    """A run's future that ends when the test says so."""

    def __init__(self):
        self.callbacks = []

    def add_done_callback(self, fn):
        self.callbacks.append(fn)

    def end(self):
        for fn in self.callbacks:
            fn(self)


class _Client:
    """Two one-thread workers; records what is submitted."""

    def __init__(self):
        self.submitted = []

    def subscribe_topic(self, topic, handler):
        pass

    def scheduler_info(self):
        return {"workers": {"tcp://a": {"nthreads": 1}, "tcp://b": {"nthreads": 1}}}

    def submit(self, fn, name, cfg, out, quick, variant, *, scheduler=None, pure=True, key=None):
        fut = _Future()
        self.submitted.append((key.removeprefix("sinslab-demo-"), scheduler, fut))
        return fut


def test_lanes_hand_out_one_run_per_free_worker_longest_first(tmp_path):
    """LPT list scheduling: the two longest runs go out at once, then one run each time a
    run ends, always the longest of those left (a stable order among equal costs); never
    more runs out than worker threads; a campaign's run computes serially (``"sync"``)."""
    from sinslab.cli import _DemoJob, _Lanes

    exp = types.SimpleNamespace(name="x")
    costs = {"a": 2.0, "b": 9.0, "c": 5.0, "d": 1.0, "e": 7.0, "f": 5.0}
    jobs = [_DemoJob(exp, label, (), cost) for label, cost in costs.items()]
    jobs[2].campaign = True
    client = _Client()
    _Lanes(client, jobs, tmp_path, quick=False)
    assert [k for k, _, _ in client.submitted] == ["b", "e"]
    running = {k: f for k, _, f in client.submitted}
    order = ["b", "e"]
    for ends in ["e", "b", "c", "f", "a", "d"]:
        running.pop(ends).end()
        new = [(k, f) for k, _, f in client.submitted if k not in order]
        assert len(new) <= 1
        for k, f in new:
            order.append(k)
            running[k] = f
        assert len(running) <= 2
    assert order == ["b", "e", "c", "f", "a", "d"]
    assert {k: s for k, s, _ in client.submitted} == {"a": None, "b": None, "c": "sync", "d": None, "e": None,
                                                      "f": None}
    assert all(job.remote and job.submitted.is_set() for job in jobs)


def test_demo_run_failing_on_a_worker_stops_nothing(tmp_path, monkeypatch, threads_cluster):
    """A run that fails on a worker: its traceback is printed, the index lists it, the
    exit status is 1, its folder keeps the previous run, and the others complete."""
    variants = {"single": ["runs=1"], "broken": ["runs=1", "seed=12"]}
    r = _demo_beside(tmp_path, monkeypatch, variants)
    assert r.exit_code == 0, r.output
    broken = tmp_path / "runs" / "campaign-dummy-broken"
    before = (broken / "summary.json").read_bytes()
    # the same folder again, now with the broken variant failing
    monkeypatch.setitem(variants, "broken", ["runs=1", "seed=13"])
    r = _demo_beside(tmp_path, monkeypatch, variants)
    assert r.exit_code == 1
    assert "RuntimeError: a broken run" in r.output
    assert (broken / "summary.json").read_bytes() == before
    assert "campaign-dummy-single: 1/1 claims passed" in r.stdout, r.output
    assert "campaign-dummy-broken" in (tmp_path / "runs" / "index.html").read_text()
    assert not [p for p in (tmp_path / "runs").iterdir() if p.name.startswith(".")]


def test_every_demo_run_declares_its_cost():
    """``DEMO_COST_S`` names exactly the runs of the experiment's demo (the default "" and
    its DEMO_VARIANTS suffixes), each with a positive number of seconds: a misspelt suffix
    would leave its run last, unnoticed. Only the package's own experiments: other test
    files register theirs in the same process."""
    own = [exp for exp in E.registry().values() if exp.module.startswith("sinslab.experiments.")]
    assert len(own) >= 7
    for exp in own:
        assert set(exp.demo_cost) == {"", *exp.variants}, exp.name
        assert all(v > 0 for v in exp.demo_cost.values()), exp.name
