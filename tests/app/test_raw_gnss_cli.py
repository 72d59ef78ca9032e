"""``sinslab navigate --gnss-raw`` on the rtklib-walk log: the run folder (solution columns
as the loosely coupled run's, satellite tables, figures), ``--max-satellites``, and every
bad input as one line and exit status 2 with the previous run left unchanged."""
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from sinslab.cli import app

WALK = Path(__file__).resolve().parents[3] / "shared" / "data" / "rtklib-walk"
pytestmark = pytest.mark.skipif(not (WALK / "gnss_1730.ubx").exists(), reason="rtklib-walk not available")
runner = CliRunner()
BASE = ["navigate", "--imu", str(WALK / "imu_1730.csv"), "--format", "rtklib-imu", "--mount", "rpy:180,0,-90",
        "--frame", "frd", "--init", "course_speed=1 m/s,course_spread=10 deg"]


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def tc_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("tc") / "run"
    r = invoke(*BASE, "--gnss-raw", WALK / "gnss_1730.ubx", "--max-satellites", "3@60:20", "--out", out)
    assert r.exit_code == 0, r.output
    return out


def test_run_folder(tc_run):
    m = json.loads((tc_run / "summary.json").read_text())["metrics"]
    assert m["gnss_systems"] == "GEC" and m["satellites_used_min"] == 3 and m["satellites_over_limit"] > 0
    assert m["pseudoranges_used"] > 5000 and m["gnss_epochs_used"] == m["gnss_epochs"]
    sol = pd.read_parquet(tc_run / "solution.parquet")
    for c in ("t_s", "t_abs_s", "lat_deg", "lon_deg", "h_m", "vE_mps", "heading_deg", "gyro_bias_x_dph"):
        assert c in sol.columns
    sats = pd.read_csv(tc_run / "gnss_satellites.csv")
    win = (sats.t_s >= 60 - 18.8) & (sats.pr_used == 1)
    assert sats.groupby("t_s").pr_used.sum().min() >= 3
    for f in ("skyplot.png", "satellites.png", "clock.png", "gnss_clock.csv"):
        assert (tc_run / f).is_file()
    assert win.any()
    assert 0 < m["pseudorange_nis_window_max"] and 0 <= m["doppler_nis_window_failing"] <= 1, m


@pytest.mark.parametrize("args, msg", [
    (["--gnss-raw", "EMPTY"], "empty.ubx: empty file"),
    (["--gnss-raw", "JUNK"], "junk.ubx: no raw measurements"),
    (["--gnss-raw", "RNX4"], "RINEX version 4"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--gnss-nav", "NAV4"], "v4.nav: RINEX version 4"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--elevation-mask", "89.9"],
     "gnss_1730.ubx: every satellite is below the 89.9 deg elevation mask"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--elevation-mask", "90"], "--elevation-mask '90.0 deg' is out of range: must be < 90 deg"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--imu-delay", "3000"], "lie outside the IMU record"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--max-satellites", "three@60:20"], "--max-satellites"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--max-satellites", "3@1e9:10"],          # was taken as a no-op
     "--max-satellites '3@1e9:10': START 1e+09 s is after the run's last GNSS epoch (133.8 s after the first)"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--max-satellites", "40@60:20"],
     "--max-satellites '40@60:20': no epoch of the window has more than 16 satellite(s) with an ephemeris"),
    (["--gnss-raw", WALK / "gnss_1730.ubx", "--gnss", WALK / "gnss_1730_sf.pos"], "not both"),
])
def test_bad_input(tc_run, tmp_path, args, msg):
    empty = tmp_path / "empty.ubx"
    empty.write_bytes(b"")
    junk = tmp_path / "junk.ubx"
    junk.write_bytes(bytes(range(256)) * 40)
    rnx = tmp_path / "v4.obs"
    rnx.write_text("     4.01           OBSERVATION DATA    M                   RINEX VERSION / TYPE\n")
    nav4 = tmp_path / "v4.nav"
    nav4.write_text("     4.01           N: GNSS NAV DATA    M                   RINEX VERSION / TYPE\n")
    sub = {"EMPTY": empty, "JUNK": junk, "RNX4": rnx, "NAV4": nav4}
    before = {p.name: p.read_bytes() for p in tc_run.iterdir() if p.is_file()}
    r = invoke(*BASE, *[sub.get(str(a), a) for a in args], "--out", tc_run, "--force")
    assert r.exit_code == 2, r.output
    lines = [ln for ln in r.output.splitlines() if "error" in ln]
    assert len(lines) == 1 and lines[0].startswith("sinslab: error:") and msg in lines[0], r.output
    assert {p.name: p.read_bytes() for p in tc_run.iterdir() if p.is_file()} == before


