"""The effect interface: what one physical effect declares, and the footprints effects share.

An effect is a frozen dataclass deriving from :class:`Effect`. Its class
declares, once:

* ``key``: its name in model files, truth files, labels and the CLI;
* where it acts: a named ``region`` of the model file (``[regions]``), or a
  named ``element`` of one ``element_kind`` (a bearing, a thrust bearing, a
  disk, a shaft element; by default the kind the field is called after: a
  field ``bearing`` names a bearing), or neither (the whole machine);
* ``explanation``: its physics in one line; ``{region}`` in it becomes the
  machine's own words for the region, the names of the disks there
  (:meth:`Effect.explain`);
* ``per_mode``: whether each mode has its own values (then not one FEM), and
  then ``name_pattern``, the names of its parameters for any number of modes;
* ``local``: a local change outside the library (the localisation scan's
  hypotheses) rather than a library effect the diagnosis names;
* ``replaces``: the keys of effects it holds as a special case (the per-mode
  FSI holds the mode-independent one), which cannot be on one model with it.

Its instances give :meth:`Effect.parameters` (names, units, bounds, linear
footprints on the model's matrices) and :meth:`Effect.plausible_scale` (the
prior scale of each parameter). :meth:`Effect.instances` lists the
zero-valued instances a model admits. An effect class becomes known to twin
through :func:`twin.fem.effects.register` (see :mod:`twin.fem.effects`).
"""

from __future__ import annotations

import dataclasses
import re
import typing
from collections.abc import Sequence
from typing import ClassVar

import numpy as np

from twin.errors import ModelError
from twin.fem.elements import node_dofs
from twin.fem.parameters import Parameter, Term

#: Plausible magnetic or seal stiffness, as a fraction of the guide bearings' direct stiffness.
FLUID_MAGNETIC_FRACTION = 0.3
#: Plausible change of a bearing or thrust coefficient (or of any parameter no effect owns), as a fraction of its value.
CHANGE_FRACTION = 0.5
#: Plausible size of a local relative change (the prior scale of the localisation scan).
LOCAL_CHANGE_SCALE = 0.5
#: A relative change leaves the coefficient non-negative.
RELATIVE_BOUNDS = (-1.0, np.inf)
#: The kinds of named element an effect can act on, and the model attribute that lists them.
ELEMENT_KINDS = {"bearing": "bearings", "thrust": "thrusts", "disk": "disks", "shaft": "shaft"}


class Effect:
    """Base class of every effect: the declarations and the methods twin calls.

    Subclasses are frozen dataclasses whose number fields (``float`` or
    ``tuple[float, ...]``) are the values of their parameters, in the order of
    :meth:`parameters`, and whose one ``str`` or ``int`` field (named by
    ``element``) names the element they act on.
    """

    key: ClassVar[str] = ""
    explanation: ClassVar[str] = ""
    region: ClassVar[str | None] = None
    element: ClassVar[str | None] = None
    element_kind: ClassVar[str | None] = None
    per_mode: ClassVar[bool] = False
    name_pattern: ClassVar[re.Pattern | None] = None
    local: ClassVar[bool] = False
    replaces: ClassVar[frozenset[str]] = frozenset()
    #: The way its parameters can move over a machine's service, from one day's state to a later one's: -1 only
    #: down, +1 only up, 0 either. The tracker, which names changes from a baseline, bounds them so; the
    #: single-record diagnosis, which names where a model differs from the machine, does not.
    in_service: ClassVar[int] = 0

    def parameters(self, model) -> list[Parameter]:
        """The effect's parameters on ``model``: names, values [SI], units, footprints and bounds."""
        raise NotImplementedError(f"{type(self).__name__} does not define parameters(model)")

    def plausible_scale(self, model) -> dict[str, float]:
        """``{parameter: a generous magnitude a real machine could show [SI]}`` (the prior scale)."""
        raise NotImplementedError(f"{type(self).__name__} does not define plausible_scale(model)")

    @classmethod
    def instances(cls, model) -> list[Effect]:
        """The zero-valued effects of this kind that ``model`` admits: one per named element of its kind, one if
        the model declares its region, one if it acts on the whole machine."""
        if cls.element is not None:
            return [cls(**{cls.element: name}) for name in element_names(model, cls.element_kind or cls.element)]
        if cls.region is not None:
            return [cls()] if cls.region in model.regions else []
        return [cls()]

    def with_modes(self, n_modes: int) -> Effect:
        """A per-mode effect with ``n_modes`` zero values (per-mode effects only)."""
        raise ModelError(f"effect '{self.key}' has no per-mode values")

    @classmethod
    def explain(cls, model=None) -> str:
        """Its physics in one line, in ``model``'s words: ``{region}`` in :attr:`explanation` names the disks in
        the effect's region (:func:`region_words`), or the region generically without a model.

        Examples
        --------
        >>> from twin.fem.effects import FluidAddedMass
        >>> FluidAddedMass.explain(hydro_unit)
        'the water around the runner moves with it, adding mass and damping to every mode alike'
        >>> FluidAddedMass.explain()
        "the water around the region 'immersed' moves with it, adding mass and damping to every mode alike"
        """
        return cls.explanation.replace("{region}", region_words(model, cls.region))


