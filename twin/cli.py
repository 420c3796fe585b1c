"""The ``twin`` command: one sub-command per stage of the loop.

    twin modal MODEL.toml [--speed RPM] [--modes N] [--json]
    twin campbell MODEL.toml [--max-speed RPM] [--points N] [--modes N] -o campbell.png
    twin export-fmu MODEL.toml -o unit.fmu [--fs HZ] [--basis full|modal] [--fmax HZ] [--inputs runner.x,...]
    twin simulate MODEL.toml --duration S --fs HZ --seed N [--truth truth.toml|paper] -o signals.nc
    twin extract signals.nc -o modes.nc [--samples J] [--fmax HZ] [--fmin HZ] [--channels A,B] [--plot stab.png]
    twin synthesize-modes MODEL.toml -o modes.nc [--truth truth.toml|paper] [--samples J] [--seed N]
    twin update MODEL.toml modes.nc -o posterior.nc [--params bearings|NAME,...] [--fsi] [--draws N] [--chains N]
                [--noise-model diagonal|full] [--collapsed] [--pole-model samples|linear] [--effect LABEL]
    twin compare MODEL.toml modes.nc [--posterior posterior.nc] [--effect LABEL] [--json] [--plot DIR]
    twin diagnose MODEL.toml modes.nc [--candidates LABEL,...] [--json]
    twin demo [--out DIR] [--hidden LABEL] [--duration S] [--seed N] [--model MODEL.toml]

Errors in the input are reported on one line (``twin: error: ...``) with exit
status 2, never as a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from twin import __version__
from twin.errors import TwinError, TwinWarning

log = logging.getLogger("twin")

#: Defaults of the options that only the Gibbs sampler takes (``twin update``).
GIBBS_DEFAULTS = {"draws": 500, "chains": 4, "burn_in": 20, "noise_model": "diagonal", "collapsed": False,
                  "pole_model": "samples"}  # fmt: skip


def _modal(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.modes import modal

    model = load_model(args.model)
    ds = modal(model, speed_rpm=args.speed, n_modes=args.modes)
    modes = [
        {
            "mode": int(ds.mode[i]),
            "frequency_hz": float(ds.frequency[i]),
            "natural_frequency_hz": float(ds.natural_frequency[i]),
            "damping_ratio": float(ds.damping_ratio[i]),
            "log_decrement": float(ds.log_decrement[i]),
            "whirl": str(ds.whirl[i].values),
            "stable": bool(ds.stable[i]),
            "pole_real": float(ds.pole[i].real),
            "pole_imag": float(ds.pole[i].imag),
        }
        for i in range(ds.sizes["mode"])
    ]
    if args.json:
        out = {"model": model.name, "n_dof": model.n_dof, "speed_rpm": ds.attrs["speed_rpm"], "modes": modes}
        print(json.dumps(out, indent=2))
        return 0
    print(f"{model.name}: {model.n_dof} DOF, {ds.attrs['speed_rpm']:g} rpm, {len(modes)} modes"
          f" ({ds.attrs['n_overdamped']} over-damped eigenvalues not listed)")  # fmt: skip
    print(f"{'mode':>4}  {'f [Hz]':>10}  {'fn [Hz]':>10}  {'zeta [%]':>8}  {'log dec':>8}  {'whirl':<8}  stable")
    for m in modes:
        print(f"{m['mode']:>4}  {m['frequency_hz']:>10.4f}  {m['natural_frequency_hz']:>10.4f}  "
              f"{100 * m['damping_ratio']:>8.3f}  {m['log_decrement']:>8.4f}  {m['whirl']:<8}  "
              f"{'yes' if m['stable'] else 'NO'}")  # fmt: skip
    return 0


def _campbell(args: argparse.Namespace) -> int:
    import matplotlib

    matplotlib.use("Agg")
    from twin.fem import load_model
    from twin.modes import campbell, plot_campbell

    model = load_model(args.model)
    max_speed = args.max_speed if args.max_speed is not None else 2.0 * model.speed_rpm
    if not max_speed > 0:
        raise TwinError(f"--max-speed must be positive, got {max_speed:g}")
    if args.points < 2:
        raise TwinError(f"--points must be at least 2, got {args.points}")
    out = Path(args.output)
    if not out.parent.is_dir():
        raise TwinError(f"cannot write {out}: folder {out.parent} does not exist")
    ds = campbell(model, np.linspace(0.0, max_speed, args.points), n_modes=args.modes, progress=True)
    fig = plot_campbell(ds)
    fig.savefig(out, dpi=120, bbox_inches="tight")
    print(f"wrote {out}")
    return 0


def _export_fmu(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.fmu import export_fmu

    if not args.fs > 0:
        raise TwinError(f"--fs must be positive, got {args.fs:g}")
    model = load_model(args.model)
    inputs = None if args.inputs is None else [s.strip() for s in args.inputs.split(",") if s.strip()]
    path = export_fmu(model, args.output, step_s=1.0 / args.fs, basis=args.basis, fmax_hz=args.fmax, inputs=inputs)
    print(f"wrote {path}")
    return 0


def _simulate(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.fem.truthfile import load_truth
    from twin.fmu.simulate import simulate

    model = load_model(args.model)
    truth = None if args.truth is None else load_truth(args.truth, model)
    simulate(model, duration_s=args.duration, fs_hz=args.fs, seed=args.seed, truth=truth,
             turbulence_asd=args.turbulence, unbalance_me=args.unbalance, noise_ratio=args.noise,
             basis=args.basis, fmax_hz=args.fmax, output=args.output, command=" ".join(sys.argv))  # fmt: skip
    print(f"wrote {args.output}")
    return 0


def _extract(args: argparse.Namespace) -> int:
    from twin.extract import extract
    from twin.netcdf import check_writable

    plot = None if args.plot is None else check_writable(args.plot)
    channels = None if args.channels is None else [c.strip() for c in args.channels.split(",") if c.strip()]
    ds = extract(args.signals, samples=args.samples, fmax_hz=args.fmax, fmin_hz=args.fmin, block_rows=args.block_rows,
                 max_order=args.max_order, channels=channels, output=args.output, command=" ".join(sys.argv))  # fmt: skip
    harmonics = ", ".join(f"{h['frequency_hz']:.3f}" for h in json.loads(ds.attrs["harmonics"]))
    print(f"{ds.sizes['mode']} modes, {ds.sizes['sample']} samples each"
          + (f"; harmonics rejected at {harmonics} Hz" if harmonics else ""))
    print(f"{'mode':>4}  {'f [Hz]':>9}  {'+-se':>7}  {'zeta [%]':>8}  {'+-se':>6}  {'MPC':>5}  {'MPD':>5}")
    for k in range(ds.sizes["mode"]):
        print(f"{int(ds.mode[k]):>4}  {float(ds.frequency[k]):>9.4f}  {float(ds.frequency_se[k]):>7.4f}  "
              f"{100 * float(ds.damping_ratio[k]):>8.3f}  {100 * float(ds.damping_ratio_se[k]):>6.3f}  "
              f"{float(ds.MPC[k]):>5.2f}  {float(ds.MPD[k]):>5.1f}")  # fmt: skip
    if plot is not None:
        import matplotlib

        matplotlib.use("Agg")
        from twin.extract.plot import plot_stabilisation

        plot_stabilisation(ds).savefig(plot, dpi=120)
        print(f"wrote {plot}")
    print(f"wrote {args.output}")
    return 0


def _synthesize_modes(args: argparse.Namespace) -> int:
    from twin.extract.modesfile import write_modes
    from twin.fem import load_model
    from twin.fem.truthfile import load_truth
    from twin.netcdf import check_writable
    from twin.update import synthesize_modes

    check_writable(args.output)
    model = load_model(args.model)
    truth = load_truth(args.truth, model)
    ds = synthesize_modes(model, truth, samples=args.samples, seed=args.seed, n_modes=args.modes,
                          command=" ".join(sys.argv))  # fmt: skip
    write_modes(ds, args.output)
    print(f"{ds.sizes['mode']} modes x {ds.sizes['sample']} samples ({truth.source}); wrote {args.output}")
    return 0


def _update(args: argparse.Namespace) -> int:
    from twin.extract import read_modes
    from twin.update import summary, update

    if args.params is None and not args.fsi:
        raise TwinError("nothing to update: give --params and/or --fsi")
    modes = read_modes(args.modes)  # a bad modes file fails before a cluster starts
    model = _model_with_effects(args.model, args.effect, modes)
    if args.method == "laplace":
        return _update_laplace(args, model, modes)
    with _tasks(args) as client:
        tree = update(model, args.modes, args.params, fsi=args.fsi, draws=args.draws, chains=args.chains,
                      burn_in=args.burn_in, seed=args.seed, noise_model=args.noise_model, collapsed=args.collapsed,
                      pole_model=args.pole_model, output=args.output, command=" ".join(sys.argv), tasks=client)  # fmt: skip
    table = summary(tree["posterior"].to_dataset())
    print(f"{tree.attrs['condensation']} condensation; {args.chains} chains x {args.draws} draws "
          f"in {tree.attrs['elapsed_s']:.1f} s")  # fmt: skip
    print(f"{'parameter':<22} {'MAP':>11} {'mean':>11} {'std':>10} {'5%':>11} {'95%':>11} {'R-hat':>6} {'ESS':>6}")
    has_diag = "r_hat" in table
    for k, p in enumerate(table["parameter"].values):
        row = table.isel(parameter=k)
        r_hat = f"{float(row.r_hat):>6.3f}" if has_diag else f"{'-':>6}"
        diag = f"{r_hat} {float(row.ess_bulk):>6.0f}" if "ess_bulk" in table else f"{r_hat} {'-':>6}"
        print(f"{p:<22} {float(row['map']):>11.4g} {float(row['mean']):>11.4g} {float(row['std']):>10.3g} "
              f"{float(row.q05):>11.4g} {float(row.q95):>11.4g} {diag}")  # fmt: skip
    print(f"wrote {args.output}")
    return 0


def _update_laplace(args: argparse.Namespace, model, modes) -> int:
    """``twin update --method laplace``: the Gaussian posterior of the pole fit, in the posterior.nc layout."""
    from twin.fem.effects import effect_label
    from twin.loop.candidates import free_names
    from twin.loop.compare import measured_modes
    from twin.loop.fit import laplace_update
    from twin.netcdf import check_writable, write_netcdf
    from twin.update.posterior import laplace_tree
    from twin.update.problem import select_parameters

    check_writable(args.output)
    sampler = [f for f, default in GIBBS_DEFAULTS.items() if getattr(args, f) != default]
    if sampler:
        raise TwinError(f"--method laplace takes no sampler settings ({', '.join('--' + f.replace('_', '-') for f in sampler)})")
    meas = measured_modes(modes)
    names = select_parameters(model, args.params)
    if args.fsi:
        per_mode = [e for e in model.effects if e.per_mode]
        if not per_mode:
            model = _model_with_effects(args.model, [*(args.effect or []), "fsi_per_mode"], modes)
            per_mode = [e for e in model.effects if e.per_mode]
        names += free_names(model, per_mode[0], meas.mode)
    updated, post = laplace_update(model, meas, names)
    attrs = {"title": f"Laplace posterior of {model.name}", "command": " ".join(sys.argv), "model": model.name,
             "method": post.attrs["method"], "effects": json.dumps([effect_label(e) for e in model.effects]),
             "chi2_before": post.attrs["chi2_before"], "chi2_after": post.attrs["chi2_after"]}  # fmt: skip
    write_netcdf(laplace_tree(post, modes, attrs, seed=args.seed if args.seed is not None else 0), args.output)
    print(f"Laplace update of {len(names)} parameters: chi2 {post.attrs['chi2_before']:.1f} -> {post.attrs['chi2_after']:.1f}")
    print(f"{'parameter':<22} {'MAP':>11} {'std':>10} {'unit':<8}")
    for k, n in enumerate(names):
        bound = " (on its physical bound)" if n in post.attrs["at_bound"].split(", ") else ""
        print(f"{n:<22} {float(post['map'][k]):>11.4g} {float(post['std'][k]):>10.3g} {str(post['unit'].values[k]):<8}{bound}")
    print(f"wrote {args.output}")
    return 0


def _model_with_effects(path: str, labels: list[str] | None, modes=None, posterior=None):
    """The model file's model with library effects added: ``--effect`` labels and those a posterior was made
    with (its ``effects`` attr); a per-mode effect takes one value per measured mode."""
    from twin.fem import load_model
    from twin.fem.effects import effect_label
    from twin.loop.candidates import add_effects

    model = load_model(path)
    wanted = list(labels or [])
    if posterior is not None:
        wanted += json.loads(posterior.attrs.get("effects", "[]"))
    present = {effect_label(e) for e in model.effects}
    wanted = [w for i, w in enumerate(wanted) if w not in present and w not in wanted[:i]]
    if not wanted:
        return model
    mode_labels = None if modes is None else [int(m) for m in modes["mode"].values]
    return add_effects(model, wanted, mode_labels)


def _compare(args: argparse.Namespace) -> int:
    from twin.extract import read_modes
    from twin.loop.compare import compare
    from twin.loop.report import comparison_text

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
        from twin.loop.plots import comparison_figures

        for path in comparison_figures(table, args.plot):
            log.info("wrote %s", path)
    if args.json:
        keep = ["measured_frequency", "model_frequency", "frequency_error", "measured_damping_ratio",
                "model_damping_ratio", "damping_error", "pole_error", "z_frequency", "z_damping", "mac"]  # fmt: skip
        rows = [{"mode": int(m), **{k: float(table[k].sel(mode=m)) for k in keep}} for m in table["mode"].values]
        shape = {str(c): float(v) for c, v in zip(table["channel"].values, table["channel_shape_error"].values)}
        print(json.dumps({"error": table.attrs["error"], "error_definition": table.attrs["error_definition"],
                          "error_rms": table.attrs["error_rms"], "chi2": table.attrs["chi2"], "n_data": table.attrs["n_data"], "modes": rows,
                          "channel_shape_error": shape,
                          "poorly_paired": [int(m) for m in np.atleast_1d(table.attrs["poorly_paired"])]}, indent=2))  # fmt: skip
    else:
        print(comparison_text(table))
    return 0


def _posterior_model(args: argparse.Namespace, modes):
    """The model of ``--effect`` and ``--posterior`` (the effects the posterior needs are added)."""
    tree = None
    if args.posterior:
        from twin.update import read_posterior

        tree = read_posterior(args.posterior)
    model = _model_with_effects(args.model, args.effect, modes, tree)
    if tree is not None:
        from twin.update import apply_posterior

        model = apply_posterior(model, tree, args.estimate)
    return model


def _diagnose(args: argparse.Namespace) -> int:
    from twin.extract import read_modes
    from twin.loop.compare import measured_modes
    from twin.loop.candidates import select
    from twin.loop.diagnose import diagnose
    from twin.loop.report import diagnosis_text

    modes = read_modes(args.modes)
    model = _posterior_model(args, modes)
    meas = measured_modes(modes, args.tolerance)
    labels = args.candidates.split(",") if args.candidates else None
    select(model, labels)  # unknown candidates fail before a cluster starts
    with _tasks(args) as client:
        d = diagnose(model, meas, candidates=labels, tolerance=args.tolerance, tasks=client)
    print(d.to_json(meas) if args.json else diagnosis_text(d, meas))
    return 0


def _demo(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.loop.demo import run_demo

    model = load_model(args.model) if args.model else None
    with _tasks(args) as client:
        r = run_demo(args.out, model=model, hidden=args.hidden, duration_s=args.duration, seed=args.seed,
                     samples=args.samples, tasks=client)  # fmt: skip
    print(f"hidden in the truth: {r.hidden_text()}")
    for k, d in enumerate(r.twin.diagnoses, start=1):
        print(f"round {k}: {d.verdict}" + (f" ({', '.join(d.missing)})" if d.missing else "")
              + (f"; at {d.locations[0].label}" if d.locations and d.verdict == "unexplained" else ""))  # fmt: skip
    if r.posterior is not None:
        ident = r.identified()
        for k, name in enumerate(ident["parameter"].values):
            err = float(ident["relative_error"][k])
            print(f"updated {name} = {float(ident['map'][k]):.4g} ± {float(ident['std'][k]):.2g} {ident['unit'].values[k]}"
                  + ("" if np.isnan(err) else f" ({100 * err:+.1f}% from the truth)"))  # fmt: skip
    _print_history(r.twin)
    print(f"{sum(r.timings_s.values()):.0f} s; report: {r.report}")
    return 0


def _print_history(tw) -> None:
    print(f"{'step':>4}  {'action':<44} {'error E':>9} {'chi2':>9}")
    for k, step in enumerate(tw.history):
        print(f"{k:>4}  {step.action:<44} {100 * step.error:>8.3f}% {float(step.table.attrs['chi2']):>9.1f}")


def _loop(args: argparse.Namespace) -> int:
    from twin.extract import read_modes
    from twin.loop.history import write_history
    from twin.loop.twin import Twin
    from twin.netcdf import atomic_output, write_netcdf
    from twin.update.posterior import laplace_tree

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise TwinError(f"--out {out} is a file, not a folder")
    modes = read_modes(args.modes)
    model = _model_with_effects(args.model, args.effect, modes)
    labels = args.candidates.split(",") if args.candidates else None
    if labels:
        from twin.loop.candidates import select

        select(model, labels)  # unknown candidates fail before any work
    tw = Twin(model, modes, tolerance=args.tolerance)
    kwargs = {} if args.method == "laplace" else {"draws": args.draws, "chains": args.chains, "seed": args.seed,
                                                  "progress": False}  # fmt: skip
    with _tasks(args) as client:
        tw.run(method=args.method, max_rounds=args.rounds, candidates=labels, tasks=client, **kwargs)
    out.mkdir(parents=True, exist_ok=True)
    meas = tw.measured
    with atomic_output(out / "diagnosis.json", ".json.part") as tmp:
        tmp.write_text(json.dumps({"rounds": [d.to_dict(meas) for d in tw.diagnoses]}, indent=2))
    write_history(tw.history_table(), out / "history.csv")
    tw.plot_history(out / "history.png")
    if tw.posterior is not None:
        if args.method == "laplace":
            from twin.fem.effects import effect_label

            attrs = {"title": f"Laplace posterior of {model.name}", "command": " ".join(sys.argv), "model": model.name,
                     "method": tw.posterior.attrs["method"],
                     "effects": json.dumps([effect_label(e) for e in tw.model.effects])}  # fmt: skip
            write_netcdf(laplace_tree(tw.posterior, modes, attrs), out / "posterior.nc")
        else:
            write_netcdf(tw.posterior, out / "posterior.nc")
    for k, d in enumerate(tw.diagnoses, start=1):
        print(f"round {k}: {d.verdict}" + (f" ({', '.join(d.missing)})" if d.missing else ""))
        print(f"  {d.summary}")
    _print_history(tw)
    wrote = ["diagnosis.json", "history.csv", "history.png"] + (["posterior.nc"] if tw.posterior is not None else [])
    print(f"wrote {', '.join(str(out / w) for w in wrote)}")
    if tw.added:
        print(f"go on with: twin compare {args.model} {args.modes} --posterior {out / 'posterior.nc'}")
    return 0


def _sweep(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.loop.report import sweep_text
    from twin.loop.scenarios import REFERENCE_EFFECTS
    from twin.loop.sweep import Settings, read_scenarios, scenario_grid, sweep

    model = load_model(args.model) if args.model else None
    if args.scenarios:
        scenarios = read_scenarios(args.scenarios)
    else:
        hidden = [h for token in args.hidden.split(",") for h in (REFERENCE_EFFECTS if token == "all" else [token])]
        scenarios = scenario_grid(hidden, _int_list(args.seeds, "--seeds"))
    settings = Settings(duration_s=args.duration, samples=args.samples)
    with _tasks(args) as client:
        table = sweep(scenarios, args.out, model=model, settings=settings, tasks=client)
    print(sweep_text(table))
    print(f"wrote {Path(args.out) / 'sweep.nc'} and one report folder per scenario")
    return 0 if bool(table["passed"].all()) else 1


def _int_list(text: str, flag: str) -> list[int]:
    try:
        return [int(x) for x in text.split(",")]
    except ValueError:
        raise TwinError(f"{flag} takes comma-separated integers, got '{text}'") from None


@contextlib.contextmanager
def _tasks(args: argparse.Namespace):
    """The Dask client of ``--scheduler``/``--workers`` (None for ``sync``), closed afterwards."""
    from twin.tasks import dask_client

    with dask_client(args.scheduler, n_workers=args.workers) as client:
        yield client


def _add_scheduler(p: argparse.ArgumentParser, what: str, default: str = "local") -> None:
    p.add_argument("--scheduler", default=default, metavar="ADDRESS",
                   help=f"where the {what} run as Dask tasks: 'local' (a local cluster of worker processes), "
                        f"a scheduler address such as tcp://host:8786, or 'sync' (in this process; "
                        f"default: {default})")  # fmt: skip
    p.add_argument("--workers", type=int, default=None, help="workers of the local cluster (default: one per core)")


def _add_loop_settings(p: argparse.ArgumentParser) -> None:
    """The demo's record and model options, shared by ``demo`` and ``sweep``."""
    from twin.loop.demo import DEMO_SAMPLES

    p.add_argument("--duration", type=float, default=1200.0, help="record length [s] (default: 1200)")
    p.add_argument("--samples", type=int, default=DEMO_SAMPLES, help=f"jackknife samples per mode (default: {DEMO_SAMPLES})")
    p.add_argument("--model", default=None, help="the twin's model file (default: models/hydro_unit.toml)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``twin`` command."""
    parser = argparse.ArgumentParser(prog="twin", description="Digital twin of a rotating machine in water.")
    parser.add_argument("--version", action="version", version=f"twin {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress and details")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("modal", help="complex modes of a model at a speed")
    p.add_argument("model", help="model file (TOML)")
    p.add_argument("--speed", type=float, default=None, help="speed [rpm] (default: the model's running speed)")
    p.add_argument("--modes", type=int, default=None, help="number of modes to list (default: all)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=_modal)

    p = sub.add_parser("campbell", help="Campbell diagram of a model over a speed range")
    p.add_argument("model", help="model file (TOML)")
    p.add_argument("--max-speed", type=float, default=None, help="highest speed [rpm] (default: 2x running speed)")
    p.add_argument("--points", type=int, default=41, help="number of speeds (default: 41)")
    p.add_argument("--modes", type=int, default=12, help="number of modes followed (default: 12)")
    p.add_argument("-o", "--output", default="campbell.png", help="figure file (default: campbell.png)")
    p.set_defaults(func=_campbell)

    p = sub.add_parser("export-fmu", help="export the model as an FMI 2.0 co-simulation FMU")
    p.add_argument("model", help="model file (TOML)")
    p.add_argument("-o", "--output", required=True, help="FMU file to write")
    p.add_argument("--fs", type=float, default=256.0, help="sampling rate = 1 / communication step [Hz] (default: 256)")
    p.add_argument("--basis", choices=("full", "modal"), default="full", help="full FEM or truncated modal basis")
    p.add_argument("--fmax", type=float, default=None, help="highest mode kept by the modal basis [Hz]")
    p.add_argument("--inputs", default=None, help="force inputs, e.g. runner.x,runner.y,12.x (default: x, y at every disk)")
    p.set_defaults(func=_export_fmu)

    from twin.fmu.simulate import DEFAULT_TURBULENCE_ASD, DEFAULT_UNBALANCE_ME

    p = sub.add_parser("simulate", help="simulate proximeter signals through the model's FMU")
    p.add_argument("model", help="model file (TOML)")
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (signals.nc)")
    p.add_argument("--duration", type=float, required=True, help="record length [s]")
    p.add_argument("--fs", type=float, default=256.0, help="sampling rate [Hz] (default: 256)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default: 1)")
    p.add_argument("--truth", default=None, help="truth file with hidden effects, or 'paper' (Table 2 FSI)")
    p.add_argument("--turbulence", type=float, default=DEFAULT_TURBULENCE_ASD,
                   help=f"runner turbulence force ASD [N/sqrt(Hz)] (default: {DEFAULT_TURBULENCE_ASD:g})")
    p.add_argument("--unbalance", type=float, default=DEFAULT_UNBALANCE_ME,
                   help=f"1X unbalance at the generator [kg m] (default: {DEFAULT_UNBALANCE_ME:g})")
    p.add_argument("--noise", type=float, default=0.05, help="sensor noise / signal RMS (default: 0.05)")
    p.add_argument("--basis", choices=("full", "modal"), default="full", help="full FEM or modal basis")
    p.add_argument("--fmax", type=float, default=None, help="highest mode of the modal basis [Hz]")
    p.set_defaults(func=_simulate)

    p = sub.add_parser("extract", help="automated modal extraction (SSI-cov) from signals to mode samples")
    p.add_argument("signals", help="signals file (NetCDF, time x channel)")
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (modes.nc)")
    p.add_argument("--samples", type=int, default=100, help="samples per mode J (default: 100)")
    p.add_argument("--fmax", type=float, default=None, help="highest frequency [Hz] (default: 40%% of fs)")
    p.add_argument("--fmin", type=float, default=0.0, help="lowest frequency [Hz] (default: 0)")
    p.add_argument("--block-rows", type=int, default=None, help="Hankel block rows (default: from fmax)")
    p.add_argument("--max-order", type=int, default=100, help="largest model order (default: 100)")
    p.add_argument("--channels", default=None, help="channels to use, e.g. UGB_x,UGB_y (default: all)")
    p.add_argument("--plot", default=None, help="stabilisation diagram figure to write (PNG)")
    p.set_defaults(func=_extract)

    p = sub.add_parser("synthesize-modes", help="paper-style synthetic modal data (noisy pole and shape samples)")
    p.add_argument("model", help="model file (TOML), the calibrated FEM")
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (modes.nc)")
    p.add_argument("--truth", default="paper", help="truth file with hidden effects, or 'paper' (default: Table 2 FSI)")
    p.add_argument("--samples", type=int, default=100, help="samples per mode J (default: 100)")
    p.add_argument("--seed", type=int, default=1, help="random seed (default: 1)")
    p.add_argument("--modes", type=int, default=None, help="number of modes (for a truth without per-mode effect)")
    p.set_defaults(func=_synthesize_modes)

    p = sub.add_parser("update", help="Bayesian updating from mode samples (APerCEM Gibbs sampler, or Laplace)")
    p.add_argument("model", help="model file (TOML)")
    p.add_argument("modes", help="modes file (NetCDF, mode x sample x channel)")
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (posterior.nc, ArviZ groups)")
    p.add_argument("--params", default=None,
                   help="parameters to update: names, globs (LGB.c*) or groups (bearings, thrust, disks)")
    p.add_argument("--fsi", action="store_true", help="update the per-mode FSI added mass and damping")
    p.add_argument("--method", choices=("gibbs", "laplace"), default="gibbs",
                   help="gibbs: the APerCEM sampler on pole and shape samples; laplace: the Gaussian posterior of "
                        "the pole fit inside the physical bounds (fast, blind to shapes); default: gibbs")
    p.add_argument("--draws", type=int, default=GIBBS_DEFAULTS["draws"], help=f"draws kept per chain (default: {GIBBS_DEFAULTS['draws']})")
    p.add_argument("--chains", type=int, default=GIBBS_DEFAULTS["chains"], help=f"number of chains (default: {GIBBS_DEFAULTS['chains']})")
    p.add_argument("--burn-in", type=int, default=GIBBS_DEFAULTS["burn_in"],
                   help=f"sweeps discarded per chain (default: {GIBBS_DEFAULTS['burn_in']})")
    p.add_argument("--seed", type=int, default=None, help="random seed of the chains")
    # literal: importing twin.update.gibbs.NOISE_MODELS here would add 0.4 s to every command's start-up
    p.add_argument("--noise-model", choices=("diagonal", "full"), default=GIBBS_DEFAULTS["noise_model"],
                   help="covariance of the residual realisations: diagonal (the paper's) or full (correlated rows, "
                        "better calibrated on synthetic data); default: diagonal")
    p.add_argument("--collapsed", action="store_true",
                   help="add to every sweep a Metropolis step of the parameters with the shapes integrated "
                        "out (4-5x the time per sweep; chains mix along the parameter-shape ridge)")
    p.add_argument("--pole-model", choices=("samples", "linear"), default=GIBBS_DEFAULTS["pole_model"],
                   help="how the pole samples enter the condensed model: at every sample (the paper's) or "
                        "linearised about each mode's mean pole (no curvature bias near resonances of the "
                        "unobserved DOFs); default: samples")
    p.add_argument("--effect", action="append", default=None, metavar="LABEL",
                   help="add a library effect first (e.g. magnetic_pull, bearing_change:LGB); repeatable")
    _add_scheduler(p, "chains")
    p.set_defaults(func=_update)

    p = sub.add_parser("compare", help="compare a model with measured modes: per-mode errors and the overall error")
    p.add_argument("model", help="model file (TOML)")
    p.add_argument("modes", help="modes file (NetCDF, mode x sample x channel)")
    p.add_argument("--posterior", default=None, help="apply this posterior (posterior.nc) to the model first")
    p.add_argument("--estimate", choices=("map", "mean"), default="map", help="posterior point estimate (default: map)")
    p.add_argument("--effect", action="append", default=None, metavar="LABEL",
                   help="add a library effect first (e.g. magnetic_pull); repeatable")
    p.add_argument("--tolerance", type=float, default=0.0,
                   help="relative pole uncertainty accepted as model-form error, added to the measurement's standard "
                        "error (default: 0)")
    p.add_argument("--plot", default=None, metavar="DIR", help="write the figures (errors, MAC, spectra) into DIR")
    p.add_argument("--history", default=None, metavar="FILE",
                   help="add this comparison's error to the history FILE (CSV, created if missing) and plot it "
                        "beside it (FILE with .png)")  # fmt: skip
    p.add_argument("--step", default=None, help="name of the step in the history (default: from --effect/--posterior)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=_compare)

    p = sub.add_parser("diagnose", help="where the model fails and which library effect is missing")
    p.add_argument("model", help="model file (TOML)")
    p.add_argument("modes", help="modes file (NetCDF, mode x sample x channel)")
    p.add_argument("--candidates", default=None, help="candidate effects, comma-separated (default: the library)")
    p.add_argument("--effect", action="append", default=None, metavar="LABEL",
                   help="add a library effect to the model first; repeatable")
    p.add_argument("--posterior", default=None,
                   help="apply this posterior (posterior.nc of twin update or twin loop) first, with the effects it "
                        "was made with: the next round of the loop")
    p.add_argument("--estimate", choices=("map", "mean"), default="map", help="posterior point estimate (default: map)")
    p.add_argument("--tolerance", type=float, default=0.0,
                   help="relative pole uncertainty accepted as model-form error, added to the measurement's standard "
                        "error (default: 0)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    _add_scheduler(p, "candidate fits")
    p.set_defaults(func=_diagnose)

    p = sub.add_parser("loop", help="the twin loop to the end: diagnose, add the missing effects, update them jointly, "
                                    "diagnose again")
    p.add_argument("model", help="model file (TOML)")
    p.add_argument("modes", help="modes file (NetCDF, mode x sample x channel)")
    p.add_argument("--out", default="twin-loop", help="folder of diagnosis.json, history.csv/.png and posterior.nc "
                                                      "(default: twin-loop)")
    p.add_argument("--method", choices=("laplace", "gibbs"), default="laplace",
                   help="how each round updates the added effects (default: laplace)")
    p.add_argument("--rounds", type=int, default=4, help="rounds at most (default: 4)")
    p.add_argument("--candidates", default=None, help="candidate effects, comma-separated (default: the library)")
    p.add_argument("--effect", action="append", default=None, metavar="LABEL",
                   help="add a library effect to the model first; repeatable")
    p.add_argument("--tolerance", type=float, default=0.0,
                   help="relative pole uncertainty accepted as model-form error, added to the measurement's standard "
                        "error (default: 0)")
    p.add_argument("--draws", type=int, default=GIBBS_DEFAULTS["draws"], help="Gibbs draws per chain")
    p.add_argument("--chains", type=int, default=GIBBS_DEFAULTS["chains"], help="Gibbs chains")
    p.add_argument("--seed", type=int, default=None, help="random seed of the chains")
    _add_scheduler(p, "candidate fits", default="sync")
    p.set_defaults(func=_loop)

    p = sub.add_parser("demo", help="the whole loop on a truth with hidden changes, with a report folder")
    p.add_argument("--out", default="twin-demo", help="report folder (default: twin-demo)")
    p.add_argument("--hidden", default="magnetic_pull",
                   help="what the truth hides: a library effect (magnetic_pull, fsi, fsi_per_mode, seal_cross_coupling, "
                        "thrust_tilt:thrust, bearing_change:UGB, bearing_change:LGB) at its reference size or scaled "
                        "(magnetic_pull@2.5), several joined by + (magnetic_pull+seal_cross_coupling), a local change "
                        "outside the library (shaft_stiffness:18@0.5, disk_mass:generator@1.1, disk_inertia:runner@1.2), "
                        "or none (default: magnetic_pull)")
    p.add_argument("--seed", type=int, default=1, help="seed of turbulence and noise (default: 1)")
    _add_loop_settings(p)
    # the demo's candidate fits take a few seconds, less than starting a cluster: in this process by default
    _add_scheduler(p, "candidate fits", default="sync")
    p.set_defaults(func=_demo)

    p = sub.add_parser("sweep", help="the demo's loop over hidden changes and seeds, one Dask task per scenario")
    p.add_argument("--hidden", default="all",
                   help="what the truths hide, comma-separated specs as for twin demo; 'all' for every library effect "
                        "at its reference size (default: all; 'all,none' adds the false-alarm check)")
    p.add_argument("--scenarios", default=None, metavar="FILE",
                   help="scenarios from a file, one 'SPEC SEED[,SEED...]' per line (instead of --hidden and --seeds), "
                        "e.g. benchmarks/loop_suite.txt")
    p.add_argument("--seeds", default="1", help="seeds of turbulence and noise, comma-separated (default: 1)")
    p.add_argument("--out", default="twin-sweep", help="folder of sweep.nc and the report folders (default: twin-sweep)")
    _add_loop_settings(p)
    _add_scheduler(p, "scenarios")
    p.set_defaults(func=_sweep)
    return parser


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings of the loop on one line (``twin: warning: ...``), others as Python prints them."""
    if issubclass(category, TwinWarning):
        print(f"twin: warning: {message}", file=sys.stderr)
    else:
        print(warnings.formatwarning(message, category, filename, lineno, line), file=sys.stderr, end="")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``twin`` command; returns the exit status."""
    args = build_parser().parse_args(argv)
    level = logging.INFO if args.verbose else logging.WARNING
    if not logging.getLogger().handlers:  # (a host such as pytest may have its own)
        logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
        handler = logging.getLogger().handlers[0]
        # Dask's scheduler runs here and logs its own life at INFO: only its warnings are shown
        handler.setLevel(level)
        handler.addFilter(lambda r: r.levelno >= logging.WARNING or not r.name.startswith("distributed"))
    warnings.showwarning = _show_warning
    try:
        return args.func(args)
    except TwinError as exc:
        print(f"twin: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. `head`, which stopped reading
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
