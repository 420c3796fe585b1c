"""Jackknife samples: consistent complex normalisation, honest spread against Monte Carlo."""

import json
import warnings

import numpy as np
import pytest

from twin.errors import SignalError
from twin.extract import extract
from twin.extract.samples import align_phase, normalise_at, order_average, order_deviations


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


def test_order_deviations_carry_the_spread_over_orders():
    """Zero mean over the samples; std / sqrt(J) is the std of the pole over the orders, and the standard error
    of the mean of the aligned shapes over them (their std over sqrt(n))."""
    rng = np.random.default_rng(3)
    p = -0.5 + 2j * np.pi * (2.0 + 0.01 * rng.standard_normal(5))
    s = (np.array([1.0, 0.6j]) + 0.05 * rng.standard_normal((5, 2))) * np.exp(1j * rng.uniform(0, 6, (5, 1)))
    ref = s[0] / np.linalg.norm(s[0])
    one = [(np.array([2]), p[:1], s[:1])]
    J = 40
    dp, ds = order_deviations([(np.arange(5), p, s)] + one, np.array([ref, ref]), J)
    assert np.allclose(dp.mean(axis=1), 0.0) and np.allclose(ds.mean(axis=1), 0.0)
    assert np.isclose(np.sqrt(np.sum(np.abs(dp[0]) ** 2) / (J - 1) / J), np.std(p, ddof=1))
    aligned = align_phase(s / np.linalg.norm(s, axis=1, keepdims=True), ref)
    # every order used J / 5 times, so the shape deviations have the orders' spread times the same scale,
    # over sqrt(5): the mean of 5 orders
    assert np.isclose(
        np.sum(np.abs(ds[0]) ** 2) / np.sum(np.abs(dp[0]) ** 2),
        np.sum(np.abs(aligned - aligned.mean(axis=0)) ** 2) / np.sum(np.abs(p - p.mean()) ** 2) / 5,
    )
    assert not dp[1].any() and not ds[1].any()  # one order: nothing to spread


