"""Self-contained HTML report of a run folder.

``render(DIR)`` reads ``summary.json``, ``config.toml`` and the figures' PNG files of a
run folder and returns one HTML page with everything embedded (figures as base64 PNG,
linked to their SVG files), so the page can be mailed or archived alone. ``build(DIR)``
writes it atomically to ``DIR/report.html`` (``sinslab report DIR``). ``index(...)``
writes the page linking several reports (``sinslab demo``).

Sections: header (experiment, purpose, version, date, quick or full), claims table
(``id="claims"``, one row per claim, pass/fail), metrics table (value, unit,
description), figures, tables (Monte Carlo statistics etc.), notes, time-series files,
configuration. After the page has loaded, a small script writes the number of figures
and of figures actually decoded (``naturalWidth > 0``) into ``data-figures-total`` and
``data-figures-loaded`` on ``<body>`` — the browser test reads them.
"""
from __future__ import annotations

import base64
import datetime as _dt
import html
import json
import math
import os
from pathlib import Path

from sinslab.app.errors import UserError
from sinslab.core.atomic import atomic_write

__all__ = ["ReportError", "render", "build", "index"]


class ReportError(UserError):
    """A run folder the report cannot be built from."""


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:2em auto;
max-width:1100px;padding:0 1em;color:#1d1d1f;line-height:1.4}
h1{margin-bottom:.1em}h2{border-bottom:1px solid #ddd;padding-bottom:.2em;margin-top:1.6em}
.sub{color:#666;margin-top:0}table{border-collapse:collapse;margin:.5em 0;font-size:.92em}
th,td{border:1px solid #ccc;padding:.3em .6em;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{font-family:ui-monospace,Menlo,Consolas,monospace;white-space:nowrap}
tr.pass td.verdict{background:#dff5e1;color:#11631d;font-weight:bold}
tr.fail td.verdict{background:#fde2e1;color:#a11;font-weight:bold}
.badge{display:inline-block;padding:.15em .6em;border-radius:1em;font-weight:bold}
.badge.ok{background:#dff5e1;color:#11631d}.badge.bad{background:#fde2e1;color:#a11}
figure{margin:1em 0;text-align:center}figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{color:#444;font-size:.92em}pre{background:#f7f7f7;padding:.8em;overflow-x:auto;font-size:.85em}
#claims td.num,#metrics td.num{white-space:normal;overflow-wrap:anywhere;max-width:18em}
#claims td:nth-child(2){min-width:22em}
"""

_SCRIPT = """
window.addEventListener('load', function () {
  var imgs = document.querySelectorAll('img.figure');
  var ok = 0;
  for (var i = 0; i < imgs.length; i++) { if (imgs[i].complete && imgs[i].naturalWidth > 0) ok++; }
  document.body.setAttribute('data-figures-total', String(imgs.length));
  document.body.setAttribute('data-figures-loaded', String(ok));
});
"""

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


def _figure_html(d: Path, fig: dict) -> str:
    png = d / fig.get("png", f"{fig['name']}.png")
    if not png.is_file():
        raise ReportError(f"{png}: figure file missing")
    b64 = base64.b64encode(png.read_bytes()).decode("ascii")
    svg = fig.get("svg")
    link = f' <a href="{e(svg)}">SVG</a>' if svg and (d / svg).is_file() else ""
    return (f'<figure id="fig-{e(fig["name"])}"><img class="figure" alt="{e(fig["name"])}" '
            f'src="data:image/png;base64,{b64}">'
            f'<figcaption><b>{e(fig["name"])}</b> — {e(fig.get("caption", ""))}{link}</figcaption></figure>')


def _table_html(d: Path, t: dict) -> str:
    import pandas as pd

    path = d / t["csv"]
    if not path.is_file():
        return f"<p>missing table file {e(t['csv'])}</p>"
    df = pd.read_csv(path)
    head = "".join(f"<th>{e(str(c))}</th>" for c in df.columns)
    rows = "".join("<tr>" + "".join(f'<td class="num">{e(_fmt(v.item() if hasattr(v, "item") else v))}</td>'
                                    for v in row) + "</tr>" for row in df.itertuples(index=False))
    return (f'<h3>{e(t["name"])}</h3><p>{e(t.get("caption", ""))}</p>'
            f'<table class="data"><tr>{head}</tr>{rows}</table>')


def render(run_dir: str | os.PathLike) -> str:
    """The report page of a run folder as HTML text (raises :class:`ReportError`)."""
    d = Path(run_dir)
    s = _load_summary(d)
    cfg_file = d / "config.toml"
    cfg_text = cfg_file.read_text(encoding="utf-8") if cfg_file.is_file() else json.dumps(
        s.get("config", {}), indent=2)
    claims = s.get("claims", [])
    n_pass = sum(bool(c.get("passed")) for c in claims)
    all_ok = n_pass == len(claims)
    info = s.get("metric_info", {})

    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
             f"<meta name='viewport' content='width=device-width, initial-scale=1'>"
             f"<title>sinslab — {e(s['experiment'])}</title><style>{_CSS}</style></head><body>"]
    parts.append(f"<h1>{e(s['experiment'])}</h1>")
    parts.append(f"<p class='sub'>{e(s.get('purpose', ''))}</p>")
    meta = [f"sinslab {e(str(s.get('sinslab_version', '?')))}",
            f"run {e(s.get('started', '?'))}",
            "quick run (--quick)" if s.get("quick") else "full scale"]
    if s.get("paper"):
        meta.append(f"after {e(s['paper'])}")
    rt = s["metrics"].get("runtime_s")
    if isinstance(rt, (int, float)):
        meta.append(f"computation {rt:.3g} s")
    parts.append("<p class='sub'>" + " · ".join(meta) + "</p>")
    badge = "ok" if all_ok else "bad"
    parts.append(f"<p><span class='badge {badge}' id='verdict'>{n_pass} of {len(claims)} claims passed"
                 f"</span></p>")

    parts.append("<h2>Claims</h2><table id='claims'><tr><th>id</th><th>statement</th>"
                 "<th>measured</th><th>expected</th><th>result</th></tr>")
    for c in claims:
        ok = bool(c.get("passed"))
        parts.append(f"<tr class='{'pass' if ok else 'fail'}' data-claim='{e(str(c.get('id')))}'>"
                     f"<td>{e(str(c.get('id')))}</td><td>{e(str(c.get('statement', '')))}</td>"
                     f"<td class='num'>{e(_fmt(c.get('measured')))}</td>"
                     f"<td class='num'>{e(_fmt(c.get('expected')))}</td>"
                     f"<td class='verdict'>{'pass' if ok else 'FAIL'}</td></tr>")
    parts.append("</table>")

    parts.append("<h2>Metrics</h2><table id='metrics'><tr><th>metric</th><th>value</th>"
                 "<th>unit</th><th>description</th></tr>")
    for name, v in s["metrics"].items():
        mi = info.get(name, {})
        parts.append(f"<tr><td><code>{e(name)}</code></td><td class='num'>{e(_fmt(v))}</td>"
                     f"<td>{e(mi.get('unit', ''))}</td><td>{e(mi.get('description', ''))}</td></tr>")
    parts.append("</table>")

    figs = s.get("figures", [])
    if figs:
        parts.append("<h2>Figures</h2>")
        parts.extend(_figure_html(d, f) for f in figs)
    tables = s.get("tables", [])
    if tables:
        parts.append("<h2>Tables</h2>")
        parts.extend(_table_html(d, t) for t in tables)
    notes = s.get("notes", [])
    if notes:
        parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{e(n)}</li>" for n in notes) + "</ul>")
    series = s.get("series", [])
    if series:
        parts.append("<h2>Time series files</h2><table><tr><th>file</th><th>rows</th>"
                     "<th>columns</th><th>description</th></tr>")
        for t in series:
            files = [f"<a href='{e(t['csv'])}'>{e(t['csv'])}</a>"]
            if t.get("parquet"):
                files.insert(0, f"<a href='{e(t['parquet'])}'>{e(t['parquet'])}</a>")
                files[-1] += f" (every {t['csv_every']}th row)"
            parts.append(f"<tr><td>{'<br>'.join(files)}</td><td class='num'>{t['rows']}</td>"
                         f"<td>{e(', '.join(t['columns']))}</td><td>{e(t.get('description', ''))}</td></tr>")
        parts.append("</table>")
    parts.append(f"<h2>Configuration</h2><p>Re-run with <code>sinslab run {e(s['experiment'])} "
                 f"--config config.toml</code>.</p><pre id='config'>{e(cfg_text)}</pre>")
    parts.append(f"<script>{_SCRIPT}</script></body></html>\n")
    return "".join(parts)


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
            verdict = f"{n}/{len(claims)}"
            cls = "ok" if n == len(claims) else "bad"
            purpose = s.get("purpose", "")
            rt = _fmt(s["metrics"].get("runtime_s"), 3)
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
            f"<table id='runs'><tr><th>experiment</th><th>purpose</th><th>claims passed</th>"
            f"<th>computation [s]</th></tr>{''.join(rows)}</table></body></html>\n")
    out.mkdir(parents=True, exist_ok=True)
    return atomic_write(out / "index.html", page)
