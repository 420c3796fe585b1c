"""The pole models of the condensed eigen-model: at every sample, or linearised about the mean pole."""

import numpy as np
import pytest
import xarray as xr

from twin.errors import UpdateError
from twin.update.condense import condense
from twin.update.poles import condense_samples, order_covariance

# a 4-DOF chain on springs, DOFs 0-2 observed, a parametrised spring at DOF 3: |o'| = 3 > |q| = 1,
# so stage 2 keeps two extra parameter-free rows
K0 = np.array([[2.0, -1, 0, 0], [-1, 2, -1, 0], [0, -1, 2, -1], [0, 0, -1, 1]])
FIXED = {"M": np.diag([1.0, 1.2, 0.9, 1.1]), "C": 0.01 * K0, "G": np.zeros((4, 4)), "K": K0}
ZERO = np.zeros((4, 4))
SPRING = {"M": ZERO, "C": ZERO, "G": ZERO, "K": np.diag([0.0, 0, 0, 1])}
OBSERVED = [0, 1, 2]


def _poles(spread: float, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return 0.8j - 0.01 + spread * (rng.standard_normal(50) + 1j * rng.standard_normal(50))


def test_linear_bases_average_to_the_bases_at_the_mean_pole():
    poles = _poles(1e-2)
    lin = condense_samples(FIXED, [SPRING], OBSERVED, poles, 0.0, pole_model="linear")
    at_mean = condense(FIXED, [SPRING], OBSERVED, poles.mean(keepdims=True), 0.0)
    assert lin.R.shape == (50, 2, 3, 3) and lin.method == "stage 2"
    np.testing.assert_allclose(lin.R.mean(axis=0), at_mean.R[0], rtol=0, atol=1e-12 * np.abs(at_mean.R).max())
    np.testing.assert_allclose(lin.T.mean(axis=0), at_mean.T[0], rtol=0, atol=1e-12 * np.abs(at_mean.T).max())


def test_linear_bases_agree_with_the_sampled_ones_to_second_order():
    # the linearisation error is quadratic in the pole deviation: a tenth of the spread, a hundredth of the error
    errors = []
    for spread in (1e-2, 1e-3):
        poles = _poles(spread)
        lin = condense_samples(FIXED, [SPRING], OBSERVED, poles, 0.0, pole_model="linear")
        exact = condense_samples(FIXED, [SPRING], OBSERVED, poles, 0.0, pole_model="samples")
        errors.append(np.abs(lin.R - exact.R).max() / np.abs(exact.R).max())
    assert errors[0] < 1e-2
    assert errors[1] / errors[0] == pytest.approx(1e-2, rel=0.3)


def test_extra_rows_are_the_same_combination_at_every_sample():
    # the extra rows are the complement chosen at the mean pole, projected: smooth in the pole
    poles = _poles(1e-3)
    c = condense(FIXED, [SPRING], OBSERVED, poles, 0.0)
    extra = c.R[:, 0, 1:]  # rows after the one parametrised row
    spread = np.abs(extra - extra.mean(axis=0)).max() / np.abs(extra).max()
    assert spread < 1e-2
    at_centre = condense(FIXED, [SPRING], OBSERVED, poles.mean(keepdims=True), 0.0)
    np.testing.assert_allclose(extra.mean(axis=0), at_centre.R[0, 0, 1:], atol=1e-2 * np.abs(extra).max())


def test_exact_pole_gives_zero_residual_in_both_models():
    k = 0.5
    # undamped: C = 0, poles ±i sqrt(eigenvalues of M⁻¹K)
    fixed = dict(FIXED, C=np.zeros((4, 4)))
    w2, V = np.linalg.eig(np.linalg.solve(fixed["M"], K0 + k * SPRING["K"]))
    j = np.argmin(w2.real)
    pole = 1j * np.sqrt(w2[j].real)
    poles = pole + 1e-4 * np.array([1, -1, 1j, -1j])
    for model in ("samples", "linear"):
        c = condense_samples(fixed, [SPRING], OBSERVED, poles, 0.0, pole_model=model)
        R = c.R[:, 0] + k * c.R[:, 1]
        mean_residual = np.mean(R @ V[:3, j].real, axis=0)
        assert np.abs(mean_residual).max() < 1e-6 * np.abs(R).max()


def test_unknown_pole_model_is_named():
    with pytest.raises(ValueError, match="unknown pole model 'mean'.*samples, linear"):
        condense_samples(FIXED, [SPRING], OBSERVED, _poles(1e-3), 0.0, pole_model="mean")


def test_order_covariance_is_the_modes_own_unless_absent_or_already_in_the_samples():
    cov = np.array([[[4.0, 1.0], [1.0, 9.0]], [[1.0, 0.0], [0.0, 2.0]]])
    modes = xr.Dataset(
        {"pole_order_cov": (("mode", "pole_part", "pole_part_2"), cov)},
        coords={"mode": [1, 2]},
        attrs={"settings": '{"order_spread": "shapes"}'},
    )
    np.testing.assert_array_equal(order_covariance(modes), cov)
    np.testing.assert_array_equal(order_covariance(modes.isel(mode=[1])), cov[1:])  # follows a mode selection
    # synthetic modes carry none, and samples extracted with order_spread="all" carry it already
    np.testing.assert_array_equal(order_covariance(modes.drop_vars("pole_order_cov")), np.zeros((2, 2, 2)))
    np.testing.assert_array_equal(order_covariance(modes.assign_attrs(settings='{"order_spread": "all"}')), 0.0)
    bad = modes.copy()
    bad["pole_order_cov"] = bad["pole_order_cov"].where(bad["pole_part"] == "real")
    with pytest.raises(UpdateError, match="pole_order_cov must be finite"):
        order_covariance(bad)
