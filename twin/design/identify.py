"""Which parameters the measured modes can determine, before any data: Fisher information.

The data of an update are, per observable target mode ``k``, its pole and its
shape on the sensors (normalised: unit norm, largest entry real positive),
with an error covariance ``Σ_k`` over ``d_k = [Re λ, Im λ, Re ψ, Im ψ]``.
Linearised at the model, ``d_k(θ) ≈ d_k(θ₀) + J_k (θ − θ₀)``, so the Fisher
information of the parameters and the expected posterior covariance are

    F = Σ_k J_kᵀ Σ_k⁺ J_k,        Cov(θ | data) ≈ (F + P₀)⁻¹

(``P₀`` the prior precision; flat by default, as the updater's; ``Σ_k⁺`` is
singular where the normalised shape cannot move and is taken there by
:func:`data_precision`, with no coordinate cut for its size). ``J_k`` is
taken by finite differences of the model's modes (a relative step of
:data:`STEP`); ``Σ_k`` comes from either

* the record (:func:`twin.design.spectrum.mode_covariance`, the Cramér-Rao
  bound of the output spectrum for the sensor layout, excitation and record
  length: what SSI can give at best), or
* sample noise as :func:`twin.update.synthesize_modes` makes it (pole
  variances and shape coefficient of variation, ``J`` samples averaged).

With per-mode FSI (``fsi=True``) every target mode has its own added mass and
damping, which move that mode only (the modal synthesis of :mod:`twin.fmu.truth`).
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from twin import __version__
from twin.design.observe import band_top, target_modes
from twin.design.spectrum import BLIND_VARIANCE, Excitation, mode_covariance, single_mode_covariance, spectrum
from twin.errors import ModelError
from twin.fem.effects import plausible_scales, with_shared_fsi
from twin.fem.model import RotorModel
from twin.fem.truthfile import PAPER_POLE_VARIANCE, PAPER_SHAPE_COV, Truth
from twin.fmu.statespace import full_state_space
from twin.modes.sensitivity import state_modes
from twin.modes.shapes import mac, normalisation_jacobian, normalise_shapes

#: Finite-difference step, as a fraction of each parameter's scale.
STEP = 1e-6
#: A parameter is determined when its expected posterior std is below this fraction of its scale.
DETERMINED_LIMIT = 0.10
#: Steps of the continuation from a dry mode to its FEM altered by per-mode FSI.
CONTINUATION_STEPS = 6
#: Per-mode FSI parameters (names of the shared effect's parameters) and their labels.
FSI_NAMES = (("added_mass", "FSI.added_mass"), ("added_damping", "FSI.added_damping"))


def parameter_scales(model: RotorModel, names: Sequence[str]) -> np.ndarray:
    """Scale of each parameter [SI]: ``|nominal|``, or the effect's plausible size for a zero nominal."""
    owned = plausible_scales(model)
    out = []
    for n in names:
        nominal = model.parameter(n).nominal
        s = abs(nominal) if nominal != 0 else owned.get(n, 0.0)
        if not s > 0:
            raise ModelError(
                f"parameter '{n}' is zero in the model and has no plausible size: add it through its effect"
            )
        out.append(float(s))
    return np.array(out)


