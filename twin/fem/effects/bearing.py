"""Changes of a guide bearing's direct stiffness and damping: alike in x and y, or each coefficient apart."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from twin.fem.effects.base import CHANGE_FRACTION, Effect, element_value, model_element
from twin.fem.effects.registry import register
from twin.fem.elements import node_dofs
from twin.fem.parameters import Parameter, Term

#: The direct coefficients of a bearing: the matrix each is in and its axis (0: x, 1: y).
DIRECT = {"kxx": ("K", 0), "kyy": ("K", 1), "cxx": ("C", 0), "cyy": ("C", 1)}


def _direct(model, b, key: str) -> float:
    """A direct coefficient of bearing ``b`` at the model's values."""
    return element_value(model, b.name, key, b.coefficients[key])


def _mean_direct(model, b, kind: str) -> float:
    """The mean absolute direct stiffness (``kind`` "K") or damping ("C") of bearing ``b`` at its nominal values."""
    keys = [k for k, (m, _) in DIRECT.items() if m == kind]
    return float(np.mean([abs(model.parameter(f"{b.name}.{k}").nominal) for k in keys]))


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
        k = min(_direct(model, b, key) for key in ("kxx", "kyy"))
        c = min(_direct(model, b, key) for key in ("cxx", "cyy"))
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
        return {
            f"{b.name}.stiffness_change": CHANGE_FRACTION * _mean_direct(model, b, "K"),
            f"{b.name}.damping_change": CHANGE_FRACTION * _mean_direct(model, b, "C"),
        }


@register
@dataclass(frozen=True)
class BearingAnisotropicChange(Effect):
    """A change of each of a guide bearing's direct coefficients apart: ``kxx``, ``kyy``, ``cxx``, ``cyy``.

    The richer form of :class:`BearingChange` (which it holds as the case of
    equal changes in x and y): a bearing whose stiffness changed in proportion
    to unequal coefficients, or wear on one side of a bearing, changes x and y
    by different amounts. Four parameters ``<bearing>.kxx_change``,
    ``<bearing>.kyy_change`` [N/m], ``<bearing>.cxx_change``, ``<bearing>.cyy_change``
    [N s/m], each bounded so that its coefficient stays non-negative, with the
    plausible scales of :class:`BearingChange`. A diagnosis that has chosen
    ``bearing_change`` at a bearing tries this in its place before it names a
    second effect (:mod:`twin.loop.diagnose`).

    Examples
    --------
    >>> m = hydro_unit.with_effects(BearingAnisotropicChange("UGB", kyy_change=-2e8))
    >>> dK = m.matrices()["K"] - hydro_unit.matrices()["K"]
    >>> y = 4 * hydro_unit.bearings[0].node + 1
    >>> float(dK[y, y]), float(dK[y - 1, y - 1])
    (-200000000.0, 0.0)
    """

    key: ClassVar[str] = "bearing_anisotropic"
    element: ClassVar[str | None] = "bearing"
    replaces: ClassVar[frozenset[str]] = frozenset({"bearing_change"})
    explanation: ClassVar[str] = (
        "the bearing's direct stiffness and damping changed by different amounts in x and in y (a proportional "
        "change of unequal coefficients, one-sided wear or clearance)"
    )
    bearing: str = ""
    kxx_change: float = 0.0  # N/m
    kyy_change: float = 0.0  # N/m
    cxx_change: float = 0.0  # N s/m
    cyy_change: float = 0.0  # N s/m

    def parameters(self, model) -> list[Parameter]:
        """``<bearing>.<coefficient>_change`` for kxx, kyy, cxx and cyy, each on its own diagonal entry."""
        b = model_element(model, "bearing", self.bearing)
        dofs = node_dofs(b.node)[:2]
        out = []
        for key, (kind, axis) in DIRECT.items():
            unit = "N/m" if kind == "K" else "N s/m"
            out.append(
                Parameter(
                    f"{b.name}.{key}_change",
                    getattr(self, f"{key}_change"),
                    unit,
                    (Term(kind, dofs, np.diag(np.eye(2)[axis])),),
                    f"change of {b.name}'s {key}",
                    bounds=(-max(_direct(model, b, key), 0.0), np.inf),
                )
            )
        return out

    def plausible_scale(self, model) -> dict[str, float]:
        """Half the bearing's mean direct stiffness (for ``kxx``, ``kyy``) and damping (``cxx``, ``cyy``)."""
        b = model_element(model, "bearing", self.bearing)
        return {
            f"{b.name}.{key}_change": CHANGE_FRACTION * _mean_direct(model, b, kind)
            for key, (kind, _) in DIRECT.items()
        }
