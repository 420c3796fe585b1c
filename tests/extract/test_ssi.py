"""Covariances, Hankel matrix and the fast multi-order SSI realisation."""

import numpy as np
import pytest

from twin.extract.ssi import block_covariances, hankel, realise
from twin.modes.shapes import mac


def test_blocks_add_up_to_the_whole_record_and_leave_one_out_is_exact():
    y = np.random.default_rng(0).standard_normal((2003, 3))
    bc = block_covariances(y, max_lag=7, n_blocks=5)
    for k in (0, 1, 7):
        direct = y[k:].T @ y[: len(y) - k] / (len(y) - k)
        assert np.allclose(bc.covariance()[k], direct, rtol=1e-12, atol=1e-14)
    # leaving out block 2 = the lagged products of every t outside that block
    edges = np.linspace(0, len(y), 6).astype(int)
    t = np.r_[0 : edges[2], edges[3] : len(y) - 7]
    direct = y[t + 7].T @ y[t] / len(t)
    assert np.allclose(bc.covariance(leave_out=2)[7], direct, rtol=1e-12)


def test_hankel_blocks():
    R = np.arange(10)[:, None, None] * np.ones((10, 2, 2))
    H = hankel(R, 3)
    assert H.shape == (8, 6)
    assert H[0, 0] == 1 and H[6, 4] == 3 + 2 + 1  # block (3, 2) holds R_6


def test_fast_multi_order_equals_least_squares_at_every_order():
    rng = np.random.default_rng(1)
    y = rng.standard_normal((5000, 3))
    y[1:] += 0.8 * y[:-1]
    R = block_covariances(y, 20).covariance()
    real = realise(R, 10, 12, fs_hz=1.0)
    H = hankel(R, 10)
    U, s, _ = np.linalg.svd(H)
    for n in (2, 6, 12):
        O = U[:, :n] * np.sqrt(s[:n])
        A = np.linalg.lstsq(O[:-3], O[3:], rcond=None)[0]
        lam_ls = np.log(np.linalg.eigvals(A).astype(complex))
        lam_ls = np.sort_complex(lam_ls[(lam_ls.imag > 0) & (lam_ls.imag < 0.99 * np.pi)])
        lam, _ = real.modes(n)
        assert np.allclose(np.sort_complex(lam), lam_ls, rtol=1e-9)


