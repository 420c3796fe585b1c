"""The closed-form conditionals of the APerCEM Gibbs sweep (the reference paper's Table 1).

For mode ``i`` and pole sample ``j`` the real-augmented PerCEM residual is

    r_ij = Σ_k c_ik H_ijk z_i,   c_i = [1, t, η_i],   z_i = [x_i*; e_i*],

linear in the parameters ``c`` for fixed ``z`` and in ``z`` for fixed ``c``.
The statistical model: ``r_ij ~ N(0, Δ_i)`` with diagonal unknown ``Δ_i``
(a weak inverse-gamma prior, see below), shape samples ``ψ̂_ij* ~ N(ψ_i*, Σ_i)`` (Σ_i from the data),
``e_i* ~ N(0, σ² I)``, flat or Gaussian priors on the scaled parameters.

One sweep draws, each from its closed-form conditional:

1. ``t | rest`` (shared parameters): Gaussian;
2. ``η_i | rest`` for every mode (the mode's own parameters): Gaussian;
3. ``(ψ_i, ε_i) | rest``: Gaussian, drawn as one block (their joint
   conditional; a blocked version of the paper's two steps, which mixes at
   least as well);
4. ``Δ_i | rest``: inverse-gamma per row.

**Correlated rows (``noise_model="full"``).** In the paper's model the rows
of ``r_ij`` are independent. The pole noise makes them anything but: a pole
sample off its mean moves the whole residual along one direction
(``∂D/∂λ ψ``), so independent rows count that one scatter once per row and
the intervals come out too narrow (90% intervals covering about half the
truths on the paper's data). With a full ``Δ_i`` step 4 draws the precision
from its Wishart conditional instead (the inverse-Wishart prior with the
same marginals as the diagonal one), and steps 1-3 weigh the rows with it.
A chain from zero spends the first half of its burn-in with diagonal ``Δ_i``:
started full, the sharper posterior traps it far from the truth.

**Overrelaxation.** The parameters and the shapes are strongly correlated
in the posterior: a parameter off its value is partly absorbed by the shapes,
so plain Gibbs draws creep along that ridge (from zero, one magnetic-pull
stiffness took about 100 sweeps to reach its posterior). Steps 1 and 2 are
therefore Adler's overrelaxed draws with ``α =`` :data:`OVERRELAXATION`,
which go past the conditional mean instead of towards it; each leaves its
conditional invariant, so the sweep still samples the posterior, and the
same chain reaches it within about 5 sweeps.

All modes are handled at once with batched dense algebra; the basis matrices
were built once (:func:`twin.update.problem.build_problem`).

**The prior on Δ.** The residual is homogeneous in ``z``: ``z = 0`` makes it
vanish for every sample. Under the scale-free Jeffreys prior ``p(Δ) ∝ 1/Δ``
the joint density is then unbounded as ``z, Δ → 0``, and a mode whose shape
samples anchor ``ψ`` weakly (a heavily damped mode identified from signals,
shape CoV of tens of percent) falls into that hole: its ``Δ`` shrinks by
orders of magnitude per sweep until the draws are NaN. Each row of ``Δ_i``
therefore has a conjugate prior ``IG(a0, a0 s_ir)``, where ``s_ir`` is the
variance over the pole samples of the residual at the data's mean shape (the
scatter the pole samples alone put into the residual), and
``a0 = NOISE_PRIOR_SHAPE`` weighs it as ``2 a0`` samples against the J of
the data. The density is then bounded and the chains stay off ``z = 0``.
"""

from __future__ import annotations

import logging

import numpy as np

from twin.update.algebra import coefficients, combined, design, joint_parameters, shape_system, weak_parameters, weigh
from twin.update.chain import Prior, State
from twin.update.problem import Problem, UpdateError
from twin.update.samplers.collapsed import marginal_move


#: Adler's overrelaxation of the parameter draws (0: plain Gibbs). Closer to -1 crosses the ridge faster
#: but leaves a sharply determined parameter oscillating about its mean, the swing shrinking by ``|alpha|`` per
#: sweep: -0.7 brings it within 3% in 10 sweeps (and 1e-3 in 20, the default burn-in).
OVERRELAXATION = -0.7

