"""Modal analysis against ROSS and against exact beam frequencies."""

import numpy as np
import pytest

from twin import modal
from twin.fem.elements import Bearing, Material, ShaftElement
from twin.fem.model import RotorModel
from twin.modes.analysis import whirl_direction

from tests.conftest import DATA

STEEL = Material("steel", 2.06e11, 7.98e10, 7850.0)


@pytest.mark.parametrize("row, speed_rpm", [(0, 0.0), (1, 134.0)])
def test_eigenvalues_match_ross(ross_model, row, speed_rpm):
    ref = np.load(DATA / "ross_rotor_28dof.npz")
    assert ref["speed"][row] == pytest.approx(speed_rpm * 2 * np.pi / 60)
    expected = ref["eigenvalues"][row]
    ds = modal(ross_model, speed_rpm=speed_rpm, n_modes=len(expected))
    err = np.abs(ds.pole.values - expected) / np.abs(expected)
    assert err.max() < 1e-8, f"largest relative deviation from ROSS {err.max():.2e}"
    # the cross-coupled bearings make the first forward mode unstable
    assert ds.pole.values[0].real > 0 and not ds.stable.values[0]
    assert ds.whirl.values[0] == "forward"
    assert ds.stable.values[1:].all()


def _pinned_beam(n_el, length, d, shear=True, rotary=True):
    coeffs = dict(kxx=1e16, kxy=0.0, kyx=0.0, kyy=1e16, cxx=0.0, cxy=0.0, cyx=0.0, cyy=0.0)
    shaft = [ShaftElement(i, length / n_el, d, 0.0, STEEL, shear=shear, rotary_inertia=rotary) for i in range(n_el)]
    return RotorModel("beam", shaft, bearings=[Bearing("A", 0, coeffs), Bearing("B", n_el, coeffs)])


def _timoshenko_simply_supported(n, length, d):
    # EI k^4 - w^2 [rho A + k^2 (rho I + E I rho / (kappa G))] + w^4 rho^2 I / (kappa G) = 0
    el = ShaftElement(0, length, d, 0.0, STEEL)
    from twin.fem.elements import cowper_shear_factor

    kappa = cowper_shear_factor(STEEL.poisson, 0.0, d)
    E, G, rho, A, I = STEEL.E, STEEL.G, STEEL.rho, el.area, el.second_moment
    k = n * np.pi / length
    a = rho**2 * I / (kappa * G)
    b = -(rho * A + k**2 * (rho * I + E * I * rho / (kappa * G)))
    c = E * I * k**4
    w2 = (-b - np.sqrt(b**2 - 4 * a * c)) / (2 * a)
    return np.sqrt(w2) / (2 * np.pi)


@pytest.mark.parametrize("slenderness", [20.0, 4.0])
def test_simply_supported_timoshenko_beam_frequencies_converge_to_exact(slenderness):
    # Exact Timoshenko frequencies of a simply supported beam; with shear on, this standard
    # element (Friswell; ROSS) converges at O(h^2), so the Richardson extrapolation of 40 and
    # 80 elements must agree with the exact value far better than either mesh alone.
    d = 0.2
    length = slenderness * d
    coarse, fine = (
        modal(_pinned_beam(n, length, d), speed_rpm=0.0, n_modes=6).natural_frequency.values for n in (40, 80)
    )
    for n in (1, 2, 3):
        exact = _timoshenko_simply_supported(n, length, d)
        # each bending mode appears twice (x and y planes)
        f40, f80 = coarse[2 * n - 2 : 2 * n], fine[2 * n - 2 : 2 * n]
        assert np.all(np.abs(f80 / exact - 1) < 3e-4)
        assert np.all(np.abs(f80 - exact) < 0.3 * np.abs(f40 - exact))  # order ~2
        np.testing.assert_allclose(f80 + (f80 - f40) / 3.0, exact, rtol=2e-6)


def test_euler_bernoulli_beam_frequency():
    d, length = 0.05, 2.0
    ds = modal(_pinned_beam(30, length, d, shear=False, rotary=False), speed_rpm=0.0, n_modes=2)
    area, inertia = np.pi * d**2 / 4, np.pi * d**4 / 64
    exact = (np.pi / length) ** 2 * np.sqrt(STEEL.E * inertia / (STEEL.rho * area)) / (2 * np.pi)
    np.testing.assert_allclose(ds.natural_frequency.values, exact, rtol=1e-6)


