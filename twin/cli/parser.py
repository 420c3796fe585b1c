"""The argument parser of the ``twin`` command: one sub-command per stage, each with a description and an example.

Every option's help states its default; ``-v``/``--quiet`` go before or
after the sub-command.
"""

from __future__ import annotations

import argparse

from twin import __version__
from twin.cli import design, loop, model, stages, track
from twin.cli.common import Formatter


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``twin`` command.

    Examples
    --------
    >>> args = build_parser().parse_args(["modal", "hydro_unit", "-v"])
    >>> args.command, args.verbose, args.quiet
    ('modal', True, False)
    """
    parser = argparse.ArgumentParser(
        prog="twin",
        formatter_class=Formatter,
        description="Digital twin of a rotating machine in water: rotor FEM, FMU, modal extraction, Bayesian\n"
        "updating, and the loop that finds what the model is missing.",
        epilog="start with:\n  twin demo                       the whole loop on a truth with a hidden magnetic pull\n"
        "  twin params hydro_unit          the shipped model's parameters and effects\n"
        "  twin COMMAND --help             each command's options and examples",
    )
    parser.add_argument("--version", action="version", version=f"twin {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log each stage and its details")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress display")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in (model, stages, design, loop, track):  # each command module registers its own sub-commands
        module.add_commands(sub)
    return parser
