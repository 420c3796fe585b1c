"""Bearing changes of the direct coefficients: alike in x and y, or each apart (the richer form), and a bearing
that changed unequally in x and y named alone."""

import numpy as np
import pytest

from twin.fem.effects import BearingAnisotropicChange, BearingChange, exclusive, from_label, holds
from twin.fem.truthfile import Truth
from twin.loop.diagnose import diagnose
from twin.update import synthesize_modes

CHANGES = {"kxx": -3e5, "kyy": -1.2e5, "cxx": -150.0, "cyy": -60.0}


def test_each_direct_coefficient_changes_alone(ross_model):
    bearing = ross_model.bearings[0]
    for key, change in CHANGES.items():
        changed = ross_model.with_effects(
            from_label(f"bearing_anisotropic:{bearing.name}", **{f"{key}_change": change})
        )
        direct = ross_model.with_values({f"{bearing.name}.{key}": bearing.coefficients[key] + change})
        for kind in ("C", "K"):
            assert np.allclose(changed.matrices()[kind], direct.matrices()[kind], rtol=1e-12, atol=1e-9), (key, kind)


def test_it_holds_the_change_alike_in_x_and_y(ross_model):
    alike = ross_model.with_effects(BearingChange("B0", -2e5, -80.0)).matrices()
    apart = ross_model.with_effects(BearingAnisotropicChange("B0", -2e5, -2e5, -80.0, -80.0)).matrices()
    assert all(np.array_equal(alike[k], apart[k]) for k in ("M", "C", "G", "K"))
    assert holds("bearing_anisotropic:B0", "bearing_change:B0") and not holds(
        "bearing_change:B0", "bearing_anisotropic:B0"
    )
    assert exclusive("bearing_change:B0", "bearing_anisotropic:B0")
    assert not exclusive("bearing_change:B6", "bearing_anisotropic:B0")


def test_bounds_keep_each_coefficient_non_negative_and_scales_follow_the_alike_change(ross_model):
    b = ross_model.bearings[0]
    params = {p.name: p for p in BearingAnisotropicChange(b.name).parameters(ross_model)}
    assert [params[f"{b.name}.{k}_change"].bounds[0] for k in CHANGES] == [-b.coefficients[k] for k in CHANGES]
    alike = BearingChange(b.name).plausible_scale(ross_model)
    apart = BearingAnisotropicChange(b.name).plausible_scale(ross_model)
    assert apart[f"{b.name}.kxx_change"] == apart[f"{b.name}.kyy_change"] == alike[f"{b.name}.stiffness_change"]
    assert apart[f"{b.name}.cyy_change"] == alike[f"{b.name}.damping_change"]


@pytest.mark.parametrize("seed", [3, 8])
def test_a_bearing_changed_unequally_in_x_and_y_is_named_alone(ross_model, seed):
    """The change alike in x and y leaves an x/y misfit that the other bearing would absorb; the richer form
    at the changed bearing explains it alone."""
    truth = Truth((BearingAnisotropicChange("B0", **{f"{k}_change": v for k, v in CHANGES.items()}),))
    data = synthesize_modes(ross_model, truth, n_modes=6, samples=50, seed=seed, pole_variance=(0.1, 0.1))
    d = diagnose(ross_model, data)
    assert d.verdict == "missing effect" and d.missing == ("bearing_anisotropic:B0",), d.summary
    fitted = d.final.value_of()
    assert fitted["B0.kxx_change"] == pytest.approx(-3e5, rel=0.05)
    assert fitted["B0.kyy_change"] == pytest.approx(-1.2e5, rel=0.05)
