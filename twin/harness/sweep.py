"""Scenario sweeps: the demo's loop over hidden changes and seeds, one task per scenario.

A scenario is a spec of what the truth hides (:mod:`twin.harness.scenarios`:
library effects at some size, several at once, a local change outside the
library, or ``none``) and a seed of the turbulence and the sensor noise. Each
runs :func:`twin.harness.demo.run_demo` into its own report folder and returns a
small summary; the scenarios are independent, so they run as tasks on Dask
(:mod:`twin.tasks`) as well as one after the other here. The summaries make
one Dataset over ``scenario`` (and ``parameter`` for the identified values),
written to ``OUT/sweep.nc``.

A scenario is *passed* when the diagnosis is right (:meth:`~twin.harness.scenarios.Scenario.expected`:
exactly the hidden library effects named; "unexplained" and the place of a
hidden local change; "nothing missing" with nothing hidden), the error falls
by at least :data:`MIN_FALL` and every identified parameter is within
:data:`MAX_PARAMETER_ERROR` of its truth or within :data:`MAX_Z` posterior
standard deviations of it (a parameter the record cannot pin down); with
nothing to add, nothing is updated. It is *passed strictly* when every
identified parameter is within :data:`MAX_PARAMETER_ERROR` of its truth,
whatever its standard deviation.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import logging
import time
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from twin.defaults import ALGORITHMS, DEMO_FMAX_HZ, RECORD_DURATION_S, SAMPLING_RATE_HZ
from twin import __version__
from twin.errors import TwinError, TwinWarning
from twin.fem.model import RotorModel
from twin.loop.bootstrap import DEFAULT_RECORDS
from twin.harness.demo import SAMPLES, run_demo
from twin.harness.scenarios import Scenario, parse_scenario, reference_labels, spec_folder
from twin.netcdf import check_folder, check_writable, write_netcdf
from twin.tasks import mapper

log = logging.getLogger(__name__)

#: Least fall of the error E (a fraction of E before) for a passed scenario.
MIN_FALL = 0.8
#: Largest relative error of an identified parameter for a passed scenario ...
MAX_PARAMETER_ERROR = 0.10
#: ... unless it is within this many of its own posterior standard deviations.
MAX_Z = 3.0


@dataclasses.dataclass(frozen=True)
class Settings:
    """What every scenario of a sweep shares (see :func:`twin.harness.demo.run_demo`)."""

    duration_s: float = RECORD_DURATION_S
    fs_hz: float = SAMPLING_RATE_HZ
    samples: int = SAMPLES
    fmax_hz: float = DEMO_FMAX_HZ
    algorithm: str = ALGORITHMS[0]
    method: str = "hmc"
    bootstrap: int | None = None  # the loop's default calibration (twin.loop.bootstrap.DEFAULT_RECORDS), not the demo's


def scenario_grid(
    model: RotorModel, hidden: Sequence[str] | None = None, seeds: Sequence[int] = (1,)
) -> list[tuple[str, int]]:
    """Every hidden spec with every seed (default: each library effect ``model`` admits at its reference size,
    :func:`twin.harness.scenarios.reference_labels`).

    Examples
    --------
    >>> scenario_grid(hydro_unit, ["magnetic_pull", "none"], seeds=[1, 2])
    [('magnetic_pull', 1), ('magnetic_pull', 2), ('none', 1), ('none', 2)]
    """
    hidden = reference_labels(model) if hidden is None else list(hidden)
    for h in hidden:
        parse_scenario(h, model)  # names a bad spec
    return [(h, int(s)) for h, s in itertools.product(hidden, seeds)]


def read_scenarios(path: str | Path, model: RotorModel) -> list[tuple[str, int]]:
    r"""Scenarios for ``model`` from a text file: one ``SPEC SEED[,SEED...]`` per line, ``#`` comments.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     f = pathlib.Path(tmp, "s.txt")
    ...     _ = f.write_text("# suite\nmagnetic_pull@0.2 31,32\nnone 40\n")
    ...     read_scenarios(f, hydro_unit)
    [('magnetic_pull@0.2', 31), ('magnetic_pull@0.2', 32), ('none', 40)]
    """
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as err:
        raise TwinError(f"{path}: cannot read the scenarios ({err.strerror})") from None
    out = []
    for n, line in enumerate(lines, start=1):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        parts = text.split()
        if len(parts) != 2:
            raise TwinError(f"{path}, line {n}: expected 'SPEC SEED[,SEED...]', got '{text}'")
        try:
            seeds = [int(x) for x in parts[1].split(",")]
            parse_scenario(parts[0], model)
        except ValueError:
            raise TwinError(f"{path}, line {n}: seeds are comma-separated integers, got '{parts[1]}'") from None
        except TwinError as err:
            raise TwinError(f"{path}, line {n}: {err}") from None
        out += [(parts[0], s) for s in seeds]
    if not out:
        raise TwinError(f"{path}: no scenario in the file")
    return out


def right_diagnosis(scenario: Scenario, row: dict) -> bool:
    """Whether a scenario's diagnosis is right (see the module docstring)."""
    named, location = set(filter(None, row["missing"].split("+"))), row["location"]
    if scenario.nothing:
        return row["verdict"] == "nothing missing"
    if not scenario.changes:
        return row["verdict"] == "missing effect" and named == set(scenario.labels)
    place = location in scenario.change_labels
    if not scenario.effects:
        return row["verdict"] == "unexplained" and place and not named
    return row["verdict"] == "partly explained" and named == set(scenario.labels) and place


