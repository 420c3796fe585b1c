"""The naming of a change from a pooled residual: which candidate, and whether the records can tell."""

import numpy as np
import scipy.special

from twin.fem.effects import MagneticPull
from twin.loop.candidates import Candidate
from twin.track import explain


def _candidate(label: str, column: list[float]) -> explain.Linearised:
    return explain.Linearised(
        Candidate(label, MagneticPull()), (f"{label}.x",), np.array([1.0]), np.array(column)[:, None]
    )


def test_a_change_the_records_can_tell_is_named_and_one_they_cannot_is_a_reading():
    rng = np.random.default_rng(3)
    a = _candidate("a", [1.0, 0.0, 0.5, 0.0])
    b = _candidate("b", [0.0, 1.0, 0.0, 0.5])
    twin_of_a = _candidate("a2", [1.0, 0.05, 0.5, 0.0])  # almost the same signature as a
    cov = 0.01 * np.eye(4)
    r = 0.8 * a.jacobian[:, 0] + rng.normal(0.0, 0.1, 4)

    clear = explain.diagnose(r, cov, [a, b])
    assert clear.label == "a" and clear.log_evidence - clear.runner_up_evidence >= explain.MIN_MARGIN
    assert clear.text.startswith("a changed: a.x = ")
    # the exact least-squares value under the unit prior, (J'C^-1 J + 1)^-1 J'C^-1 r, with the errors widened
    # by the best fit's reduced chi-square where it exceeds 1
    J = a.jacobian
    spread = max(1.0, min(explain.linear_fit(r, c.jacobian, c.scale, cov).chi2 / 3 for c in (a, b)))
    c = 0.01 * spread
    assert np.isclose(clear.mean[0], np.linalg.solve(J.T @ J / c + 1.0, J.T @ r / c)[0])

    unsure = explain.diagnose(r, cov, [a, twin_of_a, b])
    assert {unsure.label, unsure.runner_up} == {"a", "a2"}
    assert unsure.log_evidence - unsure.runner_up_evidence < explain.MIN_MARGIN
    assert "cannot yet tell them apart" in unsure.text and f"followed as {unsure.label}" in unsure.text


def test_a_residual_no_candidate_explains_names_nothing():
    a = _candidate("a", [1.0, 0.0, 0.0, 0.0])
    b = _candidate("b", [0.0, 1.0, 0.0, 0.0])
    verdict = explain.diagnose(np.array([0.0, 0.0, 0.01, -0.01]), 0.01 * np.eye(4), [a, b])
    assert verdict.log_evidence < explain.MIN_LOG_EVIDENCE
    assert verdict.text.startswith("no change the model can name stands out")


def test_a_richer_form_is_named_only_when_it_pays_and_the_runner_up_is_another_change():
    """bearing_anisotropic:B0 holds bearing_change:B0: fitting a little better is not enough to be named, and
    neither form is the other's runner-up (nor the named change its own)."""
    from twin.fem.effects import BearingAnisotropicChange, BearingChange

    def linearised(label, effect, columns):
        names = tuple(f"{label}.{i}" for i in range(len(columns)))
        return explain.Linearised(Candidate(label, effect), names, np.ones(len(columns)), np.array(columns).T)

    simple = linearised("bearing_change:B0", BearingChange("B0"), [[1.0, 0.0, 0.5, 0.0]])
    rich = linearised("bearing_anisotropic:B0", BearingAnisotropicChange("B0"), [[1.0, 0.0, 0.5, 0.0], [0, 0, 0, 1.0]])
    other = linearised("magnetic_pull", MagneticPull(), [[0.0, 1.0, 0.0, 0.5]])
    cov = 0.01 * np.eye(4)
    # a little the simple form cannot fit: the richer form's log evidence is 2.2 higher, below the margin of 3
    r = 0.8 * simple.jacobian[:, 0] + np.array([0.0, 0.02, 0.0, 0.3])
    verdict = explain.diagnose(r, cov, [rich, simple, other])
    assert verdict.label == "bearing_change:B0" and verdict.runner_up == "magnetic_pull"
    only_forms = explain.diagnose(r, cov, [rich, simple])
    assert only_forms.label == "bearing_change:B0" and only_forms.runner_up == "bearing_anisotropic:B0"
    # beyond the margin the richer form is named
    r = 0.8 * simple.jacobian[:, 0] + np.array([0.0, 0.02, 0.0, 0.4])
    assert explain.diagnose(r, cov, [rich, simple, other]).label == "bearing_anisotropic:B0"


