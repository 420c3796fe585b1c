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

from twin.fem.model import RotorModel
from twin.fem.parameters import Term
from twin.fmu.statespace import full_state_space, state_modes


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
    >>> from twin import load_model
    >>> sol = solve_modes(load_model("models/hydro_unit.toml"))
    >>> sol.right.shape == sol.left.shape
    True
    """
    ss = full_state_space(model, values=values)
    poles, right, left = state_modes(ss.A)
    n = model.n_dof
    mass = model.matrices(values)["M"]
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
    >>> from twin import load_model
    >>> m = load_model("models/hydro_unit.toml")
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
