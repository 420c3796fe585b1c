"""FMU export: FMI validation, FMPy simulation against the numpy reference, errors."""

import zipfile

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from twin import ModelError, TwinError
from twin.fmu import export_fmu, full_state_space, truncated_state_space
from twin.fmu.modal import modal_form, simulate_modal
from twin.fmu.excitation import excitation_forces, sensor_noise, turbulence_force
from tests.fmu.reference import H, fmu_reference


@pytest.fixture(scope="module")
def unit_fmu(tmp_path_factory, hydro_unit):
    return export_fmu(hydro_unit, tmp_path_factory.mktemp("fmu") / "unit.fmu", step_s=H, inputs=["runner.x", "GEN.y"])


def test_fmu_is_valid_and_self_contained(unit_fmu):
    import os

    assert validate_fmu(str(unit_fmu)) == []
    umask = os.umask(0)
    os.umask(umask)
    assert unit_fmu.stat().st_mode & 0o777 == 0o666 & ~umask  # usual permissions, not the temp file's 0600
    names = zipfile.ZipFile(unit_fmu).namelist()
    assert {"modelDescription.xml", "resources/twin_lti.bin", "sources/twin_lti.c", "sources/fmi2Functions.h"} <= set(
        names
    )
    assert any(n.startswith("binaries/") for n in names)
    md = fmpy.read_model_description(str(unit_fmu))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    assert outputs == ["SEAL_x", "SEAL_y", "UGB_x", "UGB_y", "LGB_x", "LGB_y", "GEN_x", "GEN_y"]
    assert inputs == ["F_runner_x", "F_GEN_y"]
    assert md.coSimulation is not None and md.defaultExperiment.stepSize == repr(H)


def test_fmu_equals_the_numpyfmu_reference(unit_fmu, hydro_unit):
    n = 1500
    t = np.arange(n) * H
    u = np.zeros(n, dtype=[("time", float), ("F_runner_x", float), ("F_GEN_y", float)])
    u["time"] = t
    u["F_runner_x"] = 2e4 * np.sin(2 * np.pi * 3.3 * t)
    u["F_GEN_y"] = 1e4 * (t > 1.0)
    res = fmpy.simulate_fmu(
        str(unit_fmu),
        stop_time=t[-1],
        step_size=H,
        output_interval=H,
        input=u,
        start_values={
            "steady_start": False,
            "unbalance_me": 40.0,
            "unbalance_phase": 0.3,
            "turbulence_asd": 5e3,
            "turbulence_seed": 9,
        },
    )
    ss = full_state_space(hydro_unit)
    # external inputs are held over each step (ZOH); the built-in excitation uses FOH
    ref = fmu_reference(
        ss, n, me=40.0, phase=0.3, asd=5e3, seed=9, inputs={"28.x": u["F_runner_x"], "8.y": u["F_GEN_y"]}
    )
    y = np.column_stack([res[c] for c in ss.outputs])
    np.testing.assert_allclose(res["time"], t, rtol=1e-12, atol=1e-12)
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()


def test_sensor_noise_and_unbalance_node(unit_fmu, hydro_unit):
    n = 300
    res = fmpy.simulate_fmu(
        str(unit_fmu),
        stop_time=(n - 1) * H,
        step_size=H,
        output_interval=H,
        start_values={
            "steady_start": False,
            "unbalance_me": 10.0,
            "unbalance_node": 28,
            "noise_std": 2e-6,
            "noise_seed": 4,
            "turbulence_asd": 0.0,
        },
    )
    ss = full_state_space(hydro_unit)
    ref = fmu_reference(ss, n, me=10.0, node=28) + sensor_noise(n, 8, 2e-6, 4)
    y = np.column_stack([res[c] for c in ss.outputs])
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()


def test_modal_basis_fmu(tmp_path, hydro_unit):
    fmu = export_fmu(hydro_unit, tmp_path / "modal.fmu", basis="modal", fmax_hz=100.0)
    assert validate_fmu(str(fmu)) == []
    n = 800
    res = fmpy.simulate_fmu(
        str(fmu),
        stop_time=(n - 1) * H,
        step_size=H,
        output_interval=H,
        start_values={"turbulence_asd": 1e4, "unbalance_me": 0.0, "steady_start": False},
    )
    ss = truncated_state_space(full_state_space(hydro_unit), 100.0)
    ref = fmu_reference(ss, n, asd=1e4)
    y = np.column_stack([res[c] for c in ss.outputs])
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()


def _run(fmu, step, stop, **start):
    res = fmpy.simulate_fmu(
        str(fmu), stop_time=stop, step_size=step, output_interval=step, start_values={"steady_start": False, **start}
    )
    return np.column_stack([res[name] for name in res.dtype.names[1:]])


EXCITATION = {"unbalance_me": 40.0, "unbalance_phase": 0.3, "turbulence_asd": 5e3, "turbulence_seed": 9}


