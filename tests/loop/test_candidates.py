"""The candidate library a diagnosis tries."""

import pytest

from twin import ModelError
from twin.fem.effects import effect_label, library_effects, parse_label
from twin.loop.candidates import add_effects, candidates, select


def test_library_follows_the_model(hydro_unit, ross_model):
    labels = [c.label for c in candidates(hydro_unit)]
    assert labels[:9] == [
        "fsi",
        "fsi_per_mode",
        "magnetic_pull",
        "seal_cross_coupling",
        "bearing_change:UGB",
        "bearing_change:LGB",
        "bearing_anisotropic:UGB",
        "bearing_anisotropic:LGB",
        "thrust_tilt:thrust",
    ]
    assert labels == [effect_label(e) for e in library_effects(hydro_unit)]
    # the ROSS rotor declares no regions and no thrust bearing: only its bearings can change
    ross = [parse_label(c.label) for c in candidates(ross_model)]
    assert ("bearing_change", "B0") in ross and ("bearing_change", "B6") in ross
    assert {element for _, element in ross} == {"B0", "B6"}


def test_effects_already_in_the_model_are_no_candidates(hydro_unit):
    model = add_effects(hydro_unit, ["magnetic_pull", "fsi"])
    labels = [c.label for c in candidates(model)]
    assert "magnetic_pull" not in labels and "fsi" not in labels and "fsi_per_mode" in labels
    # a richer form of an effect the model has stays a candidate; the simpler form of one it has does not
    labels = [c.label for c in candidates(add_effects(hydro_unit, ["bearing_change:UGB", "bearing_anisotropic:LGB"]))]
    assert "bearing_anisotropic:UGB" in labels and "bearing_change:LGB" not in labels


def test_unknown_candidate_is_named(hydro_unit):
    with pytest.raises(ModelError, match=r"no candidate effect \['magnetic_push'\].*available: fsi"):
        select(hydro_unit, ["magnetic_push"])
