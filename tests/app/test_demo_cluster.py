"""`sinslab demo` starts one Dask cluster for all its Monte Carlo campaigns, and hands its
runs without a campaign to that cluster's workers."""
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


def _demo_beside(tmp_path, monkeypatch, variants):
    mod = _module()
    mod.run = _run_beside
    mod.DEMO_VARIANTS = variants
    monkeypatch.setitem(sys.modules, mod.__name__, mod)
    E.register(mod)
    PLACES.clear()
    return CliRunner().invoke(app, ["demo", "--quick", "--only", "campaign-dummy", "--out", str(tmp_path / "runs")])


def test_demo_runs_without_a_campaign_go_to_the_workers(tmp_path, monkeypatch, threads_cluster):
    """The runs below CAMPAIGN_MIN_RUNS are Dask tasks on the demo's cluster, the campaign
    runs stay in the command; the summaries come in the order of the runs whatever order
    the runs end in, and every folder holds its completed run."""
    r = _demo_beside(tmp_path, monkeypatch, {"single": ["runs=1"], "more": ["runs=4"], "one": ["runs=1", "seed=5"]})
    assert r.exit_code == 0, r.output
    assert threads_cluster == [None]
    assert PLACES == {(3, 0): "command", (1, 0): "worker", (4, 0): "command", (1, 5): "worker"}
    lines = [ln.split(":")[0] for ln in r.stdout.splitlines() if "claims passed" in ln]
    assert lines == ["campaign-dummy", "campaign-dummy-single", "campaign-dummy-more", "campaign-dummy-one"]
    for label in ("campaign-dummy-single", "campaign-dummy-one"):
        s = json.loads((tmp_path / "runs" / label / "summary.json").read_text())
        assert s["name"] == label and s["metrics"]["runs"] == 1
    assert not [p for p in (tmp_path / "runs").iterdir() if p.name.startswith(".")]


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
    assert "campaign-dummy-single: 1/1 claims passed" in r.stdout
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
