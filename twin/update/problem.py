"""The updating problem: what is updated, on which data, in which scaled coordinates.

:func:`build_problem` turns a model, a modes Dataset and a choice of
parameters into the arrays the Gibbs sampler sweeps over, once:

* the PerCEM basis matrices of every (mode, pole sample), real-augmented,
  ``H_k = [R*_k, T*_k]`` acting on ``z = [x*; e*]`` (shape and perturbation);
* parameters in scaled coordinates ``θ_k = s_k t_k``: ``s_k`` is the nominal
  value, or, for a parameter whose nominal is zero (an added effect), the value
  at which it equals the nominal dynamic stiffness on its DOFs at the mode's
  mean pole (so ``t = 0`` is "no effect", ``|t| ~ 1`` a strong one);
* rows scaled to unit nominal size (``ρ_r``, RMS over the samples of the row
  norm of ``R`` at the nominal parameters), and ``ε̂ = ρ̄ e`` with ``ρ̄`` the
  geometric mean of the row scales, so ``e`` is a perturbation relative to the
  dynamic stiffness.
"""

from __future__ import annotations

import fnmatch
import logging
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from twin.errors import ModelError, UpdateError  # UpdateError: imported from here by callers
from twin.fem.effects import FluidAddedMass
from twin.fem.model import RotorModel
from twin.fem.parameters import MATRIX_KINDS, Parameter
from twin.modes.analysis import oscillating, state_matrix
from twin.modes.modesfile import NO_MODES
from twin.update.condense import LATENT_SHAPE, dynamic_stiffness, parametrised_dofs, real_augment
from twin.update.poles import check_pole_model, condense_samples

log = logging.getLogger(__name__)

#: Named groups for ``--params``.
PARAMETER_GROUPS = {
    "bearings": lambda m: [p.name for b in m.bearings for p in b.parameters()],
    "thrust": lambda m: [p.name for t in m.thrusts for p in t.parameters()],
    "disks": lambda m: [p.name for d in m.disks for p in d.parameters()],
}
#: Per-mode FSI parameters: name, unit, matrix of the footprint.
FSI_PARAMETERS = (("added_mass", "kg", "M"), ("added_damping", "N s/m", "C"))
#: Relative variance floor of the shape data (the reference entry's zero imaginary part).
VARIANCE_FLOOR = 1e-8


@dataclass(frozen=True)
class Block:
    """Basis matrices of the parameters ``columns`` on their common non-zero ``rows``.

    ``H`` has shape ``(I, len(columns), J, len(rows), n_z)``.
    """

    columns: np.ndarray
    rows: np.ndarray
    H: np.ndarray


def sparse_blocks(H: np.ndarray) -> tuple[Block, ...]:
    """Group parameter bases ``H[:, k]`` (I, K, J, n_r, n_z) by their non-zero rows."""
    support = np.any(H != 0, axis=(0, 2, 4))  # (K, n_r)
    groups: dict[bytes, list[int]] = {}
    for k in range(H.shape[1]):
        groups.setdefault(support[k].tobytes(), []).append(k)
    blocks = []
    for cols in groups.values():
        rows = np.flatnonzero(support[cols[0]])
        cols = np.array(cols)
        blocks.append(Block(cols, rows, np.ascontiguousarray(H[:, cols][:, :, :, rows])))
    return tuple(blocks)


