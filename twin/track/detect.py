"""Change detection on what the operating conditions do not explain: a multivariate EWMA control chart.

After compensation (:mod:`twin.track.physics`) each record leaves a residual per tracked pole part, with
the standard error the extraction gives it (the jackknife's; it varies three- to fivefold from record to
record with the operating point). Each residual is standardised by its own standard error times a factor
per pole part learned over the baseline (near 1 where the model and the standard errors are right), and
their correlation is estimated over the baseline, shrunk towards the identity for the few records a
baseline has. The chart smooths the standardised residuals,
``w_r = lam z_r + (1 - lam) w_{r-1}`` (a record without a mode adds nothing for it), and alarms when
``T2_r = w_r' S_w^-1 w_r`` exceeds the chi-square quantile of the false-alarm probability per record
(:func:`threshold`). ``S_w`` is the smoothed residuals' covariance: ``lam / (2 - lam) R`` from the records'
own scatter, plus what the baseline itself leaves uncertain, which every record after it shares and which
smoothing does not average away: the centre (the Hodges-Lehmann estimate over ``n`` records, variance
``pi / (3 n)`` of one record's, :func:`level_variance`) and, where the caller gives them, the learned
laws' slopes through each record's sensitivity to them (``MEWMA.add``'s ``g``). Without these the limit
holds for a chart whose baseline is known exactly; with a baseline of a few weeks the centre's error alone
is a sixth of the smoothed scatter (``lam = 0.2``, 56 records), the slopes' grows as the operating point
leaves the baseline's, and the chart alarms on them. In control, ``T2_r`` is then
chi-square distributed record by record, and successive records are correlated, so the false-alarm rate
is at most the one stated. A small persistent shift builds up over a few records; a large one alarms at
once.

The exponential smoothing caps what a small step can show: with ``lam = 0.2`` the smoothed residual holds
about nine records' worth of it. Beside the chart, :class:`StepGLR` weighs a step along each change the
model can name, from onsets 1, 2, 4, ... 32 records back: its evidence grows with the records after the step
(until the baseline's own errors cap it), with the candidate's one or two degrees of freedom instead of one
per tracked mode. The two share the false-alarm rate (:data:`DIRECTED_SHARE`), the step statistics a
Bonferroni share each per candidate and onset.

The onset of a change is the start of the window whose mean residual is most unlike zero (the generalised
likelihood ratio of a mean shift, :func:`onset`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from twin.defaults import FALSE_ALARMS_PER_YEAR  # noqa: F401 (shared with the CLI)

#: Smoothing of the chart: the weight of the newest record.
LAMBDA = 0.2


@dataclass(frozen=True)
class Baseline:
    """What the chart learned over the baseline: each residual's centre, the factor on its standard errors,
    and the residuals' correlation."""

    center: np.ndarray
    scale: np.ndarray
    correlation: np.ndarray
    n_records: int


def hodges_lehmann(values: np.ndarray) -> np.ndarray:
    """Each column's Hodges-Lehmann centre: the median of its pairwise means (itself included), NaNs left out.

    As robust as one needs over a baseline (a quarter of the records may be wild) and nearly as efficient
    as the mean for normal residuals: its variance is ``pi / (3 n)`` of one record's, against
    ``pi / (2 n)`` for the median.

    Examples
    --------
    >>> hodges_lehmann(np.array([[1.0, 0.0], [2.0, np.nan], [3.0, 4.0], [40.0, 8.0]])).tolist()
    [2.75, 4.0]
    """
    x = np.atleast_2d(np.asarray(values, dtype=float))
    out = np.full(x.shape[1], np.nan)
    for j in range(x.shape[1]):
        v = x[np.isfinite(x[:, j]), j]
        if v.size:
            i, k = np.triu_indices(v.size)
            out[j] = np.median(0.5 * (v[i] + v[k]))
    return out


