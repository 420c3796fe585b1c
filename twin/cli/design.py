"""The ``twin observe`` sub-command: what a sensor layout and a record can determine, before any data."""

from __future__ import annotations

import argparse
import json
import sys

from twin.cli.common import COUNT, add_design_inputs, command


def observe_text(obs, ident=None) -> str:
    """The observability table (and the identifiability table when given) as text."""
    import numpy as np

    from twin.design.observe import CLUSTER_SIGMAS, cluster_text

    ex = json.loads(obs.attrs["excitation"])
    lines = [
        f"{obs.attrs['model']}: {obs.sizes['mode']} target modes, {obs.sizes['channel']} channels, "
        f"{ex['duration_s']:g} s at {ex['fs_hz']:g} Hz, noise std {ex['noise_std_m']:.3g} m",
        f"{'mode':>4} {'f [Hz]':>8} {'zeta %':>7} {'best SNR dB':>11} {'vs others dB':>12} {'std f %':>8} "
        f"{'std zeta %':>10}  "
        f"{'best channel':<12} verdict",
    ]
    for i in range(obs.sizes["mode"]):
        r = obs.isel(mode=i)
        f, z = float(r.frequency), float(r.damping_ratio)
        channel = str(obs.channel.values[int(np.argmax(r.snr_db.values))])
        verdict = "observable" if bool(r.observable) else f"not observable: {str(r.reason.values)}"
        if "cluster" in r and int(r.cluster):
            verdict += f" [cluster {int(r.cluster)}]"
        lines.append(
            f"{int(r.mode):4d} {f:8.2f} {100 * z:7.2f} {float(r.best_snr_db):11.1f} "
            f"{float(r.best_prominence_db):12.1f} "
            f"{100 * float(r.frequency_std) / f:8.3g} {100 * float(r.damping_ratio_std) / z:10.3g}  "
            f"{channel:<12} {verdict}"
        )
    lines.append(
        f"{int(obs.observable.sum())} of {obs.sizes['mode']} target modes observable ({obs.attrs['rule']}); "
        "std: single-mode Whittle bound (what SSI reaches, about 2x in practice); vs others: the "
        "mode's peak against the other modes' response and the noise at its frequency (best channel)"
    )
    for label in sorted(set(obs.cluster.values.tolist()) - {0}) if "cluster" in obs else []:
        lines.append(
            f"cluster {label}: {cluster_text(obs.frequency.values[obs.cluster.values == label])}, and "
            f"their frequencies are closer than {obs.attrs.get('cluster_sigmas', CLUSTER_SIGMAS):g} rss stds: the record "
            "cannot tell them apart by frequency; the extraction reports them as one cluster"
        )
    if ident is not None:
        lines += [
            "",
            f"expected posterior std of the parameters ({ident.attrs['method']}; modes used "
            f"{ident.attrs['modes_used']}):",
            f"{'parameter':<24} {'scale':>10} {'std':>10} {'std %':>8}  verdict",
        ]
        for p in ident.parameter.values:
            r = ident.sel(parameter=p)
            lines.append(
                f"{p:<24} {float(r.scale):10.3g} {float(r['std']):10.3g} {100 * float(r.relative_std):8.3g}  "
                f"{'determined' if bool(r.determined) else 'NOT determined'}"
            )
        lines.append(
            f"{int(ident.determined.sum())} of {ident.sizes['parameter']} parameters determined "
            f"(std below 10% of the scale: |nominal|, or the effect's plausible size)"
        )
    return "\n".join(lines)


def _inputs(args: argparse.Namespace):
    """The model, truth, excitation and parameter names ``observe`` and ``sensors`` share."""
    from twin.design import Excitation
    from twin.fem import load_model
    from twin.fem.truthfile import load_truth
    from twin.update.problem import select_parameters

    model = load_model(args.model)
    truth = None if args.truth is None else load_truth(args.truth, model)
    excitation = Excitation(
        turbulence_asd=args.turbulence,
        noise_ratio=args.noise,
        noise_std_m=args.noise_std,
        duration_s=args.duration,
        fs_hz=args.fs,
    )
    names = select_parameters(model, args.params) if args.params else []
    return model, truth, excitation, names


