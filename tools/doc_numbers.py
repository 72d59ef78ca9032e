"""Audit: every number in README.md and docs/**/*.md, and whether a test checks it.

Usage::

    .venv/bin/python tools/doc_numbers.py [ROOT] [--raw [--data DIR]] [--list] [--doc NAME] [--class CLASS]

A number is **checked** when it lies inside a text that a test compares with a run, a
stored record or a measurement: the ``QUOTED`` table of ``tests/test_docs_commands.py``
(runs, ``docs/runs.json``, ``docs/benchmarks.json``), the texts given to
``support.assert_doc_quotes`` (and the other quoted literals of the test functions that
call it), the quotes of ``test_rtklib_drive_table_is_the_data``, the table rows
``examples/raw_gnss_walk.py`` prints (docs/raw-gnss.md, with ``--raw``: 8 s), and the
terminal output blocks ``test_shown_output_is_what_the_command_prints`` compares.

Every other number gets a class, so that only the prose needs reading:

- ``command``: inside a fenced block of commands, code or config (the commands run in
  ``tests/test_docs_commands.py``; their numbers are inputs);
- ``inline-code``: inside a backtick span in prose (option values, config keys, names);
- ``reference``: an equation, section, paper, figure or table number, a date, a version, a
  commit, a file name;
- ``heading``: in a heading;
- ``prose``: everything else, to be read: a paper's constant, a config default, a unit or
  scenario input, an analytic value — or a number a run produced, which must be checked.

Prints per document the count of numbers, checked, and unchecked by class; ``--list``
prints the unchecked numbers of class ``--class`` (default ``prose``) with their line.
"""
from __future__ import annotations

import ast
import contextlib
import importlib.util
import io
import re
import sys
from collections import Counter
from pathlib import Path

NUM = re.compile(r"((?:(?<!\w)[−-])?\d+(?:[.,]\d+)*)(?:e([−-]?\d+))?")
REFERENCE = re.compile(
    r"(?:\beqs?\.?|\bequations?|\bpaper|\bpapers|§|\bsection|\bfig(?:ure)?s?\.?|\btable|\bcommit|\bv(?=\d)"
    r"|\bissue|\bstep|\bline)\s*\(?$", re.I)
OUTPUT_MARK = "<!-- output of the command above -->"


def _norm(s: str) -> str:
    return " ".join(s.split())


