"""Campaigns: records at their operating points with the changes in effect, resumable, the same on Dask."""

import json

import numpy as np
import pytest
import xarray as xr

from twin import TwinError
from twin.cli import main
from twin.fem.operation import at_operating_point
from twin.track import campaign, read_schedule
from twin.track.campaign import RECORD_NAME, record_model

SCHEDULE = """days = 1
records_per_day = 4
duration = 30.0
[[change]]
start_day = 0.5
[change.truth."bearing_change:UGB"]
stiffness_change = -1.0e8
damping_change = 1.0e7
"""


@pytest.fixture()
def schedule_file(tmp_path):
    path = tmp_path / "schedule.toml"
    path.write_text(SCHEDULE)
    return path


def test_a_record_model_is_the_unit_at_its_point_with_the_changes_of_its_day(hydro_unit, schedule_file):
    s = read_schedule(schedule_file, hydro_unit)
    point = {"oil_temperature": 50.0, "power": 100.0}
    before, truth_before = record_model(hydro_unit, point, s, 0.25)
    after, truth_after = record_model(hydro_unit, point, s, 0.5)
    law = at_operating_point(hydro_unit, point)
    assert truth_before.effects == () and len(truth_after.effects) == 1
    assert before.parameter("UGB.stiffness_change").nominal == law.parameter("UGB.stiffness_change").nominal
    assert after.parameter("UGB.stiffness_change").nominal == pytest.approx(-4.0e6 * 5 - 1.0e8)
    assert after.parameter("UGB.damping_change").nominal == pytest.approx(-6.3e5 * 5 + 1.0e7)
    assert after.parameter("MAG.stiffness").nominal == law.parameter("MAG.stiffness").nominal


def test_a_campaign_writes_its_records_and_resumes_where_it_stopped(tmp_path, hydro_unit, schedule_file):
    s = read_schedule(schedule_file, hydro_unit)
    out = tmp_path / "records"
    table = campaign(hydro_unit, s, out, seed=4, progress=False)
    assert table.made.values.all() and sorted(p.name for p in out.iterdir()) == [
        RECORD_NAME.format(i) for i in range(4)
    ]
    first = [xr.load_dataset(out / RECORD_NAME.format(i)) for i in range(4)]
    for i, ds in enumerate(first):
        assert ds.attrs["start_time"] == f"2027-01-01T{6 * i:02d}:00:00Z" and ds.attrs["day"] == i / 4
        assert np.array_equal(ds.operating_point.values, table.operating_point.values[i])
        assert list(ds.condition_units.values) == ["MW", "Mvar", "m", "degC"]
        assert ds.sizes["time"] == 30 * 256 and ds.displacement.dims == ("time", "channel")
        hidden = json.loads(ds.attrs["truth"])["effects"]
        assert (hidden == {}) == (i < 2), hidden
    # an interrupted campaign: record 2 missing; only it is made again, and bit for bit
    (out / RECORD_NAME.format(2)).unlink()
    again = campaign(hydro_unit, s, out, seed=4, progress=False)
    assert list(again.made.values) == [False, False, True, False]
    assert np.array_equal(xr.load_dataset(out / RECORD_NAME.format(2)).displacement, first[2].displacement)
    with pytest.raises(TwinError, match=r"a record of another campaign \(its seed is 4, not 5\)"):
        campaign(hydro_unit, s, out, seed=5, progress=False)


