"""Shared fixtures: paths to the shipped models and test data."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(autouse=True)
def _run_from_root(monkeypatch):
    """Docstring examples and tests use paths relative to the repository root."""
    monkeypatch.chdir(ROOT)


@pytest.fixture(scope="session")
def hydro_unit():
    from twin import load_model

    return load_model(ROOT / "models" / "hydro_unit.toml")


@pytest.fixture(scope="session")
def ross_model():
    from twin import load_model

    return load_model(ROOT / "models" / "ross_reference.toml")
