"""Pair two modal sets by pole distance and MAC; frequency ratio and added damping between them.

Typical use: a model's modes against measured ones, or the same machine in
air and in water, where ``FRR = f_water / f_air`` and the added damping ratio
is ``ζ_water - ζ_air``.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from scipy.optimize import linear_sum_assignment

from twin.errors import TwinError
from twin.modes.shapes import mac


def pairing_cost(
    reference_poles: np.ndarray, reference_shapes: np.ndarray, poles: np.ndarray, shapes: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(cost, mac)``, both reference x other: ``|λ − λ_ref| / |λ_ref| + (1 − MAC)`` and the complex MAC.

    The shapes are on the same channels (or DOFs) in both sets. The pole
    distance carries the pairing where a few sensors cannot tell shapes apart
    (a 10 Hz mode and a 368 Hz mode can have MAC 0.96 on 8 proximeters); the
    MAC carries it between modes of nearly equal poles (forward and backward
    whirl).

    Examples
    --------
    >>> cost, m = pairing_cost(np.array([-1 + 10j]), np.array([[1, 0]]), np.array([-1 + 11j, -1 + 10j]),
    ...                        np.array([[1, 0], [0, 1]]))
    >>> np.round(cost, 3), m
    (array([[0.1, 1. ]]), array([[1., 0.]]))
    """
    m = mac(np.asarray(reference_shapes), np.asarray(shapes))
    reference_poles = np.asarray(reference_poles)
    dist = np.abs(np.asarray(poles)[None, :] - reference_poles[:, None]) / np.abs(reference_poles)[:, None]
    return dist + (1.0 - m), m


def assign(cost: np.ndarray, allowed: np.ndarray | None = None) -> np.ndarray:
    """For each row, its column (-1 for none): one to one, as many pairs as ``allowed`` permits, and of those
    assignments the one of least total ``cost`` (Hungarian algorithm).

    Every modal assignment of the package goes through here: a model's modes to measured ones, a tracked
    mode to a record's, an extraction pass's modes to another's, a simulated record's to the measured ones.

    Parameters
    ----------
    cost : (rows, columns) float
        Cost of each pair, zero or more (e.g. :func:`pairing_cost`); ``inf`` or NaN forbids a pair.
    allowed : (rows, columns) bool, optional
        The gates: pairs that may be made at all.

    Examples
    --------
    >>> cost = np.array([[0.1, 0.2], [0.15, 0.9]])
    >>> assign(cost).tolist()  # closest first would pair (0, 0) and leave row 1 with 0.9
    [1, 0]
    >>> assign(cost, cost < 0.5).tolist(), assign(cost, cost < 0.12).tolist()
    ([1, 0], [0, -1])
    """
    cost = np.asarray(cost, dtype=float)
    ok = np.isfinite(cost) if allowed is None else np.asarray(allowed, dtype=bool) & np.isfinite(cost)
    out = np.full(cost.shape[0], -1)
    if not ok.any():
        return out
    # a forbidden pair costs more than any assignment of allowed ones: the most pairs first, then the least cost
    forbidden = (np.abs(cost[ok]).max() + 1.0) * (min(cost.shape) + 1)
    rows, cols = linear_sum_assignment(np.where(ok, cost, forbidden))
    made = ok[rows, cols]
    out[rows[made]] = cols[made]
    return out


