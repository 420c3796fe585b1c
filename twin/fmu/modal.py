"""The modal (diagonal) form the FMU steps, its exact step coefficients for any step, and its numpy reference.

A real state space ``x' = A x + B f``, ``y = C x`` with distinct poles is, in modal coordinates
``z = W x`` (``W = V⁻¹``, ``V`` the right eigenvectors, each scaled so that its largest sensor
displacement is 1: a coordinate is the mode's displacement there [m]),

    z_i' = λ_i z_i + (W B)_i f,   y = Σ_i c_i z_i,

one complex first-order system per pole. Conjugate poles carry conjugate coordinates, so the form keeps
one pole of each pair (Im λ > 0) with output weight 2 (``y = Σ 2 Re(C v_i z_i)``) and each real pole with
weight 1. Over a step of any length ``h`` with the force linear between its ends (first-order hold),
the exact update is

    z ← a z + g0 (W B)_i f(t) + g1 (W B)_i (f(t + h) − f(t)),
    a = e^{λh},  g0 = h φ1(λh),  g1 = h φ2(λh),  φ1(x) = (eˣ − 1)/x,  φ2(x) = (eˣ − 1 − x)/x²,

three complex numbers per pole and step length: a step costs ``O(n)`` instead of a dense ``n × n``
product, and a new step length costs ``n/2`` complex exponentials. The FMU's runtime
(``twin/fmu/c/twin_lti.c``) evaluates the same formulas; :func:`simulate_modal` is its numpy reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from scipy.signal import lfilter

from twin.errors import ModelError
from twin.fmu.statespace import StateSpace

#: Largest relative mismatch ``‖V Λ W − A‖ / ‖A‖`` accepted for a modal form (a defective or nearly
#: defective system has no well-conditioned eigenvector basis and is refused with this bound).
MAX_RECONSTRUCTION_ERROR = 1e-8
#: Below this ``|λh|`` the step coefficients are summed from their Taylor series (no cancellation).
SERIES_BELOW = 0.1


@dataclass(frozen=True)
class ModalForm:
    """Diagonal form of a :class:`StateSpace`: one entry per pole kept (Im λ > 0, or real).

    Attributes
    ----------
    poles : (r,) complex
        Poles [1/s], by frequency.
    cv : (m, r) complex
        Output rows, weight included: ``y = Re(cv @ z)`` [m].
    wb : (r, p) complex
        Input rows ``(W B)_i`` per force port [1/(N s)].
    left : (r, n) complex
        ``W`` rows: ``z = left @ x`` for a state ``x`` of the state space.
    """

    poles: np.ndarray
    cv: np.ndarray
    wb: np.ndarray
    left: np.ndarray

    @property
    def n_modes(self) -> int:
        """Number of poles kept (``r``)."""
        return len(self.poles)


def modal_form(ss: StateSpace) -> ModalForm:
    """The diagonal form of ``ss`` (see the module docstring).

    Raises
    ------
    ModelError
        The system has no well-conditioned eigenvector basis (``MAX_RECONSTRUCTION_ERROR``).

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[0.0, 1.0], [-(2 * np.pi) ** 2, -0.2]])
    >>> form = modal_form(StateSpace(A, np.array([[0.0], [1.0]]), np.array([[1.0, 0.0]]), ["0.x"], ["y"], 0.0))
    >>> form.n_modes, bool(np.isclose(form.poles[0].imag / (2 * np.pi), 1.0, rtol=1e-3))
    (1, True)
    """
    lam, right = sla.eig(ss.A)
    try:
        left = np.linalg.inv(right)
    except np.linalg.LinAlgError:
        raise ModelError(
            f"{ss.attrs.get('model', 'the system')}: its eigenvectors are linearly dependent "
            "(a defective system); it has no modal form"
        ) from None
    scale = np.linalg.norm(ss.A, 1)
    mismatch = np.linalg.norm((right * lam) @ left - ss.A, 1) / (scale if scale > 0 else 1.0)
    if not mismatch <= MAX_RECONSTRUCTION_ERROR:
        raise ModelError(
            f"{ss.attrs.get('model', 'the system')}: its modal form reproduces A only to "
            f"{mismatch:.1e} (nearly defective: poles too close for a diagonal form)"
        )
    keep = lam.imag >= 0  # LAPACK returns the poles of a real matrix in exact conjugate pairs
    order = np.lexsort((lam.real[keep], lam.imag[keep]))
    lam, right, left = lam[keep][order], right[:, keep][:, order], left[keep][order]
    # scale each coordinate to metres: its largest sensor displacement is 1 (for a mode no sensor sees,
    # its largest state entry)
    seen = ss.C @ right
    ref = np.where(
        np.abs(seen).max(axis=0) > 0,
        seen[np.abs(seen).argmax(axis=0), np.arange(len(lam))],
        right[np.abs(right).argmax(axis=0), np.arange(len(lam))],
    )
    right, left = right / ref, left * ref[:, None]
    weight = np.where(lam.imag > 0, 2.0, 1.0)
    return ModalForm(lam, (ss.C @ right) * weight, left @ ss.B, left)


def _phi12(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``φ1(x) = (eˣ − 1)/x`` and ``φ2(x) = (eˣ − 1 − x)/x²``, by series where ``|x| < SERIES_BELOW``."""
    x = np.asarray(x, dtype=complex)
    small = np.abs(x) < SERIES_BELOW
    safe = np.where(small, 1.0, x)
    e = np.exp(safe)
    p1, p2 = (e - 1.0) / safe, (e - 1.0 - safe) / safe**2
    s1, s2 = np.zeros_like(x), np.zeros_like(x)
    term = np.ones_like(x)  # x^k / k!
    for k in range(16):  # |x| < 0.1: the 16th term is below 1e-16 of the first
        s1 += term / (k + 1)
        s2 += term / ((k + 1) * (k + 2))
        term = term * x / (k + 1)
    return np.where(small, s1, p1), np.where(small, s2, p2)


