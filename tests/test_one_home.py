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
    found = [
        f"{name}:{n}"
        for name, text in _sources()
        if name not in allowed
        for n, line in enumerate(text.splitlines(), 1)
        if pattern.search(line)
    ]
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
                isinstance(b, ast.Name) and b.id in ("Effect", "RelativeChange") for b in node.bases
            ):
                found.append(f"{name}:{node.lineno} class {node.name}")
            if isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name)
                and t.id in ("EFFECTS", "LOCAL_CHANGES", "REPLACES", "EXCLUSIVE", "PER_MODE_NAME")
                for t in node.targets
            ):
                found.append(f"{name}:{node.lineno} {ast.unparse(node.targets[0])}")
    assert found == []


def _class_names() -> list[tuple[str, int, str]]:
    return [
        (name, node.lineno, node.name)
        for name, text in _sources()
        for node in ast.walk(ast.parse(text))
        if isinstance(node, ast.ClassDef)
    ]


def test_one_candidate_for_the_loop_and_the_tracker():
    """A change a diagnosis can name is twin.loop.candidates.Candidate, for one record and for the tracker."""
    found = [f"{name}:{n}" for name, n, cls in _class_names() if cls == "Candidate"]
    assert len(found) == 1 and found[0].startswith("twin/loop/candidates.py:")


def test_evidence_is_computed_in_one_place():
    """ln Z of a hypothesis (Laplace's formula and its exact linear-Gaussian case) is twin.update.evidence's:
    no other module of the diagnosis, the locating scan or the tracker takes a log-determinant of its own."""
    weighing = ["twin/loop/", "twin/track/", "twin/update/laplace.py"]
    found = [
        f"{name}:{n}"
        for name, text in _sources()
        if any(name.startswith(w) for w in weighing)
        for n, line in enumerate(text.splitlines(), 1)
        if "slogdet" in line or "log1p(" in line
    ]
    assert found == []


def test_one_modal_assignment():
    """Modes are assigned one to one by twin.modes.pairing.assign (Hungarian, with gates) alone: no other module
    calls the Hungarian algorithm or walks a cost matrix's pairs closest first."""
    greedy = re.compile(r"argsort\([^)]*axis=None")
    found = [
        f"{name}:{n}"
        for name, text in _sources()
        if name != "twin/modes/pairing.py"
        for n, line in enumerate(text.splitlines(), 1)
        if "linear_sum_assignment" in line or greedy.search(line)
    ]
    assert found == []


def test_sub_commands_are_made_one_way():
    """Each command module registers its sub-commands (``add_commands``) through twin.cli.common.command; no
    module makes a sub-parser of its own or reaches for another command module's private helpers."""
    found = [
        f"{name}:{n}"
        for name, text in _sources()
        if name != "twin/cli/common.py"
        for n, line in enumerate(text.splitlines(), 1)
        if "add_parser(" in line or re.search(r"from twin\.cli\.\w+ import _", line)
    ]
    assert found == []
    modules = [name for name, text in _sources() if name.startswith("twin/cli/") and "def add_commands(sub)" in text]
    assert sorted(modules) == [
        "twin/cli/design.py",
        "twin/cli/loop.py",
        "twin/cli/model.py",
        "twin/cli/stages.py",
        "twin/cli/track.py",
    ]
