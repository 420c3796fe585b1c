"""State-space form, exact discretisation and the numpy reference recursion."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from twin import ModelError, modal
from twin.fem.effects import FluidAddedMassPerMode
from twin.fem.truthfile import Truth
from twin.fmu.statespace import StateSpace, discretize, full_state_space, simulate_reference, truncated_state_space
from twin.fmu.truth import model_state_space, target_mode_indices, truth_state_space
from twin.modes.sensitivity import state_modes


def _oscillator(wn=2 * np.pi * 3.0, zeta=0.05):
    A = np.array([[0.0, 1.0], [-(wn**2), -2 * zeta * wn]])
    return StateSpace(A, np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]]), ["0.x"], ["y"], 0.0)


@pytest.mark.parametrize("hold", ["zoh", "foh"])
def test_exact_discretisation_matches_a_tight_ode_solution(hold):
    ss, h = _oscillator(), 0.02
    t = np.arange(60) * h
    u = np.sin(2 * np.pi * 1.7 * t) + 0.3 * np.cos(2 * np.pi * 4.1 * t)
    y = simulate_reference(discretize(ss, h), ss.C, **{hold: u[:, None]})

    def force(time):
        k = min(int(np.floor(time / h + 1e-12)), len(u) - 2)
        return u[k] if hold == "zoh" else u[k] + (u[k + 1] - u[k]) * (time - t[k]) / h

    sol = solve_ivp(
        lambda s, x: ss.A @ x + ss.B[:, 0] * force(s),
        (0, t[-1]),
        [0.0, 0.0],
        t_eval=t,
        rtol=1e-12,
        atol=1e-14,
        max_step=h / 20,
    )
    np.testing.assert_allclose(y[:, 0], sol.y[0], atol=1e-9 * np.abs(sol.y[0]).max())


def test_zoh_and_foh_differ_on_a_sampled_sinusoid():
    # the reason the FMU and the reference must use the same hold
    ss, h = _oscillator(wn=2 * np.pi * 2.2, zeta=0.01), 1e-3
    t = np.arange(8000) * h
    u = np.cos(2 * np.pi * 2.2 * t)[:, None]
    zoh = simulate_reference(discretize(ss, h), ss.C, zoh=u)
    foh = simulate_reference(discretize(ss, h), ss.C, foh=u)
    assert np.abs(zoh - foh).max() > 1e-3 * np.abs(foh).max()


def test_full_state_space_poles_are_the_modal_poles(hydro_unit):
    ss = full_state_space(hydro_unit)
    poles, right, left = state_modes(ss.A)
    np.testing.assert_allclose(poles, modal(hydro_unit).pole.values, rtol=1e-10)
    np.testing.assert_allclose(np.sum(left * right, axis=1), 1.0, rtol=1e-9)
    assert ss.ports[:2] == ["0.x", "0.y"] and ss.outputs == hydro_unit.channels


def test_truncated_basis_keeps_low_modes_and_low_frequency_response(hydro_unit):
    full = full_state_space(hydro_unit)
    trunc = truncated_state_space(full, 50.0)
    kept = np.sort_complex(trunc.poles[trunc.poles.imag > 0])
    expected = modal(hydro_unit).pole.values
    expected = expected[expected.imag <= 2 * np.pi * 50.0]
    np.testing.assert_allclose(np.sort_complex(kept), np.sort_complex(expected), rtol=1e-10)
    # frequency response from the runner force to the seal sensor near a kept mode
    j, i = full.port_index("28.x"), full.outputs.index("SEAL_x")
    for f_hz in (14.0, 16.0):
        s = 2j * np.pi * f_hz
        h_full = full.C[i] @ np.linalg.solve(s * np.eye(full.n_states) - full.A, full.B[:, j])
        h_trunc = trunc.C[i] @ np.linalg.solve(s * np.eye(trunc.n_states) - trunc.A, trunc.B[:, j])
        assert abs(h_trunc - h_full) < 0.05 * abs(h_full)
    with pytest.raises(ModelError, match="positive frequency"):
        truncated_state_space(full, 0.0)


def test_a_model_with_per_mode_fsi_is_simulated_with_it(hydro_unit):
    # an update's per-mode estimate is not one FEM: the model's state space must be its modal synthesis, the
    # same system a per-mode truth of those values gives (the FEM assembly alone leaves per-mode values out)
    effect = FluidAddedMassPerMode((8e4, 0.0, 5e4), (2e7, 0.0, 1e6))
    ss = model_state_space(hydro_unit.with_effects(effect))
    expected = truth_state_space(hydro_unit, Truth((effect,)))
    np.testing.assert_allclose(np.sort_complex(ss.poles), np.sort_complex(expected.poles), rtol=1e-12)
    np.testing.assert_allclose(
        ss.C @ ss.B, expected.C @ expected.B, rtol=1e-9, atol=1e-12 * np.abs(expected.C @ expected.B).max()
    )
    dry, wet = modal(hydro_unit).pole.values, ss.poles
    dry, wet = dry[dry.imag > 0], wet[wet.imag > 0]
    dry, wet = dry[np.argsort(dry.imag)], wet[np.argsort(wet.imag)]
    dry = dry[target_mode_indices(dry, 3)]  # the over-damped bearing mode is no target
    assert wet[0].imag < 0.995 * dry[0].imag and wet[0].real < dry[0].real  # mode 1: heavier, more damped
    np.testing.assert_allclose(wet[1], dry[1], rtol=1e-9)  # mode 2 has none
    with pytest.raises(ModelError, match="already has"):
        truth_state_space(hydro_unit.with_effects(effect), Truth((effect,)))


def test_bad_step():
    with pytest.raises(ModelError, match="time step must be positive"):
        discretize(_oscillator(), 0.0)
