"""Benchmark: 1 h of 8 proximeter channels at 256 Hz through the FMU, against pure numpy.

For the full FEM (232 states) and a truncated modal basis (modes up to 100 Hz), from rest:

* ``fmpy.simulate_fmu``: FMPy's general simulation loop end to end;
* ``record_outputs``: :func:`twin.fmu.run.record_outputs`, FMPy's loader with twin's recording loop in C
  (what ``twin simulate`` runs);
* ``numpy``: the same system and excitation by the exact modal recursion in numpy
  (:func:`twin.fmu.modal.simulate_modal`, one ``scipy.signal.lfilter`` per pole), the practical lower limit
  for simulating an LTI system in Python; every time is also given as a ratio to it, measured in the same run.

Then ``twin simulate`` itself (:func:`twin.fmu.simulate.simulate`: the export, the warm-up from rest and
the record, the Dataset) for the same hour of the full FEM, and with its steady start (no warm-up), and the time to export a changed model once the C
runtime is compiled and cached (the loop re-exports after every update), against building its state space.

With ``--baseline-fmu`` an FMU of the full hydro unit exported by another version of twin (``twin export-fmu
hydro_unit -o old.fmu`` on a checkout of it) is timed in the same run through ``fmpy.simulate_fmu``, for the
record alone and for the warm-up from rest plus the record (what ``twin simulate`` ran), so a change of the
runtime is measured against the same numpy reference.

Run from the repository root:  python benchmarks/fmu_simulation.py [--duration 3600] [--baseline-fmu OLD.fmu]
[--out FILE.md]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import fmpy
import numpy as np

import twin
from twin.fmu import export_fmu, full_state_space, truncated_state_space
from twin.fmu.excitation import excitation_forces, turbulence_force
from twin.fmu.modal import modal_form, simulate_modal
from twin.fmu.run import record_outputs
from twin.fmu.simulate import default_warmup_s, simulate

ROOT = Path(__file__).resolve().parent.parent
FS = 256.0
ASD, ME = 3000.0, 100.0
START = {"turbulence_asd": ASD, "unbalance_me": ME, "steady_start": False}  # from rest, as the numpy reference


def numpy_modal(ss, n: int, h: float) -> tuple[np.ndarray, float]:
    """The FMU's run (its built-in excitation, from rest) by the numpy modal recursion, and its time [s]."""
    start = time.perf_counter()
    f = excitation_forces(ss, np.arange(n) * h, 8, ME, 28, turbulence_force(n, ASD, 1, h))
    y = simulate_modal(modal_form(ss), h, f)
    return y, time.perf_counter() - start


