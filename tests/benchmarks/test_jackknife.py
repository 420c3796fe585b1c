"""benchmarks/jackknife.py: the jackknife of the posterior mode, which the benchmarks measure the update's spread with."""

import numpy as np
import pytest

from twin.fem.truthfile import Truth
from twin.update import synthesize_modes
from twin.update.posterior import stretch
from twin.update.marginal import marginal_problem, posterior_mode
from twin.update.problem import build_problem

from tests.benchmarks import BENCHMARKS  # noqa: F401  (puts benchmarks/ on the path)
from jackknife import correlation_factors, mode_spread, perturbed  # noqa: E402

NAMES = ["UGB.kxx", "UGB.kyy"]


def _data(model, seed, samples=40):
    """Modes 3, 4 and 10 of the model itself (nothing hidden), paper noise."""
    return synthesize_modes(model, Truth(()), samples=samples, seed=seed, n_modes=10).isel(mode=[2, 3, 9])


def test_perturbation_moves_the_mean_by_one_standard_error_and_keeps_the_spread():
    import xarray as xr

    x = xr.DataArray(np.random.default_rng(0).standard_normal((3, 25)), dims=("mode", "sample"))
    moved = perturbed(x, 7)
    np.testing.assert_allclose(moved.mean("sample") - x.mean("sample"), (x.isel(sample=7) - x.mean("sample")) / 5)
    np.testing.assert_allclose(moved.std("sample"), x.std("sample"))
    assert moved.dims == x.dims


def test_stretch_keeps_the_mean_and_scales_the_spread():
    draws = np.random.default_rng(1).standard_normal((2, 300, 3))
    out = stretch(draws, np.array([1.0, 2.0, 1.5]))
    np.testing.assert_allclose(out.mean(axis=(0, 1)), draws.mean(axis=(0, 1)))
    np.testing.assert_allclose(out.std(axis=(0, 1)) / draws.std(axis=(0, 1)), [1.0, 2.0, 1.5])


@pytest.mark.slow
def test_the_adjustment_undoes_a_mode_counted_twice(hydro_unit):
    # the composite-likelihood case in its plainest form: one mode's data entered twice as if independent.
    # The model's posterior std falls by sqrt(2) (it counts the information twice); the joint perturbations
    # move both copies together and give the single mode's spread, the shuffled ones move them apart, and
    # their ratio, sqrt(2), restores the single mode's posterior std
    import xarray as xr

    one = _data(hydro_unit, 7).isel(mode=[0])
    two = xr.concat([one, one.assign_coords(mode=[99])], "mode")
    results = []
    for data in (one, two):
        problem = build_problem(hydro_unit, data, ["UGB.kxx"], pole_model="marginal")
        marg = marginal_problem(problem, data["pole"].transpose("mode", "sample").values)
        zero = np.zeros(marg.size)
        _, at = posterior_mode(marg, zero, zero)
        model_std = float(np.sqrt(np.linalg.inv(at.precision)[0, 0]) * problem.global_scale[0])
        kwargs = {"fsi": False, "eps_std": 1e-6, "prior_mean": zero, "prior_precision": zero}
        joint = float(mode_spread(marg, hydro_unit, data, ["UGB.kxx"], **kwargs)[0])
        factor = float(correlation_factors(marg, hydro_unit, data, ["UGB.kxx"], **kwargs)[0])
        results.append((model_std, joint, factor))
    (std1, joint1, factor1), (std2, joint2, factor2) = results
    assert std2 / std1 == pytest.approx(1 / np.sqrt(2), rel=1e-3)
    assert joint2 == pytest.approx(joint1, rel=1e-6)
    assert factor1 == 1.0  # one mode: nothing to shuffle
    assert factor2 == pytest.approx(np.sqrt(2), rel=0.1)
    assert std2 * factor2 == pytest.approx(std1, rel=0.1)


def test_independent_modes_are_left_about_as_they_are(hydro_unit):
    # synthetic samples are independent from mode to mode: the ratio is one up to the noise of 20 perturbations
    data = _data(hydro_unit, 11)
    problem = build_problem(hydro_unit, data, NAMES, pole_model="marginal")
    marg = marginal_problem(problem, data["pole"].transpose("mode", "sample").values)
    zero = np.zeros(marg.size)
    factors = correlation_factors(
        marg, hydro_unit, data, NAMES, fsi=False, eps_std=1e-6, prior_mean=zero, prior_precision=zero
    )
    assert ((factors > 0.7) & (factors < 1.4)).all(), factors
