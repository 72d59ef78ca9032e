"""Write docs/runs.json: the values README.md and docs/ quote from the full demo runs.

Usage (after ``make demo``, which writes ``runs/``)::

    .venv/bin/python tools/quoted_runs.py [DEMO_FOLDER]      # default: runs

For every run that ``tests/test_docs_commands.py`` quotes as ``demo LABEL`` (its ``QUOTED``
table, the one list of quoted numbers), the record keeps the experiment, the variant's
``--set`` items, the SHA-256 of the resolved config the run used, and only the metrics and
claim values the docs quote. The test checks the docs against this record and the record
against today's default configs; after a change that moves a quoted number, re-run the demo,
run this script, and update the documents until the test passes.
"""
import importlib.util
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "runs.json"


def _quoted_module():
    spec = importlib.util.spec_from_file_location("test_docs_commands", ROOT / "tests" / "test_docs_commands.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def record(demo: Path) -> dict:
    """The record of the quoted demo runs in the folder ``demo`` (``demo/LABEL/summary.json``)."""
    t = _quoted_module()
    names: dict[str, list[str]] = {}
    for _, _, run, keys, _ in t.QUOTED:
        if run.startswith("demo "):
            bucket = names.setdefault(run.split()[1], [])
            bucket += [n for k in keys for n in t.quoted_names(k) if n not in bucket]
    runs = {}
    for label in sorted(names):
        path = demo / label / "summary.json"
        if not path.is_file():
            sys.exit(f"quoted_runs: error: {path} does not exist: run `sinslab demo --out {demo}` first")
        s = json.loads(path.read_text(encoding="utf-8"))
        if s.get("quick"):
            sys.exit(f"quoted_runs: error: {path} is a --quick run; the docs quote the full demo")
        runs[label] = {
            "experiment": s["experiment"],
            "sets": list((s.get("variant") or {}).get("sets", [])),
            "config_sha256": t.config_digest(s["config"]),
            "sinslab_version": s.get("sinslab_version"),
            "values": {n: t.summary_value(s, n) for n in sorted(names[label])},
        }
    return {"about": "values README.md and docs/ quote from the full `sinslab demo` runs; written by "
                     "tools/quoted_runs.py, checked by tests/test_docs_commands.py", "runs": runs}


def main(argv: list[str]) -> None:
    demo = Path(argv[0]) if argv else Path("runs")
    text = json.dumps(record(demo), indent=1, ensure_ascii=False) + "\n"
    tmp = OUT.with_suffix(".json.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, OUT)                       # never a half-written record
    print(OUT)


if __name__ == "__main__":
    main(sys.argv[1:])
