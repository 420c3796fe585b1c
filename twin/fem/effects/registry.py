"""The registry of effects, and their labels.

An effect class is known to twin once it is registered: :func:`register` on
the class. twin finds the effects it ships by importing every module of
:mod:`twin.fem.effects` (the built-in ones first, in the order of
:data:`BUILTIN`), so a new module in that folder is all a new built-in effect
takes. A package of your own adds effects through the entry-point group
``twin.effects``, each entry a module to import (or a class to register)::

    [project.entry-points."twin.effects"]
    housing = "my_plant.effects.housing"

A *label* names one effect on one model: the key, and for an effect on a
named element the element after a colon (``magnetic_pull``,
``bearing_change:LGB``, ``shaft_stiffness:18``). :func:`effect_label` writes
it and :func:`parse_label` reads it; nothing else splits a label.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import logging
import pkgutil
from typing import NamedTuple

from twin.errors import ModelError
from twin.fem.effects.base import ELEMENT_KINDS, Effect, effect_fields

logger = logging.getLogger(__name__)

#: The modules of the built-in effects, in the order the library lists them (other modules of the folder follow
#: by name, then the entry points').
BUILTIN = ("fsi", "magnetic", "seal", "bearing", "thrust", "shaft", "disk")
#: The entry-point group through which other packages add effects.
ENTRY_POINT_GROUP = "twin.effects"
#: Modules of this package that hold no effect.
_NOT_EFFECTS = {"base", "registry"}

_REGISTRY: dict[str, type[Effect]] = {}
#: The registry in the library's order, made once after the last registration.
_ORDERED: dict[str, type[Effect]] | None = None
_loaded = False


def register(cls: type[Effect]) -> type[Effect]:
    """Make the effect class ``cls`` known to twin under its ``key`` (a class decorator).

    A second class under one key is refused, naming both.

    Examples
    --------
    The built-in effects are registered so (``twin/fem/effects/magnetic.py``)::

        @register
        @dataclass(frozen=True)
        class MagneticPull(Effect):
            key: ClassVar[str] = "magnetic_pull"
            ...

    >>> from twin.fem.effects import effect_class
    >>> effect_class("magnetic_pull").__module__
    'twin.fem.effects.magnetic'
    """
    if not (isinstance(cls, type) and issubclass(cls, Effect)):
        raise TypeError(f"{cls!r} is not an Effect class (derive it from twin.fem.effects.Effect)")
    if not cls.key or ":" in cls.key or "@" in cls.key or "+" in cls.key:
        raise ValueError(
            f"{cls.__name__}: an effect's key is a non-empty name without ':', '@' or '+', got {cls.key!r}"
        )
    if cls.element is not None and (cls.element_kind or cls.element) not in ELEMENT_KINDS:
        raise ValueError(
            f"{cls.__name__}: element kind {cls.element_kind or cls.element!r} is none of {', '.join(ELEMENT_KINDS)}"
        )
    if cls.per_mode and cls.name_pattern is None:
        raise ValueError(f"{cls.__name__}: a per-mode effect declares name_pattern, the names of its parameters")
    other = _REGISTRY.get(cls.key)
    if other is not None and other is not cls and other.__qualname__ != cls.__qualname__:
        raise ValueError(
            f"two effects with the key '{cls.key}': {other.__module__}.{other.__qualname__} and "
            f"{cls.__module__}.{cls.__qualname__}"
        )
    global _ORDERED
    _REGISTRY[cls.key] = cls
    _ORDERED = None
    return cls


def _load() -> None:
    """Import the built-in effect modules, the other modules of this folder, then the entry points."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    package = __name__.rpartition(".")[0]
    found = sorted(m.name for m in pkgutil.iter_modules(importlib.import_module(package).__path__))
    for name in [*BUILTIN, *(n for n in found if n not in BUILTIN and n not in _NOT_EFFECTS)]:
        importlib.import_module(f"{package}.{name}")
    for entry in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        try:
            loaded = entry.load()
        except Exception as exc:  # a broken plug-in must not take twin down with it
            logger.warning("effect plug-in '%s' (%s) could not be loaded: %s", entry.name, entry.value, exc)
            continue
        if isinstance(loaded, type):
            register(loaded)


