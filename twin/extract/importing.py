"""Records from measurement systems into ``signals.nc``: one reader per file format, one record layout.

A reader (:data:`twin.extract.readers.READERS`, by file suffix) returns what
its file holds as a :class:`twin.extract.readers.Table`: the channels' samples, their names and units, a time column or
a sampling rate, where the file has them. :func:`import_record` completes it
with what the caller says (``fs_hz``, ``units``, ``quantities``, ``channels``),
works out each channel's quantity from its units where none is given (µm is a
displacement, mm/s a velocity, g an acceleration), checks the record as the
extraction will (:func:`twin.extract.signals.check_record`) and returns it in
the ``signal`` layout of :mod:`twin.extract.quantities`. Every problem is an
error naming the file, and the row, column or channel.

The readers (:mod:`twin.extract.readers`): CSV and text tables with a header
line, UFF dataset 58, TDMS, MATLAB ``.mat`` and HDF5.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np  # noqa: F401 (the examples)
import xarray as xr

from twin import __version__
from twin.errors import SignalError
from twin.extract.quantities import QUANTITIES, si_factor
from twin.extract.readers import READERS
from twin.extract.signals import check_record


def quantity_of(units: str, where: str) -> str:
    """The quantity ``units`` measure: displacement, velocity or acceleration.

    Examples
    --------
    >>> quantity_of("um", "A_x"), quantity_of("mm/s", "A_x"), quantity_of("g", "A_x")
    ('displacement', 'velocity', 'acceleration')
    """
    for quantity in QUANTITIES:
        try:
            si_factor(units, quantity, where)
            return quantity
        except SignalError:
            continue
    raise SignalError(f"{where}: units {units!r} are not of a displacement, a velocity or an acceleration")


def import_record(
    path: str | Path,
    *,
    fs_hz: float | None = None,
    units: str | Mapping[str, str] | None = None,
    quantities: str | Mapping[str, str] | None = None,
    channels: Sequence[str] | None = None,
) -> xr.Dataset:
    """Read a measurement file into a record in the ``signal`` layout (``signals.nc``).

    Parameters
    ----------
    path : path
        The file; its suffix chooses the reader (:data:`READERS`).
    fs_hz : float, optional
        Sampling rate [Hz], where the file gives neither a time column nor a rate (if it does, they must agree).
    units : str or mapping, optional
        Every channel's units, or some channels' by name, where the file gives none (it must say them or be
        told: a number without units is not a measurement).
    quantities : str or mapping, optional
        Every channel's quantity (displacement, velocity, acceleration), or some channels'; by default the
        quantity of its units.
    channels : sequence of str, optional
        New names for the channels, in the file's order (the model's sensors: ``UGB_x``, ...).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = Path(tmp) / "probes.csv"
    ...     rows = [f"{k / 100:.2f},{np.sin(k / 5):.5f},{np.cos(k / 5):.5f}" for k in range(500)]
    ...     _ = path.write_text("time [s],UGB_x [um],HEAD_x [g]\\n" + "\\n".join(rows))
    ...     ds = import_record(path)
    >>> ds["quantity"].values.tolist(), ds.attrs["sampling_rate"]
    (['displacement', 'acceleration'], 100.0)
    """
    path = Path(path)
    if not path.is_file():
        raise SignalError(f"{path}: no such file")
    reader = READERS.get(path.suffix.lower())
    if reader is None:
        raise SignalError(f"{path}: no reader for '{path.suffix}' files (twin reads: {', '.join(sorted(READERS))})")
    table = reader(path)
    n = table.values.shape[1]
    names = list(table.channels) if channels is None else [str(c) for c in channels]
    if len(names) != n:
        raise SignalError(f"{path}: {len(names)} channel names given for {n} channels ({', '.join(table.channels)})")
    given_units = _per_channel(units, table.channels, "units", path)
    given_quantities = _per_channel(quantities, table.channels, "quantities", path)
    unit_list, quantity_list = [], []
    for k, c in enumerate(table.channels):
        u = given_units.get(c) or table.units[k]
        if u is None:
            raise SignalError(
                f"{path}: channel '{c}' has no units: write them in the header ('{c} [um]') or give "
                "them (--units um, or --units UGB_x=um,...)"
            )
        q = given_quantities.get(c) or (table.quantities or [None] * n)[k] or quantity_of(u, f"{path}: channel '{c}'")
        si_factor(u, q, f"{path}: channel '{c}'")  # units of that quantity
        unit_list.append(u)
        quantity_list.append(q)
    if fs_hz is not None and table.fs_hz is not None and abs(float(fs_hz) / table.fs_hz - 1) > 1e-9:
        raise SignalError(f"{path}: the file says {table.fs_hz:g} Hz, --fs {float(fs_hz):g} Hz: which is it?")
    fs = table.fs_hz if fs_hz is None else float(fs_hz)
    if table.time_s is None and fs is None:
        raise SignalError(f"{path}: no time column and no sampling rate: give the rate (--fs HZ)")
    coords = {"channel": names, "quantity": ("channel", quantity_list), "units": ("channel", unit_list)}
    if table.time_s is not None:
        coords["time"] = ("time", table.time_s - table.time_s[0], {"units": "s"})
    attrs = {
        "title": f"record imported from {path.name}",
        "producer": f"twin {__version__} twin.extract.importing",
        "source": str(path),
        **table.attrs,
    }
    if fs is not None:
        attrs["sampling_rate"] = fs
    ds = xr.Dataset({"signal": (("time", "channel"), table.values)}, coords=coords, attrs=attrs)
    rec = check_record(ds, str(path))  # the checks of the extraction: time axis, rate, NaN, flat channels
    ds.attrs["sampling_rate"] = rec.fs_hz
    return ds


def _per_channel(
    value: str | Mapping[str, str] | None, channels: Sequence[str], what: str, path: Path
) -> dict[str, str]:
    if value is None:
        return {}
    if isinstance(value, str):
        return {c: value for c in channels}
    unknown = [c for c in value if c not in channels]
    if unknown:
        raise SignalError(
            f"{path}: {what} for {', '.join(map(repr, unknown))}, which the file has not "
            f"(its channels: {', '.join(channels)})"
        )
    return dict(value)
