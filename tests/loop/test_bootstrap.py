"""Tests of twin.loop.bootstrap: the posterior's spread calibrated on records simulated at its estimate."""

import json
import warnings

import numpy as np
import pytest

from tests.conftest import DATA
from twin.errors import TwinError, TwinWarning
from twin.loop.bootstrap import (
    MAX_BATCHES,
    bootstrap_factors,
    calibrated,
    record_seeds,
    record_settings,
    target_numbered,
)
from twin.loop.pooling import MIN_RECORDS


def _seal_update(hydro_unit, draws: int = 500):
    """The sampler's update of the seal on the modes of FMU record 10130 (a 20-min record), not calibrated:
    twin, posterior."""
    from twin.loop.twin import Twin
    from twin.modes.modesfile import read_modes

    tw = Twin(hydro_unit, read_modes(DATA / "modes_seal_10130.nc"))
    tw.add_effect("seal_cross_coupling")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TwinWarning)
        post = tw.update(tw.added_parameters(), seed=10130, draws=draws, progress=False, bootstrap=0)
    return tw, post


@pytest.mark.slow
def test_the_fitted_density_is_the_update_s(hydro_unit):
    # each bootstrap record is fitted with the update's own density (marginal_setup from the posterior's
    # settings): on the measured modes themselves its mode and Laplace std must be the HMC posterior's, within
    # the draws' Monte Carlo error (bulk ESS about 1500: the mean to 0.03 std) and the Laplace's curvature
    from twin.update.marginal import posterior_mode
    from twin.update.samplers.hmc import marginal_setup

    tw, post = _seal_update(hydro_unit)
    settings = json.loads(post.attrs["settings"])
    marg, prior = marginal_setup(tw.model, tw.modes, settings)
    theta, here = posterior_mode(marg, prior.parameter_mean, prior.parameter_precision)
    scale = marg.problem.global_scale[0]
    draws = post["posterior"]["theta"].sel(parameter="SEAL.kxy").values.ravel()
    std = np.sqrt(np.linalg.inv(here.precision)[0, 0]) * scale
    assert abs(theta[0] * scale - draws.mean()) < 0.1 * draws.std()
    assert std == pytest.approx(draws.std(), rel=0.1)


def test_factors_are_the_records_rms_error_in_the_posterior_s_std(hydro_unit):
    # the records' fits given (a mapper that stands for the simulation): error = mode - estimate, its RMS over
    # the records that have it, in the std of the measured posterior's draws
    tw, post = _seal_update(hydro_unit, draws=50)
    estimate = {"SEAL.kxy": 5.0e7}
    fits = [
        {"SEAL.kxy": (5.0e7 + 1e6, 1e6)},
        {"SEAL.kxy": (5.0e7 - 4e6, 2e6)},
        "record 3: no mode",
        {"SEAL.kxy": (5.0e7, 5e5)},
        {"SEAL.kxy": (5.0e7 + 3e6, 1e6)},
    ]
    factors = bootstrap_factors(
        tw.model, tw.model, tw.modes, post, estimate, records=5, tasks=lambda function, items, **shared: fits
    )
    np.testing.assert_allclose(factors["error"].sel(parameter="SEAL.kxy").values, [1e6, -4e6, np.nan, 0.0, 3e6])
    np.testing.assert_allclose(factors["z"].sel(parameter="SEAL.kxy").values, [1.0, -2.0, np.nan, 0.0, 3.0])
    assert float(factors["rms_z"][0]) == pytest.approx(np.sqrt((1 + 4 + 0 + 9) / 4))
    sigma = post["posterior"]["theta"].sel(parameter="SEAL.kxy").values.std()
    assert float(factors["posterior_std"][0]) == pytest.approx(sigma, rel=1e-12)
    assert float(factors["rms_error"][0]) == pytest.approx(np.sqrt(26 / 4) * 1e6)
    assert float(factors["error_ratio"][0]) == pytest.approx(np.sqrt(26 / 4) * 1e6 / sigma)
    # the 90% interval of an error whose variance comes from 4 records: Student's t, 4 degrees of freedom
    widening = 2.131847 / 1.644854
    assert float(factors["factor"][0]) == pytest.approx(np.sqrt(26 / 4) * 1e6 / sigma * widening, rel=1e-6)
    assert int(factors["records_used"][0]) == 4
    assert float(factors["pooled_error_ratio"][0]) == float(factors["error_ratio"][0])  # one parameter: no pool
    # seen on 2 records of 5: two more batches of 5 (MAX_BATCHES), which find none, then too few to calibrate
    batches = iter([fits[:2] + ["x"] * 3, ["x"] * 5, ["x"] * 5])
    with pytest.raises(TwinError, match=f"fitted on 2 of {5 * MAX_BATCHES}"):
        bootstrap_factors(
            tw.model,
            tw.model,
            tw.modes,
            post,
            estimate,
            records=5,
            tasks=lambda function, items, **shared: next(batches),
        )
    with pytest.raises(TwinError, match=f"integer >= {MIN_RECORDS}"):
        bootstrap_factors(tw.model, tw.model, tw.modes, post, estimate, records=2)
    with pytest.raises(TwinError, match="lacks SEAL.kxy"):
        bootstrap_factors(tw.model, tw.model, tw.modes, post, {}, records=5)


