"""J samples per mode by a delete-d block jackknife (delete-one by default, or delete-half), and shape normalisation.

The record is cut into J contiguous blocks. For each sample ``m`` the
identification is repeated on the covariances of the record without ``d``
blocks drawn at random (the same block rows and, per mode, the same model
orders as the full record; a mode is the average over its orders), giving
``theta_m``. With ``d = J / 2`` (half the record deleted), the samples

    theta_m* = theta - c (theta_m - mean(theta_m)),   c = sqrt((J - 1)(J - d) / d)

have a standard deviation that, divided by ``sqrt(J)``, is the delete-d
jackknife standard error of the full-record estimate (Shao and Wu 1989;
``d = 1`` is the classic delete-one jackknife, ``c = J - 1``). That is the
spread the APerCEM likelihood expects from J samples treated as independent.

Delete-one gives exactly one sample per block. With ``d > 1`` there are many
more subsets than blocks, and ``M`` of them drawn at random (``M`` samples
from ``J`` blocks, ``c = sqrt((M - 1)(J - d) / d)``, the samples' std over
``sqrt(M)`` the standard error) estimate the same standard error with less
scatter of their own. The blocks must stay longer than a few time constants
of the slowest mode (15 blocks for the hydro unit's 20-min records), while
the update estimates a shape covariance over 16 real entries from the
samples, which 15 samples leave singular (``extract(samples=45, blocks=15)``).

Why not delete one block: a pole of SSI at a model order above the number of
modes changes steeply with small changes of the covariances (the noise part
of the subspace re-arranges), but the change saturates over the differences
between independent records. Probing it with small steps overstates the
spread over independent records: the infinitesimal jackknife (the
linearisation) by 3.6 on a one-mode record at order 16, the delete-one
jackknife (steps of ``1 / (J - 1)`` of a block's deviation) by 2.1 there and,
with ``benchmarks/extraction.py --seeds 12`` (hydro unit, 1 h records, J = 100),
by 0.96-4.8 for the frequencies and 1.24-4.6 for the damping ratios of ten
modes. Deleting half the record steps as far as independent records differ:
1.3 on the one-mode record, and on the hydro unit 0.93-1.25 for the
frequencies except the slowest mode's 1.52, and 0.78-1.46 for the damping
ratios except one at 2.43 (on the safe side; ``docs/decisions/extraction-jackknife.md``). The
subsets come from a fixed seed, so an extraction is repeatable.

:func:`order_deviations` adds the spread of each mode over the model orders
it is averaged over (``extract(..., order_spread="all")``): with it, the
samples' standard error covers the RMS error against the truth, SSI's bias
included, of every mode on those records (0.96-2.46 times it). By default
(``order_spread="shapes"``) it is added to the shape samples only, as the
standard error of the mode's mean shape over its orders: SSI's shapes sit
off the truth's by more than their jackknife error, while the poles'
jackknife error is what the loop's comparison is calibrated to.

Delete-one stays the default of :func:`twin.extract.extract`: the loop's
comparison and update were calibrated against its wider spread. With
delete-half samples and the order spread, the held-out suite
(``benchmarks/loop_suite.py``) passes 57 of its 69 scenarios against 61 with
delete-one: the true model's chi2 / n is 1.01 (calibrated), but the update's
intervals miss more per-mode FSI parameters. On the FMU coverage benchmark
(``benchmarks/update_coverage_fmu.py --delete-half``) delete-half samples leave the
magnetic pull, the seal and the FSI damping below 85%: the delete-one
overstatement covers SSI's bias of the poles that carry them.

The samples are centred on the full-record estimate: the deviations of the
``theta_m`` from their own mean are scaled and added to it. Poles and complex
shapes are resampled alike; every shape is brought to the phase of the
full-record shape before, and normalised the same way after (unit norm, the
mode's reference channel real and positive).
"""

from __future__ import annotations

import logging

import numpy as np
from twin.progress import bar

from twin.extract.algorithms import SSI, Algorithm, Fit
from twin.extract.ssi import BlockCovariances
from twin.extract.stabilisation import pole_distance

log = logging.getLogger(__name__)

#: A reduced-record pole farther than this (clustering distance) from the full-record one is not its counterpart.
MATCH_DISTANCE = 0.1


