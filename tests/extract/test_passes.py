"""The second SSI passes: the one the shapes are read at (its lag rule), the one over the differenced record,
the pairing of modes, what extract takes from them."""

import json
import warnings

import numpy as np
import pytest

from twin.errors import SignalError
from twin.extract import extract
from twin.modes import read_modes
from twin.extract.passes import DIFFERENCES, SHAPE_LAG_PERIODS, differenced, matching_modes, shape_lag_rows
from twin.modes.shapes import mac

FS = 20.0
F_HZ = np.array([1.0, 1.2, 6.0])
POLES = 2 * np.pi * F_HZ * (-0.02 + 1j)
SHAPES = np.array([[1.0, 0.8, 0.3j, -0.5], [0.4, -0.9, 1.0, 0.6j], [0.5, 0.5, -0.7, 0.3]])


@pytest.fixture(scope="module")
def close_pair(make_record):
    """600 s at 20 Hz on four channels: two modes 0.2 Hz (five bandwidths) apart, and one at 6 Hz."""
    return make_record(
        POLES, SHAPES, fs_hz=FS, duration_s=600.0, seed=5, noise_ratio=0.05, channels=["A_x", "A_y", "B_x", "B_y"]
    )


def _extract(ds, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return extract(ds, samples=10, fmax_hz=8.0, block_rows=6, max_order=20, progress=False, **kw)


def test_shape_lag_rows_span_the_periods_within_the_bounds():
    for f, fs in ((1.09, 256.0), (0.3, 20.0), (12.0, 100.0)):
        i = shape_lag_rows(f, fs)
        assert i / fs >= SHAPE_LAG_PERIODS / f > (i - 1) / fs  # the fewest rows that span them
    assert shape_lag_rows(1.09, 256.0, minimum=500) == 500
    assert shape_lag_rows(1.09, 256.0, maximum=120) == 120


def test_matching_modes_pairs_each_mode_once_closest_first():
    p = np.array([-0.1 + 10j, -0.1 + 10.05j, -0.1 + 20j])
    s = np.array([[1, 0], [1, 0.05], [0, 1]], dtype=complex)
    # one counterpart near the first two: the closer (the first) takes it, the second has none
    assert matching_modes(p, s, np.array([-0.1 + 10.01j, -0.1 + 20.3j]), s[[0, 2]]).tolist() == [0, -1, 1]
    assert matching_modes(p, s, np.zeros(0, complex), np.zeros((0, 2), complex)).tolist() == [-1, -1, -1]
    # the same frequency with an orthogonal shape is another mode
    assert matching_modes(p[:1], s[:1], p[:1], s[2:]).tolist() == [-1]


def test_extract_auto_reads_slow_modes_shapes_at_longer_lags_and_the_poles_at_its_own(close_pair):
    first = _extract(close_pair)
    both = _extract(close_pair, shape_block_rows="auto")
    # 6 block rows span 1.5 periods of the 6 Hz mode only: the two slow modes' shapes are read at lags over
    # 1.5 periods of the slowest, 30 block rows at 20 Hz; the 6 Hz mode's stay the first pass's
    want = shape_lag_rows(1.0, FS)
    assert want == 30 and shape_lag_rows(6.0, FS) < 6
    settings = json.loads(both.attrs["settings"])
    assert settings["block_rows"] == 6 and settings["shape_block_rows"] == want
    assert both.shape_block_rows.values.tolist() == [want, want, 6]
    assert (
        first.shape_block_rows.values.tolist() == [6, 6, 6]
        and json.loads(first.attrs["settings"])["shape_block_rows"] == 6
    )
    # the poles and their samples are the first pass's either way
    np.testing.assert_array_equal(both.pole.values, first.pole.values)
    # the slow modes' shapes and their samples come from the second pass: different samples of the same modes
    assert not np.allclose(both.shape.values[:2], first.shape.values[:2])
    np.testing.assert_array_equal(both.shape.values[2], first.shape.values[2])
    for k in range(3):
        assert float(mac(both.sensor_shape.values[k], SHAPES[k])) > 0.995
        assert float(mac(first.sensor_shape.values[k], SHAPES[k])) > 0.99
    assert "shapes read at 30 block rows" in both.attrs["samples_method"]
    ref = [list(both.channel.values).index(c) for c in both.reference_channel.values]
    np.testing.assert_allclose(both.shape.values[np.arange(3), :, ref].imag, 0.0, atol=1e-12)  # reference real


def test_an_explicit_second_pass_and_its_bad_values(close_pair):
    assert _extract(close_pair, shape_block_rows=12).shape_block_rows.values.tolist() == [12, 12, 12]  # every mode
    # blocks of 1200 samples hold twice 2 i + 2 lags (from lag 3, the first beyond a period of 8 Hz at 20 Hz)
    too_many = "shape_block_rows = 400 is too many for blocks of 60 s.*802 lags.*at most 299"
    with pytest.raises(SignalError, match=too_many):
        _extract(close_pair, shape_block_rows=400)
    for bad in (-1, "longer"):
        with pytest.raises(SignalError, match="shape_block_rows must be 'auto' or at least 0"):
            _extract(close_pair, shape_block_rows=bad)


def test_the_command_line_takes_a_number_or_auto(tmp_path, close_pair, capsys):
    from twin.cli import main

    close_pair.to_netcdf(tmp_path / "signals.nc")
    out = tmp_path / "modes.nc"
    args = [
        "extract",
        str(tmp_path / "signals.nc"),
        "-o",
        str(out),
        "--samples",
        "10",
        "--fmax",
        "8",
        "--block-rows",
        "6",
        "--max-order",
        "20",
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(args + ["--shape-block-rows", "auto"]) == 0
    assert json.loads(read_modes(out).attrs["settings"])["shape_block_rows"] == 30
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(args + ["--differenced-above", "3"]) == 0
    assert read_modes(out).differences.values.tolist() == [0, 0, DIFFERENCES]
    with pytest.raises(SystemExit):
        main(args + ["--shape-block-rows", "longer"])
    assert "expected a number of block rows or 'auto', got 'longer'" in capsys.readouterr().err


def test_differencing_keeps_a_mode_and_weighs_it_by_its_frequency():
    # one undamped mode: a sinusoid stays a sinusoid of the same frequency (the same pole), its amplitude times
    # (2 sin(pi f / fs))^2 for two differences, and a constant (a 0 Hz mode) is gone
    fs, f = 20.0, 6.0
    t = np.arange(400) / fs
    y = np.column_stack([np.cos(2 * np.pi * f * t), 0.5 * np.sin(2 * np.pi * f * t), np.full_like(t, 3.0)])
    d = differenced(y)
    assert d.shape == (400 - DIFFERENCES, 3)
    gain = (2 * np.sin(np.pi * f / fs)) ** DIFFERENCES
    np.testing.assert_allclose(d[:, 0], -gain * np.cos(2 * np.pi * f * t[1:-1]), atol=1e-12)  # centred at t - 1
    np.testing.assert_allclose(d[:, 1], -gain * 0.5 * np.sin(2 * np.pi * f * t[1:-1]), atol=1e-12)
    np.testing.assert_allclose(d[:, 2], 0.0, atol=1e-12)


def test_extract_reads_the_modes_above_the_split_from_the_differenced_record(close_pair):
    first = _extract(close_pair)
    split = _extract(close_pair, differenced_above_hz=3.0)
    assert split.differences.values.tolist() == [0, 0, DIFFERENCES] and first.differences.values.tolist() == [0, 0, 0]
    assert json.loads(split.attrs["settings"])["differenced_above_hz"] == 3.0
    assert "modes above 3 Hz read from the record differenced 2 times" in split.attrs["samples_method"]
    # the slow modes are the first pass's, samples and all
    for v in ("pole", "shape"):
        np.testing.assert_array_equal(split[v].values[:2], first[v].values[:2])
    # the 6 Hz mode is the same mode from other covariances: within 4 of its standard errors of the truth
    fast = split.pole.values[2]
    se = np.std(fast.real) / np.sqrt(fast.size), np.std(fast.imag) / np.sqrt(fast.size)
    assert not np.allclose(fast, first.pole.values[2])
    assert abs(fast.mean().real - POLES[2].real) < 4 * se[0] and abs(fast.mean().imag - POLES[2].imag) < 4 * se[1]
    assert float(mac(split.sensor_shape.values[2], SHAPES[2])) > 0.99


def test_bad_split_frequencies_are_refused(close_pair):
    for bad in (-1.0, 8.0, float("nan"), "6"):
        with pytest.raises(SignalError, match="differenced_above_hz must be a frequency from 0 to below fmax = 8 Hz"):
            _extract(close_pair, differenced_above_hz=bad)