log = logging.getLogger(__name__)


def full_precision(w: np.ndarray) -> np.ndarray:
    """Diagonal noise precisions ``(I, n_r)`` as the matrices ``(I, n_r, n_r)`` of the full noise model."""
    return w[:, :, None] * np.eye(w.shape[1])


def gaussian_draw(
    P: np.ndarray, b: np.ndarray, rng: np.random.Generator, current: np.ndarray | None = None, alpha: float = 0.0
) -> np.ndarray:
    """Draw from ``N(P⁻¹ b, P⁻¹)`` for a batch of precisions ``P`` (..., n, n) and ``b`` (..., n).

    With ``current`` and ``alpha`` in (-1, 0], Adler's overrelaxed draw
    ``μ + α (current − μ) + √(1 − α²) L⁻ᵀ ξ``: it leaves ``N(μ, P⁻¹)``
    invariant (and is reversible for it), so it can replace the plain draw
    in a Gibbs sweep; ``alpha = 0`` is the plain draw.

    Raises ``numpy.linalg.LinAlgError`` when a ``P`` is not positive definite.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> x = gaussian_draw(np.eye(2)[None] * 1e12, np.array([[2e12, 3e12]]), rng)
    >>> np.round(x, 3)
    array([[2., 3.]])
    """
    L = np.linalg.cholesky(P)
    mean = np.linalg.solve(P, b[..., None])[..., 0]
    xi = rng.standard_normal(b.shape)
    noise = np.linalg.solve(np.swapaxes(L, -1, -2), xi[..., None])[..., 0]
    if current is None or alpha == 0.0:
        return mean + noise
    return mean + alpha * (current - mean) + np.sqrt(1.0 - alpha**2) * noise


def parameter_precision(problem: Problem, state: State) -> np.ndarray:
    """Joint conditional precision of all scaled parameters ``[t, η_1, ..., η_I]`` at ``state``."""
    D = design(problem, state.z)[:, 1:]
    blocks = weigh(state.w, D) @ np.swapaxes(D, 1, 2)  # (I, K, K)
    return joint_parameters(problem, blocks, np.zeros(blocks.shape[:2]))[0]


def not_identifiable(problem: Problem, state: State) -> list[str]:
    """Parameters the data cannot determine at ``state`` (empty when all can be).

    Works on the unit-diagonal joint conditional precision of the scaled
    parameters: a parameter with no effect on the residual, or with a large
    share in a near-null direction (eigenvalue ratio below
    :data:`SINGULAR_RATIO`), is named.
    """
    return weak_parameters(problem.parameter_labels, parameter_precision(problem, state))


def initial_state(problem: Problem, noise_model: str = "diagonal") -> State:
    """Parameters at zero; ``z`` its conditional mean there (ψ near the data mean); ``Δ`` from the residual.

    ``Δ_i`` starts diagonal in either noise model (:data:`NOISE_MODELS`).

    Starting ``Δ`` at :func:`residual_scatter` instead (leaving out the model error) was tried and
    rejected: the chains then settle in local modes of lower density (paper Case B: log density
    lower by about 5600, UGB.kxx 4.5% off).
    """
    I, J, n_r, n_z = problem.H0.shape
    state = State(np.zeros(problem.n_global), np.zeros((I, problem.n_per_mode)), np.zeros((I, n_z)), np.ones((I, n_r)))
    Hc = combined(problem, coefficients(problem, state))
    P, b = shape_system(problem, Hc, state.w)
    state.z = np.linalg.solve(P, b[..., None])[..., 0]
    r = (Hc @ state.z[:, :, None]).reshape(I, J, n_r)
    ms = np.mean(r**2, axis=1)
    state.w = 1.0 / np.where(ms > 0, ms, 1.0)
    if noise_model == "full":
        state.w = full_precision(state.w)
    return state


