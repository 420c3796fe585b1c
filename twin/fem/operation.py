"""Operating conditions and the laws by which model parameters follow them.

A machine's modes move with its operating point: the magnetic pull grows with
the excitation the load needs, the seals' cross-coupling with the head across
them, the guide bearings' stiffness and damping fall as their oil warms. A
model file declares the operating data it depends on (``[[condition]]``) and
the laws (``[[law]]``)::

    [[condition]]
    name = "power"                 # how records and schedules name it
    units = "MW"                   # read with pint; laws' slopes are per one of these
    reference = 180.0              # the operating point the laws' reference values hold at
    range = [60.0, 210.0]          # where the laws are valid (checked against the bounds)
    description = "active power at the generator terminals"

    [[law]]
    parameter = "MAG.stiffness"    # a model parameter, or one a library effect brings
    reference = -6.0e7             # its value at the reference point [SI]; default: the model's
                                   # (zero for a parameter an effect brings)
    slopes = { power = -1.5e5 }    # change per unit of each condition [SI per condition unit]
    description = "pull grows with the field current the load needs"

A law is affine in the conditions, the linearisation of the physics about the
reference point within the declared ranges, and linear in its coefficients
(the reference value and the slopes), so a tracker can fit them by linear
least squares through the model's sensitivities. A parameter that a library
effect brings (``MAG.stiffness``) is added to the model at an operating point;
the model read without one (:func:`twin.load_model`) is the machine without
its operation-dependent effects, as the single-record loop uses it.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace

import numpy as np

from twin.errors import ModelError, ModelFileError
from twin.fem.effects import effect_label, effect_providing, library_effects
from twin.fem.schema import section
from twin.fem.tables import Table, array_of_tables, label_table

_IDENTIFIER = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


@dataclass(frozen=True)
class Variation:
    """How one condition varies over a campaign, in the condition's units (:func:`twin.track.profile.operating_points`):
    a mean, a daily cycle highest at ``peak_hour``, a yearly season highest on ``seasonal_peak_day``, a linear drift,
    other conditions it follows (``follows``: per unit of their departure from their mean) and a random dispatch
    level (``dispatch_std``, AR(1) with ``dispatch_correlation`` between successive records).

    A model file declares a condition's typical variation (``[condition.variation]``); a campaign's schedule
    overrides it (``[operation.<condition>]``); a condition without one stays at its reference value.
    """

    mean: float
    daily_amplitude: float = 0.0
    peak_hour: float = 18.0
    seasonal_amplitude: float = 0.0
    seasonal_peak_day: float = 200.0
    drift_per_year: float = 0.0
    dispatch_std: float = 0.0
    dispatch_correlation: float = 0.0
    follows: dict[str, float] = field(default_factory=dict)


#: The keys of a variation table that may not be negative.
_NONNEGATIVE = ("dispatch_std", "daily_amplitude", "seasonal_amplitude")


def read_variation(t: Table, base: Variation, names, name: str) -> Variation:
    """A condition's variation from table ``t`` (a schedule's ``[operation.<name>]`` or a model file's
    ``[condition.variation]``) over ``base``; ``names`` are the declared conditions, which ``follows`` may name.
    Errors name the file, the table and the key."""
    values: dict = {}
    for f in fields(Variation):
        if f.name == "follows":
            follows = t._get("follows", base.follows)
            if not isinstance(follows, dict):
                raise t.error("follows", f"expected a table of slopes by condition, got {follows!r}")
            for k, v in follows.items():
                if k not in names or k == name:
                    raise t.error("follows", f"'{k}' is not another declared condition ({', '.join(names)})")
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                    raise t.error("follows", f"the slope on '{k}' must be a finite number, got {v!r}")
            values["follows"] = {k: float(v) for k, v in follows.items()}
        else:
            values[f.name] = t.number(f.name, getattr(base, f.name), nonnegative=f.name in _NONNEGATIVE)
    if not 0 <= values["dispatch_correlation"] < 1:
        raise t.error("dispatch_correlation", f"must be in [0, 1), got {values['dispatch_correlation']:g}")
    t.finish()
    return replace(base, **values)


@dataclass(frozen=True)
class Condition:
    """One operating quantity: its name, units, reference value and valid range (in its own units).

    Examples
    --------
    >>> c = Condition("head", "m", 140.0, 125.0, 150.0, "net head")
    >>> c.contains(151.0)
    False
    """

    name: str
    units: str
    reference: float
    low: float
    high: float
    description: str = ""
    variation: Variation | None = None

    def contains(self, value: float) -> bool:
        """Whether ``value`` lies in the declared range (ends included)."""
        return bool(self.low <= value <= self.high)


@dataclass(frozen=True)
class Law:
    """A parameter's affine dependence on the conditions: ``reference + sum(slope_k * (c_k - ref_k))``.

    ``reference`` is None where the parameter keeps the model's value at the reference point.
    """

    parameter: str
    slopes: tuple[tuple[str, float], ...]
    reference: float | None = None
    description: str = ""

    @property
    def conditions(self) -> tuple[str, ...]:
        """The conditions the law depends on."""
        return tuple(name for name, _ in self.slopes)


@dataclass(frozen=True)
class Operation:
    """The operating conditions a model declares and the laws its parameters follow.

    Examples
    --------
    >>> op = hydro_unit.operation
    >>> op.names[:3]
    ('power', 'reactive_power', 'head')
    >>> round(op.reference_point()["head"], 1)
    140.0
    """

    conditions: tuple[Condition, ...]
    laws: tuple[Law, ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        """The conditions' names, in the order the model file declares them."""
        return tuple(c.name for c in self.conditions)

    @property
    def units(self) -> dict[str, str]:
        """Each condition's units."""
        return {c.name: c.units for c in self.conditions}

    @property
    def parameters(self) -> tuple[str, ...]:
        """The parameters the laws set."""
        return tuple(law.parameter for law in self.laws)

    def condition(self, name: str) -> Condition:
        for c in self.conditions:
            if c.name == name:
                return c
        raise ModelError(f"no operating condition '{name}' (the model declares: {', '.join(self.names)})")

    def reference_point(self) -> dict[str, float]:
        """The reference value of every condition."""
        return {c.name: c.reference for c in self.conditions}

    def check_point(self, point: Mapping[str, float], where: str = "operating point") -> dict[str, float]:
        """The point with every condition given, finite and in range; conditions left out take their reference.

        Raises :class:`~twin.errors.ModelError` naming ``where`` and the condition for an unknown name, a
        value that is not a finite number, or one outside the declared range.
        """
        unknown = sorted(set(point) - set(self.names))
        if unknown:
            raise ModelError(
                f"{where}: unknown operating condition '{unknown[0]}' (the model declares: {', '.join(self.names)})"
            )
        out = {}
        for c in self.conditions:
            value = point.get(c.name, c.reference)
            if (
                isinstance(value, bool)
                or not isinstance(value, (int, float, np.floating, np.integer))
                or not math.isfinite(float(value))
            ):
                raise ModelError(f"{where}: {c.name} must be a finite number [{c.units}], got {value!r}")
            if not c.contains(float(value)):
                raise ModelError(
                    f"{where}: {c.name} = {float(value):g} {c.units} is outside the model's range "
                    f"[{c.low:g}, {c.high:g}] {c.units}, where its laws hold"
                )
            out[c.name] = float(value)
        return out

    def values(self, model, point: Mapping[str, float]) -> dict[str, float]:
        """The laws' parameter values [SI] at an operating point (checked by :meth:`check_point`)."""
        point = self.check_point(point)
        out = {}
        for law in self.laws:
            base = law.reference if law.reference is not None else model.parameter(law.parameter).nominal
            out[law.parameter] = base + sum(s * (point[k] - self.condition(k).reference) for k, s in law.slopes)
        return out


