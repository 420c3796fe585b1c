"""Scenario specs: what a truth hides, scaled, combined, outside the library; bad specs are named."""

import pytest

from twin.errors import TwinError
from twin.fem.effects import DiskInertiaChange, DiskMassChange, ShaftStiffnessChange
from twin.harness.scenarios import REFERENCE_EFFECTS, parse_scenario


def test_reference_sizes_scaled_and_combined(hydro_unit):
    s = parse_scenario("magnetic_pull@2.5+bearing_change:LGB@0.5")
    assert s.labels == ("magnetic_pull", "bearing_change:LGB")
    assert s.truth_values(hydro_unit) == {
        "MAG.stiffness": -2.5e8,
        "LGB.stiffness_change": -1.5e7,
        "LGB.damping_change": -1.5e8,
    }
    assert s.expected() == "missing effect: magnetic_pull, bearing_change:LGB"
    assert parse_scenario("fsi_per_mode@0.5").effects[0].added_mass[0] == pytest.approx(5e4)
    assert set(REFERENCE_EFFECTS) == {
        "fsi",
        "fsi_per_mode",
        "magnetic_pull",
        "seal_cross_coupling",
        "bearing_change:UGB",
        "bearing_change:LGB",
        "thrust_tilt:thrust",
    }


def test_local_changes_and_the_old_name(hydro_unit):
    assert parse_scenario("shaft_stiffness_loss").changes == (ShaftStiffnessChange(18, -0.5),)
    assert parse_scenario("shaft_stiffness:4").changes == (ShaftStiffnessChange(4, -0.5),)
    assert parse_scenario("disk_mass:runner@1.2").changes == (DiskMassChange("runner", 0.2),)
    assert parse_scenario("disk_inertia:generator").changes == (DiskInertiaChange("generator", 0.2),)
    s = parse_scenario("disk_mass:generator@1.1")
    assert s.expected() == "unexplained, at disk_mass:generator" and s.truth_values(hydro_unit) == {}
    assert "the mass of disk generator (node 8" in s.describe(hydro_unit)
    assert parse_scenario("none").nothing and parse_scenario("none").expected() == "nothing missing"
    assert parse_scenario("magnetic_pull@2.5+seal_cross_coupling").folder == "magnetic_pull_x2.5+seal_cross_coupling"


@pytest.mark.parametrize(
    "spec, message",
    [
        ("gravity", "unknown 'gravity'; choose from magnetic_pull"),
        ("magnetic_pull@-1", "must be positive"),
        ("magnetic_pull@x", "LABEL or LABEL@FACTOR"),
        ("magnetic_pull+magnetic_pull@2", "'magnetic_pull' appears twice"),
        ("fsi+fsi_per_mode", "describe the same physics"),
        ("shaft_stiffness:top", "a shaft element is a number"),
    ],
)
def test_bad_specs_are_named(spec, message):
    with pytest.raises(TwinError, match=message):
        parse_scenario(spec)


def test_an_element_the_model_lacks_is_named(hydro_unit):
    with pytest.raises(TwinError, match=r"scenario 'shaft_stiffness:40': .*no shaft element 40 \(elements 0 to 27\)"):
        parse_scenario("shaft_stiffness:40").check(hydro_unit)
    with pytest.raises(TwinError, match="no disk 'rotor'"):
        parse_scenario("disk_inertia:rotor").check(hydro_unit)


def test_a_local_change_without_a_default_size_asks_for_its_factor(monkeypatch):
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
        parse_scenario("pad_stiffness_test:UGB")
    assert parse_scenario("pad_stiffness_test:UGB@0.8").changes == (PadStiffness("UGB", -0.2),)