def region_words(model, region: str | None) -> str:
    """How the machine names a region: the disks in it (``"the runner"``), else its nodes (``"node 27"``); without
    a model (or a region it declares), ``"the region 'immersed'"``.

    Examples
    --------
    >>> region_words(hydro_unit, "immersed"), region_words(hydro_unit, "seal")
    ('the runner', 'node 27')
    """
    nodes = getattr(model, "regions", {}).get(region) if region else None
    if not nodes:
        return f"the region '{region}'" if region else "the machine"
    disks = [d.name for d in model.disks if d.node in nodes]
    if disks:
        return "the " + " and the ".join(disks)
    return f"node {nodes[0]}" if len(nodes) == 1 else f"nodes {', '.join(str(n) for n in nodes)}"


def element_names(model, kind: str) -> list:
    """The names of ``model``'s elements of ``kind`` (a shaft element's name is its index).

    Examples
    --------
    >>> element_names(hydro_unit, "bearing")
    ['UGB', 'LGB']
    """
    if kind not in ELEMENT_KINDS:
        raise ModelError(f"no element kind '{kind}' (kinds: {', '.join(ELEMENT_KINDS)})")
    if kind == "shaft":
        return [e.n for e in model.shaft]
    return [item.name for item in getattr(model, ELEMENT_KINDS[kind])]


def model_element(model, kind: str, name: str):
    """The bearing, thrust bearing or disk called ``name`` (an error naming the model's ones if none)."""
    items = getattr(model, ELEMENT_KINDS[kind])
    for item in items:
        if item.name == name:
            return item
    known = ", ".join(repr(i.name) for i in items) or "none"
    raise ModelError(f"model '{model.name}' has no {kind} '{name}' (its {kind}s: {known})")


def element_value(model, element: str, key: str, default: float) -> float:
    """An element coefficient at the model's values (read without assembling the model's parameters)."""
    return float(model.values.get(f"{element}.{key}", default))


def shared_over(kind: str, dofs: tuple[int, ...]) -> tuple[Term, ...]:
    """One unit shared equally over ``dofs`` on the diagonal of matrix ``kind``."""
    return (Term(kind, dofs, np.eye(len(dofs)) / len(dofs)),)


def cross_coupled(model, region: str) -> tuple[Term, ...]:
    """Skew-symmetric ``[[0, 1], [-1, 0]] / n`` on (x, y) of each of a region's ``n`` nodes."""
    nodes = model.regions[region]
    block = np.array([[0.0, 1.0], [-1.0, 0.0]]) / len(nodes)
    return tuple(Term("K", node_dofs(n)[:2], block) for n in nodes)


def region_mass(model, region: str) -> float:
    """Mass of the disks on a region's nodes [kg] (a tenth of the rotor's if none)."""
    nodes = set(model.regions[region])
    disks = [d for d in model.disks if d.node in nodes]
    if not disks:
        return 0.1 * model.total_mass
    return sum(model.parameter(f"{d.name}.m").nominal for d in disks)


