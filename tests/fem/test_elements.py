"""Element matrices against closed-form results."""

import numpy as np
import pytest

from twin.fem.elements import (
    Bearing,
    Disk,
    Material,
    ShaftElement,
    ThrustBearing,
    cowper_shear_factor,
    node_dofs,
)

STEEL = Material("steel", 2.06e11, 7.98e10, 7850.0)


def _assemble_cantilever(n_el: int, length: float, od: float, id_: float, material: Material, shear=True):
    K = np.zeros((4 * (n_el + 1),) * 2)
    for i in range(n_el):
        el = ShaftElement(i, length / n_el, od, id_, material, shear=shear)
        K[np.ix_(el.dofs, el.dofs)] += el.K()
    return K[4:, 4:]  # node 0 clamped


@pytest.mark.parametrize("od, id_", [(0.1, 0.0), (1.05, 0.35)])
@pytest.mark.parametrize("n_el", [1, 5])
def test_cantilever_tip_deflection_is_exact_timoshenko(od, id_, n_el):
    # Timoshenko: delta = P L^3 / (3 E I) + P L / (kappa G A), exact for this element
    L, P = 2.0, 1.0e5
    K = _assemble_cantilever(n_el, L, od, id_, STEEL)
    F = np.zeros(K.shape[0])
    F[-4] = P  # x at the tip
    q = np.linalg.solve(K, F)
    el = ShaftElement(0, L, od, id_, STEEL)
    kappa = cowper_shear_factor(STEEL.poisson, id_, od)
    exact = P * L**3 / (3 * STEEL.E * el.second_moment) + P * L / (kappa * STEEL.G * el.area)
    assert q[-4] == pytest.approx(exact, rel=1e-10)
    # slope beta = dx/dz = P L^2 / (2 E I), unaffected by shear
    assert q[-1] == pytest.approx(P * L**2 / (2 * STEEL.E * el.second_moment), rel=1e-10)
    # the y-z plane gives the same deflection, with alpha = -dy/dz
    F = np.zeros(K.shape[0])
    F[-3] = P
    q = np.linalg.solve(K, F)
    assert q[-3] == pytest.approx(exact, rel=1e-10)
    assert q[-2] == pytest.approx(-P * L**2 / (2 * STEEL.E * el.second_moment), rel=1e-10)


def test_euler_bernoulli_limit_when_shear_stiffness_grows():
    # the shear stiffness kappa G A L^2 / (12 E I) grows with slenderness: phi ~ (d / L)^2 -> 0
    diffs, phis = [], []
    for length in (0.3, 3.0, 30.0, 300.0):
        tim = ShaftElement(0, length, 0.2, 0.05, STEEL)
        eb = ShaftElement(0, length, 0.2, 0.05, STEEL, shear=False)
        phis.append(tim.phi)
        diffs.append(
            [
                np.abs(getattr(tim, m)() - getattr(eb, m)()).max() / np.abs(getattr(eb, m)()).max()
                for m in ("K", "M", "G")
            ]
        )
    diffs = np.array(diffs)
    np.testing.assert_allclose(phis[1:], np.array(phis[:-1]) / 100.0, rtol=1e-12)
    assert np.all(diffs[1:] < diffs[:-1])  # converges monotonically ...
    assert np.all(diffs[-1] < 1e-5)  # ... to the Euler-Bernoulli element
    assert np.all(diffs[-1] < 3 * phis[-1])  # at the rate of phi


def test_euler_bernoulli_stiffness_matrix_closed_form():
    el = ShaftElement(0, 0.5, 0.1, 0.0, STEEL, shear=False)
    EI, L = STEEL.E * el.second_moment, 0.5
    Kxz = el.K()[np.ix_([0, 3, 4, 7], [0, 3, 4, 7])]
    expected = (
        EI
        / L**3
        * np.array(
            [
                [12, 6 * L, -12, 6 * L],
                [6 * L, 4 * L**2, -6 * L, 2 * L**2],
                [-12, -6 * L, 12, -6 * L],
                [6 * L, 2 * L**2, -6 * L, 4 * L**2],
            ]
        )
    )
    np.testing.assert_allclose(Kxz, expected, rtol=1e-13)


