"""What the ``twin`` sub-commands share: the options' types and groups, the sub-command factory, the Dask
client of ``--scheduler``, and the model with the effects ``--effect`` names.

Every command module registers its own sub-commands with these (``add_commands``); nothing here imports
the numerical stack, so ``twin --help`` and argument errors answer at once.
"""

from __future__ import annotations

import argparse
import contextlib
import math

from twin.defaults import (
    ALGORITHMS,
    CHAINS,
    DEMO_FMAX_HZ,
    DEFAULT_RECORDS,
    DRAWS,
    GIBBS_BURN_IN,
    HMC_MIN_WARMUP,
    HMC_WARMUP,
    MAX_BATCHES,
    METHODS,
    NOISE_RATIO,
    RECORD_DURATION_S,
    SAMPLES,
    SAMPLING_RATE_HZ,
)

MODEL_HELP = (
    "model file (TOML), or the name of a shipped model: hydro_unit or pelton_unit (every command), or "
    "ross_reference (ROSS's test rotor, for checking the FEM: unstable by design and without water, so not for "
    "simulate, synthesize-modes with the paper's truth, or the loop)"
)
MODES_HELP = "modes file (NetCDF: mode x sample x channel, from twin extract or twin synthesize-modes)"
#: What a truth file is, said where --truth is taken.
TRUTH_HELP = (
    "a truth file (TOML: one table per hidden effect, named as twin params names it, its keys the "
    "parameter names without their owner: [magnetic_pull] stiffness = -2e8 for MAG.stiffness, "
    '["bearing_change:UGB"] stiffness_change = -1e8 for UGB.stiffness_change; values outside the '
    "physical bounds twin params lists are refused), 'paper' (the reference paper's Table 2 per-mode FSI) "
    "or 'none' (the model as it is)"
)


class Formatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions as written; every option's default appended unless its help states it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or not action.option_strings or action.default in (None, False, argparse.SUPPRESS):
            return text
        return f"{text} (default: %(default)s)"


def common_options() -> argparse.ArgumentParser:
    """Options every sub-command takes as well (so ``twin demo -v`` works like ``twin -v demo``)."""
    p = argparse.ArgumentParser(add_help=False)
    p.add_argument(
        "-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help="log each stage and its details"
    )
    p.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        default=argparse.SUPPRESS,
        help="no progress display (bars and stage lines); results and errors are still printed",
    )
    return p


#: Modes ``twin modal`` lists by default, lowest first (a FEM has many more, up to kHz).
MODAL_MODES = 20


def number(kind: type = float, low: float = 0.0, strict: bool = False):
    """An argparse ``type``: a ``kind`` number at least ``low`` (above it when ``strict``), else a one-line error."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected {'an integer' if kind is int else 'a number'}, got {text!r}"
            ) from None
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


def command(sub, name: str, summary: str, description: str, examples: list[str], func) -> argparse.ArgumentParser:
    """A sub-command with its one-line summary, a description, and examples in its help."""
    p = sub.add_parser(
        name,
        help=summary,
        description=f"{summary[0].upper()}{summary[1:]}.\n\n{description}",
        epilog="examples:\n" + "\n".join(f"  {e}" for e in examples),
        formatter_class=Formatter,
        parents=[common_options()],
    )
    p.set_defaults(func=func)
    return p


def add_scheduler(p: argparse.ArgumentParser, what: str, default: str = "local") -> None:
    p.add_argument(
        "--scheduler",
        default=default,
        metavar="ADDRESS",
        help=f"where the {what} run as Dask tasks: 'local' (a local cluster of worker processes), "
        f"a scheduler address such as tcp://host:8786, or 'sync' (in this process)",
    )
    p.add_argument("--workers", type=COUNT, default=None, help="workers of the local cluster (default: one per core)")


def add_tolerance(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--tolerance",
        type=NONNEGATIVE,
        default=0.0,
        help="relative pole uncertainty accepted as model-form error, added to the measurement's standard error",
    )


def add_effect(p: argparse.ArgumentParser) -> None:
    """``--effect LABEL``, repeatable: library effects added to the model before the command's work."""
    p.add_argument(
        "--effect",
        action="append",
        default=None,
        metavar="LABEL",
        help="add a library effect to the model first (e.g. magnetic_pull, bearing_change:LGB); repeatable",
    )


def add_model_and_posterior(p: argparse.ArgumentParser) -> None:
    """The model, the measured modes, and what to do to the model first (compare, diagnose)."""
    p.add_argument("model", help=MODEL_HELP)
    p.add_argument("modes", help=MODES_HELP)
    add_effect(p)
    p.add_argument(
        "--posterior",
        default=None,
        help="apply this posterior (posterior.nc of twin update or twin loop) first, with the effects it "
        "was made with: the next round of the loop",
    )
    p.add_argument("--estimate", choices=("map", "mean"), default="map", help="posterior point estimate")
    add_tolerance(p)


def add_bootstrap(p: argparse.ArgumentParser, default: int | None = None) -> None:
    """``--bootstrap``, the calibration of the last update on records simulated at its estimate (by default on
    ``default`` records, the loop's :data:`twin.defaults.DEFAULT_RECORDS` when None)."""
    default = DEFAULT_RECORDS if default is None else default

    p.add_argument(
        "--bootstrap",
        type=NATURAL,
        default=None,
        metavar="R",
        help="records to simulate through the FMU at the last update's estimate, to calibrate its spread "
        "(twin.loop.bootstrap; about 12 s a 20-min record on one core; up to "
        f"{MAX_BATCHES} x R when a mode came out of too few; on the Dask workers, within a sweep "
        f"in its scenario's worker); default: {default} with --method hmc, none with "
        "the other methods; 0: none",
    )


