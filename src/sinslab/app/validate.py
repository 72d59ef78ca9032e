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
from sinslab.core.memory import available_memory, human_size

__all__ = ["option_quantity", "option_number", "check_scheduler", "starts_campaign", "check_memory",
           "available_memory", "check_workers", "usable_cores", "CONNECT_TIMEOUT_S"]

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
    if isinstance(value, float):            # as the user would have typed it: 1e9, not 1000000000.0
        value = _Shown(f"{value:g}")
    if not math.isfinite(v):
        raise CliError(f"{option} {value!r}: not a finite number")
    if ge is not None and not v >= ge:
        raise CliError(f"{option} {value!r}: out of range, must be >= {ge:g}{u}")
    if gt is not None and not v > gt:
        raise CliError(f"{option} {value!r}: out of range, must be > {gt:g}{u}")
    if le is not None and not v <= le:
        raise CliError(f"{option} {value!r}: out of range, must be <= {le:g}{u}")
    return v


class _Shown(str):
    """A number's text shown without quotes in a message."""

    def __repr__(self):
        return str(self)


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


def starts_campaign(exp, cfg) -> bool:
    """True if running ``exp`` with ``cfg`` hands ``ctx.scheduler`` to a Monte Carlo
    campaign (the module uses it and ``cfg.runs`` reaches its ``CAMPAIGN_MIN_RUNS``)."""
    import sys

    if not _uses_scheduler(exp):
        return False
    least = getattr(sys.modules.get(exp.module), "CAMPAIGN_MIN_RUNS", 1)
    runs = getattr(cfg, "runs", None)
    return runs is None or runs >= least


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
    if exp is not None and cfg is not None and not starts_campaign(exp, cfg):
        import sys

        least = getattr(sys.modules.get(exp.module), "CAMPAIGN_MIN_RUNS", 1)
        raise CliError(f"--scheduler: experiment {exp.name!r} runs its Monte Carlo campaign only with "
                       f"runs >= {least} (runs = {cfg.runs}), so a scheduler would not be used; "
                       f"give --runs N")
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


#: resident memory of one worker process of the local Dask cluster [bytes]: its imports
#: (numpy, scipy, numba and the loaded kernels, distributed) and a task's arrays; about
#: 190-240 MB measured on free-inertial's campaign, rounded up
WORKER_MEMORY = 300 * 2 ** 20


