"""Complex shape normalisation and MAC."""

import numpy as np
import pytest

from twin.modes.shapes import mac, normalise_shapes


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
