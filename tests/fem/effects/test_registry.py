"""The effects registry: labels written and read in one place, effects added as plug-ins."""

import importlib.metadata
import logging
import sys

import pytest

from tests.conftest import ROOT
from twin import load_model
from twin.errors import ModelError
from twin.fem.effects import (
    BearingChange,
    Effect,
    FluidAddedMass,
    MagneticPull,
    ShaftStiffnessChange,
    effect_classes,
    effect_label,
    effect_providing,
    exclusive,
    from_label,
    holds,
    is_per_mode_name,
    library_effects,
    local_changes,
    parse_label,
    register,
    registry,
)

PLUGIN = """
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from twin.fem.effects import Effect, register
from twin.fem.parameters import Parameter, Term


@register
@dataclass(frozen=True)
class HousingMass(Effect):
    key: ClassVar[str] = "housing_mass_test"
    region: ClassVar[str | None] = "generator"
    explanation: ClassVar[str] = "a test plug-in: extra mass on the generator region's nodes"
    mass: float = 0.0

    def parameters(self, model):
        dofs = model.region_dofs(self.region)
        return [Parameter("HOUSING.mass", self.mass, "kg", (Term("M", dofs, np.eye(len(dofs))),), "extra mass",
                          bounds=(0.0, np.inf))]

    def plausible_scale(self, model):
        return {"HOUSING.mass": 1e4}
"""


@pytest.fixture
def fresh_registry(monkeypatch):
    """The registry as a new process finds it, restored afterwards."""
    monkeypatch.setattr(registry, "_REGISTRY", dict(registry._REGISTRY))
    monkeypatch.setattr(registry, "_ORDERED", None)
    monkeypatch.setattr(registry, "_loaded", False)
    return registry


def test_every_label_of_a_model_reads_back_to_its_effect(hydro_unit):
    effects = library_effects(hydro_unit) + local_changes(hydro_unit)
    assert len({effect_label(e) for e in effects}) == len(effects)
    for effect in effects:
        if not effect.per_mode:
            assert from_label(effect_label(effect)) == effect
    assert parse_label("bearing_change:LGB") == ("bearing_change", "LGB")
    assert parse_label("magnetic_pull") == ("magnetic_pull", None)


def test_labels_with_a_wrong_element_are_named():
    with pytest.raises(ModelError, match="a shaft element is a number"):
        from_label("shaft_stiffness:top")
    with pytest.raises(ModelError, match="not on a named element"):
        from_label("magnetic_pull:GEN")
    with pytest.raises(ModelError, match="names its bearing"):
        from_label("bearing_change")
    with pytest.raises(ModelError, match="no effect 'gravity'"):
        from_label("gravity")


def test_library_and_local_changes_are_told_apart(hydro_unit):
    library, local = effect_classes(local=False), effect_classes(local=True)
    assert not set(library) & set(local) and set(library) | set(local) == set(effect_classes())
    assert list(library)[:7] == [
        "fsi",
        "fsi_per_mode",
        "magnetic_pull",
        "seal_cross_coupling",
        "bearing_change",
        "bearing_anisotropic",
        "thrust_tilt",
    ]
    assert list(local) == ["shaft_stiffness", "disk_mass", "disk_inertia"]
    assert [effect_label(e) for e in library_effects(hydro_unit)][4:9] == [
        "bearing_change:UGB",
        "bearing_change:LGB",
        "bearing_anisotropic:UGB",
        "bearing_anisotropic:LGB",
        "thrust_tilt:thrust",
    ]
    assert len(local_changes(hydro_unit)) == len(hydro_unit.shaft) + 2 * len(hydro_unit.disks)


def test_what_holds_what_is_declared_by_the_effects():
    assert holds("fsi_per_mode", "fsi") and not holds("fsi", "fsi_per_mode")
    assert exclusive("fsi", "fsi_per_mode") and not exclusive("bearing_change:UGB", "bearing_change:LGB")
    assert is_per_mode_name("FSI.added_mass_7") and not is_per_mode_name("MAG.stiffness")


def test_the_effect_of_a_parameter_is_found(hydro_unit):
    assert effect_providing(hydro_unit, "LGB.damping_change") == "bearing_change:LGB"
    assert effect_providing(hydro_unit, "FSI.added_damping_2") == "fsi_per_mode"
    assert effect_providing(hydro_unit, "UGB.kxx") is None


def test_register_refuses_what_is_not_an_effect_and_a_second_key(fresh_registry):
    with pytest.raises(TypeError, match="not an Effect class"):
        register(dict)

    class NoKey(Effect):
        pass

    with pytest.raises(ValueError, match="non-empty name"):
        register(NoKey)

    class Twice(Effect):
        key = "magnetic_pull"

    with pytest.raises(ValueError, match="two effects with the key 'magnetic_pull'"):
        register(Twice)


def test_a_plugin_through_an_entry_point_reaches_model_files_and_the_diagnosis(
    fresh_registry, monkeypatch, tmp_path, hydro_unit
):
    (tmp_path / "twin_test_plugin.py").write_text(PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "twin_test_plugin", raising=False)
    entry = importlib.metadata.EntryPoint("housing", "twin_test_plugin", registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(
        registry.importlib.metadata,
        "entry_points",
        lambda group: [entry] if group == registry.ENTRY_POINT_GROUP else [],
    )

    assert "housing_mass_test" in effect_classes(local=False)
    assert "housing_mass_test" in [effect_label(e) for e in library_effects(hydro_unit)]
    from twin.loop.candidates import candidates

    assert "housing_mass_test" in [c.label for c in candidates(hydro_unit)]
    model = hydro_unit.with_effects(from_label("housing_mass_test", mass=5e3))
    assert model.parameter("HOUSING.mass").nominal == 5e3
    path = tmp_path / "unit.toml"
    path.write_text((ROOT / "models" / "hydro_unit.toml").read_text() + "\n[effects.housing_mass_test]\nmass = 5e3\n")
    assert load_model(path).parameter("HOUSING.mass").nominal == 5e3
    assert effect_providing(hydro_unit, "HOUSING.mass") == "housing_mass_test"


def test_a_broken_plugin_is_reported_and_left_out(fresh_registry, monkeypatch, caplog):
    entry = importlib.metadata.EntryPoint("broken", "no_such_module_of_twin", registry.ENTRY_POINT_GROUP)
    monkeypatch.setattr(registry.importlib.metadata, "entry_points", lambda group: [entry])
    with caplog.at_level(logging.WARNING, logger="twin.fem.effects.registry"):
        classes = effect_classes()
    assert "magnetic_pull" in classes and "'broken'" in caplog.text and "could not be loaded" in caplog.text


def test_effects_compare_by_value():
    assert BearingChange("UGB", -1e8) == from_label("bearing_change:UGB", stiffness_change=-1e8)
    assert ShaftStiffnessChange(3) == from_label("shaft_stiffness:3")
    assert MagneticPull(-1e8) != MagneticPull(-2e8) and FluidAddedMass() == from_label("fsi")
