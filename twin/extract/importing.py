"""Records from measurement systems into ``signals.nc``: one reader per file format, one record layout.

A reader (:data:`READERS`, by file suffix) returns what its file holds as a
:class:`Table`: the channels' samples, their names and units, a time column or
a sampling rate, where the file has them. :func:`import_record` completes it
with what the caller says (``fs_hz``, ``units``, ``quantities``, ``channels``),
works out each channel's quantity from its units where none is given (µm is a
displacement, mm/s a velocity, g an acceleration), checks the record as the
extraction will (:func:`twin.extract.signals.check_record`) and returns it in
the ``signal`` layout of :mod:`twin.extract.quantities`. Every problem is an
error naming the file, and the row, column or channel.

The readers: CSV and text tables with a header line (``.csv``, ``.txt``,
``.tsv``, ``.dat``).
"""

from __future__ import annotations

import csv
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import xarray as xr

from twin import __version__
from twin.errors import SignalError
from twin.extract.quantities import QUANTITIES, si_factor
from twin.extract.signals import check_record, seconds_per

#: Column names read as the time [s] (case-insensitive, units in the header aside).
TIME_NAMES = ("time", "t", "time_s", "timestamp")
#: A header cell's units: ``name [unit]`` or ``name (unit)``.
_UNITS_IN_HEADER = re.compile(r"^\s*(?P<name>.*?)\s*[\[(](?P<units>[^\])]*)[\])]\s*$")


@dataclass
class Table:
    """What a file holds: samples (time x channel), channel names, their units (None where the file says
    none), the time [s] of each sample or the sampling rate [Hz] (either may be None)."""

    values: np.ndarray
    channels: list[str]
    units: list[str | None]
    time_s: np.ndarray | None = None
    fs_hz: float | None = None
    attrs: dict = field(default_factory=dict)


def read_table(path: Path) -> Table:
    """A CSV or text table: one header line of column names (units as ``name [unit]``), then one row per sample.

    The delimiter is found from the header (comma, semicolon, tab or spaces); lines starting with ``#`` are
    comments, except ``# sampling_rate: 256`` (or ``fs``), which gives the rate [Hz]. A column named as in
    :data:`TIME_NAMES` is the time.
    """
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise SignalError(f"{path}: not a text file (a CSV or text table is UTF-8 text)") from None
    lines = [line for line in text.splitlines() if line.strip()]
    meta = {}
    for line in lines:
        if line.lstrip().startswith("#") and ":" in line:
            key, _, value = line.lstrip("# ").partition(":")
            meta[key.strip().lower()] = value.strip()
    rows = [line for line in lines if not line.lstrip().startswith("#")]
    if len(rows) < 3:
        raise SignalError(f"{path}: a table needs a header line and at least two rows, got {len(rows)} line(s)")
    header = rows[0]
    delimiter = next((d for d in (",", ";", "\t") if d in header), None)
    split = (lambda s: next(csv.reader([s], delimiter=delimiter))) if delimiter else str.split
    names = [c.strip() for c in split(header)]
    if not names or all(_is_number(n) for n in names):
        raise SignalError(f"{path}: the first line must name the columns (e.g. time [s], UGB_x [um], ...), "
                          f"got {header[:60]!r}")  # fmt: skip
    data = np.empty((len(rows) - 1, len(names)))
    for r, row in enumerate(rows[1:], start=2):
        cells = [c.strip() for c in split(row)]
        if len(cells) != len(names):
            raise SignalError(f"{path}: row {r} has {len(cells)} values, the header {len(names)} columns")
        for c, cell in enumerate(cells):
            try:
                data[r - 2, c] = float(cell)
            except ValueError:
                raise SignalError(f"{path}: row {r}, column '{names[c]}': {cell!r} is not a number") from None
    columns, units = [], []
    for n in names:
        m = _UNITS_IN_HEADER.match(n)
        columns.append(m["name"] if m else n)
        units.append(m["units"].strip() if m else None)
    lowered = [c.lower() for c in columns]
    time_col = next((k for k, c in enumerate(lowered) if c in TIME_NAMES), None)
    time_s = None
    if time_col is not None:
        time_s = data[:, time_col] * seconds_per(units[time_col] or "s", f"{path}: the time column's")
    keep = [k for k in range(len(names)) if k != time_col]
    fs = meta.get("sampling_rate", meta.get("fs"))
    try:
        fs_hz = None if fs is None else float(fs.split()[0])
    except ValueError:
        raise SignalError(f"{path}: the comment's sampling rate {fs!r} is not a number of Hz") from None
    return Table(data[:, keep], [columns[k] for k in keep], [units[k] for k in keep], time_s, fs_hz)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


#: The readers by file suffix: each takes the path and returns a :class:`Table`.
READERS: dict[str, Callable[[Path], Table]] = {".csv": read_table, ".txt": read_table, ".tsv": read_table,
                                               ".dat": read_table}  # fmt: skip


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
            raise SignalError(f"{path}: channel '{c}' has no units: write them in the header ('{c} [um]') or give "
                              "them (--units um, or --units UGB_x=um,...)")  # fmt: skip
        q = given_quantities.get(c) or quantity_of(u, f"{path}: channel '{c}'")
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
    attrs = {"title": f"record imported from {path.name}", "producer": f"twin {__version__} twin.extract.importing",
             "source": str(path), **table.attrs}  # fmt: skip
    if fs is not None:
        attrs["sampling_rate"] = fs
    ds = xr.Dataset({"signal": (("time", "channel"), table.values)}, coords=coords, attrs=attrs)
    rec = check_record(ds, str(path))  # the checks of the extraction: time axis, rate, NaN, flat channels
    ds.attrs["sampling_rate"] = rec.fs_hz
    return ds


def _per_channel(value: str | Mapping[str, str] | None, channels: Sequence[str], what: str,
                 path: Path) -> dict[str, str]:  # fmt: skip
    if value is None:
        return {}
    if isinstance(value, str):
        return {c: value for c in channels}
    unknown = [c for c in value if c not in channels]
    if unknown:
        raise SignalError(f"{path}: {what} for {', '.join(map(repr, unknown))}, which the file has not "
                          f"(its channels: {', '.join(channels)})")  # fmt: skip
    return dict(value)