def folder_name(hidden: str, seed: int) -> str:
    """The report folder of a scenario inside the sweep's folder.

    Examples
    --------
    >>> folder_name("bearing_change:LGB@0.5", 2)
    'bearing_change_LGB_x0.5_seed2'
    """
    return f"{spec_folder(hidden)}_seed{seed}"


def run_scenario(scenario: tuple[str, int], model: RotorModel, out: str, settings: Settings) -> dict:
    """Run one scenario's demo into ``out/<folder>`` and return its summary (plain Python values)."""
    hidden, seed = scenario
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:  # sent back with the summary: a worker's stderr is not ours
        warnings.simplefilter("always")
        try:
            options = dataclasses.asdict(settings)
            if options["bootstrap"] is None and options["method"] == "hmc":
                options["bootstrap"] = DEFAULT_RECORDS
            r = run_demo(
                Path(out) / folder_name(hidden, seed), model=model, hidden=hidden, seed=seed, progress=False, **options
            )
        except Exception as exc:  # one scenario's failure fails that scenario, not the sweep  # noqa: BLE001
            log.exception("scenario %s, seed %d failed", hidden, seed)
            return _failed_row(f"{type(exc).__name__}: {exc}", time.perf_counter() - t0, caught)
    d, final = r.diagnosis, r.final
    ranking = d.ranking
    params: dict[str, dict[str, float]] = {}
    if r.posterior is not None:
        ident = r.identified()
        for k, name in enumerate(ident["parameter"].values):
            params[str(name)] = {v: float(ident[v][k]) for v in PARAMETER_VARIABLES}
    located = final.locations or d.locations
    return {
        "verdict": d.verdict
        if not r.named
        else ("missing effect" if final.verdict == "nothing missing" else final.verdict),
        "missing": "+".join(r.named) if r.named else "+".join(d.missing),
        "rounds": len(r.twin.diagnoses),
        "final_verdict": final.verdict,
        "top_score": ranking[0].log_bayes_factor if ranking else np.nan,
        "lead": ranking[0].log_bayes_factor - ranking[1].log_bayes_factor if len(ranking) > 1 else np.nan,
        "error_before": r.twin.history[0].error,
        "error_after": r.twin.history[-1].error,
        "error_after_interval": r.twin.history[-1].interval or (np.nan, np.nan),
        "chi2_before": float(r.twin.history[0].table.attrs["chi2"]),
        "chi2_after": float(r.twin.history[-1].table.attrs["chi2"]),
        "n_data": int(r.twin.history[0].table.attrs["n_data"]),
        "parameters": params,
        "location": located[0].label if located and d.verdict in ("unexplained", "partly explained") else "",
        "elapsed_s": time.perf_counter() - t0,
        "warnings": [(w.category, str(w.message)) for w in caught],
    }


def _failed_row(message: str, elapsed_s: float, caught) -> dict:
    """A scenario whose run raised: verdict ``error``, nothing measured, the message as the last warning."""
    return {
        "verdict": "error",
        "missing": "",
        "rounds": 0,
        "final_verdict": "error",
        "top_score": np.nan,
        "lead": np.nan,
        "error_before": np.nan,
        "error_after": np.nan,
        "error_after_interval": (np.nan, np.nan),
        "chi2_before": np.nan,
        "chi2_after": np.nan,
        "n_data": 0,
        "parameters": {},
        "location": "",
        "elapsed_s": elapsed_s,
        "warnings": [(w.category, str(w.message)) for w in caught] + [(TwinWarning, f"the run failed: {message}")],
    }


