"""The command line starts at once: ``import sinslab.cli``, ``sinslab list`` and
``sinslab --help`` import none of the heavy numerical or plotting packages (they are
imported by the commands that use them). Checked by the modules loaded, not by timing."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"
HEAVY = ("numba", "scipy", "matplotlib", "dask", "distributed", "pandas", "pyarrow")

_PROBE = """
import json, sys
sys.argv = ["sinslab"] + {argv!r}
import sinslab.cli
if sys.argv[1:]:
    try:
        sinslab.cli.main()
    except SystemExit:
        pass
heavy = sorted(m for m in sys.modules if m.split(".")[0] in {heavy!r})
print("\\nHEAVY=" + json.dumps(sorted({{m.split(".")[0] for m in heavy}})))
"""


@pytest.mark.parametrize("argv", [[], ["list"], ["--help"], ["run", "--help"], ["navigate", "--help"]],
                         ids=["import", "list", "help", "run-help", "navigate-help"])
def test_cli_start_imports_no_heavy_package(argv):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", _PROBE.format(argv=argv, heavy=HEAVY)],
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("HEAVY=")][-1]
    assert json.loads(line[len("HEAVY="):]) == [], line
    if argv == ["list"]:
        assert "free-inertial" in r.stdout and "static-alignment" in r.stdout


def test_probe_sees_heavy_imports():
    """The probe itself can fail: running a command that computes does import them."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", _PROBE.format(argv=["config", "free-inertial"], heavy=HEAVY)],
                       capture_output=True, text=True, env=env, timeout=120)
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("HEAVY=")][-1]
    assert "numba" in json.loads(line[len("HEAVY="):])
