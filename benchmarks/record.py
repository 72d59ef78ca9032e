"""Run one benchmark script and store its figures in ``docs/benchmarks.json``, the record the
docs quote speed and benchmark figures from.

Run: ``.venv/bin/python benchmarks/record.py [--again] NAME [ARGS...]`` (``NAME`` a script
of this folder without ``.py``: ``smoother``, ``speed``, ...; ``ARGS`` passed on to it).

A test cannot time anything (``make test`` never does), so the figures README.md and docs/
quote from ``benchmarks/`` come from this record instead: the script runs in a subprocess
with its ``--out``/``--json`` file, and the record keeps, under ``NAME``, everything it wrote
with the date (UTC), the commit and whether the tree had changes, the machine's CPU count
and its 1-minute load average before, during (sampled every 5 s: min, max) and after the
run. ``tests/test_docs_commands.py`` checks every figure the docs quote from a benchmark
(``bench NAME`` entries of its ``QUOTED`` table) against this record, so a re-run that moves
a figure fails there until the docs are updated. A run replaces the script's earlier runs;
with ``--again`` it is added to those made at the same commit with the same arguments (the
spread of repeated runs on a busy machine: the docs quote its range). The other scripts'
entries are left as they are. The record is written to a temporary name
and renamed: an interrupted run leaves the previous record whole.
"""
from __future__ import annotations

import datetime
import json
import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
RECORD = ROOT / "docs" / "benchmarks.json"
#: scripts whose output file option is ``--json`` (the others take ``--out``)
_JSON_OPTION = {"estimation", "full_rate", "navigate_cost", "rotins", "run_folder", "workers"}


def _git(*args: str) -> str:
    r = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    return r.stdout.strip() if r.returncode == 0 else ""


def run(name: str, args: list[str]) -> dict:
    """Run ``benchmarks/NAME.py ARGS`` and return its figures with the conditions of the run."""
    script = HERE / f"{name}.py"
    if not script.is_file() or name == "record":
        sys.exit(f"record: error: no benchmark script benchmarks/{name}.py")
    loads: list[float] = []
    done = threading.Event()

    def sample():
        while not done.wait(5.0):
            loads.append(os.getloadavg()[0])

    before = os.getloadavg()[0]
    start = datetime.datetime.now(datetime.timezone.utc)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "figures.json"
        opt = "--json" if name in _JSON_OPTION else "--out"
        sampler = threading.Thread(target=sample, daemon=True)
        sampler.start()
        r = subprocess.run([sys.executable, str(script), *args, opt, str(out)], cwd=ROOT)
        done.set()
        sampler.join()
        if r.returncode != 0 or not out.is_file():
            sys.exit(f"record: error: benchmarks/{name}.py {' '.join(args)} failed (exit {r.returncode}); "
                     f"the record is unchanged")
        figures = json.loads(out.read_text(encoding="utf-8"))
    after = os.getloadavg()[0]
    every = [before, *loads, after]
    return {
        "date": start.strftime("%Y-%m-%d"),
        "started_utc": start.strftime("%Y-%m-%dT%H:%M:%SZ"),
        "args": list(args),
        "commit": _git("rev-parse", "--short", "HEAD"),
        "tree_changed": bool(_git("status", "--porcelain", "--untracked-files=no")),
        "cpus": os.cpu_count(),
        "load_before": round(before, 2), "load_after": round(after, 2),
        "load_min": round(min(every), 2), "load_max": round(max(every), 2),
        "figures": figures,
    }


def store(name: str, entry: dict, again: bool = False) -> None:
    """Put the run ``entry`` under ``name`` in the record (after the earlier runs of the same
    commit and arguments with ``again``, else alone), keeping the other scripts' entries."""
    rec = json.loads(RECORD.read_text(encoding="utf-8")) if RECORD.is_file() else {}
    old = rec.get("benchmarks", {}).get(name, {}).get("runs", []) if again else []
    old = [r for r in old if (r["commit"], r["args"]) == (entry["commit"], entry["args"])]
    rec["about"] = ("figures of benchmarks/ scripts that README.md and docs/ quote, each with the date, commit, "
                    "CPU count and load average of its run; written by benchmarks/record.py, checked by "
                    "tests/test_docs_commands.py")
    rec.setdefault("benchmarks", {})[name] = {"runs": [*old, entry]}
    rec["benchmarks"] = dict(sorted(rec["benchmarks"].items()))
    tmp = RECORD.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(rec, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    os.replace(tmp, RECORD)


def main(argv: list[str]) -> None:
    again = argv[:1] == ["--again"]
    argv = argv[1:] if again else argv
    if not argv or argv[0].startswith("-"):
        sys.exit("usage: benchmarks/record.py [--again] NAME [ARGS...]")
    name = argv[0].removesuffix(".py").split("/")[-1]
    store(name, run(name, argv[1:]), again)
    print(RECORD)


if __name__ == "__main__":
    main(sys.argv[1:])
