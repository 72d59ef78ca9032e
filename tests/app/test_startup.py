"""The command line starts at once: ``import sinslab.cli``, ``sinslab list``,
``sinslab --help`` and ``sinslab config NAME`` import none of the heavy numerical or
plotting packages (they are imported by the commands that compute), and ``config NAME``
imports no experiment module but NAME's. Checked by the modules loaded, not by timing."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import sinslab.experiments as E

SRC = Path(__file__).resolve().parents[2] / "src"
HEAVY = ("numba", "scipy", "matplotlib", "dask", "distributed", "pandas", "pyarrow")

_PROBE = """
import json, sys
sys.argv = ["sinslab"] + {argv!r}
import sinslab.cli
def _exit(code):                     # the command line ends its process at once; the probe
    raise SystemExit(code)           # looks at the modules loaded after the command
sinslab.cli.exit_now = _exit
if sys.argv[1:]:
    try:
        sinslab.cli.main()
    except SystemExit:
        pass
heavy = sorted(m for m in sys.modules if m.split(".")[0] in {heavy!r})
print("\\nHEAVY=" + json.dumps(sorted({{m.split(".")[0] for m in heavy}})))
print("EXPERIMENTS=" + json.dumps(sorted(m for m in sys.modules if m.startswith("sinslab.experiments."))))
"""


def _probe(argv):
    """Run ``sinslab ARGV`` in a fresh interpreter: (result, heavy packages loaded,
    experiment modules loaded)."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", _PROBE.format(argv=argv, heavy=HEAVY)],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    found = {}
    for key in ("HEAVY", "EXPERIMENTS"):
        line = [ln for ln in r.stdout.splitlines() if ln.startswith(key + "=")][-1]
        found[key] = json.loads(line[len(key) + 1:])
    return r, found["HEAVY"], found["EXPERIMENTS"]


@pytest.mark.parametrize("argv", [[], ["list"], ["--help"], ["run", "--help"], ["navigate", "--help"]],
                         ids=["import", "list", "help", "run-help", "navigate-help"])
def test_cli_start_imports_no_heavy_package(argv):
    r, heavy, experiments = _probe(argv)
    assert heavy == [], heavy
    if argv == ["list"]:
        assert "free-inertial" in r.stdout and "static-alignment" in r.stdout
        assert set(experiments) <= {"sinslab.experiments.base"}, experiments   # names read from the sources


#: every experiment module of the package, by the NAME its source declares
EXPERIMENTS = sorted(E._declared_modules().items())


@pytest.mark.parametrize("name, modules", EXPERIMENTS, ids=[n for n, _ in EXPERIMENTS])
def test_config_imports_its_experiment_alone_and_no_heavy_package(name, modules):
    """``sinslab config NAME`` builds NAME's Config (its validators run on the defaults)
    from NAME's module alone: no other experiment module, no heavy package."""
    r, heavy, experiments = _probe(["config", name])
    assert f"— {name}: " in r.stdout.splitlines()[0], r.stdout[:200]     # the TOML was printed
    assert heavy == [], f"config {name} imports {heavy}"
    assert experiments == sorted(modules + ["sinslab.experiments.base"]), experiments


def test_unknown_experiment_named_without_importing_any():
    """A misspelt name gets its one-line error with the suggestion from the names the
    sources declare, importing no experiment module and no heavy package."""
    r, heavy, experiments = _probe(["config", "static-alignmnt"])
    assert "unknown experiment 'static-alignmnt'; did you mean 'static-alignment'?" in r.stderr
    assert heavy == [] and set(experiments) <= {"sinslab.experiments.base"}, (heavy, experiments)
    r, heavy, experiments = _probe(["config", "zzz"])
    assert "known: double-star, free-inertial" in r.stderr and heavy == []


def test_declared_modules_agree_with_the_registry():
    """The name -> module map read from the sources (what ``get`` imports before the
    registry exists) is the registry's, and ``get`` through it returns the same experiment."""
    ours = {n: e for n, e in E.registry().items() if e.module.startswith("sinslab.experiments.")}
    assert dict(EXPERIMENTS) == {n: [e.module] for n, e in ours.items()}
    for name, exp in ours.items():
        assert E._import_one(name) == exp


def test_probe_sees_heavy_imports(tmp_path):
    """The probe itself can fail: running a command that computes does import them
    (``allan`` on a small recorded file: its figures need matplotlib)."""
    rng = np.random.default_rng(1)
    rows = np.c_[0.01 * np.arange(1, 2001), rng.normal(0, 1e-3, (2000, 5)), 1 + rng.normal(0, 1e-4, 2000)]
    f = tmp_path / "rest.csv"
    f.write_text("t[s],gx[deg/s],gy[deg/s],gz[deg/s],ax[g],ay[g],az[g]\n"
                 + "".join(",".join(f"{v:.6f}" for v in row) + "\n" for row in rows))
    r, heavy, _ = _probe(["allan", str(f), "--out", str(tmp_path / "out")])
    assert (tmp_path / "out" / "summary.json").is_file(), r.stderr
    assert "matplotlib" in heavy, heavy
