"""sinslab's compiled kernels found where an install put them ahead of time.

numba compiles a kernel on its first call and caches it on disk (``cache=True``): in the
``__pycache__`` folder beside the module when that folder is writable, else in the user's
cache folder (``~/.cache/numba``). A first run would pay every compilation (15–25 s of
CPU for ``navigate``); ``sinslab compile`` (:mod:`sinslab.precompile`) does them at
install instead — the clone's ``make`` runs it, and a wheel is built with them inside.

Two things keep numba from using such a cache as is, and :func:`install` mends both for
sinslab's kernels (a cache miss of numba's own lookup goes on to these, in order):

* **read-only install.** In a wheel installed into a read-only ``site-packages`` numba
  looks in the user's cache folder, which is empty after the install: the kernels
  shipped in the package's ``__pycache__`` folders are read from there.
* **portable machine code.** A cache entry is keyed on the CPU it was compiled for
  (name and features), so a wheel built on one machine would match no other. Kernels
  compiled ahead of time for a wheel are built for the baseline CPU of the architecture
  (``NUMBA_CPU_NAME=generic``, no extra features: :data:`PORTABLE_ENV`), which every
  processor of the architecture runs, and are loaded when no entry for this CPU exists.
  Without ``fastmath`` the arithmetic is IEEE on any target, so the numbers are the same;
  ``benchmarks/cold_start.py`` measures the speed.

The source stamp that says whether a cache entry is fresh is numba's — a hash of the
source file's content (numba 0.68; earlier versions use its time and size, which a
checkout or an install may change — the kernels then compile once, as without a cache) —
and, for sinslab's kernels, a hash of the package modules that file imports, directly or
through others (:func:`dependency_digest`). numba's stamp covers the kernel's own file
only, yet a cached kernel holds the machine code of every compiled function it calls and
the value of every global constant it reads, wherever they are defined: after a change to
``sim/_rng.py`` alone the kernels of ``sim/imu.py`` that draw from it would load from the
cache as they were, and compute with the old generator. A new signature, or a kernel whose
source or imports changed, compiles as before and is cached in numba's usual place. ``SINSLAB_JITCACHE=0`` turns the two lookups off (numba's own cache
only: what a measurement of compile times wants with ``NUMBA_CACHE_DIR`` set).

BLAS table without ``scipy.linalg``
-----------------------------------
The first kernel a process runs makes numba load its array implementations, which check
that a BLAS is there by importing ``scipy.linalg.cython_blas`` — the table of BLAS
function pointers that the compiled ``np.dot`` calls. Importing it imports the package
``scipy.linalg`` first, and with it scipy's array-API layer, which walks numpy's lazily
loaded submodules (``numpy.f2py``, ``numpy.testing``, ...): ~0.1 s of CPU in every process,
a fortieth of a 1 h full-rate ``navigate``, for a table that loads in 3 ms on its own.
:func:`preload_blas_table` loads that extension module alone under its own name before
numba asks for it, so numba finds it imported; code that uses ``scipy.linalg`` still
imports the package as usual and gets the same module object. It does nothing when
``scipy.linalg`` is already imported, and anything unexpected (no scipy, another layout)
leaves the import to numba.
"""
from __future__ import annotations

import hashlib
import os
import re
import sys

__all__ = ["install", "preload_blas_table", "PORTABLE_ENV", "shipped_folder", "dependency_digest"]

#: environment of a process that compiles kernels to ship (any CPU of the architecture)
PORTABLE_ENV = {"NUMBA_CPU_NAME": "generic", "NUMBA_CPU_FEATURES": ""}

_installed = False


def _ours(cache) -> bool:
    f = getattr(cache, "_py_func", None)
    return (getattr(f, "__module__", "") or "").startswith("sinslab")


#: ``import pkg.mod``, ``from pkg.mod import a, b`` or ``from pkg import (mod, ...)`` at any
#: indentation (imports inside functions count too); group 1 the module, group 2 the names
_IMPORT = re.compile(r"^[ \t]*(?:import[ \t]+([\w.]+)|from[ \t]+([\w.]+)[ \t]+import[ \t]+"
                     r"(\([^)]*\)|[^\n#]*))", re.M)


