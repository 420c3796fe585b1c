"""Linear state-space form of a rotor model, its exact discretisation and a numpy reference.

The FEM ``M q'' + (C + Ω G) q' + K q = F`` becomes

    x' = A x + B f,   y = C_out x,   x = [q, q'],

with one force *port* per translational DOF (``f`` holds the x and y forces
at every node) and one output per sensor channel. A truncated modal basis
keeps the modes up to a frequency, in real 2x2 blocks per conjugate pair.

Exact discretisation over a step ``h`` (no integration error):

* zero-order hold (ZOH), ``f`` constant over the step:
  ``x[k+1] = Φ x[k] + Γ0 f[k]``;
* first-order hold (FOH), ``f`` linear between samples:
  ``x[k+1] = Φ x[k] + Γ0 f[k] + Γ1 (f[k+1] - f[k])``,

with ``Φ = e^{A h}``, ``Γ0 = ∫_0^h e^{A s} ds B`` and
``Γ1 = (1/h) ∫_0^h e^{A s} (h - s) ds B``, all read off one matrix
exponential of an augmented matrix (Van Loan).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.linalg as sla

from twin.errors import ModelError
from twin.fem.elements import DOF_NAMES, node_dofs
from twin.fem.model import RPM_TO_RAD_S, RotorModel
from twin.modes.analysis import state_matrix
from twin.modes.sensitivity import state_modes


@dataclass(frozen=True)
class StateSpace:
    """A continuous LTI system ``x' = A x + B f``, ``y = C x``.

    Attributes
    ----------
    A : (n, n) array
    B : (n, p) array
        One column per force port (``ports``), N -> state derivative.
    C : (m, n) array
        One row per output (``outputs``), state -> displacement [m].
    ports : list of str
        Force port names, ``"<node>.<x|y>"``.
    outputs : list of str
        Output (sensor channel) names.
    speed_rpm : float
        Rotor speed the matrices hold [rpm].
    basis : str
        ``"full"`` or ``"modal"``.
    attrs : dict
        Provenance (model, truth, basis settings).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    ports: list[str]
    outputs: list[str]
    speed_rpm: float
    basis: str = "full"
    attrs: dict = field(default_factory=dict)

    @property
    def n_states(self) -> int:
        """Number of states."""
        return self.A.shape[0]

    def port_index(self, port: str) -> int:
        """Column of ``B`` for a port name like ``"28.x"``."""
        try:
            return self.ports.index(port)
        except ValueError:
            raise ModelError(
                f"no force port '{port}'; ports are '<node>.x' / '<node>.y' for nodes 0..{len(self.ports) // 2 - 1}"
            ) from None

    def node_ports(self, node: int | str) -> list[int]:
        """Columns of ``B`` for the x and y forces at ``node`` (:meth:`port_index` of ``"<node>.x"``, ``"<node>.y"``).

        Examples
        --------
        >>> ss = full_state_space(hydro_unit)
        >>> ss.node_ports(28) == [ss.port_index("28.x"), ss.port_index("28.y")]
        True
        """
        return [self.port_index(f"{node}.{a}") for a in "xy"]

    @cached_property
    def poles(self) -> np.ndarray:
        """Eigenvalues of ``A`` [1/s] (computed once)."""
        return np.linalg.eigvals(self.A)


def force_ports(model: RotorModel) -> list[str]:
    """Names of the translational force ports of a model, ``"<node>.x"``, ``"<node>.y"``."""
    return [f"{n}.{d}" for n in range(model.n_nodes) for d in ("x", "y")]


def _port_dofs(model: RotorModel) -> np.ndarray:
    return np.array([node_dofs(n)[DOF_NAMES.index(d)] for n in range(model.n_nodes) for d in ("x", "y")])


