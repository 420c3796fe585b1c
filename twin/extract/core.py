"""Automated operational modal analysis: ``signals.nc`` in, ``modes.nc`` out.

One function, :func:`extract`: check the record, decimate to the band asked
for, covariance-driven SSI (or pLSCF, :mod:`twin.extract.algorithms`) over many orders, stabilisation diagram, automatic
clustering, running-speed harmonics removed (a known speed) or rejected, J jackknife samples per
mode; its steps are :mod:`twin.extract.steps`. It never reads the model; pair the result with model
modes by MAC with :func:`twin.pair_modes`.
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
import xarray as xr

from twin import __version__
from twin.defaults import ORDERS_PER_MODE, SAMPLES  # noqa: F401 (defaults of the extraction, shared with the CLI)
from twin.errors import TwinWarning
from twin.extract.algorithms import ALGORITHM_NAMES
from twin.extract.blocks import warn_about_few_blocks
from twin.extract.options import ExtractOptions
from twin.extract.orders import OUTLIER_MADS
from twin.extract.passes import DIFFERENCES
from twin.extract.result import extracted_modes
from twin.extract.steps import (
    Modes,
    Prepared,
    differenced_pass,
    drop_undetermined,
    finish_shapes,
    first_pass,
    prepare,
    shapes_pass,
)
from twin.modes.modesfile import write_modes
from twin.netcdf import check_writable
from twin.tasks import one_blas_thread

log = logging.getLogger(__name__)

#: Warn when more than this fraction of a mode's jackknife matches fail.
MAX_MISSING = 0.05


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
    order_spread : {"shapes", "all", "none"}, optional
        Add to the samples the spread of each mode over the model orders it
        is averaged over (:func:`twin.extract.samples.order_deviations`), so
        that they stand for the jackknife's statistical error and the
        model-order part of SSI's systematic error, in quadrature: to the
        shape samples only (``"shapes"``, SSI's default), to the pole samples
        too (``"all"``, pLSCF's default; ``True`` means the same) or to
        neither (``"none"``, ``False``). pLSCF's poles scatter beyond their
        jackknife spread (``docs/decisions/extraction-plscf.md``). The shapes get the standard error of their mean over the
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
    algorithm : {"ssi", "plscf"}
        How the poles and shapes are read from the record's covariances at
        each model order (:mod:`twin.extract.algorithms`): covariance-driven
        SSI (the default) or the poly-reference least-squares complex
        frequency-domain fit of their half spectra over the band (pLSCF,
        :mod:`twin.extract.plscf`; model orders ``m, 2m, ...`` for ``m``
        channels). pLSCF for heavily damped, overlapping modes (5-11%: the
        shipped ``pelton_unit``), SSI for lightly damped, slow ones (the
        hydro unit's); ``docs/decisions/extraction-plscf.md``.
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
    if output is not None:
        output = check_writable(output)
    p = prepare(signals, opts)
    m = first_pass(p, opts, progress)
    if opts.differenced_above_hz is not None:
        differenced_pass(p, m, opts, progress)
    drop_undetermined(p, m, opts)
    shapes_pass(p, m, opts, progress)
    ref_channel = finish_shapes(p, m, opts)
    warn_about_few_blocks(p.source, p.n_blocks, opts.chosen)
    _warn_about_samples(p.source, m.poles, m.missing)
    out = _modes_dataset(p, m, opts, ref_channel, command)
    if output is not None:
        write_modes(out, output)
    return out


def _modes_dataset(p: Prepared, m: Modes, opts: ExtractOptions, ref_channel: np.ndarray, command: str) -> xr.Dataset:
    """The modes Dataset (:func:`twin.extract.result.extracted_modes`) with the passes' variables, the settings as
    they were resolved, the lines and poles left out, and how the samples were made."""
    i, n_blocks, samples, order_spread = p.block_rows, p.n_blocks, p.samples, opts.order_spread
    out = extracted_modes(
        p.rec,
        p.ds,
        m.poles,
        m.shapes,
        m.sample_p,
        m.sample_s,
        m.jackknife_p,
        m.members,
        m.n_orders,
        [len(c.members) for c in m.clusters],
        ref_channel,
        m.diag,
    )
    out["shape_block_rows"] = ("mode", m.shape_rows, {"long_name": "block rows of the SSI pass the shapes are read at"})
    out["differences"] = (
        "mode",
        m.differences,
        {"long_name": "times the record was differenced for the SSI pass the mode is read from"},
    )
    settings = {
        "samples": samples,
        "shape_samples": m.n_samples,
        "blocks": n_blocks,
        "fmin_hz": opts.fmin_hz,
        "fmax_hz": p.fmax,
        "block_rows": i,
        "blocks_chosen": m.plan_reason,
        "shape_block_rows": m.shape_block_rows,
        "first_lag": p.first_lag,
        "max_order": m.max_order,
        "decimation": p.decimation,
        "fs_hz": p.fs,
        "duration_s": p.rec.duration_s,
        "channels": list(p.rec.channels),
        "quantities": list(p.rec.quantities),
        "criteria": dataclasses.asdict(opts.criteria),
        "block_length_s": p.block_length / p.fs,
        "delete_blocks": m.n_deleted,
        "order_spread": order_spread,
        "orders_per_mode": opts.orders_per_mode,
        "outlier_mads": OUTLIER_MADS,
        "remove_harmonics": bool(opts.remove_harmonics),
        "differenced_above_hz": None if opts.differenced_above_hz is None else float(opts.differenced_above_hz),
        "algorithm": opts.algorithm,
    }
    out.attrs.update(
        {
            "title": f"modes identified from {Path(p.source).name}",
            "producer": f"twin {__version__} twin.extract ({ALGORITHM_NAMES[opts.algorithm]}, jackknife samples)",
            "command": command,
            "settings": json.dumps(settings),
            "harmonics": json.dumps(m.harmonics),
            "undetermined_poles": json.dumps(m.undetermined),
            "samples_method": (
                f"delete-d block jackknife (d = {m.n_deleted} of {n_blocks} blocks, {samples} samples) "
                "centred on the full-record estimate"
                + {
                    "none": "",
                    "shapes": ", the shapes plus the standard error of their mean over the mode's model orders",
                    "all": ", the poles plus the mode's spread over its model orders, the shapes plus the "
                    "standard error of their mean over them",
                }[order_spread]
                + (
                    f"; the shapes from {m.n_samples} random halves of the blocks, each pole sample "
                    f"used {m.repeats} times (scaled to keep its standard error)"
                    if m.repeats > 1
                    else ""
                )
                + (f"; shapes read at {m.shape_block_rows} block rows" if m.shape_block_rows > i else "")
                + (
                    f"; modes above {opts.differenced_above_hz:g} Hz read from the record differenced "
                    f"{DIFFERENCES} times"
                    if m.differences.any()
                    else ""
                )
                + ": sample std / sqrt(J) is the standard error"
            ),
            "signals": p.source,
        }
    )
    for key in ("truth", "truth_modes", "seed", "model", "speed_rpm"):
        if key in p.rec.attrs:
            out.attrs[f"signals_{key}" if key == "seed" else key] = p.rec.attrs[key]
    return out


def _warn_about_samples(source: str, poles: np.ndarray, missing: np.ndarray) -> None:
    f = poles.imag / (2 * np.pi)
    for k in np.flatnonzero(missing.mean(axis=1) > MAX_MISSING):
        warnings.warn(
            f"{source}: the {f[k]:.4g} Hz mode has no clear counterpart in {missing[k].mean():.0%} of the "
            "identifications without a sample's blocks: its sample spread is too narrow; treat it with care",
            TwinWarning,
            stacklevel=3,
        )
