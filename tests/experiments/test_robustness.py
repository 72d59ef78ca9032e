"""The robustness sweep (sinslab.experiments.sweep, sinslab.app.claims): readings and
thresholds on a claim, the labels, re-runs of a toy experiment under physics alternatives
at a reduced size, the section of summary.json and the report, and every experiment's
declared alternatives being configurations it accepts."""
import json
import types

import pytest

from sinslab.app.claims import Claim, robustness
from sinslab.app.config import ExperimentConfig, Field, Section, resolve
from sinslab.experiments import base, execute, get, names
from sinslab.experiments import sweep as S


# ------------------------------------------------------------------ labels of one claim
def test_readings_thresholds_and_labels():
    c = Claim.at_most("a", "error small", 0.09, 0.15, origin="paper")
    c.assume("bar", "0.15 (the project's)")
    c.with_limits("bar", {"0.2": 0.2})
    assert robustness(c)["label"] == "robust"
    c.with_limits("bar", {"the paper's 0.07": 0.07})
    r = robustness(c)
    assert r["label"] == "depends on: bar" and r["depends_on"] == ["bar"]
    assert [a["passed"] for a in r["alternatives"]] == [True, False]
    assert r["alternatives"][1]["how"] == "threshold" and r["default"] is True
    # a declared physics alternative not run: "not swept", unless a reading already flips it
    d = Claim.at_least("b", "x", 3.0, 2.0).assume("bar", "2")
    d.with_limits("bar", {"1": 1.0})
    assert robustness(d, pending=["onset"])["label"].startswith("not swept")
    assert robustness(c, pending=["onset"])["label"] == "depends on: bar"
    # by construction wins; nothing declared: "not varied"
    assert robustness(d.by_construction("rescaled"))["label"] == "decided by construction: rescaled"
    assert robustness(Claim.at_most("e", "x", 1, 2))["label"] == "not varied"
    with pytest.raises(ValueError, match="undeclared"):
        Claim.at_most("f", "x", 1, 2).vary("nope", "alt", 1, True)
    with pytest.raises(ValueError, match="<= or >="):
        Claim.within("g", "x", 1, 1, abs=0.1).with_limits("bar", {"x": 1})


def test_pairs_label_only_without_a_single_flip():
    """A reading taken in a re-run varies two assumptions: it names the label only when no
    single assumption changes the verdict."""
    from sinslab.app.claims import Alternative

    c = Claim.equals("h", "converge", [True], [True]).assume("horizon", "5 s").assume("scoring", "own")
    c.vary("scoring", "rotation vector", [True], True)
    c.alternatives.append(Alternative("horizon", "60 s; rotation vector", [False], False, "rerun",
                                      combined="scoring"))
    assert robustness(c)["label"] == "depends on: horizon with scoring"
    c.vary("scoring", "another", [False], False)
    assert robustness(c)["label"] == "depends on: scoring"


# ------------------------------------------------------------------ a toy experiment
class _Scn(Section):
    gain: float = Field(1.0, description="the physics")
    size: int = Field(100, description="the size: below 50 the toy's verdict flips")
    broken: bool = Field(False, description="raise in run")


class _Cfg(ExperimentConfig):
    scenario: _Scn = _Scn()


_RUNS = []


def _run(cfg, ctx):
    if cfg.scenario.broken:
        raise RuntimeError("boom")
    _RUNS.append((cfg.scenario.gain, cfg.scenario.size, ctx.claims_only))
    g, n = cfg.scenario.gain, cfg.scenario.size
    a = Claim.at_most("small", "gain at most 2", g, 2.0, origin="paper").assume("bar", "2 (the project's)")
    a.with_limits("bar", {"3": 3.0})
    b = Claim.at_least("big", "size at least 50", n, 50, origin="paper")
    return base.Result(metrics={}, claims=[a, b])


def _axes(cfg):
    return [base.Axis("gain", "1", {"1.5": ["scenario.gain=1.5"], "2.5": ["scenario.gain=2.5"],
                                    "same": ["scenario.gain=1"]}, claims=("small",),
                      reduced=("scenario.size=60",), readings=True),
            base.Axis("size", "100", {"40": ["scenario.size=40"]}, claims=("big",)),
            base.Axis("breakage", "none", {"broken": ["scenario.broken=true"]}, claims=("small",)),
            base.Axis("reduced too far", "100", {"1.2": ["scenario.gain=1.2"]}, claims=("big",),
                      reduced=("scenario.size=10",), in_demo=False)]


