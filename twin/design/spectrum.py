"""The output spectrum of a model under the simulated excitation, and the standard errors it bounds.

The excitation is the one :func:`twin.fmu.simulate.simulate` applies: white
turbulence force on the runner (one-sided ASD ``a`` [N/√Hz] in x and y, held
over each sample, hence the factor ``sinc²(f h)``) and white sensor noise of
std ``σ_n`` per sample (one-sided PSD ``2 σ_n² / fs``). The output spectrum of
the linear system is, on a frequency grid,

    S(f) = a² sinc²(f h) H(f) H(f)ᴴ + (2 σ_n² / fs) I,
    H(f) = Σ_j c_j b_jᵀ / (i 2π f − λ_j)   (all state eigenvalues).

**Response against noise.** Mode ``k`` alone at its peak, channel ``c``:
``|c_kc|² |b_k|² a² sinc² / σ_k²`` (``σ_k = −Re λ_k``), divided by the noise
PSD, in dB.

**Expected standard errors (theory, Whittle likelihood).** A record of
length ``T`` gives ``T df`` independent Fourier coefficients per band ``df``,
each complex Gaussian with covariance ``S(f)``, so the Fisher information of
parameters ``p`` is ``F_pq = T ∫ Re tr(S⁻¹ ∂_p S S⁻¹ ∂_q S) df``. Two bounds
come from it (used by :mod:`twin.design.observe` and :mod:`twin.design.identify`):

* the *single-mode bound* (``frequency_std``, ``damping_ratio_std``): the
  mode seen alone through its own shape as a spatial filter, on the
  background of the other modes and the noise (:func:`single_mode_covariance`).
  This is what SSI gets: over 12 independent one-hour FMU records the spread
  of the SSI estimates is 0.4-3.8 times it (median about 2);
* the *Cramér-Rao bound* of the whole multichannel record (``*_crb``,
  :func:`mode_covariance`): it also uses the exact rank of the spectrum (two
  force inputs), which SSI does not; it is 4-20 times lower than the SSI
  spread for the lightly damped modes. It says what a full maximum-likelihood
  estimator could reach.

``benchmarks/extraction.py --seeds N`` is the Monte Carlo check of both.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as sla

from twin.defaults import NOISE_RATIO, RECORD_DURATION_S, SAMPLING_RATE_HZ
from twin.errors import ModelError
from twin.fem.model import RotorModel
from twin.fem.excitation import machine_excitation
from twin.fmu.simulate import sensor_noise_std
from twin.fmu.statespace import StateSpace
from twin.modes.shapes import normalisation_jacobian

#: Points of the Lorentzian-adapted frequency grid around each mode.
GRID_POINTS = 801


@dataclass(frozen=True)
class Excitation:
    """What drives the rotor and what the sensors add, as in :func:`twin.fmu.simulate.simulate`.

    Attributes
    ----------
    turbulence_asd : float, optional
        One-sided ASD of the broad-band force (turbulence, process forces), x and y [N/√Hz]; the machine's
        by default (:func:`twin.fem.excitation.machine_excitation`).
    noise_ratio : float
        Sensor noise std as a fraction of the median channel RMS of the broad-band response
        (ignored when ``noise_std_m`` is given).
    noise_std_m : float, optional
        Sensor noise std [m] per sample.
    duration_s : float
        Record length [s].
    fs_hz : float
        Sampling rate [Hz].
    """

    turbulence_asd: float | None = None
    noise_ratio: float = NOISE_RATIO
    noise_std_m: float | None = None
    duration_s: float = RECORD_DURATION_S
    fs_hz: float = SAMPLING_RATE_HZ

    def check(self) -> None:
        """Raise :class:`ModelError` naming the first setting out of range."""
        for name in ("turbulence_asd", "duration_s", "fs_hz"):
            value = getattr(self, name)
            if value is None and name == "turbulence_asd":
                continue
            if not (np.isfinite(value) and value > 0):
                raise ModelError(f"{name} must be positive, got {value}")
        if not (np.isfinite(self.noise_ratio) and self.noise_ratio >= 0):
            raise ModelError(f"noise_ratio must not be negative, got {self.noise_ratio}")
        if self.noise_std_m is not None and not (np.isfinite(self.noise_std_m) and self.noise_std_m > 0):
            raise ModelError(f"noise_std_m must be positive, got {self.noise_std_m}")


@dataclass(frozen=True)
class Spectrum:
    """The output spectrum model of a system under an excitation (see the module docstring).

    Attributes
    ----------
    poles : (n,) complex
        All eigenvalues of the state matrix [1/s].
    c : (m, n) complex
        Output vectors ``C v_j``.
    b : (n, p) complex
        Turbulence input vectors ``w_j B`` (``p`` = 2 ports, x and y).
    force_psd : float
        ``a²`` [N²/Hz].
    noise_psd : float
        ``2 σ_n² / fs`` [m²/Hz].
    noise_std_m : float
    h : float
        Sample time [s].
    """

    poles: np.ndarray
    c: np.ndarray
    b: np.ndarray
    force_psd: float
    noise_psd: float
    noise_std_m: float
    h: float

    def transfer(self, f_hz: np.ndarray) -> np.ndarray:
        """``H(f)`` [m/N], shape ``(nf, m, p)``."""
        s = 2j * np.pi * np.asarray(f_hz, dtype=float)
        return np.einsum("mj,fj,jp->fmp", self.c, 1.0 / (s[:, None] - self.poles[None, :]), self.b)

    def force_weight(self, f_hz: np.ndarray) -> np.ndarray:
        """``a² sinc²(f h)``: the held force samples' PSD [N²/Hz]."""
        return self.force_psd * np.sinc(np.asarray(f_hz) * self.h) ** 2

    def psd(self, f_hz: np.ndarray) -> np.ndarray:
        """One-sided output cross-spectral matrix [m²/Hz], shape ``(nf, m, m)``."""
        H = self.transfer(f_hz)
        S = self.force_weight(f_hz)[:, None, None] * H @ H.conj().transpose(0, 2, 1)
        return S + self.noise_psd * np.eye(self.c.shape[0])

    def select(self, rows) -> Spectrum:
        """The same system seen by a subset of its channels (``rows``: their indices)."""
        return replace(self, c=self.c[np.asarray(rows, dtype=int)])


