"""A change of the thrust bearing's tilt stiffness."""

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
class ThrustTilt(Effect):
    """A change of the thrust bearing's tilt stiffness, added to its ``k_tilt`` (the total stays non-negative)."""

    key: ClassVar[str] = "thrust_tilt"
    element: ClassVar[str | None] = "thrust"
    explanation: ClassVar[str] = (
        "the thrust pads resist tilting of the collar more or less than modelled (load, pad wear)"
    )
    thrust: str = ""
    k_tilt_change: float = 0.0  # N m/rad, added to the thrust's tilt stiffness

    def parameters(self, model) -> list[Parameter]:
        """``<thrust>.k_tilt_change`` on the thrust node's alpha, beta."""
        t = model_element(model, "thrust", self.thrust)
        k = element_value(model, t.name, "k_tilt", t.k_tilt)
        return [
            Parameter(
                f"{t.name}.k_tilt_change",
                self.k_tilt_change,
                "N m/rad",
                (Term("K", node_dofs(t.node)[2:], np.eye(2)),),
                f"change of {t.name}'s tilt stiffness",
                bounds=(-max(k, 0.0), np.inf),
            )
        ]

    def plausible_scale(self, model) -> dict[str, float]:
        """Half the thrust's tilt stiffness."""
        t = model_element(model, "thrust", self.thrust)
        return {f"{t.name}.k_tilt_change": CHANGE_FRACTION * abs(model.parameter(f"{t.name}.k_tilt").nominal)}
