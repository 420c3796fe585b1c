"""Local changes outside the library: footprints equal to changing the element itself."""

import dataclasses

import numpy as np
import pytest

from twin.fem.effects import DiskInertiaChange, DiskMassChange, ShaftStiffnessChange, effect_classes, local_changes


def test_shaft_stiffness_change_equals_weakening_the_material(hydro_unit):
    """Young's and shear moduli at half: the element's stiffness (and its Rayleigh damping share) halves exactly."""
    el = hydro_unit.shaft[18]
    weak = dataclasses.replace(
        el, material=dataclasses.replace(el.material, E=0.5 * el.material.E, G=0.5 * el.material.G)
    )
    by_material = dataclasses.replace(hydro_unit, shaft=tuple(weak if e.n == 18 else e for e in hydro_unit.shaft))
    by_change = hydro_unit.with_effects(ShaftStiffnessChange(18, -0.5))
    a, b = by_material.matrices(), by_change.matrices()
    for kind in "MCGK":
        np.testing.assert_allclose(b[kind], a[kind], rtol=1e-12, atol=1e-6 * np.abs(a[kind]).max())


def test_disk_changes_scale_the_disk(hydro_unit):
    base = hydro_unit.matrices()
    heavier = hydro_unit.with_effects(DiskMassChange("runner", 0.2)).matrices()
    x = 4 * 28
    assert heavier["M"][x, x] - base["M"][x, x] == pytest.approx(0.2 * 8.5e4)
    spun = hydro_unit.with_effects(DiskInertiaChange("generator", -0.1)).matrices()
    a = 4 * 8 + 2
    assert spun["M"][a, a] - base["M"][a, a] == pytest.approx(-0.1 * 6.5e6)
    assert spun["G"][a, a + 1] - base["G"][a, a + 1] == pytest.approx(-0.1 * 1.2e7)


def test_every_change_is_relative_bounded_and_scanned(hydro_unit):
    changes = local_changes(hydro_unit)
    assert len(changes) == len(hydro_unit.shaft) + 2 * len(hydro_unit.disks)
    for c in changes:
        (p,) = c.parameters(hydro_unit)
        assert p.unit == "1" and p.bounds[0] == -1.0 and c.plausible_scale(hydro_unit)[p.name] == 0.5
        assert c.key in effect_classes(local=True) and c.local and c.where(hydro_unit)
