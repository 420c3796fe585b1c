"""The FMU runtime's FMI 2.0 behaviour beyond stepping: FMU state, reset, and a log message per error."""

import fmpy
import numpy as np
import pytest
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

from twin.fmu import export_fmu

H = 1.0 / 256.0


@pytest.fixture(scope="module")
def fmu(tmp_path_factory, hydro_unit):
    return export_fmu(hydro_unit, tmp_path_factory.mktemp("fmu") / "unit.fmu", step_s=H, inputs=["runner.x"])


class Instance:
    """An FMPy slave of the FMU, its value references by name and the messages it logged."""

    def __init__(self, path, name="a"):
        self.md = fmpy.read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.outputs = [self.vr[v.name] for v in self.md.modelVariables if v.causality == "output"]
        self.messages = []
        self.slave = FMU2Slave(
            guid=self.md.guid,
            unzipDirectory=fmpy.extract(str(path)),
            modelIdentifier=self.md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(self._log)  # kept alive with the instance
        self.slave.instantiate(callbacks=self.callbacks)

    def _log(self, component, instance, status, category, message):
        self.messages.append(message.decode().replace("%%", "%"))

    def start(self, **values):
        s = self.slave
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        for name, value in values.items():
            kind = s.setBoolean if isinstance(value, bool) else s.setInteger if isinstance(value, int) else s.setReal
            kind([self.vr[name]], [value])
        s.exitInitializationMode()

    def run(self, t0, steps):
        out = []
        for k in range(steps):
            self.slave.setReal([self.vr["F_runner_x"]], [1e4 * np.sin(7.0 * (t0 + k * H))])
            self.slave.doStep(t0 + k * H, H)
            out.append(self.slave.getReal(self.outputs))
        return np.array(out)


EXCITED = {"unbalance_me": 30.0, "turbulence_asd": 4e3, "noise_std": 1e-6, "turbulence_seed": 5}


def test_a_saved_state_replays_bit_for_bit(fmu):
    """Every random draw and the state vector come back with the state: the steps after it repeat exactly."""
    a = Instance(fmu)
    a.start(**EXCITED)
    a.run(0.0, 50)
    state = a.slave.getFMUstate()
    first = a.run(50 * H, 40)
    a.slave.setFMUstate(state)
    again = a.run(50 * H, 40)
    np.testing.assert_array_equal(again, first)
    assert np.abs(first).max() > 0
    a.slave.freeFMUstate(state)
    a.slave.terminate()
    a.slave.freeInstance()


def test_a_serialized_state_restores_another_instance(fmu):
    a, b = Instance(fmu, "a"), Instance(fmu, "b")
    a.start(**EXCITED)
    a.run(0.0, 30)
    blob = a.slave.serializeFMUstate(a.slave.getFMUstate())
    expected = a.run(30 * H, 25)
    b.start()  # other parameters: the state brings the instance's own
    b.slave.setFMUstate(b.slave.deSerializeFMUstate(blob))
    np.testing.assert_array_equal(b.run(30 * H, 25), expected)
    assert b.slave.getReal([b.vr["unbalance_me"]]) == [30.0]
    with pytest.raises(Exception, match="fmi2DeSerializeFMUstate"):
        b.slave.deSerializeFMUstate(bytes(blob[:-8]))
    assert any("not a state of this FMU" in m for m in b.messages)


def test_reset_returns_to_the_start_values(fmu):
    a = Instance(fmu)
    start = {v.name: v.start for v in a.md.modelVariables if v.causality == "parameter"}
    a.start(**EXCITED, unbalance_node=28, steady_start=False)
    first = a.run(0.0, 20)
    a.slave.reset()
    get = {"Integer": a.slave.getInteger, "Real": a.slave.getReal, "Boolean": a.slave.getBoolean}
    types = {v.name: v.type for v in a.md.modelVariables}
    got = {v.name: get[v.type]([v.valueReference])[0] for v in a.md.modelVariables if v.causality == "parameter"}
    parse = {"Integer": int, "Real": float, "Boolean": lambda text: text == "true"}
    assert got == {k: parse[types[k]](v) for k, v in start.items()}
    a.start(**EXCITED, unbalance_node=28, steady_start=False)
    np.testing.assert_array_equal(a.run(0.0, 20), first)  # the run after a reset repeats the first


def test_every_error_says_why(fmu):
    a = Instance(fmu)
    with pytest.raises(Exception):
        a.slave.doStep(0.0, H)
    a.start()
    calls = [
        lambda: a.slave.getReal([999]),
        lambda: a.slave.setReal([a.vr["unbalance_me"]], [1.0]),
        lambda: a.slave.setInteger([a.vr["noise_seed"]], [3]),
        lambda: a.slave.getInteger([4242]),
        lambda: a.slave.getBoolean([1]),
        lambda: a.slave.doStep(0.0, -H),
    ]
    for call in calls:
        with pytest.raises(Exception):
            call()
    assert len(a.messages) == 1 + len(calls), a.messages
    assert "fmi2DoStep: called before the end of initialisation" in a.messages[0]
    assert "value reference 999" in a.messages[1] and "fixed after initialisation" in a.messages[2]


def test_identifier_documentation_and_units(tmp_path, hydro_unit):
    import zipfile

    path = export_fmu(hydro_unit, tmp_path / "t.fmu", name="hydro_unit truth: magnetic_pull")
    md = fmpy.read_model_description(str(path))
    assert md.modelName == "hydro_unit truth: magnetic_pull"
    assert md.coSimulation.modelIdentifier == "hydro_unit_truth_magnetic_pull"
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    names = zipfile.ZipFile(path).namelist()
    assert any(n.startswith("binaries/") and "/hydro_unit_truth_magnetic_pull." in n for n in names)
    page = zipfile.ZipFile(path).read("documentation/index.html").decode()
    reals = [v for v in md.modelVariables if v.type == "Real"]
    assert all(v.unit for v in reals), [v.name for v in reals if not v.unit]  # every Real has its unit
    for v in md.modelVariables:
        assert f"<td>{v.name}</td>" in page
    units = {u.name: u for u in md.unitDefinitions}
    assert {v.unit for v in reals} <= set(units)
    um = next(d for d in units["m"].displayUnits if d.name == "um")
    assert float(um.factor) == 1e6


def test_sources_build_with_a_function_prefix(tmp_path, hydro_unit):
    """Compiled from sources/ with FMI2_FUNCTION_PREFIX, two FMUs' functions carry their identifiers and
    link into one library side by side."""
    import subprocess
    import zipfile

    from twin.fmu.build import find_compiler

    cc = find_compiler()
    objects = []
    for ident in ("unit_a", "unit_b"):
        src = tmp_path / ident
        zipfile.ZipFile(export_fmu(hydro_unit, tmp_path / f"{ident}.fmu", name=ident)).extractall(src)
        obj = tmp_path / f"{ident}.o"
        subprocess.run(
            [
                cc,
                "-c",
                "-fPIC",
                f"-DFMI2_FUNCTION_PREFIX={ident}_",
                f"-I{src / 'sources'}",
                str(src / "sources" / "twin_lti.c"),
                "-o",
                str(obj),
            ],
            check=True,
        )
        objects.append(obj)
    lib = tmp_path / "both.so"
    subprocess.run([cc, "-shared", *map(str, objects), "-o", str(lib), "-lm"], check=True)
    symbols = subprocess.run(["nm", "-D", str(lib)], capture_output=True, text=True, check=True).stdout
    assert "unit_a_fmi2DoStep" in symbols and "unit_b_fmi2DoStep" in symbols
    assert " fmi2DoStep" not in symbols
