"""Physical effects: named parameters with footprints on a model region.

An effect is a small object that, given a model, returns the parameters it
adds. It acts on a named region of the model file (``[regions]``), so the
same effect fits any machine that declares that region:

========================  ==========  ==================================================
key                       region      parameters
========================  ==========  ==================================================
``fsi``                   immersed    ``FSI.added_mass`` [kg], ``FSI.added_damping`` [N s/m]
``fsi_per_mode``          immersed    ``FSI.added_mass_<i>``, ``FSI.added_damping_<i>`` per mode i
``magnetic_pull``         generator   ``MAG.stiffness`` [N/m] (negative: unbalanced magnetic pull)
``seal_cross_coupling``   seal        ``SEAL.kxy`` [N/m] (cross-coupled, forward destabilising)
========================  ==========  ==================================================

Added mass and damping are shared equally over the region's translational
DOFs (``m/n`` and ``c/n`` on each of the ``n`` immersed DOFs), as DESIGN
section 2 prescribes.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from twin.fem.elements import node_dofs
from twin.fem.parameters import Parameter, Term


def _shared(kind: str, dofs: tuple[int, ...]) -> tuple[Term, ...]:
    """One unit shared equally over ``dofs`` on the diagonal of ``kind``."""
    return (Term(kind, dofs, np.eye(len(dofs)) / len(dofs)),)


def _cross_coupled(model, region: str) -> tuple[Term, ...]:
    """Skew-symmetric ``[[0, 1], [-1, 0]] / n`` on (x, y) of each region node."""
    nodes = model.regions[region]
    block = np.array([[0.0, 1.0], [-1.0, 0.0]]) / len(nodes)
    return tuple(Term("K", node_dofs(n)[:2], block) for n in nodes)


@dataclass(frozen=True)
class FluidAddedMass:
    """Mode-independent added mass and damping of the water around the runner."""

    key: ClassVar[str] = "fsi"
    region: ClassVar[str] = "immersed"
    per_mode: ClassVar[bool] = False
    explanation: ClassVar[str] = (
        "the water around the runner moves with it, adding mass and damping to every mode alike"
    )
    added_mass: float = 0.0  # kg
    added_damping: float = 0.0  # N s/m

    def parameters(self, model) -> list[Parameter]:
        """``FSI.added_mass`` and ``FSI.added_damping`` on the immersed DOFs."""
        dofs = model.region_dofs(self.region)
        return [
            Parameter("FSI.added_mass", self.added_mass, "kg", _shared("M", dofs),
                      "added mass of the water, shared over the immersed DOFs"),
            Parameter("FSI.added_damping", self.added_damping, "N s/m", _shared("C", dofs),
                      "added damping of the water, shared over the immersed DOFs"),
        ]  # fmt: skip


@dataclass(frozen=True)
class FluidAddedMassPerMode:
    """Per-mode added mass ``m_i`` and damping ``c_i`` of the water around the runner.

    Each mode sees its own added mass and damping (the flow pattern differs
    from mode to mode), so the model is no longer a single FEM: mode ``i`` is
    the mode of the FEM altered by ``(m_i, c_i)``.
    """

    key: ClassVar[str] = "fsi_per_mode"
    region: ClassVar[str] = "immersed"
    per_mode: ClassVar[bool] = True
    explanation: ClassVar[str] = (
        "the water around the runner adds a different mass and damping to each mode"
    )
    added_mass: tuple[float, ...] = ()  # kg, one per mode
    added_damping: tuple[float, ...] = ()  # N s/m, one per mode

    def __post_init__(self) -> None:
        object.__setattr__(self, "added_mass", tuple(float(v) for v in self.added_mass))
        object.__setattr__(self, "added_damping", tuple(float(v) for v in self.added_damping))
        if len(self.added_mass) != len(self.added_damping):
            raise ValueError(
                f"fsi_per_mode needs as many added masses ({len(self.added_mass)}) "
                f"as added dampings ({len(self.added_damping)})"
            )

    @property
    def n_modes(self) -> int:
        """Number of modes the effect gives values for."""
        return len(self.added_mass)

    def parameters(self, model) -> list[Parameter]:
        """``FSI.added_mass_<i>``, ``FSI.added_damping_<i>`` for modes i = 1..n (per-mode)."""
        dofs = model.region_dofs(self.region)
        out = []
        for i, (m, c) in enumerate(zip(self.added_mass, self.added_damping), start=1):
            out.append(Parameter(f"FSI.added_mass_{i}", m, "kg", _shared("M", dofs),
                                 f"added mass of the water in mode {i}", per_mode=True))
            out.append(Parameter(f"FSI.added_damping_{i}", c, "N s/m", _shared("C", dofs),
                                 f"added damping of the water in mode {i}", per_mode=True))
        return out  # fmt: skip


@dataclass(frozen=True)
class MagneticPull:
    """Negative radial stiffness of unbalanced magnetic pull at the generator air gap."""

    key: ClassVar[str] = "magnetic_pull"
    region: ClassVar[str] = "generator"
    per_mode: ClassVar[bool] = False
    explanation: ClassVar[str] = (
        "an off-centre generator rotor is pulled further off centre by the magnetic field: a negative stiffness"
    )
    stiffness: float = 0.0  # N/m, negative for a pull

    def parameters(self, model) -> list[Parameter]:
        """``MAG.stiffness`` shared over the generator region's x and y DOFs."""
        dofs = model.region_dofs(self.region)
        # each direction carries the full stiffness: share over nodes, not over x and y
        n_nodes = len(model.regions[self.region])
        terms = (Term("K", dofs, np.eye(len(dofs)) / n_nodes),)
        return [Parameter("MAG.stiffness", self.stiffness, "N/m", terms,
                          "radial magnetic stiffness at the air gap (negative: pull)")]  # fmt: skip


@dataclass(frozen=True)
class SealCrossCoupling:
    """Cross-coupled stiffness of the runner labyrinth seals (swirling leakage flow)."""

    key: ClassVar[str] = "seal_cross_coupling"
    region: ClassVar[str] = "seal"
    per_mode: ClassVar[bool] = False
    explanation: ClassVar[str] = (
        "swirling leakage flow in the runner seals pushes the runner tangentially: a cross-coupled stiffness"
    )
    kxy: float = 0.0  # N/m; K[x, y] = +kxy, K[y, x] = -kxy

    def parameters(self, model) -> list[Parameter]:
        """``SEAL.kxy`` on the seal region (``K[x,y] = +k``, ``K[y,x] = -k``)."""
        return [Parameter("SEAL.kxy", self.kxy, "N/m", _cross_coupled(model, self.region),
                          "cross-coupled seal stiffness (positive destabilises forward whirl)")]  # fmt: skip


#: Effects by the key used in model and truth files.
EFFECTS: dict[str, type] = {
    cls.key: cls for cls in (FluidAddedMass, FluidAddedMassPerMode, MagneticPull, SealCrossCoupling)
}


def effect_fields(cls: type) -> dict[str, type]:
    """The settable values of an effect class and their Python types.

    Examples
    --------
    >>> effect_fields(MagneticPull)
    {'stiffness': <class 'float'>}
    """
    hints = {"float": float, "tuple[float, ...]": tuple}
    return {f.name: hints[str(f.type)] for f in dataclasses.fields(cls)}
