"""The ``twin`` sub-commands of the FMU, extraction and synthetic-data stages (stages 2-3)."""

from __future__ import annotations

import argparse
import json
import sys

from twin.cli.common import (
    COUNT,
    MODEL_HELP,
    NATURAL,
    NONNEGATIVE,
    POSITIVE,
    TRUTH_HELP,
    add_algorithm,
    add_record,
    command,
    rows_or_auto,
)
from twin.defaults import (
    MAX_ORDER,
    ORDERS_PER_MODE,
    SAMPLES,
    SAMPLING_RATE_HZ,
    SYNTHETIC_SAMPLES,
)
from twin.errors import TwinError


def _export_fmu(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.fmu import export_fmu

    if not args.fs > 0:
        raise TwinError(f"--fs must be positive, got {args.fs:g}")
    model = load_model(args.model)
    inputs = None if args.inputs is None else [s.strip() for s in args.inputs.split(",") if s.strip()]
    path = export_fmu(
        model,
        args.output,
        step_s=1.0 / args.fs,
        basis=args.basis,
        fmax_hz=args.fmax,
        inputs=inputs,
        kind=args.kind,
        fmi_version=args.fmi,
    )
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
        simulate(
            model,
            duration_s=args.duration,
            fs_hz=args.fs,
            seed=args.seed,
            truth=truth,
            turbulence_asd=args.turbulence,
            unbalance_me=args.unbalance,
            noise_ratio=args.noise,
            noise_std_m=args.noise_std,
            basis=args.basis,
            fmax_hz=args.fmax,
            output=args.output,
            command=" ".join(sys.argv),
        )
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
    ds = import_record(
        args.file,
        fs_hz=args.fs,
        units=per_channel(args.units, "--units"),
        quantities=per_channel(args.quantity, "--quantity"),
        channels=channels,
    )
    ds.attrs["command"] = " ".join(sys.argv)
    write_netcdf(ds, args.output)
    described = ", ".join(
        f"{c} ({q}, {u})" for c, q, u in zip(ds["channel"].values, ds["quantity"].values, ds["units"].values)
    )
    print(f"{ds.sizes['time']} samples at {ds.attrs['sampling_rate']:g} Hz of {described}; wrote {args.output}")
    return 0


def _extract(args: argparse.Namespace) -> int:
    from twin.design.observe import judge_targets
    from twin.extract import extract
    from twin.extract.harmonics import line_frequencies
    from twin.extract.options import ExtractOptions
    from twin.modes import write_modes
    from twin.netcdf import check_writable

    plot = None if args.plot is None else check_writable(args.plot, figure=True)
    channels = None if args.channels is None else [c.strip() for c in args.channels.split(",") if c.strip()]
    options = ExtractOptions(
        samples=args.samples,
        fmax_hz=args.fmax,
        fmin_hz=args.fmin,
        block_rows=args.block_rows,
        shape_block_rows=args.shape_block_rows,
        first_lag=args.first_lag,
        max_order=args.max_order,
        channels=channels,
        delete_blocks=None if args.delete_half else 1,
        order_spread=args.order_spread,
        remove_harmonics=args.remove_harmonics,
        blocks=args.blocks,
        orders_per_mode=args.orders_per_mode or None,
        differenced_above_hz=args.differenced_above,
        shape_samples=args.shape_samples,
        algorithm=args.algorithm,
    )
    ds = judge_targets(extract(args.signals, options, command=" ".join(sys.argv)), args.signals)
    write_modes(ds, args.output)  # -o is required, and checked before the command ran (twin.cli._check_outputs)
    removed, rejected = (", ".join(f"{f:.3f}" for f in fs) for fs in line_frequencies(ds.attrs["harmonics"]))
    chosen = json.loads(ds.attrs["settings"]).get("blocks_chosen")
    if chosen:
        print(f"jackknife: {chosen}")
    print(
        f"{ds.sizes['mode']} modes, {ds.sizes['sample']} samples each"
        + (f"; running-speed lines removed at {removed} Hz" if removed else "")
        + (f"; harmonics rejected at {rejected} Hz" if rejected else "")
    )
    print(f"{'mode':>4}  {'f [Hz]':>9}  {'+-se':>7}  {'zeta [%]':>8}  {'+-se':>6}  {'MPC':>5}  {'MPD':>5}")
    for k in range(ds.sizes["mode"]):
        print(
            f"{int(ds.mode[k]):>4}  {float(ds.frequency[k]):>9.4f}  {float(ds.frequency_se[k]):>7.4f}  "
            f"{100 * float(ds.damping_ratio[k]):>8.3f}  {100 * float(ds.damping_ratio_se[k]):>6.3f}  "
            f"{float(ds.MPC[k]):>5.2f}  {float(ds.MPD[k]):>5.1f}"
        )
    print(
        "se: standard error of the mean over the samples; MPC: modal phase collinearity (1 for a standing mode, "
        "0 for a circular whirl seen by an x-y pair); MPD: mean phase deviation [deg] (0 standing, 45 circular)"
    )
    if plot is not None:
        from twin.extract.plot import plot_stabilisation
        from twin.report.figures import pyplot

        pyplot()  # figures for files, no window

        plot_stabilisation(ds).savefig(plot, dpi=120)
        print(f"wrote {plot}")
    print(f"wrote {args.output}")
    return 0


def _synthesize_modes(args: argparse.Namespace) -> int:
    from twin.fem import load_model
    from twin.fem.truthfile import load_truth
    from twin.modes.modesfile import write_modes
    from twin.update import synthesize_modes

    model = load_model(args.model)
    truth = load_truth(args.truth, model)
    ds = synthesize_modes(
        model, truth, samples=args.samples, seed=args.seed, n_modes=args.modes, command=" ".join(sys.argv)
    )
    write_modes(ds, args.output)
    print(f"{ds.sizes['mode']} modes x {ds.sizes['sample']} samples ({truth.source}); wrote {args.output}")
    return 0


def add_commands(sub) -> None:
    """Add this module's sub-commands to the sub-parsers ``sub``."""
    p = command(
        sub,
        "export-fmu",
        "export the model as an FMU (FMI 2.0 or 3.0, co-simulation and model exchange)",
        "Writes the model's modal form into an FMU with the generic runtime (compiled once per machine;\n"
        "needs a C compiler, gcc or cc); forces at the disks are its inputs, the proximeter displacements\n"
        "its outputs, the modal coordinates its states.",
        [
            "twin export-fmu hydro_unit -o unit.fmu",
            "twin export-fmu hydro_unit -o unit.fmu --basis modal --fmax 120",
            "twin export-fmu hydro_unit -o unit3.fmu --fmi 3 --kind me",
        ],
        _export_fmu,
    )
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("-o", "--output", required=True, help="FMU file to write")
    p.add_argument("--fs", type=POSITIVE, default=SAMPLING_RATE_HZ, help="sampling rate = 1 / communication step [Hz]")
    p.add_argument(
        "--basis",
        choices=("full", "modal"),
        default="full",
        help="the full FEM, or a truncated basis of its modes below --fmax",
    )
    p.add_argument(
        "--fmax",
        type=POSITIVE,
        default=None,
        help="highest mode kept by the modal basis [Hz] (required with --basis modal)",
    )
    p.add_argument(
        "--inputs", default=None, help="force inputs, e.g. runner.x,runner.y,12.x (default: x, y at every disk)"
    )
    p.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version (default 2)")
    p.add_argument(
        "--kind",
        choices=("both", "cs", "me"),
        default="both",
        help="interfaces: co-simulation, model exchange or both (default both)",
    )
    p = command(
        sub,
        "simulate",
        "simulate proximeter signals through the model's FMU",
        "The machine's excitation (its model file's [excitation], or derived from the machine: a 1X\n"
        "unbalance and broad-band process forces) and sensor noise drive the FMU (through FMPy); the\n"
        "proximeter displacements are written as signals.nc (time x channel, metres).",
        [
            "twin simulate hydro_unit --duration 1200 -o signals.nc",
            "twin simulate hydro_unit --duration 600 --truth paper --seed 3 -o signals.nc",
        ],
        _simulate,
    )
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (signals.nc)")
    add_record(p, duration_required=True)
    p.add_argument("--seed", type=NATURAL, default=1, help="random seed of turbulence and noise")
    p.add_argument("--truth", default=None, help=f"what the truth hides: {TRUTH_HELP} (default: none)")
    p.add_argument(
        "--unbalance",
        type=NONNEGATIVE,
        default=None,
        help="1X unbalance [kg m] (default: the machine's, from its model file's [excitation] or balance grade G2.5)",
    )
    p.add_argument(
        "--basis",
        choices=("full", "modal"),
        default="full",
        help="the full FEM, or a truncated basis of its modes below --fmax",
    )
    p.add_argument(
        "--fmax", type=POSITIVE, default=None, help="highest mode of the modal basis [Hz] (required with --basis modal)"
    )
    p = command(
        sub,
        "import",
        "a measurement file (CSV/text, UFF 58, TDMS, MATLAB, HDF5) into signals.nc",
        "Reads the channels, their units and the time (or the rate) from the file, works out each\n"
        "channel's quantity from its units (um: displacement, mm/s: velocity, g: acceleration), checks\n"
        "the record as the extraction will and writes it as signals.nc (variable 'signal').",
        [
            "twin import probes.csv -o signals.nc",
            "twin import probes.txt -o signals.nc --fs 256 --units um --channels UGB_x,UGB_y",
            "twin import run.tdms -o signals.nc",
            "twin import test.mat -o signals.nc --units mm/s",
        ],
        _import,
    )
    p.add_argument(
        "file",
        help="the measurement file, read by its suffix: .csv, .txt, .tsv or .dat with a header "
        "line of column names (units as 'UGB_x [um]'; a column 'time [s]', or "
        "'# sampling_rate: 256' above); .uff/.unv (dataset 58 time responses); .tdms; "
        ".mat; .h5/.hdf5 (see twin.extract.readers)",
    )
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (signals.nc)")
    p.add_argument("--fs", type=POSITIVE, default=None, help="sampling rate [Hz] where the file gives none")
    p.add_argument(
        "--units",
        default=None,
        metavar="U|NAME=U,...",
        help="units of every channel, or of some by name, where the header gives none (um, mil, mm/s, g, ...)",
    )
    p.add_argument(
        "--quantity",
        default=None,
        metavar="Q|NAME=Q,...",
        help="displacement, velocity or acceleration, for every channel or some by name (default: "
        "the quantity of its units)",
    )
    p.add_argument("--channels", default=None, help="new channel names in the file's order, e.g. UGB_x,UGB_y")
    p = command(
        sub,
        "extract",
        "automated modal extraction (SSI-cov or pLSCF) from signals to mode samples",
        "Covariance-driven stochastic subspace identification (or, --algorithm plscf, a frequency-domain\n"
        "fit of the covariances' half spectra) over model orders, a stabilisation diagram cleared\n"
        "automatically, harmonics of the running speed rejected; each mode's uncertainty from jackknife\n"
        "samples over blocks of the record (modes.nc).",
        ["twin extract signals.nc -o modes.nc --fmax 60 --plot stabilisation.png"],
        _extract,
    )
    p.add_argument("signals", help="signals file (NetCDF, time x channel, from twin simulate or a measurement)")
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (modes.nc)")
    p.add_argument(
        "--samples",
        type=COUNT,
        default=None,
        help=f"jackknife samples per mode J, one per block left out (default: {SAMPLES}, or as many "
        "blocks as a short record holds; the output says which)",
    )
    p.add_argument(
        "--blocks",
        type=COUNT,
        default=None,
        help="blocks the record is cut into (default: --samples; with --delete-half it may be fewer)",
    )
    p.add_argument("--fmax", type=POSITIVE, default=None, help="highest frequency [Hz] (default: 40%% of fs)")
    p.add_argument("--fmin", type=NONNEGATIVE, default=0.0, help="lowest frequency [Hz]")
    p.add_argument(
        "--block-rows", type=COUNT, default=None, help="Hankel block rows the poles are read at (default: from fmax)"
    )
    p.add_argument(
        "--shape-block-rows",
        type=rows_or_auto,
        default=0,
        help="block rows of a second pass every mode's shapes are read at (default 0: none, the "
        "shapes come with the poles); auto: the slow modes' shapes at lags over 1.5 periods of "
        "the slowest",
    )
    p.add_argument(
        "--first-lag",
        type=COUNT,
        default=None,
        help="lag the covariance Hankel matrix starts at, in samples (default: the first at or beyond "
        "one period of fmax; 1: the textbook matrix)",
    )
    p.add_argument(
        "--differenced-above",
        type=POSITIVE,
        default=None,
        metavar="HZ",
        help="read the modes above this frequency [Hz] from a second pass over the record differenced "
        "twice, where the slow, strong modes no longer fill the covariances (default: none)",
    )
    p.add_argument(
        "--shape-samples",
        type=COUNT,
        default=None,
        metavar="M",
        help="draw the shape samples from M random halves of the blocks (a multiple of --samples), "
        "the poles keeping their own samples, each used M / samples times (default: the shapes "
        "come with the poles)",
    )
    add_algorithm(p)
    p.add_argument("--max-order", type=COUNT, default=MAX_ORDER, help="largest model order")
    p.add_argument("--channels", default=None, help="channels to use, e.g. UGB_x,UGB_y (default: all)")
    p.add_argument("--plot", default=None, help="stabilisation diagram figure to write (PNG)")
    p.add_argument(
        "--delete-half",
        action="store_true",
        help="each sample leaves out half the blocks (a spread that matches independent records) "
        "instead of one (the default: wider, what the loop is calibrated to)",
    )
    p.add_argument(
        "--order-spread",
        choices=("shapes", "all", "none"),
        default=None,
        help="add each mode's model-order error to the shape samples (the standard error of the "
        "shape's mean over its orders; the default with ssi), to the pole samples too (their spread over "
        "the orders: all, the default with plscf) or to neither (none)",
    )
    p.add_argument(
        "--orders-per-mode",
        type=NATURAL,
        default=ORDERS_PER_MODE,
        help=f"average each mode over this many of its lowest settled model orders (default "
        f"{ORDERS_PER_MODE}; 0: all of them)",
    )
    p.add_argument(
        "--keep-harmonics",
        dest="remove_harmonics",
        action="store_false",
        help="leave the lines at the multiples of the record's running speed in the record (by "
        "default they are subtracted before SSI); they are then rejected as modes by their "
        "band kurtosis",
    )
    p = command(
        sub,
        "synthesize-modes",
        "paper-style synthetic modal data (noisy pole and shape samples)",
        "Samples of poles and partial mode shapes of a truth, with the reference paper's noise model:\n"
        "modal data without signals, for checking the updater.",
        ["twin synthesize-modes hydro_unit -o modes.nc --samples 100 --seed 7"],
        _synthesize_modes,
    )
    p.add_argument("model", help=MODEL_HELP + ", the calibrated FEM")
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (modes.nc)")
    p.add_argument("--truth", default="paper", help=f"what the truth hides: {TRUTH_HELP}")
    p.add_argument("--samples", type=COUNT, default=SYNTHETIC_SAMPLES, help="samples per mode J")
    p.add_argument("--seed", type=NATURAL, default=1, help="random seed")
    p.add_argument(
        "--modes",
        type=COUNT,
        default=None,
        help="number of modes, for a truth without per-mode effect (default: the truth's per-mode count, "
        "or every lightly damped mode of the model)",
    )