def _quotes(root: Path, raw: Path | None) -> dict[str, list[str]]:
    """``{document name: [quoted texts a test checks]}``."""
    spec = importlib.util.spec_from_file_location("_tdc", root / "tests" / "test_docs_commands.py")
    t = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(t)
    quotes: dict[str, list[str]] = {}
    for q in t.QUOTED:
        quotes.setdefault(q[0], []).append(q[1])
    for f in (root / "tests").rglob("*.py"):
        tree = ast.parse(f.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if not isinstance(node, ast.FunctionDef):
                continue
            src = ast.unparse(node)
            if "assert_doc_quotes(" not in src and "quoted = [" not in src:
                continue
            docs = set(re.findall(r"docs/[\w/.-]+\.md|README\.md", src)) or {"?"}
            for c in ast.walk(node):
                if isinstance(c, ast.Constant) and isinstance(c.value, str) and re.search(r"\d", c.value):
                    for d in docs:      # a table cell's escaped pipe, as written or unescaped
                        quotes.setdefault(Path(d).name, []).extend({c.value, c.value.replace("\\|", "|")})
    if raw:
        spec = importlib.util.spec_from_file_location("_rgw", root / "examples" / "raw_gnss_walk.py")
        m = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(m)
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            m.main(raw / "rtklib-walk")
        rows = {_norm(r.replace("**", "").replace("−", "-")) for r in buf.getvalue().splitlines()
                if r.startswith("| ")}
        text = (root / "docs" / "raw-gnss.md").read_text(encoding="utf-8")
        quotes.setdefault("raw-gnss.md", []).extend(
            ln for ln in text.splitlines() if _norm(ln.replace("**", "").replace("−", "-")) in rows)
    return quotes


def audit(root: Path, raw: Path | None = None):
    """``(per document {class: count}, [(doc, line, class, number, text)])`` of every number
    (``raw``: the shared data folder, to run the raw-GNSS example)."""
    quotes = _quotes(root, raw)
    docs = [root / "README.md", *sorted((root / "docs").rglob("*.md"))]
    table, rows = {}, []
    for p in docs:
        lines = p.read_text(encoding="utf-8").splitlines()
        flat, owner = "", []
        for i, ln in enumerate(lines):
            s = _norm(ln)
            if not s:
                continue
            if flat:
                flat += " "
                owner.append(i)
            flat += s
            owner.extend([i] * len(s))
        spans = []
        for q in quotes.get(p.name, []):
            qn, k = _norm(q), 0
            while (k := flat.find(qn, k)) >= 0:
                spans.append((k, k + len(qn)))
                k += 1
        kind, fence, output = {}, False, False
        for i, ln in enumerate(lines):
            if ln.strip().startswith("```"):
                if not fence:
                    output = i > 0 and any(lines[j].strip() == OUTPUT_MARK for j in range(max(0, i - 2), i))
                fence = not fence
                kind[i] = "command"
                continue
            kind[i] = ("checked" if output else "command") if fence else (
                "heading" if ln.startswith("#") else "prose")
        count = Counter()
        for m in NUM.finditer(flat):
            i = owner[m.start()]
            cls = "checked" if any(a <= m.start() < b for a, b in spans) else kind[i]
            if cls == "prose":
                before = flat[:m.start()]
                if before.count("`") % 2 == 1:
                    cls = "inline-code"
                elif (REFERENCE.search(before[-14:]) or re.search(r"\d{4}-\d\d-\d\d|[0-9a-f]{7}\b", flat[
                        max(0, m.start() - 8):m.end() + 8]) or re.match(r"[\w-]*\.(?:md|py|csv|pos|ubx|mat|imu)\b",
                                                                        flat[m.end():])):
                    cls = "reference"
            count[cls] += 1
            if cls != "checked":
                rows.append((p.relative_to(root), i + 1, cls, m.group(0), lines[i].strip()))
        table[p.relative_to(root)] = count
    return table, rows


def main(argv: list[str]) -> None:
    opts = {"--data", "--doc", "--class"}
    args = [a for i, a in enumerate(argv) if not a.startswith("--") and (i == 0 or argv[i - 1] not in opts)]
    root = Path(args[0]).resolve() if args else Path(__file__).resolve().parents[1]
    data = Path(argv[argv.index("--data") + 1]) if "--data" in argv else root.parent / "shared" / "data"
    table, rows = audit(root, raw=data if "--raw" in argv else None)
    classes = ["checked", "prose", "inline-code", "command", "reference", "heading"]
    print(f"{'document':28s} {'numbers':>7s} " + " ".join(f"{c:>11s}" for c in classes))
    total = Counter()
    for doc, c in table.items():
        total.update(c)
        print(f"{str(doc):28s} {sum(c.values()):7d} " + " ".join(f"{c[k]:11d}" for k in classes))
    print(f"{'all':28s} {sum(total.values()):7d} " + " ".join(f"{total[k]:11d}" for k in classes))
    if "--list" in argv:
        want = argv[argv.index("--class") + 1] if "--class" in argv else "prose"
        only = argv[argv.index("--doc") + 1] if "--doc" in argv else None
        last = None
        for doc, line, cls, num, text in rows:
            if cls == want and (only is None or doc.name == only):
                if (doc, line) != last:
                    print(f"{doc}:{line}: {text[:200]}")
                last = (doc, line)


if __name__ == "__main__":
    main(sys.argv[1:])
