"""The dense algebra of the condensed residual: designs, combined bases, weighting by ``Δ⁻¹``, the shape system.

Shared by the Gibbs conditionals (:mod:`twin.update.samplers.conditionals`), the
collapsed parameter step (:mod:`twin.update.samplers.collapsed`), the prior on ``Δ``
(:func:`residual_scatter`) and every sampler's identifiability check (:func:`weak_parameters`). ``w`` is the noise
precision: ``(I, n_r)`` for diagonal ``Δ_i``, ``(I, n_r, n_r)`` for full.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from twin.update.problem import Problem

#: Eigenvalue ratio of the (unit-diagonal) parameter precision below which parameters are not identifiable.
SINGULAR_RATIO = 1e-13


def weigh(w: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``X W_i`` for residual-row vectors ``X`` (I, K, J n_r), rows fastest: diagonal ``w`` (I, n_r) or full (I, n_r, n_r)."""
    I, n_r = w.shape[:2]
    if w.ndim == 2:
        return X * np.tile(w, X.shape[-1] // n_r)[:, None, :]
    return (X.reshape(I, X.shape[1], -1, n_r) @ w[:, None]).reshape(X.shape)


def weigh_rows(w: np.ndarray, Hc: np.ndarray) -> np.ndarray:
    """``W_i Hc_ij`` for the stacked matrices ``Hc`` (I, J n_r, n_z) of :func:`combined`."""
    I, n_r = w.shape[:2]
    if w.ndim == 2:
        return Hc * np.tile(w, Hc.shape[1] // n_r)[:, :, None]
    return (w[:, None] @ Hc.reshape(I, -1, n_r, Hc.shape[-1])).reshape(Hc.shape)


def design(problem: Problem, z: np.ndarray) -> np.ndarray:
    """``D[i, k, (j, r)] = (H_ijk z_i)_r``: the residual's column per basis (k = 0 the fixed part)."""
    I, J, n_r, n_z = problem.H0.shape
    K = problem.n_global + problem.n_per_mode
    D = np.zeros((I, 1 + K, J, n_r))
    D[:, 0] = (problem.H0.reshape(I, -1, n_z) @ z[:, :, None]).reshape(I, J, n_r)
    for b in problem.blocks:
        Hz = (b.H.reshape(I, -1, n_z) @ z[:, :, None]).reshape(I, len(b.columns), J, len(b.rows))
        D[:, (1 + b.columns)[:, None], :, b.rows] = Hz.transpose(1, 3, 0, 2)  # advanced indices first
    return D.reshape(I, 1 + K, J * n_r)


def coefficients(problem: Problem, state) -> np.ndarray:
    """``c_i = [1, t, η_i]`` of every mode at a state: (I, 1 + K)."""
    I = problem.n_modes
    return np.concatenate([np.ones((I, 1)), np.broadcast_to(state.t, (I, problem.n_global)), state.eta], axis=1)


def combined(problem: Problem, c: np.ndarray) -> np.ndarray:
    """``Σ_k c_ik H_ijk``: shape (I, J n_r, n_z)."""
    I, J, n_r, n_z = problem.H0.shape
    Hc = problem.H0.copy()
    for b in problem.blocks:
        Hc[:, :, b.rows] += np.einsum("ik,ikjrz->ijrz", c[:, 1 + b.columns], b.H, optimize=True)
    return Hc.reshape(I, J * n_r, n_z)


def shape_prior(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Diagonal precision ``(I, n_z)`` and linear term ``b`` of ``z = (ψ, ε)`` from the shape data and ε's prior.

    Up to a constant, the log density of the shape samples and of ``ε`` is ``−½ Σ prec z² + b·z``.
    """
    I, J, n_r, n_z = problem.H0.shape
    prec = np.zeros((I, n_z))
    prec[:, problem.data_index] = J / problem.psi_var
    prec[:, problem.eps_index] = 1.0 / problem.eps_std**2
    b = np.zeros((I, n_z))
    b[:, problem.data_index] = problem.psi_hat.sum(axis=1) / problem.psi_var
    return prec, b


def shape_system(problem: Problem, Hc: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Precision ``P_i = Σ_j Hc_ijᵀ W_i Hc_ij + Λ_i`` and right-hand side ``b_i`` of the ``z = (ψ, ε)`` conditional."""
    n_z = problem.H0.shape[-1]
    prec, b = shape_prior(problem)
    P = np.swapaxes(Hc, 1, 2) @ weigh_rows(w, Hc)
    P[:, np.arange(n_z), np.arange(n_z)] += prec
    return P, b


def joint_parameters(problem: Problem, blocks: np.ndarray, vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-mode ``(K, K)`` matrices and ``(K,)`` vectors over ``[t, η_i]`` summed into ``[t, η_1, ..., η_I]``.

    The shared parameters ``t`` collect every mode's share; each ``η_i`` only
    its own mode's. ``blocks`` is ``(I, K, K)``, ``vectors`` ``(I, K)``.
    """
    I, Kg, Km = problem.n_modes, problem.n_global, problem.n_per_mode
    n = Kg + I * Km
    A = np.zeros((n, n))
    A[:Kg, :Kg] = blocks[:, :Kg, :Kg].sum(axis=0)
    for i in range(I):
        sl = slice(Kg + i * Km, Kg + (i + 1) * Km)
        A[:Kg, sl] = blocks[i, :Kg, Kg:]
        A[sl, :Kg] = blocks[i, Kg:, :Kg]
        A[sl, sl] = blocks[i, Kg:, Kg:]
    return A, joint_vector(problem, vectors)


def joint_vector(problem: Problem, vectors: np.ndarray) -> np.ndarray:
    """Per-mode ``(K,)`` vectors over ``[t, η_i]`` summed into ``[t, η_1, ..., η_I]`` (see :func:`joint_parameters`)."""
    Kg = problem.n_global
    return np.concatenate([vectors[:, :Kg].sum(axis=0), vectors[:, Kg:].ravel()])


def residual_scatter(problem: Problem) -> np.ndarray:
    """Variance over the pole samples of each residual row at zero parameters and the data's mean shape: (I, n_r).

    ``ε = 0``; latent shape entries (if any) by least squares.
    """
    I, J, n_r, n_z = problem.H0.shape
    Hc = problem.H0.reshape(I, J * n_r, n_z)
    z = np.zeros((I, n_z))
    z[:, problem.data_index] = problem.psi_hat.mean(axis=1)
    latent = np.setdiff1d(np.arange(n_z), np.concatenate([problem.data_index, problem.eps_index]))
    if latent.size:
        for i in range(I):
            z[i, latent] = -np.linalg.lstsq(Hc[i][:, latent], Hc[i] @ z[i], rcond=None)[0]
    r = (Hc @ z[:, :, None]).reshape(I, J, n_r)
    var = r.var(axis=1, ddof=1)
    return np.maximum(var, np.finfo(float).tiny * np.maximum(var.max(axis=1, keepdims=True), 1.0))


def weak_parameters(names: Sequence[str], P: np.ndarray) -> list[str]:
    """Names of the parameters a precision matrix ``P`` leaves undetermined.

    Works on the unit-diagonal precision: a parameter with no effect on the
    residual, or with a large share in a near-null direction (eigenvalue ratio
    below :data:`SINGULAR_RATIO`), is named.

    Examples
    --------
    >>> weak_parameters(["a", "b", "c"], np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 2.0]]))
    ['a', 'b']
    """
    diag = np.diag(P).copy()
    dead = [names[k] for k in np.flatnonzero(diag <= 0)]
    if dead:
        return dead
    d = 1 / np.sqrt(diag)
    ev, vec = np.linalg.eigh(P * d[:, None] * d[None, :])
    small = ev < SINGULAR_RATIO * ev[-1]
    involved = np.flatnonzero(np.any(np.abs(vec[:, small]) > 0.2, axis=1))
    return [names[k] for k in involved]
