"""Campaigns: a sequence of records of a unit through its FMU, under changing operation and hidden changes.

:func:`campaign` simulates what a monitoring system would collect over days or years: a record every
few hours, each at its operating point (:mod:`twin.track.profile`), the model's laws applied
(:func:`twin.fem.operation.at_operating_point`), and any hidden changes of the schedule at their size on
that day (:class:`twin.track.schedule.Change`). Each record is one ``record_<index>.nc``, a signals file
as :func:`twin.fmu.simulate.simulate` writes it, with

* ``start_time`` (ISO 8601, UTC), ``day`` (days after the first record) and ``record`` in its attrs;
* the operating data: ``operating_point`` over ``condition`` (coordinate ``condition_units``);
* ``schedule`` and ``truth`` (the changes in effect, at their size then) in its attrs, for tests and
  benchmarks: a tracker never reads them.

The records are independent tasks (Dask over records with ``tasks=``); a campaign is resumable and
extendable: a record already in the folder is kept, so the same schedule with more days simulates only
the days added (record ``i`` does not depend on the span: :meth:`twin.track.schedule.Schedule.record_terms`),
and a folder holding another campaign's records is refused, saying what differs.
"""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from twin.defaults import NOISE_RATIO
from twin.errors import ModelError, TwinError
from twin.fem.effects import effect_label, scaled
from twin.fem.model import RotorModel
from twin.fem.operation import at_operating_point, operation_of, with_change
from twin.fem.truthfile import Truth
from twin.netcdf import check_folder, global_attrs, one_writer, write_netcdf
from twin.tasks import mapper
from twin.track.profile import operating_points
from twin.track.schedule import Schedule, iso, record_terms

log = logging.getLogger(__name__)

#: File name of record ``i`` in a campaign folder.
RECORD_NAME = "record_{:05d}.nc"
#: Seeds of the FMU's random streams are 32-bit: record seeds stay below this.
SEED_LIMIT = 2**31 - 10_000


def record_seed(seed: int, index: int) -> int:
    """The turbulence seed of record ``index`` of the campaign seeded ``seed`` (its noise seed follows)."""
    return int((int(seed) * 100_003 + index) % SEED_LIMIT)


def record_model(
    model: RotorModel, point: dict[str, float], schedule: Schedule, day: float
) -> tuple[RotorModel, Truth]:
    """The unit of record ``day``: the model at its operating point with the changes in effect that day.

    Returns the model and the changes in effect (each at its size that day), as a :class:`Truth`.
    """
    m = at_operating_point(model, point)
    active = []
    for change in schedule.changes:
        fraction = change.fraction(day)
        if fraction > 0:
            for effect in change.truth.effects:
                active.append(scaled(effect, fraction))
                m = with_change(m, active[-1])
    return m, Truth(tuple(active), schedule.source)


def campaign_id(model: RotorModel, schedule: Schedule, seed: int, *, span: bool = False) -> str:
    """A digest of what makes a campaign's records: the model's file, the schedule but its span and file name
    (:meth:`~twin.track.schedule.Schedule.record_terms`) and the seed.

    ``span=True`` gives the digest of the whole schedule (its days and file name too), which the records of
    folders made before campaigns were extendable carry: such a folder is still resumed with its schedule.
    """
    text = Path(model.source).read_text() if model.source and Path(model.source).is_file() else repr(model)
    terms = schedule.to_json() if span else json.dumps(schedule.record_terms(), sort_keys=True)
    return hashlib.sha256(f"{text}\n{terms}\n{seed}".encode()).hexdigest()[:16]


