"""Harmonic recognition: band kurtosis 1.5 for a sinusoid, 3 for a mode's random response."""

import numpy as np
import pytest
import scipy.signal as sg

from twin.extract.harmonics import _line_power, band_kurtosis, grid_power, harmonic_test, remove_running_harmonics


def test_kurtosis_of_sinusoid_plus_noise_follows_the_mixture_formula():
    rng = np.random.default_rng(0)
    n, fs = 400_000, 100.0
    t = np.arange(n) / fs
    s = 0.3 * np.sin(2 * np.pi * 5.0 * t)
    g = rng.standard_normal(n)

    def band(x):
        return band_kurtosis(np.fft.rfft(x[:, None], axis=0), n, fs, 4.9, 5.1)

    (k,), _ = band(s + g)
    _, (ps,) = band(s)
    _, (pg,) = band(g)
    r = ps / (ps + pg)  # sinusoid share of the band power
    assert abs(k - (3 - 1.5 * r**2)) < 0.1


def test_harmonic_flagged_with_its_order_and_a_lightly_damped_mode_not():
    rng = np.random.default_rng(1)
    fs, n = 64.0, 200_000
    t = np.arange(n) / fs
    lam = -0.005 * 2 * np.pi * 3.0 + 2j * np.pi * 3.0  # 0.5% damped mode at 3 Hz
    q = sg.lfilter([1.0], [1.0, -np.exp(lam / fs)], rng.standard_normal(n) + 1j * rng.standard_normal(n))
    y = np.column_stack([q.real, q.imag]) + 3.0 * np.column_stack(
        [np.cos(2 * np.pi * 2.25 * t), np.sin(2 * np.pi * 2.25 * t)]
    )
    spec = np.fft.rfft(y, axis=0)
    h = harmonic_test(spec, n, fs, 1e-5 + 2j * np.pi * 2.25, running_speed_hz=2.25)
    assert h is not None and h["kurtosis"] < 1.8 and h["running_speed_multiple"] == 1
    assert harmonic_test(spec, n, fs, lam) is None  # Gaussian band: a mode
    assert harmonic_test(spec, n, fs, -0.05 * 2 * np.pi * 2.25 + 2j * np.pi * 2.25) is None  # 5% damped: not tested


def test_lightly_damped_mode_away_from_the_running_speed_multiples_is_no_harmonic():
    """A 1.11 Hz mode at 0.15% damping over 20 min: its band holds about 13 independent values, and its band
    kurtosis can fall below the threshold by chance; at 0.5X it is no harmonic of the running speed."""
    rng = np.random.default_rng(7)
    fs, n = 16.0, 19_200  # 20 min
    lam = -0.0015 * 2 * np.pi * 1.113 + 2j * np.pi * 1.113
    draws = []
    for _ in range(12):
        q = sg.lfilter([1.0], [1.0, -np.exp(lam / fs)], rng.standard_normal(n) + 1j * rng.standard_normal(n))
        y = np.column_stack([q.real, q.imag])
        spec = np.fft.rfft(y, axis=0)
        draws.append(band_kurtosis(spec, n, fs, 1.113 * 0.995, 1.113 * 1.005)[0].max())
        assert harmonic_test(spec, n, fs, lam, running_speed_hz=134 / 60) is None
        assert harmonic_test(spec, n, fs, lam) is None  # without the speed: damped beyond a sinusoid of 20 min
    assert min(draws) < 2.8  # the kurtosis alone would be a coin toss: it does scatter far below 3


def test_sinusoid_at_a_multiple_of_the_running_speed_is_a_harmonic_on_a_short_record():
    fs, n = 16.0, 19_200
    t = np.arange(n) / fs
    f2 = 2 * 134 / 60  # 2X
    y = np.column_stack([np.cos(2 * np.pi * f2 * t), np.sin(2 * np.pi * f2 * t)])
    y += 0.1 * np.random.default_rng(0).standard_normal(y.shape)
    spec = np.fft.rfft(y, axis=0)
    h = harmonic_test(spec, n, fs, -1e-6 + 2j * np.pi * f2, running_speed_hz=134 / 60)
    assert h is not None and h["running_speed_multiple"] == 2
    assert harmonic_test(spec, n, fs, -1e-6 + 2j * np.pi * f2) is not None  # without the speed too


def test_running_speed_lines_are_removed_at_the_refined_speed_and_nothing_else(make_record):
    # a 7.5%-damped mode at 2.6 Hz under a strong 1X line and a weak 2X one; the record's speed is 0.1% off
    lam = -0.075 * 2 * np.pi * 2.6 + 2j * np.pi * 2.6 * np.sqrt(1 - 0.075**2)
    f1 = 134.134 / 60
    ds = make_record([lam], np.array([[1.0, 0.5j]]), fs_hz=20.0, duration_s=1200.0, seed=3)
    t = ds["time"].values
    y = ds["displacement"].values
    line = np.outer(np.cos(2 * np.pi * f1 * t + 0.3), [5.0, 2.0]) + np.outer(np.sin(4 * np.pi * f1 * t), [0.0, 1.0])
    clean, removed = remove_running_harmonics(y - y.mean(0) + line, 20.0, 134 / 60, 8.0)
    assert [r["running_speed_multiple"] for r in removed] == [1, 2]
    assert removed[0]["frequency_hz"] == pytest.approx(f1, rel=1e-6)
    # the fit also takes the random response in the line's frequency bin: 3% of the 1X amplitude here
    assert [r["amplitude"] for r in removed] == pytest.approx([5.0, 1.0], rel=0.05)
    # what was taken away is two sinusoids at the lines and nothing else
    taken = (y - y.mean(0) + line) - clean
    basis = np.column_stack([f(2 * np.pi * r["frequency_hz"] * t) for r in removed for f in (np.cos, np.sin)])
    rest = taken - basis @ np.linalg.lstsq(basis, taken, rcond=None)[0]
    assert np.abs(rest).max() < 1e-9 * np.abs(taken).max()
    # a record without lines loses nothing
    same, none = remove_running_harmonics(y - y.mean(0), 20.0, 134 / 60, 8.0)
    assert none == [] and np.array_equal(same, y - y.mean(0))


def test_the_speed_search_grid_power_is_each_frequency_s_periodogram():
    # the chirp-z transform against one complex exponential per frequency, on the running speed's search grid
    # of a 10-min record at 64 Hz with a 1X line inside it
    rng = np.random.default_rng(3)
    fs, n = 64.0, 38_400
    t = np.arange(n) / fs
    y = rng.standard_normal((n, 3)) + np.outer(np.cos(2 * np.pi * 2.2351 * t), [2.0, 1.0, 0.5])
    grid = 134 / 60 * (1 + np.linspace(-0.005, 0.005, 41))
    direct = np.array([_line_power(y, t, f) for f in grid])
    fast = grid_power(y, fs, grid)
    assert np.max(np.abs(fast - direct)) < 1e-9 * direct.max()
    assert np.argmax(fast) == np.argmax(direct)
    assert grid_power(y, fs, grid[:1]) == pytest.approx(direct[:1], rel=1e-12)
