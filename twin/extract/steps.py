"""The extraction's steps, in the order :func:`twin.extract.extract` runs them.

1. :func:`prepare`: the record checked, decimated to the band, the running speed's lines removed, the
   Hankel matrix's size and the jackknife's blocks set;
2. :func:`first_pass`: SSI-cov over the model orders and the stabilisation diagram cleared (the modes);
3. :func:`jackknife_samples`: each mode's samples over the blocks, and its spread over the model orders;
4. :func:`differenced_pass` (``differenced_above_hz``): the modes above it read again from the record
   differenced twice;
5. :func:`drop_undetermined`: the poles whose samples scatter beyond their bandwidth left out;
6. :func:`shapes_pass` (``shape_block_rows``): shapes read again at longer lags;
7. :func:`finish_shapes`: the order spread added to the shape samples, every shape in displacement and
   normalised.

The record (:class:`Prepared`) and the modes (:class:`Modes`) carry what one step hands the next.
"""

from __future__ import annotations

import dataclasses
import logging
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.signal as sig
import xarray as xr

from twin.errors import NoModeError, SignalError, TwinWarning
from twin.extract.algorithms import ALGORITHM_NAMES
from twin.extract.blocks import (
    MIN_BLOCK_LAGS,
    MIN_BLOCK_TIME_CONSTANTS,
    adapted_blocks,
    block_count,
    check_block_length,
    most_blocks,
)
from twin.extract.harmonics import remove_running_harmonics
from twin.extract.options import ExtractOptions, as_float, jackknife_plan
from twin.extract.orders import mode_members
from twin.extract.passes import (
    DIFFERENCES,
    differenced,
    first_lag_for,
    modes_from_differenced,
    shape_lag_rows,
    shapes_at_longer_lags,
    ssi_pass,
)
from twin.extract.quantities import displacement_shapes
from twin.extract.result import MAX_POLE_SE, left_out, pole_scatter
from twin.extract.samples import jackknife, normalise_at, order_deviations, repeated
from twin.extract.signals import Record, check_record
from twin.extract.ssi import hankel_max_lag
from twin.netcdf import load_netcdf

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


@dataclass
class Prepared:
    """The record as the SSI passes read it: the checked record, its (decimated, cleaned) samples ``y`` at
    ``fs`` [Hz], the band's top ``fmax`` [Hz], the lines removed, and the Hankel matrix's block rows and
    first lag, the blocks and the samples of the jackknife."""

    ds: xr.Dataset
    source: str
    rec: Record
    y: np.ndarray
    fs: float
    decimation: int
    fmax: float
    running_hz: float | None
    removed: list
    block_rows: int
    first_lag: int
    n_blocks: int
    samples: int
    most: int
    spectrum: dict = field(default_factory=dict)

    @property
    def block_length(self) -> int:
        """Samples of one jackknife block."""
        return self.y.shape[0] // self.n_blocks


@dataclass
class Modes:
    """The modes through the steps: per mode its clusters of poles, the model orders it is averaged over
    (``members``), its full-record pole and shape, their samples and model-order deviations, the fraction of
    each sample's orders without a counterpart, and which pass read it."""

    clusters: list
    members: list
    diag: object
    max_order: int
    harmonics: list
    poles: np.ndarray
    shapes: np.ndarray
    sample_p: np.ndarray
    sample_s: np.ndarray
    missing: np.ndarray
    d_p: np.ndarray
    d_s: np.ndarray
    n_samples: int
    n_deleted: int
    repeats: int
    plan_reason: str | None = None
    differences: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    jackknife_p: np.ndarray | None = None
    n_orders: np.ndarray | None = None
    shape_rows: np.ndarray | None = None
    shape_block_rows: int = 0
    undetermined: list = field(default_factory=list)


def open_signals(signals: xr.Dataset | str | object) -> tuple[xr.Dataset, str]:
    """The signals Dataset and a name for it in messages (the file's path, or the Dataset's title)."""
    if isinstance(signals, xr.Dataset):
        return signals, str(signals.attrs.get("title", "signals"))
    return load_netcdf(signals, "signals", SignalError), str(signals)


