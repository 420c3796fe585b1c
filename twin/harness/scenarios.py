"""What a truth hides from the twin: scenario specs for ``twin demo`` and ``twin sweep``.

A *spec* is ``none`` or one or more terms joined by ``+``; a term is

* a library effect at its reference size on the machine (:func:`reference_effect`:
  the size its model file declares, or one derived from the machine), e.g.
  ``magnetic_pull`` or ``bearing_change:LGB``, or scaled with ``@``:
  ``magnetic_pull@2.5`` hides 2.5 times the reference values;
* a local change outside the library (:mod:`twin.fem.effects.shaft`, :mod:`twin.fem.effects.disk`), with ``@`` the
  factor on the element's own value: ``shaft_stiffness:18@0.5`` (element 18
  at half its bending stiffness), ``disk_mass:generator@1.1`` (10% heavier),
  ``disk_inertia:runner@1.2``; without ``@``, :data:`DEFAULT_FACTORS`;
* ``shaft_stiffness_loss``, the same as ``shaft_stiffness:18@0.5``.

So ``magnetic_pull@1.5+seal_cross_coupling@0.8`` hides two effects at once.
A scenario passes its diagnosis when the twin names exactly the hidden
library effects, says "unexplained" and points at the hidden local change, or
says "nothing missing" with nothing hidden (:meth:`Scenario.expected`).
"""

from __future__ import annotations

import dataclasses
import itertools
import re
from dataclasses import dataclass

import numpy as np

from twin.errors import ModelError, TwinError
from twin.fem.effects import effect_classes, effect_label, exclusive, from_label, parse_label, scaled
from twin.fem.truthfile import Truth

#: The largest relative change of a pole ``|p' - p| / |p|`` among the machine's lowest
#: :data:`REFERENCE_MODES` lightly damped modes that an effect makes at the reference size derived from the
#: machine (:func:`reference_effect`): beyond what a record resolves, as the hydro unit's declared sizes
#: (2% to 24%).
REFERENCE_POLE_CHANGE = 0.05
#: The lightly damped modes (:data:`twin.modes.analysis.LIGHT_DAMPING`) a derived reference size is measured on.
REFERENCE_MODES = 10
#: A derived reference size takes away at most this fraction of a coefficient.
MAX_LOSS = 0.9
#: The remaining fraction of a local change's value when a spec gives no ``@`` factor.
DEFAULT_FACTORS = {"shaft_stiffness": 0.5, "disk_mass": 1.1, "disk_inertia": 1.2}
#: Spec of a truth that is the model itself (the false-alarm check).
NOTHING = "none"
#: Older names of specs.
ALIASES = {"shaft_stiffness_loss": "shaft_stiffness:18@0.5"}

_TERM = re.compile(r"^(?P<label>[A-Za-z_]+(?::[A-Za-z0-9_]+)?)(?:@(?P<factor>[-+0-9.eE]+))?$")


def _local(label: str, factor: float):
    """The local change ``label`` at ``factor`` times the element's own value."""
    try:
        return from_label(label, change=round(factor - 1.0, 12))
    except ModelError as exc:
        raise TwinError(str(exc)) from None


