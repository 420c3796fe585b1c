"""Each concept has one home in the package: a test finds a second one before a reader does."""

import ast
import re

from tests.conftest import ROOT

PACKAGE = ROOT / "twin"


def _sources():
    for path in sorted(PACKAGE.rglob("*.py")):
        yield path.relative_to(ROOT).as_posix(), path.read_text()


def test_effect_labels_are_split_only_by_the_label_parser():
    """``parse_label`` (twin.fem.effects.registry) reads a label; nothing else splits at a colon, except the
    text-file reader's ``# key: value`` header lines, which hold no labels."""
    pattern = re.compile(r"""\.(r?partition|r?split)\(\s*["']:["']""")
    allowed = {"twin/fem/effects/registry.py", "twin/extract/readers.py"}
    found = [f"{name}:{n}" for name, text in _sources() if name not in allowed
             for n, line in enumerate(text.splitlines(), 1) if pattern.search(line)]  # fmt: skip
    assert found == []


def test_effect_classes_live_in_the_effects_package():
    """Every effect or local change is a class of twin.fem.effects (one module each); no other module defines
    one or keeps its own table of effect keys."""
    found = []
    for name, text in _sources():
        if name.startswith("twin/fem/effects/"):
            continue
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ClassDef) and any(
                    isinstance(b, ast.Name) and b.id in ("Effect", "RelativeChange") for b in node.bases):  # fmt: skip
                found.append(f"{name}:{node.lineno} class {node.name}")
            if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id in (
                    "EFFECTS", "LOCAL_CHANGES", "REPLACES", "EXCLUSIVE", "PER_MODE_NAME") for t in node.targets):  # fmt: skip
                found.append(f"{name}:{node.lineno} {ast.unparse(node.targets[0])}")
    assert found == []