@dataclass(frozen=True)
class Problem:
    """Arrays of an updating problem, in scaled coordinates (see the module docstring).

    ``I`` modes, ``J`` samples, ``K = Kg + Km`` parameters per mode (``Kg``
    shared, ``Km`` of the mode's own), ``n_r`` real rows, ``n_z`` real unknowns.

    The basis matrices ``H_k`` are stored sparsely: the fixed part ``H0``
    dense, the parameters' bases by *blocks* of parameters that touch the same
    rows (a bearing's eight coefficients touch its own two DOFs' rows only).

    Attributes
    ----------
    H0 : (I, J, n_r, n_z)
        Fixed part.
    blocks : tuple of Block
        Parameter bases; parameter index ``k`` counts the shared parameters,
        then the mode's own.
    data_index : (n_psi,) int
        Positions of ``[Re ψ; Im ψ]`` in ``z``.
    eps_index : (n_e,) int
        Positions of ``e`` in ``z``.
    psi_hat : (I, J, n_psi)
        Real-augmented shape samples.
    psi_var : (I, n_psi)
        Their variance (diagonal Σ), floored.
    global_names, global_scale, global_nominal
        Shared parameters: names, scales ``s_k`` and nominal values (SI).
    mode_names : list of str
        Per-mode parameter kinds (``added_mass``, ``added_damping``) or empty.
    mode_scale, mode_nominal : (I, Km)
        Their scales and nominal values (SI).
    modes : (I,) int
        Mode numbers of the data.
    method : str
        ``"stage 2"`` or ``"latent shape"``.
    eps_std : float
        σ of the relative perturbation ``e``.
    margin : (I,)
        Distance from each mode's mean pole to the nearest resonance of the
        unobserved DOFs ``r`` (where the Schur complement has a pole), in
        pole-sample standard deviations.
    resonance_hz : (I,)
        Frequency of that resonance [Hz].
    """

    H0: np.ndarray
    blocks: tuple[Block, ...]
    data_index: np.ndarray
    eps_index: np.ndarray
    psi_hat: np.ndarray
    psi_var: np.ndarray
    global_names: list[str]
    global_scale: np.ndarray
    global_nominal: np.ndarray
    mode_names: list[str]
    mode_scale: np.ndarray
    mode_nominal: np.ndarray
    modes: np.ndarray
    channels: list[str]
    method: str
    eps_std: float
    margin: np.ndarray
    resonance_hz: np.ndarray

    @property
    def n_modes(self) -> int:
        """I, number of modes."""
        return self.H0.shape[0]

    @property
    def n_samples(self) -> int:
        """J, samples per mode."""
        return self.H0.shape[1]

    @property
    def n_global(self) -> int:
        """Kg, shared parameters."""
        return len(self.global_names)

    @property
    def n_per_mode(self) -> int:
        """Km, parameters of each mode's own."""
        return len(self.mode_names)

    @property
    def parameter_labels(self) -> list[str]:
        """All parameter names: shared ones, then ``FSI.<kind>_<mode>`` mode by mode."""
        return self.global_names + [f"FSI.{k}_{m}" for m in self.modes for k in self.mode_names]


def select_parameters(model: RotorModel, spec: str | Sequence[str] | None) -> list[str]:
    """Parameter names from a ``--params`` value: group names, names or glob patterns.

    Groups: ``bearings`` (every guide-bearing coefficient), ``thrust``, ``disks``.

    Examples
    --------
    >>> m = hydro_unit
    >>> select_parameters(m, "LGB.c*")
    ['LGB.cxx', 'LGB.cxy', 'LGB.cyx', 'LGB.cyy']
    >>> len(select_parameters(m, "bearings,thrust.k_tilt"))
    17
    """
    if spec is None:
        return []
    items = [s.strip() for s in (spec.split(",") if isinstance(spec, str) else spec) if s.strip()]
    names = [p.name for p in model.parameters if not p.per_mode]
    out: list[str] = []
    for item in items:
        if item in PARAMETER_GROUPS:
            found = PARAMETER_GROUPS[item](model)
        elif any(ch in item for ch in "*?["):
            found = fnmatch.filter(names, item)
        else:
            if model.parameter(item).per_mode:  # an unknown name raises, listing close names
                raise ModelError(f"'{item}' is a per-mode parameter: update it with --fsi")
            found = [item]
        if not found:
            raise ModelError(
                f"'{item}' matches no parameter of model '{model.name}' (groups: {', '.join(PARAMETER_GROUPS)})"
            )
        out += [n for n in found if n not in out]
    return out


