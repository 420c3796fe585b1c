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


def test_assign_is_the_least_total_cost_over_every_one_to_one_assignment():
    """Checked against brute force over all permutations, with gates."""
    import itertools

    from twin.modes.pairing import assign

    rng = np.random.default_rng(11)
    for _ in range(40):
        rows, cols = int(rng.integers(1, 5)), int(rng.integers(1, 5))
        cost = rng.uniform(0.0, 1.0, (rows, cols))
        allowed = rng.uniform(size=(rows, cols)) < 0.7
        got = assign(cost, allowed)
        assert len(set(got[got >= 0])) == int((got >= 0).sum())  # one to one
        assert all(allowed[r, c] for r, c in enumerate(got) if c >= 0)
        best = (0, 0.0)  # (pairs, -cost) of the best assignment
        for perm in itertools.permutations(range(max(rows, cols)), rows):
            pairs = [(r, c) for r, c in enumerate(perm) if c < cols and allowed[r, c]]
            best = max(best, (len(pairs), -sum(cost[r, c] for r, c in pairs)))
        made = [(r, c) for r, c in enumerate(got) if c >= 0]
        assert len(made) == best[0]
        assert np.isclose(sum(cost[r, c] for r, c in made), -best[1])


def test_assign_with_nothing_allowed_pairs_nothing():
    from twin.modes.pairing import assign

    assert assign(np.ones((2, 3)), np.zeros((2, 3), bool)).tolist() == [-1, -1]
    assert assign(np.full((2, 2), np.inf)).tolist() == [-1, -1]
