"""Covariance-driven stochastic subspace identification (SSI-cov) at many model orders.

The output covariances ``R_k = E[y(t+k) y(t)^T]`` are accumulated per record
block, so the full record and every record with some blocks left out (the
jackknife of :mod:`twin.extract.samples`) share one pass over the data. The block
Hankel matrix of the covariances is factorised once (SVD); the system matrix
of every order then comes from one QR factorisation of the largest
observability matrix (the fast multi-order solution of Döhler and Mevel,
2012): with ``O_up = Q R`` and ``S = Q^T O_down``, the order-``n`` matrix is
``A_n = R[:n, :n]^-1 S[:n, :n]``.

The Hankel matrix may start at a later lag than the first (``first_lag``):
the same modes, without the lags where dynamics above the band live
(:func:`twin.extract.passes.first_lag_for`, the default of
:func:`twin.extract.extract`).

Only the ``max_order`` leading singular triplets of the Hankel matrix are
used. Where they are fewer than a third of its smaller side they come from
Lanczos bidiagonalisation (ARPACK, converged to machine precision, fixed
start vector) instead of the full SVD: the same modes to round-off, and a
hydro unit record extracted 1.8 times faster at 107 block rows, 3.6 times at
214 (``benchmarks/ssi_speed.py``). A jackknife sample's Hankel matrix differs
from the full record's by a sixteenth of the data: its singular vectors are
iterated from the full record's (subspace iteration, :func:`leading_singular`'s
``start``), in half the time of a fresh Lanczos run.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla

#: The leading singular triplets come from Lanczos (ARPACK) when they are at most this fraction of the
#: Hankel matrix's smaller side; else from the full SVD.
PARTIAL_SVD_FRACTION = 1.0 / 3.0
#: A jackknife sample's leading singular vectors start from the full record's (:func:`leading_singular`'s
#: ``start``), this many columns beyond the model order, ...
START_OVERSAMPLING = 10
#: ... and iterate until the leading singular values move by less than this (relative) from one
#: iteration to the next, ...
START_RTOL = 1e-3
#: ... or this many iterations have run.
START_MAX_ITERATIONS = 12


@dataclass(frozen=True)
class BlockCovariances:
    """Lagged product sums of a record, block by block.

    ``sums[j, k]`` is ``sum_t y(t+k) y(t)^T`` over the samples ``t`` of block
    ``j`` (``t + k`` may run into the next block, so the blocks add up to the
    whole record exactly) and ``counts[j, k]`` the number of terms.
    """

    sums: np.ndarray  # (n_blocks, max_lag + 1, n_channels, n_channels)
    counts: np.ndarray  # (n_blocks, max_lag + 1)

    @property
    def n_blocks(self) -> int:
        return self.sums.shape[0]

    @property
    def max_lag(self) -> int:
        return self.sums.shape[1] - 1

    def covariance(self, leave_out: int | Sequence[int] | None = None) -> np.ndarray:
        """``R_k`` for ``k = 0..max_lag`` (shape ``(max_lag + 1, l, l)``), without the block(s) ``leave_out``."""
        s, c = self.sums.sum(axis=0), self.counts.sum(axis=0)
        if leave_out is not None:
            out = np.atleast_1d(leave_out)
            s, c = s - self.sums[out].sum(axis=0), c - self.counts[out].sum(axis=0)
        return s / c[:, None, None]


def block_covariances(y: np.ndarray, max_lag: int, n_blocks: int = 1) -> BlockCovariances:
    """Lagged product sums of the record ``y`` (time x channel) in ``n_blocks`` contiguous blocks.

    Direct products (BLAS) per lag: for the tens to hundreds of lags SSI
    needs this is faster than FFT correlation.

    Examples
    --------
    >>> y = np.random.default_rng(0).standard_normal((1000, 2))
    >>> bc = block_covariances(y, max_lag=3, n_blocks=4)
    >>> np.allclose(bc.covariance()[1], y[1:].T @ y[:-1] / 999)
    True
    """
    n, l = y.shape
    edges = np.linspace(0, n, n_blocks + 1).astype(int)
    sums = np.empty((n_blocks, max_lag + 1, l, l))
    counts = np.empty((n_blocks, max_lag + 1))
    for j in range(n_blocks):
        s, e = edges[j], edges[j + 1]
        for k in range(max_lag + 1):
            te = max(s, min(e, n - k))  # t + k must stay inside the record
            sums[j, k] = y[s + k : te + k].T @ y[s:te]
            counts[j, k] = te - s
    return BlockCovariances(sums, counts)


def hankel_max_lag(block_rows: int, first_lag: int = 1) -> int:
    """The largest lag the square Hankel matrix of ``block_rows`` reads from lag ``first_lag`` on: ``2 i + k0 - 1``.

    Examples
    --------
    >>> hankel_max_lag(107), hankel_max_lag(107, first_lag=5)
    (214, 218)
    """
    return 2 * block_rows + first_lag - 1


def hankel(R: np.ndarray, block_rows: int, block_columns: int | None = None, first_lag: int = 1) -> np.ndarray:
    """Block Hankel matrix ``H[a, b] = R_{a+b+k0}`` (``k0 = first_lag``), ``block_rows + 1`` block rows,
    ``block_columns`` (default ``block_rows``) columns.

    With ``R_k = C A^(k-1) G`` the matrix factors as ``O Γ`` with the same observability matrix
    ``O = [C; C A; ...]`` for any ``k0 >= 1`` (``Γ`` starts at ``A^(k0-1) G``): starting later leaves the
    modes and their shapes as they are and leaves out the lags where dynamics of short memory live (see
    :func:`twin.extract.passes.first_lag_for`).

    Examples
    --------
    >>> R = np.arange(8.0)[:, None, None]  # R_k = k, one channel
    >>> hankel(R, 2)
    array([[1., 2.],
           [2., 3.],
           [3., 4.]])
    >>> hankel(R, 2, first_lag=3)
    array([[3., 4.],
           [4., 5.],
           [5., 6.]])
    """
    i = block_rows
    q = block_rows if block_columns is None else block_columns
    _, l, r = R.shape
    if first_lag < 1:
        raise ValueError(f"the Hankel matrix starts at lag 1 or later (lag 0 holds the sensor noise), got {first_lag}")
    if i + q - 1 + first_lag >= R.shape[0]:
        raise ValueError(
            f"{i} block rows and {q} columns from lag {first_lag} need covariances to lag "
            f"{i + q - 1 + first_lag}, got {R.shape[0] - 1}"
        )
    idx = np.arange(i + 1)[:, None] + np.arange(q)[None, :] + first_lag
    return R[idx].transpose(0, 2, 1, 3).reshape((i + 1) * l, q * r)


@dataclass(frozen=True)
class Realisation:
    """Observability factor of one covariance sequence, ready for any order up to ``max_order``."""

    C: np.ndarray  # (l, max_order) output matrix of the largest order
    R_up: np.ndarray  # (max_order, max_order) triangular factor of O_up
    S: np.ndarray  # (max_order, max_order) Q^T O_down
    singular_values: np.ndarray  # the leading ones (at least max_order of them), descending
    fs_hz: float
    basis: np.ndarray | None = None  # (m, max_order + START_OVERSAMPLING) leading left singular vectors

    @property
    def max_order(self) -> int:
        return self.C.shape[1]

    @property
    def n_channels(self) -> int:
        return self.C.shape[0]

    @property
    def orders(self) -> np.ndarray:
        """The model orders of the stabilisation diagram: 2, 4, ..., ``max_order``."""
        return np.arange(2, self.max_order + 1, 2)

    def modes(self, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Continuous-time poles [1/s] (``Im > 0`` only) and output shapes ``(l, k)`` of one order."""
        A = sla.solve_triangular(self.R_up[:order, :order], self.S[:order, :order], check_finite=False)
        mu, v = np.linalg.eig(A)
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = np.log(mu.astype(complex)) * self.fs_hz
        keep = np.isfinite(lam) & (lam.imag > 0) & (lam.imag < 0.99 * np.pi * self.fs_hz)
        return lam[keep], self.C[:, :order] @ v[:, keep]


