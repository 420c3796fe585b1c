"""Reproduce the reference paper's Case A and Case B on paper-style synthetic modal data.

Case A: FEM known, 30 FSI parameters (added mass and damping of 15 modes).
Case B: the 16 guide-bearing coefficients plus the 30 FSI parameters.
Data: the paper's Figure 2 procedure (``twin synthesize-modes``), J = 100.

Prints, for the first seed, per parameter: truth, MAP, relative error,
posterior std, z-score, with the paper's figures beside them; then the
coverage of the 90% credible intervals over all seeds.

    python benchmarks/update_cases.py --case B [--seeds 20] [--first-seed 1] [--draws 500] [--chains 1]
                                      [--method paper|hmc|gibbs] [--warmup N]
                                      [--noise-model diagonal|full] [--collapsed] [--pole-model samples|linear]
                                      [--combine intersection|independent]

``--method paper`` (the default) is the paper's sampler; ``hmc`` the update's default; ``gibbs`` with the
Gibbs options (``--noise-model``, ``--collapsed``, ``--pole-model``); ``--combine`` is an HMC option.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings

import numpy as np

import twin
from twin.errors import TwinWarning
from twin.tasks import one_blas_thread
from twin.update import summary, synthesize_modes, update
from twin.update.chain import NOISE_MODELS
from twin.update.core import MIN_MARGIN
from twin.update.samplers.gibbs import GIBBS_POLE_MODELS

#: The paper's reported MAP accuracy (relative error), for the table.
PAPER = {
    "added_mass": "~1% (modes 1, 2 worse)",
    "added_damping": "~3% (modes 1, 2 worse)",
    "bearing": "~1%",
    "LGB.cxy": "20%",
    "LGB.cyx": "52%",
}


def truth_values(model, ds) -> dict[str, float]:
    """Truth of every parameter: bearings at the model's values, FSI from the data's attrs."""
    fsi = json.loads(ds.attrs["truth"])["effects"]["fsi_per_mode"]
    out = {n: model.parameter(n).nominal for n in model.parameter_names if n.startswith(("UGB.", "LGB."))}
    for i, (m, c) in enumerate(zip(fsi["added_mass"], fsi["added_damping"]), start=1):
        out[f"FSI.added_mass_{i}"], out[f"FSI.added_damping_{i}"] = m, c
    return out


def paper_figure(name: str) -> str:
    if name.startswith("FSI."):
        return PAPER["added_mass" if "mass" in name else "added_damping"]
    return PAPER.get(name, PAPER["bearing"])


@one_blas_thread  # many small dense problems: a second BLAS thread costs more than it gains (twin.tasks)
def run(case: str, seed: int, draws: int, chains: int, model, method: str = "paper", **options):
    ds = synthesize_modes(model, samples=100, seed=seed)
    params = "bearings" if case == "B" else None
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", TwinWarning)
        tree = update(
            model,
            ds,
            params,
            fsi=True,
            method=method,
            options={"draws": draws, "chains": chains, "seed": seed, "progress": False, **options},
        )
    elapsed = time.perf_counter() - t0
    table = summary(tree["posterior"].to_dataset(), truth_values(model, ds))
    margin = tree["constant_data"]["condensation_margin"].values
    return table, elapsed, margin, [str(w.message) for w in caught]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", choices=("A", "B"), default="B")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--first-seed", type=int, default=1, help="seeds run: first-seed, ..., first-seed + seeds - 1")
    ap.add_argument("--draws", type=int, default=500)
    ap.add_argument("--chains", type=int, default=1)
    ap.add_argument("--method", choices=("paper", "hmc", "gibbs"), default="paper")
    ap.add_argument("--warmup", type=int, default=None, help="warm-up or burn-in (default: the sampler's)")
    ap.add_argument("--noise-model", choices=NOISE_MODELS, default=None, help="--method gibbs")
    ap.add_argument("--collapsed", action=argparse.BooleanOptionalAction, default=None, help="--method gibbs")
    ap.add_argument("--pole-model", choices=GIBBS_POLE_MODELS, default=None, help="--method gibbs")
    ap.add_argument(
        "--combine",
        choices=("intersection", "independent"),
        default=None,
        help="--method hmc: how each mode's pole and shape errors are combined",
    )
    args = ap.parse_args()
    options = {
        k: getattr(args, k)
        for k in ("warmup", "noise_model", "collapsed", "pole_model", "combine")
        if getattr(args, k) is not None
    }
    model = twin.load_model("models/hydro_unit.toml")
    covered, covered_ok, zmax, rows = [], [], [], []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        table, elapsed, margin, msgs = run(args.case, seed, args.draws, args.chains, model, args.method, **options)
        inside = (table["q05"] <= table["truth"]) & (table["truth"] <= table["q95"])
        flagged = {f"FSI.added_{k}_{i + 1}" for i in np.flatnonzero(margin < MIN_MARGIN) for k in ("mass", "damping")}
        ok = np.array([str(p) not in flagged for p in table["parameter"].values])
        rows += [
            (
                str(p),
                float(table["map_error"][k]),
                float(table["std"][k]) / abs(float(table["truth"][k])),
                bool(inside[k]),
            )
            for k, p in enumerate(table["parameter"].values)
        ]
        covered.append(float(inside.mean()))
        covered_ok.append(float(inside.values[ok].mean()))
        zmax.append(float(np.nanmax(np.abs(table["z_score"].values[ok]))))
        if seed == args.first_seed:
            print(
                f"Case {args.case}, seed {seed}: {table.sizes['parameter']} parameters, {args.chains} chain(s) x "
                f"{args.draws} draws in {elapsed:.1f} s (including setup)"
            )
            for m in msgs:
                print("  warning:", m)
            print(
                f"{'parameter':<22} {'truth':>11} {'MAP':>11} {'MAP err':>8} {'std/|truth|':>11} {'z':>6}  "
                f"{'R-hat':>5}  paper"
            )
            for k, p in enumerate(table["parameter"].values):
                r = table.isel(parameter=k)
                mark = " *" if str(p) in flagged else ""
                print(
                    f"{p:<22} {float(r.truth):>11.4g} {float(r['map']):>11.4g} {float(r.map_error):>+8.2%} "
                    f"{float(r['std']) / abs(float(r.truth)):>11.2%} {float(r.z_score):>+6.2f}  "
                    f"{float(r.r_hat) if 'r_hat' in r else float('nan'):>5.3f}  {paper_figure(str(p))}{mark}"
                )
            print("* mode flagged: its pole lies within 5 pole-sample stds of a resonance of the unobserved DOFs")
        rhat = f"; max R-hat {float(table['r_hat'].max()):.3f}" if "r_hat" in table else ""
        print(
            f"seed {seed}: 90% interval coverage {covered[-1]:.0%} (all), {covered_ok[-1]:.0%} (unflagged); "
            f"max |z| unflagged {zmax[-1]:.1f}{rhat}; {elapsed:.1f} s",
            flush=True,
        )
    print(
        f"coverage over {args.seeds} seeds: mean {np.mean(covered):.1%} (all parameters), "
        f"{np.mean(covered_ok):.1%} (unflagged modes); seeds with coverage >= 80%: "
        f"{sum(c >= 0.8 for c in covered)}/{args.seeds} (all), {sum(c >= 0.8 for c in covered_ok)}/{args.seeds} "
        "(unflagged)"
    )
    print(
        "by group over all seeds: 90% coverage; median |MAP error| of the parameters the data determine "
        "(posterior std < 10% of the truth), and how many they are"
    )
    for label, test in (
        ("bearings", lambda n: not n.startswith("FSI.")),
        ("added mass", lambda n: "mass" in n),
        ("added damping", lambda n: "damping" in n),
    ):
        sel = [r for r in rows if test(r[0])]
        if not sel:
            continue
        det = [abs(r[1]) for r in sel if r[2] < 0.1]
        print(
            f"  {label:<14} coverage {np.mean([r[3] for r in sel]):.0%} of {len(sel)}; determined {len(det)}: "
            f"median |error| {np.median(det) if det else float('nan'):.2%}, 90th percentile "
            f"{np.quantile(det, 0.9) if det else float('nan'):.2%}"
        )


if __name__ == "__main__":
    main()
