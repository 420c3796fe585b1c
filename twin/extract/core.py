"""Automated operational modal analysis: ``signals.nc`` in, ``modes.nc`` out.

One function, :func:`extract`: check the record, decimate to the band asked
for, covariance-driven SSI over many orders, stabilisation diagram, automatic
clustering, running-speed harmonics removed (a known speed) or rejected, J jackknife samples per
mode. It never reads the model; pair the result with model modes by MAC with
:func:`twin.pair_modes`.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import scipy.signal as sig
import xarray as xr

from twin import __version__
from twin.defaults import ORDERS_PER_MODE, SAMPLES  # noqa: F401 (defaults of the extraction, shared with the CLI)
from twin.errors import NoModeError, SignalError, TwinWarning
from twin.extract.blocks import (MIN_BLOCK_LAGS, MIN_BLOCK_TIME_CONSTANTS, adapted_blocks, block_count,
                                 check_block_length, most_blocks, warn_about_few_blocks)
from twin.extract.quantities import displacement_shapes
from twin.extract.harmonics import remove_running_harmonics
from twin.modes.modesfile import write_modes
from twin.extract.samples import jackknife, normalise_at, order_deviations, repeated
from twin.extract.signals import Record, check_record
from twin.extract.passes import (DIFFERENCES, differenced, first_lag_for, modes_from_differenced,
                                 shape_lag_rows, shapes_at_longer_lags, ssi_pass)
from twin.extract.options import ExtractOptions, as_float, jackknife_plan
from twin.extract.orders import OUTLIER_MADS, mode_members
from twin.extract.result import MAX_POLE_SE, extracted_modes, left_out, pole_scatter
from twin.extract.ssi import hankel_max_lag
from twin.netcdf import check_writable, load_netcdf
from twin.tasks import one_blas_thread

log = logging.getLogger(__name__)

#: Default upper frequency: this fraction of the sampling rate (80% of Nyquist).
DEFAULT_FMAX_FRACTION = 0.4
#: Fewest channels for shapes that tell modes apart (two x-y proximeter pairs).
MIN_CHANNELS = 4
#: Below this sampling rate [Hz] an extraction without ``fmax_hz`` warns that its band is narrow.
LOW_RATE_HZ = 50.0
#: Decimate when the sampling rate exceeds this many times ``fmax``.
SAMPLES_PER_PERIOD = 2.5
#: Default lowest frequency for the Hankel size, as a fraction of ``fmax``.
DEFAULT_FMIN_FRACTION = 0.01
#: The record must hold this many periods of the lowest frequency asked for.
MIN_CYCLES = 100
#: Warn when more than this fraction of a mode's jackknife matches fail.
MAX_MISSING = 0.05


def _open(signals: xr.Dataset | str | Path) -> tuple[xr.Dataset, str]:
    if isinstance(signals, xr.Dataset):
        return signals, str(signals.attrs.get("title", "signals"))
    return load_netcdf(signals, "signals", SignalError), str(signals)


def _decimate(rec: Record, fmax_hz: float) -> tuple[np.ndarray, float, int]:
    q = int(rec.fs_hz // (SAMPLES_PER_PERIOD * fmax_hz))
    if q < 2:
        return rec.y, rec.fs_hz, 1
    y = rec.y
    left = q
    while left > 1:  # FIR stages of at most 8 where q factors so; a prime factor above 8 is one stage
        step = next((s for s in range(min(8, left), 1, -1) if left % s == 0), left)
        y = sig.decimate(y, step, ftype="fir", zero_phase=True, axis=0)
        left //= step
    return y, rec.fs_hz / q, q


@one_blas_thread  # many small SVDs and QRs: faster than with OpenBLAS's threads (see the docstring's Notes)
def extract(
    signals: xr.Dataset | str | Path,
    options: ExtractOptions | Mapping[str, Any] | None = None,
    *,
    output: str | Path | None = None,
    progress: bool = True,
    command: str = "",
    **fields: Any,
) -> xr.Dataset:
    """Identify the modes of a record and J samples of each (automated covariance-driven SSI).

    Parameters
    ----------
    signals : xarray.Dataset or path
        ``displacement`` (time, channel) with attr ``sampling_rate`` [Hz] (``signals.nc``), or ``signal``
        with each channel's ``quantity`` and ``units`` (:mod:`twin.extract.quantities`): velocity and
        acceleration channels are read as such and every shape is reported in displacement.
    options : ExtractOptions or mapping, optional
        The options (:class:`twin.extract.options.ExtractOptions`, or a mapping of its fields); the
        defaults where not given.
    output : path, optional
        ``modes.nc`` to write (atomically).
    progress : bool
        Progress bar over the jackknife blocks.
    command : str
        The command line recorded in the file's attrs.
    **fields
        Options as keywords, over ``options`` (the Other Parameters below).

    Other Parameters
    ----------------
    samples : int, optional
        Samples per mode: each comes from the record without
        ``delete_blocks`` of its ``blocks`` (delete-d jackknife, see
        :mod:`twin.extract.samples`). With neither ``samples`` nor
        ``blocks`` given the extraction chooses both
        (:func:`twin.extract.blocks.adapted_blocks`:
        :data:`twin.defaults.SAMPLES` where the record holds that many
        blocks for the Hankel matrix, else as many as it holds) and says
        what it chose and why, naming its slowest mode's decay, in the
        ``settings`` attr (``blocks_chosen``). Given ``blocks`` alone,
        one sample per block.
    fmax_hz : float, optional
        Highest frequency of interest [Hz] (default 40% of the sampling rate).
        The record is decimated to about ``2.5 fmax``.
    fmin_hz : float
        Lowest frequency of interest [Hz]; when given, the record must hold
        100 periods of it.
    block_rows : int, optional
        Block rows ``i`` of the covariance Hankel matrix (lags ``k0`` to ``2i + k0 - 1``, ``k0 = first_lag``).
        Default: ``i / fs`` covers a quarter period of ``max(fmin, fmax / 100)``
        (about 63 block rows after decimation). The poles are read at these lags.
    shape_block_rows : int or "auto"
        0 (the default): the shapes are read at ``block_rows`` with the
        poles. A number: every mode's shapes (and their samples) are read
        from a second SSI pass with that many block rows. ``"auto"``: the
        shapes of the modes with fewer than 1.5 periods in ``block_rows``'s
        lags are read at lags over 1.5 periods of the slowest of them
        (:func:`twin.extract.passes.shape_lag_rows`; 345-350 block rows for
        the hydro unit's 1.1 and 2.9 Hz modes at 256 Hz). Neither beat the
        one pass on the hydro unit's FMU records
        (``docs/decisions/extraction-lags.md``). A mode without a counterpart in the second pass keeps
        the first pass's shapes (variable ``shape_block_rows``).
    first_lag : int, optional
        The lag the covariance Hankel matrix starts at, in samples of the
        (decimated) record, at least 1. Default: the first at or beyond one
        period of ``fmax`` (:func:`twin.extract.passes.first_lag_for`; 5 at
        256 Hz and 60 Hz): the first lags carry the dynamics above the band,
        which bent the band's shapes (``docs/decisions/extraction-lags.md``).
        1 is the textbook Hankel matrix.
    max_order : int
        Largest model order of the stabilisation diagram (orders 2, 4, ...).
    channels : sequence of str, optional
        Channels to use (default all).
    criteria : Criteria, optional
        Stabilisation and clustering settings.
    delete_blocks : int or None
        Blocks each sample leaves out: 1 (the default, delete-one jackknife)
        or None for half of them, drawn at random (delete-half: a spread
        that matches independent records, but the loop's comparison is not
        yet calibrated to it; ``docs/decisions/extraction-jackknife.md``).
    order_spread : {"shapes", "all", "none"}
        Add to the samples the spread of each mode over the model orders it
        is averaged over (:func:`twin.extract.samples.order_deviations`), so
        that they stand for the jackknife's statistical error and the
        model-order part of SSI's systematic error, in quadrature: to the
        shape samples only (``"shapes"``, the default), to the pole samples
        too (``"all"``; ``True`` means the same) or to neither (``"none"``,
        ``False``). The shapes get the standard error of their mean over the
        ``n`` orders (the spread over ``sqrt(n)``), the poles the whole
        spread. SSI's shapes sit off the truth's by more than their
        jackknife error, and the update's intervals were too narrow with
        jackknife shapes alone; the poles' jackknife error is what the loop's
        comparison is calibrated to (``docs/decisions/extraction-jackknife.md``).
    blocks : int, optional
        J, contiguous blocks the record is cut into (default ``samples``,
        or chosen with it when neither is given).
        The delete-one jackknife gives one sample per block; with more
        blocks deleted, ``samples`` may exceed ``blocks`` (random subsets),
        for a steadier spread from blocks that must stay long.
    orders_per_mode : int or None
        A mode is the average over this many of its lowest settled model
        orders (:mod:`twin.extract.orders`; default 8; None: all of them, less
        of SSI's bias and a wider jackknife; ``benchmarks/update_coverage_fmu.py --orders-per-mode 0`` measures it).
    differenced_above_hz : float, optional
        Read the modes above this natural frequency [Hz] from a second SSI
        pass over the record differenced twice
        (:func:`twin.extract.passes.differenced`; lags from ``max(first_lag,
        3)``), where the slow, strong modes no longer fill the covariances
        (:func:`twin.extract.passes.modes_from_differenced`). A mode without
        a counterpart there keeps the first pass's estimate (variable
        ``differences``: 0 or 2 per mode). Put it between a record's slow
        modes and the rest (e.g. 6 Hz for the hydro unit, whose modes below
        4 Hz are the strongest). Not the default: on the hydro unit's FMU
        records it narrows the bearings' intervals by a quarter, and the
        seal's stay too narrow (``docs/decisions/extraction-differenced.md``).
    shape_samples : int, optional
        Draw the shape samples from their own delete-half jackknife: this
        many random halves of the same ``blocks`` (a multiple of
        ``samples``; with ``samples`` chosen by the extraction, the nearest
        multiple of at least two), while the poles keep the samples of ``delete_blocks``,
        each used ``shape_samples / samples`` times with its deviation
        scaled so that the standard error stays
        (:func:`twin.extract.samples.repeated`). The update estimates each
        mode's shape covariance (``2 x channels`` real entries) from the
        samples; 15 delete-one samples leave it singular and its shrinkage
        lifts the directions the bearings are read from, while the
        delete-one spread of the poles is what the seal's and the loop's
        comparison are calibrated to
        (``docs/decisions/extraction-shape-samples.md``). ``twin demo`` and ``twin sweep`` ask for ``4 x samples``.
        Not with ``differenced_above_hz`` or ``shape_block_rows``. None or 0
        (the default): the shapes come with the poles.
    remove_harmonics : bool
        When the record gives its running speed (attr ``speed_rpm``), subtract
        the sinusoids at its multiples before SSI
        (:func:`twin.extract.harmonics.remove_running_harmonics`); they are
        listed in the ``harmonics`` attr with ``"removed": true``. On by
        default: a line next to a damped mode biases SSI's estimate of that
        mode (the 1X line at 2.23 Hz and the hydro unit's 2.6 Hz generator
        mode). Without it, the lines are only rejected as modes by their
        band kurtosis.

    Returns
    -------
    xarray.Dataset
        Dimensions ``mode``, ``sample``, ``channel`` (and ``diagram_pole`` for the
        stabilisation diagram): complex ``pole`` [1/s] and ``shape`` samples;
        per mode the full-record ``frequency`` (damped) and ``natural_frequency``
        [Hz], ``damping_ratio``, their sample std and standard error (and
        its two parts: ``*_se_jackknife`` and ``*_order_std``), the
        covariance of the pole's real and imaginary parts over the model
        orders ``pole_order_cov`` [1/s²] (dims ``pole_part``, ``pole_part_2``),
        ``sensor_shape``, ``MPC``, ``MPD`` [deg], ``model_order``.

    Notes
    -----
    Runs with one BLAS thread (:func:`twin.tasks.one_blas_thread`): its work is
    many small SVDs, QRs and eigen-solutions, on which OpenBLAS's threads cost
    more in hand-over than they gain (``benchmarks/extract_threads.py``).

    Examples
    --------
    >>> import numpy as np, scipy.signal as sig, xarray as xr
    >>> from twin.extract import extract
    >>> rng = np.random.default_rng(0)
    >>> fs, n = 20.0, 20_000
    >>> lam = -0.02 * 2 * np.pi * 2.0 + 2j * np.pi * 2.0  # one mode: 2 Hz, 2% damping
    >>> q = sig.lfilter([1.0], [1.0, -np.exp(lam / fs)], rng.standard_normal(n) + 1j * rng.standard_normal(n))
    >>> y = 2 * np.real(q[:, None] * np.array([1.0, 0.6j, 0.8, 0.5j])) + 0.1 * rng.standard_normal((n, 4))
    >>> ds = xr.Dataset({"displacement": (("time", "channel"), y)}, coords={"channel": ["A_x", "A_y", "B_x", "B_y"]},
    ...                 attrs={"sampling_rate": fs})
    >>> modes = extract(ds, samples=20, max_order=16, fmax_hz=8.0, progress=False)
    >>> modes.frequency.values.round(2), modes.damping_ratio.values.round(2), modes.MPC.values.round(2)
    (array([2.]), array([0.02]), array([0.21]))
    """
    opts = ExtractOptions.of(options, **fields)  # every option checked before the record is read
    (fmax_hz, fmin_hz, block_rows, shape_block_rows, first_lag, max_order, crit, delete_blocks, order_spread,
     remove_harmonics, orders_per_mode, differenced_above_hz) = (
        opts.fmax_hz, opts.fmin_hz, opts.block_rows, opts.shape_block_rows, opts.first_lag, opts.max_order,
        opts.criteria, opts.delete_blocks, opts.order_spread, opts.remove_harmonics, opts.orders_per_mode,
        opts.differenced_above_hz)  # fmt: skip
    if output is not None:
        output = check_writable(output)
    ds, source = _open(signals)
    rec = check_record(ds, source, opts.channels)
    nyquist = rec.fs_hz / 2
    fmax = DEFAULT_FMAX_FRACTION * rec.fs_hz if fmax_hz is None else float(fmax_hz)
    if not 0 < fmax <= nyquist:
        raise SignalError(f"{source}: fmax = {fmax:g} Hz must be positive and at most Nyquist ({nyquist:g} Hz)")
    if fmax > DEFAULT_FMAX_FRACTION * rec.fs_hz * (1 + 1e-9):
        warnings.warn(f"{source}: fmax = {fmax:g} Hz is above {DEFAULT_FMAX_FRACTION:.0%} of the sampling rate "
                      f"({DEFAULT_FMAX_FRACTION * rec.fs_hz:g} Hz): modes near Nyquist are seen with few samples per "
                      "period and through the anti-alias filter's roll-off; their estimates are poor", TwinWarning,
                      stacklevel=2)  # fmt: skip
    if not 0 <= fmin_hz < fmax:
        raise SignalError(f"{source}: fmin = {fmin_hz:g} Hz must be at least 0 and below fmax = {fmax:g} Hz")
    if differenced_above_hz is not None and not 0 <= as_float(differenced_above_hz) < fmax:  # NaN fails too
        raise SignalError(f"{source}: differenced_above_hz must be a frequency from 0 to below fmax = {fmax:g} Hz, "
                          f"got {differenced_above_hz!r}")  # fmt: skip
    chosen = opts.chosen  # the extraction chooses the blocks from the record
    n_blocks, samples = opts.n_blocks, opts.n_samples
    if fmin_hz > 0 and rec.duration_s * fmin_hz < MIN_CYCLES:
        raise SignalError(f"{source}: the record lasts {rec.duration_s:g} s, too short for modes down to "
                          f"fmin = {fmin_hz:g} Hz: it needs {MIN_CYCLES / fmin_hz:g} s ({MIN_CYCLES} periods)")  # fmt: skip
    _warn_about_layout(source, len(rec.channels), rec.fs_hz, fmax_hz)
    y, fs, q = _decimate(rec, fmax)
    speed_rpm = rec.attrs.get("speed_rpm")
    running_hz = float(speed_rpm) / 60.0 if speed_rpm else None
    removed = []
    if remove_harmonics and running_hz:
        y, removed = remove_running_harmonics(y, fs, running_hz, fmax)
        for h in removed:
            log.info("%.4f Hz (%dX) removed before SSI: a line %.0f dB above the spectrum around it",
                     h["frequency_hz"], h["running_speed_multiple"], h["line_to_floor_db"])  # fmt: skip
    n_ch = y.shape[1]
    f_low = max(fmin_hz, DEFAULT_FMIN_FRACTION * fmax)  # lags cover a quarter period of f_low
    i = block_rows or max(int(np.ceil(fs / (4 * f_low))), int(np.ceil(max_order / n_ch)) + 1)
    k0 = first_lag_for(fs, fmax) if first_lag is None else int(first_lag)
    lags = hankel_max_lag(i, k0)
    most = most_blocks(y.shape[0], lags)
    if chosen:
        n_blocks = samples = block_count(most)
    check_block_length(source, rec.duration_s, y.shape[0], n_blocks, lags, fs, i, k0)
    n_deleted, repeats = jackknife_plan(n_blocks, samples, opts)

    log.info("SSI-cov on %s: %d channels, %.0f s at %g Hz, %d block rows from lag %d, orders up to %d",
             source, n_ch, rec.duration_s, fs, i, k0, max_order)  # fmt: skip
    spectrum: dict = {}
    found = ssi_pass(y, fs, i, n_blocks, max_order, fmin_hz, fmax, crit, running_hz, rec.channels, spectrum,
                     first_lag=k0)  # fmt: skip
    plan = None
    if chosen:
        plan = adapted_blocks(y.shape[0] / fs, most, np.array([found.diag.pole[c.representative]
                                                              for c in found.modes]))  # fmt: skip
        log.info("jackknife: %s", plan.reason)
    block_len = y.shape[0] // n_blocks
    covariances, real, diag, modes = found.covariances, found.real, found.diag, found.modes
    harmonics = list(removed) + found.harmonics
    if not modes:
        raise NoModeError(f"{source}: no physical mode found between {fmin_hz:g} and {fmax:g} Hz "
                          f"({len(harmonics)} harmonic(s) rejected)", block_rows=i)  # fmt: skip

    members = mode_members(found, orders_per_mode)
    poles, shapes, sample_p, sample_s, missing = jackknife(covariances, i, fs, members, progress,
                                                           delete=delete_blocks, n_samples=samples, first_lag=k0)
    n_samples = samples
    if repeats > 1:  # the shapes from their own delete-half samples, each pole sample used `repeats` times
        n_samples = samples * repeats
        log.info("shape samples: %d random halves of the %d blocks", n_samples, n_blocks)
        sample_s = jackknife(covariances, i, fs, members, progress, delete=None, n_samples=n_samples,
                             first_lag=k0)[3]  # fmt: skip
        sample_p, missing = repeated(sample_p, repeats), np.repeat(missing, repeats, axis=1)
    d_p, d_s = order_deviations(members, shapes, n_samples)
    differences = np.zeros(len(poles), dtype=int)
    if differenced_above_hz is not None:
        log.info("SSI-cov again on the record differenced %d times for the modes above %g Hz",
                 DIFFERENCES, differenced_above_hz)  # fmt: skip
        again = ssi_pass(differenced(y), fs, i, n_blocks, max_order, max(fmin_hz, differenced_above_hz), fmax, crit,
                         running_hz, rec.channels, {}, quiet=True, first_lag=max(k0, DIFFERENCES + 1))  # fmt: skip
        first = (members, poles, shapes, sample_p, sample_s, missing, d_p, d_s)
        again_members = mode_members(again, orders_per_mode)
        read, counterpart = modes_from_differenced(again, again_members, fs, differenced_above_hz, first, progress,
                                                   delete=delete_blocks, n_samples=samples)  # fmt: skip
        members, poles, shapes, sample_p, sample_s, missing, d_p, d_s = read
        differences[counterpart >= 0] = DIFFERENCES
        modes = [again.modes[j] if j >= 0 else c for c, j in zip(modes, counterpart)]  # for the cluster sizes
    jackknife_p = sample_p
    if order_spread == "all":
        sample_p = sample_p + d_p
    n_orders = np.array([len(m[0]) for m in members])
    missing = missing / n_orders[:, None]  # per sample, the fraction of the mode's orders without a counterpart
    # blocks shorter than a few time constants cannot tell a pole's damping: its frequency alone is judged
    damping_judged = block_len / fs >= MIN_BLOCK_TIME_CONSTANTS / np.maximum(np.abs(poles.real), 1e-12)
    scatter = pole_scatter(poles, sample_p, missing.mean(axis=1), damping_judged, rec.duration_s)
    keep = scatter < MAX_POLE_SE  # pole_determined's test, with the scatter kept for the warnings
    undetermined = left_out(source, poles[~keep], sample_p[~keep], scatter[~keep], damping_judged[~keep],
                            rec.duration_s)
    if not keep.any():
        raise NoModeError(f"{source}: no physical mode found between {fmin_hz:g} and {fmax:g} Hz "
                          f"({len(undetermined)} stable pole(s) dropped: their samples scatter beyond their "
                          "bandwidth)", block_rows=i)  # fmt: skip
    if undetermined:
        new_index = np.where(keep, np.cumsum(keep) - 1, -1)
        diag = dataclasses.replace(diag, cluster=np.where(diag.cluster >= 0, new_index[diag.cluster], diag.cluster))
        poles, shapes, sample_p, sample_s, d_s, missing, jackknife_p, n_orders, differences = (
            x[keep] for x in (poles, shapes, sample_p, sample_s, d_s, missing, jackknife_p, n_orders, differences))  # fmt: skip
        members = [m for m, k in zip(members, keep) if k]
        modes = [c for c, k in zip(modes, keep) if k]
    i_s, slow = _shape_rows(shape_block_rows, poles, fs, i, block_len, source, k0)
    shape_rows = np.full(len(poles), i)
    if i_s > i:
        log.info("SSI-cov again with %d block rows for the shapes of %d mode(s) (lags of %.3g s)",
                 i_s, slow.sum(), i_s / fs)  # fmt: skip
        again = ssi_pass(y, fs, i_s, n_blocks, max_order, fmin_hz, fmax, crit, running_hz, rec.channels, spectrum,
                         quiet=True, first_lag=k0)  # fmt: skip
        read = shapes_at_longer_lags(again, fs, mode_members(again, orders_per_mode), poles[slow],
                                     shapes[slow], sample_s[slow], d_s[slow], progress, delete=delete_blocks,
                                     n_samples=samples)  # fmt: skip
        shapes[slow], sample_s[slow], d_s[slow], matched = read
        shape_rows[np.flatnonzero(slow)[matched]] = i_s
        for f in poles[slow][~matched].imag / (2 * np.pi):
            log.info("%.4f Hz: no counterpart at %d block rows, its shapes are read at %d", f, i_s, i)
    if order_spread != "none":
        sample_s = sample_s + d_s
    if rec.orders.any():  # velocity and acceleration channels: every shape in displacement, as the model's
        shapes = displacement_shapes(shapes, poles, rec.orders)
        sample_s = displacement_shapes(sample_s, poles, rec.orders)
    ref_channel = np.argmax(np.abs(shapes), axis=1)
    shapes = normalise_at(shapes, ref_channel)
    sample_s = normalise_at(sample_s, ref_channel[:, None])
    warn_about_few_blocks(source, n_blocks, chosen)
    _warn_about_samples(source, poles, missing)

    out = extracted_modes(rec, ds, poles, shapes, sample_p, sample_s, jackknife_p, members, n_orders,
                          [len(c.members) for c in modes], ref_channel, diag)  # fmt: skip
    out["shape_block_rows"] = ("mode", shape_rows, {"long_name": "block rows of the SSI pass the shapes are read at"})
    out["differences"] = ("mode", differences, {"long_name": "times the record was differenced for the SSI pass "
                                                             "the mode is read from"})  # fmt: skip
    settings = {
        "samples": samples, "shape_samples": n_samples, "blocks": n_blocks, "fmin_hz": fmin_hz, "fmax_hz": fmax,
        "block_rows": i, "blocks_chosen": None if plan is None else plan.reason,
        "shape_block_rows": max(i, i_s), "first_lag": k0, "max_order": int(real.max_order),
        "decimation": q, "fs_hz": fs, "duration_s": rec.duration_s, "channels": list(rec.channels),
        "quantities": list(rec.quantities),
        "criteria": dataclasses.asdict(crit), "block_length_s": block_len / fs,
        "delete_blocks": n_deleted, "order_spread": order_spread, "orders_per_mode": orders_per_mode,
        "outlier_mads": OUTLIER_MADS, "remove_harmonics": bool(remove_harmonics),
        "differenced_above_hz": None if differenced_above_hz is None else float(differenced_above_hz),
    }  # fmt: skip
    out.attrs.update({
        "title": f"modes identified from {Path(source).name}",
        "producer": f"twin {__version__} twin.extract (covariance-driven SSI, jackknife samples)",
        "command": command,
        "settings": json.dumps(settings),
        "harmonics": json.dumps(harmonics),
        "undetermined_poles": json.dumps(undetermined),
        "samples_method": (f"delete-d block jackknife (d = {n_deleted} of {n_blocks} blocks, {samples} samples) "
                           "centred on the full-record estimate"
                           + {"none": "", "shapes": ", the shapes plus the standard error of their mean over the "
                                                    "mode's model orders",
                              "all": ", the poles plus the mode's spread over its model orders, the shapes plus the "
                                     "standard error of their mean over them"}[order_spread]
                           + (f"; the shapes from {n_samples} random halves of the blocks, each pole sample "
                              f"used {repeats} times (scaled to keep its standard error)" if repeats > 1 else "")
                           + (f"; shapes read at {i_s} block rows" if i_s > i else "")
                           + (f"; modes above {differenced_above_hz:g} Hz read from the record differenced "
                              f"{DIFFERENCES} times" if differences.any() else "")
                           + ": sample std / sqrt(J) is the standard error"),
        "signals": source,
    })  # fmt: skip
    for key in ("truth", "truth_modes", "seed", "model", "speed_rpm"):
        if key in rec.attrs:
            out.attrs[f"signals_{key}" if key == "seed" else key] = rec.attrs[key]
    if output is not None:
        write_modes(out, output)
    return out


def _shape_rows(asked: int | str, poles: np.ndarray, fs: float, i: int, block_len: int,
                source: str, first_lag: int = 1) -> tuple[int, np.ndarray]:  # fmt: skip
    """Block rows of the pass the shapes are read at, and which modes' shapes it reads.

    ``asked``: every mode's, at that many rows (``i``, the poles' pass, or fewer: none). ``"auto"``: the
    modes whose own :func:`shape_lag_rows` exceed ``i``, at those of the slowest of them; at most what
    the jackknife blocks hold (lags ``2 i + first_lag - 1``)."""
    longest = int((block_len / MIN_BLOCK_LAGS - first_lag + 1) // 2)
    if asked == "auto":
        f_hz = np.abs(poles) / (2 * np.pi)
        slow = np.array([shape_lag_rows(f, fs) > i for f in f_hz], dtype=bool)
        if not slow.any():
            return i, slow
        return shape_lag_rows(float(f_hz[slow].min()), fs, minimum=i, maximum=longest), slow
    if asked > longest:
        raise SignalError(f"{source}: shape_block_rows = {asked} is too many for blocks of {block_len / fs:g} s: "
                          f"each block must hold {MIN_BLOCK_LAGS:g} times the {hankel_max_lag(asked, first_lag)} lags "
                          f"(at most {longest})")  # fmt: skip
    return int(asked), np.ones(len(poles), dtype=bool)


def _warn_about_layout(source: str, n_channels: int, fs_hz: float, fmax_hz: float | None) -> None:
    """Warn about a record that can only give a poor extraction: few channels, or a low rate and no fmax."""
    if n_channels < MIN_CHANNELS:
        warnings.warn(f"{source}: {n_channels} channel(s): shapes known at so few points cannot tell modes apart "
                      f"(MAC), and a mode with a node there is missed; use at least {MIN_CHANNELS} (two x-y "
                      "proximeter pairs)", TwinWarning, stacklevel=3)  # fmt: skip
    if fmax_hz is None and fs_hz < LOW_RATE_HZ:
        warnings.warn(f"{source}: sampled at {fs_hz:g} Hz and no fmax given: modes are extracted up to "
                      f"{DEFAULT_FMAX_FRACTION * fs_hz:g} Hz only ({DEFAULT_FMAX_FRACTION:.0%} of the rate); "
                      "sample faster to see a rotor's higher modes, or give fmax to say that is the band you want",
                      TwinWarning, stacklevel=3)  # fmt: skip


def _warn_about_samples(source: str, poles: np.ndarray, missing: np.ndarray) -> None:
    f = poles.imag / (2 * np.pi)
    for k in np.flatnonzero(missing.mean(axis=1) > MAX_MISSING):
        warnings.warn(f"{source}: the {f[k]:.4g} Hz mode has no clear counterpart in {missing[k].mean():.0%} of the "
                      "identifications without a sample's blocks: its sample spread is too narrow; treat it with care",
                      TwinWarning, stacklevel=3)  # fmt: skip
