"""Compressed recordings: a table shipped as ``.gz`` or inside a ``.zip`` is read as the
text it holds.

:func:`plain_file` is a context manager giving a path the readers can open: the file
itself when it is not compressed (recognised by its first bytes, not its name), else the
one table of the archive unpacked into a temporary folder that is removed afterwards.
Messages raised inside name the archive and its member (``drive.zip:gnss.csv:12: ...``),
never the temporary copy.
"""
from __future__ import annotations

import contextlib
import gzip
import shutil
import tempfile
import zipfile
from pathlib import Path

__all__ = ["plain_file", "compression"]

_GZ = b"\x1f\x8b"
_ZIP = b"PK\x03\x04"


def compression(path) -> str | None:
    """``"gz"``, ``"zip"`` or None, from the file's first bytes."""
    with open(path, "rb") as fh:
        head = fh.read(4)
    return "gz" if head[:2] == _GZ else "zip" if head == _ZIP else None


def _member(z: zipfile.ZipFile, path) -> zipfile.ZipInfo:
    files = [m for m in z.infolist() if not m.is_dir() and not Path(m.filename).name.startswith(".")]
    if len(files) == 1:
        return files[0]
    tables = [m for m in files if Path(m.filename).suffix.lower() in (".csv", ".txt", ".tsv", ".dat", ".pos")]
    if len(tables) == 1:
        return tables[0]
    names = ", ".join(m.filename for m in files[:10]) or "nothing"
    raise ValueError(f"{path}: the zip archive holds {len(files)} files ({names}); unpack the one "
                     "to read")


@contextlib.contextmanager
def plain_file(path):
    """Yield a readable uncompressed path for ``path`` (see the module notes)."""
    path = Path(path)
    kind = compression(path)
    if kind is None:
        yield path
        return
    with tempfile.TemporaryDirectory(prefix="sinslab-") as tmp:
        try:
            if kind == "gz":
                label = str(path)
                out = Path(tmp) / (path.stem if path.suffix.lower() == ".gz" else path.name)
                with gzip.open(path, "rb") as src, open(out, "wb") as dst:
                    shutil.copyfileobj(src, dst)
            else:
                with zipfile.ZipFile(path) as z:
                    m = _member(z, path)
                    label = f"{path}:{m.filename}"
                    out = Path(tmp) / Path(m.filename).name
                    with z.open(m) as src, open(out, "wb") as dst:
                        shutil.copyfileobj(src, dst)
        except (OSError, EOFError, zipfile.BadZipFile) as e:
            raise ValueError(f"{path}: cannot unpack the {kind} file ({e})") from None
        try:
            yield out
        except (ValueError, FileNotFoundError) as e:
            raise type(e)(str(e).replace(str(out), label)) from None