def campaign(
    model: RotorModel,
    schedule: Schedule,
    out: str | Path,
    *,
    seed: int = 1,
    noise_ratio: float = NOISE_RATIO,
    tasks: Any = None,
    progress: bool = True,
    command: str = "",
) -> xr.Dataset:
    """Simulate a campaign's records into ``out`` (one ``record_<index>.nc`` each), keeping those already there.

    Parameters
    ----------
    model : RotorModel
        A model with operating conditions (``[[condition]]`` and ``[[law]]`` tables).
    schedule : Schedule
        From :func:`twin.track.schedule.read_schedule`.
    out : path
        The campaign folder (made if missing).
    seed : int
        Seed of the operation's dispatch and of every record's turbulence and noise.
    noise_ratio : float
        Sensor noise std as a fraction of the median channel RMS of the turbulence response at the
        reference operating point, the same for every record (the sensors do not change).
    tasks : distributed.Client or mapper, optional
        Where the records are simulated (:func:`twin.tasks.mapper`): here by default.
    progress : bool
        A progress bar over the records.

    Returns
    -------
    xarray.Dataset
        Over ``record``: ``start_time`` (ISO 8601), ``day``, ``operating_point`` (record, condition),
        ``file``, ``made`` (False for a record that was there already).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from twin.track.schedule import read_schedule
    >>> unit = hydro_unit
    >>> with tempfile.TemporaryDirectory() as d:  # doctest: +SKIP
    ...     p = pathlib.Path(d) / "s.toml"; _ = p.write_text("days = 1\\nrecords_per_day = 2\\nduration = 60.0\\n")
    ...     table = campaign(unit, read_schedule(p, unit), pathlib.Path(d) / "records", progress=False)
    ...     int(table.made.sum())
    2
    """
    op = operation_of(model)
    for change in schedule.changes:  # a change the model cannot take fails before any work
        record_model(model, op.reference_point(), Schedule(1, 1, 1.0, changes=(change,)), change.start_day + 1e9)
    out = check_folder(out, make=True)
    ident = campaign_id(model, schedule, seed)
    idents = (ident, campaign_id(model, schedule, seed, span=True))
    days = np.array([schedule.record_day(i) for i in range(schedule.n_records)])
    start = schedule.start
    year_day0 = (
        start - start.replace(month=1, day=1, hour=0, minute=0, second=0, microsecond=0)
    ).total_seconds() / 86400.0
    points = operating_points(schedule.variations, op, days, year_day0, seed)
    this = {"model": model.name, "schedule": schedule.to_json(), "campaign_seed": int(seed)}
    todo = [i for i in range(schedule.n_records) if not _kept(out / RECORD_NAME.format(i), idents, this)]
    noise_std_m = _noise_std(model, schedule.fs_hz, noise_ratio)
    log.info("campaign %s: %d records, %d to simulate", ident, schedule.n_records, len(todo))
    with one_writer(out, "twin campaign"):  # one campaign per folder; what a killed one left is cleaned
        mapper(tasks, progress=progress, desc="records")(
            _simulate_record,
            todo,
            model=model,
            schedule=schedule,
            points=points,
            seed=seed,
            noise_std_m=noise_std_m,
            out=str(out),
            ident=ident,
            command=command,
        )
    return xr.Dataset(
        {
            "start_time": ("record", [iso(schedule.record_start(i)) for i in range(schedule.n_records)]),
            "day": ("record", days, {"units": "d", "long_name": "days after the first record's start"}),
            "operating_point": (("record", "condition"), points),
            "file": ("record", [RECORD_NAME.format(i) for i in range(schedule.n_records)]),
            "made": ("record", np.isin(np.arange(schedule.n_records), todo)),
        },
        coords={
            "record": np.arange(schedule.n_records),
            "condition": list(op.names),
            "condition_units": ("condition", [op.condition(k).units for k in op.names]),
        },
        attrs={"campaign": ident, "folder": str(out)},
    )


def _kept(path: Path, idents: tuple[str, ...], this: dict) -> bool:
    """Whether the record at ``path`` is there already, from this campaign (its digest one of ``idents``; an
    error if from another, saying what differs of ``this``: the model's name, the schedule's terms, the
    seed, else the model file's text)."""
    if not path.exists():
        return False
    try:
        attrs = global_attrs(path)  # the attrs alone: an extended year's folder holds 1460 records
    except (OSError, ValueError) as exc:
        raise TwinError(
            f"{path}: a record of the campaign folder cannot be read ({exc}): remove it to simulate it again"
        ) from None
    if attrs.get("campaign") not in idents:
        raise TwinError(
            f"{path} is a record of another campaign ({_differs(attrs, this)}): give another folder, or remove its "
            "records to start this one"
        )
    return True


