"""Each mode's pole and shape errors combined by covariance intersection: correlated by an unknown amount.

A mode's mean pole and mean shape come from one subspace estimate, so their
errors are correlated. The marginal model's residual at the data is
``m_i = H_i e_ψ + B_i e_λ`` (:mod:`twin.update.marginal`: ``e_ψ`` the mean
shape's error, ``e_λ`` the mean pole's), and with the two errors taken as
independent its covariance is ``V_i = H_i Λ_i H_iᵀ + B_i C_i B_iᵀ``. On FMU
records with a hidden seal (``benchmarks/pole_shape.py``, 24 records) the
seal's estimates from each mode's shapes and from its pole were each about
as good as they claimed (RMS z 0.86 and 1.09) but erred together,
correlation 0.62 over the records, so that taken as independent they made
the posterior too narrow (1.26). The samples show that correlation too, but
15 samples of a mode's 18 real numbers leave its direction too uncertain to
use (``docs/decisions/update-intersection.md``).

Whatever the correlation, for any ``0 < ω < 1``

    cov(m_i) ≼ H_i Λ_i H_iᵀ / ω + B_i C_i B_iᵀ / (1 - ω)

(covariance intersection; Julier and Uhlmann 1997): with this ``V_i`` no
correlation of the two errors can make the posterior narrower than the
data allow. Each mode's ``ω_i`` is the one of :data:`WEIGHT_GRID` that keeps
the most of the mode's information about the parameters (the largest
``log det Aᵢᵀ V_i(ω)⁻¹ Aᵢ``, ``Aᵢ`` the residual's slopes in the parameters)
at their nominal values: the part, shape or pole, that limits what the mode
says is inflated least.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from twin.update.marginal import Marginal, nominal, residual_moments
from twin.update.problem import UpdateError

#: How a mode's pole and shape errors are combined (``update(combine=...)``): the default first.
COMBINATIONS = ("intersection", "independent")
#: The shape share ``ω`` of each mode's residual covariance is chosen among these.
WEIGHT_GRID = np.linspace(0.02, 0.98, 49)
#: Ridge on a mode's information matrix, relative to its mean diagonal: parameters the mode says nothing about.
INFORMATION_RIDGE = 1e-9


def check_combination(name: str) -> None:
    """Raise :class:`~twin.errors.UpdateError` unless ``name`` is one of :data:`COMBINATIONS`."""
    if name not in COMBINATIONS:
        raise UpdateError(f"combine must be one of {', '.join(COMBINATIONS)}, got {name!r}")


def intersection_weights(marg: Marginal, theta: np.ndarray | None = None) -> np.ndarray:
    """Each mode's shape share ``ω_i`` of the intersected residual covariance, ``(I,)``.

    ``theta`` (scaled parameters; default their nominal values) is where the
    residual's covariance is taken. The weight maximises the log-determinant
    of the mode's information about its parameters over :data:`WEIGHT_GRID`.

    Examples
    --------
    >>> from twin.update import synthesize_modes
    >>> from twin.update.marginal import marginal_problem
    >>> from twin.update.problem import build_problem
    >>> m = hydro_unit
    >>> data = synthesize_modes(m, samples=20, seed=0).isel(mode=[2, 3])
    >>> marg = marginal_problem(build_problem(m, data, fsi=True, pole_model="marginal"), data["pole"].values)
    >>> w = intersection_weights(marg)
    >>> w.shape, bool(np.all((w > 0) & (w < 1)))
    ((2,), True)
    """
    theta = nominal(marg.problem) if theta is None else np.asarray(theta, dtype=float)
    _, _, H, B = residual_moments(marg, theta)
    shape_part = H @ marg.cov_z @ np.swapaxes(H, 1, 2)
    pole_part = B @ marg.pole_cov @ np.swapaxes(B, 1, 2)
    slopes = marg.columns[:, 1:, 0]  # (I, K, n_r): the residual's slope in each coefficient
    K = slopes.shape[1]
    weights = np.empty(len(slopes))
    for i, (A, S, P) in enumerate(zip(slopes, shape_part, pole_part)):
        try:
            both = A @ np.linalg.solve(S + P, A.T)
            ridge = INFORMATION_RIDGE * max(float(np.trace(both)) / K, np.finfo(float).tiny) * np.eye(K)
            kept = [np.linalg.slogdet(A @ np.linalg.solve(S / w + P / (1.0 - w), A.T) + ridge)[1] for w in WEIGHT_GRID]
        except np.linalg.LinAlgError:
            raise UpdateError(
                f"the residual covariance of mode {int(marg.problem.modes[i])} is singular at the "
                "nominal parameters (no shape or pole scatter?): its pole and shapes cannot be "
                "combined"
            ) from None
        weights[i] = WEIGHT_GRID[int(np.argmax(kept))]
    return weights


def intersected(marg: Marginal, weights: np.ndarray | None = None) -> Marginal:
    """``marg`` with each mode's shape covariance over ``ω_i`` and pole covariance over ``1 - ω_i``.

    ``weights`` default to :func:`intersection_weights` at the nominal
    parameters; they are kept in the result's ``weights``.

    Examples
    --------
    >>> from twin.update import synthesize_modes
    >>> from twin.update.marginal import marginal_problem
    >>> from twin.update.problem import build_problem
    >>> m = hydro_unit
    >>> data = synthesize_modes(m, samples=20, seed=0).isel(mode=[2])
    >>> marg = marginal_problem(build_problem(m, data, ["LGB.kxx"], pole_model="marginal"), data["pole"].values)
    >>> both = intersected(marg, np.array([0.25]))
    >>> round(float(both.pole_cov[0, 0, 0] / marg.pole_cov[0, 0, 0]), 12), both.weights.tolist()
    (1.333333333333, [0.25])
    """
    w = intersection_weights(marg) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (marg.problem.n_modes,) or np.any((w <= 0) | (w >= 1)):
        raise ValueError(f"need one weight strictly between 0 and 1 per mode ({marg.problem.n_modes}), got {w}")
    idx = marg.problem.data_index
    cov_z = marg.cov_z.copy()
    cov_z[:, idx[:, None], idx] /= w[:, None, None]
    return dataclasses.replace(marg, cov_z=cov_z, pole_cov=marg.pole_cov / (1.0 - w)[:, None, None], weights=w)
