"""``twin demo``: the whole loop from nothing, on a truth with hidden changes.

1. export the model as an FMU;
2. simulate the proximeter signals of a truth that hides a scenario
   (:mod:`twin.harness.scenarios`: library effects, a local change outside the
   library, or nothing), by FMI co-simulation through FMPy (runner
   turbulence, 1X unbalance, 5% noise);
3. extract the modes (automated SSI, jackknife samples);
4. go round the loop (:meth:`twin.loop.twin.Twin.run`): compare, diagnose,
   add every effect found missing, update them jointly, diagnose again;

and write a report folder: ``report.md``, the figures, ``signals.nc``,
``modes.nc``, ``diagnosis.json`` (every round), ``history.csv`` and the FMU.
"""

from __future__ import annotations

import dataclasses
import json
import logging
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from twin.defaults import (  # noqa: F401 (shared with the CLI)
    ALGORITHMS,
    DEMO_FMAX_HZ,
    DEMO_RECORDS,
    RECORD_DURATION_S,
    SAMPLES,
    SAMPLING_RATE_HZ,
)
from twin.design.observe import judge_targets, target_lines
from twin.errors import TwinError
from twin.extract.harmonics import line_frequencies
from twin.fem.effects import is_per_mode_name
from twin.fem.model import RotorModel
from twin.harness.scenarios import Scenario, parse_scenario
from twin.loop.bootstrap import check_records
from twin.loop.compare import ERROR_WEIGHTS, error_text
from twin.loop.diagnose import LN_B_KEY, Diagnosis
from twin.loop.history import HISTORY_KEY, INTERVAL_DRAWS, interval_text, write_history
from twin.loop.twin import Twin
from twin.modes.measured import Measured
from twin.modes.modesfile import write_modes
from twin.netcdf import atomic_output, check_folder
from twin.report.html import write_html_report
from twin.update.posterior import is_laplace

log = logging.getLogger(__name__)

#: Shape samples per pole sample (``extract(shape_samples=SHAPE_SAMPLES_PER_SAMPLE * samples)``): the shapes
#: from 60 random halves of the 15 blocks, enough for their covariance over the 16 real entries of a shape on
#: 8 sensors without lifting the directions the bearings are read from (docs/decisions/extraction-shape-samples.md).
SHAPE_SAMPLES_PER_SAMPLE = 4


def _samples_text(settings: dict) -> str:
    """How many jackknife samples each mode has, from a modes file's settings.

    Examples
    --------
    >>> _samples_text({"samples": 15, "shape_samples": 60})
    '15 jackknife samples of the poles and 60 of the shapes (random halves of the blocks) each'
    >>> _samples_text({"samples": 15, "shape_samples": 15})
    '15 jackknife samples each'
    """
    n, m = settings.get("samples"), settings.get("shape_samples", settings.get("samples"))
    if m == n:
        return f"{n} jackknife samples each"
    return f"{n} jackknife samples of the poles and {m} of the shapes (random halves of the blocks) each"


def default_model_path() -> Path:
    """The hydro unit model file shipped with twin (:func:`twin.fem.shipped_model`)."""
    from twin.fem import shipped_model

    return shipped_model("hydro_unit")


def truth_for_measured(truth: dict[str, float], meas: Measured, truth_modes: list[dict]) -> dict[str, float]:
    """Truth values by the twin's parameter names: a per-mode value of target mode ``i`` of the truth goes to
    the measured mode nearest to it in pole (the twin numbers per-mode parameters by measured mode).

    Examples
    --------
    >>> import numpy as np
    >>> from twin.modes.measured import Measured
    >>> meas = Measured(np.array([1, 2]), np.array([-0.1 + 6.3j, -0.2 + 63j]), np.ones((2, 2)), np.ones((2, 1)), ["a"])
    >>> modes = [{"frequency_hz": 1.0, "damping_ratio": 0.01}, {"frequency_hz": 5.0, "damping_ratio": 0.01},
    ...          {"frequency_hz": 10.0, "damping_ratio": 0.01}]
    >>> truth_for_measured({"FSI.added_mass_3": 7.0, "MAG.stiffness": -1.0}, meas, modes)
    {'MAG.stiffness': -1.0, 'FSI.added_mass_2': 7.0}
    """
    out = {k: v for k, v in truth.items() if not is_per_mode_name(k)}
    if not truth_modes or len(out) == len(truth):
        return out
    f = np.array([m["frequency_hz"] for m in truth_modes])
    z = np.array([m["damping_ratio"] for m in truth_modes])
    w = 2 * np.pi * f / np.sqrt(1 - z**2)
    target = w * (-z + 1j * np.sqrt(1 - z**2))
    for label, pole in zip(meas.mode, meas.pole):
        i = int(np.argmin(np.abs(target - pole) / np.abs(pole))) + 1
        for kind in ("added_mass", "added_damping"):
            if f"FSI.{kind}_{i}" in truth:
                out[f"FSI.{kind}_{int(label)}"] = truth[f"FSI.{kind}_{i}"]
    return out


