"""report.html: self-contained, and every figure really renders (headless Chromium)."""
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

import sinslab.experiments as E
from sinslab.app import report
from sinslab.app.config import resolve

from test_cli import Dummy

CHROMIUM = next((p for p in ("/usr/bin/chromium", shutil.which("chromium") or "",
                             shutil.which("chromium-browser") or "") if p and Path(p).exists()), None)


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    exp = E.register(Dummy)
    d = tmp_path_factory.mktemp("rep") / "run"
    E.execute(exp, resolve(exp.config, quick=exp.quick), d)
    return d


def test_report_is_self_contained(run_dir):
    html = (run_dir / "report.html").read_text()
    s = json.loads((run_dir / "summary.json").read_text())
    assert html.count("<img class=\"figure\"") == len(s["figures"]) == 2
    # no external resources: every src is a data URI, no stylesheet or script links
    assert all(src.startswith("data:image/png;base64,") for src in re.findall(r'src="([^"]+)"', html))
    assert "<link" not in html and "http://" not in html and "https://" not in html
    for c in s["claims"]:
        assert f"data-claim='{c['id']}'" in html
    for m in s["metrics"]:
        assert f"data-metric='{m}'" in html
    assert "id='config'" in html and "[scenario]" in html
    assert "a note" in html and "stats" in html


def test_report_errors(tmp_path):
    with pytest.raises(report.ReportError, match="summary.json: not found"):
        report.build(tmp_path)
    (tmp_path / "summary.json").write_text("{not json")
    with pytest.raises(report.ReportError, match="unreadable"):
        report.build(tmp_path)
    (tmp_path / "summary.json").write_text('{"experiment": "x"}')
    with pytest.raises(report.ReportError, match="metrics"):
        report.build(tmp_path)


def _render(html_file: Path, tmp_path: Path) -> str:
    """The DOM of ``html_file`` after load, as rendered by headless Chromium."""
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", "--disable-dev-shm-usage", f"--user-data-dir={tmp_path / 'profile'}",
           "--virtual-time-budget=10000", "--dump-dom", html_file.resolve().as_uri()]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout


def _body_attrs(dom: str) -> dict:
    body = re.search(r"<body([^>]*)>", dom)
    assert body, dom[:500]
    return dict(re.findall(r'([\w-]+)="([^"]*)"', body.group(1)))


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed")
def test_every_figure_loads_in_a_browser(run_dir, tmp_path):
    dom = _render(run_dir / "report.html", tmp_path)
    attrs = _body_attrs(dom)
    assert attrs.get("data-figures-total") == "2"
    assert attrs.get("data-figures-loaded") == "2"
    table = re.search(r'<table id="claims">(.*?)</table>', dom, re.S)
    assert table, "claims table missing from the rendered DOM"
    rows = re.findall(r'<tr class="(pass|fail)" data-claim="([^"]+)"', table.group(1))
    assert rows == [("pass", "lat"), ("pass", "small")]


@pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed")
def test_browser_check_detects_a_broken_figure(run_dir, tmp_path):
    html = (run_dir / "report.html").read_text()
    broken = tmp_path / "broken.html"
    broken.write_text(html.replace("data:image/png;base64,", "data:image/png;base64,AAAA", 1))
    attrs = _body_attrs(_render(broken, tmp_path))
    assert attrs.get("data-figures-total") == "2"
    assert attrs.get("data-figures-loaded") == "1"
