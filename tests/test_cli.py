"""The twin command: modal table and JSON, Campbell figure, clean errors."""

import json
from pathlib import Path

import pytest

from twin.cli import main


def test_modal_table(capsys):
    assert main(["modal", "models/hydro_unit.toml"]) == 0
    out = capsys.readouterr().out
    lines = [line for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert len(lines) >= 15
    assert "116 DOF" in out and "134 rpm" in out


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
    assert main(["campbell", "models/ross_reference.toml", "-o", str(tmp_path / "no" / "c.png")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_output_into_a_closed_pipe_is_not_an_error():
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "twin.cli", "modal", "models/hydro_unit.toml"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0)  # fmt: skip
    proc.stdout.readline()  # like `| head -1`
    proc.stdout.close()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0 and b"Traceback" not in err


def test_export_fmu_command(tmp_path, capsys):
    out = tmp_path / "unit.fmu"
    assert main(["export-fmu", "models/hydro_unit.toml", "-o", str(out), "--basis", "modal", "--fmax", "60",
                 "--inputs", "runner.x, runner.y"]) == 0  # fmt: skip
    from fmpy.validation import validate_fmu

    assert validate_fmu(str(out)) == []
    assert main(["export-fmu", "models/hydro_unit.toml", "-o", str(tmp_path / "b.fmu"), "--inputs", "shaft.x"]) == 2
    assert "no node, disk, bearing or sensor called 'shaft'" in capsys.readouterr().err
    assert not (tmp_path / "b.fmu").exists()


def _hidden_pull_modes(tmp_path):
    from twin import load_model
    from twin.extract import write_modes
    from twin.fem.effects import MagneticPull
    from twin.fem.truthfile import Truth
    from twin.update import synthesize_modes

    data = synthesize_modes(load_model("models/hydro_unit.toml"), Truth((MagneticPull(-1e8),)), n_modes=13,
                            samples=50, seed=3, pole_variance=(0.01, 0.01))  # fmt: skip
    return str(write_modes(data, tmp_path / "modes.nc"))


def test_compare_and_diagnose_commands(tmp_path, capsys):
    import json

    modes = _hidden_pull_modes(tmp_path)
    assert main(["compare", "models/hydro_unit.toml", modes, "--plot", str(tmp_path / "figs")]) == 0
    out = capsys.readouterr().out
    assert "error E = 2.74%" in out and "unweighted RMS 3.42%" in out and "GEN_y" in out
    assert sorted(p.name for p in (tmp_path / "figs").iterdir()) == ["errors.png", "mac.png", "spectra.png"]
    assert main(["diagnose", "models/hydro_unit.toml", modes, "--json", "--workers", "2",  # a local Dask cluster
                 "--candidates", "magnetic_pull,seal_cross_coupling,bearing_change:UGB"]) == 0  # fmt: skip
    report = json.loads(capsys.readouterr().out)
    assert report["verdict"] == "missing effect" and report["ranking"][0]["effect"] == "magnetic_pull"
    assert report["ranking"][0]["error_after"] < 0.2 * report["error"]
    assert main(["compare", "models/hydro_unit.toml", modes, "--effect", "magnetic_pull", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["error"] > 0.027  # a zero-valued effect changes nothing
    assert main(["diagnose", "models/hydro_unit.toml", modes, "--candidates", "magnetic_push"]) == 2
    assert "no candidate effect ['magnetic_push']" in capsys.readouterr().err


def test_update_with_an_added_effect_then_compare(tmp_path, capsys):
    from twin.loop.history import read_history

    modes = _hidden_pull_modes(tmp_path)
    post = str(tmp_path / "posterior.nc")
    history = tmp_path / "history.csv"
    assert main(["compare", "models/hydro_unit.toml", modes, "--history", str(history)]) == 0
    assert main(["update", "models/hydro_unit.toml", modes, "--effect", "magnetic_pull", "--params", "MAG.stiffness",
                 "--draws", "200", "--chains", "2", "--seed", "1", "-o", post, "--scheduler", "sync"]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["compare", "models/hydro_unit.toml", modes, "--effect", "magnetic_pull", "--posterior", post,
                 "--json", "--history", str(history)]) == 0  # fmt: skip
    after = json.loads(capsys.readouterr().out)["error"]
    assert after < 0.2 * 0.0274
    steps = read_history(history)
    assert steps["action"].values.tolist() == ["start", "add magnetic_pull; posterior posterior.nc (map)"]
    assert steps["error"].values[1] == pytest.approx(after) and steps["error"].values[0] > 0.027
    assert history.with_suffix(".png").stat().st_size > 1000
    other = tmp_path / "other.nc"
    other.write_bytes(Path(modes).read_bytes())
    assert main(["compare", "models/hydro_unit.toml", str(other), "--history", str(history)]) == 2
    assert "compares against 'modes.nc', not 'other.nc'" in capsys.readouterr().err
    assert read_history(history).sizes["step"] == 2
