"""FMU export: FMI validation, FMPy simulation against the numpy reference, errors."""

import zipfile

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from twin import ModelError, TwinError
from twin.fmu import discretize, export_fmu, full_state_space, simulate_reference, truncated_state_space
from twin.fem.model import RPM_TO_RAD_S
from twin.fmu.excitation import excitation_forces, gaussian_stream, sensor_noise, turbulence_force
from twin.fmu.steady import STEADY_STREAM, steady_start, steady_state

H = 1.0 / 256.0


@pytest.fixture(scope="module")
def unit_fmu(tmp_path_factory, hydro_unit):
    return export_fmu(hydro_unit, tmp_path_factory.mktemp("fmu") / "unit.fmu", step_s=H, inputs=["runner.x", "GEN.y"])


def _reference(ss, n, me=0.0, node=8, phase=0.0, asd=0.0, seed=1, inputs=None, steady=False, t0=0.0):
    """Exact recursion with the FMU's excitation: external inputs ZOH, unbalance and turbulence FOH; from
    rest, or (``steady``) from the FMU's steady start (twin.fmu.steady)."""
    t = t0 + np.arange(n) * H
    zoh = np.zeros((n, len(ss.ports)))
    turbulence = turbulence_force(n, asd, seed, H)
    foh = excitation_forces(ss, t, node, me, 28, turbulence, phase_rad=phase)
    for port, values in (inputs or {}).items():
        zoh[:, ss.port_index(port)] += values
    disc = discretize(ss, H)
    x0 = None
    if steady:
        omega = ss.speed_rpm * RPM_TO_RAD_S
        g = gaussian_stream((seed & (2**64 - 1)) ^ STEADY_STREAM, disc.phi.shape[0])
        x0 = steady_state(steady_start(disc, omega, ss.node_ports(28)), disc, t0_s=t0, omega_rad_s=omega,
                          me_kgm=me, phase_rad=phase, unbalance_ports=ss.node_ports(node), turbulence_asd=asd, g=g,
                          turbulence_ports=ss.node_ports(28) if asd > 0 else [], f0=turbulence[0])  # fmt: skip
    return simulate_reference(disc, ss.C, zoh=zoh, foh=foh, x0=x0)


def test_fmu_is_valid_and_self_contained(unit_fmu):
    import os

    assert validate_fmu(str(unit_fmu)) == []
    umask = os.umask(0)
    os.umask(umask)
    assert unit_fmu.stat().st_mode & 0o777 == 0o666 & ~umask  # usual permissions, not the temp file's 0600
    names = zipfile.ZipFile(unit_fmu).namelist()
    assert {"modelDescription.xml", "resources/twin_lti.bin", "sources/twin_lti.c", "sources/fmi2Functions.h"} <= set(names)
    assert any(n.startswith("binaries/") for n in names)
    md = fmpy.read_model_description(str(unit_fmu))
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    inputs = [v.name for v in md.modelVariables if v.causality == "input"]
    assert outputs == ["SEAL_x", "SEAL_y", "UGB_x", "UGB_y", "LGB_x", "LGB_y", "GEN_x", "GEN_y"]
    assert inputs == ["F_runner_x", "F_GEN_y"]
    assert md.coSimulation is not None and md.defaultExperiment.stepSize == repr(H)


def test_fmu_equals_the_numpy_reference(unit_fmu, hydro_unit):
    n = 1500
    t = np.arange(n) * H
    u = np.zeros(n, dtype=[("time", float), ("F_runner_x", float), ("F_GEN_y", float)])
    u["time"] = t
    u["F_runner_x"] = 2e4 * np.sin(2 * np.pi * 3.3 * t)
    u["F_GEN_y"] = 1e4 * (t > 1.0)
    res = fmpy.simulate_fmu(str(unit_fmu), stop_time=t[-1], step_size=H, output_interval=H, input=u,
                            start_values={"steady_start": False, "unbalance_me": 40.0, "unbalance_phase": 0.3, "turbulence_asd": 5e3,
                                          "turbulence_seed": 9})  # fmt: skip
    ss = full_state_space(hydro_unit)
    # external inputs are held over each step (ZOH); the built-in excitation uses FOH
    ref = _reference(ss, n, me=40.0, phase=0.3, asd=5e3, seed=9, inputs={"28.x": u["F_runner_x"], "8.y": u["F_GEN_y"]})
    y = np.column_stack([res[c] for c in ss.outputs])
    np.testing.assert_allclose(res["time"], t, rtol=1e-12, atol=1e-12)
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()


