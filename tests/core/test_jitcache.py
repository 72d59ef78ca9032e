"""Kernels compiled at install are found where numba alone would not look: in the package
folder when numba caches elsewhere (a read-only site-packages: the user's cache folder),
and when compiled for the baseline CPU of the architecture (the portable machine code of a
wheel)."""
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src"

_CALL = r"""
import json
from sinslab.core import earth, jitnotice
jitnotice.install()
print(json.dumps({"value": earth.radii_s(0.5, 10.0), "compiled": [k for k, _ in jitnotice.compile_log()]}))
"""


def _call(src, tmp, **extra):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "SINSLAB_JITCACHE"))}
    env.update(PYTHONPATH=str(src), SINSLAB_QUIET="1",
               PYTHONDONTWRITEBYTECODE="1", **extra)
    p = subprocess.run([sys.executable, "-c", _CALL], env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout.strip().splitlines()[-1])


def test_portable_kernels_in_the_package_folder_are_loaded_not_compiled(tmp_path):
    src = tmp_path / "src"
    shutil.copytree(SRC / "sinslab", src / "sinslab",
                    ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc", "*.lock"))
    # the install: compiled for any CPU of the architecture, into the package's own folder
    built = _call(src, tmp_path, NUMBA_CPU_NAME="generic", NUMBA_CPU_FEATURES="")
    assert "sinslab.core.earth.radii_s" in built["compiled"]
    assert list((src / "sinslab" / "core" / "__pycache__").glob("earth.radii_s-*.nbc"))
    # a run on this machine's CPU, numba caching elsewhere (as it does when the package
    # folder is read-only; NUMBA_CACHE_DIR here, since permission bits do not stop root):
    # the kernel comes from the package folder's portable entry
    user = str(tmp_path / "user-cache")
    run = _call(src, tmp_path, NUMBA_CACHE_DIR=user)
    assert "sinslab.core.earth.radii_s" not in run["compiled"] and run["value"] == built["value"]
    # numba's own lookup alone compiles it again, into its folder
    alone = _call(src, tmp_path, NUMBA_CACHE_DIR=user, SINSLAB_JITCACHE="0")
    assert "sinslab.core.earth.radii_s" in alone["compiled"] and alone["value"] == built["value"]
    assert list((tmp_path / "user-cache").rglob("earth.radii_s-*.nbc"))
