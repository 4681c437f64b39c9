"""Every notebook in notebooks/ runs top to bottom and draws at least one image; ``python
notebooks/_build.py`` writes them, so the stored files match the builder.

A notebook runs as written, except that the sizes in ``SIZES`` are set after its parameter cell
(the first code cell, papermill's convention): the same cells and code paths on fewer objects
(03_evaluation's evaluation of 20 objects in four variants is ~45 CPU s of the suite's time) and
1000 samples per object instead of 1500: the OCSVM pose at 1024 rows and resolution 32 is the
program test_normalize_methods.py compiles for its concrete OCSVM calls (1024 points), loaded from
the run's compilation cache by whichever comes second, and 02's sweep over six objects costs
a third (19.8 -> 6.2 CPU s with INSTANCES 2).

The kernel is this interpreter (a kernelspec written into a temporary JUPYTER_PATH), so the
notebooks see the same environment as the tests.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))
TIMEOUT = 180  # seconds per cell
SIZES = {"01_quickstart": "COUNT = 1000  # the test's run: fewer samples, every cell",
         "02_gradients_and_tuning": "COUNT, INSTANCES = 1000, 2  # the test's run: fewer samples and objects",
         "03_evaluation": "CLASSES, INSTANCES, COUNT = 2, 3, 1000  # the test's run: fewer objects, every cell"}


@pytest.fixture
def kernel_env(tmp_path, monkeypatch):
    spec = tmp_path / "jupyter" / "kernels" / "python3"
    spec.mkdir(parents=True)
    (spec / "kernel.json").write_text(json.dumps({
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "Python 3 (tests)", "language": "python"}))
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path / "jupyter"))
    monkeypatch.setenv("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    return tmp_path


def test_notebooks_exist():
    assert [p.name for p in NOTEBOOKS] == ["01_quickstart.ipynb", "02_gradients_and_tuning.ipynb",
                                           "03_evaluation.ipynb"]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_stored_without_outputs(path):
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code and all(not c.outputs and c.execution_count is None for c in code)
    assert "COUNT" in code[0].source  # the parameter cell comes first


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_runs(path, kernel_env):
    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    if path.stem in SIZES:
        names = SIZES[path.stem].split("=")[0].replace(",", " ").split()
        assert all(f"{n} = " in code[0].source for n in names)  # sizes the parameter cell defines
        code[0].source += "\n" + SIZES[path.stem]
    client = nbclient.NotebookClient(nb, timeout=TIMEOUT, kernel_name="python3",
                                     resources={"metadata": {"path": str(kernel_env)}})
    client.execute()
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert all(c.execution_count is not None for c in code)  # every cell ran
    errors = [o for c in code for o in c.outputs if o.output_type == "error"]
    assert not errors
    images = [o for c in code for o in c.outputs
              if o.output_type in ("display_data", "execute_result") and "image/png" in o.get("data", {})]
    assert images, f"{path.name} produced no image"


def test_stored_notebooks_match_the_builder(tmp_path):
    sys.path.insert(0, str(NOTEBOOKS[0].parent))
    import _build

    _build.build(tmp_path)
    for path in NOTEBOOKS:
        assert (tmp_path / path.name).read_text() == path.read_text(), f"run python notebooks/_build.py ({path.name})"
