"""modes.nc: complex variables stored as real and imaginary parts, read back complex."""

import numpy as np
import pytest
import xarray as xr

from twin.errors import SignalError
from twin.modes.modesfile import join_complex, read_modes, split_complex, write_modes


def test_round_trip_keeps_complex_values(tmp_path):
    rng = np.random.default_rng(0)
    ds = xr.Dataset(
        {
            "pole": (
                ("mode", "sample"),
                rng.standard_normal((2, 3)) + 1j * rng.standard_normal((2, 3)),
                {"units": "1/s"},
            ),
            "shape": (
                ("mode", "sample", "channel"),
                rng.standard_normal((2, 3, 4)) + 1j * rng.standard_normal((2, 3, 4)),
            ),
            "frequency": ("mode", [1.0, 2.0], {"units": "Hz"}),
        }
    )
    split = split_complex(ds)
    assert {"pole_real", "pole_imag", "shape_real", "shape_imag"} <= set(split.data_vars)
    assert split.pole_real.attrs["units"] == "1/s"
    xr.testing.assert_identical(join_complex(split)[["pole", "shape"]].drop_attrs(), ds[["pole", "shape"]].drop_attrs())
    path = write_modes(ds, tmp_path / "modes.nc")
    back = read_modes(path)
    assert np.array_equal(back.pole.values, ds.pole.values) and np.array_equal(back.shape.values, ds.shape.values)


def test_read_errors(tmp_path):
    with pytest.raises(SignalError, match="no such modes file"):
        read_modes(tmp_path / "none.nc")
    (tmp_path / "junk.nc").write_text("not netcdf")
    with pytest.raises(SignalError, match="junk.nc: not a NetCDF file"):
        read_modes(tmp_path / "junk.nc")
    xr.Dataset({"a": ("x", [1.0])}).to_netcdf(tmp_path / "other.nc")
    with pytest.raises(SignalError, match="not a modes file: no variable pole_real"):
        read_modes(tmp_path / "other.nc")