_files_memo: dict = {}


def _module_file(root: str, top: str, name: str) -> str | None:
    """The source file of module ``name`` of the package ``top`` whose folder is
    ``root`` (a module or a package's ``__init__``), or None."""
    if name != top and not name.startswith(top + "."):
        return None
    files = _files_memo.get(root)
    if files is None:                       # the package's modules, listed once
        files = _files_memo[root] = {os.path.join(d, f) for d, _, fs in os.walk(root) for f in fs
                                     if f.endswith(".py")}
    base = os.path.join(root, *name.split(".")[1:])
    for path in (base + ".py", os.path.join(base, "__init__.py")):
        if path in files:
            return path
    return None


_imports_memo: dict = {}


def _imported_files(path: str, root: str, top: str) -> tuple:
    """The package's source files that the file at ``path`` imports (its own imports
    only), read from the text: a static over-approximation, which can only make a kernel
    compile once more than needed, never load a stale one. Each file is read once a
    process (the sources do not change under a running process)."""
    got = _imports_memo.get(path)
    if got is not None:
        return got
    with open(path, encoding="utf-8", errors="replace") as f:
        text = f.read()
    found = set()
    for m in _IMPORT.finditer(text):
        if m.group(1):
            mods = [m.group(1)]
        else:
            names = re.findall(r"[A-Za-z_]\w*", re.sub(r"\bas[ \t]+\w+", "", m.group(3)))
            mods = [m.group(2)] + [f"{m.group(2)}.{n}" for n in names]
        for name in mods:
            parts = name.split(".")
            for i in range(len(parts)):            # the parents' __init__ run too
                file = _module_file(root, top, ".".join(parts[:i + 1]))
                if file is not None:
                    found.add(file)
    got = _imports_memo[path] = tuple(sorted(found))
    return got


def dependency_digest(module: str) -> str | None:
    """A hash of the sources of the package modules ``module`` imports, directly or
    through others (its own file excluded: numba's stamp covers it), or None when it is
    not a module of an importable package with source files.

    A cached kernel holds the compiled code of every function it calls and the values of
    the global constants it reads: a change to any of those files must make it stale."""
    if module in _digest_memo:
        return _digest_memo[module]
    top = module.split(".")[0]
    pkg_file = getattr(sys.modules.get(top), "__file__", None)
    own = getattr(sys.modules.get(module), "__file__", None)
    if not pkg_file or not own:
        return None
    root = os.path.dirname(os.path.abspath(pkg_file))
    own = os.path.abspath(own)
    seen, todo = {own}, [own]
    while todo:
        for f in _imported_files(todo.pop(), root, top):
            if f not in seen:
                seen.add(f)
                todo.append(f)
    h = hashlib.sha256()
    for f in sorted(seen - {own}):
        h.update(os.path.relpath(f, root).encode())
        h.update(_file_hash(f))
    got = _digest_memo[module] = h.hexdigest()
    return got


_digest_memo: dict = {}


_hash_memo: dict = {}


def _file_hash(path: str) -> bytes:
    """sha256 of a file's bytes (each file read once a process)."""
    got = _hash_memo.get(path)
    if got is None:
        with open(path, "rb") as f:
            got = _hash_memo[path] = hashlib.sha256(f.read()).digest()
    return got


def _stamp_dependencies(cache) -> None:
    """Extend the source stamp of a sinslab kernel's cache index with
    :func:`dependency_digest` (once per cache object; before its first lookup or save)."""
    f = cache._cache_file
    if getattr(f, "_sinslab_deps", False):
        return
    f._source_stamp = (f._source_stamp, dependency_digest(cache._py_func.__module__))
    f._sinslab_deps = True


def shipped_folder(py_file: str) -> str:
    """The ``__pycache__`` folder beside a module: where an install leaves its kernels."""
    return os.path.join(os.path.dirname(os.path.abspath(py_file)), "__pycache__")