def _basis(p: Parameter, n: int) -> dict[str, np.ndarray]:
    """The parameter's footprint matrices ``M, C, G, K``, dense."""
    return {k: p.footprint(k, n).toarray() for k in MATRIX_KINDS}


def _zero_nominal_scale(nominal_mats, basis, poles: np.ndarray, speed: float) -> float:
    """Parameter value at which its dynamic stiffness equals the nominal one on its DOFs."""
    dofs = parametrised_dofs([basis])
    idx = np.ix_(dofs, dofs)
    lam = np.array([np.mean(poles)])
    z_nom = dynamic_stiffness({k: v[idx] for k, v in nominal_mats.items()}, lam, speed)[0]
    z_k = dynamic_stiffness({k: v[idx] for k, v in basis.items()}, lam, speed)[0]
    return float(np.linalg.norm(z_nom) / np.linalg.norm(z_k))


def _condensation_margins(fixed, bases, observed, poles: np.ndarray, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """Distance of each mode's mean pole to the nearest pole of the Schur complement, in pole-sample stds."""
    s = np.union1d(observed, parametrised_dofs(bases))
    r = np.setdiff1d(np.arange(fixed["K"].shape[0]), s)
    if not len(r):
        return np.full(len(poles), np.inf), np.full(len(poles), np.nan)
    sub = {k: v[np.ix_(r, r)] for k, v in fixed.items()}
    try:
        lam = np.linalg.eigvals(state_matrix(sub["M"], sub["C"], sub["G"], sub["K"], speed))
    except ModelError:  # massless unobserved DOFs: no dynamics of their own
        return np.full(len(poles), np.inf), np.full(len(poles), np.nan)
    lam = lam[oscillating(lam)]
    mean = poles.mean(axis=1)
    spread = np.sqrt(np.var(poles.real, axis=1, ddof=1) + np.var(poles.imag, axis=1, ddof=1))
    dist = np.abs(lam[None, :] - mean[:, None])
    nearest = np.argmin(dist, axis=1)
    with np.errstate(divide="ignore"):
        margin = dist[np.arange(len(mean)), nearest] / spread
    return margin, lam[nearest].imag / (2 * np.pi)


def _observed_dofs(model: RotorModel, modes: xr.Dataset, source: str) -> np.ndarray:
    sensors = {s.name: s.dof for s in model.sensors}
    channels = [str(c) for c in modes["channel"].values]
    unknown = [c for c in channels if c not in sensors]
    if unknown:
        raise UpdateError(
            f"{source}: channel(s) {unknown} are not sensors of model '{model.name}' (sensors: {sorted(sensors)})"
        )
    dofs = np.array([sensors[c] for c in channels])
    if len(set(dofs)) < len(dofs):
        raise UpdateError(f"{source}: two channels observe the same DOF")
    return dofs


def check_modes(modes: xr.Dataset, source: str) -> None:
    """Check a modes Dataset for what the updater needs, naming the problem."""
    for v, dims in (("pole", ("mode", "sample")), ("shape", ("mode", "sample", "channel"))):
        if v not in modes:
            raise UpdateError(f"{source}: no variable '{v}'")
        if tuple(modes[v].dims) != dims:
            raise UpdateError(f"{source}: '{v}' has dimensions {tuple(modes[v].dims)}, expected {dims}")
    if modes.sizes["mode"] == 0:
        raise UpdateError(f"{source}: {NO_MODES}")
    if modes.sizes["sample"] < 2:
        raise UpdateError(f"{source}: {modes.sizes['sample']} sample per mode; the updater needs at least 2")
    for v in ("pole", "shape"):
        values = modes[v].values
        bad = ~np.isfinite(values)
        if bad.any():
            idx = np.argwhere(bad)[0]
            where = ", ".join(f"{d}={modes[d].values[i]}" for d, i in zip(modes[v].dims, idx))
            raise UpdateError(f"{source}: '{v}' is not finite at {where}")
    poles = modes["pole"].transpose("mode", "sample").values
    wrong_half = poles.mean(axis=1).imag <= 0
    if wrong_half.any():
        mode = modes["mode"].values[wrong_half][0]
        raise UpdateError(f"{source}: mode {mode} has its mean pole at Im <= 0 (expected the Im > 0 pole)")
    # A mode whose frequency the record hardly determines (a heavily damped one) can have single samples
    # below the axis: the samples stand for the mean's error (an extraction's scaled jackknife), and the
    # marginal reads the mode through that mean and its covariance, which then weigh it little.
    for mode, below in zip(modes["mode"].values, np.sum(poles.imag <= 0, axis=1)):
        if below:
            log.warning(
                "%s: mode %s has %d of %d pole samples with Im <= 0: its frequency is hardly determined",
                source,
                mode,
                below,
                poles.shape[1],
            )
    still = np.all(poles == poles[:, :1], axis=1)
    if still.any():
        raise UpdateError(
            f"{source}: mode(s) {modes['mode'].values[still].tolist()} have {poles.shape[1]} equal pole "
            "samples; the updater learns the noise of the condensed eigen-equation from their scatter, "
            "so it needs pole samples that differ (jackknife samples of an extraction, or synthetic "
            "samples with a pole variance)"
        )


def build_problem(
    model: RotorModel,
    modes: xr.Dataset,
    params: Sequence[str] = (),
    *,
    fsi: bool = False,
    eps_std: float = 1e-6,
    pole_model: str = "samples",
    source: str = "modes",
) -> Problem:
    """Set up the updating of ``params`` (and per-mode FSI) from a modes Dataset.

    Parameters
    ----------
    model : RotorModel
        The model to update; parameters not updated keep their values.
    modes : xarray.Dataset
        Complex ``pole`` (mode, sample) and ``shape`` (mode, sample, channel),
        channels named after the model's sensors (see :func:`twin.modes.read_modes`).
    params : sequence of str
        Names of the shared parameters to update.
    fsi : bool
        Also update the added mass and damping of each mode on the immersed region.
    eps_std : float
        σ of the relative perturbation ``e`` of the condensed eigen-equation.
    pole_model : {"samples", "linear", "marginal"}
        How the pole samples enter the condensed model: the bases at every
        sample (the paper's), linearised about the mean pole, or the bases at
        the mean pole with their two slopes in the pole (the errors-in-variables
        model of :mod:`twin.update.marginal`; then ``J`` is 3 in ``H0``, while
        ``psi_hat`` keeps the samples) (:mod:`twin.update.poles`).
    source : str
        Name of the data in messages.

    Returns
    -------
    Problem
    """
    check_modes(modes, source)
    check_pole_model(pole_model)
    params = list(params)
    if not params and not fsi:
        raise UpdateError("nothing to update: give parameters and/or per-mode FSI")
    observed = _observed_dofs(model, modes, source)
    n = model.n_dof
    speed = model.speed_rad_s
    shared = [model.parameter(p) for p in params]
    fixed = model.matrices({p: 0.0 for p in params})
    nominal_mats = model.matrices()
    bases = [_basis(p, n) for p in shared]
    fsi_bases, mode_nominal = [], np.zeros((modes.sizes["mode"], 0))
    if fsi:
        fsi_params = {p.name.split(".")[1]: p for p in FluidAddedMass().parameters(model)}
        fsi_bases = [_basis(fsi_params[k], n) for k, _, _ in FSI_PARAMETERS]
        mode_nominal = np.zeros((modes.sizes["mode"], len(FSI_PARAMETERS)))
    poles = modes["pole"].values.astype(complex)
    shapes = modes["shape"].values.astype(complex)
    global_nominal = np.array([p.nominal for p in shared])
    global_scale = np.abs(global_nominal)
    for k in np.flatnonzero(global_scale == 0):
        global_scale[k] = np.median([_zero_nominal_scale(nominal_mats, bases[k], pm, speed) for pm in poles])
    # per-mode FSI has no nominal value in the model: its scale is always the dynamic-stiffness one
    mode_scale = np.array(
        [[_zero_nominal_scale(nominal_mats, b, pm, speed) for b in fsi_bases] for pm in poles]
    ).reshape(mode_nominal.shape)

    margin, resonance = _condensation_margins(fixed, bases + fsi_bases, observed, poles, speed)
    condensed = [condense_samples(fixed, bases + fsi_bases, observed, pm, speed, pole_model=pole_model) for pm in poles]
    methods = {c.method for c in condensed}
    if len(methods) > 1:  # one structure for all modes
        condensed = [
            condense_samples(fixed, bases + fsi_bases, observed, pm, speed, pole_model=pole_model, force_latent=True)
            for pm in poles
        ]
    method = condensed[0].method
    if method == LATENT_SHAPE:
        log.warning(
            "too few parameter-free observed rows for stage 2: unobserved DOFs %s are sampled as latent shape entries",
            list(condensed[0].latent_dofs),
        )
    H = []
    for i, c in enumerate(condensed):
        scale = np.concatenate([[1.0], global_scale, mode_scale[i]])
        t_nom = np.concatenate([[1.0], global_nominal / global_scale, mode_nominal[i] / mode_scale[i]])
        R = c.R * scale[None, :, None, None]
        T = c.T * scale[None, :, None, None]
        R_nom = np.einsum("k,jkrc->jrc", t_nom, R)
        if pole_model == "marginal":  # the bases at the mean pole, then their slopes
            R_nom = R_nom[:1]
        rho = np.sqrt(np.mean(np.sum(np.abs(R_nom) ** 2, axis=2), axis=0))
        rho = np.where(rho > 0, rho, 1.0)
        rho_bar = float(np.exp(np.mean(np.log(rho))))
        R = real_augment(R / rho[:, None])
        T = real_augment(T * (rho_bar / rho[:, None]))
        H.append(np.swapaxes(np.concatenate([R, T], axis=-1), 0, 1))
    H = np.stack(H)
    blocks = sparse_blocks(H[:, 1:])
    n_o, n_x = len(observed), condensed[0].n_x
    n_s = condensed[0].T.shape[-1]
    data_index = np.concatenate([np.arange(n_o), n_x + np.arange(n_o)])
    eps_index = 2 * n_x + np.arange(2 * n_s)
    psi_hat = np.concatenate([shapes.real, shapes.imag], axis=-1)
    var = np.var(psi_hat, axis=1, ddof=1)
    floor = VARIANCE_FLOOR * np.mean(var, axis=1, keepdims=True)
    log.info(
        "updating %d shared and %d per-mode parameters from %d modes x %d samples (%s, %d rows)",
        len(params),
        len(fsi_bases),
        H.shape[0],
        poles.shape[1],
        method,
        H.shape[3],
    )
    return Problem(
        H0=np.ascontiguousarray(H[:, 0]),
        blocks=blocks,
        data_index=data_index,
        eps_index=eps_index,
        psi_hat=psi_hat,
        psi_var=np.maximum(var, floor),
        global_names=params,
        global_scale=global_scale,
        global_nominal=global_nominal,
        mode_names=[k for k, _, _ in FSI_PARAMETERS] if fsi else [],
        mode_scale=mode_scale,
        mode_nominal=mode_nominal,
        modes=modes["mode"].values.astype(int),
        channels=[str(c) for c in modes["channel"].values],
        method=method,
        eps_std=float(eps_std),
        margin=margin,
        resonance_hz=resonance,
    )
