"""``update``: modes.nc + model -> posterior.nc, by one of the samplers of :mod:`twin.update.samplers` or
the Laplace approximation of the pole fit (:mod:`twin.update.laplace`)."""

from __future__ import annotations

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
from twin.defaults import METHODS as DEFAULT_METHODS
from twin.errors import TwinWarning
from twin.fem.effects import effect_label
from twin.fem.model import RotorModel
from twin.fem.modelfile import load_model
from twin.modes.modesfile import read_modes, split_complex
from twin.netcdf import check_writable
from twin.update.chain import Chain, build_prior, stack
from twin.update.laplace import LaplaceOptions, laplace_posterior
from twin.update.posterior import (
    RHAT_LIMIT,
    diagnostics_json,
    parameter_coords,
    observed_data,
    summary,
    write_posterior,
)
from twin.update.priors import plausible_priors
from twin.update.problem import Problem, UpdateError, build_problem, select_parameters
from twin.update.samplers import SAMPLERS, SamplerOptions, sampler
from twin.update.samplers.base import make_options

log = logging.getLogger(__name__)

#: Condensation margin (pole spreads to the nearest resonance of the unobserved DOFs) below which a mode is flagged.
MIN_MARGIN = 5.0
#: Posterior std, relative to the nominal value (or to the posterior mean when the nominal is zero), above
#: which a parameter is reported as poorly determined.
POORLY_DETERMINED = 0.5
#: The default sampler (:mod:`twin.update.samplers.hmc`).
DEFAULT_METHOD = next(iter(SAMPLERS))
#: The Laplace approximation of the pole fit (:mod:`twin.update.laplace`), the method beside the samplers.
LAPLACE = "laplace"
#: Every method of :func:`update`: the samplers, then the Laplace approximation (:data:`twin.defaults.METHODS`).
METHODS = (*SAMPLERS, LAPLACE)
if METHODS != DEFAULT_METHODS:  # pragma: no cover (a sampler added here must be named there, for the CLI)
    raise ImportError(f"twin.defaults.METHODS {DEFAULT_METHODS} is not the update's methods {METHODS}")


