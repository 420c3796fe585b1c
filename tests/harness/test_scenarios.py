"""Scenario specs: what a truth hides, scaled, combined, outside the library; bad specs are named."""

import pytest

from twin.errors import TwinError
from twin.fem.effects import DiskInertiaChange, DiskMassChange, ShaftStiffnessChange
from twin.fem.effects import effect_label
from twin.harness.scenarios import REFERENCE_POLE_CHANGE, parse_scenario, reference_effect, reference_labels


def test_reference_sizes_scaled_and_combined(hydro_unit):
    s = parse_scenario("magnetic_pull@2.5+bearing_change:LGB@0.5", hydro_unit)
    assert s.labels == ("magnetic_pull", "bearing_change:LGB")
    assert s.truth_values(hydro_unit) == {
        "MAG.stiffness": -2.5e8,
        "LGB.stiffness_change": -1.5e7,
        "LGB.damping_change": -1.5e8,
    }
    assert s.expected() == "missing effect: magnetic_pull, bearing_change:LGB"
    assert parse_scenario("fsi_per_mode@0.5", hydro_unit).effects[0].added_mass[0] == pytest.approx(5e4)
    # the sizes hydro_unit.toml declares
    assert {effect_label(e) for e in hydro_unit.reference_changes} == {
        "fsi",
        "fsi_per_mode",
        "magnetic_pull",
        "seal_cross_coupling",
        "bearing_change:UGB",
        "bearing_change:LGB",
        "thrust_tilt:thrust",
    }


def test_local_changes_and_the_old_name(hydro_unit):
    assert parse_scenario("shaft_stiffness_loss", hydro_unit).changes == (ShaftStiffnessChange(18, -0.5),)
    assert parse_scenario("shaft_stiffness:4", hydro_unit).changes == (ShaftStiffnessChange(4, -0.5),)
    assert parse_scenario("disk_mass:runner@1.2", hydro_unit).changes == (DiskMassChange("runner", 0.2),)
    assert parse_scenario("disk_inertia:generator", hydro_unit).changes == (DiskInertiaChange("generator", 0.2),)
    s = parse_scenario("disk_mass:generator@1.1", hydro_unit)
    assert s.expected() == "unexplained, at disk_mass:generator" and s.truth_values(hydro_unit) == {}
    assert "the mass of disk generator (node 8" in s.describe(hydro_unit)
    assert (
        parse_scenario("none", hydro_unit).nothing
        and parse_scenario("none", hydro_unit).expected() == "nothing missing"
    )
    assert (
        parse_scenario("magnetic_pull@2.5+seal_cross_coupling", hydro_unit).folder
        == "magnetic_pull_x2.5+seal_cross_coupling"
    )


@pytest.mark.parametrize(
    "spec, message",
    [
        ("gravity", "unknown 'gravity'; choose from fsi, fsi_per_mode, magnetic_pull"),
        ("magnetic_pull@-1", "must be positive"),
        ("magnetic_pull@x", "LABEL or LABEL@FACTOR"),
        ("magnetic_pull+magnetic_pull@2", "'magnetic_pull' appears twice"),
        ("fsi+fsi_per_mode", "describe the same physics"),
        ("shaft_stiffness:top", "a shaft element is a number"),
    ],
)
def test_bad_specs_are_named(hydro_unit, spec, message):
    with pytest.raises(TwinError, match=message):
        parse_scenario(spec, hydro_unit)


def test_an_element_the_model_lacks_is_named(hydro_unit):
    with pytest.raises(TwinError, match=r"scenario 'shaft_stiffness:40': .*no shaft element 40 \(elements 0 to 27\)"):
        parse_scenario("shaft_stiffness:40", hydro_unit).check(hydro_unit)
    with pytest.raises(TwinError, match="no disk 'rotor'"):
        parse_scenario("disk_inertia:rotor", hydro_unit).check(hydro_unit)


def test_a_local_change_without_a_default_size_asks_for_its_factor(hydro_unit, monkeypatch):
    """A local change a plug-in adds has no default size here: hiding it needs LABEL@FACTOR, not silently none."""
    from dataclasses import dataclass
    from typing import ClassVar

    from twin.fem.effects import RelativeChange, register, registry

    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._REGISTRY))
    monkeypatch.setattr(registry, "_ORDERED", None)

    @register
    @dataclass(frozen=True)
    class PadStiffness(RelativeChange):
        key: ClassVar[str] = "pad_stiffness_test"
        element: ClassVar[str | None] = "bearing"
        bearing: str = ""
        change: float = 0.0

    with pytest.raises(TwinError, match="'pad_stiffness_test:UGB' has no default size; give it as"):
        parse_scenario("pad_stiffness_test:UGB", hydro_unit)
    assert parse_scenario("pad_stiffness_test:UGB@0.8", hydro_unit).changes == (PadStiffness("UGB", -0.2),)


def test_a_size_the_model_file_does_not_declare_is_derived_from_the_machine():
    """On the Pelton unit (no declared sizes): each effect it admits moves its lowest lightly damped modes' poles
    by at most 5%, as a loss of a bearing's coefficients in proportion, or a magnetic pull down."""
    from twin import load_model
    from twin.modes.analysis import modal
    from twin.modes.pairing import dataset_poles, pair_modes

    pelton = load_model("pelton_unit")
    labels = reference_labels(pelton)
    assert "fsi" not in labels and "seal_cross_coupling" not in labels and "magnetic_pull" in labels
    base = modal(pelton)
    light = base.isel(mode=(base["damping_ratio"].values < 0.2).nonzero()[0][:10])
    for label in ("magnetic_pull", "bearing_anisotropic:DE"):
        effect = reference_effect(pelton, label)
        other = modal(pelton.with_effects(effect))
        pairs = pair_modes(light, other, shape_var="shape")
        a = dataset_poles(light.sel(mode=pairs["reference_mode"].values))
        b = dataset_poles(other.sel(mode=pairs["other_mode"].values))
        assert max(abs(b - a) / abs(a)) == pytest.approx(REFERENCE_POLE_CHANGE, rel=0.05), label
    aniso = reference_effect(pelton, "bearing_anisotropic:DE")
    de = pelton.bearings[1].coefficients
    assert aniso.kxx_change / de["kxx"] == pytest.approx(aniso.kyy_change / de["kyy"])  # a proportional loss
    assert reference_effect(pelton, "magnetic_pull").stiffness < 0
    with pytest.raises(TwinError, match="admits no library effect 'fsi'"):
        reference_effect(pelton, "fsi")
    with pytest.raises(TwinError, match="hidden change 'fsi@2'.*admits no library effect 'fsi'"):
        parse_scenario("fsi@2", pelton)
