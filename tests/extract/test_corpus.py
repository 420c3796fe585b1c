"""Records of structures that are not the twin's: exact modes, visibility, scoring, and the extraction's
defaults on them (every visible mode, nothing spurious, the same modes whatever the number of samples)."""

import warnings

import numpy as np
import pytest

from twin.extract import extract
from twin.extract.corpus import (
    cantilever,
    close_pair,
    frequency_limit,
    score,
    shear_frame,
    simulate_record,
    truth_modes,
)
from twin.extract.signals import check_record

V, A = "velocity", "acceleration"


def _extract(ds, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return extract(ds, progress=False, **kw)


def test_shear_frame_modes_are_the_closed_form_ones():
    n, m, k, zeta = 6, 2e3, 5e6, 0.02
    truth = truth_modes(shear_frame(n, mass_kg=m, stiffness_n_m=k, damping_ratio=zeta))
    j = np.arange(1, n + 1)
    wn = 2 * np.sqrt(k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1)))
    np.testing.assert_allclose(truth.frequency.values, wn * np.sqrt(1 - zeta**2) / (2 * np.pi), rtol=1e-10)
    np.testing.assert_allclose(truth.damping_ratio.values, zeta, rtol=1e-10)


def test_cantilever_modes_converge_to_euler_bernoulli():
    ei, mu, length = 2e4, 5.0, 2.0
    truth = truth_modes(cantilever(20, length_m=length, ei_n_m2=ei, mass_per_m=mu, damping_ratio=0.0001))
    beta_l = np.array([1.875104, 4.694091, 7.854757])
    exact = beta_l**2 / (2 * np.pi * length**2) * np.sqrt(ei / mu)
    np.testing.assert_allclose(truth.frequency.values[:3], exact, rtol=2e-4)


def test_a_record_is_in_its_quantities_and_units_at_its_signal_to_noise_ratio():
    frame = shear_frame(4)
    quantities = ["displacement", V, A, V]
    ds = simulate_record(frame, duration_s=200.0, fs_hz=20.0, snr_db=20.0, quantities=quantities, seed=3)
    assert ds["units"].values.tolist() == ["um", "mm/s", "g", "mm/s"]
    rec = check_record(ds)
    assert rec.quantities == tuple(quantities)
    noise = np.asarray(ds.attrs["noise_std_si"])
    np.testing.assert_allclose(noise / rec.y.std(axis=0), 10 ** (-20 / 20), rtol=0.01)  # std of signal + noise


def test_fewer_modes_are_visible_in_more_noise():
    frame = shear_frame(5, damping_ratio=0.01)
    counts = [
        int(truth_modes(frame, simulate_record(frame, duration_s=60.0, fs_hz=20.0, snr_db=snr, seed=1)).visible.sum())
        for snr in (40, 10, 0, -10)
    ]
    assert counts[0] == 5 and counts == sorted(counts, reverse=True) and counts[-1] < 5


def test_score_counts_found_missed_and_spurious():
    truth = truth_modes(shear_frame(3, damping_ratio=0.01))
    f, phi = truth.frequency.values, truth.sensor_shape.values
    s = score(np.r_[f[0] * 1.001, f[1] * 1.003, f[1] * 1.004, 9.0], np.r_[phi[[0, 1, 1]], phi[[2]]], truth)
    assert s["found"] == [f[0], f[1]] and s["missed"] == [f[2]]
    assert s["spurious"] == [f[1] * 1.004, 9.0]  # a second estimate of one mode, and nothing there
    wrong_shape = score(f, phi[[1, 0, 2]], truth)
    assert len(wrong_shape["found"]) == 1 and len(score(f, None, truth)["found"]) == 3


def test_the_frequency_tolerance_widens_to_what_one_record_allows():
    assert frequency_limit(5.0, 0.001, 3600.0) == 0.005
    assert frequency_limit(0.6, 0.05, 300.0) == pytest.approx(3 * np.sqrt(0.05 / (np.pi * 0.6 * 300.0)))


@pytest.mark.parametrize(
    ("structure", "duration_s", "fs_hz", "snr_db", "quantities"),
    [
        (shear_frame(10, stiffness_n_m=1.6e8, damping_ratio=0.002), 240.0, 100.0, 40.0, [V, V, V, A, A] * 2),
        (shear_frame(6, stiffness_n_m=1.6e8, damping_ratio=0.005), 60.0, 100.0, 40.0, ["displacement", V, A] * 2),
        (cantilever(8, damping_ratio=0.02, sensors=4), 150.0, 400.0, 40.0, A),
        (close_pair(4.0, 0.01, 0.005), 1800.0, 16.0, 40.0, "displacement"),
        (shear_frame(5, damping_ratio=0.001), 240.0, 20.0, 40.0, V),  # 0.9 Hz: 240 s is 1.4 time constants
    ],
    ids=["240s-0.2%-vel-acc", "60s-0.5%-mixed", "cantilever-2%-acc", "two-modes-1%-apart", "240s-0.1%-slow-mode"],
)
def test_defaults_find_every_visible_mode_and_nothing_spurious(structure, duration_s, fs_hz, snr_db, quantities):
    ds = simulate_record(structure, duration_s=duration_s, fs_hz=fs_hz, snr_db=snr_db, quantities=quantities, seed=11)
    truth = truth_modes(structure, ds)
    s = score(*(_extract(ds)[v].values for v in ("frequency", "sensor_shape")), truth)
    assert not s["missed"] and not s["spurious"] and len(s["found"]) == int(truth.visible.sum()) >= 2, s


@pytest.mark.slow
def test_the_modes_found_do_not_move_with_the_number_of_samples():
    """In blocks shorter than three time constants a pole is judged on its frequency alone, so the modes
    found are the same from 4 to 60 samples of a 240 s record of 0.2%-damped modes (16 to 1 time
    constants of the slowest per block)."""
    frame = shear_frame(10, stiffness_n_m=1.6e8, damping_ratio=0.002)
    ds = simulate_record(frame, duration_s=240.0, fs_hz=100.0, snr_db=40.0, quantities=[V, V, V, A, A] * 2, seed=5)
    truth = truth_modes(frame, ds)
    found = [
        score(*(_extract(ds, samples=j)[v].values for v in ("frequency", "sensor_shape")), truth) for j in (4, 15, 60)
    ]
    assert all(s["found"] == found[0]["found"] and not s["spurious"] for s in found)
    assert len(found[0]["found"]) == 10