def sweep(
    scenarios: Sequence[tuple[str, int]],
    out: str | Path = "twin-sweep",
    *,
    model: RotorModel | None = None,
    settings: Settings = Settings(),
    tasks: Any = None,
    progress: bool = True,
) -> xr.Dataset:
    """Run the demo's loop for every scenario, one task each, and tabulate the results.

    Parameters
    ----------
    scenarios : sequence of (hidden, seed)
        E.g. from :func:`scenario_grid`.
    out : path
        Folder of the scenarios' report folders and of ``sweep.nc``. On a
        remote cluster it must be a path the workers can write.
    model : RotorModel, optional
        The twin's model (default: the demo's hydro unit).
    settings : Settings
        Record length, sampling rate, jackknife samples, highest frequency.
    tasks : distributed.Client or mapper, optional
        Where the scenarios run (:func:`twin.tasks.mapper`): here by default.
    progress : bool
        A progress bar over the scenarios.

    Returns
    -------
    xarray.Dataset
        Over ``scenario`` (coordinates ``hidden``, ``seed``): ``verdict``,
        ``missing``, ``expected``, ``location``, ``rounds``, ``top_score``, ``lead``,
        ``error_before``, ``error_after`` (and its 90% interval over the posterior, ``error_after_low``,
        ``error_after_high``), ``chi2_before``, ``chi2_after``, ``n_data``,
        ``fall``, ``found``, ``passed``, ``passed_strict``, ``elapsed_s``; over
        ``scenario`` x ``parameter``: ``map``, ``std``, ``truth``, ``relative_error``, ``z``.

    Examples
    --------
    A short record, run here (``tasks=client`` for Dask):

    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as out:  # doctest: +SKIP
    ...     table = sweep([("magnetic_pull", 1)], out, settings=Settings(duration_s=600, samples=10))
    ...     table["passed"].values
    array([ True])
    """
    from twin.fem import load_model
    from twin.harness.demo import default_model_path

    scenarios = [(str(h), int(s)) for h, s in scenarios]
    if not scenarios:
        raise TwinError("a sweep needs at least one scenario")
    model = model if model is not None else load_model(default_model_path())
    for h, _ in scenarios:
        parse_scenario(h, model).check(model)  # a bad spec fails before any work
    out = check_folder(out, make=True)
    check_writable(out / "sweep.nc")
    t0 = time.perf_counter()
    rows = mapper(tasks, progress=progress, desc="scenarios")(
        run_scenario, scenarios, model=model, out=str(out), settings=settings
    )
    for (hidden, seed), row in zip(scenarios, rows):
        for category, message in row["warnings"]:
            warnings.warn(f"scenario {hidden}, seed {seed}: {message}", category, stacklevel=2)
    table = tabulate(scenarios, rows, settings, model)
    table.attrs["elapsed_s"] = time.perf_counter() - t0
    write_netcdf(table, out / "sweep.nc")
    log.info(
        "sweep of %d scenarios in %.0f s: %d passed",
        len(scenarios),
        table.attrs["elapsed_s"],
        int(table["passed"].sum()),
    )
    return table


#: What a scenario's summary keeps of each identified parameter (:meth:`twin.harness.demo.DemoResult.identified`);
#: a summary may lack some (NaN in the table).
PARAMETER_VARIABLES = ("map", "std", "q05", "q95", "r_hat", "ess_bulk", "truth", "determined")


