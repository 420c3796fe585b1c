"""A steady start: the FMU's initial state drawn from the stationary response to its built-in excitation.

Started from rest, a lightly damped rotor takes minutes to reach its stationary response (``twin
simulate`` discards a warm-up of several of the slowest mode's time constants). Drawn instead from the
stationary law, the state is stationary from the first sample:

* **Turbulence** (white, first-order hold between draws ``f_k`` of variance ``asd² / (2 h)``): with
  ``w_k = x_k - Γ1 f_k`` the recursion ``x_{k+1} = Φ x_k + Γ0 f_k + Γ1 (f_{k+1} - f_k)`` becomes
  ``w_{k+1} = Φ w_k + (Φ Γ1 + Γ0 - Γ1) f_k``, driven by white noise and independent of ``f_k``. Its
  stationary covariance ``P`` solves the discrete Lyapunov equation ``P = Φ P Φᵀ + M Mᵀ / (2 h)``
  (per unit ASD), and ``x_0 = asd F g + Γ1 f_0`` with ``F = P^½`` (symmetric, so ``F Fᵀ = P``) and ``g`` standard normal.
* **Unbalance** (a force rotating at ω, first-order hold): the periodic solution
  ``x_k = Re(X e^{iω t_k})``, ``X = (z I - Φ)⁻¹ (Γ0 + (z - 1) Γ1) F``, ``z = e^{iωh}``, for the force
  ``Re(F e^{iωt})`` at the unbalance node's two ports.

The export ships ``F`` and ``R = (z I - Φ)⁻¹ (Γ0 + (z - 1) Γ1)`` (every port, since the unbalance node is
a parameter); the runtime forms ``x_0`` at initialisation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from twin.fmu.statespace import Discrete

#: The runtime draws the initial state's normal numbers from the generator seeded with the turbulence seed
#: XOR this constant: a stream of their own, so the turbulence forces are the same with or without them.
STEADY_STREAM = 0xD1B54A32D192ED03


@dataclass(frozen=True)
class SteadyStart:
    """``factor`` (n, n): ``F`` with ``F Fᵀ`` the stationary covariance of ``w`` per unit turbulence ASD
    [m / (N/sqrt(Hz))]; ``response`` (n, p) complex: the periodic state per unit rotating port force [m/N]."""

    factor: np.ndarray
    response: np.ndarray


def steady_start(disc: Discrete, omega_rad_s: float, turbulence_ports: list[int]) -> SteadyStart:
    """The matrices of the steady start for the step matrices ``disc``.

    Examples
    --------
    >>> import numpy as np
    >>> from twin.fmu.statespace import StateSpace, discretize
    >>> A = np.array([[0.0, 1.0], [-(2 * np.pi) ** 2, -0.2]])  # 1 Hz, lightly damped
    >>> ss = StateSpace(A, np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]]), ["0.x"], ["y"], 0.0)
    >>> d = discretize(ss, 0.01)
    >>> s = steady_start(d, 2.0, [0])
    >>> P = s.factor @ s.factor.T  # stationary: P = Φ P Φᵀ + M Mᵀ / (2h)
    >>> M = d.phi @ d.gamma1 + d.gamma0 - d.gamma1
    >>> bool(np.allclose(P, d.phi @ P @ d.phi.T + M @ M.T / 0.02))
    True
    """
    phi, g0, g1, h = disc.phi, disc.gamma0, disc.gamma1, disc.h
    n = phi.shape[0]
    factor = np.zeros((n, n))
    if turbulence_ports:
        M = phi @ g1[:, turbulence_ports] + g0[:, turbulence_ports] - g1[:, turbulence_ports]
        P = sla.solve_discrete_lyapunov(phi, M @ M.T / (2.0 * h))
        # the symmetric square root U √D Uᵀ: unlike U √D it does not depend on which eigenvectors eigh
        # picks in the rotor's nearly degenerate (x, y) eigenspaces, so the initial state is the same
        # whatever the BLAS (or its thread count) on the exporting machine
        d, U = np.linalg.eigh((P + P.T) / 2)
        factor = (U * np.sqrt(np.clip(d, 0.0, None))) @ U.T
    z = np.exp(1j * omega_rad_s * h)
    response = np.linalg.solve(z * np.eye(n) - phi, g0 + (z - 1.0) * g1)
    return SteadyStart(factor, response)


def steady_state(
    start: SteadyStart,
    disc: Discrete,
    *,
    t0_s: float,
    omega_rad_s: float,
    me_kgm: float,
    phase_rad: float,
    unbalance_ports: list[int],
    turbulence_asd: float,
    g: np.ndarray,
    turbulence_ports: list[int],
    f0: np.ndarray,
) -> np.ndarray:
    """The initial state the runtime forms (the numpy reference of it): the unbalance's periodic state at
    ``t0_s``, plus ``turbulence_asd F g`` and ``Γ1 f0`` (``f0``: the turbulence force at ``t0_s``)."""
    c = me_kgm * omega_rad_s**2 * np.exp(1j * (phase_rad + omega_rad_s * t0_s))
    x = np.real(start.response[:, unbalance_ports] @ np.array([c, -1j * c]))
    x = x + turbulence_asd * start.factor @ g
    if turbulence_ports:
        x = x + disc.gamma1[:, turbulence_ports] @ f0
    return x
