"""How a unit's operating conditions vary over a campaign: daily cycles, dispatch, seasons and drifts.

Each condition follows, at a record's start ``t`` [days] and hour of day ``h``::

    mean + daily_amplitude cos(2 pi (h - peak_hour) / 24)
         + seasonal_amplitude cos(2 pi (t_year - seasonal_peak_day) / 365.25)
         + drift_per_year t / 365.25
         + sum over k of follows[k] (value_k - mean_k)
         + dispatch

where ``dispatch`` is a random level from record to record, normal with standard deviation
``dispatch_std`` and correlation ``dispatch_correlation`` between successive records (an AR(1)
sequence), and ``follows`` couples a condition to others (the oil warms with the load). The value is
clipped to the model's range for the condition. A model file declares each condition's typical
variation (:class:`twin.fem.operation.Variation`, its ``[condition.variation]`` table: the hydro unit's
are those of a peaking unit), a schedule overrides it, and a condition without one stays at its
reference value.
"""

from __future__ import annotations

import math

import numpy as np

from twin.fem.operation import Variation, read_variation
from twin.fem.tables import Table

#: Days in a year, for seasons and drifts.
YEAR_DAYS = 365.25


def read_variations(table, operation) -> dict[str, Variation]:
    """Each declared condition's variation: the schedule's ``[operation.<condition>]`` over the model file's
    (``[condition.variation]``; a condition without one stays at its reference).

    ``table`` is the schedule's ``[operation]`` reading table; errors name the file, the table and the key.
    """
    names = operation.names
    out: dict[str, Variation] = {}
    for name in names:
        c = operation.condition(name)
        base = c.variation or Variation(mean=c.reference)
        if name not in table.data:
            out[name] = base
            continue
        t = Table(table.path, f"[operation.{name}]", table._get(name, {}))
        out[name] = read_variation(t, base, names, name)
    unknown = [k for k in table.data if k not in names]
    if unknown:
        raise table.error(unknown[0], f"no condition '{unknown[0]}' in the model (it declares: {', '.join(names)})")
    _order(out, table)
    return out


def _order(variations: dict[str, Variation], table=None) -> list[str]:
    """The conditions in an order where each comes after those it follows (an error on a cycle)."""
    done: list[str] = []
    pending = dict(variations)
    while pending:
        ready = [k for k, v in pending.items() if all(f in done for f in v.follows)]
        if not ready:
            names = ", ".join(sorted(pending))
            message = f"the conditions {names} follow each other in a circle"
            if table is not None:
                raise table.error(None, message)
            raise ValueError(message)
        for k in ready:
            done.append(k)
            del pending[k]
    return done


def operating_points(
    variations: dict[str, Variation], operation, days: np.ndarray, year_day0: float, seed: int
) -> np.ndarray:
    """The conditions at each record's start, ``(record, condition)`` in the operation's order.

    Parameters
    ----------
    variations : mapping of condition name to Variation
    operation : twin.fem.operation.Operation
        Gives the conditions' order and ranges (values are clipped to them).
    days : array
        Record starts [days after the first record].
    year_day0 : float
        Day of the year of the first record (0 on 1 January), for the seasons.
    seed : int
        Seed of the dispatch's random levels (one stream per condition).

    Examples
    --------
    >>> op = hydro_unit.operation
    >>> v = {k: Variation(mean=op.condition(k).reference) for k in op.names}
    >>> operating_points(v, op, np.arange(3) / 4, 0.0, seed=1)[:, 0]
    array([180., 180., 180.])
    """
    days = np.asarray(days, dtype=float)
    hours = (days % 1.0) * 24.0
    out: dict[str, np.ndarray] = {}
    for i, name in enumerate(_order(variations)):
        v = variations[name]
        value = (
            v.mean
            + v.daily_amplitude * np.cos(2 * np.pi * (hours - v.peak_hour) / 24.0)
            + v.seasonal_amplitude * np.cos(2 * np.pi * (year_day0 + days - v.seasonal_peak_day) / YEAR_DAYS)
            + v.drift_per_year * days / YEAR_DAYS
        )
        for k, slope in v.follows.items():
            value = value + slope * (out[k] - variations[k].mean)
        rng = np.random.default_rng([int(seed), operation.names.index(name)])
        value = value + _ar1(rng.standard_normal(days.size), v.dispatch_correlation) * v.dispatch_std
        c = operation.condition(name)
        out[name] = np.clip(value, c.low, c.high)
    return np.stack([out[k] for k in operation.names], axis=1) if out else np.zeros((days.size, 0))


def _ar1(noise: np.ndarray, rho: float) -> np.ndarray:
    """A stationary AR(1) sequence of unit variance with lag-one correlation ``rho``, from white ``noise``."""
    out = np.empty_like(noise)
    level = noise[0] if noise.size else 0.0
    for i, e in enumerate(noise):
        level = e if i == 0 else rho * level + math.sqrt(1.0 - rho * rho) * e
        out[i] = level
    return out
