"""The documentation site (``make docs``): the guides and the API reference generated from
the docstrings build with warnings as errors — a docstring that does not parse, a broken
cross-reference to a sinslab name, a page outside the table of contents all fail — and the
built site works in a browser: the home page, an API page, and the search."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from app.browser import CHROMIUM, _FLAGS

ROOT = Path(__file__).resolve().parents[1]
pytest.importorskip("sphinx", reason="the docs build with the dev extra's Sphinx")
pytest.importorskip("myst_parser", reason="the docs build with the dev extra's myst-parser")
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="chromium not installed")


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    r = subprocess.run([sys.executable, "-m", "sphinx", "-b", "html", "-n", "-W", "--keep-going", "-q",
                        "-d", str(out / ".doctrees"), str(ROOT / "docs"), str(out)],
                       capture_output=True, text=True, cwd=ROOT, timeout=900)
    assert r.returncode == 0, "docs build failed (warnings are errors):\n" + r.stderr[-6000:]
    return out


def _dom(url: str, tmp: Path) -> str:
    r = subprocess.run([CHROMIUM, *_FLAGS, f"--user-data-dir={tmp / 'profile'}", "--window-size=1280,900",
                        "--virtual-time-budget=10000", "--dump-dom", url],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout


def test_every_page_and_module_is_built(site):
    pages = {p.relative_to(site).as_posix() for p in site.rglob("*.html")}
    for doc in [*(ROOT / "docs").glob("*.md"), *(ROOT / "docs" / "methods").glob("*.md"),
                *(ROOT / "docs" / "api").glob("*.md")]:
        if doc.name == "INTERFACES.md":             # notes for contributors, not in the site
            continue
        assert doc.relative_to(ROOT / "docs").with_suffix(".html").as_posix() in pages, doc
    # the API reference covers every module the type checker covers
    from test_typing import checked_files

    for f in checked_files():
        mod = ".".join(f.relative_to(ROOT / "src").with_suffix("").parts).removesuffix(".__init__")
        if not mod.split(".")[-1].startswith("_") and (ROOT / "docs" / "api" / f"{mod}.md").is_file():
            assert f"api/{mod}.html" in pages


@needs_chromium
def test_home_api_page_and_search_in_a_browser(site, tmp_path):
    home = _dom((site / "index.html").as_uri(), tmp_path)
    assert re.search(r"<h1>sinslab", home) and "Five-minute tour" in home
    assert 'href="api/index.html"' in home and 'href="methods/000.html"' in home

    api = _dom((site / "api" / "sinslab.core.earth.html").as_uri(), tmp_path)
    assert 'id="sinslab.core.earth.gravity"' in api                  # the function's entry
    entry = api[api.index('id="sinslab.core.earth.gravity"'):][:3000]
    assert "Somigliana" in entry                                     # its docstring, rendered
    # a docstring's cross-reference to another module, linked
    assert 'href="sinslab.core.errors.html#sinslab.core.errors.InputError"' in api

    found = _dom((site / "search.html").as_uri() + "?q=normal+gravity", tmp_path)
    m = re.search(r"found (\d+) page", found)
    assert m and int(m.group(1)) > 0, found[-2000:]
    assert 'href="api/sinslab.core.earth.html' in found