def learn_baseline(residuals: np.ndarray, se: np.ndarray) -> Baseline:
    """Centre (:func:`hodges_lehmann`) and standard-error factor per residual, and a shrunk correlation,
    over baseline records.

    ``residuals`` and their standard errors ``se`` are ``(n, p)``, NaN where a mode was not found. The
    factor is the RMS of ``(r - centre) / se``; the correlation is shrunk towards the identity by
    ``p / (n + p)`` (a baseline of a few weeks has few records for many pole parts).

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> se = rng.uniform(1.0, 3.0, size=(400, 2))
    >>> b = learn_baseline(rng.normal(size=(400, 2)) * se * [1.0, 2.0], se)
    >>> np.round(b.scale, 1).tolist()
    [1.0, 2.0]
    """
    r = np.asarray(residuals, dtype=float)
    n, p = r.shape
    center = hodges_lehmann(r)
    u = (r - center) / se
    count = np.isfinite(u).sum(axis=0)
    scale = np.sqrt(np.nansum(u**2, axis=0) / np.maximum(count - 1, 1))
    scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
    z = np.nan_to_num(u / scale)
    corr = np.corrcoef(z, rowvar=False) if n > 2 else np.eye(p)
    corr = np.nan_to_num(np.atleast_2d(corr))
    np.fill_diagonal(corr, 1.0)
    shrink = p / (n + p)
    return Baseline(center, scale, (1 - shrink) * corr + shrink * np.eye(p), n)


def threshold(
    n_outputs: int,
    n_baseline: int,
    records_per_year: float,
    false_alarms_per_year: float = FALSE_ALARMS_PER_YEAR,
    estimated: int | None = None,
) -> float:
    """The chart's limit for a false-alarm probability per record of ``false_alarms_per_year / records_per_year``.

    The scales and correlation come from ``n_baseline`` records, not from an infinite past, so the limit
    is the Phase II limit of Hotelling's statistic with estimated parameters,
    ``k (n + 1)(n - 1) / (n (n - p)) F(k, n - p)``, which tends to the chi-square quantile of ``k`` degrees
    of freedom as the baseline grows (measured: with the chi-square limit and 24 baseline records the
    statistic ran at twice its nominal mean). ``k`` is ``n_outputs``, the statistic's degrees of freedom;
    ``p`` is ``estimated``, the residuals whose correlation the baseline estimated (``n_outputs`` when
    None): a statistic along ``k`` directions of ``p`` residuals (:class:`StepGLR`) keeps ``k`` degrees of
    freedom and pays for the ``p``-dimensional estimate.

    Examples
    --------
    >>> round(threshold(9, 56, 4 * 365.25), 1), round(threshold(9, 10_000, 4 * 365.25), 1)
    (55.6, 34.7)
    >>> round(threshold(2, 56, 4 * 365.25, estimated=9), 1)
    28.2
    """
    k, n = int(n_outputs), int(n_baseline)
    p = k if estimated is None else int(estimated)
    if n <= p + 1:
        raise ValueError(f"a chart of {p} residuals needs more than {p + 1} baseline records, got {n}")
    alpha = false_alarms_per_year / records_per_year
    return float(k * (n + 1) * (n - 1) / (n * (n - p)) * stats.f.isf(alpha, k, n - p))


def standardised(residuals: np.ndarray, se: np.ndarray, baseline: Baseline) -> np.ndarray:
    """Residuals in units of their standard errors times the baseline's factor, 0 where a mode was not found."""
    return np.nan_to_num((np.asarray(residuals, dtype=float) - baseline.center) / (baseline.scale * se))


def pooled(residuals: np.ndarray, se: np.ndarray, baseline: Baseline) -> tuple[np.ndarray, np.ndarray]:
    """The weighted mean of records' residuals (less the baseline's centre) and its covariance.

    Each pole part's records are weighted by their inverse variance ``(factor * se)^-2``; the parts keep
    the baseline's correlation. NaN where no record has the mode.
    """
    w = np.where(np.isfinite(residuals), 1.0 / (baseline.scale * se) ** 2, 0.0)
    total = w.sum(axis=0)
    mean = np.nansum(w * (residuals - baseline.center), axis=0) / np.where(total > 0, total, np.nan)
    std = 1.0 / np.sqrt(np.where(total > 0, total, np.nan))
    d = np.nan_to_num(std, nan=1.0)
    return mean, np.outer(d, d) * baseline.correlation


