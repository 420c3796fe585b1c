"""Read and check a signals record before identification.

Bad records are refused with a message naming the file and the channel:
missing variables, no sampling rate, a time axis that runs backwards, has a
hole or contradicts the ``sampling_rate`` attribute, NaN or inf samples, a
dead (flat) channel. A channel that looks clipped (many samples at its extreme values)
gives a :class:`~twin.errors.TwinWarning`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from twin.errors import SignalError, TwinWarning
from twin.extract.quantities import channel_quantities, derivative_orders

#: A channel whose std is below this fraction of the median channel std is dead.
DEAD_CHANNEL_RATIO = 1e-6
#: A channel with more than this fraction of its samples at its maximum or minimum is clipped.
CLIPPED_FRACTION = 1e-3
#: ... and at least this many samples: in a short record the one sample at a channel's maximum is not clipping.
CLIPPED_SAMPLES = 5
#: The ``time`` coordinate's steps may differ from their median by this fraction of a step (clock jitter,
#: times stored as float32); a missing sample is a whole step.
TIME_STEP_TOLERANCE = 0.1
#: The ``sampling_rate`` attribute and the ``time`` coordinate's mean step must agree to this fraction.
RATE_TOLERANCE = 1e-4


@dataclass(frozen=True)
class Record:
    """A checked record: zero-mean samples (time x channel) in SI (m, m/s or m/s², each channel's
    ``quantities``), sampling rate [Hz], channel names."""

    y: np.ndarray
    fs_hz: float
    channels: tuple[str, ...]
    source: str
    attrs: dict
    quantities: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.quantities:
            object.__setattr__(self, "quantities", ("displacement",) * self.y.shape[1])

    @property
    def orders(self) -> np.ndarray:
        """0, 1 or 2 per channel: displacement, velocity, acceleration (:func:`~twin.extract.quantities.derivative_orders`)."""
        return derivative_orders(self.quantities)

    @property
    def duration_s(self) -> float:
        return self.y.shape[0] / self.fs_hz


#: Units a numeric ``time`` coordinate may state (its ``units`` attr), in seconds; none stated is seconds.
TIME_UNITS = {
    "s": 1.0,
    "sec": 1.0,
    "second": 1.0,
    "seconds": 1.0,
    "ms": 1e-3,
    "millisecond": 1e-3,
    "milliseconds": 1e-3,
    "us": 1e-6,
    "µs": 1e-6,
    "microseconds": 1e-6,
    "min": 60.0,
    "minutes": 60.0,
    "h": 3600.0,
    "hours": 3600.0,
}


def seconds_per(units: str, whose: str) -> float:
    """Seconds in one ``units`` of time (:data:`TIME_UNITS`); an error saying ``whose`` units they are.

    Examples
    --------
    >>> seconds_per("ms", "the time column's")
    0.001
    """
    units = str(units).strip()
    if units not in TIME_UNITS:
        raise SignalError(f"{whose} units {units!r} are not a unit of time twin knows ({', '.join(TIME_UNITS)})")
    return TIME_UNITS[units]


def _seconds(time: xr.DataArray, source: str) -> np.ndarray:
    """The ``time`` coordinate in seconds: numbers in the unit its ``units`` attr states (seconds when it
    states none), or datetimes / durations."""
    t = np.asarray(time.values)
    if np.issubdtype(t.dtype, np.datetime64) or np.issubdtype(t.dtype, np.timedelta64):
        return (t - t[0]) / np.timedelta64(1, "s")
    scale = seconds_per(time.attrs.get("units", "s"), f"{source}: the 'time' coordinate's")
    try:
        return t.astype(float) * scale
    except (TypeError, ValueError):
        raise SignalError(
            f"{source}: the 'time' coordinate is not numbers of seconds nor datetimes (dtype {t.dtype})"
        ) from None


def time_step(ds: xr.Dataset, source: str) -> float | None:
    """The ``time`` coordinate's step [s], checked, or None without a coordinate.

    The times must be finite, increase, and be evenly spaced: every step
    within :data:`TIME_STEP_TOLERANCE` of the median step. A record whose time
    runs backwards, or has a hole, is refused rather than read as if it were
    even: its modes would be wrong (backward whirl read as forward, a hole
    spliced). The step returned is the mean over the record.
    """
    if "time" not in ds.coords or ds.sizes.get("time", 0) < 2:
        return None
    t = _seconds(ds["time"], source)
    if not np.all(np.isfinite(t)):
        first = int(np.argmax(~np.isfinite(t)))
        raise SignalError(
            f"{source}: the 'time' coordinate has {int((~np.isfinite(t)).sum())} NaN or inf "
            f"values (first at sample {first})"
        )
    dt = np.diff(t)
    if np.all(dt < 0):
        raise SignalError(
            f"{source}: the time runs backwards (from {t[0]:g} s down to {t[-1]:g} s): reverse the "
            "record (ds.isel(time=slice(None, None, -1))) or fix its time axis"
        )
    if np.any(dt <= 0):
        k = int(np.argmax(dt <= 0))
        raise SignalError(
            f"{source}: the time does not increase at sample {k + 1} ({t[k]:g} s, then "
            f"{t[k + 1]:g} s): sort the record by time or fix its time axis"
        )
    step = float(np.median(dt))
    off = np.abs(dt - step) > TIME_STEP_TOLERANCE * step
    if np.any(off):
        k = int(np.argmax(np.abs(dt - step)))
        missing = int(round(dt[k] / step)) - 1
        what = f"a step of {dt[k]:g} s" + (f" (a hole: {missing} samples missing)" if missing >= 1 else "")
        raise SignalError(
            f"{source}: the time axis is not evenly spaced: {what} after t = {t[k]:g} s, where the "
            f"record steps by {step:g} s ({int(off.sum())} uneven steps in all, tolerance "
            f"{TIME_STEP_TOLERANCE:.0%} of a step): cut the record there or resample it onto an even "
            "axis"
        )
    return float((t[-1] - t[0]) / (len(t) - 1))


def sampling_rate(ds: xr.Dataset, source: str) -> float:
    """The sampling rate [Hz]: the ``sampling_rate`` attribute, checked against the ``time`` coordinate.

    With both, they must agree within :data:`RATE_TOLERANCE`; with one, it
    is the rate. The time coordinate is checked by :func:`time_step`.
    """
    step = time_step(ds, source)
    fs = ds.attrs.get("sampling_rate")
    if fs is None and step is not None:
        return 1.0 / step
    try:
        fs = float(fs)
    except (TypeError, ValueError):
        raise SignalError(
            f"{source}: no sampling rate: set the 'sampling_rate' attribute [Hz] or an evenly "
            "spaced 'time' coordinate [s]"
        ) from None
    if not (np.isfinite(fs) and fs > 0):
        raise SignalError(f"{source}: sampling_rate must be a positive number of Hz, got {fs}")
    if step is not None and abs(fs * step - 1.0) > RATE_TOLERANCE:
        raise SignalError(
            f"{source}: the sampling_rate attribute says {fs:g} Hz but the time coordinate steps by "
            f"{step:g} s ({1 / step:g} Hz): fix the one that is wrong"
        )
    return fs


def check_record(ds: xr.Dataset, source: str = "signals", channels: Sequence[str] | None = None) -> Record:
    """Check a signals Dataset and return its zero-mean samples in SI.

    Parameters
    ----------
    ds : xarray.Dataset
        ``displacement`` over ``time`` and ``channel``, or ``signal`` with each channel's ``quantity`` and
        ``units`` (:mod:`twin.extract.quantities`, ``docs/guide/own-measurements.md``).
    source : str
        Name used in messages (usually the file name).
    channels : sequence of str, optional
        Use only these channels (e.g. to drop a dead sensor).

    Examples
    --------
    >>> y = np.random.default_rng(0).standard_normal((1000, 2))
    >>> ds = xr.Dataset({"displacement": (("time", "channel"), y)}, coords={"channel": ["A_x", "A_y"]},
    ...                 attrs={"sampling_rate": 100.0})
    >>> rec = check_record(ds)
    >>> rec.channels, rec.duration_s
    (('A_x', 'A_y'), 10.0)
    """
    variable, quantities, factors = channel_quantities(ds, source)
    da = ds[variable]
    if set(da.dims) != {"time", "channel"}:
        raise SignalError(f"{source}: '{variable}' must have dimensions (time, channel), not {da.dims}")
    names = [str(c) for c in (da["channel"].values if "channel" in da.coords else range(da.sizes["channel"]))]
    repeated = sorted({c for c in names if names.count(c) > 1})
    if repeated:
        raise SignalError(
            f"{source}: channel name(s) {', '.join(map(repr, repeated))} appear more than once: "
            "each channel needs its own name (the model's sensor it is)"
        )
    if channels is not None:
        unknown = [c for c in channels if c not in names]
        if unknown:
            raise SignalError(f"{source}: no channel {', '.join(map(repr, unknown))} (it has: {', '.join(names)})")
        pick = [names.index(c) for c in channels]
        da, quantities, factors = da.isel(channel=pick), tuple(quantities[k] for k in pick), factors[pick]
        names = list(channels)
    fs = sampling_rate(ds, source)
    y = np.asarray(da.transpose("time", "channel").values, dtype=float) * factors
    if y.shape[1] == 0 or y.shape[0] < 2:
        raise SignalError(f"{source}: the record has {y.shape[0]} samples of {y.shape[1]} channels")
    bad = ~np.isfinite(y)
    for c in np.flatnonzero(bad.any(axis=0)):
        first = int(np.argmax(bad[:, c]))
        raise SignalError(
            f"{source}: channel '{names[c]}' has {int(bad[:, c].sum())} NaN or inf samples "
            f"(first at t = {first / fs:g} s): fill the gap, cut the record or drop the channel"
        )
    std = y.std(axis=0)
    for quantity in sorted(set(quantities)):  # a displacement in m is tiny beside an acceleration in m/s²
        same = np.array([q == quantity for q in quantities])
        ref = float(np.median(std[same])) or float(std[same].max())  # most channels flat: the live one(s)
        for c in np.flatnonzero(same & (std <= DEAD_CHANNEL_RATIO * ref)):
            raise SignalError(
                f"{source}: channel '{names[c]}' is flat (std {std[c]:.3g} against {ref:.3g} for the "
                "others): a dead sensor? Leave it out (channels=... / --channels)"
            )
    for c, name in enumerate(names):
        hi, lo = y[:, c].max(), y[:, c].min()
        tol = 1e-9 * (hi - lo)
        at_hi, at_lo = np.mean(y[:, c] >= hi - tol), np.mean(y[:, c] <= lo + tol)
        if max(at_hi, at_lo) > max(CLIPPED_FRACTION, CLIPPED_SAMPLES / len(y)):
            where = (
                f"{at_hi:.2%} of its samples at its maximum {hi:.4g}"
                if at_hi >= at_lo
                else f"{at_lo:.2%} of its samples at its minimum {lo:.4g}"
            )
            warnings.warn(
                f"{source}: channel '{name}' looks clipped (saturated): {where}; the modes it sees are distorted",
                TwinWarning,
                stacklevel=3,
            )
    return Record(
        y=y - y.mean(axis=0),
        fs_hz=fs,
        channels=tuple(names),
        source=source,
        attrs=dict(ds.attrs),
        quantities=tuple(quantities),
    )