def _modes(model: RotorModel, values: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
    ss = full_state_space(model, values=values)
    lam, right, _ = state_modes(ss.A)
    return lam, (ss.C @ right.T).T


def _data_vector(pole: complex, shape: np.ndarray, ref: int) -> np.ndarray:
    shape = shape * abs(shape[ref]) / shape[ref]
    shape = shape / np.linalg.norm(shape)
    return np.concatenate([[pole.real, pole.imag], shape.real, shape.imag])


def _nearest(poles: np.ndarray, shapes: np.ndarray, pole: complex, shape: np.ndarray) -> int:
    cost = np.abs(poles - pole) / abs(pole) + (1 - mac(shapes, shape)[:, 0])
    return int(np.argmin(cost))


@dataclass(frozen=True)
class ModalPerturbations:
    """Target modes and their finite-difference moves, on every channel of a model's layout.

    The Jacobian of the normalised data follows for any subset of the channels
    (:meth:`jacobian`), which is what a sensor design needs: one set of
    eigen-solutions, many layouts.

    Attributes
    ----------
    poles : (n_modes,) complex
        Poles where linearised [1/s].
    shapes : (n_modes, m) complex
        Output vectors ``C v`` there (not normalised).
    moved_poles : (n_modes, n_columns) complex
        Poles after a step in each column's parameter.
    moved_shapes : (n_modes, n_columns, m) complex
    steps : (n_columns,)
        Step of each column [SI].
    active : (n_modes, n_columns) bool
        Whether the column moves the mode (per-mode FSI moves its own mode only).
    columns : list of str
    scales : (n_columns,)
        Size of each parameter [SI].
    """

    poles: np.ndarray
    shapes: np.ndarray
    moved_poles: np.ndarray
    moved_shapes: np.ndarray
    steps: np.ndarray
    active: np.ndarray
    columns: list[str]
    scales: np.ndarray

    def jacobian(self, rows: Sequence[int] | None = None) -> np.ndarray:
        """``∂d_k/∂θ`` on the channels ``rows`` (default all), shape ``(n_modes, 2 + 2m, n_columns)``."""
        rows = np.arange(self.shapes.shape[1]) if rows is None else np.asarray(rows, dtype=int)
        n, q = self.active.shape
        J = np.zeros((n, 2 + 2 * len(rows), q))
        for i in range(n):
            shape = self.shapes[i, rows]
            ref = int(np.argmax(np.abs(shape)))
            d0 = _data_vector(self.poles[i], shape, ref)
            for c in np.nonzero(self.active[i])[0]:
                moved = _data_vector(self.moved_poles[i, c], self.moved_shapes[i, c, rows], ref)
                J[i, :, c] = (moved - d0) / self.steps[c]
        return J


def modal_perturbations(
    model: RotorModel,
    names: Sequence[str],
    modes: Sequence[int],
    *,
    fsi: bool = False,
    values: Mapping[str, float] | None = None,
    fsi_values: np.ndarray | None = None,
) -> ModalPerturbations:
    """The target modes ``modes`` (indices into the model's poles) and their moves (see :func:`modal_jacobian`)."""
    base = with_shared_fsi(model) if fsi or fsi_values is not None else model
    values = dict(values or {})
    lam_dry, shapes_dry = _modes(base, values)
    modes = list(modes)
    columns = list(names)
    scales = list(parameter_scales(base, names))
    fsi_full = [full for _, full in FSI_NAMES]
    fsi_scales = parameter_scales(base, fsi_full) if fsi else np.zeros(0)
    if fsi:
        for i in range(len(modes)):
            for (short, _), s in zip(FSI_NAMES, fsi_scales):
                columns.append(f"FSI.{short}_{i + 1}")
                scales.append(float(s))
    m = shapes_dry.shape[1]
    shared = list(names) + (fsi_full if fsi else [])
    shared_scales = list(scales[: len(names)]) + list(fsi_scales)
    n, q = len(modes), len(columns)
    poles, shapes = np.zeros(n, dtype=complex), np.zeros((n, m), dtype=complex)
    moved_poles, moved_shapes = np.zeros((n, q), dtype=complex), np.zeros((n, q, m), dtype=complex)
    steps, active = np.ones(q), np.zeros((n, q), bool)
    for i, k in enumerate(modes):
        here = dict(values)
        pole, shape = lam_dry[k], shapes_dry[k]
        if fsi_values is not None:
            for step in range(1, CONTINUATION_STEPS + 1):  # follow the dry mode to its altered FEM
                for full, v in zip(fsi_full, fsi_values[i]):
                    here[full] = v * step / CONTINUATION_STEPS
                lam, shp = _modes(base, here)
                j = _nearest(lam, shp, pole, shape)
                pole, shape = lam[j], shp[j]
        poles[i], shapes[i] = pole, shape
        for p, (name, s) in enumerate(zip(shared, shared_scales)):
            step = STEP * s
            lam, shp = _modes(base, {**here, name: here.get(name, base.parameter(name).nominal) + step})
            j = _nearest(lam, shp, pole, shape)
            column = p if p < len(names) else len(names) + 2 * i + (p - len(names))
            moved_poles[i, column], moved_shapes[i, column], steps[column] = lam[j], shp[j], step
            active[i, column] = True
    return ModalPerturbations(poles, shapes, moved_poles, moved_shapes, steps, active, columns, np.array(scales))


def modal_jacobian(
    model: RotorModel,
    names: Sequence[str],
    modes: Sequence[int],
    *,
    fsi: bool = False,
    values: Mapping[str, float] | None = None,
    fsi_values: np.ndarray | None = None,
) -> tuple[np.ndarray, list[str], np.ndarray, np.ndarray, np.ndarray]:
    """``∂d_k/∂θ`` for target modes ``modes`` (indices into the model's oscillating modes, by frequency).

    With ``fsi_values`` (``(n_modes, 2)``: added mass [kg] and damping [N s/m]
    per mode) mode ``k`` is linearised on its own FEM, altered by its values
    and followed there from the dry mode by continuation.

    Returns
    -------
    (J, columns, scales, poles, shapes)
        ``J`` of shape ``(n_modes, 2 + 2m, n_columns)`` [data units per SI unit];
        the columns are ``names`` then, with ``fsi``, ``FSI.added_mass_<i>`` and
        ``FSI.added_damping_<i>`` per mode (1-based, as in the posterior); ``scales``
        their sizes [SI]; ``poles`` and sensor ``shapes`` of the modes where linearised.
    """
    pert = modal_perturbations(model, names, modes, fsi=fsi, values=values, fsi_values=fsi_values)
    return pert.jacobian(), pert.columns, pert.scales, pert.poles, normalise_shapes(pert.shapes)


def _ratio(cov: np.ndarray, single: np.ndarray) -> float:
    """Single-mode bound over Cramér-Rao bound, the larger of the frequency and damping coordinates, at least 1."""
    return max(float(np.max(np.diag(single) / np.maximum(np.diag(cov)[:2], 1e-300))), 1.0)


def record_ratio(sp, k: int, duration_s: float) -> float | None:
    """How far SSI stays above the Cramér-Rao bound for mode ``k``: single-mode bound / Cramér-Rao bound.

    The larger of the ratios of the frequency and damping coordinates (at least 1); ``None`` when the
    layout is blind to the mode (no finite ratio).
    """
    cov, _ = mode_covariance(sp, k, duration_s)
    single = single_mode_covariance(sp, k, duration_s)
    if np.any(np.diag(cov)[:2] >= BLIND_VARIANCE) or np.any(np.diag(single) >= BLIND_VARIANCE):
        return None
    return _ratio(cov, single)


def record_covariance(sp, k: int, duration_s: float, ratio: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Covariance of mode ``k``'s pole and shape from a record, at the level SSI reaches.

    The Cramér-Rao covariance of the pole and shape (:func:`~twin.design.spectrum.mode_covariance`)
    scaled up by ``ratio``, by default :func:`record_ratio` on this layout: SSI does not use the
    multichannel structure for the shape either. A sensor design passes the ratio of the layout it
    starts from, so that an added pair can only add information (the ratio on the larger layout
    grows as its Cramér-Rao bound falls faster than the single-mode one).
    """
    cov, shape = mode_covariance(sp, k, duration_s)
    if ratio is None:
        ratio = _ratio(cov, single_mode_covariance(sp, k, duration_s))
    return cov * ratio, shape


def record_data(
    poles: np.ndarray,
    sp,
    frequency_hz: np.ndarray,
    observable: np.ndarray,
    duration_s: float,
    ratios: Mapping[int, float] | None = None,
) -> tuple[list[int], list[np.ndarray]]:
    """The modes (indices into ``poles``) an observability table marks observable, and their record covariances.

    Each pole is matched to the table's row of nearest ``frequency_hz`` and to the spectrum's nearest pole;
    ``ratios`` (by the spectrum's pole index) fixes the :func:`record_ratio` of a mode.
    """
    used, precisions = [], []
    for i, pole in enumerate(poles):
        row = int(np.argmin(np.abs(frequency_hz - pole.imag / (2 * np.pi))))
        if bool(observable[row]):
            k = int(np.argmin(np.abs(sp.poles - pole)))
            used.append(i)
            precisions.append(data_precision(*record_covariance(sp, k, duration_s, (ratios or {}).get(k))))
    return used, precisions


def judged_columns(n_names: int, n_modes: int, used: Sequence[int], fsi: bool) -> np.ndarray:
    """Mask of the columns judged: the shared parameters, and with ``fsi`` the per-mode ones of the used modes."""
    keep = np.ones(n_names + (2 * n_modes if fsi else 0), bool)
    if fsi:
        for i in set(range(n_modes)) - set(used):
            keep[n_names + 2 * i : n_names + 2 * i + 2] = False
    return keep


def sample_covariance(
    shape: np.ndarray,
    samples: int,
    pole_variance: tuple[float, float] = PAPER_POLE_VARIANCE,
    shape_cov: float = PAPER_SHAPE_COV,
) -> np.ndarray:
    """Error covariance of a mode's mean pole and normalised shape over ``samples`` synthetic samples.

    :func:`twin.update.synthesize_modes` perturbs each real entry of the
    normalised shape ``shape`` independently (coefficient of variation
    ``shape_cov``); the data vector renormalises, which carries that error
    through :func:`twin.modes.shapes.normalisation_jacobian` (a singular
    covariance: the norm and the reference's phase hold no error).
    """
    shape = np.asarray(shape, dtype=complex)
    raw = np.concatenate([(shape_cov * shape.real) ** 2, (shape_cov * shape.imag) ** 2])
    N = normalisation_jacobian(shape)
    out = np.zeros((2 + len(raw), 2 + len(raw)))
    out[:2, :2] = np.diag(pole_variance)
    out[2:, 2:] = (N * raw) @ N.T
    return out / samples


def data_precision(cov: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """Precision of a mode's data vector ``[Re λ, Im λ, Re ψ, Im ψ]`` from its covariance (both ``2 + 2m`` square).

    The normalised shape ``ψ`` (unit norm, reference entry real) moves only
    in the ``2m - 2`` directions its normalisation leaves free (the range of
    :func:`twin.modes.shapes.normalisation_jacobian`): along ``ψ`` itself and
    the reference's imaginary part its covariance is zero by construction.
    The covariance is inverted on the poles and that range, after scaling
    every coordinate to unit variance, so that no coordinate is cut for being
    small beside another:
    a pole's variance [1/s²] and a shape entry's can differ by ten orders of
    magnitude, and a relative cut on the raw matrix discards the precise
    small entries (the small imaginary parts of the shapes) as if they were
    its structural zeros.

    Examples
    --------
    A two-channel shape: the precision on its one free shape direction, poles ``1/variance``:

    >>> psi = np.array([0.8, 0.6j])
    >>> cov = sample_covariance(psi, 1)
    >>> P = data_precision(cov, psi)
    >>> np.allclose(np.diag(P)[:2], 1 / np.array(PAPER_POLE_VARIANCE)), int(np.linalg.matrix_rank(P))
    (True, 3)
    """
    m = len(shape)
    U = np.linalg.svd(normalisation_jacobian(shape))[0][:, : 2 * m - 2]
    P = np.zeros((2 + 2 * m, 2 * m))
    P[:2, :2] = np.eye(2)
    P[2:, 2:] = U
    S = P.T @ cov @ P
    d = np.sqrt(np.clip(np.diag(S), 0, None))
    d = np.where(d > 0, d, 1.0)
    inner = np.linalg.pinv(S / np.outer(d, d), rcond=1e-10, hermitian=True) / np.outer(d, d)
    return P @ inner @ P.T


def fisher_covariance(
    J: np.ndarray, precisions: Sequence[np.ndarray], scales: np.ndarray, prior_std: np.ndarray | None = None
) -> np.ndarray:
    """``(Σ_k J_kᵀ P_k J_k + P₀)⁻¹`` [SI], ``P_k`` each mode's data precision (:func:`data_precision`);
    directions the data do not reach get a std of 10⁶ scales."""
    Js = J * scales[None, None, :]
    F = np.zeros((len(scales), len(scales)))
    for Jk, Pk in zip(Js, precisions):
        F += Jk.T @ Pk @ Jk
    if prior_std is not None:
        F += np.diag((scales / prior_std) ** 2)
    F += 1e-12 * np.eye(len(scales))
    cov_u = np.linalg.inv(F)
    return cov_u * np.outer(scales, scales)


def linearisation(
    model: RotorModel, truth: Truth | None, fsi: bool, fmax_hz: float
) -> tuple[RotorModel, np.ndarray, np.ndarray | None]:
    """Where the Jacobian is taken: the model (with the shared FSI effect when ``fsi``) or the truth's.

    Returns
    -------
    (base, targets, fsi_values)
        The model to perturb, the indices of its target modes (by frequency) and, for a truth
        with per-mode FSI, its ``(n_modes, 2)`` added mass [kg] and damping [N s/m].
    """
    from twin.fmu.truth import truth_model

    base = with_shared_fsi(model) if fsi else model
    fsi_values = None
    if truth is not None:
        base = truth_model(base, truth)
        if truth.per_mode is not None:
            fsi_values = np.column_stack([truth.per_mode.added_mass, truth.per_mode.added_damping])
    dry, _, _ = state_modes(full_state_space(base).A)
    targets = target_modes(dry, fmax_hz)
    if fsi_values is not None:
        targets = targets[: len(fsi_values)]
    return base, targets, fsi_values


def identifiability(
    model: RotorModel,
    names: Sequence[str],
    *,
    fsi: bool = False,
    excitation: Excitation | None = None,
    samples: int | None = None,
    truth: Truth | None = None,
    observability: xr.Dataset | None = None,
    fmax_hz: float | None = None,
    command: str = "",
) -> xr.Dataset:
    """Expected posterior std of parameters from the modes the sensors see (see the module docstring).

    Parameters
    ----------
    model : RotorModel
    names : sequence of str
        Shared parameters (any of the model's, effects included).
    fsi : bool
        Also per-mode added mass and damping of every mode used.
    excitation : Excitation, optional
        Record the data come from (default: 20 min, ``twin simulate``'s excitation); the
        modes used are those :func:`~twin.design.observe.observability` marks observable.
    samples : int, optional
        Instead of a record: ``J`` synthetic samples per mode with the paper's noise
        (:func:`twin.update.synthesize_modes`), all target modes used.
    truth : Truth, optional
        Linearise at the truth (its effects switched on; per-mode FSI: each mode on its own FEM).
    observability : xarray.Dataset, optional
        A table already computed for this model, truth and excitation (saves its cost).
    fmax_hz : float, optional
        Highest target frequency [Hz] (default 100 Hz, at most 0.4 fs).

    Returns
    -------
    xarray.Dataset
        Over ``parameter``: ``scale`` [SI] (``|nominal|``, or the effect's plausible size),
        ``std`` [SI], ``relative_std`` (std / scale), ``determined`` and ``correlation``;
        attrs: the modes used and the method.

    Examples
    --------
    >>> ident = identifiability(hydro_unit, ["UGB.kxx", "LGB.kxx"], samples=100)
    >>> bool(ident.determined.sel(parameter="UGB.kxx"))
    True
    """
    from twin.design.observe import observability as observe
    from twin.fmu.simulate import system_for

    if not names and not fsi:
        raise ModelError("choose parameters (names) or per-mode FSI: nothing to judge")
    for n in names:
        model.parameter(n)  # an unknown name is named
    excitation = excitation or Excitation()
    excitation.check()
    top = band_top(fmax_hz, excitation)
    base, targets, fsi_values = linearisation(model, truth, fsi, top)
    J, columns, scales, poles, shapes = modal_jacobian(base, names, list(targets), fsi=fsi, fsi_values=fsi_values)
    if samples is not None:
        if samples < 1:
            raise ModelError(f"samples must be at least 1, got {samples}")
        used = list(range(len(targets)))
        precisions = [data_precision(sample_covariance(shapes[i], samples), shapes[i]) for i in used]
        method = (
            f"{samples} synthetic samples per mode (pole variances {PAPER_POLE_VARIANCE[0]:g}, {PAPER_POLE_VARIANCE[1]:g} "
            f"rad^2/s^2; shape CoV {PAPER_SHAPE_COV:.0%})"
        )
    else:
        obs = observability if observability is not None else observe(model, excitation, truth=truth, fmax_hz=top)
        sp = spectrum(system_for(model, truth, "full", None), model, excitation)
        used, precisions = record_data(poles, sp, obs.frequency.values, obs.observable.values, excitation.duration_s)
        method = (
            f"poles and shapes of the observable modes from a {excitation.duration_s:g} s record "
            "(Cramer-Rao covariance raised to the single-mode bound of each pole)"
        )
    if not used:
        raise ModelError(
            f"no target mode of '{model.name}' is observable with this layout and record: "
            "nothing determines the parameters"
        )
    keep = judged_columns(len(names), len(targets), used, fsi)
    J = J[used][:, :, keep]
    columns = [c for c, k in zip(columns, keep) if k]
    scales = scales[keep]
    cov = fisher_covariance(J, precisions, scales)
    std = np.sqrt(np.clip(np.diag(cov), 0, None))
    return xr.Dataset(
        {
            "scale": ("parameter", scales, {"long_name": "size the std is judged against [SI]"}),
            "std": ("parameter", std, {"long_name": "expected posterior std (Fisher) [SI]"}),
            "relative_std": ("parameter", std / scales, {"units": "1"}),
            "determined": (
                "parameter",
                std / scales < DETERMINED_LIMIT,
                {"long_name": f"expected std below {DETERMINED_LIMIT:.0%} of the scale"},
            ),
            "correlation": (("parameter", "parameter_2"), cov / np.outer(std, std), {"units": "1"}),
        },
        coords={"parameter": columns, "parameter_2": columns},
        attrs={
            "title": f"identifiability of {model.name}'s parameters",
            "producer": f"twin {__version__} twin.design.identify",
            "model": model.name,
            "command": command,
            "method": method,
            "modes_used": json.dumps([int(i) + 1 for i in used]),
            "target_modes": len(targets),
            "excitation": json.dumps(excitation.__dict__),
            **({"truth": truth.to_json()} if truth is not None else {}),
        },
    )
