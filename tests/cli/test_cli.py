"""The twin command: modal table and JSON, Campbell figure, clean errors."""

import json
from pathlib import Path

import pytest

from twin.cli import main


def test_modal_table(capsys):
    assert main(["modal", "models/hydro_unit.toml"]) == 0
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert len(lines) == 20  # 20 of 112 by default
    assert "116 DOF" in out and "134 rpm" in out and "112 modes; not listed: 92 more: --modes N" in out
    zetas = [float(line.split()[3]) for line in lines]
    light = [z < 20 for z in zetas]
    assert light == sorted(light, reverse=True)  # the lightly damped modes first
    assert main(["modal", "hydro_unit", "--modes", "112"]) == 0 and "damped 20% or more:" in capsys.readouterr().out
    assert "8 over-damped eigenvalues, no modes" in out


def test_modal_lists_no_overdamped_eigenvalue_as_a_mode(tmp_path, capsys):
    """Stiffness-proportional damping on short elements: near-real eigenvalue pairs, counted but not listed."""
    text = Path("models/ross_reference.toml").read_text().replace("speed_rpm = 134.0", "speed_rpm = 3000.0")
    (tmp_path / "rotor.toml").write_text(text + "\n[damping]\nshaft_stiffness_proportional = 1e-3\n")
    assert main(["modal", str(tmp_path / "rotor.toml"), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert all(m["damping_ratio"] < 0.9999 for m in data["modes"])
    assert len(data["modes"]) + len(data["overdamped_rates_per_s"]) // 2 <= 28 and data["overdamped_rates_per_s"]
    assert main(["modal", str(tmp_path / "rotor.toml")]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.strip()[:1].isdigit()]
    assert float(lines[0].split()[3]) < 20  # a lightly damped mode first, not a 16 kHz element eigenvalue


def test_modal_json(capsys):
    assert main(["modal", "models/ross_reference.toml", "--speed", "0", "--modes", "4", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["n_dof"] == 28 and data["speed_rpm"] == 0.0 and len(data["modes"]) == 4
    first = data["modes"][0]
    assert {"frequency_hz", "damping_ratio", "whirl", "stable"} <= set(first)
    assert first["whirl"] == "forward" and first["stable"] is False


def test_campbell_command(tmp_path, capsys):
    out = tmp_path / "c.png"
    assert main(["campbell", "models/ross_reference.toml", "--points", "3", "--modes", "4", "-o", str(out)]) == 0
    assert out.stat().st_size > 1000


def test_errors_are_one_line_with_status_2(tmp_path, capsys):
    assert main(["modal", str(tmp_path / "none.toml")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("twin: error: ") and "no such file" in err and "Traceback" not in err
    # an output in a missing folder: the folder is made (as --plot and --out do)
    assert (
        main(["campbell", "ross_reference", "--points", "2", "--modes", "2", "-o", str(tmp_path / "no" / "c.png")]) == 0
    )
    assert (tmp_path / "no" / "c.png").is_file()
    capsys.readouterr()


@pytest.mark.parametrize(
    "argv, message",
    [
        (["campbell", "ross_reference", "-o", "{tmp}"], "it is a folder; give a file name inside it"),
        (["campbell", "ross_reference", "-o", "{tmp}/c"], "name a .png, .pdf, .svg file"),
        (["synthesize-modes", "hydro_unit", "-o", "{tmp}"], "it is a folder"),
        (["compare", "hydro_unit", "{tmp}"], "is a folder, not a modes file"),
        (["compare", "hydro_unit", "{tmp}/text.nc"], "text.nc: not a NetCDF file"),
        (
            ["update", "hydro_unit", "{tmp}/m.nc", "--params", "MAG.stiffness", "-o", "{tmp}/p.nc"],
            "'MAG.stiffness'; it comes with the effect 'magnetic_pull': add it first",
        ),
        (["demo", "--out", "{tmp}/text.nc"], "--out {tmp}/text.nc is a file, not a folder"),
    ],
)
def test_bad_paths_and_names_fail_early_on_one_line(tmp_path, capsys, argv, message):
    from twin import load_model
    from twin.modes import write_modes
    from twin.update import synthesize_modes

    (tmp_path / "text.nc").write_text("step,error\n")
    write_modes(synthesize_modes(load_model("hydro_unit"), samples=5, seed=1), tmp_path / "m.nc")
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("twin: error: ") and message.replace("{tmp}", str(tmp_path)) in err, err
    assert "Traceback" not in err and err.count("\n") == 1


def test_help_of_every_command_has_a_description_an_example_and_its_defaults(capsys):
    from twin.cli.parser import build_parser

    parser = build_parser()
    commands = parser._subparsers._group_actions[0].choices
    for name, sub in commands.items():
        text = sub.format_help()
        assert "examples:\n  twin " + name in text, name
        assert len(sub.description) > 60, name
        for action in sub._actions:
            if action.option_strings and action.default not in (None, False, "==SUPPRESS==") and action.help:
                assert "default" in sub._get_formatter()._get_help_string(action), (name, action.dest)

    def flat(name):
        return " ".join(commands[name].format_help().split())

    assert "(default: full)" in flat("export-fmu") and "required with --basis modal" in flat("simulate")
    assert "fresh entropy" in flat("update")


def test_verbose_and_quiet_go_after_the_command(capsys):
    assert main(["modal", "hydro_unit", "--modes", "1", "-v", "-q"]) == 0
    assert "1.113" in capsys.readouterr().out


def test_params_lists_names_bounds_and_the_effects_that_bring_more(capsys):
    assert main(["params", "hydro_unit"]) == 0
    out = capsys.readouterr().out
    assert "UGB.kxx" in out and ">= 0" in out and "magnetic_pull: " in out and "MAG.stiffness [N/m]: <= 0" in out
    assert main(["params", "hydro_unit", "--effect", "magnetic_pull", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    mag = next(p for p in data["parameters"] if p["name"] == "MAG.stiffness")
    assert mag["high"] == 0.0 and mag["low"] is None and data["effects"] == ["magnetic_pull"]
    assert "magnetic_pull" not in data["library"] and "bearings" in data["groups"]


def test_from_ross_writes_a_model_file_that_loads(tmp_path, capsys):
    out = tmp_path / "rig.toml"
    assert main(["from-ross", "tests/data/ross/rotor_example.toml", "--speed", "3000", "-o", str(out)]) == 0
    assert "7 nodes, 2 disks, 2 bearings" in capsys.readouterr().out
    assert main(["modal", str(out), "--modes", "4", "--json"]) == 0
    assert len(json.loads(capsys.readouterr().out)["modes"]) == 4
    layered = tmp_path / "layered.toml"
    layered.write_text(Path("tests/data/ross/rotor_example.toml").read_text().replace("n = 3\naxial", "n = 2\naxial"))
    assert main(["from-ross", str(layered), "--speed", "3000", "-o", str(tmp_path / "no.toml")]) == 2
    assert "second shaft element at position 2" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layered.toml", "rig.toml"]  # nothing half-written


def test_output_into_a_closed_pipe_is_not_an_error():
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "twin.cli", "modal", "models/hydro_unit.toml"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        bufsize=0,
    )
    proc.stdout.readline()  # like `| head -1`
    proc.stdout.close()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and b"Traceback" not in err


def test_export_fmu_command(tmp_path, capsys):
    out = tmp_path / "unit.fmu"
    assert (
        main(
            [
                "export-fmu",
                "models/hydro_unit.toml",
                "-o",
                str(out),
                "--basis",
                "modal",
                "--fmax",
                "60",
                "--inputs",
                "runner.x, runner.y",
            ]
        )
        == 0
    )
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(out)) == []
    assert main(["export-fmu", "models/hydro_unit.toml", "-o", str(tmp_path / "b.fmu"), "--inputs", "shaft.x"]) == 2
    assert "no node, disk, bearing or sensor called 'shaft'" in capsys.readouterr().err
    assert not (tmp_path / "b.fmu").exists()


def _hidden_pull_modes(tmp_path):
    from twin import load_model
    from twin.modes import write_modes
    from twin.fem.effects import MagneticPull
    from twin.fem.truthfile import Truth
    from twin.update import synthesize_modes

    data = synthesize_modes(
        load_model("models/hydro_unit.toml"),
        Truth((MagneticPull(-1e8),)),
        n_modes=13,
        samples=50,
        seed=3,
        pole_variance=(0.01, 0.01),
    )
    return str(write_modes(data, tmp_path / "modes.nc"))


@pytest.mark.slow
def test_compare_and_diagnose_commands(tmp_path, capsys):
    import json

    modes = _hidden_pull_modes(tmp_path)
    assert main(["compare", "models/hydro_unit.toml", modes, "--plot", str(tmp_path / "figs")]) == 0
    out = capsys.readouterr().out
    assert "error E = 0.18%" in out and "unweighted RMS 3.42%" in out and "GEN_y" in out
    assert "E weighs each mode's error by the inverse variance of its measured pole" in out
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == ["errors.png", "mac.png", "spectra.png"]
    assert (
        main(
            [
                "diagnose",
                "models/hydro_unit.toml",
                modes,
                "--json",
                "--workers",
                "2",  # a local Dask cluster
                "--candidates",
                "magnetic_pull,seal_cross_coupling,bearing_change:UGB",
            ]
        )
        == 0
    )
    report = json.loads(capsys.readouterr().out)
    assert report["verdict"] == "missing effect" and report["ranking"][0]["effect"] == "magnetic_pull"
    assert report["ranking"][0]["error_after"] < 0.2 * report["error"]
    assert main(["compare", "models/hydro_unit.toml", modes, "--effect", "magnetic_pull", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["error"] == pytest.approx(
        0.001847, rel=1e-3
    )  # a zero-valued effect changes nothing
    assert (
        main(["diagnose", "models/hydro_unit.toml", modes, "--candidates", "magnetic_pull", "--scheduler", "sync"]) == 0
    )
    assert "ln B: the log Bayes factor of the model with the candidate" in capsys.readouterr().out
    assert main(["diagnose", "models/hydro_unit.toml", modes, "--candidates", "magnetic_push"]) == 2
    assert "no candidate effect ['magnetic_push']" in capsys.readouterr().err


def test_update_with_an_added_effect_then_compare(tmp_path, capsys):
    from twin.loop.history import read_history

    modes = _hidden_pull_modes(tmp_path)
    post = str(tmp_path / "posterior.nc")
    history = tmp_path / "history.csv"
    assert main(["compare", "models/hydro_unit.toml", modes, "--history", str(history)]) == 0
    assert (
        main(
            [
                "update",
                "models/hydro_unit.toml",
                modes,
                "--effect",
                "magnetic_pull",
                "--params",
                "MAG.stiffness",
                "--draws",
                "200",
                "--chains",
                "2",
                "--seed",
                "1",
                "-o",
                post,
                "--scheduler",
                "sync",
            ]
        )
        == 0
    )
    capsys.readouterr()
    assert (
        main(
            [
                "compare",
                "models/hydro_unit.toml",
                modes,
                "--effect",
                "magnetic_pull",
                "--posterior",
                post,
                "--json",
                "--history",
                str(history),
            ]
        )
        == 0
    )
    after = json.loads(capsys.readouterr().out)["error"]
    assert after < 0.2 * 0.001847
    steps = read_history(history)
    assert steps["action"].values.tolist() == ["start", "add magnetic_pull; posterior posterior.nc (map)"]
    assert steps["error"].values[1] == pytest.approx(after) and steps["error"].values[0] > 0.0018
    assert history.with_suffix(".png").stat().st_size > 1000
    other = tmp_path / "other.nc"
    other.write_bytes(Path(modes).read_bytes())
    assert main(["compare", "models/hydro_unit.toml", str(other), "--history", str(history)]) == 2
    assert "compares against 'modes.nc', not 'other.nc'" in capsys.readouterr().err
    assert read_history(history).sizes["step"] == 2


def test_laplace_update_then_the_next_round_from_the_command_line(tmp_path, capsys):
    """update --method laplace writes a posterior.nc; compare and diagnose --posterior add its effects themselves."""
    modes = _hidden_pull_modes(tmp_path)
    post = str(tmp_path / "laplace.nc")
    assert (
        main(
            [
                "update",
                "models/hydro_unit.toml",
                modes,
                "--method",
                "laplace",
                "--effect",
                "magnetic_pull",
                "--params",
                "MAG.stiffness",
                "-o",
                post,
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "Laplace update of 1 parameters" in printed and "MAG.stiffness" in printed
    assert main(["compare", "models/hydro_unit.toml", modes, "--posterior", post, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["error"] < 0.2 * 0.001847
    assert (
        main(
            [
                "diagnose",
                "models/hydro_unit.toml",
                modes,
                "--posterior",
                post,
                "--scheduler",
                "sync",
                "--candidates",
                "seal_cross_coupling,thrust_tilt:thrust",
            ]
        )
        == 0
    )
    assert "verdict: nothing missing" in capsys.readouterr().out
    import arviz

    assert float(arviz.from_netcdf(post).posterior["theta"].mean()) == pytest.approx(-1e8, rel=0.05)
    assert (
        main(
            [
                "update",
                "models/hydro_unit.toml",
                modes,
                "--method",
                "laplace",
                "--params",
                "UGB.kxx",
                "--draws",
                "10",
                "-o",
                post,
            ]
        )
        == 2
    )
    assert "--method laplace takes no sampler settings (--draws)" in capsys.readouterr().err


@pytest.mark.slow
def test_per_mode_fsi_from_the_command_line(tmp_path, capsys):
    """compare --effect fsi_per_mode, update --fsi --method laplace, compare --posterior: the three used to fail."""
    from twin import load_model
    from twin.modes import write_modes
    from twin.fem.truthfile import paper_truth
    from twin.update import synthesize_modes

    data = synthesize_modes(load_model("models/hydro_unit.toml"), paper_truth(), samples=30, seed=4).isel(
        mode=[0, 2, 3, 4]
    )
    modes = str(write_modes(data, tmp_path / "modes.nc"))
    assert main(["compare", "models/hydro_unit.toml", modes, "--effect", "fsi_per_mode", "--json"]) == 0
    before = json.loads(capsys.readouterr().out)["error"]
    post = str(tmp_path / "fsi.nc")
    assert main(["update", "models/hydro_unit.toml", modes, "--method", "laplace", "--fsi", "-o", post]) == 0
    capsys.readouterr()
    assert main(["compare", "models/hydro_unit.toml", modes, "--posterior", post, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["error"] < 0.2 * before


@pytest.mark.slow
def test_loop_command_writes_the_rounds_the_history_and_the_posterior(tmp_path, capsys):
    from twin.loop.history import read_history

    modes = _hidden_pull_modes(tmp_path)
    out = tmp_path / "loop"
    assert (
        main(
            [
                "loop",
                "models/hydro_unit.toml",
                modes,
                "--out",
                str(out),
                "--candidates",
                "magnetic_pull,seal_cross_coupling,thrust_tilt:thrust",
                "--draws",
                "200",
                "--chains",
                "2",
                "--seed",
                "1",
                "--scheduler",
                "sync",
            ]
        )
        == 0
    )  # (the default update: the Gibbs sampler)
    printed = capsys.readouterr().out
    assert "round 1: missing effect (magnetic_pull)" in printed and "round 2: nothing missing" in printed
    assert "updated MAG.stiffness = -" in printed and "an effect is added at zero" in printed
    rounds = json.loads((out / "diagnosis.json").read_text())["rounds"]
    assert [r["verdict"] for r in rounds] == ["missing effect", "nothing missing"]
    steps = read_history(out / "history.csv")
    assert steps["error"].values[-1] < 0.2 * steps["error"].values[0]
    assert main(["compare", "models/hydro_unit.toml", modes, "--posterior", str(out / "posterior.nc"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["error"] == pytest.approx(steps["error"].values[-1], rel=1e-6)


def test_the_cli_methods_and_sampler_options_are_the_librarys():
    import dataclasses

    from twin.cli.loop import METHODS, SAMPLER_OPTIONS
    from twin.update import DEFAULT_METHOD, SAMPLERS
    from twin.update import METHODS as LIBRARY_METHODS

    assert METHODS == LIBRARY_METHODS and METHODS[0] == DEFAULT_METHOD
    fields = {f.name for s in SAMPLERS.values() for f in dataclasses.fields(s.options_type)}
    assert set(SAMPLER_OPTIONS) <= fields


def test_the_command_starts_without_the_numerical_stack():
    """``twin --help`` and argument errors answer at once: building the parser imports no numpy, xarray or Dask
    (benchmarks/startup.py times it)."""
    import subprocess
    import sys

    code = (
        "import sys; from twin.cli.parser import build_parser; build_parser(); "
        "print(sorted(m for m in ('numpy', 'xarray', 'scipy', 'distributed', 'fmpy') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.slow
def test_loop_after_an_extraction_with_documented_options_goes_to_the_end(tmp_path, capsys):
    """``twin extract --samples 15 --fmax 60`` then ``twin loop``: the calibration re-extracts its simulated
    records with the settings the modes file records, and the loop writes its result."""
    truth = tmp_path / "truth.toml"
    truth.write_text("[seal_cross_coupling]\nkxy = 4e7\n")
    signals, modes, out = tmp_path / "signals.nc", tmp_path / "modes.nc", tmp_path / "loop"
    assert (
        main(
            [
                "simulate",
                "hydro_unit",
                "--duration",
                "600",
                "--truth",
                str(truth),
                "--seed",
                "21",
                "-o",
                str(signals),
                "-q",
            ]
        )
        == 0
    )
    assert main(["extract", str(signals), "--samples", "15", "--fmax", "60", "-o", str(modes), "-q"]) == 0
    capsys.readouterr()
    assert (
        main(
            [
                "loop",
                "hydro_unit",
                str(modes),
                "--out",
                str(out),
                "--candidates",
                "seal_cross_coupling",
                "--bootstrap",
                "3",
                "--draws",
                "100",
                "--seed",
                "1",
                "--scheduler",
                "sync",
                "-q",
            ]
        )
        == 0
    )
    printed = capsys.readouterr().out
    assert "seal_cross_coupling" in printed
    assert (out / "posterior.nc").is_file() and (out / "history.csv").is_file()
    assert "calibrated on 3 simulated records" in (out / "history.csv").read_text()
