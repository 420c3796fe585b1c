"""The ``twin`` command: one sub-command per stage of the loop.

    twin modal MODEL.toml [--speed RPM] [--modes N] [--json]
    twin campbell MODEL.toml [--max-speed RPM] [--points N] [--modes N] -o campbell.png
    twin export-fmu MODEL.toml -o unit.fmu [--fs HZ] [--basis full|modal] [--fmax HZ] [--inputs runner.x,...]
    twin simulate MODEL.toml --duration S --fs HZ --seed N [--truth truth.toml|paper] -o signals.nc
    twin extract signals.nc -o modes.nc [--samples J] [--fmax HZ] [--fmin HZ] [--channels A,B] [--plot stab.png]
                 [--block-rows I] [--shape-block-rows I|auto] [--first-lag K] [--delete-half]
                 [--order-spread shapes|all|none] [--differenced-above HZ]
    twin synthesize-modes MODEL.toml -o modes.nc [--truth truth.toml|paper] [--samples J] [--seed N]
    twin update MODEL.toml modes.nc -o posterior.nc [--params bearings|NAME,...] [--fsi] [--method hmc|gibbs|paper|laplace]
                [--draws N] [--chains N] [--warmup N] [--seed N] [--effect LABEL]
    twin compare MODEL.toml modes.nc [--posterior posterior.nc] [--effect LABEL] [--json] [--plot DIR]
    twin diagnose MODEL.toml modes.nc [--posterior posterior.nc] [--candidates LABEL,...] [--json]
    twin loop MODEL.toml modes.nc [--out DIR] [--method hmc|gibbs|paper|laplace]
    twin demo [--out DIR] [--hidden SPEC] [--duration S] [--seed N] [--model MODEL.toml]
    twin sweep [--hidden SPEC,...] [--seeds N,...] [--scenarios FILE] [--out DIR]
    twin params MODEL.toml [--effect LABEL] [--json]
    twin campaign MODEL.toml --schedule SCHEDULE.toml -o DIR [--seed N] [--workers N] [--json]
    twin track MODEL.toml DIR -o OUT [--baseline-days D] [--false-alarms PER_YEAR] [--json]

The parser is :mod:`twin.cli.parser`; the stages' commands are in
:mod:`twin.cli.model` (1), :mod:`twin.cli.stages` (2-3), :mod:`twin.cli.loop` (4-5) and :mod:`twin.cli.track` (over time). Progress (a
line per stage, bars for the long ones) goes to stderr when it is a
terminal, unless ``--quiet``. Errors in the input are reported on one line (``twin: error: ...``) with exit
status 2, never as a traceback; an interrupt (Ctrl-C) on one line with status 130.
"""

from __future__ import annotations

import logging
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path

from twin.errors import TwinError, TwinWarning

log = logging.getLogger("twin")

__all__ = ["main"]


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings of the loop on one line (``twin: warning: ...``), others as Python prints them."""
    if issubclass(category, TwinWarning):
        print(f"twin: warning: {message}", file=sys.stderr)
    else:
        print(warnings.formatwarning(message, category, filename, lineno, line), file=sys.stderr, end="")


def _check_outputs(args) -> None:
    """Before any work: every command's output files (``-o``, ``--history`` and its chart, ``--design``,
    extract's ``--plot``) and output folders (``--out``, compare's ``--plot``)."""
    from twin.netcdf import check_folder, check_writable

    if getattr(args, "output", None) is not None:
        check_writable(args.output, figure=args.command == "campbell")
    if getattr(args, "history", None) is not None:
        check_writable(args.history)
        check_writable(Path(args.history).with_suffix(".png"), figure=True)
    if getattr(args, "design", None) is not None:
        check_writable(args.design)
    if getattr(args, "plot", None) is not None and args.command == "extract":
        check_writable(args.plot, figure=True)
    folders = {"out": getattr(args, "out", None), "plot": args.plot if args.command == "compare" else None}
    for flag, folder in folders.items():
        if folder is not None:
            check_folder(folder, flag)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``twin`` command; returns the exit status."""
    from twin.cli.parser import build_parser

    args = build_parser().parse_args(argv)
    level = logging.INFO if args.verbose else logging.WARNING
    if not logging.getLogger().handlers:  # (a host such as pytest may have its own)
        logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
        handler = logging.getLogger().handlers[0]
        # Dask's scheduler runs here and logs its own life at INFO: only its warnings are shown
        handler.setLevel(level)
        handler.addFilter(lambda r: r.levelno >= logging.WARNING or not r.name.startswith("distributed"))
    warnings.showwarning = _show_warning
    from twin.progress import show_stages

    show_stages(not args.quiet)
    try:
        _check_outputs(args)
        return args.func(args)
    except TwinError as exc:
        print(f"twin: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C: files are written whole or not at all (twin.netcdf.atomic_output)
        print("\ntwin: interrupted; the files written before are complete, none is half-written", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into e.g. `head`, which stopped reading
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    finally:
        show_stages(None)  # a host process (a notebook, a test) gets the library's default back


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