@dataclass(frozen=True)
class Scenario:
    """A parsed spec: the library effects and the local changes a truth hides, with their truth values.

    Examples
    --------
    >>> s = parse_scenario("magnetic_pull@2.5+seal_cross_coupling", hydro_unit)
    >>> s.labels, s.effects[0].stiffness
    (('magnetic_pull', 'seal_cross_coupling'), -250000000.0)
    >>> parse_scenario("shaft_stiffness_loss", hydro_unit).changes
    (ShaftStiffnessChange(index=18, change=-0.5),)
    """

    spec: str
    effects: tuple = ()
    changes: tuple = ()

    @property
    def labels(self) -> tuple[str, ...]:
        """Labels of the hidden library effects."""
        return tuple(effect_label(e) for e in self.effects)

    @property
    def change_labels(self) -> tuple[str, ...]:
        """Labels of the hidden local changes (``shaft_stiffness:18``, ``disk_mass:generator``)."""
        return tuple(effect_label(c) for c in self.changes)

    @property
    def nothing(self) -> bool:
        """Whether the truth is the model itself."""
        return not self.effects and not self.changes

    def truth(self) -> Truth:
        """The truth to simulate: the hidden effects and changes, all switched on."""
        return Truth((*self.effects, *self.changes), source=self.spec)

    def truth_values(self, model) -> dict[str, float]:
        """Parameter values [SI] of the hidden library effects (per-mode ones by the truth's target mode).

        Examples
        --------
        >>> parse_scenario("magnetic_pull", hydro_unit).truth_values(hydro_unit)
        {'MAG.stiffness': -100000000.0}
        """
        return {p.name: p.nominal for e in self.effects for p in e.parameters(model.with_effects(e))}

    def check(self, model) -> None:
        """Raise a :class:`~twin.errors.TwinError` when the model lacks an element or region the spec names."""
        for item in (*self.effects, *self.changes):
            try:
                item.parameters(model.with_effects(item))
            except Exception as exc:  # ModelError naming the missing element or region
                raise TwinError(f"scenario '{self.spec}': {exc}") from None

    def describe(self, model=None) -> str:
        """What the truth hides, in words."""
        if self.nothing:
            return "nothing"
        parts = []
        for e in self.effects:
            if e.per_mode:
                parts.append(f"{effect_label(e)} ({e.n_modes} modes, FSI.added_mass_1 = {e.added_mass[0]:.4g} kg, ...)")
            else:
                values = {
                    f.name: getattr(e, f.name) for f in dataclasses.fields(e) if isinstance(getattr(e, f.name), float)
                }
                parts.append(f"{effect_label(e)} (" + ", ".join(f"{k} = {v:.4g}" for k, v in values.items()) + ")")
        for c in self.changes:
            where = c.where(model) if model is not None else effect_label(c)
            parts.append(f"{where} at {1 + c.change:.0%} of its value (outside the effects library)")
        return "; ".join(parts)

    def expected(self) -> str:
        """The right diagnosis in words (see the module docstring)."""
        if self.nothing:
            return "nothing missing"
        if not self.changes:
            return f"missing effect: {', '.join(self.labels)}"
        return f"unexplained, at {', '.join(self.change_labels)}"

    @property
    def folder(self) -> str:
        """A folder name for the scenario (no ``:`` or ``@``)."""
        return spec_folder(self.spec)


def spec_folder(spec: str) -> str:
    """A folder name for a scenario spec (no ``:`` or ``@``).

    Examples
    --------
    >>> spec_folder("bearing_change:LGB@0.5")
    'bearing_change_LGB_x0.5'
    """
    return str(spec).strip().replace(":", "_").replace("@", "_x")


def parse_scenario(spec: str, model) -> Scenario:
    """Parse a hidden-change spec (see the module docstring) for ``model``; unknown labels are named.

    Examples
    --------
    >>> parse_scenario("disk_mass:generator@1.1", hydro_unit).changes
    (DiskMassChange(disk='generator', change=0.1),)
    >>> parse_scenario("magnetic_pull@x", hydro_unit)
    Traceback (most recent call last):
    ...
    twin.errors.TwinError: hidden change 'magnetic_pull@x': a term is LABEL or LABEL@FACTOR with a number FACTOR
    """
    spec = str(spec).strip()
    if spec == NOTHING:
        return Scenario(NOTHING)
    effects, changes, seen = [], [], set()
    for term in spec.split("+"):
        term = ALIASES.get(term.strip(), term.strip())
        m = _TERM.match(term)
        if not m:
            raise TwinError(f"hidden change '{spec}': a term is LABEL or LABEL@FACTOR with a number FACTOR")
        label, factor = m["label"], m["factor"]
        try:
            value = None if factor is None else float(factor)
        except ValueError:
            raise TwinError(f"hidden change '{spec}': '{factor}' is not a number") from None
        if value is not None and not value > 0:
            raise TwinError(f"hidden change '{spec}': the factor of '{label}' must be positive, got {value:g}")
        key, element = parse_label(label)
        if key in effect_classes(local=False):
            try:
                reference = reference_effect(model, label)
            except TwinError as exc:
                raise TwinError(f"hidden change '{spec}': {exc}") from None
            effects.append(scaled(reference, 1.0 if value is None else value))
        elif key in effect_classes(local=True) and element:
            if value is None and key not in DEFAULT_FACTORS:
                raise TwinError(f"hidden change '{spec}': '{label}' has no default size; give it as {label}@FACTOR")
            changes.append(_local(label, DEFAULT_FACTORS[key] if value is None else value))
        else:
            raise TwinError(f"hidden change '{spec}': unknown '{label}'; choose from {', '.join(known_terms(model))}")
        if label in seen:
            raise TwinError(f"hidden change '{spec}': '{label}' appears twice")
        seen.add(label)
    for a, b in itertools.combinations(sorted(seen), 2):
        if exclusive(a, b):
            raise TwinError(f"hidden change '{spec}': {a} and {b} describe the same physics; hide one")
    return Scenario(spec, tuple(effects), tuple(changes))