def usable_cores() -> int:
    """The CPU cores this process may run on (its affinity; the machine's count elsewhere)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def check_workers(workers: int, available: int | None = None) -> None:
    """Refuse a ``--workers`` the machine cannot give: more worker processes than cores
    (they would only share them, each with its own memory) or more than fit in the
    available memory (:data:`WORKER_MEMORY` each)."""
    cores = usable_cores()
    if workers > cores:
        raise CliError(f"--workers {workers}: this machine gives this process {cores} core(s), and worker "
                       f"processes beyond one per core only share them (each with its own ~"
                       f"{_size(WORKER_MEMORY)} of memory); give at most {cores}")
    avail = available_memory() if available is None else int(available)
    fit = int(avail // WORKER_MEMORY)
    if workers > fit:
        raise CliError(f"--workers {workers}: each worker process needs about {_size(WORKER_MEMORY)}, "
                       f"{workers} need {_size(workers * WORKER_MEMORY)} but {_size(avail)} of memory is "
                       f"available; give at most {max(fit, 0)}" + (" (or 0: run in this process)" if fit < 1 else ""))


# ------------------------------------------------------------------ memory -------------
#: bytes per simulated sample kept in arrays by an experiment (truth, IMU increments,
#: navigation solution, errors: ~40 float64 columns) — a lower bound of what runs need
BYTES_PER_SAMPLE = 40 * 8


def _size(n: float) -> str:
    return human_size(n)


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


# ------------------------------------------------------------------ option forms -------
def option_choice(option: str, value, choices) -> str:
    """``value`` if it is one of ``choices``, else a one-line error listing them."""
    if value not in choices:
        raise CliError(f"{option} {value!r}: choose one of {', '.join(choices)}")
    return value


def option_window(option: str, text) -> tuple[float | None, float | None]:
    """``START:END`` in seconds (either may be empty) -> ``(start, end)``; finite, END > START."""
    if text in (None, ""):
        return None, None
    a, sep, b = str(text).partition(":")
    if not sep:
        raise CliError(f"{option} {text!r}: expected START:END in seconds (either may be empty)")
    try:
        lo = float(a) if a.strip() else None
        hi = float(b) if b.strip() else None
    except ValueError:
        raise CliError(f"{option} {text!r}: START and END must be numbers of seconds") from None
    if any(v is not None and not math.isfinite(v) for v in (lo, hi)):
        raise CliError(f"{option} {text!r}: START and END must be finite")
    if lo is not None and hi is not None and not hi > lo:
        raise CliError(f"{option} {text!r}: END must be after START")
    return lo, hi


def check_window(option: str, text, t_first: float, t_last: float, tol: float = 0.0) -> None:
    """Refuse a window that reaches outside the record ``[t_first, t_last]`` [s] (by more
    than ``tol``, e.g. one sample interval): a clipped window would silently analyse less
    than asked for."""
    lo, hi = option_window(option, text)
    span = f"the record spans {t_first:.6g} to {t_last:.6g} s"
    if (lo is not None and lo >= t_last) or (hi is not None and hi <= t_first):
        raise CliError(f"{option} {text!r}: outside the record; {span}")
    if lo is not None and lo < t_first - tol:
        raise CliError(f"{option} {text!r}: START {lo:.6g} s is outside the record (before its "
                       f"start); {span}")
    if hi is not None and hi > t_last + tol:
        raise CliError(f"{option} {text!r}: END {hi:.6g} s is outside the record (after its "
                       f"end); {span}")


#: bounds of the time options of ``sinslab navigate`` [s]: a fix a minute late, a velocity
#: a minute old or an IMU clock an hour off is no latency but a wrong file or time base
MAX_LATENCY_S = 60.0
MAX_IMU_DELAY_S = 3600.0
#: longest lever arm accepted [m] (a large ship's antenna mast)
MAX_LEVER_M = 200.0


def check_navigate_options(*, fix_latency=0.0, velocity_lag=0.0, imu_delay=0.0, max_gap=1.0,
                           lag="aware", time_sync="none", rest=None, aid=None,
                           lever_arm=None):
    """The numeric and choice options of ``sinslab navigate``, before any file is read.
    Returns the lever arm ``(3,)`` [m] (parsed here, once, from its unit string) or the
    value given when it is not a string."""
    option_number("--fix-latency", fix_latency, ge=0.0, le=MAX_LATENCY_S, unit="s")
    option_number("--velocity-lag", velocity_lag, ge=0.0, le=MAX_LATENCY_S, unit="s")
    option_number("--imu-delay", imu_delay, ge=-MAX_IMU_DELAY_S, le=MAX_IMU_DELAY_S, unit="s")
    option_number("--max-gap", max_gap, gt=0.0, unit="s")
    option_choice("--lag", lag, ("aware", "ignore"))
    option_choice("--time-sync", time_sync, ("auto", "none"))
    if rest is not None:
        option_choice("--rest", rest, ("auto", "flags"))
        aids = {a.strip().lower() for a in str(aid or "").split(",")}
        if not aids & {"zupt", "zaru"}:
            raise CliError(f"--rest {rest!r}: rest intervals are used by ZUPT/ZARU only; "
                           f"add --aid zupt (or zaru), or drop --rest")
    if isinstance(lever_arm, str):
        from sinslab.core import units

        try:
            v = units.parse_vector(lever_arm, "length", 3)
        except (ValueError, TypeError) as e:
            raise CliError(f"--lever-arm {lever_arm!r}: {e}") from None
        bad = [f"{x:g} m" for x in v if not (math.isfinite(x) and abs(x) <= MAX_LEVER_M)]
        if bad:
            raise CliError(f"--lever-arm {lever_arm!r}: component {bad[0]} out of range, each "
                           f"must be within ±{MAX_LEVER_M:g} m (IMU -> antenna)")
        return tuple(float(x) for x in v)
    return lever_arm


def check_mount(mount, frame) -> None:
    """``--frame`` and ``--mount`` of the recorded-data commands, before any file is read."""
    from sinslab.data.frames import frame_matrix, sensor_to_body

    if frame is not None:
        try:
            frame_matrix(frame)
        except ValueError as e:
            raise CliError(f"--frame {frame!r}: {e}") from None
    if mount is not None:
        try:
            sensor_to_body(mount, frame or "rfu")
        except ValueError as e:
            raise CliError(f"--mount: {e}") from None


def check_outages(option: str, text, outages, t_ref: float, t_end: float) -> None:
    """Every outage (``[(start, length)]`` absolute [s], or a periodic spec) must start
    within the navigated span ``[t_ref, t_end)``; otherwise nothing would be measured."""
    span = t_end - t_ref
    if span <= 0:
        raise CliError(f"{option} {text!r}: the IMU record ends {-span:.1f} s before the first fix, "
                       f"so no outage can lie in it")
    for o in outages:
        if o and o[0] == "periodic":
            _, ln, per, first = o
            if not (0.0 <= first < span):
                raise CliError(f"{option} {text!r}: the first outage at {first:g} s is outside "
                               f"the record (0 to {span:.1f} s from the first fix)")
            continue
        st, ln = o
        if not (t_ref <= st and st + ln <= t_end):
            raise CliError(f"{option} {text!r}: outage {st - t_ref:g}:{ln:g} is outside the "
                           f"record (0 to {span:.1f} s from the first fix)")
