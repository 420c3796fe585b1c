"""Poles of a model and their exact first derivatives with respect to linear parameters.

For the quadratic eigenproblem ``Z(λ) φ = 0``, ``Z(λ) = λ² M + λ (C + Ω G) + K``,
with the left eigenvector ``u`` (``u Z(λ) = 0``) taken from the state-space
left eigenvector ``w = [w1, w2]`` as ``u = w2 M⁻¹`` (so that ``w v = 1``
normalises it), a parameter ``θ_p`` with footprints ``M_p, C_p, G_p, K_p``
moves the pole by

    ∂λ/∂θ_p = −u (λ² M_p + λ (C_p + Ω G_p) + K_p) φ.

The derivative needs only the footprint blocks (a few DOFs each), so a
Jacobian over dozens of parameters costs one eigen-solution.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from twin.fem.model import RPM_TO_RAD_S, RotorModel
from twin.fem.parameters import Term
from twin.modes.analysis import oscillating, state_matrix


def state_modes(A: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Poles (Im > 0, by frequency), right and left state eigenvectors with ``w_i v_i = 1``.

    Returns ``(poles, right, left)`` with ``right`` and ``left`` of shape ``(r, n)``.
    """
    lam, vl, vr = sla.eig(A, left=True, right=True)
    keep = oscillating(lam)
    order = np.argsort(lam.imag[keep], kind="stable")
    lam, vl, vr = lam[keep][order], vl[:, keep][:, order], vr[:, keep][:, order]
    left = vl.conj().T
    left /= np.sum(left * vr.T, axis=1, keepdims=True)
    return lam, vr.T, left


@dataclass(frozen=True)
class ModalSolution:
    """Oscillating modes of a model (Im λ > 0, by frequency) with left and right vectors.

    Attributes
    ----------
    poles : (r,) complex
        Poles [1/s].
    right : (r, n_dof) complex
        Right mode shapes ``φ`` on all DOFs.
    left : (r, n_dof) complex
        Left vectors ``u`` with ``∂λ/∂θ = −u Z_θ(λ) φ``.
    speed_rad_s : float
        Speed the gyroscopic matrix is taken at.
    """

    poles: np.ndarray
    right: np.ndarray
    left: np.ndarray
    speed_rad_s: float


def solve_modes(model: RotorModel, values: Mapping[str, float] | None = None) -> ModalSolution:
    """The model's modes at its running speed, some parameter values replaced.

    Examples
    --------
    >>> from twin.modes import solve_modes
    >>> sol = solve_modes(hydro_unit)
    >>> sol.right.shape == sol.left.shape
    True
    """
    mats = model.matrices(values)
    poles, right, left = state_modes(
        state_matrix(mats["M"], mats["C"], mats["G"], mats["K"], model.speed_rpm * RPM_TO_RAD_S)
    )
    n = model.n_dof
    mass = mats["M"]
    u = sla.cho_solve(sla.cho_factor(mass), left[:, n:].T).T  # M is symmetric: (w2 M⁻¹)ᵀ = M⁻¹ w2ᵀ
    return ModalSolution(poles, right[:, :n], u, model.speed_rad_s)


def _term_factor(term: Term, pole: complex, speed_rad_s: float) -> complex:
    return {"M": pole**2, "C": pole, "G": speed_rad_s * pole, "K": 1.0}[term.kind]


def pole_jacobian(
    model: RotorModel, sol: ModalSolution, names: Sequence[str], modes: Sequence[int] | None = None
) -> np.ndarray:
    """``∂λ_i/∂θ_p`` for the chosen modes (indices into ``sol.poles``) and parameters.

    Parameters
    ----------
    model : RotorModel
        Gives the footprints of the parameters ``names``.
    sol : ModalSolution
        From :func:`solve_modes` at the point of linearisation.
    names : sequence of str
        Parameter names (any, including effect parameters of the model).
    modes : sequence of int, optional
        Mode indices (default: all).

    Returns
    -------
    numpy.ndarray, complex, shape (n_modes, n_params)
        In [1/s per parameter unit].

    Examples
    --------
    >>> m = hydro_unit
    >>> jac = pole_jacobian(m, solve_modes(m), ["runner.m"], modes=[0])
    >>> jac.shape
    (1, 1)
    """
    footprints = model.footprints(list(names))
    return footprint_jacobian(sol, [footprints[n] for n in names], modes)


