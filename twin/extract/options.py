"""The extraction's options: one frozen value, checked once, whatever asks for an extraction.

:class:`ExtractOptions` holds every setting of :func:`twin.extract.extract` (what each does is said
there). It is checked when it is made, before any record is read: a bad value fails at once with
the option's name, from Python, the command line or a tracker's settings. What needs the record
(the band against its Nyquist frequency, blocks too short for its lags) is checked by the extraction.
Its :meth:`~ExtractOptions.key` (the options that differ from the defaults) is what a cache of
extracted modes records, so the cache answers only for the options it was made with.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from twin.defaults import ALGORITHMS, MAX_ORDER, ORDERS_PER_MODE, SAMPLES
from twin.errors import SignalError
from twin.extract.samples import deleted_blocks
from twin.extract.stabilisation import Criteria

#: What the model-order spread is added to (``order_spread``).
ORDER_SPREADS = ("shapes", "all", "none")
#: ``order_spread`` by default, per algorithm: pLSCF's poles scatter beyond their jackknife spread
#: (docs/decisions/extraction-plscf.md), SSI's jackknife is what the loop is calibrated to.
ORDER_SPREAD_OF = {"ssi": "shapes", "plscf": "all"}
#: Blocks each jackknife sample leaves out: 1 (delete-one); None deletes half (honest spread;
#: docs/decisions/extraction-jackknife.md).
DELETE_BLOCKS: int | None = 1


@dataclass(frozen=True)
class ExtractOptions:
    """Every setting of :func:`twin.extract.extract` (its parameters say what each does), checked once.

    Examples
    --------
    >>> from twin.extract import ExtractOptions
    >>> ExtractOptions(samples=20, fmax_hz=8.0).key()
    '{"fmax_hz": 8.0, "samples": 20}'
    >>> ExtractOptions(order_spread=True).order_spread, ExtractOptions().order_spread
    ('all', 'shapes')
    >>> ExtractOptions(algorithm="plscf").order_spread
    'all'
    >>> ExtractOptions(max_order=1)
    Traceback (most recent call last):
    twin.errors.SignalError: max_order must be at least 2 (one mode), got 1
    """

    samples: int | None = None
    fmax_hz: float | None = None
    fmin_hz: float = 0.0
    block_rows: int | None = None
    shape_block_rows: int | str = 0
    first_lag: int | None = None
    max_order: int = MAX_ORDER
    channels: tuple[str, ...] | None = None
    criteria: Criteria = field(default_factory=Criteria)
    delete_blocks: int | None = DELETE_BLOCKS
    order_spread: str | None = None
    remove_harmonics: bool = True
    blocks: int | None = None
    orders_per_mode: int | None = ORDERS_PER_MODE
    differenced_above_hz: float | None = None
    shape_samples: int | None = None
    algorithm: str = ALGORITHMS[0]

    def __post_init__(self) -> None:
        if self.algorithm not in ALGORITHMS:
            raise SignalError(f"algorithm must be one of {', '.join(ALGORITHMS)}, got {self.algorithm!r}")
        spread = {True: "all", False: "none", None: ORDER_SPREAD_OF[self.algorithm]}.get(
            self.order_spread,  # type: ignore[call-overload]
            self.order_spread,
        )
        if spread not in ORDER_SPREADS:
            raise SignalError(f"order_spread must be one of {', '.join(ORDER_SPREADS)}, got {self.order_spread!r}")
        object.__setattr__(self, "order_spread", spread)
        if self.channels is not None:
            if isinstance(self.channels, str) or not isinstance(self.channels, Sequence):
                raise SignalError(f"channels must be a list of channel names, got {self.channels!r}")
            object.__setattr__(self, "channels", tuple(str(c) for c in self.channels))
        if self.criteria is None:
            object.__setattr__(self, "criteria", Criteria())
        if not (whole_at_least_one(self.max_order) and self.max_order >= 2):
            raise SignalError(f"max_order must be at least 2 (one mode), got {self.max_order}")
        if self.samples is not None and not (whole_at_least_one(self.samples) and self.samples >= 2):
            raise SignalError(f"samples must be at least 2 (the spread needs two), got {self.samples}")
        if self.blocks is not None and not whole_at_least_one(self.blocks):
            raise SignalError(f"blocks must be a whole number of at least 1, got {self.blocks!r}")
        if self.block_rows is not None and not whole_at_least_one(self.block_rows):
            raise SignalError(f"block_rows must be a whole number of at least 1, got {self.block_rows!r}")
        if self.first_lag is not None and not whole_at_least_one(self.first_lag):
            raise SignalError(
                f"first_lag must be a whole number of samples, at least 1 (lag 0 holds the sensor "
                f"noise), got {self.first_lag!r}"
            )
        if self.orders_per_mode is not None and self.orders_per_mode < 1:
            raise SignalError(
                f"orders_per_mode must be at least 1 (None, or 0 from the command line: all), "
                f"got {self.orders_per_mode}"
            )
        rows = self.shape_block_rows
        if rows != "auto" and (
            isinstance(rows, (str, bool)) or not as_float(rows) >= 0 or not float(rows).is_integer()
        ):
            raise SignalError(
                f"shape_block_rows must be 'auto' or at least 0 (0: the shapes from the poles' pass), got {rows!r}"
            )
        if not self.chosen:  # the jackknife's plan needs no record when the blocks are given
            jackknife_plan(self.n_blocks, self.n_samples, self)

    @property
    def chosen(self) -> bool:
        """Whether the extraction chooses the blocks from the record (neither ``samples`` nor ``blocks`` given)."""
        return self.samples is None and self.blocks is None

    @property
    def n_blocks(self) -> int:
        """The blocks asked for (``blocks``, else ``samples``; the default's before the record chooses them)."""
        return SAMPLES if self.chosen else int(self.blocks if self.blocks is not None else self.samples)  # type: ignore[arg-type]

    @property
    def n_samples(self) -> int:
        """The samples asked for (``samples``, else one per block)."""
        return self.n_blocks if self.samples is None else int(self.samples)

    def settings(self) -> dict[str, Any]:
        """Every option as a JSON-ready dict."""
        out = dataclasses.asdict(self)
        out["channels"] = None if self.channels is None else list(self.channels)
        return out

    def key(self) -> str:
        """The options that differ from the defaults, as sorted JSON: ``"{}"`` for the defaults."""
        default = ExtractOptions().settings()
        return json.dumps({k: v for k, v in self.settings().items() if v != default[k]}, sort_keys=True, default=repr)

    @classmethod
    def of(cls, options: ExtractOptions | Mapping[str, Any] | None = None, **fields: Any) -> ExtractOptions:
        """Options from an instance, a mapping of fields or none, with ``fields`` over them; an unknown field is
        refused by name, with the fields there are.

        Examples
        --------
        >>> ExtractOptions.of({"samples": 10}, fmax_hz=20.0).key()
        '{"fmax_hz": 20.0, "samples": 10}'
        >>> ExtractOptions.of(colour=1)
        Traceback (most recent call last):
        twin.errors.SignalError: the extraction has no option colour (its options: algorithm, block_rows, blocks, channels, criteria, delete_blocks, differenced_above_hz, first_lag, fmax_hz, fmin_hz, max_order, order_spread, orders_per_mode, remove_harmonics, samples, shape_block_rows, shape_samples)
        """
        if isinstance(options, cls):
            return dataclasses.replace(options, **fields) if fields else options
        given = {**dict(options or {}), **fields}
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(given) - known)
        if unknown:
            raise SignalError(
                f"the extraction has no option {', '.join(unknown)} (its options: {', '.join(sorted(known))})"
            )
        if isinstance(given.get("criteria"), Mapping):
            given["criteria"] = Criteria(**given["criteria"])
        return cls(**given)


