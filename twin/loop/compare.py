"""Compare a model with measured modes: per-mode errors, per-sensor shape errors, one overall error.

The measured modes are the sample means of ``modes.nc`` (for SSI jackknife
pseudo-values, the jackknife estimate), with standard errors ``std / √J``.
Every measured mode gets a model partner, one-to-one, by the least total
pairing cost ``|λ − λ̂| / |λ̂| + (1 − MAC)`` (complex MAC on the sensor
channels): no measured mode is ever left out of the error. A partner with a
MAC below :data:`MIN_MAC` means the model has no mode like the measured one;
the comparison lists such modes (``poorly_paired``) and their large
residuals count in ``E`` and χ² like any other.

**The error** of a model is one number, the RMS over the measured modes of the
relative pole distance ``|λ_i − λ̂_i| / |λ̂_i|``, each mode's real and imaginary
part weighed by the inverse variance of its measurement::

    E² = 2 Σ_i (w_i,re Δre_i² + w_i,im Δim_i²) / Σ_i (w_i,re + w_i,im),
    with Δ = (λ − λ̂)/|λ̂| and w = (|λ̂| / σ)²,

where σ is the standard error of the samples plus ``tolerance · |λ̂|`` in
quadrature. With equal weights this is the plain RMS ``sqrt(mean_i |Δ_i|²)``.
Since ``λ = ω (−ζ + i sqrt(1 − ζ²))``, ``|Δλ|/|λ| ≈ sqrt((Δf/f)² + Δζ²)``: a 1%
frequency error weighs as much as a damping-ratio error of one percentage
point. The weights make ``E`` the χ² of the comparison written as a relative
pole error, ``E² = 2 χ² / Σ (|λ̂| / σ)²``: modes measured better than the
tolerance weigh alike, and a mode the record resolves only to a few percent (a
heavily damped one) weighs less, so that one noisy mode does not set the
error of a model that is right. The plain RMS is kept as ``error_rms``. The
table behind ``E`` has the frequency and damping errors of every mode, their
z-scores against the measurement uncertainty, the MAC, and the shape error of
every sensor.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import xarray as xr

from twin import __version__
from twin.errors import CompareError, ModelError
from twin.fem.effects import is_per_mode_name, per_mode_values, with_shared_fsi
from twin.fem.model import RotorModel
from twin.modes.analysis import damping_ratio
from twin.modes.measured import (
    TOLERANCE,
    Measured,
    channel_dofs,
    measured_modes,
    overall_error,
    pair_with_measured,
    relative_pole_error,
)
from twin.modes.pairing import pairing_cost
from twin.modes.sensitivity import solve_modes
from twin.modes.shapes import normalise_shapes
from twin.tasks import one_blas_thread

log = logging.getLogger(__name__)

#: What the ``error`` attr of a comparison is (see the module docstring).
ERROR_DEFINITION = (
    "RMS over the measured modes of |model pole - measured pole| / |measured pole|, real and "
    "imaginary parts weighed by the inverse variance of the measured pole"
)
#: What E weighs, in a sentence for the tables and reports that show it beside the per-mode errors.
ERROR_WEIGHTS = (
    "E weighs each mode's error by the inverse variance of its measured pole: a mode the record "
    "determines well counts much, one it hardly determines (a wide error bar) little, so E can be small "
    "beside a large error of such a mode; the unweighted RMS weighs every mode alike"
)
#: A measured mode whose partner has a MAC below this is reported as one the model cannot reproduce.
MIN_MAC = 0.5


@dataclass(frozen=True)
class ModelModes:
    """The model's partner of each measured mode: ``poles[k]``, ``shapes[k]`` (all DOFs) for measured index ``measured[k]``."""

    measured: np.ndarray  # indices into Measured (every measured mode)
    poles: np.ndarray
    shapes: np.ndarray  # on all DOFs
    mac: np.ndarray
    mac_matrix: np.ndarray  # measured x model, for plots (single-FEM modes)
    model_frequency: np.ndarray  # Hz, the single-FEM modes of the matrix
    partner: np.ndarray  # column of mac_matrix paired with each measured mode (the nearest for a per-mode model)


@one_blas_thread
def model_modes(model: RotorModel, meas: Measured, values: Mapping[str, float] | None = None) -> ModelModes:
    """The model's partner of every measured mode (:func:`pair_with_measured`).

    A model with a per-mode effect (per-mode FSI) gives measured mode ``k``
    (label ``k``) from the FEM altered by that mode's values (zero for a
    label beyond the values the effect has): its partner is the mode of that
    FEM of least :func:`pairing_cost`.
    """
    dofs = channel_dofs(model, meas.channels)
    sol = solve_modes(model, values)
    m, cols = pair_with_measured(sol, meas, dofs)
    rows = np.arange(len(meas.mode))
    per_mode = model.per_mode_effect
    if per_mode is None:
        return ModelModes(rows, sol.poles[cols], sol.right[cols], m[rows, cols], m, sol.poles.imag / (2 * np.pi), cols)
    poles, shapes, macs = [], [], []
    base = with_shared_fsi(model)
    all_values = {**model.values, **dict(values or {})}
    for r in rows:  # each measured mode against its own altered FEM
        label = int(meas.mode[r])
        altered = per_mode_values(model, base, label, all_values)
        try:
            s = solve_modes(base, {**_shared_values(values), **altered})
        except ModelError as exc:
            raise CompareError(f"mode {label} of the per-mode model cannot be solved at {altered}: {exc}") from None
        cost, mm = pairing_cost(meas.pole[[r]], meas.shape[[r]], s.poles, s.right[:, dofs])
        k = int(np.argmin(cost[0]))
        poles.append(s.poles[k]), shapes.append(s.right[k]), macs.append(mm[0, k])
    return ModelModes(
        rows, np.array(poles, dtype=complex), np.array(shapes), np.array(macs), m, sol.poles.imag / (2 * np.pi), cols
    )