def realise(
    R: np.ndarray,
    block_rows: int,
    max_order: int,
    fs_hz: float,
    block_columns: int | None = None,
    first_lag: int = 1,
    start: np.ndarray | None = None,
) -> Realisation:
    """Factorise the covariance Hankel matrix (SVD) and prepare the multi-order solution (QR).

    ``first_lag`` is the lag the Hankel matrix starts at (:func:`hankel`); ``R`` must reach lag
    ``2 block_rows + first_lag - 1`` (with the default square matrix). ``start`` is the ``basis`` of
    a realisation of nearly the same covariances (the full record's, for a jackknife sample): the
    leading singular vectors are iterated from it (:func:`leading_singular`).

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> e = rng.standard_normal(20000)
    >>> y = np.empty(20000); y[:2] = 0.0
    >>> for t in range(2, 20000):  # AR(2) with poles 0.95 exp(+-0.5j)
    ...     y[t] = 2 * 0.95 * np.cos(0.5) * y[t - 1] - 0.95**2 * y[t - 2] + e[t]
    >>> real = realise(block_covariances(y[:, None], 20).covariance(), 10, 2, fs_hz=1.0)
    >>> lam, _ = real.modes(2)
    >>> np.round(np.exp(lam), 2)
    array([0.84+0.46j])
    """
    l = R.shape[1]
    H = hankel(R, block_rows, block_columns, first_lag)
    max_order = min(max_order, min(H.shape) - l)
    width = min(max_order + START_OVERSAMPLING, min(H.shape))
    U, s = leading_singular(H, width, start=start)
    O = U[:, :max_order] * np.sqrt(s[:max_order])
    Q, R_up = np.linalg.qr(O[:-l])
    return Realisation(C=O[:l], R_up=R_up, S=Q.T @ O[l:], singular_values=s, fs_hz=fs_hz, basis=U[:, :width])


