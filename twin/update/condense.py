"""The perturbed condensed eigen-model (PerCEM): stages 1 and 2 (``docs/explanations/percem.md``).

For one mode with pole ``λ`` and full shape ``a``, the eigen-equation
``Z(λ) a = ε`` with ``Z(λ) = λ² M + λ (C + Ω G) + K`` is linear in the
parameters, ``Z = Z_0 + Σ_k θ_k Z_k``. DOF sets: ``o`` observed (sensor
DOFs, channel order), ``p`` parametrised (touched by a footprint), ``q = p \\ o``,
``o' = o \\ p``, ``r`` all others, ``s = o ∪ q``.

Stage 1 (exact): ``r`` carries no parameter, so the Schur complement
``Ẑ = Z_ss - Z_sr Z_rr⁻¹ Z_rs`` is ``Ẑ_0 + Σ θ_k Z_k,ss``. Its perturbation
``ε̂`` on ``s`` is the latent ``ε`` of the statistical model.

Stage 2 (``|o'| ≥ |q|`` and ``Ẑ_o'q`` of full column rank): the parameter-free
rows ``o'`` give ``a_q = Ẑ_o'q⁺ (ε̂_o' - Ẑ_o'o ψ)``; substituted into the
parametrised rows ``p`` this leaves

    R(λ, θ) ψ + T(λ, θ) ε̂ = 0,   R = Σ_k θ_k R_k,  T = Σ_k θ_k T_k   (θ_0 = 1),

plus the ``|o'| - |q|`` combinations of the ``o'`` rows that ``Ẑ_o'q`` cannot
absorb (parameter-free rows). Otherwise (*latent shape*), ``a_q`` stays an
unknown next to ``ψ`` and the rows are all of ``Ẑ``: ``x = [ψ; a_q]``.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)

#: Singular-value ratio below which ``Ẑ_o'q`` counts as rank deficient (latent-shape fallback).
RANK_TOLERANCE = 1e-9

STAGE_2 = "stage 2"
LATENT_SHAPE = "latent shape"


@dataclass(frozen=True)
class Condensed:
    """The PerCEM basis matrices of one mode at each of its pole samples.

    Attributes
    ----------
    R : (J, 1 + K, n_rows, n_x) complex
        ``R_k(λ_j)``; basis 0 is the fixed part, 1..K the parameters.
    T : (J, 1 + K, n_rows, n_s) complex
        ``T_k(λ_j)``, acting on ``ε̂`` over ``s``.
    method : str
        ``"stage 2"`` or ``"latent shape"``.
    latent_dofs : tuple of int
        Unobserved DOFs kept as latent shape entries (``x = [ψ; a_q]``); empty after stage 2.
    """

    R: np.ndarray
    T: np.ndarray
    method: str
    latent_dofs: tuple[int, ...]

    @property
    def n_x(self) -> int:
        """Length of the complex shape unknown (observed DOFs plus latent ones)."""
        return self.R.shape[-1]


def dynamic_stiffness(mats: Mapping[str, np.ndarray], poles: np.ndarray, speed_rad_s: float) -> np.ndarray:
    """``Z(λ) = λ² M + λ (C + Ω G) + K`` for each pole: shape ``(len(poles), n, n)``.

    Examples
    --------
    >>> one = {"M": np.eye(1), "C": np.zeros((1, 1)), "G": np.zeros((1, 1)), "K": 4 * np.eye(1)}
    >>> dynamic_stiffness(one, np.array([2j]), 0.0)[0]
    array([[0.+0.j]])
    """
    lam = np.asarray(poles, dtype=complex)[:, None, None]
    return lam**2 * mats["M"] + lam * (mats["C"] + speed_rad_s * mats["G"]) + mats["K"]


def parametrised_dofs(bases: Sequence[Mapping[str, np.ndarray]]) -> np.ndarray:
    """DOFs on which any basis matrix has a non-zero row or column."""
    touched = np.zeros(bases[0]["K"].shape[0], dtype=bool) if bases else np.zeros(0, dtype=bool)
    for b in bases:
        for m in b.values():
            touched |= np.any(m != 0, axis=0) | np.any(m != 0, axis=1)
    return np.flatnonzero(touched)


def condense(
    fixed: Mapping[str, np.ndarray],
    bases: Sequence[Mapping[str, np.ndarray]],
    observed: Sequence[int],
    poles: np.ndarray,
    speed_rad_s: float,
    *,
    force_latent: bool = False,
    centre: complex | None = None,
) -> Condensed:
    """PerCEM basis matrices of one mode at its pole samples.

    Parameters
    ----------
    fixed : dict of (n, n) arrays
        ``M, C, G, K`` of everything not updated (updated parameters at zero).
    bases : list of dict of (n, n) arrays
        Footprint matrices ``M_k, C_k, G_k, K_k`` of each updated parameter
        (one unit of the parameter).
    observed : sequence of int
        Observed DOFs, in the order of the shape entries (channels).
    poles : (J,) complex
        Pole samples [1/s].
    speed_rad_s : float
        Rotor speed Ω [rad/s].
    force_latent : bool
        Skip stage 2 even when it is possible (for checks).
    centre : complex, optional
        Pole at which the basis of the extra parameter-free rows is chosen
        (default: the mean of ``poles``). At every pole the extra rows are
        that basis projected on the complement of ``Ẑ_o'q``'s range, so a
        row means the same combination of the ``o'`` rows at every sample
        and the rows vary smoothly with the pole.

    Returns
    -------
    Condensed

    Examples
    --------
    A 3-DOF chain with a spring ``k`` at DOF 2 (unobserved), DOFs 0 and 1 observed:

    >>> K0 = np.array([[2., -1, 0], [-1, 2, -1], [0, -1, 1]])
    >>> fixed = {"M": np.eye(3), "C": np.zeros((3, 3)), "G": np.zeros((3, 3)), "K": K0}
    >>> Kk = np.zeros((3, 3)); Kk[2, 2] = 1.0
    >>> zero = np.zeros((3, 3))
    >>> basis = {"M": zero, "C": zero, "G": zero, "K": Kk}
    >>> lam, vec = np.linalg.eigh(K0 + 0.5 * Kk)          # true k = 0.5
    >>> pole = np.array([1j * np.sqrt(lam[0])])
    >>> c = condense(fixed, [basis], [0, 1], pole, 0.0)
    >>> c.method, c.R.shape
    ('stage 2', (1, 2, 2, 2))
    >>> residual = (c.R[0, 0] + 0.5 * c.R[0, 1]) @ vec[:2, 0]
    >>> bool(np.abs(residual).max() < 1e-12)
    True
    """
    observed = np.asarray(observed, dtype=int)
    poles = np.asarray(poles, dtype=complex)
    n = fixed["K"].shape[0]
    p = parametrised_dofs(bases)
    q = np.setdiff1d(p, observed)
    s = np.concatenate([observed, q])
    r = np.setdiff1d(np.arange(n), s)
    n_o, n_q = len(observed), len(q)

    Z_hat = _schur(fixed, s, r, poles, speed_rad_s)  # stage 1
    # basis matrices restricted to s (their footprints lie in p ⊂ s)
    Zk = (
        np.stack(
            [dynamic_stiffness({k: b[k][np.ix_(s, s)] for k in "MCGK"}, poles, speed_rad_s) for b in bases], axis=1
        )
        if bases
        else np.zeros((len(poles), 0, len(s), len(s)), complex)
    )
    all_k = np.concatenate([Z_hat[:, None], Zk], axis=1)  # (J, 1+K, n_s, n_s)

    in_p = np.isin(s, p)
    prime = np.flatnonzero(~in_p)  # positions of o' in s (all observed)
    p_pos = np.flatnonzero(in_p)
    q_pos = np.arange(n_o, n_o + n_q)
    o_pos = np.arange(n_o)
    stage2 = not force_latent and len(prime) >= n_q
    if stage2 and n_q:
        A = Z_hat[:, prime[:, None], q_pos]  # (J, n_o', n_q)
        U, sv, Vh = np.linalg.svd(A)
        stage2 = bool(np.all(sv[:, -1] > RANK_TOLERANCE * sv[:, 0]))
    if not stage2:
        log.info(
            "PerCEM: %d unobserved parametrised DOFs, %d parameter-free observed rows: latent-shape fallback",
            n_q,
            len(prime),
        )
        T = np.zeros_like(all_k)
        T[:, 0] = -np.eye(len(s))
        return Condensed(all_k, T, LATENT_SHAPE, tuple(int(d) for d in q))

    J = len(poles)
    if n_q:
        A_pinv = np.conj(np.swapaxes(Vh, -1, -2)) @ (np.conj(np.swapaxes(U[:, :, :n_q], -1, -2)) / sv[:, :, None])
        U2h = _extra_rows(U[:, :, n_q:], _complement(fixed, s, r, prime, q_pos, poles, centre, speed_rad_s))
    else:
        A_pinv = np.zeros((J, 0, len(prime)), complex)
        U2h = np.broadcast_to(np.eye(len(prime), dtype=complex), (J, len(prime), len(prime)))
    B = Z_hat[:, prime[:, None], o_pos]  # (J, n_o', n_o)
    G = A_pinv @ B  # a_q = A⁺ ε̂_o' - G ψ
    E = np.zeros((J, n_q, len(s)), complex)  # A⁺ S_o' : ε̂ -> a_q
    E[:, :, prime] = A_pinv
    Zp_o = all_k[:, :, p_pos[:, None], o_pos]  # (J, 1+K, n_p, n_o)
    Zp_q = all_k[:, :, p_pos[:, None], q_pos]  # (J, 1+K, n_p, n_q)
    R_p = Zp_o - Zp_q @ G[:, None]
    T_p = Zp_q @ E[:, None]
    T_p[:, 0, np.arange(len(p_pos)), p_pos] -= 1.0
    n_extra = U2h.shape[1]
    R_x = np.zeros((J, all_k.shape[1], n_extra, n_o), complex)
    T_x = np.zeros((J, all_k.shape[1], n_extra, len(s)), complex)
    R_x[:, 0] = U2h @ B
    T_x[:, 0][:, :, prime] = -U2h
    return Condensed(np.concatenate([R_p, R_x], axis=2), np.concatenate([T_p, T_x], axis=2), STAGE_2, ())


def _schur(
    fixed: Mapping[str, np.ndarray], s: np.ndarray, r: np.ndarray, poles: np.ndarray, speed_rad_s: float
) -> np.ndarray:
    """Stage 1: the Schur complement ``Ẑ = Z_ss − Z_sr Z_rr⁻¹ Z_rs`` at each pole, ``(J, n_s, n_s)``."""
    Z = dynamic_stiffness(fixed, poles, speed_rad_s)
    Z_ss = Z[:, s[:, None], s]
    if not len(r):
        return Z_ss
    return Z_ss - Z[:, s[:, None], r] @ np.linalg.solve(Z[:, r[:, None], r], Z[:, r[:, None], s])


def _complement(fixed, s, r, prime, q_pos, poles, centre, speed_rad_s) -> np.ndarray:
    """Orthonormal basis ``(n_o', n_o' − n_q)`` of the complement of ``Ẑ_o'q``'s range at the centre pole."""
    centre = np.mean(poles) if centre is None else centre
    Z_hat = _schur(fixed, s, r, np.array([centre]), speed_rad_s)[0]
    U = np.linalg.svd(Z_hat[np.ix_(prime, q_pos)])[0]
    return U[:, len(q_pos) :]


def _extra_rows(U2: np.ndarray, N0: np.ndarray) -> np.ndarray:
    """``N0ᴴ P⊥(λ)`` for each pole: the centre basis ``N0`` projected on each pole's complement ``U2`` (J, n_o', ·)."""
    return (np.conj(N0.T) @ U2) @ np.conj(np.swapaxes(U2, -1, -2))


def real_augment(A: np.ndarray) -> np.ndarray:
    """Real form of complex matrices on the last two axes: ``[[Re A, -Im A], [Im A, Re A]]``.

    Acting on ``[Re x; Im x]`` it gives ``[Re(A x); Im(A x)]``.

    Examples
    --------
    >>> real_augment(np.array([[1 + 2j]]))
    array([[ 1., -2.],
           [ 2.,  1.]])
    """
    re, im = A.real, A.imag
    return np.concatenate([np.concatenate([re, -im], axis=-1), np.concatenate([im, re], axis=-1)], axis=-2)


def real_vector(x: np.ndarray) -> np.ndarray:
    """``[Re x; Im x]`` along the last axis."""
    return np.concatenate([x.real, x.imag], axis=-1)


def complex_vector(x: np.ndarray) -> np.ndarray:
    """Inverse of :func:`real_vector`."""
    n = x.shape[-1] // 2
    return x[..., :n] + 1j * x[..., n:]