def with_parameters(model, names) -> object:
    """The model with the library effects added (zero-valued) that bring those of ``names`` it lacks.

    Examples
    --------
    >>> m = with_parameters(hydro_unit, ["MAG.stiffness", "UGB.kxx"])
    >>> m.parameter("MAG.stiffness").nominal
    0.0
    """
    have = set(model.parameter_names)
    wanted = []
    for name in names:
        if name in have:
            continue
        label = effect_providing(model, name)
        if label is None:
            model.parameter(name)  # raises, naming close parameters
        if label not in wanted:
            wanted.append(label)
    effects = [e for e in library_effects(model) if effect_label(e) in wanted]
    return model.with_effects(*effects) if effects else model


def with_change(model, effect):
    """The model with ``effect``'s values added: to the parameters it already has, or as a new effect.

    Examples
    --------
    >>> from twin.fem.effects import BearingChange
    >>> unit = hydro_unit.with_effects(BearingChange("UGB", -1e7))
    >>> with_change(unit, BearingChange("UGB", -2e7)).parameter("UGB.stiffness_change").nominal
    -30000000.0
    """
    params = effect.parameters(model)
    have = set(model.parameter_names)
    if all(p.name in have for p in params):
        return model.with_values({p.name: model.parameter(p.name).nominal + p.nominal for p in params})
    return model.with_effects(effect)


def at_operating_point(model, point: Mapping[str, float]):
    """The model at an operating point: the laws' effects added and their parameters set.

    Parameters
    ----------
    model : RotorModel
        A model whose file declares ``[[condition]]`` and ``[[law]]`` tables.
    point : mapping of str to float
        Condition values in their declared units; a condition left out is at its reference.

    Examples
    --------
    >>> unit = hydro_unit
    >>> low = at_operating_point(unit, {"power": 80.0})
    >>> low.parameter("MAG.stiffness").nominal > at_operating_point(unit, {}).parameter("MAG.stiffness").nominal
    True
    """
    op = operation_of(model)
    model = with_parameters(model, op.parameters)
    return model.with_values(op.values(model, point))


