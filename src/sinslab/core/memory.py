"""The memory a new allocation can get, and sizes written for people."""
from __future__ import annotations

import os

__all__ = ["available_memory", "human_size"]


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


def human_size(n: float) -> str:
    """``n`` bytes as "1.5 GiB" (three significant digits, binary prefixes)."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"):
        if n < 1024 or unit == "EiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} EiB"
