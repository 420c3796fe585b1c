"""The evidence of a hypothesis: one formula for the Laplace and the linear-Gaussian approximations.

A hypothesis explains data ``y`` (in measurement sigmas: whitened) by parameters ``θ = μ + s u`` with
the prior ``u ~ N(0, I)``, possibly truncated to physical bounds. With ``r(u)`` the residuals, ``u*``
the posterior mode and ``H = JᵀJ + I`` the Gauss-Newton Hessian of ``½|r|² + ½|u|²`` there,
Laplace's approximation of the log evidence is

    ln Z = −½|r(u*)|² − ½|u*|² − ½ ln det H − Σ_k ln P_k,

``P_k`` the prior mass inside parameter ``k``'s bounds (:func:`log_evidence`). The hypothesis of no
change has ``ln Z = −½|r|²``; differences of ``ln Z`` are log Bayes factors.

For a model linear in the parameters and no bounds, ``r(u) = y − Ĵu``, the approximation is exact:
``u* = H⁻¹Ĵᵀy`` and ``ln B = ½ yᵀĴH⁻¹Ĵᵀy − ½ ln det H`` against no change, which is
``ln N(y; 0, C + J D Jᵀ) − ln N(y; 0, C)`` for the data's covariance ``C`` and ``D = diag(s²)``
(:func:`linear_fit`). With bounds, the prior truncated to them, the evidence is still exact: the
unbounded one times the posterior's mass inside the bounds over the prior's (:func:`box_mass`), so a
change whose fit needs the wrong sign (a magnetic pull that stiffens) loses the evidence its fit
would have had. The nonlinear fit of a hypothesis to measured poles (:func:`twin.update.laplace.fit`),
the scan of local changes (:mod:`twin.loop.locate`) and the tracker's naming of a change
(:mod:`twin.track.explain`) all weigh their hypotheses with these two functions.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.stats


def log_evidence(r: np.ndarray, u: np.ndarray, hessian: np.ndarray, log_mass: float = 0.0) -> float:
    """Laplace's ``ln Z`` at a posterior mode: residuals ``r`` [sigmas] and prior coordinates ``u`` there,
    ``hessian = JᵀJ + I``, and ``log_mass = Σ ln P_k`` the log prior mass inside the bounds.

    Examples
    --------
    >>> round(log_evidence(np.array([1.0, 1.0]), np.array([1.0]), np.array([[4.0]])), 4)
    -2.1931
    """
    return float(-0.5 * (r @ r + u @ u) - 0.5 * np.linalg.slogdet(hessian)[1] - log_mass)


@dataclass(frozen=True)
class LinearFit:
    """The exact posterior of a linear-Gaussian hypothesis and its evidence against no change.

    Attributes
    ----------
    values : (k,) float
        Posterior mean of the parameters [their units].
    covariance : (k, k) float
        Posterior covariance.
    chi2 : float
        The data's χ² left at the mean (in the data's covariance).
    log_bayes_factor : float
        ``ln Z`` of the hypothesis less that of no change.
    """

    values: np.ndarray
    covariance: np.ndarray
    chi2: float
    log_bayes_factor: float


#: Seed of the quasi-Monte Carlo integration of a posterior's mass inside several finite bounds: the same
#: data give the same evidence.
MASS_SEED = 0


def box_mass(mean: np.ndarray, cov: np.ndarray, low: np.ndarray, high: np.ndarray) -> float:
    """``ln P(low <= θ <= high)`` for ``θ ~ N(mean, cov)``; infinite ends allowed.

    Only the parameters with a finite end take part (the mass of a Gaussian's marginal); one such
    parameter is integrated exactly, several by scipy's quasi-Monte Carlo (a fixed seed).

    Examples
    --------
    >>> round(float(np.exp(box_mass(np.zeros(2), np.eye(2), np.array([0.0, -np.inf]), np.array([np.inf, np.inf])))), 6)
    0.5
    """
    mean, cov = np.asarray(mean, float), np.atleast_2d(np.asarray(cov, float))
    low, high = np.asarray(low, float), np.asarray(high, float)
    sd = np.sqrt(np.diag(cov))
    # ends further than 40 standard deviations hold no mass that double precision sees
    active = (np.isfinite(low) & (low > mean - 40 * sd)) | (np.isfinite(high) & (high < mean + 40 * sd))
    if not active.any():
        return 0.0
    i = np.flatnonzero(active)
    if i.size == 1:
        k = i[0]
        return _log_interval((low[k] - mean[k]) / sd[k], (high[k] - mean[k]) / sd[k])
    dist = scipy.stats.multivariate_normal(mean[i], cov[np.ix_(i, i)], allow_singular=True)
    p = dist.cdf(high[i], lower_limit=low[i], rng=np.random.default_rng(MASS_SEED))
    return float(np.log(max(p, 1e-300)))


def _log_interval(a: float, b: float) -> float:
    """``ln(Φ(b) - Φ(a))`` for the standard normal, accurate far in either tail (where the difference of the
    two probabilities is lost to rounding: an interval below a posterior 40 standard deviations away).

    Examples
    --------
    >>> round(_log_interval(-np.inf, 0.0), 6), round(_log_interval(38.0, np.inf), 2), round(_log_interval(-40.0, -39.0), 2)
    (-0.693147, -726.56, -765.08)
    """
    if a > 0:  # the upper tail: survival functions
        upper = scipy.stats.norm.logsf(a)
        return float(upper if b == np.inf else upper + np.log1p(-np.exp(scipy.stats.norm.logsf(b) - upper)))
    if b < 0:  # the lower tail, alike
        lower = scipy.stats.norm.logcdf(b)
        return float(lower if a == -np.inf else lower + np.log1p(-np.exp(scipy.stats.norm.logcdf(a) - lower)))
    return float(np.log(scipy.stats.norm.cdf(b) - scipy.stats.norm.cdf(a)))


def truncation(values: np.ndarray, covariance: np.ndarray, scale: np.ndarray, bounds: np.ndarray) -> float:
    """What truncating the prior ``N(0, diag(scale²))`` to ``bounds`` (``(k, 2)``) adds to a log evidence: the
    posterior's (``N(values, covariance)``) log mass inside them less the prior's (:func:`box_mass`)."""
    low, high = np.asarray(bounds, float).T
    s = np.asarray(scale, float)
    return box_mass(values, covariance, low, high) - box_mass(np.zeros_like(s), np.diag(s**2), low, high)


def linear_fit(
    y: np.ndarray,
    jacobian: np.ndarray,
    scale: np.ndarray,
    cov: np.ndarray | None = None,
    bounds: np.ndarray | None = None,
) -> LinearFit:
    """The hypothesis ``y = J θ + e``, ``e ~ N(0, cov)``, ``θ ~ N(0, diag(scale²))``, weighed exactly.

    Parameters
    ----------
    y : (n,) float
        The data the hypothesis is to explain (residuals of no change).
    jacobian : (n, k) float
        ``∂y/∂θ`` per unit of each parameter.
    scale : (k,) float
        Prior std of each parameter (its plausible scale).
    cov : (n, n) float, optional
        The data's covariance (identity when None: ``y`` in sigmas already).
    bounds : (k, 2) float, optional
        Physical bounds of each parameter (low, high; infinite for none): the prior is truncated to them.
        The evidence is the posterior's mass inside them over the prior's times the unbounded evidence;
        ``values`` and ``covariance`` stay the unbounded posterior's, with the values put on a bound they
        cross.

    Examples
    --------
    >>> f = linear_fit(np.array([2.0, 0.0]), np.array([[1.0], [0.0]]), np.array([10.0]))
    >>> round(float(f.values[0]), 3), round(f.chi2, 4), round(f.log_bayes_factor, 3)
    (1.98, 0.0004, -0.327)
    """
    y, J = np.asarray(y, float), np.asarray(jacobian, float) * np.asarray(scale, float)[None, :]
    if cov is not None:
        factor = scipy.linalg.cho_factor(cov, lower=True)[0]
        y = scipy.linalg.solve_triangular(factor, y, lower=True)
        J = scipy.linalg.solve_triangular(factor, J, lower=True)
    H = J.T @ J + np.eye(J.shape[1])
    u = np.linalg.solve(H, J.T @ y)
    e = y - J @ u
    s = np.asarray(scale, float)
    values, post = s * u, np.linalg.inv(H) * np.outer(s, s)
    log_b = log_evidence(e, u, H) + 0.5 * float(y @ y)
    if bounds is not None:
        log_b += truncation(values, post, s, bounds)
        values = np.clip(values, *np.asarray(bounds, float).T)
    return LinearFit(values, post, float(e @ e), log_b)


def simplest(best: str, evidence: Mapping[str, float], margin: float) -> str:
    """The simplest form of the change ``best`` that the data allow: an effect ``best`` holds as a special case
    (:func:`twin.fem.effects.holds`) takes its place unless ``best``'s log evidence exceeds the simpler form's
    by more than ``margin``. ``evidence`` maps labels to log evidence (or log Bayes factors against one model).

    A richer form fits at least as well as the form it holds; it is named only when the data pay for its
    extra parameters, so that an equal change in x and y is not named as an anisotropic one.

    Examples
    --------
    >>> simplest("bearing_anisotropic:B0", {"bearing_anisotropic:B0": 31.0, "bearing_change:B0": 29.5}, 3.0)
    'bearing_change:B0'
    >>> simplest("bearing_anisotropic:B0", {"bearing_anisotropic:B0": 41.0, "bearing_change:B0": 29.5}, 3.0)
    'bearing_anisotropic:B0'
    """
    from twin.fem.effects import holds

    while True:
        simpler = [label for label in evidence if holds(best, label) and evidence[best] - evidence[label] <= margin]
        if not simpler:
            return best
        best = max(simpler, key=lambda label: evidence[label])
