"""Sphinx extension: the model-file reference page, written from :mod:`twin.fem.schema` at every build.

The page lists the keys the reader accepts, so it is generated from the declaration the reader uses rather than
written by hand; ``docs/reference/model-file.md`` is that generated page (not in git).
"""

from __future__ import annotations

from pathlib import Path

from twin.fem.modelfile import MODELS_DIR, load_model
from twin.fem.schema import reference_markdown


def _write(app) -> None:
    target = Path(app.srcdir) / "reference" / "model-file.md"
    target.parent.mkdir(exist_ok=True)
    text = reference_markdown([load_model(p) for p in sorted(MODELS_DIR.glob("*.toml"))])
    if not target.exists() or target.read_text(encoding="utf-8") != text:  # unchanged: Sphinx keeps its cache
        target.write_text(text, encoding="utf-8")


def setup(app) -> dict:
    app.connect("builder-inited", _write)
    return {"parallel_read_safe": True}
