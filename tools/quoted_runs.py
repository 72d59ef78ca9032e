"""Write docs/runs.json: the values README.md and docs/ quote from the full demo runs.

Usage (after ``make demo``, which writes ``runs/``)::

    .venv/bin/python tools/quoted_runs.py [DEMO_FOLDER] [--full DIR]   # default: runs
    .venv/bin/python tools/quoted_runs.py --navigate         # the quoted navigate runs (minutes)

``--full DIR`` also records the full-scale runs the docs quote that are no demo run
(``QUOTED`` entries whose run is ``full NAME --set ...``, e.g. a variant of paper 001's
noise handling), made in ``DIR`` (each run once: a folder with its summary is reused).
The second form runs every ``sinslab navigate`` command the docs quote (``QUOTED`` entries
whose run is ``navigate ...``: the drive of docs/recorded-data.md with its variants, the
walk of docs/raw-gnss.md) on the shared data folder and records, under ``navigate``, the
values quoted from each, keyed by the command without ``--out``. The test re-runs the
commands the docs show and checks them against this record, so a change that moves a
navigate number asks for this refresh. Each form keeps the other's part of the record.

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
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "runs.json"


def _quoted_module():
    spec = importlib.util.spec_from_file_location("test_docs_commands", ROOT / "tests" / "test_docs_commands.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _names(t, kind: str) -> dict[str, list[str]]:
    """``{label: [value names]}`` the QUOTED entries of one kind (``demo``, ``full``,
    ``navigate``) read, by the label the record keeps them under."""
    names: dict[str, list[str]] = {}
    for _, _, run, keys, _ in t.QUOTED:
        if run.split()[0] == kind:
            bucket = names.setdefault(t.record_label(run), [])
            bucket += [n for k in keys for n in t.quoted_names(k) if n not in bucket]
    return names


def _slug(label: str) -> str:
    return re.sub(r"[^A-Za-z0-9._]+", "-", label).strip("-")


def full_runs(work: Path) -> None:
    """Make the quoted full-scale runs that are no demo run (``full NAME --set ...``) in
    ``work/<slug>`` where that folder holds no summary yet (tens of seconds to minutes each)."""
    import shlex
    import subprocess

    t = _quoted_module()
    exe = Path(sys.executable).with_name("sinslab")
    for label in sorted(_names(t, "full")):
        folder = work / _slug(label)
        if not (folder / "summary.json").is_file():
            print(f"sinslab run {label}", flush=True)
            r = subprocess.run([str(exe), "-q", "run", *shlex.split(label), "--out", str(folder)],
                               capture_output=True, text=True)
            if r.returncode != 0:
                sys.exit(f"quoted_runs: error: `run {label}` failed (exit {r.returncode}): {r.stderr.strip()[-500:]}")


def record(demo: Path, full: Path | None = None) -> dict:
    """The record of the quoted demo runs in the folder ``demo`` (``demo/LABEL/summary.json``)
    and of the other full-scale runs in ``full`` (default ``demo``; ``full/<slug>/summary.json``)."""
    t = _quoted_module()
    names = _names(t, "demo")
    where = {label: demo / label for label in names}
    full_names = _names(t, "full")
    names.update(full_names)
    where.update({label: (full or demo) / _slug(label) for label in full_names})
    runs = {}
    for label in sorted(names):
        path = where[label] / "summary.json"
        if not path.is_file():
            sys.exit(f"quoted_runs: error: {path} does not exist: run `sinslab demo --out {demo}` "
                     f"(and `tools/quoted_runs.py --full {full or demo}`) first")
        s = json.loads(path.read_text(encoding="utf-8"))
        if s.get("quick"):
            sys.exit(f"quoted_runs: error: {path} is a --quick run; the docs quote the full demo")
        runs[label] = {
            "experiment": s["experiment"],
            "sets": (t.label_sets(label) if label in full_names
                     else list((s.get("variant") or {}).get("sets", []))),
            "config_sha256": t.config_digest(s["config"]),
            "sinslab_version": s.get("sinslab_version"),
            "values": {n: t.summary_value(s, n) for n in sorted(names[label])},
        }
    return {"about": "values README.md and docs/ quote from the full `sinslab demo` runs; written by "
                     "tools/quoted_runs.py, checked by tests/test_docs_commands.py", "runs": runs}


def navigate_record(work: Path) -> dict:
    """Run the quoted navigate commands (data files from the shared data folder) into
    ``work`` and return ``{label: {"values", "sinslab_version"}}``."""
    import shlex
    import subprocess

    t = _quoted_module()
    names = _names(t, "navigate")
    exe = Path(sys.executable).with_name("sinslab")
    out = {}
    for i, label in enumerate(sorted(names)):
        folder = work / f"nav{i}"
        argv = [str(exe), "-q", *t._substitute(shlex.split(label)), "--out", str(folder)]
        print(label, flush=True)
        r = subprocess.run(argv, capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"quoted_runs: error: `{label}` failed (exit {r.returncode}): {r.stderr.strip()[-500:]}")
        s = json.loads((folder / "summary.json").read_text(encoding="utf-8"))
        out[label] = {"sinslab_version": s.get("sinslab_version"),
                      "values": {n: t.summary_value(s, n) for n in sorted(names[label])}}
    return out


def main(argv: list[str]) -> None:
    old = json.loads(OUT.read_text(encoding="utf-8")) if OUT.is_file() else {}
    if argv[:1] == ["--navigate"]:
        import tempfile

        with tempfile.TemporaryDirectory() as work:
            rec = {**old, "navigate": navigate_record(Path(work))}
    else:
        full = None
        if "--full" in argv:
            i = argv.index("--full")
            full = Path(argv[i + 1])
            argv = argv[:i] + argv[i + 2:]
            full_runs(full)
        demo = Path(argv[0]) if argv else Path("runs")
        rec = {**record(demo, full), **({"navigate": old["navigate"]} if "navigate" in old else {})}
    rec["about"] = ("values README.md and docs/ quote from the full `sinslab demo` runs (runs) and from "
                    "`sinslab navigate` runs on the shared data (navigate); written by tools/quoted_runs.py, "
                    "checked by tests/test_docs_commands.py")
    text = json.dumps(rec, indent=1, ensure_ascii=False) + "\n"
    tmp = OUT.with_suffix(".json.tmp")
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, OUT)                       # never a half-written record
    print(OUT)


if __name__ == "__main__":
    main(sys.argv[1:])