def _shared_values(values: Mapping[str, float] | None) -> dict[str, float]:
    """The values of a per-mode model's single-FEM parameters (the per-mode ones left out)."""
    return {k: v for k, v in dict(values or {}).items() if not is_per_mode_name(k)}


def _shape_error(model_shape: np.ndarray, measured_shape: np.ndarray) -> np.ndarray:
    """|ψ_model a − ψ̂| per channel, ``a`` the complex factor that fits best (unit-norm shapes)."""
    mod = normalise_shapes(model_shape)
    a = np.sum(mod.conj() * measured_shape, axis=-1, keepdims=True) / np.sum(np.abs(mod) ** 2, axis=-1, keepdims=True)
    return np.abs(a * mod - measured_shape)


@one_blas_thread
def compare(
    model: RotorModel,
    modes: xr.Dataset | Measured,
    *,
    values: Mapping[str, float] | None = None,
    tolerance: float = TOLERANCE,
    min_mac: float = MIN_MAC,
) -> xr.Dataset:
    """Model against measured modes: the per-mode and per-sensor table and the overall error.

    Parameters
    ----------
    model : RotorModel
    modes : xarray.Dataset or Measured
        Measured modes (``modes.nc`` layout) or their summary.
    values : mapping, optional
        Parameter values overriding the model's.
    tolerance : float
        Relative pole uncertainty added to the standard error in the z-scores.
    min_mac : float
        A partner with a lower MAC is reported as poorly paired (``poorly_paired``).

    Returns
    -------
    xarray.Dataset
        Dimensions ``mode`` (every measured mode) and ``channel``;
        per-mode variables (measured and model poles, frequencies, damping
        ratios, their errors and z-scores, ``pole_error``, ``mac``), ``shape_error``
        (mode x channel), ``channel_shape_error``, ``mac_matrix``; attrs
        ``error`` (E, a fraction), ``chi2``, ``n_data``, ``poorly_paired``
        (measured modes whose partner has a MAC below ``min_mac``) and, when ``modes.nc`` has
        them, ``target_observability`` (the record's target modes, observable or not: never counted).

    Examples
    --------
    >>> from twin.loop import compare
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> table = compare(model, synthesize_modes(model, samples=20, seed=1))
    >>> round(100 * table.attrs["error"], 2)  # the model lacks the water's added mass: E in %
    1.91
    """
    meas = modes if isinstance(modes, Measured) else measured_modes(modes, tolerance)
    mm = model_modes(model, meas, values)
    m = meas
    dofs = channel_dofs(model, meas.channels)
    f_meas, f_mod = m.pole.imag / (2 * np.pi), mm.poles.imag / (2 * np.pi)
    z_meas, z_mod = damping_ratio(m.pole), damping_ratio(mm.poles)
    resid = mm.poles - m.pole
    z_re, z_im = resid.real / m.sigma[:, 0], resid.imag / m.sigma[:, 1]
    shape_err = _shape_error(mm.shapes[:, dofs], m.shape)
    poorly = m.mode[mm.mac < min_mac]
    error = overall_error(mm.poles, m.pole, m.sigma)
    pct = {"units": "1"}
    ds = xr.Dataset(
        {
            "measured_frequency": ("mode", f_meas, {"units": "Hz"}),
            "model_frequency": ("mode", f_mod, {"units": "Hz"}),
            "frequency_error": (
                "mode",
                f_mod / f_meas - 1,
                {**pct, "long_name": "relative frequency error (model / measured - 1)"},
            ),
            "measured_damping_ratio": ("mode", z_meas, pct),
            "model_damping_ratio": ("mode", z_mod, pct),
            "damping_error": ("mode", z_mod - z_meas, {**pct, "long_name": "damping ratio error (model - measured)"}),
            "relative_damping_error": (
                "mode",
                z_mod / z_meas - 1,
                {**pct, "long_name": "relative damping ratio error"},
            ),
            "pole_error": (
                "mode",
                relative_pole_error(mm.poles, m.pole),
                {**pct, "long_name": "|model pole - measured pole| / |measured pole|"},
            ),
            "z_frequency": (
                "mode",
                z_im,
                {**pct, "long_name": "imaginary-part error in measurement sigmas (sign of the frequency error)"},
            ),
            "z_damping": (
                "mode",
                -z_re,
                {
                    **pct,
                    "long_name": "minus the real-part error in measurement sigmas (sign of the damping error: the real part is -zeta omega)",
                },
            ),
            "frequency_sigma": (
                "mode",
                m.sigma[:, 1] / np.abs(m.pole.imag),
                {**pct, "long_name": "relative standard uncertainty of the measured frequency"},
            ),
            "damping_sigma": (
                "mode",
                m.sigma[:, 0] / np.abs(m.pole),
                {**pct, "long_name": "standard uncertainty of the measured damping ratio"},
            ),
            "mac": ("mode", mm.mac, pct),
            "partner": (
                "mode",
                mm.partner + 1,
                {"long_name": "model mode (column of mac_matrix) paired with the measured mode"},
            ),
            "measured_pole": ("mode", m.pole, {"units": "1/s", "long_name": "measured mean pole"}),
            "model_pole": ("mode", mm.poles, {"units": "1/s", "long_name": "model pole"}),
            "measured_shape": (("mode", "channel"), m.shape, {**pct, "long_name": "measured mean shape"}),
            "model_shape": (
                ("mode", "channel"),
                normalise_shapes(mm.shapes[:, dofs]),
                {**pct, "long_name": "model shape"},
            ),
            "shape_error": (
                ("mode", "channel"),
                shape_err,
                {**pct, "long_name": "|aligned model shape - measured shape| (unit norm)"},
            ),
            "channel_shape_error": (
                "channel",
                np.sqrt(np.mean(shape_err**2, axis=0)),
                {**pct, "long_name": "RMS shape error over modes"},
            ),
            "mac_matrix": (("mode_measured", "mode_model"), mm.mac_matrix, pct),
            "model_mode_frequency": ("mode_model", mm.model_frequency, {"units": "Hz"}),
        },
        coords={
            "mode": ("mode", m.mode),
            "channel": ("channel", meas.channels),
            "mode_measured": ("mode_measured", meas.mode),
            "mode_model": ("mode_model", np.arange(1, len(mm.model_frequency) + 1)),
        },
        attrs={
            "title": f"{model.name} against {meas.source}",
            "producer": f"twin {__version__} twin.loop.compare",
            "error": error,
            "error_definition": ERROR_DEFINITION,
            "error_rms": overall_error(mm.poles, m.pole),
            "chi2": float(np.sum(z_re**2 + z_im**2)),
            "n_data": int(2 * len(m.mode)),
            "tolerance": tolerance,
            "min_mac": min_mac,
            "poorly_paired": np.array(poorly, dtype=int),
            "model": model.name,
        },
    )
    if m.targets:
        ds.attrs["target_observability"] = m.targets
    if len(poorly):
        log.info("measured mode(s) %s have no model mode like them (partner MAC < %g)", poorly.tolist(), min_mac)
    return ds


