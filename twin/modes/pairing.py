"""Pair two modal sets by MAC; frequency ratio and added damping between them.

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

#: Weight of the relative frequency distance in the pairing cost; it only
#: breaks ties between shapes of (nearly) equal MAC.
FREQUENCY_TIE_BREAK = 1e-3


def assign_modes(
    mac_matrix: np.ndarray,
    f_reference: np.ndarray,
    f_other: np.ndarray,
    min_mac: float = 0.0,
    max_ratio: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one assignment maximising the total MAC; returns ``(rows, cols)`` of the kept pairs.

    A tiny relative-frequency term breaks ties; pairs below ``min_mac``, or
    whose frequencies differ by more than a factor ``max_ratio``, are dropped.

    Examples
    --------
    >>> assign_modes(np.array([[0.2, 0.9], [0.95, 0.1]]), np.array([1.0, 2.0]), np.array([2.1, 0.9]))
    (array([0, 1]), array([1, 0]))
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        distance = np.abs(np.log(np.abs(np.asarray(f_other)[None, :] / np.asarray(f_reference)[:, None])))
    distance = np.nan_to_num(distance, nan=1e3, posinf=1e3)
    cost = -mac_matrix + FREQUENCY_TIE_BREAK * distance
    allowed = np.ones_like(cost, dtype=bool) if max_ratio is None else distance <= np.log(max_ratio)
    cost = np.where(allowed, cost, 1e6)
    rows, cols = linear_sum_assignment(cost)
    keep = (mac_matrix[rows, cols] >= min_mac) & allowed[rows, cols]
    return rows[keep], cols[keep]


def _shapes(ds: xr.Dataset, shape_var: str) -> xr.DataArray:
    if shape_var not in ds:
        raise TwinError(f"modal set '{ds.attrs.get('title', '?')}' has no variable '{shape_var}' to pair on")
    return ds[shape_var]


def pair_modes(
    reference: xr.Dataset, other: xr.Dataset, *, shape_var: str = "sensor_shape", min_mac: float = 0.0
) -> xr.Dataset:
    """Pair the modes of two modal sets one-to-one by complex MAC.

    The assignment maximises the total MAC (Hungarian algorithm); a tiny
    frequency term breaks ties between equally similar shapes. Pairs whose
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
    >>> from twin import load_model, shipped_model, modal
    >>> air = modal(load_model(shipped_model("hydro_unit")), n_modes=6)
    >>> pairs = pair_modes(air, air)
    >>> bool((pairs.mac > 0.999).all()), float(pairs.frequency_ratio[0])
    (True, 1.0)
    """
    a, b = _shapes(reference, shape_var), _shapes(other, shape_var)
    dim = [d for d in a.dims if d != "mode"]
    if len(dim) != 1 or b.dims != a.dims:
        raise TwinError(f"'{shape_var}' must have dims ('mode', <one shape dim>) in both sets, got {a.dims} and {b.dims}")
    dim = dim[0]
    if dim in a.coords and dim in b.coords:
        missing = sorted(set(a[dim].values.tolist()) - set(b[dim].values.tolist()))
        if missing:
            raise TwinError(f"the other modal set lacks {dim}(s) {missing} of the reference")
        b = b.sel({dim: a[dim].values})
    m = mac(a.values, b.values)
    fa, fb = reference["frequency"].values, other["frequency"].values
    rows, cols = assign_modes(m, fa, fb, min_mac)
    za, zb = reference["damping_ratio"].values[rows], other["damping_ratio"].values[cols]
    return xr.Dataset(
        {
            "reference_mode": ("pair", reference["mode"].values[rows]),
            "other_mode": ("pair", other["mode"].values[cols]),
            "mac": ("pair", m[rows, cols], {"units": "1"}),
            "reference_frequency": ("pair", fa[rows], {"units": "Hz"}),
            "other_frequency": ("pair", fb[cols], {"units": "Hz"}),
            "frequency_ratio": ("pair", fb[cols] / fa[rows], {"units": "1", "long_name": "other / reference frequency (FRR)"}),
            "reference_damping_ratio": ("pair", za, {"units": "1"}),
            "other_damping_ratio": ("pair", zb, {"units": "1"}),
            "added_damping_ratio": ("pair", zb - za, {"units": "1", "long_name": "other - reference damping ratio"}),
        },
        coords={"pair": np.arange(1, len(rows) + 1)},
        attrs={"shape_var": shape_var, "min_mac": min_mac},
    )  # fmt: skip


def frequency_ratio(air: xr.Dataset, water: xr.Dataset, **kwargs) -> xr.DataArray:
    """FRR ``f_water / f_air`` per MAC-paired mode (keywords as :func:`pair_modes`).

    Examples
    --------
    >>> from twin.modes import frequency_ratio
    >>> from twin import load_model, shipped_model, modal
    >>> m = load_model(shipped_model("hydro_unit"))
    >>> air = modal(m, n_modes=4)
    >>> water = modal(m, n_modes=4, values={"runner.m": 1.3 * m.parameter("runner.m").nominal})
    >>> frequency_ratio(air, water).values.round(3)  # heavier runner: lower frequencies
    array([1.   , 0.998, 0.992, 0.991])
    """
    return pair_modes(air, water, **kwargs)["frequency_ratio"]


def added_damping_ratio(air: xr.Dataset, water: xr.Dataset, **kwargs) -> xr.DataArray:
    """Added damping ratio ``ζ_water - ζ_air`` per MAC-paired mode (keywords as :func:`pair_modes`)."""
    return pair_modes(air, water, **kwargs)["added_damping_ratio"]
