"""The model's side of tracking: the tracked modes, their poles at an operating point, the laws learned.

The operating laws of the model (:mod:`twin.fem.operation`) say how each parameter moves with the
conditions; their slopes are what a baseline teaches. A record's modes are predicted by the FEM at the
record's operating point with the current slopes, so the dependence on the conditions is physical (through
the parameters) and not a regression of frequencies; the fit is Gauss-Newton on the slopes, linear in
each step (:func:`fit_laws`), with the declared slopes as a Gaussian prior and one constant offset per
tracked pole part for what the model gets wrong at every operating point alike.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from twin.errors import TwinError
from twin.fem.model import RotorModel
from twin.fem.operation import at_operating_point, operation_of
from twin.modes.analysis import damping_ratio, oscillating
from twin.modes.pairing import partners
from twin.modes.sensitivity import pole_jacobian, solve_modes

#: Modes damped more than this are not tracked (their poles scatter too much from record to record).
MAX_TRACKED_DAMPING = 0.1
#: Prior std of a law's slope as a fraction of its declared value (the declared law is a fair guess).
SLOPE_PRIOR = 1.0
#: Gauss-Newton steps of the baseline's fit at the most, and the relative change that ends it.
FIT_STEPS = 6
FIT_TOLERANCE = 1e-4


@dataclass(frozen=True)
class Tracked:
    """The modes a tracker follows: the model's poles [1/s] and sensor shapes at the reference point."""

    poles: np.ndarray
    shapes: np.ndarray
    channels: tuple[str, ...]

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.poles.imag / (2 * np.pi)


def slope_keys(model: RotorModel) -> list[tuple[str, str]]:
    """``(parameter, condition)`` of every slope of the model's laws, in the laws' order."""
    return [(law.parameter, k) for law in operation_of(model).laws for k, _ in law.slopes]


def declared_slopes(model: RotorModel) -> np.ndarray:
    """The slopes the model file declares, in :func:`slope_keys`' order."""
    return np.array([s for law in operation_of(model).laws for _, s in law.slopes])


def with_slopes(model: RotorModel, slopes: np.ndarray) -> RotorModel:
    """The model with its laws' slopes replaced (in :func:`slope_keys`' order)."""
    op = operation_of(model)
    values = iter(np.asarray(slopes, dtype=float))
    laws = tuple(
        dataclasses.replace(law, slopes=tuple((k, float(next(values))) for k, _ in law.slopes)) for law in op.laws
    )
    return dataclasses.replace(model, operation=dataclasses.replace(op, laws=laws))


def _sensor_shapes(model: RotorModel, right: np.ndarray, channels: tuple[str, ...]) -> np.ndarray:
    by_name = {s.name: s.dof for s in model.sensors}
    return right[:, [by_name[c] for c in channels]]


def tracked_modes(
    model: RotorModel, channels: tuple[str, ...], fmax_hz: float, max_damping: float = MAX_TRACKED_DAMPING
) -> Tracked:
    """The model's modes at the reference operating point that a tracker can follow on ``channels``.

    Forward and backward modes up to ``fmax_hz`` damped less than ``max_damping``.

    Examples
    --------
    >>> unit = hydro_unit
    >>> t = tracked_modes(unit, tuple(unit.channels), 60.0)
    >>> np.round(t.frequency_hz[:3], 2)
    array([ 1.11,  2.74, 10.13])
    """
    ref = at_operating_point(model, {})
    sol = solve_modes(ref)
    keep = oscillating(sol.poles) & (sol.poles.imag / (2 * np.pi) <= fmax_hz) & (damping_ratio(sol.poles) < max_damping)
    idx = np.flatnonzero(keep)
    idx = idx[np.argsort(sol.poles.imag[idx])]
    if idx.size == 0:
        raise TwinError(f"model '{model.name}' has no mode below {fmax_hz:g} Hz damped less than {max_damping:.0%}")
    return Tracked(sol.poles[idx], _sensor_shapes(ref, sol.right[idx], channels), tuple(channels))


def laws_jacobian_columns(model: RotorModel, point: dict[str, float]) -> list[tuple[str, float]]:
    """For each slope (:func:`slope_keys`' order): its parameter and ``c_k - ref_k`` at ``point``."""
    op = operation_of(model)
    point = op.check_point(point)
    return [(p, point[k] - op.condition(k).reference) for p, k in slope_keys(model)]