def error_text(table: xr.Dataset) -> str:
    """``E = …%`` with what it is and the unweighted RMS beside it, from a comparison table.

    Examples
    --------
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> print(error_text(compare(model, synthesize_modes(model, samples=20, seed=1))))  # doctest: +NORMALIZE_WHITESPACE
    E = 1.91% (15 measured modes; RMS over the measured modes of |model pole - measured pole| / |measured pole|,
    real and imaginary parts weighed by the inverse variance of the measured pole; unweighted RMS 6.61%)
    """
    return (
        f"E = {100 * table.attrs['error']:.2f}% ({table.sizes['mode']} measured modes; "
        f"{table.attrs['error_definition']}; unweighted RMS {100 * table.attrs['error_rms']:.2f}%)"
    )


COMPARISON_COLUMNS = (
    "measured_frequency",
    "model_frequency",
    "frequency_error",
    "measured_damping_ratio",
    "model_damping_ratio",
    "damping_error",
    "pole_error",
    "z_frequency",
    "z_damping",
    "mac",
)


def comparison_json(table: xr.Dataset) -> dict:
    """The ``twin compare --json`` layout of a comparison table: ``E`` and its terms, one entry per measured mode.

    Frequencies in Hz, damping ratios as fractions; ``channel_shape_error`` per sensor channel.

    Examples
    --------
    >>> from twin.update import synthesize_modes
    >>> out = comparison_json(compare(hydro_unit, synthesize_modes(hydro_unit, samples=20, seed=1)))
    >>> round(out["error"], 4), len(out["modes"]), out["modes"][0]["mode"]
    (0.0191, 15, 1)
    """
    rows = [
        {"mode": int(m), **{k: float(table[k].sel(mode=m)) for k in COMPARISON_COLUMNS}} for m in table["mode"].values
    ]
    shape = {str(c): float(v) for c, v in zip(table["channel"].values, table["channel_shape_error"].values)}
    return {
        "error": table.attrs["error"],
        "error_definition": table.attrs["error_definition"],
        "error_rms": table.attrs["error_rms"],
        "chi2": table.attrs["chi2"],
        "n_data": table.attrs["n_data"],
        "modes": rows,
        "channel_shape_error": shape,
        "poorly_paired": [int(m) for m in np.atleast_1d(table.attrs["poorly_paired"])],
    }