def partners(
    reference_poles: np.ndarray, reference_shapes: np.ndarray, poles: np.ndarray, shapes: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(mac, cols)``: mode ``cols[r]`` of the other set is reference mode ``r``'s partner, for every ``r``.

    One-to-one where it can be, by the least total :func:`pairing_cost` (Hungarian algorithm); when the other
    set has fewer modes, the reference modes left over take their nearest. ``mac`` is the whole
    reference x other MAC matrix.

    Examples
    --------
    >>> _, cols = partners(np.array([-1 + 10j, -1 + 20j]), np.eye(2), np.array([-1 + 21j, -1 + 9j]), np.eye(2)[::-1])
    >>> cols.tolist()
    [1, 0]
    """
    cost, m = pairing_cost(reference_poles, reference_shapes, poles, shapes)
    out = assign(cost)
    left = out < 0
    out[left] = np.argmin(cost[left], axis=1)
    return m, out


def dataset_poles(ds: xr.Dataset) -> np.ndarray:
    """The complex poles [1/s] of a modal set: its ``pole``, or from ``frequency`` [Hz] and ``damping_ratio``."""
    if "pole" in ds:
        return np.asarray(ds["pole"].values, dtype=complex)
    omega_d = 2 * np.pi * np.asarray(ds["frequency"].values, dtype=float)
    zeta = np.asarray(ds["damping_ratio"].values, dtype=float)
    return omega_d * (-zeta / np.sqrt(1 - np.minimum(zeta**2, 1 - 1e-12)) + 1j)


def _shapes(ds: xr.Dataset, shape_var: str) -> xr.DataArray:
    if shape_var not in ds:
        raise TwinError(f"modal set '{ds.attrs.get('title', '?')}' has no variable '{shape_var}' to pair on")
    return ds[shape_var]


def pair_modes(
    reference: xr.Dataset, other: xr.Dataset, *, shape_var: str = "sensor_shape", min_mac: float = 0.0
) -> xr.Dataset:
    """Pair the modes of two modal sets one-to-one by complex MAC.

    The assignment has the least total :func:`pairing_cost` (Hungarian
    algorithm), the pairing a comparison with measured modes uses; pairs whose
    MAC is below ``min_mac`` are dropped.

    Parameters
    ----------
    reference, other : xarray.Dataset
        Modal sets as returned by :func:`twin.modal`: ``frequency``,
        ``damping_ratio`` and a complex shape variable over ``mode`` and one
        shape dimension (e.g. ``channel``), matched by coordinate labels.
    shape_var : str
        The shape variable to compare (``"sensor_shape"`` or ``"shape"``).
    min_mac : float
        Smallest MAC for a pair to count.

    Returns
    -------
    xarray.Dataset
        Dimension ``pair``: ``reference_mode``, ``other_mode``, ``mac``,
        ``reference_frequency``, ``other_frequency`` [Hz],
        ``frequency_ratio`` (other / reference), ``reference_damping_ratio``,
        ``other_damping_ratio``, ``added_damping_ratio`` (other - reference).

    Examples
    --------
    >>> from twin import pair_modes
    >>> from twin import modal
    >>> air = modal(hydro_unit, n_modes=6)
    >>> pairs = pair_modes(air, air)
    >>> bool((pairs.mac > 0.999).all()), float(pairs.frequency_ratio[0])
    (True, 1.0)
    """
    a, b = _shapes(reference, shape_var), _shapes(other, shape_var)
    dim = [d for d in a.dims if d != "mode"]
    if len(dim) != 1 or b.dims != a.dims:
        raise TwinError(
            f"'{shape_var}' must have dims ('mode', <one shape dim>) in both sets, got {a.dims} and {b.dims}"
        )
    dim = dim[0]
    if dim in a.coords and dim in b.coords:
        missing = sorted(set(a[dim].values.tolist()) - set(b[dim].values.tolist()))
        if missing:
            raise TwinError(f"the other modal set lacks {dim}(s) {missing} of the reference")
        b = b.sel({dim: a[dim].values})
    fa, fb = reference["frequency"].values, other["frequency"].values
    cost, m = pairing_cost(dataset_poles(reference), a.values, dataset_poles(other), b.values)
    out = assign(cost)
    rows = np.flatnonzero(out >= 0)
    cols = out[rows]
    keep = m[rows, cols] >= min_mac
    rows, cols = rows[keep], cols[keep]
    za, zb = reference["damping_ratio"].values[rows], other["damping_ratio"].values[cols]
    return xr.Dataset(
        {
            "reference_mode": ("pair", reference["mode"].values[rows]),
            "other_mode": ("pair", other["mode"].values[cols]),
            "mac": ("pair", m[rows, cols], {"units": "1"}),
            "reference_frequency": ("pair", fa[rows], {"units": "Hz"}),
            "other_frequency": ("pair", fb[cols], {"units": "Hz"}),
            "frequency_ratio": (
                "pair",
                fb[cols] / fa[rows],
                {"units": "1", "long_name": "other / reference frequency (FRR)"},
            ),
            "reference_damping_ratio": ("pair", za, {"units": "1"}),
            "other_damping_ratio": ("pair", zb, {"units": "1"}),
            "added_damping_ratio": ("pair", zb - za, {"units": "1", "long_name": "other - reference damping ratio"}),
        },
        coords={"pair": np.arange(1, len(rows) + 1)},
        attrs={"shape_var": shape_var, "min_mac": min_mac},
    )


def frequency_ratio(air: xr.Dataset, water: xr.Dataset, **kwargs) -> xr.DataArray:
    """FRR ``f_water / f_air`` per MAC-paired mode (keywords as :func:`pair_modes`).

    Examples
    --------
    >>> from twin.modes import frequency_ratio
    >>> from twin import modal
    >>> m = hydro_unit
    >>> air = modal(m, n_modes=4)
    >>> water = modal(m, n_modes=4, values={"runner.m": 1.3 * m.parameter("runner.m").nominal})
    >>> frequency_ratio(air, water).values.round(3)  # heavier runner: lower frequencies
    array([1.   , 0.998, 0.992, 0.991])
    """
    return pair_modes(air, water, **kwargs)["frequency_ratio"]


def added_damping_ratio(air: xr.Dataset, water: xr.Dataset, **kwargs) -> xr.DataArray:
    """Added damping ratio ``ζ_water - ζ_air`` per MAC-paired mode (keywords as :func:`pair_modes`)."""
    return pair_modes(air, water, **kwargs)["added_damping_ratio"]