def test_sensor_noise_and_unbalance_node(unit_fmu, hydro_unit):
    n = 300
    res = fmpy.simulate_fmu(str(unit_fmu), stop_time=(n - 1) * H, step_size=H, output_interval=H,
                            start_values={"steady_start": False, "unbalance_me": 10.0, "unbalance_node": 28, "noise_std": 2e-6, "noise_seed": 4,
                                          "turbulence_asd": 0.0})  # fmt: skip
    ss = full_state_space(hydro_unit)
    ref = _reference(ss, n, me=10.0, node=28) + sensor_noise(n, 8, 2e-6, 4)
    y = np.column_stack([res[c] for c in ss.outputs])
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()


def test_modal_basis_fmu(tmp_path, hydro_unit):
    fmu = export_fmu(hydro_unit, tmp_path / "modal.fmu", basis="modal", fmax_hz=100.0)
    assert validate_fmu(str(fmu)) == []
    n = 800
    res = fmpy.simulate_fmu(str(fmu), stop_time=(n - 1) * H, step_size=H, output_interval=H,
                            start_values={"turbulence_asd": 1e4, "unbalance_me": 0.0, "steady_start": False})
    ss = truncated_state_space(full_state_space(hydro_unit), 100.0)
    ref = _reference(ss, n, asd=1e4)
    y = np.column_stack([res[c] for c in ss.outputs])
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()


def test_wrong_communication_step_is_refused(unit_fmu):
    with pytest.raises(Exception, match="fmi2DoStep"):
        fmpy.simulate_fmu(str(unit_fmu), stop_time=0.1, step_size=H / 2, output_interval=H / 2)


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
    res = fmpy.simulate_fmu(str(unit_fmu), stop_time=(n - 1) * H, step_size=H, output_interval=H,
                            start_values={"unbalance_me": 10.0, "turbulence_asd": 0.0, "steady_start": False})  # fmt: skip
    ref = _reference(full_state_space(hydro_unit), n, me=10.0, node=hydro_unit.regions["generator"][0])
    y = np.column_stack([res[c] for c in hydro_unit.channels])
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()


def test_resources_in_a_folder_with_spaces_and_percent_signs(unit_fmu, tmp_path):
    # FMI 2 passes the resource location as a percent-encoded file:// URI
    folder = tmp_path / "odd name %41 é"
    zipfile.ZipFile(unit_fmu).extractall(folder)
    res = fmpy.simulate_fmu(str(folder), stop_time=10 * H, step_size=H, output_interval=H,
                            start_values={"unbalance_me": 1.0})  # fmt: skip
    assert len(res) == 11 and np.abs(res["GEN_x"]).max() > 0


def test_the_default_experiment_shows_the_unit_running(unit_fmu, hydro_unit):
    """Without start values the FMU runs with twin's default unbalance and turbulence: the outputs move,
    and equal the reference with those values."""
    from twin.defaults import DEFAULT_TURBULENCE_ASD, DEFAULT_UNBALANCE_ME

    md = fmpy.read_model_description(str(unit_fmu))
    stop = float(md.defaultExperiment.stopTime)
    assert stop >= 10.0
    res = fmpy.simulate_fmu(str(unit_fmu), output_interval=H)  # the default experiment, as a host runs it
    n = len(res)
    assert abs(res["time"][-1] - stop) < H / 2
    ref = _reference(full_state_space(hydro_unit), n, me=DEFAULT_UNBALANCE_ME, asd=DEFAULT_TURBULENCE_ASD,
                     node=hydro_unit.regions["generator"][0], steady=True)  # fmt: skip
    y = np.column_stack([res[c] for c in hydro_unit.channels])
    assert np.abs(y - ref).max() < 1e-9 * np.abs(ref).max()
    assert np.all(np.std(y[n // 2:], axis=0) > 1e-7)  # every channel moves by more than 0.1 um