def posterior_table(posterior: xr.DataTree, model: RotorModel) -> xr.Dataset:
    """``map``, ``std``, the 90% interval ``q05``-``q95``, ``r_hat``, ``ess_bulk``, ``unit`` and ``determined`` over ``parameter``.

    ``determined`` is False for the parameters the update reports as not determined by the data
    (the posterior's ``undetermined`` attr; the Laplace fit reports none).

    From a sampler's posterior (:func:`twin.update.update`'s DataTree: its
    :func:`twin.update.summary`) or a Laplace one (the fit's exact MAP and std in ``constant_data``:
    Gaussian quantiles, no R-hat or ESS, which are NaN). The attr ``method`` says which.
    """
    from twin.update import summary

    if not is_laplace(posterior):
        table = summary(posterior["posterior"].to_dataset())
        for key in ("r_hat", "ess_bulk"):
            if key not in table:  # one chain has no R-hat
                table[key] = ("parameter", np.full(table.sizes["parameter"], np.nan))
        units = [model.parameter(str(n)).unit for n in table["parameter"].values]
        settings = json.loads(posterior.attrs.get("settings", "{}"))
        runs = f"{settings.get('chains', '?')} chains x {settings.get('draws', '?')} draws"
        kind = posterior.attrs.get("method", "hmc")
        if kind == "hmc":
            method = f"APerCEM, HMC on the marginal (pole deviations and shapes integrated out), {runs}"
        else:
            method = f"APerCEM, {posterior.attrs.get('sampler', kind)}, {runs}"
        undetermined = set(json.loads(posterior.attrs.get("undetermined", "[]")))
        determined = [str(n) not in undetermined for n in table["parameter"].values]
        return (
            table[["map", "std", "q05", "q95", "r_hat", "ess_bulk"]]
            .assign(unit=("parameter", units), determined=("parameter", determined))
            .assign_attrs(method=method)
        )
    fit = posterior["constant_data"].to_dataset()
    units = [model.parameter(str(n)).unit for n in fit["parameter"].values]
    z = 1.6448536269514722  # the 95% point of the standard normal
    nan = np.full(fit.sizes["parameter"], np.nan)
    return xr.Dataset(
        {
            "map": fit["map"],
            "std": fit["std"],
            "q05": fit["map"] - z * fit["std"],
            "q95": fit["map"] + z * fit["std"],
            "r_hat": ("parameter", nan),
            "ess_bulk": ("parameter", nan),
            "unit": ("parameter", units),
            "determined": ("parameter", np.full(fit.sizes["parameter"], True)),
        },
        attrs={"method": posterior.attrs["method"]},
    )


@dataclasses.dataclass(frozen=True)
class DemoResult:
    """What the demo did: the scenario, the twin (with its history and diagnoses), the update, where it went."""

    out: Path
    scenario: Scenario
    twin: Twin
    truth: dict[str, float]  # by the twin's parameter names
    timings_s: dict[str, float]
    model: RotorModel

    @property
    def diagnosis(self) -> Diagnosis:
        """The first round's diagnosis."""
        return self.twin.diagnoses[0]

    @property
    def final(self) -> Diagnosis:
        """The last round's diagnosis."""
        return self.twin.diagnoses[-1]

    @property
    def named(self) -> tuple[str, ...]:
        """Every effect the loop added."""
        return tuple(self.twin.added)

    @property
    def posterior(self) -> xr.DataTree | None:
        """The posterior of the last update, a sampler's or the Laplace fit's (None when nothing was added)."""
        return self.twin.posterior

    def hidden_text(self) -> str:
        """What the truth hides, in words."""
        return self.scenario.describe(self.model)

    @property
    def report(self) -> Path:
        return self.out / "report.md"

    def identified(self) -> xr.Dataset:
        """The update's :func:`posterior_table` with the ``truth`` and the ``relative_error`` (NaN without a truth)."""
        post = posterior_table(self.posterior, self.twin.model)
        truth = np.array([self.truth.get(str(n), np.nan) for n in post["parameter"].values])
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(truth != 0, post["map"].values / truth - 1.0, np.nan)
        return post.assign(
            truth=("parameter", truth, {"units": "SI"}),
            relative_error=("parameter", rel, {"units": "1", "long_name": "MAP / truth - 1"}),
        )


