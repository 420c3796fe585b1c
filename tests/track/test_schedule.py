"""Schedules and operating profiles: reading, defaults, errors that name the file, table and key."""

import datetime as dt

import numpy as np
import pytest

from twin import ModelFileError
from twin.fem.effects import ShaftStiffnessChange
from twin.fem.operation import Variation
from twin.track.profile import operating_points
from twin.track.schedule import Change, read_schedule

BASE = "days = 3\nrecords_per_day = 4\nduration = 600.0\n"
CHANGE = """
[[change]]
start_day = 1.5
ramp_days = 2.0
[change.truth."bearing_change:UGB"]
stiffness_change = -1.0e8
[change.truth."shaft_stiffness:18"]
change = -0.3
"""


def _read(tmp_path, text, model):
    path = tmp_path / "schedule.toml"
    path.write_text(text)
    return read_schedule(path, model)


def test_a_schedule_with_defaults_and_a_change(tmp_path, hydro_unit):
    s = _read(tmp_path, BASE + 'start = "2027-03-01T06:00:00+01:00"\n' + CHANGE, hydro_unit)
    assert s.n_records == 12 and s.duration_s == 600.0 and s.fs_hz == 256.0
    assert s.start == dt.datetime(2027, 3, 1, 5, tzinfo=dt.UTC)
    assert s.variations["power"].mean == hydro_unit.operation.condition("power").variation.mean == 150.0
    assert s.variations["oil_temperature"].follows == {"power": 0.04}
    (change,) = s.changes
    assert change.truth.effects[1] == ShaftStiffnessChange(18, -0.3)
    assert [change.fraction(d) for d in (1.0, 1.5, 2.5, 3.5, 9.0)] == [0.0, 0.0, 0.5, 1.0, 1.0]


def test_operation_tables_override_the_defaults(tmp_path, hydro_unit):
    s = _read(
        tmp_path, BASE + "[operation.power]\nmean = 120.0\ndispatch_std = 0.0\ndaily_amplitude = 0.0\n", hydro_unit
    )
    assert s.variations["power"] == Variation(mean=120.0, dispatch_correlation=0.3)
    days = np.arange(s.n_records) / 4
    points = operating_points(s.variations, hydro_unit.operation, days, 0.0, seed=5)
    assert np.all(points[:, 0] == 120.0)
    # the oil follows the power's departure from its mean: here none, so only its season and dispatch
    oil = points[:, 3]
    assert abs(oil.mean() - (45.0 + 3.0 * np.cos(2 * np.pi * (0.0 - 200.0) / 365.25))) < 1.5


def test_operating_points_are_seeded_clipped_and_follow_their_daily_cycle(hydro_unit):
    op = hydro_unit.operation
    variations = {k: op.condition(k).variation for k in op.names}
    days = np.arange(4 * 400) / 4
    a = operating_points(variations, op, days, 0.0, seed=11)
    assert np.array_equal(a, operating_points(variations, op, days, 0.0, seed=11))
    assert not np.array_equal(a, operating_points(variations, op, days, 0.0, seed=12))
    for j, name in enumerate(op.names):
        c = op.condition(name)
        assert c.low <= a[:, j].min() and a[:, j].max() <= c.high
    power = a[:, 0].reshape(-1, 4)  # 00, 06, 12, 18 h: the evening peak is highest on average
    assert np.argmax(power.mean(axis=0)) == 3
    # the dispatch's correlation between successive records, without the daily cycle
    residual = power - power.mean(axis=0)
    r = np.corrcoef(residual.ravel()[:-1], residual.ravel()[1:])[0, 1]
    assert 0.1 < r < 0.5


@pytest.mark.parametrize(
    "text, table, key, problem",
    [
        ("days = 3\nduration = 600.0\n", "(top level)", "records_per_day", "missing key"),
        (BASE.replace("600.0", "30000.0"), "(top level)", "duration", "longer than the 21600 s between two records"),
        (BASE + 'start = "yesterday"\n', "(top level)", "start", "not an ISO 8601 time"),
        (BASE + "start = 2027-01-01T00:00:00\n", "(top level)", "start", "give the time zone"),
        (BASE + "[operation.load]\nmean = 1.0\n", "[operation]", "load", "no condition 'load'"),
        (BASE + "[operation.power]\nmeen = 1.0\n", "[operation.power]", "meen", "did you mean 'mean'"),
        (
            BASE + "[operation.power]\ndispatch_correlation = 1.0\n",
            "[operation.power]",
            "dispatch_correlation",
            "must be in [0, 1)",
        ),
        (
            BASE + "[operation.power]\nfollows = { oil_temperature = 1.0 }\n",
            "[operation]",
            None,
            "follow each other in a circle",
        ),
        (
            BASE + CHANGE.replace("start_day = 1.5", "start_day = -1.0"),
            "[[change]] #1",
            "start_day",
            "must not be negative",
        ),
        (
            BASE + CHANGE.replace("bearing_change:UGB", "bearing_change:XGB"),
            '[[change]] #1: [change.truth."bearing_change:XGB"]',
            "bearing",
            "no bearing named 'XGB'",
        ),
        (
            BASE + CHANGE.replace("shaft_stiffness:18", "shaft_stiffness:99"),
            '[[change]] #1: [change.truth."shaft_stiffness:18"]'.replace("18", "99"),
            None,
            "no shaft element 99",
        ),
        (
            BASE + CHANGE.replace("stiffness_change = -1.0e8", "stiffnes_change = -1.0e8"),
            '[[change]] #1: [change.truth."bearing_change:UGB"]',
            "stiffnes_change",
            "did you mean 'stiffness_change'",
        ),
        (BASE + "[[change]]\nstart_day = 1.0\n", "[[change]] #1: [change.truth]", None, "at least one effect table"),
    ],
)
def test_schedule_errors_name_the_table_and_key(tmp_path, hydro_unit, text, table, key, problem):
    with pytest.raises(ModelFileError) as info:
        _read(tmp_path, text, hydro_unit)
    err = info.value
    assert err.path.endswith("schedule.toml") and err.table == table and err.key == key, str(err)
    assert problem in err.problem, str(err)


def test_a_change_ramps_linearly_to_its_full_size():
    from twin.fem.truthfile import Truth

    c = Change(Truth(()), start_day=2.0, ramp_days=0.0)
    assert (c.fraction(1.99), c.fraction(2.0)) == (0.0, 1.0)
