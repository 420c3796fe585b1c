"""Writing the loop's NetCDF files: atomically, so a failure never leaves a half-written file."""

from __future__ import annotations

import logging
import os
import tempfile
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
    path = check_writable(path)
    fd, tmp = tempfile.mkstemp(suffix=".nc.part", dir=path.parent)
    os.close(fd)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        ds.to_netcdf(tmp, engine="netcdf4")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    log.info("wrote %s", path)
    return path
