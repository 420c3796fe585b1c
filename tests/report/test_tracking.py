"""The tracking report's gaps: stated by time, drawn broken."""

import numpy as np
import xarray as xr

from twin.report.tracking import _broken, record_gaps


def _table(gap_before):
    times = np.datetime64("2027-01-01T00") + np.arange(len(gap_before)) * np.timedelta64(6, "h")
    times = times + np.cumsum(np.array(gap_before) * 86400).astype("timedelta64[s]")
    day = (times - times[0]) / np.timedelta64(1, "D")
    return xr.Dataset({"gap_before": ("time", gap_before)}, coords={"time": times, "day": ("time", day)})


def test_gaps_are_stated_from_the_last_record_before_to_the_first_after():
    table = _table([0.0, 0.0, 3.0, 0.0, 1.5])
    assert record_gaps(table) == [
        {"from": "2027-01-01T06:00:00Z", "to": "2027-01-04T12:00:00Z", "days": 3.0},
        {"from": "2027-01-04T18:00:00Z", "to": "2027-01-06T12:00:00Z", "days": 1.5},
    ]
    assert record_gaps(table.drop_vars("gap_before")) == []


def test_a_line_is_broken_at_each_gap():
    table = _table([0.0, 0.0, 3.0, 0.0])
    y = np.array([1.0, 2.0, 3.0, 4.0])
    day, broken = _broken(table, table.day.values, y)
    assert np.isnan(broken[2]) and np.isnan(day[2])
    assert broken[~np.isnan(broken)].tolist() == y.tolist()
