"""Extraction time with the Hankel matrix's leading singular triplets from Lanczos (the default) against the full SVD.

One 20 min record of the hydro unit (FMU, 256 Hz, seed 1, no hidden effect) is
extracted as the loop does (``fmax 60 Hz``, 15 delete-one samples and 60
shape samples from random halves of the blocks, ``--shape-samples``) twice per
setting in the same process (a number: one SSI pass with that many block
rows, as extract does by default; ``auto``: the default block rows and
``shape_block_rows="auto"``, a second pass for the slow modes' shapes,
:mod:`twin.extract.passes`): once as shipped (ARPACK's Lanczos for
the ``max_order`` leading triplets, :func:`twin.extract.ssi.leading_singular`)
and once with ``PARTIAL_SVD_FRACTION = 0`` (every realisation from the full
SVD). It reports the wall times, their ratio and the largest differences of
the two results' frequencies, damping ratios and shape samples.

    python benchmarks/ssi_speed.py [--block-rows 107,214[,auto]] [--seed 1] [--repeat 2] [--shape-samples 60]

Writes ``benchmarks/results/ssi_speed.md``.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

from twin.tasks import one_blas_thread

RESULTS = Path(__file__).parent / "results" / "ssi_speed.md"


@one_blas_thread
def timed_extractions(signals, block_rows: int | None, repeat: int, shape_samples: int = 0) -> dict:
    """Best-of-``repeat`` wall time of ``extract`` with Lanczos and with the full SVD, and the results' differences.

    ``block_rows``: one SSI pass with that many; None: ``shape_block_rows="auto"`` (two passes).
    ``shape_samples``: ``extract``'s (0: the shapes come with the poles' samples)."""
    import twin.extract.ssi as ssi
    from twin.extract import extract
    from twin.harness.demo import SAMPLES

    options = {"shape_block_rows": "auto"} if block_rows is None else {"block_rows": block_rows}
    if shape_samples:
        options["shape_samples"] = shape_samples

    def run():
        best, out = np.inf, None
        for _ in range(repeat):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                out = extract(signals, fmax_hz=60.0, samples=SAMPLES, progress=False, **options)
            best = min(best, time.perf_counter() - t0)
        return best, out

    t_lanczos, lanczos = run()
    fraction, ssi.PARTIAL_SVD_FRACTION = ssi.PARTIAL_SVD_FRACTION, 0.0
    try:
        t_full, full = run()
    finally:
        ssi.PARTIAL_SVD_FRACTION = fraction
    same = lanczos.sizes["mode"] == full.sizes["mode"]
    diff = {}
    if same:
        diff = {
            "frequency": float(np.max(np.abs(lanczos.frequency.values / full.frequency.values - 1))),
            "damping": float(np.max(np.abs(lanczos.damping_ratio.values / full.damping_ratio.values - 1))),
            "shape": float(np.max(np.abs(lanczos.shape.values - full.shape.values))),
        }
    settings = json.loads(lanczos.attrs["settings"])
    rows = (
        f"{settings['block_rows']}"
        if block_rows is not None
        else f"{settings['block_rows']}, slow modes' shapes at {settings['shape_block_rows']}"
    )
    return {
        "block_rows": rows,
        "modes": int(lanczos.sizes["mode"]),
        "same_modes": same,
        "t_lanczos": t_lanczos,
        "t_full": t_full,
        **diff,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--block-rows",
        default="107,214",
        help="comma-separated block rows of one pass, or auto (a second pass for the slow modes' shapes)",
    )
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repeat", type=int, default=2, help="runs per setting; the fastest counts")
    ap.add_argument(
        "--shape-samples",
        type=int,
        default=None,
        help="extract's shape samples (default: the loop's, 4 per sample; 0: none; auto block rows take none)",
    )
    args = ap.parse_args()
    from twin import load_model, shipped_model
    from twin.fmu.simulate import simulate
    from twin.harness.demo import SAMPLES, SHAPE_SAMPLES_PER_SAMPLE

    shape_samples = SHAPE_SAMPLES_PER_SAMPLE * SAMPLES if args.shape_samples is None else args.shape_samples

    model = load_model(shipped_model("hydro_unit"))
    signals = simulate(model, duration_s=1200.0, fs_hz=256.0, seed=args.seed, progress=False)
    settings = [None if b.strip() == "auto" else int(b) for b in args.block_rows.split(",")]
    rows = [timed_extractions(signals, b, args.repeat, 0 if b is None else shape_samples) for b in settings]
    lines = [
        "# SSI: leading singular triplets by Lanczos against the full SVD",
        "",
        f"Command: `python benchmarks/ssi_speed.py --block-rows {args.block_rows} --seed {args.seed} "
        f"--repeat {args.repeat} --shape-samples {shape_samples}`; one BLAS thread, best of {args.repeat}; "
        f"{shape_samples or 'no'} shape samples of their own (none with auto block rows).",
        "",
        "| block rows | modes | extract, Lanczos [s] | extract, full SVD [s] | full / Lanczos | "
        "max rel. diff. frequency | max rel. diff. damping | max abs. diff. shape samples |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for r in rows:
        d = (
            f"{r['frequency']:.1e} | {r['damping']:.1e} | {r['shape']:.1e}"
            if r["same_modes"]
            else "different modes found | | "
        )
        lines.append(
            f"| {r['block_rows']} | {r['modes']} | {r['t_lanczos']:.1f} | {r['t_full']:.1f} | "
            f"{r['t_full'] / r['t_lanczos']:.2f} | {d} |"
        )
    RESULTS.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
