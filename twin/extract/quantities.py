"""What each channel of a record measures, and in which units.

A record's channels may measure displacement (proximeters), velocity
(geophones, velocity pickups) or acceleration (accelerometers). A
``signals.nc`` says so in one of two layouts:

* a variable ``displacement`` over ``(time, channel)``: every channel a
  displacement, in the variable's ``units`` attr (metres when it has none),
  as twin writes its own records;
* a variable ``signal`` over ``(time, channel)`` with the coordinates
  ``quantity`` (``displacement``, ``velocity`` or ``acceleration``) and
  ``units`` over ``channel``: any mix.

Units are read with pint (µm, mm, mil, in; mm/s, in/s, ips; m/s², g, ...;
``mil`` is the thousandth of an inch and ``g`` the standard gravity, as on
vibration instruments) and every channel converted to SI (m, m/s, m/s²)
before the identification. A channel's mode shape entry is the displacement's
times ``λ`` for a velocity and ``λ²`` for an acceleration (``λ`` the mode's
pole), so the extraction reports every shape in displacement
(:func:`displacement_shapes`), where it can be compared with the model's.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr

from twin.errors import SignalError
from twin.units import registry

#: The quantities a channel may measure: their SI unit and their order of time derivative of the displacement.
QUANTITIES = {"displacement": ("m", 0), "velocity": ("m/s", 1), "acceleration": ("m/s**2", 2)}
#: Units as vibration instruments write them, in pint's words (pint's ``mil`` is an angle, its ``g`` a gram).
ALIASES = {
    "mil": "thou",
    "mils": "thou",
    "g": "standard_gravity",
    "G": "standard_gravity",
    "gn": "standard_gravity",
    "ips": "inch / second",
    "micron": "micrometer",
    "microns": "micrometer",
    "m/s2": "m/s**2",
    "m/s^2": "m/s**2",
    "mm/s2": "mm/s**2",
}
#: The SI units of each quantity written without pint (so a record in SI needs no units library).
_SI = {
    "displacement": {"m", "meter", "metre", "meters", "metres"},
    "velocity": {"m/s", "m s-1", "meter/second"},
    "acceleration": {"m/s**2", "m/s^2", "m/s2", "m s-2", "meter/second**2"},
}


def si_factor(units: str, quantity: str, where: str) -> float:
    """The factor that takes ``quantity`` in ``units`` to SI (m, m/s or m/s²); an error naming ``where`` if
    the units are unknown or not of that quantity.

    Examples
    --------
    >>> si_factor("um", "displacement", "A_x"), round(si_factor("mil", "displacement", "A_x"), 12)
    (1e-06, 2.54e-05)
    >>> round(si_factor("g", "acceleration", "A_x"), 5), si_factor("mm/s", "velocity", "A_x")
    (9.80665, 0.001)
    """
    if quantity not in QUANTITIES:
        raise SignalError(f"{where}: quantity {quantity!r} is not one of {', '.join(QUANTITIES)}")
    text = str(units).strip()
    if text in _SI[quantity]:
        return 1.0
    import pint

    ureg = registry()
    try:
        value = ureg.Quantity(1.0, ALIASES.get(text, text))
        factor = float(value.to(QUANTITIES[quantity][0]).magnitude)
    except pint.errors.DimensionalityError:
        raise SignalError(
            f"{where}: units {text!r} are not units of {quantity} (its SI unit: "
            f"{QUANTITIES[quantity][0].replace('**', '^')})"
        ) from None
    except (pint.errors.UndefinedUnitError, ValueError, TypeError, AttributeError, AssertionError):
        raise SignalError(
            f"{where}: units {text!r} are not units twin can read (e.g. m, um, mil; m/s, mm/s, in/s; m/s^2, g)"
        ) from None
    return factor


def channel_quantities(ds: xr.Dataset, source: str) -> tuple[str, tuple[str, ...], np.ndarray]:
    """The record's variable, each channel's quantity and its factor to SI.

    Returns ``(variable, quantities, factors)``: ``displacement`` (every channel a displacement in the
    variable's ``units``) or ``signal`` (the ``quantity`` and ``units`` coordinates over ``channel``).
    """
    if "signal" in ds.data_vars and "displacement" in ds.data_vars:
        raise SignalError(f"{source}: both 'signal' and 'displacement': give one (docs: your own measurements)")
    if "signal" not in ds.data_vars:
        if "displacement" not in ds.data_vars:
            raise SignalError(
                f"{source}: no variable 'displacement' or 'signal' (it has: "
                f"{', '.join(map(str, ds.data_vars)) or 'none'})"
            )
        n = ds["displacement"].sizes.get("channel", 0)
        factor = si_factor(ds["displacement"].attrs.get("units", "m"), "displacement", f"{source}: 'displacement'")
        return "displacement", ("displacement",) * n, np.full(n, factor)
    da = ds["signal"]
    for coord in ("quantity", "units"):
        if coord not in da.coords or da[coord].dims != ("channel",):
            raise SignalError(
                f"{source}: 'signal' needs a '{coord}' coordinate over 'channel' (what each channel "
                "measures: displacement, velocity or acceleration, and in which units)"
            )
    names = [str(c) for c in (da["channel"].values if "channel" in da.coords else range(da.sizes["channel"]))]
    quantities = tuple(str(q).strip().lower() for q in da["quantity"].values)
    factors = np.array(
        [si_factor(u, q, f"{source}: channel '{c}'") for c, q, u in zip(names, quantities, da["units"].values)]
    )
    return "signal", quantities, factors


def derivative_orders(quantities: Sequence[str]) -> np.ndarray:
    """0, 1 or 2 per channel: how many times the channel's quantity is the displacement differentiated.

    Examples
    --------
    >>> derivative_orders(["displacement", "velocity", "acceleration"]).tolist()
    [0, 1, 2]
    """
    return np.array([QUANTITIES[q][1] for q in quantities], dtype=int)


def displacement_shapes(shapes: np.ndarray, poles: np.ndarray, orders: np.ndarray) -> np.ndarray:
    """Shapes measured in the channels' quantities, in displacement: entry ``c`` divided by ``λ ** orders[c]``.

    ``shapes`` (modes, ..., channels) and ``poles`` (modes,): a mode's velocity is ``λ`` times its displacement,
    its acceleration ``λ²`` times.

    Examples
    --------
    >>> lam = np.array([-0.1 + 10j])
    >>> bool(np.abs(displacement_shapes(np.array([[1.0, lam[0], lam[0] ** 2]]), lam, np.array([0, 1, 2])) - 1).max() < 1e-12)
    True
    """
    shapes = np.asarray(shapes, dtype=complex)
    scale = np.asarray(poles, dtype=complex).reshape((-1,) + (1,) * (shapes.ndim - 1)) ** np.asarray(orders)
    return shapes / scale