def test_report_says_tightly_coupled_and_leads_with_its_rows(tc_run):
    """The report of a raw run: the line under the title names the coupling and the
    constellations; the metrics start with the satellites' rows, not the loosely coupled
    run's fix rows; rows named after fixes say they compare with the single-point solution."""
    from sinslab.app.commands.raw_gnss import _RAW_FIRST
    s = json.loads((tc_run / "summary.json").read_text())
    assert s["purpose"].startswith("INS + GNSS tightly coupled: pseudoranges and range rates")
    assert "(GPS, Galileo, BeiDou)" in s["purpose"]
    names = list(s["metrics"])
    assert names[:len(_RAW_FIRST)] == list(_RAW_FIRST)
    assert names[-1] == "outage_end_hz_err_m"              # no outage: its rows last, not first
    info = s["metric_info"]
    assert all(info[k]["description"] for k in _RAW_FIRST)
    assert "single-point solution" in info["hz_err_with_fixes_median_m"]["description"]
    assert "single-point" in info["fixes_after_grid"]["description"]
    html = (tc_run / "report.html").read_text()
    assert "tightly coupled" in html and "loosely coupled" not in html


def test_satellites_below_the_mask_only():
    """Every satellite below the elevation mask (here an 89.9° mask) is one line naming the
    file, not a filter without measurements (the CLI case is in test_bad_input)."""
    from sinslab.app.commands.navigate_config import RawKeys
    from sinslab.app.commands.raw_gnss import load_raw
    from sinslab.core.errors import InputError
    from sinslab.data import load_imu
    imu = load_imu(WALK / "imu_1730.csv", "rtklib-imu").imu
    keys = RawKeys(file=str(WALK / "gnss_1730.ubx"), elevation_mask="89.9 deg")
    with pytest.raises(InputError, match="gnss_1730.ubx: every satellite is below the 89.9 deg"):
        load_raw(keys, imu, echo=lambda *a: None)


def test_raw_claims_share_the_nis_rule_of_the_loosely_coupled_runs():
    """raw_claims: every claim is the project's check; a mean ν²/S well below 1 is a
    pessimistic noise model (passes, named in the verdict), well above 1 fails
    (overconfident), 1 ± chi-square noise is consistent — the verdicts of
    described.nis_claim, the rule of the loosely coupled navigate claims."""
    from types import SimpleNamespace

    from sinslab.app.commands.raw_gnss import raw_claims
    from sinslab.app.described import NIS_FACTOR, nis_claim

    rng = np.random.default_rng(1)

    def raw(pr_nis, dp_nis):
        def rows(nis):                          # the driver's record of the rows (RowLog)
            nis = np.asarray(nis, float).reshape(-1, 4)       # epochs of 4 rows, the last row unused
            used = np.ones(nis.shape, bool)
            used[:, -1] = False
            return SimpleNamespace(nis=list(nis), used=list(used))
        return {"pseudoranges": rows(pr_nis), "range_rates": rows(dp_nis)}

    # ν²/S of a consistent row is chi-square with 1 dof (mean 1)
    cases = [(0.2 * rng.chisquare(1, 400), True, "pessimistic noise model"),
             (rng.chisquare(1, 400), True, "consistent"),
             (5.0 * rng.chisquare(1, 400), False, "overconfident noise model")]
    for nis, passed, verdict in cases:
        claims, extra = raw_claims(raw(nis, nis))
        assert [c.id for c in claims] == ["pseudorange_nis_not_overconfident", "doppler_nis_not_overconfident"]
        assert all(c.origin == "check" for c in claims)
        assert all(c.passed is passed for c in claims), (verdict, [c.measured for c in claims])
        assert extra["pseudorange_nis_verdict"] == extra["doppler_nis_verdict"] == verdict
        used = nis.reshape(-1, 4)[:, :3].ravel()                # only the rows used count
        assert extra["pseudorange_nis_mean"] == pytest.approx(float(np.mean(used)))
        assert claims[0].expected == NIS_FACTOR and verdict in claims[0].statement
        # the same verdict as the loosely coupled rule for a 1-dof measurement
        assert nis_claim("x", "the fixes", used, 1)[2] == verdict