def decimate(rec: Record, fmax_hz: float) -> tuple[np.ndarray, float, int]:
    """The record's samples decimated to about :data:`SAMPLES_PER_PERIOD` ``fmax`` (FIR, zero phase), the new
    rate [Hz] and the factor."""
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


def prepare(signals, opts: ExtractOptions) -> Prepared:
    """The record checked against the options, decimated to the band, its running speed's lines removed, and the
    Hankel matrix's size and the jackknife's blocks set (the record's own checks: band, length, blocks)."""
    ds, source = open_signals(signals)
    rec = check_record(ds, source, opts.channels)
    nyquist = rec.fs_hz / 2
    fmin_hz, differenced_above_hz = opts.fmin_hz, opts.differenced_above_hz
    fmax = DEFAULT_FMAX_FRACTION * rec.fs_hz if opts.fmax_hz is None else float(opts.fmax_hz)
    if not 0 < fmax <= nyquist:
        raise SignalError(f"{source}: fmax = {fmax:g} Hz must be positive and at most Nyquist ({nyquist:g} Hz)")
    if fmax > DEFAULT_FMAX_FRACTION * rec.fs_hz * (1 + 1e-9):
        warnings.warn(
            f"{source}: fmax = {fmax:g} Hz is above {DEFAULT_FMAX_FRACTION:.0%} of the sampling rate "
            f"({DEFAULT_FMAX_FRACTION * rec.fs_hz:g} Hz): modes near Nyquist are seen with few samples per "
            "period and through the anti-alias filter's roll-off; their estimates are poor",
            TwinWarning,
            stacklevel=4,
        )
    if not 0 <= fmin_hz < fmax:
        raise SignalError(f"{source}: fmin = {fmin_hz:g} Hz must be at least 0 and below fmax = {fmax:g} Hz")
    if differenced_above_hz is not None and not 0 <= as_float(differenced_above_hz) < fmax:  # NaN fails too
        raise SignalError(
            f"{source}: differenced_above_hz must be a frequency from 0 to below fmax = {fmax:g} Hz, "
            f"got {differenced_above_hz!r}"
        )
    n_blocks, samples = opts.n_blocks, opts.n_samples
    if fmin_hz > 0 and rec.duration_s * fmin_hz < MIN_CYCLES:
        raise SignalError(
            f"{source}: the record lasts {rec.duration_s:g} s, too short for modes down to "
            f"fmin = {fmin_hz:g} Hz: it needs {MIN_CYCLES / fmin_hz:g} s ({MIN_CYCLES} periods)"
        )
    warn_about_layout(source, len(rec.channels), rec.fs_hz, opts.fmax_hz)
    y, fs, q = decimate(rec, fmax)
    speed_rpm = rec.attrs.get("speed_rpm")
    running_hz = float(speed_rpm) / 60.0 if speed_rpm else None
    removed = []
    if opts.remove_harmonics and running_hz:
        y, removed = remove_running_harmonics(y, fs, running_hz, fmax)
        for h in removed:
            log.info(
                "%.4f Hz (%dX) removed before SSI: a line %.0f dB above the spectrum around it",
                h["frequency_hz"],
                h["running_speed_multiple"],
                h["line_to_floor_db"],
            )
    f_low = max(fmin_hz, DEFAULT_FMIN_FRACTION * fmax)  # lags cover a quarter period of f_low
    i = opts.block_rows or max(int(np.ceil(fs / (4 * f_low))), int(np.ceil(opts.max_order / y.shape[1])) + 1)
    k0 = first_lag_for(fs, fmax) if opts.first_lag is None else int(opts.first_lag)
    lags = hankel_max_lag(i, k0)
    most = most_blocks(y.shape[0], lags)
    if opts.chosen:
        n_blocks = samples = block_count(most)
    check_block_length(source, rec.duration_s, y.shape[0], n_blocks, lags, fs, i, k0)
    return Prepared(ds, source, rec, y, fs, q, fmax, running_hz, removed, i, k0, n_blocks, samples, most)


