"""twin.update.samplers.hmc: HMC on the marginal posterior."""

import warnings

import numpy as np
import pytest

from twin.errors import TwinWarning
from twin.fem.truthfile import PAPER_TABLE2
from twin.update import summary, synthesize_modes, update
from twin.update.marginal import (
    posterior_mode,
)
from twin.update.problem import select_parameters

from tests.conftest import DATA
from twin.update.samplers.hmc import MIN_STEPS, PATH_JITTER, PATH_LENGTH, run_chain


def test_mode_is_a_stationary_point_and_the_chain_samples_about_it(small):
    marg, _ = small
    zero = np.zeros(marg.size)
    theta, at = posterior_mode(marg, zero, zero)
    std = np.sqrt(np.diag(np.linalg.inv(at.precision)))
    assert np.all(np.abs(at.gradient) * std < 1e-3)  # within 1e-3 posterior std of the exact mode
    chain = run_chain(marg, 400, rng=np.random.default_rng(4))
    x = np.concatenate([chain.t, chain.eta.reshape(400, -1)], axis=1)
    assert 0.6 < chain.accepted.mean() < 1.0
    # where the data determine a parameter well (Laplace std < 10% of its scale) the posterior is close to
    # the Gaussian at the mode, a little wider: each mode's Student t carries less information than the
    # Gauss-Newton curvature (3 chains of 2000 draws: 1.08-1.27 times its std); 400 draws add about 10%
    sharp = std < 0.1
    assert sharp.sum() >= 6
    ratio = x[:, sharp].std(axis=0) / std[sharp]
    assert np.all((ratio > 0.85) & (ratio < 1.5)), ratio
    assert np.all(np.abs(x[:, sharp].mean(axis=0) - theta[sharp]) < 0.3 * std[sharp])
    # LGB.kxx and LGB.kyy from three modes are barely determined (std about 100%): the chain still spreads
    # over their (non-Gaussian) posterior instead of sticking
    assert np.all(x[:, ~sharp].std(axis=0) > 0.5 * std[~sharp])


@pytest.mark.slow
def test_the_per_mode_slice_step_keeps_the_posterior(small):
    # HMC alone and HMC followed by the slice step of each mode's own parameters sample the same posterior:
    # every mean within 4 Monte Carlo std of the difference (from each chain's bulk ESS), every std within 15%
    from twin.update.posterior import _arviz

    az = _arviz()
    marg, _ = small
    out = []
    for slicing in (True, False):
        chain = run_chain(marg, 1500, rng=np.random.default_rng(8), per_mode_slice=slicing)
        x = np.concatenate([chain.t, chain.eta.reshape(1500, -1)], axis=1)
        ess = np.array([az.ess(x[None, :, k]) for k in range(marg.size)])
        out.append((x, ess))
    (x1, e1), (x2, e2) = out
    se = np.sqrt(x1.var(axis=0) / e1 + x2.var(axis=0) / e2)
    assert np.all(np.abs(x1.mean(axis=0) - x2.mean(axis=0)) < 4 * se)
    np.testing.assert_allclose(x1.std(axis=0), x2.std(axis=0), rtol=0.15)


@pytest.mark.slow
def test_a_quarter_turn_decorrelates_the_draws_and_their_spread(small):
    """Lag-one autocorrelation of each parameter and of its squared deviation, one chain of 2000 draws.

    A path of about a quarter period turns the Gaussian at the mode by 90 degrees: a draw independent of the
    last in its value and its square (0.18 for an exact Gaussian with ±20% jitter; measured 0.08-0.25 here).
    The earlier half turn (length 3, ±50%) gave antithetic values (-0.33 to -0.43) and squares that followed
    each other (0.37-0.56), which the interval's quantiles and the folded R-hat depend on.
    """
    marg, _ = small
    chain = run_chain(marg, 2000, rng=np.random.default_rng(4))
    x = np.concatenate([chain.t, chain.eta.reshape(2000, -1)], axis=1)
    z = (x - x.mean(axis=0)) / x.std(axis=0)

    def lag_one(v: np.ndarray) -> np.ndarray:
        v = v - v.mean(axis=0)
        return (v[1:] * v[:-1]).mean(axis=0) / v.var(axis=0)

    assert np.all(np.abs(lag_one(z)) < 0.4), lag_one(z)
    assert np.all(lag_one(z**2) < 0.33), lag_one(z**2)


def test_zero_noise_limit_is_the_exact_answer(hydro_unit):
    data = synthesize_modes(hydro_unit, samples=10, seed=3, shape_cov=1e-8, pole_variance=(1e-12, 1e-12))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TwinWarning)
        tree = update(
            hydro_unit,
            data,
            "bearings",
            fsi=True,
            options={"draws": 30, "chains": 1, "seed": 0, "eps_std": 1e-09, "progress": False},
        )
    truth = {n: hydro_unit.parameter(n).nominal for n in select_parameters(hydro_unit, "bearings")}
    for i, (m, c) in enumerate(zip(PAPER_TABLE2.added_mass, PAPER_TABLE2.added_damping), start=1):
        truth[f"FSI.added_mass_{i}"], truth[f"FSI.added_damping_{i}"] = m, c
    table = summary(tree["posterior"].to_dataset(), truth)
    assert table.sizes["parameter"] == 46
    np.testing.assert_allclose(table["mean"], table["truth"], rtol=1e-4)