def spectrum(ss: StateSpace, model: RotorModel, excitation: Excitation) -> Spectrum:
    """The :class:`Spectrum` of ``ss`` under ``excitation`` (the broad-band force at the machine's node for it).

    Examples
    --------
    >>> from twin.fmu.statespace import full_state_space
    >>> m = hydro_unit
    >>> sp = spectrum(full_state_space(m), m, Excitation())
    >>> sp.psd([10.0]).shape
    (1, 8, 8)
    """
    excitation.check()
    machine = machine_excitation(model)
    asd = machine.broadband_asd if excitation.turbulence_asd is None else excitation.turbulence_asd
    if not asd > 0:
        raise ModelError(f"model '{model.name}': no broad-band force drives it (its [excitation] broadband_asd is 0)")
    ports = ss.node_ports(machine.broadband_node)
    h = 1.0 / excitation.fs_hz
    noise_std = sensor_noise_std(ss, h, asd, ports, excitation.noise_ratio, excitation.noise_std_m)
    lam, V = sla.eig(ss.A)
    c = ss.C @ V
    b = np.linalg.solve(V, ss.B[:, ports])
    noise_psd = max(2.0 * noise_std**2 / excitation.fs_hz, 1e-300)
    return Spectrum(lam, c, b, asd**2, noise_psd, noise_std, h)


