"""Stage 2: the rotor as an FMI 2.0 co-simulation FMU (export) and its state-space form."""

from twin.fmu.build import FMUBuildError
from twin.fmu.export import export_fmu
from twin.fmu.statespace import StateSpace, discretize, full_state_space, simulate_reference, truncated_state_space

__all__ = [
    "FMUBuildError",
    "StateSpace",
    "discretize",
    "export_fmu",
    "full_state_space",
    "simulate_reference",
    "truncated_state_space",
]
