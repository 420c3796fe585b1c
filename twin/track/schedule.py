"""Campaign schedules: how long, how often, how the operation varies, and what changes when.

A schedule is a TOML file read for one model (its operating conditions are the model file's
``[[condition]]`` tables, :mod:`twin.fem.operation`)::

    days = 90                      # length of the campaign [days]
    records_per_day = 4            # evenly spread over each day, the first at midnight
    duration = 600.0               # length of each record [s]
    fs = 256.0                     # sampling rate [Hz] (default 256)
    start = 2027-01-01T00:00:00Z   # the first record's start (UTC; default 2027-01-01T00:00:00Z)

    [operation.power]              # how a condition varies (see twin.track.profile); every key optional,
    mean = 150.0                   # the defaults: the model file's [condition.variation] tables
    daily_amplitude = 35.0

    [[change]]                     # a hidden change, any number of them
    start_day = 40.0               # days after the first record
    ramp_days = 0.0                # 0: a step; else reached in full after this many days
    [change.truth."bearing_change:UGB"]     # the same tables as a truth file, at full size
    stiffness_change = -1.0e8
    damping_change = 1.0e7

Every problem is a :class:`~twin.errors.ModelFileError` naming the file, the table and the key.
"""

from __future__ import annotations

import datetime as dt
import json
from typing import Any
from dataclasses import asdict, dataclass, field
from pathlib import Path

from twin.defaults import SAMPLING_RATE_HZ
from twin.errors import ModelFileError
from twin.fem.model import RotorModel
from twin.fem.operation import operation_of
from twin.fem.tables import Table, array_of_tables, read_toml
from twin.fem.truthfile import Truth, truth_from_tables
from twin.fem.operation import Variation
from twin.track.profile import read_variations

#: The first record's start when a schedule names none.
DEFAULT_START = dt.datetime(2027, 1, 1, tzinfo=dt.UTC)


@dataclass(frozen=True)
class Change:
    """A hidden change: its truth at full size, the day it starts and how many days it takes to reach it."""

    truth: Truth
    start_day: float
    ramp_days: float = 0.0

    def fraction(self, day: float) -> float:
        """How much of the change has happened at ``day`` (days after the first record): 0 to 1.

        Examples
        --------
        >>> c = Change(Truth(()), start_day=10.0, ramp_days=4.0)
        >>> c.fraction(9.0), c.fraction(11.0), c.fraction(20.0)
        (0.0, 0.25, 1.0)
        """
        if day < self.start_day:
            return 0.0
        if self.ramp_days == 0:
            return 1.0
        return float(min(1.0, (day - self.start_day) / self.ramp_days))


@dataclass(frozen=True)
class Schedule:
    """A parsed schedule (see the module's text for the file)."""

    days: float
    records_per_day: int
    duration_s: float
    fs_hz: float = SAMPLING_RATE_HZ
    start: dt.datetime = DEFAULT_START
    variations: dict[str, Variation] = field(default_factory=dict)
    changes: tuple[Change, ...] = ()
    source: str = ""

    @property
    def n_records(self) -> int:
        """How many records the campaign holds."""
        return round(self.days * self.records_per_day)

    def record_day(self, index: int) -> float:
        """Start of record ``index`` in days after the first record's start."""
        return index / self.records_per_day

    def record_start(self, index: int) -> dt.datetime:
        """Start of record ``index`` (UTC)."""
        return self.start + dt.timedelta(days=self.record_day(index))

    def to_json(self) -> str:
        """The schedule as JSON, for the records' attrs (the truth of each change included)."""
        return json.dumps(self._fields())

    def record_terms(self) -> dict[str, Any]:
        """What makes each record of a campaign: the schedule but its span (``days``) and its file's name.

        Record ``i`` of a campaign is the same whatever the span (the dispatch of the operating
        conditions is drawn record after record), so two schedules with equal terms make the same
        records and a campaign is extended by days by giving it more.

        Examples
        --------
        >>> a, b = Schedule(30, 4, 600.0, source="a.toml"), Schedule(60, 4, 600.0, source="b.toml")
        >>> a.record_terms() == b.record_terms(), a.record_terms() == Schedule(30, 2, 600.0).record_terms()
        (True, False)
        """
        return record_terms(self._fields())

    def _fields(self) -> dict[str, Any]:
        return {
            "days": self.days,
            "records_per_day": self.records_per_day,
            "duration_s": self.duration_s,
            "fs_hz": self.fs_hz,
            "start": iso(self.start),
            "source": self.source,
            "operation": {k: asdict(v) for k, v in self.variations.items()},
            "changes": [
                {"start_day": c.start_day, "ramp_days": c.ramp_days, "truth": json.loads(c.truth.to_json())}
                for c in self.changes
            ],
        }


