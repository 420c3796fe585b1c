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
from typing import Any

import xarray as xr

from twin.errors import TwinError

log = logging.getLogger(__name__)

#: First bytes of a NetCDF-4 (HDF5) and a classic NetCDF file.
NETCDF_MAGIC = (b"\x89HDF", b"CDF")
#: Figure files the command line writes.
FIGURE_TYPES = (".png", ".pdf", ".svg")


def load_netcdf(path: str | Path, kind: str, error: type[TwinError] = TwinError) -> xr.Dataset:
    """Load a NetCDF file of the loop into memory, or raise ``error`` saying what is wrong with it.

    ``kind`` names the file in messages (``"signals"``, ``"modes"``).
    """
    path = Path(path)
    if path.is_dir():
        raise error(f"{path}: is a folder, not a {kind} file")
    if not path.is_file():
        raise error(f"{path}: no such {kind} file")
    try:
        with open(path, "rb") as f:
            magic = f.read(4)
    except OSError as exc:
        raise error(f"{path}: cannot read the {kind} file ({exc.strerror})") from None
    if not magic.startswith(NETCDF_MAGIC):
        raise error(f"{path}: not a NetCDF file (a {kind} file is NetCDF-4 or classic NetCDF, as twin writes it)")
    try:
        return xr.load_dataset(path)
    except (OSError, ValueError) as exc:
        raise error(f"{path}: not a readable NetCDF {kind} file ({exc})") from None


def global_attrs(path: str | Path) -> dict[str, Any]:
    """A NetCDF file's global attributes alone, without xarray's decoding: four times quicker than
    opening it as a Dataset, for the checks that read a few attrs of many files (a track's cache).

    Raises ``OSError`` for a file that is not readable NetCDF.
    """
    import netCDF4

    with netCDF4.Dataset(path) as ds:
        return {k: ds.getncattr(k) for k in ds.ncattrs()}


def check_writable(path: str | Path, figure: bool = False) -> Path:
    """Fail early, before any long computation, when ``path`` cannot be written; create its missing folders.

    A folder is no file name; a read-only folder is refused. ``figure``
    also asks for a file type matplotlib writes (``.png``, ``.pdf``, ``.svg``).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     check_writable(Path(tmp) / "new" / "a.nc").parent.is_dir()
    True
    """
    path = Path(path)
    if path.is_dir():
        raise TwinError(f"cannot write {path}: it is a folder; give a file name inside it")
    if figure and path.suffix.lower() not in FIGURE_TYPES:
        raise TwinError(f"cannot write the figure {path}: name a {', '.join(FIGURE_TYPES)} file")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise TwinError(f"cannot write {path}: cannot create folder {path.parent} ({exc.strerror})") from None
    problem = _unwritable(path.parent)
    if problem:
        raise TwinError(f"cannot write {path}: folder {path.parent} is not writable ({problem})")
    return path


def _unwritable(folder: Path) -> str | None:
    """Why no file can be made in ``folder`` (None if one can): a file made there and removed, which also
    tells a read-only file system, or a folder the owner may not write, where root's permissions ignore it."""
    try:
        with tempfile.TemporaryFile(dir=folder):
            return None
    except OSError as exc:
        return exc.strerror or str(exc)


def check_folder(path: str | Path, flag: str | None = None, make: bool = False) -> Path:
    """Check, before any work, that results can be written into the folder ``path`` (made if ``make``).

    Refused with a :class:`~twin.errors.TwinError` naming it (and the option ``flag``, if given): a file
    there, or a folder (or, when it does not exist yet, the folder it would be made in) that is not writable.
    A refused command leaves nothing behind, not even an empty folder.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     check_folder(Path(tmp) / "report").exists(), check_folder(Path(tmp) / "report", make=True).is_dir()
    (False, True)
    """
    path = Path(path)
    what = f"--{flag} {path}" if flag else f"the folder {path}"
    existing = path
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise TwinError(
            f"{what} is a file, not a folder"
            if existing == path
            else f"cannot write into {what}: {existing} is a file, not a folder"
        )
    problem = _unwritable(existing)
    if problem:
        where = "it is not writable" if existing == path else f"{existing}, where it would be made, is not writable"
        raise TwinError(f"cannot write into {what}: {where} ({problem})")
    if make:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise TwinError(f"cannot write into {what}: cannot create it ({exc.strerror})") from None
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
    empty = [k for k, v in ds.variables.items() if v.size == 0 and {"contiguous", "chunksizes"} & set(v.encoding)]
    if empty:  # a layout read from a file with data cannot hold none (NetCDF: Invalid argument)
        ds = ds.copy()
        for k in empty:
            ds[k].encoding = {e: v for e, v in ds[k].encoding.items() if e not in ("contiguous", "chunksizes")}
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
