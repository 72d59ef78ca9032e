"""The notebooks of notebooks/: kept in git without outputs, and every one runs from top to
bottom in a fresh kernel (nbclient) without an error, drawing what it says it draws.

``make test`` runs them with the rest; they carry the ``notebook`` marker, so ``make
notebooks`` (``pytest -m notebook``) runs them alone, and ``-m 'not notebook'`` leaves
them out of a quick local run.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
#: the shared data set (the recorded drive), found as the other tests of recorded files find it
DATA = ROOT.parent / "shared" / "data"
#: notebook -> the data folders it reads
NEEDS = {"02_recorded_drive.ipynb": ["rtklib-drive"]}


def test_four_notebooks_with_outputs_stripped():
    assert [p.name for p in NOTEBOOKS] == ["01_tour.ipynb", "02_recorded_drive.ipynb", "03_paper_000.ipynb",
                                           "04_monte_carlo.ipynb"]
    for p in NOTEBOOKS:
        nb = json.loads(p.read_text(encoding="utf-8"))
        assert set(nb["metadata"]) <= {"kernelspec", "language_info"}, (p.name, nb["metadata"])
        for cell in nb["cells"]:
            if cell["cell_type"] == "code":
                assert cell["outputs"] == [] and cell["execution_count"] is None, \
                    f"{p.name}: outputs in git (strip them: clear all outputs and save)"
            assert not cell.get("attachments"), p.name
            assert set(cell.get("metadata", {})) <= {"tags"}, (p.name, cell["metadata"])


@pytest.mark.notebook
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat", reason="the notebooks extra runs the notebooks")
    nbclient = pytest.importorskip("nbclient", reason="the notebooks extra runs the notebooks")
    pytest.importorskip("ipykernel", reason="the notebooks extra runs the notebooks")
    missing = [d for d in NEEDS.get(path.name, []) if not (DATA / d).is_dir()]
    if missing:
        pytest.skip(f"shared data folder not available: {', '.join(missing)}")
    # the kernel inherits the environment: figures without a display, no progress bars,
    # the data folder where a notebook looks for it
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    monkeypatch.setenv("SINSLAB_QUIET", "1")
    monkeypatch.setenv("SINSLAB_DATA", str(DATA))
    nb = nbformat.read(path, as_version=4)
    # a cell that runs for minutes has hung (the notebooks take seconds a cell)
    client = nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    figures = [o for o in outputs if "image/png" in o.get("data", {})]
    assert figures, f"{path.name} drew no figure"