def effect_classes(local: bool | None = None) -> dict[str, type[Effect]]:
    """The registered effect classes by key, in the library's order: library effects (``local=False``), local
    changes (``local=True``) or all (``None``).

    Examples
    --------
    >>> from twin.fem.effects import effect_classes
    >>> list(effect_classes(local=False))[:4]
    ['fsi', 'fsi_per_mode', 'magnetic_pull', 'seal_cross_coupling']
    >>> list(effect_classes(local=True))
    ['shaft_stiffness', 'disk_mass', 'disk_inertia']
    """
    return {k: c for k, c in _ordered().items() if local is None or c.local == local}


def _ordered() -> dict[str, type[Effect]]:
    """Every registered class: the built-in modules' in :data:`BUILTIN` order, then the folder's other
    modules', then other packages', each group in the order of registration."""
    global _ORDERED
    _load()
    if _ORDERED is None:
        package = __name__.rpartition(".")[0] + "."
        order = {key: i for i, key in enumerate(_REGISTRY)}

        def rank(key: str) -> tuple[int, int, int]:
            module = _REGISTRY[key].__module__
            name = module[len(package) :] if module.startswith(package) else None
            if name in BUILTIN:
                return (0, BUILTIN.index(name), order[key])
            return (1 if name is not None else 2, 0, order[key])

        _ORDERED = {k: _REGISTRY[k] for k in sorted(_REGISTRY, key=rank)}
    return _ORDERED


def effect_class(key: str, local: bool | None = None) -> type[Effect]:
    """The effect class registered under ``key`` (an error listing the known keys if none)."""
    classes = effect_classes(local)
    if key not in classes:
        raise ModelError(f"no effect '{key}' (known: {', '.join(classes)})")
    return classes[key]


class Label(NamedTuple):
    """A parsed effect label: the effect's key and the element it acts on (``None`` for none)."""

    key: str
    element: str | None


def effect_label(effect: Effect) -> str:
    """A name unique among a model's effects: the key, with the element for element effects.

    Examples
    --------
    >>> from twin.fem.effects import BearingChange, MagneticPull
    >>> effect_label(MagneticPull()), effect_label(BearingChange("LGB"))
    ('magnetic_pull', 'bearing_change:LGB')
    """
    if effect.element is None:
        return effect.key
    return f"{effect.key}:{getattr(effect, effect.element)}"


def parse_label(label: str) -> Label:
    """The key and the element of an effect label (:func:`effect_label`'s inverse).

    Examples
    --------
    >>> parse_label("bearing_change:LGB"), parse_label("fsi")
    (Label(key='bearing_change', element='LGB'), Label(key='fsi', element=None))
    """
    key, colon, element = str(label).partition(":")
    return Label(key, element if colon else None)


def from_label(label: str, **values) -> Effect:
    """The effect a label names, with ``values`` for its number fields (zero-valued without), its element
    converted to the element field's type (a shaft element's number).

    Examples
    --------
    >>> from_label("shaft_stiffness:18", change=-0.5)
    ShaftStiffnessChange(index=18, change=-0.5)
    >>> from_label("bearing_change:UGB", stiffness_change=-1e8)
    BearingChange(bearing='UGB', stiffness_change=-100000000.0, damping_change=0.0)
    """
    key, element = parse_label(label)
    cls = effect_class(key)
    if cls.element is None:
        if element is not None:
            raise ModelError(
                f"effect '{key}' acts on {'region ' + repr(cls.region) if cls.region else 'the machine'}"
                f", not on a named element: call it '{key}'"
            )
        return cls(**values)
    if not element:
        raise ModelError(f"effect '{key}' names its {cls.element_kind or cls.element}: '{key}:<name>'")
    if effect_fields(cls)[cls.element] is int:
        try:
            element = int(element)
        except ValueError:
            raise ModelError(
                f"'{label}': a {cls.element_kind or cls.element} element is a number, e.g. {key}:0"
            ) from None
    return cls(**{cls.element: element}, **values)


