"""Opening a MATLAB ``.mat`` file, shared by the readers of the layouts it may hold
(:mod:`.matlab`: PSINS matrices; :mod:`.navego`: NaveGo structs)."""
from __future__ import annotations

from pathlib import Path

__all__ = ["loadmat"]


def loadmat(path):
    """A ``.mat`` file's variables (``scipy.io.loadmat``), or one clear error: missing file,
    MATLAB v7.3 (HDF5, which scipy cannot read), anything else unreadable."""
    import scipy.io
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    with open(path, "rb") as fh:
        head = fh.read(128)
    if head[:8] == b"\x89HDF\r\n\x1a\n" or (len(head) >= 128 and b"MATLAB 7.3" in head[:116]):
        raise ValueError(f"{path}: a MATLAB v7.3 (HDF5) file, which scipy cannot read; save it "
                         "from MATLAB with save(..., '-v7') (NaveGo's own files are v5/v7)")
    try:
        return scipy.io.loadmat(path)
    except Exception as e:  # noqa: BLE001 - scipy raises several kinds
        raise ValueError(f"{path}: cannot read as a MATLAB .mat file ({e})") from None
