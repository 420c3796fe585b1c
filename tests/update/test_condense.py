"""The perturbed condensed eigen-model: exact at the truth, linear in the parameters."""

import numpy as np

from twin.fem.effects import FluidAddedMass
from twin.fem.truthfile import PAPER_TABLE2
from twin.update.condense import (
    LATENT_SHAPE,
    STAGE_2,
    complex_vector,
    condense,
    dynamic_stiffness,
    real_augment,
    real_vector,
)
from twin.update.problem import _basis, select_parameters


def _case_b(model):
    """Fixed part (bearings at zero), bases of the 16 bearing coefficients and of the FSI mass and damping."""
    bearings = select_parameters(model, "bearings")
    fsi = {p.name: p for p in FluidAddedMass().parameters(model)}
    bases = [_basis(model.parameter(b), model.n_dof) for b in bearings]
    bases += [_basis(fsi["FSI.added_mass"], model.n_dof), _basis(fsi["FSI.added_damping"], model.n_dof)]
    truth = np.array([model.parameter(b).nominal for b in bearings])
    return model.matrices({b: 0.0 for b in bearings}), bases, truth


def test_exact_data_give_a_zero_residual_and_least_squares_recovers_all_46_parameters(hydro_unit, paper_truth_modes):
    fixed, bases, bearings = _case_b(hydro_unit)
    obs = hydro_unit.sensor_dofs
    rows, rhs = [], []
    for i, (lam, shape) in enumerate(zip(paper_truth_modes.poles, paper_truth_modes.shapes)):
        c = condense(fixed, bases, obs, np.array([lam]), hydro_unit.speed_rad_s)
        assert c.method == STAGE_2 and c.R.shape == (1, 19, 8, 8)
        psi = shape[obs] / np.linalg.norm(shape[obs])
        theta = np.r_[1.0, bearings, PAPER_TABLE2.added_mass[i], PAPER_TABLE2.added_damping[i]]
        residual = np.einsum("k,krc,c->r", theta, c.R[0], psi)
        scale = np.abs(np.einsum("krc,c->r", c.R[0], psi)).max()
        assert np.abs(residual).max() < 1e-9 * scale  # zero to round-off of the eigen-solution
        design = np.einsum("krc,c->rk", c.R[0, 1:], psi)
        full = np.zeros((8, 46), complex)
        full[:, :16], full[:, 16 + 2 * i : 18 + 2 * i] = design[:, :16], design[:, 16:]
        rows.append(full)
        rhs.append(-c.R[0, 0] @ psi)
    A, b = np.vstack(rows), np.concatenate(rhs)
    truth = np.r_[bearings, np.ravel(np.c_[PAPER_TABLE2.added_mass, PAPER_TABLE2.added_damping])]
    As = np.vstack([A.real, A.imag]) * np.abs(truth)  # scaled by the nominal (true) values
    x = np.linalg.lstsq(As, np.concatenate([b.real, b.imag]), rcond=None)[0] * np.abs(truth)
    np.testing.assert_allclose(x, truth, rtol=1e-6)
    assert np.linalg.cond(As) < 1e7  # DESIGN: ~1e5 on the prototype


def test_latent_shape_fallback_is_exact_too(hydro_unit, paper_truth_modes):
    fixed, bases, bearings = _case_b(hydro_unit)
    obs = hydro_unit.sensor_dofs
    i = 2
    lam, shape = paper_truth_modes.poles[i], paper_truth_modes.shapes[i]
    c = condense(fixed, bases, obs, np.array([lam]), hydro_unit.speed_rad_s, force_latent=True)
    assert c.method == LATENT_SHAPE and c.latent_dofs == (112, 113)  # runner x, y
    x = np.concatenate([shape[obs], shape[list(c.latent_dofs)]])
    theta = np.r_[1.0, bearings, PAPER_TABLE2.added_mass[i], PAPER_TABLE2.added_damping[i]]
    residual = np.einsum("k,krc,c->r", theta, c.R[0], x)
    assert np.abs(residual).max() < 1e-9 * np.abs(c.R[0, 0] @ x).max()
    np.testing.assert_array_equal(c.T[0, 0], -np.eye(len(x)))


def test_too_few_parameter_free_rows_fall_back_to_latent_shape(hydro_unit, paper_truth_modes):
    # observe only the seal node: o' = {27x, 27y} but FSI and LGB add q = {25x, 25y, 28x, 28y}
    fixed, bases, _ = _case_b(hydro_unit)
    c = condense(fixed, bases[8:], [108, 109], paper_truth_modes.poles[:1], hydro_unit.speed_rad_s)
    assert c.method == LATENT_SHAPE and len(c.latent_dofs) == 4


def test_perturbation_enters_through_T(hydro_unit, paper_truth_modes):
    # a force perturbation eps on s shifts the condensed residual by T eps, and only by that
    fixed, bases, bearings = _case_b(hydro_unit)
    obs = hydro_unit.sensor_dofs
    lam = paper_truth_modes.poles[3] + 5j  # any lambda: a forced response, not an eigen-solution
    theta = np.r_[bearings, PAPER_TABLE2.added_mass[3], PAPER_TABLE2.added_damping[3]]
    mats = {k: fixed[k] + sum(t * b[k] for t, b in zip(theta, bases)) for k in "MCGK"}
    rng = np.random.default_rng(0)
    s = np.concatenate([obs, [112, 113]])
    eps = np.zeros(hydro_unit.n_dof, complex)
    eps[s] = 1e6 * (rng.standard_normal(10) + 1j * rng.standard_normal(10))
    a = np.linalg.solve(dynamic_stiffness(mats, np.array([lam]), hydro_unit.speed_rad_s)[0] + 0j, eps)
    c = condense(fixed, bases, obs, np.array([lam]), hydro_unit.speed_rad_s)
    coef = np.r_[1.0, theta]
    R, T = np.einsum("k,krc->rc", coef, c.R[0]), np.einsum("k,krc->rc", coef, c.T[0])
    np.testing.assert_allclose(R @ a[obs] + T @ eps[s], 0, atol=1e-8 * np.abs(T @ eps[s]).max())


def test_real_augmentation_matches_complex_products():
    rng = np.random.default_rng(1)
    A = rng.standard_normal((3, 4)) + 1j * rng.standard_normal((3, 4))
    x = rng.standard_normal(4) + 1j * rng.standard_normal(4)
    np.testing.assert_allclose(real_augment(A) @ real_vector(x), real_vector(A @ x))
    np.testing.assert_allclose(complex_vector(real_vector(x)), x)


def test_a_basis_without_entries_adds_nothing(hydro_unit):
    # a basis with no entries adds nothing: the PerCEM is the same as without it
    fixed, bases, _ = _case_b(hydro_unit)
    zero = {k: np.zeros_like(v) for k, v in bases[0].items()}
    lam = np.array([-1.0 + 60.0j])
    a = condense(fixed, bases[:2], hydro_unit.sensor_dofs, lam, hydro_unit.speed_rad_s)
    b = condense(fixed, [*bases[:2], zero], hydro_unit.sensor_dofs, lam, hydro_unit.speed_rad_s)
    np.testing.assert_allclose(b.R[:, :3], a.R)
    assert np.all(b.R[:, 3] == 0)
