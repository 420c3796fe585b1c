"""Measured modes as a comparison or an update needs them: sample means, uncertainties, the model's partners.

The measured modes are the sample means of ``modes.nc`` (for SSI jackknife
pseudo-values, the jackknife estimate), with standard errors ``std / √J``
per real and imaginary part of each pole; the shapes are the normalised
sample means on the channels. :func:`pair_with_measured` gives every
measured mode its partner among a model's modes
(:func:`twin.modes.pairing.partners`).
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass

import numpy as np
import xarray as xr

from twin.errors import CompareError
from twin.fem.model import RotorModel
from twin.modes.modesfile import NO_MODES
from twin.modes.pairing import partners
from twin.modes.sensitivity import ModalSolution
from twin.modes.shapes import normalise_shapes

#: Relative pole uncertainty accepted as model-form error (added to the standard error in quadrature). Zero
#: by default: with the right model, the pole errors of 20-min FMU records of the hydro unit against the
#: extraction's jackknife standard errors alone have chi2 / n of about 1 (``benchmarks/loop_suite.py``);
#: a tolerance of 1e-3 made it 0.2 and dulled the diagnosis.
TOLERANCE = 0.0
#: Floor of the measured-pole uncertainty relative to ``|λ|``, for samples that do not scatter (exact synthetic data).
SIGMA_FLOOR = 1e-9


@dataclass(frozen=True)
class Measured:
    """Measured modes reduced to what the comparison needs.

    Attributes
    ----------
    mode : (n,) int
        Mode labels of ``modes.nc``.
    pole : (n,) complex
        Mean pole [1/s].
    sigma : (n, 2) float
        Uncertainty of the real and imaginary part of ``pole`` [1/s]:
        standard error and ``tolerance * |pole|`` added in quadrature.
    shape : (n, c) complex
        Mean shape on the channels (unit norm, largest entry real positive).
    channels : list of str
    source : str
    band_hz : (float, float), optional
        Frequency band the modes were extracted from (``modes.nc`` settings;
        None for modes that did not come from a record).
    duration_s : float, optional
        Length of the record [s].
    zeta_max : float, optional
        Largest damping ratio the extraction accepts.
    targets : str
        The record's target modes, observable or not and found or not (``modes.nc``'s
        ``target_observability`` attr, JSON; empty when the extraction could not judge them).
    """

    mode: np.ndarray
    pole: np.ndarray
    sigma: np.ndarray
    shape: np.ndarray
    channels: list[str]
    source: str = ""
    band_hz: tuple[float, float] | None = None
    duration_s: float | None = None
    zeta_max: float | None = None
    targets: str = ""

    @property
    def frequency(self) -> np.ndarray:
        """Damped frequency [Hz]."""
        return self.pole.imag / (2 * np.pi)

    def subset(self, keep: np.ndarray) -> Measured:
        """The measured modes at indices ``keep``."""
        return dataclasses.replace(
            self, mode=self.mode[keep], pole=self.pole[keep], sigma=self.sigma[keep], shape=self.shape[keep]
        )


def measured_modes(modes: xr.Dataset, tolerance: float = TOLERANCE) -> Measured:
    """Sample means and uncertainties of a modes Dataset (``modes.nc`` layout).

    Examples
    --------
    >>> from twin.modes import measured_modes
    >>> from twin.update import synthesize_modes
    >>> meas = measured_modes(synthesize_modes(hydro_unit, samples=20))
    >>> meas.pole.shape, meas.shape.shape
    ((15,), (15, 8))
    """
    source = str(modes.encoding.get("source", modes.attrs.get("source", modes.attrs.get("title", "modes"))))
    for name in ("pole", "shape"):
        if name not in modes:
            raise CompareError(f"{source}: no variable '{name}' (a modes.nc file has pole and shape samples)")
    if modes.sizes.get("mode", 0) == 0:
        raise CompareError(f"{source}: {NO_MODES}")
    pole, shape = (
        modes["pole"].transpose("mode", "sample").values,
        modes["shape"].transpose("mode", "sample", "channel").values,
    )
    bad = ~np.isfinite(pole).all(axis=1) | ~np.isfinite(shape).all(axis=(1, 2))
    if bad.any():
        raise CompareError(
            f"{source}: mode(s) {modes['mode'].values[bad].tolist()} have non-finite pole or shape samples"
        )
    J = pole.shape[1]
    if J < 2:
        raise CompareError(f"{source}: the uncertainty needs at least 2 samples per mode, got {J}")
    if not 0 <= tolerance < 1:
        raise CompareError(f"tolerance must be in [0, 1), got {tolerance}")
    mean = pole.mean(axis=1)
    se = np.stack([pole.real.std(axis=1, ddof=1), pole.imag.std(axis=1, ddof=1)], axis=1) / np.sqrt(J)
    floor = SIGMA_FLOOR * np.abs(mean)[:, None]
    sigma = np.maximum(np.sqrt(se**2 + (tolerance * np.abs(mean))[:, None] ** 2), floor)
    band, duration, zeta_max = _record(modes)
    return Measured(
        modes["mode"].values,
        mean,
        sigma,
        normalise_shapes(shape.mean(axis=1)),
        [str(c) for c in modes["channel"].values],
        source,
        band,
        duration,
        zeta_max,
        str(modes.attrs.get("target_observability", "")),
    )


def _record(modes: xr.Dataset) -> tuple[tuple[float, float] | None, float | None, float | None]:
    """Band [Hz], record length [s] and largest damping ratio of an extraction, from its ``settings`` attr."""
    try:
        settings = json.loads(modes.attrs["settings"])
        band = (float(settings["fmin_hz"]), float(settings["fmax_hz"]))
        return band, float(settings["duration_s"]), float(settings["criteria"]["zeta_max"])
    except (KeyError, TypeError, ValueError):  # synthetic modes, or settings of another producer
        return None, None, None


def channel_dofs(model: RotorModel, channels: list[str]) -> np.ndarray:
    """The model DOF of each measured channel (error naming the channels the model lacks)."""
    dofs = dict(zip(model.channels, model.sensor_dofs))
    missing = [c for c in channels if c not in dofs]
    if missing:
        raise CompareError(
            f"measured channel(s) {missing} are not sensors of model '{model.name}' "
            f"(its sensors: {', '.join(model.channels)})"
        )
    return np.array([dofs[c] for c in channels])


def pair_with_measured(sol: ModalSolution, meas: Measured, dofs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(mac_matrix, cols)``: model mode ``cols[r]`` of ``sol`` is measured mode ``r``'s partner, for every ``r``.

    ``dofs`` are the model DOFs of the measured channels (:func:`channel_dofs`). Every measured mode gets a
    partner (:func:`twin.modes.pairing.partners`): a mode the model cannot reproduce gets a poor one (low
    MAC, large pole distance), which a comparison reports and counts in its error, never drops.

    Examples
    --------
    >>> from twin.fem.truthfile import Truth
    >>> from twin.modes import solve_modes
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> data = synthesize_modes(model, Truth(()), n_modes=6, samples=5, seed=1, pole_variance=(1e-8, 1e-8))
    >>> meas, sol = measured_modes(data), solve_modes(model)
    >>> _, cols = pair_with_measured(sol, meas, channel_dofs(model, meas.channels))
    >>> cols.tolist(), bool(np.allclose(sol.poles[cols], meas.pole, rtol=1e-4))  # the model's own target modes
    ([0, 2, 4, 5, 6, 7], True)
    """
    return partners(meas.pole, meas.shape, sol.poles, sol.right[:, dofs])


