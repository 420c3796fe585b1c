"""The ``modes.nc`` file: identified modes with J samples each (its variables: ``docs/guide/extract.md``).

In memory the poles and shapes are complex (``pole`` over mode x sample,
``shape`` over mode x sample x channel, the full-record ``sensor_shape`` over
mode x channel), so the Dataset pairs with :func:`twin.modal` output through
:func:`twin.pair_modes`. NetCDF has no complex type: on disk each complex
variable ``v`` is stored as ``v_real`` and ``v_imag`` (``pole_real``,
``pole_imag``, ``shape_real``, ``shape_imag``, ...).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from twin.errors import SignalError
from twin.netcdf import load_netcdf, write_netcdf

#: Complex variables of a modes Dataset, stored as <name>_real / <name>_imag.
COMPLEX_VARIABLES = ("pole", "shape", "sensor_shape")
#: What the stages that need modes say of a modes Dataset with none (an extraction that found no mode writes one).
NO_MODES = (
    "it holds no mode (the extraction found none in its band): nothing to compare or update; look at its "
    "stabilisation diagram (twin extract --plot) and try another band, more orders or a longer record"
)


def split_complex(ds: xr.Dataset) -> xr.Dataset:
    """The on-disk layout: every complex variable as ``<name>_real`` and ``<name>_imag``."""
    out = ds.copy()
    for name in [v for v in ds.data_vars if np.iscomplexobj(ds[v])]:
        da = ds[name]
        out = out.drop_vars(name)
        for part, values in (("real", da.real), ("imag", da.imag)):
            attrs = {**da.attrs, "long_name": f"{da.attrs.get('long_name', name)} ({part} part)"}
            out[f"{name}_{part}"] = values.assign_attrs(attrs)
    return out


def join_complex(ds: xr.Dataset) -> xr.Dataset:
    """Inverse of :func:`split_complex`."""
    out = ds.copy()
    for name in COMPLEX_VARIABLES:
        if f"{name}_real" in ds and f"{name}_imag" in ds:
            re, im = ds[f"{name}_real"], ds[f"{name}_imag"]
            attrs = {k: v for k, v in re.attrs.items() if k != "long_name"}
            long_name = str(re.attrs.get("long_name", name)).removesuffix(" (real part)")
            out[name] = (re + 1j * im).assign_attrs({**attrs, "long_name": long_name})
            out = out.drop_vars([f"{name}_real", f"{name}_imag"])
    return out


def write_modes(ds: xr.Dataset, path: str | Path) -> Path:
    """Write a modes Dataset to NetCDF (complex parts stored apart, atomic write)."""
    return write_netcdf(split_complex(ds), path)


def read_modes(path: str | Path) -> xr.Dataset:
    """Read a ``modes.nc`` file; poles and shapes come back complex.

    Raises
    ------
    SignalError
        When the file is missing, not NetCDF, or lacks the pole and shape variables.
    """
    return modes_from(load_netcdf(path, "modes", SignalError), path)


def modes_from(ds: xr.Dataset, path: str | Path) -> xr.Dataset:
    """The modes Dataset held by ``ds``, loaded from the file ``path`` (:func:`read_modes` without the read)."""
    missing = [v for v in ("pole_real", "pole_imag", "shape_real", "shape_imag") if v not in ds]
    if missing:
        raise SignalError(f"{path}: not a modes file: no variable {', '.join(missing)}")
    out = join_complex(ds)
    out.encoding["source"] = str(path)  # where the data came from, for the messages of the stages that use them
    return out
