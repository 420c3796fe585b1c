"""The win64 binary beside linux64: cross-compiled with Debian's mingw-w64, checked by building it and, where
Wine is installed, by running it against the Linux binary."""

import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest

from twin.fmu import export_fmu
from twin.fmu.build import CROSS_TARGETS

WIN64 = next(t for t in CROSS_TARGETS if t.fmi2_folder == "win64")
HOST = Path(__file__).parent / "data" / "fmi2_host.c"


def _wine() -> str | None:
    return (
        shutil.which("wine64")
        or shutil.which("wine")
        or next((p for p in ("/usr/lib/wine/wine64",) if Path(p).is_file()), None)
    )


@pytest.fixture(scope="module")
def fmus(tmp_path_factory, hydro_unit):
    if not shutil.which(WIN64.compiler):
        pytest.skip(f"no {WIN64.compiler}: apt-get install gcc-mingw-w64-x86-64")
    folder = tmp_path_factory.mktemp("win")
    return {v: export_fmu(hydro_unit, folder / f"unit{v}.fmu", fmi_version=v) for v in (2, 3)}


def test_the_fmu_ships_a_win64_dll_with_both_apis(fmus):
    for version, folder in ((2, "win64"), (3, "x86_64-windows")):
        data = zipfile.ZipFile(fmus[version]).read(f"binaries/{folder}/hydro_unit.dll")
        pe = int.from_bytes(data[0x3C:0x40], "little")
        assert data[:2] == b"MZ" and data[pe : pe + 4] == b"PE\0\0"
        assert int.from_bytes(data[pe + 4 : pe + 6], "little") == 0x8664  # x86-64
        assert b"fmi2DoStep" in data and b"fmi3DoStep" in data  # the export table's names


def test_the_win64_dll_runs_under_wine_as_the_linux_binary_does(fmus, tmp_path):
    wine = _wine()
    if wine is None:
        pytest.skip("no Wine: apt-get install wine64")
    fmu = fmus[2]
    unzipped = Path(fmpy.extract(str(fmu), str(tmp_path / "unit")))
    host = tmp_path / "host.exe"
    subprocess.run([shutil.which(WIN64.compiler), "-O2", "-o", str(host), str(HOST)], check=True)
    guid = fmpy.read_model_description(str(fmu)).guid
    dll = "Z:" + str(unzipped / "binaries" / "win64" / "hydro_unit.dll").replace("/", "\\")
    resources = "file:///Z:" + (unzipped / "resources").as_posix()
    n = 200
    proc = subprocess.run(
        [wine, str(host), dll, guid, resources, str(n)],
        capture_output=True,
        text=True,
        timeout=600,
        env={"WINEDEBUG": "-all", "HOME": str(Path.home()), "PATH": "/usr/bin:/bin"},
    )
    assert proc.returncode == 0, proc.stderr
    windows = np.array([[float(x) for x in line.split()] for line in proc.stdout.splitlines()])
    res = fmpy.simulate_fmu(str(fmu), stop_time=(n - 1) / 256, step_size=1 / 256, output_interval=1 / 256)
    linux = np.column_stack([res[c] for c in res.dtype.names[1:]])
    assert windows.shape == linux.shape
    np.testing.assert_allclose(windows, linux, rtol=0, atol=1e-12 * np.abs(linux).max())
