"""Diagnosis on synthetic modes with a hidden effect (paper Figure 2 procedure, fixed seeds).

Each truth hides one library effect from a twin that lacks it. The modes have
pole noise of 0.1 rad/s (std per sample, 100 samples) and 5% shape noise.
"""

import numpy as np
import pytest

from twin.fem.effects import (
    BearingChange,
    DiskMassChange,
    FluidAddedMass,
    MagneticPull,
    SealCrossCoupling,
    ShaftStiffnessChange,
    ThrustTilt,
    exclusive,
)
from twin.fem.truthfile import Truth
from twin.loop.diagnose import consistent, diagnose
from twin.modes.measured import measured_modes
from twin.update import synthesize_modes

HIDDEN = {
    "magnetic_pull": (MagneticPull(-1e8), {"MAG.stiffness": -1e8}),
    "seal_cross_coupling": (SealCrossCoupling(5e7), {"SEAL.kxy": 5e7}),
    "fsi": (FluidAddedMass(6e4, 2e6), {"FSI.added_mass": 6e4, "FSI.added_damping": 2e6}),
    "thrust_tilt:thrust": (ThrustTilt("thrust", 6e8), {"thrust.k_tilt_change": 6e8}),
    "bearing_change:LGB": (BearingChange("LGB", -3e7, -3e8), {"LGB.damping_change": -3e8}),
}


def _modes(model, effects, seed=3):
    return synthesize_modes(
        model, Truth(tuple(effects)), n_modes=13, samples=100, seed=seed, pole_variance=(0.01, 0.01)
    )


@pytest.mark.parametrize("label", list(HIDDEN))
def test_hidden_effect_is_ranked_first_and_recovered(hydro_unit, label):
    effect, truth = HIDDEN[label]
    meas = measured_modes(_modes(hydro_unit, [effect]))
    d = diagnose(hydro_unit, meas)
    top = d.ranking[0]
    assert d.verdict == "missing effect" and d.missing == (label,) and top.label == label
    assert top.error_after(meas) < 0.2 * top.error_before(meas)  # the error falls by more than 80%
    fitted = dict(zip(top.names, top.values))
    for name, value in truth.items():
        assert fitted[name] == pytest.approx(value, rel=0.10), name
    # strong evidence over the runner-up: another change, not the hidden one's richer form (which fits as well)
    runner_up = next(f for f in d.ranking[1:] if not exclusive(f.label, label))
    assert runner_up.log_bayes_factor < top.log_bayes_factor - 3


def test_undetermined_parameter_is_reported_with_its_uncertainty(hydro_unit):
    """The LGB's direct stiffness hardly moves the poles (its cross-coupling dominates): a wide posterior."""
    effect, _ = HIDDEN["bearing_change:LGB"]
    d = diagnose(hydro_unit, measured_modes(_modes(hydro_unit, [effect])), candidates=["bearing_change:LGB"])
    fit = d.ranking[0]
    k = fit.names.index("LGB.stiffness_change")
    assert abs(fit.values[k] - effect.stiffness_change) < 3 * fit.std[k]
    assert fit.std[k] > 0.1 * abs(effect.stiffness_change)


def test_no_hidden_effect_no_false_alarm(hydro_unit):
    for seed in (3, 4):
        d = diagnose(hydro_unit, _modes(hydro_unit, [MagneticPull(0.0)], seed=seed))
        assert d.verdict == "nothing missing" and d.missing == (), d.summary
        assert all(f.log_bayes_factor < 3 for f in d.fits)


@pytest.mark.slow
def test_effect_outside_the_library_is_located(hydro_unit):
    """A local shaft stiffness loss (element 18 at half stiffness) is no library effect."""
    d = diagnose(hydro_unit, _modes(hydro_unit, [ShaftStiffnessChange(18, -0.5)]))
    assert d.verdict == "unexplained" and d.missing == ()
    loc = d.locations[0]
    assert loc.label == "shaft_stiffness:18" and loc.element == 18
    assert abs(loc.relative_change + 0.5) < 3 * loc.std  # the fitted change, within its uncertainty
    assert "no effect of the library explains it" in d.summary and "shaft element 18" in d.summary
    assert d.failing_modes["frequency"]


