"""Fit one candidate effect to measured poles, and its evidence (Laplace approximation).

Data: the measured poles ``λ̂_i`` with uncertainties ``σ`` (real and
imaginary part, see :func:`twin.loop.compare.measured_modes`). Parameters:
the effect's ``θ = s ⊙ u`` with ``s`` its plausible scale
(:meth:`plausible_scale` of the effect) and prior ``u ~ N(0, I)``, halved to
one side for sign-constrained parameters (added mass and damping ≥ 0,
magnetic stiffness ≤ 0).

The MAP ``u*`` minimises ``½|r(u)|² + ½|u|²`` with ``r`` the pole residuals in
sigmas (Levenberg-Marquardt, exact pole derivatives from
:mod:`twin.loop.sensitivity`, modes followed by MAC from one step to the
next). The log evidence against the model without the effect (the log Bayes
factor) is, to Laplace's approximation with the Gauss-Newton Hessian
``H = JᵀJ + I``,

    ln B = ½|r(0)|² − ½|r(u*)|² − ½|u*|² − ½ ln det H + n_signed ln 2.

The first two terms are the better fit; the rest is the Occam factor: a
parameter the data pin far more sharply than its plausible scale costs about
``ln(s/σ_θ)``. Per-mode effects fit each mode on its own (their parameters
touch one mode each), and their log evidences add.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from twin.errors import ModelError
from twin.fem.effects import CHANGE_FRACTION, FluidAddedMass, with_shared_fsi
from twin.fem.model import RotorModel
from twin.loop.candidates import Candidate, with_effect
from twin.loop.compare import Measured, channel_dofs, overall_error, pair_with_measured
from twin.loop.sensitivity import ModalSolution, pole_jacobian, solve_modes
from twin.modes.shapes import mac

log = logging.getLogger(__name__)

#: Levenberg-Marquardt iterations at most, and the Newton decrement ``gᵀH⁻¹g / 2`` (a change of the log evidence) that counts as converged.
MAX_ITERATIONS = 40
DECREMENT_TOLERANCE = 1e-3


@dataclass(frozen=True)
class Fit:
    """The fitted candidate.

    Attributes
    ----------
    label : str
        Candidate label.
    names, units : list of str
        Fitted parameters.
    values, std : (k,) float
        MAP and Laplace posterior std [SI].
    scale : (k,) float
        Prior (plausible) scale [SI].
    measured : (n,) int
        Indices of the measured modes used (paired with the model).
    poles_before, poles_after : (n,) complex
        Model poles without and with the fitted effect.
    chi2_before, chi2_after : float
        Sum of squared residuals in sigmas.
    log_bayes_factor : float
        ``ln B`` against the model without the effect.
    converged : bool
    at_bound : list of str
        Sign-constrained parameters whose MAP sits at zero.
    """

    label: str
    names: list[str]
    units: list[str]
    values: np.ndarray
    std: np.ndarray
    scale: np.ndarray
    measured: np.ndarray
    poles_before: np.ndarray
    poles_after: np.ndarray
    chi2_before: float
    chi2_after: float
    log_bayes_factor: float
    converged: bool
    at_bound: list[str] = field(default_factory=list)

    def error_before(self, meas: Measured) -> float:
        """The overall error ``E`` of the model without the effect, on the modes used."""
        return overall_error(self.poles_before, meas.pole[self.measured], meas.sigma[self.measured])

    def error_after(self, meas: Measured) -> float:
        """The overall error ``E`` with the fitted effect, on the modes used."""
        return overall_error(self.poles_after, meas.pole[self.measured], meas.sigma[self.measured])

    @property
    def residual_dof(self) -> int:
        """Degrees of freedom left to the residuals: two data per mode used, less the parameters."""
        return 2 * len(self.measured) - len(self.names)


class _Tracker:
    """Follows the model modes paired with measured modes from one parameter point to the next."""

    def __init__(self, model: RotorModel, sol: ModalSolution, meas: Measured, keep: np.ndarray | None = None):
        _, rows, cols = pair_with_measured(sol, meas, channel_dofs(model, meas.channels))
        if keep is not None:
            sel = np.isin(rows, keep)
            rows, cols = rows[sel], cols[sel]
        self.rows = rows
        self.update(sol, cols)

    def follow(self, sol: ModalSolution) -> np.ndarray:
        """Indices into ``sol`` of the tracked modes (MAC on all DOFs, nearest pole breaks ties)."""
        m = mac(self.shapes, sol.right)
        dist = np.abs(sol.poles[None, :] - self.poles[:, None]) / np.abs(self.poles[:, None])
        return np.argmax(m - 1e-3 * dist, axis=1)

    def update(self, sol: ModalSolution, cols: np.ndarray) -> None:
        self.cols, self.shapes, self.poles = cols, sol.right[cols], sol.poles[cols]


def scaled_rows(values: np.ndarray, meas: Measured, rows: np.ndarray) -> np.ndarray:
    """Complex per-mode rows (residuals or Jacobian rows) as real parts over σ_re, then imaginary over σ_im."""
    values = np.asarray(values)
    shape = (-1,) + (1,) * (values.ndim - 1)
    sig_re, sig_im = meas.sigma[rows, 0].reshape(shape), meas.sigma[rows, 1].reshape(shape)
    return np.concatenate([values.real / sig_re, values.imag / sig_im])


def _residual(poles: np.ndarray, meas: Measured, rows: np.ndarray) -> np.ndarray:
    return scaled_rows(poles - meas.pole[rows], meas, rows)


def _jacobian(model, sol, names, cols, meas, rows, scale) -> np.ndarray:
    return scaled_rows(pole_jacobian(model, sol, names, cols) * scale[None, :], meas, rows)


def fit_parameters(
    model: RotorModel,
    meas: Measured,
    label: str,
    names: Sequence[str],
    scale: np.ndarray,
    signs: Sequence[int],
    keep: np.ndarray | None = None,
) -> Fit:
    """MAP fit of parameters ``names`` (zero at the start) to the measured poles, with its evidence.

    The parameters are ``θ = scale * u`` with the prior of the module
    docstring; ``keep`` restricts the data to some measured modes (indices).
    """
    names, scale, signs = list(names), np.asarray(scale, float), np.asarray(signs)
    base = {n: model.parameter(n).nominal for n in names}

    def values(u):
        return {n: base[n] + s * x for n, s, x in zip(names, scale, u)}

    sol = solve_modes(model, values(np.zeros(len(names))))
    tracker = _Tracker(model, sol, meas, keep)
    rows = tracker.rows
    poles_before = tracker.poles.copy()
    u = np.zeros(len(names))
    r0 = r = _residual(tracker.poles, meas, rows)
    J = _jacobian(model, sol, names, tracker.cols, meas, rows, scale)
    cost = 0.5 * (r @ r + u @ u)
    mu, converged = 1e-3, False
    for _ in range(MAX_ITERATIONS):
        H = J.T @ J + np.eye(len(u))
        g = J.T @ r + u
        # a sign-constrained parameter at zero, pushed outwards, stays at zero
        free = ~((signs != 0) & (u == 0.0) & (signs * g > 0))
        Hf, gf = H[np.ix_(free, free)], g[free]
        if not free.any() or 0.5 * gf @ np.linalg.solve(Hf, gf) < DECREMENT_TOLERANCE:
            converged = True
            break
        step = np.zeros(len(u))
        step[free] = np.linalg.solve(Hf + mu * np.diag(np.diag(Hf)), -gf)
        trial = u + step
        trial = np.where(signs > 0, np.maximum(trial, 0.0), np.where(signs < 0, np.minimum(trial, 0.0), trial))
        s_new = solve_modes(model, values(trial))
        cols = tracker.follow(s_new)
        r_new = _residual(s_new.poles[cols], meas, rows)
        new_cost = 0.5 * (r_new @ r_new + trial @ trial)
        if new_cost <= cost:
            u, r, cost, sol = trial, r_new, new_cost, s_new
            tracker.update(sol, cols)
            J = _jacobian(model, sol, names, cols, meas, rows, scale)
            mu = max(mu / 3, 1e-9)
        else:
            mu *= 4
            if mu > 1e8:
                converged = True  # no descent direction left: a (possibly constrained) minimum
                break
    H = J.T @ J + np.eye(len(u))
    ln_det = float(np.linalg.slogdet(H)[1])
    n_signed = int(np.count_nonzero(signs))
    ln_b = 0.5 * (r0 @ r0 - r @ r - u @ u) - 0.5 * ln_det + n_signed * np.log(2.0)
    std = scale * np.sqrt(np.diag(np.linalg.inv(H)))
    at_bound = [n for n, sg, x in zip(names, signs, u) if sg and x == 0.0]
    units = [model.parameter(n).unit for n in names]
    return Fit(label, names, units, scale * u, std, scale, rows, poles_before, tracker.poles.copy(),
               float(r0 @ r0), float(r @ r), float(ln_b), converged, at_bound)  # fmt: skip


def fit_candidate(model: RotorModel, meas: Measured, candidate: Candidate) -> Fit:
    """Fit one candidate effect to the measured poles (see the module docstring).

    Examples
    --------
    >>> import dataclasses
    >>> from twin import load_model
    >>> from twin.fem.effects import MagneticPull
    >>> from twin.loop.candidates import Candidate
    >>> from twin.loop.compare import measured_modes
    >>> from twin.update import synthesize_modes
    >>> from twin.fem.truthfile import Truth
    >>> model = load_model("models/hydro_unit.toml")
    >>> data = synthesize_modes(model, Truth((MagneticPull(-2e8),)), n_modes=8, samples=50, seed=1,
    ...                         pole_variance=(0.01, 0.01))
    >>> fit = fit_candidate(model, measured_modes(data), Candidate("magnetic_pull", MagneticPull()))
    >>> round(float(fit.values[0]) / -2e8, 1)
    1.0
    """
    if candidate.per_mode:
        return _fit_per_mode(model, meas, candidate)
    altered = with_effect(model, candidate.effect)
    priors = effect_priors(altered, candidate.effect)
    return fit_parameters(altered, meas, candidate.label, list(priors), np.array([s for s, _ in priors.values()]),
                          [g for _, g in priors.values()])  # fmt: skip


def _fit_per_mode(model: RotorModel, meas: Measured, candidate: Candidate) -> Fit:
    """Per-mode FSI: each paired mode fitted alone with its own added mass and damping; evidences add."""
    base = with_shared_fsi(model)
    shared = ["FSI.added_mass", "FSI.added_damping"]
    scales = FluidAddedMass().plausible_scale(base)
    scale = np.array([scales[n] for n in shared])
    fits = []
    for row in _Tracker(base, solve_modes(base), meas).rows:
        fit = fit_parameters(base, meas, candidate.label, shared, scale, FluidAddedMass.signs, keep=np.array([row]))
        if len(fit.measured) == 1:
            label = int(meas.mode[row])
            fits.append(dataclasses.replace(fit, names=[f"{n}_{label}" for n in fit.names],
                                            at_bound=[f"{n}_{label}" for n in fit.at_bound]))  # fmt: skip

    def joined(attr):
        return np.concatenate([getattr(f, attr) for f in fits]) if fits else np.array([])

    return Fit(candidate.label, [n for f in fits for n in f.names], [u for f in fits for u in f.units],
               joined("values"), joined("std"), joined("scale"), joined("measured").astype(int),
               joined("poles_before"), joined("poles_after"), float(sum(f.chi2_before for f in fits)),
               float(sum(f.chi2_after for f in fits)), float(sum(f.log_bayes_factor for f in fits)),
               all(f.converged for f in fits), [n for f in fits for n in f.at_bound])  # fmt: skip


def effect_priors(model: RotorModel, effect) -> dict[str, tuple[float, int]]:
    """``{parameter: (plausible scale [SI], allowed sign)}`` of an effect of ``model``, in parameter order."""
    names = [p.name for p in effect.parameters(model)]
    scales = effect.plausible_scale(model)
    signs = tuple(effect.signs) * (len(names) // max(len(effect.signs), 1))  # per-mode effects repeat theirs
    return {n: (scales[n], g) for n, g in zip(names, signs)}


def prior_scales(model: RotorModel, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """Prior scale [SI] and allowed sign of each parameter, for :func:`fit_parameters`.

    An effect's parameter takes the effect's plausible scale and sign; any other
    parameter :data:`twin.fem.effects.CHANGE_FRACTION` of its nominal value, either sign.

    Examples
    --------
    >>> from twin import load_model
    >>> from twin.loop.candidates import add_effects
    >>> model = add_effects(load_model("models/hydro_unit.toml"), ["magnetic_pull"])
    >>> scale, signs = prior_scales(model, ["MAG.stiffness", "UGB.kxx"])
    >>> signs.tolist(), bool(scale[1] == 0.5 * model.parameter("UGB.kxx").nominal)
    ([-1, 0], True)
    """
    owned = {n: prior for effect in model.effects for n, prior in effect_priors(model, effect).items()}
    scale, sign = [], []
    for n in names:
        nominal = model.parameter(n).nominal  # names an unknown parameter clearly
        s, g = owned.get(n, (CHANGE_FRACTION * abs(nominal), 0))
        if not s > 0:
            raise ModelError(f"parameter '{n}' has no prior scale (nominal {nominal:g}): give it through an effect")
        scale.append(float(s)), sign.append(int(g))
    return np.array(scale), np.array(sign)


def laplace_update(model: RotorModel, meas: Measured, names: Sequence[str]) -> tuple[RotorModel, xr.Dataset]:
    """Gaussian (Laplace) posterior of parameters ``names`` from the measured poles, and the model at its MAP.

    The fit of :func:`fit_parameters` from the model's current values, with the
    priors of :func:`prior_scales`. Poles only: fast, and blind to shape errors.

    Returns
    -------
    (model, posterior) : the model with the MAP values; a Dataset over
        ``parameter`` with ``map``, ``std`` and ``prior_scale`` [SI], attrs
        ``chi2_before``, ``chi2_after``, ``log_bayes_factor``, ``converged``.

    Examples
    --------
    >>> from twin import load_model
    >>> from twin.fem.effects import MagneticPull
    >>> from twin.fem.truthfile import Truth
    >>> from twin.loop.candidates import add_effects
    >>> from twin.loop.compare import measured_modes
    >>> from twin.update import synthesize_modes
    >>> base = load_model("models/hydro_unit.toml")
    >>> data = synthesize_modes(base, Truth((MagneticPull(-1e8),)), n_modes=8, samples=50, seed=1,
    ...                         pole_variance=(0.01, 0.01))
    >>> model = add_effects(base, ["magnetic_pull"])
    >>> updated, post = laplace_update(model, measured_modes(data), ["MAG.stiffness"])
    >>> round(float(post["map"][0]) / -1e8, 2), round(updated.parameter("MAG.stiffness").nominal / -1e8, 2)
    (1.0, 1.0)
    """
    names = list(names)
    scale, signs = prior_scales(model, names)
    fit = fit_parameters(model, meas, "update", names, scale, signs)
    values = {n: model.parameter(n).nominal + v for n, v in zip(names, fit.values)}
    post = xr.Dataset(
        {
            "map": ("parameter", [values[n] for n in names], {"long_name": "posterior mode (Laplace)"}),
            "std": ("parameter", fit.std, {"long_name": "posterior std (Laplace)"}),
            "prior_scale": ("parameter", scale, {"long_name": "prior std (plausible scale)"}),
            "unit": ("parameter", fit.units),
        },
        coords={"parameter": names},
        attrs={"method": "Laplace approximation of the pole-fit posterior (twin.loop.fit.laplace_update)",
               "chi2_before": fit.chi2_before, "chi2_after": fit.chi2_after,
               "log_bayes_factor": fit.log_bayes_factor, "converged": int(fit.converged),
               "at_bound": ", ".join(fit.at_bound)},
    )  # fmt: skip
    if not fit.converged:
        log.warning("Laplace update of %s did not converge in %d iterations", names, MAX_ITERATIONS)
    return model.with_values(values), post