def level_variance(n_records: int) -> float:
    """Variance of a baseline's centre (:func:`hodges_lehmann` over ``n_records`` records) in units of one
    record's, for normal residuals: ``pi / (3 n)``.

    Examples
    --------
    >>> round(level_variance(56), 4)
    0.0187
    """
    return float(np.pi / (3 * max(int(n_records), 1)))


def record_covariance(se: np.ndarray, baseline: Baseline) -> np.ndarray:
    """One record's residual covariance: its standard errors times the factors, with the baseline's correlation."""
    d = np.nan_to_num(baseline.scale * se, nan=1.0)
    return np.outer(d, d) * baseline.correlation


class MEWMA:
    """The chart's recursion record by record: ``add`` smooths one standardised residual and returns ``T2``;
    ``reset`` starts again from zero (after an alarm).

    ``uncertain`` is the covariance of parameters the baseline learned (the laws' slopes) whose error
    moves every later record's residual alike; ``add``'s ``g`` is the record's standardised residual's
    sensitivity to them (``(p, K)``, zero rows where a mode was not found). Their error, smoothed as the
    residuals are, is added to the statistic's covariance, beside the centre's (:func:`level_variance`).

    Examples
    --------
    >>> chart = MEWMA(Baseline(np.zeros(2), np.ones(2), np.eye(2), 100), lam=0.5)
    >>> round(chart.add(np.zeros(2)), 2), round(chart.add(np.array([3.0, 0.0])), 2)
    (0.0, 6.54)
    """

    def __init__(self, baseline: Baseline, lam: float = LAMBDA, uncertain: np.ndarray | None = None) -> None:
        self.lam = lam
        self.cov = (lam / (2.0 - lam) + level_variance(baseline.n_records)) * baseline.correlation
        self.inverse = np.linalg.inv(self.cov)
        self.uncertain = None if uncertain is None else np.atleast_2d(np.asarray(uncertain, dtype=float))
        self.w = np.zeros(len(baseline.correlation))
        self.g: np.ndarray | None = None

    def add(self, z: np.ndarray, g: np.ndarray | None = None) -> float:
        self.w = self.lam * z + (1.0 - self.lam) * self.w
        if self.uncertain is None or g is None:
            return float(self.w @ self.inverse @ self.w)
        self.g = self.lam * g + (1.0 - self.lam) * (0.0 if self.g is None else self.g)
        total = self.cov + self.g @ self.uncertain @ self.g.T
        return float(self.w @ np.linalg.solve(total, self.w))

    def reset(self) -> None:
        self.w = np.zeros_like(self.w)
        self.g = None


def mewma(z: np.ndarray, baseline: Baseline, lam: float = LAMBDA) -> np.ndarray:
    """The chart's statistic ``T2`` for each record (``z`` standardised, ``(n, p)``), from zero, with the
    baseline centre's uncertainty (:class:`MEWMA` without slopes).

    Examples
    --------
    >>> b = Baseline(np.zeros(2), np.ones(2), np.eye(2), 100)
    >>> np.round(mewma(np.array([[0.0, 0.0], [3.0, 0.0]]), b, lam=0.5), 2)
    array([0.  , 6.54])
    """
    chart = MEWMA(baseline, lam)
    return np.array([chart.add(zi) for zi in z])


def onset(z: np.ndarray, baseline: Baseline) -> int:
    """Index (into ``z``) of the most likely start of a mean shift that lasts to the last record.

    For each start ``k`` the likelihood ratio of a shift is ``n_k m_k' R^-1 m_k`` with ``m_k`` the mean of
    ``z[k:]`` and ``n_k`` its records; the start with the largest ratio wins.

    Examples
    --------
    >>> z = np.r_[np.zeros(20), np.full(6, 3.0)][:, None]
    >>> onset(z, Baseline(np.zeros(1), np.ones(1), np.eye(1), 100))
    20
    """
    inv = np.linalg.inv(baseline.correlation)
    best, where = -np.inf, 0
    for k in range(len(z)):
        m = z[k:].mean(axis=0)
        g = (len(z) - k) * m @ inv @ m
        if g > best:
            best, where = g, k
    return where


