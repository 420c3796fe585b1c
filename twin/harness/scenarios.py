"""What a truth hides from the twin: scenario specs for ``twin demo`` and ``twin sweep``.

A *spec* is ``none`` or one or more terms joined by ``+``; a term is

* a library effect at its reference size (:data:`REFERENCE_EFFECTS`), e.g.
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

from twin.errors import ModelError, TwinError
from twin.fem.effects import (
    BearingChange,
    FluidAddedMass,
    MagneticPull,
    SealCrossCoupling,
    ThrustTilt,
    effect_classes,
    effect_label,
    exclusive,
    from_label,
    parse_label,
    scaled,
)
from twin.fem.truthfile import PAPER_TABLE2, Truth

#: Library effects a scenario can hide, at their reference sizes (SI). Each changes the modes well
#: beyond what 20 min of signals resolve (the truth model scores E of about 0.07% against its own
#: extracted modes) and keeps the truth stable at 134 rpm (a seal cross-coupling of 7e7 N/m already
#: makes it unstable; UGB damping -5e7 N s/m too). The per-mode FSI is the reference paper's Table 2.
REFERENCE_EFFECTS = {
    "magnetic_pull": MagneticPull(-1e8),
    "seal_cross_coupling": SealCrossCoupling(5e7),
    "fsi": FluidAddedMass(6e4, 2e6),
    "fsi_per_mode": PAPER_TABLE2,
    "thrust_tilt:thrust": ThrustTilt("thrust", 1e9),
    "bearing_change:LGB": BearingChange("LGB", -3e7, -3e8),
    "bearing_change:UGB": BearingChange("UGB", -2e8, 2e7),
}
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
    >>> s = parse_scenario("magnetic_pull@2.5+seal_cross_coupling")
    >>> s.labels, s.effects[0].stiffness
    (('magnetic_pull', 'seal_cross_coupling'), -250000000.0)
    >>> parse_scenario("shaft_stiffness_loss").changes
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
        >>> parse_scenario("magnetic_pull").truth_values(hydro_unit)
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
        return self.spec.replace(":", "_").replace("@", "_x")


def parse_scenario(spec: str) -> Scenario:
    """Parse a hidden-change spec (see the module docstring); unknown labels are named.

    Examples
    --------
    >>> parse_scenario("disk_mass:generator@1.1").changes
    (DiskMassChange(disk='generator', change=0.1),)
    >>> parse_scenario("magnetic_pull@x")
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
        if label in REFERENCE_EFFECTS:
            effects.append(scaled(REFERENCE_EFFECTS[label], 1.0 if value is None else value))
        elif key in effect_classes(local=True) and element:
            if value is None and key not in DEFAULT_FACTORS:
                raise TwinError(f"hidden change '{spec}': '{label}' has no default size; give it as {label}@FACTOR")
            changes.append(_local(label, DEFAULT_FACTORS[key] if value is None else value))
        else:
            raise TwinError(f"hidden change '{spec}': unknown '{label}'; choose from {', '.join(known_terms())}")
        if label in seen:
            raise TwinError(f"hidden change '{spec}': '{label}' appears twice")
        seen.add(label)
    for a, b in itertools.combinations(sorted(seen), 2):
        if exclusive(a, b):
            raise TwinError(f"hidden change '{spec}': {a} and {b} describe the same physics; hide one")
    return Scenario(spec, tuple(effects), tuple(changes))


def known_terms() -> list[str]:
    """The labels a spec term can start with (local changes with a placeholder).

    Examples
    --------
    >>> known_terms()[-4:]
    ['shaft_stiffness:<element>', 'disk_mass:<disk>', 'disk_inertia:<disk>', 'shaft_stiffness_loss']
    """
    return [*REFERENCE_EFFECTS, "shaft_stiffness:<element>", "disk_mass:<disk>", "disk_inertia:<disk>", *ALIASES]
