"""A rotor saved by ROSS read as a twin model: the bridge from ROSS's ``Rotor.save`` files, without ROSS.

ROSS (``ross-rotordynamics``) saves a rotor as TOML: one table per element,
named ``<Class>_<tag>`` (``ShaftElement_...``, ``DiskElement_...``,
``BearingElement_...``, ``SealElement_...``), with the element's own
parameters. :func:`read_ross` turns such a file into the contents of a twin
model file (the layout :mod:`twin.fem.schema` declares), :func:`ross_model_text`
writes them as a model file to extend (sensors, regions, excitation, operating
conditions), and :func:`load_ross` builds the model. Where ROSS is installed,
:func:`from_ross` takes a ``ross.Rotor`` itself (it saves it and reads the file:
one path for both).

What maps, and how:

* shaft elements (uniform sections) become ``[[shaft]]`` sections, consecutive
  elements of one section and material joined; their shear, rotary-inertia and
  gyroscopic switches and their proportional damping (``alpha``, ``beta``) are
  the model's (twin holds one of each for the whole shaft);
* disks become ``[[disk]]``; bearings and seals become ``[[bearing]]``, their
  coefficients taken at the running speed: ROSS gives them per ``frequency``
  [rad/s], and twin interpolates linearly between the two frequencies around
  the speed;
* names are ROSS's tags with anything that is not a letter, digit, ``_`` or
  ``-`` replaced by ``_``;
* one proximeter pair (``[[sensor]]``) at each bearing (not at seals), named
  after it, unless ``sensors=False``.

What twin's lateral model cannot hold is refused with the element's table and
key: tapered or layered shaft elements, axial force or torque, bearing mass
coefficients, a bearing linked to another node (a support with its own mass),
point masses, active magnetic bearings, speeds outside a bearing's frequency
range. Axial and torsional coefficients (``kzz``, ``czz``) are left out: the
model is lateral (4 DOF per node).
"""

from __future__ import annotations

import logging
import math
import re
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from twin.errors import ModelFileError
from twin.fem.elements import BEARING_COEFFICIENTS
from twin.fem.tables import Table, read_toml

log = logging.getLogger(__name__)

#: Table keys of an active magnetic bearing's controller: twin's bearings are passive coefficients.
AMB_KEYS = ("kp_pid", "kd_pid", "ki_pid", "k_amp", "k_sense", "i0", "g0")
#: Keys of a bearing's mass coefficients, which twin's bearings do not have.
MASS_KEYS = ("mxx", "mxy", "myx", "myy")
#: Relative tolerance within which two values of a section (diameters, damping factors) count as equal.
SAME = 1e-12


def _name(tag: str) -> str:
    """A ROSS tag as a twin name (letters, digits, ``_``, ``-``; a letter first)."""
    name = re.sub(r"[^A-Za-z0-9_\-]", "_", tag.strip())
    return name if name[:1].isalpha() else f"e_{name}"


def _close(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=SAME, abs_tol=0.0)


class _Element(Table):
    """One element table of a ROSS file (:class:`~twin.fem.tables.Table`: errors name the file and the table)."""

    def __init__(self, path: str, key: str, data: Mapping[str, Any]) -> None:
        super().__init__(path, f'["{key}"]', data)
        self.key = key
        self.kind = key.split("_", 1)[0]
        self.tag = str(data.get("tag", key.split("_", 1)[-1]))

    def at_speed(self, key: str, omega: float) -> float:
        """A bearing coefficient at the speed ``omega`` [rad/s]: interpolated over ``frequency`` when it varies."""
        values = self.data.get(key, [0.0])
        values = np.atleast_1d(np.asarray(values, dtype=float))
        if not np.all(np.isfinite(values)):
            raise self.error(key, "expected finite numbers")
        if values.size == 1:
            return float(values[0])
        freq = np.asarray(self.data.get("frequency", []), dtype=float)
        if freq.shape != values.shape:
            raise self.error(key, f"{values.size} values but {freq.size} frequencies")
        order = np.argsort(freq)
        freq, values = freq[order], values[order]
        if not freq[0] * (1 - 1e-9) <= omega <= freq[-1] * (1 + 1e-9):
            raise self.error(
                "frequency",
                f"the coefficients are given from {freq[0]:.6g} to {freq[-1]:.6g} rad/s; the running speed "
                f"{omega:.6g} rad/s ({omega * 30 / math.pi:.6g} rpm) is outside, and twin does not extrapolate them",
            )
        return float(np.interp(omega, freq, values))


