"""Every notebook in notebooks/ runs top to bottom without a failing cell.

``pip install -e ".[test,notebooks]" && python -m pytest -m notebooks`` runs it (skipped, saying
which, without nbclient and nbformat): the default run leaves it out (35 s of CPU, a sixth of
the suite, which must stay under three minutes on two cores with its installation), as the
documentation build of ``.ci/run`` executes every notebook and fails on a failing cell.
"""

from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))

#: run before each notebook's cells in the shared kernel: a namespace as a new kernel's, no figure
#: left open, the notebook's own empty folder as the working directory
_FRESH = """\
%reset -f
import os as _os, matplotlib.pyplot as _plt
_plt.close("all"); _plt.rcdefaults()
_os.makedirs({folder!r}); _os.chdir({folder!r})
del _os, _plt
"""


@pytest.mark.notebooks
def test_every_notebook_runs(tmp_path, monkeypatch):
    """One kernel runs the notebooks one after the other, each from a reset namespace in a folder of
    its own: a kernel of its own cost each notebook 2-3 s of start-up and imports (numpy, matplotlib,
    sympy, cfdesign), a fifth of the notebooks' time in the suite.  The documentation build
    (``.ci/run``) executes each notebook in a kernel of its own, so a notebook that leaned on
    another's state fails there.  The kernel talks over Unix sockets in the test's folder, not TCP
    ports: a kernel and a Dask cluster started at once on random ports can collide."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    from jupyter_client.manager import KernelManager

    monkeypatch.setenv("MPLBACKEND", "Agg")
    combined, owner = nbformat.v4.new_notebook(), []
    for path in NOTEBOOKS:
        nb = nbformat.read(path, as_version=4)
        combined.cells.append(nbformat.v4.new_code_cell(_FRESH.format(folder=str(tmp_path / path.stem))))
        owner.append(path.name)
        for cell in nb.cells:
            if cell.cell_type == "code":
                combined.cells.append(cell)
                owner.append(path.name)
    km = KernelManager(kernel_name="python3", transport="ipc", ip=str(tmp_path / "kernel"))
    client = nbclient.NotebookClient(combined, km=km, timeout=300, startup_timeout=120,
                                     resources={"metadata": {"path": str(tmp_path)}})
    with client.setup_kernel():
        for index, cell in enumerate(combined.cells):
            try:
                client.execute_cell(cell, index)
            except nbclient.exceptions.CellExecutionError as exc:
                pytest.fail(f"{owner[index]}: a cell failed:\n{exc}")


def test_there_are_notebooks():
    assert NOTEBOOKS, "notebooks/ holds no notebook"
