"""Unbalanced magnetic pull at the generator's air gap: a negative radial stiffness."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from twin.fem.effects.base import FLUID_MAGNETIC_FRACTION, Effect, direct_stiffness
from twin.fem.effects.registry import register
from twin.fem.parameters import Parameter, Term


@register
@dataclass(frozen=True)
class MagneticPull(Effect):
    """Negative radial stiffness of unbalanced magnetic pull at the generator air gap."""

    key: ClassVar[str] = "magnetic_pull"
    region: ClassVar[str | None] = "generator"
    explanation: ClassVar[str] = (
        "an off-centre rotor at {region} is pulled further off centre by the magnetic field: a negative stiffness"
    )
    stiffness: float = 0.0  # N/m, negative for a pull

    def parameters(self, model) -> list[Parameter]:
        """``MAG.stiffness`` shared over the generator region's x and y DOFs."""
        dofs = model.region_dofs(self.region)
        # each direction carries the full stiffness: share over nodes, not over x and y
        n_nodes = len(model.regions[self.region])
        terms = (Term("K", dofs, np.eye(len(dofs)) / n_nodes),)
        return [
            Parameter(
                "MAG.stiffness",
                self.stiffness,
                "N/m",
                terms,
                "radial magnetic stiffness at the air gap (negative: pull)",
                bounds=(-np.inf, 0.0),
            )
        ]

    def plausible_scale(self, model) -> dict[str, float]:
        """30% of the guide bearings' direct stiffness (geometric mean) [N/m]."""
        return {"MAG.stiffness": FLUID_MAGNETIC_FRACTION * direct_stiffness(model)}
