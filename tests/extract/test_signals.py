"""Checks on a signals record before identification: every bad input named by file and channel."""

import warnings

import numpy as np
import pytest
import xarray as xr

from twin.errors import SignalError, TwinWarning
from twin.extract.signals import check_record


def record(y=None, fs=100.0, names=("A_x", "A_y", "B_x")):
    y = np.random.default_rng(0).standard_normal((4000, len(names))) if y is None else y
    return xr.Dataset(
        {"displacement": (("time", "channel"), y)},
        coords={"channel": list(names)},
        attrs={} if fs is None else {"sampling_rate": fs},
    )


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


def timed(t, fs=None):
    return record(fs=fs).assign_coords(time=t)


def test_a_time_axis_that_runs_backwards_or_repeats_is_refused():
    t = np.arange(4000) / 256
    with pytest.raises(SignalError, match=r"rec.nc: the time runs backwards \(from 15.6211 s down to 0 s\)"):
        check_record(timed(t[::-1], 256.0), "rec.nc")
    with pytest.raises(SignalError, match="the time does not increase at sample 100"):
        check_record(timed(np.r_[t[:100], t[99], t[101:]]), "rec.nc")
    with pytest.raises(SignalError, match="'time' coordinate has 1 NaN or inf values"):
        check_record(timed(np.where(np.arange(4000) == 7, np.nan, t)), "rec.nc")


def test_a_hole_in_the_time_axis_is_refused_not_spliced():
    t = np.arange(4000) / 256
    with pytest.raises(SignalError, match=r"a step of 10.0039 s \(a hole: 2560 samples missing\) after t = 5 s"):
        check_record(timed(np.where(t > 5, t + 10, t), 256.0), "rec.nc")
    jitter = np.random.default_rng(3).uniform(-0.04, 0.04, 4000) / 256  # within a tenth of a step: clock jitter
    assert check_record(timed(t + jitter)).fs_hz == pytest.approx(256.0, rel=1e-4)


def test_a_sampling_rate_that_contradicts_the_time_axis_is_refused():
    t = np.arange(4000) / 256
    with pytest.raises(
        SignalError,
        match=r"sampling_rate attribute says 512 Hz but the time coordinate steps by "
        r"0.00390625 s \(256 Hz\)",
    ):
        check_record(timed(t, 512.0), "rec.nc")
    assert check_record(timed(t, 256.0)).fs_hz == 256.0
    start = np.datetime64("2026-06-01T12:00")  # datetimes are seconds too
    assert check_record(timed(start + (t * 1e9).astype("timedelta64[ns]"), 256.0)).fs_hz == 256.0


def test_a_short_record_is_not_called_clipped():
    y = np.random.default_rng(4).standard_normal((512, 3))  # 2 s at 256 Hz: one sample at each extreme
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_record(record(y, fs=256.0), "rec.nc")


def test_a_time_coordinate_in_milliseconds_is_read_as_such():
    t = np.arange(4000) * 1000.0 / 256  # ms
    ds = timed(t)
    ds["time"].attrs["units"] = "ms"
    assert check_record(ds).fs_hz == pytest.approx(256.0)
    ds["time"].attrs["units"] = "fortnights"
    with pytest.raises(SignalError, match="units 'fortnights' are not a unit of time"):
        check_record(ds, "rec.nc")


def test_a_channel_name_given_twice_is_refused():
    with pytest.raises(SignalError, match="rec.nc: channel name\\(s\\) 'A_x' appear more than once"):
        check_record(record(names=("A_x", "A_x", "B_x")), "rec.nc")