def add_method(p: argparse.ArgumentParser, what: str) -> None:
    """``--method``: one of the update's samplers, or the Laplace fit."""
    p.add_argument(
        "--method",
        choices=METHODS,
        default=METHODS[0],
        help=f"{what}: hmc, HMC on the marginal posterior (the default, calibrated on FMU records); "
        "gibbs, the Gibbs sampler of the full APerCEM; paper, the reference paper's Gibbs sampler; "
        "laplace, the Gaussian posterior of the pole fit inside the physical bounds (fast, blind to "
        "shapes)",
    )


def add_algorithm(p: argparse.ArgumentParser) -> None:
    """``--algorithm``: how the extraction reads the modes (:mod:`twin.extract.algorithms`)."""
    p.add_argument(
        "--algorithm",
        choices=ALGORITHMS,
        default=ALGORITHMS[0],
        help="how the extraction reads the modes from the record's covariances: ssi, covariance-driven SSI "
        "(the default; lightly damped and slow modes); plscf, a least-squares fit of their half spectra "
        "over the band (heavily damped, overlapping modes, 4%% of critical and more)",
    )


def add_chain_options(p: argparse.ArgumentParser) -> None:
    """The options every sampler takes (their defaults are the sampler's own: twin.update.samplers)."""
    p.add_argument("--draws", type=COUNT, default=None, help=f"draws kept per chain (default: {DRAWS})")
    p.add_argument("--chains", type=COUNT, default=None, help=f"number of chains (default: {CHAINS})")
    p.add_argument(
        "--warmup",
        type=NATURAL,
        default=None,
        help=f"iterations per chain before the draws kept (default: the sampler's: {HMC_WARMUP} warm-up "
        f"iterations of HMC, at least {HMC_MIN_WARMUP}; {GIBBS_BURN_IN} burn-in sweeps of the Gibbs "
        "samplers)",
    )
    p.add_argument("--seed", type=NATURAL, default=None, help="random seed of the chains (default: fresh entropy)")


def add_loop_settings(p: argparse.ArgumentParser, records: int | None = None) -> None:
    """The demo's record and model options, shared by ``demo`` and ``sweep``; ``records``: the default of
    ``--bootstrap`` (the loop's when None)."""
    p.add_argument("--duration", type=POSITIVE, default=RECORD_DURATION_S, help="record length [s]")
    p.add_argument("--samples", type=COUNT, default=SAMPLES, help="jackknife samples per mode")
    p.add_argument(
        "--fmax",
        type=POSITIVE,
        default=DEMO_FMAX_HZ,
        help="highest frequency the extraction looks for modes up to [Hz]",
    )
    add_algorithm(p)
    p.add_argument("--model", default=None, help="the twin's model file (default: the shipped hydro_unit)")
    add_method(p, "how each round updates the added effects")
    add_bootstrap(p, records)


def add_record(p: argparse.ArgumentParser, duration_required: bool) -> None:
    """The record and its excitation, as ``simulate`` makes it and ``observe`` judges it."""
    if duration_required:
        p.add_argument("--duration", type=POSITIVE, required=True, help="record length [s]")
    else:
        p.add_argument("--duration", type=POSITIVE, default=RECORD_DURATION_S, help="record length [s]")
    p.add_argument("--fs", type=POSITIVE, default=SAMPLING_RATE_HZ, help="sampling rate [Hz]")
    p.add_argument(
        "--turbulence",
        type=NONNEGATIVE,
        default=None,
        help="one-sided ASD of the broad-band force (turbulence, process forces) [N/sqrt(Hz)] (default: the "
        "machine's, from its model file's [excitation] or its weight)",
    )
    p.add_argument(
        "--noise",
        type=NONNEGATIVE,
        default=NOISE_RATIO,
        help="sensor noise std as a fraction of the median channel RMS (0.05: 5%% of the typical signal)",
    )
    p.add_argument(
        "--noise-std",
        type=NONNEGATIVE,
        default=None,
        help="sensor noise std [m] per sample, instead of --noise (the same sensors on another layout)",
    )


def add_design_inputs(p: argparse.ArgumentParser) -> None:
    """The model, record, truth and parameters ``observe`` and ``sensors`` judge."""
    p.add_argument("model", help=MODEL_HELP)
    add_record(p, duration_required=False)
    p.add_argument(
        "--fmax", type=POSITIVE, default=None, help="highest target frequency [Hz] (default: 100, at most 0.4 fs)"
    )
    p.add_argument(
        "--truth",
        default=None,
        help=f"judge a truth with hidden effects instead of the model: {TRUTH_HELP} (default: none)",
    )
    p.add_argument(
        "--params",
        default=None,
        help="parameters to judge: names, glob patterns or groups (bearings, thrust, disks), comma-separated",
    )
    p.add_argument(
        "--fsi", action="store_true", help="also judge per-mode added mass and damping of every observable mode"
    )


@contextlib.contextmanager
def tasks(args: argparse.Namespace):
    """The Dask client of ``--scheduler``/``--workers`` (None for ``sync``), closed afterwards."""
    from twin.tasks import dask_client

    with dask_client(args.scheduler, n_workers=args.workers) as client:
        yield client


def model_with_effects(path: str, labels: list[str] | None, modes=None):
    """The model file's model with the ``--effect`` labels added (:func:`twin.loop.candidates.with_effects`)."""
    from twin.fem import load_model
    from twin.loop.candidates import with_effects

    return with_effects(load_model(path), labels or (), modes)
