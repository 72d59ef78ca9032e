"""Headless-Chromium checks of a report page (shared by the report tests)."""
from __future__ import annotations

import json
import re
import shutil
import subprocess
from html import unescape
from pathlib import Path
from urllib.parse import unquote

CHROMIUM = next((p for p in ("/usr/bin/chromium", shutil.which("chromium") or "",
                             shutil.which("chromium-browser") or "") if p and Path(p).exists()), None)

_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
          "--disable-background-networking", "--disable-component-update", "--disable-sync",
          "--disable-dev-shm-usage", "--hide-scrollbars"]

#: Metric-name suffixes that carry a unit: such a metric must show a unit in the report.
UNIT_SUFFIXES = ("_m", "_s", "_deg", "_arcmin", "_arcsec", "_mps", "_dph", "_ug", "_ppm",
                 "_min", "_dpsh", "_ugpsHz", "_dphpsh", "_ugpsh", "_mps2", "_us")


def render(html_file: Path, tmp: Path, width: int = 1280) -> str:
    """The DOM of ``html_file`` after load, as laid out by headless Chromium at ``width`` px."""
    cmd = [CHROMIUM, *_FLAGS, f"--user-data-dir={tmp / 'profile'}", f"--window-size={width},900",
           "--virtual-time-budget=10000", "--dump-dom", html_file.resolve().as_uri()]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout


def screenshot(html_file: Path, png: Path, tmp: Path, width: int = 1280, height: int = 3000) -> None:
    cmd = [CHROMIUM, *_FLAGS, f"--user-data-dir={tmp / 'profile'}", f"--window-size={width},{height}",
           "--virtual-time-budget=10000", f"--screenshot={png}", html_file.resolve().as_uri()]
    subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=True)


def body_attrs(dom: str) -> dict:
    body = re.search(r"<body([^>]*)>", dom)
    assert body, dom[:500]
    return dict(re.findall(r'([\w-]+)="([^"]*)"', body.group(1)))


def problems(run_dir: Path, tmp: Path, width: int = 1280) -> list[str]:
    """What is wrong with ``run_dir/report.html`` as a reader sees it at ``width`` px
    (empty: nothing)."""
    run_dir = Path(run_dir)
    dom = render(run_dir / "report.html", tmp, width)
    out = []
    a = body_attrs(dom)
    if a.get("data-figures-total") != a.get("data-figures-loaded"):
        out.append(f"figures loaded {a.get('data-figures-loaded')} of {a.get('data-figures-total')}")
    if int(a.get("data-page-width", 0)) > int(a.get("data-view-width", 0)):
        out.append(f"page overflows: {a.get('data-page-width')} px wide in {a.get('data-view-width')} px")
    if int(a.get("data-claims-right", 0)) > int(a.get("data-view-width", 0)):
        out.append(f"claims table: verdicts end at {a.get('data-claims-right')} px in {a.get('data-view-width')} px")
    if int(a.get("data-claims-overflow", 0)):
        out.append(f"claims table: {a.get('data-claims-overflow')} cell(s) overflow their column")
    html_text = (run_dir / "report.html").read_text(encoding="utf-8")
    from sinslab.app.report import is_cjk

    if any(is_cjk(c) for c in html_text) and a.get("data-cjk-font") != "loaded":
        out.append(f"CJK text without its font (font {a.get('data-cjk-font')})")
    claims = re.search(r'<table id="claims">(.*?)</table>', dom, re.S)
    if claims:
        for cell in re.findall(r'<td class="num">(.*?)</td>', claims.group(1), re.S):
            text = unescape(re.sub(r"<[^>]+>", "", cell))
            if re.search(r"[\[{]", text):
                out.append(f"raw structure in a claim cell: {text[:80]!r}")
    s = json.loads((run_dir / "summary.json").read_text())
    if not s["claims"] and ("id=\"claims\"" in dom or "claims passed" in dom):
        out.append("a claims section without claims")
    for name in s["metrics"]:
        row = re.search(rf'<tr data-metric="{re.escape(name)}">(.*?)</tr>', dom, re.S)
        if row is None:
            out.append(f"metric {name} not shown")
            continue
        unit = re.search(r'<td class="unit">(.*?)</td>', row.group(1), re.S)
        if name.endswith(UNIT_SUFFIXES) and not (unit and unit.group(1).strip()):
            out.append(f"metric {name} has no unit")
    for href in re.findall(r'href="([^"]+)"', dom):
        if href.startswith(("#", "data:")):
            continue
        if "://" in href and not href.startswith("file://"):
            out.append(f"external link {href}")
            continue
        target = run_dir / unquote(href.removeprefix("file://"))
        if not target.is_file():
            out.append(f"broken link {href}")
    return out
