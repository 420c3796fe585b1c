"""The naming of a change from a pooled residual: which candidate, and whether the records can tell."""

import numpy as np

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
    # the exact least-squares value under the unit prior: (J'C^-1 J + 1)^-1 J'C^-1 r
    J = a.jacobian
    assert np.isclose(clear.mean[0], np.linalg.solve(J.T @ J / 0.01 + 1.0, J.T @ r / 0.01)[0])

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
