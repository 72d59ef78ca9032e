"""Self-contained HTML report of a run folder.

``render(DIR)`` reads ``summary.json``, ``config.toml`` and the figures' PNG files of a
run folder and returns one HTML page with everything embedded (figures as base64 PNG,
linked to their SVG files), so the page can be mailed or archived alone. ``build(DIR)``
writes it atomically to ``DIR/report.html`` (``sinslab report DIR``). ``index(...)``
writes the page linking several reports (``sinslab demo``).

Sections: header (run name — a demo variant's own name, with the ``--set`` lines that
make it —, purpose, version, date, quick or full for experiments, computation and
writing time), claims table (``id="claims"``, one row per claim, measured and expected
values labelled with their units, pass/fail; no section when the run checked no claim),
robustness (``id="robustness"``: per claim its label — robust, depends on …, decided by
construction, not swept —, its verdict under each alternative, flips marked, and the
assumptions with their defaults and whose they are),
metrics table (value, unit, description), figures, tables (Monte Carlo statistics etc.),
notes, time-series files (each described), configuration with the command line that
re-runs the run. Wide tables scroll inside their box, never the page. After the page has loaded, a small script writes the number of figures
and of figures actually decoded (``naturalWidth > 0``) into ``data-figures-total`` and
``data-figures-loaded`` on ``<body>``, and the page's laid-out and visible widths into
``data-page-width`` and ``data-view-width`` (a wider page scrolls sideways) — the browser
test reads them.
"""
from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import math
import os
import re
from pathlib import Path

from sinslab.app.claims import declared, tally
from sinslab.app.errors import UserError
from sinslab.core.atomic import atomic_write

__all__ = ["ReportError", "render", "build", "index", "figure_caption", "is_cjk"]


