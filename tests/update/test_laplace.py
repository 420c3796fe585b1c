"""update(method="laplace"): the Gaussian approximation of the pole fit, in the posterior.nc layout."""

import json

import numpy as np
import pytest

from twin.fem.effects import MagneticPull
from twin.fem.truthfile import PAPER_TABLE2, Truth
from twin.modes import measured_modes
from twin.update import LaplaceOptions, UpdateError, read_posterior, summary, synthesize_modes, update
from twin.update.laplace import laplace_update


def _pull_data(model, size=-1e8, seed=1):
    return synthesize_modes(
        model, Truth((MagneticPull(size),)), n_modes=8, samples=50, seed=seed, pole_variance=(0.01, 0.01)
    )


def test_the_laplace_method_finds_the_pull_and_writes_the_posterior_file(hydro_unit, tmp_path):
    model = hydro_unit.with_effects(MagneticPull())
    data = _pull_data(hydro_unit, -1.5e8, seed=7)
    tree = update(
        model,
        data,
        "MAG.stiffness",
        method="laplace",
        options={"draws": 400, "seed": 3},
        output=tmp_path / "posterior.nc",
    )
    _, fitted = laplace_update(model, measured_modes(data), ["MAG.stiffness"])
    theta = tree["posterior"]["theta"].sel(parameter="MAG.stiffness").values
    assert theta.shape == (1, 400)
    # the draws are the Gaussian of the fit: their mean within 4 standard errors of its MAP, their std its std
    mean, std = float(fitted["map"][0]), float(fitted["std"][0])
    assert abs(theta.mean() - mean) < 4 * std / np.sqrt(400)
    assert abs(theta.std() / std - 1) < 0.2
    assert abs(mean / -1.5e8 - 1) < 3 * std / 1.5e8  # the truth within three posterior std
    settings = json.loads(tree.attrs["settings"])
    assert settings["method"] == "laplace" and settings["draws"] == 400 and settings["seed"] == 3
    back = read_posterior(tmp_path / "posterior.nc")
    np.testing.assert_allclose(summary(back["posterior"].to_dataset())["mean"].values, theta.mean(), rtol=1e-12)
    assert back["posterior"]["units"].values.tolist() == ["N/m"]


def test_the_laplace_method_updates_the_per_mode_fsi(hydro_unit):
    data = synthesize_modes(hydro_unit, samples=20, seed=0, shape_cov=1e-4, pole_variance=(1e-6, 1e-6))
    tree = update(hydro_unit, data.isel(mode=[2, 3, 9]), fsi=True, method="laplace")
    mass = tree["posterior"]["added_mass"].mean(("chain", "draw")).values
    # the paper's Table 2 added masses of modes 3, 4 and 10, as the samplers find them
    np.testing.assert_allclose(mass, np.array(PAPER_TABLE2.added_mass)[[2, 3, 9]], rtol=0.02)


def test_the_laplace_method_refuses_what_it_does_not_have(hydro_unit):
    data = _pull_data(hydro_unit)
    model = hydro_unit.with_effects(MagneticPull())
    with pytest.raises(UpdateError, match="the 'laplace' method has no option warmup"):
        update(model, data, "MAG.stiffness", method="laplace", options={"warmup": 5})
    with pytest.raises(UpdateError, match="the 'laplace' method takes LaplaceOptions"):
        update(model, data, "MAG.stiffness", method="laplace", options=__import__("twin").update.HMCOptions())
    with pytest.raises(UpdateError, match="has its own priors"):
        update(model, data, "MAG.stiffness", method="laplace", priors="flat")
    with pytest.raises(UpdateError, match="nothing to update"):
        update(model, data, [], method="laplace")
    with pytest.raises(UpdateError, match="draws must be a whole number"):
        LaplaceOptions(draws=0)
