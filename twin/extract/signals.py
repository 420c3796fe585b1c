"""Read and check a signals record before identification.

Bad records are refused with a message naming the file and the channel:
missing variables, no sampling rate, NaN or inf samples, a dead (flat)
channel. A channel that looks clipped (many samples at its extreme values)
gives a :class:`~twin.errors.TwinWarning`.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from twin.errors import SignalError, TwinWarning

#: A channel whose std is below this fraction of the median channel std is dead.
DEAD_CHANNEL_RATIO = 1e-6
#: A channel with more than this fraction of its samples at its maximum or minimum is clipped.
CLIPPED_FRACTION = 1e-3


@dataclass(frozen=True)
class Record:
    """A checked record: zero-mean samples (time x channel) [m], sampling rate [Hz], channel names."""

    y: np.ndarray
    fs_hz: float
    channels: tuple[str, ...]
    source: str
    attrs: dict

    @property
    def duration_s(self) -> float:
        return self.y.shape[0] / self.fs_hz


def sampling_rate(ds: xr.Dataset, source: str) -> float:
    """The ``sampling_rate`` attribute [Hz], or the spacing of the ``time`` coordinate."""
    fs = ds.attrs.get("sampling_rate")
    if fs is None and "time" in ds.coords and ds.sizes.get("time", 0) > 1:
        dt = np.diff(np.asarray(ds["time"].values, dtype=float))
        if np.all(dt > 0) and np.ptp(dt) <= 1e-6 * np.median(dt):
            fs = 1.0 / float(np.median(dt))
    try:
        fs = float(fs)
    except (TypeError, ValueError):
        raise SignalError(f"{source}: no sampling rate: set the 'sampling_rate' attribute [Hz] or an evenly "
                          "spaced 'time' coordinate [s]") from None  # fmt: skip
    if not (np.isfinite(fs) and fs > 0):
        raise SignalError(f"{source}: sampling_rate must be a positive number of Hz, got {fs}")
    return fs


def check_record(
    ds: xr.Dataset, source: str = "signals", channels: Sequence[str] | None = None, variable: str = "displacement"
) -> Record:
    """Check a signals Dataset and return its zero-mean samples.

    Parameters
    ----------
    ds : xarray.Dataset
        ``displacement`` over ``time`` and ``channel`` (``docs/guide/own-measurements.md``).
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
    if variable not in ds:
        raise SignalError(f"{source}: no variable '{variable}' (it has: {', '.join(map(str, ds.data_vars)) or 'none'})")
    da = ds[variable]
    if set(da.dims) != {"time", "channel"}:
        raise SignalError(f"{source}: '{variable}' must have dimensions (time, channel), not {da.dims}")
    names = [str(c) for c in (da["channel"].values if "channel" in da.coords else range(da.sizes["channel"]))]
    if channels is not None:
        unknown = [c for c in channels if c not in names]
        if unknown:
            raise SignalError(f"{source}: no channel {', '.join(map(repr, unknown))} (it has: {', '.join(names)})")
        da = da.isel(channel=[names.index(c) for c in channels])
        names = list(channels)
    fs = sampling_rate(ds, source)
    y = np.asarray(da.transpose("time", "channel").values, dtype=float)
    if y.shape[1] == 0 or y.shape[0] < 2:
        raise SignalError(f"{source}: the record has {y.shape[0]} samples of {y.shape[1]} channels")
    bad = ~np.isfinite(y)
    for c in np.flatnonzero(bad.any(axis=0)):
        first = int(np.argmax(bad[:, c]))
        raise SignalError(f"{source}: channel '{names[c]}' has {int(bad[:, c].sum())} NaN or inf samples "
                          f"(first at t = {first / fs:g} s): fill the gap, cut the record or drop the channel")  # fmt: skip
    std = y.std(axis=0)
    ref = float(np.median(std)) or float(std.max())  # most channels flat: compare with the live one(s)
    for c in np.flatnonzero(std <= DEAD_CHANNEL_RATIO * ref):
        raise SignalError(f"{source}: channel '{names[c]}' is flat (std {std[c]:.3g} against {ref:.3g} for the "
                          "others): a dead sensor? Leave it out (channels=... / --channels)")  # fmt: skip
    for c, name in enumerate(names):
        hi, lo = y[:, c].max(), y[:, c].min()
        tol = 1e-9 * (hi - lo)
        at_hi, at_lo = np.mean(y[:, c] >= hi - tol), np.mean(y[:, c] <= lo + tol)
        if max(at_hi, at_lo) > CLIPPED_FRACTION:
            where = f"{at_hi:.2%} of its samples at its maximum {hi:.4g}" if at_hi >= at_lo else \
                f"{at_lo:.2%} of its samples at its minimum {lo:.4g}"  # fmt: skip
            warnings.warn(f"{source}: channel '{name}' looks clipped (saturated): {where}; the modes it sees "
                          "are distorted", TwinWarning, stacklevel=3)  # fmt: skip
    return Record(y=y - y.mean(axis=0), fs_hz=fs, channels=tuple(names), source=source, attrs=dict(ds.attrs))