def read_ross(path: str | Path, speed_rpm: float, *, name: str | None = None, sensors: bool = True) -> dict[str, Any]:
    """The contents of a twin model file for the rotor a ROSS ``Rotor.save`` file describes, at ``speed_rpm``.

    Parameters
    ----------
    path : str or Path
        The ROSS file (TOML).
    speed_rpm : float
        The running speed [rpm]: the model's, and where speed-dependent bearing coefficients are taken.
    name : str, optional
        The model's name (default: the file's name without its suffix).
    sensors : bool
        A proximeter pair at each bearing.

    Returns
    -------
    dict
        The model file's tables (:func:`twin.fem.modelfile.model_from_dict` builds the model,
        :func:`ross_model_text` writes it).

    Raises
    ------
    ModelFileError
        What twin's lateral model cannot hold, naming the file, the element's table and the key.

    Examples
    --------
    >>> from pathlib import Path
    >>> data = read_ross(Path("tests/data/ross/rotor_example.toml"), 3000.0)
    >>> len(data["shaft"]), [b["name"] for b in data["bearing"]], data["bearing"][0]["kyy"]
    (1, ['Bearing_0', 'Bearing_1'], 800000.0)
    """
    path = Path(path)
    raw = read_toml(path)
    if not isinstance(raw.get("ross_version"), str):
        raise ModelFileError(str(path), "(top level)", "ross_version", "not a file saved by ROSS's Rotor.save")
    if not (isinstance(speed_rpm, (int, float)) and math.isfinite(speed_rpm) and speed_rpm >= 0):
        raise ModelFileError(
            str(path), "(top level)", None, f"the speed must be a non-negative number of rpm, got {speed_rpm!r}"
        )
    omega = speed_rpm * math.pi / 30.0
    elements = [_Element(str(path), k, v) for k, v in raw.items() if isinstance(v, dict) and k != "parameters"]
    known = {"ShaftElement", "DiskElement"}
    for e in elements:
        if e.kind == "PointMass":
            raise e.error(None, "a point mass (a support's mass, on a node outside the shaft): twin has none")
        if e.kind not in known and "kxx" not in e.data:
            raise e.error(None, f"an element of kind {e.kind} twin does not read")
    shaft = [e for e in elements if e.kind == "ShaftElement"]
    if not shaft:
        raise ModelFileError(str(path), "(top level)", None, "no ShaftElement tables: not a rotor")
    data: dict[str, Any] = {"model": {}, "materials": {}, "shaft": [], "disk": [], "bearing": []}
    _shaft(shaft, data)
    n_nodes = data["shaft"][-1]["nodes"][1] + 1
    names: set[str] = set()
    for e in (e for e in elements if e.kind == "DiskElement"):
        node = _node(e, n_nodes)
        data["disk"].append(
            {"name": _unique(e, names), "node": node, "mass": e.number("m"), "Id": e.number("Id"), "Ip": e.number("Ip")}
        )
    for e in (e for e in elements if e.kind not in known):
        data["bearing"].append(_bearing(e, n_nodes, omega, names))
    data["model"] = {
        "name": name or _name(path.stem),
        "speed_rpm": float(speed_rpm),
        "description": f"read from {path.name} (ROSS {raw['ross_version']}) at {speed_rpm:g} rpm",
        **data.pop("flags"),
    }
    if sensors:
        data["sensor"] = [
            {"name": b["name"], "node": b["node"], "location": f"at {b['name']}"}
            for b, e in zip(data["bearing"], (e for e in elements if e.kind not in known))
            if e.kind != "SealElement"
        ]
    if not data["disk"]:
        del data["disk"]
    if not data["bearing"]:
        del data["bearing"]
    return data


