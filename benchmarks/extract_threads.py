"""Extraction time with one BLAS thread (as ``extract`` runs) against the machine's threads.

One 20 min record of the hydro unit (FMU, 256 Hz, no hidden effect) is
extracted as the loop does (``fmax 60 Hz``, 15 delete-one samples, 60 shape
samples from random halves of the blocks), alternately as shipped (one BLAS
thread, :func:`twin.tasks.one_blas_thread`) and with the threads OpenBLAS
would use by itself (``extract.__wrapped__``, the same code without the
limit), ``--repeat`` times each in the same process. It reports the best
wall times, their ratio and the largest differences of the two results.

    python benchmarks/extract_threads.py [--seed 1] [--repeat 2]

Writes ``benchmarks/results/extract_threads.md``. Run it on an idle machine:
the threaded runs need the cores free.
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).parent / "results" / "extract_threads.md"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=2, help="runs per setting; the fastest counts")
    args = ap.parse_args()
    from twin import load_model, shipped_model
    from twin.extract import extract
    from twin.fmu.simulate import simulate
    from twin.harness.demo import SAMPLES, SHAPE_SAMPLES_PER_SAMPLE
    from twin.tasks import blas_threads

    model = load_model(shipped_model("hydro_unit"))
    signals = simulate(model, duration_s=1200.0, fs_hz=256.0, seed=args.seed, progress=False)
    options = dict(fmax_hz=60.0, samples=SAMPLES, shape_samples=SHAPE_SAMPLES_PER_SAMPLE * SAMPLES, progress=False)
    runs = {"one BLAS thread (extract)": extract, "BLAS's own threads": extract.__wrapped__}
    best, out = {k: np.inf for k in runs}, {}
    for _ in range(args.repeat):
        for name, function in runs.items():
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out[name] = function(signals, **options)
            best[name] = min(best[name], time.perf_counter() - t0)
    one, many = out.values()
    threads = blas_threads()
    lines = [
        "# Extraction: one BLAS thread against the machine's",
        "",
        f"Command: `python benchmarks/extract_threads.py --seed {args.seed} --repeat {args.repeat}`; one 20-min "
        f"record at 256 Hz, fmax 60 Hz, {SAMPLES} samples and {SHAPE_SAMPLES_PER_SAMPLE * SAMPLES} shape samples; best of "
        f"{args.repeat}; BLAS's own threads here: {threads}.",
        "",
        "| setting | extract [s] |",
        "| --- | --- |",
    ]
    lines += [f"| {name} | {t:.1f} |" for name, t in best.items()]
    t_one, t_many = best.values()
    lines += ["", f"Threaded / one thread: {t_many / t_one:.2f}."]
    if one.sizes["mode"] == many.sizes["mode"]:
        lines.append(
            f"Same {one.sizes['mode']} modes; largest relative difference of the frequencies "
            f"{np.max(np.abs(one.frequency.values / many.frequency.values - 1)):.1e}, of the damping ratios "
            f"{np.max(np.abs(one.damping_ratio.values / many.damping_ratio.values - 1)):.1e}."
        )
    else:
        lines.append(f"Different modes found: {one.sizes['mode']} with one thread, {many.sizes['mode']} threaded.")
    RESULTS.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
