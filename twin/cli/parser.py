"""The argument parser of the ``twin`` command: one sub-command per stage, each with a description and an example.

Every option's help states its default; ``-v``/``--quiet`` go before or
after the sub-command.
"""

from __future__ import annotations

import argparse
import math

from twin import __version__
from twin.cli import design, loop, stages, track
from twin.defaults import (CHAINS, DEFAULT_RECORDS, DEFAULT_TURBULENCE_ASD, DEFAULT_UNBALANCE_ME, DEMO_RECORDS, DRAWS,
                           GIBBS_BURN_IN, HMC_MIN_WARMUP, HMC_WARMUP, MAX_BATCHES, METHODS, ORDERS_PER_MODE, SAMPLES)

MODEL_HELP = ("model file (TOML), or the name of a shipped model: hydro_unit (every command), or ross_reference "
              "(ROSS's test rotor, for checking the FEM: unstable by design and without water, so not for simulate, "
              "synthesize-modes with the paper's truth, or the loop)")
MODES_HELP = "modes file (NetCDF: mode x sample x channel, from twin extract or twin synthesize-modes)"
#: What a truth file is, said where --truth is taken.
TRUTH_HELP = ("a truth file (TOML: one table per hidden effect, named as twin params names it, its keys the "
              "parameter names without their owner: [magnetic_pull] stiffness = -2e8 for MAG.stiffness, "
              "[\"bearing_change:UGB\"] stiffness_change = -1e8 for UGB.stiffness_change; values outside the "
              "physical bounds twin params lists are refused), 'paper' (the reference paper's Table 2 per-mode FSI) "
              "or 'none' (the model as it is)")


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions as written; every option's default appended unless its help states it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or not action.option_strings or action.default in (None, False, argparse.SUPPRESS):
            return text
        return f"{text} (default: %(default)s)"


def _common() -> argparse.ArgumentParser:
    """Options every sub-command takes as well (so ``twin demo -v`` works like ``twin -v demo``)."""
    p = argparse.ArgumentParser(add_help=False)
    p.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                   help="log each stage and its details")  # fmt: skip
    p.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                   help="no progress display (bars and stage lines); results and errors are still printed")
    return p


#: Modes ``twin modal`` lists by default, lowest first (a FEM has many more, up to kHz).
MODAL_MODES = 20


