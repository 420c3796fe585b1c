"""Channel quantities and units: read, converted to SI, and the shapes reported in displacement."""

import warnings

import numpy as np
import pytest
import xarray as xr

from twin.errors import SignalError
from twin.extract import extract
from twin.extract.quantities import channel_quantities, si_factor
from twin.extract.signals import check_record
from twin.modes import mac


@pytest.mark.parametrize(
    "units, quantity, factor",
    [
        ("m", "displacement", 1.0),
        ("um", "displacement", 1e-6),
        ("µm", "displacement", 1e-6),
        ("mil", "displacement", 25.4e-6),
        ("mm", "displacement", 1e-3),
        ("mm/s", "velocity", 1e-3),
        ("in/s", "velocity", 0.0254),
        ("ips", "velocity", 0.0254),
        ("m/s^2", "acceleration", 1.0),
        ("g", "acceleration", 9.80665),
        ("mm/s**2", "acceleration", 1e-3),
    ],
)
def test_units_as_instruments_write_them_are_taken_to_si(units, quantity, factor):
    assert si_factor(units, quantity, "A_x") == pytest.approx(factor, rel=1e-12)


def test_units_of_another_quantity_or_unknown_are_named():
    with pytest.raises(
        SignalError, match=r"channel 'A_x': units 'mm/s' are not units of displacement \(its SI unit: m\)"
    ):
        si_factor("mm/s", "displacement", "channel 'A_x'")
    with pytest.raises(SignalError, match="units 'bananas/s' are not units twin can read"):
        si_factor("bananas/s", "velocity", "channel 'A_x'")
    with pytest.raises(SignalError, match="quantity 'jerk' is not one of displacement, velocity, acceleration"):
        si_factor("m/s**3", "jerk", "channel 'A_x'")


def _record(y, quantities=None, units=None, fs=32.0):
    names = [f"ch{k}" for k in range(y.shape[1])]
    if quantities is None:
        return xr.Dataset(
            {"displacement": (("time", "channel"), y, {} if units is None else {"units": units})},
            coords={"channel": names},
            attrs={"sampling_rate": fs},
        )
    return xr.Dataset(
        {"signal": (("time", "channel"), y)},
        coords={"channel": names, "quantity": ("channel", quantities), "units": ("channel", units)},
        attrs={"sampling_rate": fs},
    )


def test_a_displacement_record_of_earlier_versions_reads_unchanged_and_its_units_are_read():
    y = np.random.default_rng(0).standard_normal((2000, 2)) * 1e-6
    old = check_record(_record(y))
    assert old.quantities == ("displacement", "displacement") and np.allclose(old.y, y - y.mean(axis=0))
    in_um = check_record(_record(y * 1e6, units="um"))
    np.testing.assert_allclose(in_um.y, old.y, rtol=1e-12)


def test_a_mixed_record_is_converted_channel_by_channel_and_mistakes_are_named():
    y = np.random.default_rng(1).standard_normal((2000, 3))
    rec = check_record(_record(y, ["displacement", "velocity", "acceleration"], ["um", "mm/s", "g"]))
    assert rec.orders.tolist() == [0, 1, 2]
    np.testing.assert_allclose(rec.y.std(axis=0), y.std(axis=0) * [1e-6, 1e-3, 9.80665], rtol=1e-12)
    with pytest.raises(SignalError, match="'signal' needs a 'units' coordinate over 'channel'"):
        check_record(_record(y, ["velocity"] * 3, ["m/s"] * 3).drop_vars("units"))
    with pytest.raises(SignalError, match="channel 'ch1': units 'm' are not units of velocity"):
        check_record(_record(y, ["displacement", "velocity", "acceleration"], ["m", "m", "g"]))
    both = _record(y, ["velocity"] * 3, ["m/s"] * 3).assign(displacement=(("time", "channel"), y))
    with pytest.raises(SignalError, match="both 'signal' and 'displacement'"):
        channel_quantities(both, "rec.nc")


def test_shapes_of_velocity_and_acceleration_channels_are_reported_in_displacement(make_record):
    """Velocity is the displacement times the pole, acceleration times its square: read as displacements, the
    shapes of a mixed record are wrong (the MAC against the true shape falls); declared, they are the true ones."""
    poles = np.array([-0.002 * 2 * np.pi * 2 + 2j * np.pi * 2, -0.002 * 2 * np.pi * 5 + 2j * np.pi * 5])
    true = np.array([[1.0, 0.5, -0.3, 0.8], [0.2, -1.0, 0.6, 0.4]]) + 0j
    orders = np.array([0, 0, 1, 2])
    measured = make_record(poles, true * poles[:, None] ** orders, fs_hz=32.0, duration_s=1200.0, seed=3)
    y = measured["displacement"].values * [1.0, 1.0, 1e3, 1 / 9.80665]  # m, m, mm/s, g
    declared = _record(y, ["displacement", "displacement", "velocity", "acceleration"], ["m", "m", "mm/s", "g"])
    declared = declared.assign_coords(channel=["a", "b", "c", "d"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        right = extract(declared, fmax_hz=8.0, progress=False)
        wrong = extract(measured, fmax_hz=8.0, progress=False)
    np.testing.assert_allclose(right["frequency"].values, [2.0, 5.0], rtol=2e-3)
    assert np.all(np.abs(np.diag(mac(right["sensor_shape"].values, true))) > 0.999)
    assert np.all(np.abs(np.diag(mac(wrong["sensor_shape"].values, true))) < 0.9)
    assert right.attrs["settings"].count("acceleration") == 1
