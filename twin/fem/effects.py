"""Physical effects: named parameters with footprints on a model region.

An effect is a small object that, given a model, returns the parameters it
adds. It acts on a named region of the model file (``[regions]``), so the
same effect fits any machine that declares that region:

========================  ==========  ==================================================
key                       region      parameters
========================  ==========  ==================================================
``fsi``                   immersed    ``FSI.added_mass`` [kg], ``FSI.added_damping`` [N s/m]
``fsi_per_mode``          immersed    ``FSI.added_mass_<i>``, ``FSI.added_damping_<i>`` per mode i
``magnetic_pull``         generator   ``MAG.stiffness`` [N/m] (negative: unbalanced magnetic pull)
``seal_cross_coupling``   seal        ``SEAL.kxy`` [N/m] (cross-coupled, forward destabilising)
``bearing_change``        (bearing)   ``<B>.stiffness_change`` [N/m], ``<B>.damping_change`` [N s/m]
``thrust_tilt``           (thrust)    ``<T>.k_tilt_change`` [N m/rad]
========================  ==========  ==================================================

Added mass and damping are shared equally over the region's translational
DOFs (``m/n`` and ``c/n`` on each of the ``n`` immersed DOFs). The last two act on a named element of the model
(``bearing = "LGB"``, ``thrust = "thrust"``) instead of a region; their
parameters are *changes* added to the element's own coefficients.

Every effect also states :meth:`plausible_scale`: for each parameter, a
generous magnitude a real machine could show. The diagnosis uses it as the
prior scale of the parameter (the Occam factor of its evidence). And every
parameter carries its physical bounds (:attr:`twin.fem.parameters.Parameter.bounds`):
added mass and damping are not negative, a magnetic pull is not positive, a
bearing or tilt-stiffness change leaves the total coefficient non-negative.
Fits and priors stay inside them; :func:`describe` states them.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from twin.errors import ModelError
from twin.fem.elements import POSITIVE, UNBOUNDED, node_dofs
from twin.fem.parameters import Parameter, Term

#: Names of per-mode parameters (``FSI.added_mass_3``), as :class:`FluidAddedMassPerMode` names them.
PER_MODE_NAME = re.compile(r"^FSI\.added_(mass|damping)_\d+$")

#: Ratio of a plausible water added damping to added mass [1/s] (the paper's
#: Table 2 spans 13 to 2700 1/s over its 15 modes).
FSI_DAMPING_PER_MASS = 1000.0
#: Plausible magnetic or seal stiffness, as a fraction of the guide bearings' direct stiffness.
FLUID_MAGNETIC_FRACTION = 0.3
#: Plausible change of a bearing or thrust coefficient (or of any parameter no effect owns), as a fraction of its value.
CHANGE_FRACTION = 0.5


def _shared(kind: str, dofs: tuple[int, ...]) -> tuple[Term, ...]:
    """One unit shared equally over ``dofs`` on the diagonal of ``kind``."""
    return (Term(kind, dofs, np.eye(len(dofs)) / len(dofs)),)


def _region_mass(model, region: str) -> float:
    """Mass of the disks on a region's nodes [kg] (a tenth of the rotor's if none)."""
    nodes = set(model.regions[region])
    disks = [d for d in model.disks if d.node in nodes]
    if not disks:
        return 0.1 * model.total_mass
    return sum(model.parameter(f"{d.name}.m").nominal for d in disks)


def _direct_stiffness(model) -> float:
    """Geometric mean of the guide bearings' direct stiffnesses |kxx|, |kyy| [N/m]."""
    values = [abs(model.parameter(f"{b.name}.{k}").nominal) for b in model.bearings for k in ("kxx", "kyy")]
    values = [v for v in values if v > 0]
    if not values:
        raise ModelError(f"model '{model.name}' has no bearing stiffness to scale a stiffness effect by")
    return float(np.exp(np.mean(np.log(values))))


def _element(model, kind: str, name: str):
    items = {"bearing": model.bearings, "thrust": model.thrusts}[kind]
    for item in items:
        if item.name == name:
            return item
    known = ", ".join(repr(i.name) for i in items) or "none"
    raise ModelError(f"model '{model.name}' has no {kind} '{name}' (its {kind}s: {known})")


def _element_value(model, element: str, key: str, default: float) -> float:
    """An element coefficient at the model's values (read without assembling the model's parameters)."""
    return float(model.values.get(f"{element}.{key}", default))


