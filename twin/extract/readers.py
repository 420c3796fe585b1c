"""Readers of measurement files: each returns what its file holds as one :class:`Table`.

One reader per file format, chosen by suffix (:data:`READERS`); what a reader
cannot find in its file (units, a sampling rate) it leaves as None for
:func:`twin.extract.importing.import_record` to take from the caller.

========================  ======================================================
suffix                    reader
========================  ======================================================
.csv .txt .tsv .dat       :func:`read_table`: a header line, one row per sample
.uff .unv                 :func:`read_uff`: Universal File Format dataset 58
                          (time responses, read with pyuff)
.tdms                     :func:`read_tdms`: NI TDMS (read with npTDMS)
.mat                      :func:`read_mat`: MATLAB (v4 to v7 with scipy, v7.3
                          with h5py)
.h5 .hdf5 .hdf            :func:`read_hdf5`: HDF5 (h5py)
========================  ======================================================

MATLAB and HDF5 files have no standard layout for a record; their readers take
what such files usually hold (:func:`table_of_arrays`): a 2-D array of samples
(``data``, ``signals``, ...) or one 1-D array per channel, a time array
(``time``, ``t``) or a sampling rate (``fs``, ``sampling_rate``), and channel
names and units as string arrays or attributes.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from twin.errors import SignalError
from twin.extract.signals import seconds_per

#: Column or array names read as the time [s] (case-insensitive, units in the header aside).
TIME_NAMES = ("time", "t", "time_s", "timestamp")
#: Names read as the sampling rate [Hz] (case-insensitive): a comment, a scalar variable or an attribute.
RATE_NAMES = ("sampling_rate", "fs", "fs_hz", "sample_rate", "sampling_frequency", "rate")
#: Names of a 2-D array of samples in a MATLAB or HDF5 file (case-insensitive).
DATA_NAMES = ("data", "signals", "signal", "samples", "y", "displacement", "values")
#: Names of the channel names and of their units in a MATLAB or HDF5 file.
CHANNEL_NAMES, UNIT_NAMES = ("channels", "channel_names", "names", "labels"), ("units", "unit")
#: A header cell's units: ``name [unit]`` or ``name (unit)``.
_UNITS_IN_HEADER = re.compile(r"^\s*(?P<name>.*?)\s*[\[(](?P<units>[^\])]*)[\])]\s*$")
#: UFF dataset 58 ``ordinate_spec_data_type`` codes of the quantities the extraction reads.
UFF_QUANTITIES = {8: "displacement", 11: "velocity", 12: "acceleration"}


@dataclass
class Table:
    """What a file holds: samples (time x channel), channel names, their units and quantities (None where the
    file says none), the time [s] of each sample or the sampling rate [Hz] (either may be None), and
    attributes to keep (``start_time``, ISO 8601, where the file has one)."""

    values: np.ndarray
    channels: list[str]
    units: list[str | None]
    time_s: np.ndarray | None = None
    fs_hz: float | None = None
    attrs: dict = field(default_factory=dict)
    quantities: list[str | None] | None = None


def read_table(path: Path) -> Table:
    """A CSV or text table: one header line of column names (units as ``name [unit]``), then one row per sample.

    The delimiter is found from the header (comma, semicolon, tab or spaces); lines starting with ``#`` are
    comments, except ``# sampling_rate: 256`` (or another of :data:`RATE_NAMES`), which gives the rate [Hz],
    and ``# start_time: 2026-05-01T06:00:00Z``. A column named as in :data:`TIME_NAMES` is the time.
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
        raise SignalError(
            f"{path}: the first line must name the columns (e.g. time [s], UGB_x [um], ...), got {header[:60]!r}"
        )
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
    fs = next((meta[k] for k in RATE_NAMES if k in meta), None)
    attrs = {"start_time": meta["start_time"]} if "start_time" in meta else {}
    return Table(
        data[:, keep],
        [columns[k] for k in keep],
        [units[k] for k in keep],
        time_s,
        _rate(fs.split()[0] if fs else None, f"{path}: the comment's sampling rate"),
        attrs,
    )


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _rate(value, where: str) -> float | None:
    """A sampling rate [Hz] as read from a file, checked to be a positive number."""
    if value is None:
        return None
    try:
        fs = float(np.asarray(value).squeeze())
    except (TypeError, ValueError):
        raise SignalError(f"{where} {value!r} is not a number of Hz") from None
    if not np.isfinite(fs) or fs <= 0:
        raise SignalError(f"{where} is {fs:g} Hz: a sampling rate is a positive number")
    return fs


