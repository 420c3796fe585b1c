"""What an installed copy carries: every data file the package reads is declared as package data."""

import fnmatch
import tomllib

from tests.conftest import ROOT


def test_every_data_file_of_the_package_is_declared():
    """A wheel holds the .py files and the declared package data only: the shipped models and the FMU's C
    runtime must be declared, or a non-editable install cannot load a model or export an FMU."""
    globs = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]["twin"]
    package = ROOT / "twin"
    data = [
        p.relative_to(package).as_posix()
        for p in package.rglob("*")
        if p.is_file() and p.suffix not in (".py", ".pyc") and "__pycache__" not in p.parts
    ]
    assert data, "the package has data files (models, C runtime)"
    undeclared = [f for f in data if not any(fnmatch.fnmatch(f, g) for g in globs)]
    assert undeclared == []


def test_public_examples_import_what_they_show():
    """A public function's example runs when copied into a fresh session: it imports the function itself."""
    import importlib
    import inspect
    import re

    missing = []
    for name in ("twin", "twin.fem", "twin.modes", "twin.fmu", "twin.extract", "twin.update", "twin.loop"):
        module = importlib.import_module(name)
        for public in module.__all__:
            obj = getattr(module, public)
            code = "\n".join(x for x in (inspect.getdoc(obj) or "").splitlines() if x.strip().startswith(">>>"))
            uses = re.search(rf"(?<![\w.]){public}\b", code)
            if callable(obj) and uses and not re.search(rf"import[^\n]*\b{public}\b", code):
                missing.append(f"{name}.{public}")
    assert missing == []


def test_help_names_every_stage():
    import twin

    for stage in ("twin.fem", "twin.fmu", "twin.extract", "twin.update", "twin.loop"):
        assert stage in twin.__doc__, stage


def test_python_dash_m_twin_is_the_command_line(tmp_path):
    """``python -m twin`` runs the same command line as the ``twin`` script (where a script is not on the path)."""
    import subprocess
    import sys

    import twin

    done = subprocess.run([sys.executable, "-m", "twin", "--version"], capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 0 and done.stdout.strip() == f"twin {twin.__version__}"
    bad = subprocess.run([sys.executable, "-m", "twin", "track"], capture_output=True, text=True, cwd=tmp_path)
    assert bad.returncode == 2 and "the following arguments are required" in bad.stderr


def test_the_version_has_one_source():
    """pyproject.toml reads the version from twin.__version__ rather than stating it again."""
    import importlib.metadata

    import twin

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "twin.__version__"}
    assert importlib.metadata.version("twin") == twin.__version__
    assert (ROOT / "twin" / "py.typed").is_file()  # the type hints are declared for users' type checkers