def _toy():
    m = types.ModuleType("robust_toy")
    m.NAME, m.PURPOSE, m.Config, m.run, m.ROBUSTNESS = "robust-toy", "toy", _Cfg, _run, _axes
    return base.Experiment.from_module(m)


def test_sweep_reruns_at_the_reduced_size_and_compares_like_with_like(tmp_path):
    exp = _toy()
    cfg = resolve(exp.config)
    _RUNS.clear()
    s = execute(exp, cfg, tmp_path / "r", robustness="full")
    rob = s["robustness"]
    assert rob["swept"] and rob["paper_claims"] == 2
    small, big = rob["claims"]["small"], rob["claims"]["big"]
    # re-runs: reduced default, 1.5, 2.5 at size 60 (the alternative equal to the default is
    # the reduced default itself: made once), 40 at full size, the broken one, the too-far ones
    reruns = [r for r in _RUNS if r[2]]
    assert (1.0, 60, True) in reruns and (1.5, 60, True) in reruns and (2.5, 60, True) in reruns
    assert len(reruns) == len(set(reruns)) and _RUNS[0] == (1.0, 100, False)
    by = {a["name"]: a for a in small["alternatives"]}
    assert by["2.5"]["passed"] is False and by["2.5"]["baseline"] is True and by["1.5"]["passed"] is True
    # the re-run's own reading of another bar, compared with the same reading of the reduced run
    assert by["2.5; 3"]["passed"] is True and by["2.5; 3"]["combined"] == "bar"
    # a failed re-run is undecided, with its error
    assert by["broken"]["passed"] is None and "boom" in by["broken"]["note"]
    assert small["label"] == "depends on: gain"
    # a reduction that decides otherwise shows as an assumption of its own
    assert any(a["assumption"] == S.SIZE and a["passed"] is False for a in big["alternatives"])
    assert "size" in big["depends_on"] and S.SIZE in big["depends_on"]
    assert [a["assumption"] for a in rob["axes"]] == ["gain", "size", "breakage", "reduced too far"]
    html = (tmp_path / "r" / "report.html").read_text()
    assert "id='robustness'" in html and "depends on: gain" in html
    on_disk = json.loads((tmp_path / "r" / "summary.json").read_text())["robustness"]
    assert on_disk["claims"]["small"]["label"] == "depends on: gain"


def test_without_the_sweep_the_physics_is_pending(tmp_path):
    exp = _toy()
    s = execute(exp, resolve(exp.config), tmp_path / "r")
    rob = s["robustness"]
    assert not rob["swept"] and rob["claims"]["small"]["label"].startswith("not swept")
    assert rob["claims"]["small"]["pending"] == ["gain", "breakage"]
    assert rob["paper_claims_robust"] == 0


def test_the_demo_leaves_out_the_axes_it_cannot_afford(tmp_path):
    exp = _toy()
    rob = execute(exp, resolve(exp.config), tmp_path / "r", robustness="demo")["robustness"]
    assert [a["assumption"] for a in rob["axes"]] == ["gain", "size", "breakage"]
    big = rob["claims"]["big"]
    assert big["pending"] == ["reduced too far"] and big["label"] == "depends on: size"
    assert all(a["assumption"] != S.SIZE for a in big["alternatives"])


def test_cli_prints_the_labels_and_the_robust_count(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from sinslab import experiments as E
    from sinslab.cli import app

    monkeypatch.setattr(E, "_registry", {**E.registry(), "robust-toy": _toy()})
    r = CliRunner().invoke(app, ["-q", "run", "robust-toy", "--robustness", "--out", str(tmp_path / "r")])
    assert r.exit_code == 0, r.output
    assert "(paper; depends on: gain)" in r.stdout
    assert "paper: 2 of 2 reproduced, 0 robust" in r.stdout and "robustness sweep" in r.stdout


# ------------------------------------------------------------------ the experiments' declarations
@pytest.mark.parametrize("name", [n for n in names() if n != "free-inertial"])
def test_every_alternative_is_a_configuration_the_experiment_accepts(name):
    """Each axis of each experiment (and of its demo variants) resolves at the sweep's and the
    demo's sizes; its default and source are stated."""
    exp = get(name)
    for sets in [()] + list(exp.variants.values()):
        cfg = resolve(exp.config, sets=list(sets))
        for ax in exp.axes(cfg):
            assert ax.default and ax.source in ("paper", "project") and ax.alternatives
            for alt in ax.alternatives.values():
                for size in (ax.sets(False), ax.sets(True)):
                    resolve(exp.config, overrides=cfg.model_dump(mode="json"), sets=list(size) + list(alt))
