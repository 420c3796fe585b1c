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


def test_one_writer_refuses_a_second_while_the_first_runs(tmp_path):
    from twin.netcdf import LOCK_NAME, one_writer

    with one_writer(tmp_path, "twin track") as lock:
        assert lock == tmp_path / LOCK_NAME and lock.exists()
        with pytest.raises(TwinError, match=rf"is being written by twin track \(process {os.getpid()} on "):
            with one_writer(tmp_path, "twin track"):
                pass
    assert not lock.exists()  # gone when the block ends
    with pytest.raises(RuntimeError):  # ... however it ends
        with one_writer(tmp_path, "twin track"):
            raise RuntimeError("stopped")
    assert not (tmp_path / LOCK_NAME).exists()


def test_one_writer_takes_over_from_a_killed_writer_and_removes_its_leftovers(tmp_path, caplog):
    """A writer killed outright leaves its lock and its half-written temporary files: the next one removes
    them; the finished files and anything else stay."""
    import json
    import socket
    import subprocess
    import sys

    from twin.netcdf import LOCK_NAME, one_writer

    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    pid = int(gone.stdout)  # a process that has exited
    (tmp_path / LOCK_NAME).write_text(json.dumps({"pid": pid, "host": socket.gethostname(), "what": "twin track"}))
    (tmp_path / "modes").mkdir()
    left = [tmp_path / ".track.nc.x1y2.nc.part", tmp_path / "modes" / ".record_00003.nc.abcd.nc.part"]
    for p in left:
        p.write_bytes(b"half a file")
    kept = [tmp_path / "track.nc", tmp_path / "modes" / "record_00002.nc", tmp_path / "notes.part"]
    for p in kept:
        p.write_bytes(b"done")
    with one_writer(tmp_path, "twin track"):
        assert not any(p.exists() for p in left) and all(p.exists() for p in kept)
    assert "taking over the lock of a writer that is gone" in caplog.text
    assert not (tmp_path / LOCK_NAME).exists()


def test_a_campaign_into_a_folder_another_writer_holds_is_refused_before_any_record(tmp_path, hydro_unit):
    from twin.netcdf import one_writer
    from twin.track import campaign, read_schedule

    (tmp_path / "schedule.toml").write_text("days = 1\nrecords_per_day = 2\nduration = 30.0\n")
    schedule = read_schedule(tmp_path / "schedule.toml", hydro_unit)
    out = tmp_path / "records"
    out.mkdir()
    with one_writer(out, "twin campaign"):
        with pytest.raises(TwinError, match="is being written by twin campaign"):
            campaign(hydro_unit, schedule, out, seed=1, progress=False)
    assert [p.name for p in out.iterdir()] == []


def test_a_write_the_disk_refuses_is_one_clear_error_and_leaves_nothing(tmp_path, monkeypatch):
    """A full disk surfaces from the netCDF library as "RuntimeError: NetCDF: HDF error": one line that names the
    file (and the space left when the disk is nearly full), no temporary file left."""
    import shutil
    from collections import namedtuple

    def full(*args, **kwargs):
        raise RuntimeError("NetCDF: HDF error")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", full)
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage(10e9, 10e9 - 2e6, 2e6))
    with pytest.raises(TwinError, match=r"cannot write .*a\.nc: NetCDF: HDF error; its disk has 2 MB free"):
        write_netcdf(xr.Dataset({"a": ("x", np.arange(3.0))}), tmp_path / "a.nc")
    assert not list(tmp_path.iterdir())
