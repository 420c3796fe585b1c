"""The ``twin`` sub-commands of the model, FMU, extraction and synthetic-data stages (stages 1-3)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from twin.errors import TwinError


def _modal(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.modes import modal

    model = load_model(args.model)
    every = modal(model, speed_rpm=args.speed)
    ds = every.isel(mode=slice(0, args.modes))
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
    shown = "" if len(modes) == every.sizes["mode"] else f"the first {len(modes)} of "
    print(f"{model.name}: {model.n_dof} DOF, {ds.attrs['speed_rpm']:g} rpm, {shown}{every.sizes['mode']} modes"
          f" ({ds.attrs['n_overdamped']} over-damped eigenvalues not listed" + ("; --modes N for more)" if shown else ")"))  # fmt: skip
    print(f"{'mode':>4}  {'f [Hz]':>10}  {'fn [Hz]':>10}  {'zeta [%]':>8}  {'log dec':>8}  {'whirl':<8}  stable")
    for m in modes:
        print(f"{m['mode']:>4}  {m['frequency_hz']:>10.4f}  {m['natural_frequency_hz']:>10.4f}  "
              f"{100 * m['damping_ratio']:>8.3f}  {m['log_decrement']:>8.4f}  {m['whirl']:<8}  "
              f"{'yes' if m['stable'] else 'NO'}")  # fmt: skip
    return 0


def _campbell(args: argparse.Namespace) -> int:
    import numpy as np

    from twin.fem import load_model
    from twin.modes import campbell, plot_campbell
    from twin.report.figures import pyplot

    pyplot()  # figures for files, no window

    model = load_model(args.model)
    max_speed = args.max_speed if args.max_speed is not None else 2.0 * model.speed_rpm
    if not max_speed > 0:
        raise TwinError(f"--max-speed must be positive, got {max_speed:g}")
    if args.points < 2:
        raise TwinError(f"--points must be at least 2, got {args.points}")
    out = Path(args.output)  # checked by main, a figure type
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
    path = export_fmu(model, args.output, step_s=1.0 / args.fs, basis=args.basis, fmax_hz=args.fmax, inputs=inputs,
                      kind=args.kind, fmi_version=args.fmi)
    print(f"wrote {path}")
    return 0


def _simulate(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.fem.truthfile import load_truth
    from twin.fmu.simulate import simulate

    model = load_model(args.model)
    from twin.progress import stage

    truth = None if args.truth is None else load_truth(args.truth, model)
    with stage(f"simulate {args.duration:g} s of {model.name} at {args.fs:g} Hz through its FMU (FMPy)"):
        simulate(model, duration_s=args.duration, fs_hz=args.fs, seed=args.seed, truth=truth,
                 turbulence_asd=args.turbulence, unbalance_me=args.unbalance, noise_ratio=args.noise,
                 noise_std_m=args.noise_std, basis=args.basis, fmax_hz=args.fmax, output=args.output,
                 command=" ".join(sys.argv))  # fmt: skip
    print(f"wrote {args.output}")
    return 0


def _import(args: argparse.Namespace) -> int:
    from twin.extract.importing import import_record
    from twin.netcdf import write_netcdf

    def per_channel(text: str | None, flag: str):
        if text is None or "=" not in text:
            return text
        pairs = [p.split("=", 1) for p in text.split(",") if p.strip()]
        if any(len(p) != 2 or not p[0].strip() for p in pairs):
            raise TwinError(f"{flag} takes one value or NAME=VALUE pairs separated by commas, got {text!r}")
        return {k.strip(): v.strip() for k, v in pairs}

    channels = None if args.channels is None else [c.strip() for c in args.channels.split(",") if c.strip()]
    ds = import_record(args.file, fs_hz=args.fs, units=per_channel(args.units, "--units"),
                       quantities=per_channel(args.quantity, "--quantity"), channels=channels)  # fmt: skip
    ds.attrs["command"] = " ".join(sys.argv)
    write_netcdf(ds, args.output)
    described = ", ".join(f"{c} ({q}, {u})" for c, q, u in zip(ds["channel"].values, ds["quantity"].values,
                                                                 ds["units"].values))  # fmt: skip
    print(f"{ds.sizes['time']} samples at {ds.attrs['sampling_rate']:g} Hz of {described}; wrote {args.output}")
    return 0


def _extract(args: argparse.Namespace) -> int:
    from twin.design.observe import judge_targets
    from twin.extract import extract
    from twin.extract.options import ExtractOptions
    from twin.modes import write_modes
    from twin.extract.harmonics import line_frequencies
    from twin.netcdf import check_writable

    plot = None if args.plot is None else check_writable(args.plot, figure=True)
    channels = None if args.channels is None else [c.strip() for c in args.channels.split(",") if c.strip()]
    options = ExtractOptions(samples=args.samples, fmax_hz=args.fmax, fmin_hz=args.fmin, block_rows=args.block_rows,
                             shape_block_rows=args.shape_block_rows, first_lag=args.first_lag,
                             max_order=args.max_order, channels=channels,
                             delete_blocks=None if args.delete_half else 1, order_spread=args.order_spread,
                             remove_harmonics=args.remove_harmonics, blocks=args.blocks,
                             orders_per_mode=args.orders_per_mode or None,
                             differenced_above_hz=args.differenced_above, shape_samples=args.shape_samples)  # fmt: skip
    if args.output is not None:
        check_writable(args.output)
    ds = judge_targets(extract(args.signals, options, command=" ".join(sys.argv)), args.signals)
    if args.output is not None:
        write_modes(ds, args.output)
    removed, rejected = (", ".join(f"{f:.3f}" for f in fs) for fs in line_frequencies(ds.attrs["harmonics"]))
    chosen = json.loads(ds.attrs["settings"]).get("blocks_chosen")
    if chosen:
        print(f"jackknife: {chosen}")
    print(f"{ds.sizes['mode']} modes, {ds.sizes['sample']} samples each"
          + (f"; running-speed lines removed at {removed} Hz" if removed else "")
          + (f"; harmonics rejected at {rejected} Hz" if rejected else ""))
    print(f"{'mode':>4}  {'f [Hz]':>9}  {'+-se':>7}  {'zeta [%]':>8}  {'+-se':>6}  {'MPC':>5}  {'MPD':>5}")
    for k in range(ds.sizes["mode"]):
        print(f"{int(ds.mode[k]):>4}  {float(ds.frequency[k]):>9.4f}  {float(ds.frequency_se[k]):>7.4f}  "
              f"{100 * float(ds.damping_ratio[k]):>8.3f}  {100 * float(ds.damping_ratio_se[k]):>6.3f}  "
              f"{float(ds.MPC[k]):>5.2f}  {float(ds.MPD[k]):>5.1f}")  # fmt: skip
    print("se: standard error of the mean over the samples; MPC: modal phase collinearity (1 for a standing mode, "
          "0 for a circular whirl seen by an x-y pair); MPD: mean phase deviation [deg] (0 standing, 45 circular)")
    if plot is not None:
        from twin.extract.plot import plot_stabilisation
        from twin.report.figures import pyplot

        pyplot()  # figures for files, no window

        plot_stabilisation(ds).savefig(plot, dpi=120)
        print(f"wrote {plot}")
    print(f"wrote {args.output}")
    return 0


def _synthesize_modes(args: argparse.Namespace) -> int:
    from twin.modes.modesfile import write_modes
    from twin.fem import load_model
    from twin.fem.truthfile import load_truth
    from twin.update import synthesize_modes

    model = load_model(args.model)
    truth = load_truth(args.truth, model)
    ds = synthesize_modes(model, truth, samples=args.samples, seed=args.seed, n_modes=args.modes,
                          command=" ".join(sys.argv))  # fmt: skip
    write_modes(ds, args.output)
    print(f"{ds.sizes['mode']} modes x {ds.sizes['sample']} samples ({truth.source}); wrote {args.output}")
    return 0


def _params(args: argparse.Namespace) -> int:
    """``twin params``: the names ``--params`` and ``--effect`` take, with values, units and bounds."""
    import numpy as np

    from twin.cli.loop import _model_with_effects
    from twin.fem.effects import describe, effect_label
    from twin.loop.candidates import candidates as library_candidates
    from twin.update.problem import PARAMETER_GROUPS

    model = _model_with_effects(args.model, args.effect)
    groups = {n: g for g, f in PARAMETER_GROUPS.items() for n in f(model)}
    def finite(x: float) -> float | None:
        return float(x) if np.isfinite(x) else None  # JSON has no infinity: an open side is null

    rows = [{"name": p.name, "nominal": p.nominal, "unit": p.unit, "group": groups.get(p.name, "effects"),
             "low": finite(p.bounds[0]), "high": finite(p.bounds[1]), "bounds": p.bounds_text() or "either sign",
             "description": p.description} for p in model.parameters]  # fmt: skip
    effects = [describe(e, model) for e in model.effects]
    library = library_candidates(model)
    candidates = [describe(c.effect, model) for c in library]
    if args.json:
        print(json.dumps({"model": model.name, "n_dof": model.n_dof, "speed_rpm": model.speed_rpm,
                          "channels": list(model.channels), "parameters": rows, "groups": list(PARAMETER_GROUPS),
                          "effects": [effect_label(e) for e in model.effects],
                          "library": [c.label for c in library]}, indent=2))  # fmt: skip
        return 0
    print(f"{model.name}: {model.n_dof} DOF, {model.speed_rpm:g} rpm, sensors {', '.join(model.channels)}")
    print(f"\n{len(rows)} parameters (SI units; --params takes names, globs such as 'LGB.c*', or the groups "
          f"{', '.join(PARAMETER_GROUPS)}):")  # fmt: skip
    print(f"  {'name':<26} {'nominal':>11} {'unit':<10} {'group':<9} {'bounds':<16} description")
    for r in rows:
        print(f"  {r['name']:<26} {r['nominal']:>11.4g} {r['unit']:<10} {r['group']:<9} {r['bounds']:<16} "
              f"{r['description']}")  # fmt: skip
    print("\neffects of the model: " + ("none" if not effects else ""))
    for text in effects:
        print(f"  {text}")
    print("\nlibrary effects it can take (--effect LABEL adds one; the label is the text before the colon):")
    for text in candidates:
        print(f"  {text}")
    return 0
