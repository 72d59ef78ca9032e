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


_BLAS = r"""
import json, sys
FIRST = sys.argv[1]
if FIRST == "linalg":
    import scipy.linalg          # the package first: numba's own import path
import numpy as np
from sinslab.estimation import kernels
rng = np.random.default_rng(7)
n = 12
A = rng.standard_normal((n, n))
P = A @ A.T
Phi = np.eye(n) + 0.01 * rng.standard_normal((n, n))
Q = np.diag(rng.uniform(0.1, 1.0, n))
kernels.cov_predict(P, Phi, Q, n, np.empty((n, n)), np.empty((n, n)))   # np.dot: BLAS
linalg_loaded = "scipy.linalg" in sys.modules
import scipy.linalg
from scipy.linalg import cython_blas
out = {"P": P.tobytes().hex(), "linalg_before_use": linalg_loaded,
       "same_module": cython_blas is sys.modules["scipy.linalg.cython_blas"],
       "expm": float(scipy.linalg.expm(np.array([[0.0, 1.0], [0.0, 0.0]]))[0, 1])}
print(json.dumps(out))
"""


def test_numbas_blas_table_loads_without_scipy_linalg_and_gives_the_same_numbers():
    """``preload_blas_table``: a process that runs a kernel calling BLAS (``cov_predict``'s
    ``np.dot``) has not imported ``scipy.linalg``; the products are bit for bit those of a
    process that imported ``scipy.linalg`` first (numba's own import), and ``scipy.linalg``
    imported afterwards works and holds the same BLAS table module."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("SINSLAB_JITCACHE")}
    env.update(PYTHONPATH=str(SRC), SINSLAB_QUIET="1")
    res = {}
    for first in ("sinslab", "linalg"):
        p = subprocess.run([sys.executable, "-c", _BLAS, first], env=env, capture_output=True, text=True,
                           timeout=300)
        assert p.returncode == 0, p.stderr
        res[first] = json.loads(p.stdout.strip().splitlines()[-1])
    assert res["sinslab"]["linalg_before_use"] is False
    assert res["linalg"]["linalg_before_use"] is True
    assert res["sinslab"]["P"] == res["linalg"]["P"]
    for r in res.values():
        assert r["same_module"] and r["expm"] == 1.0