def _unique(e: _Element, names: set[str]) -> str:
    name = _name(e.tag)
    if name in names:
        raise e.error("tag", f"two elements are called '{name}' once written as twin names: give them distinct tags")
    names.add(name)
    return name


def _node(e: _Element, n_nodes: int) -> int:
    n = e.data.get("n")
    if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n < n_nodes:
        raise e.error("n", f"expected a node of the shaft (0 to {n_nodes - 1}), got {n!r}")
    return n


def _bearing(e: _Element, n_nodes: int, omega: float, names: set[str]) -> dict[str, Any]:
    if any(k in e.data for k in AMB_KEYS):
        raise e.error(None, "an active magnetic bearing (a controller): twin's bearings are passive coefficients")
    if e.data.get("n_link") is not None:
        raise e.error(
            "n_link",
            "a bearing linked to another node (a support with its own mass): twin's bearings "
            "act between the shaft and the ground",
        )
    for key in MASS_KEYS:
        if any(v != 0 for v in np.atleast_1d(e.data.get(key, 0))):
            raise e.error(key, "a bearing mass coefficient: twin's bearings have stiffness and damping only")
    node = _node(e, n_nodes)
    out: dict[str, Any] = {"name": _unique(e, names), "node": node}
    out.update({key: e.at_speed(key, omega) for key in BEARING_COEFFICIENTS})
    return out


def _shaft(elements: list[_Element], data: dict[str, Any]) -> None:
    """``[[shaft]]`` sections, materials and the shaft's switches and damping from ROSS's shaft elements."""
    by_position: dict[int, _Element] = {}
    for e in elements:
        n = e.data.get("n")
        if isinstance(n, bool) or not isinstance(n, int) or n < 0:
            raise e.error("n", f"expected the element's position (0, 1, ...), got {n!r}")
        if n in by_position:
            raise e.error(
                "n",
                f"a second shaft element at position {n} (a layer, such as a hub or a sleeve over "
                f"the shaft, with {by_position[n].key}): twin's shaft has one element per position",
            )
        by_position[n] = e
    positions = sorted(by_position)
    if positions != list(range(len(positions))):
        gap = next(i for i, p in enumerate(positions) if p != i)
        raise ModelFileError(elements[0].path, "(shaft)", None, f"no shaft element at position {gap}")
    switches: dict[str, set] = {"shear_effects": set(), "rotary_inertia": set(), "gyroscopic": set()}
    damping: dict[str, set] = {"alpha": set(), "beta": set()}
    current: dict[str, Any] | None = None
    for n in positions:
        e = by_position[n]
        od, id_ = e.number("odl"), e.number("idl")
        if not (_close(od, e.number("odr")) and _close(id_, e.number("idr"))):
            raise e.error("odr", "a tapered element (its diameters differ at its ends): twin's elements are uniform")
        for key in ("axial_force", "torque"):
            if e.number(key, 0.0) != 0.0:
                raise e.error(key, f"a shaft {key.replace('_', ' ')}: twin's elements do not model it")
        if str(e.data.get("shear_method_calc", "cowper")) != "cowper":
            raise e.error("shear_method_calc", "twin's shear coefficient is Cowper's: save the rotor with 'cowper'")
        for key in switches:
            switches[key].add(bool(e.data.get(key, True)))
        for key in damping:
            damping[key].add(e.number(key, 0.0))
        material = _material(e, data["materials"])
        length = e.number("L")
        same = (
            current is not None
            and current["material"] == material
            and _close(current["outer_diameter"], od)
            and _close(current["inner_diameter"], id_)
        )
        if same:
            current["nodes"][1] = n + 1
            current["element_lengths"].append(length)
        else:
            current = {
                "nodes": [n, n + 1],
                "material": material,
                "outer_diameter": od,
                "inner_diameter": id_,
                "element_lengths": [length],
            }
            data["shaft"].append(current)
    for key, values in {**switches, **damping}.items():
        if len(values) > 1:
            raise ModelFileError(
                elements[0].path, "(shaft)", key, f"the shaft elements differ in '{key}': twin holds one for the shaft"
            )
    for section in data["shaft"]:
        lengths = section["element_lengths"]
        if all(_close(v, lengths[0]) for v in lengths):
            section["length"] = float(sum(lengths))
            del section["element_lengths"]
    data["flags"] = {
        "shear_deformation": switches["shear_effects"].pop(),
        "rotary_inertia": switches["rotary_inertia"].pop(),
        "gyroscopic": switches["gyroscopic"].pop(),
    }
    alpha, beta = damping["alpha"].pop(), damping["beta"].pop()
    if alpha or beta:
        data["damping"] = {"shaft_mass_proportional": alpha, "shaft_stiffness_proportional": beta}