def relative_pole_error(model_pole: np.ndarray, measured_pole: np.ndarray) -> np.ndarray:
    """``|λ − λ̂| / |λ̂|`` of paired poles [1/s]."""
    return np.abs(model_pole - measured_pole) / np.abs(measured_pole)


def overall_error(model_pole: np.ndarray, measured_pole: np.ndarray, sigma: np.ndarray | None = None) -> float:
    """The error ``E`` (a fraction, not %): weighted RMS over modes of the relative pole distance.

    The error of a model against measured modes, as :func:`twin.loop.compare.compare` reports it (its
    module docstring says why the weights).

    Parameters
    ----------
    model_pole, measured_pole : (n,) complex
        Paired poles [1/s].
    sigma : (n, 2) float, optional
        Uncertainty of the real and imaginary part of each measured pole [1/s]
        (:attr:`Measured.sigma`); without it, all modes weigh alike (plain RMS).

    Examples
    --------
    >>> measured = np.array([100j, -60 + 80j])  # |λ| = 100 1/s
    >>> model = np.array([101j, -57 + 80j])  # 1% and 3% off
    >>> round(overall_error(model, measured), 4)  # plain RMS
    0.0224
    >>> round(overall_error(model, measured, np.array([[0.1, 0.1], [1.0, 1.0]])), 4)  # 2nd mode 10x less sure
    0.0104
    """
    if sigma is None:
        return float(np.sqrt(np.mean(relative_pole_error(model_pole, measured_pole) ** 2)))
    delta = (np.asarray(model_pole) - measured_pole) / np.abs(measured_pole)
    w = (np.abs(measured_pole)[:, None] / np.asarray(sigma)) ** 2
    return float(np.sqrt(2 * np.sum(w[:, 0] * delta.real**2 + w[:, 1] * delta.imag**2) / np.sum(w)))
