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
"""

from __future__ import annotations

from collections.abc import Sequence

from twin.fem.effects import FluidAddedMass, plausible_scales
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
    >>> from twin import load_model, shipped_model
    >>> from twin.update import plausible_priors
    >>> from twin.fem.effects import MagneticPull
    >>> m = load_model(shipped_model("hydro_unit")).with_effects(MagneticPull())
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
