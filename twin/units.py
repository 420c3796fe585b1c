"""One pint unit registry for the package, with the units of a power plant's operating data.

pint reads µm, mm/s, g, MW, degC and their kin; the registry adds ``var`` (volt-ampere reactive, so
``Mvar`` reads), which pint leaves out. Built once, on first use, so importing twin needs no pint.
"""

from __future__ import annotations

from functools import lru_cache


@lru_cache(maxsize=1)
def registry():
    """The package's :class:`pint.UnitRegistry`.

    Examples
    --------
    >>> ureg = registry()
    >>> float(ureg.Quantity(1.0, "Mvar").to("var").magnitude)
    1000000.0
    """
    import pint

    ureg = pint.UnitRegistry()
    ureg.define("var = volt * ampere = VAr")
    return ureg


def conversion(value: float, units: str, to: str) -> float:
    """``value`` in ``units`` expressed in ``to`` (offsets included: degF to degC); pint's errors as they come.

    Examples
    --------
    >>> round(conversion(113.0, "degF", "degC"), 6), conversion(2.0e5, "kW", "MW")
    (45.0, 200.0)
    """
    ureg = registry()
    return float(ureg.Quantity(value, units).to(to).magnitude)