def first_pass(p: Prepared, opts: ExtractOptions, progress: bool) -> Modes:
    """SSI-cov over the model orders, the stabilisation diagram cleared into modes, and each mode's jackknife
    samples over the blocks and spread over its model orders (:func:`jackknife_samples`)."""
    n_deleted, repeats = jackknife_plan(p.n_blocks, p.samples, opts)
    log.info(
        "%s on %s: %d channels, %.0f s at %g Hz, %d block rows from lag %d, orders up to %d",
        ALGORITHM_NAMES[opts.algorithm],
        p.source,
        p.y.shape[1],
        p.rec.duration_s,
        p.fs,
        p.block_rows,
        p.first_lag,
        opts.max_order,
    )
    found = ssi_pass(
        p.y,
        p.fs,
        p.block_rows,
        p.n_blocks,
        opts.max_order,
        opts.fmin_hz,
        p.fmax,
        opts.criteria,
        p.running_hz,
        p.rec.channels,
        p.spectrum,
        first_lag=p.first_lag,
        algorithm=opts.algorithm,
    )
    reason = None
    if opts.chosen:
        plan = adapted_blocks(
            p.y.shape[0] / p.fs, p.most, np.array([found.diag.pole[c.representative] for c in found.modes])
        )
        log.info("jackknife: %s", plan.reason)
        reason = plan.reason
    harmonics = list(p.removed) + found.harmonics
    if not found.modes:
        raise NoModeError(
            f"{p.source}: no physical mode found between {opts.fmin_hz:g} and {p.fmax:g} Hz "
            f"({len(harmonics)} harmonic(s) rejected)",
            block_rows=p.block_rows,
        )
    return jackknife_samples(p, found, opts, progress, n_deleted, repeats, reason, harmonics)


def jackknife_samples(
    p: Prepared,
    found,
    opts: ExtractOptions,
    progress: bool,
    n_deleted: int,
    repeats: int,
    plan_reason: str | None,
    harmonics: list,
) -> Modes:
    """Each mode of the first pass with its delete-d jackknife samples (and, with ``shape_samples``, shape
    samples of their own delete-half jackknife) and its deviations over the model orders it is averaged over."""
    members = mode_members(found, opts.orders_per_mode)
    poles, shapes, sample_p, sample_s, missing = jackknife(
        found.covariances,
        p.block_rows,
        p.fs,
        members,
        progress,
        delete=opts.delete_blocks,
        n_samples=p.samples,
        first_lag=p.first_lag,
        algorithm=found.algorithm,
        near=found.real,
    )
    n_samples = p.samples
    if repeats > 1:  # the shapes from their own delete-half samples, each pole sample used `repeats` times
        n_samples = p.samples * repeats
        log.info("shape samples: %d random halves of the %d blocks", n_samples, p.n_blocks)
        sample_s = jackknife(
            found.covariances,
            p.block_rows,
            p.fs,
            members,
            progress,
            delete=None,
            n_samples=n_samples,
            first_lag=p.first_lag,
            algorithm=found.algorithm,
            near=found.real,
        )[3]
        sample_p, missing = repeated(sample_p, repeats), np.repeat(missing, repeats, axis=1)
    d_p, d_s = order_deviations(members, shapes, n_samples)
    return Modes(
        list(found.modes),
        members,
        found.diag,
        int(found.real.max_order),
        harmonics,
        poles,
        shapes,
        sample_p,
        sample_s,
        missing,
        d_p,
        d_s,
        n_samples,
        n_deleted,
        repeats,
        plan_reason,
        np.zeros(len(poles), dtype=int),
    )


