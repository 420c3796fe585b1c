"""Identifiability of parameters (twin.design.identify): the Fisher algebra, the undetermined bearing terms, the CLI."""

import numpy as np
import pytest

from twin import load_model, shipped_model
from twin.cli import main
from twin.design import identifiability
from twin.design.identify import _data_vector, fisher_covariance, modal_jacobian, sample_covariance
from twin.errors import ModelError
from twin.fmu.statespace import full_state_space, state_modes
from twin.loop.sensitivity import pole_jacobian, solve_modes
from twin.modes.shapes import normalise_shapes
from twin.update.synthetic import POLE_VARIANCE, SHAPE_COV


@pytest.fixture(scope="module")
def unit():
    return load_model(shipped_model("hydro_unit"))


def test_the_jacobian_of_the_poles_matches_the_exact_derivative(unit):
    names = ["UGB.kxx", "LGB.cyy", "generator.m"]
    J, columns, scales, poles, _ = modal_jacobian(unit, names, [0, 4, 9])
    exact = pole_jacobian(unit, solve_modes(unit), names, modes=[0, 4, 9])
    assert columns == names
    size = np.abs(exact).max(axis=0)  # forward differences: 1e-3 of each column's largest entry
    assert (np.abs(J[:, 0, :] - exact.real) < 1e-3 * size).all()
    assert (np.abs(J[:, 1, :] - exact.imag) < 1e-3 * size).all()


def test_fisher_covariance_of_one_parameter_is_the_weighted_least_squares_variance():
    J = np.array([[[2.0], [0.0], [1.0]], [[1.0], [3.0], [0.0]]])  # two modes, three data, one parameter
    covs = [np.diag([0.5, 1.0, 2.0]), np.diag([1.0, 4.0, 1.0])]
    expected = 1.0 / (4 / 0.5 + 1 / 2.0 + 1 / 1.0 + 9 / 4.0)
    assert fisher_covariance(J, covs, np.array([1.0]))[0, 0] == pytest.approx(expected, rel=1e-9)
    assert fisher_covariance(J, covs, np.array([7.0]))[0, 0] == pytest.approx(expected, rel=1e-9)  # scale-free


def test_sample_covariance_is_the_covariance_of_renormalised_synthetic_samples():
    """Monte Carlo: shapes perturbed as synthesize_modes does, then normalised as the data vector is."""
    rng = np.random.default_rng(5)
    shape = normalise_shapes(np.array([[0.7, 0.5 + 0.2j, -0.3 + 0.1j, 0.2 - 0.05j]]))[0]
    ref = int(np.argmax(np.abs(shape)))
    e = SHAPE_COV * rng.standard_normal((2, 200_000, 4))
    noisy = shape.real * (1 + e[0]) + 1j * shape.imag * (1 + e[1])
    data = np.array([_data_vector(0j, s, ref)[2:] for s in noisy])
    expected = sample_covariance(shape, 1)
    assert np.allclose(np.diag(expected)[:2], POLE_VARIANCE)
    size = np.sqrt(np.outer(np.diag(expected)[2:], np.diag(expected)[2:])).max()
    assert np.allclose(np.cov(data.T), expected[2:, 2:], atol=0.02 * size)  # 200000 draws, second order in 5%
    assert np.allclose(sample_covariance(shape, 100), expected / 100)


def test_the_lgb_direct_stiffnesses_are_undetermined_and_the_ugb_ones_determined(unit):
    """Case B (16 bearings + per-mode FSI, paper truth, 100 samples): LGB.kxx and LGB.kyy are left undetermined."""
    from twin.fem.truthfile import paper_truth
    from twin.update.problem import select_parameters

    ident = identifiability(unit, select_parameters(unit, "bearings"), fsi=True, samples=100, truth=paper_truth())
    assert bool(ident.determined.sel(parameter="UGB.kxx")) and bool(ident.determined.sel(parameter="UGB.kyy"))
    assert not ident.determined.sel(parameter="LGB.kxx") and not ident.determined.sel(parameter="LGB.kyy")
    assert ident.relative_std.sel(parameter="UGB.kxx") < 0.01
    assert ident.sizes["parameter"] == 16 + 2 * 15


def test_more_samples_shrink_the_std_as_one_over_their_root(unit):
    a = identifiability(unit, ["UGB.kxx", "LGB.cxx"], samples=25)
    b = identifiability(unit, ["UGB.kxx", "LGB.cxx"], samples=100)
    assert np.allclose(a["std"] / b["std"], 2.0, rtol=1e-6)


def test_nothing_to_judge_is_refused(unit):
    with pytest.raises(ModelError, match="nothing to judge"):
        identifiability(unit, [])


def test_observe_command_prints_both_tables(capsys):
    assert main(["observe", "hydro_unit", "--params", "LGB.k*", "-q"]) == 0  # 20 min: LGB.kxx, kyy undetermined
    out = capsys.readouterr().out
    assert "target modes observable" in out
    assert "LGB.kxx" in out and "NOT determined" in out
    assert out.count("not observable") >= 4


def test_the_fisher_std_is_the_samplers_on_case_b(unit, case_b_posterior):
    """Expected posterior std before any data against the default sampler's on paper Case B (J = 100, seed 1).

    Both describe the same data (the poles and shapes of the 15 modes, their noise) linearised at the truth,
    so for the determined parameters the ratio is about 1: median 1.03 measured, 1.06-1.09 on data seeds 5, 9
    and 13 (``benchmarks/identifiability.py``). The Fisher carries the synthetic shape noise through the
    normalisation of its data vector (:func:`twin.modes.shapes.normalisation_jacobian`); with the raw
    entries' variances taken as the normalised shape's, 35 of 43 were within 1.5.

    Three are outside here: LGB.cxy, LGB.cyx and the added damping of mode 12 (the sampler 0.53-0.64 times
    the Fisher std; LGB.cyx on every data seed tried). They rest on the small imaginary shape entries, which
    the relative synthetic noise leaves almost exact, and the Fisher's pseudo-inverse and the sampler's
    variance floor and perturbation ``ε`` cut those at different levels. On data seed 13 the FSI of modes 6
    and 8 are at 1.55-1.59 as well (39 of 43 within).
    """
    from twin.fem.truthfile import paper_truth
    from twin.update import summary
    from twin.update.problem import select_parameters

    ident = identifiability(unit, select_parameters(unit, "bearings"), fsi=True, samples=100, truth=paper_truth())
    sampled = summary(case_b_posterior["posterior"].to_dataset())["std"].sel(parameter=ident.parameter)
    ratio = (sampled / ident["std"]).where(ident.determined, drop=True)
    assert ratio.sizes["parameter"] == 43
    assert 0.9 <= float(ratio.median()) <= 1.15
    within = np.abs(np.log(ratio)) <= np.log(1.5)
    assert int(within.sum()) >= 40, ratio.parameter.values[~within.values]
    assert float(ratio.min()) > 0.45 and float(ratio.max()) < 1.5
    undetermined = (sampled / ident["std"]).where(~ident.determined, drop=True)  # LGB.kxx, LGB.kyy, mass of mode 1
    assert ((undetermined > 0.67) & (undetermined < 1.5)).all()