def test_extraction_standard_error_has_its_two_parts(make_record):
    """frequency_se (from the samples) is the jackknife part and the order spread in quadrature (to sampling)."""
    poles = np.array([-0.02 * 2 * np.pi * 2.0 + 2j * np.pi * 2.0])
    ds = make_record(poles, np.array([[1.0, 0.6j, 0.3, 0.8j]]), fs_hz=20.0, duration_s=1000.0, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = extract(ds, samples=40, max_order=16, progress=False, delete_blocks=None, order_spread=True)
        plain = extract(ds, samples=40, max_order=16, progress=False, delete_blocks=None)
    for q in ("frequency", "damping_ratio"):
        total, jk, order = (float(m[f"{q}{x}"][0]) for x in ("_se", "_se_jackknife", "_order_std"))
        assert order > 0 and np.isclose(jk, float(plain[f"{q}_se"][0]))
        # the two parts are drawn independently: their cross term is of order 1/sqrt(J) of the sum
        assert abs(total**2 / (jk**2 + order**2) - 1) < 3 / np.sqrt(40), (q, total, jk, order)
    assert np.isclose(float(m.frequency[0]), float(plain.frequency[0]))  # same estimate
    # the pole's covariance over the orders, whose Im-Im part is the frequency's order spread
    cov = plain["pole_order_cov"].values[0]
    assert np.isclose(np.sqrt(cov[1, 1]) / (2 * np.pi), float(plain["frequency_order_std"][0]), rtol=1e-9)
    assert cov[0, 1] == cov[1, 0] and np.all(np.linalg.eigvalsh(cov) >= -1e-12 * cov.max())  # PSD to rounding


def test_shape_samples_of_their_own_keep_the_poles_standard_error(make_record):
    """extract(shape_samples=M): the shapes from M random halves of the blocks, the delete-one pole samples each
    used M / J times with the same standard error."""
    poles = np.array([-0.02 * 2 * np.pi * 2.0 + 2j * np.pi * 2.0])
    ds = make_record(poles, np.array([[1.0, 0.6j, 0.3, 0.8j]]), fs_hz=20.0, duration_s=1000.0, seed=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        both = extract(ds, samples=20, max_order=16, progress=False, shape_samples=60)
        one = extract(ds, samples=20, max_order=16, progress=False)
        halves = extract(ds, samples=60, blocks=20, max_order=16, progress=False, delete_blocks=None)
        none = extract(ds, samples=20, max_order=16, progress=False, shape_samples=0)
    assert none.sizes["sample"] == 20 and json.loads(none.attrs["settings"])["shape_samples"] == 20
    assert both.sizes["sample"] == 60 and json.loads(both.attrs["settings"])["shape_samples"] == 60
    np.testing.assert_array_equal(both["shape"].values, halves["shape"].values)
    p = both["pole"].values
    assert np.all(p[:, 0::3] == p[:, 1::3]) and np.all(p[:, 0::3] == p[:, 2::3])  # each used 3 times in a row
    assert np.isclose(p.mean(), one["pole"].values.mean(), rtol=1e-12)
    np.testing.assert_allclose(both.frequency_se, one.frequency_se, rtol=1e-9)
    # the damping ratio is not linear in the pole: its std moves a little with the scaled deviations
    np.testing.assert_allclose(both.damping_ratio_se, one.damping_ratio_se, rtol=0.05)
    assert "the shapes from 60 random halves of the blocks" in both.attrs["samples_method"]
    for bad in (30, 10, 2.5, -40, "60"):
        with pytest.raises(SignalError, match=f"shape_samples must be a whole multiple of samples = 20 .*got {bad!r}"):
            extract(ds, samples=20, max_order=16, progress=False, shape_samples=bad)
    # as many as the poles' (what a modes file records when the shapes come with the poles) is the same as none:
    # the loop's calibration re-extracts its records with the settings the file records
    same = extract(ds, samples=20, max_order=16, progress=False, shape_samples=20)
    np.testing.assert_array_equal(same["shape"].values, one["shape"].values)
    with pytest.raises(SignalError, match="shape_samples is not available with differenced_above_hz"):
        extract(ds, samples=20, max_order=16, progress=False, shape_samples=40, differenced_above_hz=1.0)


def _spread_ratios(make_record, seeds, delete_blocks=1):
    """Mean jackknife standard error / std over independent records, for frequency and damping ratio."""
    poles = np.array([-0.02 * 2 * np.pi * 2.0 + 2j * np.pi * 2.0])
    shapes = np.array([[1.0, 0.6j]])
    f, z, se_f, se_z, missed = [], [], [], [], 0
    for seed in range(seeds):
        ds = make_record(poles, shapes, fs_hz=20.0, duration_s=1000.0, seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                m = extract(ds, samples=20, max_order=16, progress=False, delete_blocks=delete_blocks)
            except SignalError:  # two channels, orders 8x the true one: the pole can wander too much to be stable
                missed += 1
                continue
        k = int(np.argmin(np.abs(m.frequency.values - 2.0)))
        f.append(float(m.frequency[k])), z.append(float(m.damping_ratio[k]))
        se_f.append(float(m.frequency_se_jackknife[k])), se_z.append(float(m.damping_ratio_se_jackknife[k]))
    assert missed <= seeds // 10, f"no mode found in {missed} of {seeds} records"
    return np.mean(se_f) / np.std(f, ddof=1), np.mean(se_z) / np.std(z, ddof=1)


@pytest.mark.slow  # 20-30 s: a non-default option, run in CI's slow pass
def test_more_samples_than_blocks_estimate_the_same_standard_error(make_record):
    """Delete-half: 60 random half-subsets of 20 blocks and 20 of them estimate one standard error (Shao-Wu
    scaling with M samples); delete-one cannot give more samples than blocks."""
    poles = np.array([-0.02 * 2 * np.pi * 2.0 + 2j * np.pi * 2.0])
    se = {20: [], 60: []}
    for seed in range(6):
        ds = make_record(poles, np.array([[1.0, 0.6j, 0.3, 0.8j]]), fs_hz=20.0, duration_s=1000.0, seed=seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for m_samples in se:
                m = extract(
                    ds,
                    samples=m_samples,
                    blocks=20,
                    max_order=16,
                    progress=False,
                    delete_blocks=None,
                    order_spread="none",
                )
                assert m.sizes["sample"] == m_samples and json.loads(m.attrs["settings"])["blocks"] == 20
                se[m_samples].append([float(m.frequency_se[0]), float(m.damping_ratio_se[0])])
    a, b = np.array(se[20]), np.array(se[60])
    # 6 records x 20 subsets know the mean SE to about +-7%: the two agree within 25%
    assert np.all(np.abs(b.mean(axis=0) / a.mean(axis=0) - 1) < 0.25), (a.mean(axis=0), b.mean(axis=0))
    with pytest.raises(SignalError, match="one sample per block"):
        extract(ds, samples=40, blocks=20, max_order=16, progress=False, delete_blocks=1)


def test_spread_ratio_against_independent_records(make_record):
    """sample std / sqrt(J) (jackknife standard error) against the std over 16 independent records."""
    ratio_f, ratio_z = _spread_ratios(make_record, 16)
    # 16 records estimate a std to about +-18%. Measured: 2.8 (frequency) and 1.6 (damping): the
    # delete-one samples are conservative (too wide), never too narrow; this pins that down.
    assert 0.8 < ratio_f < 4.0, ratio_f
    assert 0.8 < ratio_z < 2.5, ratio_z


@pytest.mark.slow
def test_spread_ratio_on_forty_records(make_record):
    """Delete-half samples on 40 records (std known to about +-11%): within +-30% and that sampling error.

    The delete-one jackknife gave 2.1 (frequency) and 1.8 (damping) here: it overstates the spread of a
    pole at model orders above the number of modes (:mod:`twin.extract.samples`).
    """
    ratio_f, ratio_z = _spread_ratios(make_record, 40, delete_blocks=None)
    assert 0.7 < ratio_f < 1.6, ratio_f
    assert 0.7 < ratio_z < 1.6, ratio_z