def record_terms(fields: dict[str, Any]) -> dict[str, Any]:
    """A schedule's JSON fields (:meth:`Schedule.to_json`, read back) without its span and its files' names."""
    out = {k: v for k, v in fields.items() if k not in ("days", "source")}
    out["changes"] = [
        {**c, "truth": {k: v for k, v in c.get("truth", {}).items() if k != "source"}} for c in out.get("changes", [])
    ]
    return out


def iso(time: dt.datetime) -> str:
    """ISO 8601 in UTC with a ``Z``, to the second: ``2027-01-01T06:00:00Z``."""
    return time.astimezone(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def read_schedule(path: str | Path, model: RotorModel) -> Schedule:
    """Read and check a schedule file for ``model``.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> text = 'days = 2\\nrecords_per_day = 4\\nduration = 600.0\\n'
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = pathlib.Path(d) / "s.toml"; _ = p.write_text(text)
    ...     s = read_schedule(p, hydro_unit)
    >>> s.n_records, iso(s.record_start(5))
    (8, '2027-01-02T06:00:00Z')
    """
    op = operation_of(model)
    path = str(path)
    top = Table(path, "(top level)", read_toml(path))
    days = top.number("days", positive=True)
    per_day = top.integer("records_per_day")
    if per_day < 1:
        raise top.error("records_per_day", f"must be at least 1, got {per_day}")
    duration = top.number("duration", positive=True)
    fs = top.number("fs", 256.0, positive=True)
    if duration * fs < 2:
        raise top.error("duration", f"{duration:g} s at {fs:g} Hz gives fewer than two samples")
    if duration > 86400.0 / per_day:
        raise top.error("duration", f"{duration:g} s is longer than the {86400.0 / per_day:g} s between two records")
    start = _start(top)
    if round(days * per_day) < 1:
        raise top.error("days", f"{days:g} days at {per_day} a day make no record")
    variations = read_variations(Table(path, "[operation]", top._get("operation", {})), op)
    changes = []
    for t in array_of_tables(top, "change"):
        start_day = t.number("start_day", nonnegative=True)
        ramp = t.number("ramp_days", 0.0, nonnegative=True)
        try:
            truth = truth_from_tables(t._get("truth", {}), model, path, "[change.truth]", prefix="change.truth.")
        except ModelFileError as err:  # name the change the table belongs to
            raise ModelFileError(path, f"{t.where}: {err.table}", err.key, err.problem) from None
        if any(e.per_mode for e in truth.effects):
            raise ModelFileError(
                path,
                f"{t.where}: [change.truth]",
                None,
                "a per-mode effect is no change of the FEM: a campaign's change acts on the model's parameters",
            )
        t.finish()
        changes.append(Change(truth, start_day, ramp))
    top.finish()
    return Schedule(days, per_day, duration, fs, start, variations, tuple(changes), path)


def _start(top) -> dt.datetime:
    value = top._get("start", None)
    if value is None:
        return DEFAULT_START
    if isinstance(value, str):
        try:
            value = dt.datetime.fromisoformat(value)
        except ValueError:
            raise top.error("start", f"{value!r} is not an ISO 8601 time (e.g. 2027-01-01T00:00:00Z)") from None
    if not isinstance(value, dt.datetime):
        raise top.error("start", f"expected a date and time (e.g. 2027-01-01T00:00:00Z), got {value!r}")
    if value.tzinfo is None:
        raise top.error("start", "give the time zone (e.g. 2027-01-01T00:00:00Z for UTC): records are stamped in UTC")
    return value.astimezone(dt.UTC)