#: The share of the false-alarm rate given to the step statistics along the candidate changes (all of them
#: together, :class:`StepGLR`); the omnibus chart (:class:`MEWMA`) has the rest.
DIRECTED_SHARE = 0.5
#: The onsets a step is sought at (:class:`StepGLR`), in records back from the latest: a doubling grid, which
#: loses little of the ratio at any onset between them and keeps the limit's share per onset large.
ONSETS = (1, 2, 4, 8, 16, 32)


class StepGLR:
    """The generalised likelihood ratio of a step along each candidate change, from an onset :data:`ONSETS`
    records back: a statistic for small steps, which the exponential smoothing of :class:`MEWMA` caps at a
    few records' worth of evidence.

    Each record's standardised residual ``z_i`` (covariance ``R``, the baseline's correlation) would move by
    ``a_i θ`` under a change ``θ`` of a candidate, ``a_i = diag(weight_i) J`` with ``J`` the residuals'
    sensitivity to its ``k`` parameters (``directions``, ``(p, k)`` each). For the records from onset ``s``
    on, the score ``b = Σ a_i' R^-1 z_i`` has in control the covariance ``V = Σ a_i' R^-1 a_i`` plus what
    every record shares: the baseline centre's error (``level`` times ``R``, :func:`level_variance`) through
    ``A = Σ a_i`` and the laws' slopes (covariance ``uncertain``) through each record's sensitivity ``g_i``
    to them. ``b' V^-1 b`` is then chi-square with ``k`` degrees of freedom, and grows with the records
    after a step (until the shared errors cap it) where the MEWMA's stays.

    Examples
    --------
    >>> glr = StepGLR(np.eye(2), [np.array([[1.0], [0.0]])], level=0.0)
    >>> [round(float(glr.add(np.array([1.0, 5.0]), np.ones(2))[0]), 1) for _ in range(5)]
    [1.0, 2.0, 2.0, 4.0, 4.0]
    """

    def __init__(
        self,
        correlation: np.ndarray,
        directions: list[np.ndarray],
        level: float,
        uncertain: np.ndarray | None = None,
        onsets: tuple[int, ...] = ONSETS,
    ) -> None:
        self.inverse = np.linalg.inv(correlation)
        self.directions = [np.asarray(d, dtype=float).reshape(len(correlation), -1) for d in directions]
        self.level, self.onsets = float(level), tuple(sorted(int(k) for k in onsets))
        self.uncertain = None if uncertain is None else np.atleast_2d(np.asarray(uncertain, dtype=float))
        self.reset()

    def reset(self) -> None:
        """Forget the records so far (after an alarm)."""
        self._records: list[list[tuple]] = []

    def add(self, z: np.ndarray, weight: np.ndarray, g: np.ndarray | None = None) -> np.ndarray:
        """One record (standardised residual ``z``, its standardisation ``weight``, zero where a mode was not
        found, and its sensitivity ``g`` to the laws' slopes): the largest ratio over the onsets, per
        candidate."""
        z, weight = np.asarray(z, float), np.asarray(weight, float)
        terms = []  # this record's share of each candidate's sums, kept for the later records' onsets
        for J in self.directions:
            a = weight[:, None] * J
            ra = self.inverse @ a
            terms.append((ra.T @ z, a.T @ ra, a, None if g is None else ra.T @ g))
        self._records = [*self._records, terms][-self.onsets[-1] :]
        out = np.zeros(len(self.directions))
        for c in range(len(self.directions)):
            k = self.directions[c].shape[1]
            b, V, A = np.zeros(k), np.zeros((k, k)), np.zeros_like(self.directions[c])
            B = None if self.uncertain is None else np.zeros((k, len(self.uncertain)))
            best = 0.0
            for back, record in enumerate(reversed(self._records), start=1):  # from the latest record back
                rz, ra_a, a, rg = record[c]
                b, V, A = b + rz, V + ra_a, A + a
                if B is not None and rg is not None:
                    B = B + rg
                if back not in self.onsets:
                    continue
                total = V + self.level * (A.T @ self.inverse @ A)
                if B is not None:
                    total = total + B @ self.uncertain @ B.T
                best = max(best, float(b @ np.linalg.pinv(total, rcond=1e-10, hermitian=True) @ b))
            out[c] = best
        return out
