"""The rotor model: elements, sensors, regions and linear parameters.

:class:`RotorModel` holds what a model file describes and assembles

    M q'' + (C + Ω G) q' + K q = F

at any parameter values. Everything uncertain (bearing coefficients, disk
inertias, thrust tilt, switched-on effects) is a :class:`~twin.fem.parameters.Parameter`,
so each matrix is ``X0 + Σ θ_k X_k`` and later stages can read the footprints.
"""

from __future__ import annotations

import dataclasses
import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from twin.errors import ModelError
from twin.fem.elements import (
    DOF_NAMES,
    DOFS_PER_NODE,
    Bearing,
    Disk,
    ShaftElement,
    ThrustBearing,
    node_dofs,
)
from twin.fem.parameters import MATRIX_KINDS, Parameter, Term

RPM_TO_RAD_S = 2.0 * np.pi / 60.0


@dataclass(frozen=True)
class Sensor:
    """One proximeter channel: displacement of ``node`` along ``direction`` (x or y).

    ``name`` is the channel name used in every file, e.g. ``"UGB_x"``.
    """

    name: str
    node: int
    direction: str
    location: str = ""

    @property
    def dof(self) -> int:
        """Global DOF index the channel observes."""
        return node_dofs(self.node)[DOF_NAMES.index(self.direction)]


