"""Atomic file output: every file sinslab writes goes through :func:`atomic_write` or
:func:`atomic_path`.

The content is written to a hidden temporary name in the same folder, flushed, fsynced and
renamed over the final name with ``os.replace``, so an interrupted writer never leaves a
half-written file under its final name (at worst a hidden ``.NAME.tmp-*`` file, removed
on a clean interrupt).
"""
from __future__ import annotations

import contextlib
import os
import secrets
from pathlib import Path
from typing import Iterator

__all__ = ["atomic_path", "atomic_write"]

def _tmp_name(path: Path) -> Path:
    return path.with_name(f".{path.name}.tmp-{os.getpid()}-{secrets.token_hex(4)}")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success rename it to ``path``.

    For writers that want a file name (``fig.savefig(tmp)``, ``df.to_parquet(tmp)``).
    On any exception (including KeyboardInterrupt/SystemExit) the temporary file is
    removed and ``path`` is untouched.
    """
    path = Path(path)
    tmp = _tmp_name(path)
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"writer produced no file for {path}")
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise


def atomic_write(path: str | os.PathLike, data: str | bytes, encoding: str = "utf-8") -> Path:
    """Write ``data`` to ``path`` atomically (temporary name + ``os.replace``)."""
    path = Path(path)
    raw = data.encode(encoding) if isinstance(data, str) else data
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(raw)
    return path
