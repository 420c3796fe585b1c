"""A folder of records as a tracker sees it: start times, operating data, and modes extracted once.

Every ``*.nc`` in the folder is a record (a signals file, :mod:`twin.extract.signals`) that carries its
start time (attr ``start_time``, ISO 8601) and its operating data (``operating_point`` over
``condition``, with ``condition_units``; attrs named after the conditions are read too). Operating data
in other units than the model's (kW against MW, degF against degC) are converted with pint. Each record's
modes are extracted once into the tracker's cache folder (``<stem>.nc``), so a folder that grows is
processed incrementally: only the records added since the last call are extracted. A cache file keeps
what it was made from (the record's size, modification time and SHA-256, and the extraction's options):
a record replaced or edited since, or other options, make it stale and the record is extracted again,
so a cache never answers for data it was not made from.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import itertools
import logging
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from twin.errors import NoModeError, SignalError, TwinError, TwinWarning
from twin.extract.options import ExtractOptions
from twin.fem.operation import Operation
from twin.netcdf import check_folder, global_attrs, load_netcdf, write_netcdf
from twin.tasks import mapper

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RecordInfo:
    """What the tracker knows of a record before its modes: file, start time (UTC), operating point."""

    path: Path
    start: dt.datetime
    point: dict[str, float]
    model: str | None = None  # the machine the record says it is of (a simulated record's ``model`` attr)
    speed_rpm: float | None = None  # the running speed it says it was taken at


def parse_time(text: str, where: str) -> dt.datetime:
    """An ISO 8601 time with its zone, in UTC; a :class:`~twin.errors.SignalError` naming ``where`` otherwise.

    Examples
    --------
    >>> parse_time("2027-01-01T06:00:00Z", "r.nc").isoformat()
    '2027-01-01T06:00:00+00:00'
    """
    try:
        value = dt.datetime.fromisoformat(str(text))
    except ValueError:
        raise SignalError(f"{where}: start_time {text!r} is not an ISO 8601 time (e.g. 2027-01-01T06:00:00Z)") from None
    if value.tzinfo is None:
        raise SignalError(
            f"{where}: start_time {text!r} has no time zone (records are compared in UTC: add Z or +01:00)"
        )
    return value.astimezone(dt.UTC)


def record_info(path: Path, operation: Operation) -> RecordInfo:
    """Start time and operating point of the record at ``path``, in the model's units, checked."""
    import pint

    from twin.units import conversion

    try:
        with xr.open_dataset(path) as ds:
            attrs = dict(ds.attrs)
            if "operating_point" in ds and "condition" in ds["operating_point"].dims:
                names = [str(c) for c in ds["condition"].values]
                units = (
                    [str(u) for u in ds["condition_units"].values]
                    if "condition_units" in ds.coords
                    else [operation.units.get(n, "") for n in names]
                )
                given = {n: (float(v), u) for n, v, u in zip(names, ds["operating_point"].values, units)}
            else:
                given = {n: (attrs[n], operation.condition(n).units) for n in operation.names if n in attrs}
    except (OSError, ValueError) as exc:
        raise SignalError(f"{path}: cannot be read as a record ({exc})") from None
    if "start_time" not in attrs:
        raise SignalError(f"{path}: no start_time attr: a tracked record says when it started (ISO 8601, UTC)")
    start = parse_time(attrs["start_time"], str(path))
    point = {}
    for name in operation.names:
        if name not in given:
            raise SignalError(
                f"{path}: no operating data for '{name}' (the model's conditions: "
                f"{', '.join(operation.names)}; give operating_point over condition)"
            )
        value, units = given[name]
        want = operation.condition(name).units
        try:
            point[name] = float(value) if units in ("", want) else conversion(float(value), units, want)
        except (pint.errors.PintError, ValueError, TypeError, AttributeError, AssertionError) as exc:
            raise SignalError(
                f"{path}: operating data '{name}' in {units!r} cannot be read as {want} ({type(exc).__name__})"
            ) from None
    try:
        point = operation.check_point(point, str(path))
    except TwinError as exc:
        raise SignalError(str(exc)) from None
    speed = attrs.get("speed_rpm")
    try:
        speed = float(speed) if speed is not None else None
    except (TypeError, ValueError):
        speed = None
    model = str(attrs["model"]) if "model" in attrs else None
    return RecordInfo(Path(path), start, point, model, speed)