def _two_mode_system(fs: float, n_lags: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A 2-mode discrete system at ``fs`` (real 2x2 blocks ``[[Re, Im], [-Im, Re]]``): ``A``, ``C``, its exact
    output covariances ``R_0 ... R_(n_lags - 1)`` under unit state noise, and its poles."""
    import scipy.linalg as sla

    poles = np.array([-0.1 + 2j * np.pi * 1.5, -0.3 + 2j * np.pi * 4.0])
    mu = np.exp(poles / fs)
    A = np.zeros((4, 4))
    for k, m in enumerate(mu):
        A[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = [[m.real, m.imag], [-m.imag, m.real]]
    C = np.array([[1.0, 0.0, 0.3, 0.2], [0.0, 1.0, -0.5, 1.0], [0.4, 0.4, 0.0, 1.0]])
    sigma = sla.solve_discrete_lyapunov(A, np.eye(4))
    R = np.array([C @ np.linalg.matrix_power(A, k) @ sigma @ C.T for k in range(n_lags)])
    return A, C, R, poles


def test_exact_covariances_give_the_exact_poles():
    """With the exact output covariances of a 2-mode system, SSI returns its poles to round-off."""
    fs = 20.0
    _, _, R, poles = _two_mode_system(fs, 13)
    lam, _ = realise(R, 6, 4, fs).modes(4)
    assert np.allclose(np.sort_complex(lam), np.sort_complex(poles), rtol=1e-9)


def test_leading_triplets_by_lanczos_equal_the_full_svd():
    """A Hankel matrix of 60 lags of a 4-channel record: the 20 leading singular values and vectors from
    ARPACK are the full SVD's to round-off, so the realisation's poles are the same."""
    import twin.extract.ssi as ssi

    rng = np.random.default_rng(3)
    y = rng.standard_normal((20000, 4))
    for k in range(1, 4):
        y[k:] += 0.6**k * y[:-k]
    R = block_covariances(y, 120).covariance()
    H = hankel(R, 60)
    U, s = ssi.leading_singular(H, 20)
    U_full, s_full, _ = np.linalg.svd(H, full_matrices=False)
    assert np.allclose(s, s_full[:20], rtol=1e-10)
    assert np.allclose(np.abs(np.sum(U * U_full[:, :20], axis=0)), 1.0, atol=1e-9)  # same vectors up to sign
    partial = realise(R, 60, 20, fs_hz=1.0).modes(20)[0]
    fraction, ssi.PARTIAL_SVD_FRACTION = ssi.PARTIAL_SVD_FRACTION, 0.0  # every triplet from the full SVD
    try:
        full = realise(R, 60, 20, fs_hz=1.0).modes(20)[0]
    finally:
        ssi.PARTIAL_SVD_FRACTION = fraction
    assert np.allclose(np.sort_complex(partial), np.sort_complex(full), rtol=1e-8, atol=1e-10)


def _mode_shapes(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """The exact output shapes of ``A``'s modes with Im > 0, by frequency, as columns (channels, modes)."""
    mu, v = np.linalg.eig(A)
    up = np.flatnonzero(mu.imag > 0)
    return C @ v[:, up[np.argsort(np.angle(mu[up]))]]


def _by_frequency(lam: np.ndarray, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(lam.imag)
    return lam[order], phi[:, order]


def test_hankel_from_a_later_lag():
    R = np.arange(12)[:, None, None] * np.ones((12, 2, 2))
    H = hankel(R, 3, first_lag=4)
    assert H[0, 0] == 4 and H[6, 4] == 3 + 2 + 4  # block (3, 2) holds R_9
    with pytest.raises(ValueError, match="covariances to lag 12, got 11"):
        hankel(R, 3, first_lag=7)
    with pytest.raises(ValueError, match="starts at lag 1 or later"):
        hankel(R, 3, first_lag=0)


def test_a_later_first_lag_gives_the_same_exact_modes():
    """R_k = C A^(k-1) G from any first lag on: the same poles and shapes to round-off."""
    fs = 20.0
    A, C, R, poles = _two_mode_system(fs, 20)
    exact = _mode_shapes(A, C)
    for k0 in (1, 2, 5):
        lam, phi = _by_frequency(*realise(R, 6, 4, fs, first_lag=k0).modes(4))
        assert np.allclose(lam, poles, rtol=1e-9)
        assert all(mac(phi[:, k], exact[:, k]) > 1 - 1e-12 for k in range(2))


def test_a_short_memory_part_bends_the_modes_unless_the_lags_start_after_it():
    """A part of the covariances that lives at lags 1-2 only (dynamics above the band, a filter) is no
    mode of an order-4 model: from lag 1 it bends the poles and shapes; from lag 3 they are exact."""
    fs = 20.0
    A, C, R, poles = _two_mode_system(fs, 20)
    short = 0.03 * np.abs(R[1]).max() * np.array([[1.0, -0.7, 0.3], [0.0, 0.7, 1.0], [0.3, 0.0, -1.0]])
    R[1] += short
    R[2] += 0.4 * short
    exact = _mode_shapes(A, C)
    lam1, phi1 = _by_frequency(*realise(R, 6, 4, fs, first_lag=1).modes(4))
    lam3, phi3 = _by_frequency(*realise(R, 6, 4, fs, first_lag=3).modes(4))
    assert np.max(np.abs(lam1 - poles) / np.abs(poles)) > 1e-3
    assert min(mac(phi1[:, k], exact[:, k]) for k in range(2)) < 0.9999
    assert np.allclose(lam3, poles, rtol=1e-9)
    assert all(mac(phi3[:, k], exact[:, k]) > 1 - 1e-12 for k in range(2))