def _cross_coupled(model, region: str) -> tuple[Term, ...]:
    """Skew-symmetric ``[[0, 1], [-1, 0]] / n`` on (x, y) of each region node."""
    nodes = model.regions[region]
    block = np.array([[0.0, 1.0], [-1.0, 0.0]]) / len(nodes)
    return tuple(Term("K", node_dofs(n)[:2], block) for n in nodes)


@dataclass(frozen=True)
class FluidAddedMass:
    """Mode-independent added mass and damping of the water around the runner."""

    key: ClassVar[str] = "fsi"
    region: ClassVar[str | None] = "immersed"
    element: ClassVar[str | None] = None
    per_mode: ClassVar[bool] = False
    explanation: ClassVar[str] = (
        "the water around the runner moves with it, adding mass and damping to every mode alike"
    )
    added_mass: float = 0.0  # kg
    added_damping: float = 0.0  # N s/m

    def parameters(self, model) -> list[Parameter]:
        """``FSI.added_mass`` and ``FSI.added_damping`` on the immersed DOFs."""
        dofs = model.region_dofs(self.region)
        return [
            Parameter("FSI.added_mass", self.added_mass, "kg", _shared("M", dofs),
                      "added mass of the water, shared over the immersed DOFs", bounds=POSITIVE),
            Parameter("FSI.added_damping", self.added_damping, "N s/m", _shared("C", dofs),
                      "added damping of the water, shared over the immersed DOFs", bounds=POSITIVE),
        ]  # fmt: skip

    def plausible_scale(self, model) -> dict[str, float]:
        """Twice the immersed disks' mass [kg]; that times 1000 1/s for the damping [N s/m]."""
        m = 2.0 * _region_mass(model, self.region)
        return {"FSI.added_mass": m, "FSI.added_damping": m * FSI_DAMPING_PER_MASS}


@dataclass(frozen=True)
class FluidAddedMassPerMode:
    """Per-mode added mass ``m_i`` and damping ``c_i`` of the water around the runner.

    Each mode sees its own added mass and damping (the flow pattern differs
    from mode to mode), so the model is no longer a single FEM: mode ``i`` is
    the mode of the FEM altered by ``(m_i, c_i)``.
    """

    key: ClassVar[str] = "fsi_per_mode"
    region: ClassVar[str | None] = "immersed"
    element: ClassVar[str | None] = None
    per_mode: ClassVar[bool] = True
    explanation: ClassVar[str] = (
        "the water around the runner adds a different mass and damping to each mode"
    )
    added_mass: tuple[float, ...] = ()  # kg, one per mode
    added_damping: tuple[float, ...] = ()  # N s/m, one per mode

    def __post_init__(self) -> None:
        object.__setattr__(self, "added_mass", tuple(float(v) for v in self.added_mass))
        object.__setattr__(self, "added_damping", tuple(float(v) for v in self.added_damping))
        if len(self.added_mass) != len(self.added_damping):
            raise ValueError(
                f"fsi_per_mode needs as many added masses ({len(self.added_mass)}) "
                f"as added dampings ({len(self.added_damping)})"
            )

    @property
    def n_modes(self) -> int:
        """Number of modes the effect gives values for."""
        return len(self.added_mass)

    def parameters(self, model) -> list[Parameter]:
        """``FSI.added_mass_<i>``, ``FSI.added_damping_<i>`` for modes i = 1..n (per-mode)."""
        dofs = model.region_dofs(self.region)
        out = []
        for i, (m, c) in enumerate(zip(self.added_mass, self.added_damping), start=1):
            out.append(Parameter(f"FSI.added_mass_{i}", m, "kg", _shared("M", dofs),
                                 f"added mass of the water in mode {i}", per_mode=True, bounds=POSITIVE))
            out.append(Parameter(f"FSI.added_damping_{i}", c, "N s/m", _shared("C", dofs),
                                 f"added damping of the water in mode {i}", per_mode=True, bounds=POSITIVE))
        return out  # fmt: skip

    def plausible_scale(self, model) -> dict[str, float]:
        """Per mode, the scales of :meth:`FluidAddedMass.plausible_scale`."""
        base = FluidAddedMass().plausible_scale(model)
        out = {}
        for i in range(1, self.n_modes + 1):
            out[f"FSI.added_mass_{i}"] = base["FSI.added_mass"]
            out[f"FSI.added_damping_{i}"] = base["FSI.added_damping"]
        return out


