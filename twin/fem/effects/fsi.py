"""The water around the runner: added mass and damping, alike for every mode or mode by mode.

Added mass and damping are shared equally over the ``immersed`` region's
translational DOFs (``m/n`` and ``c/n`` on each of the ``n`` immersed DOFs).
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from twin.fem.effects.base import Effect, region_mass, shared_over
from twin.fem.effects.registry import register
from twin.fem.elements import POSITIVE
from twin.fem.parameters import Parameter

#: Ratio of a plausible water added damping to added mass [1/s] (the paper's
#: Table 2 spans 13 to 2700 1/s over its 15 modes).
FSI_DAMPING_PER_MASS = 1000.0


@register
@dataclass(frozen=True)
class FluidAddedMass(Effect):
    """Mode-independent added mass and damping of the water around the runner."""

    key: ClassVar[str] = "fsi"
    region: ClassVar[str | None] = "immersed"
    explanation: ClassVar[str] = "the water around {region} moves with it, adding mass and damping to every mode alike"
    added_mass: float = 0.0  # kg
    added_damping: float = 0.0  # N s/m

    def parameters(self, model) -> list[Parameter]:
        """``FSI.added_mass`` and ``FSI.added_damping`` on the immersed DOFs."""
        dofs = model.region_dofs(self.region)
        return [
            Parameter(
                "FSI.added_mass",
                self.added_mass,
                "kg",
                shared_over("M", dofs),
                "added mass of the water, shared over the immersed DOFs",
                bounds=POSITIVE,
            ),
            Parameter(
                "FSI.added_damping",
                self.added_damping,
                "N s/m",
                shared_over("C", dofs),
                "added damping of the water, shared over the immersed DOFs",
                bounds=POSITIVE,
            ),
        ]

    def plausible_scale(self, model) -> dict[str, float]:
        """Twice the immersed disks' mass [kg]; that times 1000 1/s for the damping [N s/m]."""
        m = 2.0 * region_mass(model, self.region)
        return {"FSI.added_mass": m, "FSI.added_damping": m * FSI_DAMPING_PER_MASS}


@register
@dataclass(frozen=True)
class FluidAddedMassPerMode(Effect):
    """Per-mode added mass ``m_i`` and damping ``c_i`` of the water around the runner.

    Each mode sees its own added mass and damping (the flow pattern differs
    from mode to mode), so the model is no longer a single FEM: mode ``i`` is
    the mode of the FEM altered by ``(m_i, c_i)``. It holds the
    mode-independent :class:`FluidAddedMass` as a special case.
    """

    key: ClassVar[str] = "fsi_per_mode"
    region: ClassVar[str | None] = "immersed"
    per_mode: ClassVar[bool] = True
    replaces: ClassVar[frozenset[str]] = frozenset({"fsi"})
    explanation: ClassVar[str] = "the water around {region} adds a different mass and damping to each mode"
    #: Names of its parameters for any number of modes (``FSI.added_mass_3``); every per-mode effect has one.
    name_pattern: ClassVar[re.Pattern] = re.compile(r"^FSI\.added_(mass|damping)_\d+$")
    per_mode_text: ClassVar[str] = "FSI.added_mass_<i> [kg] and FSI.added_damping_<i> [N s/m] per mode i: >= 0"
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

    def with_modes(self, n_modes: int) -> FluidAddedMassPerMode:
        """Zero added mass and damping for modes 1..``n_modes``."""
        return FluidAddedMassPerMode((0.0,) * n_modes, (0.0,) * n_modes)

    def parameters(self, model) -> list[Parameter]:
        """``FSI.added_mass_<i>``, ``FSI.added_damping_<i>`` for modes i = 1..n (per-mode)."""
        dofs = model.region_dofs(self.region)
        out = []
        for i, (m, c) in enumerate(zip(self.added_mass, self.added_damping), start=1):
            out.append(
                Parameter(
                    f"FSI.added_mass_{i}",
                    m,
                    "kg",
                    shared_over("M", dofs),
                    f"added mass of the water in mode {i}",
                    per_mode=True,
                    bounds=POSITIVE,
                )
            )
            out.append(
                Parameter(
                    f"FSI.added_damping_{i}",
                    c,
                    "N s/m",
                    shared_over("C", dofs),
                    f"added damping of the water in mode {i}",
                    per_mode=True,
                    bounds=POSITIVE,
                )
            )
        return out

    def plausible_scale(self, model) -> dict[str, float]:
        """Per mode, the scales of :meth:`FluidAddedMass.plausible_scale`."""
        base = FluidAddedMass().plausible_scale(model)
        out = {}
        for i in range(1, self.n_modes + 1):
            out[f"FSI.added_mass_{i}"] = base["FSI.added_mass"]
            out[f"FSI.added_damping_{i}"] = base["FSI.added_damping"]
        return out


def with_shared_fsi(model):
    """The model with a mode-independent FSI effect (zero-valued if it had none).

    Per-mode FSI values act through the shared effect's footprint: mode ``i``
    is a mode of this model with ``FSI.added_mass`` and ``FSI.added_damping``
    raised by ``(m_i, c_i)``.
    """
    if any(isinstance(e, FluidAddedMass) for e in model.effects):
        return model
    return dataclasses.replace(model, effects=(*model.effects, FluidAddedMass()))


def per_mode_values(model, base, label: int, values: Mapping[str, float]) -> dict[str, float]:
    """Values of ``base`` (with shared FSI) that give mode ``label`` of a per-mode FSI model.

    A label beyond the values of the model's per-mode effect adds nothing.
    """
    shared_m = values.get("FSI.added_mass", base.parameter("FSI.added_mass").nominal)
    shared_c = values.get("FSI.added_damping", base.parameter("FSI.added_damping").nominal)
    names = set(model.parameter_names)

    def own(name: str) -> float:
        return values.get(name, model.parameter(name).nominal if name in names else 0.0)

    return {
        "FSI.added_mass": shared_m + own(f"FSI.added_mass_{label}"),
        "FSI.added_damping": shared_c + own(f"FSI.added_damping_{label}"),
    }
