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


def test_a_bounded_prior_gives_the_integral_over_the_truncated_prior():
    """The evidence of a sign-bounded change is the integral of the likelihood over the prior truncated to the
    bound (and renormalised): a fit that needs the other sign loses most of its evidence."""
    J, cov, scale = np.array([[1.0], [0.5]]), 0.2 * np.eye(2), np.array([2.0])
    for y in (np.array([1.2, 0.4]), np.array([-1.2, -0.4])):

        def integrand(x: float, y=y) -> float:
            return 2.0 * scipy.stats.norm.pdf(x, scale=2.0) * scipy.stats.multivariate_normal(J[:, 0] * x, cov).pdf(y)

        z, _ = scipy.integrate.quad(integrand, 0.0, 30.0, epsabs=1e-14)
        no_change = scipy.stats.multivariate_normal(np.zeros(2), cov).pdf(y)
        f = linear_fit(y, J, scale, cov, bounds=np.array([[0.0, np.inf]]))
        assert np.isclose(f.log_bayes_factor, np.log(z / no_change), rtol=1e-8)
        assert f.values[0] >= 0.0
    wrong_sign = linear_fit(np.array([-1.2, -0.4]), J, scale, cov, bounds=np.array([[0.0, np.inf]]))
    assert wrong_sign.log_bayes_factor < linear_fit(np.array([-1.2, -0.4]), J, scale, cov).log_bayes_factor - 3


def test_the_mass_inside_two_bounds_is_the_orthant_probability():
    from twin.update.evidence import box_mass

    rho = 0.5
    cov = np.array([[1.0, rho], [rho, 1.0]])
    both = box_mass(np.zeros(2), cov, np.zeros(2), np.full(2, np.inf))
    assert np.isclose(np.exp(both), 0.25 + np.arcsin(rho) / (2 * np.pi), atol=1e-5)
    # ends far from the mass play no part; one end is integrated exactly
    assert box_mass(np.zeros(2), cov, np.full(2, -100.0), np.full(2, np.inf)) == 0.0
    assert np.isclose(
        box_mass(np.array([1.0, 0.0]), cov, np.array([0.0, -np.inf]), np.full(2, np.inf)), scipy.stats.norm.logcdf(1.0)
    )