def _module(name: str, path: Path, what: str):
    """Import the library a reader needs, or say how to install it."""
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError:
        package = {"nptdms": "npTDMS"}.get(name, name)
        raise SignalError(
            f"{path}: reading {what} files needs {package}: pip install {package} (or pip install 'twin[formats]')"
        ) from None


def _no_label(text) -> str | None:
    text = str(text).strip() if text is not None else ""
    return None if text.upper() in ("", "NONE") else text


def read_uff(path: Path) -> Table:
    """The time responses (dataset 58, function type 1) of a Universal File: one channel per response.

    A channel is named by its ``rsp_ent_name`` where one is set, else by its node and direction (``12+Z``);
    its units are the ordinate's units label, its quantity its ordinate data type (8 displacement,
    11 velocity, 12 acceleration); the sampling rate is ``1 / abscissa_inc``.
    """
    pyuff = _module("pyuff", path, "UFF")
    try:
        sets = pyuff.UFF(str(path)).read_sets()
    except Exception as exc:  # noqa: BLE001 (pyuff raises what its parser meets; say which file)
        raise SignalError(f"{path}: not a readable Universal File ({exc})") from None
    sets = [sets] if isinstance(sets, dict) else list(sets)
    responses = [s for s in sets if s.get("type") == 58 and s.get("func_type") == 1]
    if not responses:
        types = sorted({f"{s.get('type')}" + (f"/{s['func_type']}" if "func_type" in s else "") for s in sets})
        raise SignalError(
            f"{path}: no time response (dataset 58, function type 1) among its datasets ({', '.join(types) or 'none'})"
        )
    names, units, quantities, columns = [], [], [], []
    _dir = {1: "+X", 2: "+Y", 3: "+Z", -1: "-X", -2: "-Y", -3: "-Z"}
    for k, s in enumerate(responses):
        name = _no_label(s.get("rsp_ent_name")) or f"{s.get('rsp_node', k + 1)}{_dir.get(s.get('rsp_dir'), '')}"
        if name in names:
            name = f"{name}_{k + 1}"
        names.append(name)
        units.append(_no_label(s.get("ordinate_axis_units_lab")))
        quantities.append(UFF_QUANTITIES.get(int(s.get("ordinate_spec_data_type", 0) or 0)))
        columns.append(np.real(np.asarray(s["data"], dtype=complex)))
    incs = {float(s["abscissa_inc"]) for s in responses}
    lengths = {len(c) for c in columns}
    if len(lengths) > 1 or len(incs) > 1:
        raise SignalError(
            f"{path}: its time responses differ in length ({sorted(lengths)} samples) or in "
            f"step ({sorted(incs)} s): one record has one time axis"
        )
    step = incs.pop()
    attrs = {"start_time": _no_label(responses[0].get("id4"))} if _no_label(responses[0].get("id4")) else {}
    return Table(
        np.column_stack(columns),
        names,
        units,
        None,
        _rate(1 / step if step > 0 else 0, f"{path}: the abscissa step's rate"),
        attrs,
        quantities,
    )