def update(
    model: RotorModel | str | Path,
    modes: xr.Dataset | str | Path,
    params: str | Sequence[str] | None = None,
    *,
    fsi: bool = False,
    method: str = DEFAULT_METHOD,
    options: SamplerOptions | LaplaceOptions | Mapping[str, Any] | None = None,
    priors: str | Mapping[str, tuple[float, float]] = "plausible",
    output: str | Path | None = None,
    tasks: Any = None,
) -> xr.DataTree:
    """Bayesian updating of a model from modal samples with the APerCEM (perturbed condensed eigen-model).

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
    method : {"hmc", "gibbs", "paper", "laplace"}
        The sampler (:mod:`twin.update.samplers`): HMC on the marginal posterior (the default,
        :mod:`~twin.update.samplers.hmc`), the Gibbs sampler of the full model
        (:mod:`~twin.update.samplers.gibbs`), or the reference paper's Gibbs sampler
        (:mod:`~twin.update.samplers.paper`); or ``"laplace"``, the Gaussian approximation of the fit of
        the model's poles to the mean measured poles (:mod:`twin.update.laplace`): seconds instead of
        minutes, shapes unused, its own truncated priors (:func:`twin.update.priors.prior_for`).
    options : SamplerOptions, LaplaceOptions or mapping, optional
        The method's options (:class:`HMCOptions`, :class:`GibbsOptions`, :class:`PaperOptions`,
        :class:`~twin.update.laplace.LaplaceOptions`), or a mapping of their fields; the defaults where
        not given.
    priors : {"plausible", "flat"} or mapping
        ``"plausible"``: each updated parameter of the model's effects (and the per-mode FSI of ``fsi``)
        gets a Gaussian prior centred on the model's value, as wide as the effect's plausible scale
        (:func:`twin.update.priors.plausible_priors`): no change where the data determine the parameter,
        a bound on what they do not; the others are flat. ``"flat"``: flat on every parameter. A mapping
        ``{name: (mean, std)}`` in SI units: these Gaussian priors, over the plausible ones of the same names.
    output : path, optional
        ``posterior.nc`` to write (atomically); checked before any work.
    tasks : distributed.Client or mapper, optional
        Where the chains run, one task each (:func:`twin.tasks.mapper`): in this process by default.
        The draws do not depend on it.

    Returns
    -------
    xarray.DataTree
        Groups ``posterior``, ``sample_stats``, ``observed_data``, ``constant_data`` (ArviZ's layout,
        SI units); attrs with the method, its settings, R-hat and ESS per parameter.

    Examples
    --------
    >>> from twin.update import synthesize_modes, update
    >>> m = hydro_unit
    >>> data = synthesize_modes(m, samples=20, seed=0, shape_cov=1e-4, pole_variance=(1e-6, 1e-6))
    >>> post = update(m, data.isel(mode=[2, 3, 9]), fsi=True, options={"draws": 50, "chains": 1, "seed": 1,
    ...                                                                 "progress": False})
    >>> mass = post["posterior"]["added_mass"].mean(("chain", "draw")).values
    >>> np.round(mass / [7.80e4, 6.09e4, 4.87e4], 2)   # paper Table 2, modes 3, 4, 10
    array([1., 1., 1.])
    """
    started = time.perf_counter()
    if method not in METHODS:
        raise UpdateError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    chosen = None if method == LAPLACE else sampler(method)
    opts = make_options(LAPLACE, LaplaceOptions, options, {}, "method") if chosen is None else chosen.options(options)
    if isinstance(priors, str) and priors not in ("plausible", "flat"):
        raise UpdateError(f"priors must be 'plausible', 'flat' or a mapping {{name: (mean, std)}}, got {priors!r}")
    if chosen is None and not (isinstance(priors, str) and priors == "plausible"):
        raise UpdateError(
            "the Laplace update has its own priors (twin.update.priors.prior_for): leave priors 'plausible'"
        )
    if output is not None:
        check_writable(output)
    source_model = str(model) if not isinstance(model, RotorModel) else model.source
    model = load_model(model) if not isinstance(model, RotorModel) else model
    source = str(modes) if not isinstance(modes, xr.Dataset) else modes.encoding.get("source", "modes")
    modes = read_modes(modes) if not isinstance(modes, xr.Dataset) else modes
    names = select_parameters(model, params)
    if chosen is None:
        return _laplace(
            model, modes, names, fsi, opts, output, started, {"model_source": source_model, "modes_source": source}
        )
    pole_model = chosen.pole_model(opts)
    problem = build_problem(model, modes, names, fsi=fsi, eps_std=opts.eps_std, pole_model=pole_model, source=source)
    given = {} if isinstance(priors, str) else dict(priors)
    priors = {**(plausible_priors(model, names, fsi) if priors != "flat" else {}), **given}
    prior = build_prior(problem, priors, chosen.noise_model(opts), chosen.noise_prior_shape(opts))
    frequency = np.abs(modes["pole"].mean("sample").values.imag) / (2 * np.pi)
    _warn_margins(problem, frequency, modes.sizes["sample"], pole_model == "marginal")
    target = chosen.prepare(problem, modes, opts)
    bad = chosen.undetermined(target)
    if bad:
        raise UpdateError(f"the data cannot determine these parameters (singular conditional): {', '.join(bad)}")
    result = stack(chosen.run(target, prior, opts, tasks))
    elapsed = time.perf_counter() - started
    settings = {
        "method": chosen.name,
        "params": names,
        "fsi": fsi,
        **opts.settings(),
        "priors": {k: list(v) for k, v in priors.items()} or "flat",
    }
    attrs = {
        "title": f"APerCEM posterior of {model.name}",
        "producer": f"twin {__version__}",
        "model": model.name,
        "model_source": source_model,
        "modes_source": source,
        "method": chosen.name,
        "settings": json.dumps(settings),
        "condensation": problem.method,
        "effects": json.dumps([effect_label(e) for e in model.effects]),
        "sampler": chosen.describe(opts),
        "elapsed_s": elapsed,
        **chosen.attrs(target),
    }
    if "truth" in modes.attrs:
        attrs["truth"] = modes.attrs["truth"]
    units = [model.parameter(n).unit for n in problem.global_names]
    tree = posterior_tree(problem, result, modes, attrs, units)
    table = summary(tree["posterior"].to_dataset())
    tree.attrs["diagnostics"] = diagnostics_json(table)
    undetermined = undetermined_parameters(table, problem)
    tree.attrs["undetermined"] = json.dumps(sorted(undetermined))
    _warn_diagnostics(table, undetermined)
    if output is not None:
        write_posterior(tree, output)
    log.info(
        "updated %d parameters in %.1f s (%s, %d chains x %d draws)",
        table.sizes["parameter"],
        elapsed,
        chosen.name,
        opts.chains,
        opts.draws,
    )
    return tree