def test_windowed_nis_monitor_on_the_rows():
    """The windowed NIS monitor of the fix rows on the pseudorange and range-rate rows: the
    sum of one-at-a-time ν²/S of the rows used over 30 s is χ² with as many degrees of
    freedom (Mehra & Peschon 1971). Consistent rows (χ²(1) draws) give no warning; a 60-s
    stretch of pseudoranges four times their σ² is named with its span; the consistent
    range rates beside it are not."""
    from sinslab.app.plausibility import row_consistency_findings
    from sinslab.fusion.observer import RowLog

    rng = np.random.default_rng(3)
    t = np.arange(300.0)

    def log(scale):
        nis = rng.chisquare(1, (t.size, 8)) * scale[:, None]
        used = np.ones(nis.shape, bool)
        used[:, -2:] = False                                    # two rows refused: not counted
        nis[:, -2:] = 1e6
        return RowLog(t=list(t), nis=list(nis), used=list(used))

    calm = np.ones(t.size)
    found, m = row_consistency_findings({"pseudoranges": log(calm), "range_rates": log(calm)})
    assert found == [] and m["pseudorange_nis_window_failing"] == 0.0, m
    assert 0.7 < m["pseudorange_nis_window_max"] < m["pseudorange_nis_window_limit"] < 1.5, m
    bad = np.where((t >= 120) & (t < 180), 4.0, 1.0)
    found, m = row_consistency_findings({"pseudoranges": log(bad), "range_rates": log(calm)})
    assert len(found) == 1 and "its pseudorange rows for" in found[0].text, [f.text for f in found]
    dur = float(found[0].text.split(" rows for ")[1].split(" s ")[0])
    assert 60 <= dur <= 90, found[0].text                       # the stretch and the windows reaching into it
    assert m["pseudorange_nis_window_max"] > 3.0 and m["doppler_nis_window_failing"] == 0.0, m


def _rows(seed, bias=None, scale=1.0, n=240):
    """A RowLog-like record of n 1-Hz epochs of 6 satellites' pseudoranges: innovations
    ν ~ N(0, scale² S) with S = 4 m²; ``bias=(sat, t0, t1, b)`` adds b·√S to one satellite."""
    from types import SimpleNamespace
    rng = np.random.default_rng(seed)
    sats = np.array(["G02", "G05", "G07", "E11", "E12", "C20"])
    t = np.arange(n, dtype=float)
    nu = 2.0 * scale * rng.standard_normal((n, sats.size))
    if bias is not None:
        j, t0, t1, b = bias
        nu[(t >= t0) & (t < t1), j] += 2.0 * b
    used = np.ones(sats.size, bool)
    return SimpleNamespace(t=list(t), meta={"sat": [sats] * n}, innovation=list(nu), nis=list(nu ** 2 / 4.0),
                           used=[used] * n)


def test_raw_innovation_windows():
    """The windowed monitors of the loosely coupled runs on the satellites' rows: a
    consistent record gives no finding (false alarm 1e-3 per window, 30 s in a row); ν
    three times its σ is an overconfident stretch (first of the findings); one satellite's innovations shifted by
    4 σ for 90 s are that satellite's bias, found and named (by 1.5 σ: below the floor of
    RAW_BIAS_FLOOR = 3 σ, no finding)."""
    from sinslab.app.commands.raw_gnss import raw_consistency_findings
    assert raw_consistency_findings({"pseudoranges": _rows(1)}) == []
    f = raw_consistency_findings({"pseudoranges": _rows(2, scale=3.0)})[0]      # (its means spread 3× too)
    assert f.text.startswith("the filter is overconfident about the pseudoranges for ") and "of the epochs" in f.text
    # within σ for 90 s: significant, but what single-frequency ranges do (ionosphere, multipath)
    assert raw_consistency_findings({"pseudoranges": _rows(3, bias=(2, 100, 190, 1.5))}) == []
    (f,) = [x for x in raw_consistency_findings({"pseudoranges": _rows(3, bias=(2, 100, 190, 4.0))})
            if "biased" in x.text]                  # (its NIS windows are over too)
    assert f.text.startswith("the pseudorange innovations are biased for ") and " in pseudorange G07: " in f.text \
        and "pseudorange G07 innovation +4." in f.text
    assert "multipath" in f.text
    dur = float(f.text.split("biased for ")[1].split(" s")[0])
    assert 60 <= dur <= 120, f.text


def test_the_walk_run_is_consistent_in_its_windows(tc_run):
    """The recorded walk (mean NIS 0.2: a pessimistic noise model; satellites' innovations
    biased by up to 1.1 σ for the whole run, as single-frequency ranges are) raises no
    window warning."""
    s = json.loads((tc_run / "summary.json").read_text())
    assert not [w for w in s["warnings"] if "pseudorange" in w or "range rate" in w], s["warnings"]