def test_a_campaign_is_extended_by_days_with_the_records_of_the_longer_one(tmp_path, hydro_unit):
    """More days with the same schedule otherwise (here in another file) simulate the days added only, and the
    folder then holds the records a campaign of all the days makes from scratch; another schedule's terms are
    refused by name."""
    short, longer = tmp_path / "short.toml", tmp_path / "longer.toml"
    short.write_text(SCHEDULE.replace("days = 1", "days = 0.5"))
    longer.write_text(SCHEDULE)
    out, whole = tmp_path / "records", tmp_path / "whole"
    campaign(hydro_unit, read_schedule(short, hydro_unit), out, seed=6, progress=False)
    table = campaign(hydro_unit, read_schedule(longer, hydro_unit), out, seed=6, progress=False)
    assert list(table.made.values) == [False, False, True, True]
    reference = campaign(hydro_unit, read_schedule(longer, hydro_unit), whole, seed=6, progress=False)
    assert np.array_equal(table.operating_point, reference.operating_point)
    for i in range(4):
        a, b = (xr.load_dataset(f / RECORD_NAME.format(i)) for f in (out, whole))
        assert np.array_equal(a.displacement, b.displacement)
        assert json.loads(a.attrs["truth"])["effects"] == json.loads(b.attrs["truth"])["effects"]
    other = tmp_path / "other.toml"
    other.write_text(SCHEDULE.replace("records_per_day = 4", "records_per_day = 2").replace("days = 1", "days = 3"))
    with pytest.raises(TwinError, match=r"another campaign \(its schedule differs in records_per_day \(4, not 2\)\)"):
        campaign(hydro_unit, read_schedule(other, hydro_unit), out, seed=6, progress=False)


def test_a_campaign_on_dask_workers_makes_the_same_records(tmp_path, hydro_unit, schedule_file):
    """The same records to 1e-5 of the peak (about 2e-6 measured): the BLAS runs one thread on a worker and
    several here, and the stationary covariance of lightly damped modes (a discrete Lyapunov solution)
    amplifies the difference in the last digits; the draws are the same."""
    from twin.tasks import dask_client

    s = read_schedule(schedule_file, hydro_unit)
    here = campaign(hydro_unit, s, tmp_path / "here", seed=2, progress=False)
    with dask_client("local", n_workers=2) as client:
        there = campaign(hydro_unit, s, tmp_path / "there", seed=2, tasks=client, progress=False)
    assert np.array_equal(here.operating_point, there.operating_point)
    for i in range(4):
        a = xr.load_dataset(tmp_path / "here" / RECORD_NAME.format(i))
        b = xr.load_dataset(tmp_path / "there" / RECORD_NAME.format(i))
        peak = float(np.abs(a.displacement).max())
        assert float(np.abs(a.displacement - b.displacement).max()) < 1e-5 * peak


def test_the_campaign_command(tmp_path, schedule_file, capsys):
    out = tmp_path / "records"
    args = ["campaign", "hydro_unit", "--schedule", str(schedule_file), "-o", str(out), "--scheduler", "sync"]
    assert main(args + ["--json", "-q"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary == {
        "records": 4,
        "made": 4,
        "kept": 0,
        "folder": str(out),
        "first": "2027-01-01T00:00:00Z",
        "last": "2027-01-01T18:00:00Z",
    }
    assert main(args + ["-q"]) == 0
    assert "(0 simulated, 4 there already)" in capsys.readouterr().out
    # a model without operating conditions, a schedule with an error: one line, status 2
    assert main(["campaign", "ross_reference", "--schedule", str(schedule_file), "-o", str(tmp_path / "r")]) == 2
    assert "declares no operating conditions" in capsys.readouterr().err
    schedule_file.write_text(SCHEDULE.replace("duration = 30.0", "duration = -1.0"))
    assert main(args) == 2
    assert "key 'duration': must be positive" in capsys.readouterr().err


def test_a_change_that_makes_the_machine_unstable_is_named_with_its_record_and_day(tmp_path, hydro_unit):
    path = tmp_path / "schedule.toml"
    path.write_text(
        'days = 1\nrecords_per_day = 4\nduration = 30.0\n[[change]]\nstart_day = 0.5\n[change.truth."seal_cross_coupling"]\n'
        "kxy = 1.0e9\n"
    )
    with pytest.raises(TwinError, match=r"record 2 \(day 0\.5; seal_cross_coupling; power .*\): .* is unstable"):
        campaign(hydro_unit, read_schedule(path, hydro_unit), tmp_path / "records", seed=1, progress=False)