def library_effects(model) -> list[Effect]:
    """Every library effect that ``model``'s regions and elements admit, zero-valued (present ones included).

    Examples
    --------
    >>> [effect_label(e) for e in library_effects(hydro_unit)][:3]
    ['fsi', 'fsi_per_mode', 'magnetic_pull']
    """
    return [e for cls in effect_classes(local=False).values() for e in cls.instances(model)]


def local_changes(model) -> list[Effect]:
    """Every local change the model can take, zero-valued: each shaft element's stiffness, each disk's mass
    and inertia (the hypotheses of the localisation scan).

    Examples
    --------
    >>> changes = local_changes(hydro_unit)
    >>> len(changes), changes[-1]
    (36, DiskInertiaChange(disk='runner', change=0.0))
    """
    return [e for cls in effect_classes(local=True).values() for e in cls.instances(model)]


def is_per_mode_name(name: str) -> bool:
    """Whether ``name`` is a per-mode parameter of a registered per-mode effect (``FSI.added_mass_3``).

    Examples
    --------
    >>> is_per_mode_name("FSI.added_damping_12"), is_per_mode_name("FSI.added_mass")
    (True, False)
    """
    return any(cls.name_pattern.match(name) for cls in _ordered().values() if cls.per_mode)


def effect_providing(model, name: str) -> str | None:
    """The label of the library effect that brings parameter ``name`` (``None`` if none does).

    Examples
    --------
    >>> model = hydro_unit
    >>> effect_providing(model, "MAG.stiffness"), effect_providing(model, "FSI.added_mass_3")
    ('magnetic_pull', 'fsi_per_mode')
    """
    for cls in effect_classes(local=False).values():
        if cls.per_mode:
            if cls.name_pattern.match(name):
                return cls.key
            continue
        for effect in cls.instances(model):
            if name in {p.name for p in effect.parameters(model)}:
                return effect_label(effect)
    return None


def holds(new: str, old: str) -> bool:
    """Whether the effect labelled ``new`` holds the one labelled ``old`` as a special case (its ``replaces``;
    on one element, for element effects), so that it takes the other's place on a model.

    Examples
    --------
    >>> holds("fsi_per_mode", "fsi"), holds("fsi", "fsi_per_mode")
    (True, False)
    """
    a, b = parse_label(new), parse_label(old)
    classes = effect_classes()
    return a.key in classes and b.key in classes[a.key].replaces and a.element == b.element


def exclusive(a: str, b: str) -> bool:
    """Whether two labelled effects describe the same physics (one holds the other): a model or a truth has at
    most one of them.

    Examples
    --------
    >>> exclusive("fsi", "fsi_per_mode"), exclusive("fsi", "magnetic_pull")
    (True, False)
    """
    return holds(a, b) or holds(b, a)


def describe(effect: Effect, model) -> str:
    """One paragraph on an effect: its physics, and each parameter with unit, physical bounds and prior scale.

    Examples
    --------
    >>> from twin.fem.effects import MagneticPull
    >>> print(describe(MagneticPull(), hydro_unit))  # doctest: +NORMALIZE_WHITESPACE
    magnetic_pull: an off-centre rotor at the generator is pulled further off centre by the magnetic field: a
    negative stiffness. MAG.stiffness [N/m]: <= 0, plausible scale 8.91e+07.
    """
    scales = effect.plausible_scale(model)
    parts = []
    for p in effect.parameters(model):
        bounds = p.bounds_text() or "either sign"
        parts.append(f"{p.name} [{p.unit}]: {bounds}, plausible scale {scales[p.name]:.3g}")
    if effect.per_mode and parts:
        parts = [f"per mode i = 1..{effect.n_modes}, like the first: " + parts[0] + "; " + parts[1]]
    elif effect.per_mode:
        parts = [effect.per_mode_text]
    return f"{effect_label(effect)}: {effect.explain(model)}. " + "; ".join(parts) + "."
