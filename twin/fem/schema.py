"""The model file's tables and keys: what each means, its unit, its default and its rule.

This is the one statement of the model-file format. The reader
(:mod:`twin.fem.modelfile`, :mod:`twin.fem.operation`) takes each key's kind,
default and rule from here, and the docs' model-file reference is generated
from it (:func:`reference_text`), so the page and the reader cannot disagree.
The tables of switched-on effects (``[effects."<label>"]``) take their keys
from the registered effects (:mod:`twin.fem.effects`), and the page lists them
from there.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from twin.fem.excitation import BALANCE_GRADE_MM_S
from twin.fem.tables import MISSING

#: The default of a key that must be given.
REQUIRED = MISSING
#: How the value of each kind of key is written.
KINDS = {
    "number": "a number",
    "string": "a string",
    "name": "a name (letters, digits, '_' or '-', starting with a letter)",
    "boolean": "true or false",
    "node": "a node number",
    "place": "a disk's or a region's name, or a node number",
    "array": "an array",
    "table": "a table",
}
#: What a rule on a number means.
RULES = {"positive": "> 0", "nonnegative": ">= 0"}


@dataclass(frozen=True)
class Key:
    """One key of a table: its kind (:data:`KINDS`), meaning, unit, default (:data:`REQUIRED` if none) and rule.

    ``default_text`` says how a default that is not a fixed value is found (derived from the machine, or one of
    two keys required).
    """

    name: str
    kind: str
    doc: str
    unit: str = ""
    default: Any = REQUIRED
    rule: str = ""
    default_text: str = ""

    def default_words(self) -> str:
        """The default as the reference page shows it."""
        if self.default_text:
            return self.default_text
        if self.default is REQUIRED:
            return "required"
        if isinstance(self.default, bool):
            return str(self.default).lower()
        if self.default is None:
            return "none"
        return repr(self.default) if not isinstance(self.default, str) else f'"{self.default}"'


@dataclass(frozen=True)
class Section:
    """One table (``[name]``) or array of tables (``[[name]]``) of a model file, and its keys."""

    header: str
    doc: str
    keys: tuple[Key, ...] = ()
    #: For a table whose keys the user names (``[regions]``): what a key is.
    free_keys: str = ""

    def key(self, name: str) -> Key:
        """The key called ``name`` (a KeyError names the table: a reader asking for an undeclared key is a bug)."""
        for k in self.keys:
            if k.name == name:
                return k
        raise KeyError(f"{self.header} declares no key '{name}'")


def _coefficient(name: str) -> Key:
    kind, unit = ("stiffness", "N/m") if name[0] == "k" else ("damping", "N s/m")
    direct = name[1] == name[2]
    rule = ("positive" if kind == "stiffness" else "nonnegative") if direct else ""
    what = "direct" if direct else "cross-coupled"
    cause = "displacement" if kind == "stiffness" else "velocity"
    return Key(name, "number", f"{what} {kind}: force in {name[1]} per unit {cause} in {name[2]}", unit, rule=rule)


SECTIONS: tuple[Section, ...] = (
    Section(
        "[model]",
        "The machine: its name, running speed and which physics its shaft elements have.",
        (
            Key("name", "name", "the model's name (in every output file and message)"),
            Key("speed_rpm", "number", "running speed", "rpm", rule="nonnegative"),
            Key("description", "string", "one line on the machine", default=""),
            Key("shear_deformation", "boolean", "Timoshenko shear deformation of the shaft elements", default=True),
            Key("rotary_inertia", "boolean", "rotary inertia of the shaft elements' sections", default=True),
            Key(
                "gyroscopic",
                "boolean",
                "gyroscopic coupling of the shaft elements (disks always have it)",
                default=True,
            ),
        ),
    ),
    Section(
        "[materials.<name>]",
        "One table per material; shaft sections name it. Give exactly one of `G` and `poisson`.",
        (
            Key("E", "number", "Young's modulus", "Pa", rule="positive"),
            Key("rho", "number", "density", "kg/m3", rule="positive"),
            Key("G", "number", "shear modulus", "Pa", None, "positive", "one of G and poisson"),
            Key(
                "poisson",
                "number",
                "Poisson's ratio, in (-1, 0.5): G = E / (2 (1 + poisson))",
                "1",
                None,
                "",
                "one of G and poisson",
            ),
        ),
    ),
    Section(
        "[[shaft]]",
        "A section of the shaft from one node to another, of uniform tubular cross-section; the sections join "
        "node 0 to the last node without gaps or overlaps. Give exactly one of `length` and `element_lengths`.",
        (
            Key("nodes", "array", "[first, last]: the section's end node numbers; it has last - first elements"),
            Key("material", "string", "the name of a `[materials.<name>]` table"),
            Key("outer_diameter", "number", "outer diameter", "m", rule="positive"),
            Key(
                "inner_diameter",
                "number",
                "bore diameter, smaller than the outer one (0: solid)",
                "m",
                rule="nonnegative",
            ),
            Key(
                "length",
                "number",
                "the section's length, split equally over its elements",
                "m",
                None,
                "positive",
                "one of length and element_lengths",
            ),
            Key(
                "element_lengths",
                "array",
                "each element's length, one per element",
                "m",
                None,
                "",
                "one of length and element_lengths",
            ),
        ),
    ),
    Section(
        "[[disk]]",
        "A rigid disk on a node: an impeller, a runner, a generator rotor, a coupling.",
        (
            Key("name", "name", "the disk's name (unique among disks, bearings and thrust bearings)"),
            Key("node", "node", "where it sits"),
            Key("mass", "number", "mass", "kg", rule="nonnegative"),
            Key("Id", "number", "diametral moment of inertia", "kg m2", rule="nonnegative"),
            Key("Ip", "number", "polar moment of inertia", "kg m2", rule="nonnegative"),
        ),
    ),
    Section(
        "[[bearing]]",
        "A guide (radial) bearing on a node: eight linear coefficients between the shaft and the ground, "
        "force = -K u - C u' in x and y.",
        (
            Key("name", "name", "the bearing's name (in effect labels: `bearing_change:<name>`)"),
            Key("node", "node", "where it sits"),
            *(_coefficient(c) for c in ("kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy")),
        ),
    ),
    Section(
        "[[thrust]]",
        "A thrust (axial) bearing on a node, seen by the lateral model as a tilt stiffness and damping.",
        (
            Key("name", "name", "the thrust bearing's name (in effect labels: `thrust_tilt:<name>`)"),
            Key("node", "node", "where it sits"),
            Key("k_tilt", "number", "tilt stiffness", "N m/rad", rule="nonnegative"),
            Key("c_tilt", "number", "tilt damping", "N m s/rad", rule="nonnegative"),
        ),
    ),
    Section(
        "[[sensor]]",
        "A displacement probe position (a proximeter pair): its channels are `<name>_x` and `<name>_y`.",
        (
            Key("name", "name", "the sensor's name"),
            Key("node", "node", "the node it measures"),
            Key("location", "string", "where it is, in words", default=""),
            Key("directions", "array", 'the measured directions, "x" and/or "y"', default=["x", "y"]),
        ),
    ),
    Section(
        "[regions]",
        "Named places of the machine, each an array of node numbers. Effects that act on a region exist on a "
        "model only when it declares the region; `[excitation]` may name a region as a place.",
        free_keys="a region's name; its value is an array of distinct node numbers",
    ),
    Section(
        "[damping]",
        "Rayleigh damping of the shaft elements (not of disks or bearings): C = a M + b K of the shaft.",
        (
            Key("shaft_mass_proportional", "number", "a, the mass-proportional factor", "1/s", 0.0, "nonnegative"),
            Key(
                "shaft_stiffness_proportional",
                "number",
                "b, the stiffness-proportional factor",
                "s",
                0.0,
                "nonnegative",
            ),
        ),
    ),
    Section(
        "[excitation]",
        "What drives the machine in operation ({mod}`twin.fem.excitation`): its 1X unbalance and its broad-band "
        "process forces, and the largest response a simulation may reach. Left out, each is derived from the "
        "machine.",
        (
            Key("unbalance_at", "place", "where the residual unbalance sits", default_text="the heaviest disk"),
            Key(
                "unbalance_me",
                "number",
                "the unbalance",
                "kg m",
                None,
                "nonnegative",
                "balance_grade's permissible unbalance for the rotor's mass and speed (ISO 21940-11)",
            ),
            Key("balance_grade", "number", "the balance quality grade G", "mm/s", BALANCE_GRADE_MM_S, "positive"),
            Key(
                "broadband_at",
                "place",
                "where broad-band process forces act",
                default_text="the immersed region, else the heaviest disk",
            ),
            Key(
                "broadband_asd",
                "number",
                "their amplitude spectral density, white, in x and y",
                "N/√Hz",
                None,
                "nonnegative",
                "3e-4 of the rotor's weight per √Hz",
            ),
            Key(
                "max_response",
                "number",
                "the largest peak-to-peak displacement a simulation may reach",
                "m",
                None,
                "positive",
                "10 times the ISO 20816-1 zone C/D boundary 13 200/√n µm at n rpm",
            ),
        ),
    ),
    Section(
        '[reference_changes."<label>"]',
        "The size of a library effect that benchmarks and demos hide at reference size (`twin demo --hidden "
        "LABEL`, `LABEL@1`), with the keys of `[effects]` (per-mode effects take one value per mode). An effect "
        "without one is hidden at a size derived from the machine ({func}`twin.harness.scenarios.reference_effect`).",
        free_keys='as `[effects."<label>"]` below',
    ),
    Section(
        "[[condition]]",
        "An operating condition the records carry ({mod}`twin.fem.operation`): power, temperature, head...",
        (
            Key("name", "string", "the condition's name (letters, digits and '_'), as the records' variables"),
            Key("units", "string", "its units, as pint reads them (MW, degC, m)"),
            Key("reference", "number", "the value at which the model's coefficients hold, inside the range", "units"),
            Key("range", "array", "[low, high]: the values the machine runs at", "units"),
            Key("description", "string", "one line on it", default=""),
            Key(
                "variation",
                "table",
                "how it varies in a campaign by default, a `[condition.variation]` table with the keys of a "
                "schedule's `[operation.<condition>]` (mean, daily_amplitude, peak_hour, seasonal_amplitude, "
                "seasonal_peak_day, drift_per_year, dispatch_std, dispatch_correlation, follows; "
                "{class}`twin.fem.operation.Variation`); a schedule overrides it",
                default=None,
                default_text="stays at the reference",
            ),
        ),
    ),
    Section(
        "[[law]]",
        "How one model parameter moves with the operating conditions: linearly, "
        "value = nominal + sum of slope x (condition - its reference).",
        (
            Key("parameter", "string", "a parameter of the model (as `twin params` names it)"),
            Key(
                "slopes",
                "table",
                "the slope per unit of each condition, e.g. { power = -1.5e5 }",
                "parameter unit per condition unit",
            ),
            Key(
                "reference",
                "number",
                "the parameter's value at the conditions' references",
                "parameter unit",
                None,
                default_text="the parameter's nominal value",
            ),
            Key("description", "string", "one line on the law", default=""),
        ),
    ),
)

BY_HEADER = {s.header: s for s in SECTIONS}


def section(header: str) -> Section:
    """The section of a model file with this header (``"[model]"``, ``"[[bearing]]"`` ...).

    Examples
    --------
    >>> section("[[bearing]]").key("kxx").unit
    'N/m'
    """
    return BY_HEADER[header]


def _key_row(key: Key) -> str:
    rule = f" ({RULES[key.rule]})" if key.rule else ""
    return f"| `{key.name}` | {KINDS[key.kind]}{rule} | {key.unit} | {key.default_words()} | {key.doc} |"


def _regions_used() -> str:
    """The regions the registered effects act on, each with its effects' keys."""
    from twin.fem.effects import effect_classes

    regions: dict[str, list[str]] = {}
    for key, cls in effect_classes(local=False).items():
        if cls.region is not None:
            regions.setdefault(cls.region, []).append(f"`{key}`")
    return "; ".join(f"`{r}` ({', '.join(keys)})" for r, keys in regions.items())