def _grid(pole: complex, f_top_hz: float) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies [Hz] and weights [Hz] dense near the pole: ``f = f_k + γ tan u``, ``γ`` its half-width."""
    gamma = max(-pole.real, 1e-12) / (2 * np.pi)
    f_k = pole.imag / (2 * np.pi)
    lo, hi = np.arctan((1e-3 * f_k - f_k) / gamma), np.arctan((f_top_hz - f_k) / gamma)
    u = np.linspace(lo, hi, GRID_POINTS)
    f = f_k + gamma * np.tan(u)
    w = gamma / np.cos(u) ** 2 * np.gradient(u)
    return f, w


def partner_mode(sp: Spectrum, k: int) -> int:
    """Index of the conjugate of pole ``k`` (for a real-data system its vectors are the conjugates)."""
    return int(np.argmin(np.abs(sp.poles - np.conj(sp.poles[k])) + (np.arange(len(sp.poles)) == k) * 1e300))


def mode_fisher(sp: Spectrum, k: int, duration_s: float) -> tuple[np.ndarray, list[str]]:
    """Fisher information of mode ``k``'s parameters from a record of ``duration_s``.

    Parameters: ``Re λ``, ``Im λ`` [1/s], the real and imaginary parts of its
    output vector ``c`` turned so that its largest entry is real positive, in
    units of that entry (the imaginary part of the largest entry fixed), and
    ``log σ_n²``.

    Returns
    -------
    (F, names)
        ``F`` is ``(q, q)``; ``names`` label its rows.
    """
    lam = sp.poles[k]
    partner = partner_mode(sp, k)
    f, w = _grid(lam, 0.5 / sp.h)
    s = 2j * np.pi * f
    ck, bk = sp.c[:, k], sp.b[k]
    m = len(ck)
    ref = int(np.argmax(np.abs(ck)))
    turn = ck[ref] / abs(ck[ref])
    ck, bk = ck / turn, bk * turn  # largest output entry real positive (the product c bᵀ is unchanged)
    g1, g2 = 1.0 / (s - lam), 1.0 / (s - np.conj(lam))
    H = sp.transfer(f)
    # two terms per mode (λ and its conjugate; for a real-data system the partner's vectors are the conjugates)
    cb = np.outer(ck, bk)
    cb_bar = np.outer(sp.c[:, partner], sp.b[partner])
    dH = [
        cb * g1[:, None, None] ** 2 + cb_bar * g2[:, None, None] ** 2,
        1j * cb * g1[:, None, None] ** 2 - 1j * cb_bar * g2[:, None, None] ** 2,
    ]
    names = ["pole.real", "pole.imag"]
    scale = np.abs(ck).max()
    for j in range(m):
        for part, unit in (("real", 1.0), ("imag", 1j)):
            if part == "imag" and j == ref:
                continue
            e = np.zeros((m, 1), dtype=complex)
            e[j, 0] = scale
            term = (
                unit * e * bk[None, :] * g1[:, None, None]
                + np.conj(unit) * e * np.conj(bk)[None, :] * g2[:, None, None]
            )
            dH.append(term)
            names.append(f"shape.{j}.{part}")
    q = np.array(sp.force_weight(f))
    dS = [q[:, None, None] * (d @ H.conj().transpose(0, 2, 1) + H @ d.conj().transpose(0, 2, 1)) for d in dH]
    dS.append(sp.noise_psd * np.broadcast_to(np.eye(m), (len(f), m, m)))
    names.append("log_noise")
    S_inv = np.linalg.inv(sp.psd(f))
    X = np.stack([S_inv @ d for d in dS])  # (p, nf, m, m)
    F = duration_s * np.einsum("f,pfab,qfba->pq", w, X, X).real
    return 0.5 * (F + F.T), names


def mode_covariance(sp: Spectrum, k: int, duration_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Cramér-Rao covariance of mode ``k``'s pole and normalised sensor shape from a record.

    Returns
    -------
    (cov, shape)
        ``cov`` of shape ``(2 + 2m, 2 + 2m)`` over ``[Re λ, Im λ, Re ψ, Im ψ]`` ([1/s] and 1),
        ``ψ`` the shape normalised as everywhere in the package (unit norm, largest
        entry real positive); ``shape`` is that ``ψ``.
    """
    F, _ = mode_fisher(sp, k, duration_s)
    cov = np.linalg.pinv(F, rcond=1e-13, hermitian=True)[:-1, :-1]  # the noise level is a nuisance
    c = sp.c[:, k]
    m, ref = len(c), int(np.argmax(np.abs(c)))
    c = c * abs(c[ref]) / c[ref] / abs(c[ref])  # in units of its largest entry, which is real positive
    norm = np.linalg.norm(c)
    shape = c / norm
    # the Fisher's coordinates are x = [Re c, Im c without Im c_ref]; ψ = x / |x| (Im ψ_ref = 0 throughout)
    to_psi = np.delete(normalisation_jacobian(shape), m + ref, axis=1) / norm
    G = np.zeros((2 + 2 * m, 2 + 2 * m - 1))
    G[:2, :2] = np.eye(2)
    G[2:, 2:] = to_psi
    return G @ cov @ G.T, shape


#: Variance given to a coordinate the data do not inform (its Fisher information is zero).
BLIND_VARIANCE = 1e200