def test_a_parameter_seen_on_too_few_records_is_seen_on_more(hydro_unit):
    # a mode found in one simulated record of five: batches of five more records until it was seen on
    # MIN_RECORDS; a parameter never seen asks for none (it has no factor); the first batch's seeds are the
    # seeds of a bootstrap of 5 records
    tw, post = _seal_update(hydro_unit, draws=50)
    estimate = {"SEAL.kxy": 5.0e7}
    seen, unseen = {"SEAL.kxy": (5.0e7 + 1e6, 1e6)}, "record: no mode"
    asked = []

    def tasks(function, items, **shared):
        asked.append(list(items))
        return [seen if (len(asked) - 1) * 5 + k in (2, 6, 7) else unseen for k in range(len(items))]

    factors = bootstrap_factors(tw.model, tw.model, tw.modes, post, estimate, records=5, seed=3, tasks=tasks)
    assert [len(a) for a in asked] == [5, 5] and asked[0] == record_seeds(3, 5)
    assert factors.sizes["record"] == 10 and factors["record"].values.tolist() == asked[0] + asked[1]
    assert int(factors["records_used"][0]) == 3
    assert float(factors["rms_z"][0]) == pytest.approx(1.0)
    assert float(factors["rms_error"][0]) == pytest.approx(1e6)
    # seen on none of the first five (the estimate's mode is not what the sensors see): no more records,
    # and nothing to calibrate on
    asked.clear()
    with pytest.raises(TwinError, match="fitted on 0 of 5"):
        bootstrap_factors(
            tw.model,
            tw.model,
            tw.modes,
            post,
            estimate,
            records=5,
            tasks=lambda function, items, **shared: asked.append(items) or [unseen] * len(items),
        )
    assert len(asked) == 1


def test_calibrated_stretches_determined_draws_only_and_keeps_the_mean(hydro_unit):
    import xarray as xr

    _, post = _seal_update(hydro_unit, draws=50)
    factors = xr.Dataset({"factor": ("parameter", [1.5])}, coords={"parameter": ["SEAL.kxy"], "record": [1, 2, 3]})
    before = post["posterior"]["theta"].values
    out = calibrated(post, factors, ["SEAL.kxy"])
    after = out["posterior"]["theta"].values
    assert after.mean() == pytest.approx(before.mean(), rel=1e-12)
    assert after.std() == pytest.approx(1.5 * before.std(), rel=1e-12)
    assert json.loads(out.attrs["bootstrap_calibration"]) == {"SEAL.kxy": 1.5}
    assert json.loads(out.attrs["bootstrap_records"]) == [1, 2, 3]
    assert float(out["bootstrap"]["factor"][0]) == 1.5  # the records' errors travel with the posterior
    np.testing.assert_array_equal(post["posterior"]["theta"].values, before)  # the input is left alone
    kept = calibrated(post, factors, [])  # not determined: its prior-bound draws stay
    np.testing.assert_array_equal(kept["posterior"]["theta"].values, before)


def test_record_settings_say_what_is_missing():
    import xarray as xr

    with pytest.raises(TwinError, match="attr 'settings'"):
        record_settings(xr.Dataset())
    assert record_seeds(7, 3) != record_seeds(8, 3)


@pytest.mark.slow
def test_bootstrap_update_of_a_short_record_end_to_end(hydro_unit):
    # the whole path on 4-min records (the fixture's settings with the length shortened): simulate through the
    # FMU, extract with the modes' settings, fit, stretch. Each record's fit finds the seal
    from twin.loop.twin import Twin
    from twin.modes.modesfile import read_modes

    modes = read_modes(DATA / "modes_seal_10130.nc")
    settings = json.loads(modes.attrs["settings"])
    modes.attrs["settings"] = json.dumps({**settings, "duration_s": 240.0})
    tw = Twin(hydro_unit, modes)
    tw.add_effect("seal_cross_coupling")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TwinWarning)
        post = tw.update(tw.added_parameters(), seed=1, draws=100, progress=False, bootstrap=3)
    applied = json.loads(post.attrs["bootstrap_calibration"])
    assert set(applied) == {"SEAL.kxy"} and 0.1 < applied["SEAL.kxy"] < 10
    assert len(json.loads(post.attrs["bootstrap_records"])) == 3
    assert tw.model.parameter("SEAL.kxy").nominal > 0
    assert tw.history[-1].action == "update SEAL.kxy, calibrated on 3 simulated records"
    assert [s.action for s in tw.history].count("update SEAL.kxy") == 0  # the step is replaced, not added


