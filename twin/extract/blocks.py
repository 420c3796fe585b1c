"""How a record is cut into the jackknife's blocks: how many, how long, and why.

Each jackknife sample is the identification without one block (or half of
them), and each block must hold the Hankel matrix's lags a few times over
(:func:`check_block_length`). Given a number of samples or blocks, the
extraction checks that; given neither, it chooses (:func:`adapted_blocks`):
:data:`twin.defaults.SAMPLES` blocks where the record holds them, else as
many as it holds, and says so.

A mode's decay does not set the number: the delete-one samples stay
calibrated in blocks far shorter than a time constant (the covariance sums
run across the block edges, so every sample keeps the whole decay but one
block's worth), while fewer blocks leave each standard error with fewer
degrees of freedom (docs/decisions/extraction-adapted-blocks.md). The decay
enters the pole test instead: in blocks shorter than
:data:`MIN_BLOCK_TIME_CONSTANTS` time constants a pole is judged on its
frequency (:func:`twin.extract.result.pole_scatter`).

Examples
--------
>>> import numpy as np
>>> adapted_blocks(1200.0, 40, np.array([-0.04 + 6j])).reason
'15 blocks of 80 s (the default number); each longer than 3 time constants of the slowest mode (0.9549 Hz, 3 x 25 s)'
>>> adapted_blocks(120.0, 9, np.array([-0.04 + 6j])).blocks
9
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from twin.defaults import SAMPLES
from twin.errors import SignalError, TwinWarning

#: Each jackknife block must be this many times longer than the largest lag.
MIN_BLOCK_LAGS = 2.0
#: Warn when a block is shorter than this many time constants of a mode (samples then too narrow); a pole in such
#: blocks is judged on its frequency alone (:func:`twin.extract.result.pole_determined`). The adapted choice makes
#: blocks at least this long where it can.
MIN_BLOCK_TIME_CONSTANTS = 3.0
#: Fewer blocks than this leave a standard error so few degrees of freedom that the extraction warns.
FEW_BLOCKS = 6


@dataclasses.dataclass(frozen=True)
class BlockPlan:
    """The blocks an extraction cuts its record into: their number, length [s] and why."""

    blocks: int
    block_s: float
    reason: str


def most_blocks(n_samples: int, lags: int) -> int:
    """The most blocks a record of ``n_samples`` time samples holds for a Hankel matrix reading ``lags`` lags.

    >>> most_blocks(2400, 40)
    30
    """
    return int(n_samples // int(MIN_BLOCK_LAGS * lags))


def check_block_length(
    source: str,
    duration_s: float,
    n_samples: int,
    n_blocks: int,
    lags: int,
    fs_hz: float,
    block_rows: int,
    first_lag: int,
) -> None:
    """Refuse ``n_blocks`` blocks too short for the Hankel matrix's lags, saying how many the record holds.

    >>> check_block_length("r.nc", 120.0, 2400, 40, 40, 20.0, 20, 1)
    Traceback (most recent call last):
    ...
    twin.errors.SignalError: r.nc: 120 s is too short for 40 blocks with 20 block rows from lag 1: each block needs 4 s; ask for fewer samples or blocks (at most 30)...
    """
    if n_samples // n_blocks >= MIN_BLOCK_LAGS * lags:
        return
    most = most_blocks(n_samples, lags)
    fix = (
        f"ask for fewer samples or blocks (at most {most}), or none: the extraction then chooses"
        if most >= 2
        else "the record is too short for a jackknife of two blocks: give a longer record, a higher fmin or fewer "
        "block rows"
    )
    raise SignalError(
        f"{source}: {duration_s:g} s is too short for {n_blocks} blocks with {block_rows} block rows "
        f"from lag {first_lag}: each block needs {MIN_BLOCK_LAGS * lags / fs_hz:g} s; {fix}"
    )


def block_count(most: int) -> int:
    """The blocks the extraction chooses for a record holding at most ``most``: :data:`twin.defaults.SAMPLES`,
    or ``most`` where the record holds fewer (at least 2, which :func:`check_block_length` then judges).

    >>> block_count(30), block_count(9)
    (15, 9)
    """
    return max(2, min(SAMPLES, int(most)))


def adapted_blocks(duration_s: float, most: int, poles: np.ndarray) -> BlockPlan:
    """The blocks for a record of ``duration_s`` [s] holding at most ``most`` blocks, and why, naming the
    slowest of the modes the full record identifies (continuous-time ``poles`` [1/s]) and how much of its
    decay a block holds.

    The number is :func:`block_count`'s.

    >>> plan = adapted_blocks(120.0, 9, np.array([-2.0 + 30j]))
    >>> plan.blocks, plan.reason
    (9, '9 blocks of 13.3 s, the most the record holds for the Hankel matrix (the default is 15); each longer than 3 time constants of the slowest mode (4.775 Hz, 3 x 0.5 s)')
    """
    n = block_count(most)
    block_s = duration_s / n
    why = (
        "(the default number)"
        if n == SAMPLES
        else f", the most the record holds for the Hankel matrix (the default is {SAMPLES})"
    )
    poles = np.asarray(poles)
    if poles.size:
        k = int(np.argmin(np.abs(poles.real)))
        tau = 1.0 / max(abs(poles[k].real), 1e-12)
        slowest = (
            f"the slowest mode ({abs(poles[k].imag) / (2 * np.pi):.4g} Hz, {MIN_BLOCK_TIME_CONSTANTS:g} x {tau:.3g} s)"
        )
        why += (
            f"; each longer than {MIN_BLOCK_TIME_CONSTANTS:g} time constants of {slowest}"
            if block_s >= MIN_BLOCK_TIME_CONSTANTS * tau
            else f"; shorter than {MIN_BLOCK_TIME_CONSTANTS:g} time constants of {slowest}: such a mode's pole is "
            "judged on its frequency"
        )
    return BlockPlan(n, block_s, f"{n} blocks of {block_s:.3g} s" + ("" if why.startswith(",") else " ") + why)


def warn_about_few_blocks(source: str, n_blocks: int, chosen: bool) -> None:
    """Warn when the standard errors rest on fewer than :data:`FEW_BLOCKS` blocks."""
    if n_blocks < FEW_BLOCKS:
        warnings.warn(
            f"{source}: the samples come from {n_blocks} blocks"
            + (", the most the record holds for the Hankel matrix" if chosen else "")
            + f": each standard error rests on {n_blocks - 1} degrees of freedom; read them as rough"
            + (
                " (a longer record, fewer block rows or a higher fmin allow more blocks)"
                if chosen
                else f" (at least {FEW_BLOCKS} samples give steadier ones)"
            ),
            TwinWarning,
            stacklevel=3,
        )
