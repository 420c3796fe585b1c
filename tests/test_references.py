"""Every cross-reference a docstring or a documentation page makes to a twin object names one that exists."""

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
ROLE = re.compile(r":(?:func|class|mod|data|meth|attr|exc):`~?(twin\.[\w.]+)`")


def resolves(name: str) -> bool:
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for attr in parts[i:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False
        return True
    return False


@pytest.mark.parametrize("path", sorted((ROOT / "twin").rglob("*.py")), ids=lambda p: str(p.relative_to(ROOT)))
def test_docstring_references_resolve(path):
    names = sorted(set(ROLE.findall(path.read_text())))
    assert [n for n in names if not resolves(n)] == []


MYST_ROLE = re.compile(r"\{(?:func|class|mod|data|meth|attr|exc)\}`~?(twin\.[\w.]+)`")
PAGES = sorted(p for p in (ROOT / "docs").rglob("*.md") if "_build" not in p.parts)


@pytest.mark.parametrize("path", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_documentation_references_resolve(path):
    names = sorted(set(MYST_ROLE.findall(path.read_text())))
    assert [n for n in names if not resolves(n)] == []
