"""The reference paper's Gibbs sampler (its Table 1), as published.

**What it is.** The Gibbs sampler of :mod:`twin.update.samplers.gibbs` in
the paper's configuration: diagonal ``Δ_i`` (independent residual rows),
no collapsed step, and the condensed model's bases rebuilt at every pole
sample (``pole_model="samples"``). Its only options are the shared ones.

**When to use it.** To reproduce the paper's results (its Cases A and B,
``benchmarks/update_cases.py``) or to compare a new sampler against the
published one. On extracted modes it is the slowest to mix and its
intervals are too narrow where the pole noise correlates the residual's
rows; use the HMC sampler (the default) for anything else.

Examples
--------
>>> from twin.update import PaperOptions, synthesize_modes, update
>>> m = hydro_unit
>>> data = synthesize_modes(m, samples=20, seed=0).isel(mode=[2, 3])
>>> post = update(m, data, fsi=True, method="paper", options=PaperOptions(draws=20, chains=1, seed=1, progress=False))
>>> post.attrs["sampler"].startswith("Gibbs (diagonal Delta, samples pole model)")
True
"""

from __future__ import annotations

from dataclasses import dataclass

from twin.defaults import GIBBS_BURN_IN
from twin.update.chain import NOISE_PRIOR_SHAPE
from twin.update.samplers.gibbs import Gibbs, GibbsOptions
from twin.update.samplers.base import SamplerOptions


@dataclass(frozen=True)
class PaperOptions(SamplerOptions):
    """Options of the paper's sampler: the shared ones (:class:`~twin.update.samplers.base.SamplerOptions`).

    ``warmup`` is the number of burn-in sweeps (20 by default).
    """

    warmup: int = GIBBS_BURN_IN

    def gibbs(self) -> GibbsOptions:
        """The same run as options of the Gibbs sampler in the paper's configuration."""
        return GibbsOptions(
            draws=self.draws,
            chains=self.chains,
            warmup=self.warmup,
            seed=self.seed,
            eps_std=self.eps_std,
            progress=self.progress,
            noise_model="diagonal",
            collapsed=False,
            pole_model="samples",
            noise_prior_shape=NOISE_PRIOR_SHAPE,
        )


class PaperGibbs(Gibbs):
    """The paper's Gibbs sampler (see the module docstring)."""

    name = "paper"
    options_type = PaperOptions  # type: ignore[assignment]

    def gibbs_options(self, options: PaperOptions) -> GibbsOptions:  # type: ignore[override]
        return options.gibbs()

    def describe(self, options: PaperOptions) -> str:  # type: ignore[override]
        return super().describe(options) + "; the reference paper's Table 1"
