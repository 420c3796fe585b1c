"""The tracker on small campaigns: a step detected and named, no alarm without a change, incremental runs.

Nine days of eight 4-minute records (the operating point moving as at a peaking plant), six days of
baseline. A record's modes take about a second to extract, so each tracking here takes a minute on two
workers: those tests are marked slow.
"""

import json

import numpy as np
import pytest
import xarray as xr

from twin import TwinError
from twin.cli import main
from twin.track import alarms_json, campaign, read_schedule, track
from twin.track.tracker import IDENTITY_TOLERANCE, _identify

CAMPAIGN = """days = 9
records_per_day = 8
duration = 240.0
"""
#: A step of the upper guide bearing at 1.5 times the library's reference change, on day 7.
STEP = (
    CAMPAIGN
    + """[[change]]
start_day = 7.0
[change.truth."bearing_change:UGB"]
stiffness_change = -3.0e8
damping_change = 3.0e7
"""
)
BASELINE_DAYS = 6.0


@pytest.fixture(scope="module")
def client():
    from twin.tasks import dask_client

    with dask_client("local", n_workers=2) as c:
        yield c


def _records(tmp, text, seed, model, client):
    (tmp / "schedule.toml").write_text(text)
    folder = tmp / "records"
    campaign(model, read_schedule(tmp / "schedule.toml", model), folder, seed=seed, tasks=client, progress=False)
    return folder


@pytest.fixture(scope="module")
def step(tmp_path_factory, hydro_unit, client):
    tmp = tmp_path_factory.mktemp("step")
    folder = _records(tmp, STEP, 21, hydro_unit, client)
    table = track(hydro_unit, folder, tmp / "out", baseline_days=BASELINE_DAYS, tasks=client, progress=False)
    return folder, tmp / "out", table


@pytest.mark.slow
def test_a_step_is_detected_within_two_days_and_named(step):
    _, out, table = step
    summary = alarms_json(table)
    assert summary["records"] == 72
    assert len(summary["alarms"]) >= 1
    first = summary["alarms"][0]
    assert 7.0 <= first["day"] <= 9.0
    assert first["effects"] == ["bearing_change:UGB"]
    assert first["named_day"] is not None and first["day"] <= first["named_day"] <= 9.0
    assert abs(first["onset_day"] - 7.0) <= 0.5
    # the followed damping change: its 5-95% interval at the last record holds the truth (3e7 N s/m)
    last = table.isel(time=-1).sel(tracked_parameter="UGB.damping_change")
    assert float(last.parameter_low) < 3.0e7 < float(last.parameter_high)
    # the outputs: the chart below its limit over the baseline's end and the day after, the report written
    assert np.all(
        table.statistic.values[(table.day.values >= BASELINE_DAYS) & (table.day.values < 7.0)] < float(table.limit)
    )
    page = (out / "report.html").read_text()
    assert "bearing_change:UGB" in page and page.count("data:image/png;base64,") == 4
    saved = xr.load_dataset(out / "track.nc")
    assert saved.sizes["time"] == 72 and saved.sizes["alarm"] == table.sizes["alarm"]


@pytest.mark.slow
def test_no_alarm_without_a_change_under_varying_conditions(tmp_path, hydro_unit, client):
    folder = _records(tmp_path, CAMPAIGN, 22, hydro_unit, client)
    table = track(hydro_unit, folder, tmp_path / "out", baseline_days=BASELINE_DAYS, tasks=client, progress=False)
    power = table.operating_point.sel(condition="power").values
    assert power.max() - power.min() > 50.0  # the load moved by more than 50 MW
    assert table.sizes["alarm"] == 0
    assert np.nanmax(table.statistic.values) < float(table.limit)


@pytest.mark.slow
def test_records_added_later_give_the_alarms_of_one_run(step, tmp_path, hydro_unit, client):
    folder, _, whole = step
    grows = tmp_path / "records"
    grows.mkdir()
    paths = sorted(folder.glob("*.nc"))
    for p in paths[:58]:
        (grows / p.name).symlink_to(p)
    first = track(hydro_unit, grows, tmp_path / "out", baseline_days=BASELINE_DAYS, tasks=client, progress=False)
    assert first.sizes["time"] == 58
    for p in paths[58:]:
        (grows / p.name).symlink_to(p)
    again = track(hydro_unit, grows, tmp_path / "out", baseline_days=BASELINE_DAYS, tasks=client, progress=False)
    assert alarms_json(again) == alarms_json(whole)
    np.testing.assert_allclose(again.statistic.values, whole.statistic.values, rtol=1e-9, equal_nan=True)


