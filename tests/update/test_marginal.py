"""twin.update.marginal: the errors-in-variables PerCEM marginal."""

import numpy as np
import pytest

from twin.update import synthesize_modes, update
from twin.update.marginal import (
    log_density,
    marginal_problem,
    mode_density,
    residual_moments,
    tail_kernel,
)
from twin.update.problem import UpdateError, build_problem, select_parameters
from twin.update.shrinkage import held_out_intensity


def test_the_shape_covariances_are_the_samples_own_shrunk_by_each_modes_intensity_and_refuse_too_few(hydro_unit, small):
    marg, data = small
    p = marg.problem
    own = marginal_problem(p, data["pole"].values, "sample")
    J = p.psi_hat.shape[1]
    for i in range(p.n_modes):  # J = 30 samples of 16 entries: their covariance (variances floored as the model's)
        expected = np.cov(p.psi_hat[i].T)
        np.fill_diagonal(expected, p.psi_var[i])  # Im of the reference entry: no scatter, the floor
        got = own.cov_z[i][np.ix_(p.data_index, p.data_index)] * J
        np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
    shrunk = marg.cov_z[0][np.ix_(p.data_index, p.data_index)]
    assert np.allclose(np.diag(shrunk), np.diag(own.cov_z[0][np.ix_(p.data_index, p.data_index)]))
    assert own.shape_covariance == "sample" and marg.shape_covariance == "shrunk"
    # held-out: the samples' correlations times 1 - λ_i, each mode's λ_i by its samples held out in turn
    held = marginal_problem(p, data["pole"].values, "held-out")
    for i, lam in enumerate(held_out_intensity(p.psi_hat)):
        blocks = [m.cov_z[i][np.ix_(p.data_index, p.data_index)] for m in (held, own, marg)]
        d = np.sqrt(np.outer(np.diag(blocks[1]), np.diag(blocks[1])))
        off = ~np.eye(len(d), dtype=bool)
        np.testing.assert_allclose((blocks[0] / d)[off], (1 - lam) * (blocks[1] / d)[off], atol=1e-9)
        # the paper's shape errors are independent entries: the chance correlations of 30 samples are shrunk away
        assert lam > 0.9
        assert np.abs((blocks[2] / d)[off]).max() < 0.1
    few = synthesize_modes(hydro_unit, samples=12, seed=7).isel(mode=[2, 3, 9])  # 12 samples span 11 of 15
    problem = build_problem(hydro_unit, few, select_parameters(hydro_unit, "LGB.k*"), pole_model="marginal")
    with pytest.raises(UpdateError, match=r"mode\(s\) 3 \(rank 11 of 15\), 4 \(rank 11 of 15\), 10 \(rank 11 of 15\)"):
        marginal_problem(problem, few["pole"].values, "sample")
    with pytest.raises(UpdateError, match="shape_covariance must be one of shrunk, held-out, sample"):
        update(hydro_unit, few, "LGB.k*", options={"shape_covariance": "full", "progress": False})
    with pytest.raises(UpdateError, match="the 'gibbs' sampler has no option shape_covariance"):
        update(hydro_unit, few, "LGB.k*", method="gibbs", options={"shape_covariance": "sample"})


def test_residual_covariance_is_that_of_the_shape_and_pole_errors(small):
    # V_i is the covariance of H_i z + B_i δ for z ~ N(μ_i, Λ_i) and δ ~ N(0, C_i): checked by drawing them
    marg, _ = small
    p = marg.problem
    theta = np.random.default_rng(1).normal(0.0, 0.3, marg.size)
    m, V, H, B = residual_moments(marg, theta)
    rng = np.random.default_rng(2)
    n = 40000
    for i in range(p.n_modes):
        z = rng.multivariate_normal(marg.mean_z[i], marg.cov_z[i], size=n)
        d = rng.multivariate_normal(np.zeros(2), marg.pole_cov[i], size=n)
        r = z @ H[i].T + d @ B[i].T
        np.testing.assert_allclose(r.mean(axis=0), m[i], atol=4 * np.sqrt(np.diag(V[i]).max() / n))
        scale = np.sqrt(np.outer(np.diag(V[i]), np.diag(V[i])))
        np.testing.assert_allclose(np.cov(r.T) / scale, V[i] / scale, atol=0.03)


