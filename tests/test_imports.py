"""The import graph follows the loop: no circle between modules, no import from a stage up to a later one,
and no module over 600 lines."""

import ast
from pathlib import Path

import pytest

from tests.conftest import ROOT

PACKAGE = ROOT / "twin"
#: The stages in the order of the loop; a module may import from its own stage and the ones before it.
#: ``common`` is what every stage shares (defaults, errors, NetCDF, progress, tasks), ``report`` what the loop and
#: the tracker show, ``harness`` the loop's validation on hidden truths, ``cli`` is on top of all.
STAGES = ("common", "fem", "modes", "fmu", "design", "extract", "update", "report", "loop", "track", "harness", "cli")
COMMON = {"defaults", "errors", "netcdf", "progress", "tasks", "units"}
MAX_LINES = 600


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(name: str) -> bool:
    path = ROOT.joinpath(*name.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def _imports(path: Path) -> set[str]:
    """The twin modules ``path`` imports, wherever in the file (lazy imports count); ``from twin import
    __version__`` does not: the version is set before the package imports anything."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.split(".")[0] == "twin"}
        elif (
            isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "twin" and not node.level
        ):
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                if _is_module(sub):
                    found.add(sub)
                elif not (node.module == "twin" and alias.name == "__version__"):
                    found.add(node.module)
    return found


def _graph() -> dict[str, set[str]]:
    graph = {}
    for path in PACKAGE.rglob("*.py"):
        name = _module_name(path)
        deps = _imports(path) - {name}
        if path.name == "__init__.py":  # a package re-exports its own modules: that is not a dependency on them
            deps = {d for d in deps if not d.startswith(name + ".")}
        graph[name] = deps
    return graph


def _stage(module: str) -> str:
    parts = module.split(".")
    if len(parts) == 1:
        return "common"
    if parts[1] == "__main__":  # python -m twin: the command line
        return "cli"
    return "common" if parts[1] in COMMON else parts[1]


def test_every_module_has_a_stage():
    assert {_stage(m) for m in _graph()} <= set(STAGES) | {"models"}


def test_no_import_circle():
    graph = _graph()
    circles, state = [], {}

    def visit(node: str, path: list[str]) -> None:
        state[node] = "open"
        for dep in sorted(graph.get(node, ())):
            if state.get(dep) == "open":
                circles.append(" -> ".join(path[path.index(dep) :] + [dep]) if dep in path else f"{node} -> {dep}")
            elif dep not in state:
                visit(dep, path + [dep])
        state[node] = "done"

    for module in sorted(graph):
        if module not in state:
            visit(module, [module])
    assert circles == []


def test_no_import_from_a_later_stage():
    order = {s: k for k, s in enumerate(STAGES)}
    up = [
        f"{m} -> {d}"
        for m, deps in sorted(_graph().items())
        for d in sorted(deps)
        if m != "twin" and order[_stage(d)] > order[_stage(m)]
    ]  # the package's facade re-exports any stage
    assert up == []


@pytest.mark.parametrize("path", sorted(PACKAGE.rglob("*.py")), ids=lambda p: str(p.relative_to(ROOT)))
def test_modules_are_small(path):
    assert len(path.read_text().splitlines()) <= MAX_LINES
