"""The collapsed parameter step: its marginal against the joint density, and the posterior it samples."""

import numpy as np
import pytest

from twin.update.algebra import coefficients, combined, shape_system
from twin.update.chain import Prior, State
from twin.update.samplers.collapsed import approximate, marginal_move
from twin.update.samplers.conditionals import log_density
from twin.update.samplers.gibbs import run_chain

from tests.conftest import TOY_SIZES

I, J, N_R, N_PSI, N_E = TOY_SIZES


@pytest.mark.parametrize("full", [False, True], ids=["diagonal", "full"])
def test_marginal_is_the_joint_density_with_the_shapes_integrated_out(toy, full):
    # z | θ is Gaussian, so log ∫ p(θ, z) dz = log p(θ, ẑ) − ½ log|P(θ)| + const exactly (Laplace identity);
    # log_density is the sampler's joint density, written independently of the marginal
    problem, state, _ = toy
    if full:
        A = np.random.default_rng(9).standard_normal((I, N_R, N_R))
        state = State(state.t, state.eta, state.z, A @ np.swapaxes(A, 1, 2) + 0.5 * np.eye(N_R))
    prior = Prior.flat(problem, noise_model="full" if full else "diagonal")
    got, ref = [], []
    for t, eta in [(0.4, (-0.3, 0.7)), (-1.1, (0.2, 0.1)), (2.0, (1.5, -0.8))]:
        s = State(np.array([t]), np.array(eta)[:, None], state.z.copy(), state.w)
        P, b = shape_system(problem, combined(problem, coefficients(problem, s)), s.w)
        s.z = np.linalg.solve(P, b[..., None])[..., 0]
        got.append(approximate(problem, s, prior).log_marginal)
        ref.append(log_density(problem, s, prior=prior) - 0.5 * np.sum(np.linalg.slogdet(P)[1]))
    np.testing.assert_allclose(np.diff(got), np.diff(ref), rtol=1e-9, atol=1e-9)


@pytest.mark.slow  # 20-30 s: a non-default option, run in CI's slow pass
def test_collapsed_chain_samples_the_same_posterior_as_plain_gibbs(toy):
    problem, _, _ = toy
    n = 6000
    plain = run_chain(problem, n, burn_in=50, rng=np.random.default_rng(1))
    coll = run_chain(problem, n, burn_in=50, rng=np.random.default_rng(2), collapsed=True)
    assert coll.accepted.mean() > 0.02 and not plain.accepted.any()  # a rough toy: few big moves are taken
    for a, b in [(plain.t[:, 0], coll.t[:, 0]), (plain.eta[:, 1, 0], coll.eta[:, 1, 0])]:
        # means agree within a few Monte Carlo errors (draws thinned by 20 are nearly independent)
        se = np.hypot(a[::20].std() / np.sqrt(n / 20), b[::20].std() / np.sqrt(n / 20))
        assert abs(a.mean() - b.mean()) < 4 * se
        assert b.std() == pytest.approx(a.std(), rel=0.15)


def test_a_move_is_reversible_bookkeeping(toy):
    problem, state, _ = toy
    prior = Prior.flat(problem)
    rng = np.random.default_rng(0)
    moves = [marginal_move(problem, state, prior, rng) for _ in range(50)]
    assert any(accepted for accepted, _ in moves)
    accepted, at = moves[-1]
    P, b = shape_system(problem, combined(problem, coefficients(problem, state)), state.w)
    np.testing.assert_allclose(at.P, P)  # the approximation handed to the z step is at the state's θ
