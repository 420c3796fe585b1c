"""The FMU as FMI 2.0 model exchange: a host's solver integrates its modal states; directional derivatives."""

import ctypes

import fmpy
import numpy as np
import pytest
from fmpy.fmi2 import FMU2Model
from fmpy.validation import validate_fmu
from scipy.integrate import solve_ivp

from twin.fmu import export_fmu, full_state_space, truncated_state_space
from twin.fmu.modal import modal_form

H = 1.0 / 256.0
FMAX = 60.0
START = {"steady_start": True, "noise_std": 0.0, "unbalance_me": 100.0, "turbulence_asd": 3000.0}


@pytest.fixture(scope="module")
def modal_fmu(tmp_path_factory, hydro_unit):
    return export_fmu(
        hydro_unit, tmp_path_factory.mktemp("me") / "modal.fmu", basis="modal", fmax_hz=FMAX, inputs=["runner.x"]
    )


def _cs(fmu, stop, names):
    res = fmpy.simulate_fmu(
        str(fmu),
        fmi_type="CoSimulation",
        stop_time=stop,
        step_size=H,
        output_interval=H,
        start_values=START,
        output=names,
    )
    return np.column_stack([res[n] for n in names])


class Host:
    """A model-exchange host that stops its solver at every time event, as the standard asks: scipy's
    DOP853 between the FMU's nextEventTime instants, through FMPy's FMU2Model."""

    def __init__(self, fmu):
        self.md = fmpy.read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.nx = sum(1 for v in self.md.modelVariables if v.derivative is not None)
        self.fmu = FMU2Model(
            guid=self.md.guid,
            unzipDirectory=fmpy.extract(str(fmu)),
            modelIdentifier=self.md.modelExchange.modelIdentifier,
        )
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        fmpy.simulation.apply_start_values(self.fmu, self.md, START)
        self.fmu.exitInitializationMode()
        self.buf = (ctypes.c_double * self.nx)()

    def _vector(self, get):
        get(self.buf, self.nx)
        return np.array(self.buf)

    def _rhs(self, t, x):
        self.fmu.setTime(t)
        self.fmu.setContinuousStates((ctypes.c_double * self.nx)(*x), self.nx)
        return self._vector(self.fmu.getDerivatives)

    def run(self, stop, outputs, rtol):
        vr = [self.vr[n] for n in outputs]
        event = self.fmu.newDiscreteStates()[-1]
        self.fmu.enterContinuousTimeMode()
        x = self._vector(self.fmu.getContinuousStates)
        atol = rtol * self._vector(self.fmu.getNominalsOfContinuousStates)
        t, rows = 0.0, [self.fmu.getReal(vr)]
        while t < stop - 1e-12:
            t_next = min(event, stop)
            sol = solve_ivp(self._rhs, (t, t_next), x, method="DOP853", rtol=rtol, atol=atol)
            assert sol.success, f"t = {t}: {sol.message}"
            x = sol.y[:, -1]
            t = t_next
            self.fmu.setTime(t)
            self.fmu.setContinuousStates((ctypes.c_double * self.nx)(*x), self.nx)
            self.fmu.completedIntegratorStep()
            self.fmu.enterEventMode()
            event = self.fmu.newDiscreteStates()[-1]
            self.fmu.enterContinuousTimeMode()
            rows.append(self.fmu.getReal(vr))
        return np.array(rows)


def test_a_host_that_stops_at_events_integrates_it_to_its_tolerance(modal_fmu):
    """Model exchange follows the co-simulation's exact trajectory to the host solver's tolerance."""
    outputs = ["SEAL_x", "UGB_y", "LGB_x", "GEN_y"]
    stop = 1.0
    cs = _cs(modal_fmu, stop, outputs)
    rms = np.sqrt(np.mean(cs**2, axis=0))
    errors = [np.max(np.abs(Host(modal_fmu).run(stop, outputs, rtol) - cs) / rms) for rtol in (1e-6, 1e-9)]
    assert errors[1] < 1e-8 and errors[1] < errors[0] / 100, errors


def test_fmpy_simulates_it_as_model_exchange_to_its_tolerance(modal_fmu):
    """FMPy's CVode (which integrates past time events and interpolates back) converges to the exact
    trajectory as its tolerance shrinks."""
    assert validate_fmu(str(modal_fmu)) == []
    outputs = ["SEAL_x", "GEN_y"]
    cs = _cs(modal_fmu, 0.5, outputs)
    errors = []
    for rtol in (1e-6, 1e-9):
        res = fmpy.simulate_fmu(
            str(modal_fmu),
            fmi_type="ModelExchange",
            stop_time=0.5,
            output_interval=H,
            start_values=START,
            output=outputs,
            relative_tolerance=rtol,
        )
        after = np.r_[res["time"][1:] != res["time"][:-1], True]  # the row after each event
        me = np.column_stack([res[n] for n in outputs])[after]
        np.testing.assert_allclose(res["time"][after], np.arange(len(cs)) * H, atol=1e-12)
        errors.append(np.max(np.abs(me - cs) / np.sqrt(np.mean(cs**2, axis=0))))
    assert errors[1] < 1e-5 and errors[1] < errors[0] / 10, errors


def test_directional_derivatives_are_the_modal_matrices(modal_fmu, hydro_unit):
    """d der(z)/dz is the 2x2 block of each pole, d der(z)/du the modal input row, dy/dz the output row."""
    host = Host(modal_fmu)
    md, fmu = host.md, host.fmu
    states = [v.valueReference for v in md.modelVariables if v.name.startswith("z[")]
    ders = [v.valueReference for v in md.modelVariables if v.name.startswith("der(")]
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    u = host.vr["F_runner_x"]
    form = modal_form(truncated_state_space(full_state_space(hydro_unit), FMAX))
    A = np.zeros((host.nx, host.nx))
    for i, lam in enumerate(form.poles):
        A[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[lam.real, -lam.imag], [lam.imag, lam.real]]
    C = np.zeros((len(outputs), host.nx))
    C[:, 0::2], C[:, 1::2] = form.cv.real, -form.cv.imag
    port = form.wb[:, 2 * 28]  # runner (node 28), x
    B = np.column_stack([port.real, port.imag]).ravel()
    seed = np.random.default_rng(1).standard_normal(host.nx + 1)
    jac = np.array(fmu.getDirectionalDerivative(ders + outputs, states + [u], list(seed)))
    expected = np.r_[A @ seed[:-1] + B * seed[-1], C @ seed[:-1]]
    np.testing.assert_allclose(jac, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())