def _differs(theirs: dict, this: dict) -> str:
    """What makes a kept record another campaign's, in words.

    Examples
    --------
    >>> _differs({"model": "a", "schedule": "{}", "campaign_seed": 2}, {"model": "a", "schedule": "{}", "campaign_seed": 1})
    'its seed is 2, not 1'
    >>> _differs({"model": "a", "schedule": "{}", "campaign_seed": 1}, {"model": "a", "schedule": "{}", "campaign_seed": 1})
    "the model file's text differs (the same model name, edited since)"
    >>> _differs({"model": "a", "schedule": '{"days": 9, "duration_s": 60.0}', "campaign_seed": 1},
    ...          {"model": "a", "schedule": '{"days": 2, "duration_s": 600.0}', "campaign_seed": 1})
    'its schedule differs in duration_s (60.0, not 600.0)'
    """
    words = []
    if str(theirs.get("model")) != this["model"]:
        words.append(f"it is of {theirs.get('model')}, not {this['model']}")
    try:
        old, new = (record_terms(json.loads(str(x))) for x in (theirs.get("schedule"), this["schedule"]))
    except (TypeError, ValueError, AttributeError):
        old, new = {"schedule": theirs.get("schedule")}, {"schedule": this["schedule"]}
    keys = [k for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)]
    if keys:
        shown = [k if isinstance(new.get(k), (dict, list)) else f"{k} ({old.get(k)}, not {new.get(k)})" for k in keys]
        words.append(f"its schedule differs in {', '.join(shown)}")
    if str(theirs.get("campaign_seed")) != str(this["campaign_seed"]):
        words.append(f"its seed is {theirs.get('campaign_seed')}, not {this['campaign_seed']}")
    return "; ".join(words) or "the model file's text differs (the same model name, edited since)"


def _noise_std(model: RotorModel, fs_hz: float, noise_ratio: float) -> float:
    """Sensor noise std [m] from the reference operating point's response to the machine's broad-band force."""
    from twin.fem.excitation import machine_excitation
    from twin.fmu.simulate import sensor_noise_std, system_for

    ref = at_operating_point(model, {})
    ss = system_for(ref, None, "full", None)
    excitation = machine_excitation(ref)
    ports = ss.node_ports(excitation.broadband_node)
    return sensor_noise_std(ss, 1.0 / fs_hz, excitation.broadband_asd, ports, noise_ratio, None)


def _simulate_record(
    index: int,
    *,
    model: RotorModel,
    schedule: Schedule,
    points: np.ndarray,
    seed: int,
    noise_std_m: float,
    out: str,
    ident: str,
    command: str,
) -> str:
    from twin.fmu.simulate import simulate

    op = model.operation
    day = schedule.record_day(index)
    point = dict(zip(op.names, (float(v) for v in points[index])))
    unit, truth = record_model(model, point, schedule, day)
    try:
        ds = simulate(
            unit,
            duration_s=schedule.duration_s,
            fs_hz=schedule.fs_hz,
            seed=record_seed(seed, index),
            noise_std_m=noise_std_m,
            progress=False,
            command=command,
        )
    except ModelError as exc:  # an unstable or absurd machine: say which record, day and change made it
        hidden = ", ".join(effect_label(e) for e in truth.effects) or "no hidden change"
        conditions = ", ".join(f"{k} {v:g}" for k, v in point.items())
        raise ModelError(f"record {index} (day {day:g}; {hidden}; {conditions}): {exc}") from None
    ds = ds.assign(operating_point=("condition", points[index], {"long_name": "operating conditions of the record"}))
    ds = ds.assign_coords(
        condition=("condition", list(op.names)),
        condition_units=("condition", [op.condition(k).units for k in op.names]),
    )
    ds.attrs.update(
        {
            "title": f"campaign record {index} of {model.name}",
            "start_time": iso(schedule.record_start(index)),
            "day": day,
            "record": index,
            "campaign": ident,
            "campaign_seed": int(seed),
            "schedule": schedule.to_json(),
            "truth": truth.to_json(),
        }
    )
    path = Path(out) / RECORD_NAME.format(index)
    write_netcdf(ds, path)
    return str(path)


def campaign_json(table: xr.Dataset, folder: str | Path) -> dict:
    """The ``twin campaign --json`` layout of :func:`campaign`'s table: how many records, made or found, and when.

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> table = xr.Dataset({"made": ("record", [True, False]),
    ...                     "start_time": ("record", np.array(["2026-01-01T00:00", "2026-01-01T06:00"], "M8[s]"))})
    >>> campaign_json(table, "records")["kept"]
    1
    """
    made = int(table.made.sum())
    return {
        "records": int(table.sizes["record"]),
        "made": made,
        "kept": int(table.sizes["record"]) - made,
        "folder": str(Path(folder)),
        "first": str(table.start_time.values[0]),
        "last": str(table.start_time.values[-1]),
    }
