"""Checks on a signals record before identification: every bad input named by file and channel."""

import warnings

import numpy as np
import pytest
import xarray as xr

from twin.errors import SignalError, TwinWarning
from twin.extract.signals import check_record


def record(y=None, fs=100.0, names=("A_x", "A_y", "B_x")):
    y = np.random.default_rng(0).standard_normal((4000, len(names))) if y is None else y
    return xr.Dataset({"displacement": (("time", "channel"), y)}, coords={"channel": list(names)},
                      attrs={} if fs is None else {"sampling_rate": fs})  # fmt: skip


def test_good_record_is_zero_mean_and_keeps_names():
    ds = record()
    ds["displacement"] += 5.0
    rec = check_record(ds, "rec.nc")
    assert rec.channels == ("A_x", "A_y", "B_x") and rec.fs_hz == 100.0
    assert np.allclose(rec.y.mean(axis=0), 0.0, atol=1e-12)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_samples_name_the_channel_and_time(bad):
    ds = record()
    ds["displacement"][250, 1] = bad
    with pytest.raises(SignalError, match=r"rec.nc: channel 'A_y' has 1 NaN or inf samples \(first at t = 2.5 s\)"):
        check_record(ds, "rec.nc")


def test_dead_channel_is_an_error_naming_it():
    y = np.random.default_rng(1).standard_normal((4000, 3))
    y[:, 2] = 1e-3  # a flat line
    with pytest.raises(SignalError, match="channel 'B_x' is flat"):
        check_record(record(y), "rec.nc")
    y[:, 1] = 0.0  # two of three flat: the median is 0, the live channel must not be blamed
    with pytest.raises(SignalError, match="channel 'A_y' is flat"):
        check_record(record(y), "rec.nc")


def test_clipped_channel_warns_naming_it():
    y = np.random.default_rng(2).standard_normal((4000, 3))
    y[:, 0] = np.clip(y[:, 0], -5, 1.5)  # about 7% of the samples saturate
    with pytest.warns(TwinWarning, match=r"channel 'A_x' looks clipped \(saturated\): .* at its maximum 1.5"):
        check_record(record(y), "rec.nc")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_record(record(), "rec.nc")  # a Gaussian record is not clipped


def test_sampling_rate_from_time_coordinate_or_error():
    ds = record(fs=None).assign_coords(time=np.arange(4000) * 0.004)
    assert check_record(ds).fs_hz == pytest.approx(250.0)
    with pytest.raises(SignalError, match="rec.nc: no sampling rate"):
        check_record(record(fs=None), "rec.nc")
    with pytest.raises(SignalError, match="sampling_rate must be a positive"):
        check_record(record(fs=-1.0), "rec.nc")


def test_missing_variable_wrong_dims_unknown_channel():
    with pytest.raises(SignalError, match="rec.nc: no variable 'displacement'"):
        check_record(record().rename({"displacement": "disp"}), "rec.nc")
    ds = xr.Dataset({"displacement": (("t", "c"), np.zeros((10, 2)))}, attrs={"sampling_rate": 1.0})
    with pytest.raises(SignalError, match=r"must have dimensions \(time, channel\)"):
        check_record(ds, "rec.nc")
    with pytest.raises(SignalError, match="no channel 'C_x' .*has: A_x, A_y, B_x"):
        check_record(record(), "rec.nc", channels=["A_x", "C_x"])
    assert check_record(record(), channels=["B_x", "A_x"]).channels == ("B_x", "A_x")
