"""Covariances of a mode's shape samples with their correlations shrunk, and how much to shrink them.

A mode's ``J`` shape samples give its mean shape's covariance, but with
``J`` about the number of entries their correlation matrix is singular and
its small directions are noise. :func:`shrunk_covariance` keeps the
entries' variances and multiplies the correlations by ``1 - λ``. The
intensity ``λ`` is either Schäfer and Strimmer's (2005), which minimises
the expected squared (Frobenius) error of the correlations, or
:func:`held_out_intensity`'s, which maximises the Gaussian likelihood of
each sample held out of the others' estimate. The update weighs the data
with the covariance's inverse, whose smallest directions the Frobenius loss
hardly sees and the likelihood does. On the hydro unit's FMU records the
held-out intensity brings the bearings' 90% intervals into calibration but
makes a hidden magnetic pull's too narrow (its shapes err beyond their
samples), so the update's default stays Schäfer and Strimmer's
(``docs/decisions/update-shrinkage.md``).
"""

from __future__ import annotations

import numpy as np

#: An entry whose scatter over the samples is below this fraction of the largest in its group (a mode's
#: shape) has none: the reference channel's imaginary part, zero up to round-off (see :func:`scatters`).
NO_SCATTER = 1e-12
#: The intensities :func:`held_out_intensity` chooses among (``λ = 0``, the samples' own correlations, is
#: singular when the samples are fewer than the entries).
INTENSITY_GRID = np.linspace(0.01, 1.0, 100)


def scatters(spread: np.ndarray) -> np.ndarray:
    """Which entries scatter: a spread above :data:`NO_SCATTER` times the largest of its group (last axis).

    Round-off is no scatter: the reference entry's imaginary part of a normalised shape is zero up to it,
    and its "correlations" with the other entries would be noise.

    Examples
    --------
    >>> scatters(np.array([[1.0, 0.5, 3e-17, 0.0]]))
    array([[ True,  True, False, False]])
    """
    spread = np.asarray(spread, dtype=float)
    return spread > NO_SCATTER * spread.max(axis=-1, keepdims=True)


