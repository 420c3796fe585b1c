"""Atomic NetCDF writing with normal permissions."""

import os

import numpy as np
import pytest
import xarray as xr

from twin.errors import TwinError
from twin.netcdf import global_attrs, write_netcdf


def test_written_file_has_umask_permissions_and_no_leftovers(tmp_path):
    path = write_netcdf(xr.Dataset({"a": ("x", np.arange(3.0))}), tmp_path / "a.nc")
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
    assert [p.name for p in tmp_path.iterdir()] == ["a.nc"]


def test_failed_write_leaves_nothing(tmp_path):
    bad = xr.Dataset({"a": ("x", np.array([object()], dtype=object))})
    with pytest.raises(Exception):
        write_netcdf(bad, tmp_path / "b.nc")
    assert not list(tmp_path.iterdir())
    with pytest.raises(TwinError, match="it is a folder"):
        write_netcdf(bad, tmp_path)


def test_global_attrs_reads_the_attrs_alone_and_refuses_what_is_not_netcdf(tmp_path):
    path = write_netcdf(xr.Dataset({"x": ("t", np.arange(3.0))}, attrs={"a": "text", "n": 3}), tmp_path / "f.nc")
    got = global_attrs(path)
    assert got["a"] == "text" and int(got["n"]) == 3
    (tmp_path / "bad.nc").write_text("not NetCDF")
    with pytest.raises(OSError):
        global_attrs(tmp_path / "bad.nc")
