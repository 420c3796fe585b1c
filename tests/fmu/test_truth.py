"""Truth state spaces: altered FEM, and per-mode FSI by modal synthesis."""

import dataclasses
import json

import numpy as np
import pytest

from twin import ModelError, modal
from twin.fem.effects import FluidAddedMass, MagneticPull
from twin.fem.truthfile import PAPER_TABLE2, Truth, paper_truth
from twin.fmu.statespace import full_state_space, modal_state_space
from twin.fmu.truth import (
    synthesize_per_mode_fsi,
    target_mode_indices,
    truth_state_space,
)
from twin.modes.sensitivity import state_modes


@pytest.fixture(scope="module")
def paper_ss(hydro_unit):
    return truth_state_space(hydro_unit, paper_truth())


def test_target_modes_skip_over_damped_modes(hydro_unit):
    poles = modal(hydro_unit).pole.values
    targets = target_mode_indices(poles, 15)
    assert 1 not in targets and 3 not in targets  # modes 2 and 4, damped 66% and 15% by the UGB
    np.testing.assert_array_equal(targets + 1, [1, 3, *range(5, 18)])
    with pytest.raises(ModelError, match="only"):
        target_mode_indices(poles[:5], 15)


def test_per_mode_truth_modes_are_the_modes_of_their_own_altered_fem(hydro_unit, paper_ss):
    poles = np.linalg.eigvals(paper_ss.A)
    assert paper_ss.n_states == 30 and paper_ss.attrs["target_modes"][:4] == [1, 3, 5, 6]
    for i in range(15):
        altered = dataclasses.replace(
            hydro_unit, effects=(FluidAddedMass(PAPER_TABLE2.added_mass[i], PAPER_TABLE2.added_damping[i]),)
        )
        fem_poles = modal(altered).pole.values
        synthesized = poles[2 * i] if poles[2 * i].imag > 0 else poles[2 * i + 1]
        assert np.min(np.abs(fem_poles - synthesized)) < 1e-9 * abs(synthesized)
    recorded = json.loads(paper_ss.attrs["truth_modes"])
    assert len(recorded) == 15
    assert json.loads(paper_ss.attrs["truth"])["effects"]["fsi_per_mode"]["added_mass"][0] == 1.0e5


def test_modal_synthesis_with_equal_values_reproduces_the_altered_fem_response(hydro_unit):
    # same (m, c) for every mode: the synthesis is the truncated altered FEM (values small enough
    # that no target mode becomes over-damped, so both sides have the same target modes)
    m, c = 5.0e3, 5.0e4
    ss = synthesize_per_mode_fsi(hydro_unit, (m,) * 6, (c,) * 6)
    full = full_state_space(dataclasses.replace(hydro_unit, effects=(FluidAddedMass(m, c),)))
    expected = modal(dataclasses.replace(hydro_unit, effects=(FluidAddedMass(m, c),))).pole.values
    got = np.sort_complex(np.linalg.eigvals(ss.A))
    got = got[got.imag > 0]
    targets = target_mode_indices(expected, 6)
    np.testing.assert_allclose(np.sort_complex(got), np.sort_complex(expected[targets]), rtol=1e-9)
    # and the same modal system as taking those modes straight from the altered FEM
    lam, right, left = state_modes(full.A)
    direct = modal_state_space(
        lam[targets], full.C @ right[targets].T, left[targets] @ full.B, full.ports, full.outputs, full.speed_rpm
    )
    for s in 2j * np.pi * np.array([1.0, 15.0, 16.01, 40.0]):
        h_direct = direct.C @ np.linalg.solve(s * np.eye(12) - direct.A, direct.B)
        h_syn = ss.C @ np.linalg.solve(s * np.eye(12) - ss.A, ss.B)
        np.testing.assert_allclose(h_syn, h_direct, rtol=1e-6, atol=1e-9 * np.abs(h_direct).max())


def test_mode_independent_truth_alters_the_fem(hydro_unit):
    truth = Truth((MagneticPull(stiffness=-3e8),), "test")
    ss = truth_state_space(hydro_unit, truth)
    assert ss.basis == "full"
    expected = modal(dataclasses.replace(hydro_unit, effects=truth.effects)).pole.values
    np.testing.assert_allclose(np.sort_complex(ss.poles[ss.poles.imag > 0]), np.sort_complex(expected), rtol=1e-9)
