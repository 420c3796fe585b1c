"""What every sampler of the update shares: the prior, the draws of a chain, and the Gibbs sampler's state.

All coordinates are scaled: a shared parameter ``θ_k`` is sampled as
``t_k = θ_k / s_k`` and a mode's own parameter as ``η_iq = θ_iq / s_iq``
(the scales of :class:`twin.update.problem.Problem`), so that one step
size and one prior precision mean the same for a bearing stiffness of
1e9 N/m and an added mass of 1e4 kg.

* :class:`Prior`: independent Gaussian priors on the scaled parameters
  (flat where the precision is zero) and, for the Gibbs samplers, the prior on
  the residual noise ``Δ``; :func:`build_prior` makes one from ``{name: (mean, std)}``.
* :class:`Chain`: the draws of one chain, with the statistics of whichever
  sampler made them; :func:`stack` puts chains on a leading axis.
* :class:`State`: one state of a Gibbs chain.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields

import numpy as np

from twin.update.algebra import residual_scatter
from twin.update.problem import Problem, UpdateError

#: Shape ``a0`` of the inverse-gamma prior on each row of Δ (worth ``2 a0`` pole samples).
NOISE_PRIOR_SHAPE = 5.0
#: Covariance models of the residual realisations ``r_ij ~ N(0, Δ_i)``: ``diagonal`` (the paper's:
#: independent rows) or ``full`` (correlated rows; inverse-Wishart prior and conditional).
NOISE_MODELS = ("diagonal", "full")


def check_noise_model(name: str) -> None:
    """Raise :class:`UpdateError` unless ``name`` is one of :data:`NOISE_MODELS`."""
    if name not in NOISE_MODELS:
        raise UpdateError(f"unknown noise model '{name}'; choose one of {', '.join(NOISE_MODELS)}")


@dataclass
class State:
    """One state of the chain, in scaled coordinates."""

    t: np.ndarray  # (Kg,)
    eta: np.ndarray  # (I, Km)
    z: np.ndarray  # (I, n_z)
    w: np.ndarray  # 1 / Δ: (I, n_r) diagonal, or the precision matrices (I, n_r, n_r) full
    accepted: bool = False  # whether the last sweep's collapsed step moved the parameters


@dataclass(frozen=True)
class Prior:
    """Independent Gaussian priors on the scaled parameters (precision 0: flat), and the prior on Δ.

    ``global_mean``/``global_precision`` are ``(Kg,)``, ``mode_mean``/``mode_precision`` ``(I, Km)``.
    Each row of ``Δ_i`` is ``IG(noise_shape, noise_rate[i, r])`` (both zero: Jeffreys). With
    ``noise_model="full"``, ``Δ_i`` is a full covariance with the inverse-Wishart prior of the same
    marginals, ``IW(2 a0 + n_r − 1, 2 diag(noise_rate_i))`` (see :data:`NOISE_MODELS`).
    """

    global_mean: np.ndarray
    global_precision: np.ndarray
    mode_mean: np.ndarray
    mode_precision: np.ndarray
    noise_shape: float = 0.0
    noise_rate: np.ndarray | float = 0.0
    noise_model: str = "diagonal"

    def __post_init__(self) -> None:
        check_noise_model(self.noise_model)

    @classmethod
    def flat(cls, problem: Problem, noise_shape: float = NOISE_PRIOR_SHAPE, noise_model: str = "diagonal") -> Prior:
        """Flat priors on every parameter (the paper's choice); the weak data-scaled prior on Δ."""
        I, Kg, Km = problem.n_modes, problem.n_global, problem.n_per_mode
        rate = noise_shape * residual_scatter(problem) if noise_shape > 0 else 0.0
        return cls(np.zeros(Kg), np.zeros(Kg), np.zeros((I, Km)), np.zeros((I, Km)), noise_shape, rate, noise_model)

    @property
    def parameter_mean(self) -> np.ndarray:
        """Prior means of the scaled parameters as one vector ``[t, η_1, ..., η_I]``."""
        return np.concatenate([self.global_mean, self.mode_mean.ravel()])

    @property
    def parameter_precision(self) -> np.ndarray:
        """Prior precisions of the scaled parameters as one vector ``[t, η_1, ..., η_I]``."""
        return np.concatenate([self.global_precision, self.mode_precision.ravel()])

    @property
    def full(self) -> bool:
        """Whether ``Δ_i`` is a full covariance matrix."""
        return self.noise_model == "full"


@dataclass(frozen=True)
class Chain:
    """Draws of one chain (scaled parameters; see :class:`Problem` for the scales)."""

    t: np.ndarray  # (draws, Kg)
    eta: np.ndarray  # (draws, I, Km)
    psi: np.ndarray  # (draws, I, n_psi)
    noise: np.ndarray  # (draws, I): mean of Δ_i over rows
    lp: np.ndarray  # (draws,): log joint density, up to a constant
    accepted: np.ndarray  # (draws,): whether the collapsed step moved the parameters (all False without it)
    acceptance_rate: np.ndarray  # (draws,): HMC's Metropolis acceptance probability (NaN for the Gibbs sampler)
    step_size: np.ndarray  # (draws,): HMC's leapfrog step, whitened units (NaN for the Gibbs sampler)
    n_steps: np.ndarray  # (draws,): HMC's leapfrog steps in the trajectory (0 for the Gibbs sampler)


def stack(chains: Sequence[Chain]) -> Chain:
    """Chains stacked on a leading ``chain`` axis."""
    return Chain(*(np.stack([getattr(c, f.name) for c in chains]) for f in fields(Chain)))


def build_prior(
    problem: Problem,
    priors: Mapping[str, tuple[float, float]] | None,
    noise_model: str = "diagonal",
    noise_shape: float = NOISE_PRIOR_SHAPE,
) -> Prior:
    """Gaussian priors ``{name: (mean, std)}`` in SI -> a :class:`Prior` on the scaled parameters; flat elsewhere.

    Names: shared parameter names, ``FSI.added_mass`` / ``FSI.added_damping``
    (every mode) or ``FSI.added_mass_<mode>`` (one mode). ``noise_shape`` 0
    leaves out the prior on the Gibbs sampler's ``Δ`` (the HMC's marginal
    model has no ``Δ``).

    Examples
    --------
    >>> from twin.update import synthesize_modes
    >>> from twin.update.problem import build_problem
    >>> m = hydro_unit
    >>> problem = build_problem(m, synthesize_modes(m, samples=5, seed=0).isel(mode=[2, 3]), ["UGB.kxx"])
    >>> prior = build_prior(problem, {"UGB.kxx": (5e8, 1e8)}, noise_shape=0.0)
    >>> bool(prior.global_precision[0] > 0), float(prior.noise_shape)
    (True, 0.0)
    """
    prior = Prior.flat(problem, noise_shape=noise_shape, noise_model=noise_model)
    for name, (mean, std) in (priors or {}).items():
        if not std > 0:
            raise UpdateError(f"prior of '{name}': the std must be positive, got {std}")
        if name in problem.global_names:
            k = problem.global_names.index(name)
            s = problem.global_scale[k]
            prior.global_mean[k], prior.global_precision[k] = mean / s, (s / std) ** 2
            continue
        hit = False
        for q, kind in enumerate(problem.mode_names):
            for i, m in enumerate(problem.modes):
                if name in (f"FSI.{kind}", f"FSI.{kind}_{m}"):
                    s = problem.mode_scale[i, q]
                    prior.mode_mean[i, q], prior.mode_precision[i, q] = mean / s, (s / std) ** 2
                    hit = True
        if not hit:
            raise UpdateError(
                f"prior given for '{name}', which is not updated (updated: {', '.join(problem.parameter_labels)})"
            )
    return prior
