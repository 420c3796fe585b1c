"""Cross-checks with FMI importers nobody here wrote: DNV's libcosim (libcosimpy, FMI 1.0 and 2.0 only) runs
the FMU as FMPy does, and the FMU Manipulation Toolbox's checker finds it conformant to FMI 2.0 and 3.0."""

import subprocess
import sys

import fmpy
import numpy as np
import pytest

from twin.fmu import export_fmu

H_NS = 3_906_250  # 1/256 s in libcosim's nanoseconds, exactly
H = H_NS * 1e-9


@pytest.fixture(scope="module")
def fmu(tmp_path_factory, hydro_unit):
    return export_fmu(
        hydro_unit, tmp_path_factory.mktemp("fmu") / "unit.fmu", step_s=H, basis="modal", fmax_hz=60.0, inputs=[]
    )


def _libcosim_run(path, steps, starts, instances=("unit",)):
    """Outputs per step of each instance of the FMU in one libcosim execution."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    log_output_level(CosimLogLevel.WARNING)
    md = fmpy.read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    outputs = [vr[v.name] for v in md.modelVariables if v.causality == "output"]
    execution = CosimExecution.from_step_size(step_size=H_NS)
    slaves = [
        execution.add_local_slave(local_slave=CosimLocalSlave(fmu_path=str(path), instance_name=name))
        for name in instances
    ]
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer=observer)
    for slave, values in zip(slaves, starts):
        for name, value in values.items():
            setter = execution.integer_initial_value if isinstance(value, int) else execution.real_initial_value
            setter(slave_index=slave, variable_reference=vr[name], value=value)
    out = [[] for _ in slaves]
    for _ in range(steps):
        execution.step()
        for k, slave in enumerate(slaves):
            out[k].append(observer.last_real_values(slave_index=slave, variable_references=outputs))
    return [np.array(y) for y in out], [v.name for v in md.modelVariables if v.causality == "output"]


def test_libcosim_runs_two_instances_as_fmpy_does(fmu):
    pytest.importorskip("libcosimpy", reason="pip install libcosimpy (in the test extra)")
    starts = [{"turbulence_asd": 2000.0, "turbulence_seed": 4}, {"unbalance_me": 50.0, "turbulence_seed": 9}]
    runs, names = _libcosim_run(fmu, 300, starts, instances=("a", "b"))
    for y, values in zip(runs, starts):
        res = fmpy.simulate_fmu(str(fmu), stop_time=300 * H, step_size=H, output_interval=H, start_values=values)
        reference = np.column_stack([res[c] for c in names])[1:]  # libcosim observes after each step
        np.testing.assert_array_equal(y, reference)
        assert np.abs(y).max() > 0


@pytest.mark.parametrize("version", [2, 3])
def test_the_fmu_manipulation_toolbox_finds_it_conformant(tmp_path, hydro_unit, version):
    """FMI 2.0 and 3.0, co-simulation and model exchange in one FMU each."""
    pytest.importorskip("fmu_manipulation_toolbox", reason="pip install fmu-manipulation-toolbox (in the test extra)")
    fmu = export_fmu(hydro_unit, tmp_path / f"unit{version}.fmu", basis="modal", fmax_hz=60.0, fmi_version=version)
    proc = subprocess.run(
        [sys.executable, "-m", "fmu_manipulation_toolbox", "-input", str(fmu), "-check"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    text = proc.stdout + proc.stderr
    assert f"compliant with FMI-{version}.0" in text, text
    assert "No semantic error" in text, text
    assert "ERROR" not in text.upper().replace("NO SEMANTIC ERROR", ""), text