def leading_singular(H: np.ndarray, k: int, start: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` leading left singular vectors ``(m, k)`` and singular values (descending) of ``H``.

    Lanczos (ARPACK, ``tol=0``, a fixed start vector so the result is repeatable) when ``k`` is at most
    :data:`PARTIAL_SVD_FRACTION` of the smaller side, else (or should ARPACK not converge) the full SVD, all
    of whose singular values are returned.

    With ``start``, orthonormal columns that nearly span the leading left singular vectors (those of a
    matrix close to ``H``: a jackknife sample's Hankel matrix leaves out a sixteenth of the record),
    subspace iteration from them: ``Q <- orth(H H^T Q)``, the Ritz values of ``Q^T H`` after each step,
    until the leading ``k - START_OVERSAMPLING`` singular values move by less than :data:`START_RTOL`
    (relative). On 16 of the hydro unit's records each mode's jackknife spread came out as with Lanczos
    (a median relative difference of 1e-10, 99% within 0.5%) in about half the time.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((90, 6)) @ rng.standard_normal((6, 80)) + 0.01 * rng.standard_normal((90, 80))
    >>> U, s = leading_singular(H, 5)
    >>> U.shape, bool(np.allclose(s, np.linalg.svd(H, compute_uv=False)[:5]))
    ((90, 5), True)
    >>> start, _ = leading_singular(H + 0.01 * rng.standard_normal(H.shape), 16)
    >>> U2, s2 = leading_singular(H, 16, start=start)
    >>> bool(np.allclose(s2[:6], np.linalg.svd(H, compute_uv=False)[:6], rtol=1e-9))
    True
    """
    if start is not None and start.shape[0] == H.shape[0] and start.shape[1] >= k:
        return _iterate_subspace(H, start[:, :k], max(k - START_OVERSAMPLING, 1))
    if k <= PARTIAL_SVD_FRACTION * min(H.shape):
        v0 = np.ones(min(H.shape)) / np.sqrt(min(H.shape))
        try:
            U, s, _ = spla.svds(H, k=k, tol=0, v0=v0, solver="arpack")
        except spla.ArpackNoConvergence:
            pass  # the full SVD below
        else:
            order = np.argsort(s)[::-1]
            return U[:, order], s[order]
    U, s, _ = np.linalg.svd(H, full_matrices=False)
    return U, s


def _iterate_subspace(H: np.ndarray, Q: np.ndarray, watched: int) -> tuple[np.ndarray, np.ndarray]:
    """Subspace iteration of ``H H^T`` from the orthonormal ``Q``, with Rayleigh-Ritz after each step
    (:func:`leading_singular`'s ``start``): the Ritz values from the Gram matrix of ``Z = H^T Q``, which
    the next step multiplies by ``H``."""
    previous = None
    Z = H.T @ Q
    for _ in range(START_MAX_ITERATIONS):
        Q, _ = np.linalg.qr(H @ Z)
        Z = H.T @ Q
        s2, W = np.linalg.eigh(Z.T @ Z)
        s = np.sqrt(np.clip(s2[::-1], 0.0, None))
        if previous is not None and np.all(np.abs(s[:watched] - previous) <= START_RTOL * s[:watched]):
            break
        previous = s[:watched]
    return Q @ W[:, ::-1], s
