"""Calibration of the default APerCEM sampler on the twin's own data: FMU signals -> extracted modes -> posterior.

For each scenario and seed: the truth (the hydro unit with a hidden effect) is
simulated through its FMU (20-min record), the modes are extracted, the
hidden effect is added to the twin's model and its parameters are updated by
:func:`twin.update.update` with its defaults (the default sampler, 4 chains
x 500 draws). The scenario ``bearings`` hides nothing and updates the 16
guide-bearing coefficients (truth: the model's values). Any other hidden
change of library effects :func:`twin.harness.scenarios.parse_scenario` reads
is a scenario too: another size (``magnetic_pull@0.3``) or several effects
at once (``seal_cross_coupling+fsi``), all their parameters updated.

Each update is calibrated on ``R`` records simulated at its estimate
(``Twin.update(bootstrap=R)``, :mod:`twin.loop.bootstrap`; by default the
loop's :data:`~twin.defaults.DEFAULT_RECORDS`, 12) and its draws
un-stretched by the factors, so one run gives both the sampler's own
posterior ("model" columns) and the loop's calibrated one. With
``--bootstrap 0`` there is no calibration and the second column is the sampler's again.

Reported per parameter group: the share of 90% intervals that cover the truth
(85-95% is calibrated), the median relative error of the MAP, the share of
parameters with R-hat <= 1.01, and the least bulk ESS.

    python benchmarks/update_coverage_fmu.py [--scenarios magnetic_pull,seal_cross_coupling,fsi,fsi_per_mode,bearings]
                                             [--seeds 20] [--first-seed 101] [--workers 2] [--duration 1200]
                                             [--keep-harmonics] [--delete-half] [--samples J] [--blocks B]
                                             [--orders-per-mode N] [--order-spread {shapes,all,none}]
                                             [--shape-samples M]
                                             [--shape-covariance {held-out,shrunk,sample}] [--combine {intersection,independent}]
                                             [--pole-error {samples+orders,samples}] [--flat-priors]
                                             [--streams {fmu,numpy}] [--bootstrap R]

One dataset takes about a minute on one core (simulation, extraction, 4
chains), and its calibration about 11 s per simulated record (20 min:
about 3.5 min with the default 12); ``--workers`` runs datasets as Dask tasks. Results go to
``benchmarks/results/update_coverage_fmu.md``.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

from extraction_options import add_extraction_options, extraction_flags, extraction_options
from numpy_records import STREAMS, numpy_signals

from twin.loop.bootstrap import DEFAULT_RECORDS
from twin.update.marginal import SHAPE_COVARIANCES
from twin.update.posterior import RHAT_LIMIT
from twin.update.poles import POLE_ERRORS

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "update_coverage_fmu.md"
SCENARIOS = ("magnetic_pull", "seal_cross_coupling", "fsi", "fsi_per_mode", "bearings")


def group(name: str) -> str:
    """The parameter group of a parameter name."""
    if name.startswith(("UGB.k", "LGB.k")):
        return "bearing stiffness"
    if name.startswith(("UGB.c", "LGB.c")):
        return "bearing damping"
    if name.startswith("FSI.added_mass_"):
        return "per-mode added mass"
    if name.startswith("FSI.added_damping_"):
        return "per-mode added damping"
    return name


def loop_extraction(extraction: dict | None) -> dict:
    """The ``extract`` keywords of the twin's loop (``twin demo``), with the options given instead.

    The loop's samples (``samples`` if given) and its shape samples
    (:data:`twin.harness.demo.SHAPE_SAMPLES_PER_SAMPLE` per sample), unless ``extraction`` sets ``blocks`` or
    ``delete_blocks`` (the shapes then come with the poles) or ``shape_samples`` itself (0: none).

    Examples
    --------
    >>> loop_extraction(None)
    {'samples': 15, 'shape_samples': 60}
    >>> loop_extraction({"samples": 45, "blocks": 15, "delete_blocks": None})
    {'samples': 45, 'blocks': 15, 'delete_blocks': None}
    >>> loop_extraction({"shape_samples": 0})
    {'samples': 15}
    """
    from twin.harness.demo import SAMPLES, SHAPE_SAMPLES_PER_SAMPLE

    options = dict(extraction or {})
    options.setdefault("samples", SAMPLES)
    if "shape_samples" not in options and not {"blocks", "delete_blocks"} & set(options):
        options["shape_samples"] = SHAPE_SAMPLES_PER_SAMPLE * options["samples"]
    if not options.get("shape_samples", 1):
        del options["shape_samples"]
    return options


def scenario_record(job: tuple[str, int], duration_s: float, extraction: dict | None = None, streams: str = "fmu"):
    """Simulate and extract one dataset of a scenario (``extraction``: options of :func:`twin.extract.extract`
    other than its defaults; ``streams``: ``"fmu"`` through the FMU, ``"numpy"`` the same record from numpy's
    random numbers, :func:`numpy_records.numpy_signals`); the twin with the hidden effect added, the names to
    update and their truths.

    Returns ``(twin, names, truth)``: a :class:`twin.loop.twin.Twin` on the extracted modes, the parameter
    names (the 16 bearing coefficients for ``bearings``, else the added effect's, per-mode ones by measured
    mode) and ``{name: true value}``.
    """
    from twin import load_model, shipped_model
    from twin.extract import extract
    from twin.fmu.simulate import simulate
    from twin.harness.demo import truth_for_measured
    from twin.harness.scenarios import parse_scenario
    from twin.loop.twin import Twin
    from twin.update.problem import select_parameters

    name, seed = job
    model = load_model(shipped_model("hydro_unit"))
    scenario = parse_scenario("none" if name == "bearings" else name, model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if streams == "numpy":
            signals = numpy_signals(model, scenario.truth(), duration_s, seed)
        else:
            signals = simulate(
                model, duration_s=duration_s, fs_hz=256.0, seed=seed, truth=scenario.truth(), progress=False
            )
        modes = extract(signals, fmax_hz=60.0, progress=False, **loop_extraction(extraction))
        tw = Twin(model, modes)
        if name == "bearings":
            names = select_parameters(model, "bearings")
            return tw, names, {n: model.parameter(n).nominal for n in names}
        for label in scenario.labels:
            tw.add_effect(label)
    truth = truth_for_measured(
        scenario.truth_values(model), tw.measured, json.loads(modes.attrs.get("truth_modes", "[]"))
    )
    return tw, tw.added_parameters(), truth


def one_dataset(
    job: tuple[str, int],
    duration_s: float,
    extraction: dict | None = None,
    shape_covariance: str = SHAPE_COVARIANCES[0],
    combine: str | None = None,
    pole_error: str | None = None,
    plausible: bool = True,
    streams: str = "fmu",
    bootstrap: int = 0,
) -> list[dict]:
    """Simulate (``streams`` as :func:`scenario_record`'s), extract (``extraction``: options of
    :func:`twin.extract.extract` other than its defaults) and update one dataset (``shape_covariance``,
    ``combine`` and ``pole_error`` as the HMC sampler's options, ``plausible`` its priors); one row per
    parameter. ``q05_model``/``q95_model`` are the sampler's interval; ``q05``/``q95`` with ``bootstrap``
    records the one calibrated on them (``bootstrap_factor``), without the sampler's again."""
    from twin.errors import TwinError
    from twin.harness.demo import posterior_table
    from twin.update.posterior import stretch
    from twin.update.posterior import parameter_draws
    from twin.update.problem import UpdateError

    name, seed = job
    started = time.perf_counter()
    tw, names, truth = scenario_record(job, duration_s, extraction, streams)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            options = {"shape_covariance": shape_covariance, "combine": combine, "pole_error": pole_error}
            post = tw.update(
                names,
                seed=seed,
                progress=False,
                priors="plausible" if plausible else "flat",
                bootstrap=bootstrap,
                **{k: v for k, v in options.items() if v is not None},
            )
        except (UpdateError, TwinError) as err:  # e.g. shape samples that do not span every entry
            return [{"scenario": name, "seed": seed, "refused": str(err)}]
    table = posterior_table(post, tw.model)
    factors = json.loads(post.attrs.get("bootstrap_calibration", "{}"))
    draws = parameter_draws(post["posterior"].to_dataset()).stack(sample=("chain", "draw")).transpose("sample", ...)
    inverse = np.array([1.0 / factors.get(str(p), 1.0) for p in draws["parameter"].values])
    q_model = draws.copy(data=stretch(draws.values, inverse)).quantile([0.05, 0.95], "sample")
    elapsed = time.perf_counter() - started
    seen = {}  # {label: {records it was seen on, of them in the first batch, records' RMS and mean error, RMS z}}
    if "bootstrap" in post.children:
        boot = post["bootstrap"].to_dataset()
        for p in boot["parameter"].values:
            z, error = boot["z"].sel(parameter=p).values, boot["error"].sel(parameter=p).values
            seen[str(p)] = {
                "records_seen": int(boot["records_used"].sel(parameter=p)),
                "records_seen_first_batch": int(np.isfinite(z[:bootstrap]).sum()),
            }
            if np.isfinite(z).any():
                seen[str(p)].update(
                    bootstrap_rms_error=float(np.sqrt(np.nanmean(error**2))),
                    bootstrap_mean_error=float(np.nanmean(error)),
                    bootstrap_rms_z=float(np.sqrt(np.nanmean(z**2))),
                )
            else:
                seen[str(p)].update(bootstrap_rms_error=None, bootstrap_mean_error=None, bootstrap_rms_z=None)
    sampler_std = draws.std("sample")
    rows = []
    for k, p in enumerate(table["parameter"].values):
        p = str(p)
        if p not in truth:
            continue
        rows.append(
            {
                "scenario": name,
                "seed": seed,
                "parameter": p,
                "group": group(p),
                "truth": truth[p],
                **{v: float(table[v][k]) for v in ("map", "q05", "q95", "r_hat", "ess_bulk")},
                "q05_model": float(q_model.sel(parameter=p)[0]),
                "q95_model": float(q_model.sel(parameter=p)[1]),
                "determined": bool(table["determined"][k]),
                "factor": factors.get(p, 1.0),
                "sampler_std": float(sampler_std.sel(parameter=p)) / factors.get(p, 1.0),
                **seen.get(p, {}),
                "elapsed_s": elapsed,
            }
        )
    return rows


def _covers(row: dict, posterior: str = "model") -> bool:
    """Whether a row's 90% interval holds its truth: the model's posterior's (the update's default), or the one
    adjusted for the modes' correlation (``"adjusted"``, ``adjust="jackknife"``)."""
    suffix = "_model" if posterior == "model" else ""
    return bool(row["q05" + suffix] <= row["truth"] <= row["q95" + suffix])


def record_interval(rows: list[dict], level: float = 0.9, resamples: int = 2000) -> tuple[float, float]:
    """The ``level`` interval of the share of ``rows`` whose interval (the default's) covers the truth, by resampling
    whole records (``(scenario, seed)``) with replacement: the values of one record share its extraction errors.

    Examples
    --------
    >>> rows = [{"scenario": "s", "seed": k, "q05_model": 0.0, "q95_model": 1.0, "truth": 0.5 if k % 10 else 2.0}
    ...         for k in range(40)]
    >>> lo, hi = record_interval(rows)
    >>> bool(lo < 0.9 < hi), bool(hi <= 1.0)
    (True, True)
    """
    records: dict[tuple, list[bool]] = {}
    for r in rows:
        records.setdefault((r["scenario"], r["seed"]), []).append(_covers(r))
    hits = np.array([sum(v) for v in records.values()], dtype=float)
    counts = np.array([len(v) for v in records.values()], dtype=float)
    pick = np.random.default_rng(0).integers(0, len(hits), size=(resamples, len(hits)))
    share = hits[pick].sum(axis=1) / counts[pick].sum(axis=1)
    lo, hi = np.quantile(share, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def mixing(rows: list[dict], limit: float = RHAT_LIMIT) -> str:
    """How many of ``rows`` have an R-hat at most ``limit``, of how many, and the highest R-hat.

    A share rounded to a whole percent would hide one value above the limit among a few hundred.

    Examples
    --------
    >>> mixing([{"r_hat": 1.002}, {"r_hat": 1.0136}])
    '1 of 2 (highest 1.014)'
    >>> mixing([])
    '-'
    """
    if not rows:
        return "-"
    r_hat = [r["r_hat"] for r in rows]
    return f"{sum(v <= limit for v in r_hat)} of {len(r_hat)} (highest {max(r_hat):.3f})"


def report(rows: list[dict], second: str = "adjusted (adjust='jackknife')") -> list[str]:
    """Coverage (the model's posterior, the update's default, and the jackknife-adjusted one), accuracy and
    mixing by scenario and group.

    R-hat and ESS are over the parameters the update reports as determined by the data; those it reports as
    not determined are counted, with their coverage. The default intervals' coverage of the determined values
    alone is given with its 90% interval over records (:func:`record_interval`): an undetermined value's wide
    interval covers whatever the truth, and the values of one record err together.
    """
    lines = [
        "| scenario | parameter group | values | 90% interval covers: the sampler's posterior | "
        f"{second} | determined, sampler [90% over records] | determined, {second.split(' (')[0]} | median abs. error of the MAP | not determined (covered) | "
        "R-hat <= 1.01 (determined) | least bulk ESS (determined) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    keys = sorted({(r["scenario"], r["group"]) for r in rows}, key=lambda k: (scenario_order(k[0]), k[1]))
    for scenario, grp in keys:
        sel = [r for r in rows if r["scenario"] == scenario and r["group"] == grp]
        model = np.mean([_covers(r, "model") for r in sel])
        inside = np.mean([_covers(r, "adjusted") for r in sel])
        err = np.median([abs(r["map"] / r["truth"] - 1) for r in sel if r["truth"] != 0] or [np.nan])
        det = [r for r in sel if r["determined"]]
        und = [r for r in sel if not r["determined"]]
        mixed = mixing(det)
        least = f"{min(r['ess_bulk'] for r in det):.0f}" if det else "-"
        covered = sum(_covers(r) for r in und)
        if det:
            lo, hi = record_interval(det)
            determined = f"{np.mean([_covers(r) for r in det]):.0%} [{lo:.0%}-{hi:.0%}]"
            determined += f" | {np.mean([_covers(r, 'adjusted') for r in det]):.0%}"
        else:
            determined = "- | -"
        lines.append(
            f"| {scenario} | {grp} | {len(sel)} | {model:.0%} | {inside:.0%} | {determined} | {err:.1%} | "
            f"{len(und)} ({covered}) | {mixed} | {least} |"
        )
    model = np.mean([_covers(r, "model") for r in rows])
    inside = np.mean([_covers(r, "adjusted") for r in rows])
    lines += [
        "",
        f"All: the 90% intervals cover the truth for {model:.0%} of {len(rows)} values with the model's "
        f"posterior (uncalibrated), {inside:.0%} {second}.",
    ]
    return lines


def add_dataset_options(ap: argparse.ArgumentParser, scenarios: str, seeds: int, first_seed: int) -> None:
    """``--scenarios``, ``--seeds``, ``--first-seed``, ``--workers``, ``--duration`` and ``--rows`` (with these
    defaults), and the extraction's flags (:func:`add_extraction_options`): the options of the benchmarks over
    FMU datasets."""
    ap.add_argument("--scenarios", default=scenarios)
    ap.add_argument("--seeds", type=int, default=seeds)
    ap.add_argument("--first-seed", type=int, default=first_seed)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--duration", type=float, default=1200.0)
    ap.add_argument("--rows", type=Path, default=None, help="also write every row (one per parameter) as JSON")
    ap.add_argument(
        "--streams",
        choices=STREAMS,
        default=STREAMS[0],
        help="the records' random numbers: the FMU's own, or numpy's through the same system (numpy_records.py)",
    )
    add_extraction_options(ap)


def dataset_jobs(args: argparse.Namespace) -> list[tuple[str, int]]:
    """``(scenario, seed)`` of every dataset the options ask for; exits saying why a scenario cannot be one
    (:func:`scenario_problem`)."""
    names = [n.strip() for n in args.scenarios.split(",")]
    for n in names:
        problem = scenario_problem(n)
        if problem:
            raise SystemExit(f"--scenarios: {problem}")
    return [(n, args.first_seed + k) for n in names for k in range(args.seeds)]


def scenario_problem(name: str) -> str | None:
    """Why ``name`` cannot be a scenario of these benchmarks, or None: one of :data:`SCENARIOS`, or any hidden
    change of library effects :func:`twin.harness.scenarios.parse_scenario` reads (other sizes, several effects
    at once), whose parameters the twin can add and update.

    Examples
    --------
    >>> scenario_problem("magnetic_pull@2.5") is None, scenario_problem("seal_cross_coupling+fsi") is None
    (True, True)
    >>> scenario_problem("shaft_stiffness:18")
    "'shaft_stiffness:18' changes the model outside the effect library: nothing to add and update"
    """
    from twin import load_model, shipped_model
    from twin.errors import TwinError
    from twin.harness.scenarios import parse_scenario

    if name in SCENARIOS:
        return None
    try:
        scenario = parse_scenario(name, load_model(shipped_model("hydro_unit")))
    except TwinError as err:
        return f"{err}; or one of {', '.join(SCENARIOS)}"
    if scenario.changes:
        return f"'{name}' changes the model outside the effect library: nothing to add and update"
    if not scenario.effects:
        return f"'{name}' hides nothing: use 'bearings' to update the bearings of a model without a hidden effect"
    return None


def scenario_order(name: str) -> tuple[int, str]:
    """Sort key of a scenario in the reports: :data:`SCENARIOS`' order, then other specs by name.

    Examples
    --------
    >>> sorted(["fsi", "magnetic_pull@2.5", "magnetic_pull"], key=scenario_order)
    ['magnetic_pull', 'fsi', 'magnetic_pull@2.5']
    """
    return (SCENARIOS.index(name), "") if name in SCENARIOS else (len(SCENARIOS), name)


def run_datasets(function, jobs: list[tuple[str, int]], workers: int, **shared) -> list:
    """``function(job, **shared)`` for every job, as Dask tasks on ``workers`` local processes (in this
    process for one)."""
    from twin.tasks import dask_client, mapper

    with dask_client("local" if workers > 1 else "sync", n_workers=workers) as client:
        return mapper(client, progress=True, desc="datasets")(function, jobs, **shared)


def dataset_command(script: str, args: argparse.Namespace) -> str:
    """The command line of a benchmark over FMU datasets with the options of :func:`add_dataset_options`."""
    streams = "" if args.streams == STREAMS[0] else f" --streams {args.streams}"
    return (
        f"python benchmarks/{script} --scenarios {args.scenarios} --seeds {args.seeds} "
        f"--first-seed {args.first_seed} --workers {args.workers} --duration {args.duration:g}"
        f"{streams}{extraction_flags(args)}"
    )


def dataset_benchmark(
    description: str,
    script: str,
    one_dataset,
    report,
    results: Path,
    title: str,
    note: str,
    scenarios: str,
    seeds: int,
    first_seed: int,
) -> None:
    """The whole run of a benchmark over FMU datasets without options of its own: parse the options of
    :func:`add_dataset_options` (with these defaults), run ``one_dataset(job, duration_s, extraction, streams)`` for
    every dataset, and write ``title``, the command, ``note`` and ``report(rows)`` to ``results``."""
    ap = argparse.ArgumentParser(description=description)
    add_dataset_options(ap, scenarios=scenarios, seeds=seeds, first_seed=first_seed)
    args = ap.parse_args()
    jobs = dataset_jobs(args)
    t0 = time.perf_counter()
    results_ = run_datasets(
        one_dataset,
        jobs,
        args.workers,
        duration_s=args.duration,
        extraction=extraction_options(args),
        streams=args.streams,
    )
    rows = [r for rs in results_ for r in rs]
    lines = [
        f"# {title}",
        "",
        f"Command: `{dataset_command(script, args)}`; {len(jobs)} datasets in "
        f"{time.perf_counter() - t0:.0f} s.{' ' + note if note else ''}",
        "",
    ] + report(rows)
    write_results(results, lines, rows, args.rows)


def write_results(path: Path, lines: list[str], rows: list[dict], rows_path: Path | None) -> None:
    """The report ``lines`` to ``path`` and the terminal, and every row as JSON to ``rows_path`` when given."""
    if rows_path is not None:
        rows_path.write_text(json.dumps(rows))
    path.parent.mkdir(exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_dataset_options(ap, scenarios=",".join(SCENARIOS), seeds=20, first_seed=101)
    ap.add_argument(
        "--shape-covariance",
        choices=SHAPE_COVARIANCES,
        default=SHAPE_COVARIANCES[0],
        help="the update's shape covariance (twin update --shape-covariance; sample: needs "
        "--delete-half with more blocks than entries)",
    )
    ap.add_argument(
        "--combine",
        choices=("intersection", "independent"),
        default="intersection",
        help="how the update combines each mode's pole and shape errors (twin update --combine)",
    )
    ap.add_argument(
        "--pole-error",
        choices=POLE_ERRORS,
        default=POLE_ERRORS[0],
        help="each mean pole's error (twin update --pole-error)",
    )
    ap.add_argument(
        "--flat-priors", action="store_true", help="no prior on the effects' parameters (twin update --flat-priors)"
    )
    ap.add_argument(
        "--bootstrap",
        type=int,
        default=DEFAULT_RECORDS,
        metavar="R",
        help="calibrate each posterior on R records simulated at its estimate (twin loop --bootstrap; "
        f"default {DEFAULT_RECORDS}, the loop's); 0: none, the second coverage column is the sampler's "
        "again",
    )
    args = ap.parse_args()
    jobs = dataset_jobs(args)
    t0 = time.perf_counter()
    results = run_datasets(
        one_dataset,
        jobs,
        args.workers,
        duration_s=args.duration,
        extraction=extraction_options(args),
        shape_covariance=args.shape_covariance,
        combine=args.combine,
        pole_error=args.pole_error,
        plausible=not args.flat_priors,
        streams=args.streams,
        bootstrap=args.bootstrap,
    )
    rows = [r for rs in results for r in rs if "refused" not in r]
    refused = [r for rs in results for r in rs if "refused" in r]
    lines = [
        "# Calibration of the default APerCEM sampler on FMU data",
        "",
        f"Command: `{dataset_command('update_coverage_fmu.py', args)}"
        f"{'' if args.shape_covariance == SHAPE_COVARIANCES[0] else ' --shape-covariance ' + args.shape_covariance}"
        f"{'' if args.combine == 'intersection' else ' --combine ' + args.combine}"
        f"{'' if args.pole_error == POLE_ERRORS[0] else ' --pole-error ' + args.pole_error}"
        f"{' --flat-priors' if args.flat_priors else ''}"
        f"{f' --bootstrap {args.bootstrap}' if args.bootstrap != DEFAULT_RECORDS else ''}`; "
        f"{len(jobs)} datasets in {time.perf_counter() - t0:.0f} s.",
        "",
    ] + report(
        rows,
        f"calibrated on {args.bootstrap} simulated records"
        + (" (the default)" if args.bootstrap == DEFAULT_RECORDS else "")
        if args.bootstrap
        else "not calibrated (--bootstrap 0)",
    )
    lines += [
        f"Refused by the update (not counted above): {r['scenario']} seed {r['seed']}: {r['refused']}" for r in refused
    ]
    write_results(RESULTS, lines, rows, args.rows)


if __name__ == "__main__":
    main()