def step_coefficients(poles: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``a``, ``g0``, ``g1`` of the exact first-order-hold step of length ``h`` [s] for each pole.

    Examples
    --------
    >>> a, g0, g1 = step_coefficients(np.array([-1.0 + 0j]), 0.5)
    >>> bool(np.isclose(a[0], np.exp(-0.5))), bool(np.isclose(g0[0], 1 - np.exp(-0.5)))
    (True, True)
    """
    if not (np.isfinite(h) and h > 0):
        raise ModelError(f"the time step must be positive, got {h}")
    x = np.asarray(poles, dtype=complex) * h
    p1, p2 = _phi12(x)
    return np.exp(x), h * p1, h * p2


def simulate_modal(
    form: ModalForm, h: float, foh: np.ndarray, zoh: np.ndarray | None = None, z0: np.ndarray | None = None
) -> np.ndarray:
    """Outputs of the modal recursion for port forces sampled every ``h`` [s] (the runtime's reference).

    Parameters
    ----------
    form : ModalForm
    h : float
        Step [s].
    foh : (N, p) array
        Forces linear between samples [N].
    zoh : (N, p) array, optional
        Forces held over each step [N].
    z0 : (r,) complex, optional
        Initial modal state (``form.left @ x0``; zeros by default).

    Returns
    -------
    (N, m) array
        ``y[k]`` at ``t_k = k h``.

    Examples
    --------
    >>> A = np.array([[-1.0]])
    >>> form = modal_form(StateSpace(A, np.array([[1.0]]), np.array([[1.0]]), ["0.x"], ["y"], 0.0))
    >>> round(float(simulate_modal(form, 0.1, np.ones((200, 1)))[-1, 0]), 6)  # static gain 1
    1.0
    """
    a, g0, g1 = step_coefficients(form.poles, h)
    foh = np.asarray(foh, dtype=float)
    delta = np.zeros_like(foh)
    delta[:-1] = np.diff(foh, axis=0)
    drive = (foh @ form.wb.T) * g0 + (delta @ form.wb.T) * g1
    if zoh is not None:
        drive += (np.asarray(zoh, dtype=float) @ form.wb.T) * g0
    z0 = np.zeros(form.n_modes, dtype=complex) if z0 is None else np.asarray(z0, dtype=complex)
    states = np.empty((len(foh), form.n_modes), dtype=complex)
    for i in range(form.n_modes):  # z[0] = z0, z[k] = a z[k-1] + drive[k-1]: a first-order filter per pole
        states[:, i] = lfilter([1.0], [1.0, -a[i]], np.concatenate([[z0[i]], drive[:-1, i]]))
    return np.real(states @ form.cv.T)
