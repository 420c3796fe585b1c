"""Are the extraction's standard errors honest when its blocks are shorter than a mode's decay?

For each record (a 5-storey shear frame of :mod:`twin.extract.corpus`,
velocity channels at 40 dB, sampled at 20 Hz, one damping ratio and length
per row) and each number of delete-one blocks J, many seeds are extracted
(``extract(samples=J)``); for every mode below 5.5 Hz found within 1%, the
z-score of its frequency and damping ratio against the truth,
``(estimate - truth) / standard error``. Honest standard errors give an RMS z
near 1 and about 5% beyond 2 (a t distribution with J - 1 degrees of
freedom: RMS ``sqrt((J - 1) / (J - 3))``, 1.08 for J = 15, 1.29 for 6). The
slowest mode's time constant is given beside the blocks' length.

Run:  python benchmarks/jackknife_blocks.py [--seeds 20] [--blocks 15,8,6] [--workers 2]

Writes ``benchmarks/results/jackknife_blocks.md``.
"""

from __future__ import annotations

import argparse
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from twin.extract import extract
from twin.extract.corpus import shear_frame, simulate_record, truth_modes

RESULTS = Path(__file__).parent / "results" / "jackknife_blocks.md"
#: (record length [s], damping ratio) per row.
RECORDS = ((240.0, 0.002), (600.0, 0.0005), (600.0, 0.01), (3600.0, 0.001))
FS_HZ, SNR_DB, FIRST_SEED = 20.0, 40.0, 100


def z_scores(duration_s: float, zeta: float, blocks: tuple[int, ...], seed: int) -> dict:
    """Per number of blocks, the frequency and damping z-scores of the modes below 5.5 Hz of one record."""
    structure = shear_frame(5, damping_ratio=zeta)
    ds = simulate_record(structure, duration_s=duration_s, fs_hz=FS_HZ, snr_db=SNR_DB, quantities="velocity", seed=seed)
    truth = truth_modes(structure, ds)
    out = {}
    for J in blocks:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = extract(ds, samples=J, progress=False)
        zf, zd = [], []
        for f0, z0 in zip(truth.frequency.values, truth.damping_ratio.values):
            k = int(np.argmin(np.abs(m.frequency.values - f0)))
            if f0 < 5.5 and abs(m.frequency.values[k] / f0 - 1) < 0.01:
                zf.append(float((m.frequency.values[k] - f0) / m.frequency_se.values[k]))
                zd.append(float((m.damping_ratio.values[k] - z0) / m.damping_ratio_se.values[k]))
        out[J] = (zf, zd)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--blocks", default="15,8,6")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    blocks = tuple(int(x) for x in args.blocks.split(","))
    lines = [
        "| record | slowest time constant [s] | J | block [s] | modes | frequency RMS z | freq. beyond 2 "
        "| damping RMS z | damp. beyond 2 |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    with ProcessPoolExecutor(args.workers) as pool:
        for duration_s, zeta in RECORDS:
            jobs = [pool.submit(z_scores, duration_s, zeta, blocks, FIRST_SEED + s) for s in range(args.seeds)]
            results = [j.result() for j in jobs]
            truth = truth_modes(shear_frame(5, damping_ratio=zeta))
            slow = (1 / (2 * np.pi * truth.frequency.values * truth.damping_ratio.values)).max()  # 1 / (zeta omega)
            for J in blocks:
                zf = np.concatenate([r[J][0] for r in results])
                zd = np.concatenate([r[J][1] for r in results])
                row = (
                    f"| shear frame 5, {100 * zeta:g}%, {duration_s:g} s | {slow:.0f} | {J} | {duration_s / J:.3g} "
                    f"| {len(zf)} | {np.sqrt(np.mean(zf**2)):.2f} | {np.mean(np.abs(zf) > 2):.1%} "
                    f"| {np.sqrt(np.mean(zd**2)):.2f} | {np.mean(np.abs(zd) > 2):.1%} |"
                )
                print(row, flush=True)
                lines.append(row)
    text = (
        "# Jackknife standard errors against the blocks' length\n\n"
        f"`python benchmarks/jackknife_blocks.py --seeds {args.seeds} --blocks {args.blocks}` (seeds "
        f"{FIRST_SEED} to {FIRST_SEED + args.seeds - 1}; velocity, {SNR_DB:g} dB, {FS_HZ:g} Hz; modes below "
        "5.5 Hz found within 1%)\n\n" + "\n".join(lines) + "\n"
    )
    RESULTS.write_text(text)
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