def check_demo(
    out: str | Path, model: RotorModel | None, hidden: str, method: str = "hmc", bootstrap: int | None = None
) -> tuple[RotorModel, Scenario, Path]:
    """Check the demo's inputs before any work (and before a cluster starts): the model, what is hidden, the
    method and its calibration, the report folder. Returns the model, the scenario and the (made) folder.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     model, scenario, out = check_demo(tmp, None, "magnetic_pull@2")
    >>> scenario.labels
    ('magnetic_pull',)
    """
    from twin.fem import load_model

    check_records(bootstrap, method)
    if model is None:
        path = default_model_path()
        if not path.exists():
            raise TwinError(
                f"the demo model {path} is not there (an installed copy without the source tree?): give a model file"
            )
        model = load_model(path)
    scenario = parse_scenario(hidden, model)
    scenario.check(model)
    return model, scenario, check_folder(out)


def run_demo(
    out: str | Path = "twin-demo",
    *,
    model: RotorModel | None = None,
    hidden: str = "magnetic_pull",
    duration_s: float = RECORD_DURATION_S,
    fs_hz: float = SAMPLING_RATE_HZ,
    samples: int = SAMPLES,
    fmax_hz: float = DEMO_FMAX_HZ,
    seed: int = 1,
    algorithm: str = ALGORITHMS[0],
    method: str = "hmc",
    bootstrap: int | None = None,
    progress: bool = True,
    tasks: Any = None,
) -> DemoResult:
    """Run the loop end to end on a truth that hides ``hidden`` and write the report folder ``out``.

    Parameters
    ----------
    out : path
        Report folder (created; files in it are replaced).
    model : RotorModel, optional
        The twin's model (default: :func:`default_model_path`).
    hidden : str
        What the truth hides: a scenario spec (:func:`twin.harness.scenarios.parse_scenario`),
        e.g. ``magnetic_pull``, ``magnetic_pull@2.5+seal_cross_coupling``,
        ``disk_mass:generator@1.1`` or ``none``.
    duration_s, fs_hz : float
        Record length [s] and sampling rate [Hz] of the simulated signals.
    samples : int
        Jackknife samples per mode (delete-one, the poles'); the shapes get
        :data:`SHAPE_SAMPLES_PER_SAMPLE` times as many, random halves of the
        same blocks (``extract(shape_samples=...)``).
    fmax_hz : float
        Highest frequency of the extraction [Hz].
    algorithm : {"ssi", "plscf"}
        How the extraction reads the modes (:mod:`twin.extract.algorithms`).
    seed : int
        Seed of the turbulence and the sensor noise (and of the sampler's chains).
    method : {"hmc", "gibbs", "paper", "laplace"}
        How each round updates the effects the loop added: one of the APerCEM
        samplers of :func:`twin.update.update` (the default: HMC on the marginal,
        4 chains x 500 draws) or the Laplace approximation of the pole fit
        (:func:`twin.update.laplace.laplace_update`).
    bootstrap : int, optional
        HMC only: records simulated at the last update's estimate to
        calibrate its spread (:mod:`twin.loop.bootstrap`; about 11 s a 20-min
        record on one core, on ``tasks``); default :data:`~twin.defaults.DEMO_RECORDS` with
        the sampler (the loop's default is
        :data:`twin.defaults.DEFAULT_RECORDS`); 0: none.
    progress : bool
        Progress bars.
    tasks : distributed.Client or mapper, optional
        Where the diagnosis's candidate fits (and the bootstrap's records) run
        (:func:`twin.tasks.mapper`): in this process by default.

    Returns
    -------
    DemoResult
    """
    from twin.extract import extract
    from twin.extract.plot import plot_stabilisation
    from twin.fmu import export_fmu
    from twin.fmu.simulate import simulate
    from twin.progress import stage
    from twin.report.figures import comparison_figures, pyplot

    model, scenario, out = check_demo(out, model, hidden, method, bootstrap)
    out.mkdir(parents=True, exist_ok=True)
    if bootstrap is None and method == "hmc":
        bootstrap = DEMO_RECORDS
    timings: dict[str, float] = {}
    with stage("export FMU", timings):
        export_fmu(model, out / f"{model.name}.fmu", step_s=1.0 / fs_hz)
    with stage("simulate truth (FMU through FMPy)", timings):
        signals = simulate(
            model,
            duration_s=duration_s,
            fs_hz=fs_hz,
            seed=seed,
            truth=scenario.truth(),
            output=out / "signals.nc",
            progress=progress,
            command="twin demo",
        )
    with stage("extract modes", timings):
        modes = extract(
            signals,
            samples=samples,
            shape_samples=SHAPE_SAMPLES_PER_SAMPLE * samples,
            fmax_hz=fmax_hz,
            algorithm=algorithm,
            progress=progress,
            command="twin demo",
        )
        modes = judge_targets(modes, signals)
        write_modes(modes, out / "modes.nc")
        fig = plot_stabilisation(modes)
        fig.savefig(out / "stabilisation.png", dpi=110)
        pyplot().close(fig)
    with stage("diagnose, add, update (loop rounds)", timings):
        tw = Twin(model, modes)
        tw.run(
            method=method,
            tasks=tasks,
            progress=progress,
            **({"seed": seed} if method != "laplace" else {}),
            **({"bootstrap": bootstrap} if method == "hmc" else {}),
        )
    meas = tw.measured
    with atomic_output(out / "diagnosis.json", ".json.part") as tmp:
        tmp.write_text(json.dumps({"rounds": [d.to_dict(meas) for d in tw.diagnoses]}, indent=2))
    if tw.added:
        comparison_figures([tw.history[0].table, tw.compare()], out, labels=["before", "after"], signals=signals)
    else:
        comparison_figures(tw.history[0].table, out, labels=["model"], signals=signals)
    tw.plot_history(out / "history.png")
    write_history(tw.history_table(), out / "history.csv")
    truth = truth_for_measured(scenario.truth_values(model), meas, json.loads(modes.attrs.get("truth_modes", "[]")))
    result = DemoResult(out, scenario, tw, truth, timings, model)
    write_report(result, modes)
    return result


