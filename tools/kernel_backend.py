"""The build backend of sinslab: setuptools', with the numba kernels compiled into the wheel.

A wheel is built as setuptools builds it; then ``python -m sinslab.precompile --portable``
runs on the built package (its ``build/lib`` tree), so that the kernels of the commands are
in the package's ``__pycache__`` folders, compiled for any CPU of the architecture
(:mod:`sinslab.core.jitcache` finds them there, in a read-only ``site-packages`` too). The
wheel's build environment therefore holds sinslab's own dependencies
(:func:`get_requires_for_build_wheel`). An editable install (``pip install -e``) builds
nothing of the kind: the clone's ``make`` runs ``sinslab compile`` in the environment
itself. ``SINSLAB_BUILD_KERNELS=0`` builds a wheel without kernels (they then compile on
first use).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from setuptools import build_meta as _orig
from setuptools.build_meta import *  # noqa: F401,F403 - every other hook is setuptools'
from setuptools.command.build_py import build_py as _build_py

ROOT = Path(__file__).resolve().parents[1]


def _dependencies() -> list[str]:
    """The ``[project] dependencies`` of pyproject.toml."""
    try:
        import tomllib
    except ImportError:                     # Python < 3.11
        import tomli as tomllib             # type: ignore[no-redef]
    with open(ROOT / "pyproject.toml", "rb") as fh:
        return list(tomllib.load(fh)["project"]["dependencies"])


def _wanted() -> bool:
    return os.environ.get("SINSLAB_BUILD_KERNELS", "1") != "0"


def get_requires_for_build_wheel(config_settings=None):
    """setuptools' requirements, and sinslab's dependencies to run the commands that
    compile the kernels."""
    extra = _dependencies() if _wanted() else []
    return _orig.get_requires_for_build_wheel(config_settings) + extra


class build_py(_build_py):
    """setuptools' build_py, then the kernels compiled on the built package (not for an
    editable install)."""

    def run(self):
        super().run()
        if getattr(self, "editable_mode", False) or not _wanted():
            return
        lib = Path(self.build_lib).resolve()
        # the built package first; the rest of PYTHONPATH is how an isolated build (pip)
        # gives its processes the build environment's packages
        path = os.pathsep.join([str(lib)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])
        env = dict(os.environ, PYTHONPATH=path, PYTHONDONTWRITEBYTECODE="1")
        env.pop("NUMBA_CACHE_DIR", None)        # the kernels go beside the built modules
        r = subprocess.run([sys.executable, "-m", "sinslab.precompile", "--portable"], env=env,
                           cwd=str(lib.parent))
        if r.returncode:
            raise RuntimeError("compiling sinslab's kernels into the wheel failed "
                               "(SINSLAB_BUILD_KERNELS=0 builds one without them)")
        for lock in lib.rglob("*.lock"):        # the compile locks of sinslab.core.jitlock
            lock.unlink()