def full_state_space(model: RotorModel, speed_rpm: float | None = None, values=None) -> StateSpace:
    """State-space form of the full FEM (``2 n_dof`` states).

    Examples
    --------
    >>> from twin.fmu import full_state_space
    >>> ss = full_state_space(hydro_unit)
    >>> ss.A.shape, ss.B.shape, ss.C.shape
    ((232, 232), (232, 58), (8, 232))
    """
    speed_rpm = model.speed_rpm if speed_rpm is None else float(speed_rpm)
    mats = model.matrices(values)
    n = model.n_dof
    A = state_matrix(mats["M"], mats["C"], mats["G"], mats["K"], speed_rpm * RPM_TO_RAD_S)
    ports = _port_dofs(model)
    unit = np.zeros((n, len(ports)))
    unit[ports, np.arange(len(ports))] = 1.0
    B = np.vstack([np.zeros((n, len(ports))), sla.cho_solve(sla.cho_factor(mats["M"]), unit)])
    C = np.zeros((len(model.sensors), 2 * n))
    C[np.arange(len(model.sensors)), model.sensor_dofs] = 1.0
    return StateSpace(
        A, B, C, force_ports(model), model.channels, speed_rpm, "full", {"model": model.name, "basis": "full"}
    )


def modal_state_space(
    poles: np.ndarray,
    cv: np.ndarray,
    wb: np.ndarray,
    ports: Sequence[str],
    outputs: Sequence[str],
    speed_rpm: float,
    attrs: dict | None = None,
) -> StateSpace:
    """Real modal state space from complex modes (one of each conjugate pair given).

    Mode ``i`` contributes ``y = 2 Re(C v_i z_i)`` with ``z_i' = λ_i z_i + w_i B f``,
    where ``v_i`` (right) and ``w_i`` (left, ``w_i v_i = 1``) are eigenvectors
    of the *state* matrix. In real coordinates ``(Re z, Im z)`` each mode is a
    2x2 block ``[[σ, -ω], [ω, σ]]``. The modes may come from different
    systems (modal synthesis), hence the projections are given per mode.

    Parameters
    ----------
    poles : (r,) complex
        Eigenvalues with positive imaginary part.
    cv : (m, r) complex
        Output projection ``C v_i`` of each mode.
    wb : (r, p) complex
        Input projection ``w_i B`` of each mode.

    Examples
    --------
    >>> ss = modal_state_space(np.array([-1 + 10j]), np.array([[0.5]]), np.array([[1.0]]), ["0.x"], ["y"], 0.0)
    >>> ss.A
    array([[ -1., -10.],
           [ 10.,  -1.]])
    """
    poles = np.asarray(poles, dtype=complex)
    r = len(poles)
    A = np.zeros((2 * r, 2 * r))
    for i, lam in enumerate(poles):
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[lam.real, -lam.imag], [lam.imag, lam.real]]
    Bm = np.empty((2 * r, wb.shape[1]))
    Bm[0::2], Bm[1::2] = wb.real, wb.imag
    Cm = np.empty((cv.shape[0], 2 * r))
    Cm[:, 0::2], Cm[:, 1::2] = 2 * cv.real, -2 * cv.imag
    return StateSpace(A, Bm, Cm, list(ports), list(outputs), speed_rpm, "modal", dict(attrs or {}))


def truncated_state_space(full: StateSpace, fmax_hz: float) -> StateSpace:
    """Keep the oscillating modes of ``full`` up to ``fmax_hz`` (damped frequency) in a real modal basis.

    Examples
    --------
    >>> from twin.fmu import truncated_state_space
    >>> ss = truncated_state_space(full_state_space(hydro_unit), 100.0)
    >>> ss.n_states
    34
    """
    if not fmax_hz > 0:
        raise ModelError(f"the modal basis needs a positive frequency limit, got {fmax_hz}")
    lam, right, left = state_modes(full.A)
    keep = lam.imag <= 2 * np.pi * fmax_hz
    if not keep.any():
        raise ModelError(f"no mode below {fmax_hz:g} Hz to build a modal basis from")
    attrs = {**full.attrs, "basis": "modal", "fmax_hz": fmax_hz, "n_modes": int(keep.sum())}
    return modal_state_space(
        lam[keep], full.C @ right[keep].T, left[keep] @ full.B, full.ports, full.outputs, full.speed_rpm, attrs
    )