def operation_of(model) -> Operation:
    """The model's operating conditions and laws; a :class:`~twin.errors.ModelError` if it declares none."""
    if model.operation is None:
        raise ModelError(
            f"model '{model.name}' declares no operating conditions: the twin over time needs its "
            "[[condition]] and [[law]] tables (see models/hydro_unit.toml)"
        )
    return model.operation


def read_operation(top, model) -> Operation | None:
    """The ``[[condition]]`` and ``[[law]]`` tables of a model file (``top``, a model file's reading table).

    Every problem is a :class:`~twin.errors.ModelFileError` naming the file, the table and the key: a
    condition without units pint reads, a reference outside its range, a law on an unknown parameter or
    condition, a law that takes its parameter outside the physical bounds somewhere in the declared ranges.
    """
    conditions: list[Condition] = []
    variations: list[tuple[Table, object]] = []
    for t in array_of_tables(top, "condition", section=section("[[condition]]")):
        name = t.read("name")
        if not _IDENTIFIER.match(name):
            raise t.error("name", f"{name!r} is not a valid condition name (letters, digits and '_')")
        label_table(t, name)
        if name in {c.name for c in conditions}:
            raise t.error("name", f"a second condition named '{name}'")
        units = t.read("units")
        _check_units(t, units)
        reference = t.read("reference")
        span = t.read("range")
        if (
            len(span) != 2
            or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in span)
            or not span[0] < span[1]
        ):
            raise t.error("range", f"expected [low, high] with low < high, got {span!r}")
        if not span[0] <= reference <= span[1]:
            raise t.error("reference", f"{reference:g} {units} is outside the range [{span[0]:g}, {span[1]:g}]")
        conditions.append(Condition(name, units, reference, float(span[0]), float(span[1]), t.read("description")))
        variations.append((t, t.read("variation")))
        t.finish()
    names = [c.name for c in conditions]
    for i, ((t, raw), c) in enumerate(zip(variations, conditions)):
        if raw is not None:
            table = Table(t.path, f"{t.where}, [condition.variation]", raw)
            variation = read_variation(table, Variation(mean=c.reference), names, c.name)
            conditions[i] = dataclasses.replace(c, variation=variation)
    laws_tables = array_of_tables(top, "law", section=section("[[law]]"))
    if not conditions:
        if laws_tables:
            raise laws_tables[0].error(None, "a law needs operating conditions: declare them in [[condition]] tables")
        return None
    op = Operation(tuple(conditions))
    laws: list[Law] = []
    for t in laws_tables:
        parameter = t.read("parameter")
        label_table(t, parameter)
        if parameter in {law.parameter for law in laws}:
            raise t.error("parameter", f"a second law for '{parameter}': put every condition's slope in one law")
        try:
            extended = with_parameters(model, [parameter])
            p = extended.parameter(parameter)
        except ModelError as exc:
            raise t.error("parameter", str(exc)) from None
        if p.per_mode:
            raise t.error("parameter", f"'{parameter}' takes one value per mode; a law sets a single FEM parameter")
        reference = t.read("reference")
        slopes_table = t.read("slopes")
        if not isinstance(slopes_table, dict) or not slopes_table:
            raise t.error("slopes", "expected a table of slopes by condition, e.g. slopes = { power = -1.5e5 }")
        slopes = []
        for k, v in slopes_table.items():
            if k not in op.names:
                raise t.error("slopes", f"no condition '{k}' (declared: {', '.join(op.names)})")
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise t.error("slopes", f"the slope on '{k}' must be a finite number, got {v!r}")
            slopes.append((k, float(v)))
        law = Law(parameter, tuple(slopes), reference, t.read("description"))
        t.finish()
        _check_bounds(t, op, law, p, extended)
        laws.append(law)
    return dataclasses.replace(op, laws=tuple(laws))


def _check_units(table, units: str) -> None:
    """Refuse units pint cannot read (a typo in a file is found at load time, not in a report)."""
    import pint

    from twin.units import registry

    try:
        registry().Unit(units)
    except (pint.errors.PintError, ValueError, TypeError, AttributeError, AssertionError) as exc:
        raise table.error("units", f"{units!r} are not units pint reads ({type(exc).__name__})") from None


def _check_bounds(table, op: Operation, law: Law, parameter, model) -> None:
    """Refuse a law that takes its parameter outside its physical bounds at a corner of the declared ranges."""
    one = dataclasses.replace(op, laws=(law,))
    names = law.conditions
    for corner in itertools.product(*[(op.condition(k).low, op.condition(k).high) for k in names]):
        point = dict(zip(names, corner))
        value = one.values(model, point)[law.parameter]
        if not parameter.within(value):
            at = ", ".join(f"{k} = {v:g} {op.condition(k).units}" for k, v in point.items())
            raise ModelFileError(
                table.path,
                table.where,
                "slopes",
                f"at {at} the law gives {law.parameter} = {value:.4g} {parameter.unit}, outside its "
                f"physical bounds ({parameter.bounds_text()})",
            )