def number(kind: type = float, low: float = 0.0, strict: bool = False):
    """An argparse ``type``: a ``kind`` number at least ``low`` (above it when ``strict``), else a one-line error."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {'an integer' if kind is int else 'a number'}, got {text!r}") from None
        if not (value > low if strict else value >= low) or not math.isfinite(value):
            what = "an integer" if kind is int else "a finite number"
            raise argparse.ArgumentTypeError(f"must be {what} {'>' if strict else '>='} {low:g}, got {text}")
        return value

    parse.__name__ = kind.__name__
    return parse


#: Non-negative and positive numbers and counts for the options' ``type``.
NONNEGATIVE, POSITIVE, COUNT, NATURAL = number(), number(strict=True), number(int, 1), number(int, 0)


def rows_or_auto(text: str) -> int | str:
    """``--shape-block-rows``: a whole number of block rows, or ``auto`` (the argparse type of ``twin extract``
    and of the benchmarks' extraction options).

    Examples
    --------
    >>> rows_or_auto("350"), rows_or_auto("auto")
    (350, 'auto')
    """
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of block rows or 'auto', got {text!r}") from None


def _command(sub, name: str, summary: str, description: str, examples: list[str], func) -> argparse.ArgumentParser:
    """A sub-command with its one-line summary, a description, and examples in its help."""
    p = sub.add_parser(name, help=summary, description=f"{summary[0].upper()}{summary[1:]}.\n\n{description}",
                       epilog="examples:\n" + "\n".join(f"  {e}" for e in examples), formatter_class=_Formatter,
                       parents=[_common()])  # fmt: skip
    p.set_defaults(func=func)
    return p


def _add_scheduler(p: argparse.ArgumentParser, what: str, default: str = "local") -> None:
    p.add_argument("--scheduler", default=default, metavar="ADDRESS",
                   help=f"where the {what} run as Dask tasks: 'local' (a local cluster of worker processes), "
                        f"a scheduler address such as tcp://host:8786, or 'sync' (in this process)")  # fmt: skip
    p.add_argument("--workers", type=COUNT, default=None, help="workers of the local cluster (default: one per core)")


def _add_tolerance(p: argparse.ArgumentParser) -> None:
    p.add_argument("--tolerance", type=NONNEGATIVE, default=0.0,
                   help="relative pole uncertainty accepted as model-form error, added to the measurement's standard "
                        "error")  # fmt: skip


def _add_model_and_posterior(p: argparse.ArgumentParser) -> None:
    """The model, the measured modes, and what to do to the model first (compare, diagnose)."""
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("modes", help=MODES_HELP)
    p.add_argument("--effect", action="append", default=None, metavar="LABEL",
                   help="add a library effect to the model first (e.g. magnetic_pull); repeatable")
    p.add_argument("--posterior", default=None,
                   help="apply this posterior (posterior.nc of twin update or twin loop) first, with the effects it "
                        "was made with: the next round of the loop")  # fmt: skip
    p.add_argument("--estimate", choices=("map", "mean"), default="map", help="posterior point estimate")
    _add_tolerance(p)


def _add_bootstrap(p: argparse.ArgumentParser, default: int | None = None) -> None:
    """``--bootstrap``, the calibration of the last update on records simulated at its estimate (by default on
    ``default`` records, the loop's :data:`twin.defaults.DEFAULT_RECORDS` when None)."""
    default = DEFAULT_RECORDS if default is None else default

    p.add_argument("--bootstrap", type=NATURAL, default=None, metavar="R",
                   help="records to simulate through the FMU at the last update's estimate, to calibrate its spread "
                        "(twin.loop.bootstrap; about 12 s a 20-min record on one core; up to "
                        f"{MAX_BATCHES} x R when a mode came out of too few; on the Dask workers, within a sweep "
                        f"in its scenario's worker); default: {default} with --method hmc, none with "
                        "the other methods; 0: none")  # fmt: skip

def _add_method(p: argparse.ArgumentParser, what: str) -> None:
    """``--method``: one of the update's samplers, or the Laplace fit."""
    p.add_argument("--method", choices=METHODS, default=METHODS[0],
                   help=f"{what}: hmc, HMC on the marginal posterior (the default, calibrated on FMU records); "
                        "gibbs, the Gibbs sampler of the full APerCEM; paper, the reference paper's Gibbs sampler; "
                        "laplace, the Gaussian posterior of the pole fit inside the physical bounds (fast, blind to "
                        "shapes)")  # fmt: skip


def _add_chain_options(p: argparse.ArgumentParser) -> None:
    """The options every sampler takes (their defaults are the sampler's own: twin.update.samplers)."""
    p.add_argument("--draws", type=COUNT, default=None, help=f"draws kept per chain (default: {DRAWS})")
    p.add_argument("--chains", type=COUNT, default=None, help=f"number of chains (default: {CHAINS})")
    p.add_argument("--warmup", type=NATURAL, default=None,
                   help=f"iterations per chain before the draws kept (default: the sampler's: {HMC_WARMUP} warm-up "
                        f"iterations of HMC, at least {HMC_MIN_WARMUP}; {GIBBS_BURN_IN} burn-in sweeps of the Gibbs "
                        "samplers)")  # fmt: skip
    p.add_argument("--seed", type=NATURAL, default=None, help="random seed of the chains (default: fresh entropy)")


def _add_loop_settings(p: argparse.ArgumentParser, records: int | None = None) -> None:
    """The demo's record and model options, shared by ``demo`` and ``sweep``; ``records``: the default of
    ``--bootstrap`` (the loop's when None)."""
    p.add_argument("--duration", type=POSITIVE, default=1200.0, help="record length [s]")
    p.add_argument("--samples", type=COUNT, default=SAMPLES, help="jackknife samples per mode")
    p.add_argument("--model", default=None, help="the twin's model file (default: the shipped hydro_unit)")
    _add_method(p, "how each round updates the added effects")
    _add_bootstrap(p, records)


def _add_record(p: argparse.ArgumentParser, duration_required: bool) -> None:
    """The record and its excitation, as ``simulate`` makes it and ``observe`` judges it."""
    if duration_required:
        p.add_argument("--duration", type=POSITIVE, required=True, help="record length [s]")
    else:
        p.add_argument("--duration", type=POSITIVE, default=1200.0, help="record length [s]")
    p.add_argument("--fs", type=POSITIVE, default=256.0, help="sampling rate [Hz]")
    p.add_argument("--turbulence", type=NONNEGATIVE, default=DEFAULT_TURBULENCE_ASD,
                   help="one-sided ASD of the runner turbulence force [N/sqrt(Hz)]")
    p.add_argument("--noise", type=NONNEGATIVE, default=0.05,
                   help="sensor noise std as a fraction of the median channel RMS (0.05: 5%% of the typical signal)")
    p.add_argument("--noise-std", type=NONNEGATIVE, default=None,
                   help="sensor noise std [m] per sample, instead of --noise (the same sensors on another layout)")


def _add_design_inputs(p: argparse.ArgumentParser) -> None:
    """The model, record, truth and parameters ``observe`` and ``sensors`` judge."""
    p.add_argument("model", help=MODEL_HELP)
    _add_record(p, duration_required=False)
    p.add_argument("--fmax", type=POSITIVE, default=None, help="highest target frequency [Hz] (default: 100, at most 0.4 fs)")
    p.add_argument("--truth", default=None, help=f"judge a truth with hidden effects instead of the model: {TRUTH_HELP} "
                                                  "(default: none)")
    p.add_argument("--params", default=None,
                   help="parameters to judge: names, glob patterns or groups (bearings, thrust, disks), comma-separated")
    p.add_argument("--fsi", action="store_true", help="also judge per-mode added mass and damping of every observable mode")


def _add_stages(sub) -> None:

    p = _command(sub, "modal", "complex modes of a model at a speed",
                 "Frequency, damping ratio, log decrement and whirl of every under-damped mode (the state-space\n"
                 "eigenproblem of M, C + Omega G, K).",
                 ["twin modal hydro_unit", "twin modal models/ross_reference.toml --speed 0 --modes 4 --json"],
                 stages._modal)  # fmt: skip
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("--speed", type=NONNEGATIVE, default=None, help="speed [rpm] (default: the model's running speed)")
    p.add_argument("--modes", type=COUNT, default=MODAL_MODES, help="number of modes, lowest first")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")

    p = _command(sub, "campbell", "Campbell diagram of a model over a speed range",
                 "Frequencies of the first modes against speed, forward and backward whirl, with the 1X line.",
                 ["twin campbell hydro_unit -o campbell.png --max-speed 300"], stages._campbell)  # fmt: skip
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("--max-speed", type=POSITIVE, default=None, help="highest speed [rpm] (default: 2x running speed)")
    p.add_argument("--points", type=COUNT, default=41, help="number of speeds")
    p.add_argument("--modes", type=COUNT, default=12, help="number of modes followed")
    p.add_argument("-o", "--output", default="campbell.png", help="figure file (.png, .pdf or .svg)")

    p = _command(sub, "params", "the parameters and effects of a model",
                 "Every parameter (name, nominal value, unit, physical bounds, what it is), the effects the model\n"
                 "has, and the library effects it can take with the parameters each brings: the names that\n"
                 "twin update --params and --effect take.",
                 ["twin params hydro_unit", "twin params hydro_unit --effect magnetic_pull --json"], stages._params)  # fmt: skip
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("--effect", action="append", default=None, metavar="LABEL",
                   help="add a library effect first (e.g. magnetic_pull); repeatable")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")

    p = _command(sub, "observe", "which modes and parameters a sensor layout and record can determine",
                 "Before any measurement: per target mode (damped less than 10%, up to --fmax) the peak response\n"
                 "against the sensor noise on each channel, the expected standard error of its frequency and\n"
                 "damping from SSI on such a record (theory: the Whittle likelihood of the output spectrum), and\n"
                 "whether it is observable. With --params/--fsi, the expected posterior std of those parameters\n"
                 "from the observable modes' poles and shapes (Fisher information), and whether each is determined.",
                 ["twin observe hydro_unit", "twin observe hydro_unit --duration 3600 --params bearings --fsi --truth paper",
                  "twin observe hydro_unit -o observability.nc"], design._observe)  # fmt: skip
    _add_design_inputs(p)
    p.add_argument("-o", "--output", default=None, help="write the observability table (NetCDF: mode x channel)")

    p = _command(sub, "sensors", "where to add proximeter pairs so the target modes and parameters are determined",
                 "Greedy sensor design: adds one x-y pair at a time at the candidate node that makes the most\n"
                 "target modes observable, then (with --params/--fsi) the most parameters determined, then ranks\n"
                 "best on the D-optimal criterion; prints each pair's gain and, for modes no node can make\n"
                 "observable, where they are seen best and the sensor noise that would do. Writes the model file\n"
                 "with the added [[sensor]] entries; the sensors keep the current layout's noise std [m].",
                 ["twin sensors hydro_unit --add 2 -o unit_10.toml",
                  "twin sensors hydro_unit --add 3 --params bearings --fsi --truth paper --duration 3600 -o unit.toml",
                  "twin sensors hydro_unit --add 1 --candidates 12,16,20 -o unit.toml --design design.nc"],
                 design._sensors)  # fmt: skip
    _add_design_inputs(p)
    p.add_argument("--add", type=COUNT, required=True, help="number of proximeter pairs (x and y) to add")
    p.add_argument("--candidates", default=None,
                   help="nodes a pair may go to, comma-separated (default: every node without a sensor)")
    p.add_argument("-o", "--output", required=True, help="model file to write: the model with the added sensors")
    p.add_argument("--design", default=None, help="also write the design, step by step (NetCDF)")

    p = _command(sub, "export-fmu", "export the model as an FMU (FMI 2.0 or 3.0, co-simulation and model exchange)",
                 "Writes the model's modal form into an FMU with the generic runtime (compiled once per machine;\n"
                 "needs a C compiler, gcc or cc); forces at the disks are its inputs, the proximeter displacements\n"
                 "its outputs, the modal coordinates its states.",
                 ["twin export-fmu hydro_unit -o unit.fmu", "twin export-fmu hydro_unit -o unit.fmu --basis modal --fmax 120",
                  "twin export-fmu hydro_unit -o unit3.fmu --fmi 3 --kind me"],
                 stages._export_fmu)  # fmt: skip
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("-o", "--output", required=True, help="FMU file to write")
    p.add_argument("--fs", type=POSITIVE, default=256.0, help="sampling rate = 1 / communication step [Hz]")
    p.add_argument("--basis", choices=("full", "modal"), default="full",
                   help="the full FEM, or a truncated basis of its modes below --fmax")
    p.add_argument("--fmax", type=POSITIVE, default=None,
                   help="highest mode kept by the modal basis [Hz] (required with --basis modal)")
    p.add_argument("--inputs", default=None, help="force inputs, e.g. runner.x,runner.y,12.x (default: x, y at every disk)")
    p.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version (default 2)")
    p.add_argument("--kind", choices=("both", "cs", "me"), default="both",
                   help="interfaces: co-simulation, model exchange or both (default both)")

    p = _command(sub, "simulate", "simulate proximeter signals through the model's FMU",
                 "Turbulence on the runner, unbalance at the generator and sensor noise drive the FMU (through\n"
                 "FMPy); the proximeter displacements are written as signals.nc (time x channel, metres).",
                 ["twin simulate hydro_unit --duration 1200 -o signals.nc",
                  "twin simulate hydro_unit --duration 600 --truth paper --seed 3 -o signals.nc"], stages._simulate)  # fmt: skip
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (signals.nc)")
    _add_record(p, duration_required=True)
    p.add_argument("--seed", type=NATURAL, default=1, help="random seed of turbulence and noise")
    p.add_argument("--truth", default=None, help=f"what the truth hides: {TRUTH_HELP} (default: none)")
    p.add_argument("--unbalance", type=NONNEGATIVE, default=DEFAULT_UNBALANCE_ME, help="1X unbalance at the generator [kg m]")
    p.add_argument("--basis", choices=("full", "modal"), default="full",
                   help="the full FEM, or a truncated basis of its modes below --fmax")
    p.add_argument("--fmax", type=POSITIVE, default=None,
                   help="highest mode of the modal basis [Hz] (required with --basis modal)")

    p = _command(sub, "import", "a measurement file (CSV/text, UFF 58, TDMS, MATLAB, HDF5) into signals.nc",
                 "Reads the channels, their units and the time (or the rate) from the file, works out each\n"
                 "channel's quantity from its units (um: displacement, mm/s: velocity, g: acceleration), checks\n"
                 "the record as the extraction will and writes it as signals.nc (variable 'signal').",
                 ["twin import probes.csv -o signals.nc",
                  "twin import probes.txt -o signals.nc --fs 256 --units um --channels UGB_x,UGB_y",
                  "twin import run.tdms -o signals.nc", "twin import test.mat -o signals.nc --units mm/s"],
                 stages._import)  # fmt: skip
    p.add_argument("file", help="the measurement file, read by its suffix: .csv, .txt, .tsv or .dat with a header "
                                "line of column names (units as 'UGB_x [um]'; a column 'time [s]', or "
                                "'# sampling_rate: 256' above); .uff/.unv (dataset 58 time responses); .tdms; "
                                ".mat; .h5/.hdf5 (see twin.extract.readers)")
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (signals.nc)")
    p.add_argument("--fs", type=POSITIVE, default=None, help="sampling rate [Hz] where the file gives none")
    p.add_argument("--units", default=None, metavar="U|NAME=U,...",
                   help="units of every channel, or of some by name, where the header gives none (um, mil, mm/s, g, ...)")
    p.add_argument("--quantity", default=None, metavar="Q|NAME=Q,...",
                   help="displacement, velocity or acceleration, for every channel or some by name (default: "
                        "the quantity of its units)")  # fmt: skip
    p.add_argument("--channels", default=None, help="new channel names in the file's order, e.g. UGB_x,UGB_y")

    p = _command(sub, "extract", "automated modal extraction (SSI-cov) from signals to mode samples",
                 "Covariance-driven stochastic subspace identification over model orders, a stabilisation\n"
                 "diagram cleared automatically, harmonics of the running speed rejected; each mode's\n"
                 "uncertainty from jackknife samples over blocks of the record (modes.nc).",
                 ["twin extract signals.nc -o modes.nc --fmax 60 --plot stabilisation.png"],
                 stages._extract)  # fmt: skip
    p.add_argument("signals", help="signals file (NetCDF, time x channel, from twin simulate or a measurement)")
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (modes.nc)")
    p.add_argument("--samples", type=COUNT, default=None,
                   help=f"jackknife samples per mode J, one per block left out (default: {SAMPLES}, or as many "
                        "blocks as a short record holds; the output says which)")
    p.add_argument("--blocks", type=COUNT, default=None,
                   help="blocks the record is cut into (default: --samples; with --delete-half it may be fewer)")
    p.add_argument("--fmax", type=POSITIVE, default=None, help="highest frequency [Hz] (default: 40%% of fs)")
    p.add_argument("--fmin", type=NONNEGATIVE, default=0.0, help="lowest frequency [Hz]")
    p.add_argument("--block-rows", type=COUNT, default=None,
                   help="Hankel block rows the poles are read at (default: from fmax)")
    p.add_argument("--shape-block-rows", type=rows_or_auto, default=0,
                   help="block rows of a second pass every mode's shapes are read at (default 0: none, the "
                        "shapes come with the poles); auto: the slow modes' shapes at lags over 1.5 periods of "
                        "the slowest")
    p.add_argument("--first-lag", type=COUNT, default=None,
                   help="lag the covariance Hankel matrix starts at, in samples (default: the first at or beyond "
                        "one period of fmax; 1: the textbook matrix)")
    p.add_argument("--differenced-above", type=POSITIVE, default=None, metavar="HZ",
                   help="read the modes above this frequency [Hz] from a second pass over the record differenced "
                        "twice, where the slow, strong modes no longer fill the covariances (default: none)")
    p.add_argument("--shape-samples", type=COUNT, default=None, metavar="M",
                   help="draw the shape samples from M random halves of the blocks (a multiple of --samples), "
                        "the poles keeping their own samples, each used M / samples times (default: the shapes "
                        "come with the poles)")
    p.add_argument("--max-order", type=COUNT, default=100, help="largest model order")
    p.add_argument("--channels", default=None, help="channels to use, e.g. UGB_x,UGB_y (default: all)")
    p.add_argument("--plot", default=None, help="stabilisation diagram figure to write (PNG)")
    p.add_argument("--delete-half", action="store_true",
                   help="each sample leaves out half the blocks (a spread that matches independent records) "
                        "instead of one (the default: wider, what the loop is calibrated to)")
    p.add_argument("--order-spread", choices=("shapes", "all", "none"), default="shapes",
                   help="add each mode's model-order error to the shape samples (the standard error of the "
                        "shape's mean over its orders; the default), to the pole samples too (their spread over "
                        "the orders: all) or to neither (none)")
    p.add_argument("--orders-per-mode", type=NATURAL, default=ORDERS_PER_MODE,
                   help=f"average each mode over this many of its lowest settled model orders (default "
                        f"{ORDERS_PER_MODE}; 0: all of them)")
    p.add_argument("--keep-harmonics", dest="remove_harmonics", action="store_false",
                   help="leave the lines at the multiples of the record's running speed in the record (by "
                        "default they are subtracted before SSI); they are then rejected as modes by their "
                        "band kurtosis")

    p = _command(sub, "synthesize-modes", "paper-style synthetic modal data (noisy pole and shape samples)",
                 "Samples of poles and partial mode shapes of a truth, with the reference paper's noise model:\n"
                 "modal data without signals, for checking the updater.",
                 ["twin synthesize-modes hydro_unit -o modes.nc --samples 100 --seed 7"], stages._synthesize_modes)  # fmt: skip
    p.add_argument("model", help=MODEL_HELP + ", the calibrated FEM")
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (modes.nc)")
    p.add_argument("--truth", default="paper", help=f"what the truth hides: {TRUTH_HELP}")
    p.add_argument("--samples", type=COUNT, default=100, help="samples per mode J")
    p.add_argument("--seed", type=NATURAL, default=1, help="random seed")
    p.add_argument("--modes", type=COUNT, default=None,
                   help="number of modes, for a truth without per-mode effect (default: the truth's per-mode count, "
                        "or every lightly damped mode of the model)")  # fmt: skip


def _add_loop(sub) -> None:
    p = _command(sub, "update", "Bayesian updating from mode samples (APerCEM: HMC on the marginal, the Gibbs sampler, or Laplace)",
                 "The posterior of the chosen parameters given the measured poles and shapes, written in the\n"
                 "ArviZ layout (posterior.nc: posterior, sample_stats, observed_data groups).",
                 ["twin update hydro_unit modes.nc --params bearings --fsi -o posterior.nc",
                  "twin update hydro_unit modes.nc --effect magnetic_pull --params MAG.stiffness -o posterior.nc",
                  "twin update hydro_unit modes.nc --method laplace --effect magnetic_pull --params MAG.stiffness "
                  "-o posterior.nc"], loop._update)  # fmt: skip
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("modes", help=MODES_HELP)
    p.add_argument("-o", "--output", required=True, help="NetCDF file to write (posterior.nc, ArviZ groups)")
    p.add_argument("--params", default=None,
                   help="parameters to update: names, globs (LGB.c*) or groups (bearings, thrust, disks); twin params "
                        "lists the names (default: none, then --fsi is needed)")  # fmt: skip
    p.add_argument("--fsi", action="store_true", help="update the per-mode FSI added mass and damping")
    _add_method(p, "how to update")
    _add_chain_options(p)
    p.add_argument("--noise-model", choices=("full", "diagonal"), default=None,
                   help="--method gibbs: covariance of the residual realisations: full (correlated rows, the "
                        "default) or diagonal (the paper's)")  # fmt: skip
    p.add_argument("--collapsed", action=argparse.BooleanOptionalAction, default=None,
                   help="--method gibbs: a Metropolis step of the parameters with the shapes integrated out in "
                        "every sweep (the default; chains mix along the parameter-shape ridge); --no-collapsed: "
                        "plain Gibbs")
    p.add_argument("--pole-model", choices=("linear", "samples"), default=None,
                   help="--method gibbs: the condensed model linearised about each mode's mean pole (the default) "
                        "or rebuilt at every pole sample (the paper's)")
    p.add_argument("--flat-priors", action="store_true",
                   help="no prior on the effects' parameters (by default each gets a Gaussian one about the "
                        "model's value, as wide as its effect's plausible scale: a bound where the data say little)")
    p.add_argument("--effect", action="append", default=None, metavar="LABEL",
                   help="add a library effect first (e.g. magnetic_pull, bearing_change:LGB); repeatable")
    _add_scheduler(p, "chains")

    p = _command(sub, "compare", "compare a model with measured modes: per-mode errors and the overall error",
                 "Each measured mode against its model partner (one-to-one, by pole distance and MAC): frequency\n"
                 "and damping errors with their z-scores, the MAC, the shape error per sensor, and the error E\n"
                 "(the uncertainty-weighted RMS relative pole distance).",
                 ["twin compare hydro_unit modes.nc --plot figures",
                  "twin compare hydro_unit modes.nc --posterior posterior.nc --history history.csv"], loop._compare)  # fmt: skip
    _add_model_and_posterior(p)
    p.add_argument("--plot", default=None, metavar="DIR",
                   help="write the figures (errors, MAC, spectra) into the folder DIR (created if missing)")
    p.add_argument("--signals", default=None, metavar="FILE",
                   help="with --plot: the record the modes came from (signals.nc), for spectra.png as its power "
                        "spectral density per channel with the identified and the model modes marked (default: the "
                        "modal spectra rebuilt from the modes)")  # fmt: skip
    p.add_argument("--history", default=None, metavar="FILE",
                   help="append this comparison's error as one row of the CSV file FILE (created if missing), and "
                        "redraw the error chart beside it, FILE with the suffix .png (history.csv: history.png)")  # fmt: skip
    p.add_argument("--step", default=None, help="name of the step in the history (default: from --effect/--posterior)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")

    p = _command(sub, "diagnose", "where the model fails and which library effect is missing",
                 "Fits the library's effects to the measured poles and compares them by evidence (Laplace\n"
                 "approximation inside the physical bounds), stepwise; outside the library it locates shaft\n"
                 "stiffness and disk mass or inertia changes. Verdicts: missing effect, partly explained,\n"
                 "unexplained (with the place), nothing missing, not enough data.",
                 ["twin diagnose hydro_unit modes.nc",
                  "twin diagnose hydro_unit modes.nc --posterior posterior.nc --json"], loop._diagnose)  # fmt: skip
    _add_model_and_posterior(p)
    p.add_argument("--candidates", default=None, help="candidate effects, comma-separated (default: the library)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    _add_scheduler(p, "candidate fits")

    p = _command(sub, "loop", "the twin loop to the end: diagnose, add the missing effects, update them jointly, "
                              "diagnose again",
                 "Rounds of diagnose, add every effect found, update all added effects jointly, until nothing\n"
                 "new is missing; writes diagnosis.json, history.csv/.png and posterior.nc into --out.",
                 ["twin loop hydro_unit modes.nc --out twin-loop"], loop._loop)  # fmt: skip
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("modes", help=MODES_HELP)
    p.add_argument("--out", default="twin-loop", help="folder of diagnosis.json, history.csv/.png and posterior.nc")
    _add_method(p, "how each round updates the added effects")
    _add_bootstrap(p)
    p.add_argument("--rounds", type=COUNT, default=4, help="rounds at most")
    p.add_argument("--candidates", default=None, help="candidate effects, comma-separated (default: the library)")
    p.add_argument("--effect", action="append", default=None, metavar="LABEL",
                   help="add a library effect to the model first; repeatable")
    _add_tolerance(p)
    _add_chain_options(p)
    _add_scheduler(p, "candidate fits and calibration records")

    p = _command(sub, "demo", "the whole loop on a truth with hidden changes, with a report folder",
                 "Exports the FMU, simulates a truth with a hidden change, extracts the modes, and runs the\n"
                 "loop; report.md and report.html in --out say what was found and how the error fell.",
                 ["twin demo", "twin demo --hidden 'magnetic_pull@1.5+seal_cross_coupling' --seed 4",
                  "twin demo --hidden disk_mass:generator@1.1 --out heavier-generator"], loop._demo)  # fmt: skip
    p.add_argument("--out", default="twin-demo", help="report folder")
    p.add_argument("--hidden", default="magnetic_pull",
                   help="what the truth hides: a library effect (magnetic_pull, fsi, fsi_per_mode, seal_cross_coupling, "
                        "thrust_tilt:thrust, bearing_change:UGB, bearing_change:LGB) at its reference size or scaled "
                        "(magnetic_pull@2.5), several joined by + (magnetic_pull+seal_cross_coupling), a local change "
                        "outside the library (shaft_stiffness:18@0.5, disk_mass:generator@1.1, disk_inertia:runner@1.2), "
                        "or none")  # fmt: skip
    p.add_argument("--seed", type=NATURAL, default=1, help="seed of turbulence and noise")
    _add_loop_settings(p, DEMO_RECORDS)
    # the calibration's records (twin.loop.bootstrap) take most of the demo's time: on a local cluster by default
    _add_scheduler(p, "candidate fits and calibration records")

    p = _command(sub, "sweep", "the demo's loop over hidden changes and seeds, one Dask task per scenario",
                 "Runs the demo for every scenario and tabulates the verdict, the error's fall and the parameter\n"
                 "errors (sweep.nc); exit status 1 when a scenario fails.",
                 ["twin sweep --hidden all,none --seeds 1,2", "twin sweep --scenarios benchmarks/loop_suite.txt --workers 2"],
                 loop._sweep)  # fmt: skip
    p.add_argument("--hidden", default="all",
                   help="what the truths hide, comma-separated specs as for twin demo; 'all' for every library effect "
                        "at its reference size ('all,none' adds the false-alarm check)")  # fmt: skip
    p.add_argument("--scenarios", default=None, metavar="FILE",
                   help="scenarios from a file, one 'SPEC SEED[,SEED...]' per line (instead of --hidden and --seeds), "
                        "e.g. benchmarks/loop_suite.txt")
    p.add_argument("--seeds", default="1", help="seeds of turbulence and noise, comma-separated")
    p.add_argument("--out", default="twin-sweep", help="folder of sweep.nc and the report folders")
    _add_loop_settings(p)
    _add_scheduler(p, "scenarios")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``twin`` command.

    Examples
    --------
    >>> args = build_parser().parse_args(["modal", "hydro_unit", "-v"])
    >>> args.command, args.verbose, args.quiet
    ('modal', True, False)
    """
    parser = argparse.ArgumentParser(
        prog="twin", formatter_class=_Formatter,
        description="Digital twin of a rotating machine in water: rotor FEM, FMU, modal extraction, Bayesian\n"
                    "updating, and the loop that finds what the model is missing.",
        epilog="start with:\n  twin demo                       the whole loop on a truth with a hidden magnetic pull\n"
               "  twin params hydro_unit          the shipped model's parameters and effects\n"
               "  twin COMMAND --help             each command's options and examples")  # fmt: skip
    parser.add_argument("--version", action="version", version=f"twin {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log each stage and its details")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress display")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_stages(sub)
    _add_loop(sub)
    track.add_commands(sub, _command, _add_scheduler)
    return parser