def tabulate(
    scenarios: Sequence[tuple[str, int]], rows: Sequence[dict], settings: Settings, model: RotorModel
) -> xr.Dataset:
    """The Dataset of a sweep from the scenarios on ``model`` and their summaries (see :func:`sweep`)."""
    names = sorted({n for r in rows for n in r["parameters"]})
    par = {k: np.full((len(rows), len(names)), np.nan) for k in PARAMETER_VARIABLES}
    for i, r in enumerate(rows):
        for j, n in enumerate(names):
            for k, value in r["parameters"].get(n, {}).items():
                par[k][i, j] = value
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = par["map"] / par["truth"] - 1.0
        z = (par["map"] - par["truth"]) / par["std"]
    before = np.array([r["error_before"] for r in rows])
    after = np.array([r["error_after"] for r in rows])
    after_interval = np.array([r["error_after_interval"] for r in rows], dtype=float).reshape(len(rows), 2)
    fall = 1.0 - after / before
    hidden = [h for h, _ in scenarios]
    parsed = [parse_scenario(h, model) for h in hidden]
    found = np.array([right_diagnosis(sc, r) for sc, r in zip(parsed, rows)])
    within = np.isnan(par["truth"]) | (np.abs(rel) <= MAX_PARAMETER_ERROR)  # no truth: nothing to check
    close = within | (np.abs(z) <= MAX_Z)
    nothing = np.array([not sc.effects for sc in parsed])  # nothing to add and update
    passed = found & (nothing | ((fall >= MIN_FALL) & close.all(axis=1)))
    strict = found & (nothing | ((fall >= MIN_FALL) & within.all(axis=1)))
    dims, pdims = ("scenario",), ("scenario", "parameter")
    return xr.Dataset(
        {
            "verdict": (dims, [r["verdict"] for r in rows]),
            "missing": (
                dims,
                [r["missing"] for r in rows],
                {"long_name": "effects the loop named, joined by + ('' for none)"},
            ),
            "expected": (dims, [sc.expected() for sc in parsed], {"long_name": "the right diagnosis"}),
            "final_verdict": (
                dims,
                [r["final_verdict"] for r in rows],
                {"long_name": "verdict of the loop's last round"},
            ),
            "rounds": (dims, [r["rounds"] for r in rows], {"long_name": "diagnosis rounds of the loop"}),
            "chi2_before": (dims, [r["chi2_before"] for r in rows], {"long_name": "chi2 of the model before the loop"}),
            "chi2_after": (dims, [r["chi2_after"] for r in rows], {"long_name": "chi2 after the loop"}),
            "n_data": (
                dims,
                [r["n_data"] for r in rows],
                {"long_name": "data of the comparison (2 per measured mode)"},
            ),
            "top_score": (dims, [r["top_score"] for r in rows], {"long_name": "log Bayes factor of the top candidate"}),
            "lead": (dims, [r["lead"] for r in rows], {"long_name": "log Bayes factor of the top over the runner-up"}),
            "error_before": (dims, before, {"units": "1", "long_name": "overall error E before the update"}),
            "error_after": (dims, after, {"units": "1", "long_name": "overall error E after the update"}),
            "error_after_low": (
                dims,
                after_interval[:, 0],
                {
                    "units": "1",
                    "long_name": "5% quantile of E after the update over its posterior (NaN: no sampler's posterior)",
                },
            ),
            "error_after_high": (
                dims,
                after_interval[:, 1],
                {"units": "1", "long_name": "95% quantile of E after the update over its posterior"},
            ),
            "fall": (dims, fall, {"units": "1", "long_name": "1 - E after / E before"}),
            "found": (
                dims,
                found,
                {
                    "long_name": "the diagnosis is right: exactly the hidden effects named, nothing "
                    "missing with none hidden, unexplained at the hidden local change"
                },
            ),
            "passed": (
                dims,
                passed,
                {
                    "long_name": f"found, fall >= {MIN_FALL}, every parameter within "
                    f"{MAX_PARAMETER_ERROR:.0%} or {MAX_Z:g} std of its truth"
                },
            ),
            "passed_strict": (
                dims,
                strict,
                {
                    "long_name": f"found, fall >= {MIN_FALL}, every parameter within "
                    f"{MAX_PARAMETER_ERROR:.0%} of its truth"
                },
            ),
            "location": (
                dims,
                [r["location"] for r in rows],
                {
                    "long_name": "local change the diagnosis points to when "
                    "the library does not explain the data ('' for none)"
                },
            ),
            "elapsed_s": (dims, [r["elapsed_s"] for r in rows], {"units": "s"}),
            "map": (pdims, par["map"], {"units": "SI", "long_name": "identified value (posterior MAP)"}),
            "std": (pdims, par["std"], {"units": "SI", "long_name": "posterior standard deviation"}),
            "q05": (pdims, par["q05"], {"units": "SI", "long_name": "5% posterior quantile"}),
            "q95": (pdims, par["q95"], {"units": "SI", "long_name": "95% posterior quantile"}),
            "r_hat": (pdims, par["r_hat"], {"units": "1", "long_name": "R-hat over the chains (NaN: Laplace)"}),
            "ess_bulk": (
                pdims,
                par["ess_bulk"],
                {"units": "1", "long_name": "bulk ESS over the chains (NaN: Laplace)"},
            ),
            "truth": (pdims, par["truth"], {"units": "SI"}),
            "determined": (
                pdims,
                par["determined"],
                {
                    "units": "1",
                    "long_name": "1: determined by the data, 0: reported as not determined (NaN: not identified)",
                },
            ),
            "relative_error": (pdims, rel, {"units": "1", "long_name": "MAP / truth - 1"}),
            "z": (pdims, z, {"units": "1", "long_name": "(MAP - truth) / std"}),
        },
        coords={"hidden": (dims, hidden), "seed": (dims, [s for _, s in scenarios]), "parameter": names},
        attrs={
            "title": "twin scenario sweep",
            "producer": f"twin {__version__}",
            "settings": json.dumps(dataclasses.asdict(settings)),
        },
    )
