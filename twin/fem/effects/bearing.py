"""A change of a guide bearing's direct stiffness and damping, alike in x and y."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from twin.fem.effects.base import CHANGE_FRACTION, Effect, element_value, model_element
from twin.fem.effects.registry import register
from twin.fem.elements import node_dofs
from twin.fem.parameters import Parameter, Term


@register
@dataclass(frozen=True)
class BearingChange(Effect):
    """A change of a guide bearing's direct stiffness and damping, alike in x and y.

    Wear, a changed clearance or oil temperature, or re-shimming change a
    guide bearing's coefficients. The change is added to ``kxx``, ``kyy``
    (``stiffness_change``) and ``cxx``, ``cyy`` (``damping_change``) of the
    named bearing: the parameters ``<bearing>.stiffness_change`` and
    ``<bearing>.damping_change``, bounded so that the total stays non-negative.
    """

    key: ClassVar[str] = "bearing_change"
    element: ClassVar[str | None] = "bearing"
    explanation: ClassVar[str] = (
        "the bearing is softer or stiffer than modelled (wear, clearance, lubricant temperature)"
    )
    bearing: str = ""
    stiffness_change: float = 0.0  # N/m, added to kxx and kyy
    damping_change: float = 0.0  # N s/m, added to cxx and cyy

    def parameters(self, model) -> list[Parameter]:
        """``<bearing>.stiffness_change`` and ``<bearing>.damping_change`` on the bearing's x, y."""
        b = model_element(model, "bearing", self.bearing)
        dofs = node_dofs(b.node)[:2]
        k = min(element_value(model, b.name, key, b.coefficients[key]) for key in ("kxx", "kyy"))
        c = min(element_value(model, b.name, key, b.coefficients[key]) for key in ("cxx", "cyy"))
        return [
            Parameter(
                f"{b.name}.stiffness_change",
                self.stiffness_change,
                "N/m",
                (Term("K", dofs, np.eye(2)),),
                f"change of {b.name}'s direct stiffness kxx and kyy",
                bounds=(-max(k, 0.0), np.inf),
            ),
            Parameter(
                f"{b.name}.damping_change",
                self.damping_change,
                "N s/m",
                (Term("C", dofs, np.eye(2)),),
                f"change of {b.name}'s direct damping cxx and cyy",
                bounds=(-max(c, 0.0), np.inf),
            ),
        ]

    def plausible_scale(self, model) -> dict[str, float]:
        """Half the bearing's mean direct stiffness and damping."""
        b = model_element(model, "bearing", self.bearing)
        k = np.mean([abs(model.parameter(f"{b.name}.{c}").nominal) for c in ("kxx", "kyy")])
        c = np.mean([abs(model.parameter(f"{b.name}.{c}").nominal) for c in ("cxx", "cyy")])
        return {
            f"{b.name}.stiffness_change": CHANGE_FRACTION * float(k),
            f"{b.name}.damping_change": CHANGE_FRACTION * float(c),
        }