class _PortableCodegen:
    """Stands in for the codegen in numba's cache key: the key of the baseline CPU."""

    def __init__(self, codegen):
        self._triple = codegen.magic_tuple()[0]

    def magic_tuple(self):
        return (self._triple, PORTABLE_ENV["NUMBA_CPU_NAME"], PORTABLE_ENV["NUMBA_CPU_FEATURES"])


def _index_files(cache):
    """numba's index of the kernel, then the one in the package folder if that is another."""
    from numba.core.caching import IndexDataCacheFile

    primary = cache._cache_file
    yield primary
    py_file = getattr(cache._impl.locator, "_py_file", None)
    if py_file is None:
        return
    folder = shipped_folder(py_file)
    if os.path.abspath(cache._cache_path) != folder and os.path.isdir(folder):
        yield IndexDataCacheFile(cache_path=folder, filename_base=cache._impl.filename_base,
                                 source_stamp=primary._source_stamp)


def _load_elsewhere(cache, sig, target_context):
    """The kernel from the package folder (this CPU's entry, then the portable one) or the
    portable entry of numba's own index; None when there is none."""
    codegen = target_context.codegen()
    keys = [cache._index_key(sig, codegen), cache._index_key(sig, _PortableCodegen(codegen))]
    for i, f in enumerate(_index_files(cache)):
        for k, key in enumerate(keys):
            if i == 0 and k == 0:
                continue                        # numba's own lookup, already missed
            try:
                data = f.load(key)
            except Exception:                   # noqa: BLE001 - an unreadable index is a miss
                data = None
            if data is not None:
                return cache._impl.rebuild(target_context, data)
    return None


#: the extension module numba's compiled ``np.dot`` takes its BLAS functions from
BLAS_TABLE = "scipy.linalg.cython_blas"


def preload_blas_table() -> bool:
    """Import :data:`BLAS_TABLE` without importing ``scipy.linalg`` (see the module notes).

    Returns whether the module is imported now (by this call or before)."""
    import sys

    if BLAS_TABLE in sys.modules:
        return True
    if "scipy.linalg" in sys.modules:
        return False                          # the package is there: numba's import is cheap
    try:
        import importlib.machinery
        import importlib.util

        import scipy
        folder = os.path.join(os.path.dirname(os.path.abspath(scipy.__file__)), "linalg")
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = os.path.join(folder, "cython_blas" + suffix)
            if os.path.isfile(path):
                break
        else:
            return False
        spec = importlib.util.spec_from_file_location(BLAS_TABLE, path)
        if spec is None or spec.loader is None:
            return False
        module = importlib.util.module_from_spec(spec)
        sys.modules[BLAS_TABLE] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[BLAS_TABLE]
            raise
    except Exception:                         # noqa: BLE001 - numba imports it its own way then
        return False
    return True


def install() -> None:
    """Stamp sinslab's cached kernels with their imports' sources too, and let numba's
    cache lookup of them go on to the package folder and to portable entries (once per
    process; other packages' functions are left alone). ``SINSLAB_JITCACHE=0`` turns off
    the extra lookups, not the stamp."""
    global _installed
    if _installed:
        return
    from numba.core.caching import Cache

    load = Cache.load_overload
    save = Cache.save_overload
    lookups = os.environ.get("SINSLAB_JITCACHE", "") != "0"

    def load_overload(self, sig, target_context):
        ours = _ours(self)
        if ours:
            _stamp_dependencies(self)
        data = load(self, sig, target_context)
        if data is None and lookups and ours and getattr(self, "_enabled", False):
            target_context.refresh()
            data = _load_elsewhere(self, sig, target_context)
        return data

    def save_overload(self, sig, data):
        if _ours(self):
            _stamp_dependencies(self)
        return save(self, sig, data)

    load_overload.__doc__ = load.__doc__
    save_overload.__doc__ = save.__doc__
    setattr(Cache, "load_overload", load_overload)   # methods replaced on purpose
    setattr(Cache, "save_overload", save_overload)
    _installed = True
