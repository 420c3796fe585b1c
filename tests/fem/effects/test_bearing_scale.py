"""A proportional bearing change: the same matrices as scaling the bearing's eight coefficients, and a change
the diagnosis names and sizes on modes it hides in."""

import dataclasses

import numpy as np
import pytest

from twin.fem.effects import effect_classes, from_label
from twin.fem.effects.bearing_scale import BearingScale
from twin.fem.truthfile import Truth
from twin.loop.diagnose import diagnose
from twin.modes.measured import measured_modes
from twin.update import synthesize_modes

COEFFICIENTS = ("kxx", "kxy", "kyx", "kyy", "cxx", "cxy", "cyx", "cyy")


@pytest.mark.parametrize("bearing, change", [("UGB", -0.3), ("LGB", 0.25)])
def test_it_equals_scaling_all_eight_coefficients(hydro_unit, bearing, change):
    scaled = hydro_unit.with_effects(BearingScale(bearing, change)).matrices()
    values = {f"{bearing}.{c}": (1 + change) * hydro_unit.parameter(f"{bearing}.{c}").nominal for c in COEFFICIENTS}
    direct = hydro_unit.with_values(values).matrices()
    for kind in ("M", "C", "G", "K"):
        assert np.allclose(scaled[kind], direct[kind], rtol=1e-12, atol=1e-9 * np.abs(direct[kind]).max()), kind


def test_it_is_a_library_effect_on_every_bearing_bounded_as_a_relative_change(hydro_unit):
    assert effect_classes(local=False)["bearing_scale"] is BearingScale
    assert BearingScale.instances(hydro_unit) == [BearingScale("UGB"), BearingScale("LGB")]
    assert from_label("bearing_scale:LGB", scale_change=-0.2) == BearingScale("LGB", -0.2)
    (parameter,) = BearingScale("LGB").parameters(hydro_unit)
    assert parameter.name == "LGB.scale_change" and parameter.unit == "1" and parameter.bounds[0] == -1.0
    assert BearingScale("LGB").plausible_scale(hydro_unit) == {"LGB.scale_change": 0.5}


def test_it_follows_the_bearing_values_the_model_has(hydro_unit):
    """At an operating point where the laws change a bearing's coefficients, the footprint is those values."""
    stiffer = dataclasses.replace(hydro_unit, values={**hydro_unit.values, "UGB.kxx": 2e9})
    (term,) = [t for t in BearingScale("UGB").parameters(stiffer)[0].terms if t.kind == "K"]
    assert term.value[0, 0] == 2e9


def test_a_hidden_proportional_change_is_named_and_sized(hydro_unit):
    truth = Truth((BearingScale("UGB", -0.3),))
    modes = synthesize_modes(hydro_unit, truth, n_modes=13, samples=100, seed=3, pole_variance=(0.01, 0.01))
    d = diagnose(hydro_unit, measured_modes(modes))
    top = d.ranking[0]
    assert d.verdict == "missing effect" and d.missing == ("bearing_scale:UGB",), d.summary
    fitted = dict(zip(top.names, top.values))
    assert fitted["UGB.scale_change"] == pytest.approx(-0.3, rel=0.1)