def differenced_pass(p: Prepared, m: Modes, opts: ExtractOptions, progress: bool) -> None:
    """The modes above ``differenced_above_hz`` read again from the record differenced twice, where the slow,
    strong modes no longer fill the covariances; a mode without a counterpart there keeps its estimate."""
    above = opts.differenced_above_hz
    log.info("SSI-cov again on the record differenced %d times for the modes above %g Hz", DIFFERENCES, above)
    again = ssi_pass(
        differenced(p.y),
        p.fs,
        p.block_rows,
        p.n_blocks,
        opts.max_order,
        max(opts.fmin_hz, above),
        p.fmax,
        opts.criteria,
        p.running_hz,
        p.rec.channels,
        {},
        quiet=True,
        first_lag=max(p.first_lag, DIFFERENCES + 1),
        algorithm=opts.algorithm,
    )
    first = (m.members, m.poles, m.shapes, m.sample_p, m.sample_s, m.missing, m.d_p, m.d_s)
    again_members = mode_members(again, opts.orders_per_mode)
    read, counterpart = modes_from_differenced(
        again, again_members, p.fs, above, first, progress, delete=opts.delete_blocks, n_samples=p.samples
    )
    m.members, m.poles, m.shapes, m.sample_p, m.sample_s, m.missing, m.d_p, m.d_s = read
    m.differences[counterpart >= 0] = DIFFERENCES
    m.clusters = [again.modes[j] if j >= 0 else c for c, j in zip(m.clusters, counterpart)]  # for the cluster sizes


def drop_undetermined(p: Prepared, m: Modes, opts: ExtractOptions) -> None:
    """The pole samples with the model-order spread (``order_spread="all"``); the poles whose samples scatter
    beyond their bandwidth left out (listed in ``m.undetermined``); a record with no pole left has no mode."""
    m.jackknife_p = m.sample_p
    if opts.order_spread == "all":
        m.sample_p = m.sample_p + m.d_p
    m.n_orders = np.array([len(x[0]) for x in m.members])
    m.missing = m.missing / m.n_orders[:, None]  # per sample, the fraction of the mode's orders without a counterpart
    # blocks shorter than a few time constants cannot tell a pole's damping: its frequency alone is judged
    damping_judged = p.block_length / p.fs >= MIN_BLOCK_TIME_CONSTANTS / np.maximum(np.abs(m.poles.real), 1e-12)
    scatter = pole_scatter(m.poles, m.sample_p, m.missing.mean(axis=1), damping_judged, p.rec.duration_s)
    keep = scatter < MAX_POLE_SE  # pole_determined's test, with the scatter kept for the warnings
    m.undetermined = left_out(
        p.source, m.poles[~keep], m.sample_p[~keep], scatter[~keep], damping_judged[~keep], p.rec.duration_s
    )
    if not keep.any():
        raise NoModeError(
            f"{p.source}: no physical mode found between {opts.fmin_hz:g} and {p.fmax:g} Hz "
            f"({len(m.undetermined)} stable pole(s) dropped: their samples scatter beyond their "
            "bandwidth)",
            block_rows=p.block_rows,
        )
    if m.undetermined:
        new_index = np.where(keep, np.cumsum(keep) - 1, -1)
        m.diag = dataclasses.replace(
            m.diag, cluster=np.where(m.diag.cluster >= 0, new_index[m.diag.cluster], m.diag.cluster)
        )
        m.poles, m.shapes, m.sample_p, m.sample_s, m.d_s, m.missing, m.jackknife_p, m.n_orders, m.differences = (
            x[keep]
            for x in (
                m.poles,
                m.shapes,
                m.sample_p,
                m.sample_s,
                m.d_s,
                m.missing,
                m.jackknife_p,
                m.n_orders,
                m.differences,
            )
        )
        m.members = [x for x, k in zip(m.members, keep) if k]
        m.clusters = [c for c, k in zip(m.clusters, keep) if k]