def _laplace(
    model: RotorModel,
    modes: xr.Dataset,
    names: list[str],
    fsi: bool,
    opts: LaplaceOptions,
    output: str | Path | None,
    started: float,
    sources: dict,
) -> xr.DataTree:
    """:func:`update` by the Laplace approximation (:func:`twin.update.laplace.laplace_posterior`)."""
    if not names and not fsi:
        raise UpdateError("nothing to update: name parameters (params) or update the per-mode FSI (fsi=True)")
    _, fitted, tree = laplace_posterior(
        model, modes, names, fsi=fsi, seed=opts.seed, draws=opts.draws, tolerance=opts.tolerance
    )
    settings = {"method": LAPLACE, "params": names, "fsi": fsi, **opts.settings(), "priors": "plausible"}
    tree.attrs.update(
        {
            "producer": f"twin {__version__}",
            **sources,
            "settings": json.dumps(settings),
            "elapsed_s": time.perf_counter() - started,
        }
    )
    if "truth" in modes.attrs:
        tree.attrs["truth"] = modes.attrs["truth"]
    if output is not None:
        write_posterior(tree, output)
    log.info(
        "Laplace update of %d parameters in %.1f s: chi2 %.1f -> %.1f",
        fitted.sizes["parameter"],
        time.perf_counter() - started,
        fitted.attrs["chi2_before"],
        fitted.attrs["chi2_after"],
    )
    return tree


def _warn_margins(problem: Problem, frequency_hz: np.ndarray, n_samples: int, marginal: bool) -> None:
    """Warn of modes within :data:`MIN_MARGIN` spreads of a resonance of the unobserved DOFs.

    The spread is the pole samples' std for the Gibbs pole models, which evaluate the condensed model at
    (or linearise it over) the samples, and the mean pole's standard error for the marginal model.
    """
    margin, unit = (
        (problem.margin * np.sqrt(n_samples), "mean-pole standard errors")
        if marginal
        else (problem.margin, "pole-sample stds")
    )
    for i in np.flatnonzero(margin < MIN_MARGIN):
        warnings.warn(
            f"mode {problem.modes[i]} ({frequency_hz[i]:.2f} Hz) lies {margin[i]:.1f} {unit} from "
            f"a resonance of the unobserved DOFs ({problem.resonance_hz[i]:.2f} Hz): the condensed model is "
            "ill-conditioned there and this mode's parameters are unreliable",
            TwinWarning,
            stacklevel=3,
        )


