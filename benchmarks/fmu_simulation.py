"""Benchmark: 1 h of 8 proximeter channels at 256 Hz through the FMU, against pure numpy.

For the full FEM (232 states) and a truncated modal basis (modes up to 100 Hz):

* ``fmpy``: ``fmpy.simulate_fmu`` end to end (what ``twin simulate`` does);
* ``doStep only``: the same number of ``fmi2DoStep`` calls from Python with no
  recording, which splits FMPy's per-step overhead from the FMU's own step;
* ``numpy modal``: the same system and excitation by the exact modal
  recursion (each complex mode is a first-order IIR filter, ``scipy.signal.lfilter``),
  the practical lower limit for simulating an LTI system in Python.

It also times exporting a changed model once the C runtime is compiled and
cached (the loop re-exports after every update), against building its state
space in the same process.

Run from the repository root:  python benchmarks/fmu_simulation.py [--duration 3600]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.linalg as sla
from scipy.signal import lfilter

import twin
from twin.fmu import export_fmu, full_state_space, truncated_state_space
from twin.fmu.excitation import excitation_forces, turbulence_force

ROOT = Path(__file__).resolve().parent.parent
FS = 256.0
ASD, ME = 3000.0, 100.0


def numpy_modal(ss, n: int, h: float) -> tuple[np.ndarray, float]:
    """Exact FOH recursion of the diagonalised system (as the FMU's built-in excitation), one lfilter per mode.

    ``z[k+1] = a z[k] + g0 u[k] + g1 (u[k+1] - u[k])`` with ``a = e^{λh}``,
    ``g0 = (a - 1)/λ`` and ``g1 = (a - 1 - λh)/(λ² h)``.
    """
    start = time.perf_counter()
    t = np.arange(n) * h
    f = excitation_forces(ss, t, 8, ME, 28, turbulence_force(n, ASD, 1, h))
    used = np.nonzero(np.any(f != 0, axis=0))[0]
    lam, vec = sla.eig(ss.A)
    left = np.linalg.inv(vec)
    drive = f[:, used] @ (left @ ss.B[:, used]).T  # (n, states): modal forcing
    a = np.exp(lam * h)
    g0 = (a - 1) / lam
    g1 = (a - 1 - lam * h) / (lam**2 * h)
    z = np.empty_like(drive)
    k = np.arange(n)
    for i in range(len(lam)):
        # lfilter gives x[k] = a x[k-1] + g1 u[k] + (g0 - g1) u[k-1] with x[0] = g1 u[0];
        # the FMU starts from rest (z[0] = 0), so remove the free response of that start
        x = lfilter([g1[i], g0[i] - g1[i]], [1.0, -a[i]], drive[:, i])
        z[:, i] = x - g1[i] * drive[0, i] * a[i] ** k
    y = np.real(z @ (ss.C @ vec).T)
    return y, time.perf_counter() - start


def fmu_runs(fmu: Path, n: int, h: float) -> tuple[float, float, np.ndarray]:
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    start = time.perf_counter()
    res = fmpy.simulate_fmu(str(fmu), stop_time=(n - 1) * h, step_size=h, output_interval=h,
                            start_values={"turbulence_asd": ASD, "unbalance_me": ME, "steady_start": False})  # fmt: skip
    total = time.perf_counter() - start
    y = np.column_stack([res[name] for name in res.dtype.names[1:]])

    md = fmpy.read_model_description(str(fmu))
    unzipped = fmpy.extract(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier)
    slave.instantiate()
    slave.setReal([3, 1], [ASD, ME])
    slave.setBoolean([8], [False])  # from rest, as the numpy reference
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    start = time.perf_counter()
    t = 0.0
    for k in range(n - 1):
        slave.doStep(currentCommunicationPoint=t, communicationStepSize=h)
        t = (k + 1) * h
    steps = time.perf_counter() - start
    slave.terminate()
    slave.freeInstance()
    return total, steps, y


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=3600.0, help="simulated time [s] (default 3600)")
    args = parser.parse_args()
    h = 1.0 / FS
    n = int(round(args.duration * FS))
    model = twin.load_model(ROOT / "models" / "hydro_unit.toml")
    full = full_state_space(model)
    modal = truncated_state_space(full, 100.0)
    print(f"{args.duration:g} s at {FS:g} Hz = {n} steps, 8 channels; turbulence {ASD:g} N/sqrt(Hz), unbalance {ME:g} kg m")
    with tempfile.TemporaryDirectory() as tmp:
        export_fmu(model, Path(tmp) / "warm.fmu", step_s=h)  # compiles (or finds) the cached runtime
        changed = model.with_values({"UGB.kxx": 7e8})
        start = time.perf_counter()
        export_fmu(changed, Path(tmp) / "changed.fmu", step_s=h)
        export_s = time.perf_counter() - start
        start = time.perf_counter()
        full_state_space(changed)
        build_s = time.perf_counter() - start
        print(f"re-export of a changed model (runtime cached): {1e3 * export_s:.0f} ms, "
              f"{export_s / build_s:.1f}x building its state space ({1e3 * build_s:.0f} ms)")
        for label, ss in (("full FEM", full), ("modal <= 100 Hz", modal)):
            fmu = export_fmu(model, Path(tmp) / f"{ss.basis}.fmu", step_s=h, state_space=ss, inputs=[])
            total, steps, y = fmu_runs(fmu, n, h)
            y_ref, ref = numpy_modal(ss, n, h)
            dev = np.abs(y - y_ref).max() / np.abs(y_ref).max()
            print(f"{label:>16} ({ss.n_states:3d} states): fmpy {total:7.2f} s | doStep loop only {steps:7.2f} s "
                  f"({1e6 * steps / n:5.1f} us/step) | numpy modal {ref:6.2f} s | fmpy / numpy = {total / ref:5.1f}x "
                  f"| max deviation {dev:.1e}")


if __name__ == "__main__":
    main()