@dataclass(frozen=True)
class RotorModel:
    """A lateral rotor FEM with linear parameters.

    Build it from a model file with :func:`twin.load_model`, or directly.

    Parameters
    ----------
    name : str
        Model name.
    shaft : sequence of ShaftElement
        Consecutive elements; element ``i`` spans nodes ``i`` and ``i + 1``.
    disks, bearings, thrusts : sequences of Disk, Bearing, ThrustBearing
    sensors : sequence of Sensor
    speed_rpm : float
        Running speed [rpm].
    regions : mapping of str to tuple of int
        Named node sets (``immersed``, ``generator``, ``seal``, ...), where
        physical effects act.
    effects : sequence
        Switched-on effects (see :mod:`twin.fem.effects`): each adds parameters.
    rayleigh : (float, float)
        Structural damping of the shaft, ``C_shaft = a M_shaft + b K_shaft``
        with ``a`` [1/s], ``b`` [s].
    values : mapping of str to float
        Parameter values that replace the elements' nominal values (e.g. a
        posterior applied to the model).
    source : str
        Where the model came from (file path), for provenance.
    description : str
        One line saying what the machine is.
    operation : Operation, optional
        Operating conditions and the laws the parameters follow in them
        (:mod:`twin.fem.operation`); None for a model that declares none.
    excitation : Excitation, optional
        What the model file's ``[excitation]`` table declares (:mod:`twin.fem.excitation`; the rest is derived
        from the machine by :func:`twin.fem.excitation.machine_excitation`); None for a model that declares none.
    reference_changes : sequence
        Effects at the sizes the model file declares for hidden changes of reference size
        (``[reference_changes]``; :func:`twin.harness.scenarios.reference_effect` derives the others).

    Examples
    --------
    >>> from twin import RotorModel
    >>> from twin.fem.elements import Material
    >>> steel = Material("steel", 211e9, 81.2e9, 7810.0)
    >>> shaft = [ShaftElement(i, 0.25, 0.05, 0.0, steel) for i in range(4)]
    >>> coeffs = dict(kxx=1e6, kxy=0., kyx=0., kyy=1e6, cxx=10., cxy=0., cyx=0., cyy=10.)
    >>> m = RotorModel("demo", shaft, bearings=[Bearing("A", 0, coeffs), Bearing("B", 4, coeffs)])
    >>> m.n_dof, len(m.parameters)
    (20, 16)
    >>> m.matrices()["K"].shape
    (20, 20)
    """

    name: str
    shaft: Sequence[ShaftElement]
    disks: Sequence[Disk] = ()
    bearings: Sequence[Bearing] = ()
    thrusts: Sequence[ThrustBearing] = ()
    sensors: Sequence[Sensor] = ()
    speed_rpm: float = 0.0
    regions: Mapping[str, tuple[int, ...]] = field(default_factory=dict)
    effects: Sequence[object] = ()
    rayleigh: tuple[float, float] = (0.0, 0.0)
    values: Mapping[str, float] = field(default_factory=dict)
    source: str = ""
    description: str = ""
    operation: object | None = None
    excitation: object | None = None
    reference_changes: Sequence[object] = ()

    def __post_init__(self) -> None:
        for name in ("shaft", "disks", "bearings", "thrusts", "sensors", "effects", "reference_changes"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        object.__setattr__(self, "regions", {k: tuple(int(n) for n in v) for k, v in dict(self.regions).items()})
        object.__setattr__(self, "values", {k: float(v) for k, v in dict(self.values).items()})
        for i, el in enumerate(self.shaft):
            if el.n != i:
                raise ModelError(f"shaft element {i} must start at node {i}, starts at node {el.n}")
        if not self.shaft:
            raise ModelError("a rotor model needs at least one shaft element")
        for what, node in self._located_items():
            if not 0 <= node < self.n_nodes:
                raise ModelError(f"{what} is on node {node}, but the model has nodes 0..{self.n_nodes - 1}")
        unknown = set(self.values) - set(self._base_parameters_by_name)
        if unknown:
            raise ModelError(f"values given for unknown parameters: {sorted(unknown)}")

    def _located_items(self):
        for d in self.disks:
            yield f"disk '{d.name}'", d.node
        for b in self.bearings:
            yield f"bearing '{b.name}'", b.node
        for t in self.thrusts:
            yield f"thrust bearing '{t.name}'", t.node
        for s in self.sensors:
            yield f"sensor '{s.name}'", s.node
        for r, nodes in self.regions.items():
            for n in nodes:
                yield f"region '{r}'", n

    # -- geometry ---------------------------------------------------------------
    @property
    def physics(self) -> dict[str, object]:
        """Which physics the shaft's elements include, and its structural damping (as the model file set them).

        Each of ``shear_deformation`` (Timoshenko), ``rotary_inertia`` and ``gyroscopic`` is True or False for
        the whole shaft, or ``"mixed"``; ``shaft_mass_proportional`` [1/s] and ``shaft_stiffness_proportional``
        [s] are the Rayleigh damping's coefficients.

        Examples
        --------
        >>> hydro_unit.physics["gyroscopic"], hydro_unit.physics["shaft_stiffness_proportional"]
        (True, 6e-05)
        """

        def kind(flags: list[bool]) -> object:
            return flags[0] if len(set(flags)) == 1 else "mixed"

        return {
            "shear_deformation": kind([el.shear for el in self.shaft]),
            "rotary_inertia": kind([el.rotary_inertia for el in self.shaft]),
            "gyroscopic": kind([el.gyroscopic for el in self.shaft]),
            "shaft_mass_proportional": self.rayleigh[0],
            "shaft_stiffness_proportional": self.rayleigh[1],
        }

    @property
    def n_nodes(self) -> int:
        """Number of nodes."""
        return len(self.shaft) + 1

    @property
    def n_dof(self) -> int:
        """Number of degrees of freedom (4 per node)."""
        return DOFS_PER_NODE * self.n_nodes

    @cached_property
    def node_z(self) -> np.ndarray:
        """Axial position of each node [m], node 0 at z = 0."""
        return np.concatenate([[0.0], np.cumsum([el.length for el in self.shaft])])

    @cached_property
    def dof_labels(self) -> list[str]:
        """Label of each DOF, e.g. ``'3.x'`` for x at node 3."""
        return [f"{n}.{d}" for n in range(self.n_nodes) for d in DOF_NAMES]

    @property
    def channels(self) -> list[str]:
        """Sensor channel names, in model-file order."""
        return [s.name for s in self.sensors]

    @property
    def sensor_dofs(self) -> np.ndarray:
        """Global DOF index observed by each channel."""
        return np.array([s.dof for s in self.sensors], dtype=int)

    def region_dofs(self, region: str, directions: Sequence[str] = ("x", "y")) -> tuple[int, ...]:
        """DOFs of a named region's nodes along the given directions."""
        if region not in self.regions:
            raise ModelError(
                f"model '{self.name}' declares no region '{region}' (has: {sorted(self.regions) or 'none'})"
            )
        return tuple(node_dofs(n)[DOF_NAMES.index(d)] for n in self.regions[region] for d in directions)

    # -- parameters ---------------------------------------------------------------
    @cached_property
    def _base_parameters_by_name(self) -> dict[str, Parameter]:
        params: list[Parameter] = []
        for d in self.disks:
            params += d.parameters()
        for b in self.bearings:
            params += b.parameters()
        for t in self.thrusts:
            params += t.parameters()
        for e in self.effects:
            params += e.parameters(self)
        out: dict[str, Parameter] = {}
        for p in params:
            if p.name in out:
                raise ModelError(f"two parameters are named '{p.name}': element names must be unique")
            out[p.name] = p
        return out

    @cached_property
    def parameters(self) -> tuple[Parameter, ...]:
        """All linear parameters, nominal values set to the model's current values."""
        return tuple(
            dataclasses.replace(p, nominal=self.values[p.name]) if p.name in self.values else p
            for p in self._base_parameters_by_name.values()
        )

    @property
    def parameter_names(self) -> list[str]:
        """Names of all parameters, e.g. ``['runner.m', ..., 'UGB.kxx', ...]``."""
        return [p.name for p in self.parameters]

    def parameter(self, name: str) -> Parameter:
        """The parameter called ``name`` (error listing close names if none)."""
        for p in self.parameters:
            if p.name == name:
                return p
        from twin.fem.effects import effect_providing

        close = difflib.get_close_matches(name, self.parameter_names, n=3)
        effect = effect_providing(self, name)
        if effect is not None:
            hint = f"; it comes with the effect '{effect}': add it first (twin ... --effect {effect})"
        else:
            hint = f"; did you mean {close}?" if close else "; twin params MODEL lists them"
        raise ModelError(f"model '{self.name}' has no parameter '{name}'{hint}")

    def with_values(self, values: Mapping[str, float]) -> RotorModel:
        """A copy of the model with some parameter values replaced.

        Examples
        --------
        >>> from twin import load_model, shipped_model
        >>> m = load_model(shipped_model("ross_reference"))
        >>> m.with_values({"B0.kxx": 2e6}).parameter("B0.kxx").nominal
        2000000.0
        """
        for name in values:
            self.parameter(name)
        return dataclasses.replace(self, values={**self.values, **values})

    def with_effects(self, *effects) -> RotorModel:
        """A copy of the model with more effects switched on (library effects or local changes).

        Examples
        --------
        >>> from twin.fem.effects import MagneticPull
        >>> m = hydro_unit.with_effects(MagneticPull(-1e8))
        >>> m.parameter("MAG.stiffness").nominal
        -100000000.0
        """
        return dataclasses.replace(self, effects=(*self.effects, *effects))

    @property
    def per_mode_effect(self):
        """The effect that acts mode by mode (:class:`twin.fem.effects.FluidAddedMassPerMode`), if any.

        The FEM assembly leaves it out; the simulation synthesises it on the dry modes
        (:func:`twin.fmu.truth.synthesize_per_mode_fsi`), the comparison adds it to each mode's pole.

        Examples
        --------
        >>> from twin.fem.effects import FluidAddedMassPerMode, MagneticPull
        >>> m = hydro_unit.with_effects(MagneticPull(-1e8))
        >>> m.per_mode_effect is None
        True
        >>> m.with_effects(FluidAddedMassPerMode((1e5,), (0.0,))).per_mode_effect.added_mass
        (100000.0,)
        """
        return next((e for e in self.effects if e.per_mode), None)

    def without_per_mode_effect(self) -> RotorModel:
        """A copy of the model without its per-mode effect: the single FEM the assembly builds.

        Examples
        --------
        >>> from twin.fem.effects import FluidAddedMassPerMode
        >>> m = hydro_unit
        >>> m.with_effects(FluidAddedMassPerMode((1e5,), (0.0,))).without_per_mode_effect().effects == m.effects
        True
        """
        return dataclasses.replace(self, effects=tuple(e for e in self.effects if not e.per_mode))

    # -- assembly -----------------------------------------------------------------
    @cached_property
    def fixed_matrices(self) -> dict[str, np.ndarray]:
        """The parameter-free part ``M0, C0, G0, K0`` (shaft and its damping)."""
        out = {k: np.zeros((self.n_dof, self.n_dof)) for k in MATRIX_KINDS}
        for el in self.shaft:
            for term in el.terms():
                term.add_to(out[term.kind])
        a, b = self.rayleigh  # fixed M and K hold the shaft only: disks are parameters
        out["C"] += a * out["M"] + b * out["K"]
        for m in out.values():
            m.setflags(write=False)
        return out

    def matrices(self, values: Mapping[str, float] | None = None) -> dict[str, np.ndarray]:
        """Assemble ``M, C, G, K`` at the model's values, some replaced by ``values``.

        ``G`` is per rad/s: the damping-like matrix at speed Ω is ``C + Ω G``.
        Per-mode effect parameters are not part of the single FEM and are skipped.

        Parameters
        ----------
        values : mapping of str to float, optional
            Parameter values [SI] overriding the model's for this assembly only.

        Returns
        -------
        dict
            ``{"M": ..., "C": ..., "G": ..., "K": ...}``, dense ``n_dof x n_dof`` arrays.
        """
        values = dict(values or {})
        for name in values:
            self.parameter(name)
        out = {k: v.copy() for k, v in self.fixed_matrices.items()}
        for p in self.parameters:
            if p.per_mode:
                continue
            theta = values.get(p.name, p.nominal)
            if theta == 0.0:
                continue
            for term in p.terms:
                term.add_to(out[term.kind], theta)
        return out

    def footprints(self, names: Sequence[str] | None = None) -> dict[str, list[Term]]:
        """Footprint terms of the named parameters (all by default), by name."""
        params = self.parameters if names is None else [self.parameter(n) for n in names]
        return {p.name: list(p.terms) for p in params}

    @property
    def speed_rad_s(self) -> float:
        """Running speed [rad/s]."""
        return self.speed_rpm * RPM_TO_RAD_S

    @cached_property
    def total_mass(self) -> float:
        """Mass of shaft and disks [kg]."""
        return sum(el.mass for el in self.shaft) + sum(self.values.get(f"{d.name}.m", d.m) for d in self.disks)
