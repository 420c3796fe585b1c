"""One SSI pass over a record, and two second ones (options): longer lags to read mode shapes at, and the
record differenced twice to read the faster modes from.

:func:`ssi_pass` runs covariance-driven SSI with a given number of block
rows, clusters the stabilisation diagram and sorts the clusters into modes
and harmonics. :func:`twin.extract.extract` runs it once, with lags of a
quarter period of ``max(fmin, fmax / 100)``, for every mode's pole and
shape. With ``shape_block_rows`` it runs it again and reads shapes there: a
number of block rows for every mode, or ``"auto"`` for the modes whose
:data:`SHAPE_LAG_PERIODS` periods the first lags do not span, at lags over
that many periods of the slowest of them (:func:`shape_lag_rows`).
:func:`matching_modes` pairs the two passes' modes and
:func:`shapes_at_longer_lags` reads the shapes. The jackknife of both passes
leaves out the same blocks, so pole sample ``m`` and shape sample ``m``
still come from the same reduced record. With ``differenced_above_hz`` it
runs one over the record differenced twice (:func:`differenced`) and takes
every mode above that frequency from it, pole, shape and samples
(:func:`modes_from_differenced`).

Why it is there and not the default: the first pass's lags can be short against the slowest modes'
periods, and the shapes read there may carry a bias; but on the hydro unit's FMU records neither second
pass beat the one pass over every parameter (the figures are in ``docs/decisions/extraction-lags.md`` and
``docs/decisions/extraction-differenced.md``).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence

import numpy as np

from twin.extract.harmonics import HARMONIC_MAX_DAMPING, harmonic_test
from twin.extract.samples import MATCH_DISTANCE, jackknife, order_deviations
from twin.extract.algorithms import SSI, Algorithm, Fit
from twin.extract.ssi import BlockCovariances, block_covariances, hankel_max_lag
from twin.extract.stabilisation import Cluster, Criteria, Diagram, cluster_poles, diagram, pole_distance
from twin.modes.analysis import damping_ratio
from twin.modes.pairing import assign

log = logging.getLogger(__name__)

#: Times the record is differenced for the pass the upper modes are read from
#: (``extract(differenced_above_hz=...)``, :func:`differenced`).
DIFFERENCES = 2
#: By default the shapes are read at lags (block rows over the sampling rate) spanning this many periods
#: of the slowest mode the first pass finds (docs/decisions/extraction-lags.md).
SHAPE_LAG_PERIODS = 1.5


def shape_lag_rows(slowest_hz: float, fs_hz: float, minimum: int = 1, maximum: int | None = None) -> int:
    """Block rows ``i`` whose lags ``i / fs`` span :data:`SHAPE_LAG_PERIODS` periods of the slowest mode.

    Kept within ``[minimum, maximum]`` (the block length bounds it: each jackknife block must hold
    ``MIN_BLOCK_LAGS`` times the ``2 i`` lags); a bound that cuts the rule short is logged.

    Examples
    --------
    >>> shape_lag_rows(1.1, 256.0), shape_lag_rows(1.1, 256.0, minimum=400), shape_lag_rows(1.1, 256.0, maximum=200)
    (350, 400, 200)
    """
    i = int(np.ceil(SHAPE_LAG_PERIODS * fs_hz / slowest_hz))
    if maximum is not None and i > maximum:
        log.info(
            "shape block rows held to %d by the block length (%.3f Hz over %g periods asks for %d)",
            maximum,
            slowest_hz,
            SHAPE_LAG_PERIODS,
            i,
        )
        i = maximum
    return max(i, int(minimum))


def first_lag_for(fs_hz: float, fmax_hz: float) -> int:
    """The lag the covariance Hankel matrix starts at by default: the first at or beyond one period of ``fmax``.

    A record holds dynamics above the band of interest: the structure's stiffer modes, aliased or not,
    with damping that grows with frequency, and on a real record the sensors' and the anti-aliasing
    filter's. Their covariances die out within a few samples, but at the first lags they are part of
    every ``R_k``, and SSI at the diagram's model orders, which has no room for them, bends the band's
    modes to fit them. Starting the Hankel matrix at one period of the highest frequency of interest
    leaves the band's modes as they are (:func:`twin.extract.ssi.hankel`) and those lags out.

    On the hydro unit's 20-min FMU records at 256 Hz (fmax 60 Hz, lags from 5) this took away a bias
    of the shapes that no jackknife shows: the lower guide bearing's direct damping had come out about
    one posterior std low on average (mean z of LGB.cxx and LGB.cyy -0.9 to -1.1 on forty unseen
    records, median error 0.7-1.1%), now +0.1 to +0.5 (0.3-0.4%) (docs/decisions/extraction-lags.md).

    Examples
    --------
    >>> first_lag_for(256.0, 60.0), first_lag_for(150.0, 60.0), first_lag_for(100.0, 50.0)
    (5, 3, 2)
    """
    return max(1, int(np.ceil(fs_hz / fmax_hz - 1e-9)))


@dataclasses.dataclass(frozen=True)
class SSIPass:
    """One SSI pass: its block rows, the covariances, the realisation, the clustered diagram and its modes."""

    block_rows: int
    covariances: BlockCovariances
    real: Fit
    first_lag: int
    diag: Diagram
    modes: list[Cluster]
    harmonics: list[dict]
    algorithm: Algorithm = SSI


def ssi_pass(
    y: np.ndarray,
    fs: float,
    i: int,
    n_blocks: int,
    max_order: int,
    fmin_hz: float,
    fmax: float,
    crit: Criteria,
    running_hz: float | None,
    channels: Sequence[str],
    spectrum: dict,
    quiet: bool = False,
    first_lag: int = 1,
    algorithm: str = "ssi",
) -> SSIPass:
    """SSI-cov (or another ``algorithm``, :mod:`twin.extract.algorithms`) with ``i`` block rows from lag ``first_lag``
    on, the stabilisation diagram clustered and its clusters sorted into modes and harmonics.

    The record's FFT is computed once, into ``spectrum``, when a cluster must be tested as a harmonic;
    ``quiet`` logs the sorting at debug level only (a second pass, whose harmonics the first reported).

    Examples
    --------
    One 2 Hz mode (2% damping) on four channels, 1000 s at 20 Hz, 20 block rows in 10 blocks, orders to 12:

    >>> import scipy.signal as sig
    >>> rng = np.random.default_rng(0)
    >>> lam = 2 * np.pi * 2.0 * (-0.02 + 1j)
    >>> q = sig.lfilter([1.0], [1.0, -np.exp(lam / 20.0)], rng.standard_normal(20_000) + 1j * rng.standard_normal(20_000))
    >>> y = 2 * np.real(q[:, None] * np.array([1.0, 0.6j, 0.8, 0.5j])) + 0.1 * rng.standard_normal((20_000, 4))
    >>> found = ssi_pass(y, 20.0, 20, 10, 12, 0.0, 8.0, Criteria(), None, ["a", "b", "c", "d"], {})
    >>> found.block_rows, len(found.modes), round(float(found.diag.frequency_hz[found.modes[0].representative]), 2)
    (20, 1, 2.0)
    """
    say = log.debug if quiet else log.info
    covariances = block_covariances(y, hankel_max_lag(i, first_lag), n_blocks)
    how = Algorithm(algorithm, (fmin_hz, fmax))
    real = how.fit(covariances.covariance(), i, max_order, fs, first_lag=first_lag)
    orders = real.orders
    diag = diagram(real, orders, fmin_hz, fmax, crit)
    diag, clusters = cluster_poles(diag, len(orders), crit)

    rep_zeta = [float(damping_ratio(diag.pole[c.representative])) for c in clusters]
    # the FFT of the record only when some cluster is damped little enough to be tested as a harmonic
    if "fft" not in spectrum and min(rep_zeta, default=1.0) < HARMONIC_MAX_DAMPING:
        spectrum["fft"] = np.fft.rfft(y, axis=0)
    harmonics, modes = [], []
    labels = np.full(len(diag.pole), -1)  # -1 no mode, -2 harmonic, else the mode index
    for c, zeta in zip(clusters, rep_zeta):
        h = harmonic_test(spectrum.get("fft"), y.shape[0], fs, diag.pole[c.representative], running_hz)
        if h is None and zeta > 0:
            labels[c.members] = len(modes)
            modes.append(c)
        elif h is None:  # not damped and not a sinusoid: not physical
            say(
                "%.4f Hz: stable pole without damping that is no harmonic; dropped",
                diag.pole[c.representative].imag / (2 * np.pi),
            )
        else:
            h["channel"] = channels[h.pop("channel_index")]
            harmonics.append(h)
            say("%.4f Hz is a harmonic (band kurtosis %.2f), not a mode", h["frequency_hz"], h["kurtosis"])
            labels[c.members] = -2
    return SSIPass(i, covariances, real, first_lag, dataclasses.replace(diag, cluster=labels), modes, harmonics, how)


def matching_modes(
    poles: np.ndarray, shapes: np.ndarray, other_poles: np.ndarray, other_shapes: np.ndarray
) -> np.ndarray:
    """For each mode, the index of the same mode among ``other_*`` (-1 for none), one to one.

    Two modes are the same when their clustering distance (relative pole distance plus ``1 - MAC``) is
    below ``MATCH_DISTANCE``; each mode is used at most once, by the assignment of least total distance
    (:func:`twin.modes.pairing.assign`).

    Examples
    --------
    >>> p = np.array([-0.1 + 7j, -0.1 + 7.5j])
    >>> s = np.array([[1.0, 0.0], [0.0, 1.0]], dtype=complex)
    >>> matching_modes(p, s, p[::-1] * 1.01, s[::-1]).tolist()
    [1, 0]
    >>> matching_modes(p, s, p[:1] * 1.5, s[:1]).tolist()
    [-1, -1]
    """
    if not len(poles) or not len(other_poles):
        return np.full(len(poles), -1)
    dist = pole_distance(np.asarray(poles), np.asarray(shapes), np.asarray(other_poles), np.asarray(other_shapes))
    return assign(dist, dist < MATCH_DISTANCE)


def shapes_at_longer_lags(
    again: SSIPass,
    fs: float,
    members: list,
    poles: np.ndarray,
    shapes: np.ndarray,
    sample_shapes: np.ndarray,
    shape_deviations: np.ndarray,
    progress: bool = True,
    delete: int | None = 1,
    n_samples: int | None = None,
) -> tuple[np.ndarray, ...]:
    """The shapes, their jackknife samples and model-order deviations of each mode read from a second pass.

    Parameters
    ----------
    again : SSIPass
        The pass with the longer lags (the same record and blocks as the first).
    fs : float
        Sampling rate [Hz] of the record the passes ran on.
    members : list of (orders, poles, shapes)
        The second pass's modes at the orders each is averaged over (as for
        :func:`twin.extract.samples.jackknife`).
    poles, shapes : (modes,), (modes, channels)
        The first pass's full-record estimates, which find each mode's counterpart (:func:`matching_modes`).
    sample_shapes, shape_deviations : (modes, J, channels)
        The first pass's shape samples and order deviations (:func:`twin.extract.samples.order_deviations`),
        kept for a mode without a counterpart.
    delete, n_samples
        As for :func:`twin.extract.samples.jackknife`, and the same as the first pass's: sample ``m`` of both
        leaves out the same blocks.

    Returns
    -------
    (shapes, sample_shapes, shape_deviations, matched)
        The inputs with every matched mode's replaced, and ``(modes,)`` whether it was.
    """
    shapes, sample_shapes, shape_deviations = (np.array(x) for x in (shapes, sample_shapes, shape_deviations))
    matched = np.zeros(len(poles), dtype=bool)
    if not members:
        return shapes, sample_shapes, shape_deviations, matched
    l_poles, l_shapes, _, l_samples, _ = jackknife(
        again.covariances,
        again.block_rows,
        fs,
        members,
        progress,
        delete=delete,
        n_samples=n_samples,
        first_lag=again.first_lag,
        algorithm=again.algorithm,
    )
    _, l_dev = order_deviations(members, l_shapes, l_samples.shape[1])
    match = matching_modes(poles, shapes, l_poles, l_shapes)
    matched = match >= 0
    j = match[matched]
    shapes[matched], sample_shapes[matched], shape_deviations[matched] = l_shapes[j], l_samples[j], l_dev[j]
    return shapes, sample_shapes, shape_deviations, matched


def differenced(y: np.ndarray, times: int = DIFFERENCES) -> np.ndarray:
    """The record ``(time, channel)`` differenced ``times`` times along time: the same modes, reweighted.

    ``d(t) = y(t) - y(t - 1)`` is a filter of length two applied to every
    channel alike, so beyond ``times`` lags the covariances of the differenced
    record are the record's modes with the same poles and shapes, each
    scaled by one number (that of its pole). Its spectrum is the record's
    times ``(2 sin(pi f / fs))^(2 times)``: a mode at a tenth of another's
    frequency loses 40 dB against it after two differences. A record of
    displacements, whose spectrum falls steeply with frequency, then no
    longer has its slowest and strongest modes fill the covariances that the
    faster modes are read from (see :func:`modes_from_differenced`).

    Examples
    --------
    >>> differenced(np.array([[0.0], [1.0], [4.0], [9.0]])).ravel()  # t**2: second difference 2
    array([2., 2.])
    """
    return np.diff(np.asarray(y, dtype=float), n=int(times), axis=0)


def modes_from_differenced(
    again: SSIPass,
    again_members: list,
    fs: float,
    above_hz: float,
    first: tuple,
    progress: bool = True,
    delete: int | None = 1,
    n_samples: int | None = None,
) -> tuple:
    """Replace each first-pass mode above ``above_hz`` by its counterpart in a pass over the differenced record.

    Why: on a record of displacements the slowest modes are the strongest
    and their covariances, estimated from few of their long periods, err
    slowly over the lags. SSI of the faster modes from the same covariances
    takes part of that error up, and not as scatter that the jackknife shows:
    on simulated 20-min records of the hydro unit with a hidden seal
    cross-coupling (numpy noise through its exact modes, 19 records), the
    11.6 Hz mode's mean shape erred along the seal's direction by -1.03 of
    its samples' standard errors on average (RMS 1.53), and without the
    modes below 5 Hz in the record by +0.29 (RMS 0.78). Read from the record
    differenced twice (:func:`differenced`), the same mode erred +0.24 (RMS
    1.11) with 1.3 times the information, and the 41-53 Hz modes' shapes held
    2.5-8 times more (``docs/decisions/extraction-differenced.md``).
    The differenced record loses the slow modes themselves, so they stay
    with the first pass. Pooled over 126 simulated records (numpy's random
    streams and the FMU's) the differenced 11.6 Hz mode holds
    1.4-2.1 times the shape information without the slow modes' bias, but
    errs beyond that information (RMS z 1.52 along the seal; 2.15 on the
    FMU's records 2201-2220), so this is not the default.

    Parameters
    ----------
    again : SSIPass
        The pass over the differenced record (the same blocks as the first, two samples shorter).
    again_members : list of (orders, poles, shapes)
        Its modes at the orders each is averaged over (as for :func:`twin.extract.samples.jackknife`).
    fs : float
        Sampling rate [Hz] of the passes.
    above_hz : float
        Modes of the first pass with a natural frequency above this [Hz] are looked for in ``again``.
    first : tuple
        The first pass's ``(members, poles, shapes, sample_poles, sample_shapes, missing, pole_deviations,
        shape_deviations)``: as :func:`twin.extract.samples.jackknife` and
        :func:`twin.extract.samples.order_deviations` give them.
    progress, delete, n_samples
        As for :func:`twin.extract.samples.jackknife`, and the same as the first pass's.

    Returns
    -------
    tuple
        ``first`` with every matched mode's entries replaced, and ``(modes,)`` the index of each mode's
        counterpart among ``again.modes`` (-1: none, the first pass's estimate kept).
    """
    members = list(first[0])
    arrays = [np.array(x) for x in first[1:]]
    poles, shapes = arrays[0], arrays[1]
    counterpart = np.full(len(poles), -1)
    upper = np.flatnonzero(np.abs(poles) / (2 * np.pi) > above_hz)
    d_members = list(again_members)
    if not len(upper) or not d_members:
        _log_unmatched(poles[upper])
        return (members, *arrays), counterpart
    d_poles, d_shapes, d_sp, d_ss, d_missing = jackknife(
        again.covariances,
        again.block_rows,
        fs,
        d_members,
        progress,
        delete=delete,
        n_samples=n_samples,
        first_lag=again.first_lag,
        algorithm=again.algorithm,
    )
    d_dp, d_ds = order_deviations(d_members, d_shapes, d_sp.shape[1])
    match = matching_modes(poles[upper], shapes[upper], d_poles, d_shapes)
    for k, j in zip(upper[match >= 0], match[match >= 0]):
        members[k] = d_members[j]
        for target, source in zip(arrays, (d_poles, d_shapes, d_sp, d_ss, d_missing, d_dp, d_ds)):
            target[k] = source[j]
        counterpart[k] = j
    _log_unmatched(poles[upper[match < 0]])
    return (members, *arrays), counterpart


def _log_unmatched(poles: np.ndarray) -> None:
    for f in np.abs(poles) / (2 * np.pi):
        log.info("%.4f Hz: no counterpart in the differenced record, read from the record itself", f)
