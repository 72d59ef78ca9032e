"""`sinslab demo` starts one Dask cluster for all its Monte Carlo campaigns."""
import contextlib
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
    replaced by ``client``; returns the exit code."""
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


def test_demo_without_campaigns_starts_no_cluster(tmp_path, monkeypatch):
    def no_cluster(*a, **k):
        raise AssertionError("a cluster was started")

    _demo(tmp_path, monkeypatch, no_cluster, DEMO_VARIANTS={}, QUICK={"runs": 1})
    assert SEEN == [(1, None)]
