"""Each of sinslab's cached kernels compiled by one process at a time, the others loading it.

The kernels are cached on disk (``cache=True``). On an empty cache, processes that start
the same work together (a command and its Dask workers, each running a run that
synthesises a trajectory first) would each compile the same kernel at the same moment and
each pay its full compile time, since none finds it in the cache before the first has
finished. :func:`install` puts a lock file beside each kernel's cache index (an exclusive
``flock`` held while the kernel is loaded or compiled for a signature): a process that
finds another one compiling the kernel waits for it and then loads the kernel from the
cache, so every kernel is compiled once per cache whatever the number of processes. The
waiting process gives its CPU to the others meanwhile.

Only sinslab's kernels with a disk cache are concerned; signatures already loaded in the
process, other packages' functions and uncached kernels go straight to numba. Within a
process the locks are taken under numba's compiler lock (an ``RLock``: one thread compiles
at a time anyway) and are re-entrant, so a kernel typed again while it compiles (a nested
or recursive call) never waits for itself. Locks follow the call graph (a kernel's lock is
held while the kernels it calls compile), which has no cycles, so processes cannot wait for
each other in a ring. A process that dies holding a lock releases it with its file. Where
no lock file can be made (a read-only cache, a platform without ``flock``) the kernel
compiles as before.
"""
from __future__ import annotations

import contextlib
import os
from typing import Any, Iterator

__all__ = ["install", "kernel_lock"]

_installed = False
#: lock path -> [file object, depth], the kernel locks this process holds
_held: dict = {}


def _lock_path(dispatcher):
    """The lock file of ``dispatcher``'s disk cache, or None (not sinslab's, no disk cache)."""
    f = getattr(dispatcher, "py_func", None)
    if not (getattr(f, "__module__", "") or "").startswith("sinslab"):
        return None
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    index = getattr(cache_file, "_index_path", None)
    return None if index is None else index + ".lock"


@contextlib.contextmanager
def kernel_lock(dispatcher: Any) -> Iterator[None]:
    """Hold ``dispatcher``'s compile lock (re-entrant within the process); a no-op for a
    function this module does not lock."""
    from numba.core.compiler_lock import global_compiler_lock

    path = _lock_path(dispatcher)
    with global_compiler_lock:
        if path is None:
            yield
            return
        if path in _held:
            _held[path][1] += 1
            try:
                yield
            finally:
                _held[path][1] -= 1
            return
        fh = _acquire(path)
        if fh is None:
            yield
            return
        _held[path] = [fh, 1]
        try:
            yield
        finally:
            del _held[path]
            fh.close()              # closing the file releases the lock


def _acquire(path):
    """An open file holding the exclusive lock on ``path``, or None where none can be had."""
    try:
        import fcntl
    except ImportError:             # no flock on this platform
        return None
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        fh = open(path, "a")
    except OSError:
        return None
    try:
        fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
    except OSError:
        fh.close()
        return None
    return fh


def install() -> None:
    """Make numba's dispatchers take the kernel lock before loading or compiling a sinslab
    kernel for a signature not yet in the process (once per process)."""
    global _installed
    if _installed:
        return
    from numba.core import sigutils
    from numba.core.dispatcher import Dispatcher

    compile_ = Dispatcher.compile

    def compile(self, sig):
        if _lock_path(self) is None:
            return compile_(self, sig)
        args, _ = sigutils.normalize_signature(sig)
        if tuple(args) in self.overloads:
            return compile_(self, sig)
        with kernel_lock(self):
            return compile_(self, sig)

    compile.__doc__ = compile_.__doc__
    setattr(Dispatcher, "compile", compile)
    _installed = True