def shapes_pass(p: Prepared, m: Modes, opts: ExtractOptions, progress: bool) -> None:
    """With ``shape_block_rows``, the shapes (and their samples) of the modes it asks for read from a second
    pass at more block rows; a mode without a counterpart there keeps its shapes (``m.shape_rows``)."""
    i = p.block_rows
    i_s, slow = shape_rows(opts.shape_block_rows, m.poles, p.fs, i, p.block_length, p.source, p.first_lag)
    m.shape_rows = np.full(len(m.poles), i)
    m.shape_block_rows = max(i, i_s)
    if i_s <= i:
        return
    log.info(
        "SSI-cov again with %d block rows for the shapes of %d mode(s) (lags of %.3g s)", i_s, slow.sum(), i_s / p.fs
    )
    again = ssi_pass(
        p.y,
        p.fs,
        i_s,
        p.n_blocks,
        opts.max_order,
        opts.fmin_hz,
        p.fmax,
        opts.criteria,
        p.running_hz,
        p.rec.channels,
        p.spectrum,
        quiet=True,
        first_lag=p.first_lag,
        algorithm=opts.algorithm,
    )
    read = shapes_at_longer_lags(
        again,
        p.fs,
        mode_members(again, opts.orders_per_mode),
        m.poles[slow],
        m.shapes[slow],
        m.sample_s[slow],
        m.d_s[slow],
        progress,
        delete=opts.delete_blocks,
        n_samples=p.samples,
    )
    m.shapes[slow], m.sample_s[slow], m.d_s[slow], matched = read
    m.shape_rows[np.flatnonzero(slow)[matched]] = i_s
    for f in m.poles[slow][~matched].imag / (2 * np.pi):
        log.info("%.4f Hz: no counterpart at %d block rows, its shapes are read at %d", f, i_s, i)


def finish_shapes(p: Prepared, m: Modes, opts: ExtractOptions) -> np.ndarray:
    """The model-order spread added to the shape samples (unless ``order_spread="none"``), every shape in
    displacement (velocity and acceleration channels) and normalised at its largest channel, which is returned."""
    if opts.order_spread != "none":
        m.sample_s = m.sample_s + m.d_s
    if p.rec.orders.any():  # velocity and acceleration channels: every shape in displacement, as the model's
        m.shapes = displacement_shapes(m.shapes, m.poles, p.rec.orders)
        m.sample_s = displacement_shapes(m.sample_s, m.poles, p.rec.orders)
    ref_channel = np.argmax(np.abs(m.shapes), axis=1)
    m.shapes = normalise_at(m.shapes, ref_channel)
    m.sample_s = normalise_at(m.sample_s, ref_channel[:, None])
    return ref_channel


def shape_rows(
    asked: int | str, poles: np.ndarray, fs: float, i: int, block_len: int, source: str, first_lag: int = 1
) -> tuple[int, np.ndarray]:
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
        raise SignalError(
            f"{source}: shape_block_rows = {asked} is too many for blocks of {block_len / fs:g} s: "
            f"each block must hold {MIN_BLOCK_LAGS:g} times the {hankel_max_lag(asked, first_lag)} lags "
            f"(at most {longest})"
        )
    return int(asked), np.ones(len(poles), dtype=bool)


def warn_about_layout(source: str, n_channels: int, fs_hz: float, fmax_hz: float | None) -> None:
    """Warn about a record that can only give a poor extraction: few channels, or a low rate and no fmax."""
    if n_channels < MIN_CHANNELS:
        warnings.warn(
            f"{source}: {n_channels} channel(s): shapes known at so few points cannot tell modes apart "
            f"(MAC), and a mode with a node there is missed; use at least {MIN_CHANNELS} (two x-y "
            "proximeter pairs)",
            TwinWarning,
            stacklevel=5,
        )
    if fmax_hz is None and fs_hz < LOW_RATE_HZ:
        warnings.warn(
            f"{source}: sampled at {fs_hz:g} Hz and no fmax given: modes are extracted up to "
            f"{DEFAULT_FMAX_FRACTION * fs_hz:g} Hz only ({DEFAULT_FMAX_FRACTION:.0%} of the rate); "
            "sample faster to see a rotor's higher modes, or give fmax to say that is the band you want",
            TwinWarning,
            stacklevel=5,
        )