def _diag(value: float, fmt: str) -> str:
    return "-" if not np.isfinite(value) else format(value, fmt)


def _md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)] + [
        "| " + " | ".join(r) + " |" for r in rows
    ]


def write_report(result: DemoResult, modes: xr.Dataset) -> Path:
    """Write ``report.md`` of a demo run and ``report.html``, the same with the figures embedded."""
    tw, d, meas = result.twin, result.diagnosis, result.twin.measured
    name = tw.history[0].model.name
    if result.scenario.nothing:
        hidden = f"Nothing is hidden: the truth is the twin's model, `{name}`."
    else:
        hidden = (
            f"Hidden in the truth: **{result.hidden_text()}** (SI; spec `{result.scenario.spec}`). "
            f"The twin's model, `{name}`, does not have it. The right diagnosis: {result.scenario.expected()}."
        )
    settings = json.loads(modes.attrs["settings"])
    removed, rejected = (
        ", ".join(f"{f:.3f} Hz" for f in fs) or "none" for fs in line_frequencies(modes.attrs["harmonics"])
    )
    lines = ["# twin demo", "", hidden, "", "## What was run", ""]
    lines += _md_table(["stage", "time [s]"], [[k, f"{v:.1f}"] for k, v in result.timings_s.items()])
    lines += [
        "",
        f"Total: {sum(result.timings_s.values()):.1f} s.",
        "",
        "## Identified modes",
        "",
        f"{modes.sizes['mode']} modes, {_samples_text(settings)} "
        f"(fmax {settings.get('fmax_hz')} Hz); running-speed lines removed before SSI: {removed}; "
        f"harmonics rejected: {rejected}.",
        *[f"\n{line}." for line in target_lines(modes.attrs)],
        "",
        "![stabilisation diagram](stabilisation.png)",
        "",
    ]
    before = tw.history[0].table
    lines += ["## Model against measurement", "", f"Error {error_text(before)}. {ERROR_WEIGHTS}.", ""]
    rows = [
        [
            str(int(r["mode"])),
            f"{float(r.measured_frequency):.4f}",
            f"{float(r.model_frequency):.4f}",
            f"{100 * float(r.frequency_error):+.2f}",
            f"{100 * float(r.measured_damping_ratio):.3f}",
            f"{100 * float(r.model_damping_ratio):.3f}",
            f"{float(r.mac):.3f}",
        ]
        for r in (before.isel(mode=k) for k in range(before.sizes["mode"]))
    ]
    lines += _md_table(
        ["mode", "f meas [Hz]", "f model [Hz]", "df [%]", "zeta meas [%]", "zeta model [%]", "MAC"], rows
    )
    lines += [
        "",
        "The model's errors per measured mode"
        + (" before and after the update, on one scale" if tw.added else "")
        + "; the bars at zero are the measurement's own standard uncertainty:",
        "",
        "![errors](errors.png)",
        "",
        "The MAC of each measured mode against the model modes near the band (red: the model mode paired with it):",
        "",
        "![MAC](mac.png)",
        "",
        "The record's power spectral density per channel, with the identified modes (black) and the model's "
        "partners (dashed) marked:",
        "",
        "![spectra](spectra.png)",
        "",
        "## Diagnosis",
        "",
    ]
    for k, dk in enumerate(tw.diagnoses, start=1):
        lines += [
            f"Round {k}: **{dk.verdict}**" + (f" ({', '.join(dk.missing)})" if dk.missing else "") + ".",
            "",
            dk.summary,
            "",
        ]
    lines += ["Round 1, every candidate fitted alone:", ""]
    rows = [
        [str(k), f.label, f"{f.log_bayes_factor:.1f}", f"{100 * f.error_after(meas):.3f}"]
        for k, f in enumerate(d.ranking, start=1)
    ]
    lines += _md_table(["rank", "effect", "ln B", "E after fit [%]"], rows)
    lines += ["", LN_B_KEY + ".", "", "Why:", ""] + [f"- {d.explanations[f.label]}" for f in d.ranking] + [""]
    if result.posterior is not None:
        ident = result.identified()
        lines += [
            "## Update",
            "",
            f"Every effect the loop added ({', '.join(tw.added)}), jointly: {ident.attrs['method']}.",
            "",
        ]
        rows = [
            [
                str(r["parameter"].values) + ("" if bool(r.determined) else " (not determined)"),
                f"{float(r.truth):.4g}",
                f"{float(r['map']):.4g}",
                f"{float(r.q05):.4g} to {float(r.q95):.4g}",
                f"{float(r['std']):.2g}",
                _diag(float(r.r_hat), ".3f"),
                _diag(float(r.ess_bulk), ".0f"),
                f"{100 * float(r.relative_error):+.1f}",
                str(r["unit"].values),
            ]
            for r in (ident.isel(parameter=k) for k in range(ident.sizes["parameter"]))
        ]
        lines += _md_table(
            ["parameter", "truth", "MAP", "90% interval", "std", "R-hat", "ESS", "error [%]", "unit"], rows
        )
        lines += [
            "",
            "R-hat (at most 1.01 when the chains agree) and the bulk ESS over all chains are the "
            "sampler's own diagnostics (ArviZ); '-' where the method has none. A parameter marked not "
            "determined has a posterior std over half its size: its interval is what the data allow.",
            "",
        ]
        calibration = json.loads(result.posterior.attrs.get("bootstrap_calibration", "null"))
        if calibration is not None:
            records = len(json.loads(result.posterior.attrs["bootstrap_records"]))
            lines += [
                f"The intervals are calibrated on {records} records simulated at the estimate "
                "(twin.loop.bootstrap): each determined parameter's draws stretched by its RMS error over "
                "those records in the posterior's std: "
                + (", ".join(f"{k} x{v:.2f}" for k, v in calibration.items()) or "none determined")
                + ".",
                "",
            ]
    lines += ["## History", ""]
    rows = [
        [str(k), s.action, f"{100 * s.error:.3f}", interval_text(s.interval), f"{float(s.table.attrs['chi2']):.1f}"]
        for k, s in enumerate(tw.history)
    ]
    lines += _md_table(["step", "action", "E [%]", "E, 90% over the posterior [%]", "chi2"], rows)
    lines += [
        "",
        f"{HISTORY_KEY}. The interval is E's spread over the update's posterior: E of the model at {INTERVAL_DRAWS} of "
        "its draws (twin.loop.history.error_interval). E is not the density the update fits, so E at the "
        "estimate need not be the interval's least.",
    ]
    first, last = tw.history[0].error, tw.history[-1].error
    lines += [
        "",
        f"The error fell from {100 * first:.2f}% to {100 * last:.3f}% ({100 * (1 - last / first):.1f}% less).",
        "",
        "![history](history.png)",
        "",
    ]
    path = result.out / "report.md"
    with atomic_output(path, ".md.part") as tmp:
        tmp.write_text("\n".join(lines))
    write_html_report(path, title=f"twin demo: {result.scenario.spec}")
    return path