def jackknife_plan(n_blocks: int, samples: int, options: ExtractOptions) -> tuple[int, int]:
    """The blocks each sample deletes, and how many times each pole sample is used beside ``shape_samples``
    delete-half shape samples (1: none asked, or as many as the poles': the shapes come with the poles, as a
    modes file's settings record it). With blocks the extraction chose, ``shape_samples`` is taken to the
    nearest multiple (at least two) of the samples."""
    shape_samples = options.shape_samples
    try:
        n_deleted = len(deleted_blocks(n_blocks, options.delete_blocks, n_samples=samples)[0])
    except ValueError as exc:
        raise SignalError(f"delete_blocks: {exc}") from None
    if shape_samples is None or as_float(shape_samples) in (0, samples):
        return n_deleted, 1
    if options.chosen and whole_at_least_one(shape_samples):
        shape_samples = samples * max(2, round(int(shape_samples) / samples))
    if not whole_at_least_one(shape_samples) or int(shape_samples) % samples or int(shape_samples) <= samples:
        raise SignalError(
            f"shape_samples must be a whole multiple of samples = {samples} (e.g. {4 * samples}; "
            f"{samples} or none: the shapes come with the poles), got {shape_samples!r}"
        )
    if n_blocks < 4:
        raise SignalError(
            f"shape_samples draws random halves of the blocks: it needs at least 4 blocks, got {n_blocks}"
        )
    if options.differenced_above_hz is not None or options.shape_block_rows != 0:
        raise SignalError(
            "shape_samples is not available with differenced_above_hz or shape_block_rows: those "
            "passes redraw the samples of the modes they read"
        )
    return n_deleted, int(shape_samples) // samples


def as_float(value: object) -> float:
    """``value`` as a float, NaN when it is none (a string, None or an array)."""
    if isinstance(value, (str, bool)):
        return float("nan")
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return float("nan")


def whole_at_least_one(value: object) -> bool:
    """Whether ``value`` is a whole number >= 1 (``3`` or ``3.0``; not ``2.5``, ``0`` or ``"3"``)."""
    number = as_float(value)  # NaN for a non-number, which is no whole number
    return number.is_integer() and number >= 1