def direct_stiffness(model) -> float:
    """Geometric mean of the absolute direct stiffnesses ``kxx`` and ``kyy`` of the guide bearings [N/m]."""
    values = [abs(model.parameter(f"{b.name}.{k}").nominal) for b in model.bearings for k in ("kxx", "kyy")]
    values = [v for v in values if v > 0]
    if not values:
        raise ModelError(f"model '{model.name}' has no bearing stiffness to scale a stiffness effect by")
    return float(np.exp(np.mean(np.log(values))))


class RelativeChange(Effect):
    """A local change: one relative parameter ``δ`` of an element's own coefficients, prior scale
    :data:`LOCAL_CHANGE_SCALE`, bounded below by -1."""

    local: ClassVar[bool] = True

    def plausible_scale(self, model) -> dict[str, float]:
        """:data:`LOCAL_CHANGE_SCALE` (a relative change)."""
        return {p.name: LOCAL_CHANGE_SCALE for p in self.parameters(model)}

    def where(self, model) -> str:
        """The place in words (the diagnosis's and the tracker's reports name it)."""
        return f"{self.element_kind or self.element} {getattr(self, self.element)}"


def effect_fields(cls: type) -> dict[str, type]:
    """The settable values of an effect class and their Python types.

    Examples
    --------
    >>> from twin.fem.effects import MagneticPull
    >>> effect_fields(MagneticPull)
    {'stiffness': <class 'float'>}
    """
    return {f.name: _field_kind(cls, f) for f in dataclasses.fields(cls)}


def _field_kind(cls: type, field: dataclasses.Field) -> type:
    """``float``, ``int``, ``str`` or ``tuple`` for a field annotated as such (or as ``tuple[float, ...]``),
    whether the annotation is a type or, under ``from __future__ import annotations``, its text."""
    kind = field.type
    if isinstance(kind, str):
        kind = {"float": float, "int": int, "str": str}.get(kind, tuple if kind.startswith("tuple[") else kind)
    elif typing.get_origin(kind) is tuple:
        kind = tuple
    if kind not in (float, int, str, tuple):
        raise TypeError(
            f"effect {cls.__name__}: field '{field.name}' is {field.type!r}; an effect's fields are "
            f"float, int, str or tuple[float, ...]"
        )
    return kind


def scaled(effect: Effect, factor: float) -> Effect:
    """The effect (or local change) with every value multiplied by ``factor``; element names and indices kept.

    Examples
    --------
    >>> from twin.fem.effects import BearingChange
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


def plausible_scales(model) -> dict[str, float]:
    """``{parameter: plausible scale [SI]}`` of every parameter of the model's switched-on effects.

    Examples
    --------
    >>> from twin.fem.effects import MagneticPull
    >>> m = hydro_unit.with_effects(MagneticPull())
    >>> {k: round(v / 1e6, 1) for k, v in plausible_scales(m).items()}
    {'MAG.stiffness': 89.1}
    """
    out: dict[str, float] = {}
    for effect in model.effects:
        scales = effect.plausible_scale(model)
        out.update({p.name: scales[p.name] for p in effect.parameters(model)})
    return out


def free_names(model, effect: Effect, labels: Sequence[int]) -> list[str]:
    """The parameters of ``effect`` that measured modes ``labels`` can determine (a per-mode effect's for those modes).

    Examples
    --------
    >>> from twin.fem.effects import FluidAddedMassPerMode
    >>> free_names(hydro_unit, FluidAddedMassPerMode((0.0,) * 3, (0.0,) * 3), [1, 3])
    ['FSI.added_mass_1', 'FSI.added_damping_1', 'FSI.added_mass_3', 'FSI.added_damping_3']
    """
    names = [p.name for p in effect.parameters(model)]
    if effect.per_mode:
        wanted = {int(m) for m in labels}
        names = [n for n in names if int(n.rsplit("_", 1)[1]) in wanted]
    return names
