"""The documentation keeps up with the package: every module in the API reference, a short front page,
no internal work numbers."""

import pkgutil
import re

import twin
from tests.conftest import ROOT


def test_every_module_is_in_the_api_reference():
    listed = "\n".join(p.read_text() for p in (ROOT / "docs" / "api").glob("*.md"))
    modules = [
        m.name
        for m in pkgutil.walk_packages(twin.__path__, prefix="twin.")
        if not m.name.startswith(("twin.cli", "twin.__main__"))
    ]  # the CLI: from its parser (docs/cli.md)
    missing = [m for m in modules if f".. automodule:: {m}\n" not in listed]
    assert missing == []


def test_the_readme_is_a_front_page_that_starts_with_the_two_commands():
    lines = (ROOT / "README.md").read_text().splitlines()
    assert len(lines) <= 150
    assert "pip install -e . && twin demo" in lines[:6]
    assert "pip install -e '.[test]' && python -m pytest && python -m pytest -m slow" in lines[:6]


def test_no_internal_work_numbers_in_the_project():
    pattern = re.compile(r"\b(stop|stops) [0-9]+|\bissue [0-9]+", re.IGNORECASE)
    found = []
    for folder in ("twin", "docs", "benchmarks"):
        for path in (ROOT / folder).rglob("*"):
            if path.is_file() and path.suffix in {".py", ".md", ".txt", ".toml", ".c"} and "_build" not in path.parts:
                found += [
                    f"{path.relative_to(ROOT)}:{n}"
                    for n, line in enumerate(path.read_text().splitlines(), 1)
                    if pattern.search(line)
                ]
    found += [
        f"README.md:{n}"
        for n, line in enumerate((ROOT / "README.md").read_text().splitlines(), 1)
        if pattern.search(line)
    ]
    assert found == []


def test_the_blocking_docs_build_pins_every_docs_tool():
    """CI builds the docs with the toolchain in .ci/docs-constraints.txt: every package of the docs extra is
    pinned there, and the CI script uses the file."""
    import tomllib

    extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]["docs"]
    names = {re.split(r"[<>=!~\[ ]", r, maxsplit=1)[0].lower() for r in extra}
    lines = (ROOT / ".ci" / "docs-constraints.txt").read_text().splitlines()
    pins = dict(line.lower().split("==") for line in lines if line and not line.startswith("#"))
    assert names <= set(pins), f"docs tools without a pin: {sorted(names - set(pins))}"
    assert "-c .ci/docs-constraints.txt" in (ROOT / ".ci" / "run").read_text()
