"""A proportional change of a guide bearing: all its stiffness and damping coefficients by one factor.

A fluid-film bearing's eight dynamic coefficients at a given eccentricity are
dimensionless numbers times ``W / c`` (stiffness) and ``W / (c Ω)`` (damping),
with ``W`` the static load and ``c`` the radial clearance; the oil's viscosity
sets the eccentricity through the Sommerfeld number. A changed clearance or
load at an unchanged operating state therefore scales every coefficient,
cross-coupled ones included, by one factor. This effect is that factor: the
relative change ``δ`` of the bearing's whole stiffness and damping matrices
(``K_b`` and ``C_b`` become ``(1 + δ) K_b`` and ``(1 + δ) C_b``), one
parameter where :class:`~twin.fem.effects.BearingChange` has two absolute
changes of the direct terms alone.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from twin.fem.effects.base import CHANGE_FRACTION, RELATIVE_BOUNDS, Effect, element_value, model_element
from twin.fem.effects.registry import register
from twin.fem.elements import BEARING_COEFFICIENTS, node_dofs
from twin.fem.parameters import Parameter, Term


@register
@dataclass(frozen=True)
class BearingScale(Effect):
    """All of a guide bearing's eight coefficients larger or smaller by one factor ``1 + scale_change``.

    Examples
    --------
    >>> model = hydro_unit
    >>> softer = model.with_effects(BearingScale("LGB", -0.2))
    >>> dK = softer.matrices()["K"] - model.matrices()["K"]
    >>> x = 4 * model.bearings[1].node
    >>> float(dK[x, x + 1] / model.parameter("LGB.kxy").nominal)
    -0.2
    """

    key: ClassVar[str] = "bearing_scale"
    element: ClassVar[str | None] = "bearing"
    explanation: ClassVar[str] = (
        "all of the bearing's stiffness and damping coefficients, cross-coupled ones included, are larger "
        "or smaller by one factor (a changed clearance or static load)"
    )
    bearing: str = ""
    scale_change: float = 0.0  # relative: -0.2 leaves 80% of every coefficient

    def parameters(self, model) -> list[Parameter]:
        """``<bearing>.scale_change`` on the bearing's whole stiffness and damping blocks at the model's values."""
        b = model_element(model, "bearing", self.bearing)
        blocks = {"K": np.zeros((2, 2)), "C": np.zeros((2, 2))}
        for key, (kind, row, col) in BEARING_COEFFICIENTS.items():
            blocks[kind][row, col] = element_value(model, b.name, key, b.coefficients[key])
        dofs = node_dofs(b.node)[:2]
        terms = tuple(Term(kind, dofs, block) for kind, block in blocks.items() if np.any(block))
        return [
            Parameter(
                f"{b.name}.scale_change",
                self.scale_change,
                "1",
                terms,
                f"relative change of all of {b.name}'s stiffness and damping coefficients",
                bounds=RELATIVE_BOUNDS,
            )
        ]

    def plausible_scale(self, model) -> dict[str, float]:
        """Half of the coefficients (a relative change of 0.5)."""
        b = model_element(model, "bearing", self.bearing)
        return {f"{b.name}.scale_change": CHANGE_FRACTION}
