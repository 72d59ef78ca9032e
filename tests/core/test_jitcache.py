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


_STALE = r"""
from sinslab.core import jitnotice
jitnotice.install()
from sinslab._stamp_a import f
print(f(1.0))
"""


def _value(src):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("NUMBA_", "SINSLAB_JITCACHE"))}
    env.update(PYTHONPATH=str(src), SINSLAB_QUIET="1", PYTHONDONTWRITEBYTECODE="1")
    p = subprocess.run([sys.executable, "-c", _STALE], env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    return float(p.stdout.strip().splitlines()[-1])


def test_a_cached_kernel_is_stale_when_a_module_it_imports_changes(tmp_path):
    """A cached kernel holds the machine code of the compiled functions it calls and the
    values of the global constants it reads, from whatever module: ``a.f`` calls ``b.g``,
    which reads ``c.K``. Changing ``c`` (imported through ``b``), then ``b``, recompiles
    ``a.f``; numba's own stamp (``a``'s source) would load the first result every time."""
    src = tmp_path / "src"
    shutil.copytree(SRC / "sinslab", src / "sinslab",
                    ignore=shutil.ignore_patterns("__pycache__", "*.nbi", "*.nbc", "*.lock"))
    pkg = src / "sinslab"
    (pkg / "_stamp_a.py").write_text("from numba import njit\nfrom sinslab._stamp_b import g\n\n\n"
                                     "@njit(cache=True)\ndef f(x):\n    return g(x) + 1.0\n")
    b = "from numba import njit\nfrom sinslab._stamp_c import K\n\n\n@njit(cache=True)\ndef g(x):\n    return {} * x + K\n"
    (pkg / "_stamp_b.py").write_text(b.format("2.0"))
    (pkg / "_stamp_c.py").write_text("K = 10.0\n")
    assert _value(src) == 13.0
    assert list((pkg / "__pycache__").glob("_stamp_a.f-*.nbc"))        # cached, then
    assert _value(src) == 13.0                                          # loaded from the cache
    (pkg / "_stamp_c.py").write_text("K = 20.0\n")
    assert _value(src) == 23.0
    (pkg / "_stamp_b.py").write_text(b.format("3.0"))
    assert _value(src) == 24.0
