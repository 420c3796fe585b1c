"""The samplers of the update, behind one interface (:class:`~twin.update.samplers.base.Sampler`).

=========  ==========================================  =====================================================
name       sampler                                      use it
=========  ==========================================  =====================================================
``hmc``    :mod:`~twin.update.samplers.hmc`             by default: calibrated on FMU records, fastest per
                                                        effective draw
``gibbs``  :mod:`~twin.update.samplers.gibbs`           to compare; sensor layouts with latent shape entries
``paper``  :mod:`~twin.update.samplers.paper`           to reproduce the reference paper
=========  ==========================================  =====================================================
"""

from twin.update.problem import UpdateError
from twin.update.samplers.base import Sampler, SamplerOptions
from twin.update.samplers.gibbs import Gibbs, GibbsOptions
from twin.update.samplers.hmc import HMC, HMCOptions
from twin.update.samplers.paper import PaperGibbs, PaperOptions

#: The samplers by name; the first is the default.
SAMPLERS: dict[str, Sampler] = {s.name: s for s in (HMC(), Gibbs(), PaperGibbs())}


def sampler(name: str) -> Sampler:
    """The sampler called ``name`` (a key of :data:`SAMPLERS`).

    Examples
    --------
    >>> from twin.update import sampler
    >>> sampler("paper").options().warmup
    20
    >>> sampler("nuts")
    Traceback (most recent call last):
    twin.errors.UpdateError: unknown sampler 'nuts'; choose one of hmc, gibbs, paper
    """
    try:
        return SAMPLERS[name]
    except (KeyError, TypeError):
        raise UpdateError(f"unknown sampler {name!r}; choose one of {', '.join(SAMPLERS)}") from None


__all__ = [
    "SAMPLERS",
    "Gibbs",
    "GibbsOptions",
    "HMC",
    "HMCOptions",
    "PaperGibbs",
    "PaperOptions",
    "Sampler",
    "SamplerOptions",
    "sampler",
]