@dataclass(frozen=True)
class MagneticPull:
    """Negative radial stiffness of unbalanced magnetic pull at the generator air gap."""

    key: ClassVar[str] = "magnetic_pull"
    region: ClassVar[str | None] = "generator"
    element: ClassVar[str | None] = None
    per_mode: ClassVar[bool] = False
    explanation: ClassVar[str] = (
        "an off-centre generator rotor is pulled further off centre by the magnetic field: a negative stiffness"
    )
    stiffness: float = 0.0  # N/m, negative for a pull

    def parameters(self, model) -> list[Parameter]:
        """``MAG.stiffness`` shared over the generator region's x and y DOFs."""
        dofs = model.region_dofs(self.region)
        # each direction carries the full stiffness: share over nodes, not over x and y
        n_nodes = len(model.regions[self.region])
        terms = (Term("K", dofs, np.eye(len(dofs)) / n_nodes),)
        return [Parameter("MAG.stiffness", self.stiffness, "N/m", terms,
                          "radial magnetic stiffness at the air gap (negative: pull)", bounds=(-np.inf, 0.0))]  # fmt: skip

    def plausible_scale(self, model) -> dict[str, float]:
        """30% of the guide bearings' direct stiffness (geometric mean) [N/m]."""
        return {"MAG.stiffness": FLUID_MAGNETIC_FRACTION * _direct_stiffness(model)}


@dataclass(frozen=True)
class SealCrossCoupling:
    """Cross-coupled stiffness of the runner labyrinth seals (swirling leakage flow)."""

    key: ClassVar[str] = "seal_cross_coupling"
    region: ClassVar[str | None] = "seal"
    element: ClassVar[str | None] = None
    per_mode: ClassVar[bool] = False
    explanation: ClassVar[str] = (
        "swirling leakage flow in the runner seals pushes the runner tangentially: a cross-coupled stiffness"
    )
    kxy: float = 0.0  # N/m; K[x, y] = +kxy, K[y, x] = -kxy

    def parameters(self, model) -> list[Parameter]:
        """``SEAL.kxy`` on the seal region (``K[x,y] = +k``, ``K[y,x] = -k``)."""
        return [Parameter("SEAL.kxy", self.kxy, "N/m", _cross_coupled(model, self.region),
                          "cross-coupled seal stiffness (positive destabilises forward whirl)", bounds=UNBOUNDED)]  # fmt: skip

    def plausible_scale(self, model) -> dict[str, float]:
        """30% of the guide bearings' direct stiffness (geometric mean) [N/m]."""
        return {"SEAL.kxy": FLUID_MAGNETIC_FRACTION * _direct_stiffness(model)}


@dataclass(frozen=True)
class BearingChange:
    """A change of a guide bearing's direct stiffness and damping, alike in x and y.

    Wear, a changed clearance or oil temperature, or re-shimming change a
    guide bearing's coefficients. The change is added to ``kxx``, ``kyy``
    (``stiffness_change``) and ``cxx``, ``cyy`` (``damping_change``) of the
    named bearing: the parameters ``<bearing>.stiffness_change`` and
    ``<bearing>.damping_change``.
    """

    key: ClassVar[str] = "bearing_change"
    region: ClassVar[str | None] = None
    element: ClassVar[str | None] = "bearing"
    per_mode: ClassVar[bool] = False
    explanation: ClassVar[str] = (
        "the guide bearing is softer or stiffer than modelled (wear, clearance, oil temperature)"
    )
    bearing: str = ""
    stiffness_change: float = 0.0  # N/m, added to kxx and kyy
    damping_change: float = 0.0  # N s/m, added to cxx and cyy

    def parameters(self, model) -> list[Parameter]:
        """``<bearing>.stiffness_change`` and ``<bearing>.damping_change`` on the bearing's x, y."""
        b = _element(model, "bearing", self.bearing)
        dofs = node_dofs(b.node)[:2]
        k = min(_element_value(model, b.name, key, b.coefficients[key]) for key in ("kxx", "kyy"))
        c = min(_element_value(model, b.name, key, b.coefficients[key]) for key in ("cxx", "cyy"))
        return [
            Parameter(f"{b.name}.stiffness_change", self.stiffness_change, "N/m", (Term("K", dofs, np.eye(2)),),
                      f"change of {b.name}'s direct stiffness kxx and kyy", bounds=(-max(k, 0.0), np.inf)),
            Parameter(f"{b.name}.damping_change", self.damping_change, "N s/m", (Term("C", dofs, np.eye(2)),),
                      f"change of {b.name}'s direct damping cxx and cyy", bounds=(-max(c, 0.0), np.inf)),
        ]  # fmt: skip

    def plausible_scale(self, model) -> dict[str, float]:
        """Half the bearing's mean direct stiffness and damping."""
        b = _element(model, "bearing", self.bearing)
        k = np.mean([abs(model.parameter(f"{b.name}.{c}").nominal) for c in ("kxx", "kyy")])
        c = np.mean([abs(model.parameter(f"{b.name}.{c}").nominal) for c in ("cxx", "cyy")])
        return {f"{b.name}.stiffness_change": CHANGE_FRACTION * float(k),
                f"{b.name}.damping_change": CHANGE_FRACTION * float(c)}  # fmt: skip


