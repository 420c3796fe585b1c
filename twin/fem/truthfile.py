"""Truth files: the effects that make synthetic "measured" data differ from the model.

A truth file is TOML with one table per effect of :mod:`twin.fem.effects`,
named by its label as ``twin params`` and ``--effect`` name it, its keys the
effect's parameter names without their owner (a value left out is zero)::

    [fsi_per_mode]                 # mode i of the truth: FEM altered by (m_i, c_i)
    added_mass = [1.00e5, 9.83e4, ...]      # kg      FSI.added_mass_<i>
    added_damping = [7.52e7, 1.26e7, ...]   # N s/m   FSI.added_damping_<i>

    [magnetic_pull]
    stiffness = -2.0e8                      # N/m     MAG.stiffness

    ["bearing_change:UGB"]                  # quoted: a TOML key holds no colon otherwise
    stiffness_change = -1.0e8               # N/m     UGB.stiffness_change

    ["shaft_stiffness:18"]                  # a local change outside the library (twin.fem.local)
    change = -0.3                           # relative: element 18 keeps 70% of its bending stiffness

Values outside a parameter's physical bounds (a positive magnetic pull, a
negative added mass) are refused, naming the file, table and key.

The truth is written into the attrs of every file made from it, so tests can
check answers; nothing that plays the twin's role may read it.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

from twin.errors import ModelFileError
from twin.fem.effects import FluidAddedMassPerMode, effect_classes, effect_fields, effect_label, parse_label
from twin.fem.model import RotorModel
from twin.fem.modelfile import check_effect_bounds, effect_elements, read_effect_tables
from twin.fem.tables import Table, read_toml

#: The reference paper's Table 2: per-mode added mass [kg] and added damping [N s/m] of modes 1-15.
PAPER_TABLE2 = FluidAddedMassPerMode(
    added_mass=(
        1.00e5,
        9.83e4,
        7.80e4,
        6.09e4,
        7.00e4,
        5.08e4,
        5.09e4,
        7.05e4,
        3.48e4,
        4.87e4,
        6.67e4,
        7.49e4,
        5.15e4,
        3.07e4,
        5.15e4,
    ),
    added_damping=(
        7.52e7,
        1.26e7,
        9.99e5,
        7.92e6,
        1.01e7,
        1.43e6,
        6.45e6,
        1.65e6,
        2.90e6,
        1.64e7,
        1.20e7,
        1.92e6,
        1.51e8,
        7.32e7,
        1.37e8,
    ),
)
#: The reference paper's noise of its synthetic modal data (its Figure 2): the coefficient of variation of
#: the shape entries, and the pole samples' variances [rad²/s²] of the real and the imaginary part.
PAPER_SHAPE_COV = 0.05
PAPER_POLE_VARIANCE = (1.58, 1.1)


@dataclass(frozen=True)
class Truth:
    """Effects switched on in a truth model, and where they came from."""

    effects: tuple
    source: str = ""

    @property
    def per_mode(self):
        """The per-mode effect, if any (at most one)."""
        found = [e for e in self.effects if e.per_mode]
        return found[0] if found else None

    @property
    def mode_independent(self) -> tuple:
        """The effects that alter the single FEM."""
        return tuple(e for e in self.effects if not e.per_mode)

    def to_json(self) -> str:
        """The truth as JSON, for file attrs: ``{"source": ..., "effects": {key: {field: value}}}``."""
        return json.dumps({"source": self.source, "effects": {effect_label(e): asdict(e) for e in self.effects}})


#: Fields of the truth descriptions in files written before the fields took their parameters' names.
_RENAMED = {
    ("bearing_change", "stiffness"): "stiffness_change",
    ("bearing_change", "damping"): "damping_change",
    ("thrust_tilt", "k_tilt"): "k_tilt_change",
}


def truth_from_json(text: str) -> Truth:
    """The truth a file's ``truth`` attr describes (:meth:`Truth.to_json`'s inverse).

    Library effects and local changes outside the library (:func:`twin.fem.effects.effect_classes`, as a
    scenario such as ``shaft_stiffness:18@0.5`` hides).

    Examples
    --------
    >>> truth_from_json(paper_truth().to_json()) == paper_truth()
    True
    >>> from twin.fem.effects import ShaftStiffnessChange
    >>> truth_from_json(Truth((ShaftStiffnessChange(18, -0.5),)).to_json()).effects
    (ShaftStiffnessChange(index=18, change=-0.5),)
    """
    known = effect_classes()
    try:
        data = json.loads(text)
        effects = []
        for label, fields in data["effects"].items():
            cls = known[parse_label(label).key]
            fields = {_RENAMED.get((cls.key, k), k): v for k, v in fields.items()}
            kinds = effect_fields(cls)
            effects.append(cls(**{k: tuple(v) if kinds.get(k) is tuple else v for k, v in fields.items()}))
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ModelFileError("(truth attr)", "effects", None, f"not a truth description: {exc}") from exc
    return Truth(tuple(effects), str(data.get("source", "")))


def paper_truth() -> Truth:
    """The built-in truth of the hydro unit: the paper's Table 2 per-mode FSI."""
    return Truth((PAPER_TABLE2,), "reference paper, Table 2")


def load_truth(path: str | Path, model: RotorModel) -> Truth:
    """Read and validate a truth file for ``model`` (regions must exist in the model).

    ``path`` may also be ``"paper"`` for :func:`paper_truth`, or ``"none"`` for no hidden effect (the
    model as it is, as ``twin demo --hidden none``).

    Examples
    --------
    >>> t = load_truth("paper", hydro_unit)
    >>> t.per_mode.n_modes
    15
    """
    if str(path) == "paper":
        region = PAPER_TABLE2.region
        if region not in model.regions:
            raise ModelFileError(
                "paper",
                "(truth)",
                None,
                f"the paper's truth is per-mode FSI on the region "
                f"'{region}', which model '{model.name}' does not declare: give 'none' or a truth "
                "file of effects this model can take",
            )
        return paper_truth()
    if str(path) == "none":
        return Truth((), "none (the model as it is)")
    path = Path(path)
    return truth_from_tables(read_toml(path), model, str(path))


def truth_from_tables(data: dict, model: RotorModel, path: str, where: str = "(top level)", prefix: str = "") -> Truth:
    """A truth from the parsed tables of a truth file (or of a table holding them, as a schedule's
    ``[change.truth]``: ``where`` names it, ``prefix`` is its dotted name): library effects and local
    changes, validated for ``model``; errors name ``path``, the table and the key.

    Examples
    --------
    >>> unit = hydro_unit
    >>> truth_from_tables({"shaft_stiffness:18": {"change": -0.3}}, unit, "schedule.toml").effects
    (ShaftStiffnessChange(index=18, change=-0.3),)
    """
    elements = effect_elements(model.bearings, model.thrusts)
    tables: list[str] = []
    effects = read_effect_tables(
        Table(path, where, data),
        model.regions,
        prefix=prefix,
        elements=elements,
        tables_read=tables,
        local_allowed=True,
    )
    if not effects:
        raise ModelFileError(path, where, None, "a truth needs at least one effect table")
    if sum(e.per_mode for e in effects) > 1:
        raise ModelFileError(path, where, None, "at most one per-mode effect")
    check_effect_bounds(effects, model, path, tables)
    return Truth(tuple(effects), path)
