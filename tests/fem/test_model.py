"""RotorModel assembly: ROSS matrices, linear parameters, the hydro unit."""

import numpy as np
import pytest

from twin import ModelError, modal
from twin.fem.parameters import MATRIX_KINDS

from tests.conftest import DATA


def test_matrices_match_ross(ross_model):
    ref = np.load(DATA / "ross_rotor_28dof.npz")
    mats = ross_model.matrices()
    for kind in MATRIX_KINDS:
        err = np.abs(mats[kind] - ref[kind]).max() / np.abs(ref[kind]).max()
        assert err < 1e-9, f"{kind}: relative deviation from ROSS {err:.2e}"


def test_matrix_symmetries(hydro_unit):
    mats = hydro_unit.matrices()
    np.testing.assert_allclose(mats["M"], mats["M"].T, atol=0)
    np.testing.assert_allclose(mats["G"], -mats["G"].T, atol=0)
    shaft_k = hydro_unit.fixed_matrices["K"]
    np.testing.assert_allclose(shaft_k, shaft_k.T, atol=0)
    assert np.all(np.linalg.eigvalsh(mats["M"]) > 0)


def test_parameters_enter_linearly(hydro_unit):
    base = hydro_unit.matrices()
    theta = {"UGB.kxy": 3.0e8, "runner.m": 9.0e4, "generator.Ip": 1.1e7, "thrust.c_tilt": 5e7}
    changed = hydro_unit.matrices(theta)
    for kind in MATRIX_KINDS:
        expected = base[kind].copy()
        for name, value in theta.items():
            p = hydro_unit.parameter(name)
            expected += (value - p.nominal) * p.footprint(kind, hydro_unit.n_dof).toarray()
        np.testing.assert_allclose(changed[kind], expected, rtol=1e-13, atol=1e-6)
    # X(theta) = X0 + sum theta_k X_k exactly at the nominal values
    for kind in MATRIX_KINDS:
        rebuilt = hydro_unit.fixed_matrices[kind] + sum(
            p.nominal * p.footprint(kind, hydro_unit.n_dof).toarray() for p in hydro_unit.parameters
        )
        np.testing.assert_allclose(base[kind], rebuilt, rtol=1e-13, atol=1e-6)


def test_with_values_and_unknown_parameter(hydro_unit):
    m = hydro_unit.with_values({"LGB.cxx": 1.0e9})
    assert m.parameter("LGB.cxx").nominal == 1.0e9
    assert hydro_unit.parameter("LGB.cxx").nominal == 1.53e9
    with pytest.raises(ModelError, match=r"no parameter 'UGB\.kzz'.*UGB\.k"):
        hydro_unit.with_values({"UGB.kzz": 1.0})
    with pytest.raises(ModelError, match="no parameter"):
        hydro_unit.matrices({"nope": 1.0})


def test_hydro_unit_description(hydro_unit):
    assert (hydro_unit.n_nodes, hydro_unit.n_dof) == (29, 116)
    assert hydro_unit.speed_rpm == 134.0
    assert hydro_unit.parameter("runner.m").nominal == 85e3
    assert hydro_unit.channels == ["SEAL_x", "SEAL_y", "UGB_x", "UGB_y", "LGB_x", "LGB_y", "GEN_x", "GEN_y"]
    assert len(hydro_unit.sensor_dofs) == 8
    # the paper's bearing coefficients
    assert hydro_unit.parameter("UGB.kyx").nominal == -1.54e9
    assert hydro_unit.parameter("LGB.kxy").nominal == 1.07e10
    bearing_params = [n for n in hydro_unit.parameter_names if n.startswith(("UGB.", "LGB."))]
    assert len(bearing_params) == 16
    # bearings sit at observed nodes; the immersed runner node is next to the observed seal node
    observed = set(hydro_unit.sensor_dofs)
    for name in bearing_params:
        assert set(hydro_unit.parameter(name).dofs) <= observed
    immersed = hydro_unit.region_dofs("immersed")
    assert len(immersed) == 2 and not set(immersed) & observed
    assert hydro_unit.regions["immersed"][0] - 1 == hydro_unit.regions["seal"][0]
    assert np.all(np.diff(hydro_unit.node_z) > 0)


def test_hydro_unit_modes_meet_the_design_targets(hydro_unit):
    ds = modal(hydro_unit)
    f, zeta = ds.frequency.values, ds.damping_ratio.values
    assert 1.0 < f[0] < 5.0
    light = (f < 100.0) & (zeta > 0.003) & (zeta < 0.10)
    assert light.sum() >= 15
    assert ds.stable.all()


def test_model_rejects_items_off_the_shaft(ross_model):
    import dataclasses

    from twin.fem.elements import Disk

    with pytest.raises(ModelError, match="disk 'far' is on node 9"):
        dataclasses.replace(ross_model, disks=(Disk("far", 9, 1.0, 1.0, 1.0),))


def test_the_model_says_which_physics_is_on():
    from twin.fem.modelfile import model_from_dict

    data = {
        "model": {"name": "m", "speed_rpm": 0.0, "shear_deformation": False, "gyroscopic": True},
        "materials": {"steel": {"E": 2.1e11, "G": 8.1e10, "rho": 7800.0}},
        "shaft": [{"nodes": [0, 2], "length": 1.0, "outer_diameter": 0.1, "inner_diameter": 0.0, "material": "steel"}],
        "damping": {"shaft_stiffness_proportional": 1e-4},
    }
    physics = model_from_dict(data).physics
    assert physics["shear_deformation"] is False and physics["rotary_inertia"] is True
    assert physics["gyroscopic"] is True and physics["shaft_stiffness_proportional"] == 1e-4