def test_the_fmu_equals_its_modal_reference_to_1e_12_of_the_rms(unit_fmu, hydro_unit):
    """The runtime steps the modal form (twin.fmu.modal) exactly as its numpy reference does."""
    n = 2000
    y = _run(unit_fmu, H, (n - 1) * H, **EXCITATION)
    ss = full_state_space(hydro_unit)
    f = excitation_forces(ss, np.arange(n) * H, 8, 40.0, 28, turbulence_force(n, 5e3, 9, H), phase_rad=0.3)
    ref = simulate_modal(modal_form(ss), H, f)
    rms = np.sqrt(np.mean(ref**2, axis=0))
    assert np.max(np.abs(y - ref) / rms) < 1e-12


@pytest.mark.parametrize(("step", "common"), [(H / 2, H), (3 * H, 3 * H), (1e-3, 0.125)])
def test_any_communication_step_follows_the_same_trajectory(unit_fmu, step, common):
    """The built-in excitation lives on the exported step's grid and a step is exact whatever its length,
    so the outputs at common times do not depend on the steps taken (1e-3 s ends on the grid every 1/8 s)."""
    stop = 48 * 0.125
    y_h = _run(unit_fmu, H, stop, **EXCITATION)
    y_s = _run(unit_fmu, step, stop, **EXCITATION)
    common = np.arange(0.0, stop + 1e-9, common)
    a, b = y_h[np.round(common / H).astype(int)], y_s[np.round(common / step).astype(int)]
    rms = np.sqrt(np.mean(y_h**2, axis=0))
    assert np.max(np.abs(a - b) / rms) < 1e-12


def test_re_export_needs_no_compiler(tmp_path, monkeypatch, hydro_unit, unit_fmu):
    """The compiled runtime is cached: a changed model exports without a compiler (its time is measured in
    benchmarks/fmu_simulation.py)."""
    monkeypatch.setenv("CC", "no-such-compiler")
    changed = hydro_unit.with_values({"UGB.kxx": 7e8})
    assert export_fmu(changed, tmp_path / "changed.fmu").stat().st_size > 1000


def test_export_errors_leave_no_file(tmp_path, hydro_unit):
    unstable = hydro_unit.with_values({"LGB.cxx": 1e3, "LGB.cyy": 1e3})
    with pytest.raises(ModelError, match=r"unstable at 134 rpm: modes at \[.*\] Hz grow"):
        export_fmu(unstable, tmp_path / "bad.fmu")
    with pytest.raises(TwinError, match="does not exist"):
        export_fmu(hydro_unit, tmp_path / "no" / "x.fmu")
    with pytest.raises(ModelError, match="no node, disk, bearing or sensor called 'turbine'"):
        export_fmu(hydro_unit, tmp_path / "bad.fmu", inputs=["turbine.x"])
    with pytest.raises(ModelError, match="needs fmax_hz"):
        export_fmu(hydro_unit, tmp_path / "bad.fmu", basis="modal")
    assert list(tmp_path.iterdir()) == []


def test_unbalance_defaults_to_the_generator_node(unit_fmu, hydro_unit):
    n = 200
    res = fmpy.simulate_fmu(
        str(unit_fmu),
        stop_time=(n - 1) * H,
        step_size=H,
        output_interval=H,
        start_values={"unbalance_me": 10.0, "turbulence_asd": 0.0, "steady_start": False},
    )
    ref = fmu_reference(full_state_space(hydro_unit), n, me=10.0, node=hydro_unit.regions["generator"][0])
    y = np.column_stack([res[c] for c in hydro_unit.channels])
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()


def test_resources_in_a_folder_with_spaces_and_percent_signs(unit_fmu, tmp_path):
    # FMI 2 passes the resource location as a percent-encoded file:// URI
    folder = tmp_path / "odd name %41 é"
    zipfile.ZipFile(unit_fmu).extractall(folder)
    res = fmpy.simulate_fmu(
        str(folder), stop_time=10 * H, step_size=H, output_interval=H, start_values={"unbalance_me": 1.0}
    )
    assert len(res) == 11 and np.abs(res["GEN_x"]).max() > 0


def test_the_default_experiment_shows_the_unit_running(unit_fmu, hydro_unit):
    """Without start values the FMU runs with the machine's own unbalance and broad-band force (its model
    file's [excitation]): the outputs move, and equal the reference with those values."""
    from twin.fem.excitation import machine_excitation

    machine = machine_excitation(hydro_unit)

    md = fmpy.read_model_description(str(unit_fmu))
    stop = float(md.defaultExperiment.stopTime)
    assert stop >= 10.0
    res = fmpy.simulate_fmu(str(unit_fmu), output_interval=H)  # the default experiment, as a host runs it
    n = len(res)
    assert abs(res["time"][-1] - stop) < H / 2
    ref = fmu_reference(
        full_state_space(hydro_unit),
        n,
        me=machine.unbalance_me,
        asd=machine.broadband_asd,
        node=machine.unbalance_node,
        steady=True,
    )
    y = np.column_stack([res[c] for c in hydro_unit.channels])
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()
    assert np.all(np.std(y[n // 2 :], axis=0) > 1e-7)  # every channel moves by more than 0.1 um
