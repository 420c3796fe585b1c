"""Every benchmark script imports: the names it takes from twin still exist."""

import importlib

import pytest

from tests.benchmarks import BENCHMARKS

SCRIPTS = sorted(p.stem for p in BENCHMARKS.glob("*.py"))


def test_there_are_benchmarks():
    assert len(SCRIPTS) >= 10


@pytest.mark.parametrize("name", SCRIPTS)
def test_benchmark_imports(name):
    module = importlib.import_module(name)
    assert module.__doc__, f"benchmarks/{name}.py has no docstring saying what it measures"