@pytest.mark.slow
def test_heavier_disk_is_located_not_taken_for_a_magnetic_pull(hydro_unit):
    """A 10% heavier generator lowers the generator modes like a negative stiffness would, but as λ²."""
    d = diagnose(hydro_unit, _modes(hydro_unit, [DiskMassChange("generator", 0.1)]))
    assert d.verdict == "unexplained" and d.locations[0].label == "disk_mass:generator", d.summary
    assert d.locations[0].relative_change == pytest.approx(0.1, abs=3 * d.locations[0].std)


def test_two_effects_at_once_are_named_together_and_fitted_jointly(hydro_unit):
    truth = [MagneticPull(-1.5e8), SealCrossCoupling(4e7)]
    meas = measured_modes(_modes(hydro_unit, truth))
    d = diagnose(hydro_unit, meas)
    assert d.verdict == "missing effect" and set(d.missing) == {"magnetic_pull", "seal_cross_coupling"}, d.summary
    fitted = d.final.value_of()
    assert fitted["MAG.stiffness"] == pytest.approx(-1.5e8, rel=0.05)
    assert fitted["SEAL.kxy"] == pytest.approx(4e7, rel=0.05)
    assert d.final.error_after(meas) < 0.2 * d.final.error_before(meas)
    assert [a for a, _, _ in d.path].count("add") >= 2


def test_per_mode_fsi_does_not_stand_in_for_simpler_effects(hydro_unit):
    """Two parameters per mode fit every pole alone: magnetic pull with mode-independent FSI is named as such."""
    truth = [MagneticPull(-1e8), FluidAddedMass(6e4, 2e6)]
    meas = measured_modes(_modes(hydro_unit, truth))
    d = diagnose(hydro_unit, meas)
    assert d.verdict == "missing effect" and set(d.missing) == {"magnetic_pull", "fsi"}, d.summary
    assert d.final.value_of()["MAG.stiffness"] == pytest.approx(-1e8, rel=0.05)


def test_fits_stay_inside_the_physical_bounds(hydro_unit):
    """A magnetic pull fitted to data that want a positive stiffness stops at zero, said so."""
    from twin.update.laplace import fit

    meas = measured_modes(_modes(hydro_unit, [ThrustTilt("thrust", 8e8)]))
    f = fit(hydro_unit.with_effects(MagneticPull()), meas, ["MAG.stiffness"], "magnetic_pull")
    assert f.values[0] <= 0.0 and f.at_bound == ["MAG.stiffness"]
    g = fit(
        hydro_unit.with_effects(ThrustTilt("thrust")),
        measured_modes(_modes(hydro_unit, [ThrustTilt("thrust", -4.8e8)])),
        ["thrust.k_tilt_change"],
    )
    assert g.values[0] >= -hydro_unit.parameter("thrust.k_tilt").nominal  # the total tilt stiffness stays >= 0


def test_too_few_measured_modes_is_not_enough_data(hydro_unit):
    import dataclasses

    meas = measured_modes(_modes(hydro_unit, [MagneticPull(-1e8)]))
    few = dataclasses.replace(meas.subset(np.array([0, 3])), band_hz=(0.0, 60.0), duration_s=1200.0, zeta_max=0.25)
    d = diagnose(hydro_unit, few, candidates=["magnetic_pull", "seal_cross_coupling"])
    assert d.verdict == "not enough data" and d.missing == ()
    assert "2 of the model's 12 modes between 0 and 60 Hz" in d.summary
    short = dataclasses.replace(meas, band_hz=(0.0, 60.0), duration_s=5.0, zeta_max=0.25)
    d = diagnose(hydro_unit, short, candidates=["magnetic_pull"])
    assert d.verdict == "not enough data" and "shorter than 100 periods" in d.summary


