"""Poly-reference least-squares complex frequency-domain identification (pLSCF, "PolyMAX") at many orders.

The same covariances as SSI (:mod:`twin.extract.ssi`), read in the frequency
domain. Their half spectra ``S+(f) = sum_k w_k R_k exp(-2 pi i f k / fs)``
over the lags ``k0..L`` (``k0 = first_lag``) are, for a linear structure
under broad-band excitation, a rational matrix function of
``z^-1 = exp(-2 pi i f / fs)`` whose poles are the modes' (a mode contributes
``psi g^T mu^k`` to ``R_k``). With every channel a reference, a right matrix
fraction ``S+ = B(z^-1) A(z^-1)^-1`` of order ``p`` (``A`` an ``m x m`` matrix
polynomial with the identity as its leading coefficient, ``B`` one row per
channel) is fitted over the band of interest by linear least squares with
``B`` eliminated (the reduced normal equations of Guillaume et al. 2003 and
Peeters et al. 2004, "The PolyMAX frequency-domain method"). Its poles are
the eigenvalues of the block companion matrix of ``A`` (``p m`` of them); a
mode's shape is ``B(z_r^-1) x_r`` with ``A(z_r^-1) x_r = 0``.

Why beside SSI: the fit sees only the band, and the window ``w_k =
exp(-k / tau)`` (``tau`` such that ``w_L = 1%``) weighs down the long lags,
where the covariances of heavily damped modes are gone and only their
estimation error is left. On a machine whose modes are damped 4-11% and
overlap (the shipped ``pelton_unit``: eight modes below 100 Hz), SSI found
three of them on 20-min records and this fit, on the same covariances, seven
(``docs/decisions/extraction-plscf.md``). The window's damping is taken off
exactly (``lambda = lambda_w + fs / tau``). The window also sets the
frequency resolution, which lightly damped, slow modes need: their lags must
span many of their periods (more block rows) or SSI serves them better.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The lag window falls to this at the last lag (``tau = L / ln(1 / WINDOW_END)``).
WINDOW_END = 0.01
#: Frequency lines of the half spectra per lag (zero padding), at least.
LINES_PER_LAG = 4
#: Polynomial orders of the stabilisation diagram, at least (a record with many channels and a small
#: ``max_order`` still gets a diagram to stabilise over).
MIN_ORDERS = 4


@dataclass(frozen=True)
class MatrixFraction:
    """The pLSCF fits of one covariance sequence at polynomial orders ``1..P`` (``m`` poles each).

    Its :meth:`modes` answers for a model order ``n`` (the number of poles, a multiple of the channels ``m``,
    as SSI's state dimension), like :class:`twin.extract.ssi.Realisation`.
    """

    T: np.ndarray  # ((P + 1) m, (P + 1) m) sum over channels of Re(Y_o^H Y_o)
    S: np.ndarray  # (l, P + 1, (P + 1) m) Re(X^H Y_o) per channel
    X: np.ndarray  # (P + 1, P + 1) Re(X^H X)
    window_rate: float  # fs / tau [1/s], the damping the lag window adds to every pole
    fs_hz: float

    @property
    def n_channels(self) -> int:
        return self.S.shape[0]

    @property
    def n_references(self) -> int:
        return self.T.shape[0] // self.S.shape[1]

    @property
    def max_order(self) -> int:
        return (self.S.shape[1] - 1) * self.n_references

    @property
    def orders(self) -> np.ndarray:
        """The model orders of the stabilisation diagram: ``m, 2m, ..., P m``."""
        m = self.n_references
        return m * np.arange(1, self.max_order // m + 1)

    def modes(self, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Continuous-time poles [1/s] (``Im > 0`` only) and output shapes ``(l, k)`` at ``order // m`` (at least 1)."""
        m = self.n_references
        p = max(1, int(order) // m)
        q = (p + 1) * m
        S = self.S[:, : p + 1, :q]  # (l, p + 1, q)
        RinvS = np.linalg.solve(self.X[: p + 1, : p + 1], S)  # (l, p + 1, q)
        M = self.T[:q, :q] - np.einsum("oaj,oak->jk", S, RinvS)
        # A(w) = sum_j alpha_j w^j with alpha_p = I: the least-squares alpha_0..alpha_{p-1}
        alpha = np.concatenate([np.linalg.solve(-M[: p * m, : p * m], M[: p * m, p * m :]), np.eye(m)])
        beta = -RinvS @ alpha  # (l, p + 1, m): B_o(w) = sum_j w^j beta_o[j]
        companion = np.zeros((p * m, p * m))
        companion[:-m, m:] = np.eye((p - 1) * m)
        companion[-m:, :] = -alpha[: p * m].reshape(p, m, m).transpose(1, 0, 2).reshape(m, p * m)
        w, v = np.linalg.eig(companion)  # roots w_r = 1 / mu_r of det A(w), v_r = [x_r; w_r x_r; ...]
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = -np.log(w.astype(complex)) * self.fs_hz + self.window_rate
        keep = np.isfinite(lam) & (lam.imag > 0) & (lam.imag < 0.99 * np.pi * self.fs_hz)
        w, x = w[keep], v[:m, keep]
        powers = w[None, :] ** np.arange(p + 1)[:, None]  # (p + 1, k)
        shapes = np.einsum("ojm,jk,mk->ok", beta, powers, x)
        return lam[keep], shapes


def matrix_fraction(
    R: np.ndarray, max_order: int, fs_hz: float, band_hz: tuple[float, float], first_lag: int = 1
) -> MatrixFraction:
    """Half spectra of the covariances ``R`` (lags ``0..L``) and the reduced normal equations of every order.

    Parameters
    ----------
    R : (L + 1, l, l)
        Output covariances; every channel is a reference.
    max_order : int
        Largest number of poles (model order): polynomial orders up to ``max_order // m``, at least
        :data:`MIN_ORDERS`.
    fs_hz : float
        Sampling rate [Hz].
    band_hz : (float, float)
        The band the fraction is fitted over [Hz].
    first_lag : int
        The first lag the half spectra use (lag 0 holds the sensor noise).

    Examples
    --------
    One 2 Hz mode (2% damping) on two channels:

    >>> from twin.extract.ssi import block_covariances
    >>> import scipy.signal as sig
    >>> rng = np.random.default_rng(0)
    >>> lam = 2 * np.pi * 2.0 * (-0.02 + 1j)
    >>> q = sig.lfilter([1.0], [1.0, -np.exp(lam / 20.0)], rng.standard_normal(40_000) + 1j * rng.standard_normal(40_000))
    >>> y = 2 * np.real(q[:, None] * np.array([1.0, 0.6j])) + 0.1 * rng.standard_normal((40_000, 2))
    >>> fit = matrix_fraction(block_covariances(y, 60).covariance(), 8, 20.0, (0.5, 8.0))
    >>> poles, shapes = fit.modes(2)
    >>> f, zeta = poles.imag / (2 * np.pi), -poles.real / np.abs(poles)
    >>> np.round(f[zeta < 0.2], 2), np.round(zeta[zeta < 0.2], 3)
    (array([1.99]), array([0.02]))
    """
    if first_lag < 1 or first_lag >= R.shape[0] - 1:
        raise ValueError(
            f"the half spectra start at lag 1 to {R.shape[0] - 2} (lag 0 holds the sensor noise), got {first_lag}"
        )
    # lags k0, k0 + 1, ... read as 1, 2, ...: the same modes (R_k = sum psi (g^T mu^(k0 - 1)) mu^(k - k0 + 1)), and
    # a numerator of the fraction's order still holds them
    R = np.asarray(R)[first_lag - 1 :]
    L = R.shape[0] - 1
    l, m = R.shape[1], R.shape[2]
    P = max(MIN_ORDERS, int(max_order) // m)
    tau = L / np.log(1.0 / WINDOW_END)
    k = np.arange(L + 1)
    w = np.where(k >= 1, np.exp(-k / tau), 0.0)
    n_fft = int(2 ** np.ceil(np.log2(LINES_PER_LAG * (L + 1))))
    f = np.fft.fftfreq(n_fft, 1.0 / fs_hz)
    band = (f >= band_hz[0]) & (f <= band_hz[1])
    if band.sum() < 2 * (P + 1):
        raise ValueError(
            f"the band {band_hz[0]:g}-{band_hz[1]:g} Hz holds {band.sum()} frequency lines of the half spectra, "
            f"fewer than the {2 * (P + 1)} the fit of order {P} needs"
        )
    H = np.fft.fft(R * w[:, None, None], n=n_fft, axis=0)[band]  # (Nf, l, m)
    H = H / np.abs(H).max()
    X = np.exp(-2j * np.pi * f[band] / fs_hz)[:, None] ** np.arange(P + 1)[None, :]  # (Nf, P + 1)
    G = np.einsum("foi,foj->fij", H.conj(), H)  # sum over channels of H_o^H H_o, (Nf, m, m)
    T = np.einsum("fa,fb,fij->aibj", X.conj(), X, G).real.reshape((P + 1) * m, (P + 1) * m)
    S = -np.einsum("fa,fb,foj->oabj", X.conj(), X, H).real.reshape(l, P + 1, (P + 1) * m)
    return MatrixFraction(T=T, S=S, X=(X.conj().T @ X).real, window_rate=fs_hz / tau, fs_hz=fs_hz)
