"""twin.update.samplers.slice: slice sampling of independent blocks side by side."""

import numpy as np
import pytest
from scipy import stats

from twin.update.samplers.slice import block_axes, slice_blocks


def test_block_axes_are_the_principal_axes_of_each_blocks_conditional_precision():
    rng = np.random.default_rng(0)
    A = rng.normal(size=(7, 7))
    precision = A @ A.T + 7 * np.eye(7)  # one shared parameter, three blocks of two
    axes, widths = block_axes(precision, n_global=1, n_blocks=3, block_size=2, width=3.0)
    for i in range(3):
        block = precision[1 + 2 * i : 3 + 2 * i, 1 + 2 * i : 3 + 2 * i]
        # each axis is an eigenvector of the block, its width 3 conditional std along it
        curvature = np.einsum("ka,kl,la->a", axes[i], block, axes[i])
        np.testing.assert_allclose(block @ axes[i], axes[i] * curvature, atol=1e-12)
        np.testing.assert_allclose(widths[i], 3.0 / np.sqrt(curvature))


def test_correlated_gaussian_blocks_are_sampled_with_their_own_covariances():
    # three independent 2-D Gaussians with scales 1e-2 to 1e2 and correlations -0.9 to 0.9; the axes from
    # the exact precision (as the HMC metric gives them); 3000 sweeps of nearly independent draws: the
    # variance's relative Monte Carlo error is about sqrt(2 / 3000) = 2.6%, the tolerance 4 times that
    covs = np.array([[[1e-4, 0.9e-4], [0.9e-4, 1e-4]], [[1.0, -0.9 * 3], [-0.9 * 3, 9.0]], [[1e4, 0.0], [0.0, 4e2]]])
    prec = np.linalg.inv(covs)
    full = np.zeros((6, 6))
    for i in range(3):
        full[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = prec[i]
    axes, widths = block_axes(full, n_global=0, n_blocks=3, block_size=2)
    mean = np.array([[1.0, -1.0], [5.0, 0.0], [-300.0, 20.0]])

    def log_f(x):
        d = x - mean
        return -0.5 * np.einsum("ia,iab,ib->i", d, prec, d)

    rng = np.random.default_rng(1)
    x, draws = mean.copy(), []
    for _ in range(3000):
        x, f = slice_blocks(log_f, x, axes, widths, rng)
        draws.append(x)
    draws = np.array(draws)
    np.testing.assert_allclose(f, log_f(x))
    for i in range(3):
        c = np.cov(draws[:, i].T)
        sd = np.sqrt(np.diag(covs[i]))
        np.testing.assert_allclose(np.sqrt(np.diag(c)), sd, rtol=0.05)
        assert c[0, 1] / np.prod(np.sqrt(np.diag(c))) == pytest.approx(covs[i][0, 1] / np.prod(sd), abs=0.03)
        assert np.all(np.abs(draws[:, i].mean(axis=0) - mean[i]) < 0.1 * sd)


def test_a_heavy_tail_is_followed_by_stepping_out():
    # a Student t with 3 degrees of freedom from the interval the sampler uses, 2 std of the curvature at its
    # mode (2 sqrt(3/4)): its 99% quantile is 5.2 such std out. Over 8000 draws the share below each of its
    # 1%, 10%, 50%, 90% and 99% quantiles is within 3 binomial std of an effective 4000 draws
    rng = np.random.default_rng(2)
    log_f = lambda x: stats.t.logpdf(x[:, 0], df=3)  # noqa: E731
    x, draws = np.zeros((1, 1)), []
    for _ in range(8000):
        x, _ = slice_blocks(log_f, x, np.ones((1, 1, 1)), np.full((1, 1), 2 * np.sqrt(0.75)), rng)
        draws.append(x[0, 0])
    q = np.array([0.01, 0.1, 0.5, 0.9, 0.99])
    below = np.mean(np.array(draws)[:, None] < stats.t.ppf(q, df=3), axis=0)
    np.testing.assert_array_less(np.abs(below - q), 3 * np.sqrt(q * (1 - q) / 4000))


def test_a_block_never_leaves_its_support():
    # two half-normal blocks (log density -inf below zero): no draw below zero, and the half-normal's mean
    rng = np.random.default_rng(3)
    log_f = lambda x: np.where(x[:, 0] >= 0, -0.5 * x[:, 0] ** 2, -np.inf)  # noqa: E731
    x, draws = np.ones((2, 1)), []
    for _ in range(3000):
        x, _ = slice_blocks(log_f, x, np.ones((2, 1, 1)), np.ones((2, 1)), rng)
        draws.append(x[:, 0])
    draws = np.array(draws)
    assert draws.min() >= 0.0
    np.testing.assert_allclose(draws.mean(axis=0), np.sqrt(2 / np.pi), rtol=0.06)
    # a block that starts outside its support could never close in on a point of the slice
    with pytest.raises(ValueError, match=r"block\(s\) \[1\] start where their log density is not finite"):
        slice_blocks(log_f, np.array([[1.0], [-1.0]]), np.ones((2, 1, 1)), np.ones((2, 1)), rng)
