"""The model's side of tracking: predictions at an operating point, the laws learned, a change named."""

import numpy as np
import pytest

from twin.fem.operation import at_operating_point
from twin.modes.analysis import modal
from twin.track import explain
from twin.track.physics import (
    declared_slopes,
    fit_laws,
    parts,
    predict,
    tracked_modes,
    with_slopes,
)


@pytest.fixture(scope="module")
def tracked(hydro_unit):
    return tracked_modes(hydro_unit, tuple(hydro_unit.channels), 60.0)


def test_predicted_poles_are_the_model_s_at_the_point_and_their_slope_derivatives_are_right(hydro_unit, tracked):
    point = {"power": 90.0, "oil_temperature": 52.0}
    poles, jac = predict(hydro_unit, tracked, point)
    exact = modal(at_operating_point(hydro_unit, point), n_modes=30)
    for p in poles:
        assert np.min(np.abs(exact.pole.values - p)) < 1e-8 * abs(p)
    # the derivative by the UGB stiffness slope, against a central difference
    j = 4  # UGB.stiffness_change per degC
    s0, h = declared_slopes(hydro_unit), 1e5
    up = predict(with_slopes(hydro_unit, s0 + h * np.eye(len(s0))[j]), tracked, point, with_jacobian=False)[0]
    down = predict(with_slopes(hydro_unit, s0 - h * np.eye(len(s0))[j]), tracked, point, with_jacobian=False)[0]
    assert np.allclose(jac[:, j], (up - down) / (2 * h), rtol=1e-3, atol=1e-12)


def test_the_laws_are_learned_through_the_model(hydro_unit, tracked):
    """Exact poles of a unit whose oil-temperature laws are 30% steeper than declared, over 12 operating points."""
    truth = declared_slopes(hydro_unit) * np.where(np.arange(8) >= 4, 1.3, 1.0)
    rng = np.random.default_rng(2)
    points = [
        {"power": rng.uniform(80, 210), "reactive_power": rng.uniform(-40, 80), "oil_temperature": rng.uniform(35, 55)}
        for _ in range(12)
    ]
    offset = 0.01 * np.abs(parts(tracked.poles))
    y = np.array([parts(predict(with_slopes(hydro_unit, truth), tracked, p, with_jacobian=False)[0]) for p in points])
    sigma = 1e-3 * np.abs(y)
    fit = fit_laws(hydro_unit, tracked, points, y + offset, sigma)
    assert np.allclose(fit.offsets, offset, rtol=1e-2, atol=1e-6)
    # the LGB's damping slope sets the 1.1 Hz mode: learned to within its standard error
    assert fit.slopes[7] == pytest.approx(truth[7], rel=0.02)
    assert np.all(np.abs(fit.slopes - truth) < 4 * np.sqrt(fit.covariance.diagonal()) + 1e-6 * np.abs(truth))


def test_a_change_is_named_from_the_frequencies_it_moves(hydro_unit, tracked):
    cands = explain.candidates(hydro_unit, tracked)
    by_label = {c.label: c for c in cands}
    assert "bearing_change:UGB" in by_label and "shaft_stiffness:18" in by_label
    m = len(tracked.poles)
    sigma = 1e-3 * np.abs(tracked.poles.imag)
    cov = np.diag(np.r_[np.ones(m), sigma**2])
    for label, values in [
        ("bearing_change:LGB", [-3e7, -3e8]),
        ("magnetic_pull", [-1e8]),
        ("shaft_stiffness:18", [-0.5]),
    ]:
        r = by_label[label].jacobian @ np.array(values)
        r[:m] = np.nan  # the frequencies only, as the tracker
        verdict = explain.diagnose(r, cov, cands)
        assert verdict.label == label, verdict.text
