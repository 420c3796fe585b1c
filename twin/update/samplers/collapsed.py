"""A Metropolis step of the parameters with the shapes integrated out.

Given the noise ``Δ``, ``z = (ψ, ε)`` is Gaussian given the parameters
``θ = (t, η)``: precision ``P_i(θ) = Σ_j H_ij(θ)ᵀ W_i H_ij(θ) + Λ_i`` and
linear term ``b_i`` (the shape data). The marginal of the parameters is
therefore exact and cheap::

    log p(θ | Δ, data) = Σ_i ½ b_iᵀ P_i(θ)⁻¹ b_i − ½ log |P_i(θ)| + log prior(θ) + const.

When ``Δ`` is small the Gibbs steps ``θ | z`` and ``z | θ`` are both sharp
and crawl along the ridge where a parameter change is absorbed by the shapes
(paper Case B: chains of 300 sweeps from different seeds disagree, R-hat up
to 3). This step moves ``θ`` on its marginal: the proposal is the Gaussian
of the Gauss-Newton linearisation at ``(θ, ẑ(θ))``, ``ẑ = P⁻¹ b``, reduced to
``θ`` (the Schur complement over ``z``), and it is accepted with the exact
marginal ratio. On Case B about 85-97% of the proposals are accepted. The
sweep draws ``z | θ`` right after it, as a step that integrates ``z`` out
requires.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from twin.update.algebra import coefficients, combined, design, joint_parameters, shape_system, weigh
from twin.update.chain import Prior, State
from twin.update.problem import Problem


@dataclass(frozen=True)
class Approximation:
    """The marginal at ``θ`` and its Gaussian approximation ``N(θ + S⁻¹ g, S⁻¹)``."""

    log_marginal: float
    S: np.ndarray
    L: np.ndarray
    step: np.ndarray
    Hc: np.ndarray  # Σ_k c_k H_k at θ, for the z step that follows
    P: np.ndarray  # precision of z | θ
    b: np.ndarray


def _flat(problem: Problem, state: State) -> np.ndarray:
    """``θ = [t, η_1, ..., η_I]`` as one vector."""
    return np.concatenate([state.t, state.eta.ravel()])


def _set(problem: Problem, state: State, theta: np.ndarray) -> State:
    """``state`` with the parameters of :func:`_flat`'s vector ``theta``."""
    Kg = problem.n_global
    return dataclasses.replace(state, t=theta[:Kg].copy(), eta=theta[Kg:].reshape(state.eta.shape).copy())


def approximate(problem: Problem, state: State, prior: Prior) -> Approximation:
    """Exact log marginal of ``θ`` (up to a constant) and its Gauss-Newton Gaussian at ``state``'s ``θ``.

    Raises ``numpy.linalg.LinAlgError`` when a precision is not positive definite.
    """
    c = coefficients(problem, state)
    Hc = combined(problem, c)
    P, b = shape_system(problem, Hc, state.w)
    Lp = np.linalg.cholesky(P)
    y = np.linalg.solve(Lp, b[..., None])[..., 0]
    log_marginal = 0.5 * np.sum(y**2) - np.sum(np.log(np.diagonal(Lp, axis1=1, axis2=2)))
    z_hat = np.linalg.solve(np.swapaxes(Lp, 1, 2), y[..., None])[..., 0]
    D = design(problem, z_hat)
    Jt = D[:, 1:]  # (I, K, J n_r): the residual's derivative in the parameters at ẑ
    r = D[:, 0] + np.einsum("ik,ikn->in", c[:, 1:], Jt)
    JtW = weigh(state.w, Jt)
    C = JtW @ np.swapaxes(Jt, 1, 2)
    B = JtW @ Hc  # (I, K, n_z)
    PinvBt = np.linalg.solve(P, np.swapaxes(B, 1, 2))
    blocks = C - B @ PinvBt  # θ-precision of each mode, z integrated out
    grads = -(JtW @ r[:, :, None])[..., 0]
    S, g = joint_parameters(problem, blocks, grads)
    precision = prior.parameter_precision
    S[np.diag_indices_from(S)] += precision
    g -= precision * (_flat(problem, state) - prior.parameter_mean)
    log_marginal += float(
        -0.5 * np.sum(prior.global_precision * (state.t - prior.global_mean) ** 2)
        - 0.5 * np.sum(prior.mode_precision * (state.eta - prior.mode_mean) ** 2)
    )
    L = np.linalg.cholesky(S)
    step = np.linalg.solve(L.T, np.linalg.solve(L, g))
    return Approximation(float(log_marginal), S, L, step, Hc, P, b)


def _log_q(at: Approximation, x_from: np.ndarray, x_to: np.ndarray) -> float:
    """``log N(x_to; x_from + step, S⁻¹)`` up to the constant, ``at`` the approximation at ``x_from``."""
    d = x_to - x_from - at.step
    return float(np.sum(np.log(np.diag(at.L))) - 0.5 * d @ at.S @ d)


def marginal_move(
    problem: Problem, state: State, prior: Prior, rng: np.random.Generator
) -> tuple[bool, Approximation | None]:
    """One Metropolis-Hastings step of ``θ = (t, η)`` on their marginal given ``Δ`` (``z`` integrated out).

    Updates ``state.t`` and ``state.eta`` when accepted; ``state.z`` is left
    as it is and must be drawn from ``z | θ`` next. Returns whether the step
    was accepted, and the approximation at the state's (new) ``θ``, whose
    ``Hc``, ``P`` and ``b`` give that draw (None when ``P`` or ``S`` is not
    positive definite there).

    Examples
    --------
    >>> from twin.update.chain import Prior
    >>> from twin.update.samplers.conditionals import initial_state
    >>> from twin.update.problem import Problem, sparse_blocks
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((1, 2, 8, 3, 3))
    >>> problem = Problem(H0=H[:, 0].copy(), blocks=sparse_blocks(H[:, 1:]), data_index=np.arange(2),
    ...     eps_index=np.array([2]), psi_hat=rng.standard_normal((1, 8, 2)), psi_var=np.full((1, 2), 0.1),
    ...     global_names=["a"], global_scale=np.ones(1), global_nominal=np.ones(1), mode_names=[],
    ...     mode_scale=np.ones((1, 0)), mode_nominal=np.zeros((1, 0)), modes=np.array([1]), channels=["c"],
    ...     method="stage 2", eps_std=0.5, margin=np.full(1, np.inf), resonance_hz=np.full(1, np.nan))
    >>> state = initial_state(problem)
    >>> moved = [marginal_move(problem, state, Prior.flat(problem), rng)[0] for _ in range(50)]
    >>> any(moved)
    True
    """
    try:
        here = approximate(problem, state, prior)
    except np.linalg.LinAlgError:
        return False, None
    x0 = _flat(problem, state)
    x1 = x0 + here.step + np.linalg.solve(here.L.T, rng.standard_normal(x0.size))
    proposed = _set(problem, state, x1)
    try:
        there = approximate(problem, proposed, prior)
    except np.linalg.LinAlgError:
        return False, here
    log_ratio = there.log_marginal - here.log_marginal + _log_q(there, x1, x0) - _log_q(here, x0, x1)
    if np.log(rng.uniform()) < log_ratio:
        state.t, state.eta = proposed.t, proposed.eta
        return True, there
    return False, here
