"""The statistics of the calibration on simulated records: pooling each parameter's error ratio with the
others', and widening the interval for a variance estimated from a few records (:mod:`twin.loop.bootstrap`)."""

from __future__ import annotations

import numpy as np

#: Fewer records than this whose fit found a mode: no calibration (a :class:`TwinError`).
MIN_RECORDS = 3
#: The interval the factor is matched at (the twin reports 90% intervals).
LEVEL = 0.90


def pooled_rms(rms: np.ndarray, records: np.ndarray, members: np.ndarray) -> tuple[np.ndarray, float]:
    """Each member's RMS error shrunk towards the members' pooled RMS error (empirical Bayes).

    ``c_p²`` is a mean of ``n_p`` squared errors: if they were normal, ``log c_p²`` would scatter about
    the parameter's true value with variance ``ψ'(n_p / 2)`` (0.181 for 12 records). The variance of the
    true values across the members is what the spread of ``log c_p²`` has beyond that,
    ``τ² = max(0, var_p log c_p² - mean ψ')``; each member's ``log c_p²`` is then pulled towards the log of
    the pooled mean square by ``v_p / (τ² + v_p)`` (fully when the spread is noise alone, hardly when the
    parameters differ far more than 12 records can blur). Non-members and members without a finite
    positive value are returned as given.

    Returns the shrunk RMS errors and ``τ²`` (0 with fewer than two members).

    Examples
    --------
    >>> import numpy as np
    >>> c, tau2 = pooled_rms(np.array([0.8, 1.0, 1.2, 5.0]), np.array([12, 12, 12, 12]),
    ...                      np.array([True, True, True, False]))
    >>> c.round(3).tolist(), tau2  # three values as close as 12 records make them: pooled, sqrt(mean c²)
    ([1.013, 1.013, 1.013, 5.0], 0.0)
    """
    from scipy.special import polygamma

    c = np.asarray(rms, dtype=float).copy()
    n = np.asarray(records, dtype=float)
    k = np.asarray(members, dtype=bool) & np.isfinite(c) & (c > 0) & (n >= MIN_RECORDS)
    if k.sum() < 2:
        return c, 0.0
    y, noise = np.log(c[k] ** 2), polygamma(1, n[k] / 2)
    centre = np.log(np.sum(n[k] * c[k] ** 2) / np.sum(n[k]))
    tau2 = float(max(0.0, np.var(y, ddof=1) - np.mean(noise)))
    c[k] = np.exp((centre + tau2 / (tau2 + noise) * (y - centre)) / 2)
    return c, tau2


def predictive_widening(records: np.ndarray | int, level: float = LEVEL) -> np.ndarray:
    """``t_R / z`` at the ``level`` interval: the widening of an interval whose scale comes from ``R`` records.

    The error of the measured record is predicted from ``R`` errors of the same kind: with their mean square
    as its variance, its ``level`` interval is Student's t with ``R`` degrees of freedom, not the normal's.
    NaN below :data:`MIN_RECORDS`.

    Examples
    --------
    >>> predictive_widening(np.array([12, 20, 2])).round(3)
    array([1.084, 1.049,   nan])
    """
    from scipy.stats import norm, t

    r = np.asarray(records, dtype=float)
    q = (1 + level) / 2
    with np.errstate(invalid="ignore"):
        return np.where(r >= MIN_RECORDS, t.ppf(q, np.maximum(r, 1)) / norm.ppf(q), np.nan)
