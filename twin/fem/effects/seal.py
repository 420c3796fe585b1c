"""Cross-coupled stiffness of the runner's labyrinth seals (swirling leakage flow)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from twin.fem.effects.base import FLUID_MAGNETIC_FRACTION, Effect, cross_coupled, direct_stiffness
from twin.fem.effects.registry import register
from twin.fem.elements import UNBOUNDED
from twin.fem.parameters import Parameter


@register
@dataclass(frozen=True)
class SealCrossCoupling(Effect):
    """Cross-coupled stiffness of the runner labyrinth seals (swirling leakage flow)."""

    key: ClassVar[str] = "seal_cross_coupling"
    region: ClassVar[str | None] = "seal"
    explanation: ClassVar[str] = (
        "swirling leakage flow in the seals at {region} pushes the rotor tangentially: a cross-coupled stiffness"
    )
    kxy: float = 0.0  # N/m; K[x, y] = +kxy, K[y, x] = -kxy

    def parameters(self, model) -> list[Parameter]:
        """``SEAL.kxy`` on the seal region (``K[x,y] = +k``, ``K[y,x] = -k``)."""
        return [
            Parameter(
                "SEAL.kxy",
                self.kxy,
                "N/m",
                cross_coupled(model, self.region),
                "cross-coupled seal stiffness (positive destabilises forward whirl)",
                bounds=UNBOUNDED,
            )
        ]

    def plausible_scale(self, model) -> dict[str, float]:
        """30% of the guide bearings' direct stiffness (geometric mean) [N/m]."""
        return {"SEAL.kxy": FLUID_MAGNETIC_FRACTION * direct_stiffness(model)}