def _not_identifiable(problem: Problem, state: State) -> UpdateError:
    bad = not_identifiable(problem, state)
    which = ", ".join(bad) if bad else "(no single parameter stands out)"
    return UpdateError(f"the data cannot determine these parameters (singular conditional): {which}")


def conditional_shared(
    problem: Problem, state: State, prior: Prior, D: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Precision ``P`` and ``b`` (mean ``P⁻¹ b``) of the shared parameters ``t | rest``.

    ``D`` is the design at ``state.z`` when already computed.
    """
    Kg = problem.n_global
    D = design(problem, state.z) if D is None else D
    D0, Dg, Dm = D[:, 0], D[:, 1 : 1 + Kg], D[:, 1 + Kg :]
    DgW = weigh(state.w, Dg)
    off = D0 + np.einsum("ik,ikn->in", state.eta, Dm)
    P = (DgW @ np.swapaxes(Dg, 1, 2)).sum(axis=0) + np.diag(prior.global_precision)
    b = -np.einsum("ikn,in->k", DgW, off) + prior.global_precision * prior.global_mean
    return P, b


def conditional_own(
    problem: Problem, state: State, prior: Prior, D: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Precisions ``(I, Km, Km)`` and ``b`` ``(I, Km)`` of each mode's own parameters ``η_i | rest``."""
    Kg = problem.n_global
    D = design(problem, state.z) if D is None else D
    D0, Dg, Dm = D[:, 0], D[:, 1 : 1 + Kg], D[:, 1 + Kg :]
    DmW = weigh(state.w, Dm)
    off = D0 + np.einsum("k,ikn->in", state.t, Dg)
    P = DmW @ np.swapaxes(Dm, 1, 2) + prior.mode_precision[:, :, None] * np.eye(problem.n_per_mode)
    b = -np.einsum("ikn,in->ik", DmW, off) + prior.mode_precision * prior.mode_mean
    return P, b


def conditional_shape(problem: Problem, state: State, Hc: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Precisions ``(I, n_z, n_z)`` and ``b`` of ``z_i = (ψ_i, ε_i) | rest``.

    ``Hc`` is ``Σ_k c_k H_k`` at the state's parameters when already computed.
    """
    Hc = combined(problem, coefficients(problem, state)) if Hc is None else Hc
    return shape_system(problem, Hc, state.w)


def conditional_noise(
    problem: Problem, state: State, Hc: np.ndarray | None = None, prior: Prior | None = None
) -> tuple[float, np.ndarray]:
    """The conditional of the noise precision ``W_i = Δ_i⁻¹ | rest``.

    Diagonal noise model: shape ``a`` and rates ``(I, n_r)`` of ``1/Δ_ir ~ Gamma(a, rate)``.
    Full noise model (``prior.full``): degrees of freedom ``ν`` and scale matrices ``S`` ``(I, n_r, n_r)``
    of ``W_i ~ Wishart(ν, S_i⁻¹)``.

    ``prior`` sets the prior on Δ (default: Jeffreys, ``p(Δ) ∝ 1/Δ`` per row, diagonal model).
    """
    I, J, n_r, n_z = problem.H0.shape
    Hc = combined(problem, coefficients(problem, state)) if Hc is None else Hc
    r = (Hc @ state.z[:, :, None]).reshape(I, J, n_r)
    a0, b0 = (0.0, 0.0) if prior is None else (prior.noise_shape, prior.noise_rate)
    if prior is not None and prior.full:
        nu0 = _prior_df(a0, n_r)
        scale = np.swapaxes(r, 1, 2) @ r + 2.0 * np.asarray(b0)[..., None] * np.eye(n_r)
        return J + nu0, scale
    return J / 2.0 + a0, np.maximum(0.5 * np.sum(r**2, axis=1) + b0, np.finfo(float).tiny)


def _prior_df(a0: float, n_r: int) -> float:
    """Degrees of freedom of the inverse-Wishart prior whose diagonal marginals are ``IG(a0, ·)`` (0: Jeffreys)."""
    return 2.0 * a0 + n_r - 1.0 if a0 > 0 else 0.0


def wishart_draw(df: float, scale: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Draw ``W ~ Wishart(df, S⁻¹)`` for a batch of scale matrices ``S`` (..., n, n) (Bartlett).

    Its mean is ``df S⁻¹``; ``df`` must exceed ``n − 1``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> W = wishart_draw(4000.0, np.array([[[2000.0, 0.0], [0.0, 4000.0]]]), rng)
    >>> np.round(np.diag(W[0]), 1)  # close to the mean 4000 S⁻¹
    array([2., 1.])
    """
    n = scale.shape[-1]
    C = np.linalg.cholesky(scale)
    A = np.tril(rng.standard_normal(scale.shape), -1)
    idx = np.arange(n)
    A[..., idx, idx] = np.sqrt(rng.chisquare(df - idx, size=scale.shape[:-2] + (n,)))
    B = np.linalg.solve(np.swapaxes(C, -1, -2), A)  # C⁻ᵀ A: (C⁻ᵀ)(C⁻ᵀ)ᵀ = S⁻¹
    return B @ np.swapaxes(B, -1, -2)


def log_density(problem: Problem, state: State, rate: np.ndarray | None = None, prior: Prior | None = None) -> float:
    """Log joint density of ``state`` and the data, up to a constant (flat parameter priors).

    ``rate`` is :func:`conditional_noise`'s rate (diagonal model) or scale (full model) at the state
    (same ``prior``) when already computed.
    """
    J = problem.n_samples
    a0 = 0.0 if prior is None else prior.noise_shape
    rate = conditional_noise(problem, state, prior=prior)[1] if rate is None else rate
    psi = state.z[:, problem.data_index]
    data = (
        -0.5 * np.sum((problem.psi_hat - psi[:, None]) ** 2 / problem.psi_var[:, None])
        - 0.5 * np.sum(state.z[:, problem.eps_index] ** 2) / problem.eps_std**2
    )
    if prior is not None and prior.full:
        n_r = state.w.shape[1]
        nu0 = _prior_df(a0, n_r)
        logdet = np.linalg.slogdet(state.w)[1]
        return float(0.5 * (J + nu0 + n_r + 1) * np.sum(logdet) - 0.5 * np.sum(state.w * rate) + data)
    return float(
        (0.5 * J + a0) * np.sum(np.log(state.w)) - np.sum(state.w * rate) - np.sum(np.log(1.0 / state.w)) + data
    )


def sweep(problem: Problem, state: State, prior: Prior, rng: np.random.Generator, collapsed: bool = False) -> float:
    """One Gibbs sweep (t, then η_i, then (ψ_i, ε_i), then Δ_i), updating ``state`` in place.

    With ``collapsed``, a Metropolis step of ``(t, η)`` on their marginal
    (``z`` integrated out, :func:`twin.update.samplers.collapsed.marginal_move`)
    follows their Gibbs steps, before the ``z`` step; ``state.accepted`` says
    whether it moved.
    Returns the log joint density at the new state (up to a constant).
    """
    D = design(problem, state.z)  # depends on z only: shared by the t and η steps
    try:
        if problem.n_global:
            state.t = gaussian_draw(*conditional_shared(problem, state, prior, D), rng, state.t, OVERRELAXATION)
        if problem.n_per_mode:
            state.eta = gaussian_draw(*conditional_own(problem, state, prior, D), rng, state.eta, OVERRELAXATION)
    except np.linalg.LinAlgError:
        raise _not_identifiable(problem, state) from None
    at = None
    if collapsed:
        state.accepted, at = marginal_move(problem, state, prior, rng)
    Hc = combined(problem, coefficients(problem, state)) if at is None else at.Hc
    try:
        system = conditional_shape(problem, state, Hc) if at is None else (at.P, at.b)
        state.z = gaussian_draw(*system, rng)
    except np.linalg.LinAlgError:
        raise UpdateError("the shape conditional is singular: too few rows for the latent shape entries") from None
    a, rate = conditional_noise(problem, state, Hc, prior)
    state.w = wishart_draw(a, rate, rng) if prior.full else rng.gamma(a, 1.0 / rate)
    return log_density(problem, state, rate, prior)
