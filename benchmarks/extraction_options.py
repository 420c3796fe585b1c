"""The extraction options the benchmarks share: their command-line flags and the ``extract`` keywords they give.

Each flag left out keeps :func:`twin.extract.extract`'s default, so a benchmark run without them measures the
twin's default extraction.

Examples
--------
>>> import argparse
>>> ap = argparse.ArgumentParser()
>>> add_extraction_options(ap)
>>> args = ap.parse_args(["--delete-half", "--samples", "45", "--blocks", "15", "--orders-per-mode", "0"])
>>> extraction_options(args)
{'samples': 45, 'blocks': 15, 'delete_blocks': None, 'orders_per_mode': None}
>>> extraction_flags(args)
' --delete-half --samples 45 --blocks 15 --orders-per-mode 0'
"""

from __future__ import annotations

import argparse

from twin.cli.common import rows_or_auto

#: Flags whose value is passed on as given (flag name, ``extract`` keyword).
VALUED = (
    ("samples", "samples"),
    ("blocks", "blocks"),
    ("order_spread", "order_spread"),
    ("block_rows", "block_rows"),
    ("shape_block_rows", "shape_block_rows"),
    ("first_lag", "first_lag"),
    ("differenced_above", "differenced_above_hz"),
    ("shape_samples", "shape_samples"),
)


def add_extraction_options(ap: argparse.ArgumentParser) -> None:
    """Add ``--keep-harmonics``, ``--delete-half``, ``--samples``, ``--blocks``, ``--orders-per-mode``,
    ``--order-spread``, ``--block-rows``, ``--shape-block-rows``, ``--first-lag``, ``--differenced-above`` and
    ``--shape-samples`` (as ``twin extract``'s) to a benchmark's parser."""
    ap.add_argument(
        "--keep-harmonics",
        dest="remove_harmonics",
        action="store_false",
        help="leave the running-speed lines in the record (removed by default)",
    )
    ap.add_argument("--delete-half", action="store_true", help="delete-half jackknife samples (default delete-one)")
    ap.add_argument("--samples", type=int, default=None, help="jackknife samples per mode (default: the benchmark's)")
    ap.add_argument(
        "--blocks",
        type=int,
        default=None,
        help="blocks the record is cut into (default: --samples; fewer with --delete-half)",
    )
    ap.add_argument(
        "--orders-per-mode",
        type=int,
        default=None,
        help="lowest settled orders each mode is averaged over (default: extract's; 0: all)",
    )
    ap.add_argument(
        "--order-spread",
        choices=("shapes", "all", "none"),
        default=None,
        help="what the model-order spread is added to (default: extract's)",
    )
    ap.add_argument("--block-rows", type=int, default=None, help="Hankel block rows (default: extract's, from fmax)")
    ap.add_argument(
        "--shape-block-rows",
        default=None,
        type=rows_or_auto,
        help="block rows of a second pass the shapes are read at, or auto (default: extract's, none)",
    )
    ap.add_argument(
        "--first-lag",
        type=int,
        default=None,
        help="lag the Hankel matrix starts at (default: extract's, one period of fmax; 1: the old one)",
    )
    ap.add_argument(
        "--differenced-above",
        type=float,
        default=None,
        metavar="HZ",
        help="modes above this frequency from the record differenced twice (default: extract's, none)",
    )
    ap.add_argument(
        "--shape-samples",
        type=int,
        default=None,
        metavar="M",
        help="the shapes from M random halves of the blocks, the poles keeping theirs (default: the "
        "benchmark's, 4 x samples for the loop's records; 0: none)",
    )


def extraction_options(args: argparse.Namespace) -> dict:
    """The ``extract`` keywords the flags ask for (none for a flag left out)."""
    options = {key: getattr(args, flag) for flag, key in VALUED if getattr(args, flag) is not None}
    if args.delete_half:
        options["delete_blocks"] = None
    if args.orders_per_mode is not None:
        options["orders_per_mode"] = args.orders_per_mode or None
    if not args.remove_harmonics:
        options["remove_harmonics"] = False
    return options


def extraction_flags(args: argparse.Namespace) -> str:
    """The flags given, as they would be typed (for a results file's command line)."""
    flags = ("" if args.remove_harmonics else " --keep-harmonics") + (" --delete-half" if args.delete_half else "")
    for flag in (
        "samples",
        "blocks",
        "orders_per_mode",
        "order_spread",
        "block_rows",
        "shape_block_rows",
        "first_lag",
        "differenced_above",
        "shape_samples",
    ):
        if getattr(args, flag) is not None:
            flags += f" --{flag.replace('_', '-')} {getattr(args, flag)}"
    return flags