def _effect_rows(models: Sequence) -> list[str]:
    """One row per library effect a model file can switch on: its table, where it acts, its keys (with units
    when one of ``models`` admits the effect)."""
    from twin.fem.effects import effect_classes, effect_fields

    rows = []
    for key, cls in effect_classes(local=False).items():
        if cls.per_mode:
            continue
        kind = cls.element_kind or cls.element
        table = f'[effects."{key}:<{kind}>"]' if kind else f"[effects.{key}]"
        where = f"a {kind}" if kind else (f"region `{cls.region}`" if cls.region else "the whole machine")
        instance = next((e for m in models for e in cls.instances(m)), None)
        if instance is not None:
            model = next(m for m in models if instance in cls.instances(m))
            keys = [f"`{p.name.split('.', 1)[1]}` [{p.unit}]" for p in instance.parameters(model)]
        else:
            keys = [f"`{n}`" for n, t in effect_fields(cls).items() if t is float]
        rows.append(f"| `{table}` | {where} | {', '.join(keys)} | {cls.explain()} |")
    return rows


def reference_markdown(models: Sequence = ()) -> str:
    """The model-file reference as Markdown: every table, every key with its kind, unit, default and meaning.

    The effects' keys get their units from the first of ``models`` (e.g. the shipped ones) that admits each.

    Examples
    --------
    >>> text = reference_markdown()
    >>> "| `speed_rpm` | a number (>= 0) | rpm | required | running speed |" in text
    True
    """
    out = [
        "# Model file reference",
        "",
        "A model file is TOML, data only: nothing in it is executed. This page is generated from the "
        "declaration the reader uses ({mod}`twin.fem.schema`), so it lists every key the reader accepts; "
        "a key it does not know is an error that names the file, the table, the key and the closest known "
        "one. Units are SI except `speed_rpm`. `models/hydro_unit.toml` and `models/ross_reference.toml` are "
        "full examples; {doc}`../guide/model` explains the model.",
        "",
    ]
    for s in SECTIONS:
        out += [f"## `{s.header}`", "", s.doc, ""]
        if s.free_keys:
            out += [f"Keys: {s.free_keys}.", ""]
        if s.header == "[regions]":
            out += [f"Regions the registered effects act on: {_regions_used()}.", ""]
        if s.keys:
            out += ["| key | value | unit | default | meaning |", "| --- | --- | --- | --- | --- |"]
            out += [_key_row(k) for k in s.keys] + [""]
    out += [
        '## `[effects."<label>"]`',
        "",
        "An effect switched on in the model, with its values (a value left out is zero). The table is named by "
        "the effect's label, quoted when it has a colon, and its keys are the effect's parameter names without "
        "their owner. The effects registered now, plug-ins included:",
        "",
        "| table | acts on | keys | what it is |",
        "| --- | --- | --- | --- |",
        *_effect_rows(models),
        "",
    ]
    return "\n".join(out)
