"""The ``twin`` sub-commands of the model (stage 1): its modes, its Campbell diagram, its parameters and effects,
and a model file from a ROSS rotor."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from twin.cli.common import (
    COUNT,
    MODAL_MODES,
    MODEL_HELP,
    NONNEGATIVE,
    POSITIVE,
    add_effect,
    command,
    model_with_effects,
)
from twin.errors import TwinError


def _modal(args: argparse.Namespace) -> int:
    import numpy as np

    from twin.fem import load_model
    from twin.modes import modal
    from twin.modes.analysis import LIGHT_DAMPING, modes_json

    model = load_model(args.model)
    every = modal(model, speed_rpm=args.speed)
    chosen = every if args.fmax is None else every.sel(mode=every.frequency.values <= args.fmax)
    if args.json:
        print(json.dumps(modes_json(chosen.isel(mode=slice(0, args.modes))), indent=2))
        return 0
    listed = modes_json(chosen)["modes"]
    light = [m for m in listed if m["damping_ratio"] < LIGHT_DAMPING]
    heavy = [m for m in listed if m["damping_ratio"] >= LIGHT_DAMPING]
    rows = MODAL_MODES if args.modes is None else args.modes
    light, heavy = light[:rows], heavy[: max(rows - len(light), 0)]
    hidden = []
    if len(light) + len(heavy) < len(listed):
        hidden.append(f"{len(listed) - len(light) - len(heavy)} more: --modes N")
    if len(chosen.mode) < len(every.mode):
        hidden.append(f"{len(every.mode) - len(chosen.mode)} above {args.fmax:g} Hz")
    rates = np.atleast_1d(every.attrs["overdamped_rates"])
    if len(rates):
        hidden.append(
            f"{len(rates)} over-damped eigenvalues, no modes (decay rates {rates.min():.3g} to {rates.max():.3g} 1/s)"
        )
    print(
        f"{model.name}: {model.n_dof} DOF, {every.attrs['speed_rpm']:g} rpm, {len(every.mode)} modes"
        + (f"; not listed: {'; '.join(hidden)}" if hidden else "")
    )
    print(f"{'mode':>4}  {'f [Hz]':>10}  {'fn [Hz]':>10}  {'zeta [%]':>8}  {'log dec':>8}  {'whirl':<8}  stable")
    for group, title in ((light, None), (heavy, f"damped {100 * LIGHT_DAMPING:g}% or more:")):
        if group and title:
            print(title)
        for m in group:
            print(
                f"{m['mode']:>4}  {m['frequency_hz']:>10.4f}  {m['natural_frequency_hz']:>10.4f}  "
                f"{100 * m['damping_ratio']:>8.3f}  {m['log_decrement']:>8.4f}  {m['whirl']:<8}  "
                f"{'yes' if m['stable'] else 'NO'}"
            )
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


def _from_ross(args: argparse.Namespace) -> int:
    """``twin from-ross``: a ROSS rotor file as a twin model file, checked by reading it back."""
    from twin.fem.modelfile import model_from_dict
    from twin.fem.ross import read_ross, ross_model_text
    from twin.netcdf import atomic_output

    data = read_ross(args.rotor, args.speed, name=args.name, sensors=not args.no_sensors)
    model = model_from_dict(data, source=args.rotor)
    with atomic_output(args.output, ".toml.part") as tmp:
        Path(tmp).write_text(ross_model_text(data, Path(args.rotor).name), encoding="utf-8")
    print(
        f"{args.output}: model '{model.name}' at {model.speed_rpm:g} rpm, {model.n_nodes} nodes, "
        f"{len(model.disks)} disks, {len(model.bearings)} bearings; channels {', '.join(model.channels) or 'none'}"
    )
    return 0


def _params(args: argparse.Namespace) -> int:
    """``twin params``: the names ``--params`` and ``--effect`` take, with values, units and bounds."""
    from twin.fem.effects import describe
    from twin.loop.candidates import candidates as library_candidates
    from twin.loop.candidates import parameters_json
    from twin.update.problem import PARAMETER_GROUPS

    model = model_with_effects(args.model, args.effect)
    out = parameters_json(model)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    rows = out["parameters"]
    effects = [describe(e, model) for e in model.effects]
    candidates = [describe(c.effect, model) for c in library_candidates(model)]
    print(f"{model.name}: {model.n_dof} DOF, {model.speed_rpm:g} rpm, sensors {', '.join(model.channels)}")
    on = model.physics
    flags = ", ".join(
        f"{label} {'on' if on[key] is True else 'off' if on[key] is False else 'on some elements'}"
        for key, label in (
            ("shear_deformation", "shear deformation (Timoshenko)"),
            ("rotary_inertia", "rotary inertia"),
            ("gyroscopic", "gyroscopic coupling"),
        )
    )
    print(
        f"shaft: {len(model.shaft)} elements, {flags}; structural damping {on['shaft_mass_proportional']:g} M + "
        f"{on['shaft_stiffness_proportional']:g} K"
    )
    glob = f"'{model.bearings[0].name}.c*'" if model.bearings else "'*.m'"
    print(
        f"\n{len(rows)} parameters (SI units; --params takes names, globs such as {glob}, or the groups "
        f"{', '.join(PARAMETER_GROUPS)}):"
    )
    print(f"  {'name':<26} {'nominal':>11} {'unit':<10} {'group':<9} {'bounds':<16} description")
    for r in rows:
        print(
            f"  {r['name']:<26} {r['nominal']:>11.4g} {r['unit']:<10} {r['group']:<9} {r['bounds']:<16} "
            f"{r['description']}"
        )
    print("\neffects of the model: " + ("none" if not effects else ""))
    for text in effects:
        print(f"  {text}")
    print("\nlibrary effects it can take (--effect LABEL adds one; the label is the text before the colon):")
    for text in candidates:
        print(f"  {text}")
    from twin.fem.excitation import machine_excitation

    print("\nexcitation (the model file's [excitation], or derived from the machine):")
    for line in machine_excitation(model).describe().splitlines():
        print(f"  {line}")
    return 0


def add_commands(sub) -> None:
    """Add this module's sub-commands to the sub-parsers ``sub``."""
    p = command(
        sub,
        "modal",
        "complex modes of a model at a speed",
        "Frequency, damping ratio, log decrement and whirl of every mode (the oscillating eigenvalues of the\n"
        "state-space eigenproblem of M, C + Omega G, K): the lightly damped ones first, lowest frequency first,\n"
        "then those damped 20% or more (an amplification factor below API 684's 2.5); the over-damped\n"
        "eigenvalues are counted, not listed.",
        ["twin modal hydro_unit", "twin modal models/ross_reference.toml --speed 0 --modes 4 --json"],
        _modal,
    )
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("--speed", type=NONNEGATIVE, default=None, help="speed [rpm] (default: the model's running speed)")
    p.add_argument(
        "--modes",
        type=COUNT,
        default=None,
        help=f"number of modes, lowest first (default: {MODAL_MODES} in the table, all in the JSON)",
    )
    p.add_argument("--fmax", type=POSITIVE, default=None, help="list only the modes up to this damped frequency [Hz]")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table (every mode unless limited)")
    p = command(
        sub,
        "campbell",
        "Campbell diagram of a model over a speed range",
        "Frequencies of the first modes against speed, forward and backward whirl, with the 1X line.",
        ["twin campbell hydro_unit -o campbell.png --max-speed 300"],
        _campbell,
    )
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("--max-speed", type=POSITIVE, default=None, help="highest speed [rpm] (default: 2x running speed)")
    p.add_argument("--points", type=COUNT, default=41, help="number of speeds")
    p.add_argument("--modes", type=COUNT, default=12, help="number of modes followed")
    p.add_argument("-o", "--output", default="campbell.png", help="figure file (.png, .pdf or .svg)")
    p = command(
        sub,
        "from-ross",
        "a model file from a rotor saved by ROSS",
        "Reads a ROSS Rotor.save file (TOML; ROSS itself is not needed) and writes a twin model file at a\n"
        "running speed: shaft sections, materials, disks, bearings and seals with their coefficients at that\n"
        "speed, the shaft's switches and proportional damping, and a proximeter pair at each bearing. Add\n"
        "regions, the excitation and operating conditions to it (the model-file reference lists them).",
        ["twin from-ross compressor.toml --speed 9000 -o compressor_twin.toml"],
        _from_ross,
    )
    p.add_argument("rotor", help="the file ROSS's Rotor.save wrote (TOML)")
    p.add_argument("--speed", type=NONNEGATIVE, required=True, help="running speed [rpm]")
    p.add_argument("-o", "--output", required=True, help="the model file to write (TOML)")
    p.add_argument("--name", default=None, help="the model's name (default: the ROSS file's name)")
    p.add_argument("--no-sensors", action="store_true", help="no proximeter pairs at the bearings")
    p = command(
        sub,
        "params",
        "the parameters and effects of a model",
        "Every parameter (name, nominal value, unit, physical bounds, what it is), the effects the model\n"
        "has, and the library effects it can take with the parameters each brings: the names that\n"
        "twin update --params and --effect take.",
        ["twin params hydro_unit", "twin params hydro_unit --effect magnetic_pull --json"],
        _params,
    )
    p.add_argument("model", help=MODEL_HELP)
    add_effect(p)
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
