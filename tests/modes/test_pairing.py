"""Pairing two modal sets by MAC; frequency ratio and added damping."""

import numpy as np

from twin import modal, pair_modes
from twin.fem.effects import FluidAddedMass
from twin.modes.pairing import added_damping_ratio, frequency_ratio


def test_pairing_recovers_a_permutation(hydro_unit):
    ds = modal(hydro_unit, n_modes=10)
    perm = np.random.default_rng(3).permutation(10)
    shuffled = ds.isel(mode=perm).assign_coords(mode=np.arange(1, 11))
    pairs = pair_modes(ds, shuffled)
    np.testing.assert_array_equal(pairs.other_mode.values, np.argsort(perm) + 1)
    np.testing.assert_allclose(pairs.mac, 1.0)
    np.testing.assert_allclose(pairs.frequency_ratio, 1.0)
    # channels are matched by name, not by position
    reordered = shuffled.isel(channel=[7, 6, 5, 4, 3, 2, 1, 0])
    np.testing.assert_array_equal(pair_modes(ds, reordered).other_mode, pairs.other_mode)


def test_frequency_ratio_and_added_damping_in_water(hydro_unit):
    import dataclasses

    water_model = dataclasses.replace(hydro_unit, effects=(FluidAddedMass(added_mass=8e4, added_damping=5e7),))
    air, water = modal(hydro_unit, n_modes=13), modal(water_model, n_modes=13)
    # on all DOFs the pairing is unambiguous (8 sensors can make different modes look alike)
    pairs = pair_modes(air, water, shape_var="shape", min_mac=0.9)
    assert pairs.sizes["pair"] >= 7
    frr = frequency_ratio(air, water, shape_var="shape", min_mac=0.9)
    np.testing.assert_allclose(frr, pairs.other_frequency / pairs.reference_frequency)
    assert np.all(frr < 1.0 + 1e-9)
    added = added_damping_ratio(air, water, shape_var="shape", min_mac=0.9)
    np.testing.assert_allclose(added, pairs.other_damping_ratio - pairs.reference_damping_ratio)
    assert added.min() > 0 and added.max() > 0.01  # every paired mode gains damping in water


def test_min_mac_drops_unrelated_modes(hydro_unit):
    ds = modal(hydro_unit, n_modes=6)
    other = ds.copy()
    other["sensor_shape"] = other.sensor_shape * 0 + np.eye(6, 8)
    pairs = pair_modes(ds, other, min_mac=0.99)
    assert pairs.sizes["pair"] < 6