def _standardised(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Samples ``(..., J, n)`` centred and over their std; an entry without scatter is all zeros. And the stds."""
    J = x.shape[-2]
    x = x - x.mean(axis=-2, keepdims=True)
    sd = np.sqrt(np.sum(x**2, axis=-2, keepdims=True) / (J - 1))
    return np.divide(x, sd, out=np.zeros_like(x), where=scatters(sd)), sd


def shrunk_covariance(
    samples: np.ndarray, variance: np.ndarray, intensity: float | np.ndarray | None = None
) -> np.ndarray:
    """Covariance of the samples' entries with their correlations shrunk toward zero.

    The shape samples of a mode are strongly correlated across channels (one
    source of error moves every entry), and a parameter is informed by a
    combination of entries: their variances alone understate its error (3-5
    times in variance along the magnetic pull's direction of the hydro
    unit's generator mode). With ``J`` not much larger than the number of
    entries, the sample correlation matrix is singular, so each group's is
    shrunk toward the identity, by default with the intensity of Schäfer and
    Strimmer (2005, target "D"): ``λ = Σ_{a≠b} Var(r_ab) / Σ_{a≠b} r_ab²``,
    clipped to [0, 1], from the same samples.

    Parameters
    ----------
    samples : (..., J, n)
        Real samples of each group (e.g. per mode) on the second-to-last axis.
    variance : (..., n)
        The entries' variances (the diagonal of the result; may be floored).
    intensity : float or (...,) array, optional
        ``λ`` itself (one, or one per group) instead of Schäfer and Strimmer's
        (0: the samples' own correlations; :func:`held_out_intensity` gives one per group).

    Returns
    -------
    (..., n, n)
        Covariance with the given diagonal and correlations ``(1 - λ) r_ab``.

    Examples
    --------
    Two entries that move together, and one on its own:

    >>> rng = np.random.default_rng(0)
    >>> a, b = rng.standard_normal((2, 200))
    >>> x = np.stack([a, a + 0.1 * b, rng.standard_normal(200)], axis=-1)
    >>> np.round(shrunk_covariance(x, np.var(x, axis=0, ddof=1)), 1)
    array([[0.9, 0.9, 0.1],
           [0.9, 0.9, 0.1],
           [0.1, 0.1, 1. ]])
    """
    x, _ = _standardised(np.asarray(samples, dtype=float))  # an entry without scatter correlates with nothing
    J = x.shape[-2]
    w = x[..., :, None] * x[..., None, :]  # (..., J, n, n)
    w_bar = w.mean(axis=-3)
    r = J / (J - 1) * w_bar
    off = ~np.eye(x.shape[-1], dtype=bool)
    if intensity is None:
        var_r = J / (J - 1) ** 3 * np.sum((w - w_bar[..., None, :, :]) ** 2, axis=-3)
        total = np.sum(np.where(off, r**2, 0.0), axis=(-2, -1))
        lam = np.clip(
            np.divide(
                np.sum(np.where(off, var_r, 0.0), axis=(-2, -1)), total, out=np.ones_like(total), where=total > 0
            ),
            0.0,
            1.0,
        )
    else:
        lam = np.broadcast_to(np.asarray(intensity, dtype=float), r.shape[:-2])
    corr = np.where(off, (1.0 - lam[..., None, None]) * r, 1.0)
    s = np.sqrt(np.asarray(variance, dtype=float))
    return corr * s[..., :, None] * s[..., None, :]


def held_out_intensity(samples: np.ndarray, grid: np.ndarray = INTENSITY_GRID) -> np.ndarray:
    """Each group's shrinkage intensity ``λ`` by the likelihood of its samples, each held out of the others.

    For every sample ``j`` the other ``J - 1`` give the mean, the entries'
    stds and the correlations ``R_(j)``; the held-out deviation is scored by
    the Gaussian log-likelihood under ``(1 - λ) R_(j) + λ I`` scaled by those
    stds (and by ``J / (J - 1)``: the others' mean errs too). The ``λ`` of
    ``grid`` with the largest sum over ``j`` is returned. This is the loss the
    update's Gaussian likelihood puts on the covariance, so where the
    samples' small directions hold up out of sample they are kept; Schäfer
    and Strimmer's intensity judges the correlations one by one. Entries
    that do not scatter (:func:`scatters`) are left out. The samples should
    be about independent (delete-one jackknife pseudo-values are;
    overlapping delete-half samples are not, and make ``λ`` too small).

    Parameters
    ----------
    samples : (..., J, n)
        Real samples of each group on the second-to-last axis, ``J ≥ 4``.
    grid : (G,)
        Intensities to choose among, in (0, 1].

    Returns
    -------
    (...,)
        The chosen ``λ`` per group.

    Examples
    --------
    Ten entries driven by one common error (correlations 0.8) keep most of it; independent ones are
    shrunk to about the identity:

    >>> rng = np.random.default_rng(1)
    >>> common = 2.0 * rng.standard_normal((15, 1)) + rng.standard_normal((15, 10))
    >>> alone = rng.standard_normal((15, 10))
    >>> np.round(held_out_intensity(np.stack([common, alone])), 2)
    array([0.28, 0.99])
    """
    x = np.asarray(samples, dtype=float)
    J = x.shape[-2]
    grid = np.asarray(grid, dtype=float)
    if J < 4:
        raise ValueError(f"held_out_intensity needs at least 4 samples per group, got {J}")
    if grid.ndim != 1 or grid.size == 0 or np.any((grid <= 0) | (grid > 1)):
        raise ValueError("the intensity grid must be a non-empty 1-D array within (0, 1]")
    batch = x.shape[:-2]
    x = x.reshape(-1, J, x.shape[-1])
    out = np.empty(len(x))
    rest = ~np.eye(J, dtype=bool)
    for g, xg in enumerate(x):
        xg = xg[:, scatters(xg.std(axis=0))]
        if xg.shape[1] < 2:  # no correlations to shrink
            out[g] = 1.0
            continue
        others = np.stack([xg[keep] for keep in rest])  # (J, J - 1, n): sample j left out
        z, sd = _standardised(others)
        sd = np.where(scatters(sd), sd, 1.0)
        R = np.swapaxes(z, 1, 2) @ z / (J - 2)  # the others' correlations
        R[:, np.arange(R.shape[-1]), np.arange(R.shape[-1])] = 1.0  # also where only sample j moved an entry
        e, V = np.linalg.eigh(R)
        e = np.clip(e, 0.0, None)
        u = np.einsum("jab,ja->jb", V, (xg - others.mean(axis=1)) / sd[:, 0])
        s = (1.0 - grid[:, None, None]) * e + grid[:, None, None]  # (G, J, n): eigenvalues of the shrunk
        score = -0.5 * np.sum(np.log(s) + u**2 / s * (J - 1) / J, axis=(1, 2))
        out[g] = grid[int(np.argmax(score))]
    return out.reshape(batch)
