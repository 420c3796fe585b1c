"""twin.loop.pooling: the error ratios pooled over parameters, and the interval widened for a few records."""

import numpy as np
import pytest

from twin.loop.pooling import pooled_rms, predictive_widening


def test_pooled_rms_shrinks_the_records_noise_and_keeps_real_differences():
    from scipy.special import polygamma

    rng = np.random.default_rng(5)
    # the noise the shrinkage assumes: log of a mean of 12 squared normals has variance psi'(6) = 0.1813
    y = np.log(np.mean(rng.standard_normal((200_000, 12)) ** 2, axis=1))
    assert np.var(y) == pytest.approx(polygamma(1, 6), rel=0.02)
    records, members = np.full(16, 12), np.ones(16, bool)
    # sixteen parameters with one true RMS error 1.3, each seen on 12 records: their spread (20% here) is
    # the records' noise, and every one is pulled to the pooled value sqrt(mean c²)
    rng = np.random.default_rng(1)
    c = np.sqrt(np.mean((1.3 * rng.standard_normal((12, 16))) ** 2, axis=0))
    shrunk, tau2 = pooled_rms(c, records, members)
    assert c.std() / c.mean() > 0.15 and tau2 == 0.0
    np.testing.assert_allclose(shrunk, np.sqrt(np.mean(c**2)), rtol=1e-12)
    # true RMS errors 0.4 and 4 (ten times apart): a difference 12 records cannot blur, each value stays
    true = np.repeat([0.4, 4.0], 8)
    c = np.sqrt(np.mean((true * rng.standard_normal((12, 16))) ** 2, axis=0))
    shrunk, tau2 = pooled_rms(c, records, members)
    assert tau2 > 2.0
    assert np.max(np.abs(np.log(shrunk / c))) < 0.1
    # non-members are left alone and do not move the pool
    alone, _ = pooled_rms(np.append(c, 50.0), np.append(records, 12), np.append(members, False))
    np.testing.assert_array_equal(alone, np.append(shrunk, 50.0))


def test_the_widened_interval_covers_a_new_error_90_percent_of_the_time():
    # the exact property the t widening stands on: z ~ N(0, c^2), c^2 estimated by the mean square of R draws,
    # a new z falls inside +-1.645 c_hat widening for 90% of repetitions (40000: 0.90 to +-0.004 at 2.7 sigma)
    rng = np.random.default_rng(62)
    for records in (4, 12):
        z = 1.3 * rng.standard_normal((40000, records + 1))
        c_hat = np.sqrt(np.mean(z[:, :records] ** 2, axis=1))
        inside = np.abs(z[:, -1]) <= 1.6448536 * c_hat * predictive_widening(records)
        assert inside.mean() == pytest.approx(0.90, abs=0.004)
        bare = np.abs(z[:, -1]) <= 1.6448536 * c_hat
        assert bare.mean() < 0.885  # without it: 83.5% (R = 4), 87.4% (R = 12)
