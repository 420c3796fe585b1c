"""update(): paper Cases A and B, the zero-noise limit, the posterior file, bad input, the CLI."""

import json
import warnings

import numpy as np
import pytest
import xarray as xr

from twin.cli import main
from twin.errors import ModelError, TwinWarning
from twin.modes.modesfile import write_modes
from twin.fem.effects import FluidAddedMassPerMode
from twin.fem.truthfile import PAPER_TABLE2
from twin.update import UpdateError, apply_posterior, read_posterior, summary, synthesize_modes, update
from twin.update import GibbsOptions
from twin.update.problem import build_problem, select_parameters


def _truth(model):
    out = {n: model.parameter(n).nominal for n in select_parameters(model, "bearings")}
    for i, (m, c) in enumerate(zip(PAPER_TABLE2.added_mass, PAPER_TABLE2.added_damping), start=1):
        out[f"FSI.added_mass_{i}"], out[f"FSI.added_damping_{i}"] = m, c
    return out


def _run(model, data, params, method="hmc", priors="plausible", output=None, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", TwinWarning)
        tree = update(
            model,
            data,
            params,
            fsi=True,
            method=method,
            options={**options, "progress": False},
            priors=priors,
            output=output,
        )
    return tree, [str(w.message) for w in caught]


@pytest.mark.parametrize("pole_model", ["samples", "linear"])
def test_gibbs_reduces_to_the_exact_answer_as_the_noise_goes_to_zero(hydro_unit, pole_model):
    data = synthesize_modes(hydro_unit, samples=10, seed=3, shape_cov=1e-8, pole_variance=(1e-12, 1e-12))
    tree, _ = _run(
        hydro_unit,
        data,
        "bearings",
        "gibbs",
        draws=30,
        chains=1,
        seed=0,
        eps_std=1e-9,
        pole_model=pole_model,
        noise_model="diagonal",
        collapsed=False,
    )
    table = summary(tree["posterior"].to_dataset(), _truth(hydro_unit))
    assert table.sizes["parameter"] == 46
    np.testing.assert_allclose(table["mean"], table["truth"], rtol=1e-4)


def test_case_b_regression_on_paper_data(hydro_unit, paper_modes):
    tree, messages = _run(hydro_unit, paper_modes, "bearings", "paper", draws=200, chains=2, seed=1)
    table = summary(tree["posterior"].to_dataset(), _truth(hydro_unit))
    err = {str(p): float(e) for p, e in zip(table["parameter"].values, table["map_error"].values)}
    well_determined = [
        "UGB.kxx",
        "UGB.kyx",
        "UGB.kyy",
        "UGB.cxx",
        "UGB.cyy",
        "LGB.kxy",
        "LGB.kyx",
        "LGB.cxx",
        "LGB.cyy",
        "FSI.added_mass_3",
        "FSI.added_mass_4",
        "FSI.added_mass_10",
        "FSI.added_damping_2",
        "FSI.added_damping_4",
        "FSI.added_damping_10",
        "FSI.added_damping_11",
        "FSI.added_damping_14",
    ]
    # 4%: the paper's 1-3% plus the Monte Carlo error of 2 x 200 draws (the largest, added_mass_3, moves
    # between 2.7% and 3.7% with the chains' random stream)
    for name in well_determined:
        assert abs(err[name]) < 0.04, (name, err[name])
    # the modes near a resonance of the unobserved DOFs are flagged, and the hardly determined parameters named
    flagged = {int(m.split()[1]) for m in messages if "resonance of the unobserved" in m}
    assert flagged == {5, 6, 12, 13, 15}
    assert any("hardly determine" in m and "LGB.kyy" in m for m in messages)
    assert float(table["r_hat"].sel(parameter="UGB.kxx")) < 1.05


def test_case_a_regression_and_burn_in_from_zero(hydro_unit, paper_modes):
    tree, _ = _run(hydro_unit, paper_modes, None, "paper", draws=150, chains=1, seed=2, warmup=0)
    post = tree["posterior"]
    mass = post["added_mass"].isel(chain=0).values
    for mode in (3, 4, 10, 11):  # runner-dominated modes: ~1-3% as in the paper
        assert abs(np.median(mass[:, mode - 1]) / PAPER_TABLE2.added_mass[mode - 1] - 1) < 0.04
    # started from zero, the chain is in its stationary range within 10 sweeps (the paper: burn-in < 10)
    m10 = mass[:, 9]
    lo, hi = np.quantile(m10[50:], [0.005, 0.995])
    assert np.all((m10[10:] > lo - (hi - lo)) & (m10[10:] < hi + (hi - lo)))
    assert post["added_damping"].attrs["units"] == "N s/m"


def test_full_noise_and_linear_pole_models_give_calibrated_case_a_intervals(hydro_unit, paper_modes):
    # the pole noise moves every residual row together: with a full Δ_i (inverse-Wishart) the 90% intervals
    # cover the truth; with the paper's diagonal Δ_i they are too narrow (|z| up to 9 on these data, coverage
    # about 50%). Linearised in the pole, the modes near a resonance of the unobserved DOFs lose the bias the
    # model's curvature puts into their residuals: with the bases at every pole sample, the added damping of
    # modes 13 and 15 sits at |z| = 49 and 12 on these data; linearised, every |z| is below 3.7.
    # benchmarks/update_cases.py --noise-model --pole-model measures them over 20 seeds. Flat priors: the
    # default one on the added damping (std 1.7e8 N s/m) pulls mode 15's, which this model puts at a third of
    # its truth of 1.37e8, further down (|z| 3.7 -> 4.6); the default sampler determines it to 0.4%.
    tree, _ = _run(
        hydro_unit,
        paper_modes,
        None,
        "gibbs",
        "flat",
        draws=300,
        chains=1,
        seed=2,
        noise_model="full",
        collapsed=False,
        pole_model="linear",
    )
    settings = json.loads(tree.attrs["settings"])
    assert settings["noise_model"] == "full" and settings["pole_model"] == "linear"
    table = summary(tree["posterior"].to_dataset(), _truth(hydro_unit))
    assert table.sizes["parameter"] == 30
    assert np.all(np.abs(table["z_score"]) < 4), table["z_score"].to_series().abs().nlargest(3)
    inside = (table["q05"] <= table["truth"]) & (table["truth"] <= table["q95"])
    assert float(inside.mean()) >= 0.8
    with pytest.raises(UpdateError, match="unknown noise model 'banded'; choose one of diagonal, full"):
        update(hydro_unit, paper_modes, None, fsi=True, method="gibbs", options={"noise_model": "banded"})


def test_posterior_file_round_trip_through_arviz_and_datatree(hydro_unit, paper_modes, tmp_path):
    az = pytest.importorskip("arviz")
    sub = paper_modes.isel(mode=[2, 3, 9])
    out = tmp_path / "posterior.nc"
    tree, _ = _run(hydro_unit, sub, "LGB.k*", draws=40, chains=2, seed=5, output=out)
    idata = az.from_netcdf(out)
    assert set(idata.groups()) >= {"posterior", "sample_stats", "observed_data", "constant_data"}
    assert idata.posterior["theta"].dims == ("chain", "draw", "parameter")
    assert list(idata.posterior["parameter"].values) == ["LGB.kxx", "LGB.kxy", "LGB.kyx", "LGB.kyy"]
    assert list(idata.posterior["units"].values) == ["N/m"] * 4  # each parameter's SI unit, as a coordinate
    assert idata.posterior["added_mass"].dims == ("chain", "draw", "mode")
    back = read_posterior(out)
    xr.testing.assert_allclose(back["posterior"]["theta"], tree["posterior"]["theta"])
    with xr.open_datatree(out) as dt:
        assert "shape_real" in dt["posterior"] and dt.attrs["condensation"] == "stage 2"
    settings = json.loads(back.attrs["settings"])
    assert settings["draws"] == 40 and settings["params"][0] == "LGB.kxx"
    assert "truth" in back.attrs and set(json.loads(back.attrs["diagnostics"])) >= {"LGB.kxy", "FSI.added_mass_3"}


def test_apply_posterior_updates_the_twin(hydro_unit):
    post = xr.Dataset(
        {
            "theta": (("chain", "draw", "parameter"), np.full((1, 4, 1), 7.0e8)),
            "added_mass": (("chain", "draw", "mode"), np.full((1, 4, 2), 5.0e4)),
            "added_damping": (("chain", "draw", "mode"), np.full((1, 4, 2), 1.0e6)),
        },
        coords={"parameter": ["UGB.kxx"], "mode": [1, 2]},
    )
    m = apply_posterior(hydro_unit, post, "mean")
    assert m.parameter("UGB.kxx").nominal == 7.0e8
    fsi = [e for e in m.effects if isinstance(e, FluidAddedMassPerMode)]
    assert fsi and fsi[0].added_mass == (5.0e4, 5.0e4)
    assert m.parameter("FSI.added_damping_2").nominal == 1.0e6
    sub = post.assign(added_mass=post["added_mass"] * [1.0, 2.0]).assign_coords(mode=[4, 3])
    sub = apply_posterior(m, sub, "mean")
    fsi = [e for e in sub.effects if isinstance(e, FluidAddedMassPerMode)]
    assert fsi[0].added_mass == (5.0e4, 5.0e4, 1.0e5, 5.0e4)  # modes 1, 2 kept, 3 and 4 replaced
    with pytest.raises(Exception, match="distinct target modes numbered from 1"):
        apply_posterior(hydro_unit, post.assign_coords(mode=[0, 1]))


def test_a_posterior_estimate_on_or_beyond_a_physical_bound_is_applied_with_a_warning_naming_it(hydro_unit):
    def post(value):
        return xr.Dataset(
            {"theta": (("chain", "draw", "parameter"), np.full((1, 2, 1), value))}, coords={"parameter": ["UGB.kxx"]}
        )

    with pytest.warns(TwinWarning, match=r"UGB.kxx is on its physical bound, 0 \(bounds \[0, inf\]\)"):
        assert apply_posterior(hydro_unit, post(0.0)).parameter("UGB.kxx").nominal == 0.0
    with pytest.warns(TwinWarning, match="UGB.kxx, -5e.07, lies outside its physical bounds"):
        assert apply_posterior(hydro_unit, post(-5e7)).parameter("UGB.kxx").nominal == 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        apply_posterior(hydro_unit, post(7e8))


def test_a_mode_with_samples_below_the_axis_is_updated_and_a_conjugate_mode_refused(hydro_unit, paper_modes, caplog):
    """An extraction's scaled jackknife samples of a heavily damped mode may reach Im <= 0 (FMU record 10445,
    3.5 Hz at 16% damping: 4 of 60): the mean pole is the mode, so the update takes it and says so; a mode
    whose mean pole is the conjugate one is refused, naming it."""
    sub = paper_modes.isel(mode=[2, 3]).copy(deep=True)
    sub["pole"][0, :3] = sub["pole"][0, :3].real - 1j * abs(sub["pole"][0, :3].imag) * 0.1
    assert sub["pole"][0].mean().imag > 0
    with caplog.at_level("WARNING", logger="twin.update.problem"):
        problem = build_problem(hydro_unit, sub, [], fsi=True, pole_model="marginal")
    assert problem.psi_hat.shape[0] == 2  # both modes kept
    assert "mode 3 has 3 of 100 pole samples with Im <= 0" in caplog.text
    flipped = sub.copy(deep=True)
    flipped["pole"][1] = flipped["pole"][1].conj()
    with pytest.raises(UpdateError, match="mode 4 has its mean pole at Im <= 0"):
        update(hydro_unit, flipped, None, fsi=True, options={"progress": False})


def test_bad_requests_are_named(hydro_unit, paper_modes):
    sub = paper_modes.isel(mode=[2, 3])
    with pytest.raises(UpdateError, match="nothing to update"):
        update(hydro_unit, sub, None, options={"progress": False})
    with pytest.raises(ModelError, match="no parameter 'UGB.kzz'"):
        update(hydro_unit, sub, "UGB.kzz", options={"progress": False})
    with pytest.raises(ModelError, match="matches no parameter"):
        update(hydro_unit, sub, "XYZ.*", options={"progress": False})
    with pytest.raises(UpdateError, match="draws must be"):
        update(hydro_unit, sub, None, fsi=True, options={"draws": 0})
    bad = sub.copy(deep=True)
    bad["pole"][1, 7] = np.nan
    with pytest.raises(UpdateError, match="'pole' is not finite at mode=4, sample=7"):
        update(hydro_unit, bad, None, fsi=True, options={"progress": False})
    still = sub.copy(deep=True)
    still["pole"][0, :] = still["pole"][0, 0]
    with pytest.raises(UpdateError, match=r"mode\(s\) \[3\] have 100 equal pole samples.*samples that differ"):
        update(hydro_unit, still, None, fsi=True, options={"progress": False})
    renamed = sub.assign_coords(channel=["SEAL_x", "SEAL_y", "UGB_x", "UGB_y", "LGB_x", "LGB_y", "GEN_x", "EXC_y"])
    with pytest.raises(UpdateError, match=r"channel\(s\) \['EXC_y'\] are not sensors"):
        update(hydro_unit, renamed, None, fsi=True, options={"progress": False})
    with pytest.raises(UpdateError, match="unknown pole model 'mean'; choose one of samples, linear"):
        update(hydro_unit, sub, None, fsi=True, method="gibbs", options={"pole_model": "mean"})
    with pytest.raises(UpdateError, match="pole_error must be one of samples\\+orders, samples, got 'orders'"):
        update(hydro_unit, sub, None, fsi=True, options={"pole_error": "orders"})
    with pytest.raises(UpdateError, match="the 'gibbs' sampler has no option pole_error"):
        update(hydro_unit, sub, None, fsi=True, method="gibbs", options={"pole_error": "samples"})
    with pytest.raises(UpdateError, match="the 'hmc' sampler takes HMCOptions, got GibbsOptions"):
        update(hydro_unit, sub, None, fsi=True, options=GibbsOptions())
    with pytest.raises(UpdateError, match="unknown method 'nuts'; choose one of hmc, gibbs, paper, laplace"):
        update(hydro_unit, sub, None, fsi=True, method="nuts")
    with pytest.raises(UpdateError, match="priors must be 'plausible', 'flat' or a mapping"):
        update(hydro_unit, sub, None, fsi=True, priors="wide")
    with pytest.raises(UpdateError, match="prior given for 'UGB.kxx', which is not updated"):
        update(hydro_unit, sub, None, fsi=True, priors={"UGB.kxx": (1e9, 1e8)})
    # the runner mass and the per-mode added mass have the same footprint: not identifiable together
    with pytest.raises(UpdateError, match="cannot determine.*runner.m"):
        update(hydro_unit, sub, "runner.m", fsi=True, options={"draws": 5, "chains": 1, "progress": False})


def test_the_poles_order_spread_widens_what_the_poles_say(hydro_unit):
    # modes 3 and 4 with poles 100 times more precise than the paper's (so the added mass is read from them)
    # and a spread over model orders 10 times their mean pole's covariance: by default the added mass's std
    # grows by up to sqrt(11) (measured 2.9-4.0); with pole_error="samples" it is as without the spread
    data = synthesize_modes(hydro_unit, samples=50, seed=1, pole_variance=(1e-4, 1e-4)).isel(mode=[2, 3])
    d = data["pole"].values - data["pole"].values.mean(axis=1, keepdims=True)
    parts = np.stack([d.real, d.imag], axis=-1)
    mean_cov = np.einsum("ija,ijb->iab", parts, parts) / (d.shape[1] - 1) / d.shape[1]
    spread = data.assign(pole_order_cov=(("mode", "pole_part", "pole_part_2"), 10.0 * mean_cov))
    std = {}
    for label, modes, error in (("orders", spread, None), ("samples", spread, "samples"), ("none", data, None)):
        options = {"draws": 200, "chains": 2, "seed": 3, "progress": False, **({"pole_error": error} if error else {})}
        tree = update(hydro_unit, modes, None, fsi=True, options=options)
        std[label] = tree["posterior"]["added_mass"].std(("chain", "draw")).values
    np.testing.assert_allclose(std["samples"], std["none"])
    assert np.all(std["orders"] > 2.0 * std["samples"]), (std["orders"], std["samples"])


def test_synthetic_modes_follow_the_paper_noise_model(hydro_unit, paper_truth_modes):
    ds = synthesize_modes(hydro_unit, samples=4000, seed=7)
    dev = ds["pole"].values - paper_truth_modes.poles[:, None]
    np.testing.assert_allclose(np.var(dev.real, axis=1).mean(), 1.58, rtol=0.03)
    np.testing.assert_allclose(np.var(dev.imag, axis=1).mean(), 1.1, rtol=0.03)
    shape = ds["shape"].values
    true = ds["sensor_shape"].values
    big = np.abs(true.real) > 0.1
    cov = np.std(shape.real, axis=1) / np.abs(true.real)
    np.testing.assert_allclose(cov[big].mean(), 0.05, rtol=0.05)
    assert json.loads(ds.attrs["truth"])["effects"]["fsi_per_mode"]["added_mass"][0] == 1.0e5
    np.testing.assert_allclose(ds["frequency"].values, paper_truth_modes.poles.imag / (2 * np.pi))


@pytest.mark.slow
def test_cli_synthesizes_and_updates(hydro_unit, tmp_path, capsys):
    modes = tmp_path / "modes.nc"
    assert main(["synthesize-modes", "models/hydro_unit.toml", "-o", str(modes), "--samples", "20", "--seed", "4"]) == 0
    sub = tmp_path / "sub.nc"
    from twin.modes.modesfile import read_modes

    write_modes(read_modes(modes).isel(mode=[2, 3, 9]), sub)
    post = tmp_path / "post.nc"
    code = main(
        [
            "update",
            "models/hydro_unit.toml",
            str(sub),
            "-o",
            str(post),
            "--fsi",
            "--draws",
            "30",
            "--chains",
            "2",
            "--seed",
            "1",
            "--workers",
            "2",
        ]
    )  # (chains on a local Dask cluster)
    out = capsys.readouterr().out
    assert code == 0 and post.is_file() and "FSI.added_mass_3" in out and "R-hat" in out
    back = read_posterior(post)
    settings = json.loads(back.attrs["settings"])
    assert settings["method"] == "hmc" and back.attrs["method"] == "hmc"  # the calibrated sampler is the default
    assert back["sample_stats"]["accepted"].dims == ("chain", "draw") and bool(back["sample_stats"]["accepted"].any())
    paper = tmp_path / "paper.nc"
    assert (
        main(
            [
                "update",
                "hydro_unit",
                str(sub),
                "-o",
                str(paper),
                "--fsi",
                "--draws",
                "10",
                "--chains",
                "1",
                "--method",
                "paper",
                "-q",
            ]
        )
        == 0
    )
    settings = json.loads(read_posterior(paper).attrs["settings"])
    assert (
        settings["method"] == "paper"
        and "Gibbs (diagonal Delta, samples pole model)" in read_posterior(paper).attrs["sampler"]
    )
    assert not read_posterior(paper)["sample_stats"]["accepted"].any()
    gibbs = tmp_path / "gibbs.nc"
    assert (
        main(
            [
                "update",
                "hydro_unit",
                str(sub),
                "-o",
                str(gibbs),
                "--fsi",
                "--draws",
                "10",
                "--chains",
                "1",
                "--method",
                "gibbs",
                "--no-collapsed",
                "--warmup",
                "5",
                "-q",
            ]
        )
        == 0
    )
    settings = json.loads(read_posterior(gibbs).attrs["settings"])
    assert (settings["method"], settings["collapsed"], settings["warmup"], settings["pole_model"]) == (
        "gibbs",
        False,
        5,
        "linear",
    )
    assert (
        main(["update", "hydro_unit", str(sub), "-o", str(tmp_path / "x.nc"), "--fsi", "--noise-model", "diagonal"])
        == 2
    )
    assert "the 'hmc' sampler has no option noise_model" in capsys.readouterr().err
    assert main(["update", "models/hydro_unit.toml", str(sub), "-o", str(tmp_path / "x.nc")]) == 2
    assert "nothing to update" in capsys.readouterr().err
    assert (
        main(["update", "models/hydro_unit.toml", str(tmp_path / "none.nc"), "-o", str(tmp_path / "x.nc"), "--fsi"])
        == 2
    )
    assert "no such modes file" in capsys.readouterr().err
    assert not (tmp_path / "x.nc").exists()