@dataclass(frozen=True)
class ThrustTilt:
    """A change of the thrust bearing's tilt stiffness."""

    key: ClassVar[str] = "thrust_tilt"
    region: ClassVar[str | None] = None
    element: ClassVar[str | None] = "thrust"
    per_mode: ClassVar[bool] = False
    explanation: ClassVar[str] = (
        "the thrust pads resist tilting of the collar more or less than modelled (load, pad wear)"
    )
    thrust: str = ""
    k_tilt_change: float = 0.0  # N m/rad, added to the thrust's tilt stiffness

    def parameters(self, model) -> list[Parameter]:
        """``<thrust>.k_tilt_change`` on the thrust node's alpha, beta."""
        t = _element(model, "thrust", self.thrust)
        k = _element_value(model, t.name, "k_tilt", t.k_tilt)
        return [Parameter(f"{t.name}.k_tilt_change", self.k_tilt_change, "N m/rad",
                          (Term("K", node_dofs(t.node)[2:], np.eye(2)),),
                          f"change of {t.name}'s tilt stiffness", bounds=(-max(k, 0.0), np.inf))]  # fmt: skip

    def plausible_scale(self, model) -> dict[str, float]:
        """Half the thrust's tilt stiffness."""
        t = _element(model, "thrust", self.thrust)
        return {f"{t.name}.k_tilt_change": CHANGE_FRACTION * abs(model.parameter(f"{t.name}.k_tilt").nominal)}


#: Effects by the key used in model and truth files.
EFFECTS: dict[str, type] = {
    cls.key: cls
    for cls in (FluidAddedMass, FluidAddedMassPerMode, MagneticPull, SealCrossCoupling, BearingChange, ThrustTilt)
}


def library_effects(model) -> list:
    """Every library effect that ``model``'s regions and elements admit, zero-valued (present ones included).

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> [effect_label(e) for e in library_effects(load_model(shipped_model("hydro_unit")))][:3]
    ['fsi', 'fsi_per_mode', 'magnetic_pull']
    """
    effects: list = [cls() for cls in (FluidAddedMass, FluidAddedMassPerMode, MagneticPull, SealCrossCoupling)
                     if cls.region in model.regions]  # fmt: skip
    effects += [BearingChange(b.name) for b in model.bearings]
    effects += [ThrustTilt(t.name) for t in model.thrusts]
    return effects


def effect_providing(model, name: str) -> str | None:
    """The label of the library effect that brings parameter ``name`` (``None`` if none does).

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> model = load_model(shipped_model("hydro_unit"))
    >>> effect_providing(model, "MAG.stiffness"), effect_providing(model, "FSI.added_mass_3")
    ('magnetic_pull', 'fsi_per_mode')
    """
    if re.fullmatch(r"FSI\.added_(mass|damping)_\d+", name):
        return "fsi_per_mode"
    for effect in library_effects(model):
        if not effect.per_mode and name in {p.name for p in effect.parameters(model)}:
            return effect_label(effect)
    return None


def with_shared_fsi(model):
    """The model with a mode-independent FSI effect (zero-valued if it had none).

    Per-mode FSI values act through the shared effect's footprint: mode ``i``
    is a mode of this model with ``FSI.added_mass`` and ``FSI.added_damping``
    raised by ``(m_i, c_i)``.
    """
    if any(isinstance(e, FluidAddedMass) for e in model.effects):
        return model
    return dataclasses.replace(model, effects=(*model.effects, FluidAddedMass()))


