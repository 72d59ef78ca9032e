"""Shared validators of command-line input: option values, Dask scheduler addresses,
the memory a configuration needs.

Every function raises :class:`~sinslab.app.errors.CliError` (or
:class:`~sinslab.app.config.ConfigError`) whose one-line message names the option or
config key and the problem, before any work starts::

    lat = option_quantity("--lat", text, "angle", ge="-90 deg", le="90 deg")
    check_scheduler("tcp://10.0.0.5:8786", exp, cfg)      # reachable within seconds
    check_memory(cfg)                                      # arrays that fit in memory
"""
from __future__ import annotations

import math
import os
import re
import socket
import threading

from sinslab.app.errors import CliError

__all__ = ["option_quantity", "option_number", "check_scheduler", "check_memory",
           "available_memory", "CONNECT_TIMEOUT_S"]

#: longest wait for a scheduler's host name to resolve and its port to answer [s]
CONNECT_TIMEOUT_S = 3.0


def _bound(text, kind):
    from sinslab.core import units

    return units.parse(text, kind)


def option_quantity(option: str, text, kind: str, *, ge: str | None = None,
                    gt: str | None = None, le: str | None = None, lt: str | None = None) -> float:
    """The SI value of the option's ``"<number> <unit>"`` text, of quantity ``kind``.

    Bounds are unit strings (``ge="0 s"``). Raises :class:`CliError` naming ``option``.
    """
    from sinslab.core import units

    try:
        v = units.parse(str(text).strip(), kind)
    except (ValueError, TypeError) as e:
        raise CliError(f"{option} {text!r}: {e}") from None
    if not math.isfinite(v):
        raise CliError(f"{option} {text!r}: not a finite value")
    for b, ok, word in ((ge, lambda x, y: x >= y, ">="), (gt, lambda x, y: x > y, ">"),
                        (le, lambda x, y: x <= y, "<="), (lt, lambda x, y: x < y, "<")):
        if b is not None and not ok(v, _bound(b, kind)):
            raise CliError(f"{option} {text!r}: out of range, must be {word} {b}")
    return v


def option_number(option: str, value, *, ge: float | None = None, gt: float | None = None,
                  le: float | None = None, unit: str = "") -> float:
    """A finite number given to ``option`` (text or number), within the bounds."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise CliError(f"{option} {value!r}: not a number{' of ' + unit if unit else ''}") from None
    u = f" {unit}" if unit else ""
    if not math.isfinite(v):
        raise CliError(f"{option} {value!r}: not a finite number")
    if ge is not None and not v >= ge:
        raise CliError(f"{option} {value!r}: must be >= {ge:g}{u}")
    if gt is not None and not v > gt:
        raise CliError(f"{option} {value!r}: must be > {gt:g}{u}")
    if le is not None and not v <= le:
        raise CliError(f"{option} {value!r}: must be <= {le:g}{u}")
    return v


# ------------------------------------------------------------------ Dask scheduler -----
_ADDR = re.compile(r"^(?:(?P<proto>tcp|tls)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+)"
                   r":(?P<port>\d{1,5})/?$")


def _uses_scheduler(exp) -> bool:
    """True if the experiment's code hands ``ctx.scheduler`` to a Monte Carlo campaign."""
    import inspect

    try:
        mod = inspect.getmodule(exp.run)
        src = inspect.getsource(mod) if mod is not None else ""
    except (OSError, TypeError):
        return True                                 # cannot tell: let it through
    return "ctx.scheduler" in src


def _resolve_host(host: str, port: int, timeout: float):
    box: dict = {}

    def work():
        try:
            box["r"] = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
        except OSError as e:
            box["e"] = e

    th = threading.Thread(target=work, daemon=True)
    th.start()
    th.join(timeout)
    if th.is_alive():
        raise TimeoutError
    if "e" in box:
        raise box["e"]
    return box["r"]


def check_scheduler(address: str, exp=None, cfg=None, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """Refuse, in at most about ``2 * timeout`` seconds, a ``--scheduler`` that cannot work.

    ``"sync"`` (serial, no Dask) is accepted. Otherwise the address must read
    ``[tcp://|tls://]HOST:PORT``, the host must resolve and the port accept a TCP
    connection. With ``exp`` given, an experiment that runs no Monte Carlo campaign is
    refused too: the option would be ignored.
    """
    text = str(address).strip()
    if exp is not None and not _uses_scheduler(exp):
        raise CliError(f"--scheduler: experiment {exp.name!r} runs no Monte Carlo campaign, "
                       f"so a scheduler would not be used")
    if text == "sync":
        return
    m = _ADDR.match(text)
    if not m:
        raise CliError(f"--scheduler {address!r}: not a Dask scheduler address "
                       f"(expected tcp://HOST:PORT, e.g. tcp://10.0.0.5:8786)")
    host, port = m["host"].strip("[]"), int(m["port"])
    if not 0 < port < 65536:
        raise CliError(f"--scheduler {address!r}: port {port} is out of range")
    try:
        infos = _resolve_host(host, port, timeout)
    except TimeoutError:
        raise CliError(f"--scheduler {address!r}: host {host!r} did not resolve within "
                       f"{timeout:g} s") from None
    except OSError as e:
        raise CliError(f"--scheduler {address!r}: cannot resolve host {host!r} "
                       f"({e.strerror or e})") from None
    last = None
    for fam, typ, proto, _, sa in infos:
        try:
            with socket.socket(fam, typ, proto) as s:
                s.settimeout(timeout)
                s.connect(sa)
                return
        except OSError as e:
            last = e
    why = "timed out" if isinstance(last, socket.timeout) else (
        getattr(last, "strerror", None) or str(last))
    raise CliError(f"--scheduler {address!r}: no scheduler answers at {host}:{port} ({why})")


# ------------------------------------------------------------------ memory -------------
#: bytes per simulated sample kept in arrays by an experiment (truth, IMU increments,
#: navigation solution, errors: ~40 float64 columns) — a lower bound of what runs need
BYTES_PER_SAMPLE = 40 * 8


def available_memory() -> int:
    """Bytes of memory available to a new allocation (MemAvailable, else physical size)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 1 << 62


def _size(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"):
        if n < 1024 or unit == "EiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} EiB"


def check_memory(cfg, available: int | None = None) -> None:
    """Refuse a configuration whose sampled arrays cannot fit in memory, before allocating.

    Every section holding a ``duration`` and a ``sample_interval`` (time quantities)
    gives ``duration / sample_interval`` samples of :data:`BYTES_PER_SAMPLE` bytes; the
    total must stay below the available memory. The message names the key and the size.
    """
    from sinslab.app.config import ConfigError

    avail = available_memory() if available is None else int(available)

    def walk(sec, prefix):
        fields = getattr(type(sec), "model_fields", {})
        for k in fields:
            v = getattr(sec, k)
            if hasattr(type(v), "model_fields"):
                yield from walk(v, f"{prefix}{k}.")
        if "duration" in fields and "sample_interval" in fields:
            yield prefix, sec.duration, sec.sample_interval

    for prefix, dur, dt in walk(cfg, ""):
        try:
            n = float(dur) / float(dt)
        except (TypeError, ValueError, ZeroDivisionError):
            continue
        need = n * BYTES_PER_SAMPLE
        if need > avail:
            dt_txt = getattr(dt, "text", f"{float(dt):g} s")
            dur_txt = getattr(dur, "text", f"{float(dur):g} s")
            raise ConfigError(f"config key {prefix}sample_interval: {dt_txt} over {dur_txt} is "
                              f"{n:.3g} samples, at least {_size(need)} of arrays, but "
                              f"{_size(avail)} of memory is available")
