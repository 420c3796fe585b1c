"""Bad inputs from the command line: a clear one-line error (status 2) before any work, or a correct result.

Each case is a file or an argument a newcomer could give; none may end in a
silent wrong answer, a traceback or lost work.
"""

import tempfile
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main


def _unwritable(tmp_path: Path) -> Path:
    """A folder nobody may write into: read-only for a user; /sys for root, whom permissions do not stop."""
    folder = tmp_path / "read-only"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:
        return folder
    sys_folder = Path("/sys")
    try:
        tempfile.TemporaryFile(dir=sys_folder).close()
    except OSError:
        return sys_folder
    pytest.skip("no folder here that this user cannot write")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Signals with bad time axes, a one-channel record, an empty modes file, truth files out of bounds."""
    from tests.conftest import modal_record
    from twin import load_model
    from twin.modes import write_modes
    from twin.update import synthesize_modes

    tmp = tmp_path_factory.mktemp("bad")
    poles = [-0.02 * 2 * np.pi * 2 + 2j * np.pi * 2, -0.01 * 2 * np.pi * 5 + 2j * np.pi * 5]
    shapes = [[1.0, 0.3j, 0.5], [0.2, 1.0, -0.4j]]
    ds = modal_record(poles, shapes, fs_hz=32.0, duration_s=400.0, seed=3, channels=["UGB_x", "UGB_y", "LGB_x"])
    ds.to_netcdf(tmp / "good.nc")
    ds.isel(time=slice(None, None, -1)).to_netcdf(tmp / "backwards.nc")
    ds.assign_attrs(sampling_rate=64.0).to_netcdf(tmp / "rate.nc")
    t = ds["time"].values
    ds.assign_coords(time=np.where(t > 100, t + 10, t)).to_netcdf(tmp / "hole.nc")
    ds.isel(channel=[0]).to_netcdf(tmp / "one_channel.nc")
    modes = synthesize_modes(load_model("hydro_unit"), samples=5, seed=1)
    write_modes(modes.isel(mode=[]), tmp / "empty.nc")
    write_modes(modes, tmp / "modes.nc")
    (tmp / "pull.toml").write_text("[magnetic_pull]\nstiffness = 5e7\n")
    (tmp / "fsi.toml").write_text("[fsi_per_mode]\nadded_mass = [1e5, -2.0]\nadded_damping = [0.0, 0.0]\n")
    (tmp / "model.toml").write_text(
        Path("models/hydro_unit.toml").read_text() + "\n[effects.fsi]\nadded_mass = -1.0\nadded_damping = 0.0\n"
    )
    return tmp


@pytest.mark.parametrize(
    "argv, message",
    [
        (["extract", "{f}/backwards.nc", "-o", "{o}/m.nc", "--samples", "5"], "backwards.nc: the time runs backwards"),
        (
            ["extract", "{f}/rate.nc", "-o", "{o}/m.nc", "--samples", "5"],
            "rate.nc: the sampling_rate attribute says 64 Hz but the time coordinate steps by 0.03125 s (32 Hz)",
        ),
        (
            ["extract", "{f}/hole.nc", "-o", "{o}/m.nc", "--samples", "5"],
            "hole.nc: the time axis is not evenly spaced: a step of 10.0312 s (a hole: 320 samples missing)",
        ),
        (["compare", "hydro_unit", "{f}/empty.nc"], "empty.nc: it holds no mode"),
        (["diagnose", "hydro_unit", "{f}/empty.nc", "--scheduler", "sync"], "empty.nc: it holds no mode"),
        (
            ["update", "hydro_unit", "{f}/empty.nc", "--params", "UGB.kxx", "-o", "{o}/p.nc"],
            "empty.nc: it holds no mode",
        ),
        (
            ["loop", "hydro_unit", "{f}/empty.nc", "--out", "{o}/loop", "--scheduler", "sync"],
            "empty.nc: it holds no mode",
        ),
        (
            ["simulate", "hydro_unit", "--truth", "{f}/pull.toml", "--duration", "5", "-o", "{o}/s.nc"],
            "pull.toml: [magnetic_pull]: key 'stiffness': MAG.stiffness = 5e+07 is outside its physical bounds (<= 0",
        ),
        (
            ["synthesize-modes", "hydro_unit", "--truth", "{f}/fsi.toml", "-o", "{o}/m.nc"],
            "fsi.toml: [fsi_per_mode]: key 'added_mass': FSI.added_mass_2 = -2 is outside its physical bounds (>= 0",
        ),
        (["modal", "{f}/model.toml"], "model.toml: [effects.fsi]: key 'added_mass': FSI.added_mass = -1 is outside"),
        (["modal", "hydro_unit", "--speed", "-134"], "argument --speed: must be a finite number >= 0, got -134"),
        (["campbell", "hydro_unit", "--max-speed", "nan", "-o", "{o}/c.png"], "argument --max-speed: must be a finite"),
        (
            ["extract", "{f}/good.nc", "-o", "{o}/m.nc", "--samples", "0"],
            "argument --samples: must be an integer >= 1, got 0",
        ),
        (["demo", "--hidden", "magnetic_pul", "--out", "{o}/demo"], "hidden change 'magnetic_pul': unknown"),
    ],
)
def test_bad_input_is_one_line_before_any_work(files, tmp_path, capsys, monkeypatch, argv, message):
    import twin.tasks

    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster started before the inputs were checked")

    monkeypatch.setattr(twin.tasks, "dask_client", no_cluster)
    argv = [a.replace("{f}", str(files)).replace("{o}", str(tmp_path)) for a in argv]
    with pytest.raises(SystemExit) if message.startswith("argument") else _no_raise():
        assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and message in err.strip().splitlines()[-1], err  # argparse's usage comes first
    assert message.startswith("argument") or err.count("\n") == 1, err
    assert not [p for p in tmp_path.iterdir()], "no output may be left from a refused command"


class _no_raise:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


@pytest.mark.parametrize(
    "argv",
    [
        ["loop", "hydro_unit", "{f}/modes.nc", "--out", "{ro}/loop"],
        ["compare", "hydro_unit", "{f}/modes.nc", "--plot", "{ro}"],
        ["compare", "hydro_unit", "{f}/modes.nc", "--history", "{ro}/history.csv"],
        ["demo", "--out", "{ro}/demo"],
        ["extract", "{f}/good.nc", "-o", "{ro}/m.nc"],
        ["extract", "{f}/good.nc", "-o", "{f}/m.nc", "--plot", "{ro}/stab.png"],
    ],
)
def test_an_unwritable_output_is_refused_before_the_work(files, tmp_path, capsys, monkeypatch, argv):
    import twin.tasks

    monkeypatch.setattr(twin.tasks, "dask_client", lambda *a, **k: pytest.fail("a cluster started"))
    ro = _unwritable(tmp_path)
    assert main([a.replace("{f}", str(files)).replace("{ro}", str(ro)) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("twin: error: cannot write") and str(ro) in err and err.count("\n") == 1, err


def test_a_one_channel_record_is_extracted(files, tmp_path, capsys):
    assert (
        main(["extract", str(files / "one_channel.nc"), "-o", str(tmp_path / "m.nc"), "--samples", "5", "--fmax", "8"])
        == 0
    )
    from twin.modes import read_modes

    modes = read_modes(tmp_path / "m.nc")
    assert modes.sizes["channel"] == 1 and modes.sizes["mode"] >= 1
    assert np.all(modes["MPD"].values == 0.0)  # one component lies on its own line
    assert "1 channel(s)" in capsys.readouterr().err


def test_no_truth_is_a_truth_as_the_demo_takes_it(tmp_path, capsys):
    assert (
        main(["synthesize-modes", "hydro_unit", "--truth", "none", "--samples", "3", "-o", str(tmp_path / "m.nc")]) == 0
    )
    assert "none (the model as it is)" in capsys.readouterr().out


def test_an_interrupt_is_one_line(monkeypatch, capsys):
    import twin.cli.model

    def interrupted(args):
        raise KeyboardInterrupt  # what Ctrl-C raises in the main thread

    monkeypatch.setattr(twin.cli.model, "_modal", interrupted)
    from twin.cli.parser import build_parser

    parser = build_parser()
    monkeypatch.setattr("twin.cli.parser.build_parser", lambda: parser)
    parser._subparsers._group_actions[0].choices["modal"].set_defaults(func=interrupted)
    assert main(["modal", "hydro_unit"]) == 130
    err = capsys.readouterr().err
    assert err.strip() == "twin: interrupted; the files written before are complete, none is half-written"


def test_warnings_are_one_line_and_name_what_they_assume(files, tmp_path, capsys):
    assert main(["simulate", "hydro_unit", "--fs", "20", "--duration", "2", "-o", str(tmp_path / "s.nc")]) == 0
    err = capsys.readouterr().err
    assert "twin: warning: fs = 20 Hz is low for modes up to" in err and "UserWarning" not in err
    assert "twin: simulate 2 s of hydro_unit at 20 Hz through its FMU" in err  # the stage, on a terminal as in a log
    assert (
        main(["extract", str(files / "good.nc"), "-o", str(tmp_path / "m.nc"), "--fmax", "14", "--samples", "5"]) == 0
    )
    out, err = capsys.readouterr()
    assert "fmax = 14 Hz is above 40% of the sampling rate (12.8 Hz)" in err
    assert "MPC: modal phase collinearity" in out and "MPD: mean phase deviation [deg]" in out


def test_the_truth_files_naming_is_in_the_help(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert '["bearing_change:UGB"] stiffness_change = -1e8 for UGB.stiffness_change' in text and "'none'" in text


@pytest.mark.parametrize(
    "command, said",
    [
        ("update", "250 warm-up iterations of HMC, at least 50; 20 burn-in sweeps of the Gibbs samplers"),
        ("compare", "FILE with the suffix .png (history.csv: history.png)"),
        ("modal", "ross_reference (ROSS's test rotor, for checking the FEM: unstable by design and without water"),
    ],
)
def test_the_help_says_what_the_command_does(capsys, command, said):
    from twin.update import HMCOptions, PaperOptions

    assert HMCOptions().warmup == 250 and HMCOptions.MIN_WARMUP == 50 and PaperOptions().warmup == 20
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert said in " ".join(capsys.readouterr().out.split())


def test_a_measurement_table_comes_in_with_its_units(tmp_path, capsys):
    t = np.arange(12000) / 32.0
    rng = np.random.default_rng(2)
    y = np.column_stack([np.sin(2 * np.pi * 2 * t + p) for p in (0.0, 1.0, 2.0)]) * 0.01 + rng.standard_normal(
        (12000, 3)
    )
    (tmp_path / "probes.txt").write_text(
        "# sampling_rate: 32\nA B C\n" + "\n".join(" ".join(f"{v:.6f}" for v in r) for r in y)
    )
    assert main(["import", str(tmp_path / "probes.txt"), "-o", str(tmp_path / "s.nc")]) == 2
    assert "channel 'A' has no units" in capsys.readouterr().err and not (tmp_path / "s.nc").exists()
    assert main(["import", str(tmp_path / "probes.txt"), "-o", str(tmp_path / "s.nc"), "--units", "A=um,=mm/s"]) == 2
    assert "--units takes one value or NAME=VALUE pairs" in capsys.readouterr().err
    assert (
        main(
            [
                "import",
                str(tmp_path / "probes.txt"),
                "-o",
                str(tmp_path / "s.nc"),
                "--units",
                "A=um,B=um,C=mm/s",
                "--channels",
                "UGB_x,UGB_y,LGB_x",
            ]
        )
        == 0
    )
    assert (
        "12000 samples at 32 Hz of UGB_x (displacement, um), UGB_y (displacement, um), LGB_x (velocity, mm/s)"
        in capsys.readouterr().out
    )
    from twin.extract.signals import check_record
    import xarray as xr

    assert check_record(xr.load_dataset(tmp_path / "s.nc")).quantities == ("displacement", "displacement", "velocity")


def test_extract_says_how_many_blocks_it_chose_and_a_refusal_names_a_number_it_takes(files, tmp_path, capsys):
    import re

    import xarray as xr

    short = tmp_path / "short.nc"
    with xr.open_dataset(files / "good.nc") as ds:
        ds.isel(time=slice(0, 32 * 60)).load().to_netcdf(short)  # 60 s
    rc = main(["extract", str(short), "-o", str(tmp_path / "m.nc"), "--samples", "15", "-q"])
    err = capsys.readouterr().err
    most = re.search(r"too short for 15 blocks .*at most (\d+)\), or none: the extraction then chooses", err)
    assert rc == 2 and most, err
    assert main(["extract", str(short), "-o", str(tmp_path / "m.nc")]) == 0
    out = capsys.readouterr().out
    assert f"jackknife: {most.group(1)} blocks of " in out and "the most the record holds" in out
    assert f"{most.group(1)} samples each" in out