def fmu_runs(fmu: Path, outputs: list[str], n: int, h: float) -> tuple[float, float, np.ndarray]:
    """Seconds of ``fmpy.simulate_fmu`` and of ``record_outputs`` for ``n`` samples, and the outputs."""
    start = time.perf_counter()
    res = fmpy.simulate_fmu(str(fmu), stop_time=(n - 1) * h, step_size=h, output_interval=h, start_values=START)
    general = time.perf_counter() - start
    y_fmpy = np.column_stack([res[name] for name in outputs])
    start = time.perf_counter()
    y = record_outputs(fmu, outputs=outputs, n_samples=n, step_s=h, start_values=START)
    recorded = time.perf_counter() - start
    if not np.array_equal(y, y_fmpy):
        raise SystemExit("record_outputs and fmpy.simulate_fmu differ")
    return general, recorded, y


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=3600.0, help="simulated time [s] (default 3600)")
    parser.add_argument("--out", type=Path, default=None, help="also write the table to this Markdown file")
    parser.add_argument(
        "--baseline-fmu",
        type=Path,
        default=None,
        help="an FMU of the full hydro unit from another twin version, timed in the same run",
    )
    args = parser.parse_args()
    if args.baseline_fmu is not None and not args.baseline_fmu.is_file():
        parser.error(f"--baseline-fmu: no file {args.baseline_fmu}")
    h = 1.0 / FS
    n = int(round(args.duration * FS))
    model = twin.load_model(ROOT / "models" / "hydro_unit.toml")
    full = full_state_space(model)
    modal = truncated_state_space(full, 100.0)
    lines = [
        f"{args.duration:g} s at {FS:g} Hz = {n} samples of 8 channels; turbulence {ASD:g} N/sqrt(Hz), "
        f"unbalance {ME:g} kg m",
        "",
        "| system | states | fmpy.simulate_fmu [s] | record_outputs [s] | numpy modal [s] | "
        "fmpy / numpy | record / numpy | us per step (record) | max deviation / peak |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    with tempfile.TemporaryDirectory() as tmp:
        export_fmu(model, Path(tmp) / "warm.fmu", step_s=h)  # compiles (or finds) the cached runtime
        changed = model.with_values({"UGB.kxx": 7e8})
        start = time.perf_counter()
        export_fmu(changed, Path(tmp) / "changed.fmu", step_s=h)
        export_s = time.perf_counter() - start
        start = time.perf_counter()
        full_state_space(changed)
        build_s = time.perf_counter() - start
        ref_full = None
        for label, ss in (("full FEM", full), ("modal <= 100 Hz", modal)):
            fmu = export_fmu(model, Path(tmp) / f"{ss.basis}.fmu", step_s=h, state_space=ss, inputs=[])
            general, recorded, y = fmu_runs(fmu, ss.outputs, n, h)
            y_ref, ref = numpy_modal(ss, n, h)
            ref_full = ref if ref_full is None else ref_full
            dev = np.abs(y - y_ref).max() / np.abs(y_ref).max()
            lines.append(
                f"| {label} | {ss.n_states} | {general:.2f} | {recorded:.2f} | {ref:.2f} | "
                f"{general / ref:.2f} | {recorded / ref:.2f} | {1e6 * recorded / n:.1f} | {dev:.1e} |"
            )
        twin_s = {}
        for steady in (False, True):
            start = time.perf_counter()
            simulate(model, duration_s=args.duration, fs_hz=FS, seed=1, steady_start=steady, progress=False)
            twin_s[steady] = time.perf_counter() - start
    lines += [""] + [
        f"twin simulate of the full FEM ({what}): {twin_s[steady]:.2f} s, "
        f"{twin_s[steady] / ref_full:.2f} x the numpy modal reference of the same run"
        for steady, what in ((False, "from rest, default warm-up"), (True, "steady start, no warm-up"))
    ]
    if args.baseline_fmu is not None:
        lines.append("")
        n_warm = int(np.ceil(default_warmup_s(full) * FS))
        for what, samples in (("the record", n), (f"warm-up ({n_warm * h:.1f} s) and record", n_warm + n)):
            start = time.perf_counter()
            fmpy.simulate_fmu(
                str(args.baseline_fmu), stop_time=(samples - 1) * h, step_size=h, output_interval=h, start_values=START
            )
            spent = time.perf_counter() - start
            lines.append(
                f"baseline FMU {args.baseline_fmu.name}, {what} through fmpy.simulate_fmu: {spent:.2f} s, "
                f"{spent / ref_full:.2f} x the numpy modal reference of the same run"
            )
    lines += [
        f"re-export of a changed model (runtime cached): {1e3 * export_s:.0f} ms, "
        f"{export_s / build_s:.1f} x building its state space ({1e3 * build_s:.0f} ms)"
    ]
    text = "\n".join(lines)
    print(text)
    if args.out is not None:
        command = "python benchmarks/fmu_simulation.py" + (
            f" --duration {args.duration:g}" if args.duration != 3600 else ""
        )
        if args.baseline_fmu is not None:
            command += f" --baseline-fmu {args.baseline_fmu.name}"
        args.out.write_text(f"# FMU simulation speed\n\nCommand: `{command}`\n\n{text}\n")


if __name__ == "__main__":
    main()
