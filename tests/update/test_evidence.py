"""The one evidence formula: exact for a linear-Gaussian hypothesis, checked against direct computations."""

import numpy as np
import scipy.integrate
import scipy.stats

from twin.update.evidence import linear_fit, log_evidence


def test_linear_fit_is_the_ratio_of_the_two_gaussian_marginal_likelihoods():
    rng = np.random.default_rng(5)
    n, k = 7, 2
    J = rng.normal(size=(n, k))
    scale = np.array([0.5, 2.0])
    A = rng.normal(size=(n, n))
    cov = A @ A.T / n + 0.1 * np.eye(n)
    y = J @ np.array([0.3, -1.0]) + rng.multivariate_normal(np.zeros(n), cov)

    f = linear_fit(y, J, scale, cov)

    with_change = scipy.stats.multivariate_normal(np.zeros(n), cov + (J * scale**2) @ J.T).logpdf(y)
    no_change = scipy.stats.multivariate_normal(np.zeros(n), cov).logpdf(y)
    assert np.isclose(f.log_bayes_factor, with_change - no_change, rtol=1e-10)
    ci = np.linalg.inv(cov)
    post = np.linalg.inv(J.T @ ci @ J + np.diag(1 / scale**2))
    assert np.allclose(f.covariance, post, rtol=1e-10)
    assert np.allclose(f.values, post @ J.T @ ci @ y, rtol=1e-10)
    e = y - J @ f.values
    assert np.isclose(f.chi2, e @ ci @ e, rtol=1e-10)


def test_laplace_evidence_of_a_linear_model_is_the_integral_over_the_prior():
    a, y = np.array([1.5, -0.4, 0.7]), np.array([0.9, 0.1, 0.8])
    H = np.array([[1.0 + a @ a]])
    u = np.array([a @ y / H[0, 0]])

    def integrand(x: float) -> float:
        r = y - a * x
        return scipy.stats.norm.pdf(x) * np.exp(-0.5 * r @ r)

    z, _ = scipy.integrate.quad(integrand, -20, 20, epsabs=1e-14)
    assert np.isclose(log_evidence(y - a * u, u, H), np.log(z), rtol=1e-10)
    # the truncated prior's mass enters as its log: a sign constraint halves the prior
    assert np.isclose(log_evidence(y - a * u, u, H, np.log(0.5)) - log_evidence(y - a * u, u, H), np.log(2))


def test_the_simplest_form_the_data_allow_is_named():
    """A richer form is named only beyond the margin over the form it holds; unrelated effects play no part."""
    from twin.update.evidence import simplest

    evidence = {"fsi_per_mode": 52.0, "fsi": 50.0, "magnetic_pull": 51.9}
    assert simplest("fsi_per_mode", evidence, 3.0) == "fsi"
    assert simplest("fsi_per_mode", evidence, 1.0) == "fsi_per_mode"
    assert simplest("magnetic_pull", evidence, 3.0) == "magnetic_pull"
    assert simplest("bearing_anisotropic:UGB", {"bearing_anisotropic:UGB": 9.0, "bearing_change:LGB": 8.0}, 3.0) == (
        "bearing_anisotropic:UGB"
    )
