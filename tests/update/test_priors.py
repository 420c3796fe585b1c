"""plausible_priors: the effects' parameters within a magnitude a machine could show; update's default priors."""

import json
import warnings

import numpy as np
import pytest

from twin.errors import TwinWarning
from twin.fem.effects import MagneticPull, SealCrossCoupling
from twin.fem.truthfile import PAPER_TABLE2
from twin.update import summary, synthesize_modes, update
from twin.update.priors import plausible_priors


def test_the_effects_parameters_get_their_plausible_scale_and_the_models_own_none(hydro_unit):
    model = hydro_unit.with_effects(MagneticPull(stiffness=-1e7), SealCrossCoupling())
    got = plausible_priors(model, ["MAG.stiffness", "SEAL.kxy", "LGB.kxx"])
    scale = {**MagneticPull().plausible_scale(model), **SealCrossCoupling().plausible_scale(model)}
    assert got == {"MAG.stiffness": (-1e7, scale["MAG.stiffness"]), "SEAL.kxy": (0.0, scale["SEAL.kxy"])}
    assert plausible_priors(model, ["SEAL.kxy"]).keys() == {"SEAL.kxy"}  # only what is updated
    assert plausible_priors(hydro_unit, ["LGB.kxx", "UGB.cyy"]) == {}
    # the per-mode FSI: twice the runner's mass (the immersed disk), and 1000 1/s times that for the damping
    runner = hydro_unit.parameter("runner.m").nominal
    assert plausible_priors(hydro_unit, [], fsi=True) == {
        "FSI.added_mass": (0.0, 2 * runner),
        "FSI.added_damping": (0.0, 2000 * runner),
    }


def _added_mass_6(model, data, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TwinWarning)
        tree = update(
            model, data, None, fsi=True, options={"draws": 200, "chains": 2, "seed": 1, "progress": False}, **kw
        )
    draws = tree["posterior"]["added_mass"].values[..., 0].ravel()
    return tree, float(np.std(draws)), np.quantile(draws, [0.05, 0.95])


@pytest.mark.slow
def test_the_default_prior_bounds_what_the_data_do_not_determine(hydro_unit):
    # mode 6 alone with 10 samples whose poles scatter 10 rad/s and shapes 20%: the data hardly say what its
    # added mass is (truth 5.08e4 kg). Flat, the chains wander to 1e6 kg and disagree (std 1.0e6, R-hat 1.8);
    # with the default prior (std 1.7e5 kg, twice the runner's mass) the std is 8.3e4 kg and the interval
    # holds the truth
    data = synthesize_modes(hydro_unit, samples=10, seed=2, pole_variance=(100.0, 100.0), shape_cov=4e-2)
    data = data.isel(mode=[5])
    scale = 2 * hydro_unit.parameter("runner.m").nominal
    flat, std_flat, _ = _added_mass_6(hydro_unit, data, priors="flat")
    tree, std, (q05, q95) = _added_mass_6(hydro_unit, data)
    assert std_flat > 2 * scale
    assert std < scale
    assert q05 < PAPER_TABLE2.added_mass[5] < q95
    settings = json.loads(tree.attrs["settings"])
    assert settings["priors"]["FSI.added_mass"] == [0.0, scale]
    assert json.loads(flat.attrs["settings"])["priors"] == "flat"


def test_a_given_prior_replaces_the_plausible_one(hydro_unit):
    # mode 3's added mass (truth 7.8e4 kg, data std about 2e3 kg) under a prior 9e4 +- 1e3 kg given for it:
    # the posterior is about the product of the two Gaussians (the plausible prior, std 1.7e5 kg, adds nothing)
    data = synthesize_modes(hydro_unit, samples=20, seed=0).isel(mode=[2])
    table = {}
    for label, priors in (("data", "plausible"), ("given", {"FSI.added_mass_3": (9e4, 1e3)})):
        tree = update(
            hydro_unit,
            data,
            None,
            fsi=True,
            priors=priors,
            options={"draws": 100, "chains": 2, "seed": 0, "progress": False},
        )
        table[label] = summary(tree["posterior"].to_dataset()).sel(parameter="FSI.added_mass_3")
    given = json.loads(tree.attrs["settings"])["priors"]
    assert given["FSI.added_mass_3"] == [9e4, 1e3] and given["FSI.added_damping"][0] == 0.0
    w_data, w_prior = float(table["data"]["std"]) ** -2, 1e3**-2
    mean = (w_data * float(table["data"]["mean"]) + w_prior * 9e4) / (w_data + w_prior)
    assert abs(float(table["given"]["mean"]) - mean) < 0.75 * (w_data + w_prior) ** -0.5  # the shift: 6 stds
    assert float(table["given"]["std"]) == pytest.approx((w_data + w_prior) ** -0.5, rel=0.2)