class ReportError(UserError):
    """A run folder the report cannot be built from."""


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,"sinslab CJK subset",sans-serif;margin:2em auto;
max-width:1100px;padding:0 1em;color:#1d1d1f;line-height:1.4}
h1{margin-bottom:.1em}h2{border-bottom:1px solid #ddd;padding-bottom:.2em;margin-top:1.6em}
.sub{color:#666;margin-top:0}table{border-collapse:collapse;margin:.5em 0;font-size:.92em}
th,td{border:1px solid #ccc;padding:.3em .6em;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{font-family:ui-monospace,Menlo,Consolas,monospace;white-space:nowrap}
tr.pass td.verdict{background:#dff5e1;color:#11631d;font-weight:bold}
tr.fail td.verdict{background:#fde2e1;color:#a11;font-weight:bold}
.badge{display:inline-block;padding:.15em .6em;border-radius:1em;font-weight:bold}
.badge.ok{background:#dff5e1;color:#11631d}.badge.bad{background:#fde2e1;color:#a11}
ul.warn li{background:#fff4d6;color:#6b4b00;padding:.2em .5em;margin:.2em 0;list-style:none}
figure{margin:1em 0;text-align:center}figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{color:#444;font-size:.92em}pre{background:#f7f7f7;padding:.8em;overflow-x:auto;font-size:.85em}
#metrics td.num{white-space:normal;overflow-wrap:anywhere;max-width:22em}.scroll{max-width:100%;overflow-x:auto}
#claims{table-layout:fixed;width:100%}#claims td{overflow-wrap:anywhere}#claims td.num{white-space:normal}
#claims col.id{width:13%}#claims col.origin{width:6.5%}#claims col.statement{width:33%}
#claims col.measured,#claims col.expected{width:20%}#claims col.result{width:7.5%}
#claims code.id,#claims span.q{white-space:normal;overflow-wrap:anywhere}
td.cols{overflow-wrap:anywhere;max-width:28em}.variant{background:#f4f7fb;padding:.4em .8em;border-left:3px solid #4a7bd0}
code.id,#runs td:first-child{white-space:nowrap}span.q{white-space:nowrap}#rerun{overflow-wrap:anywhere}
"""

_SCRIPT = """
window.addEventListener('load', function () {
  var imgs = document.querySelectorAll('img.figure');
  var ok = 0;
  for (var i = 0; i < imgs.length; i++) { if (imgs[i].complete && imgs[i].naturalWidth > 0) ok++; }
  document.body.setAttribute('data-figures-total', String(imgs.length));
  document.body.setAttribute('data-figures-loaded', String(ok));
  document.body.setAttribute('data-page-width', String(document.documentElement.scrollWidth));
  document.body.setAttribute('data-view-width', String(document.documentElement.clientWidth));
  var right = 0, cells = document.querySelectorAll('#claims td.verdict');
  for (var j = 0; j < cells.length; j++) { right = Math.max(right, cells[j].getBoundingClientRect().right); }
  document.body.setAttribute('data-claims-right', String(Math.ceil(right)));
  var over = 0, tds = document.querySelectorAll('#claims td');
  for (var k = 0; k < tds.length; k++) { if (tds[k].scrollWidth > tds[k].clientWidth + 1) over++; }
  document.body.setAttribute('data-claims-overflow', String(over));
  if (!document.fonts) return;
  document.fonts.ready.then(function () {
    var cjk = 'none';
    document.fonts.forEach(function (f) { if (f.family.indexOf('sinslab CJK') >= 0) cjk = f.status; });
    document.body.setAttribute('data-cjk-font', cjk);
  });
});
"""

#: Unicode blocks of CJK text (punctuation, ideographs and their extensions, compatibility
#: ideographs, full-width forms): shown with the embedded font subset
_CJK = ((0x3000, 0x303F), (0x3400, 0x4DBF), (0x4E00, 0x9FFF), (0xF900, 0xFAFF), (0xFF00, 0xFFEF))


#: one character of those blocks (a page is searched in one pass: reports run to a megabyte)
_CJK_CHAR = re.compile("[" + "".join(f"{chr(a)}-{chr(b)}" for a, b in _CJK) + "]")


def is_cjk(ch: str) -> bool:
    """True for a character of the CJK blocks the report's font subset serves."""
    o = ord(ch)
    return any(a <= o <= b for a, b in _CJK)


def _cjk_font_css(text: str) -> str:
    """An ``@font-face`` of the CJK subset (fonts/cjk-subset.otf, embedded) when ``text``
    holds CJK characters: a reader's machine without a CJK font shows them, not boxes."""
    if _CJK_CHAR.search(text) is None:
        return ""
    font = Path(__file__).with_name("fonts") / "cjk-subset.otf"
    try:
        b64 = base64.b64encode(font.read_bytes()).decode("ascii")
    except OSError:
        return ""
    ranges = ",".join(f"U+{a:04X}-{b:04X}" for a, b in _CJK)
    return (f"@font-face{{font-family:'sinslab CJK subset';src:url(data:font/otf;base64,{b64}) "
            f"format('opentype');unicode-range:{ranges}}}")

e = html.escape


def _fmt(v, digits=6) -> str:
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return f"{v:.{digits}g}" if math.isfinite(v) else "n/a"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x, digits) for x in v) + "]"
    return str(v)


#: Units written against the number ("0.10′", "2.3×"); every other unit after a space.
_TIGHT = {"′", "″", "°", "×", "%", "°/h", "°/√h"}
#: One spelling of each unit on a page: the signs a reader knows (°/h, µg), whatever ASCII
#: spelling a metric or claim was declared with.
_UNIT_SIGN = {"arcmin": "′", "arcsec": "″", "deg": "°", "deg/h": "°/h", "dph": "°/h", "x": "×",
              "deg/s": "°/s", "deg/sqrt(h)": "°/√h", "dpsh": "°/√h", "deg/h/sqrt(h)": "°/h/√h",
              "ug": "µg", "ug/sqrt(Hz)": "µg/√Hz", "ug/sqrt(h)": "µg/√h", "deg/sqrt(s)": "°/√s"}


def unit_sign(unit: str) -> str:
    """The one spelling of ``unit`` shown on a page (``deg/h`` -> ``°/h``, ``ug`` -> ``µg``)."""
    return _UNIT_SIGN.get(unit, unit) if isinstance(unit, str) else unit


_SUP = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def num(v, sig: int = 3) -> str:
    """A number as a person reads it: ``sig`` significant digits, no exponent between
    1e-3 and 1e7, integers in full, a true minus sign; ``n/a`` for None/NaN."""
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v).replace("-", "−")
    if not isinstance(v, float):
        return str(v)
    if not math.isfinite(v):
        return "n/a" if math.isnan(v) else ("∞" if v > 0 else "−∞")
    a = abs(v)
    if a == 0:
        t = "0"
    elif 1e-3 <= a < 1e7:
        digits = max(sig - 1 - int(math.floor(math.log10(a))), 0)
        t = f"{v:.{digits}f}"
        if "." in t:
            t = t.rstrip("0").rstrip(".")
    else:
        m, ex = f"{v:.{sig - 1}e}".split("e")
        m = m.rstrip("0").rstrip(".") if "." in m else m
        t = f"{m}×10" + str(int(ex)).translate(_SUP)
    return t.replace("-", "−")


def with_unit(v, unit: str = "", sig: int = 3) -> str:
    """``num(v)`` followed by its unit ("0.1′", "3.2 m"); no unit for n/a."""
    t = num(v, sig)
    unit = _UNIT_SIGN.get(unit, unit or "")
    if not unit or t == "n/a" or isinstance(v, bool):
        return t
    return t + unit if unit in _TIGHT else f"{t} {unit}"


def _unit_at(unit, i: int) -> str:
    if isinstance(unit, (list, tuple)):
        return unit[i] if i < len(unit) else ""
    return unit or ""


def _values(v, unit, i0: int = 0) -> str:
    """A value or list of values with unit(s), components joined by ", "."""
    if isinstance(v, (list, tuple)):
        return ", ".join(with_unit(x, _unit_at(unit, i0 + j) if isinstance(unit, (list, tuple))
                                   else unit) for j, x in enumerate(v))
    return with_unit(v, _unit_at(unit, i0) if isinstance(unit, (list, tuple)) else unit)


def quantity(value, names=None, unit="") -> str:
    """A measured value as text: "φE 0.1′ · φN −0.47′" (names), "1.2 m · 3.4 m" (list),
    "alignment ends 3600 s, 6134 s · ..." (dict of named values)."""
    if isinstance(value, dict):
        keys = list(value)
        labels = names if names and len(names) == len(keys) else keys
        return " · ".join(f"{lab} {_values(value[k], _unit_at(unit, i) if isinstance(unit, (list, tuple)) else unit)}"
                          for i, (k, lab) in enumerate(zip(keys, labels)))
    if isinstance(value, (list, tuple)):
        parts = []
        for i, x in enumerate(value):
            u = _unit_at(unit, i) if isinstance(unit, (list, tuple)) else unit
            t = _values(x, u)
            parts.append(f"{names[i]} {t}" if names and i < len(names) else t)
        return " · ".join(parts)
    return with_unit(value, unit if isinstance(unit, str) else _unit_at(unit, 0))


_REL = {"<=": "≤", ">=": "≥", "==": "="}


def criterion(exp: dict, names=None, n: int | None = None) -> str:
    """The expectation of a claim (its ``expected`` entry in summary.json) as text."""
    rel = exp.get("relation", "text")
    unit = exp.get("unit", "")
    val = exp.get("value")
    if rel == "text" or (val is None and rel != "within"):
        return str(exp.get("text", ""))
    if rel == "within":
        tol, rtol = exp.get("tolerance"), exp.get("rel_tolerance")
        pm = f"{num(rtol * 100)} %" if rtol is not None and tol is None else None
        if isinstance(val, list):
            tols = tol if isinstance(tol, list) else [tol] * len(val)
            parts = [f"{with_unit(v, _unit_at(unit, i) if isinstance(unit, list) else unit)} ± "
                     f"{pm or with_unit(tols[i], _unit_at(unit, i) if isinstance(unit, list) else unit)}"
                     for i, v in enumerate(val)]
            return " · ".join(f"{_short(names[i])} {p}" if names and i < len(names) else p
                              for i, p in enumerate(parts))
        u = unit if isinstance(unit, str) else ""
        return f"{with_unit(val, u)} ± {pm or with_unit(tol, u)}"
    if rel == "between" and isinstance(val, list) and len(val) == 2:
        u = unit if isinstance(unit, str) else ""
        return f"between {with_unit(val[0], u)} and {with_unit(val[1], u)}"
    op = _REL.get(rel, rel)
    if isinstance(val, list):
        parts = [f"{op} {_values(v, _unit_at(unit, i) if isinstance(unit, list) else unit)}"
                 for i, v in enumerate(val)]
        if names and len(names) == len(val):
            return " · ".join(f"{_short(nm)} {p}" for nm, p in zip(names, parts))
        if len(set(parts)) == 1:
            return parts[0] + " each"
        return " · ".join(parts)
    t = f"{op} {with_unit(val, unit if isinstance(unit, str) else '')}"
    return t + (" each" if n and n > 1 else "")


def _short(name: str) -> str:
    """A component's name without the measured details in brackets ("euler (RMS/σ 1.2)"
    -> "euler"): the expected column names what is expected, it does not repeat the
    measured column."""
    return str(name).split(" (", 1)[0]


def claim_texts(c: dict) -> tuple[str, str]:
    """(measured, expected) of one claim of summary.json as plain text (the terminal summary)."""
    return _claim_cells(c)


def _claim_cells(c: dict) -> tuple[str, str]:
    """(measured, expected) texts of one claim of summary.json (old flat layouts too)."""
    m, x = c.get("measured"), c.get("expected")
    if isinstance(m, dict) and "value" in m and isinstance(x, dict) and "relation" in x:
        names, unit, val = m.get("names"), m.get("unit", ""), m.get("value")
        n = len(val) if isinstance(val, list) else None
        return quantity(val, names, unit), criterion(x, names, n)
    return quantity(m), (x if isinstance(x, str) else quantity(x))


def _metric_text(v, unit: str) -> str:
    if isinstance(v, list):
        return " · ".join(_metric_text(x, unit) for x in v)
    if isinstance(v, dict):
        return " · ".join(f"{k} {_metric_text(x, unit)}" for k, x in v.items())
    return num(v, 4)


def _load_summary(d: Path) -> dict:
    f = d / "summary.json"
    if not d.is_dir():
        raise ReportError(f"{d}: not a folder")
    if not f.is_file():
        raise ReportError(f"{f}: not found (not a finished sinslab run)")
    try:
        s = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError) as err:
        raise ReportError(f"{f}: unreadable ({err})") from None
    for k in ("experiment", "metrics", "claims"):
        if k not in s:
            raise ReportError(f"{f}: no {k!r} entry (not a sinslab summary)")
    return s


def _figure_html(d: Path, fig: dict, k: int = 0) -> str:
    png = d / fig.get("png", f"{fig['name']}.png")
    if not png.is_file():
        raise ReportError(f"{png}: figure file missing")
    b64 = base64.b64encode(png.read_bytes()).decode("ascii")
    svg = fig.get("svg")
    link = f' <a href="{e(svg)}">SVG</a>' if svg and (d / svg).is_file() else ""
    label, caption = figure_caption(fig["name"], fig.get("caption", ""))
    return (f'<figure id="fig-{e(fig["name"])}"><img class="figure" alt="{e(fig["name"])}" '
            f'src="data:image/png;base64,{b64}">'
            f'<figcaption><b>Figure {k}: {e(label)}</b> — {e(caption)}{link}</figcaption></figure>')


_LEADING_NUMBER = re.compile(r"^\s*Fig(?:ure|\.)?\s*(\d+)\s*[:.]\s*", re.I)
_PAPER_FIG = re.compile(r"paper(?:'s)? Figs?\.?\s*\d", re.I)


def figure_caption(name: str, caption: str) -> tuple[str, str]:
    """``(label, caption)`` of a figure under the page's own numbering ("Figure k:"), so
    that a page numbers its figures once: a file named after the paper's figure
    (``fig2_reduced``) or a caption starting "Fig. 2:" becomes the reference "(the paper's
    Fig. 2)" — once, not where the caption cites the paper's figure already."""
    caption = caption or ""
    m = _LEADING_NUMBER.match(caption)
    paper = m[1] if m else None
    if m:
        caption = caption[m.end():]
        caption = caption[:1].upper() + caption[1:]
    mn = re.match(r"fig(\d+)_(.+)$", name)
    label = mn[2].replace("_", " ") if mn else name
    paper = paper or (mn[1] if mn else None)
    if paper and not _PAPER_FIG.search(caption):
        label += f" (the paper's Fig. {paper})"
    return label, caption


def _table_html(d: Path, t: dict) -> str:
    import pandas as pd

    path = d / t["csv"]
    if not path.is_file():
        return f"<p>missing table file {e(t['csv'])}</p>"
    df = pd.read_csv(path)
    head = "".join(f"<th>{_breakable(str(c))}</th>" for c in df.columns)
    rows = "".join("<tr>" + "".join(f'<td class="num">{e(num(v.item() if hasattr(v, "item") else v, 4))}</td>'
                                    for v in row) + "</tr>" for row in df.itertuples(index=False))
    return (f'<h3>{e(t["name"])}</h3><p>{e(t.get("caption", ""))}</p>'
            f'<div class="scroll"><table class="data"><tr>{head}</tr>{rows}</table></div>')


def _wide(table_html: str) -> str:
    """A table inside a horizontally scrolling box, so a wide table never widens the page."""
    return f"<div class='scroll'>{table_html}</div>"


def render(run_dir: str | os.PathLike, summary: dict | None = None) -> str:
    """The report page of a run folder as HTML text (raises :class:`ReportError`).

    ``summary`` is the run's summary when it is not yet written to ``summary.json``."""
    d = Path(run_dir)
    s = summary if summary is not None else _load_summary(d)
    cfg_file = d / "config.toml"
    cfg_text = cfg_file.read_text(encoding="utf-8") if cfg_file.is_file() else json.dumps(
        s.get("config", {}), indent=2)
    claims = s.get("claims", [])
    n_pass = sum(bool(c.get("passed")) for c in claims)
    all_ok = n_pass == len(claims)
    info = s.get("metric_info", {})
    is_command = s.get("kind") == "command"
    title = s.get("name") or s["experiment"]
    variant = s.get("variant") or {}

    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
             f"<meta name='viewport' content='width=device-width, initial-scale=1'>"
             f"<title>sinslab — {e(title)}</title><style>{_CSS}</style></head><body>"]
    parts.append(f"<h1>{e(title)}</h1>")
    parts.append(f"<p class='sub'>{e(s.get('purpose', ''))}</p>")
    if variant.get("sets"):
        parts.append(f"<p class='variant'>Variant of <b>{e(s['experiment'])}</b>, changed by "
                     + ", ".join(f"<code>--set {e(x)}</code>" for x in variant["sets"]) + "</p>")
    meta = [f"sinslab {e(str(s.get('sinslab_version', '?')))}",
            f"run {e(s.get('started', '?'))}"]
    if not is_command:
        meta.append("quick run (--quick)" if s.get("quick") else "full scale")
    if s.get("paper"):
        meta.append(f"after {e(s['paper'])}")
    timing = s.get("timing") or {}
    rt = timing.get("compute_s", s["metrics"].get("runtime_s"))
    if isinstance(rt, (int, float)):
        meta.append(f"computation {with_unit(float(rt), 's')}")
    out_s = sum(v for k, v in timing.items() if k not in ("compute_s", "robustness_s") and isinstance(v, (int, float)))
    if out_s:
        meta.append(f"writing the run folder {with_unit(float(out_s), 's')}")
    parts.append("<p class='sub'>" + " · ".join(meta) + "</p>")

    warns = s.get("warnings") or []
    if warns:                                  # plausibility checks of the data and the run
        parts.append("<h2>Warnings</h2><ul class='warn' id='warnings'>"
                     + "".join(f"<li>⚠ {e(w)}</li>" for w in warns) + "</ul>")
    if claims:
        badge = "ok" if all_ok else "bad"
        parts.append(f"<p><span class='badge {badge}' id='verdict'>{n_pass} of {len(claims)} claims "
                     f"passed</span>" + (f" <span class='sub' id='origins'>{e(tally(claims, s.get('robustness')))}</span>"
                                          if any(c.get("origin") for c in claims) else "") + "</p>")
        parts.append("<h2>Claims</h2>" + _wide(
            "<table id='claims'>" + "".join(f"<col class='{c}'>" for c in _CLAIM_COLUMNS)
            + "<tr><th>id</th><th>origin</th><th>statement</th>"
            "<th>measured</th><th>expected</th><th>result</th></tr>" + "".join(
                _claim_row(c) for c in claims) + "</table>"))
        if declared(s.get("robustness")):
            parts.append(_robustness_html(s["robustness"], claims))

    parts.append("<h2>Metrics</h2>")
    rows = []
    for name, v in s["metrics"].items():
        mi = info.get(name, {})
        rows.append(f"<tr data-metric='{e(name)}'><td><code>{_breakable(name)}</code></td>"
                    f"<td class='num'>{e(_metric_text(v, mi.get('unit', '')))}</td>"
                    f"<td class='unit'>{e('' if isinstance(v, bool) else unit_sign(mi.get('unit', '')))}</td>"
                    f"<td>{e(mi.get('description', ''))}</td></tr>")
    parts.append(_wide("<table id='metrics'><tr><th>metric</th><th>value</th><th>unit</th>"
                       "<th>description</th></tr>" + "".join(rows) + "</table>"))

    figs = s.get("figures", [])
    if figs:
        parts.append("<h2>Figures</h2>")
        parts.extend(_figure_html(d, f, k) for k, f in enumerate(figs, 1))
    tables = s.get("tables", [])
    if tables:
        parts.append("<h2>Tables</h2>")
        parts.extend(_table_html(d, t) for t in tables)
    notes = s.get("notes", [])
    if notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(
            f"<li><pre>{e(n)}</pre></li>" if "\n" in n.strip() else f"<li>{e(n)}</li>"
            for n in notes) + "</ul>")
    series = s.get("series", [])
    if series:
        rows = []
        for t in series:
            files = [f"<a href='{e(t['csv'])}'>{e(t['csv'])}</a>"]
            if t.get("parquet"):
                files.insert(0, f"<a href='{e(t['parquet'])}'>{e(t['parquet'])}</a> (every row)")
                files[-1] += f" (every {t['csv_every']}th row)"
            desc = t.get("description") or _series_description(t)
            rows.append(f"<tr><td>{'<br>'.join(files)}</td><td class='num'>{t['rows']}</td>"
                        f"<td class='cols'>{e(', '.join(t['columns']))}</td><td>{e(desc)}</td></tr>")
        parts.append("<h2>Time series files</h2>" + _wide(
            "<table id='series'><tr><th>file</th><th>rows</th><th>columns</th><th>description</th></tr>"
            + "".join(rows) + "</table>"))
    rerun = s.get("rerun") or f"sinslab run {s['experiment']} --config config.toml"
    parts.append(f"<h2>Configuration</h2><p>Re-run from this folder with <code id='rerun'>{e(rerun)}</code>.</p>"
                 f"<pre id='config'>{e(cfg_text)}</pre>")
    parts.append(f"<script>{_SCRIPT}</script></body></html>\n")
    page = "".join(parts)
    return page.replace("</style>", _cjk_font_css(page) + "</style>", 1)


#: the claims table's columns (their widths in the page's CSS: the table fits the page,
#: its verdicts in view at 1400 px and less)
_CLAIM_COLUMNS = ("id", "origin", "statement", "measured", "expected", "result")


def _parts(text: str) -> str:
    """HTML of a "a · b · c" value list: each short item kept on one line, breaks between
    items."""
    return " · ".join(f"<span class='q'>{e(p)}</span>" if len(p) <= 32 else e(p)
                      for p in text.split(" · "))


def _breakable(name: str) -> str:
    """A snake_case name that may wrap after its underscores (and nowhere else)."""
    return "_<wbr>".join(e(p) for p in name.split("_"))


def _claim_row(c: dict) -> str:
    ok = bool(c.get("passed"))
    measured, expected = _claim_cells(c)
    return (f"<tr class='{'pass' if ok else 'fail'}' data-claim='{e(str(c.get('id')))}'>"
            f"<td><code class='id'>{e(str(c.get('id')))}</code></td><td>{e(c.get('origin') or '')}</td>"
            f"<td>{e(str(c.get('statement', '')))}</td>"
            f"<td class='num'>{_parts(measured)}</td><td class='num'>{_parts(expected)}</td>"
            f"<td class='verdict'>{'pass' if ok else 'FAIL'}</td></tr>")


#: the robustness section's own rules (kept inside the section)
_ROBUST_CSS = ("#robustness td.flip{background:#fff4d6}#robustness td.label{font-weight:bold}"
               "#robustness ul{margin:0;padding-left:1.1em}#robustness li.flip{color:#8a5a00}"
               "#robustness .src{color:#666;font-size:.9em}")


def _robustness_html(rob: dict, claims: list) -> str:
    """The robustness section: the assumptions once (default, whose, the claims resting on
    them), then per claim its label and its verdict at the default and under each
    alternative (flipped verdicts marked)."""
    entries = rob.get("claims") or {}
    head = f"{rob.get('paper_claims_robust', 0)} of {rob.get('paper_claims', 0)} paper claims robust"
    if rob.get("swept"):
        cpu = rob.get("cpu_s")
        head += (f"; physics alternatives re-run ({len(rob.get('axes') or [])} assumptions"
                 + (f", {with_unit(float(cpu), 's')} CPU in this process" if isinstance(cpu, (int, float)) else "")
                 + ")")
    else:
        head += "; physics alternatives not run (sinslab run NAME --robustness runs them)"
    assumptions = {}
    for c in claims:
        for x in (entries.get(c.get("id")) or {}).get("assumptions", []):
            a = assumptions.setdefault(x["name"], {**x, "claims": []})
            a["claims"].append(str(c.get("id")))
    arows = "".join(f"<tr><td>{e(a['name'])}</td><td>{e(a['default'])}</td>"
                    f"<td>{'the paper' if a.get('source') == 'paper' else 'the project'}</td>"
                    f"<td>{', '.join(f'<code>{e(i)}</code>' for i in a['claims'])}</td></tr>"
                    for a in assumptions.values())
    rows = []
    for c in claims:
        r = entries.get(c.get("id"))
        if r is None:
            continue
        names, unit = (c.get("measured") or {}).get("names"), (c.get("measured") or {}).get("unit", "")
        default = bool(r.get("default"))
        items = []
        for a in r.get("alternatives", []):
            base = a.get("baseline", default)
            ok = a.get("passed")
            flip = ok is not None and bool(ok) != bool(base)
            verdict = "undecided" if ok is None else ("pass" if ok else "FAIL")
            val = "" if a.get("value") is None else f": {quantity(a['value'], names, unit)}"
            extra = f" ({a['note']})" if a.get("note") else ""
            if "baseline" in a and bool(base) != default:
                extra += f" [the reduced run at the default: {'pass' if base else 'FAIL'}]"
            items.append(f"<li class='{'flip' if flip else ''}'>{e(a['assumption'])} — {e(a['name'])}{e(val)} → "
                         f"<b>{verdict}</b>{e(extra)} <span class='src'>({e(a.get('how', ''))})</span></li>")
        flipped = bool(r.get("depends_on"))
        rows.append(f"<tr class='{'pass' if default else 'fail'}' data-robust='{e(str(c.get('id')))}'>"
                    f"<td><code class='id'>{e(str(c.get('id')))}</code></td><td>{e(c.get('origin') or '')}</td>"
                    f"<td class='label{' flip' if flipped else ''}'>{e(r.get('label', ''))}</td>"
                    f"<td class='verdict'>{'pass' if default else 'FAIL'}</td><td><ul>{''.join(items)}</ul></td></tr>")
    return (f"<h2>Robustness</h2><style>{_ROBUST_CSS}</style><p class='sub' id='robust-summary'>{e(head)}</p>"
            + _wide("<table id='assumptions'><tr><th>assumption</th><th>default</th><th>whose</th>"
                    "<th>claims</th></tr>" + arows + "</table>")
            + _wide("<table id='robustness'><tr><th>claim</th><th>origin</th><th>label</th><th>default</th>"
                    "<th>alternatives (verdict)</th></tr>" + "".join(rows) + "</table>"))


def _series_description(t: dict) -> str:
    """A description for a time-series file that declared none: what its columns hold."""
    cols = [c for c in t.get("columns", []) if c not in ("t_s", "t", "time_s")]
    return (f"{t.get('name', 'table')}: {len(cols)} column(s) against time t_s; units in the "
            "column names' suffixes (_m, _mps, _arcmin, _arcsec, _deg, _dph)")


def build(run_dir: str | os.PathLike) -> Path:
    """(Re)write ``run_dir/report.html`` atomically; return its path."""
    d = Path(run_dir)
    text = render(d)
    return atomic_write(d / "report.html", text)


def index(out: str | os.PathLike, runs: list[tuple[str, str | os.PathLike]],
          failed: dict[str, str] | None = None) -> Path:
    """Write ``out/index.html`` linking the reports of ``runs`` (``[(name, run_dir)]``)."""
    out = Path(out)
    rows = []
    for name, rd in runs:
        rd = Path(rd)
        rel = os.path.relpath(rd / "report.html", out)
        try:
            s = _load_summary(rd)
            claims = s.get("claims", [])
            n = sum(bool(c.get("passed")) for c in claims)
            verdict = f"{n}/{len(claims)}" + (f" ({tally(claims, s.get('robustness'))})"
                                               if any(c.get("origin") for c in claims) else "")
            cls = "ok" if n == len(claims) else "bad"
            purpose = s.get("purpose", "")
            sets = (s.get("variant") or {}).get("sets")
            if sets:
                purpose = f"{s['experiment']} with {', '.join(sets)} — {purpose}"
            rt = num((s.get("timing") or {}).get("compute_s", s["metrics"].get("runtime_s")))
        except ReportError as err:
            verdict, cls, purpose, rt = "no summary", "bad", str(err), "n/a"
        rows.append(f"<tr><td><a href='{e(rel)}'>{e(name)}</a></td><td>{e(purpose)}</td>"
                    f"<td><span class='badge {cls}'>{e(verdict)}</span></td><td class='num'>{e(rt)}</td></tr>")
    for name, err in (failed or {}).items():
        rows.append(f"<tr><td>{e(name)}</td><td>{e(err)}</td><td><span class='badge bad'>error"
                    f"</span></td><td></td></tr>")
    from sinslab import __version__

    page = (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>sinslab runs</title>"
            f"<style>{_CSS}</style></head><body><h1>sinslab runs</h1>"
            f"<p class='sub'>sinslab {e(__version__)} · {_dt.datetime.now().isoformat(timespec='seconds')}</p>"
            f"<div class='scroll'><table id='runs'><tr><th>run</th><th>what it runs</th><th>claims passed</th>"
            f"<th>computation [s]</th></tr>{''.join(rows)}</table></div></body></html>\n")
    out.mkdir(parents=True, exist_ok=True)
    return atomic_write(out / "index.html", page)
