"""A tracker's folder of records: each record's modes extracted once, and again when the record changed."""

import os
import shutil

import xarray as xr

from twin.fem.operation import operation_of
from twin.track import campaign, read_schedule
from twin.track.records import extract_new, is_fresh, records_in

SCHEDULE = "days = 1\nrecords_per_day = 2\nduration = 60.0\n"


def _made(paths):
    return [p.stat().st_mtime_ns for p in paths]


def test_a_cache_answers_only_for_the_record_and_options_it_was_made_from(tmp_path, hydro_unit):
    (tmp_path / "schedule.toml").write_text(SCHEDULE)
    folder = tmp_path / "records"
    campaign(hydro_unit, read_schedule(tmp_path / "schedule.toml", hydro_unit), folder, seed=3, progress=False)
    records = records_in(folder, operation_of(hydro_unit))
    cache = tmp_path / "modes"
    targets = extract_new(records, cache, progress=False)
    first = _made(targets)
    assert all(is_fresh(t, r.path, {}) for t, r in zip(targets, records))

    # called again, or on the same bytes under a new time stamp (a copied folder): nothing is extracted
    os.utime(records[0].path, ns=(1, 1))
    assert _made(extract_new(records, cache, progress=False)) == first

    # a record replaced by other data under the same name is extracted again; the other is kept
    other = tmp_path / "other.nc"
    with xr.open_dataset(records[1].path) as ds:
        changed = ds.load()
    changed["displacement"] = changed.displacement * 1.5 + 1e-7 * changed.displacement.shift(time=1).fillna(0.0)
    changed.to_netcdf(other)
    shutil.move(other, records[1].path)
    again = _made(extract_new(records, cache, progress=False))
    assert again[0] == first[0] and again[1] != first[1]

    # a record edited in place with its size and time stamp restored: its bytes differ, so it is extracted again
    stat = records[0].path.stat()
    data = bytearray(records[0].path.read_bytes())
    data[-100] ^= 0xFF  # one byte of its samples
    records[0].path.write_bytes(bytes(data))
    os.utime(records[0].path, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert records[0].path.stat().st_size == stat.st_size
    assert not is_fresh(targets[0], records[0].path, {})

    # other extraction options make every cache file stale
    assert not is_fresh(targets[1], records[1].path, {"fmax_hz": 40.0})


def test_records_of_another_machine_or_speed_are_warned_about(tmp_path, hydro_unit):
    import warnings

    import pytest

    from twin.errors import TwinWarning
    from twin.track.records import check_machine

    (tmp_path / "schedule.toml").write_text(SCHEDULE)
    folder = tmp_path / "records"
    campaign(hydro_unit, read_schedule(tmp_path / "schedule.toml", hydro_unit), folder, seed=3, progress=False)
    records = records_in(folder, operation_of(hydro_unit))
    assert [(r.model, r.speed_rpm) for r in records] == [("hydro_unit", 134.0)] * 2
    with warnings.catch_warnings(record=True) as caught:  # the machine's own records: nothing to say
        warnings.simplefilter("always")
        check_machine(records, hydro_unit.name, hydro_unit.speed_rpm)
    assert caught == []
    with xr.open_dataset(records[1].path) as ds:
        other = ds.load()
    other.attrs.update(model="heavier_runner", speed_rpm=150.0)
    other.to_netcdf(tmp_path / "other.nc")
    shutil.move(tmp_path / "other.nc", records[1].path)
    records = records_in(folder, operation_of(hydro_unit))
    with pytest.warns(TwinWarning) as caught:
        check_machine(records, hydro_unit.name, hydro_unit.speed_rpm)
    messages = [str(w.message) for w in caught]
    assert messages[0].startswith("1 of 2 records say they are of heavier_runner (record_00001.nc)")
    assert messages[1].startswith("1 of 2 records were taken at 150 rpm")


def test_a_gap_is_an_interval_beyond_four_of_the_baselines_median():
    import numpy as np

    from twin.track.records import GAP_INTERVALS, gaps_before

    rng = np.random.default_rng(3)
    days = np.cumsum(rng.uniform(0.2, 0.3, size=40))  # about four records a day, irregular
    days[30:] += 1.5  # an outage of about a day and a half after the 30th record
    gap, threshold = gaps_before(days, 20)
    assert threshold == GAP_INTERVALS * np.median(np.diff(days[:20]))
    assert np.flatnonzero(gap).tolist() == [30]
    assert gap[30] == days[30] - days[29]
    # records at the baseline's cadence, or a single record, have none
    assert not gaps_before(np.arange(10) * 0.25, 5)[0].any()
    assert gaps_before(np.array([0.0]), 1)[0].tolist() == [0.0]
