"""What a ``navigate`` process imports, and where: a package a run has no use for is never
imported, and matplotlib, which only the outputs use, is imported by the code that draws
them once the run has computed. Checked by the modules loaded and the sinslab code on the
stack when each is first imported (a fresh interpreter), not by memory or time
(``benchmarks/navigate_memory.py`` measures what this buys):

- importing the command's compute path (the command module, the recorded-data front end,
  the readers) loads none of pyarrow, pandas, matplotlib, dask, distributed, scipy.stats;
- a run on a CSV log reads the log and runs the filter without matplotlib (the modules
  loaded when the filter returns), imports it from the plotting module to build the
  figures, and never imports pandas, dask, distributed, scipy.stats or scipy.spatial (the
  attitude conversions a run needs are closed forms; pyarrow it uses: it parses the CSV
  and writes the full-rate solution as Parquet).
"""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from sinslab.sim import trajectory as tr
from support import simulated_car_drive

SRC = Path(__file__).resolve().parents[2] / "src"
NEVER = ("pandas", "dask", "distributed", "scipy.stats", "scipy.spatial")
LATE = ("matplotlib",)                        # imported to draw the outputs only

_PROBE = r"""
import importlib.abc, json, sys, traceback
WATCH = set(sys.argv[1].split(","))
events = {}
class Watch(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name in WATCH and name not in events:
            events[name] = [f"{f.filename.replace(chr(92), '/').split('/src/')[-1]}:{f.name}"
                            for f in traceback.extract_stack() if "sinslab" in f.filename]
        return None                             # found by the usual finders
sys.meta_path.insert(0, Watch())
heavy = lambda: sorted(m for m in sys.modules if m in WATCH)
if sys.argv[2] == "import":
    import sinslab.app.commands.navigate, sinslab.fusion.recorded, sinslab.data
    import sinslab.cli
    print("PROBE " + json.dumps({"imported": heavy()}))
    sys.exit(0)
import sinslab.fusion.recorded as R
at_filter = []
def filter_only(*a, _f=R.navigate_recorded, **k):
    try:
        return _f(*a, **k)
    finally:
        at_filter.extend(heavy())
R.navigate_recorded = filter_only
from sinslab.cli import app
try:
    app(sys.argv[3:], standalone_mode=False)
finally:
    print("PROBE " + json.dumps({"at_filter": at_filter, "imported": heavy(), "events": events}))
"""


def _probe(*argv):
    env = dict(os.environ, SINSLAB_QUIET="1", MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]))
    r = subprocess.run([sys.executable, "-c", _PROBE, ",".join(NEVER + LATE + ("pyarrow",)), *argv],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("PROBE ")][-1]
    return json.loads(line[6:])


def test_compute_path_imports_no_output_or_campaign_package():
    assert _probe("import")["imported"] == []


@pytest.fixture(scope="module")
def csv_log(tmp_path_factory):
    from sinslab.data import write_fixes, write_imu

    d = tmp_path_factory.mktemp("log")
    segs = [tr.Static(duration=30.0), tr.Accelerate(duration=5.0, accel=2.0), tr.Level(duration=25.0)]
    imu, fx, _, _, _ = simulated_car_drive(segs)
    write_imu(d / "imu.csv", imu, "csv")
    write_fixes(d / "fixes.csv", fx)
    return d


def test_csv_run_imports_output_packages_only_to_write_outputs(csv_log, tmp_path):
    out = tmp_path / "run"
    p = _probe("run", "-q", "navigate", "--imu", str(csv_log / "imu.csv"), "--fixes",
               str(csv_log / "fixes.csv"), "--out", str(out))
    assert (out / "solution.parquet").is_file() and (out / "track.png").is_file()
    assert [m for m in LATE + NEVER if m in p["at_filter"]] == [], f"read and filtered with {p['at_filter']} loaded"
    assert [m for m in NEVER if m in p["imported"]] == [], p["events"]
    # the probe sees the imports it looks for: the run uses pyarrow and matplotlib
    assert sorted(p["events"]) == ["matplotlib", "pyarrow"], p["events"]
    mpl = p["events"]["matplotlib"]
    assert any(f.startswith("sinslab/app/plotting.py") for f in mpl), mpl