def check_machine(records: Sequence[RecordInfo], model_name: str, speed_rpm: float) -> None:
    """Warn when records say they are of another machine, or were taken at another running speed, than the model
    they are tracked with: their modes then differ from the model's for a reason no change explains.

    Examples
    --------
    >>> import warnings
    >>> r = RecordInfo(Path("r.nc"), dt.datetime(2027, 1, 1, tzinfo=dt.UTC), {}, "pelton_unit", 600.0)
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     check_machine([r], "hydro_unit", 134.0)
    >>> print(w[0].message)
    1 of 1 records say they are of pelton_unit (r.nc), not of hydro_unit, which tracks them
    >>> print(w[1].message)
    1 of 1 records were taken at 600 rpm (r.nc), not at hydro_unit's 134 rpm: their modes differ for that reason alone
    """
    other = [r for r in records if r.model is not None and r.model != model_name]
    if other:
        names = ", ".join(sorted({str(r.model) for r in other}))
        warnings.warn(
            f"{len(other)} of {len(records)} records say they are of {names} ({other[0].path.name}"
            f"{' ...' if len(other) > 1 else ''}), not of {model_name}, which tracks them",
            TwinWarning,
            stacklevel=2,
        )
    tolerance = 1e-6 * max(abs(speed_rpm), 1.0)
    off = [r for r in records if r.speed_rpm is not None and abs(r.speed_rpm - speed_rpm) > tolerance]
    if off:
        speeds = ", ".join(f"{v:g}" for v in sorted({float(r.speed_rpm) for r in off}))  # type: ignore[arg-type]
        warnings.warn(
            f"{len(off)} of {len(records)} records were taken at {speeds} rpm ({off[0].path.name}"
            f"{' ...' if len(off) > 1 else ''}), not at {model_name}'s {speed_rpm:g} rpm: their modes differ for "
            "that reason alone",
            TwinWarning,
            stacklevel=2,
        )


def records_in(
    folder: str | Path, operation: Operation, set_aside: list[tuple[str, str]] | None = None
) -> list[RecordInfo]:
    """The records of ``folder`` (``*.nc``), in order of their start times.

    Raises :class:`~twin.errors.TwinError` for a missing folder or one without a usable record. A record that
    cannot be used (unreadable, without a start time or operating data, operating data out of the model's
    ranges, or starting at the same time as another) raises a :class:`~twin.errors.SignalError` naming the
    file, or, when a list ``set_aside`` is given, is left out and listed there as ``(file name, reason)``.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise TwinError(f"{folder}: no such folder of records")
    infos = []
    for path in sorted(folder.glob("*.nc")):
        try:
            infos.append(record_info(path, operation))
        except SignalError as exc:
            if set_aside is None:
                raise
            set_aside.append((path.name, str(exc)))
    infos.sort(key=lambda r: r.start)
    kept = infos[:1]
    for a, b in itertools.pairwise(infos):
        if a.start == b.start:
            reason = f"{b.path}: starts at the same time as {a.path.name} ({a.start.isoformat()})"
            if set_aside is None:
                raise SignalError(reason)
            set_aside.append((b.path.name, reason))
        else:
            kept.append(b)
    if not kept:
        aside = f" ({len(set_aside)} set aside, the first: {set_aside[0][1]})" if set_aside else ""
        raise TwinError(f"{folder}: no usable record (*.nc) in it{aside}")
    return kept


def digest(path: Path) -> str:
    """SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def stamp(path: Path) -> str:
    """A file's size and modification time: a change of either means the file may have changed."""
    st = path.stat()
    return f"{st.st_size}:{st.st_mtime_ns}"


def is_fresh(target: Path, record: Path, options: ExtractOptions | Mapping[str, Any] | None = None) -> bool:
    """Whether the cache file ``target`` holds the modes of ``record`` as it is now, extracted with ``options``
    (:class:`twin.extract.options.ExtractOptions`: its :meth:`~twin.extract.options.ExtractOptions.key`).

    The record's bytes decide (their SHA-256), not its size and modification time: a record edited in place
    with its stamp restored is extracted again, and one copied or touched is not (hashing a 10-minute
    record takes a few hundredths of a second).
    """
    if not target.exists():
        return False
    try:
        attrs = global_attrs(target)
        made = {k: str(attrs.get(k, "")) for k in ("record_sha256", "extract_settings")}
    except (OSError, ValueError):
        return False  # a damaged cache file is made again
    if made["extract_settings"] != ExtractOptions.of(options).key():
        return False
    return made["record_sha256"] == digest(record)


def provenance(record: Path, options: ExtractOptions | Mapping[str, Any] | None = None) -> dict[str, str]:
    """What a cache file of ``record``'s modes records of its source (:func:`is_fresh` reads it back)."""
    return {
        "record_stamp": stamp(record),
        "record_sha256": digest(record),
        "extract_settings": ExtractOptions.of(options).key(),
    }


