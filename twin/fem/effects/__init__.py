"""Physical effects and local changes: named parameters that enter the model's matrices linearly.

An effect is a small frozen dataclass (:class:`Effect`) that, given a model,
returns the parameters it adds. It acts on a named region of the model file
(``[regions]``) or on a named element, so the same effect fits any machine
that declares that region or element. The library:

============================  ==========  ==================================================
key                           acts on     parameters
============================  ==========  ==================================================
``fsi``                       immersed    ``FSI.added_mass`` [kg], ``FSI.added_damping`` [N s/m]
``fsi_per_mode``              immersed    ``FSI.added_mass_<i>``, ``FSI.added_damping_<i>`` per mode i
``magnetic_pull``             generator   ``MAG.stiffness`` [N/m] (negative: unbalanced magnetic pull)
``seal_cross_coupling``       seal        ``SEAL.kxy`` [N/m] (cross-coupled, forward destabilising)
``bearing_change:<B>``        a bearing   ``<B>.stiffness_change`` [N/m], ``<B>.damping_change`` [N s/m]
``bearing_anisotropic:<B>``   a bearing   ``<B>.kxx_change`` ... ``<B>.cyy_change`` (each direct coefficient)
``bearing_scale:<B>``         a bearing   ``<B>.scale_change`` [1] (all eight coefficients by one factor)
``thrust_tilt:<T>``           a thrust    ``<T>.k_tilt_change`` [N m/rad]
============================  ==========  ==================================================

and the local changes outside it, the localisation scan's hypotheses, one
relative parameter each: ``shaft_stiffness:<e>`` (``shaft<e>.stiffness_change``),
``disk_mass:<d>`` (``<d>.m  ass_change``), ``disk_inertia:<d>`` (``<d>.inertia_change``).
:func:`effect_classes` lists every registered one, those of other modules of
this folder and of other packages included.

Every effect states :meth:`Effect.plausible_scale`: for each parameter, a
generous magnitude a real machine could show, which the diagnosis uses as
the prior scale of the parameter (the Occam factor of its evidence). And every
parameter carries its physical bounds (:attr:`twin.fem.parameters.Parameter.bounds`):
added mass and damping are not negative, a magnetic pull is not positive, a
bearing or tilt-stiffness change leaves the total coefficient non-negative.
Fits and priors stay inside them; :func:`describe` states them.

Adding an effect
----------------
Write one module with one :class:`Effect` subclass: its declarations, its
``parameters`` and ``plausible_scale``, and :func:`register` on it. In this
folder the module is found by itself; in a package of your own, name it in the
``twin.effects`` entry-point group (:mod:`twin.fem.effects.registry`). Model
files, truth files, ``twin params``, the diagnosis and the tracker then know it.
"""

from twin.fem.effects.base import (
    CHANGE_FRACTION,
    FLUID_MAGNETIC_FRACTION,
    LOCAL_CHANGE_SCALE,
    RELATIVE_BOUNDS,
    Effect,
    RelativeChange,
    effect_fields,
    element_names,
    free_names,
    plausible_scales,
    scaled,
)
from twin.fem.effects.bearing import BearingAnisotropicChange, BearingChange
from twin.fem.effects.bearing_scale import BearingScale
from twin.fem.effects.disk import DiskInertiaChange, DiskMassChange
from twin.fem.effects.fsi import (
    FSI_DAMPING_PER_MASS,
    FluidAddedMass,
    FluidAddedMassPerMode,
    per_mode_values,
    with_shared_fsi,
)
from twin.fem.effects.magnetic import MagneticPull
from twin.fem.effects.registry import (
    Label,
    describe,
    effect_class,
    effect_classes,
    effect_label,
    effect_providing,
    exclusive,
    from_label,
    holds,
    is_per_mode_name,
    library_effects,
    local_changes,
    parse_label,
    register,
)
from twin.fem.effects.seal import SealCrossCoupling
from twin.fem.effects.shaft import ShaftStiffnessChange
from twin.fem.effects.thrust import ThrustTilt

__all__ = [
    "CHANGE_FRACTION",
    "FLUID_MAGNETIC_FRACTION",
    "FSI_DAMPING_PER_MASS",
    "LOCAL_CHANGE_SCALE",
    "RELATIVE_BOUNDS",
    "BearingAnisotropicChange",
    "BearingChange",
    "BearingScale",
    "DiskInertiaChange",
    "DiskMassChange",
    "Effect",
    "FluidAddedMass",
    "FluidAddedMassPerMode",
    "Label",
    "MagneticPull",
    "RelativeChange",
    "SealCrossCoupling",
    "ShaftStiffnessChange",
    "ThrustTilt",
    "describe",
    "effect_class",
    "effect_classes",
    "effect_fields",
    "effect_label",
    "effect_providing",
    "element_names",
    "exclusive",
    "free_names",
    "from_label",
    "holds",
    "is_per_mode_name",
    "library_effects",
    "local_changes",
    "parse_label",
    "per_mode_values",
    "plausible_scales",
    "register",
    "scaled",
    "with_shared_fsi",
]
