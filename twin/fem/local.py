"""Local changes outside the effects library: one shaft element's stiffness, one disk's mass or inertia.

A crack or a weakened section softens one shaft element; a repair, an added
balancing mass or a rewound generator pole changes one disk. No library
effect (:mod:`twin.fem.effects`) describes such a change, but each is one
linear parameter, the *relative* change ``δ`` of an element's own
coefficients:

==========================  =============================  ==============================================
key                         parameter                      footprint (``δ`` times)
==========================  =============================  ==============================================
``shaft_stiffness:<e>``     ``shaft<e>.stiffness_change``  the element's stiffness matrix, and its share
                                                           ``b K_e`` of the Rayleigh damping
``disk_mass:<d>``           ``<d>.mass_change``            the disk's mass on x, y
``disk_inertia:<d>``        ``<d>.inertia_change``         the disk's diametral (M) and polar (G) inertia
==========================  =============================  ==============================================

With ``δ = -0.5`` a shaft element keeps half its bending stiffness (Young's
and shear moduli halved alike: a Timoshenko element's stiffness is then
exactly halved). Every change is bounded below by ``-1`` (nothing negative).

They follow the effect protocol (``key``, ``element``, ``parameters(model)``,
``plausible_scale(model)``, ``explanation``), so a truth can hide one
(:mod:`twin.loop.scenarios`) and the diagnosis scans them all to say where a
model fails when no library effect explains it (:func:`twin.loop.diagnose.locate`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from twin.errors import ModelError
from twin.fem.elements import node_dofs
from twin.fem.parameters import Parameter, Term

#: Plausible size of a local relative change (the prior scale of the localisation scan).
LOCAL_CHANGE_SCALE = 0.5
#: A relative change leaves the coefficient positive.
RELATIVE_BOUNDS = (-1.0, np.inf)


def _disk(model, name: str):
    for d in model.disks:
        if d.name == name:
            return d
    known = ", ".join(repr(d.name) for d in model.disks) or "none"
    raise ModelError(f"model '{model.name}' has no disk '{name}' (its disks: {known})")


def _disk_value(model, disk, key: str) -> float:
    return float(model.values.get(f"{disk.name}.{key}", getattr(disk, key)))


class _RelativeChange:
    """What every local change shares: one relative parameter with the scan's prior scale."""

    region: ClassVar[str | None] = None
    per_mode: ClassVar[bool] = False

    def plausible_scale(self, model) -> dict[str, float]:
        """:data:`LOCAL_CHANGE_SCALE` (a relative change)."""
        return {p.name: LOCAL_CHANGE_SCALE for p in self.parameters(model)}


@dataclass(frozen=True)
class ShaftStiffnessChange(_RelativeChange):
    """A relative change of one shaft element's bending stiffness (a crack or a weakened section).

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> model = load_model(shipped_model("hydro_unit"))
    >>> weak = model.with_effects(ShaftStiffnessChange(18, -0.5))
    >>> dK = weak.matrices()["K"] - model.matrices()["K"]
    >>> bool(np.allclose(dK, -0.5 * model.shaft[18].terms()[2].to_dense(model.n_dof)))
    True
    """

    key: ClassVar[str] = "shaft_stiffness"
    element: ClassVar[str | None] = "index"
    explanation: ClassVar[str] = "one shaft element is softer or stiffer than modelled (a crack, a weakened section)"
    index: int = 0
    change: float = 0.0  # relative: -0.5 keeps half the stiffness

    def parameters(self, model) -> list[Parameter]:
        """``shaft<e>.stiffness_change`` on the element's stiffness (and stiffness-proportional damping)."""
        if not 0 <= self.index < len(model.shaft):
            raise ModelError(f"model '{model.name}' has no shaft element {self.index} "
                             f"(elements 0 to {len(model.shaft) - 1})")  # fmt: skip
        el = model.shaft[self.index]
        K = next(t for t in el.terms() if t.kind == "K")
        terms = [K]
        if model.rayleigh[1]:
            terms.append(Term("C", K.dofs, model.rayleigh[1] * K.value))
        z = model.node_z
        return [Parameter(f"shaft{self.index}.stiffness_change", self.change, "1", tuple(terms),
                          f"relative bending-stiffness change of shaft element {self.index} (nodes {el.n}-{el.n + 1}, "
                          f"z = {z[el.n]:.2f} to {z[el.n + 1]:.2f} m)", bounds=RELATIVE_BOUNDS)]  # fmt: skip


    def where(self, model) -> str:
        """The place in words."""
        el = model.shaft[self.index]
        z = model.node_z
        return f"shaft element {self.index} (nodes {el.n}-{el.n + 1}, z = {z[el.n]:.2f} to {z[el.n + 1]:.2f} m)"


