"""Sphinx extension: the notebooks of ``notebooks/`` executed into ``docs/examples/`` at every build.

Their input files (``notebooks/data/``) are copied beside them first, so a notebook reads ``data/...`` alike
in ``notebooks/`` and in the build.

Each notebook runs in its own kernel that talks to the build over IPC sockets
(files in a private temporary folder) rather than TCP: a kernel started over
TCP is handed ports that were free a moment before, which another process on a
busy machine can take first, and the build then fails for a reason that has
nothing to do with the docs. The executed notebooks (outputs included) are
what myst-nb renders; their outputs are never committed.
"""

from __future__ import annotations

import logging
import shutil
import tempfile
from pathlib import Path

import nbformat
from nbclient import NotebookClient
from traitlets.config import Config

logger = logging.getLogger(__name__)

#: Seconds a cell may run before the build fails.
CELL_TIMEOUT_S = 900


def execute(source: Path, target: Path, timeout_s: int = CELL_TIMEOUT_S) -> None:
    """Execute the notebook ``source`` with its folder ``target.parent`` as working directory, write it to ``target``.

    An error in a cell raises (nbclient's ``CellExecutionError``, naming the cell), so the build fails on it.
    """
    notebook = nbformat.read(source, as_version=4)
    with tempfile.TemporaryDirectory(prefix="twin-docs-kernel-") as sockets:
        config = Config({"KernelManager": {"transport": "ipc", "ip": str(Path(sockets) / "kernel")}})
        client = NotebookClient(
            notebook,
            timeout=timeout_s,
            kernel_name="python3",
            config=config,
            resources={"metadata": {"path": str(target.parent)}},
        )
        client.execute()
    nbformat.write(notebook, target)


def _execute_all(app) -> None:
    source_dir = Path(app.srcdir).parent / "notebooks"
    target_dir = Path(app.srcdir) / "examples"
    target_dir.mkdir(exist_ok=True)
    if (source_dir / "data").is_dir():  # the notebooks' input files, found beside them as in notebooks/
        shutil.copytree(source_dir / "data", target_dir / "data", dirs_exist_ok=True)
    for source in sorted(source_dir.glob("*.ipynb")):
        logger.info("executing %s", source.name)
        execute(source, target_dir / source.name)


def setup(app) -> dict:
    app.connect("builder-inited", _execute_all)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
