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
clipped to the model's range for the condition. The defaults (:data:`DEFAULT_VARIATION`) are those of a
peaking hydro unit; a condition without defaults stays at its reference value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from twin.fem.tables import Table

#: Days in a year, for seasons and drifts.
YEAR_DAYS = 365.25


@dataclass(frozen=True)
class Variation:
    """How one condition varies (in the condition's units; see the module's text)."""

    mean: float
    daily_amplitude: float = 0.0
    peak_hour: float = 18.0
    seasonal_amplitude: float = 0.0
    seasonal_peak_day: float = 200.0
    drift_per_year: float = 0.0
    dispatch_std: float = 0.0
    dispatch_correlation: float = 0.0
    follows: dict[str, float] = field(default_factory=dict)


#: Defaults by condition name, for the hydro unit's conditions: a peaking unit dispatched around 150 MW
#: with an evening peak; reactive power following the load; the head with the reservoir's yearly fill
#: (highest in late spring); the guide-bearing oil 0.04 degC warmer per MW of load (bearing losses) and
#: with the cooling water's season (warmest in summer).
DEFAULT_VARIATION: dict[str, dict] = {
    "power": {
        "mean": 150.0,
        "daily_amplitude": 35.0,
        "peak_hour": 18.0,
        "dispatch_std": 25.0,
        "dispatch_correlation": 0.3,
    },
    "reactive_power": {
        "mean": 25.0,
        "daily_amplitude": 15.0,
        "peak_hour": 18.0,
        "dispatch_std": 15.0,
        "dispatch_correlation": 0.3,
    },
    "head": {
        "mean": 140.0,
        "seasonal_amplitude": 5.0,
        "seasonal_peak_day": 150.0,
        "dispatch_std": 0.5,
        "dispatch_correlation": 0.95,
    },
    "oil_temperature": {
        "mean": 45.0,
        "seasonal_amplitude": 3.0,
        "seasonal_peak_day": 200.0,
        "follows": {"power": 0.04},
        "dispatch_std": 0.7,
        "dispatch_correlation": 0.6,
    },
}


def read_variations(table, operation) -> dict[str, Variation]:
    """Each declared condition's variation: the schedule's ``[operation.<condition>]`` over the defaults.

    ``table`` is the schedule's ``[operation]`` reading table; errors name the file, the table and the key.
    """
    names = operation.names
    out: dict[str, Variation] = {}
    for name in names:
        c = operation.condition(name)
        base = Variation(**{"mean": c.reference, **DEFAULT_VARIATION.get(name, {})})
        if name not in table.data:
            out[name] = base
            continue
        t = Table(table.path, f"[operation.{name}]", table._get(name, {}))
        values = {}
        for f in fields(Variation):
            if f.name == "follows":
                follows = t._get("follows", base.follows)
                if not isinstance(follows, dict):
                    raise t.error("follows", f"expected a table of slopes by condition, got {follows!r}")
                for k, v in follows.items():
                    if k not in names or k == name:
                        raise t.error("follows", f"'{k}' is not another declared condition ({', '.join(names)})")
                    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                        raise t.error("follows", f"the slope on '{k}' must be a finite number, got {v!r}")
                values["follows"] = {k: float(v) for k, v in follows.items()}
            else:
                values[f.name] = t.number(
                    f.name,
                    getattr(base, f.name),
                    nonnegative=f.name in ("dispatch_std", "daily_amplitude", "seasonal_amplitude"),
                )
        if not 0 <= values["dispatch_correlation"] < 1:
            raise t.error("dispatch_correlation", f"must be in [0, 1), got {values['dispatch_correlation']:g}")
        t.finish()
        out[name] = replace(base, **values)
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
