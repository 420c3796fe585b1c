"""The control chart: standardisation, its limit, the statistic in control, the onset of a shift."""

import numpy as np
import pytest
from scipy import stats

from twin.track import detect


def test_the_factor_on_the_standard_errors_and_the_correlation_are_learned():
    rng = np.random.default_rng(3)
    se = rng.uniform(0.5, 2.0, size=(2000, 3))
    mix = np.array([[1.0, 0.0, 0.0], [0.6, 0.8, 0.0], [0.0, 0.0, 1.0]])
    r = (rng.normal(size=(2000, 3)) @ mix.T) * se * [1.0, 1.5, 0.7] + [0.0, 2.0, -1.0]
    b = detect.learn_baseline(r, se)
    assert np.allclose(b.scale, [1.0, 1.5, 0.7], rtol=0.05)
    assert b.correlation[0, 1] == pytest.approx(0.6, abs=0.05) and abs(b.correlation[0, 2]) < 0.05
    assert np.allclose(b.center, [0.0, 2.0, -1.0], atol=0.1)


def test_the_limit_is_the_phase_two_limit_and_tends_to_the_chi_square_quantile():
    alpha = 0.1 / (4 * 365.25)
    assert detect.threshold(9, 10**7, 4 * 365.25) == pytest.approx(stats.chi2.isf(alpha, 9), rel=1e-3)
    assert detect.threshold(9, 24, 4 * 365.25) > 3 * detect.threshold(9, 10**7, 4 * 365.25)
    with pytest.raises(ValueError, match="needs more than 10 baseline records"):
        detect.threshold(9, 10, 1460.0)


def test_in_control_the_statistic_is_chi_square_and_a_shift_builds_up():
    rng = np.random.default_rng(5)
    p, lam = 4, 0.2
    b = detect.Baseline(np.zeros(p), np.ones(p), np.eye(p), 10**6)
    z = rng.normal(size=(20000, p))
    t2 = detect.mewma(z, b, lam)[100:]  # past the start-up from zero
    assert t2.mean() == pytest.approx(p, rel=0.05)
    assert np.mean(t2 > stats.chi2.isf(0.01, p)) == pytest.approx(0.01, abs=0.004)
    shifted = np.r_[rng.normal(size=(50, p)), rng.normal(size=(30, p)) + [2.0, 0.0, 0.0, 0.0]]
    t2 = detect.mewma(shifted, b, lam)
    assert t2[70:].mean() > 3 * t2[:50].mean()
    assert 47 <= detect.onset(shifted, b) <= 53


def test_what_the_baseline_leaves_uncertain_is_counted_so_the_statistic_stays_chi_square():
    # each campaign learns its centre (Hodges-Lehmann) over a short baseline, and shares a slope error that moves
    # its records' residuals by g_r @ delta, with g_r varying from record to record (the operating point)
    rng = np.random.default_rng(11)
    p, n, lam, k = 3, 40, 0.2, 2
    slope_cov = np.diag([0.04, 0.01])
    t2 = []
    for _ in range(300):
        center = detect.hodges_lehmann(rng.normal(size=(n, p)))
        b = detect.Baseline(center, np.ones(p), np.eye(p), n)
        delta = rng.multivariate_normal(np.zeros(k), slope_cov)
        g = rng.normal(size=(120, p, k))
        z = rng.normal(size=(120, p)) + g @ delta - center
        chart = detect.MEWMA(b, lam, uncertain=slope_cov)
        t2.append([chart.add(zi, gi) for zi, gi in zip(z, g)][40:])
    assert np.mean(t2) == pytest.approx(p, rel=0.1)
    assert np.mean(np.array(t2) > stats.chi2.isf(0.01, p)) < 0.02


def test_pooled_residuals_weigh_each_record_by_its_standard_error():
    b = detect.Baseline(np.zeros(2), np.ones(2), np.eye(2), 100)
    r = np.array([[1.0, np.nan], [3.0, 2.0]])
    se = np.array([[1.0, 1.0], [1.0, 2.0]])
    mean, cov = detect.pooled(r, se, b)
    assert mean == pytest.approx([2.0, 2.0]) and cov.diagonal() == pytest.approx([0.5, 4.0])


def test_the_step_statistic_is_chi_square_in_control_at_each_onset():
    """With the correlation known and nothing shared, the ratio at one onset is chi-square with the candidate's
    degrees of freedom: its 1% quantile is exceeded by 1% of the records, for one and two directions."""
    rng = np.random.default_rng(11)
    p = 4
    mix = rng.normal(size=(p, p))
    C = mix @ mix.T + p * np.eye(p)
    R = C / np.sqrt(np.outer(C.diagonal(), C.diagonal()))
    L = np.linalg.cholesky(R)
    J1, J2 = rng.normal(size=(p, 1)), rng.normal(size=(p, 2))
    glr = detect.StepGLR(R, [J1, J2], level=0.0, onsets=(1,))
    stats_ = np.array([glr.add(L @ rng.normal(size=p), rng.uniform(0.5, 2.0, p)) for _ in range(20000)])
    for c, k in enumerate((1, 2)):
        assert np.mean(stats_[:, c] > stats.chi2.isf(0.01, k)) == pytest.approx(0.01, abs=0.002)


def test_a_step_builds_up_with_the_records_until_the_baseline_s_own_error_caps_it():
    """A noise-free step theta along a direction a: from N records back the ratio is N F theta^2 / (1 + level N)
    (F = a' R^-1 a), so it grows with the records and tends to F theta^2 / level, what the baseline's centre
    leaves uncertain; a reset forgets the records."""
    R = np.array([[1.0, 0.3], [0.3, 1.0]])
    a = np.array([[1.0], [0.5]])
    F = (a.T @ np.linalg.solve(R, a)).item()
    theta, level = 0.4, 0.02
    glr = detect.StepGLR(R, [a], level=level, onsets=(1, 2, 4, 8, 16, 32))
    for n in range(1, 33):
        value = glr.add(a[:, 0] * theta, np.ones(2))[0]
        back = max(k for k in (1, 2, 4, 8, 16, 32) if k <= n)
        assert value == pytest.approx(back * F * theta**2 / (1 + level * back), rel=1e-10)
    assert value < F * theta**2 / level
    glr.reset()
    assert glr.add(np.zeros(2), np.ones(2))[0] == 0.0
