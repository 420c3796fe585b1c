"""The ``twin`` sub-commands of updating and the loop: update, compare, diagnose, loop, demo, sweep (stages 4-5)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from twin.cli.common import (
    COUNT,
    MODEL_HELP,
    MODES_HELP,
    NATURAL,
    add_bootstrap,
    add_chain_options,
    add_effect,
    add_loop_settings,
    add_method,
    add_model_and_posterior,
    add_scheduler,
    add_tolerance,
    command,
    model_with_effects,
    tasks,
)
from twin.defaults import (
    DEMO_RECORDS,
    MAX_ROUNDS,
    METHODS,  # noqa: F401 (what --method takes: twin.update.METHODS)
)
from twin.errors import TwinError

log = logging.getLogger("twin")


#: The ``twin update`` options that go to the sampler's options (twin.update.samplers), by their field names.
SAMPLER_OPTIONS = ("draws", "chains", "warmup", "seed", "noise_model", "collapsed", "pole_model")


def sampler_options(args: argparse.Namespace) -> dict:
    """The sampler options given on the command line (those left out keep the sampler's defaults)."""
    return {k: getattr(args, k) for k in SAMPLER_OPTIONS if getattr(args, k, None) is not None}


def _update(args: argparse.Namespace) -> int:
    from twin.modes import read_modes
    from twin.netcdf import check_writable
    from twin.update import sampler, summary, update
    from twin.update.posterior import write_posterior
    from twin.update.problem import check_modes

    if args.params is None and not args.fsi:
        raise TwinError("nothing to update: give --params and/or --fsi")
    check_writable(args.output)
    modes = read_modes(args.modes)  # a bad modes file fails before a cluster starts
    model = model_with_effects(args.model, args.effect, modes)
    check_modes(modes, args.modes)
    if args.method == "laplace":
        return _update_laplace(args, model, modes)
    from twin.progress import stage
    from twin.update.problem import select_parameters

    params = None if args.params is None else select_parameters(model, args.params)  # before a cluster starts
    options = sampler(args.method).options(sampler_options(args), progress=True)  # bad options fail here too
    with tasks(args) as client, stage(f"APerCEM ({args.method}): {options.chains} chains x {options.draws} draws"):
        tree = update(
            model,
            modes,
            params,
            fsi=args.fsi,
            method=args.method,
            options=options,
            priors="flat" if args.flat_priors else "plausible",
            tasks=client,
        )
    tree.attrs["command"] = " ".join(sys.argv)
    write_posterior(tree, args.output)
    table = summary(tree["posterior"].to_dataset())
    print(
        f"{tree.attrs['condensation']} condensation; {options.chains} chains x {options.draws} draws "
        f"in {tree.attrs['elapsed_s']:.1f} s"
    )
    print(f"{'parameter':<22} {'MAP':>11} {'mean':>11} {'std':>10} {'5%':>11} {'95%':>11} {'R-hat':>6} {'ESS':>6}")
    has_diag = "r_hat" in table
    undetermined = set(json.loads(tree.attrs.get("undetermined", "[]")))
    for k, p in enumerate(table["parameter"].values):
        row = table.isel(parameter=k)
        r_hat = f"{float(row.r_hat):>6.3f}" if has_diag else f"{'-':>6}"
        diag = f"{r_hat} {float(row.ess_bulk):>6.0f}" if "ess_bulk" in table else f"{r_hat} {'-':>6}"
        mark = "  not determined by the data" if str(p) in undetermined else ""
        print(
            f"{p:<22} {float(row['map']):>11.4g} {float(row['mean']):>11.4g} {float(row['std']):>10.3g} "
            f"{float(row.q05):>11.4g} {float(row.q95):>11.4g} {diag}{mark}"
        )
    print(f"wrote {args.output}")
    return 0


def _update_laplace(args: argparse.Namespace, model, modes) -> int:
    """``twin update --method laplace``: :func:`twin.update.update`'s Laplace fit, its table printed."""
    from twin.update import LaplaceOptions, update
    from twin.update.posterior import write_posterior

    given = [f for f in SAMPLER_OPTIONS if getattr(args, f, None) is not None and f != "seed"]
    if given:
        raise TwinError(
            f"--method laplace takes no sampler settings ({', '.join('--' + f.replace('_', '-') for f in given)})"
        )
    options = LaplaceOptions(seed=args.seed if args.seed is not None else 0)
    tree = update(model, modes, args.params, fsi=args.fsi, method="laplace", options=options)
    tree.attrs["command"] = " ".join(sys.argv)
    write_posterior(tree, args.output)
    fit = tree["constant_data"].to_dataset()
    names = [str(n) for n in fit["parameter"].values]
    at_bound = tree.attrs["at_bound"].split(", ")
    units = json.loads(tree.attrs["units"])  # the per-mode FSI's too, which the fit added to the model
    print(
        f"Laplace update of {len(names)} parameters: chi2 {tree.attrs['chi2_before']:.1f} -> {tree.attrs['chi2_after']:.1f}"
    )
    print(f"{'parameter':<22} {'MAP':>11} {'std':>10} {'unit':<8}")
    for k, n in enumerate(names):
        bound = " (on its physical bound)" if n in at_bound else ""
        print(f"{n:<22} {float(fit['map'][k]):>11.4g} {float(fit['std'][k]):>10.3g} {units[n]:<8}{bound}")
    print(f"wrote {args.output}")
    return 0


def _compare(args: argparse.Namespace) -> int:

    from twin.harness.sweep_report import comparison_text
    from twin.loop.compare import compare
    from twin.modes import read_modes

    modes = read_modes(args.modes)
    model = _posterior_model(args, modes)
    table = compare(model, modes, tolerance=args.tolerance)
    if args.history:
        from twin.loop.history import append_step, plot_history

        done = [f"add {', '.join(args.effect)}"] if args.effect else []
        done += [f"posterior {Path(args.posterior).name} ({args.estimate})"] if args.posterior else []
        history = append_step(args.history, args.step or "; ".join(done) or "start", table, Path(args.modes).name)
        plot_history(history, Path(args.history).with_suffix(".png"))
        log.info("history: %d steps in %s", history.sizes["step"], args.history)
    if args.plot:
        from twin.errors import SignalError
        from twin.netcdf import load_netcdf
        from twin.report.figures import comparison_figures

        signals = None if args.signals is None else load_netcdf(args.signals, "signals", SignalError)
        for path in comparison_figures(table, args.plot, signals=signals):
            log.info("wrote %s", path)
    if args.json:
        from twin.loop.compare import comparison_json

        print(json.dumps(comparison_json(table), indent=2))
    else:
        print(comparison_text(table))
    return 0


def _posterior_model(args: argparse.Namespace, modes):
    """The model of ``--effect`` and ``--posterior`` (:func:`twin.loop.candidates.posterior_model`)."""
    from twin.fem import load_model

    if not args.posterior:
        return model_with_effects(args.model, args.effect, modes)
    from twin.loop.candidates import posterior_model
    from twin.update import read_posterior

    return posterior_model(
        load_model(args.model), read_posterior(args.posterior), args.estimate, args.effect or (), modes
    )


def _diagnose(args: argparse.Namespace) -> int:
    from twin.harness.sweep_report import diagnosis_text
    from twin.loop.candidates import select
    from twin.loop.diagnose import diagnose
    from twin.modes import read_modes
    from twin.modes.measured import measured_modes

    modes = read_modes(args.modes)
    model = _posterior_model(args, modes)
    meas = measured_modes(modes, args.tolerance)
    labels = args.candidates.split(",") if args.candidates else None
    select(model, labels)  # unknown candidates fail before a cluster starts
    from twin.progress import stage

    with tasks(args) as client, stage("diagnose: the library's effects, then local changes"):
        d = diagnose(model, meas, candidates=labels, tolerance=args.tolerance, tasks=client, progress=True)
    print(d.to_json(meas) if args.json else diagnosis_text(d, meas))
    return 0


def _demo(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.harness.demo import check_demo, run_demo

    model, _, _ = check_demo(
        args.out, load_model(args.model) if args.model else None, args.hidden, args.method, args.bootstrap
    )  # before a cluster starts
    with tasks(args) as client:
        r = run_demo(
            args.out,
            model=model,
            hidden=args.hidden,
            duration_s=args.duration,
            seed=args.seed,
            samples=args.samples,
            fmax_hz=args.fmax,
            algorithm=args.algorithm,
            method=args.method,
            bootstrap=args.bootstrap,
            tasks=client,
        )
    print(f"hidden in the truth: {r.hidden_text()}")
    for k, d in enumerate(r.twin.diagnoses, start=1):
        print(
            f"round {k}: {d.verdict}"
            + (f" ({', '.join(d.missing)})" if d.missing else "")
            + (f"; at {d.locations[0].label}" if d.locations and d.verdict == "unexplained" else "")
        )
    if r.posterior is not None:
        _print_updated(r.identified())
    _print_history(r.twin)
    print(f"{sum(r.timings_s.values()):.0f} s; report: {r.report}")
    return 0


def _print_updated(table) -> None:
    """One line per updated parameter: MAP ± std, the 90% interval, R-hat and ESS (when sampled), the error
    from the truth (when known: a ``relative_error`` column)."""
    import numpy as np

    for k, name in enumerate(table["parameter"].values):
        err = float(table["relative_error"][k]) if "relative_error" in table else np.nan
        rhat = float(table["r_hat"][k]) if "r_hat" in table else np.nan
        print(
            f"updated {name} = {float(table['map'][k]):.4g} ± {float(table['std'][k]):.2g} {table['unit'].values[k]}"
            f", 90% in {float(table['q05'][k]):.4g} to {float(table['q95'][k]):.4g}"
            + ("" if np.isnan(rhat) else f", R-hat {rhat:.3f}, ESS {float(table['ess_bulk'][k]):.0f}")
            + ("" if np.isnan(err) else f" ({100 * err:+.1f}% from the truth)")
        )


def _print_history(tw) -> None:
    from twin.loop.history import HISTORY_KEY, interval_text

    width = max(44, *(len(step.action) for step in tw.history))
    print(f"{'step':>4}  {'action':<{width}} {'error E':>9} {'90% over the posterior':>23} {'chi2':>9}")
    for k, step in enumerate(tw.history):
        interval = "-" if step.interval is None else interval_text(step.interval) + "%"
        print(
            f"{k:>4}  {step.action:<{width}} {100 * step.error:>8.3f}% {interval:>23} "
            f"{float(step.table.attrs['chi2']):>9.1f}"
        )
    print(f"{HISTORY_KEY}.")


def _loop(args: argparse.Namespace) -> int:
    from twin.loop.bootstrap import check_records
    from twin.loop.history import write_history
    from twin.loop.twin import Twin
    from twin.modes import read_modes
    from twin.netcdf import atomic_output, write_netcdf

    out = Path(args.out)
    modes = read_modes(args.modes)
    model = model_with_effects(args.model, args.effect, modes)
    labels = args.candidates.split(",") if args.candidates else None
    if labels:
        from twin.loop.candidates import select

        labels = [c.label for c in select(model, labels)]  # unknown candidates fail before any work
    tw = Twin(model, modes, tolerance=args.tolerance)
    check_records(args.bootstrap, args.method)
    kwargs = {} if args.method == "laplace" else {**sampler_options(args), "bootstrap": args.bootstrap}
    with tasks(args) as client:
        tw.run(method=args.method, max_rounds=args.rounds, candidates=labels, tasks=client, progress=True, **kwargs)
    out.mkdir(parents=True, exist_ok=True)
    meas = tw.measured
    with atomic_output(out / "diagnosis.json", ".json.part") as tmp:
        tmp.write_text(json.dumps({"rounds": [d.to_dict(meas) for d in tw.diagnoses]}, indent=2))
    write_history(tw.history_table(), out / "history.csv")
    tw.plot_history(out / "history.png")
    if tw.posterior is not None:
        tree = tw.posterior_tree()
        tree.attrs["command"] = " ".join(sys.argv)
        write_netcdf(tree, out / "posterior.nc")
    for k, d in enumerate(tw.diagnoses, start=1):
        print(f"round {k}: {d.verdict}" + (f" ({', '.join(d.missing)})" if d.missing else ""))
        print(f"  {d.summary}")
    if tw.posterior is not None:
        from twin.harness.demo import posterior_table

        _print_updated(posterior_table(tw.posterior, tw.model))
    _print_history(tw)
    wrote = ["diagnosis.json", "history.csv", "history.png"] + (["posterior.nc"] if tw.posterior is not None else [])
    print(f"wrote {', '.join(str(out / w) for w in wrote)}")
    if tw.added:
        print(f"go on with: twin compare {args.model} {args.modes} --posterior {out / 'posterior.nc'}")
    return 0


def _sweep(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.harness.demo import default_model_path
    from twin.harness.scenarios import reference_labels
    from twin.harness.sweep import Settings, read_scenarios, scenario_grid, sweep
    from twin.harness.sweep_report import sweep_text

    model = load_model(args.model if args.model else default_model_path())
    if args.scenarios:
        scenarios = read_scenarios(args.scenarios, model)
    else:
        hidden = [
            h for token in args.hidden.split(",") for h in (reference_labels(model) if token == "all" else [token])
        ]
        scenarios = scenario_grid(model, hidden, _int_list(args.seeds, "--seeds"))
    settings = Settings(
        duration_s=args.duration,
        samples=args.samples,
        fmax_hz=args.fmax,
        algorithm=args.algorithm,
        method=args.method,
        bootstrap=args.bootstrap,
    )
    with tasks(args) as client:
        table = sweep(scenarios, args.out, model=model, settings=settings, tasks=client)
    print(sweep_text(table))
    print(f"wrote {Path(args.out) / 'sweep.nc'} and one report folder per scenario")
    return 0 if bool(table["passed"].all()) else 1


def _int_list(text: str, flag: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",")]
    except ValueError:
        raise TwinError(f"{flag} takes comma-separated integers, got '{text}'") from None


def add_commands(sub) -> None:
    """Add this module's sub-commands to the sub-parsers ``sub``."""
    p = command(
        sub,
        "update",
        "Bayesian updating from mode samples (APerCEM: HMC on the marginal, the Gibbs sampler, or Laplace)",
        "The posterior of the chosen parameters given the measured poles and shapes, written in the\n"
        "ArviZ layout (posterior.nc: posterior, sample_stats, observed_data groups).",
        [
            "twin update hydro_unit modes.nc --params bearings --fsi -o posterior.nc",
            "twin update hydro_unit modes.nc --effect magnetic_pull --params MAG.stiffness -o posterior.nc",
            "twin update hydro_unit modes.nc --method laplace --effect magnetic_pull --params MAG.stiffness "
            "-o posterior.nc",
        ],
        _update,
    )
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("modes", help=MODES_HELP)
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (posterior.nc, ArviZ groups)")
    p.add_argument(
        "--params",
        default=None,
        help="parameters to update: names, globs (LGB.c*) or groups (bearings, thrust, disks); twin params "
        "lists the names (default: none, then --fsi is needed)",
    )
    p.add_argument("--fsi", action="store_true", help="update the per-mode FSI added mass and damping")
    add_method(p, "how to update")
    add_chain_options(p)
    p.add_argument(
        "--noise-model",
        choices=("full", "diagonal"),
        default=None,
        help="--method gibbs: covariance of the residual realisations: full (correlated rows, the "
        "default) or diagonal (the paper's)",
    )
    p.add_argument(
        "--collapsed",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="--method gibbs: a Metropolis step of the parameters with the shapes integrated out in "
        "every sweep (the default; chains mix along the parameter-shape ridge); --no-collapsed: "
        "plain Gibbs",
    )
    p.add_argument(
        "--pole-model",
        choices=("linear", "samples"),
        default=None,
        help="--method gibbs: the condensed model linearised about each mode's mean pole (the default) "
        "or rebuilt at every pole sample (the paper's)",
    )
    p.add_argument(
        "--flat-priors",
        action="store_true",
        help="no prior on the effects' parameters (by default each gets a Gaussian one about the "
        "model's value, as wide as its effect's plausible scale: a bound where the data say little)",
    )
    add_effect(p)
    add_scheduler(p, "chains")
    p = command(
        sub,
        "compare",
        "compare a model with measured modes: per-mode errors and the overall error",
        "Each measured mode against its model partner (one-to-one, by pole distance and MAC): frequency\n"
        "and damping errors with their z-scores, the MAC, the shape error per sensor, and the error E\n"
        "(the uncertainty-weighted RMS relative pole distance).",
        [
            "twin compare hydro_unit modes.nc --plot figures",
            "twin compare hydro_unit modes.nc --posterior posterior.nc --history history.csv",
        ],
        _compare,
    )
    add_model_and_posterior(p)
    p.add_argument(
        "--plot",
        default=None,
        metavar="DIR",
        help="write the figures (errors, MAC, spectra) into the folder DIR (created if missing)",
    )
    p.add_argument(
        "--signals",
        default=None,
        metavar="FILE",
        help="with --plot: the record the modes came from (signals.nc), for spectra.png as its power "
        "spectral density per channel with the identified and the model modes marked (default: the "
        "modal spectra rebuilt from the modes)",
    )
    p.add_argument(
        "--history",
        default=None,
        metavar="FILE",
        help="append this comparison's error as one row of the CSV file FILE (created if missing), and "
        "redraw the error chart beside it, FILE with the suffix .png (history.csv: history.png)",
    )
    p.add_argument("--step", default=None, help="name of the step in the history (default: from --effect/--posterior)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p = command(
        sub,
        "diagnose",
        "where the model fails and which library effect is missing",
        "Fits the library's effects to the measured poles and compares them by evidence (Laplace\n"
        "approximation inside the physical bounds), stepwise; outside the library it locates shaft\n"
        "stiffness and disk mass or inertia changes. Verdicts: missing effect, partly explained,\n"
        "unexplained (with the place), nothing missing, not enough data.",
        ["twin diagnose hydro_unit modes.nc", "twin diagnose hydro_unit modes.nc --posterior posterior.nc --json"],
        _diagnose,
    )
    add_model_and_posterior(p)
    p.add_argument("--candidates", default=None, help="candidate effects, comma-separated (default: the library)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    add_scheduler(p, "candidate fits")
    p = command(
        sub,
        "loop",
        "the twin loop to the end: diagnose, add the missing effects, update them jointly, diagnose again",
        "Rounds of diagnose, add every effect found, update all added effects jointly, until nothing\n"
        "new is missing; writes diagnosis.json, history.csv/.png and posterior.nc into --out.",
        ["twin loop hydro_unit modes.nc --out twin-loop"],
        _loop,
    )
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("modes", help=MODES_HELP)
    p.add_argument("--out", default="twin-loop", help="folder of diagnosis.json, history.csv/.png and posterior.nc")
    add_method(p, "how each round updates the added effects")
    add_bootstrap(p)
    p.add_argument("--rounds", type=COUNT, default=MAX_ROUNDS, help="rounds at most")
    p.add_argument("--candidates", default=None, help="candidate effects, comma-separated (default: the library)")
    add_effect(p)
    add_tolerance(p)
    add_chain_options(p)
    add_scheduler(p, "candidate fits and calibration records")
    p = command(
        sub,
        "demo",
        "the whole loop on a truth with hidden changes, with a report folder",
        "Exports the FMU, simulates a truth with a hidden change, extracts the modes, and runs the\n"
        "loop; report.md and report.html in --out say what was found and how the error fell.",
        [
            "twin demo",
            "twin demo --hidden 'magnetic_pull@1.5+seal_cross_coupling' --seed 4",
            "twin demo --hidden disk_mass:generator@1.1 --out heavier-generator",
        ],
        _demo,
    )
    p.add_argument("--out", default="twin-demo", help="report folder")
    p.add_argument(
        "--hidden",
        default="magnetic_pull",
        help="what the truth hides: a library effect (magnetic_pull, fsi, fsi_per_mode, seal_cross_coupling, "
        "thrust_tilt:thrust, bearing_change:UGB, bearing_change:LGB) at its reference size or scaled "
        "(magnetic_pull@2.5), several joined by + (magnetic_pull+seal_cross_coupling), a local change "
        "outside the library (shaft_stiffness:18@0.5, disk_mass:generator@1.1, disk_inertia:runner@1.2), "
        "or none",
    )
    p.add_argument("--seed", type=NATURAL, default=1, help="seed of turbulence and noise")
    add_loop_settings(p, DEMO_RECORDS)
    # the calibration's records (twin.loop.bootstrap) take most of the demo's time: on a local cluster by default
    add_scheduler(p, "candidate fits and calibration records")
    p = command(
        sub,
        "sweep",
        "the demo's loop over hidden changes and seeds, one Dask task per scenario",
        "Runs the demo for every scenario and tabulates the verdict, the error's fall and the parameter\n"
        "errors (sweep.nc); exit status 1 when a scenario fails.",
        ["twin sweep --hidden all,none --seeds 1,2", "twin sweep --scenarios benchmarks/loop_suite.txt --workers 2"],
        _sweep,
    )
    p.add_argument(
        "--hidden",
        default="all",
        help="what the truths hide, comma-separated specs as for twin demo; 'all' for every library effect "
        "at its reference size ('all,none' adds the false-alarm check)",
    )
    p.add_argument(
        "--scenarios",
        default=None,
        metavar="FILE",
        help="scenarios from a file, one 'SPEC SEED[,SEED...]' per line (instead of --hidden and --seeds), "
        "e.g. benchmarks/loop_suite.txt",
    )
    p.add_argument("--seeds", default="1", help="seeds of turbulence and noise, comma-separated")
    p.add_argument("--out", default="twin-sweep", help="folder of sweep.nc and the report folders")
    add_loop_settings(p)
    add_scheduler(p, "scenarios")