def posterior_tree(
    problem: Problem, chains: Chain, modes: xr.Dataset, attrs: dict, units: Sequence[str] | None = None
) -> xr.DataTree:
    """The ArviZ-layout DataTree of a run (SI units; ``theta``'s ``units`` coordinate gives each parameter's)."""
    n_chain, n_draw = chains.lp.shape
    coords = {"chain": np.arange(n_chain), "draw": np.arange(n_draw)}
    post = xr.Dataset(coords=coords)
    if problem.n_global:
        post["theta"] = xr.DataArray(
            chains.t * problem.global_scale,
            dims=("chain", "draw", "parameter"),
            coords=parameter_coords(problem.global_names, units),
            attrs={"long_name": "updated model parameters (SI units of each parameter: coordinate units)"},
        )
    mode_coord = {"mode": problem.modes}
    mode_units = {"added_mass": "kg", "added_damping": "N s/m"}
    for q, kind in enumerate(problem.mode_names):
        post[kind] = xr.DataArray(
            chains.eta[..., q] * problem.mode_scale[:, q],
            dims=("chain", "draw", "mode"),
            coords=mode_coord,
            attrs={
                "units": mode_units[kind],
                "long_name": f"per-mode FSI {kind.replace('_', ' ')} on the immersed DOFs",
            },
        )
    n_o = len(problem.channels)
    shape = chains.psi[..., :n_o] + 1j * chains.psi[..., n_o:]
    post["shape"] = xr.DataArray(
        shape,
        dims=("chain", "draw", "mode", "channel"),
        coords={**mode_coord, "channel": problem.channels},
        attrs={"long_name": "observed mode shape (latent ψ)"},
    )
    post = split_complex(post)
    stats = xr.Dataset(
        {
            "lp": (("chain", "draw"), chains.lp, {"long_name": "log joint density, up to a constant"}),
            "noise_variance": (
                ("chain", "draw", "mode"),
                chains.noise,
                {
                    "long_name": "mean variance of a row of the condensed residual: Δ_i (Gibbs) or "
                    "V_i (marginal model) (relative units)"
                },
            ),
            "accepted": (
                ("chain", "draw"),
                chains.accepted,
                {
                    "long_name": "whether the collapsed Metropolis step (Gibbs) or the HMC trajectory "
                    "moved the parameters (all false when the sampler is plain Gibbs)"
                },
            ),
        },
        coords={**coords, **mode_coord},
    )
    if np.any(chains.n_steps):  # HMC (the marginal model): ArviZ's names for its step statistics
        stats["acceptance_rate"] = (
            ("chain", "draw"),
            chains.acceptance_rate,
            {"long_name": "Metropolis acceptance probability of the HMC trajectory"},
        )
        stats["step_size"] = (
            ("chain", "draw"),
            chains.step_size,
            {"long_name": "leapfrog step, in the parameters whitened by the metric"},
        )
        stats["n_steps"] = (("chain", "draw"), chains.n_steps, {"long_name": "leapfrog steps of the trajectory"})
    observed = observed_data(modes)
    constant = xr.Dataset(
        {
            "nominal": ("parameter", problem.global_nominal, {"long_name": "value before the update (SI)"}),
            "scale": ("parameter", problem.global_scale, {"long_name": "scale of the sampled coordinate (SI)"}),
            "fsi_scale": (("mode", "fsi_parameter"), problem.mode_scale),
            "condensation_margin": (
                "mode",
                problem.margin,
                {"long_name": "pole-sample stds to the nearest resonance of the unobserved DOFs"},
            ),
        },
        coords={"parameter": problem.global_names, "fsi_parameter": problem.mode_names, **mode_coord},
    )
    return xr.DataTree.from_dict(
        {
            "/": xr.Dataset(attrs=attrs),
            "posterior": post,
            "sample_stats": stats,
            "observed_data": observed,
            "constant_data": constant,
        }
    )


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
        high = [
            f"{n} ({r:.3f})" for n, r in zip(names, table["r_hat"].values) if r > RHAT_LIMIT and n not in undetermined
        ]
        if high:
            warnings.warn(
                f"R-hat above {RHAT_LIMIT} (chains disagree; run longer): {', '.join(high)}", TwinWarning, stacklevel=3
            )
    if undetermined:
        parts = []
        for n, rel in undetermined.items():
            r_hat = f", R-hat {float(table['r_hat'].sel(parameter=n)):.3f}" if "r_hat" in table else ""
            parts.append(f"{n} (std {rel:.0%}{r_hat})")
        warnings.warn(f"the data hardly determine: {', '.join(parts)}", TwinWarning, stacklevel=3)