def test_json_layout(hydro_unit):
    meas = measured_modes(_modes(hydro_unit, [MagneticPull(-1e8)]))
    d = diagnose(hydro_unit, meas, candidates=["magnetic_pull", "seal_cross_coupling"])
    out = d.to_dict(meas)
    assert [r["effect"] for r in out["ranking"]] == ["magnetic_pull", "seal_cross_coupling"]
    first = out["ranking"][0]
    assert set(first) >= {"effect", "score", "error_after", "error_before", "parameters", "why", "explains"}
    assert first["parameters"]["MAG.stiffness"]["unit"] == "N/m" and first["explains"]


def test_consistency_quantile():
    assert consistent(10.0, 10) and not consistent(60.0, 10) and consistent(0.0, 0)


def test_candidate_fits_on_a_dask_cluster_give_the_same_diagnosis(hydro_unit, dask_local):
    effect, _ = HIDDEN["magnetic_pull"]
    meas = measured_modes(_modes(hydro_unit, [effect]))
    labels = ["magnetic_pull", "seal_cross_coupling", "thrust_tilt:thrust"]
    here = diagnose(hydro_unit, meas, candidates=labels)
    there = diagnose(hydro_unit, meas, candidates=labels, tasks=dask_local)
    assert there.missing == here.missing == ("magnetic_pull",)
    assert [f.label for f in there.fits] == labels  # results come back in the candidates' order
    # the workers run one BLAS thread each, so sums run in another order: equal to the optimiser's tolerance
    np.testing.assert_allclose(
        [f.log_bayes_factor for f in there.fits], [f.log_bayes_factor for f in here.fits], rtol=1e-6
    )


@pytest.mark.parametrize(
    "pick_ln_b, richer_ln_b, chosen",
    [(20.0, 10.0, "bearing_change:B6"), (20.0, 18.0, "bearing_anisotropic:B0"), (5.0, 2.5, None)],
)
def test_a_second_effect_enters_only_when_it_pays_for_itself_against_a_richer_form(
    ross_model, pick_ln_b, richer_ln_b, chosen
):
    """With a bearing change at B0 chosen, one at B6 must beat B0's anisotropic change by strong evidence."""
    from types import SimpleNamespace

    from twin.loop.candidates import select
    from twin.loop.diagnose import _against_richer

    first, pick, richer = select(ross_model, ["bearing_change:B0", "bearing_change:B6", "bearing_anisotropic:B0"])
    fitted = {pick.label: SimpleNamespace(log_bayes_factor=pick_ln_b)}
    fitted[richer.label] = SimpleNamespace(log_bayes_factor=richer_ln_b)

    def run(*args, **kwargs):
        raise AssertionError("both are fitted already")

    out = _against_richer(pick, [first], [pick, richer], fitted, run, {})
    assert (out.label if out else None) == chosen
    assert _against_richer(pick, [], [pick, richer], fitted, run, {}) is pick  # nothing chosen: nothing richer


@pytest.mark.parametrize("margin, kept", [(2.0, "bearing_change:B0"), (5.0, "bearing_anisotropic:B0")])
def test_a_chosen_richer_form_gives_way_when_the_others_explain_what_it_added(ross_model, margin, kept):
    """After a second effect comes in, the richer form stays only while it beats its simpler form by 3."""
    from types import SimpleNamespace

    from twin.loop.candidates import select
    from twin.loop.diagnose import _simplify

    simple, rich, other = select(ross_model, ["bearing_change:B0", "bearing_anisotropic:B0", "bearing_change:B6"])
    current = SimpleNamespace(log_evidence=100.0, value_of=lambda: {})

    def run(func, candidates, **shared):
        assert [c.label for c in candidates] == ["bearing_change:B0"] and shared["included"] == (other,)
        return [SimpleNamespace(label="bearing_change:B0", log_evidence=100.0 - margin)]

    included, path = [rich, other], []
    fit, lnz = _simplify(included, [simple, rich, other], path, current, None, None, [], run)
    assert [c.label for c in included] == [kept, "bearing_change:B6"]
    assert (path == [("simplify", "bearing_anisotropic:B0", margin)]) == (kept == "bearing_change:B0")
    assert lnz == fit.log_evidence == (100.0 - margin if kept == "bearing_change:B0" else 100.0)
