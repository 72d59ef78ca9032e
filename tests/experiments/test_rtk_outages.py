"""rtk-outages: a quick run end to end (one drive): the files, the metrics of every
outage length, the INS re-fixing at once where RTK alone needs seconds, no wrong
integers, the NEES claims present where the simulated errors are the modelled ones and
left out with multipath."""
import sinslab.experiments as E
from sinslab.app.config import resolve
from sinslab.experiments import rtk_outages as ro


def test_quick_run(tmp_path):
    exp = E.get("rtk-outages")
    cfg = resolve(exp.config, quick=exp.quick, sets=["runs=1"])
    s = E.execute(exp, cfg, tmp_path / "r", quick=True)
    m = s["metrics"]
    for L in (5, 10, 30):
        assert 0.0 <= m[f"refix_1s_ins_{L}s"] <= 1.0 and 0.0 <= m[f"refix_1s_alone_{L}s"] <= 1.0
    assert m["refix_1s_ins_10s"] == 1.0 and m["refix_time_alone_10s_median"] >= 2.0
    assert m["wrong_integers_ins"] == 0 and m["wrong_integers_alone"] == 0
    assert m["fixed_rms_horizontal_ins"] < 0.02 and len(m["nees_float"]) == 4
    ids = {c["id"]: c["passed"] for c in s["claims"]}
    assert set(ids) == {"fixed_rms_horizontal_ins", "refix_1s_ins_10s", "no_wrong_integers_ins",
                        "nees_fixed_in_band", "nees_float_in_band"} and all(ids.values())
    assert (tmp_path / "r" / "refix.png").is_file() and (tmp_path / "r" / "table_refix.csv").is_file()
    # with code multipath the filters' white-noise model is wrong: no NEES claims
    mp = resolve(exp.config, quick=exp.quick, sets=["gnss.code_multipath=0.5 m"])
    assert {c.id for c in ro._claims(mp, m)} == {"fixed_rms_horizontal_ins", "refix_1s_ins_10s",
                                                  "no_wrong_integers_ins"}