def _material(e: _Element, materials: dict[str, dict[str, float]]) -> str:
    m = e.data.get("material")
    if not isinstance(m, dict):
        raise e.error("material", "expected the element's material table")
    mat = _Element(e.path, f"{e.key}.material", m)
    name = _name(str(m.get("name", "material")))
    props = {"E": mat.number("E"), "G": mat.number("G_s"), "rho": mat.number("rho")}
    if name in materials and materials[name] != props:
        raise mat.error("name", f"two materials are called '{name}' with different properties")
    materials[name] = props
    return name


def load_ross(path: str | Path, speed_rpm: float, *, name: str | None = None, sensors: bool = True):
    """The twin model of a ROSS ``Rotor.save`` file at ``speed_rpm`` (:func:`read_ross`).

    Examples
    --------
    >>> from twin.fem import load_ross
    >>> m = load_ross("tests/data/ross/rotor_example.toml", 3000.0)
    >>> m.n_nodes, [b.name for b in m.bearings], m.channels
    (7, ['Bearing_0', 'Bearing_1'], ['Bearing_0_x', 'Bearing_0_y', 'Bearing_1_x', 'Bearing_1_y'])
    """
    from twin.fem.modelfile import model_from_dict

    return model_from_dict(read_ross(path, speed_rpm, name=name, sensors=sensors), source=str(path))


def from_ross(rotor, speed_rpm: float, *, name: str | None = None, sensors: bool = True):
    """The twin model of a ``ross.Rotor`` at ``speed_rpm``: the rotor saved by ROSS, then read (:func:`read_ross`).

    Needs ROSS (``pip install twin[ross]``) only to have the rotor; the file is read without it.
    """
    if not hasattr(rotor, "save"):
        raise TypeError(f"expected a ross.Rotor (it has a save method), got {type(rotor).__name__}")
    with tempfile.TemporaryDirectory(prefix="twin-ross-") as folder:
        path = Path(folder) / f"{name or 'rotor'}.toml"
        rotor.save(path)
        return load_ross(path, speed_rpm, name=name or "rotor", sensors=sensors)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {value!r}")


def ross_model_text(data: Mapping[str, Any], source: str = "") -> str:
    """A model file's text for the tables :func:`read_ross` gives, with a header comment naming ``source``.

    Examples
    --------
    >>> text = ross_model_text(read_ross("tests/data/ross/rotor_example.toml", 3000.0), "rotor_example.toml")
    >>> print(text.splitlines()[3])
    [model]
    """
    lines = [
        f"# A twin model file read from the ROSS rotor {source} (twin from-ross).".replace("  ", " "),
        "# Add what ROSS does not hold: regions, the excitation, operating conditions (see the model-file reference).",
        "",
    ]
    for table in ("model", "damping"):
        if table in data:
            lines += [f"[{table}]", *(f"{k} = {_toml_value(v)}" for k, v in data[table].items()), ""]
    for mat, props in data.get("materials", {}).items():
        lines += [f"[materials.{mat}]", *(f"{k} = {_toml_value(v)}" for k, v in props.items()), ""]
    for array in ("shaft", "disk", "bearing", "sensor"):
        for item in data.get(array, []):
            lines += [f"[[{array}]]", *(f"{k} = {_toml_value(v)}" for k, v in item.items()), ""]
    return "\n".join(lines)
