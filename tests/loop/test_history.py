"""The error history file: round trip, appending, refusals, the chart."""

import numpy as np
import pytest
import xarray as xr

from twin.errors import TwinError
from twin.loop.history import (
    append_step,
    history_dataset,
    plot_history,
    read_history,
    write_history,
)


def test_round_trip_keeps_actions_errors_and_the_modes(tmp_path):
    h = history_dataset(["start", "add a, b", 'update "x"'], [0.0851, 0.0851, 0.00226], [912.5, 912.5, 14.0], "m.nc")
    back = read_history(write_history(h, tmp_path / "h.csv"))
    xr.testing.assert_allclose(back, h, rtol=1e-14)
    assert back.attrs == h.attrs and back["action"].values.tolist() == h["action"].values.tolist()


def test_file_is_a_plain_csv_with_the_error_in_percent(tmp_path):
    import pandas as pd

    h = history_dataset(["start", "add a, b"], [0.0851, 0.00226], [912.5, 14.0], "m.nc", [None, (0.0022, 0.0031)])
    frame = pd.read_csv(write_history(h, tmp_path / "h.csv"))
    assert frame.columns.tolist() == [
        "step",
        "action",
        "error_percent",
        "chi2",
        "modes",
        "error_low_percent",
        "error_high_percent",
    ]
    assert frame["error_percent"].tolist() == pytest.approx([8.51, 0.226]) and frame["action"][1] == "add a, b"
    assert np.isnan(frame["error_low_percent"][0]) and frame["error_high_percent"][1] == pytest.approx(0.31)
    back = read_history(tmp_path / "h.csv")
    xr.testing.assert_allclose(back, h, rtol=1e-14)


def test_a_history_written_without_the_interval_is_read_and_extended(tmp_path):
    # the header twin wrote before the error's interval (stop 65): read, and appended to in the new layout
    path = tmp_path / "h.csv"
    path.write_text("step,action,error_percent,chi2,modes\n0,start,8.51,912.5,m.nc\n")
    old = read_history(path)
    assert old["error"].values.tolist() == [0.0851] and np.isnan(old["error_low"].values).all()
    h = append_step(path, "again", xr.Dataset(attrs={"error": 0.05, "chi2": 400.0}), "m.nc")
    assert h["error"].values.tolist() == [0.0851, 0.05]
    assert path.read_text().splitlines()[0].endswith("error_low_percent,error_high_percent")


def test_the_error_interval_is_the_quantiles_of_e_over_the_draws(hydro_unit):
    # E at each of 40 posterior draws of a hidden pull against exact modes: the interval's ends are the 5% and
    # 95% quantiles of those errors, computed here directly with compare at each draw
    from twin.fem.effects import MagneticPull
    from twin.fem.truthfile import Truth
    from twin.loop.compare import compare
    from twin.loop.history import error_interval
    from twin.modes.measured import measured_modes
    from twin.update import synthesize_modes

    meas = measured_modes(synthesize_modes(hydro_unit, Truth((MagneticPull(-1e8),)), n_modes=13, samples=50, seed=3))
    model = hydro_unit.with_effects(MagneticPull(0.0))
    values = np.random.default_rng(1).normal(-1e8, 3e6, (2, 20))
    post = xr.Dataset(
        {"theta": (("chain", "draw", "parameter"), values[..., None])}, coords={"parameter": ["MAG.stiffness"]}
    )
    errors = [compare(model.with_values({"MAG.stiffness": v}), meas).attrs["error"] for v in values.ravel()]
    assert error_interval(model, post, meas, draws=40) == pytest.approx(tuple(np.quantile(errors, [0.05, 0.95])))
    at_map = compare(model.with_values({"MAG.stiffness": -1e8}), meas).attrs["error"]
    assert error_interval(model, post, meas, draws=40)[1] > at_map


def test_append_refuses_other_modes_and_leaves_the_file(tmp_path):
    path = tmp_path / "h.csv"
    table = xr.Dataset(attrs={"error": 0.05, "chi2": 400.0})
    append_step(path, "start", table, "a.nc")
    before = path.read_text()
    with pytest.raises(TwinError, match="compares against 'a.nc', not 'b.nc'"):
        append_step(path, "again", table, "b.nc")
    assert path.read_text() == before
    assert append_step(path, "again", table, "a.nc").sizes["step"] == 2


@pytest.mark.parametrize(
    "text, message",
    [
        ("a,b\n1,2\n", "not a twin history"),
        ("step,action,error_percent,chi2,modes\n0,start,lots,1,m.nc\n", "row 2 is not"),
        ("step,action,error_percent,chi2,modes\n0,start\n", "row 2 is not"),
        ("step,action,error_percent,chi2,modes\n0,start,1,1,a.nc\n1,x,1,1,b.nc\n", "different measured modes"),
    ],
)
def test_malformed_history_is_named(tmp_path, text, message):
    path = tmp_path / "h.csv"
    path.write_text(text)
    with pytest.raises(TwinError, match=f"h.csv: {message}"):
        read_history(path)
    with pytest.raises(TwinError, match="cannot read the history"):
        read_history(tmp_path / "missing.csv")


def test_chart_is_written(tmp_path):
    h = history_dataset(["start", "update"], [0.08, 0.002], [900.0, 12.0])
    assert plot_history(h, tmp_path / "h.png").stat().st_size > 1000
