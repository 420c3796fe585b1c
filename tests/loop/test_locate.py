"""The localisation scan: linearised screening, then nonlinear refits of the best places."""

import numpy as np
import pytest

from twin.fem.effects import ShaftStiffnessChange
from twin.fem.truthfile import Truth
from twin.loop.locate import locate, screen
from twin.modes.measured import measured_modes
from twin.update import synthesize_modes
from twin.update.laplace import log_evidence_as_is


@pytest.fixture(scope="module")
def weak_element(hydro_unit):
    data = synthesize_modes(
        hydro_unit, Truth((ShaftStiffnessChange(6, -0.3),)), n_modes=13, samples=100, seed=9, pole_variance=(0.01, 0.01)
    )
    return measured_modes(data)


def test_screening_ranks_the_changed_element_among_the_first(hydro_unit, weak_element):
    ranked = screen(hydro_unit, weak_element)
    assert len(ranked) == 36 and ranked[0][1] >= ranked[-1][1]
    assert "shaft6" in [c.parameters(hydro_unit)[0].name.split(".")[0] for c, _ in ranked[:3]]


def test_refit_finds_the_element_and_its_change(hydro_unit, weak_element):
    lnz, _ = log_evidence_as_is(hydro_unit, weak_element)
    best = locate(hydro_unit, weak_element, reference=lnz)[0]
    assert best.label == "shaft_stiffness:6" and best.element == 6
    assert best.relative_change == pytest.approx(-0.3, abs=3 * best.std) and best.explained > 0.95
    assert best.log_bayes_factor > 3 and "shaft element 6 (nodes 6-7" in best.text()
    assert np.isfinite(best.std)
