"""The Gibbs conditionals against brute force, on a small hand-built problem."""

import numpy as np
import pytest
from scipy.integrate import trapezoid
from scipy.stats import invwishart

from twin.update.chain import Prior, State
from twin.update.samplers.conditionals import (
    conditional_noise,
    conditional_own,
    conditional_shape,
    conditional_shared,
    gaussian_draw,
    initial_state,
    log_density,
    sweep,
    wishart_draw,
)
from twin.update.samplers.gibbs import run_chain, run_chains
from twin.update.problem import Problem, UpdateError, sparse_blocks

from tests.conftest import TOY_SIZES

I, J, N_R, N_PSI, N_E = TOY_SIZES
N_Z = N_PSI + N_E


def _residual(H, c, z):
    """r[i, j, :] = Σ_k c[i, k] H[i, k, j] z[i]: the definition, written out."""
    return np.einsum("ik,ikjrz,iz->ijr", c, H, z)


def _log_lik(H, c, z, w):
    """Gaussian log likelihood of the residuals: ``w`` the row precisions (I, n_r) or full (I, n_r, n_r)."""
    r = _residual(H, c, z)
    if w.ndim == 2:
        return -0.5 * np.sum(w[:, None, :] * r**2)
    return -0.5 * np.einsum("ijr,irs,ijs->", r, w, r)


def _full(state, seed=7):
    """The state with full noise precisions: random symmetric positive definite (I, n_r, n_r)."""
    A = np.random.default_rng(seed).standard_normal((I, N_R, N_R))
    return State(state.t, state.eta, state.z, A @ np.swapaxes(A, 1, 2) + 0.5 * np.eye(N_R))


def _grid_moments(logp, lo, hi, n=20001):
    x = np.linspace(lo, hi, n)
    lp = np.array([logp(v) for v in x])
    p = np.exp(lp - lp.max())
    p /= trapezoid(p, x)
    mean = trapezoid(x * p, x)
    return mean, trapezoid((x - mean) ** 2 * p, x)


