"""Fixtures shared by the tests and the docstring examples: the shipped models, loaded once per session.

Docstring examples use ``hydro_unit`` (the shipped hydro unit) as NumPy's use ``np``: the name is in every
doctest's namespace, so 90 examples share one loaded model and its cached matrices instead of reloading it. A
reader runs an example after ``hydro_unit = load_model(shipped_model("hydro_unit"))``, as the API reference says.
"""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent


@pytest.fixture(autouse=True)
def _run_from_root(monkeypatch):
    """Docstring examples and tests use paths relative to the repository root."""
    monkeypatch.chdir(ROOT)


@pytest.fixture(scope="session")
def hydro_unit():
    """The shipped hydro unit (a frozen model: sharing it cannot leak one test's change into another)."""
    from twin import load_model

    return load_model(ROOT / "models" / "hydro_unit.toml")


@pytest.fixture(scope="session")
def ross_model():
    """The shipped two-disk rotor of ROSS's examples."""
    from twin import load_model

    return load_model(ROOT / "models" / "ross_reference.toml")


@pytest.fixture(autouse=True)
def _shipped_model_in_doctests(doctest_namespace, hydro_unit):
    doctest_namespace["hydro_unit"] = hydro_unit