def predict(
    model: RotorModel, tracked: Tracked, point: dict[str, float], with_jacobian: bool = True
) -> tuple[np.ndarray, np.ndarray | None]:
    """The tracked poles [1/s] of ``model`` at ``point`` and their derivatives by the laws' slopes.

    Each tracked mode is continued to the point by pairing (pole distance and MAC on the channels,
    :func:`twin.modes.pairing.partners`). Returns ``(poles (m,), d poles / d slopes (m, K))``.
    """
    m = at_operating_point(model, point)
    sol = solve_modes(m)
    idx = tracked_indices(m, sol, tracked)
    poles = sol.poles[idx]
    if not with_jacobian:
        return poles, None
    columns = laws_jacobian_columns(model, point)
    names = sorted({p for p, _ in columns})
    jac = pole_jacobian(m, sol, names, modes=idx)
    index = {n: i for i, n in enumerate(names)}
    return poles, np.stack([jac[:, index[p]] * dc for p, dc in columns], axis=1) if columns else np.zeros((len(idx), 0))


def tracked_indices(model: RotorModel, sol, tracked: Tracked) -> np.ndarray:
    """Indices into ``sol.poles`` (a :func:`twin.modes.sensitivity.solve_modes` solution of ``model``) of the
    modes that continue the tracked ones: paired by pole distance and MAC on the channels
    (:func:`twin.modes.pairing.partners`)."""
    up = np.flatnonzero(oscillating(sol.poles))
    shapes = _sensor_shapes(model, sol.right[up], tracked.channels)
    _, cols = partners(tracked.poles, tracked.shapes, sol.poles[up], shapes)
    return up[cols]


def parts(poles: np.ndarray) -> np.ndarray:
    """Real and imaginary parts side by side: ``(..., m)`` complex to ``(..., 2m)`` real."""
    poles = np.asarray(poles)
    return np.concatenate([poles.real, poles.imag], axis=-1)


@dataclass(frozen=True)
class LawFit:
    """The laws learned over a baseline: slopes with their covariance, and the offsets per pole part."""

    slopes: np.ndarray
    covariance: np.ndarray
    offsets: np.ndarray
    keys: tuple[tuple[str, str], ...]
    declared: np.ndarray


def fit_laws(
    model: RotorModel, tracked: Tracked, points: list[dict[str, float]], measured: np.ndarray, sigma: np.ndarray
) -> LawFit:
    """Learn the laws' slopes and the pole offsets from baseline records.

    Parameters
    ----------
    model, tracked
        The model and its tracked modes.
    points : list of dict
        The baseline records' operating points.
    measured, sigma : (n, 2m) arrays
        Measured pole parts (:func:`parts`) and their standard errors per record; NaN where a tracked mode
        was not found.

    Returns
    -------
    LawFit
        The posterior mean and covariance of the slopes, a Gaussian prior centred on the declared slopes
        with :data:`SLOPE_PRIOR` times their size as its std.
    """
    keys = slope_keys(model)
    declared = declared_slopes(model)
    prior_std = np.where(declared != 0, SLOPE_PRIOR * np.abs(declared), 1.0)
    slopes = declared.copy()
    n_out = measured.shape[1]
    ok = np.isfinite(measured) & np.isfinite(sigma) & (sigma > 0)
    w = np.where(ok, 1.0 / np.where(ok, sigma, 1.0) ** 2, 0.0)
    y = np.where(ok, measured, 0.0)
    for _ in range(FIT_STEPS):
        g, jac = zip(*(predict(with_slopes(model, slopes), tracked, p) for p in points))
        G, Jr = parts(np.array(g)), np.array([parts(j.T).T for j in jac])  # (n, 2m), (n, 2m, K)
        # unknowns: slope steps (K) and offsets (2m); residual y - G - offsets - J dslopes
        K = len(keys)
        A = np.zeros((K + n_out, K + n_out))
        b = np.zeros(K + n_out)
        for r in range(len(points)):
            X = np.concatenate([Jr[r], np.eye(n_out)], axis=1)
            A += X.T @ (w[r][:, None] * X)
            b += X.T @ (w[r] * (y[r] - G[r]))
        A[:K, :K] += np.diag(1.0 / prior_std**2)
        b[:K] -= (slopes - declared) / prior_std**2
        A[K:, K:] += np.diag(np.where(A.diagonal()[K:] > 0, 0.0, 1.0))  # an output never measured: offset 0
        step = np.linalg.solve(A, b)
        slopes = slopes + step[:K]
        offsets = step[K:]
        if np.all(np.abs(step[:K]) <= FIT_TOLERANCE * np.maximum(np.abs(slopes), prior_std)):
            break
    cov = np.linalg.inv(A)[:K, :K]
    return LawFit(slopes, cov, offsets, tuple(keys), declared)
