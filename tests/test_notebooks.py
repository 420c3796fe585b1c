"""The notebooks run from top to bottom (code cells executed in order, no kernel needed)."""

import matplotlib
import nbformat
import pytest

from conftest import ROOT

NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs(path, monkeypatch):
    import matplotlib.pyplot as plt

    matplotlib.use("Agg")
    monkeypatch.chdir(path.parent)
    nb = nbformat.read(path, as_version=4)
    namespace: dict = {"__name__": "__notebook__"}
    for i, cell in enumerate(c for c in nb.cells if c.cell_type == "code"):
        assert not cell.get("outputs"), f"{path.name}: cell {i} has committed outputs"
        exec(compile(cell.source, f"{path.name}[{i}]", "exec"), namespace)  # noqa: S102
    plt.close("all")
    assert NOTEBOOKS
