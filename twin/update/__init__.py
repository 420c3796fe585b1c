"""Stage 4: APerCEM Bayesian updating: modes.nc + model -> posterior.nc.

* :func:`update`: the posterior of shared parameters and per-mode FSI, drawn by
  one of the samplers of :mod:`twin.update.samplers` (``method``): HMC on the
  marginal posterior (the default), the Gibbs sampler of the full model, or
  the reference paper's Gibbs sampler; each takes its own options
  (:class:`HMCOptions`, :class:`GibbsOptions`, :class:`PaperOptions`); or by
  the Laplace approximation of the pole fit (``method="laplace"``,
  :mod:`twin.update.laplace`, :class:`LaplaceOptions`);
* :func:`synthesize_modes`: paper-style synthetic modal data (its Figure 2);
* :func:`apply_posterior`: the model with the posterior MAP or mean applied;
* :func:`summary`, :func:`read_posterior`: the posterior's table and file;
* :func:`plausible_priors`: the priors the update gives the effects by default.
"""

from twin.update.core import DEFAULT_METHOD, METHODS, update
from twin.update.laplace import LaplaceOptions
from twin.update.posterior import apply_posterior, read_posterior, summary
from twin.update.priors import plausible_priors
from twin.update.problem import UpdateError
from twin.update.samplers import SAMPLERS, GibbsOptions, HMCOptions, PaperOptions, SamplerOptions, sampler
from twin.update.synthetic import synthesize_modes

__all__ = [
    "DEFAULT_METHOD",
    "METHODS",
    "SAMPLERS",
    "GibbsOptions",
    "HMCOptions",
    "LaplaceOptions",
    "PaperOptions",
    "SamplerOptions",
    "UpdateError",
    "apply_posterior",
    "plausible_priors",
    "read_posterior",
    "sampler",
    "summary",
    "synthesize_modes",
    "update",
]
