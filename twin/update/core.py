"""``update``: modes.nc + model -> posterior.nc, by the APerCEM Gibbs sampler."""

from __future__ import annotations

import dataclasses
import json
import logging
import time
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from twin import __version__
from twin.errors import TwinWarning
from twin.extract.modesfile import read_modes, split_complex
from twin.fem.effects import PER_MODE_NAME, effect_label
from twin.fem.model import RotorModel
from twin.fem.modelfile import load_model
from twin.netcdf import check_writable
from twin.update.adjust import ADJUSTMENTS, correlation_factors, stretch
from twin.update.gibbs import (NOISE_PRIOR_SHAPE, Chain, Prior, check_noise_model, initial_state, not_identifiable,
                               run_chains, stack, weak_parameters)  # fmt: skip
from twin.update.intersection import check_combination, intersected
from twin.update.marginal import Marginal, check_shape_covariance, marginal_precision, marginal_problem
from twin.update.marginal import run_chains as run_marginal
from twin.update.poles import POLE_ERRORS, check_pole_model, order_covariance
from twin.update.priors import plausible_priors
from twin.update.problem import Problem, UpdateError, build_problem, select_parameters
from twin.update.posterior import RHAT_LIMIT, diagnostics_json, observed_data, summary, write_posterior

log = logging.getLogger(__name__)

#: Condensation margin (pole spreads to the nearest resonance of the unobserved DOFs) below which a mode is flagged.
MIN_MARGIN = 5.0
#: Posterior std, relative to the nominal value (or to the posterior mean when the nominal is zero), above
#: which a parameter is reported as poorly determined.
POORLY_DETERMINED = 0.5
#: Sweeps discarded at the start of each chain by default (the chains start from zero).
BURN_IN = 20
#: The default: the errors-in-variables PerCEM with the shapes, perturbations and pole deviations
#: integrated out, its parameters sampled by HMC (:mod:`twin.update.marginal`); ``noise_model`` and
#: ``collapsed`` only apply to the Gibbs configurations (``pole_model`` "linear" or "samples"). Where the
#: Gibbs sampler with a full Δ left weakly determined parameters unmixed (paper Case B: bulk ESS 2 of
#: 500), this one mixes (README, benchmarks/update_speed.py). Its 90% intervals cover about 91% of the
#: truths on the paper's data (Case A and B); on extracted modes, with each mode's pole and shape errors
#: combined by covariance intersection (``combine``), the model's own posterior (no ``adjust``) covers
#: 89-95.4% by parameter group over 100-160 FMU records each, except a hidden seal: 82.7% of 220 records,
#: below the 85-95% aimed at (the bearings' stiffness 95.4% of 1120 values; README, stop 61;
#: benchmarks/results/update_coverage_fmu.md).
CALIBRATED = {"pole_model": "marginal"}
#: The reference paper's configuration (its Table 1): diagonal Δ, bases at every pole sample, plain Gibbs.
PAPER = {"noise_model": "diagonal", "collapsed": False, "pole_model": "samples"}