def known_terms(model) -> list[str]:
    """The labels a spec term can start with on ``model`` (local changes with a placeholder).

    Examples
    --------
    >>> known_terms(hydro_unit)[-4:]
    ['shaft_stiffness:<element>', 'disk_mass:<disk>', 'disk_inertia:<disk>', 'shaft_stiffness_loss']
    """
    return [*reference_labels(model), "shaft_stiffness:<element>", "disk_mass:<disk>", "disk_inertia:<disk>", *ALIASES]


def reference_labels(model) -> list[str]:
    """The library effects a scenario can hide on ``model``: every one it admits, per-mode ones only where the
    model file declares their reference size (a per-mode size cannot be derived).

    Examples
    --------
    >>> reference_labels(hydro_unit)[:3]
    ['fsi', 'fsi_per_mode', 'magnetic_pull']
    """
    from twin.loop.candidates import candidates

    declared = {effect_label(e) for e in model.reference_changes}
    return [c.label for c in candidates(model, present=True) if not c.per_mode or c.label in declared]


def reference_effect(model, label: str):
    """The library effect ``label`` at its reference size on ``model``: what the model file's
    ``[reference_changes]`` declares, or else a size derived from the machine.

    The derived size moves the parameters together: a change that can take a coefficient away (bounded below by
    minus its value: a bearing's, a tilt stiffness's) as a proportional loss of the coefficients, a parameter
    that is never positive (a magnetic pull) down and any other up by its plausible scale
    (:meth:`twin.fem.effects.Effect.plausible_scale`); all scaled so that the largest relative pole change
    among the :data:`REFERENCE_MODES` lowest lightly damped modes is :data:`REFERENCE_POLE_CHANGE` (a loss of
    at most :data:`MAX_LOSS` of a coefficient), and halved while the machine, stable without it, is unstable with it.

    Examples
    --------
    >>> reference_effect(hydro_unit, "magnetic_pull")  # declared in hydro_unit.toml
    MagneticPull(stiffness=-100000000.0)
    """
    for e in model.reference_changes:
        if effect_label(e) == label:
            return e
    from twin.loop.candidates import candidates

    found = {c.label: c for c in candidates(model, present=True)}
    if label not in found:
        raise TwinError(f"model '{model.name}' admits no library effect '{label}' (it admits: {', '.join(found)})")
    candidate = found[label]
    if candidate.per_mode:
        raise TwinError(
            f"'{label}' has one value per mode: model '{model.name}' declares no reference size for it "
            f'([reference_changes."{label}"] in its model file)'
        )
    return _derived(model, candidate)


def _derived(model, candidate):
    from twin.modes.analysis import LIGHT_DAMPING, modal
    from twin.modes.pairing import dataset_poles, pair_modes

    effect = candidate.effect
    with_effect = model.with_effects(effect)
    scales = effect.plausible_scale(with_effect)
    direction, largest = [], np.inf
    for p in effect.parameters(with_effect):
        low, high = p.bounds
        if np.isfinite(low) and low < 0:  # a change that can take the coefficient away: a proportional loss
            direction.append(low)
            largest = MAX_LOSS
        else:  # a stiffness that is never positive goes down, anything else up, by its plausible scale
            direction.append(-scales[p.name] if high <= 0 else scales[p.name])
    base = modal(model)
    light = base.isel(mode=np.flatnonzero(base["damping_ratio"].values < LIGHT_DAMPING)[:REFERENCE_MODES])

    def change(t: float) -> tuple[float, bool]:
        other = modal(model.with_effects(candidate.with_values(t * np.asarray(direction))))
        pairs = pair_modes(light, other, shape_var="shape")
        a = dataset_poles(light.sel(mode=pairs["reference_mode"].values))
        b = dataset_poles(other.sel(mode=pairs["other_mode"].values))
        return float(np.max(np.abs(b - a) / np.abs(a))), bool(other["stable"].values.all())

    t = min(1.0, largest)
    for _ in range(3):  # the pole change is about linear in the size: a secant step or two
        moved, _stable = change(t)
        if moved <= 0:
            raise TwinError(f"'{candidate.label}' does not move the modes of model '{model.name}'")
        t = min(t * REFERENCE_POLE_CHANGE / moved, largest)
    for _ in range(6 if bool(base["stable"].values.all()) else 0):  # a stable machine stays stable
        if change(t)[1]:
            break
        t /= 2
    return candidate.with_values(t * np.asarray(direction))
