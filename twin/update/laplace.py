"""The Laplace update: a hypothesis (a set of model parameters) fitted to measured poles, and its evidence.

Data: the measured poles ``λ̂_i`` with uncertainties ``σ`` (real and
imaginary part, see :func:`twin.modes.measured_modes`), every measured
mode paired with a model mode (:func:`twin.modes.measured.pair_with_measured`).
A *hypothesis* is a list of the model's parameters: those of its effects, of
a candidate effect, of a local change, or element coefficients. Each has the
prior ``θ_k = μ_k + s_k u_k``, ``u_k ~ N(0, 1)`` truncated to the
parameter's physical bounds (:attr:`twin.fem.parameters.Parameter.bounds`):
``μ_k = 0`` and ``s_k`` the effect's plausible scale for an effect's
parameter (no effect until the data say so), ``μ_k`` the model's value and
``s_k`` :data:`twin.fem.effects.CHANGE_FRACTION` of it for any other.

The MAP ``u*`` minimises ``½|r(u)|² + ½|u|²`` inside the bounds, ``r`` the
pole residuals in sigmas (projected Levenberg-Marquardt, exact pole
derivatives from :mod:`twin.modes.sensitivity`). The pairing is redone at
every trial point, so a model mode that moves past another is followed to
where it pairs best. That makes the objective jump where a mode changes
partner: a strongly moved mode pairs with a wrong, nearby model mode at the
start, and the first step towards its real partner looks worse. So the
descent starts from the best of a few points along each shared parameter's
prior (:data:`START_POINTS`), the others held at the start. The log evidence of the hypothesis is, to Laplace's
approximation with the Gauss-Newton Hessian ``H = JᵀJ + I``
(:func:`twin.update.evidence.log_evidence`),

    ln Z = −½|r(u*)|² − ½|u*|² − ½ ln det H − Σ_k ln P_k,

``P_k`` the prior mass inside parameter ``k``'s bounds (½ for a sign
constraint); the model as it is, with nothing fitted, has ``ln Z = −½|r|²``.
The log Bayes factor of one hypothesis against another is the difference of
their ``ln Z``: the better fit, less the Occam factor, a parameter the data
pin far more sharply than its plausible scale costing about ``ln(s/σ_θ)``.

A model with per-mode FSI (``fsi_per_mode``) gives each measured mode from its
own FEM, altered by that mode's added mass and damping: its poles cost one
eigen-solution per measured mode, and the mode's own parameters move only it.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from twin.errors import ModelError, UpdateError
from twin.fem.effects import (
    FluidAddedMassPerMode,
    effect_label,
    free_names,
    is_per_mode_name,
    library_effects,
    per_mode_values,
    with_shared_fsi,
)
from twin.fem.model import RotorModel
from twin.modes.measured import (
    TOLERANCE,
    Measured,
    channel_dofs,
    measured_modes,
    overall_error,
    pair_with_measured,
)
from twin.modes.pairing import pairing_cost
from twin.modes.sensitivity import (
    ModalSolution,
    follow_mode,
    pole_jacobian,
    solve_modes,
)
from twin.modes.shapes import mac
from twin.tasks import one_blas_thread
from twin.update.evidence import log_evidence
from twin.update.priors import BoundedPrior, prior_for

log = logging.getLogger(__name__)

#: Start points tried along each shared parameter's prior, in prior units (the best becomes the start).
START_POINTS = (-2.0, -1.0, -0.5, 0.5, 1.0, 2.0)
#: A per-mode partner followed by Newton must keep this MAC (all DOFs) with its last shape, else it is paired anew.
FOLLOW_MAC = 0.9
#: Levenberg-Marquardt iterations at most, and the Newton decrement ``gᵀH⁻¹g / 2`` (a change of the log evidence) that counts as converged.
MAX_ITERATIONS = 40
DECREMENT_TOLERANCE = 1e-3


@dataclass(frozen=True)
class Poles:
    """Model partners of the measured modes at one parameter point: poles, MACs, and ``∂λ/∂θ`` if asked."""

    poles: np.ndarray  # (n,) complex
    mac: np.ndarray  # (n,)
    jacobian: np.ndarray | None  # (n, k) complex, per SI unit of each parameter


class PoleModel:
    """The model's partner of every measured mode as a function of parameter values.

    Examples
    --------
    >>> from twin.modes.measured import measured_modes
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> at = PoleModel(model, measured_modes(synthesize_modes(model, samples=5, seed=1))).at({}, ["runner.m"])
    >>> at.poles.shape, at.jacobian.shape
    ((15,), (15, 1))
    """

    def __init__(self, model: RotorModel, meas: Measured) -> None:
        self.model, self.meas = model, meas
        self.dofs = channel_dofs(model, meas.channels)
        self.per_mode = model.per_mode_effect is not None
        self.base = with_shared_fsi(model) if self.per_mode else model
        self._followed: dict[int, tuple[complex, np.ndarray]] = {}  # per-mode partners, by measured index

    def at(self, values: Mapping[str, float], names: Sequence[str] = ()) -> Poles:
        """Partners at ``values`` (overriding the model's), with ``∂λ/∂θ`` for ``names`` when given."""
        if not self.per_mode:
            sol = solve_modes(self.model, values)
            m, cols = pair_with_measured(sol, self.meas, self.dofs)
            jac = pole_jacobian(self.model, sol, list(names), cols) if len(names) else None
            return Poles(sol.poles[cols], m[np.arange(len(cols)), cols], jac)
        return self._per_mode_at(values, names)

    def _partner(self, r: int, values: Mapping[str, float]) -> tuple[ModalSolution, int]:
        """The partner of measured mode ``r`` in the FEM at ``values``: followed by Newton from its last
        partner (:func:`twin.modes.sensitivity.follow_mode`), or, the first time or when the followed mode
        changed shape (MAC on all DOFs below :data:`FOLLOW_MAC`), chosen by pairing cost among all modes."""
        if r in self._followed:
            pole, shape = self._followed[r]
            sol = follow_mode(self.base, values, pole, shape)
            if sol is not None and mac(shape[None, :], sol.right[:1])[0, 0] >= FOLLOW_MAC:
                self._followed[r] = (sol.poles[0], sol.right[0])
                return sol, 0
        sol = solve_modes(self.base, values)
        cost, _ = pairing_cost(self.meas.pole[[r]], self.meas.shape[[r]], sol.poles, sol.right[:, self.dofs])
        k = int(np.argmin(cost[0]))
        self._followed[r] = (sol.poles[k], sol.right[k])
        return sol, k

    def _per_mode_at(self, values: Mapping[str, float], names: Sequence[str]) -> Poles:
        shared = {k: v for k, v in values.items() if not is_per_mode_name(k)}
        all_values = {**self.model.values, **dict(values)}
        n = len(self.meas.mode)
        poles, macs = np.empty(n, complex), np.empty(n)
        jac = np.zeros((n, len(names)), complex) if len(names) else None
        fsi = ["FSI.added_mass", "FSI.added_damping"]
        for r in range(n):
            label = int(self.meas.mode[r])
            altered = per_mode_values(self.model, self.base, label, all_values)
            sol, k = self._partner(r, {**shared, **altered})
            macs[r] = float(mac(self.meas.shape[r][None, :], sol.right[k, self.dofs][None, :])[0, 0])
            poles[r] = sol.poles[k]
            if jac is None:
                continue
            own = {f"FSI.added_mass_{label}": 0, f"FSI.added_damping_{label}": 1}
            cols = [j for j, nm in enumerate(names) if not is_per_mode_name(nm)]
            if cols:
                jac[r, cols] = pole_jacobian(self.base, sol, [names[j] for j in cols], [k])[0]
            mine = [(j, own[nm]) for j, nm in enumerate(names) if nm in own]
            if mine:
                d = pole_jacobian(self.base, sol, fsi, [k])[0]
                for j, q in mine:
                    jac[r, j] = d[q]
        return Poles(poles, macs, jac)


@dataclass(frozen=True)
class Fit:
    """A fitted hypothesis.

    Attributes
    ----------
    label : str
        What was fitted (a candidate label, ``a+b`` for several, ``update``).
    names, units : list of str
        Fitted parameters.
    values, std : (k,) float
        MAP and Laplace posterior std [SI].
    covariance : (k, k) float
        Laplace posterior covariance [SI].
    scale : (k,) float
        Prior (plausible) scale [SI].
    poles_before, poles_after : (n,) complex
        Partners of every measured mode at the start values and at the MAP.
    mac_after : (n,) float
        Their MAC at the MAP.
    chi2_before, chi2_after : float
        Sum of squared residuals in sigmas.
    log_evidence : float
        ``ln Z`` of the hypothesis (module docstring); comparable between
        hypotheses on the same measured modes.
    log_bayes_factor : float
        ``ln Z`` less that of the reference hypothesis (by default the model
        as it is, at the start values).
    converged : bool
    at_bound : list of str
        Parameters whose MAP sits on a physical bound.
    """

    label: str
    names: list[str]
    units: list[str]
    values: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    scale: np.ndarray
    poles_before: np.ndarray
    poles_after: np.ndarray
    mac_after: np.ndarray
    chi2_before: float
    chi2_after: float
    log_evidence: float
    log_bayes_factor: float
    converged: bool
    at_bound: list[str] = field(default_factory=list)

    def error_before(self, meas: Measured) -> float:
        """The overall error ``E`` at the start values."""
        return overall_error(self.poles_before, meas.pole, meas.sigma)

    def error_after(self, meas: Measured) -> float:
        """The overall error ``E`` at the MAP."""
        return overall_error(self.poles_after, meas.pole, meas.sigma)

    @property
    def residual_dof(self) -> int:
        """Degrees of freedom left to the residuals: two data per measured mode, less the parameters."""
        return 2 * len(self.poles_after) - len(self.names)

    def value_of(self) -> dict[str, float]:
        """``{name: MAP}`` [SI]."""
        return dict(zip(self.names, map(float, self.values)))


def scaled_rows(values: np.ndarray, meas: Measured) -> np.ndarray:
    """Complex per-mode rows (residuals or Jacobian rows) as real parts over σ_re, then imaginary over σ_im."""
    values = np.asarray(values)
    shape = (-1,) + (1,) * (values.ndim - 1)
    sig_re, sig_im = meas.sigma[:, 0].reshape(shape), meas.sigma[:, 1].reshape(shape)
    return np.concatenate([values.real / sig_re, values.imag / sig_im])


def residual(poles: np.ndarray, meas: Measured) -> np.ndarray:
    """Pole residuals of every measured mode in sigmas (real parts, then imaginary parts)."""
    return scaled_rows(poles - meas.pole, meas)


def log_evidence_as_is(model: RotorModel, meas: Measured) -> tuple[float, np.ndarray]:
    """``(ln Z, poles)`` of the model as it is, nothing fitted: ``ln Z = −½|r|²``."""
    at = PoleModel(model, meas).at({})
    r = residual(at.poles, meas)
    return float(-0.5 * r @ r), at.poles


@one_blas_thread
def fit(
    model: RotorModel,
    meas: Measured,
    names: Sequence[str],
    label: str = "fit",
    *,
    reference: float | None = None,
    start: Mapping[str, float] | None = None,
) -> Fit:
    """MAP fit of the hypothesis ``names`` to the measured poles, with its log evidence.

    Parameters
    ----------
    model : RotorModel
        Has every parameter of ``names`` (add candidate effects first).
    meas : Measured
    names : sequence of str
        The hypothesis: parameters to fit, priors from :func:`prior_for`.
    label : str
        Name of the hypothesis in reports.
    reference : float, optional
        ``ln Z`` of the hypothesis to compare with (default: the model as it is).
    start : mapping, optional
        Start values [SI] (default: the model's values, clipped into the bounds).

    Returns
    -------
    Fit

    Examples
    --------
    >>> from twin.fem.effects import MagneticPull
    >>> from twin.fem.truthfile import Truth
    >>> from twin.modes.measured import measured_modes
    >>> from twin.update import synthesize_modes
    >>> base = hydro_unit
    >>> data = synthesize_modes(base, Truth((MagneticPull(-2e8),)), n_modes=8, samples=50, seed=1,
    ...                         pole_variance=(0.01, 0.01))
    >>> f = fit(base.with_effects(MagneticPull()), measured_modes(data), ["MAG.stiffness"], "magnetic_pull")
    >>> round(float(f.values[0]) / -2e8, 1), f.log_bayes_factor > 3
    (1.0, True)
    """
    names = list(names)
    prior = prior_for(model, names)
    pm = PoleModel(model, meas)
    first = {n: model.parameter(n).nominal for n in names} | dict(start or {})
    u0 = prior.coordinates(first)
    u = _best_start(pm, prior, u0, meas)
    at = pm.at(prior.values(u), names)
    as_is = np.array([model.parameter(n).nominal for n in names])
    moved = not np.allclose(list(prior.values(u0).values()), as_is, rtol=1e-12, atol=1e-12 * prior.scale.max(initial=0))
    poles_before = pm.at({}).poles if moved or u is not u0 else at.poles  # the model as it is
    r0 = residual(poles_before, meas)
    r = residual(at.poles, meas)
    J = scaled_rows(at.jacobian * prior.scale[None, :], meas)
    cost = 0.5 * (r @ r + u @ u)
    lo, hi = prior.u_low, prior.u_high
    mu, converged = 1e-3, False
    for _ in range(MAX_ITERATIONS):
        H = J.T @ J + np.eye(len(u))
        g = J.T @ r + u
        # a parameter on a bound, pushed outwards, stays there
        free = ~(((u <= lo) & (g > 0)) | ((u >= hi) & (g < 0)))
        Hf, gf = H[np.ix_(free, free)], g[free]
        if not free.any() or 0.5 * gf @ np.linalg.solve(Hf, gf) < DECREMENT_TOLERANCE:
            converged = True
            break
        step = np.zeros(len(u))
        step[free] = np.linalg.solve(Hf + mu * np.diag(np.diag(Hf)), -gf)
        trial = np.clip(u + step, lo, hi)
        try:
            new = pm.at(prior.values(trial), names)
        except ModelError:  # a point where the model cannot be solved (mass not positive definite): step back
            new = None
        r_new = residual(new.poles, meas) if new is not None else None
        new_cost = 0.5 * (r_new @ r_new + trial @ trial) if new is not None else np.inf
        if new_cost <= cost:
            u, r, cost, at = trial, r_new, new_cost, new
            J = scaled_rows(at.jacobian * prior.scale[None, :], meas)
            mu = max(mu / 3, 1e-9)
        else:
            mu *= 4
            if mu > 1e8:
                converged = True  # no descent direction left: a (possibly constrained) minimum
                break
    H = J.T @ J + np.eye(len(u))
    ln_z = log_evidence(r, u, H, prior.log_mass)
    ref = float(-0.5 * r0 @ r0) if reference is None else float(reference)
    cov = np.linalg.inv(H) * np.outer(prior.scale, prior.scale)
    std = np.sqrt(np.diag(cov))
    on_bound = (np.isfinite(lo) & (u <= lo)) | (np.isfinite(hi) & (u >= hi))
    units = [model.parameter(n).unit for n in names]
    values = np.array([prior.values(u)[n] for n in names])
    return Fit(
        label,
        names,
        units,
        values,
        std,
        cov,
        prior.scale,
        poles_before,
        at.poles.copy(),
        at.mac.copy(),
        float(r0 @ r0),
        float(r @ r),
        ln_z,
        ln_z - ref,
        converged,
        [n for n, b in zip(names, on_bound) if b],
    )


def _best_start(pm: PoleModel, prior: BoundedPrior, u0: np.ndarray, meas: Measured) -> np.ndarray:
    """``u0`` or the point of :data:`START_POINTS` along one shared parameter with the lowest objective."""
    best, best_cost = u0, np.inf
    shared = [k for k, n in enumerate(prior.names) if not is_per_mode_name(n)]
    points = [u0]
    for k in shared:
        for x in START_POINTS:
            u = u0.copy()
            u[k] = np.clip(x, prior.u_low[k], prior.u_high[k])
            if not np.array_equal(u, u0) and not any(np.array_equal(u, q) for q in points):
                points.append(u)
    for u in points:
        try:
            r = residual(pm.at(prior.values(u)).poles, meas)
        except ModelError:
            continue
        cost = 0.5 * (r @ r + u @ u)
        if cost < best_cost:
            best, best_cost = u, cost
    return best


@one_blas_thread
def laplace_update(model: RotorModel, meas: Measured, names: Sequence[str]) -> tuple[RotorModel, xr.Dataset]:
    """Gaussian (Laplace) posterior of parameters ``names`` from the measured poles, and the model at its MAP.

    The fit of :func:`fit` from the model's current values, with the priors
    of :func:`prior_for`. Poles only: fast, and blind to shape errors.

    Returns
    -------
    (model, posterior) : the model with the MAP values; a Dataset over
        ``parameter`` with ``map``, ``std`` and ``prior_scale`` [SI], attrs
        ``chi2_before``, ``chi2_after``, ``log_bayes_factor``, ``converged``.

    Examples
    --------
    >>> from twin.fem.effects import MagneticPull
    >>> from twin.fem.truthfile import Truth
    >>> from twin.loop.candidates import add_effects
    >>> from twin.modes.measured import measured_modes
    >>> from twin.update import synthesize_modes
    >>> base = hydro_unit
    >>> data = synthesize_modes(base, Truth((MagneticPull(-1e8),)), n_modes=8, samples=50, seed=1,
    ...                         pole_variance=(0.01, 0.01))
    >>> model = add_effects(base, ["magnetic_pull"])
    >>> updated, post = laplace_update(model, measured_modes(data), ["MAG.stiffness"])
    >>> round(float(post["map"][0]) / -1e8, 2), round(updated.parameter("MAG.stiffness").nominal / -1e8, 2)
    (1.0, 1.0)
    """
    names = list(names)
    f = fit(model, meas, names, "update")
    values = f.value_of()
    post = xr.Dataset(
        {
            "map": ("parameter", f.values, {"long_name": "posterior mode (Laplace)"}),
            "std": ("parameter", f.std, {"long_name": "posterior std (Laplace)"}),
            "prior_scale": ("parameter", f.scale, {"long_name": "prior std (plausible scale)"}),
            "covariance": (("parameter", "parameter_2"), f.covariance, {"long_name": "posterior covariance (Laplace)"}),
            "low": ("parameter", [model.parameter(n).bounds[0] for n in names], {"long_name": "physical lower bound"}),
            "high": ("parameter", [model.parameter(n).bounds[1] for n in names], {"long_name": "physical upper bound"}),
            "unit": ("parameter", f.units),
        },
        coords={"parameter": names, "parameter_2": names},
        attrs={
            "method": "Laplace approximation of the pole-fit posterior (twin.update.laplace.laplace_update)",
            "chi2_before": f.chi2_before,
            "chi2_after": f.chi2_after,
            "log_bayes_factor": f.log_bayes_factor,
            "converged": int(f.converged),
            "at_bound": ", ".join(f.at_bound),
        },
    )
    if not f.converged:
        log.warning("Laplace update of %s did not converge in %d iterations", names, MAX_ITERATIONS)
    return model.with_values(values), post


def laplace_file(
    post: xr.Dataset, model: RotorModel, modes: xr.Dataset, seed: int | None = 0, command: str = "", draws: int = 1000
) -> xr.DataTree:
    """A Laplace posterior of :func:`laplace_update` of ``model`` in the ``posterior.nc`` layout
    (:func:`twin.update.posterior.laplace_tree`), with the model, its effects and the fit's chi2 in the attrs."""
    from twin.update.posterior import laplace_tree

    attrs = {
        "title": f"Laplace posterior of {model.name}",
        "command": command,
        "model": model.name,
        "method": post.attrs["method"],
        "effects": json.dumps([effect_label(e) for e in model.effects]),
        "chi2_before": post.attrs["chi2_before"],
        "chi2_after": post.attrs["chi2_after"],
        "at_bound": post.attrs["at_bound"],
        "units": json.dumps({str(n): str(u) for n, u in zip(post["parameter"].values, post["unit"].values)}),
    }
    return laplace_tree(post, modes, attrs, draws=draws, seed=seed)


def with_per_mode_fsi(model: RotorModel, labels: Sequence[int]) -> RotorModel:
    """The model with a zero-valued per-mode FSI effect over modes 1 to ``max(labels)``, if it has none.

    Examples
    --------
    >>> with_per_mode_fsi(hydro_unit, [2, 5]).per_mode_effect.n_modes
    5
    """
    if model.per_mode_effect is not None:
        return model
    if not any(e.per_mode for e in library_effects(model)):
        raise ModelError(f"model '{model.name}' has no immersed region for the per-mode FSI")
    n = int(max(labels))
    return model.with_effects(FluidAddedMassPerMode((0.0,) * n, (0.0,) * n))


def laplace_posterior(
    model: RotorModel,
    modes: xr.Dataset,
    names: Sequence[str],
    *,
    fsi: bool = False,
    seed: int | None = 0,
    draws: int = 1000,
    tolerance: float = TOLERANCE,
) -> tuple[RotorModel, xr.Dataset, xr.DataTree]:
    """The Laplace update of ``names`` (and with ``fsi`` each measured mode's added mass and damping) from the
    measured poles of ``modes`` (with ``tolerance`` the relative pole uncertainty accepted as model-form
    error, :func:`twin.modes.measured_modes`): the model at the MAP, the fit's Dataset
    (:func:`laplace_update`) and the posterior in the ``posterior.nc`` layout (:func:`laplace_file`:
    ``draws`` draws of the Gaussian, from ``seed``). :func:`twin.update.update` with ``method="laplace"``
    returns the last.

    Examples
    --------
    >>> from twin.fem.effects import MagneticPull
    >>> from twin.fem.truthfile import Truth
    >>> from twin.update import synthesize_modes
    >>> base = hydro_unit
    >>> data = synthesize_modes(base, Truth((MagneticPull(-1e8),)), n_modes=8, samples=50, seed=1,
    ...                         pole_variance=(0.01, 0.01))
    >>> updated, fitted, tree = laplace_posterior(base.with_effects(MagneticPull()), data, ["MAG.stiffness"])
    >>> sorted(tree.children), round(updated.parameter("MAG.stiffness").nominal / -1e8, 2)
    (['constant_data', 'observed_data', 'posterior', 'sample_stats'], 1.0)
    """
    meas = measured_modes(modes, tolerance)
    names = list(names)
    if fsi:
        model = with_per_mode_fsi(model, meas.mode)
        names += free_names(model, model.per_mode_effect, meas.mode)
    updated, post = laplace_update(model, meas, names)
    return updated, post, laplace_file(post, model, modes, seed, draws=draws)


@dataclass(frozen=True)
class LaplaceOptions:
    """Options of the Laplace update (:func:`twin.update.update` with ``method="laplace"``).

    Attributes
    ----------
    draws : int
        Draws of the Gaussian posterior written to ``posterior.nc`` (kept inside the physical bounds).
    seed : int, optional
        Seed of those draws.
    tolerance : float
        Relative pole uncertainty accepted as model-form error, added to the measured poles' own
        (:func:`twin.modes.measured_modes`).
    """

    draws: int = 1000
    seed: int | None = 0
    tolerance: float = TOLERANCE

    def __post_init__(self) -> None:
        if not (isinstance(self.draws, int) and self.draws >= 1):
            raise UpdateError(f"draws must be a whole number of at least 1, got {self.draws!r}")
        if not (isinstance(self.tolerance, (int, float)) and self.tolerance >= 0):
            raise UpdateError(f"tolerance must be a relative uncertainty of zero or more, got {self.tolerance!r}")

    def settings(self) -> dict:
        """The options as a JSON-ready dict."""
        return dataclasses.asdict(self)