def _observe(args: argparse.Namespace) -> int:
    from twin.design import identifiability, observability

    model, truth, excitation, names = _inputs(args)
    command = " ".join(sys.argv)
    obs = observability(model, excitation, truth=truth, fmax_hz=args.fmax, command=command)
    ident = None
    if args.params or args.fsi:
        ident = identifiability(
            model,
            names,
            fsi=args.fsi,
            excitation=excitation,
            truth=truth,
            observability=obs,
            fmax_hz=args.fmax,
            command=command,
        )
    if args.output:
        from twin.netcdf import write_netcdf

        write_netcdf(obs, args.output)
    print(observe_text(obs, ident))
    return 0


def sensors_text(design) -> str:
    """A sensor design (:func:`twin.design.design_sensors`) as text: the pairs with their gains, then per mode."""
    from twin.design.identify import DETERMINED_LIMIT  # here, not at import: the command line starts fast
    from twin.design.observe import PROMINENCE_LIMIT_DB, SNR_LIMIT_DB

    judged = "relative_std" in design
    lines = [
        f"{design.attrs['model']}: {design.sizes['mode']} target modes; sensor noise std "
        f"{design.attrs['noise_std_m']:.3g} m on every sensor",
        f"{'step':>4} {'node':>5} {'sensor':<8} {'observable':>10} {'gain':>5}"
        + (f" {'determined':>10} {'gain':>5}" if judged else "")
        + f" {'criterion':>9} {'gain':>7}  location",
    ]
    for i in range(design.sizes["step"]):
        r = design.isel(step=i)
        prev = design.isel(step=max(i - 1, 0))
        node = "now" if i == 0 else str(int(r.node))
        row = f"{i:4d} {node:>5} {str(r.sensor.values):<8} {int(r.n_observable):10d} {int(r.n_observable - prev.n_observable):+5d}"
        if judged:
            row += f" {int(r.n_determined):10d} {int(r.n_determined - prev.n_determined):+5d}"
        row += f" {float(r.criterion):9.3f} {float(r.criterion - prev.criterion):+7.3f}  {str(r.location.values)}"
        lines.append(row)
    last = design.isel(step=-1)
    lines += [
        "",
        f"{'mode':>4} {'f [Hz]':>8} {'now':>4} {'after':>5} {'std f %':>8} {'std zeta %':>10} "
        f"{'SNR dB':>7}  where seen best (any candidate)",
    ]
    for k in range(design.sizes["mode"]):
        now, after = bool(design.observable[0, k]), bool(last.observable[k])
        best = f"node {int(design.best_node[k])}: {float(design.best_node_snr_db[k]):.0f} dB"
        if not after and float(design.best_node_snr_db[k]) < SNR_LIMIT_DB:
            best += f"; {SNR_LIMIT_DB:g} dB there with a noise std <= {float(design.noise_std_needed_m[k]):.2g} m"
        if not after and float(design.most_prominent_db[k]) < PROMINENCE_LIMIT_DB:
            best += (
                f"; masked at every node by the other modes' response, whatever the noise (at best "
                f"{float(design.most_prominent_db[k]):.1f} dB, node {int(design.most_prominent_node[k])})"
            )
        lines.append(
            f"{k + 1:4d} {float(design.frequency[k]):8.2f} {'yes' if now else 'no':>4} "
            f"{'yes' if after else 'no':>5} {100 * float(last.frequency_rel_std[k]):8.3g} "
            f"{100 * float(last.damping_rel_std[k]):10.3g} {float(last.best_snr_db[k]):7.1f}  {best}"
        )
    if judged:
        lines += ["", f"{'parameter':<24} {'std % now':>10} {'after':>8}"]
        for j, p in enumerate(design.parameter.values):
            a, b = float(design.relative_std[0, j]), float(last.relative_std[j])
            lines.append(
                f"{p:<24} {100 * a:10.3g} {100 * b:8.3g}  {'determined' if b < DETERMINED_LIMIT else 'NOT determined'}"
            )
    return "\n".join(lines)


