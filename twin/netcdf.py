"""Writing the loop's files atomically, so a failure never leaves a half-written file.

:func:`atomic_output` is the one way the package writes an output file
(NetCDF files, FMUs, histories, reports): into a temporary file in the same
folder, renamed over the target only when complete, with the usual
permissions (``0666`` less the umask).
"""

from __future__ import annotations

import logging
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import xarray as xr

from twin.errors import TwinError

log = logging.getLogger(__name__)


def load_netcdf(path: str | Path, kind: str, error: type[TwinError] = TwinError) -> xr.Dataset:
    """Load a NetCDF file of the loop into memory, or raise ``error`` saying what is wrong with it.

    ``kind`` names the file in messages (``"signals"``, ``"modes"``).
    """
    path = Path(path)
    if not path.is_file():
        raise error(f"{path}: no such {kind} file")
    try:
        return xr.load_dataset(path)
    except (OSError, ValueError) as exc:
        raise error(f"{path}: not a readable NetCDF {kind} file ({exc})") from None


def check_writable(path: str | Path) -> Path:
    """Fail early, before any long computation, when ``path``'s folder is missing or read-only."""
    path = Path(path)
    if not path.parent.is_dir():
        raise TwinError(f"cannot write {path}: folder {path.parent} does not exist")
    if not os.access(path.parent, os.W_OK):
        raise TwinError(f"cannot write {path}: folder {path.parent} is not writable")
    return path


def write_netcdf(ds: xr.Dataset, path: str | Path) -> Path:
    """Write ``ds`` to ``path`` through a temporary file in the same folder, then rename it.

    The file gets the usual permissions (``0666`` less the umask).

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     p = write_netcdf(xr.Dataset({"a": ("x", np.arange(3.0))}), Path(tmp) / "a.nc")
    ...     float(xr.load_dataset(p).a.sum())
    3.0
    """
    with atomic_output(path, ".nc.part") as tmp:
        ds.to_netcdf(tmp, engine="netcdf4")
    log.info("wrote %s", path)
    return path


@contextmanager
def atomic_output(path: str | Path, suffix: str = ".part") -> Iterator[Path]:
    """A temporary path to write ``path``'s content to; renamed to ``path`` when the block succeeds.

    On any error the temporary file is removed and ``path`` is left as it was.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     with atomic_output(Path(tmp) / "a.txt") as part:
    ...         _ = part.write_text("done")
    ...     sorted(p.name for p in Path(tmp).iterdir())
    ['a.txt']
    """
    path = check_writable(path)
    fd, tmp = tempfile.mkstemp(suffix=suffix, dir=path.parent)
    os.close(fd)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