@pytest.mark.slow
def test_a_record_after_an_outage_leaves_every_earlier_verdict_and_the_limit(step, tmp_path, hydro_unit, client):
    """The limit is set at the baseline's cadence, not over the span of all records: a record 60 days after the
    rest (an outage) changes neither the limit nor an earlier statistic or alarm."""
    import shutil

    folder, out, whole = step
    records, cached = tmp_path / "records", tmp_path / "out"
    shutil.copytree(folder, records)
    shutil.copytree(out, cached)
    with xr.open_dataset(folder / "record_00000.nc") as ds:
        late = ds.load()
    start = np.datetime64(str(whole.time.values[-1])[:19]) + np.timedelta64(60, "D")
    late.attrs["start_time"] = str(start) + "Z"
    late.to_netcdf(records / "after_the_outage.nc")
    table = track(hydro_unit, records, cached, baseline_days=BASELINE_DAYS, tasks=client, progress=False)
    assert table.sizes["time"] == whole.sizes["time"] + 1
    assert float(table.limit) == float(whole.limit)
    np.testing.assert_allclose(table.statistic.values[:-1], whole.statistic.values, rtol=1e-9, equal_nan=True)
    assert alarms_json(table)["alarms"][: len(alarms_json(whole)["alarms"])] == alarms_json(whole)["alarms"]
    # the outage is stated as a gap, in track.nc, --json and the report
    gap = float(table.day.values[-1] - table.day.values[-2])
    assert gap == pytest.approx(60.0, abs=1e-3)
    assert table.gap_before.values[-1] == gap and not table.gap_before.values[:-1].any()
    last = np.datetime_as_string(whole.time.values[-1], unit="s") + "Z"
    assert alarms_json(table)["gaps"] == [{"from": last, "to": str(start) + "Z", "days": round(gap, 4)}]
    assert alarms_json(whole)["gaps"] == []
    assert "Gaps in the records" in (cached / "report.html").read_text()


@pytest.mark.slow
def test_a_second_tracker_on_one_folder_is_refused(step, tmp_path, hydro_unit, client):
    from twin.netcdf import one_writer

    folder, out, _ = step
    with one_writer(out, "twin track"):
        with pytest.raises(TwinError, match=r"is being written by twin track \(process"):
            track(hydro_unit, folder, out, baseline_days=BASELINE_DAYS, tasks=client, progress=False)


@pytest.mark.slow
def test_records_that_cannot_be_used_are_set_aside_and_the_rest_tracked(step, tmp_path, hydro_unit, client):
    import shutil

    from twin.errors import SignalError

    folder, out, whole = step
    records, cached = tmp_path / "records", tmp_path / "out"
    shutil.copytree(folder, records)
    shutil.copytree(out, cached)  # the good records' modes: nothing of them is extracted again
    (records / "truncated.nc").write_bytes((folder / "record_00000.nc").read_bytes()[:2000])
    with xr.open_dataset(folder / "record_00003.nc") as ds:
        good = ds.load()
    nan = good.copy(deep=True)
    nan["displacement"][100:200, 2] = np.nan
    nan.attrs["start_time"] = "2027-01-01T01:00:00Z"
    nan.to_netcdf(records / "with_nan.nc")
    far = good.copy(deep=True)
    far["operating_point"][0] = 1.0e4  # MW: out of the model's range
    far.attrs["start_time"] = "2027-01-01T02:00:00Z"
    far.to_netcdf(records / "out_of_range.nc")
    table = track(hydro_unit, records, cached, baseline_days=BASELINE_DAYS, tasks=client, progress=False)
    summary = alarms_json(table)
    assert sorted(a["file"] for a in summary["set_aside"]) == ["out_of_range.nc", "truncated.nc", "with_nan.nc"]
    assert summary["alarms"] == alarms_json(whole)["alarms"]  # the rest tracked as before
    assert "Records set aside" in (cached / "report.html").read_text()
    with pytest.raises(SignalError):  # --strict: the first of them stops the track
        track(hydro_unit, records, cached, baseline_days=BASELINE_DAYS, tasks=client, progress=False, strict=True)


