"""HMC on the marginal posterior: the default sampler of the update.

**What it samples.** The errors-in-variables PerCEM of
:mod:`twin.update.marginal`: each mode's mean pole and mean shape with their
covariances, the true shapes, the perturbations and the pole deviations
integrated out in closed form, so that only the parameters ``θ = (t, η)``
are left. They are few (a handful of shared parameters, two per mode with
per-mode FSI) and the density is smooth with an exact gradient.

**How.** Hamiltonian Monte Carlo with the metric adapted in the warm-up, a
jittered path length of about a quarter period and the step size tuned by
dual averaging (:func:`run_chain`), each trajectory followed by a slice step
of every mode's own parameters given the shared ones
(:mod:`twin.update.samplers.slice`); after each kept draw the shapes are
drawn given ``θ`` in closed form, so the posterior holds latent shapes as
the Gibbs samplers' does.

**When to use it.** Always, unless the point is to reproduce the reference
paper (:mod:`twin.update.samplers.paper`) or to compare with the Gibbs
sampler of the full model (:mod:`twin.update.samplers.gibbs`). It is the
sampler whose intervals were calibrated on the twin's own FMU records (the
benchmarks' coverage pages), it mixes weakly determined parameters that the
Gibbs samplers leave stuck (the paper's Case B), and it is the fastest per
effective draw (``benchmarks/update_speed.py``). It needs the stage-2
condensation (every parametrised DOF observed or condensed); where a sensor
layout leaves latent shape entries, use the Gibbs sampler.

Examples
--------
>>> from twin.update import HMCOptions, synthesize_modes, update
>>> m = hydro_unit
>>> data = synthesize_modes(m, samples=20, seed=0).isel(mode=[2, 3, 9])
>>> post = update(m, data, fsi=True, options=HMCOptions(draws=50, chains=1, seed=1, progress=False))
>>> post.attrs["method"]
'hmc'
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import scipy.linalg as sla
import xarray as xr

from twin.defaults import HMC_MIN_WARMUP, HMC_WARMUP
from twin.fem.effects import is_per_mode_name
from twin.fem.model import RotorModel
from twin.progress import bar
from twin.tasks import mapper, one_blas_thread
from twin.update.algebra import weak_parameters
from twin.update.chain import Chain, Prior, build_prior
from twin.update.intersection import COMBINATIONS, check_combination, intersected
from twin.update.marginal import (
    SHAPE_COVARIANCES,
    STUDENT_DOF,
    Density,
    Marginal,
    check_shape_covariance,
    log_density,
    marginal_precision,
    marginal_problem,
    mode_density,
    posterior_mode,
    shape_draw,
)
from twin.update.poles import POLE_ERRORS, order_covariance
from twin.update.problem import Problem, UpdateError, build_problem
from twin.update.samplers.base import Sampler, SamplerOptions
from twin.update.samplers.slice import block_axes, slice_blocks
from twin.update.shrinkage import shrunk_covariance

log = logging.getLogger(__name__)

#: Warm-up iterations by default (the step size and the metric are tuned there).
WARMUP = HMC_WARMUP
#: Mean path length of a trajectory in the whitened parameters: a quarter period of the Gaussian at the mode
#: (see :func:`run_chain`).
PATH_LENGTH = 0.5 * np.pi
#: Relative jitter of the path length: uniform within ``PATH_LENGTH (1 ± PATH_JITTER)``.
PATH_JITTER = 0.2
#: Fewest leapfrog steps of a trajectory (see :func:`run_chain`).
MIN_STEPS = 2
#: Acceptance rate the step size is tuned to.
TARGET_ACCEPT = 0.8


@dataclass(frozen=True)
class HMCOptions(SamplerOptions):
    """Options of the HMC sampler (with those of :class:`~twin.update.samplers.base.SamplerOptions`).

    Attributes
    ----------
    warmup : int
        Warm-up iterations per chain (the metric and the step size are tuned there), at least 50.
    per_mode_slice : bool
        Follow each trajectory by a slice step of every mode's own parameters given the shared ones.
    student_dof : float
        Degrees of freedom of each mode's Student t tail (:func:`twin.update.marginal.tail_kernel`).
    shape_covariance : {"shrunk", "held-out", "sample"}
        Each mode's shape covariance from its samples: correlations shrunk toward zero by Schäfer and
        Strimmer's intensity (the default, the one calibrated), by the intensity under which each sample
        held out of the others is most likely, or none (which needs samples spanning every shape entry).
        The other two are kept for the benchmarks that compare them.
    combine : {"intersection", "independent"}
        How each mode's pole and shape errors, which come from one estimate, are combined: by covariance
        intersection (the default: a bound whatever their correlation, :mod:`twin.update.intersection`), or
        as if independent (which overstates what a mode says; kept for the benchmark that measures it).
    pole_error : {"samples+orders", "samples"}
        Each mean pole's error: its samples' covariance over ``J`` plus its spread over the model orders
        the extraction averaged over (the default; :func:`twin.update.poles.order_covariance`), or the
        samples' alone.
    """

    warmup: int = WARMUP
    per_mode_slice: bool = True
    student_dof: float = STUDENT_DOF
    shape_covariance: str = SHAPE_COVARIANCES[0]
    combine: str = COMBINATIONS[0]
    pole_error: str = POLE_ERRORS[0]

    MIN_WARMUP: ClassVar[int] = HMC_MIN_WARMUP

    def __post_init__(self) -> None:
        super().__post_init__()
        check_shape_covariance(self.shape_covariance)
        check_combination(self.combine)
        if self.pole_error not in POLE_ERRORS:
            raise UpdateError(f"pole_error must be one of {', '.join(POLE_ERRORS)}, got {self.pole_error!r}")
        if not self.student_dof > 0:
            raise UpdateError(f"student_dof must be positive, got {self.student_dof!r}")


class HMC(Sampler):
    """HMC on the marginal posterior (see the module docstring)."""

    name = "hmc"
    options_type = HMCOptions

    def prepare(self, problem: Problem, modes: xr.Dataset, options: HMCOptions) -> Marginal:
        return marginal_of(problem, modes, options)

    def undetermined(self, target: Marginal) -> list[str]:
        return weak_parameters(target.problem.parameter_labels, marginal_precision(target))

    def run(self, target: Marginal, prior: Prior, options: HMCOptions, tasks: Any = None) -> list[Chain]:
        return run_chains(
            target,
            options.draws,
            options.chains,
            warmup=options.warmup,
            prior=prior,
            seed=options.seed,
            progress=options.progress,
            tasks=tasks,
            nu=options.student_dof,
            per_mode_slice=options.per_mode_slice,
        )

    def describe(self, options: HMCOptions) -> str:
        slice_step = ", each trajectory followed by a slice step of every eta_i | t" if options.per_mode_slice else ""
        return (
            "HMC on the marginal of (t, eta), with (psi, eps) and the pole deviations integrated out "
            f"(errors-in-variables PerCEM, Student t tail per mode){slice_step}; then psi | t, eta (closed form)"
        )

    def attrs(self, target: Marginal) -> dict[str, str]:
        if target.weights is None:
            return {}
        return {
            "intersection_weights": json.dumps(
                {str(int(m)): round(float(w), 4) for m, w in zip(target.problem.modes, target.weights)}
            )
        }


def marginal_of(problem: Problem, modes: xr.Dataset, options: HMCOptions | None = None) -> Marginal:
    """The marginal model (:mod:`twin.update.marginal`) of ``problem`` on ``modes``, as the HMC sampler samples it.

    ``problem`` is built with ``pole_model="marginal"``; ``options`` say how each mode's errors are estimated
    and combined (``shape_covariance``, ``pole_error``, ``combine``).
    """
    options = options or HMCOptions()
    order_cov = order_covariance(modes) if options.pole_error == "samples+orders" else None
    marg = marginal_problem(
        problem, modes["pole"].transpose("mode", "sample").values, options.shape_covariance, order_cov=order_cov
    )
    return intersected(marg) if options.combine == "intersection" else marg


def marginal_setup(model: RotorModel, modes: xr.Dataset, settings: Mapping[str, Any]) -> tuple[Marginal, Prior]:
    """The marginal model and the prior of an HMC update of ``model`` on ``modes`` with ``settings``.

    ``settings`` is an HMC posterior's (its attr ``settings``, parsed): the parameters, ``fsi``, the
    priors and the options. Used to repeat an update's density on other modes
    (:mod:`twin.loop.bootstrap`): priors of per-mode FSI of modes these modes lack are left out.

    Examples
    --------
    >>> from twin.update import synthesize_modes
    >>> m = hydro_unit
    >>> data = synthesize_modes(m, samples=20, seed=0).isel(mode=[2, 3, 9])
    >>> marg, prior = marginal_setup(m, data, {"method": "hmc", "params": ["UGB.kxx"],
    ...                                        "priors": {"UGB.kxx": [5e8, 1e8]}})
    >>> marg.problem.parameter_labels, float(prior.parameter_mean[0]) > 0
    (['UGB.kxx'], True)
    """
    if settings.get("method", "hmc") != "hmc":
        raise UpdateError(
            f"the posterior's sampler is {settings['method']!r}: only the HMC sampler's density "
            "can be repeated (method='hmc')"
        )
    fields = {k: settings[k] for k in HMCOptions.__dataclass_fields__ if k in settings}
    options = HMCOptions(**fields)
    problem = build_problem(
        model,
        modes,
        list(settings["params"]),
        fsi=bool(settings.get("fsi", False)),
        eps_std=options.eps_std,
        pole_model="marginal",
    )
    priors = settings.get("priors", "flat")
    priors = {} if priors == "flat" else {k: (float(v[0]), float(v[1])) for k, v in priors.items()}
    labels = set(problem.parameter_labels)
    priors = {k: v for k, v in priors.items() if k in labels or not is_per_mode_name(k)}
    return marginal_of(problem, modes, options), build_prior(problem, priors, "full", 0.0)


@one_blas_thread
def run_chain(
    marg: Marginal,
    draws: int,
    *,
    warmup: int = WARMUP,
    prior_mean: np.ndarray | None = None,
    prior_precision: np.ndarray | None = None,
    rng: np.random.Generator | None = None,
    progress: bool = False,
    label: str = "HMC",
    nu: float = STUDENT_DOF,
    per_mode_slice: bool = True,
) -> Chain:
    """One HMC chain on the marginal: ``warmup`` iterations that tune it, then ``draws`` kept.

    The metric (mass matrix) is first the Gauss-Newton precision at the
    posterior mode; in the warm-up it is replaced by the covariance of the
    warm-up's own draws (:func:`warmup_covariance`), where the posterior is
    not the Gaussian at its mode (the Student t of each mode's residual gives
    heavier tails along weakly determined directions). The step size is tuned
    to :data:`TARGET_ACCEPT` by dual averaging (Hoffman and Gelman 2014).

    Each trajectory runs for a path length drawn uniformly within
    ``PATH_LENGTH (1 ± PATH_JITTER)``, in a whole number of leapfrog steps no
    longer than the tuned step size. In the whitened parameters the Gaussian
    at the mode turns by that length in radians: a quarter turn takes a draw
    to one independent of it, in its value and in its square (the spread,
    which the interval's quantiles and the folded R-hat depend on); a half
    turn gives antithetic draws, whose bulk ESS flatters the spread. The step
    size is rounded down to fit the length, so that no few large steps fall
    on the same turn every time.

    A trajectory takes at least :data:`MIN_STEPS` leapfrog steps: with one or
    two parameters the dual averaging otherwise ends either side of the path
    length, a chain taking it in one step (accepting about 71%) and another in
    two (about 95%), and the chains' step sizes differ by orders of magnitude.

    With ``per_mode_slice`` (and per-mode parameters), each trajectory is
    followed by a slice-sampling update of every mode's own parameters given
    the shared ones (:func:`twin.update.samplers.slice.slice_blocks`, along
    the principal axes of each mode's block of the metric, with
    :func:`twin.update.marginal.mode_density`): given ``t`` the modes are
    independent, so a mode whose parameters the data barely determine no
    longer holds the others back through the one step size and the one
    accept-reject of the joint trajectory.

    The chain starts from a draw of the Gaussian at the posterior mode. In the
    :class:`~twin.update.chain.Chain` it returns, ``noise`` is the mean
    residual variance ``diag V_i``, ``accepted`` whether the trajectory was
    accepted, ``acceptance_rate`` its Metropolis acceptance probability,
    ``step_size`` and ``n_steps`` its leapfrog steps.

    Examples
    --------
    >>> from twin.update import synthesize_modes
    >>> from twin.update.problem import build_problem
    >>> m = hydro_unit
    >>> data = synthesize_modes(m, samples=50, seed=0).isel(mode=[2, 3])
    >>> marg = marginal_problem(build_problem(m, data, fsi=True, pole_model="marginal"), data["pole"].values)
    >>> chain = run_chain(marg, 100, rng=np.random.default_rng(0))
    >>> mass = chain.eta[:, :, 0] * marg.problem.mode_scale[:, 0]
    >>> np.round(np.median(mass, axis=0) / [7.80e4, 6.09e4], 1)   # paper Table 2, modes 3 and 4
    array([1., 1.])
    """
    rng = rng or np.random.default_rng()
    p = marg.problem
    n = marg.size
    prior_mean = np.zeros(n) if prior_mean is None else prior_mean
    prior_precision = np.zeros(n) if prior_precision is None else prior_precision
    mode, at_mode = posterior_mode(marg, prior_mean, prior_precision, nu)
    Lm = np.linalg.cholesky(at_mode.precision)  # mass matrix: whitened y = Lmᵀ θ

    def evaluate(y: np.ndarray) -> tuple[Density | None, np.ndarray]:
        theta = sla.solve_triangular(Lm, y, trans="T", lower=True)
        try:
            d = log_density(marg, theta, prior_mean, prior_precision, nu, curvature=False)
        except np.linalg.LinAlgError:
            return None, theta
        return (d if np.isfinite(d.log_p) else None), theta

    def gradient(d: Density) -> np.ndarray:
        return sla.solve_triangular(Lm, d.gradient, lower=True)

    y = Lm.T @ mode + rng.standard_normal(n)
    here, theta = evaluate(y)
    if here is None:
        y, (here, theta) = Lm.T @ mode, evaluate(Lm.T @ mode)
    g = gradient(here)
    slicing = per_mode_slice and p.n_per_mode > 0
    f = held = None  # each mode's density in its own parameters, and the shared ones it was built at
    if slicing:
        axes, widths = block_axes(Lm @ Lm.T, p.n_global, p.n_modes, p.n_per_mode)
    warm = warmup
    window = _mass_window(warm)
    eps, log_eps_bar, h_bar, mu, k = 0.5, 0.0, 0.0, np.log(5.0), 0
    log_eps_max = np.log(PATH_LENGTH * (1 + PATH_JITTER) / MIN_STEPS)  # any longer step gives MIN_STEPS steps too
    seen = []
    out = np.empty((draws, n))
    psi = np.empty((draws, p.n_modes, len(p.data_index)))
    noise, lps, accepted = np.empty((draws, p.n_modes)), np.empty(draws), np.zeros(draws, bool)
    rates, step_sizes, n_steps = np.empty(draws), np.empty(draws), np.empty(draws, int)
    for it in bar(range(warm + draws), desc=label, progress=progress, leave=False):
        length = rng.uniform(1 - PATH_JITTER, 1 + PATH_JITTER) * PATH_LENGTH
        steps = max(MIN_STEPS, int(np.ceil(length / eps)))
        step = length / steps  # the jittered length exactly: a whole number of steps of at most eps
        mom = rng.standard_normal(n)
        h0 = -here.log_p + 0.5 * mom @ mom
        yn, gn, pn, new = y.copy(), g, mom + 0.5 * step * g, None
        for s in range(steps):
            yn = yn + step * pn
            new, theta_n = evaluate(yn)
            if new is None:
                break
            gn = gradient(new)
            pn = pn + (step if s < steps - 1 else 0.5 * step) * gn
        a = 0.0 if new is None else float(min(1.0, np.exp(h0 - (-new.log_p + 0.5 * pn @ pn))))
        moved = rng.uniform() < a
        if moved:
            y, g, here, theta = yn, gn, new, theta_n
        if slicing:
            if f is None or not np.array_equal(theta[: p.n_global], held):  # its coefficients depend on t only
                f, held = mode_density(marg, theta, prior_mean, prior_precision, nu), theta[: p.n_global].copy()
            eta = slice_blocks(f, theta[p.n_global :].reshape(p.n_modes, -1), axes, widths, rng)[0]
            theta = np.concatenate([theta[: p.n_global], eta.ravel()])
            y = Lm.T @ theta
            here, _ = evaluate(y)
            g = gradient(here)
        if it < warm:  # dual averaging (Hoffman and Gelman 2014)
            k += 1
            h_bar += ((TARGET_ACCEPT - a) - h_bar) / (k + 10)
            log_eps = min(mu - np.sqrt(k) / 0.05 * h_bar, log_eps_max)
            log_eps_bar = k**-0.75 * log_eps + (1 - k**-0.75) * log_eps_bar
            eps = float(np.exp(log_eps if it < warm - 1 else log_eps_bar))
            if window[0] <= it < window[1]:
                seen.append(theta)
            if it == window[1] - 1:  # the warm-up's own covariance becomes the metric
                Lm = np.linalg.cholesky(np.linalg.inv(warmup_covariance(np.array(seen), at_mode.precision)))
                y, g = Lm.T @ theta, gradient(here)
                if slicing:
                    axes, widths = block_axes(Lm @ Lm.T, p.n_global, p.n_modes, p.n_per_mode)
                log_eps_bar, h_bar, mu, k = 0.0, 0.0, np.log(10 * eps), 0
            continue
        j = it - warm
        out[j], lps[j], noise[j], accepted[j] = theta, here.log_p, here.residual_variance, moved
        rates[j], step_sizes[j], n_steps[j] = a, step, steps
        psi[j] = shape_draw(marg, theta, rng)
    log.debug("%s: step size %.3g after the warm-up, accepted %.0f%%", label, eps, 100 * accepted.mean())
    Kg = p.n_global
    return Chain(
        out[:, :Kg],
        out[:, Kg:].reshape(draws, p.n_modes, p.n_per_mode),
        psi,
        noise,
        lps,
        accepted,
        rates,
        step_sizes,
        n_steps,
    )


def _mass_window(warm: int) -> tuple[int, int]:
    """Warm-up iterations whose draws set the metric: after the first fifth, up to the last fifth."""
    return warm // 5, warm - warm // 5


def warmup_covariance(draws: np.ndarray, precision: np.ndarray) -> np.ndarray:
    """The metric's covariance from warm-up draws, regularised toward the Gauss-Newton one.

    In the coordinates whitened by the Gauss-Newton ``precision`` the
    posterior's covariance is the identity where the posterior is the
    Gaussian at its mode. There the draws' covariance is estimated with its
    correlations shrunk toward zero (:func:`shrunk_covariance`) and the
    variances toward one, with the weight ``5 / (N + 5)`` of the N draws
    (as Stan regularises its metric).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> draws = rng.standard_normal((400, 2)) * [1.0, 3.0]   # the second direction 3x wider than assumed
    >>> np.round(np.sqrt(np.diag(warmup_covariance(draws, np.eye(2)))), 1)
    array([1., 3.])
    """
    L = np.linalg.cholesky(precision)
    w = draws @ L  # whitened: w = Lᵀ θ per draw
    N = len(w)
    var = np.var(w, axis=0, ddof=1)
    var = (N * var + 5.0) / (N + 5.0)
    cov_w = shrunk_covariance(w, var)
    Linv = sla.solve_triangular(L, np.eye(len(L)), lower=True)  # θ = L⁻ᵀ w
    return Linv.T @ cov_w @ Linv


def run_chains(
    marg: Marginal,
    draws: int,
    chains: int,
    *,
    warmup: int = WARMUP,
    prior: Prior | None = None,
    seed: int | None = None,
    progress: bool = False,
    tasks: Any = None,
    nu: float = STUDENT_DOF,
    per_mode_slice: bool = True,
) -> list[Chain]:
    """Independent HMC chains (seeds spawned from ``seed``), each from its own draw about the posterior mode.

    ``prior`` is a :class:`twin.update.chain.Prior` (its Gaussian parameter
    priors are used; the marginal model has no ``Δ``). ``tasks`` says where
    the chains run (:func:`twin.tasks.mapper`); the chains do not depend on it.
    """
    mean = precision = None
    if prior is not None:
        mean, precision = prior.parameter_mean, prior.parameter_precision
    seeds = np.random.SeedSequence(seed).spawn(chains)
    jobs = [(s, f"chain {c + 1}/{chains}") for c, s in enumerate(seeds)]
    return mapper(tasks, progress=progress, desc="chains")(
        _chain_task,
        jobs,
        marg=marg,
        draws=draws,
        warmup=warmup,
        mean=mean,
        precision=precision,
        progress=progress and tasks is None,
        nu=nu,
        per_mode_slice=per_mode_slice,
    )


def _chain_task(
    job: tuple[np.random.SeedSequence, str],
    marg: Marginal,
    draws: int,
    warmup: int,
    mean: np.ndarray | None,
    precision: np.ndarray | None,
    progress: bool,
    nu: float,
    per_mode_slice: bool,
) -> Chain:
    seed, label = job
    return run_chain(
        marg,
        draws,
        warmup=warmup,
        prior_mean=mean,
        prior_precision=precision,
        rng=np.random.default_rng(seed),
        progress=progress,
        label=label,
        nu=nu,
        per_mode_slice=per_mode_slice,
    )
