"""How a mode's pole samples enter the condensed eigen-model.

The condensed eigen-equation ``R(λ, θ) ψ + T(λ, θ) ε = 0`` is far from
linear in the pole ``λ``: the Schur complement over the unobserved DOFs has
a pole at every resonance of those DOFs, and stage 2 inverts a matrix that
depends on ``λ``. Two ways of evaluating it at the samples ``λ̂_j`` of a
mode (:data:`POLE_MODELS`):

``samples`` (the paper's)
    The basis matrices at every pole sample, ``H(λ̂_j)``. The mean of the
    residual over the samples is then not the residual at the mean pole:
    the pole noise adds about ``½ tr(C ∇²H)`` (``C`` the pole covariance),
    which is small for a mode far from the resonances of the unobserved
    DOFs and dominates for a mode a few pole stds from one. Least squares
    on such residuals is biased, and the posterior intervals miss.
``linear``
    The basis matrices linearised in the pole about the mode's mean pole
    ``λ̄``: ``H(λ̄) + Re δ_j ∂H/∂Re λ + Im δ_j ∂H/∂Im λ`` with
    ``δ_j = λ̂_j − λ̄``. Each residual then scatters about the residual at
    ``λ̄`` exactly as the pole sample scatters about ``λ̄`` (the errors-in-
    variables model of the pole to first order): their mean is the residual
    at the mean pole, and their covariance, which the sampler learns in
    ``Δ_i``, is the pole covariance carried through ``∂H/∂λ``. The mean pole
    is within ``std/√J`` of the truth, where the condensed model is close to
    linear. It needs five condensations per mode instead of ``J``.
``marginal`` (the default of :func:`twin.update.update`)
    The errors-in-variables model itself: one residual per mode, at the mean
    pole, and the mean pole's deviation from the true pole a latent Gaussian
    with the covariance of the mean (the pole samples' covariance over
    ``J``), integrated out together with the shapes
    (:mod:`twin.update.marginal`). The "samples" of the condensed model are
    then three: the bases at the mean pole and their slopes along ``Re λ``
    and ``Im λ``.

The derivatives are central differences with step :data:`STEP` times the
spread of the pole samples.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Mapping, Sequence

import numpy as np
import xarray as xr

from twin.errors import UpdateError
from twin.update.condense import Condensed, condense

#: Ways the pole samples enter the condensed model (see the module docstring).
POLE_MODELS = ("samples", "linear", "marginal")
#: What the marginal model takes as each mean pole's error (``update(pole_error=...)``; the default first; see
#: :func:`order_covariance`).
POLE_ERRORS = ("samples+orders", "samples")
#: Finite-difference step of the pole derivatives, relative to the spread of the pole samples.
STEP = 0.01


log = logging.getLogger(__name__)


def order_covariance(modes: xr.Dataset) -> np.ndarray:
    """Each mode's pole covariance over its model orders, ``[Re, Im]`` [1/s²], ``(I, 2, 2)``.

    SSI's estimate of a pole depends on the model order, and the extraction
    averages each mode over a set of orders: the spread over them
    (``modes.nc``'s ``pole_order_cov``) is a part of the pole's error that
    no jackknife of the record shows. The marginal model adds it to the
    covariance of the mean pole (``update(pole_error="samples+orders")``,
    the default). Zero where the modes carry none (synthetic modes, another
    producer) or where their pole samples carry it already
    (``extract(order_spread="all")``).

    Examples
    --------
    >>> import xarray as xr
    >>> modes = xr.Dataset({"pole_order_cov": (("mode", "pole_part", "pole_part_2"), [[[4.0, 1.0], [1.0, 9.0]]])},
    ...                    attrs={"settings": '{"order_spread": "shapes"}'})
    >>> order_covariance(modes)[0].tolist()
    [[4.0, 1.0], [1.0, 9.0]]
    >>> order_covariance(modes.assign_attrs(settings='{"order_spread": "all"}'))[0].tolist()
    [[0.0, 0.0], [0.0, 0.0]]
    """
    n = modes.sizes["mode"]
    if "pole_order_cov" not in modes:
        log.info("the modes carry no pole_order_cov: each mean pole's error is its samples' alone")
        return np.zeros((n, 2, 2))
    try:
        spread = json.loads(str(modes.attrs.get("settings", "{}"))).get("order_spread")
    except (ValueError, AttributeError):
        spread = None
    if spread == "all":
        log.info("the pole samples carry the model-order spread already (order_spread='all'): nothing added")
        return np.zeros((n, 2, 2))
    cov = modes["pole_order_cov"].transpose("mode", ...).values
    if cov.shape != (n, 2, 2) or not np.all(np.isfinite(cov)):
        raise UpdateError(f"pole_order_cov must be finite, one 2 x 2 matrix per mode, got shape {cov.shape}")
    return np.array(cov, dtype=float)


def check_pole_model(name: str) -> None:
    """Raise :class:`~twin.errors.UpdateError` unless ``name`` is one of :data:`POLE_MODELS`."""
    if name not in POLE_MODELS:
        raise UpdateError(f"unknown pole model '{name}'; choose one of {', '.join(POLE_MODELS)}")


def condense_samples(
    fixed: Mapping[str, np.ndarray],
    bases: Sequence[Mapping[str, np.ndarray]],
    observed: Sequence[int],
    poles: np.ndarray,
    speed_rad_s: float,
    *,
    pole_model: str = "samples",
    force_latent: bool = False,
) -> Condensed:
    """The PerCEM basis matrices of one mode at its pole samples, by ``pole_model``.

    Arguments as :func:`twin.update.condense.condense`; ``pole_model`` is one
    of :data:`POLE_MODELS`. The extra parameter-free rows are chosen at the
    mean pole in every model. With ``marginal`` the three "samples" are the
    bases at the mean pole and their derivatives along ``Re λ`` and ``Im λ``.

    Examples
    --------
    A 3-DOF chain, DOFs 0 and 1 observed, a spring at DOF 2; three pole samples
    about ``2j``. Linearised, the bases average to those at the mean pole:

    >>> K0 = np.array([[2., -1, 0], [-1, 2, -1], [0, -1, 1]])
    >>> fixed = {"M": np.eye(3), "C": np.zeros((3, 3)), "G": np.zeros((3, 3)), "K": K0}
    >>> zero = np.zeros((3, 3)); Kk = zero.copy(); Kk[2, 2] = 1.0
    >>> basis = {"M": zero, "C": zero, "G": zero, "K": Kk}
    >>> poles = np.array([2j - 0.1, 2j + 0.1, 2j + 0.05j])
    >>> lin = condense_samples(fixed, [basis], [0, 1], poles, 0.0, pole_model="linear")
    >>> at_mean = condense(fixed, [basis], [0, 1], poles.mean(keepdims=True), 0.0)
    >>> bool(np.allclose(lin.R.mean(axis=0), at_mean.R[0]))
    True
    """
    check_pole_model(pole_model)
    poles = np.asarray(poles, dtype=complex)
    centre = complex(poles.mean())
    if pole_model == "samples":
        return condense(fixed, bases, observed, poles, speed_rad_s, force_latent=force_latent, centre=centre)
    spread = float(np.sqrt(np.var(poles.real) + np.var(poles.imag)))
    h = STEP * (spread if spread > 0 else abs(centre))
    at = centre + np.array([0.0, h, -h, 1j * h, -1j * h])
    c = condense(fixed, bases, observed, at, speed_rad_s, force_latent=force_latent, centre=centre)
    if pole_model == "marginal":

        def slopes(f: np.ndarray) -> np.ndarray:
            return np.stack([f[0], (f[1] - f[2]) / (2 * h), (f[3] - f[4]) / (2 * h)])

        return dataclasses.replace(c, R=slopes(c.R), T=slopes(c.T))
    d = (poles - centre)[:, None, None, None]

    def linearised(f: np.ndarray) -> np.ndarray:
        return f[0] + d.real * (f[1] - f[2]) / (2 * h) + d.imag * (f[3] - f[4]) / (2 * h)

    return dataclasses.replace(c, R=linearised(c.R), T=linearised(c.T))