def _sensors(args: argparse.Namespace) -> int:
    from twin.design.sensors import design_sensors, write_layout
    from twin.errors import ModelError
    from twin.netcdf import check_writable

    model, truth, excitation, names = _inputs(args)
    candidates = None
    if args.candidates:
        try:
            candidates = [int(c) for c in args.candidates.split(",") if c.strip()]
        except ValueError as exc:
            raise ModelError(
                f"--candidates: expected node numbers separated by commas, got '{args.candidates}'"
            ) from exc
    check_writable(args.output)
    if args.design:
        check_writable(args.design)
    design = design_sensors(
        model,
        args.add,
        candidates=candidates,
        names=names,
        fsi=args.fsi,
        excitation=excitation,
        truth=truth,
        fmax_hz=args.fmax,
        command=" ".join(sys.argv),
    )
    write_layout(model, design, args.output)
    if args.design:
        from twin.netcdf import write_netcdf

        write_netcdf(design, args.design)
    print(sensors_text(design))
    print(f"wrote {args.output} (simulate it with --noise-std {design.attrs['noise_std_m']:.4g} for the same sensors)")
    return 0


def add_commands(sub) -> None:
    """Add this module's sub-commands to the sub-parsers ``sub``."""
    p = command(
        sub,
        "observe",
        "which modes and parameters a sensor layout and record can determine",
        "Before any measurement: per target mode (damped less than 10%, up to --fmax) the peak response\n"
        "against the sensor noise on each channel, the expected standard error of its frequency and\n"
        "damping from SSI on such a record (theory: the Whittle likelihood of the output spectrum), and\n"
        "whether it is observable. With --params/--fsi, the expected posterior std of those parameters\n"
        "from the observable modes' poles and shapes (Fisher information), and whether each is determined.",
        [
            "twin observe hydro_unit",
            "twin observe hydro_unit --duration 3600 --params bearings --fsi --truth paper",
            "twin observe hydro_unit -o observability.nc",
        ],
        _observe,
    )
    add_design_inputs(p)
    p.add_argument("-o", "--output", default=None, help="write the observability table (NetCDF: mode x channel)")
    p = command(
        sub,
        "sensors",
        "where to add proximeter pairs so the target modes and parameters are determined",
        "Greedy sensor design: adds one x-y pair at a time at the candidate node that makes the most\n"
        "target modes observable, then (with --params/--fsi) the most parameters determined, then ranks\n"
        "best on the D-optimal criterion; prints each pair's gain and, for modes no node can make\n"
        "observable, where they are seen best and the sensor noise that would do. Writes the model file\n"
        "with the added [[sensor]] entries; the sensors keep the current layout's noise std [m].",
        [
            "twin sensors hydro_unit --add 2 -o unit_10.toml",
            "twin sensors hydro_unit --add 3 --params bearings --fsi --truth paper --duration 3600 -o unit.toml",
            "twin sensors hydro_unit --add 1 --candidates 12,16,20 -o unit.toml --design design.nc",
        ],
        _sensors,
    )
    add_design_inputs(p)
    p.add_argument("--add", type=COUNT, required=True, help="number of proximeter pairs (x and y) to add")
    p.add_argument(
        "--candidates",
        default=None,
        help="nodes a pair may go to, comma-separated (default: every node without a sensor)",
    )
    p.add_argument("-o", "--output", required=True, help="model file to write: the model with the added sensors")
    p.add_argument("--design", default=None, help="also write the design, step by step (NetCDF)")
