"""The update's default priors: an effect's parameters within a magnitude a real machine could show.

Every effect states a plausible scale for each of its parameters
(:meth:`twin.fem.effects.FluidAddedMass.plausible_scale` and the others: a
generous magnitude, e.g. twice the immersed disks' mass for an added mass).
The update puts a Gaussian prior on each of them, centred on the model's
value and as wide as that scale. Where the data determine a parameter the
prior is far wider than the posterior and changes nothing (a hidden pull at
2% posterior std against a scale of 220%: a shift of 0.004 std). Where they do
not, the errors-in-variables density is flat far out (as a per-mode added
mass grows, the mode's residual and its covariance grow together), and
without a prior the posterior of such a parameter runs off to values no
machine has: on 20 FMU records with a per-mode FSI (seeds 1001-1020), 7 of
the 58 per-mode values the data hardly determined had 90% intervals wholly
above the truth, up to 7e6 kg against 5e4 kg, and chains that disagreed
(R-hat up to 1.53). The model's own parameters (bearings, disks, ...) have
no such scale and stay flat.

The Laplace update (:mod:`twin.update.laplace`) puts a prior on every parameter it fits
(:func:`prior_for`, :class:`BoundedPrior`): the effects' as above, the model's own at half their value, each
truncated to the parameter's physical bounds, so its evidence has a proper prior to weigh a hypothesis by.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.stats

from twin.errors import ModelError
from twin.fem.effects import CHANGE_FRACTION, FluidAddedMass, plausible_scales
from twin.fem.model import RotorModel


def plausible_priors(model: RotorModel, names: Sequence[str], fsi: bool = False) -> dict[str, tuple[float, float]]:
    """Gaussian priors ``{name: (mean, std)}`` [SI] for the updated parameters of the model's effects.

    Each parameter of a switched-on effect (library or local change) that is
    among ``names`` gets its model value as mean and its effect's plausible
    scale as std. With ``fsi`` (the per-mode added mass and damping of
    :func:`twin.update.update`), ``FSI.added_mass`` and ``FSI.added_damping``
    get zero mean and the mode-independent FSI's scales, for every mode.

    Examples
    --------
    >>> from twin.update import plausible_priors
    >>> from twin.fem.effects import MagneticPull
    >>> m = hydro_unit.with_effects(MagneticPull())
    >>> {k: (v[0], round(v[1] / 1e6, 1)) for k, v in plausible_priors(m, ["MAG.stiffness", "LGB.kxx"]).items()}
    {'MAG.stiffness': (0.0, 89.1)}
    >>> sorted(plausible_priors(m, [], fsi=True))
    ['FSI.added_damping', 'FSI.added_mass']
    """
    scales = plausible_scales(model)
    out = {n: (float(model.parameter(n).nominal), float(scales[n])) for n in names if scales.get(n, 0.0) > 0}
    if fsi:
        scale = FluidAddedMass().plausible_scale(model)
        for name in ("FSI.added_mass", "FSI.added_damping"):
            out.setdefault(name, (0.0, float(scale[name])))
    return out


@dataclass(frozen=True)
class BoundedPrior:
    """Truncated Gaussian priors ``θ = mean + scale u``, ``u ~ N(0, 1)`` inside ``[low, high]`` (SI).

    Examples
    --------
    >>> p = BoundedPrior(["MAG.stiffness"], np.zeros(1), np.array([1e8]), np.array([-np.inf]), np.zeros(1))
    >>> round(p.log_mass, 4)  # a sign constraint keeps half the prior
    -0.6931
    """

    names: list[str]
    mean: np.ndarray
    scale: np.ndarray
    low: np.ndarray
    high: np.ndarray

    @property
    def u_low(self) -> np.ndarray:
        """Lower bounds in prior units."""
        return (self.low - self.mean) / self.scale

    @property
    def u_high(self) -> np.ndarray:
        """Upper bounds in prior units."""
        return (self.high - self.mean) / self.scale

    @property
    def log_mass(self) -> float:
        """``Σ ln P_k``: the log prior mass inside the bounds."""
        mass = scipy.stats.norm.cdf(self.u_high) - scipy.stats.norm.cdf(self.u_low)
        return float(np.sum(np.log(mass)))

    def values(self, u: np.ndarray) -> dict[str, float]:
        """Parameter values [SI] at prior coordinates ``u``."""
        return {n: float(m + s * x) for n, m, s, x in zip(self.names, self.mean, self.scale, u)}

    def coordinates(self, values: Mapping[str, float]) -> np.ndarray:
        """Prior coordinates ``u`` of values [SI], clipped into the bounds."""
        u = (np.array([values[n] for n in self.names]) - self.mean) / self.scale
        return np.clip(u, self.u_low, self.u_high)


def prior_for(model: RotorModel, names: Sequence[str]) -> BoundedPrior:
    """The Laplace update's truncated priors of parameters ``names`` of ``model``.

    An effect's parameter: mean 0 and the effect's plausible scale (no effect until the data say so); any
    other: mean the model's value and :data:`twin.fem.effects.CHANGE_FRACTION` of it; both truncated to the
    parameter's physical bounds (:mod:`twin.update.laplace`).

    Examples
    --------
    >>> from twin.fem.effects import MagneticPull
    >>> model = hydro_unit.with_effects(MagneticPull())
    >>> p = prior_for(model, ["MAG.stiffness", "UGB.kxx"])
    >>> float(p.mean[0]), bool(p.scale[1] == 0.5 * model.parameter("UGB.kxx").nominal), float(p.high[0]), float(p.low[1])
    (0.0, True, 0.0, 0.0)
    """
    owned = plausible_scales(model)
    mean, scale, low, high = [], [], [], []
    for n in names:
        p = model.parameter(n)  # names an unknown parameter clearly
        if n in owned:
            m, s = 0.0, owned[n]
        else:
            m, s = p.nominal, CHANGE_FRACTION * abs(p.nominal)
        if not s > 0:
            raise ModelError(f"parameter '{n}' has no prior scale (nominal {p.nominal:g}): give it through an effect")
        mean.append(m), scale.append(float(s)), low.append(p.bounds[0]), high.append(p.bounds[1])
    return BoundedPrior(list(names), np.array(mean), np.array(scale), np.array(low), np.array(high))