def footprint_jacobian(
    sol: ModalSolution, footprints: Sequence[Sequence[Term]], modes: Sequence[int] | None = None
) -> np.ndarray:
    """``∂λ_i/∂θ_p`` for footprints given as term lists (one list per parameter), see :func:`pole_jacobian`."""
    idx = np.arange(len(sol.poles)) if modes is None else np.asarray(modes, dtype=int)
    out = np.zeros((len(idx), len(footprints)), dtype=complex)
    for p, terms in enumerate(footprints):
        for term in terms:
            dofs = np.asarray(term.dofs)
            u, phi = sol.left[np.ix_(idx, dofs)], sol.right[np.ix_(idx, dofs)]
            factor = np.array([_term_factor(term, lam, sol.speed_rad_s) for lam in sol.poles[idx]])
            out[:, p] -= factor * np.einsum("ij,jk,ik->i", u, term.value, phi)
    return out


#: Newton iterations at most, and the relative pole step that counts as converged (:func:`follow_mode`).
NEWTON_ITERATIONS = 30
NEWTON_TOLERANCE = 1e-12


def follow_mode(
    model: RotorModel, values: Mapping[str, float] | None, pole: complex, shape: np.ndarray
) -> ModalSolution | None:
    """The one mode of the model at ``values`` that continues the mode ``(pole, shape)``; None if Newton fails.

    Newton's method on the quadratic eigenproblem ``Z(λ) φ = 0`` (Ruhe's
    nonlinear inverse iteration: ``y = Z(λ)⁻¹ Z'(λ) φ``, ``λ ← λ − vᴴφ / vᴴy``,
    ``φ ← y / vᴴy`` with the fixed ``v`` the starting shape), from a nearby
    solution: one 116-DOF factorisation per step instead of the full
    state-space eigen-solution of :func:`solve_modes`. The left vector comes
    from one more solve with the last factorisation, normalised so that
    ``∂λ/∂θ = −u Z_θ(λ) φ`` as in :func:`solve_modes`.

    Examples
    --------
    >>> m = hydro_unit
    >>> sol = solve_modes(m)
    >>> near = follow_mode(m, {"runner.m": 9e4}, sol.poles[4], sol.right[4])
    >>> exact = solve_modes(m, {"runner.m": 9e4})
    >>> bool(np.isclose(near.poles[0], exact.poles[4], rtol=1e-10))
    True
    """
    mats = model.matrices(values)
    M, D, K = mats["M"], mats["C"] + model.speed_rad_s * mats["G"], mats["K"]
    lam, x = complex(pole), np.asarray(shape, dtype=complex)
    v = x / np.vdot(x, x)
    x = x / np.vdot(v, x)
    for _ in range(NEWTON_ITERATIONS):
        with np.errstate(all="ignore"):
            lu = sla.lu_factor(lam**2 * M + lam * D + K, check_finite=False)
            y = sla.lu_solve(lu, (2 * lam * M + D) @ x, check_finite=False)
            vy = np.vdot(v, y)
        if not np.isfinite(vy) or vy == 0:
            return None
        step = np.vdot(v, x) / vy
        lam, x = lam - step, y / vy
        if abs(step) < NEWTON_TOLERANCE * abs(lam):
            break
    else:
        return None
    with np.errstate(all="ignore"):  # Z(λ) is singular now: the solve may overflow, then the full solution is used
        lu = sla.lu_factor(lam**2 * M + lam * D + K, check_finite=False)
        w = sla.lu_solve(lu, v, trans=2, check_finite=False)  # Z(λ)ᴴ w ∝ v: the left vector, up to scale
        w = w / np.linalg.norm(w)
        left = w.conj() / (w.conj() @ (2 * lam * M + D) @ x)
    if not (np.all(np.isfinite(left)) and np.all(np.isfinite(x)) and lam.imag > 0):
        return None
    return ModalSolution(np.array([lam]), x[None, :], left[None, :], model.speed_rad_s)