@pytest.mark.parametrize("full", [False, True], ids=["diagonal", "full"])
def test_shared_parameter_conditional_matches_numerical_integration(toy, full):
    problem, state, H = toy
    state = _full(state) if full else state
    P, b = conditional_shared(problem, state, Prior.flat(problem))

    def logp(t):
        c = np.stack([np.ones(I), np.full(I, t), state.eta[:, 0]], axis=1)
        return _log_lik(H, c, state.z, state.w)

    assert P.shape == (1, 1)
    mean, var = _grid_moments(logp, -20, 20)
    np.testing.assert_allclose([b[0] / P[0, 0], 1 / P[0, 0]], [mean, var], rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("full", [False, True], ids=["diagonal", "full"])
def test_own_parameter_conditional_matches_numerical_integration(toy, full):
    problem, state, H = toy
    state = _full(state) if full else state
    P, b = conditional_own(problem, state, Prior.flat(problem))
    for i in range(I):

        def logp(e, i=i):
            eta = state.eta.copy()
            eta[i, 0] = e
            c = np.stack([np.ones(I), np.full(I, state.t[0]), eta[:, 0]], axis=1)
            return _log_lik(H, c, state.z, state.w)

        mean, var = _grid_moments(logp, -20, 20)
        np.testing.assert_allclose([b[i, 0] / P[i, 0, 0], 1 / P[i, 0, 0]], [mean, var], rtol=1e-6, atol=1e-9)


def test_gaussian_prior_adds_its_precision(toy):
    problem, state, _ = toy
    flat = conditional_shared(problem, state, Prior.flat(problem))
    prior = Prior(np.array([2.0]), np.array([5.0]), np.zeros((I, 1)), np.zeros((I, 1)))
    P, b = conditional_shared(problem, state, prior)
    np.testing.assert_allclose([P[0, 0], b[0]], [flat[0][0, 0] + 5.0, flat[1][0] + 10.0])


@pytest.mark.parametrize("full", [False, True], ids=["diagonal", "full"])
def test_shape_conditional_matches_the_brute_force_quadratic_form(toy, full):
    problem, state, H = toy
    state = _full(state) if full else state
    P, b = conditional_shape(problem, state)
    c = np.stack([np.ones(I), np.full(I, state.t[0]), state.eta[:, 0]], axis=1)
    for i in range(I):

        def logp(z, i=i):
            zz = state.z.copy()
            zz[i] = z
            data = -0.5 * np.sum((problem.psi_hat[i] - z[:N_PSI]) ** 2 / problem.psi_var[i])
            return _log_lik(H, c, zz, state.w) + data - 0.5 * np.sum(z[N_PSI:] ** 2) / problem.eps_std**2

        # the log density is quadratic: its Hessian (central differences) is -P, its gradient at 0 is b
        h, e = 1e-3, np.eye(N_Z)
        hess = np.array(
            [
                [
                    (
                        logp(h * (e[a] + e[d]))
                        - logp(h * (e[a] - e[d]))
                        - logp(h * (e[d] - e[a]))
                        + logp(-h * (e[a] + e[d]))
                    )
                    / (4 * h * h)
                    for d in range(N_Z)
                ]
                for a in range(N_Z)
            ]
        )
        grad = np.array([(logp(h * e[a]) - logp(-h * e[a])) / (2 * h) for a in range(N_Z)])
        np.testing.assert_allclose(-hess, P[i], rtol=1e-5, atol=1e-6)
        np.testing.assert_allclose(grad, b[i], rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("a0", [0.0, 5.0])
def test_noise_conditional_matches_numerical_integration(toy, a0):
    problem, state, H = toy
    prior = Prior.flat(problem, noise_shape=a0)
    a, rate = conditional_noise(problem, state, prior=prior)
    c = np.stack([np.ones(I), np.full(I, state.t[0]), state.eta[:, 0]], axis=1)
    ss = np.sum(_residual(H, c, state.z) ** 2, axis=1)  # (I, n_r)
    b0 = np.broadcast_to(prior.noise_rate, ss.shape)
    for i, r in [(0, 0), (1, 2)]:
        # prior IG(a0, b0) on Δ (a0 = 0: Jeffreys 1/Δ) times the Gaussian likelihood of the J residuals of that row
        def logp(log_d, i=i, r=r):
            d = np.exp(log_d)  # density of log Δ: the Jacobian Δ turns Δ^(-a0-1) into Δ^(-a0)
            return -(0.5 * J + a0) * log_d - (0.5 * ss[i, r] + b0[i, r]) / d

        # E[1/Δ] by integration over log Δ against the Gamma(a, rate) mean a / rate
        x = np.linspace(-12, 8, 40001)
        lp = np.array([logp(v) for v in x])
        p = np.exp(lp - lp.max())
        mean_w = trapezoid(np.exp(-x) * p, x) / trapezoid(p, x)
        np.testing.assert_allclose(a / rate[i, r], mean_w, rtol=1e-6)


def test_full_noise_conditional_is_the_wishart_of_the_log_density(toy):
    # log_density as a function of Δ = W⁻¹ (everything else fixed; the diagonal model's density is in Δ
    # too) must be the inverse-Wishart(ν, S) log pdf of conditional_noise (W ~ Wishart(ν, S⁻¹)), up to a
    # constant: compare differences between states against scipy's inverse Wishart
    problem, state, H = toy
    prior = Prior.flat(problem, noise_model="full")
    state = _full(state)
    df, S = conditional_noise(problem, state, prior=prior)
    c = np.stack([np.ones(I), np.full(I, state.t[0]), state.eta[:, 0]], axis=1)
    r = _residual(H, c, state.z)
    np.testing.assert_allclose(S, np.swapaxes(r, 1, 2) @ r + 2 * prior.noise_rate[:, :, None] * np.eye(N_R))
    assert df == J + 2 * prior.noise_shape + N_R - 1  # the inverse-Wishart prior with the diagonal's marginals
    others = [_full(state, seed) for seed in (8, 9)]
    lp = [log_density(problem, s, prior=prior) for s in (state, *others)]
    ref = [sum(invwishart.logpdf(np.linalg.inv(s.w[i]), df, S[i]) for i in range(I)) for s in (state, *others)]
    np.testing.assert_allclose(np.diff(lp), np.diff(ref), rtol=1e-9)


def test_wishart_draw_has_the_wishart_mean_and_variance():
    rng = np.random.default_rng(0)
    S = np.array([[2.0, 0.5, 0.0], [0.5, 1.0, -0.3], [0.0, -0.3, 3.0]])
    V, df, n = np.linalg.inv(S), 7.5, 100_000
    W = wishart_draw(df, np.broadcast_to(S, (n, 3, 3)), rng)
    np.testing.assert_allclose(W.mean(axis=0), df * V, atol=0.02 * np.abs(df * V).max())
    var = df * (V**2 + np.outer(np.diag(V), np.diag(V)))  # Var(W_ij) of Wishart(df, V)
    np.testing.assert_allclose(W.var(axis=0), var, rtol=0.05)
    np.testing.assert_array_equal(W, np.swapaxes(W, 1, 2))


def test_full_noise_chain_runs_from_zero_through_a_diagonal_warm_up(toy):
    problem, _, _ = toy
    prior = Prior.flat(problem, noise_model="full")
    chain = run_chain(problem, 40, burn_in=6, prior=prior, rng=np.random.default_rng(2))
    assert np.all(np.isfinite(chain.lp)) and np.all(chain.noise > 0)
    state = initial_state(problem, "full")
    assert state.w.shape == (I, N_R, N_R)
    lp = sweep(problem, state, prior, np.random.default_rng(3))
    assert lp == pytest.approx(log_density(problem, state, prior=prior))
    with pytest.raises(UpdateError, match="unknown noise model 'banded'"):
        Prior.flat(problem, noise_model="banded")


def test_noise_prior_is_the_residual_scatter_over_the_pole_samples(toy):
    problem, _, H = toy
    prior = Prior.flat(problem)
    z = np.zeros((I, N_Z))
    z[:, :N_PSI] = problem.psi_hat.mean(axis=1)
    r = np.einsum("ijrz,iz->ijr", H[:, 0], z)  # zero parameters, mean shape, no perturbation
    np.testing.assert_allclose(prior.noise_rate, prior.noise_shape * r.var(axis=1, ddof=1), rtol=1e-12)
    assert prior.noise_shape > 0


def test_noise_prior_keeps_a_weakly_anchored_mode_off_zero(toy):
    # shape samples so scattered that psi hardly anchors z: under Jeffreys the density is unbounded at z = 0
    # and the chain falls in (Δ shrinks without end); the inverse-gamma prior keeps Δ at the residual scale
    problem, _, _ = toy
    loose = Problem(**{**problem.__dict__, "psi_var": np.full((I, N_PSI), 1e4)})
    kept = run_chain(loose, 200, rng=np.random.default_rng(4), prior=Prior.flat(loose))
    scatter = Prior.flat(loose).noise_rate.mean(axis=1) / Prior.flat(loose).noise_shape
    assert np.all(kept.noise[-50:] > 1e-3 * scatter)
    with np.errstate(all="ignore"):
        fallen = run_chain(loose, 200, rng=np.random.default_rng(4), prior=Prior.flat(loose, noise_shape=0.0))
    assert not np.all(fallen.noise[-1] > 1e-3 * scatter)


def test_gaussian_draw_has_the_right_mean_and_covariance():
    rng = np.random.default_rng(0)
    P = np.array([[4.0, 1.0], [1.0, 2.0]])
    b = np.array([1.0, -1.0])
    x = gaussian_draw(np.broadcast_to(P, (200_000, 2, 2)), np.broadcast_to(b, (200_000, 2)), rng)
    np.testing.assert_allclose(x.mean(axis=0), np.linalg.solve(P, b), atol=5e-3)
    np.testing.assert_allclose(np.cov(x.T), np.linalg.inv(P), atol=5e-3)


@pytest.mark.parametrize("alpha", [-0.7, -0.95])
def test_overrelaxed_draw_leaves_the_gaussian_invariant_and_anticorrelates(alpha):
    rng = np.random.default_rng(5)
    P = np.array([[4.0, 1.0], [1.0, 2.0]])
    b = np.array([1.0, -1.0])
    mean, cov, n = np.linalg.solve(P, b), np.linalg.inv(P), 200_000
    x = rng.multivariate_normal(mean, cov, n)  # a draw from the conditional ...
    y = gaussian_draw(np.broadcast_to(P, (n, 2, 2)), np.broadcast_to(b, (n, 2)), rng, x, alpha)
    np.testing.assert_allclose(y.mean(axis=0), mean, atol=5e-3)  # ... is taken to another one
    np.testing.assert_allclose(np.cov(y.T), cov, atol=5e-3)
    lag = np.cov(x[:, 0], y[:, 0])[0, 1] / cov[0, 0]
    assert lag == pytest.approx(alpha, abs=0.01)  # the pair is correlated by alpha (plain Gibbs: 0)


def test_sweeps_sample_the_shared_conditional(toy):
    # with z and Δ fixed, the t-step alone draws from N(P^-1 b, P^-1)
    problem, state, _ = toy
    P, b = conditional_shared(problem, state, Prior.flat(problem))
    rng = np.random.default_rng(1)
    draws = [gaussian_draw(P, b, rng)[0] for _ in range(20000)]
    assert abs(np.mean(draws) - b[0] / P[0, 0]) < 4 * np.sqrt(1 / P[0, 0] / 20000)
    assert np.std(draws) == pytest.approx(np.sqrt(1 / P[0, 0]), rel=0.03)


def test_chain_runs_from_zero_and_reports_the_log_density(toy):
    problem, _, _ = toy
    chain = run_chain(problem, 50, burn_in=5, rng=np.random.default_rng(2))
    assert chain.t.shape == (50, 1) and chain.eta.shape == (50, I, 1) and chain.psi.shape == (50, I, N_PSI)
    assert np.all(np.isfinite(chain.lp)) and np.all(chain.noise > 0)
    state = initial_state(problem)
    assert np.all(state.t == 0) and np.all(state.eta == 0)
    prior = Prior.flat(problem)
    lp = sweep(problem, state, prior, np.random.default_rng(3))
    assert lp == pytest.approx(log_density(problem, state, prior=prior))


def test_a_parameter_with_no_effect_is_named(toy):
    problem, state, H = toy
    H = H.copy()
    H[:, 1] = 0.0  # the shared parameter touches nothing
    dead = Problem(**{**problem.__dict__, "blocks": sparse_blocks(H[:, 1:])})
    with pytest.raises(UpdateError, match="cannot determine.*: a"):
        sweep(dead, state, Prior.flat(dead), np.random.default_rng(0))


def test_chains_on_a_dask_cluster_are_the_chains_run_here(toy, dask_local):
    problem, _, _ = toy
    here = run_chains(problem, 20, 3, burn_in=2, seed=11)
    there = run_chains(problem, 20, 3, burn_in=2, seed=11, tasks=dask_local)
    assert len(there) == 3
    for a, b in zip(here, there):
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.psi, b.psi)
        np.testing.assert_array_equal(a.lp, b.lp)
    assert not np.array_equal(here[0].t, here[1].t)  # the chains have their own streams