def read_tdms(path: Path) -> Table:
    """The channels of a TDMS file (all groups; a channel is named ``group/channel`` where names repeat).

    The units are a channel's ``unit_string`` (or ``NI_UnitDescription``) property, the rate ``1 /
    wf_increment``, the start time ``wf_start_time``.
    """
    nptdms = _module("nptdms", path, "TDMS")
    try:
        tdms = nptdms.TdmsFile.read(str(path))
    except Exception as exc:  # noqa: BLE001 (npTDMS raises what its parser meets; say which file)
        raise SignalError(f"{path}: not a readable TDMS file ({exc})") from None
    chans = [(g.name, c) for g in tdms.groups() for c in g.channels() if len(c) > 0]
    if not chans:
        raise SignalError(f"{path}: no channel with data")
    short = [c.name for _, c in chans]
    names = [c.name if short.count(c.name) == 1 else f"{g}/{c.name}" for g, c in chans]
    lengths = {len(c) for _, c in chans}
    if len(lengths) > 1:
        raise SignalError(
            f"{path}: its channels differ in length ({sorted(lengths)} samples): one record has one time axis"
        )
    props = [c.properties for _, c in chans]
    units = [_no_label(p.get("unit_string", p.get("NI_UnitDescription"))) for p in props]
    incs = {float(p["wf_increment"]) for p in props if "wf_increment" in p}
    if len(incs) > 1:
        raise SignalError(f"{path}: its channels have different steps (wf_increment {sorted(incs)} s)")
    fs = _rate(1 / incs.pop(), f"{path}: wf_increment's rate") if incs else None
    start = props[0].get("wf_start_time")
    attrs = {"start_time": str(np.datetime64(start, "ms")) + "Z"} if start is not None else {}
    values = np.column_stack([np.asarray(c[:], dtype=float) for _, c in chans])
    return Table(values, names, units, None, fs, attrs)


def read_mat(path: Path) -> Table:
    """A MATLAB file (:func:`table_of_arrays` says which variables are read); v7.3 files are HDF5."""
    from scipy.io import loadmat

    try:
        content = loadmat(str(path), squeeze_me=True, chars_as_strings=True)
    except NotImplementedError:  # v7.3: HDF5 inside, arrays stored transposed
        return read_hdf5(path, transposed=True)
    except Exception as exc:  # noqa: BLE001 (scipy raises what its parser meets; say which file)
        raise SignalError(f"{path}: not a readable MATLAB file ({exc})") from None
    arrays = {k: v for k, v in content.items() if not k.startswith("__")}
    return table_of_arrays(arrays, {}, path)


def read_hdf5(path: Path, transposed: bool = False) -> Table:
    """An HDF5 file: its datasets (named by their last path part) and the root's attributes, read by
    :func:`table_of_arrays`; a dataset's ``units`` attribute gives its channel's units."""
    h5py = _module("h5py", path, "HDF5")
    arrays, attrs, units = {}, {}, {}
    try:
        with h5py.File(path, "r") as f:
            attrs = {k: _text(v) for k, v in f.attrs.items()}

            def visit(group):  # in the file's order: creation order where the file tracks it, else by name
                for key, obj in group.items():
                    if isinstance(obj, h5py.Group):
                        visit(obj)
                        continue
                    value = obj[()]
                    arrays[key] = value.T if transposed and np.ndim(value) == 2 else value
                    for k, v in obj.attrs.items():
                        if k.lower() in UNIT_NAMES:
                            units[key] = _text(v)
                        elif k.lower() in RATE_NAMES + CHANNEL_NAMES + ("start_time",):
                            attrs.setdefault(k, _text(v))

            visit(f)
    except OSError as exc:
        raise SignalError(f"{path}: not a readable HDF5 file ({exc})") from None
    if transposed:  # MATLAB v7.3 strings are uint16 arrays: leave them to the caller's options
        arrays = {k: v for k, v in arrays.items() if not (np.ndim(v) == 2 and v.dtype == np.uint16)}
    return table_of_arrays(arrays, attrs, path, units)


def _text(value):
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, np.ndarray) and value.dtype.kind in "SOU":
        return [_text(v) for v in value.ravel()]
    return value


