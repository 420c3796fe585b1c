"""The Fisher std before any data against the default sampler's posterior std, paper Case B.

For each data seed: ``twin.design.identifiability`` (16 bearings + per-mode
FSI, J = 100 synthetic samples, linearised at the paper's truth) and the
default sampler's posterior (``twin.update.update``, 2 x 500 draws, chain seed
2, ``adjust="none"``: the model's own posterior) on ``synthesize_modes(seed)``.
Prints, for the determined parameters, how many ratios sampler / Fisher lie
within a factor 1.5, their median and range, and every parameter outside.

    python benchmarks/identifiability.py [--seeds 1,5,9] [--draws 500] [--chains 2]
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from twin import load_model, shipped_model
from twin.design import identifiability
from twin.errors import TwinWarning
from twin.fem.truthfile import paper_truth
from twin.update import summary, synthesize_modes, update
from twin.update.problem import select_parameters

#: The issue's factor between the two stds.
FACTOR = 1.5


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1,5,9", help="data seeds, comma-separated")
    ap.add_argument("--draws", type=int, default=500)
    ap.add_argument("--chains", type=int, default=2)
    args = ap.parse_args()
    unit = load_model(shipped_model("hydro_unit"))
    names = select_parameters(unit, "bearings")
    started = time.perf_counter()
    ident = identifiability(unit, names, fsi=True, samples=100, truth=paper_truth())
    print(f"Fisher: {ident.attrs['method']} ({time.perf_counter() - started:.1f} s)")
    determined = ident.determined.values
    print("| data seed | within a factor 1.5 | median | range | undetermined (ratio) | outside |")
    print("| --- | --- | --- | --- | --- | --- |")
    for seed in (int(s) for s in args.seeds.split(",")):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TwinWarning)
            post = update(
                unit,
                synthesize_modes(unit, samples=100, seed=seed),
                names,
                fsi=True,
                options={"draws": args.draws, "chains": args.chains, "seed": 2, "progress": False},
            )
        sampled = summary(post["posterior"].to_dataset())["std"].sel(parameter=ident.parameter)
        ratio = (sampled / ident["std"]).values
        r = ratio[determined]
        within = np.abs(np.log(r)) <= np.log(FACTOR)
        outside = [f"{p} {x:.2f}" for p, x in zip(ident.parameter.values[determined][~within], r[~within])]
        undetermined = ", ".join(
            f"{p} {x:.2f}" for p, x in zip(ident.parameter.values[~determined], ratio[~determined])
        )
        print(
            f"| {seed} | {int(within.sum())} of {len(r)} | {np.median(r):.2f} | {r.min():.2f}-{r.max():.2f} | "
            f"{undetermined} | {', '.join(outside) or 'none'} |",
            flush=True,
        )
    print(f"({time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()