def _prior(problem: Problem, priors: Mapping[str, tuple[float, float]] | None, noise_model: str = "diagonal",
           noise_shape: float = NOISE_PRIOR_SHAPE) -> Prior:  # fmt: skip
    """Gaussian priors ``{name: (mean, std)}`` in SI -> scaled precisions; flat elsewhere.

    Names: shared parameter names, ``FSI.added_mass`` / ``FSI.added_damping``
    (every mode) or ``FSI.added_mass_<mode>`` (one mode). ``noise_shape`` 0 leaves out the prior on
    the Gibbs sampler's Δ (the marginal model has none, and its three "samples" have no scatter to scale it).
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
            raise UpdateError(f"prior given for '{name}', which is not updated "
                              f"(updated: {', '.join(problem.parameter_labels)})")  # fmt: skip
    return prior


def marginal_of(problem: Problem, modes: xr.Dataset, *, shape_covariance: str = "shrunk", logdet: bool = False,
                pole_error: str = "samples+orders", combine: str = "intersection") -> Marginal:  # fmt: skip
    """The marginal model (:mod:`twin.update.marginal`) of ``problem`` on ``modes``, as :func:`update` samples it.

    The keywords are :func:`update`'s (its defaults for the marginal model).
    """
    order_cov = order_covariance(modes) if pole_error == "samples+orders" else None
    marg = marginal_problem(problem, modes["pole"].transpose("mode", "sample").values, shape_covariance,
                            logdet=logdet, order_cov=order_cov)  # fmt: skip
    return intersected(marg) if combine == "intersection" else marg


def marginal_setup(model: RotorModel, modes: xr.Dataset, settings: Mapping[str, Any]) -> tuple[Marginal, Prior]:
    """The marginal model and the prior of an update of ``model`` on ``modes`` with ``settings``.

    ``settings`` is a marginal-model posterior's (its attr ``settings``, parsed): the parameters, ``fsi``,
    ``eps_std``, the priors and the marginal's options. Used to repeat an update's density on other modes
    (:mod:`twin.loop.bootstrap`): priors of per-mode FSI of modes these modes lack are left out.

    Examples
    --------
    >>> import json
    >>> from twin import load_model, shipped_model
    >>> from twin.update import synthesize_modes
    >>> m = load_model(shipped_model("hydro_unit"))
    >>> data = synthesize_modes(m, samples=20, seed=0).isel(mode=[2, 3, 9])
    >>> marg, prior = marginal_setup(m, data, {"params": ["UGB.kxx"], "priors": {"UGB.kxx": [5e8, 1e8]}})
    >>> marg.problem.parameter_labels, float(prior.parameter_mean[0]) > 0
    (['UGB.kxx'], True)
    """
    if settings.get("pole_model", "marginal") != "marginal":
        raise UpdateError(f"the posterior's pole model is {settings['pole_model']!r}: only the marginal model's "
                          "density can be repeated (pole_model='marginal')")  # fmt: skip
    problem = build_problem(model, modes, list(settings["params"]), fsi=bool(settings.get("fsi", False)),
                            eps_std=float(settings.get("eps_std", 1e-6)), pole_model="marginal")  # fmt: skip
    priors = settings.get("priors", "flat")
    priors = {} if priors == "flat" else {k: (float(v[0]), float(v[1])) for k, v in priors.items()}
    labels = set(problem.parameter_labels)
    priors = {k: v for k, v in priors.items() if k in labels or not PER_MODE_NAME.match(k)}
    prior = _prior(problem, priors, "full", 0.0)
    marg = marginal_of(problem, modes, shape_covariance=settings.get("shape_covariance", "shrunk"),
                       logdet=bool(settings.get("logdet", False)),
                       pole_error=settings.get("pole_error") or "samples+orders",
                       combine=settings.get("combine") or "intersection")  # fmt: skip
    return marg, prior


def _warn_margins(problem: Problem, frequency_hz: np.ndarray, n_samples: int, marginal: bool) -> None:
    """Warn of modes within :data:`MIN_MARGIN` spreads of a resonance of the unobserved DOFs.

    The spread is the pole samples' std for the Gibbs pole models, which evaluate the condensed model at
    (or linearise it over) the samples, and the mean pole's standard error for the marginal model.
    """
    margin, unit = (problem.margin * np.sqrt(n_samples), "mean-pole standard errors") if marginal else \
        (problem.margin, "pole-sample stds")  # fmt: skip
    for i in np.flatnonzero(margin < MIN_MARGIN):
        warnings.warn(
            f"mode {problem.modes[i]} ({frequency_hz[i]:.2f} Hz) lies {margin[i]:.1f} {unit} from "
            f"a resonance of the unobserved DOFs ({problem.resonance_hz[i]:.2f} Hz): the condensed model is "
            "ill-conditioned there and this mode's parameters are unreliable",
            TwinWarning, stacklevel=3,
        )  # fmt: skip


def posterior_tree(problem: Problem, chains: Chain, modes: xr.Dataset, attrs: dict) -> xr.DataTree:
    """The ArviZ-layout DataTree of a run (SI units)."""
    n_chain, n_draw = chains.lp.shape
    coords = {"chain": np.arange(n_chain), "draw": np.arange(n_draw)}
    post = xr.Dataset(coords=coords)
    if problem.n_global:
        post["theta"] = xr.DataArray(chains.t * problem.global_scale, dims=("chain", "draw", "parameter"),
                                     coords={"parameter": problem.global_names},
                                     attrs={"long_name": "updated model parameters (SI units of each parameter)"})  # fmt: skip
    mode_coord = {"mode": problem.modes}
    units = {"added_mass": "kg", "added_damping": "N s/m"}
    for q, kind in enumerate(problem.mode_names):
        post[kind] = xr.DataArray(chains.eta[..., q] * problem.mode_scale[:, q], dims=("chain", "draw", "mode"),
                                  coords=mode_coord, attrs={"units": units[kind],
                                  "long_name": f"per-mode FSI {kind.replace('_', ' ')} on the immersed DOFs"})  # fmt: skip
    n_o = len(problem.channels)
    shape = chains.psi[..., :n_o] + 1j * chains.psi[..., n_o:]
    post["shape"] = xr.DataArray(shape, dims=("chain", "draw", "mode", "channel"),
                                 coords={**mode_coord, "channel": problem.channels},
                                 attrs={"long_name": "observed mode shape (latent ψ)"})  # fmt: skip
    post = split_complex(post)
    stats = xr.Dataset(
        {
            "lp": (("chain", "draw"), chains.lp, {"long_name": "log joint density, up to a constant"}),
            "noise_variance": (("chain", "draw", "mode"), chains.noise,
                               {"long_name": "mean variance of a row of the condensed residual: Δ_i (Gibbs) or "
                                             "V_i (marginal model) (relative units)"}),
            "accepted": (("chain", "draw"), chains.accepted,
                         {"long_name": "whether the collapsed Metropolis step (Gibbs) or the HMC trajectory "
                                       "moved the parameters (all false when the sampler is plain Gibbs)"}),
        },  # fmt: skip
        coords={**coords, **mode_coord},
    )
    if np.any(chains.n_steps):  # HMC (the marginal model): ArviZ's names for its step statistics
        stats["acceptance_rate"] = (("chain", "draw"), chains.acceptance_rate,
                                    {"long_name": "Metropolis acceptance probability of the HMC trajectory"})
        stats["step_size"] = (("chain", "draw"), chains.step_size,
                              {"long_name": "leapfrog step, in the parameters whitened by the metric"})
        stats["n_steps"] = (("chain", "draw"), chains.n_steps, {"long_name": "leapfrog steps of the trajectory"})
    observed = observed_data(modes)
    constant = xr.Dataset(
        {
            "nominal": ("parameter", problem.global_nominal, {"long_name": "value before the update (SI)"}),
            "scale": ("parameter", problem.global_scale, {"long_name": "scale of the sampled coordinate (SI)"}),
            "fsi_scale": (("mode", "fsi_parameter"), problem.mode_scale),
            "condensation_margin": ("mode", problem.margin,
                                    {"long_name": "pole-sample stds to the nearest resonance of the unobserved DOFs"}),
        },  # fmt: skip
        coords={"parameter": problem.global_names, "fsi_parameter": problem.mode_names, **mode_coord},
    )
    return xr.DataTree.from_dict(
        {"/": xr.Dataset(attrs=attrs), "posterior": post, "sample_stats": stats, "observed_data": observed,
         "constant_data": constant}  # fmt: skip
    )


def update(
    model: RotorModel | str | Path,
    modes: xr.Dataset | str | Path,
    params: str | Sequence[str] | None = None,
    *,
    fsi: bool = False,
    draws: int = 500,
    chains: int = 4,
    burn_in: int = BURN_IN,
    seed: int | None = None,
    priors: Mapping[str, tuple[float, float]] | None = None,
    plausible: bool = True,
    eps_std: float = 1e-6,
    noise_model: str = "full",
    collapsed: bool = True,
    pole_model: str = CALIBRATED["pole_model"],
    adjust: str | None = None,
    shape_covariance: str = "shrunk",
    combine: str | None = None,
    pole_error: str | None = None,
    logdet: bool = False,
    output: str | Path | None = None,
    progress: bool = True,
    command: str = "",
    tasks: Any = None,
) -> xr.DataTree:
    """Bayesian updating of a model from modal samples with the APerCEM (perturbed condensed eigen-model).

    By default the shapes, the perturbations and the pole deviations are
    integrated out and the parameters sampled by HMC on their marginal
    (:mod:`twin.update.marginal`); ``pole_model="linear"`` or ``"samples"``
    give the Gibbs sampler (``**twin.update.PAPER``: the paper's).

    Parameters
    ----------
    model : RotorModel or path
        The model (``MODEL.toml``); parameters not updated keep their values.
    modes : xarray.Dataset or path
        ``modes.nc`` from :func:`twin.extract.extract` or :func:`twin.update.synthesize_modes`.
    params : str or sequence of str, optional
        Shared parameters: names, globs or groups (``bearings``, ``thrust``, ``disks``).
    fsi : bool
        Also update the per-mode FSI added mass and damping on the immersed region.
    draws, chains, burn_in : int
        Kept draws per chain, number of chains, discarded sweeps per chain.
        Every Gibbs chain starts from zero parameters; every HMC chain from a
        draw about the posterior mode, after at least
        :data:`twin.update.marginal.WARMUP` warm-up iterations.
    seed : int, optional
        Seed of the chains.
    priors : mapping, optional
        Gaussian priors ``{name: (mean, std)}`` in SI units; they replace the
        ``plausible`` ones of the same names. Parameters without one are flat.
    plausible : bool
        Give each updated parameter of the model's effects (and the per-mode
        FSI of ``fsi``) a Gaussian prior centred on the model's value, as wide
        as the effect's plausible scale (:func:`twin.update.priors.plausible_priors`):
        no change where the data determine the parameter, a bound on what
        they do not. False: flat.
    eps_std : float
        σ of the perturbation ε of the condensed eigen-equation, relative to
        the dynamic stiffness.
    noise_model : {"full", "diagonal"}
        Gibbs sampler only: covariance of the residual realisations ``Δ_i``,
        a full matrix (inverse-Wishart), which accounts for rows correlated by
        the pole noise, or diagonal (the paper's model).
    collapsed : bool
        Gibbs sampler only: add to every sweep a Metropolis step of the
        parameters on their marginal with the shapes integrated out
        (:mod:`twin.update.collapsed`).
    pole_model : {"marginal", "linear", "samples"}
        How the pole samples enter the condensed eigen-model
        (:mod:`twin.update.poles`): through the mean pole and its covariance,
        the pole deviation integrated out with the shapes, sampled by HMC (the
        default); or, for the Gibbs sampler, linearised about each mode's mean
        pole, or the basis matrices at every sample (the paper's).
        ``**twin.update.PAPER`` gives the paper's sampler.
    adjust : {"none", "jackknife"}, optional
        ``"none"`` (the default): the model's posterior. ``"jackknife"``
        (marginal model only): stretch each parameter's draws about their mean
        by what the correlation of the modes adds to the spread of its
        posterior mode over perturbations of the data by its own samples,
        where that is more than one (:mod:`twin.update.adjust`: modes
        extracted from one record are correlated, the model's modes
        independent); the factors are in the attr ``spread_adjustment``. On
        the twin's FMU records the factor measured no error of the model's
        intervals (README, stop 58), so it is not the default.
    shape_covariance : {"shrunk", "held-out", "sample"}
        Marginal model only: each mode's shape covariance from its samples, its
        correlations shrunk toward zero by Schäfer and Strimmer's intensity (the
        default), or by the intensity under which each sample held out of the
        others is most likely (:func:`twin.update.shrinkage.held_out_intensity`:
        on FMU records the bearings calibrated, a hidden pull or seal narrower
        than its error; README), or the samples' own, which needs samples
        spanning every shape entry (:func:`twin.update.marginal.shape_covariance_of`).
    combine : {"intersection", "independent"}, optional
        Marginal model only (its default there: ``"intersection"``): how each
        mode's pole and shape errors, which come from one estimate and are
        correlated, are combined. ``"intersection"``: by covariance
        intersection, an upper bound on the residual's covariance whatever
        that correlation (:mod:`twin.update.intersection`; each mode's shape
        share is in the attr ``intersection_weights``); ``"independent"``: as
        if uncorrelated, which overstates what a mode says when its pole and
        its shape inform the same parameter.
    pole_error : {"samples+orders", "samples"}, optional
        Marginal model only (its default there: ``"samples+orders"``): each
        mean pole's error is its samples' covariance over ``J`` plus the
        pole's spread over the model orders the extraction averaged it over
        (``modes.nc``'s ``pole_order_cov``,
        :func:`twin.update.poles.order_covariance`: zero for synthetic modes),
        or the samples' alone.
    logdet : bool
        Marginal model only: keep each mode's ``-½ log |V_i(θ)|`` in the
        density (the Gaussian marginal of the residual, the model before
        stop 44). By default the density is the errors-in-variables
        likelihood ``exp(-q_i / 2)`` alone (:mod:`twin.update.marginal`).
    output : path, optional
        ``posterior.nc`` to write (atomically).
    progress : bool
        Progress bars over the sweeps (over the chains when they run on Dask).
    tasks : distributed.Client or mapper, optional
        Where the chains run, one task each (:func:`twin.tasks.mapper`): in
        this process by default. The draws do not depend on it.

    Returns
    -------
    xarray.DataTree
        Groups ``posterior``, ``sample_stats``, ``observed_data``, ``constant_data``;
        attrs with the settings, the method, R-hat and ESS per parameter.

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> from twin.update import synthesize_modes, update
    >>> m = load_model(shipped_model("hydro_unit"))
    >>> data = synthesize_modes(m, samples=20, seed=0, shape_cov=1e-4, pole_variance=(1e-6, 1e-6))
    >>> post = update(m, data.isel(mode=[2, 3, 9]), fsi=True, draws=50, chains=1, seed=1, progress=False)
    >>> mass = post["posterior"]["added_mass"].mean(("chain", "draw")).values
    >>> np.round(mass / [7.80e4, 6.09e4, 4.87e4], 2)   # paper Table 2, modes 3, 4, 10
    array([1., 1., 1.])
    """
    started = time.perf_counter()
    for name, value, least in (("draws", draws, 1), ("chains", chains, 1), ("burn_in", burn_in, 0)):
        if int(value) != value or value < least:
            raise UpdateError(f"{name} must be an integer >= {least}, got {value}")
    check_noise_model(noise_model)
    check_pole_model(pole_model)
    adjust = adjust or "none"
    if adjust not in ADJUSTMENTS:
        raise UpdateError(f"adjust must be one of {', '.join(ADJUSTMENTS)}, got {adjust!r}")
    if adjust != "none" and pole_model != "marginal":
        raise UpdateError(f"adjust={adjust!r} needs pole_model='marginal' (it searches the marginal's mode)")
    combine = combine or ("intersection" if pole_model == "marginal" else "independent")
    check_combination(combine)
    if combine != "independent" and pole_model != "marginal":
        raise UpdateError(f"combine={combine!r} needs pole_model='marginal' (the Gibbs sampler samples each "
                          "mode's pole and shapes as the paper's model does)")  # fmt: skip
    check_shape_covariance(shape_covariance)
    if shape_covariance != "shrunk" and pole_model != "marginal":
        raise UpdateError(f"shape_covariance={shape_covariance!r} needs pole_model='marginal' (the Gibbs sampler "
                          "learns its residual noise instead)")  # fmt: skip
    pole_error = pole_error or ("samples+orders" if pole_model == "marginal" else "samples")
    if pole_error not in POLE_ERRORS:
        raise UpdateError(f"pole_error must be one of {', '.join(POLE_ERRORS)}, got {pole_error!r}")
    for asked, setting in ((pole_error != "samples", f"pole_error={pole_error!r}"), (logdet, "logdet=True")):
        if asked and pole_model != "marginal":
            raise UpdateError(f"{setting} needs pole_model='marginal' (the Gibbs sampler's likelihood is the "
                              "paper's, on the pole samples themselves)")  # fmt: skip
    if output is not None:
        check_writable(output)
    source_model = str(model) if not isinstance(model, RotorModel) else model.source
    model = load_model(model) if not isinstance(model, RotorModel) else model
    source = str(modes) if not isinstance(modes, xr.Dataset) else "modes"
    modes = read_modes(modes) if not isinstance(modes, xr.Dataset) else modes
    names = select_parameters(model, params)
    problem = build_problem(model, modes, names, fsi=fsi, eps_std=eps_std, pole_model=pole_model, source=source)
    priors = {**(plausible_priors(model, names, fsi) if plausible else {}), **(priors or {})}
    prior = _prior(problem, priors, noise_model, 0.0 if pole_model == "marginal" else NOISE_PRIOR_SHAPE)
    frequency = np.abs(modes["pole"].mean("sample").values.imag) / (2 * np.pi)
    _warn_margins(problem, frequency, modes.sizes["sample"], pole_model == "marginal")
    if pole_model == "marginal":
        marg = marginal_of(problem, modes, shape_covariance=shape_covariance, logdet=logdet, pole_error=pole_error,
                           combine=combine)  # fmt: skip
        bad = weak_parameters(problem.parameter_labels, marginal_precision(marg))
    else:
        bad = not_identifiable(problem, initial_state(problem))
    if bad:
        raise UpdateError(f"the data cannot determine these parameters (singular conditional): {', '.join(bad)}")
    if pole_model == "marginal":
        chains_out = run_marginal(marg, draws, chains, burn_in=burn_in, prior=prior, seed=seed, progress=progress,
                                  tasks=tasks)  # fmt: skip
    else:
        chains_out = run_chains(problem, draws, chains, burn_in=burn_in, prior=prior, seed=seed, progress=progress,
                                tasks=tasks, collapsed=collapsed)  # fmt: skip
    result = stack(chains_out)
    factors = None
    if adjust == "jackknife":
        result, factors = _adjusted(result, marg, model, modes, names, fsi, eps_std, prior)
    elapsed = time.perf_counter() - started
    settings = {"params": names, "fsi": fsi, "draws": draws, "chains": chains, "burn_in": burn_in, "seed": seed,
                "eps_std": eps_std, "noise_model": noise_model, "collapsed": collapsed, "pole_model": pole_model,
                "adjust": adjust, "shape_covariance": shape_covariance, "combine": combine,
                "pole_error": pole_error, "logdet": logdet, "plausible": plausible,
                "priors": {k: list(v) for k, v in priors.items()} or "flat"}  # fmt: skip
    attrs = {
        "title": f"APerCEM posterior of {model.name}",
        "producer": f"twin {__version__}",
        "command": command,
        "model": model.name,
        "model_source": source_model,
        "modes_source": source,
        "settings": json.dumps(settings),
        "condensation": problem.method,
        "effects": json.dumps([effect_label(e) for e in model.effects]),
        "sampler": _sampler_text(pole_model, collapsed),
        "elapsed_s": elapsed,
    }
    if pole_model == "marginal" and marg.weights is not None:
        attrs["intersection_weights"] = json.dumps({str(int(m)): round(float(w), 4)
                                                    for m, w in zip(problem.modes, marg.weights)})
    if factors is not None:
        attrs["spread_adjustment"] = json.dumps(dict(zip(problem.parameter_labels, np.round(factors, 4).tolist())))
    if "truth" in modes.attrs:
        attrs["truth"] = modes.attrs["truth"]
    tree = posterior_tree(problem, result, modes, attrs)
    table = summary(tree["posterior"].to_dataset())
    tree.attrs["diagnostics"] = diagnostics_json(table)
    undetermined = undetermined_parameters(table, problem)
    tree.attrs["undetermined"] = json.dumps(sorted(undetermined))
    _warn_diagnostics(table, undetermined)
    if output is not None:
        write_posterior(tree, output)
    log.info("updated %d parameters in %.1f s (%d chains x %d draws)", table.sizes["parameter"], elapsed, chains, draws)
    return tree


def _adjusted(result: Chain, marg: Marginal, model: RotorModel, modes: xr.Dataset, names: Sequence[str],
              fsi: bool, eps_std: float, prior: Prior) -> tuple[Chain, np.ndarray | None]:  # fmt: skip
    """The draws stretched by what the modes' correlation adds to the spread (:mod:`twin.update.adjust`)."""
    ratio = correlation_factors(marg, model, modes, names, fsi=fsi, eps_std=eps_std, prior_mean=prior.parameter_mean,
                                prior_precision=prior.parameter_precision)  # fmt: skip
    if ratio is None:
        return result, None
    factors = np.maximum(1.0, ratio)
    flat = np.concatenate([result.t, result.eta.reshape(*result.eta.shape[:2], -1)], axis=-1)
    flat = stretch(flat, factors)
    problem = marg.problem
    Kg = problem.n_global
    log.info("posterior spread stretched for the modes' correlation: %s",
             ", ".join(f"{n} x{f:.2f}" for n, f in zip(problem.parameter_labels, factors) if f > 1.0))  # fmt: skip
    return dataclasses.replace(result, t=flat[..., :Kg], eta=flat[..., Kg:].reshape(result.eta.shape)), factors


def _sampler_text(pole_model: str, collapsed: bool) -> str:
    if pole_model == "marginal":
        return ("HMC on the marginal of (t, eta), with (psi, eps) and the pole deviations integrated out "
                "(errors-in-variables PerCEM, Student t tail per mode), each trajectory followed by a slice step "
                "of every eta_i | t; then psi | t, eta (closed form)")  # fmt: skip
    return "Gibbs: t | rest, eta_i | rest, " + ("Metropolis (t, eta) | Delta with (psi, eps) integrated out, "
            if collapsed else "") + "(psi_i, eps_i) | rest, Delta_i | rest (closed form)"  # fmt: skip


def undetermined_parameters(table: xr.Dataset, problem: Problem) -> dict[str, float]:
    """The parameters whose posterior std exceeds :data:`POORLY_DETERMINED` of their size, with std / size.

    The size is the nominal value, or the posterior mean where the nominal is zero (an effect's
    parameter, per-mode FSI). Such a parameter is reported as not determined by the data: its
    interval is what the data allow, and its R-hat and ESS are not held against the sampler.
    """
    names = [str(p) for p in table["parameter"].values]
    nominal = dict(zip(problem.global_names, problem.global_nominal))
    ref = np.array([abs(nominal.get(n, 0.0)) or abs(m) for n, m in zip(names, table["mean"].values)])
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = table["std"].values / ref
    return {n: float(r) for n, r in zip(names, rel) if not r <= POORLY_DETERMINED}


def _warn_diagnostics(table: xr.Dataset, undetermined: Mapping[str, float]) -> None:
    names = [str(p) for p in table["parameter"].values]
    if "r_hat" in table:
        high = [f"{n} ({r:.3f})" for n, r in zip(names, table["r_hat"].values)
                if r > RHAT_LIMIT and n not in undetermined]  # fmt: skip
        if high:
            warnings.warn(f"R-hat above {RHAT_LIMIT} (chains disagree; run longer): {', '.join(high)}",
                          TwinWarning, stacklevel=3)  # fmt: skip
    if undetermined:
        parts = []
        for n, rel in undetermined.items():
            r_hat = f", R-hat {float(table['r_hat'].sel(parameter=n)):.3f}" if "r_hat" in table else ""
            parts.append(f"{n} (std {rel:.0%}{r_hat})")
        warnings.warn(f"the data hardly determine: {', '.join(parts)}", TwinWarning, stacklevel=3)