@pytest.mark.parametrize("shear", [True, False])
def test_mass_matrix_carries_the_element_mass_and_symmetries(shear):
    el = ShaftElement(3, 0.4, 0.9, 0.3, STEEL, shear=shear)
    M, K, G = el.M(), el.K(), el.G()
    np.testing.assert_allclose(M, M.T, atol=0)
    np.testing.assert_allclose(K, K.T, atol=0)
    np.testing.assert_allclose(G, -G.T, atol=0)
    assert np.all(np.linalg.eigvalsh(M) > 0)
    assert np.linalg.eigvalsh(K).min() > -1e-6 * np.abs(K).max()
    # a rigid translation x = 1 carries the translational mass only
    rigid = np.zeros(8)
    rigid[[0, 4]] = 1.0
    trans = ShaftElement(3, 0.4, 0.9, 0.3, STEEL, shear=shear, rotary_inertia=False)
    assert rigid @ trans.M() @ rigid == pytest.approx(el.mass, rel=1e-12)
    assert np.abs(K @ rigid).max() < 1e-6 * np.abs(K).max()  # no strain energy
    assert el.dofs == node_dofs(3) + node_dofs(4)


def test_gyroscopic_matrix_is_twice_the_polar_rotary_inertia():
    # spinning a rigid element about a tilt: G couples alpha and beta with total Ip = 2 rho I L
    el = ShaftElement(0, 0.4, 0.5, 0.1, STEEL, shear=False)
    tilt_alpha, tilt_beta = np.zeros(8), np.zeros(8)
    tilt_alpha[[2, 6]] = 1.0
    tilt_beta[[3, 7]] = 1.0
    # a rigid rotation also moves x (beta) / y (alpha) linearly; the G coupling of pure
    # rotations of a rigid body must equal its polar moment 2 rho I L
    z = np.array([0.0, 0.4])
    tilt_beta[[0, 4]] = z  # x = beta * z
    tilt_alpha[[1, 5]] = -z  # y = -alpha * z
    ip = 2 * STEEL.rho * el.second_moment * el.length
    assert tilt_alpha @ el.G() @ tilt_beta == pytest.approx(ip, rel=1e-12)


def test_cowper_factor_hollow_and_solid():
    assert cowper_shear_factor(0.3, 0.0, 1.0) == pytest.approx(6 * 1.3 / (7 + 6 * 0.3))
    # thin-walled tube limit (m -> 1): 2 (1 + nu) / (4 + 3 nu)
    assert cowper_shear_factor(0.3, 0.999999, 1.0) == pytest.approx(2 * 1.3 / (4 + 0.9), rel=1e-5)


def test_disk_bearing_thrust_footprints():
    disk = {p.name: p for p in Disk("D", 1, 10.0, 2.0, 3.0).parameters()}
    assert disk["D.m"].dofs == (4, 5) and disk["D.m"].kinds == ("M",)
    G = disk["D.Ip"].footprint("G", 8).toarray()
    assert G[6, 7] == 1.0 and G[7, 6] == -1.0  # G[alpha, beta] = +Ip
    coeffs = dict(kxx=1.0, kxy=2.0, kyx=3.0, kyy=4.0, cxx=5.0, cxy=6.0, cyx=7.0, cyy=8.0)
    K = sum(p.nominal * p.footprint("K", 8).toarray() for p in Bearing("B", 1, coeffs).parameters())
    np.testing.assert_array_equal(K[4:6, 4:6], [[1.0, 2.0], [3.0, 4.0]])
    C = sum(p.nominal * p.footprint("C", 8).toarray() for p in Bearing("B", 1, coeffs).parameters())
    np.testing.assert_array_equal(C[4:6, 4:6], [[5.0, 6.0], [7.0, 8.0]])
    thrust = {p.name: p for p in ThrustBearing("T", 0, 1e9, 1e6).parameters()}
    assert thrust["T.k_tilt"].dofs == (2, 3) and thrust["T.c_tilt"].kinds == ("C",)
