"""One status line on stderr while numba compiles sinslab's kernels.

The compiled kernels are cached on disk (``cache=True``), so they compile once after an
install or an upgrade: a minute of work that would otherwise look like a hang. While a
kernel of sinslab compiles, stderr shows::

    compiling numerical kernels (first run only)… 5 done, 21 s: sinslab.sim._synth._synth

and the line is erased as soon as that compilation ends, so it never mixes with other
output. Silent when stderr is not a terminal or bars are off
(:func:`sinslab.core.progress.is_quiet`). :func:`install` is called by the modules that
define kernels; it costs nothing once numba is imported.

:func:`install` also installs :mod:`sinslab.core.jitlock`, so that processes started
together (a command and its Dask workers) compile each kernel once between them, and
:mod:`sinslab.core.jitcache`, so that kernels compiled at install are found (in a
read-only package folder, or compiled for any CPU of the architecture), and loads the BLAS
table of numba's ``np.dot`` without ``scipy.linalg``
(:func:`sinslab.core.jitcache.preload_blas_table`).

:func:`compile_log` gives, after the fact, the CPU seconds each kernel's compilation took
(own time, nested compilations of other sinslab kernels excluded), for measuring.
"""
from __future__ import annotations

import sys
import time

__all__ = ["install", "compile_log"]

_listener = None
MESSAGE = "compiling numerical kernels (first run only)…"


def _ours(ev):
    d = ev.data.get("dispatcher") if isinstance(ev.data, dict) else None
    f = getattr(d, "py_func", None)
    mod = getattr(f, "__module__", "") or ""
    return (mod + "." + f.__qualname__) if f is not None and mod.startswith("sinslab") else None


def install() -> None:
    """Register the listener on numba's compile events (once per process), and the
    compile lock that keeps processes from compiling the same kernel at once
    (:func:`sinslab.core.jitlock.install`)."""
    global _listener
    if _listener is not None:
        return
    from sinslab.core import jitcache, jitlock

    # before numba's array implementations load (at the first kernel call)
    jitcache.preload_blas_table()
    from numba.core import event

    jitlock.install()
    jitcache.install()

    class _Listener(event.Listener):
        def __init__(self):
            self.stack = []          # [name or None, cpu start, child cpu of ours]
            self.log = []            # (name, own CPU s)
            self.count = 0
            self.t0 = None
            self.shown = False

        def on_start(self, ev):
            name = _ours(ev)
            self.stack.append([name, time.process_time(), 0.0])
            if name is not None and sum(1 for s in self.stack if s[0]) == 1:
                if self.t0 is None:
                    self.t0 = time.perf_counter()
                self._show(name)

        def on_end(self, ev):
            name, c0, child = self.stack.pop()
            if name is None:
                return
            dt = time.process_time() - c0
            self.log.append((name, dt - child))
            for fr in reversed(self.stack):
                if fr[0] is not None:
                    fr[2] += dt
                    break
            else:
                self.count += 1
                self._clear()

        def _show(self, name):
            from sinslab.core.progress import is_quiet
            if is_quiet():
                return
            el = time.perf_counter() - (self.t0 or time.perf_counter())
            try:
                sys.stderr.write(f"\r{MESSAGE} {self.count} done, {el:.0f} s: {name}\x1b[K")
                sys.stderr.flush()
                self.shown = True
            except (OSError, ValueError):
                pass

        def _clear(self):
            if self.shown:
                try:
                    sys.stderr.write("\r\x1b[K")
                    sys.stderr.flush()
                except (OSError, ValueError):
                    pass
                self.shown = False

    _listener = _Listener()
    event.register("numba:compile", _listener)


def compile_log() -> list[tuple[str, float]]:
    """``[(kernel, own CPU seconds), ...]`` of the compilations seen so far in this
    process (empty when everything came from the cache)."""
    return list(_listener.log) if _listener is not None else []
