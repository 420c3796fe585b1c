"""Sphinx configuration of twin's documentation (``python -m sphinx -W -b html docs docs/_build/html``)."""

from __future__ import annotations

import sys
from pathlib import Path

import twin

# docs/_ext: the notebooks executed at build time (executed_notebooks), the parser as the command-line page
# renders it (cli_reference), the model-file reference from the reader's declaration (model_file_reference)
sys.path.insert(0, str(Path(__file__).parent / "_ext"))

project = "twin"
author = "the twin developers"
release = version = twin.__version__
copyright = "the twin developers"

extensions = [
    "myst_nb",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "sphinxarg.ext",
    "executed_notebooks",
    "model_file_reference",
]
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}

# The notebooks of notebooks/ are pages of the docs, executed at every build by executed_notebooks (docs/_ext)
# into docs/examples/ (generated, not in git), where they write their output folders; myst-nb renders them as
# executed. Their outputs are never committed.
nb_execution_mode = "off"
nb_merge_streams = True
exclude_patterns = ["_build", "examples/*-output"]
myst_enable_extensions = ["dollarmath", "deflist"]
myst_heading_anchors = 3

# The docstrings are NumPy style; their types are prose ("(I, 2, 2)", "path"), not cross-references.
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
autodoc_default_options = {"members": True, "member-order": "bysource"}
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True
nitpicky = False
# A docstring's type is prose such as "(n_modes, m) complex"; Sphinx tries each word as a Python name and
# finds several attributes called ``n_modes`` or ``channels``. Those guesses are not links anyone wrote.
suppress_warnings = ["ref.python"]

html_theme = "pydata_sphinx_theme"
html_title = "twin"
html_theme_options = {"navigation_with_keys": False, "show_toc_level": 2}