@pytest.mark.slow
def test_the_track_command(step, capsys):
    folder, out, table = step
    args = ["track", "hydro_unit", str(folder), "-o", str(out), "--scheduler", "sync"]
    assert (
        main(args + ["--baseline-days", str(BASELINE_DAYS), "--json", "-q"]) == 0
    )  # the modes are there: nothing is extracted again
    summary = json.loads(capsys.readouterr().out)
    assert summary == alarms_json(table)
    assert set(summary["alarms"][0]) >= {"time", "day", "effects", "verdict"}
    assert summary["alarms"][0]["time"].endswith("Z")
    # a baseline too short for the chart: one line, status 2
    assert main(args + ["--baseline-days", "0.1", "-q"]) == 2
    assert "the baseline (0.1 days) holds 1 records" in capsys.readouterr().err
    # a baseline with fewer records than the chart has residuals, plus two: one line, status 2
    assert main(args + ["--baseline-days", "1", "-q"]) == 2
    assert "the baseline (1 days) holds 8 records: a chart of" in capsys.readouterr().err
    # a false-alarm rate at or above one per record: refused, not a NaN limit that never alarms
    assert main(args + ["--baseline-days", str(BASELINE_DAYS), "--false-alarms", "1e5", "-q"]) == 2
    assert "one or more per record at" in capsys.readouterr().err
    # every record in the baseline: said as such, not "0 alarms" as if the unit had been watched
    assert main(args + ["--baseline-days", "30", "-q"]) == 0
    assert "all in the 30-day baseline: none monitored yet" in capsys.readouterr().out
    assert "No record monitored yet" in (out / "report.html").read_text()


@pytest.mark.parametrize("rate", [-1.0, 0.0, float("nan"), float("inf")])
def test_a_false_alarm_rate_that_is_no_rate_is_refused_before_any_work(rate, tmp_path, hydro_unit):
    with pytest.raises(TwinError, match="false-alarm rate must be a positive number"):
        track(hydro_unit, tmp_path / "not-read", tmp_path / "out", false_alarms_per_year=rate, progress=False)
    assert not (tmp_path / "out").exists()


def test_the_records_folder_is_not_the_trackers_folder(tmp_path, hydro_unit):
    (tmp_path / "records").mkdir()
    with pytest.raises(TwinError, match="is the folder of records"):
        track(hydro_unit, tmp_path / "records", tmp_path / "records" / ".." / "records", progress=False)


def test_a_folder_without_records_is_refused(tmp_path, hydro_unit):
    (tmp_path / "records").mkdir()
    with pytest.raises(TwinError, match="records"):
        track(hydro_unit, tmp_path / "records", tmp_path / "out", progress=False)


class _Measured:
    def __init__(self, pole, shape):
        self.pole, self.shape = np.asarray(pole), np.asarray(shape)
        self.sigma = np.ones((len(self.pole), 2))


def test_a_mode_a_change_moves_far_is_still_found_by_its_shape():
    """Three tracked modes; the first measured 20% from its prediction (half the way to the second is 74%)."""
    predicted = np.array([-0.05 + 7.0j, -1.3 + 17.2j, -0.6 + 63.6j])
    shapes = np.eye(3, 4) + 0.05
    moved = predicted[0] * 1.2
    found, _ = _identify(_Measured([moved, predicted[1], predicted[2]], shapes), predicted, shapes)
    np.testing.assert_array_equal(found, [moved, predicted[1], predicted[2]])
    # the same distance with a shape only like the first (MAC 0.77): not the first mode
    unlike = shapes[0] + 0.6 * np.array([0.0, 0.0, 0.0, 1.0])
    found, _ = _identify(_Measured([moved, predicted[1]], np.array([unlike, shapes[1]])), predicted, shapes)
    assert np.isnan(found[0]) and found[1] == predicted[1]
    # close to the prediction a looser shape will do
    near = predicted[0] * (1 + 0.5 * IDENTITY_TOLERANCE)
    found, _ = _identify(_Measured([near], np.array([unlike])), predicted, shapes)
    assert found[0] == near
    # no mode is taken beyond half the way to its neighbour, however alike the shape
    far = predicted[1] * 1.5
    found, _ = _identify(_Measured([far], shapes[1:2]), predicted, shapes)
    assert np.all(np.isnan(found))