def test_modal_dataset_contents(hydro_unit):
    ds = modal(hydro_unit, n_modes=5)
    assert dict(ds.sizes) == {"mode": 5, "dof": 116, "channel": 8}
    pole = ds.pole.values
    np.testing.assert_allclose(ds.frequency, pole.imag / (2 * np.pi))
    np.testing.assert_allclose(ds.natural_frequency, np.abs(pole) / (2 * np.pi))
    np.testing.assert_allclose(ds.damping_ratio, -pole.real / np.abs(pole))
    zeta = ds.damping_ratio.values
    np.testing.assert_allclose(ds.log_decrement, 2 * np.pi * zeta / np.sqrt(1 - zeta**2), rtol=1e-12)
    # shapes: unit norm, largest entry real positive, on all DOFs and on the sensors
    for var in ("shape", "sensor_shape"):
        s = ds[var].values
        np.testing.assert_allclose(np.linalg.norm(s, axis=1), 1.0, rtol=1e-12)
        pivot = s[np.arange(5), np.abs(s).argmax(axis=1)]
        np.testing.assert_allclose(pivot.imag, 0.0, atol=1e-14)
        assert np.all(pivot.real > 0)
    # the sensor shape is the full shape at the sensor DOFs, up to a complex factor
    full = ds.shape.values[:, hydro_unit.sensor_dofs]
    ratio = full / ds.sensor_shape.values
    np.testing.assert_allclose(ratio, ratio[:, :1] * np.ones((1, 8)), rtol=1e-9)
    # each mode satisfies the eigenproblem
    mats = hydro_unit.matrices()
    omega = 134 * 2 * np.pi / 60
    for lam, phi in zip(pole, ds.shape.values):
        z = lam**2 * mats["M"] + lam * (mats["C"] + omega * mats["G"]) + mats["K"]
        assert np.linalg.norm(z @ phi) < 1e-9 * np.linalg.norm(z, 2)
    assert ds.attrs["speed_rpm"] == 134.0 and ds.attrs["n_dof"] == 116


def test_whirl_direction_of_orbits():
    fwd = np.array([1, -1j, 0, 0])  # x = cos, y = sin
    bwd = np.array([1, 1j, 0, 0])
    line = np.array([1, 1, 0, 0])
    labels, index = whirl_direction(np.array([np.r_[fwd, fwd], np.r_[bwd, 0.5 * bwd], np.r_[fwd, bwd]]))
    assert list(labels) == ["forward", "backward", "mixed"]
    np.testing.assert_allclose(index[:2], [1.0, -1.0])
    # a node that barely moves does not vote
    labels, _ = whirl_direction(np.array([np.r_[fwd, 1e-3 * bwd]]))
    assert labels[0] == "forward"
    _, index = whirl_direction(np.array([line]))
    assert index[0] == 0.0


def test_speed_changes_gyroscopic_splitting(ross_model):
    slow = modal(ross_model, speed_rpm=0.0, n_modes=4)
    fast = modal(ross_model, speed_rpm=5000.0, n_modes=4)
    # backward/forward pairs split further apart with speed
    split = lambda ds: ds.frequency.values[3] - ds.frequency.values[2]  # noqa: E731
    assert split(fast) > split(slow)


def test_bad_speed_and_mode_count(ross_model):
    from twin import ModelError

    with pytest.raises(ModelError, match="finite"):
        modal(ross_model, speed_rpm=float("nan"))
    with pytest.raises(ModelError, match="n_modes"):
        modal(ross_model, n_modes=0)


def test_overdamped_eigenvalues_are_no_modes_anywhere(ross_model):
    """Stiffness-proportional damping on short elements gives near-real eigenvalue pairs: neither the modal table
    nor the modes the loop and the tracker solve for count them, and both agree on the modes that remain."""
    import dataclasses

    from twin.modes.analysis import OSCILLATION_RATIO
    from twin.modes.sensitivity import solve_modes

    damped = dataclasses.replace(ross_model, rayleigh=(0.0, 1e-3), speed_rpm=3000.0)
    ds = modal(damped)
    poles = solve_modes(damped).poles
    assert ds.attrs["n_overdamped"] > 10  # the element eigenvalues this damping makes
    assert np.all(poles.imag >= OSCILLATION_RATIO * np.abs(poles))
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(ds.pole.values), rtol=1e-9)
