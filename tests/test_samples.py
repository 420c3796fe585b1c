"""Jackknife samples: consistent complex normalisation, honest spread against Monte Carlo."""

import warnings

import numpy as np

from twin.extract import extract
from twin.extract.samples import align_phase, normalise_at, order_average


def test_align_and_normalise_keep_shapes_complex_and_consistent():
    rng = np.random.default_rng(0)
    ref = np.array([1.0, 0.5j, -0.3 + 0.2j])
    shapes = ref * np.exp(1j * rng.uniform(0, 2 * np.pi, (6, 1))) * rng.uniform(0.5, 2, (6, 1))
    aligned = align_phase(shapes, ref)
    assert np.allclose(aligned / np.abs(shapes[:, :1]), ref, atol=1e-12)
    out = normalise_at(shapes, 1)
    assert np.allclose(np.linalg.norm(out, axis=1), 1.0)
    assert np.allclose(out[:, 1].imag, 0.0, atol=1e-12) and np.all(out[:, 1].real > 0)
    assert np.allclose(out, out[0], atol=1e-12)  # same shape, same normalisation in every sample
    assert abs(out[0, 2].imag) > 0.1  # the other components stay complex


def test_order_average_of_identical_estimates_is_that_estimate():
    s = np.array([[1.0, 1j], [1j, -1.0]])  # the same shape up to a phase
    p, shape = order_average(np.array([1 + 2j, 1 + 2j]), s, s[0])
    assert p == 1 + 2j and np.allclose(shape, s[0] / np.sqrt(2))


def test_spread_ratio_against_independent_records(make_record):
    """sample std / sqrt(J) (jackknife standard error) against the std over 16 independent records."""
    poles = np.array([-0.02 * 2 * np.pi * 2.0 + 2j * np.pi * 2.0])
    shapes = np.array([[1.0, 0.6j]])
    f, z, se_f, se_z = [], [], [], []
    for seed in range(16):
        ds = make_record(poles, shapes, fs_hz=20.0, duration_s=1000.0, seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = extract(ds, samples=20, max_order=16, progress=False)
        k = int(np.argmin(np.abs(m.frequency.values - 2.0)))
        f.append(float(m.frequency[k])), z.append(float(m.damping_ratio[k]))
        se_f.append(float(m.frequency_se[k])), se_z.append(float(m.damping_ratio_se[k]))
    ratio_f = np.mean(se_f) / np.std(f, ddof=1)
    ratio_z = np.mean(se_z) / np.std(z, ddof=1)
    # 16 records estimate a std to about +-18%. Measured: 2.8 (frequency) and 1.6 (damping): the
    # samples are conservative (too wide), never too narrow; this pins that down.
    assert 0.8 < ratio_f < 4.0, ratio_f
    assert 0.8 < ratio_z < 2.5, ratio_z