def per_mode_values(model, base, label: int, values: Mapping[str, float]) -> dict[str, float]:
    """Values of ``base`` (with shared FSI) that give mode ``label`` of a per-mode FSI model.

    A label beyond the values of the model's per-mode effect adds nothing.
    """
    shared_m = values.get("FSI.added_mass", base.parameter("FSI.added_mass").nominal)
    shared_c = values.get("FSI.added_damping", base.parameter("FSI.added_damping").nominal)
    names = set(model.parameter_names)

    def own(name: str) -> float:
        return values.get(name, model.parameter(name).nominal if name in names else 0.0)

    return {"FSI.added_mass": shared_m + own(f"FSI.added_mass_{label}"),
            "FSI.added_damping": shared_c + own(f"FSI.added_damping_{label}")}  # fmt: skip


def free_names(model, effect, labels: Sequence[int]) -> list[str]:
    """The parameters of ``effect`` that measured modes ``labels`` can determine (a per-mode effect's for those modes).

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> free_names(load_model(shipped_model("hydro_unit")), FluidAddedMassPerMode((0.0,) * 3, (0.0,) * 3), [1, 3])
    ['FSI.added_mass_1', 'FSI.added_damping_1', 'FSI.added_mass_3', 'FSI.added_damping_3']
    """
    names = [p.name for p in effect.parameters(model)]
    if effect.per_mode:
        wanted = {int(m) for m in labels}
        names = [n for n in names if int(n.rsplit("_", 1)[1]) in wanted]
    return names


def effect_label(effect) -> str:
    """A name unique among a model's effects: the key, with the element for element effects.

    Examples
    --------
    >>> effect_label(MagneticPull()), effect_label(BearingChange("LGB"))
    ('magnetic_pull', 'bearing_change:LGB')
    """
    if effect.element is None:
        return effect.key
    return f"{effect.key}:{getattr(effect, effect.element)}"


def plausible_scales(model) -> dict[str, float]:
    """``{parameter: plausible scale [SI]}`` of every parameter of the model's switched-on effects.

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> m = load_model(shipped_model("hydro_unit")).with_effects(MagneticPull())
    >>> {k: round(v / 1e6, 1) for k, v in plausible_scales(m).items()}
    {'MAG.stiffness': 89.1}
    """
    out: dict[str, float] = {}
    for effect in model.effects:
        scales = effect.plausible_scale(model)
        out.update({p.name: scales[p.name] for p in effect.parameters(model)})
    return out


def describe(effect, model) -> str:
    """One paragraph on an effect: its physics, and each parameter with unit, physical bounds and prior scale.

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> print(describe(MagneticPull(), load_model(shipped_model("hydro_unit"))))  # doctest: +NORMALIZE_WHITESPACE
    magnetic_pull: an off-centre generator rotor is pulled further off centre by the magnetic field: a negative
    stiffness. MAG.stiffness [N/m]: <= 0, plausible scale 8.91e+07.
    """
    scales = effect.plausible_scale(model)
    parts = []
    for p in effect.parameters(model):
        bounds = p.bounds_text() or "either sign"
        parts.append(f"{p.name} [{p.unit}]: {bounds}, plausible scale {scales[p.name]:.3g}")
    if effect.per_mode and parts:
        parts = [f"per mode i = 1..{effect.n_modes}, like the first: " + parts[0] + "; " + parts[1]]
    elif effect.per_mode:
        parts = ["FSI.added_mass_<i> [kg] and FSI.added_damping_<i> [N s/m] per mode i: >= 0"]
    return f"{effect_label(effect)}: {effect.explanation}. " + "; ".join(parts) + "."


def scaled(effect, factor: float):
    """The effect (or local change) with every value multiplied by ``factor``; element names and indices kept.

    Examples
    --------
    >>> scaled(BearingChange("UGB", -2e8, 2e7), 0.5)
    BearingChange(bearing='UGB', stiffness_change=-100000000.0, damping_change=10000000.0)
    """
    changes = {}
    for f in dataclasses.fields(effect):
        value = getattr(effect, f.name)
        if isinstance(value, float):
            changes[f.name] = factor * value
        elif isinstance(value, tuple):
            changes[f.name] = tuple(factor * v for v in value)
    return dataclasses.replace(effect, **changes)


def effect_fields(cls: type) -> dict[str, type]:
    """The settable values of an effect class and their Python types.

    Examples
    --------
    >>> effect_fields(MagneticPull)
    {'stiffness': <class 'float'>}
    """
    hints = {"float": float, "tuple[float, ...]": tuple, "str": str, "int": int}
    return {f.name: hints[str(f.type)] for f in dataclasses.fields(cls)}
