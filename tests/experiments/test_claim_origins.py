"""Every claim of every experiment says whose statement it tests: ``origin = "paper"`` (a
sentence of the paper) or ``"check"`` (a test the project adds), so that reports count the
paper's reproduced statements apart from the checks. Generic over the registered
experiments: a new experiment, or a new claim, without an origin fails here."""
import pytest
from support import run_experiment

import sinslab.experiments as E
from sinslab.app.claims import Claim, tally

OURS = sorted(n for n, e in E.registry().items() if e.module.startswith("sinslab.experiments."))


@pytest.mark.parametrize("name", OURS)
def test_every_claim_of_a_quick_run_has_an_origin(name):
    res = run_experiment(name)
    assert res.claims, f"{name}: no claims"
    missing = [c.id for c in res.claims if c.origin not in ("paper", "check")]
    assert not missing, f"{name}: claims without an origin ('paper' or 'check'): {missing}"
    # an experiment with a robustness sweep says, for every claim, what its verdict rests on
    # (an assumption with alternatives) or that its set-up decides it
    if E.registry()[name].robustness is not None:
        bare = [c.id for c in res.claims if not (c.construction or c.assumptions)]
        assert not bare, f"{name}: claims that declare no assumption: {bare}"


def test_tally_counts_by_origin_and_reads_old_summaries():
    cl = [Claim.at_most("a", "", 1, 2, origin="paper"), Claim.at_most("b", "", 3, 2, origin="paper"),
          Claim.at_most("c", "", 1, 2, origin="check")]
    assert tally(cl) == "paper: 1 of 2 reproduced · checks: 1 of 1"
    old = [{"id": "x", "passed": True}, {"id": "y", "passed": False, "origin": None}]
    assert tally(old) == "claims: 1 of 2 passed"
    assert tally([c.as_dict() for c in cl] + old) == ("paper: 1 of 2 reproduced · checks: 1 of 1 · "
                                                      "claims: 1 of 2 passed")
    assert tally([]) == ""
