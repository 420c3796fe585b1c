"""The command line's defaults are the library's: each option's default equals its function's."""

import dataclasses
import inspect

import pytest

from twin.cli.parser import build_parser
from twin.extract.options import ExtractOptions
from twin.fmu.simulate import simulate
from twin.harness.demo import run_demo
from twin.harness.sweep import Settings
from twin.loop.twin import Twin
from twin.update import synthesize_modes


def cli_default(argv: list[str], option: str):
    """The value ``option`` takes when the command line leaves it out."""
    return getattr(build_parser().parse_args(argv), option)


def signature_default(func, name: str):
    return inspect.signature(func).parameters[name].default


EXTRACT = {f.name: f.default for f in dataclasses.fields(ExtractOptions)}


@pytest.mark.parametrize(
    "argv, option, library",
    [
        (["simulate", "hydro_unit", "--duration", "60", "-o", "s.nc"], "fs", signature_default(simulate, "fs_hz")),
        (
            ["simulate", "hydro_unit", "--duration", "60", "-o", "s.nc"],
            "noise",
            signature_default(simulate, "noise_ratio"),
        ),
        (["demo"], "duration", signature_default(run_demo, "duration_s")),
        (["demo"], "samples", signature_default(run_demo, "samples")),
        (["demo"], "fmax", signature_default(run_demo, "fmax_hz")),
        (["sweep"], "fmax", Settings().fmax_hz),
        (["extract", "s.nc", "-o", "m.nc"], "max_order", EXTRACT["max_order"]),
        (["extract", "s.nc", "-o", "m.nc"], "samples", EXTRACT["samples"]),
        (["extract", "s.nc", "-o", "m.nc"], "fmin", EXTRACT["fmin_hz"]),
        (["synthesize-modes", "hydro_unit", "-o", "m.nc"], "samples", signature_default(synthesize_modes, "samples")),
        (["loop", "hydro_unit", "m.nc"], "rounds", signature_default(Twin.run, "max_rounds")),
    ],
    ids=lambda v: v if isinstance(v, str) else None,
)
def test_an_option_left_out_takes_the_library_default(argv, option, library):
    assert cli_default(argv, option) == library