@dataclass(frozen=True)
class DiskMassChange(_RelativeChange):
    """A relative change of one disk's mass (added or lost mass at a node).

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> model = load_model(shipped_model("hydro_unit"))
    >>> heavier = model.with_effects(DiskMassChange("generator", 0.1))
    >>> float(np.trace(heavier.matrices()["M"] - model.matrices()["M"])) / 2  # kg on x and on y
    60000.0
    """

    key: ClassVar[str] = "disk_mass"
    element: ClassVar[str | None] = "disk"
    explanation: ClassVar[str] = "one disk is heavier or lighter than modelled"
    disk: str = ""
    change: float = 0.0  # relative

    def parameters(self, model) -> list[Parameter]:
        """``<disk>.mass_change`` on the disk's x and y."""
        d = _disk(model, self.disk)
        x, y = node_dofs(d.node)[:2]
        m = _disk_value(model, d, "m")
        return [Parameter(f"{d.name}.mass_change", self.change, "1", (Term("M", (x, y), m * np.eye(2)),),
                          f"relative mass change of disk {d.name} (node {d.node})", bounds=RELATIVE_BOUNDS)]  # fmt: skip


    def where(self, model) -> str:
        """The place in words."""
        d = _disk(model, self.disk)
        return f"the mass of disk {d.name} (node {d.node}, z = {model.node_z[d.node]:.2f} m)"


@dataclass(frozen=True)
class DiskInertiaChange(_RelativeChange):
    """A relative change of one disk's moments of inertia, diametral and polar alike.

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> model = load_model(shipped_model("hydro_unit"))
    >>> [p.name for p in DiskInertiaChange("runner", 0.2).parameters(model)]
    ['runner.inertia_change']
    """

    key: ClassVar[str] = "disk_inertia"
    element: ClassVar[str | None] = "disk"
    explanation: ClassVar[str] = "one disk's moments of inertia differ from the model's"
    disk: str = ""
    change: float = 0.0  # relative

    def parameters(self, model) -> list[Parameter]:
        """``<disk>.inertia_change`` on the disk's rotations (mass matrix) and its gyroscopic block."""
        d = _disk(model, self.disk)
        a, b = node_dofs(d.node)[2:]
        Id, Ip = _disk_value(model, d, "Id"), _disk_value(model, d, "Ip")
        terms = (Term("M", (a, b), Id * np.eye(2)), Term("G", (a, b), Ip * np.array([[0.0, 1.0], [-1.0, 0.0]])))
        return [Parameter(f"{d.name}.inertia_change", self.change, "1", terms,
                          f"relative change of the moments of inertia of disk {d.name} (node {d.node})",
                          bounds=RELATIVE_BOUNDS)]  # fmt: skip


    def where(self, model) -> str:
        """The place in words."""
        d = _disk(model, self.disk)
        return f"the moments of inertia of disk {d.name} (node {d.node}, z = {model.node_z[d.node]:.2f} m)"


#: Local changes by key.
LOCAL_CHANGES: dict[str, type] = {cls.key: cls for cls in (ShaftStiffnessChange, DiskMassChange, DiskInertiaChange)}


def local_changes(model) -> list:
    """Every local change the model can take, zero-valued: each shaft element's stiffness, each disk's mass
    and inertia (the hypotheses of the localisation scan).

    Examples
    --------
    >>> from twin import load_model, shipped_model
    >>> changes = local_changes(load_model(shipped_model("hydro_unit")))
    >>> len(changes), changes[-1]
    (36, DiskInertiaChange(disk='runner', change=0.0))
    """
    return ([ShaftStiffnessChange(e.n) for e in model.shaft] + [DiskMassChange(d.name) for d in model.disks]
            + [DiskInertiaChange(d.name) for d in model.disks])  # fmt: skip
