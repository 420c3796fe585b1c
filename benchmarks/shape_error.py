"""Where a parameter's error beyond its posterior comes from on the twin's own data: poles or shapes, seen or not.

For each scenario and seed (the FMU records of ``update_coverage_fmu.py``: 20-min records, default
extraction), the parameters are updated five ways and each error is taken in posterior stds (the std
from the 90% interval's width, ``z = (MAP - truth) / std``):

* ``default``: :func:`twin.update.update` as the loop runs it;
* ``true shapes``, ``true Re``, ``true Im``: the same with every mode's shape samples moved so that their
  mean is the truth's shape on the sensors (all of it, its real parts only, its imaginary parts only), the
  samples keeping their scatter and the poles untouched: what is left is the poles' error and the shapes'
  scatter, so the z falls to about one where the shapes' error beyond their samples is the cause;
* ``poles only``: the Laplace fit of the poles (:func:`twin.update.laplace.laplace_update`), shapes unused.

And the sandwich, the data's own view of the estimate's error: the RMS move of the posterior mode over
perturbations of the data by its samples, every mode by the same sample
(:func:`jackknife.mode_spread`, ``pairing="joint"``), over the default posterior's std. Where it
is about one while the default's RMS z is above one, the error is one the record cannot see.

    python benchmarks/shape_error.py [--scenarios seal_cross_coupling,bearings] [--seeds 16] [--first-seed 601]
                                     [--workers 2] [--duration 1200] [--rows rows.json]
                                     [the extraction flags of update_coverage_fmu.py: --delete-half ...]

Results go to ``benchmarks/results/shape_error.md``.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from update_coverage_fmu import (
    dataset_benchmark,
    group,
    scenario_order,
    scenario_record,
)

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "shape_error.md"
#: The ways each dataset is updated (see the module docstring), the loop's first.
VARIANTS = ("default", "true shapes", "true Re", "true Im", "poles only")
#: The standard normal's 95% point: a 90% interval is 2 of these stds wide.
Z95 = 1.6448536269514722


def truth_shapes(tw, truth: dict[str, float]) -> np.ndarray:
    """The truth's shape of every measured mode on the sensors, ``(mode, channel)``, normalised as its samples
    are (unit norm, the extraction's ``reference_channel`` real and positive)."""
    from twin.extract.samples import normalise_at
    from twin.loop.compare import model_modes
    from twin.modes.measured import channel_dofs

    partners = model_modes(tw.model, tw.measured, truth)
    shapes = partners.shapes[:, channel_dofs(tw.model, tw.measured.channels)]
    reference = [tw.measured.channels.index(str(c)) for c in tw.modes["reference_channel"].values]
    return normalise_at(shapes, np.array(reference))


def moved(modes, target: np.ndarray, part: str):
    """``modes`` with each mode's shape samples moved by ``part`` (``all``, ``re``, ``im``) of the difference
    between ``target`` and their mean."""
    mean = modes["shape"].mean("sample").transpose("mode", "channel")
    shift = target - mean.values
    shift = {"all": shift, "re": shift.real, "im": 1j * shift.imag}[part]
    out = modes.copy()
    out["shape"] = (modes["shape"] + mean.copy(data=shift)).transpose(*modes["shape"].dims)
    return out


def one_dataset(
    job: tuple[str, int], duration_s: float, extraction: dict | None = None, streams: str = "fmu"
) -> list[dict]:
    """Simulate (``streams`` as :func:`update_coverage_fmu.scenario_record`'s), extract (``extraction``:
    options of :func:`twin.extract.extract`) and update one dataset the five ways; one row per parameter."""
    from jackknife import mode_spread

    from twin.fem.effects import is_per_mode_name
    from twin.harness.demo import posterior_table
    from twin.loop.twin import Twin
    from twin.update.marginal import marginal_problem
    from twin.update.problem import build_problem

    name, seed = job
    tw, names, truth = scenario_record(job, duration_s, extraction, streams)
    target = truth_shapes(tw, truth)
    datasets = {
        "default": tw.modes,
        "true shapes": moved(tw.modes, target, "all"),
        "true Re": moved(tw.modes, target, "re"),
        "true Im": moved(tw.modes, target, "im"),
    }
    tables = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for variant, modes in datasets.items():
            post = Twin(tw.model, modes).update(names, seed=seed, progress=False)
            tables[variant] = posterior_table(post, tw.model)
        tables["poles only"] = posterior_table(Twin(tw.model, tw.modes).update(names, method="laplace"), tw.model)
        shared = [n for n in names if not is_per_mode_name(n)]
        fsi = len(shared) < len(names)
        problem = build_problem(tw.model, tw.modes, shared, fsi=fsi, pole_model="marginal")
        marg = marginal_problem(problem, tw.modes["pole"].transpose("mode", "sample").values)
        flat = np.zeros(marg.size)
        joint = mode_spread(
            marg, tw.model, tw.modes, shared, fsi=fsi, eps_std=1e-6, prior_mean=flat, prior_precision=flat
        )
    sandwich = dict(zip(problem.parameter_labels, joint if joint is not None else np.full(marg.size, np.nan)))
    rows = []
    for p, value in truth.items():
        if p not in sandwich:
            continue
        row = {
            "scenario": name,
            "seed": seed,
            "parameter": p,
            "group": group(p),
            "truth": value,
            "joint_spread": float(sandwich[p]),
        }
        for variant, table in tables.items():
            t = table.sel(parameter=p)
            std = float(t["q95"] - t["q05"]) / (2 * Z95)
            row[variant] = {
                "map": float(t["map"]),
                "std": std,
                "covered": bool(t["q05"] <= value <= t["q95"]),
                "determined": bool(t["determined"]),
            }
        rows.append(row)
    return rows


def report(rows: list[dict]) -> list[str]:
    """Per scenario and group, over the values the default update determines: RMS z and 90% coverage of each
    variant, the median sandwich / posterior std and the median relative error of the MAP."""
    lines = [
        "| scenario | parameter group | values | "
        + " | ".join(f"{v}: RMS z (covered)" for v in VARIANTS)
        + " | sandwich / posterior std | median abs. error: default, true shapes, poles only |",
        "| --- | --- | --- | " + " | ".join("---" for _ in VARIANTS) + " | --- | --- |",
    ]
    keys = sorted({(r["scenario"], r["group"]) for r in rows}, key=lambda k: (scenario_order(k[0]), k[1]))
    for scenario, grp in keys:
        sel = [r for r in rows if r["scenario"] == scenario and r["group"] == grp and r["default"]["determined"]]
        if not sel:
            continue
        cells = []
        for v in VARIANTS:
            z = np.array([(r[v]["map"] - r["truth"]) / r[v]["std"] for r in sel])
            cells.append(f"{np.sqrt(np.mean(z**2)):.2f} ({np.mean([r[v]['covered'] for r in sel]):.0%})")
        ratio = np.nanmedian([r["joint_spread"] / r["default"]["std"] for r in sel])
        errors = ", ".join(
            f"{np.median([abs(r[v]['map'] / r['truth'] - 1) for r in sel if r['truth']]):.1%}"
            for v in ("default", "true shapes", "poles only")
        )
        lines.append(f"| {scenario} | {grp} | {len(sel)} | " + " | ".join(cells) + f" | {ratio:.2f} | {errors} |")
    return lines


def main() -> None:
    dataset_benchmark(
        __doc__.splitlines()[0],
        "shape_error.py",
        one_dataset,
        report,
        RESULTS,
        "Where the updated parameters' error comes from on FMU data",
        "Over the values the default update determines; z = (MAP - truth) / std, the std from the 90% "
        "interval's width.",
        scenarios="seal_cross_coupling,bearings",
        seeds=16,
        first_seed=601,
    )


if __name__ == "__main__":
    main()
