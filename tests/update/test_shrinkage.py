"""twin.update.shrinkage: shape covariances with their correlations shrunk, and the intensity."""

import numpy as np
import pytest

from twin.update.shrinkage import INTENSITY_GRID, held_out_intensity, shrunk_covariance


def test_shrunk_covariance_keeps_real_correlations_and_drops_chance_ones():
    rng = np.random.default_rng(5)
    # J = 15 samples of 16 entries, all driven by one common error plus their own: correlation 0.8
    common = rng.standard_normal((400, 15, 1))
    x = 2.0 * common + rng.standard_normal((400, 15, 16))
    cov = shrunk_covariance(x, np.var(x, axis=1, ddof=1))
    corr = cov / np.sqrt(
        np.diagonal(cov, axis1=1, axis2=2)[:, :, None] * np.diagonal(cov, axis1=1, axis2=2)[:, None, :]
    )
    off = ~np.eye(16, dtype=bool)
    assert np.mean(corr[:, off]) == pytest.approx(0.8 * (1 - 0.15), abs=0.06)  # kept, shrunk by about 0.15 at J = 15
    assert np.all(np.linalg.eigvalsh(cov) > 0)  # positive definite although J - 1 < 16
    # the variance of the mean along the common direction: the samples' covariance, not their variances alone
    u = np.ones(16)
    assert np.median(u @ cov @ u / (u @ (np.diagonal(cov, axis1=1, axis2=2) * u).T)) > 10
    # independent entries: the chance correlations of 15 samples (std 0.26) are mostly shrunk away
    y = rng.standard_normal((400, 15, 16))
    cy = shrunk_covariance(y, np.var(y, axis=1, ddof=1))
    r = cy / np.sqrt(np.diagonal(cy, axis1=1, axis2=2)[:, :, None] * np.diagonal(cy, axis1=1, axis2=2)[:, None, :])
    assert np.sqrt(np.mean(r[:, off] ** 2)) < 0.1
    # many samples: the sample covariance
    z = rng.standard_normal((20000, 3)) @ np.array([[1.0, 0.5, 0.0], [0.0, 1.0, 0.3], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(shrunk_covariance(z, np.var(z, axis=0, ddof=1)), np.cov(z.T), atol=0.01)


def _held_out_by_definition(x: np.ndarray) -> float:
    """The intensity by its definition, one covariance and one solve per held-out sample and grid point."""
    J, n = x.shape
    scores = []
    for lam in INTENSITY_GRID:
        score = 0.0
        for j in range(J):
            rest = np.delete(x, j, axis=0)
            d = rest.std(axis=0, ddof=1)
            C = ((1 - lam) * np.corrcoef(rest.T) + lam * np.eye(n)) * np.outer(d, d) * J / (J - 1)
            r = x[j] - rest.mean(axis=0)
            score -= 0.5 * (np.linalg.slogdet(C)[1] + r @ np.linalg.solve(C, r))
        scores.append(score)
    return float(INTENSITY_GRID[int(np.argmax(scores))])


def test_held_out_intensity_is_its_definition_and_ignores_entries_without_scatter():
    rng = np.random.default_rng(3)
    for _ in range(3):
        x = rng.standard_normal((15, 1)) * rng.uniform(0, 2) + rng.standard_normal((15, 12)) * rng.uniform(0.5, 2, 12)
        assert held_out_intensity(x) == pytest.approx(_held_out_by_definition(x), abs=1e-12)
        # the reference channel's imaginary part: zero up to round-off in every sample, left out
        still = np.concatenate([x, 1e-20 * rng.standard_normal((15, 1))], axis=1)
        assert held_out_intensity(still) == held_out_intensity(x)
    assert held_out_intensity(np.ones((6, 3))) == 1.0  # nothing scatters: nothing to shrink
    batch = rng.standard_normal((2, 3, 10, 5))
    assert held_out_intensity(batch).shape == (2, 3)
    with pytest.raises(ValueError, match="at least 4 samples"):
        held_out_intensity(rng.standard_normal((3, 5)))
    with pytest.raises(ValueError, match=r"within \(0, 1\]"):
        held_out_intensity(rng.standard_normal((10, 5)), grid=np.array([0.0, 0.5]))


def test_held_out_intensity_is_closer_in_the_likelihoods_loss_where_errors_share_directions():
    # J = 15 samples of 16 entries whose errors share three strong directions, as a mode's shape errors do:
    # the covariance the Gaussian likelihood uses is judged by Stein's loss tr(C⁻¹S) - log det(C⁻¹S) - n
    rng = np.random.default_rng(0)
    n, J = 16, 15

    def stein(C, S):
        M = np.linalg.solve(C, S)
        return np.mean(np.trace(M, axis1=1, axis2=2) - np.linalg.slogdet(M)[1] - n)

    A = 3.0 * rng.standard_normal((n, 3))
    S = A @ A.T + np.diag(rng.uniform(0.5, 2.0, n))
    x = rng.standard_normal((300, J, n)) @ np.linalg.cholesky(S).T
    var = x.var(axis=1, ddof=1)
    held_out = stein(shrunk_covariance(x, var, intensity=held_out_intensity(x)), S)
    assert held_out < 0.7 * stein(shrunk_covariance(x, var), S)  # 8.1 against 14.5 for Schäfer-Strimmer's
    # independent entries: about the identity, as Schäfer and Strimmer's
    y = rng.standard_normal((300, J, n))
    assert np.median(held_out_intensity(y)) > 0.9
    vy = y.var(axis=1, ddof=1)
    assert stein(shrunk_covariance(y, vy, intensity=held_out_intensity(y)), np.eye(n)) == pytest.approx(
        stein(shrunk_covariance(y, vy), np.eye(n)), rel=0.1
    )
