"""The modal form the FMU steps: its step coefficients, and its accuracy against an exact solution."""

import numpy as np
import pytest
import scipy.linalg as sla

from twin import ModelError
from twin.fmu import full_state_space
from twin.fmu.excitation import excitation_forces, turbulence_force
from twin.fmu.modal import SERIES_BELOW, modal_form, simulate_modal, step_coefficients
from twin.fmu.statespace import StateSpace


@pytest.mark.parametrize("lam", [-2.0 + 60.0j, -1e-6 + 1e-5j, -5e5 + 0j, -0.3 + 0j])
def test_step_coefficients_are_the_exact_foh_integrals(lam):
    """a, g0, g1 against the augmented matrix exponential (Van Loan) of the scalar system, on both sides of
    the series threshold."""
    for h in (1e-3, 0.25 * SERIES_BELOW / abs(lam), 4 * SERIES_BELOW / abs(lam)):
        E = sla.expm(np.array([[lam * h, h, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]], dtype=complex))
        a, g0, g1 = (c[0] for c in step_coefficients(np.array([lam]), h))
        np.testing.assert_allclose([a, g0, g1], E[0], rtol=1e-12, atol=1e-300)


def test_a_defective_system_has_no_modal_form():
    A = np.array([[-1.0, 1.0], [0.0, -1.0]])  # a Jordan block
    ss = StateSpace(A, np.eye(2)[:, :1], np.eye(2)[:1], ["0.x"], ["y"], 0.0)
    with pytest.raises(ModelError, match="defective"):
        modal_form(ss)


def _exact_longdouble(ss, used, forces, h):
    """The first-order-hold recursion in extended precision (np.longdouble): the augmented exponential by a
    Taylor series with scaling and squaring, then the recursion, both with ~1e-19 round-off."""
    L = np.longdouble
    n, p = ss.A.shape[0], len(used)
    big = np.zeros((n + 2 * p, n + 2 * p), dtype=L)
    big[:n, :n] = ss.A.astype(L) * L(h)
    big[:n, n : n + p] = ss.B[:, used].astype(L) * L(h)
    big[n : n + p, n + p :] = np.eye(p, dtype=L)
    squarings = max(0, int(np.ceil(np.log2(np.abs(big.astype(float)).sum(axis=0).max() / 0.25))))
    X = big / L(2.0**squarings)
    E, term = np.eye(len(big), dtype=L), np.eye(len(big), dtype=L)
    for k in range(1, 30):  # ||X|| <= 0.25: the 30th term is below 1e-19
        term = term @ X / L(k)
        E = E + term
    for _ in range(squarings):
        E = E @ E
    phi, g0, g1 = E[:n, :n], E[:n, n : n + p], E[:n, n + p :]
    f = forces[:, used].astype(L)
    df = np.zeros_like(f)
    df[:-1] = np.diff(f, axis=0)
    drive = f @ g0.T + df @ g1.T
    x, C = np.zeros(n, dtype=L), ss.C.astype(L)
    y = np.empty((len(f), C.shape[0]), dtype=L)
    for k in range(len(f)):
        y[k] = C @ x
        x = phi @ x + drive[k]
    return y.astype(float)


@pytest.mark.slow
def test_the_modal_recursion_is_within_1e_9_of_the_rms_of_the_exact_solution(hydro_unit):
    """The full hydro unit's 232 states from rest under its built-in excitation, 8 s at 256 Hz: the modal
    recursion (what the FMU steps) against the same recursion in extended precision. The dense double
    recursion of the same system is about 1.5e-9 off; the modal one about 3e-10."""
    ss = full_state_space(hydro_unit)
    h, n = 1 / 256, 2048
    f = excitation_forces(ss, np.arange(n) * h, 8, 100.0, 28, turbulence_force(n, 3000.0, 4, h))
    used = np.nonzero(np.any(f != 0, axis=0))[0]
    exact = _exact_longdouble(ss, used, f, h)
    rms = np.sqrt(np.mean(exact**2, axis=0))
    assert np.max(np.abs(simulate_modal(modal_form(ss), h, f) - exact) / rms) < 1e-9


def test_the_modal_reference_is_the_dense_recursion_from_any_initial_state():
    """A 2-mode system with a real pole: simulate_modal from z0 = W x0 against the dense exact recursion."""
    from twin.fmu.statespace import discretize, simulate_reference

    A = np.array([[0.0, 1.0, 0.0], [-400.0, -0.8, 30.0], [0.0, 0.0, -5.0]])
    ss = StateSpace(A, np.array([[0.0], [1.0], [2.0]]), np.array([[1.0, 0.0, 0.5]]), ["0.x"], ["y"], 0.0)
    h, n = 0.01, 500
    f = np.sin(np.arange(n) * h * 13.0)[:, None]
    x0 = np.array([1e-3, -0.2, 0.05])
    form = modal_form(ss)
    dense = simulate_reference(discretize(ss, h), ss.C, foh=f, x0=x0)
    np.testing.assert_allclose(simulate_modal(form, h, f, z0=form.left @ x0), dense, rtol=0, atol=1e-12)