def check_stable(ss: StateSpace, name: str) -> None:
    """Raise a ModelError naming the growing modes if any pole has a positive real part."""
    growing = ss.poles[ss.poles.real > 0]
    if growing.size:
        freqs = ", ".join(f"{f:.3f}" for f in sorted({abs(p.imag) / (2 * np.pi) for p in growing}))
        raise ModelError(
            f"{name} is unstable at {ss.speed_rpm:g} rpm: modes at [{freqs}] Hz grow; a simulation of it would diverge"
        )


@dataclass(frozen=True)
class Discrete:
    """Exact step matrices of a :class:`StateSpace` for step ``h``: ``Φ``, ``Γ0``, ``Γ1``."""

    phi: np.ndarray
    gamma0: np.ndarray
    gamma1: np.ndarray
    h: float


def discretize(ss: StateSpace, h: float) -> Discrete:
    """Exact ZOH/FOH step matrices for step ``h`` [s] from one matrix exponential.

    ``expm([[A, B, 0], [0, 0, I/h], [0, 0, 0]] h)`` has first block row
    ``[Φ, Γ0, Γ1]``.

    Examples
    --------
    >>> import numpy as np
    >>> from twin.fmu import discretize
    >>> ss = StateSpace(np.array([[-1.0]]), np.array([[1.0]]), np.array([[1.0]]), ["0.x"], ["y"], 0.0)
    >>> d = discretize(ss, 0.5)
    >>> bool(np.isclose(d.phi[0, 0], np.exp(-0.5))), bool(np.isclose(d.gamma0[0, 0], 1 - np.exp(-0.5)))
    (True, True)
    """
    if not (np.isfinite(h) and h > 0):
        raise ModelError(f"the time step must be positive, got {h}")
    n, p = ss.B.shape
    big = np.zeros((n + 2 * p, n + 2 * p))
    big[:n, :n] = ss.A * h
    big[:n, n : n + p] = ss.B * h
    big[n : n + p, n + p :] = np.eye(p)
    E = sla.expm(big)
    return Discrete(E[:n, :n], E[:n, n : n + p], E[:n, n + p :], h)


def simulate_reference(
    disc: Discrete,
    C: np.ndarray,
    zoh: np.ndarray | None = None,
    foh: np.ndarray | None = None,
    x0: np.ndarray | None = None,
) -> np.ndarray:
    """Outputs of the exact recursion for sampled forces (the numpy reference).

    Forces held constant over each step (``zoh``) and forces linear between
    samples (``foh``) superpose, so one port may carry both.

    Parameters
    ----------
    disc : Discrete
    C : (m, n) output matrix
    zoh, foh : (N, p) arrays, optional
        Port forces at the sample times ``t_k = k h`` [N].
    x0 : initial state (zeros by default)

    Returns
    -------
    (N, m) array
        ``y[k] = C x[k]``, ``x[0] = x0``.

    Examples
    --------
    >>> import numpy as np
    >>> from twin.fmu import simulate_reference
    >>> ss = StateSpace(np.array([[-1.0]]), np.array([[1.0]]), np.array([[1.0]]), ["0.x"], ["y"], 0.0)
    >>> y = simulate_reference(discretize(ss, 0.1), ss.C, zoh=np.ones((200, 1)))
    >>> round(float(y[-1, 0]), 6)  # step response settles at the static gain 1
    1.0
    """
    given = [f for f in (zoh, foh) if f is not None]
    if not given:
        raise ValueError("give zoh and/or foh forces")
    N = len(given[0])
    x = np.zeros(disc.phi.shape[0]) if x0 is None else np.array(x0, dtype=float)
    drive = np.zeros((N, disc.phi.shape[0]))
    if zoh is not None:
        drive += np.asarray(zoh, dtype=float) @ disc.gamma0.T
    if foh is not None:
        foh = np.asarray(foh, dtype=float)
        delta = np.zeros_like(foh)
        delta[:-1] = np.diff(foh, axis=0)
        drive += foh @ disc.gamma0.T + delta @ disc.gamma1.T
    out = np.empty((N, C.shape[0]))
    phi_t = disc.phi.T
    for k in range(N):
        out[k] = C @ x
        x = x @ phi_t + drive[k]
    return out
