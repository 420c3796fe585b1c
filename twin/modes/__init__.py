"""Modes: the complex modes of a rotor model and their derivatives, measured modes, MAC, pairing, the Campbell diagram, and the ``modes.nc`` file."""

from twin.modes.analysis import modal, state_matrix, whirl_direction
from twin.modes.campbell import campbell, plot_campbell
from twin.modes.measured import Measured, measured_modes
from twin.modes.modesfile import read_modes, write_modes
from twin.modes.pairing import added_damping_ratio, frequency_ratio, pair_modes
from twin.modes.sensitivity import ModalSolution, solve_modes
from twin.modes.shapes import mac, normalise_shapes

__all__ = [
    "Measured",
    "ModalSolution",
    "added_damping_ratio",
    "campbell",
    "frequency_ratio",
    "mac",
    "measured_modes",
    "modal",
    "normalise_shapes",
    "pair_modes",
    "plot_campbell",
    "read_modes",
    "solve_modes",
    "state_matrix",
    "whirl_direction",
    "write_modes",
]