def _pole_block(F: np.ndarray) -> np.ndarray:
    """The ``(Re λ, Im λ)`` block of ``F``'s pseudo-inverse; :data:`BLIND_VARIANCE` where ``F`` is blind to them.

    A coordinate outside the range of ``F`` (a mode with no response on the channels) would get a
    variance of zero from the pseudo-inverse; it is uninformed, so its variance is huge instead.
    """
    cov = np.linalg.pinv(F, rcond=1e-13, hermitian=True)
    seen = np.einsum("ij,ji->i", F, cov)[:2]  # diagonal of the projector onto F's range
    block = cov[:2, :2].copy()
    for i in np.nonzero(seen < 0.5)[0]:
        block[i, :] = block[:, i] = 0.0
        block[i, i] = BLIND_VARIANCE
    return block


def pole_covariance(sp: Spectrum, k: int, duration_s: float) -> np.ndarray:
    """Cramér-Rao covariance of ``(Re λ, Im λ)`` of mode ``k`` [1/s²], the other parameters unknown too."""
    F, _ = mode_fisher(sp, k, duration_s)
    return _pole_block(F)


def _mode_terms(sp: Spectrum, k: int, pole: complex, s: np.ndarray) -> np.ndarray:
    """``H_k(f)``: mode ``k`` and its conjugate alone, with the pole replaced by ``pole``, ``(nf, m, p)``."""
    partner = partner_mode(sp, k)
    cb, cb_bar = np.outer(sp.c[:, k], sp.b[k]), np.outer(sp.c[:, partner], sp.b[partner])
    return cb / (s - pole)[:, None, None] + cb_bar / (s - np.conj(pole))[:, None, None]


def single_mode_covariance(sp: Spectrum, k: int, duration_s: float) -> np.ndarray:
    """Covariance bound of ``(Re λ, Im λ)`` of mode ``k`` for an estimator that sees it alone [1/s²].

    The channels are combined through the mode's own shape ``u = c_k / |c_k|``
    (a modal filter); the scalar spectrum ``uᴴ S u`` is the mode's Lorentzian
    pair on a background of the other modes and the noise. The Whittle Fisher
    information of (Re λ, Im λ, the mode's level, the background's level) on
    that one spectrum gives the bound. Unlike :func:`mode_covariance` it does
    not use the exact two-input structure of the multichannel spectrum, which
    SSI cannot exploit either; over independent FMU records the spread of the
    SSI estimates is 0.4-3.8 times this bound (``benchmarks/extraction.py``).
    """
    lam = sp.poles[k]
    f, w = _grid(lam, 0.5 / sp.h)
    s = 2j * np.pi * f
    u = sp.c[:, k] / np.linalg.norm(sp.c[:, k])
    q = sp.force_weight(f)

    def alone(pole: complex) -> np.ndarray:
        g = np.einsum("a,fap->fp", u.conj(), _mode_terms(sp, k, pole, s))
        return q * np.sum(np.abs(g) ** 2, axis=1)

    total = np.einsum("a,fab,b->f", u.conj(), sp.psd(f), u).real
    own = alone(lam)
    h = 1e-6 * abs(lam)
    d = (
        np.array(
            [
                (alone(lam + h) - alone(lam - h)) / (2 * h),
                (alone(lam + 1j * h) - alone(lam - 1j * h)) / (2 * h),
                own,
                total - own,
            ]
        )
        / total
    )
    F = duration_s * np.einsum("f,pf,qf->pq", w, d, d)
    return _pole_block(F)


def zeta_frequency_std(pole: complex, cov: np.ndarray) -> tuple[float, float]:
    """Std of the damped frequency [Hz] and of the damping ratio from the covariance of ``(Re λ, Im λ)``."""
    mod = abs(pole)
    grad = np.array([-(pole.imag**2) / mod**3, pole.real * pole.imag / mod**3])  # ∂ζ/∂(Re λ, Im λ)
    blind = np.diag(cov) >= BLIND_VARIANCE  # coordinates the data do not inform: infinite std
    f_std = np.inf if blind[1] else np.sqrt(max(cov[1, 1], 0.0)) / (2 * np.pi)
    z_std = np.inf if blind.any() else np.sqrt(max(grad @ cov @ grad, 0.0))
    return float(f_std), float(z_std)
