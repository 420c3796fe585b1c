"""Exact pole derivatives against central differences."""

import dataclasses

import numpy as np
import pytest

from twin.fem.effects import (
    BearingChange,
    FluidAddedMass,
    MagneticPull,
    SealCrossCoupling,
)
from twin.modes.sensitivity import pole_jacobian, solve_modes


@pytest.mark.parametrize(
    "name",
    [
        "runner.m",
        "generator.Id",
        "UGB.kxy",
        "LGB.cxx",
        "thrust.k_tilt",
        "MAG.stiffness",
        "SEAL.kxy",
        "FSI.added_damping",
        "LGB.stiffness_change",
    ],
)
def test_pole_derivatives_match_central_differences(hydro_unit, name):
    model = dataclasses.replace(
        hydro_unit, effects=(MagneticPull(), SealCrossCoupling(), FluidAddedMass(), BearingChange("LGB"))
    )
    sol = solve_modes(model)
    jac = pole_jacobian(model, sol, [name], modes=range(15))[:, 0]
    x0 = model.parameter(name).nominal
    h = 1e-4 * max(abs(x0), 1e7 if "FSI" not in name else 1e4)
    up = solve_modes(model, {name: x0 + h}).poles[:15]
    down = solve_modes(model, {name: x0 - h}).poles[:15]
    fd = (up - down) / (2 * h)
    # a wrong term gives O(1) errors; 1e-3 leaves room for the near-degenerate 97 Hz triplet's curvature
    assert np.max(np.abs(fd - jac)) < 1e-3 * np.max(np.abs(jac))


def test_left_vectors_annihilate_the_dynamic_stiffness(hydro_unit):
    sol = solve_modes(hydro_unit)
    mats = hydro_unit.matrices()
    for k in range(5):
        lam = sol.poles[k]
        Z = lam**2 * mats["M"] + lam * (mats["C"] + sol.speed_rad_s * mats["G"]) + mats["K"]
        assert np.linalg.norm(sol.left[k] @ Z) < 1e-9 * np.linalg.norm(Z) * np.linalg.norm(sol.left[k])
        assert np.linalg.norm(Z @ sol.right[k]) < 1e-9 * np.linalg.norm(Z) * np.linalg.norm(sol.right[k])
