"""Complex modal analysis of the rotor at a given speed.

The state-space form of ``M q'' + (C + Ω G) q' + K q = 0`` is

    A = [[0, I], [-M⁻¹ K, -M⁻¹ (C + Ω G)]],

whose eigenvalues come in conjugate pairs ``λ = σ ± i ω_d``. The modes are
the eigenvalues with ``ω_d > 0`` sorted by damped frequency; real
(over-damped) eigenvalues are counted but not listed as modes.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping

import numpy as np
import scipy.linalg as sla
import xarray as xr

from twin import __version__
from twin.errors import ModelError
from twin.fem.elements import DOF_NAMES
from twin.fem.model import RPM_TO_RAD_S, RotorModel
from twin.modes.shapes import normalise_shapes

log = logging.getLogger(__name__)

#: Orbits whose nodes have less than this share of the largest squared
#: amplitude do not vote on the whirl direction of a mode.
WHIRL_AMPLITUDE_SHARE = 1e-2


def state_matrix(M: np.ndarray, C: np.ndarray, G: np.ndarray, K: np.ndarray, speed_rad_s: float) -> np.ndarray:
    """First-order system matrix ``A`` for ``x = [q, q']`` at speed Ω [rad/s].

    Examples
    --------
    >>> import numpy as np
    >>> from twin.modes import state_matrix
    >>> one = np.eye(1)
    >>> state_matrix(one, 0 * one, 0 * one, 4 * one, 0.0)
    array([[ 0.,  1.],
           [-4., -0.]])
    """
    n = M.shape[0]
    try:
        factor = sla.cho_factor(M)
    except sla.LinAlgError:
        raise ModelError("the mass matrix is not positive definite: some DOF carries no mass or inertia") from None
    minv_k = sla.cho_solve(factor, K)
    minv_c = sla.cho_solve(factor, C + speed_rad_s * G)
    return np.block([[np.zeros((n, n)), np.eye(n)], [-minv_k, -minv_c]])


def damping_ratio(poles: np.ndarray) -> np.ndarray:
    """Damping ratio ``-Re(lambda) / |lambda|`` of poles [1/s] (0 for a pole at the origin).

    Examples
    --------
    >>> float(damping_ratio(-0.1 + 1j * np.sqrt(0.99)))
    0.1
    """
    poles = np.asarray(poles)
    wn = np.abs(poles)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(wn > 0, -poles.real / wn, 0.0)


def whirl_direction(shapes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Whirl direction of modes from their complex shapes on all DOFs.

    For each node with complex amplitudes ``(x, y)``, the orbit turns with the
    rotor (forward, from +x towards +y) when ``Im(x ȳ) > 0``. The normalised
    index ``κ = 2 Im(x ȳ) / (|x|² + |y|²)`` is +1 for a circular forward
    orbit, -1 for a backward one and 0 for a straight line. A mode is
    *forward* when all nodes that move (``|x|²+|y|²`` above 1% of the largest)
    whirl forward, *backward* when all whirl backward, *mixed* otherwise.

    Parameters
    ----------
    shapes : array_like, complex, shape (n_modes, n_dof)
        Shapes on all DOFs in ``[x, y, alpha, beta]`` node order.

    Returns
    -------
    labels : numpy.ndarray of str, shape (n_modes,)
    index : numpy.ndarray, shape (n_modes,)
        Amplitude-weighted mean of κ over the nodes, in [-1, 1].

    Examples
    --------
    >>> import numpy as np
    >>> from twin.modes import whirl_direction
    >>> fwd = np.array([[1, -1j, 0, 0, 2, -2j, 0, 0]])  # x = cos, y = sin at both nodes
    >>> whirl_direction(fwd)
    (array(['forward'], dtype='<U8'), array([1.]))
    """
    shapes = np.atleast_2d(np.asarray(shapes, dtype=complex))
    x, y = shapes[:, 0::4], shapes[:, 1::4]
    weight = np.abs(x) ** 2 + np.abs(y) ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        kappa = np.where(weight > 0, 2 * np.imag(x * y.conj()) / weight, 0.0)
    moving = weight > WHIRL_AMPLITUDE_SHARE * weight.max(axis=1, keepdims=True)
    forward = np.all((kappa > 0) | ~moving, axis=1)
    backward = np.all((kappa < 0) | ~moving, axis=1)
    labels = np.where(forward, "forward", np.where(backward, "backward", "mixed"))
    index = np.sum(weight * kappa, axis=1) / np.sum(weight, axis=1)
    return labels.astype("<U8"), index


#: An eigenvalue whose imaginary part is below this fraction of its magnitude (a damping ratio above 0.99995)
#: is over-damped, not a mode: it decays by a factor of about exp(-600) before one cycle is complete. Stiffness-
#: proportional damping on short shaft elements gives many such eigenvalues; round-off turns pairs of them
#: into complex pairs with a tiny imaginary part, which would otherwise be listed as modes at ζ = 100%.
OSCILLATION_RATIO = 1e-2
#: A mode damped less than this is lightly damped: a damping ratio of 0.2 is an amplification factor of 2.5,
#: below which API 684 counts a mode as critically damped, not a critical speed (``twin modal`` lists the lightly
#: damped modes first).
LIGHT_DAMPING = 0.2


def oscillating(poles: np.ndarray) -> np.ndarray:
    """Which poles are modes: ``Im λ > 0`` and the damped frequency at least :data:`OSCILLATION_RATIO` of ``|λ|``.

    Every place that takes a model's modes from its eigenvalues uses this one test.

    Examples
    --------
    >>> oscillating(np.array([-1 + 10j, -1 - 10j, -5 + 1e-6j, -3 + 0j])).tolist()
    [True, False, False, False]
    """
    poles = np.asarray(poles)
    return (poles.imag > 0) & (poles.imag >= OSCILLATION_RATIO * np.abs(poles))


def modal(
    model: RotorModel,
    speed_rpm: float | None = None,
    n_modes: int | None = None,
    values: Mapping[str, float] | None = None,
) -> xr.Dataset:
    """Complex modes of the rotor at a speed.

    Parameters
    ----------
    model : RotorModel
    speed_rpm : float, optional
        Rotor speed [rpm]; the model's running speed by default.
    n_modes : int, optional
        Keep only the lowest ``n_modes`` modes (by damped frequency).
    values : mapping, optional
        Parameter values overriding the model's (e.g. ``{"UGB.kxx": 7e8}``).

    Returns
    -------
    xarray.Dataset
        Dimensions ``mode``, ``dof``, ``channel``. Variables: ``pole``
        (complex, 1/s), ``frequency`` (damped, Hz), ``natural_frequency`` (Hz),
        ``damping_ratio``, ``log_decrement``, ``whirl``
        (forward/backward/mixed), ``whirl_index`` (-1..1), ``stable``,
        ``shape`` (complex, on all DOFs, unit norm, largest entry real
        positive) and ``sensor_shape`` (complex, on the sensor channels,
        normalised the same way on the channels alone). The modes are the
        oscillating eigenvalues, lowest damped frequency first; the
        over-damped ones (:data:`OSCILLATION_RATIO`) are counted in the attrs
        (``n_overdamped``) with their decay rates (``overdamped_rates``, 1/s).

    Examples
    --------
    >>> from twin import load_model, modal, shipped_model
    >>> ds = modal(load_model(shipped_model("ross_reference")), speed_rpm=0.0, n_modes=4)
    >>> ds.sizes["mode"], [round(float(f), 2) for f in ds.frequency.values]
    (4, [16.26, 16.35, 49.0, 49.94])
    >>> bool(ds.stable[0])  # cross-coupled bearings destabilise the first forward mode
    False
    """
    speed_rpm = model.speed_rpm if speed_rpm is None else float(speed_rpm)
    if not (np.isfinite(speed_rpm) and speed_rpm >= 0):
        raise ModelError(
            f"speed must be a finite, non-negative number of rpm, got {speed_rpm:g} (the model's "
            "spin direction is fixed by its gyroscopic matrix)"
        )
    if n_modes is not None and n_modes < 1:
        raise ModelError(f"n_modes must be at least 1, got {n_modes}")
    mats = model.matrices(values)
    omega = speed_rpm * RPM_TO_RAD_S
    A = state_matrix(mats["M"], mats["C"], mats["G"], mats["K"], omega)
    eigvals, eigvecs = sla.eig(A)

    modes = oscillating(eigvals)
    still = ~modes & ~oscillating(eigvals.conj())  # a real eigenvalue, or either member of a near-real pair
    rates = np.sort(-eigvals[still].real)
    n_overdamped = len(rates)
    if n_overdamped:
        log.info(
            "%s at %g rpm: %d over-damped eigenvalues (decay rates %.3g to %.3g 1/s) are not listed as modes",
            model.name,
            speed_rpm,
            n_overdamped,
            rates[0],
            rates[-1],
        )
    order = np.argsort(eigvals.imag[modes], kind="stable")
    poles = eigvals[modes][order]
    shapes = eigvecs[: model.n_dof, modes][:, order].T
    if n_modes is not None:
        poles, shapes = poles[:n_modes], shapes[:n_modes]
    ds = modes_dataset(model, poles, shapes, speed_rpm, n_overdamped)
    ds.attrs["overdamped_rates"] = rates
    return ds


def modes_dataset(
    model: RotorModel, poles: np.ndarray, shapes: np.ndarray, speed_rpm: float, n_overdamped: int = 0
) -> xr.Dataset:
    """Wrap poles and full-DOF shapes of a model into the modal Dataset of :func:`modal`."""
    shapes = normalise_shapes(shapes)
    sensor_dofs = model.sensor_dofs
    sensor_shapes = normalise_shapes(shapes[:, sensor_dofs]) if len(sensor_dofs) else np.zeros((len(poles), 0))
    whirl, whirl_index = whirl_direction(shapes)
    zeta = damping_ratio(poles)
    with np.errstate(invalid="ignore", divide="ignore"):
        log_dec = -2 * np.pi * poles.real / poles.imag
    n_modes = len(poles)
    mode = np.arange(1, n_modes + 1)
    nodes = np.repeat(np.arange(model.n_nodes), 4)
    directions = np.tile(np.array(DOF_NAMES), model.n_nodes)
    ds = xr.Dataset(
        data_vars={
            "pole": ("mode", poles, {"units": "1/s", "long_name": "complex pole (sigma + i omega_d)"}),
            "frequency": ("mode", poles.imag / (2 * np.pi), {"units": "Hz", "long_name": "damped natural frequency"}),
            "natural_frequency": (
                "mode",
                np.abs(poles) / (2 * np.pi),
                {"units": "Hz", "long_name": "undamped natural frequency |pole|/2pi"},
            ),
            "damping_ratio": ("mode", zeta, {"units": "1", "long_name": "damping ratio -Re(pole)/|pole|"}),
            "log_decrement": ("mode", log_dec, {"units": "1", "long_name": "logarithmic decrement"}),
            "whirl": ("mode", whirl, {"long_name": "whirl direction (forward, backward, mixed)"}),
            "whirl_index": (
                "mode",
                whirl_index,
                {"units": "1", "long_name": "mean orbit index, +1 circular forward, -1 circular backward"},
            ),
            "stable": ("mode", poles.real < 0, {"long_name": "Re(pole) < 0"}),
            "shape": (
                ("mode", "dof"),
                shapes,
                {"units": "1", "long_name": "complex mode shape on all DOFs (m and rad)"},
            ),
            "sensor_shape": (
                ("mode", "channel"),
                sensor_shapes,
                {"units": "1", "long_name": "complex mode shape on the sensor channels"},
            ),
        },
        coords={
            "mode": ("mode", mode, {"long_name": "mode number, by damped frequency"}),
            "dof": ("dof", model.dof_labels),
            "node": ("dof", nodes),
            "direction": ("dof", directions),
            "channel": ("channel", model.channels),
            "channel_node": ("channel", np.array([s.node for s in model.sensors], dtype=int)),
            "channel_direction": ("channel", np.array([s.direction for s in model.sensors], dtype="<U1")),
            "channel_location": ("channel", np.array([s.location for s in model.sensors], dtype=object).astype(str)),
        },
        attrs={
            "title": f"modes of {model.name} at {speed_rpm:g} rpm",
            "model": model.name,
            "model_source": model.source,
            "speed_rpm": speed_rpm,
            "speed_rad_s": speed_rpm * RPM_TO_RAD_S,
            "n_dof": model.n_dof,
            "n_overdamped": n_overdamped,
            "producer": f"twin {__version__} twin.modal",
        },
    )
    return ds


def modes_json(ds: xr.Dataset) -> dict:
    """The ``twin modal --json`` layout of :func:`modal`'s modes: the model, its speed and one entry per mode.

    Frequencies in Hz, poles in 1/s, the damping ratio as a fraction; beside the modes, the decay rates [1/s]
    of the over-damped eigenvalues, which are no modes.

    Examples
    --------
    >>> out = modes_json(modal(hydro_unit, n_modes=2))
    >>> out["model"], [m["mode"] for m in out["modes"]], sorted(out["modes"][0])[:3]
    ('hydro_unit', [1, 2], ['damping_ratio', 'frequency_hz', 'log_decrement'])
    """
    modes = [
        {
            "mode": int(ds.mode[i]),
            "frequency_hz": float(ds.frequency[i]),
            "natural_frequency_hz": float(ds.natural_frequency[i]),
            "damping_ratio": float(ds.damping_ratio[i]),
            "log_decrement": float(ds.log_decrement[i]),
            "whirl": str(ds.whirl[i].values),
            "stable": bool(ds.stable[i]),
            "pole_real": float(ds.pole[i].real),
            "pole_imag": float(ds.pole[i].imag),
        }
        for i in range(ds.sizes["mode"])
    ]
    return {
        "model": ds.attrs["model"],
        "n_dof": int(ds.attrs["n_dof"]),
        "speed_rpm": ds.attrs["speed_rpm"],
        "modes": modes,
        "overdamped_rates_per_s": [float(r) for r in np.atleast_1d(ds.attrs.get("overdamped_rates", []))],
    }