def test_calibrate_needs_the_sampler_s_update(hydro_unit):
    from twin.loop.twin import Twin
    from twin.modes.modesfile import read_modes

    tw = Twin(hydro_unit, read_modes(DATA / "modes_seal_10130.nc"))
    with pytest.raises(ValueError, match="needs the HMC sampler's update"):
        tw.calibrate(5)
    tw.add_effect("seal_cross_coupling")
    with pytest.raises(ValueError, match="needs method='hmc'"):
        tw.update(["SEAL.kxy"], method="laplace", bootstrap=5)
    with pytest.raises(ValueError, match="needs method='hmc'"):
        tw.run(method="laplace", bootstrap=5)


def test_the_sampler_s_update_of_a_record_is_calibrated_by_default(hydro_unit, monkeypatch):
    # the loop's default: DEFAULT_RECORDS records for the sampler on modes extracted from a record, none for the
    # Laplace fit or when told 0, and none for modes that came from no record (synthesize_modes)
    from twin.loop.bootstrap import DEFAULT_RECORDS
    from twin.loop.twin import Twin
    from twin.modes.modesfile import read_modes
    from twin.update import synthesize_modes

    asked = []
    monkeypatch.setattr(Twin, "calibrate", lambda self, records, **kw: asked.append(records) or self.posterior)
    tw = Twin(hydro_unit, read_modes(DATA / "modes_seal_10130.nc"))
    tw.add_effect("seal_cross_coupling")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TwinWarning)
        tw.update(["SEAL.kxy"], seed=1, draws=20, chains=1, progress=False)
        tw.update(["SEAL.kxy"], seed=1, draws=20, chains=1, progress=False, bootstrap=0)
        tw.update(["SEAL.kxy"], method="laplace")
    assert asked == [DEFAULT_RECORDS] == [12]
    synthetic = Twin(hydro_unit, synthesize_modes(hydro_unit, samples=20, seed=1))
    synthetic.add_effect("seal_cross_coupling")
    synthetic.update(["SEAL.kxy"], seed=1, draws=20, chains=1, progress=False)
    assert asked == [12]
    with pytest.raises(ValueError, match="whole number of records"):
        tw.update(["SEAL.kxy"], bootstrap=2.5)


def test_a_simulated_record_s_modes_take_the_measured_numbers():
    # a record that lacks a mode (here the 3.84 Hz one of the seal record, dropped) keeps the numbers of the
    # others, so its per-mode FSI parameters are the measured modes'
    from twin.loop.bootstrap import matched_modes
    from twin.modes.modesfile import read_modes

    modes = read_modes(DATA / "modes_seal_10130.nc")
    reference = {int(m): float(f) for m, f in zip(modes["mode"].values, modes["frequency"].values)}
    assert matched_modes(modes, reference)["mode"].values.tolist() == list(range(1, 12))
    fewer = modes.drop_sel(mode=3).assign_coords(mode=range(1, 11))
    assert matched_modes(fewer, reference)["mode"].values.tolist() == [1, 2, *range(4, 12)]
    low = modes.isel(mode=range(7))  # up to 17.15 Hz, where 3% moves no mode onto another one
    shifted = low.assign(frequency=low["frequency"] * 1.03)  # 3% off: no mode is the measured one
    assert matched_modes(shifted, reference).sizes["mode"] == 0


def test_a_measured_mode_s_reference_is_the_simulated_system_s_frequency(hydro_unit):
    # the records scatter about the system simulated, so a measured mode extracted 1.3% off (as the 3.81 Hz
    # mode of seal record 10406) is matched at the system's frequency: a record's mode found where the system
    # has it keeps the measured number, one found where the measured one was too
    from twin.fem.effects import SealCrossCoupling
    from twin.fmu.truth import model_state_space
    from twin.loop.bootstrap import MATCH_TOLERANCE, matched_modes, simulated_reference
    from twin.modes.modesfile import read_modes

    modes = read_modes(DATA / "modes_seal_10130.nc")
    poles = model_state_space(hydro_unit.with_effects(SealCrossCoupling(5e7))).poles
    system_hz = np.abs(poles.imag) / (2 * np.pi)
    off = modes.copy()
    off["frequency"] = modes["frequency"].where(modes["mode"] != 3, 3.759)  # the truth's 3.8095 Hz, 1.3% off
    reference = simulated_reference(poles, off)
    assert list(reference) == modes["mode"].values.tolist()
    for label, f in reference.items():  # each measured mode is a pole of the system, within 1% of the truth's
        assert np.min(np.abs(system_hz - f)) < 1e-9 * f
        assert abs(f / float(abs(modes["frequency"].sel(mode=label))) - 1) < 0.01
    assert abs(reference[3] / float(off["frequency"].sel(mode=3)) - 1) > 0.012
    assert 3 in matched_modes(modes, reference)["mode"].values  # the record's mode where the system has it
    assert 3 in matched_modes(off, reference)["mode"].values  # and where the measured record had it
    assert MATCH_TOLERANCE >= 0.013
    far = off.assign(frequency=off["frequency"] * 1.2)  # no pole within 5%: the measured frequencies stay
    own = {int(m): float(f) for m, f in zip(far["mode"].values, far["frequency"].values)}
    assert simulated_reference(poles[:0], far) == simulated_reference(np.array([1j]), far) == own


