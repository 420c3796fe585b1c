"""The jackknife of the posterior mode: how far the modes' correlation widens the update's spread.

The marginal model treats the modes as independent; modes extracted from one
record are not (their jackknife samples come from the same blocks). A
Godambe-style check measures the spread of the posterior mode over
perturbations of the data by its own samples twice: with every mode moved by
the same sample (``joint``) and with the samples shifted from mode to mode
(``shuffled``). Their ratio is what the modes' correlation adds.

The update does not use it: its factor, from 20 perturbations of 15 pole
samples, scatters by about 20% even without any correlation, and on FMU
records it did not track the posterior's error (the decision log's page on
the jackknife adjustment). The benchmarks that measured that keep it here.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
import xarray as xr

from twin.fem.model import RotorModel
from twin.update.intersection import intersected
from twin.update.marginal import Marginal, marginal_problem, posterior_mode
from twin.update.problem import UpdateError, build_problem

log = logging.getLogger(__name__)

#: At most this many samples perturb the data (one mode search each), evenly spaced over the J.
PERTURBATIONS = 20
#: Fewer perturbations than this whose mode was found: no adjustment (with a warning in the log).
MIN_PERTURBATIONS = 5


def perturbed(x: xr.DataArray, j: int | np.ndarray) -> xr.DataArray:
    """The samples ``x`` (dims ``mode``, ``sample``, ...) with their mean moved by ``(x_j - x̄) / sqrt(J)``.

    ``j`` is one sample for every mode, or one per mode. The move has the covariance of the mean's own
    error (the samples' covariance over J), and the samples keep their spread.

    Examples
    --------
    >>> x = xr.DataArray([[0.0, 1.0, 2.0, 5.0], [1.0, 1.0, 4.0, 2.0]], dims=("mode", "sample"))
    >>> perturbed(x, 3).mean("sample").values.tolist()
    [3.5, 2.0]
    >>> perturbed(x, np.array([3, 2])).mean("sample").values.tolist()
    [3.5, 3.0]
    """
    J = x.sizes["sample"]
    mean = x.mean("sample")
    pick = x.isel(sample=xr.DataArray(np.broadcast_to(j, (x.sizes["mode"],)), dims="mode"))
    return (x + (pick.drop_vars("sample", errors="ignore") - mean) / np.sqrt(J)).transpose(*x.dims)


def correlation_factors(
    marg: Marginal,
    model: RotorModel,
    modes: xr.Dataset,
    names: Sequence[str],
    *,
    fsi: bool,
    eps_std: float,
    prior_mean: np.ndarray,
    prior_precision: np.ndarray,
) -> np.ndarray | None:
    """Per parameter, the spread of the posterior mode with the modes' samples joint over that with them shuffled.

    ``marg`` is the marginal problem of ``modes`` itself (the perturbed data's take its shape covariance
    estimator). Parameters in the
    order of the posterior (shared, then per mode); ``None`` when fewer than
    :data:`MIN_PERTURBATIONS` perturbations of either kind give a mode.
    """
    centre, _ = posterior_mode(marg, prior_mean, prior_precision)
    spread = {}
    for pairing in ("joint", "shuffled"):
        spread[pairing] = mode_spread(
            marg,
            model,
            modes,
            names,
            fsi=fsi,
            eps_std=eps_std,
            prior_mean=prior_mean,
            prior_precision=prior_precision,
            pairing=pairing,
            centre=centre,
        )
        if spread[pairing] is None:
            return None
    joint, shuffled = spread["joint"], spread["shuffled"]
    return np.divide(joint, shuffled, out=np.ones_like(joint), where=shuffled > 0)


def mode_spread(
    marg: Marginal,
    model: RotorModel,
    modes: xr.Dataset,
    names: Sequence[str],
    *,
    fsi: bool,
    eps_std: float,
    prior_mean: np.ndarray,
    prior_precision: np.ndarray,
    pairing: str = "joint",
    centre: np.ndarray | None = None,
) -> np.ndarray | None:
    """RMS move [SI] of each parameter's posterior mode over perturbations of the data by its samples.

    Each perturbation moves the data's mean by a sample's deviation over
    ``sqrt(J)`` (:func:`perturbed`) and searches the mode again from the data's
    own: with ``pairing="joint"`` every mode by the same sample, with
    ``"shuffled"`` mode ``i`` by the ``i``-th next of the same picks (the
    modes' samples made independent). The joint RMS is the estimate's standard
    error with every correlation of the samples in it. ``centre`` is the
    posterior mode of ``marg`` (scaled; searched when not given). ``None``
    when fewer than :data:`MIN_PERTURBATIONS` modes are found.
    """
    scales = np.concatenate([marg.problem.global_scale, marg.problem.mode_scale.ravel()])
    if centre is None:
        centre, _ = posterior_mode(marg, prior_mean, prior_precision)
    J, I = modes.sizes["sample"], modes.sizes["mode"]
    picks = np.unique(np.linspace(0, J - 1, min(PERTURBATIONS, J)).round().astype(int))
    shift = np.arange(I) if pairing == "shuffled" else np.zeros(I, int)
    moves = []
    for k in range(len(picks)):
        j = picks[(k + shift) % len(picks)]
        data = modes.copy()
        data["pole"], data["shape"] = perturbed(modes["pole"], j), perturbed(modes["shape"], j)
        try:
            problem = build_problem(model, data, names, fsi=fsi, eps_std=eps_std, pole_model="marginal")
            perturbed_marg = marginal_problem(
                problem,
                data["pole"].transpose("mode", "sample").values,
                marg.shape_covariance,
                order_cov=marg.order_cov,
            )
            if marg.weights is not None:  # the same combination of each mode's pole and shapes as the data's
                perturbed_marg = intersected(perturbed_marg, marg.weights)
            theta, _ = posterior_mode(perturbed_marg, prior_mean, prior_precision, start=centre)
        except (UpdateError, np.linalg.LinAlgError):
            continue
        moves.append((theta - centre) * scales)
    if len(moves) < MIN_PERTURBATIONS:
        log.warning(
            "the posterior's spread is not adjusted: the mode was found for %d of %d perturbations",
            len(moves),
            len(picks),
        )
        return None
    return np.sqrt(np.mean(np.square(moves), axis=0))
