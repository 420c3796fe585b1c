"""Read and validate TOML model files into a :class:`~twin.fem.model.RotorModel`.

A model file is data only: nothing in it is executed. Every problem is
reported as a :class:`~twin.errors.ModelFileError` naming the file, the table
and the key. The tables and keys, with their units, defaults and rules, are
declared in :mod:`twin.fem.schema` (the docs' model-file reference is generated
from it); ``models/hydro_unit.toml`` is a full example.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from twin.errors import ModelError, ModelFileError
from twin.fem.effects import effect_classes, effect_fields, effect_label, parse_label
from twin.fem.elements import (
    BEARING_COEFFICIENTS,
    Bearing,
    Disk,
    Material,
    ShaftElement,
    ThrustBearing,
)
from twin.fem.excitation import Excitation
from twin.fem.model import RotorModel, Sensor
from twin.fem.operation import read_operation
from twin.fem.schema import section
from twin.fem.tables import MISSING, Table, array_of_tables, label_table, read_toml

MODELS_DIR = Path(__file__).resolve().parent.parent / "models"


def shipped_model(name: str = "hydro_unit") -> Path:
    """The path of a model file shipped with twin (``hydro_unit``, ``ross_reference``), wherever twin is installed.

    Examples
    --------
    >>> from twin import shipped_model
    >>> shipped_model().name, shipped_model("ross_reference").exists()
    ('hydro_unit.toml', True)
    """
    path = MODELS_DIR / f"{name}.toml"
    if not path.is_file():
        known = ", ".join(sorted(p.stem for p in MODELS_DIR.glob("*.toml")))
        raise ModelFileError(str(path), "(file)", None, f"no shipped model '{name}' (shipped: {known})")
    return path


def load_model(path: str | Path) -> RotorModel:
    """Read a TOML model file and build the rotor model.

    Parameters
    ----------
    path : str or Path
        The model file, or the name of a shipped model (``"hydro_unit"``,
        :func:`shipped_model`) when no such file exists.

    Returns
    -------
    RotorModel

    Raises
    ------
    ModelFileError
        The file is missing, not TOML, or a table/key is wrong; the message
        names the file, the table and the key.

    Examples
    --------
    >>> from twin import load_model
    >>> m = load_model(shipped_model("hydro_unit"))
    >>> m.n_nodes, m.n_dof, m.channels[:2]
    (29, 116, ['SEAL_x', 'SEAL_y'])
    """
    if not Path(path).exists() and re.fullmatch(r"[A-Za-z_]\w*", str(path)) and (MODELS_DIR / f"{path}.toml").is_file():
        path = MODELS_DIR / f"{path}.toml"
    return model_from_dict(read_toml(path), source=str(path))


def model_from_dict(data: Mapping[str, Any], source: str = "<dict>") -> RotorModel:
    """Build a model from the parsed contents of a model file (see :func:`load_model`).

    Examples
    --------
    >>> d = {"model": {"name": "m", "speed_rpm": 0.0},
    ...      "materials": {"steel": {"E": 2.1e11, "G": 8.1e10, "rho": 7800.0}},
    ...      "shaft": [{"nodes": [0, 2], "length": 1.0, "outer_diameter": 0.1,
    ...                 "inner_diameter": 0.0, "material": "steel"}]}
    >>> model_from_dict(d).n_nodes
    3
    """
    top = Table(source, "(top level)", data)
    head = Table(source, "[model]", top._get("model", MISSING), section("[model]"))
    name = head.read("name")
    speed_rpm = head.read("speed_rpm")
    description = head.read("description")
    flags = {k: head.read(k) for k in ("shear_deformation", "rotary_inertia", "gyroscopic")}
    head.finish()

    materials = _read_materials(top)
    shaft = _read_shaft(top, materials, flags)
    n_nodes = len(shaft) + 1

    names: dict[str, str] = {}

    def unique(table: Table, kind: str) -> str:
        nm = table.read("name")
        label_table(table, nm)
        if nm in names:
            raise table.error("name", f"'{nm}' is already the name of a {names[nm]}")
        names[nm] = kind
        return nm

    disks = []
    for t in array_of_tables(top, "disk", section=section("[[disk]]")):
        nm = unique(t, "disk")
        disks.append(Disk(nm, t.read("node", n_nodes), t.read("mass"), t.read("Id"), t.read("Ip")))
        t.finish()
    bearings = []
    for t in array_of_tables(top, "bearing", section=section("[[bearing]]")):
        nm = unique(t, "bearing")
        node = t.read("node", n_nodes)
        # a guide bearing holds the shaft: positive direct stiffness, non-negative direct damping (the schema's rules)
        bearings.append(Bearing(nm, node, {k: t.read(k) for k in BEARING_COEFFICIENTS}))
        t.finish()
    thrusts = []
    for t in array_of_tables(top, "thrust", section=section("[[thrust]]")):
        nm = unique(t, "thrust bearing")
        thrusts.append(ThrustBearing(nm, t.read("node", n_nodes), t.read("k_tilt"), t.read("c_tilt")))
        t.finish()
    sensors = _read_sensors(top, n_nodes)
    regions = _read_regions(top, n_nodes)
    rayleigh = _read_damping(top)
    excitation = _read_excitation(top, n_nodes, disks, regions)
    tables: list[str] = []
    effects = _read_effects(top, regions, effect_elements(bearings, thrusts), tables)
    reference_tables: list[str] = []
    reference_changes = read_effect_tables(
        Table(top.path, "[reference_changes]", top._get("reference_changes", {})),
        regions,
        prefix="reference_changes.",
        elements=effect_elements(bearings, thrusts),
        tables_read=reference_tables,
    )
    model = RotorModel(
        name=name,
        shaft=shaft,
        disks=disks,
        bearings=bearings,
        thrusts=thrusts,
        sensors=sensors,
        speed_rpm=speed_rpm,
        regions=regions,
        effects=(),
        rayleigh=rayleigh,
        source=source,
        description=description,
        excitation=excitation,
    )
    check_effect_bounds(effects, model, source, tables)
    check_effect_bounds(reference_changes, model, source, reference_tables)
    model = dataclasses.replace(model, reference_changes=tuple(reference_changes))
    model = model.with_effects(*effects)
    operation = read_operation(top, model)
    top.finish()
    return dataclasses.replace(model, operation=operation) if operation is not None else model


def check_effect_bounds(effects: Sequence, model, path: str, tables: Sequence[str]) -> None:
    """Refuse effect values outside their parameters' physical bounds, naming the file, table and key.

    A magnetic pull is not positive, added mass and damping are not negative, a
    bearing change leaves the bearing's coefficient non-negative
    (:attr:`twin.fem.parameters.Parameter.bounds`, as ``twin params`` lists them).
    """
    for effect, table in zip(effects, tables):
        try:
            parameters = effect.parameters(model)
        except ModelError as exc:  # a local change's element the model lacks
            raise ModelFileError(path, table, None, str(exc)) from None
        for p in parameters:
            if p.within(p.nominal):
                continue
            key = p.name.split(".", 1)[1]
            if effect.per_mode:  # FSI.added_mass_3: entry 3 of added_mass
                key = key.rsplit("_", 1)[0]
            raise ModelFileError(
                path,
                table,
                key,
                f"{p.name} = {p.nominal:.4g} is outside its physical bounds ({p.bounds_text()}: {p.description})",
            )


def _read_materials(top: Table) -> dict[str, Material]:
    tables = Table(top.path, "[materials]", top._get("materials", MISSING))
    out = {}
    for key in tables.data:
        tables.used.add(key)
        t = Table(top.path, f"[materials.{key}]", tables.data[key], section("[materials.<name>]"))
        E = t.read("E")
        rho = t.read("rho")
        if t.has("G") == t.has("poisson"):
            raise t.error("G", "give exactly one of 'G' (shear modulus) and 'poisson'")
        if t.has("G"):
            G = t.read("G")
        else:
            nu = t.read("poisson")
            if not -1.0 < nu < 0.5:
                raise t.error("poisson", f"must lie in (-1, 0.5), got {nu:g}")
            G = E / (2 * (1 + nu))
        t.finish()
        out[key] = Material(key, E, G, rho)
    if not out:
        raise tables.error(None, "at least one material is needed")
    return out


def _read_shaft(top: Table, materials: dict[str, Material], flags: dict[str, bool]) -> list[ShaftElement]:
    sections = []
    for t in array_of_tables(top, "shaft", required=True, section=section("[[shaft]]")):
        nodes = t.read("nodes")
        if len(nodes) != 2 or any(isinstance(n, bool) or not isinstance(n, int) or n < 0 for n in nodes):
            raise t.error("nodes", f"expected [first, last] node numbers, got {nodes!r}")
        first, last = nodes
        if last <= first:
            raise t.error("nodes", f"last node must come after the first, got {nodes!r}")
        n_el = last - first
        if t.has("length") == t.has("element_lengths"):
            raise t.error("length", "give exactly one of 'length' (split equally) and 'element_lengths'")
        if t.has("length"):
            lengths = [t.read("length") / n_el] * n_el
        else:
            lengths = t.read("element_lengths")
            if len(lengths) != n_el:
                raise t.error("element_lengths", f"nodes {nodes} span {n_el} elements, got {len(lengths)} lengths")
            for v in lengths:
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not v > 0:
                    raise t.error("element_lengths", f"every length must be a positive number, got {v!r}")
        od = t.read("outer_diameter")
        id_ = t.read("inner_diameter")
        if id_ >= od:
            raise t.error("inner_diameter", f"must be smaller than outer_diameter ({od:g} m), got {id_:g}")
        mat = t.read("material")
        if mat not in materials:
            raise t.error("material", f"unknown material '{mat}' (defined: {', '.join(sorted(materials))})")
        t.finish()
        sections.append(
            (
                first,
                last,
                t,
                [
                    ShaftElement(
                        first + i,
                        float(L),
                        od,
                        id_,
                        materials[mat],
                        flags["shear_deformation"],
                        flags["rotary_inertia"],
                        flags["gyroscopic"],
                    )
                    for i, L in enumerate(lengths)
                ],
            )
        )
    sections.sort(key=lambda s: s[0])
    expected = 0
    elements: list[ShaftElement] = []
    for first, last, t, els in sections:
        if first < expected:
            raise t.error("nodes", f"section {[first, last]} overlaps the section ending at node {expected}")
        if first > expected:
            raise t.error("nodes", f"gap: no shaft element joins nodes {expected} and {first}")
        elements += els
        expected = last
    return elements


def _read_sensors(top: Table, n_nodes: int) -> list[Sensor]:
    sensors: list[Sensor] = []
    for t in array_of_tables(top, "sensor", section=section("[[sensor]]")):
        nm = t.read("name")
        label_table(t, nm)
        node = t.read("node", n_nodes)
        location = t.read("location")
        directions = t.read("directions")
        if not directions or any(d not in ("x", "y") for d in directions) or len(set(directions)) != len(directions):
            raise t.error("directions", f"expected distinct 'x' and/or 'y', got {directions!r}")
        t.finish()
        for d in directions:
            channel = f"{nm}_{d}"
            if channel in {s.name for s in sensors}:
                raise t.error("name", f"channel '{channel}' is defined twice")
            sensors.append(Sensor(channel, node, d, location))
    return sensors


def _read_regions(top: Table, n_nodes: int) -> dict[str, tuple[int, ...]]:
    t = Table(top.path, "[regions]", top._get("regions", {}))
    out = {}
    for key in list(t.data):
        nodes = t.node_list(key, n_nodes)
        if not nodes or len(set(nodes)) != len(nodes):
            raise t.error(key, f"expected a non-empty list of distinct nodes, got {nodes!r}")
        out[key] = tuple(nodes)
    return out


def _read_location(t: Table, key: str, n_nodes: int, places: dict[str, int]) -> int | None:
    """A node given by number, or by the name of a disk or a region (its first node); None when not given."""
    t.section.key(key)  # a declared place
    if not t.has(key):
        return None
    value = t._get(key, None)
    if isinstance(value, str):
        if value not in places:
            known = ", ".join(sorted(places)) or "none"
            raise t.error(key, f"'{value}' names no disk or region of the model (disks and regions: {known})")
        return places[value]
    return t.node(key, n_nodes)


def _read_excitation(top: Table, n_nodes: int, disks, regions) -> Excitation | None:
    if not top.has("excitation"):
        return None
    t = Table(top.path, "[excitation]", top._get("excitation", {}), section("[excitation]"))
    places = {**{k: v[0] for k, v in regions.items()}, **{d.name: d.node for d in disks}}
    out = Excitation(
        unbalance_node=_read_location(t, "unbalance_at", n_nodes, places),
        unbalance_me=t.read("unbalance_me"),
        balance_grade=t.read("balance_grade"),
        broadband_node=_read_location(t, "broadband_at", n_nodes, places),
        broadband_asd=t.read("broadband_asd"),
        max_response=t.read("max_response"),
    )
    t.finish()
    return out


def _read_damping(top: Table) -> tuple[float, float]:
    t = Table(top.path, "[damping]", top._get("damping", {}), section("[damping]"))
    a = t.read("shaft_mass_proportional")
    b = t.read("shaft_stiffness_proportional")
    t.finish()
    return (a, b)


def effect_elements(bearings, thrusts) -> dict[str, list[str]]:
    """Names of the elements a model file's effects can act on, by element kind (``bearing``, ``thrust``)."""
    return {"bearing": [b.name for b in bearings], "thrust": [t.name for t in thrusts]}