def test_an_updated_per_mode_model_is_simulated_with_each_value_on_its_measured_mode(hydro_unit):
    # the update numbers per-mode FSI by measured mode; target mode 3 (9.2 Hz) unmeasured, the third measured
    # mode is target mode 4: simulated, each measured mode must come out as the comparison reads it
    from twin.fem.effects import FluidAddedMassPerMode
    from twin.fmu.truth import model_state_space
    from twin.loop.compare import model_modes
    from twin.modes.measured import measured_modes
    from twin.update import synthesize_modes

    modes = synthesize_modes(hydro_unit, samples=20, seed=1).sel(mode=[1, 2, 4, 5]).assign_coords(mode=[1, 2, 3, 4])
    updated = hydro_unit.with_effects(FluidAddedMassPerMode((1e5, 2e5, 4e5, 5e4), (1e7, 0.0, 5e6, 2e6)))
    expected = model_modes(updated, measured_modes(modes)).poles
    simulated = model_state_space(target_numbered(updated, modes)).poles
    nearest = simulated[np.argmin(np.abs(simulated[None, :] - expected[:, None]), axis=1)]
    np.testing.assert_allclose(nearest, expected, rtol=1e-9)
    as_numbered = model_state_space(updated).poles  # values by target number: measured mode 3 comes out wrong
    assert np.min(np.abs(as_numbered - expected[2])) > 1e-3 * abs(expected[2])
    assert target_numbered(hydro_unit, modes) is hydro_unit


def test_the_records_of_a_calibration_are_extracted_with_settings_that_work(make_record):
    """Whatever a user gave the extraction, its modes file records settings the calibration can extract its
    records with: ``--samples 15`` alone recorded ``shape_samples = 15``, which the extraction refused, and
    the loop lost its result after the work."""
    from twin.extract import extract

    poles = [-0.02 * 2 * np.pi * 2 + 2j * np.pi * 2, -0.01 * 2 * np.pi * 5 + 2j * np.pi * 5]
    record = make_record(poles, [[1.0, 0.3j, 0.5], [0.2, 1.0, -0.4j]], fs_hz=32.0, duration_s=600.0, seed=5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", TwinWarning)
        for given in ({"samples": 15}, {"samples": 10, "shape_samples": 40}, {"samples": 12, "delete_blocks": None}):
            modes = extract(record, fmax_hz=8.0, progress=False, **given)
            duration_s, fs_hz, options = record_settings(modes)
            again = extract(record, progress=False, **options)
            assert (duration_s, fs_hz) == (600.0, 32.0)
            np.testing.assert_array_equal(again["pole"].values, modes["pole"].values)


def test_a_calibration_that_cannot_run_keeps_the_sampler_s_posterior_with_a_warning(hydro_unit, monkeypatch):
    import twin.loop.bootstrap
    from twin.loop.twin import Twin
    from twin.modes.modesfile import read_modes

    def fails(*args, **kwargs):
        raise TwinError("the update's density was fitted on 0 of 3 simulated records")

    monkeypatch.setattr(twin.loop.bootstrap, "bootstrap_factors", fails)
    tw = Twin(hydro_unit, read_modes(DATA / "modes_seal_10130.nc"))
    tw.add_effect("seal_cross_coupling")
    with pytest.warns(
        TwinWarning,
        match=r"could not be calibrated on simulated records \(the update's density was "
        r"fitted on 0 of 3 simulated records\); it is the sampler's own",
    ):
        post = tw.update(tw.added_parameters(), seed=1, draws=100, progress=False, bootstrap=3)
    assert "bootstrap_calibration" not in post.attrs and tw.posterior is post
    assert tw.history[-1].action == "update SEAL.kxy (not calibrated)" and tw.history[-1].interval is not None
    assert tw.model.parameter("SEAL.kxy").nominal > 0
