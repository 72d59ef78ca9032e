"""Report pages a reader can read: the claims table fits a 1400 px page with its verdicts in
view (headless Chromium), CJK text renders from the font subset the page embeds (on a
machine without a CJK font, as CI's), the page numbers its figures once, and a yes/no
metric carries no unit."""
import json
from pathlib import Path

import pytest

from browser import CHROMIUM, body_attrs, problems, render

from sinslab.app import report
from sinslab.app.described import metric_info

ROOT = Path(__file__).resolve().parents[2]
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed")

#: the claims of a quick transfer-alignment run as summary.json holds them: long statements,
#: measured values with details in their names (which the expected column once repeated)
_NAMES = ["euler (RMS/σ 9.11, 1.86, 1.84; margin -6.11)", "dcm (all 30 runs diverged)",
          "kain (all 30 runs diverged)"]
_STATEMENT = ("large installation: methods 1-3 (euler, dcm, kain) do not converge to the true misalignment "
              "(at the assumed 1′ attitude and 0.01 m/s velocity noise, master error 0.5′ 1σ; the "
              "verdict_sweep table shows where it flips)")


def _claim(cid, names, value, passed=True):
    return {"id": cid, "statement": _STATEMENT, "origin": "paper", "passed": passed,
            "measured": {"value": value, "names": names, "unit": ""},
            "expected": {"relation": "==", "value": value, "tolerance": None, "rel_tolerance": None,
                         "unit": "", "text": ""}}


@pytest.fixture
def run_dir(tmp_path):
    d = tmp_path / "ta"
    d.mkdir()
    s = {"experiment": "transfer-alignment", "sinslab_version": "0", "config": {}, "quick": True,
         "purpose": "paper 002: transfer alignment",
         "paper": "Attitude matching method of transfer alignment (基于量测失准角的传递对准姿态匹配方法; four forms)",
         "metrics": {"time_sync_ppm_applied": True, "final_x_m": 1.5},
         "metric_info": metric_info("navigate", {"time_sync_ppm_applied": True, "final_x_m": 1.5}),
         "claims": [_claim("large_methods_1_3_fail", _NAMES, [False, False, False]),
                    _claim("small_all_converge_in_a_long_identifier_name", _NAMES + ["optimal (RMS/σ 1.03, 0.94)"],
                           [True] * 4, passed=False)],
         "figures": [], "series": [], "tables": []}
    (d / "summary.json").write_text(json.dumps(s, ensure_ascii=False))
    report.build(d)
    return d


def test_expected_names_what_is_expected_not_the_measured_details(run_dir):
    measured, expected = report.claim_texts(json.loads((run_dir / "summary.json").read_text())["claims"][0])
    assert "margin -6.11" in measured
    assert expected == "euler = no · dcm = no · kain = no"


@needs_chromium
@pytest.mark.parametrize("width", [1400, 1024])
def test_claims_fit_the_page_and_cjk_renders(run_dir, tmp_path, width):
    assert problems(run_dir, tmp_path, width) == []
    a = body_attrs(render(run_dir / "report.html", tmp_path, width))
    assert 0 < int(a["data-claims-right"]) <= width and a["data-cjk-font"] == "loaded", a


def test_every_cjk_character_of_the_sources_is_in_the_embedded_font():
    """tools/make_cjk_font.py made the subset from the sources' CJK texts: a text added
    since needs the subset made again."""
    from fontTools.ttLib import TTFont

    cmap = TTFont(Path(report.__file__).with_name("fonts") / "cjk-subset.otf").getBestCmap()
    used = {c for p in (ROOT / "src" / "sinslab").rglob("*.py")
            for c in p.read_text(encoding="utf-8") if report.is_cjk(c)}
    assert used and not sorted(c for c in used if ord(c) not in cmap)


def test_a_page_without_cjk_embeds_no_font(tmp_path):
    d = tmp_path / "plain"
    d.mkdir()
    (d / "summary.json").write_text(json.dumps({"experiment": "x", "metrics": {}, "claims": []}))
    assert "@font-face" not in report.render(d)


def test_the_page_search_finds_the_cjk_characters_is_cjk_names():
    """The one-pass search of a page for CJK text agrees with is_cjk on both edges of every
    block and just outside them, and embeds the font only for a page that has one."""
    for a, b in report._CJK:
        for o in (a - 1, a, b, b + 1):
            ch = chr(o)
            assert (report._CJK_CHAR.search(f"plain {ch} text") is not None) == report.is_cjk(ch), hex(o)
    assert report._cjk_font_css("a page, no CJK: é ü — ∑") == ""
    assert report._cjk_font_css("姿态误差").startswith("@font-face")


@pytest.mark.parametrize("name, caption, label, text", [
    ("att_sigma", "Fig. 2: attitude error σ", "att_sigma (the paper's Fig. 2)", "Attitude error σ"),
    ("fig2_reduced", "Reduced filter: residual and limit (paper Fig. 2)", "reduced",
     "Reduced filter: residual and limit (paper Fig. 2)"),
    ("fig5_trend", "ε estimates", "trend (the paper's Fig. 5)", "ε estimates"),
    ("wave", "a wave", "wave", "a wave"),
])
def test_one_figure_numbering(name, caption, label, text):
    """The page's "Figure k:" is the only figure number; the paper's stays a reference."""
    assert report.figure_caption(name, caption) == (label, text)


def test_a_yes_no_metric_has_no_unit(run_dir):
    s = json.loads((run_dir / "summary.json").read_text())
    assert s["metric_info"]["time_sync_ppm_applied"]["unit"] == ""
    html = (run_dir / "report.html").read_text()
    row = html.split("data-metric='time_sync_ppm_applied'>")[1].split("</tr>")[0]
    assert "<td class='unit'></td>" in row and ">yes<" in row