def align_phase(shapes: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Rotate each shape (last axis) by the complex factor that makes ``reference^H shape`` real positive.

    Examples
    --------
    >>> ref = np.array([1.0, 1j])
    >>> np.round(align_phase(np.array([[1j, -1.0]]), ref), 12)
    array([[1.+0.j, 0.+1.j]])
    """
    c = np.sum(np.conj(reference) * shapes, axis=-1, keepdims=True)
    return shapes * np.where(np.abs(c) > 0, np.conj(c) / np.where(np.abs(c) > 0, np.abs(c), 1.0), 1.0)


def normalise_at(shapes: np.ndarray, channel: np.ndarray | int) -> np.ndarray:
    """Unit norm with the given channel real and positive (one fixed channel per mode, for every sample).

    ``shapes`` has the channel on the last axis; ``channel`` broadcasts against the other axes.

    Examples
    --------
    >>> np.round(normalise_at(np.array([2j, 1j]), 1), 6)
    array([0.894427+0.j, 0.447214+0.j])
    """
    shapes = np.asarray(shapes, dtype=complex)
    idx = np.broadcast_to(np.asarray(channel), shapes.shape[:-1])[..., None]
    pivot = np.take_along_axis(shapes, idx, axis=-1)
    norm = np.linalg.norm(shapes, axis=-1, keepdims=True)
    return shapes / (norm * pivot / np.abs(pivot))


def aligned_unit(shapes: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Shapes (last axis) scaled to unit norm and brought to the phase of ``reference`` (:func:`align_phase`)."""
    return align_phase(shapes / np.linalg.norm(shapes, axis=-1, keepdims=True), reference)


def order_average(poles: np.ndarray, shapes: np.ndarray, reference: np.ndarray) -> tuple[complex, np.ndarray]:
    """One mode estimate from its poles at several orders: mean pole, mean phase-aligned unit shape."""
    mean = aligned_unit(shapes, reference).mean(axis=0)
    return complex(poles.mean()), mean / np.linalg.norm(mean)


def blocks_deleted(n_blocks: int, delete: int | None) -> int:
    """How many blocks each sample leaves out: ``delete``, or half of them for None (checked).

    Examples
    --------
    >>> blocks_deleted(100, None), blocks_deleted(100, 1)
    (50, 1)
    """
    d = n_blocks // 2 if delete is None else int(delete)
    if not 1 <= d < n_blocks:
        raise ValueError(
            f"a jackknife sample must leave out between 1 and {n_blocks - 1} of the {n_blocks} blocks, got {d}"
        )
    return d


def deleted_blocks(n_blocks: int, delete: int | None, seed: int = 0, n_samples: int | None = None) -> list[np.ndarray]:
    """The blocks each sample leaves out: block ``m`` alone for ``delete = 1`` (one sample per block), else
    ``n_samples`` (default ``n_blocks``) random subsets of :func:`blocks_deleted` blocks (fixed ``seed``).

    Examples
    --------
    >>> [b.tolist() for b in deleted_blocks(3, 1)]
    [[0], [1], [2]]
    >>> [len(b) for b in deleted_blocks(4, None)]
    [2, 2, 2, 2]
    >>> len(deleted_blocks(4, None, n_samples=12))
    12
    """
    d = blocks_deleted(n_blocks, delete)
    n_samples = n_blocks if n_samples is None else int(n_samples)
    if d == 1:
        if n_samples != n_blocks:
            raise ValueError(
                f"the delete-one jackknife gives one sample per block: {n_samples} samples need "
                f"{n_samples} blocks, not {n_blocks} (or delete more than one block)"
            )
        return [np.array([m]) for m in range(n_blocks)]
    if n_samples < 2:
        raise ValueError(f"the spread needs at least 2 samples, got {n_samples}")
    rng = np.random.default_rng(seed)
    return [np.sort(rng.permutation(n_blocks)[:d]) for _ in range(n_samples)]


def repeated(samples: np.ndarray, times: int) -> np.ndarray:
    """Samples (axis 1) each used ``times`` times in a row, their deviations scaled to keep the standard error.

    ``J`` samples whose std over ``sqrt(J)`` is a standard error become ``M = times J`` samples with the
    same mean and the same std over ``sqrt(M)``: deviation ``d`` becomes ``c d`` with
    ``c = sqrt((M - 1) M / (times (J - 1) J))``. It lets pole samples of a delete-one jackknife stand beside
    ``M`` shape samples of another (``extract(shape_samples=M)``).

    Examples
    --------
    >>> x = np.array([[1.0, 2.0, 6.0]])
    >>> y = repeated(x, 4)
    >>> y.shape, float(y.mean())
    ((1, 12), 3.0)
    >>> bool(np.isclose(y.std(ddof=1) / np.sqrt(12), x.std(ddof=1) / np.sqrt(3)))
    True
    """
    samples = np.asarray(samples)
    J, M = samples.shape[1], samples.shape[1] * int(times)
    if times < 1 or J < 2:
        raise ValueError(f"need at least 2 samples used at least once each, got {J} used {times} times")
    mean = samples.mean(axis=1, keepdims=True)
    c = np.sqrt((M - 1) * M / (times * (J - 1) * J))
    return mean + c * np.repeat(samples - mean, times, axis=1)


def order_deviations(
    members: list[tuple[np.ndarray, np.ndarray, np.ndarray]], shapes: np.ndarray, n_samples: int, seed: int = 1
) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample deviations that carry the spread of each mode over its model orders.

    SSI's estimate of a mode depends on the model order; the mode is the
    average over its orders, and the spread of its full-record poles over
    those orders is a measure of what the choice of order leaves uncertain.
    Sample ``m`` of mode ``k`` gets the deviation of one of its orders from
    their mean (every order used equally often, in a fixed random sequence),
    scaled so that the pole deviations' std divided by ``sqrt(J)`` (the
    standard error the samples stand for) is the std of the mode's pole
    over its ``n`` orders, and the shape deviations' is the standard error
    of the mode's mean shape over them, their std over ``sqrt(n)``. The
    update reads the bearings and most of a magnetic pull from the shapes;
    with each order's full spread the 90% intervals covered the truth for
    98-100% of the bearing values on every set of FMU records
    (``benchmarks/update_coverage_fmu.py --order-spread all``). The poles keep their full spread:
    the update's ``pole_order_cov`` and the loop's comparison were
    calibrated with it.

    Parameters
    ----------
    members : list of (orders, poles, shapes)
        As for :func:`jackknife`.
    shapes : ndarray, shape (n_modes, channels)
        Full-record shapes, the phase reference of each mode.
    n_samples : int
        J, samples per mode.
    seed : int
        Seed of the sequence of orders.

    Returns
    -------
    (pole_deviations, shape_deviations)
        ``(n_modes, J)`` and ``(n_modes, J, channels)``, zero mean over the
        samples (zero for a mode seen at one order only).

    Examples
    --------
    Two orders: the pole's standard error is its spread over them, the shape's the spread of their mean:

    >>> shapes = np.array([[1.0, 0.0], [0.8, 0.6]])
    >>> members = [(np.array([4, 6]), np.array([-1 + 10j, -1 + 10.2j]), shapes)]
    >>> dp, ds = order_deviations(members, shapes[:1], n_samples=16)
    >>> round(float(dp.imag.std(ddof=1) / 4), 4), round(float(np.std([10, 10.2], ddof=1)), 4)
    (0.1414, 0.1414)
    >>> ds[0].real.std(axis=0, ddof=1) / 4, np.std(shapes, axis=0, ddof=1) / np.sqrt(2)
    (array([0.1, 0.3]), array([0.1, 0.3]))
    """
    rng = np.random.default_rng(seed)
    J = n_samples
    dp = np.zeros((len(members), J), dtype=complex)
    ds = np.zeros((len(members), J, shapes.shape[1]), dtype=complex)
    for k, (_, p, s) in enumerate(members):
        n = len(p)
        if n < 2:
            continue
        which = rng.permutation(np.resize(np.arange(n), J))
        p_m, s_m = p[which], aligned_unit(s, shapes[k])[which]
        d_p, d_s = p_m - p_m.mean(), s_m - s_m.mean(axis=0)
        spread = np.sqrt(np.sum(np.abs(p - p.mean()) ** 2) / (n - 1))  # std of the pole over the orders
        have = np.sqrt(np.sum(np.abs(d_p) ** 2) / (J - 1))
        scale = np.sqrt(J) * spread / have if have > 0 else 0.0
        dp[k], ds[k] = scale * d_p, scale * d_s / np.sqrt(n)  # the shapes: the standard error of their mean
    return dp, ds


def jackknife(
    blocks: BlockCovariances,
    block_rows: int,
    fs_hz: float,
    members: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
    progress: bool = True,
    delete: int | None = 1,
    n_samples: int | None = None,
    first_lag: int = 1,
    algorithm: Algorithm = SSI,
    near: Fit | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Full-record estimates and delete-d jackknife samples of the given modes.

    Each mode is estimated as the average of its poles (and phase-aligned
    shapes) over a fixed set of model orders: smoother in the data than one
    order, which the jackknife needs.

    Parameters
    ----------
    blocks : BlockCovariances
        Lagged products of the record in J blocks.
    block_rows : int
    fs_hz : float
        Sampling rate of the record the covariances come from.
    members : list of (orders, poles, shapes)
        Per mode, the full-record poles [1/s] and unit shapes ``(k, channels)``
        at the model orders the mode is averaged over.
    delete : int, optional
        Blocks each sample leaves out (None: ``J // 2``, delete-half; 1 is the delete-one jackknife).
    n_samples : int, optional
        M, samples per mode (default J, the number of blocks; only delete-d with ``d > 1`` may ask for
        another number, see :func:`deleted_blocks`).
    first_lag : int
        The lag the Hankel matrix starts at, as for the full record (:func:`twin.extract.ssi.hankel`).
    algorithm : Algorithm
        The identification algorithm and band, as for the full record (:mod:`twin.extract.algorithms`).
    near : Fit, optional
        The full record's fit (the first pass's), which each sample's fit starts from
        (:meth:`~twin.extract.algorithms.Algorithm.fit`); made here when not given.

    Returns
    -------
    (poles, shapes, sample_poles, sample_shapes, missing)
        Full-record ``(n_modes,)`` poles and ``(n_modes, channels)`` shapes;
        ``(n_modes, M)`` pole samples, ``(n_modes, M, channels)`` shape samples
        (centred on the full-record estimate; phase-aligned, not yet
        normalised); ``(n_modes, M)`` how many of the mode's orders had no pole
        within ``MATCH_DISTANCE`` in the reduced record (those orders keep
        their full-record value in that sample).
    """
    n_modes, n_ch, J = len(members), members[0][2].shape[1], blocks.n_blocks
    left_out = deleted_blocks(J, delete, n_samples=n_samples)
    d, M = len(left_out[0]), len(left_out)
    full = [order_average(p, s, s[0]) for _, p, s in members]
    poles = np.array([f[0] for f in full])
    shapes = np.array([f[1] for f in full])
    sub_p = np.empty((n_modes, M), dtype=complex)
    sub_s = np.empty((n_modes, M, n_ch), dtype=complex)
    missing = np.zeros((n_modes, M), dtype=int)
    all_orders = np.unique(np.concatenate([m[0] for m in members]))
    max_order = int(all_orders.max())
    # each sample's fit starts from the full record's (SSI's singular vectors: in half the time)
    if near is None and algorithm.starts_near:
        near = algorithm.fit(blocks.covariance(), block_rows, max_order, fs_hz, first_lag=first_lag)
    for j in bar(range(M), desc="jackknife", unit="sample", progress=progress, mininterval=0.5):
        real = algorithm.fit(
            blocks.covariance(leave_out=left_out[j]), block_rows, max_order, fs_hz, first_lag=first_lag, near=near
        )
        at = {}
        for n in all_orders:
            lam, phi = real.modes(int(n))
            at[int(n)] = (lam, phi.T / np.linalg.norm(phi.T, axis=1, keepdims=True))
        for k, (orders, p_ref, s_ref) in enumerate(members):
            p_k, s_k = [], []
            for n, p0, s0 in zip(orders, p_ref, s_ref):
                lam, phi = at[int(n)]
                dist = pole_distance(np.array([p0]), s0[None, :], lam, phi)[0] if len(lam) else np.array([np.inf])
                best = int(np.argmin(dist))
                if dist[best] > MATCH_DISTANCE:  # no clear counterpart: this order keeps its full-record value
                    p_k.append(p0), s_k.append(s0)
                    missing[k, j] += 1
                else:
                    p_k.append(lam[best]), s_k.append(phi[best])
            sub_p[k, j], sub_s[k, j] = order_average(np.array(p_k), np.array(s_k), shapes[k])
    c = np.sqrt((M - 1) * (J - d) / d)
    sample_p = poles[:, None] - c * (sub_p - sub_p.mean(axis=1, keepdims=True))
    sample_s = shapes[:, None, :] - c * (sub_s - sub_s.mean(axis=1, keepdims=True))
    return poles, shapes, sample_p, sample_s, missing