def _read_effects(
    top: Table, regions: Mapping[str, tuple[int, ...]], elements: Mapping[str, Sequence[str]], tables_read: list[str]
) -> list:
    tables = Table(top.path, "[effects]", top._get("effects", {}))
    return read_effect_tables(
        tables, regions, prefix="effects.", per_mode_allowed=False, elements=elements, tables_read=tables_read
    )


def read_effect_tables(
    tables: Table,
    regions: Mapping[str, tuple[int, ...]],
    prefix: str = "",
    per_mode_allowed: bool = True,
    elements: Mapping[str, Sequence[str]] | None = None,
    tables_read: list[str] | None = None,
    local_allowed: bool = False,
) -> list:
    """Effects from tables keyed by effect label (``[prefix + label]``), validated against the registered
    effects (:func:`twin.fem.effects.effect_classes`).

    A table is named as ``twin params`` and ``--effect`` name the effect: ``[magnetic_pull]``, or, for an
    element effect, ``["bearing_change:UGB"]`` (quoted: TOML keys hold no colon otherwise; the older
    ``[bearing_change]`` with ``bearing = "UGB"`` is read too). Its keys are the effect's parameter names
    without their owner (``stiffness`` for ``MAG.stiffness``, ``stiffness_change`` for
    ``UGB.stiffness_change``); a value left out is zero (no change). ``elements`` maps ``"bearing"`` and
    ``"thrust"`` to the model's element names, against which element effects are checked.
    ``tables_read``, if given, gets each effect's table name, for the messages of later checks.
    With ``local_allowed`` (truth files), local changes outside the library are read too
    (``["shaft_stiffness:18"]``, ``["disk_mass:generator"]`` with
    ``change``, the relative change); their element is named in the table's name and checked against the
    model by :func:`check_effect_bounds`.
    """
    known = effect_classes(local=None if local_allowed else False)
    out = []
    for key in tables.data:
        tables.used.add(key)
        base, element = parse_label(key)
        element = element or ""
        if base not in known:
            close = difflib.get_close_matches(base, known, n=1)
            hint = f"; did you mean '{close[0]}'?" if close else f"; known: {', '.join(known)}"
            raise tables.error(key, f"unknown effect{hint}")
        cls = known[base]
        if cls.local and not element:
            raise tables.error(key, f"a local change names its element: ['{base}:<{cls.element}>']")
        t = Table(tables.path, f"[{prefix}{key}]" if ":" not in key else f'[{prefix}"{key}"]', tables.data[key])
        if element and cls.element is None:
            raise t.error(
                None, f"effect '{base}' acts on a region, not on a named element: call the table [{prefix}{base}]"
            )
        if cls.per_mode and not per_mode_allowed:
            raise t.error(None, "a per-mode effect is not a single FEM; it belongs in a truth file")
        if cls.region is not None and cls.region not in regions:
            raise t.error(None, f"effect '{key}' acts on region '{cls.region}', which [regions] does not declare")
        values = {}
        defaults = {fd.name: fd.default for fd in dataclasses.fields(cls)}
        for name, kind in effect_fields(cls).items():
            if kind is int:  # a shaft element's index, from the table's name
                try:
                    values[name] = int(element)
                except ValueError:
                    raise t.error(None, f"'{element}' is not a shaft element's number") from None
            elif kind is str:
                if element and name in t.data and t.data[name] != element:
                    raise t.error(name, f"{t.data[name]!r} contradicts the table's name, which says {element!r}")
                values[name] = element if element else t.string(name)
                t.used.add(name)
                kind = cls.element_kind or cls.element
                names = elements.get(kind) if elements is not None else None
                if names is not None and values[name] not in names:
                    raise t.error(
                        name,
                        f"no {kind} named {values[name]!r} in the model "
                        f"(its {kind}s: {', '.join(map(repr, names)) or 'none'})",
                    )
            elif kind is tuple:
                items = t.array(name)
                for v in items:
                    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                        raise t.error(name, f"expected an array of numbers, got {v!r} in it")
                values[name] = tuple(float(v) for v in items)
            else:
                values[name] = t.number(name, defaults[name] if defaults[name] is not dataclasses.MISSING else MISSING)
        t.finish()
        try:
            effect = cls(**values)
        except ValueError as exc:
            raise t.error(None, str(exc)) from None
        if any(effect_label(e) == effect_label(effect) for e in out):
            raise t.error(None, f"a second table for the effect '{effect_label(effect)}'")
        out.append(effect)
        if tables_read is not None:
            tables_read.append(t.where)
    return out
