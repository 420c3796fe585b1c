"""A local change of one shaft element's bending stiffness (a crack or a weakened section).

A local change lies outside the effects library: the diagnosis does not name
it as a missing effect but scans every element for it to say where a model
fails when no library effect explains the residuals
(:func:`twin.loop.locate.locate`). Its parameter is the *relative* change
``δ`` of the element's own stiffness; with ``δ = -0.5`` a shaft element keeps
half its bending stiffness (Young's and shear moduli halved alike: a
Timoshenko element's stiffness is then exactly halved). It is bounded below
by -1 (nothing negative).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from twin.errors import ModelError
from twin.fem.effects.base import RELATIVE_BOUNDS, RelativeChange
from twin.fem.effects.registry import register
from twin.fem.parameters import Parameter, Term


@register
@dataclass(frozen=True)
class ShaftStiffnessChange(RelativeChange):
    """A relative change of one shaft element's bending stiffness (a crack or a weakened section).

    Its footprint is the element's stiffness matrix and its share ``b K_e`` of
    the Rayleigh damping.

    Examples
    --------
    >>> import numpy as np
    >>> model = hydro_unit
    >>> weak = model.with_effects(ShaftStiffnessChange(18, -0.5))
    >>> dK = weak.matrices()["K"] - model.matrices()["K"]
    >>> bool(np.allclose(dK, -0.5 * model.shaft[18].terms()[2].to_dense(model.n_dof)))
    True
    """

    key: ClassVar[str] = "shaft_stiffness"
    element: ClassVar[str | None] = "index"
    element_kind: ClassVar[str | None] = "shaft"
    explanation: ClassVar[str] = "one shaft element is softer or stiffer than modelled (a crack, a weakened section)"
    #: In service a shaft element only softens (a crack grows, a shrink fit or a coupling loosens); none stiffens.
    in_service: ClassVar[int] = -1
    index: int = 0
    change: float = 0.0  # relative: -0.5 keeps half the stiffness

    def parameters(self, model) -> list[Parameter]:
        """``shaft<e>.stiffness_change`` on the element's stiffness (and stiffness-proportional damping)."""
        if not 0 <= self.index < len(model.shaft):
            raise ModelError(
                f"model '{model.name}' has no shaft element {self.index} (elements 0 to {len(model.shaft) - 1})"
            )
        el = model.shaft[self.index]
        K = next(t for t in el.terms() if t.kind == "K")
        terms = [K]
        if model.rayleigh[1]:
            terms.append(Term("C", K.dofs, model.rayleigh[1] * K.value))
        z = model.node_z
        return [
            Parameter(
                f"shaft{self.index}.stiffness_change",
                self.change,
                "1",
                tuple(terms),
                f"relative bending-stiffness change of shaft element {self.index} (nodes {el.n}-{el.n + 1}, "
                f"z = {z[el.n]:.2f} to {z[el.n + 1]:.2f} m)",
                bounds=RELATIVE_BOUNDS,
            )
        ]

    def where(self, model) -> str:
        """The place in words."""
        el = model.shaft[self.index]
        z = model.node_z
        return f"shaft element {self.index} (nodes {el.n}-{el.n + 1}, z = {z[el.n]:.2f} to {z[el.n + 1]:.2f} m)"
