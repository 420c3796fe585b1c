"""The interface every sampler of the update implements, and the options they share.

A sampler turns an updating problem (:class:`twin.update.problem.Problem`,
built from the model and the modes) into chains of draws
(:class:`twin.update.chain.Chain`) in four steps, which
:func:`twin.update.update` calls in turn:

1. :meth:`Sampler.prepare`: what it samples, built from the problem and the
   modes (the problem itself for the Gibbs samplers, the marginal model for HMC);
2. :meth:`Sampler.undetermined`: the parameters the data cannot determine
   (the update refuses to start with any);
3. :meth:`Sampler.run`: the chains, in this process or as tasks;
4. :meth:`Sampler.attrs`: what the posterior file records of the run besides
   the options.

Each sampler has its own options, a frozen dataclass derived from
:class:`SamplerOptions`, whose fields are the settings a user may change.
"""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import xarray as xr

from twin.defaults import CHAINS, DRAWS, HMC_WARMUP
from twin.update.chain import Chain, Prior
from twin.update.problem import Problem, UpdateError


@dataclass(frozen=True)
class SamplerOptions:
    """Settings every sampler takes.

    Attributes
    ----------
    draws : int
        Draws kept per chain.
    chains : int
        Independent chains (their seeds spawned from ``seed``).
    warmup : int
        Iterations at the start of each chain that are not kept (warm-up or burn-in).
    seed : int, optional
        Seed of the chains; the draws depend on it alone, not on where the chains run.
    eps_std : float
        σ of the perturbation ε of the condensed eigen-equation, relative to
        the dynamic stiffness.
    progress : bool
        Progress bars over the iterations (over the chains when they run as tasks).
    """

    draws: int = DRAWS
    chains: int = CHAINS
    warmup: int = HMC_WARMUP
    seed: int | None = None
    eps_std: float = 1e-6
    progress: bool = True

    #: The smallest ``warmup`` a sampler accepts.
    MIN_WARMUP: ClassVar[int] = 0

    def __post_init__(self) -> None:
        for name, least in (("draws", 1), ("chains", 1), ("warmup", self.MIN_WARMUP)):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < least:
                raise UpdateError(f"{name} must be a whole number >= {least}, got {value!r}")
        if not self.eps_std > 0:
            raise UpdateError(f"eps_std must be positive, got {self.eps_std!r}")

    def settings(self) -> dict[str, Any]:
        """The options as a JSON-ready dict (``progress`` left out: it changes nothing in the draws)."""
        out = dataclasses.asdict(self)
        out.pop("progress")
        return out


class Sampler(ABC):
    """One way of drawing the APerCEM posterior (see the module docstring)."""

    #: The name :func:`twin.update.update` knows it by.
    name: ClassVar[str]
    #: Its options' type.
    options_type: ClassVar[type[SamplerOptions]] = SamplerOptions

    def pole_model(self, options: SamplerOptions) -> str:
        """How the pole samples enter the condensed model it samples (:data:`twin.update.poles.POLE_MODELS`)."""
        return "marginal"

    def noise_prior_shape(self, options: SamplerOptions) -> float:
        """The weight of the prior on the residual noise ``Δ`` (0: the sampler has no ``Δ``)."""
        return 0.0

    def noise_model(self, options: SamplerOptions) -> str:
        """The covariance model of ``Δ`` the prior is built for."""
        return "full"

    @abstractmethod
    def prepare(self, problem: Problem, modes: xr.Dataset, options: SamplerOptions) -> Any:
        """What the chains sample, built once from the problem and the modes."""

    @abstractmethod
    def undetermined(self, target: Any) -> list[str]:
        """The parameters the data cannot determine (empty when all can be)."""

    @abstractmethod
    def run(self, target: Any, prior: Prior, options: SamplerOptions, tasks: Any = None) -> list[Chain]:
        """The chains (one task each where ``tasks`` says, :func:`twin.tasks.mapper`)."""

    @abstractmethod
    def describe(self, options: SamplerOptions) -> str:
        """One line saying what runs, for the posterior's attr ``sampler``."""

    def attrs(self, target: Any) -> dict[str, str]:
        """Attributes of the posterior that record what the run found besides its options."""
        return {}

    def options(self, options: SamplerOptions | Mapping[str, Any] | None = None, **fields: Any) -> SamplerOptions:
        """This sampler's options from an options object, a mapping of fields, or keyword fields.

        Examples
        --------
        >>> from twin.update.samplers import sampler
        >>> sampler("hmc").options(draws=100).draws
        100
        >>> sampler("gibbs").options({"warmup": 5}).warmup
        5
        """
        return make_options(self.name, self.options_type, options, fields)


def make_options(name: str, options_type: type, options: Any, fields: Mapping[str, Any], what: str = "sampler") -> Any:
    """The options of the ``what`` called ``name``: ``options_type`` from an instance of it, a mapping of its fields or none, with ``fields`` over them.

    A field the type does not have is refused by name, with the fields it has.

    Examples
    --------
    >>> make_options("any", SamplerOptions, {"draws": 10}, {}).draws
    10
    >>> make_options("any", SamplerOptions, {"colour": 1}, {})
    Traceback (most recent call last):
    twin.errors.UpdateError: the 'any' sampler has no option colour (its options: chains, draws, eps_std, progress, seed, warmup)
    """
    if options is None:
        options = {}
    if dataclasses.is_dataclass(options) and not isinstance(options, type):
        if not isinstance(options, options_type):
            raise UpdateError(f"the {name!r} {what} takes {options_type.__name__}, got {type(options).__name__}")
        return dataclasses.replace(options, **fields) if fields else options
    given = {**dict(options), **fields}
    known = {f.name for f in dataclasses.fields(options_type)}
    unknown = sorted(set(given) - known)
    if unknown:
        raise UpdateError(
            f"the {name!r} {what} has no option {', '.join(unknown)} (its options: {', '.join(sorted(known))})"
        )
    return options_type(**given)