def adopt(target: str | Path, record: str | Path, options: ExtractOptions | Mapping[str, Any] | None = None) -> None:
    """Mark the cache file ``target`` as the modes of ``record``: for modes extracted from the same signals
    elsewhere (records copied into another folder with other attrs). The caller vouches for the signals."""
    with xr.open_dataset(target) as ds:
        ds = ds.load()
    ds.attrs.update(provenance(Path(record), options))
    write_netcdf(ds, target)


def _extract_one(path: str, *, cache: str, options: ExtractOptions, strict: bool = True) -> str:
    from twin.extract import extract
    from twin.modes.modesfile import write_modes

    source = Path(path)
    target = Path(cache) / (source.stem + ".nc")
    made = provenance(source, options)
    try:
        with warnings.catch_warnings(record=True) as caught:  # one record's notes, logged: not one line per record
            warnings.simplefilter("always", TwinWarning)
            modes = extract(path, options, progress=False)
        for w in caught:
            log.info("%s", w.message)
    except NoModeError as exc:  # a record without any mode is a fact to keep, not a reason to stop
        write_netcdf(xr.Dataset(attrs={"no_mode": str(exc), "signals": str(path), **made}), target)
        return str(target)
    except SignalError as exc:  # NaNs, a dead channel...: set aside with the reason, unless strict
        if strict:
            raise
        write_netcdf(xr.Dataset(attrs={"unusable": str(exc), "signals": str(path), **made}), target)
        return str(target)
    modes.attrs.update(made)
    write_modes(modes, target)
    return str(target)


def extract_new(
    records: list[RecordInfo],
    cache: str | Path,
    *,
    options: ExtractOptions | Mapping[str, Any] | None = None,
    tasks: Any = None,
    progress: bool = True,
    strict: bool = True,
) -> list[Path]:
    """Extract the modes of the records not yet in ``cache``; the cache files of all records, in order.

    ``options`` are :func:`twin.extract.extract`'s (:class:`~twin.extract.options.ExtractOptions` or a mapping of
    its fields; the defaults without), checked before any record is read. The records are
    independent tasks (``tasks``, :func:`twin.tasks.mapper`). A record in which no mode stands out is kept
    as such (a cache file with a ``no_mode`` attr) and not analysed again; unless ``strict``, so is a record the
    extraction cannot use (an ``unusable`` attr with the reason, :class:`UnusableRecord` from :func:`read_cached`). A cache file that is not the
    record's as it is now (:func:`is_fresh`) is made again.
    """
    cache = check_folder(cache, make=True)
    options = ExtractOptions.of(options)
    targets = [cache / (r.path.stem + ".nc") for r in records]
    todo = [str(r.path) for r, t in zip(records, targets) if not is_fresh(t, r.path, options)]
    if todo:
        log.info("extracting the modes of %d new or changed records (of %d)", len(todo), len(records))
        mapper(tasks, progress=progress, desc="extract")(
            _extract_one, todo, cache=str(cache), options=options, strict=strict
        )
    return targets


class UnusableRecord(SignalError):
    """A record's cache file says the extraction could not use the record (the message says why)."""


def read_cached(path: Path) -> xr.Dataset | None:
    """A record's cached modes (None for a record without any mode); :class:`UnusableRecord` with the reason for
    a record the extraction could not use."""
    from twin.modes.modesfile import modes_from

    ds = load_netcdf(path, "modes", SignalError)
    if "unusable" in ds.attrs:
        raise UnusableRecord(str(ds.attrs["unusable"]))
    return None if "no_mode" in ds.attrs else modes_from(ds, path)


#: A gap in the records: more time between two of them than this many times the baseline's median interval.
GAP_INTERVALS = 4.0


def gaps_before(days: np.ndarray, n_base: int) -> tuple[np.ndarray, float]:
    """The time without records before each record [d], where it is a gap (0 elsewhere), and the gap's threshold.

    A gap is an interval longer than :data:`GAP_INTERVALS` times the median interval between the
    baseline's ``n_base`` first records (the cadence the chart's limit is set for): an outage, a
    logger down, a unit at standstill. The chart goes on across it, so a change that happened during
    the gap shows as a step at the first record after it.

    Examples
    --------
    >>> gap, threshold = gaps_before(np.array([0.0, 0.25, 0.5, 0.75, 1.0, 3.0, 3.25]), 5)
    >>> gap.tolist(), threshold
    ([0.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0], 1.0)
    """
    days = np.asarray(days, dtype=float)
    step = np.diff(days)
    base = step[: max(n_base - 1, 0)]
    threshold = GAP_INTERVALS * float(np.median(base)) if base.size and np.median(base) > 0 else np.inf
    gap = np.zeros(len(days))
    if len(days) > 1:
        gap[1:] = np.where(step > threshold, step, 0.0)
    return gap, threshold
