"""The notebooks run from top to bottom (code cells executed in order, no kernel needed).

A cell tagged ``parameters`` (papermill's convention) is followed by the
test's overrides: output folders under ``tmp_path``, so a run leaves nothing in
the source tree, and a 10-min record instead of 20 for the end-to-end loop.
"""

import matplotlib
import nbformat
import pytest

from tests.conftest import ROOT

NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
OVERRIDES = {
    # 10 min instead of 20: twice the reference pull, so that it still stands five times above the noise floor
    "end_to_end": "OUT = TMP / 'end-to-end'\nDURATION_S = 600.0\nSAMPLES = 10\nHIDDEN = 'magnetic_pull@2'",
    "posterior_analysis": "OUT = TMP\nPOSTERIOR = TMP / 'posterior.nc'",
    "own_machine": "OUT = TMP / 'own-machine'",
}


# the end-to-end notebook simulates and extracts a record (about 25 s), the own-machine one a loop and a 10-day
# campaign (about two minutes): slow
SLOW = ("end_to_end", "own_machine")
PARAMS = [pytest.param(p, id=p.stem, marks=[pytest.mark.slow] if p.stem in SLOW else []) for p in NOTEBOOKS]


@pytest.mark.parametrize("path", PARAMS)
def test_notebook_runs(path, monkeypatch, tmp_path):
    import matplotlib.pyplot as plt

    matplotlib.use("Agg")
    monkeypatch.chdir(path.parent)
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    namespace: dict = {"__name__": "__notebook__", "TMP": tmp_path}
    for i, cell in enumerate(c for c in nb.cells if c.cell_type == "code"):
        assert not cell.get("outputs") and cell.get("execution_count") is None, f"{path.name}: cell {i} has outputs"
        exec(compile(cell.source, f"{path.name}[{i}]", "exec"), namespace)  # noqa: S102
        if "parameters" in cell.metadata.get("tags", []):
            exec(OVERRIDES.get(path.stem, ""), namespace)  # noqa: S102
    plt.close("all")
    assert NOTEBOOKS


def test_notebooks_are_listed_and_have_a_parameters_cell():
    assert {p.stem for p in NOTEBOOKS} >= {"end_to_end", "posterior_analysis", "hydro_unit_modes", "own_machine"}
    for path in NOTEBOOKS:
        if path.stem in OVERRIDES:
            cells = nbformat.read(path, as_version=4).cells
            assert any("parameters" in c.metadata.get("tags", []) for c in cells), path.name