def test_default_mixes_every_case_b_parameter(hydro_unit, case_b_posterior):
    # paper Case B (16 bearings, 30 FSI parameters, J = 100): the Gibbs default left LGB.kxy and mode 13's
    # FSI at bulk ESS 2 of 500; on the marginal every parameter mixes, and the determined ones have the
    # paper's accuracy (about 1-3%; 4% allows for the Monte Carlo error of 2 x 500 draws)
    tree = case_b_posterior
    truth = {n: hydro_unit.parameter(n).nominal for n in select_parameters(hydro_unit, "bearings")}
    for i, (m, c) in enumerate(zip(PAPER_TABLE2.added_mass, PAPER_TABLE2.added_damping), start=1):
        truth[f"FSI.added_mass_{i}"], truth[f"FSI.added_damping_{i}"] = m, c
    table = summary(tree["posterior"].to_dataset(), truth)
    assert float(table["ess_bulk"].min()) >= 200  # 100 per chain of 500
    assert float(table["r_hat"].max()) <= 1.02
    determined = (table["std"] / np.abs(table["truth"])) < 0.02  # (LGB.cxy, std 3.6%: the paper's 20%)
    assert int(determined.sum()) >= 35
    assert float(np.abs(table["map_error"].where(determined)).max()) < 0.04
    assert float(np.abs(table["z_score"]).max()) < 3.5
    inside = (table["q05"] <= table["truth"]) & (table["truth"] <= table["q95"])
    assert float(inside.mean()) >= 0.8  # 90% intervals; 46 values


def _update_record(hydro_unit, name: str, effect: str, seed: int):
    """The sampler's default update of ``effect`` on the extracted modes ``tests/data/<name>``, without the loop's
    calibration on simulated records (it stretches the draws; R-hat and ESS are the sampler's): the posterior and
    its table."""
    from twin.modes.modesfile import read_modes
    from twin.harness.demo import posterior_table
    from twin.loop.twin import Twin

    tw = Twin(hydro_unit, read_modes(DATA / name))
    tw.add_effect(effect)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TwinWarning)
        post = tw.update(tw.added_parameters(), seed=seed, progress=False, bootstrap=0)
    return post, posterior_table(post, tw.model)


@pytest.mark.slow
def test_default_mixes_a_per_mode_fsi_record_where_hmc_alone_did_not(hydro_unit):
    # modes extracted from the 20-min FMU record of seed 10034 with per-mode FSI in its truth; mode
    # 5's added damping is barely determined, with a long tail. HMC alone (per_mode_slice=False, sampler seed
    # 10034) had a chain set its metric in that tail: R-hat 1.034 and bulk ESS 168 for determined values of
    # other modes. With the per-mode slice step every determined value mixes (1.003 and 1853 measured)
    _, table = _update_record(hydro_unit, "modes_fsi_per_mode_10034.nc", "fsi_per_mode", seed=10034)
    determined = table["determined"].values.astype(bool)
    assert determined.sum() >= 14  # of 20: mode 5's damping and a few others are reported as not determined
    assert float(table["r_hat"].values[determined].max()) <= 1.01
    assert float(table["ess_bulk"].values[determined].min()) >= 400  # 100 per chain of 500


@pytest.mark.slow
def test_one_parameter_chains_take_two_leapfrog_steps_and_agree(hydro_unit):
    # modes extracted from the 20-min FMU record of seed 10130 with a seal cross-coupling in its truth,
    # one parameter. When a trajectory could be one leapfrog step, each chain's dual averaging ended either side
    # of the path length, by chance: the four chains of sampler seed 10130 accepted 71-96% (one step of about
    # the path length, or two), bulk ESS 855 and R-hat 1.0118. With two steps at least (and the step size capped
    # where that many steps cover the longest path) they accept alike: 95% each, ESS 1581, R-hat 1.0047 measured
    post, table = _update_record(hydro_unit, "modes_seal_10130.nc", "seal_cross_coupling", seed=10130)
    assert table.sizes["parameter"] == 1 and bool(table["determined"][0])
    assert float(table["r_hat"][0]) <= 1.01
    assert float(table["ess_bulk"][0]) >= 1000  # of 2000 draws: about a quarter turn a trajectory
    stats = post["sample_stats"]
    assert int(stats["n_steps"].min()) >= MIN_STEPS == 2
    assert float(stats["step_size"].max()) <= PATH_LENGTH * (1 + PATH_JITTER) / MIN_STEPS
    rates = stats["acceptance_rate"].mean("draw").values
    assert np.all((rates > 0.85) & (rates < 1.0)), rates  # one step of about the path length accepts 71-80%