def test_tail_kernel_is_the_gaussian_inside_and_the_student_t_outside():
    n_r, nu = 16, 5.0
    q = np.linspace(0.0, 200.0, 2001)
    kernel, weight = tail_kernel(q, n_r, nu)
    inside = q <= n_r
    np.testing.assert_allclose(kernel[inside], -0.5 * q[inside])
    assert np.all(weight[inside] == 1.0) and np.all(weight <= 1.0)  # no mode weighs more than the Gaussian
    # beyond n_r: the multivariate t's log kernel up to a constant, joined with the same value and slope
    t = -0.5 * (nu + n_r) * np.log1p(q / nu)
    np.testing.assert_allclose(np.diff(kernel[~inside]), np.diff(t[~inside]), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(-2 * np.gradient(kernel, q)[1:-1], weight[1:-1], atol=2e-3)
    assert weight[-1] == pytest.approx((nu + n_r) / (nu + 200.0))
    gauss, ones = tail_kernel(q, n_r, np.inf)
    np.testing.assert_allclose(gauss, -0.5 * q)
    np.testing.assert_array_equal(ones, 1.0)


def test_density_is_the_errors_in_variables_likelihood(small):
    # log p = sum_i kernel(q_i), q_i = m_i' V_i^-1 m_i, by direct solves
    marg, _ = small
    theta = np.random.default_rng(5).normal(0.0, 0.3, marg.size)
    m, V, _, _ = residual_moments(marg, theta)
    q = np.array([mi @ np.linalg.solve(Vi, mi) for mi, Vi in zip(m, V)])
    kernel, _ = tail_kernel(q, V.shape[1])
    assert log_density(marg, theta).log_p == pytest.approx(kernel.sum(), rel=1e-10)
    # no mode's term exceeds 0: the density cannot spike where a V_i nearly loses rank (the log-det's trap)
    assert np.all(kernel <= 0.0)


def test_mode_density_is_each_modes_term_with_the_shared_parameters_held(small):
    # the per-mode densities the slice step moves sum to log_density less the shared parameters' prior, at
    # any per-mode values with t held; t itself is held at the value they were built at
    marg = small[0]
    p = marg.problem
    rng = np.random.default_rng(6)
    theta = rng.normal(0.0, 0.3, marg.size)
    mean, prec = rng.normal(size=marg.size), rng.uniform(0.0, 2.0, marg.size)
    f = mode_density(marg, theta, mean, prec)
    Kg = p.n_global
    for _ in range(3):
        eta = theta[Kg:] + rng.normal(0.0, 0.2, p.n_modes * p.n_per_mode)
        moved = np.concatenate([theta[:Kg], eta])
        shared_prior = -0.5 * np.sum(prec[:Kg] * (theta[:Kg] - mean[:Kg]) ** 2)
        total = f(eta.reshape(p.n_modes, p.n_per_mode)).sum() + shared_prior
        assert total == pytest.approx(log_density(marg, moved, mean, prec).log_p, rel=1e-10)


def test_order_covariance_is_added_to_each_mean_poles(small):
    marg, data = small
    extra = np.array([[[4.0, 1.0], [1.0, 9.0]]] * marg.problem.n_modes) * 1e-4
    more = marginal_problem(marg.problem, data["pole"].values, order_cov=extra)
    np.testing.assert_allclose(more.pole_cov - marg.pole_cov, extra)
    np.testing.assert_array_equal(more.order_cov, extra)
    with pytest.raises(UpdateError, match=r"order_cov must be one 2 x 2 matrix per mode \(3, 2, 2\), got \(2, 2, 2\)"):
        marginal_problem(marg.problem, data["pole"].values, order_cov=extra[:2])


@pytest.mark.parametrize("nu", [5.0, np.inf])
def test_gradient_matches_finite_differences(small, nu):
    marg, _ = small
    rng = np.random.default_rng(3)
    theta = rng.normal(0.0, 0.3, marg.size)
    mean, prec = rng.normal(size=marg.size), rng.uniform(0.0, 2.0, marg.size)
    d = log_density(marg, theta, mean, prec, nu)
    for k in range(marg.size):
        h = 1e-4 * max(1.0, abs(theta[k]))
        e = np.zeros(marg.size)
        e[k] = h
        fd = log_density(marg, theta + e, mean, prec, nu).log_p - log_density(marg, theta - e, mean, prec, nu).log_p
        assert fd / (2 * h) == pytest.approx(d.gradient[k], rel=1e-4, abs=1e-6 * np.abs(d.gradient).max())
