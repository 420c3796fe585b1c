"""The held-out suite of the twin loop on FMU signals: pass counts and the chi2 calibration.

Runs ``twin sweep --scenarios benchmarks/loop_suite.txt`` (every library
effect at three sizes, every pair of two, local changes outside the library,
nothing hidden on 20 seeds: 69 scenarios, 20-min records, 15 jackknife
samples) and writes ``benchmarks/results/loop_suite.md``: the sweep's table,
the pass count per group, and the calibration of the measured-pole
uncertainty, chi2 / n of the true model against its own extracted modes over
the nothing-hidden seeds (about 1 when the uncertainty is honest).

    python benchmarks/loop_suite.py [--workers 2] [--out twin-suite] [--method hmc|laplace]
                                    [--bootstrap R] [--from-table twin-suite/sweep.nc]
                                    [--model pelton_unit --fmax 100 --algorithm plscf]

``--model`` runs another shipped machine's suite, ``benchmarks/loop_suite_<model>.txt`` (the same scenario
kinds on its own effects and elements), into ``results/loop_suite_<model>.md``; ``--fmax`` is the highest
frequency its extraction looks for modes up to, ``--algorithm`` how it reads them (``plscf`` for the
Pelton unit's heavily damped modes).

About 20 min on 2 cores without the calibration of each scenario's last
update (``--bootstrap 0``, as ``results/loop_suite.md`` was measured); the
loop's default calibration adds 12 simulated records to every scenario whose
loop updates (about 1 min each on 2 cores, not measured over the suite). ``--method`` is how the loop updates (the APerCEM
sampler, twin.update.update's default, by default; results in ``loop_suite.md``, or the Laplace
approximation of the pole fit: ``loop_suite_laplace.md``). ``--from-table``
rewrites the results from a sweep already run (its method from the table).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import scipy.stats
import xarray as xr

ROOT = Path(__file__).resolve().parent.parent
SUITE = ROOT / "benchmarks" / "loop_suite.txt"
RESULTS = {
    "hmc": ROOT / "benchmarks" / "results" / "loop_suite.md",
    "laplace": ROOT / "benchmarks" / "results" / "loop_suite_laplace.md",
}


def group(spec: str) -> str:
    """The suite group of a scenario spec."""
    if spec == "none":
        return "nothing hidden"
    from twin.fem.effects import effect_classes, parse_label

    if parse_label(spec).key in effect_classes(local=True):
        return "outside the library"
    return "two effects" if "+" in spec else "one effect, three sizes"


def summary(table: xr.Dataset) -> list[str]:
    from twin.harness.sweep_report import sweep_text

    specs = [str(h) for h in table["hidden"].values]
    groups = np.array([group(s) for s in specs])
    lines = ["| group | scenarios | passed | right diagnosis | passed strictly |", "| --- | --- | --- | --- | --- |"]
    for g in ("one effect, three sizes", "two effects", "outside the library", "nothing hidden"):
        k = groups == g
        if k.any():
            lines.append(
                f"| {g} | {int(k.sum())} | {int(table['passed'].values[k].sum())} | "
                f"{int(table['found'].values[k].sum())} | {int(table['passed_strict'].values[k].sum())} |"
            )
    lines.append(
        f"| all | {len(specs)} | {int(table['passed'].sum())} | {int(table['found'].sum())} | "
        f"{int(table['passed_strict'].sum())} |"
    )
    none = groups == "nothing hidden"
    if none.any():
        chi2, n = table["chi2_before"].values[none], table["n_data"].values[none]
        lo, hi = scipy.stats.chi2.ppf([0.05, 0.95], n.sum()) / n.sum()
        lines += [
            "",
            f"Calibration: with nothing hidden, chi2 / n of the true model against its own extracted modes "
            f"= {chi2.sum() / n.sum():.2f} over {int(none.sum())} records ({int(n.sum())} data; a chi2 law "
            f"gives 90% of its values in {lo:.2f}-{hi:.2f}); per record "
            + ", ".join(f"{c / m:.2f}" for c, m in zip(chi2, n))
            + ".",
        ]
    lines += ["", "```", sweep_text(table), "```"]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="hydro_unit", help="a shipped machine")
    parser.add_argument("--fmax", type=float, default=None, help="twin sweep --fmax (default: the sweep's)")
    parser.add_argument(
        "--algorithm", default=None, help="twin sweep --algorithm: how the extraction reads the modes (default: ssi)"
    )
    parser.add_argument("--out", default="twin-suite")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--method", choices=tuple(RESULTS), default="hmc")
    parser.add_argument("--from-table", default=None)
    parser.add_argument(
        "--bootstrap",
        type=int,
        default=None,
        metavar="R",
        help="records each scenario's last update is calibrated on (twin sweep --bootstrap; default: the loop's)",
    )
    args = parser.parse_args()
    hydro = args.model == "hydro_unit"
    suite = SUITE if hydro else SUITE.with_name(f"loop_suite_{args.model}.txt")
    extra = (
        ([] if hydro else ["--model", args.model])
        + ([] if args.fmax is None else ["--fmax", f"{args.fmax:g}"])
        + ([] if args.algorithm is None else ["--algorithm", args.algorithm])
    )
    command = [
        "twin",
        "sweep",
        "--scenarios",
        str(suite),
        *extra,
        "--out",
        args.out,
        "--workers",
        str(args.workers),
        "--method",
        args.method,
        *(["--bootstrap", str(args.bootstrap)] if args.bootstrap is not None else []),
    ]
    own = "".join(f" {a}" for a in extra)
    flag = ("" if args.bootstrap is None else f" --bootstrap {args.bootstrap}") + own
    t0 = time.perf_counter()
    if args.from_table is None:
        subprocess.run(command, check=False)
        path = Path(args.out) / "sweep.nc"
    else:
        path = Path(args.from_table)
    table = xr.load_dataset(path)
    method = json.loads(table.attrs.get("settings", "{}")).get("method", "laplace")  # tables before it: Laplace
    method = {"gibbs": "hmc"}.get(method, method)  # tables whose 'gibbs' ran the HMC sampler
    lines = [
        "# The twin loop on scenarios it was not tuned to" + ("" if hydro else f": {args.model}"),
        "",
        f"Command: `python benchmarks/loop_suite.py --workers {args.workers} --method {method}"
        f"{'' if args.bootstrap is None else f' --bootstrap {args.bootstrap}'}{own}`, i.e. "
        f"`twin sweep --scenarios benchmarks/{suite.name} --workers {args.workers} --method {method}{flag}` "
        f"({table.attrs.get('producer', 'twin')}); sweep {table.attrs.get('elapsed_s', float('nan')):.0f} s.",
        "",
    ]
    lines += summary(table)
    results = RESULTS[method]
    if not hydro:
        results = results.with_name(results.name.replace("loop_suite", f"loop_suite_{args.model}"))
    results.parent.mkdir(exist_ok=True)
    results.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"wrote {results} in {time.perf_counter() - t0:.0f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
