"""Local changes of one disk: its mass, or its moments of inertia (a repair, a balancing mass, a rewound pole).

Like :mod:`twin.fem.effects.shaft`, each is one relative parameter ``δ`` of
the disk's own value, outside the effects library: the localisation scan's
hypotheses (:func:`twin.loop.locate.locate`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from twin.fem.effects.base import RELATIVE_BOUNDS, RelativeChange, model_element
from twin.fem.effects.registry import register
from twin.fem.elements import node_dofs
from twin.fem.parameters import Parameter, Term


def _disk_value(model, disk, key: str) -> float:
    return float(model.values.get(f"{disk.name}.{key}", getattr(disk, key)))


@dataclass(frozen=True)
class _DiskChange(RelativeChange):
    """A relative change of one of a disk's values (its ``what``)."""

    element: ClassVar[str | None] = "disk"
    what: ClassVar[str] = ""
    disk: str = ""
    change: float = 0.0  # relative

    def where(self, model) -> str:
        """The place in words."""
        d = model_element(model, "disk", self.disk)
        return f"{self.what} of disk {d.name} (node {d.node}, z = {model.node_z[d.node]:.2f} m)"


@register
@dataclass(frozen=True)
class DiskMassChange(_DiskChange):
    """A relative change of one disk's mass (added or lost mass at a node).

    Examples
    --------
    >>> model = hydro_unit
    >>> heavier = model.with_effects(DiskMassChange("generator", 0.1))
    >>> float(np.trace(heavier.matrices()["M"] - model.matrices()["M"])) / 2  # kg on x and on y
    60000.0
    """

    key: ClassVar[str] = "disk_mass"
    explanation: ClassVar[str] = "one disk is heavier or lighter than modelled"
    what: ClassVar[str] = "the mass"

    def parameters(self, model) -> list[Parameter]:
        """``<disk>.mass_change`` on the disk's x and y."""
        d = model_element(model, "disk", self.disk)
        x, y = node_dofs(d.node)[:2]
        m = _disk_value(model, d, "m")
        return [
            Parameter(
                f"{d.name}.mass_change",
                self.change,
                "1",
                (Term("M", (x, y), m * np.eye(2)),),
                f"relative mass change of disk {d.name} (node {d.node})",
                bounds=RELATIVE_BOUNDS,
            )
        ]


@register
@dataclass(frozen=True)
class DiskInertiaChange(_DiskChange):
    """A relative change of one disk's moments of inertia, diametral and polar alike.

    Examples
    --------
    >>> model = hydro_unit
    >>> [p.name for p in DiskInertiaChange("runner", 0.2).parameters(model)]
    ['runner.inertia_change']
    """

    key: ClassVar[str] = "disk_inertia"
    explanation: ClassVar[str] = "one disk's moments of inertia differ from the model's"
    what: ClassVar[str] = "the moments of inertia"

    def parameters(self, model) -> list[Parameter]:
        """``<disk>.inertia_change`` on the disk's rotations (mass matrix) and its gyroscopic block."""
        d = model_element(model, "disk", self.disk)
        a, b = node_dofs(d.node)[2:]
        Id, Ip = _disk_value(model, d, "Id"), _disk_value(model, d, "Ip")
        terms = (Term("M", (a, b), Id * np.eye(2)), Term("G", (a, b), Ip * np.array([[0.0, 1.0], [-1.0, 0.0]])))
        return [
            Parameter(
                f"{d.name}.inertia_change",
                self.change,
                "1",
                terms,
                f"relative change of the moments of inertia of disk {d.name} (node {d.node})",
                bounds=RELATIVE_BOUNDS,
            )
        ]
