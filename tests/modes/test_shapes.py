"""Complex shape normalisation and MAC."""

import numpy as np
import pytest

from twin.modes.shapes import mac, normalisation_jacobian, normalise_shapes


def test_normalise_is_invariant_to_complex_scaling():
    rng = np.random.default_rng(1)
    shapes = rng.normal(size=(5, 8)) + 1j * rng.normal(size=(5, 8))
    factors = rng.normal(size=(5, 1)) + 1j * rng.normal(size=(5, 1))
    a, b = normalise_shapes(shapes), normalise_shapes(factors * shapes)
    np.testing.assert_allclose(a, b, atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(a, axis=1), 1.0)
    pivot = a[np.arange(5), np.abs(a).argmax(axis=1)]
    assert np.all(pivot.real > 0) and np.allclose(pivot.imag, 0.0)
    assert np.all(normalise_shapes(np.zeros((2, 3))) == 0)


def test_the_normalisation_jacobian_is_the_derivative_of_normalise_shapes():
    rng = np.random.default_rng(3)
    shape = normalise_shapes(rng.standard_normal(6) + 0.3j * rng.standard_normal(6))
    N = normalisation_jacobian(shape)
    h = 1e-6
    for k in range(12):
        x = np.zeros(12)
        x[k] = h
        step = x[:6] + 1j * x[6:]
        plus, minus = (normalise_shapes(shape + s * step) for s in (1, -1))
        slope = (plus - minus) / (2 * h)
        assert np.allclose(np.concatenate([slope.real, slope.imag]), N[:, k], atol=1e-8)
    assert np.linalg.matrix_rank(N) == 12 - 2  # the norm and the reference's phase


def test_mac_properties():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(4, 6)) + 1j * rng.normal(size=(4, 6))
    m = mac(a, a * (2 - 1j))
    np.testing.assert_allclose(np.diag(m), 1.0)
    assert np.all((m >= 0) & (m <= 1 + 1e-12))
    np.testing.assert_allclose(m, m.T, atol=1e-14)
    # complex MAC tells forward from backward circular orbits, which real MAC cannot
    assert float(mac([1, -1j], [1, 1j])) == pytest.approx(0.0)
    assert float(mac(np.real([1, -1j]), np.real([1, 1j]))) == pytest.approx(1.0)
    assert mac(a, a[:2]).shape == (4, 2)
    with pytest.raises(ValueError, match="same length"):
        mac(a, a[:, :3])


def test_mpc_and_mpd_of_real_and_circular_shapes():
    from twin.modes.shapes import mpc, mpd

    real = np.array([1.0, -0.5, 0.2, 0.1]) * np.exp(0.7j)
    circular = np.array([1.0, 1j, 0.5, 0.5j])
    assert np.allclose(mpc(np.array([real, circular])), [1.0, 0.0], atol=1e-12)
    assert np.allclose(mpd(np.array([real, circular])), [0.0, 45.0], atol=1e-9)
