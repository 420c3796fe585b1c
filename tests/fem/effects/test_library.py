"""Physical effects: footprints on model regions and their physical sign."""

import dataclasses

import numpy as np
import pytest

from twin import ModelError, modal
from twin.fem.effects import FluidAddedMass, FluidAddedMassPerMode, MagneticPull, SealCrossCoupling, effect_classes


def _with(model, effect):
    import dataclasses

    return dataclasses.replace(model, effects=(effect,))


def _conservative(model):
    """The unit at rest with symmetric, undamped bearings: Rayleigh's theorem holds exactly."""
    import dataclasses

    values = {
        p.name: 0.0
        for p in model.parameters
        if p.name.split(".")[1] in ("kxy", "kyx", "cxx", "cxy", "cyx", "cyy", "c_tilt")
    }
    return dataclasses.replace(model, values=values, rayleigh=(0.0, 0.0), speed_rpm=0.0)


def _undamped_frequencies(model, n):
    import scipy.linalg as sla

    mats = model.matrices()
    return np.sqrt(sla.eigh(mats["K"], mats["M"], eigvals_only=True, subset_by_index=[0, n - 1])) / (2 * np.pi)


def test_fsi_is_shared_equally_over_the_immersed_dofs(hydro_unit):
    model = _with(hydro_unit, FluidAddedMass(added_mass=1.0e5, added_damping=2.0e6))
    dofs = hydro_unit.region_dofs("immersed")
    dM = model.matrices()["M"] - hydro_unit.matrices()["M"]
    dC = model.matrices()["C"] - hydro_unit.matrices()["C"]
    np.testing.assert_allclose(np.diag(dM)[list(dofs)], 1.0e5 / len(dofs))
    assert dM.sum() == pytest.approx(1.0e5) and dC.sum() == pytest.approx(2.0e6)
    assert np.count_nonzero(dM) == len(dofs)
    # Rayleigh: added mass lowers every frequency of the conservative system
    air = _undamped_frequencies(_conservative(hydro_unit), 20)
    water = _undamped_frequencies(_with(_conservative(hydro_unit), FluidAddedMass(added_mass=1.0e5)), 20)
    assert np.all(water <= air * (1 + 1e-12)) and np.any(water < air * 0.95)


def test_per_mode_fsi_parameters(hydro_unit):
    effect = FluidAddedMassPerMode(added_mass=(1e5, 9e4), added_damping=(7e7, 1e7))
    params = effect.parameters(hydro_unit)
    assert [p.name for p in params] == [
        "FSI.added_mass_1",
        "FSI.added_damping_1",
        "FSI.added_mass_2",
        "FSI.added_damping_2",
    ]
    assert all(p.per_mode for p in params)
    # per-mode parameters are not part of the single FEM
    model = _with(hydro_unit, effect)
    np.testing.assert_array_equal(model.matrices()["M"], hydro_unit.matrices()["M"])
    with pytest.raises(ValueError, match="as many added masses"):
        FluidAddedMassPerMode(added_mass=(1.0,), added_damping=())


def test_magnetic_pull_is_a_negative_stiffness_at_the_generator(hydro_unit):
    model = _with(hydro_unit, MagneticPull(stiffness=-2.0e8))
    dK = model.matrices()["K"] - hydro_unit.matrices()["K"]
    x, y = hydro_unit.region_dofs("generator")
    assert dK[x, x] == dK[y, y] == -2.0e8
    assert np.count_nonzero(dK) == 2
    # Rayleigh: a negative stiffness lowers every frequency of the conservative system
    f_air = _undamped_frequencies(_conservative(hydro_unit), 20)
    f_mag = _undamped_frequencies(_with(_conservative(hydro_unit), MagneticPull(stiffness=-2.0e8)), 20)
    assert np.all(f_mag <= f_air * (1 + 1e-12)) and np.any(f_mag < f_air * (1 - 1e-3))


def test_seal_cross_coupling_destabilises_forward_whirl(ross_model):
    import dataclasses

    model = dataclasses.replace(ross_model, regions={"seal": (3,)})
    base = modal(model, n_modes=4)
    coupled = modal(_with(model, SealCrossCoupling(kxy=2.0e5)), n_modes=4)
    forward = base.whirl.values == "forward"
    # forward modes lose damping, backward modes gain it
    assert np.all(coupled.damping_ratio.values[forward] < base.damping_ratio.values[forward])
    assert np.all(coupled.damping_ratio.values[~forward] > base.damping_ratio.values[~forward])
    K = _with(model, SealCrossCoupling(kxy=1.0)).matrices()["K"] - model.matrices()["K"]
    assert K[12, 13] == 1.0 and K[13, 12] == -1.0


def test_every_library_effect_has_a_region_or_an_element_and_an_explanation():
    for key, cls in effect_classes(local=False).items():
        assert cls.key == key and (cls.region is None) != (cls.element is None) and len(cls.explanation) > 20


def test_region_effects_explain_themselves_in_the_machines_words(hydro_unit):
    # the disks in the effect's region name it; a region without a disk is named by its nodes; every
    # placeholder is filled, on any machine and without one
    other = dataclasses.replace(hydro_unit, regions={"generator": (8,), "immersed": (27, 28), "seal": (26, 27)})
    assert FluidAddedMass.explain(hydro_unit).startswith("the water around the runner ")
    assert MagneticPull.explain(other).startswith("an off-centre rotor at the generator ")
    assert "the seals at nodes 26, 27 " in SealCrossCoupling.explain(other)
    assert FluidAddedMass.explain(other).startswith("the water around the runner ")  # node 28 of the two
    for cls in effect_classes(local=False).values():
        assert "{" not in cls.explain(hydro_unit) and "{" not in cls.explain()


def test_element_effects_change_the_named_element(hydro_unit):
    from twin.fem.effects import BearingChange, ThrustTilt

    model = dataclasses.replace(hydro_unit, effects=(BearingChange("LGB", -2e7, 1e8), ThrustTilt("thrust", 1e8)))
    base, changed = hydro_unit.matrices(), model.matrices()
    x, y = 4 * 25, 4 * 25 + 1
    assert changed["K"][x, x] - base["K"][x, x] == pytest.approx(-2e7)
    assert changed["K"][y, y] - base["K"][y, y] == pytest.approx(-2e7)
    assert changed["C"][x, x] - base["C"][x, x] == pytest.approx(1e8)
    assert changed["K"][x, y] == base["K"][x, y]
    a = 4 * 3 + 2
    assert changed["K"][a, a] - base["K"][a, a] == pytest.approx(1e8)
    scales = BearingChange("LGB").plausible_scale(hydro_unit)
    assert scales["LGB.stiffness_change"] == pytest.approx(0.5 * (1.1e8 + 5.47e7) / 2)


def test_element_effect_on_a_missing_element_names_it(hydro_unit):
    from twin.fem.effects import BearingChange

    with pytest.raises(ModelError, match="no bearing 'XGB'.*'UGB', 'LGB'"):
        dataclasses.replace(hydro_unit, effects=(BearingChange("XGB"),)).parameters


def test_every_effect_states_a_positive_scale_for_each_parameter(hydro_unit):
    for cls in effect_classes().values():
        effects = cls.instances(hydro_unit)
        assert effects, cls.key
        for effect in effects:
            effect = effect.with_modes(2) if effect.per_mode else effect
            scales = effect.plausible_scale(hydro_unit)
            assert set(scales) == {p.name for p in effect.parameters(hydro_unit)} != set()
            assert all(v > 0 for v in scales.values())