def table_of_arrays(
    arrays: Mapping[str, object], attrs: Mapping[str, object], path: Path, units_of: Mapping[str, str] | None = None
) -> Table:
    """A record from named arrays and attributes (a MATLAB or HDF5 file).

    The samples are the 2-D array named as in :data:`DATA_NAMES` (or the only 2-D numeric array), with time
    along the axis that matches the time array (else the longer one); without one, every 1-D numeric array
    of one length is a channel, named by its variable. The time is an array named in :data:`TIME_NAMES`,
    the rate a scalar or attribute named in :data:`RATE_NAMES`; channel names and units are string arrays
    or attributes named in :data:`CHANNEL_NAMES` and :data:`UNIT_NAMES` (one string for every channel).
    """
    lower = {k.lower(): k for k in arrays}
    meta = {k.lower(): v for k, v in attrs.items()}

    def lookup(names):
        for n in names:
            if n in lower:
                return arrays[lower[n]]
            if n in meta:
                return meta[n]
        return None

    def numeric(v):
        return isinstance(v, np.ndarray) and v.dtype.kind in "fiu" and v.size > 1

    time = lookup(TIME_NAMES)
    time_s = None if time is None else np.asarray(time, dtype=float).ravel()
    skip = {lower[n] for n in TIME_NAMES + RATE_NAMES + CHANNEL_NAMES + UNIT_NAMES if n in lower}
    two_d = {k: v for k, v in arrays.items() if numeric(v) and v.ndim == 2 and k not in skip}
    data_key = next((lower[n] for n in DATA_NAMES if n in lower and lower[n] in two_d), None)
    if data_key is None and len(two_d) == 1:
        data_key = next(iter(two_d))
    if data_key is None and len(two_d) > 1:
        raise SignalError(
            f"{path}: several 2-D arrays ({', '.join(sorted(two_d))}) and none named "
            f"{' or '.join(DATA_NAMES[:3])}: which holds the samples?"
        )
    if data_key is not None:
        values = np.asarray(two_d[data_key], dtype=float)
        n_t = len(time_s) if time_s is not None else max(values.shape)
        if values.shape[0] != n_t and values.shape[1] == n_t:
            values = values.T
        names = lookup(CHANNEL_NAMES)
        names = [f"{data_key}_{k + 1}" for k in range(values.shape[1])] if names is None else _strings(names)
        given = lookup(UNIT_NAMES)
        units = (
            [(units_of or {}).get(data_key)] * values.shape[1]
            if given is None
            else _every_channel(_strings(given), values.shape[1])
        )
    else:
        one_d = {
            k: np.asarray(v, dtype=float).ravel()
            for k, v in arrays.items()
            if numeric(v) and np.squeeze(v).ndim == 1 and k not in skip
        }
        if not one_d:
            raise SignalError(
                f"{path}: no array of samples (a 2-D array such as 'data', or one 1-D array per "
                f"channel) among its variables ({', '.join(sorted(arrays)) or 'none'})"
            )
        lengths = {len(v) for v in one_d.values()}
        if len(lengths) > 1:
            raise SignalError(
                f"{path}: its 1-D arrays differ in length ("
                + ", ".join(f"{k}: {len(v)}" for k, v in one_d.items())
                + "): one record has one time axis"
            )
        names = list(one_d)
        values = np.column_stack(list(one_d.values()))
        units = [(units_of or {}).get(k) for k in names]
        common = lookup(UNIT_NAMES)
        if common is not None and not any(units):
            units = _every_channel(_strings(common), len(names))
    if len(names) != values.shape[1] or len(units) != values.shape[1]:
        raise SignalError(f"{path}: {values.shape[1]} channels but {len(names)} channel names and {len(units)} units")
    start = lookup(("start_time",))
    return Table(
        values,
        [str(n) for n in names],
        [_no_label(u) for u in units],
        time_s,
        _rate(lookup(RATE_NAMES), f"{path}: its sampling rate"),
        {"start_time": str(_strings(start)[0])} if start is not None else {},
    )


def _every_channel(strings: list[str], n: int) -> list[str]:
    """One string for every one of ``n`` channels: a single one repeated, else as given."""
    return strings * n if len(strings) == 1 else strings


def _strings(value) -> list[str]:
    value = _text(value)
    if isinstance(value, str):
        return [value]
    return [str(_text(v)).strip() for v in np.asarray(value, dtype=object).ravel()]


#: The readers by file suffix: each takes the path and returns a :class:`Table`.
READERS: dict[str, Callable[[Path], Table]] = {
    ".csv": read_table,
    ".txt": read_table,
    ".tsv": read_table,
    ".dat": read_table,
    ".uff": read_uff,
    ".unv": read_uff,
    ".tdms": read_tdms,
    ".mat": read_mat,
    ".h5": read_hdf5,
    ".hdf5": read_hdf5,
    ".hdf": read_hdf5,
}