def test_a_name_must_stand_out_from_all_the_others_together():
    """Beating the runner-up by the margin is not enough when several others share the rest of the evidence:
    the odds are against them all together (each local change one place of many)."""
    a = _candidate("a", [1.0, 0.0, 0.0, 0.0])
    near = [_candidate(f"b{i}", [0.9, 0.1 * (i + 1), 0.0, 0.0]) for i in range(4)]
    r = np.array([0.5, 0.02, 0.0, 0.0])
    verdict = explain.diagnose(r, 0.01 * np.eye(4), [a, *near])
    fits = {c.label: explain.linear_fit(r, c.jacobian, c.scale, 0.01 * np.eye(4)).log_bayes_factor for c in [a, *near]}
    others = np.array([v for k, v in fits.items() if k != verdict.label])
    assert np.isclose(verdict.odds, fits[verdict.label] - scipy.special.logsumexp(others))
    assert verdict.odds < verdict.log_evidence - verdict.runner_up_evidence
    assert verdict.clear == (verdict.odds >= explain.MIN_MARGIN and verdict.log_evidence >= explain.MIN_LOG_EVIDENCE)


def test_library_effects_and_local_changes_share_the_prior_by_halves():
    from twin.fem.effects import ShaftStiffnessChange

    lib = [_candidate(label, [1.0, 0.0]) for label in ("a", "b")]
    local = [
        explain.Linearised(
            Candidate(f"shaft_stiffness:{k}", ShaftStiffnessChange(k)), ("d",), np.ones(1), np.ones((2, 1))
        )
        for k in range(1, 7)
    ]
    prior = explain.log_prior([*lib, *local])
    assert np.isclose(prior["a"], np.log(0.25)) and np.isclose(prior["shaft_stiffness:3"], np.log(1 / 12))
    assert np.isclose(sum(np.exp(v) for v in prior.values()), 1.0)


def test_residuals_beyond_their_stated_errors_weaken_the_naming():
    """A pooled residual whose best fit leaves a chi-square four times its degrees of freedom is weighed with
    its errors widened by that ratio: the odds between two changes shrink."""
    a = _candidate("a", [1.0, 0.0, 0.5, 0.0, 0.0, 0.0])
    b = _candidate("b", [1.0, 0.3, 0.0, 0.0, 0.0, 0.0])
    cov = 0.01 * np.eye(6)
    r = 0.6 * a.jacobian[:, 0]
    calm = explain.diagnose(r, cov, [a, b])
    scatter = np.array([0.0, 0.0, 0.0, 0.25, -0.25, 0.2])  # what neither explains
    wild = explain.diagnose(r + scatter, cov, [a, b])
    assert calm.label == wild.label == "a"
    assert wild.odds < calm.odds / 2


def test_a_large_change_is_refitted_on_the_full_model(hydro_unit):
    """The upper guide bearing 30% softer and its damping half up: the sensitivities at no change put the
    first modes' shift four times off, the refit on the full model finds the change from its exact poles."""
    from twin.track.physics import tracked_modes

    tracked = tracked_modes(hydro_unit, tuple(hydro_unit.channels), 40.0)
    cands = {c.label: c for c in explain.candidates(hydro_unit, tracked)}
    ugb = cands["bearing_change:UGB"]
    truth = np.array([-2e8, 2e7])
    quiet = explain.changed_poles(hydro_unit, tracked, {}, [])[0]
    r = explain.changed_poles(hydro_unit, tracked, {}, [(ugb, truth)])[0] - quiet
    cov = np.diag((1e-3 * np.abs(quiet)) ** 2)
    setting = explain.Setting(hydro_unit, tracked, {}, [])
    linear = explain.linear_fit(r, ugb.jacobian, ugb.scale, cov, ugb.bounds)
    fit = explain.refit(r, cov, np.ones(len(r), bool), ugb, setting, linear)
    assert np.allclose(fit.values, truth, rtol=0.02)
    assert not np.allclose(linear.values, truth, rtol=0.2)
    verdict = explain.diagnose(r, cov, list(cands.values()), setting)
    assert verdict.label == "bearing_change:UGB" and verdict.clear
