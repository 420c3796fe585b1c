"""``twin demo``: the whole loop from nothing, on a truth with a hidden effect.

1. export the model as an FMU;
2. simulate the proximeter signals of a truth with one library effect hidden
   (FMI co-simulation through FMPy: runner turbulence, 1X unbalance, 5% noise);
3. extract the modes (automated SSI, jackknife samples);
4. compare the model with them, diagnose the missing effect;
5. add the top-ranked effect, update its parameters, compare again;

and write a report folder: ``report.md``, the figures, ``signals.nc``,
``modes.nc``, ``diagnosis.json``, ``history.csv`` and the FMU.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from twin.errors import TwinError
from twin.fem.effects import BearingChange, FluidAddedMass, MagneticPull, SealCrossCoupling, ThrustTilt
from twin.fem.model import RotorModel
from twin.fem.truthfile import Truth
from twin.loop.compare import error_text
from twin.loop.diagnose import Diagnosis
from twin.loop.history import write_history
from twin.netcdf import atomic_output
from twin.loop.twin import Twin

log = logging.getLogger(__name__)

#: Effects the demo and the hidden-effect tests can hide, with their truth values (SI).
HIDDEN_EFFECTS = {
    "magnetic_pull": MagneticPull(-1e8),
    "seal_cross_coupling": SealCrossCoupling(5e7),
    "fsi": FluidAddedMass(6e4, 2e6),
    "thrust_tilt:thrust": ThrustTilt("thrust", 1e9),
    "bearing_change:LGB": BearingChange("LGB", -3e7, -3e8),
    "bearing_change:UGB": BearingChange("UGB", -2e8, 2e7),
}
# Sizes: each changes the modes well beyond what 20 min of signals resolve (the error E of the truth model
# against its own extracted modes is about 0.07%; 0.2-0.3% unweighted) and keeps the truth stable at
# 134 rpm (a seal cross-coupling of 7e7 N/m already makes it unstable; UGB damping -5e7 N s/m too). The
# tilt stiffness change is 4x its prior scale (half the nominal tilt stiffness): smaller changes move the
# modes too little for 20 min of signals to pin them to 10%; the prior pulls its MAP about 5% low.
#: Jackknife samples per mode of the demo: 80 s blocks of its 20-min record, longer than three time
#: constants (about 3 x 25 s) of the unit's slowest mode, so the sample spread is honest for every mode.
DEMO_SAMPLES = 15
#: ``hidden`` value of a truth with no effect hidden (the false-alarm check).
NOTHING = "none"


@dataclasses.dataclass(frozen=True)
class ShaftStiffnessLoss:
    """A local loss of shaft bending stiffness (a crack, a weakened section): no effect of the library.

    Hidden in a demo's truth, it checks that the diagnosis says no library
    effect explains the discrepancy and points at the element.

    Examples
    --------
    >>> from twin import load_model
    >>> model = load_model("models/hydro_unit.toml")
    >>> weak = ShaftStiffnessLoss(18, 0.5).apply(model)
    >>> weak.shaft[18].material.E / model.shaft[18].material.E
    0.5
    """

    element: int
    factor: float  # remaining fraction of the element's E and G

    def apply(self, model: RotorModel) -> RotorModel:
        """``model`` with the element's Young's and shear moduli times :attr:`factor`."""
        if not 0 < self.factor:
            raise TwinError(f"a shaft stiffness factor must be positive, got {self.factor}")
        if not any(e.n == self.element for e in model.shaft):
            raise TwinError(f"model '{model.name}' has no shaft element {self.element} "
                            f"(elements 0 to {len(model.shaft) - 1})")  # fmt: skip

        def weaken(e):
            mat = dataclasses.replace(e.material, E=self.factor * e.material.E, G=self.factor * e.material.G)
            return dataclasses.replace(e, material=mat)

        return dataclasses.replace(model, shaft=tuple(weaken(e) if e.n == self.element else e for e in model.shaft))

    def describe(self) -> str:
        """The change in words, for reports."""
        return f"shaft element {self.element} at {self.factor:.0%} of its bending stiffness (outside the effects library)"


#: Hidden changes outside the effects library: the diagnosis should call them unexplained and locate them.
OUTSIDE_LIBRARY = {"shaft_stiffness_loss": ShaftStiffnessLoss(18, 0.5)}


def hidden_labels() -> list[str]:
    """Every ``hidden`` value the demo takes: library effects, changes outside the library, :data:`NOTHING`.

    Examples
    --------
    >>> hidden_labels()[-3:]
    ['bearing_change:UGB', 'shaft_stiffness_loss', 'none']
    """
    return [*HIDDEN_EFFECTS, *OUTSIDE_LIBRARY, NOTHING]


def default_model_path() -> Path:
    """The hydro unit model file of the source tree (``models/hydro_unit.toml``)."""
    return Path(__file__).resolve().parents[2] / "models" / "hydro_unit.toml"


def truth_values(model: RotorModel, effect) -> dict[str, float]:
    """The parameter values [SI] an effect has when added to ``model``.

    Examples
    --------
    >>> from twin import load_model
    >>> truth_values(load_model("models/hydro_unit.toml"), HIDDEN_EFFECTS["magnetic_pull"])
    {'MAG.stiffness': -100000000.0}
    """
    return {p.name: p.nominal for p in effect.parameters(dataclasses.replace(model, effects=(effect,)))}


@dataclasses.dataclass(frozen=True)
class DemoResult:
    """What the demo did: the twin (with its history), the diagnosis, the update and where it all went."""

    out: Path
    twin: Twin
    diagnosis: Diagnosis
    posterior: xr.Dataset | None
    truth: dict[str, float]
    timings_s: dict[str, float]
    outside: ShaftStiffnessLoss | None = None  # the hidden change, when it is outside the effects library

    def hidden_text(self) -> str:
        """What the truth hides, in words."""
        if self.outside is not None:
            return self.outside.describe()
        return ", ".join(f"{n} = {v:.4g}" for n, v in self.truth.items()) or "nothing"

    @property
    def report(self) -> Path:
        return self.out / "report.md"

    def identified(self) -> xr.Dataset:
        """The update's ``map``, ``std``, ``unit`` with the ``truth`` and the ``relative_error`` (NaN without a truth)."""
        post = self.posterior
        truth = np.array([self.truth.get(str(n), np.nan) for n in post["parameter"].values])
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(truth != 0, post["map"].values / truth - 1.0, np.nan)
        return post.assign(truth=("parameter", truth, {"units": "SI"}),
                           relative_error=("parameter", rel, {"units": "1", "long_name": "MAP / truth - 1"}))  # fmt: skip


def run_demo(
    out: str | Path = "twin-demo",
    *,
    model: RotorModel | None = None,
    hidden: str = "magnetic_pull",
    duration_s: float = 1200.0,
    fs_hz: float = 256.0,
    samples: int = DEMO_SAMPLES,
    fmax_hz: float = 60.0,
    seed: int = 1,
    progress: bool = True,
    tasks: Any = None,
) -> DemoResult:
    """Run the loop end to end on a truth with ``hidden`` and write the report folder ``out``.

    Parameters
    ----------
    out : path
        Report folder (created; files in it are replaced).
    model : RotorModel, optional
        The twin's model (default: :func:`default_model_path`).
    hidden : str
        Label of the hidden effect, a key of :data:`HIDDEN_EFFECTS`, a change
        outside the library (a key of :data:`OUTSIDE_LIBRARY`), or
        :data:`NOTHING` for a truth that is the model itself.
    duration_s, fs_hz : float
        Record length [s] and sampling rate [Hz] of the simulated signals.
    samples : int
        Jackknife samples per mode.
    fmax_hz : float
        Highest frequency of the extraction [Hz].
    seed : int
        Seed of the turbulence and the sensor noise.
    progress : bool
        Progress bars.
    tasks : distributed.Client or mapper, optional
        Where the diagnosis's candidate fits run (:func:`twin.tasks.mapper`):
        in this process by default.

    Returns
    -------
    DemoResult
    """
    from twin.extract import extract
    from twin.extract.plot import plot_stabilisation
    from twin.fem import load_model
    from twin.fmu import export_fmu
    from twin.fmu.simulate import simulate
    from twin.loop.plots import _pyplot, comparison_figures

    if hidden not in hidden_labels():
        raise TwinError(f"unknown hidden effect '{hidden}'; choose one of {', '.join(hidden_labels())}")
    if model is None:
        path = default_model_path()
        if not path.exists():
            raise TwinError(f"the demo model {path} is not there (an installed copy without the source tree?): "
                            "give a model file")  # fmt: skip
        model = load_model(path)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    effects = (HIDDEN_EFFECTS[hidden],) if hidden in HIDDEN_EFFECTS else ()
    outside = OUTSIDE_LIBRARY.get(hidden)
    truth = {k: v for e in effects for k, v in truth_values(model, e).items()}
    timings: dict[str, float] = {}

    def stage(name: str, t0: float) -> None:
        timings[name] = time.perf_counter() - t0
        log.info("%s: %.1f s", name, timings[name])

    t0 = time.perf_counter()
    export_fmu(model, out / f"{model.name}.fmu", step_s=1.0 / fs_hz)
    stage("export FMU", t0)
    t0 = time.perf_counter()
    signals = simulate(outside.apply(model) if outside else model, duration_s=duration_s, fs_hz=fs_hz, seed=seed, truth=Truth(effects, source=hidden),
                       output=out / "signals.nc", progress=progress, command="twin demo")  # fmt: skip
    stage("simulate truth (FMU through FMPy)", t0)
    t0 = time.perf_counter()
    modes = extract(signals, samples=samples, fmax_hz=fmax_hz, output=out / "modes.nc", progress=progress,
                    command="twin demo")  # fmt: skip
    fig = plot_stabilisation(modes)
    fig.savefig(out / "stabilisation.png", dpi=110)
    _pyplot().close(fig)
    stage("extract modes", t0)
    t0 = time.perf_counter()
    tw = Twin(model, modes)
    comparison_figures(tw.compare(), out, prefix="before_")
    d = tw.diagnose(tasks=tasks)
    (out / "diagnosis.json").write_text(d.to_json(tw.measured))
    stage("compare and diagnose", t0)
    posterior = None
    t0 = time.perf_counter()
    if d.missing is not None:
        tw.add_effect(d.missing)
        posterior = tw.update(d.ranking[0].names, method="laplace")
        comparison_figures(tw.compare(), out, prefix="after_")
    else:
        log.info("the diagnosis found no missing effect (%s): nothing to add", d.verdict)
    stage("add effect and update", t0)
    tw.plot_history(out / "history.png")
    write_history(tw.history_table(), out / "history.csv")
    result = DemoResult(out, tw, d, posterior, truth, timings, outside)
    write_report(result, modes)
    return result


def _md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + " --- |" * len(header)] + ["| " + " | ".join(r) + " |" for r in rows]


def write_report(result: DemoResult, modes: xr.Dataset) -> Path:
    """Write ``report.md`` of a demo run (figures are already in the folder)."""
    tw, d, meas = result.twin, result.diagnosis, result.twin.measured
    name = tw.history[0].model.name
    if result.outside is None and not result.truth:
        hidden = f"Nothing is hidden: the truth is the twin's model, `{name}`."
    else:
        units = "" if result.outside is not None else " (SI)"
        hidden = f"Hidden in the truth: **{result.hidden_text()}**{units}. The twin's model, `{name}`, does not have it."
    settings = json.loads(modes.attrs["settings"])
    lines = ["# twin demo", "", hidden,
             "", "## What was run", ""]  # fmt: skip
    lines += _md_table(["stage", "time [s]"], [[k, f"{v:.1f}"] for k, v in result.timings_s.items()])
    lines += ["", f"Total: {sum(result.timings_s.values()):.1f} s.", "",
              "## Identified modes", "",
              f"{modes.sizes['mode']} modes, {modes.sizes['sample']} jackknife samples each "
              f"(fmax {settings.get('fmax_hz')} Hz); harmonics rejected: "
              + (", ".join(f"{h['frequency_hz']:.3f} Hz" for h in json.loads(modes.attrs["harmonics"])) or "none")
              + ".", "", "![stabilisation diagram](stabilisation.png)", ""]  # fmt: skip
    before = tw.history[0].table
    lines += ["## Model against measurement", "", f"Error {error_text(before)}.", ""]
    rows = [[str(int(r["mode"])), f"{float(r.measured_frequency):.4f}", f"{float(r.model_frequency):.4f}",
             f"{100 * float(r.frequency_error):+.2f}", f"{100 * float(r.measured_damping_ratio):.3f}",
             f"{100 * float(r.model_damping_ratio):.3f}", f"{float(r.mac):.3f}"]
            for r in (before.isel(mode=k) for k in range(before.sizes["mode"]))]  # fmt: skip
    lines += _md_table(["mode", "f meas [Hz]", "f model [Hz]", "df [%]", "zeta meas [%]", "zeta model [%]", "MAC"], rows)
    lines += ["", "![errors](before_errors.png) ![MAC](before_mac.png)", "", "![spectra](before_spectra.png)", "",
              "## Diagnosis", "", f"Verdict: **{d.verdict}**" + (f" ({d.missing})" if d.missing else "") + ".", "",
              d.summary, ""]  # fmt: skip
    rows = [[str(k), f.label, f"{f.log_bayes_factor:.1f}", f"{100 * f.error_after(meas):.3f}"]
            for k, f in enumerate(d.ranking, start=1)]  # fmt: skip
    lines += _md_table(["rank", "effect", "ln B", "E after fit [%]"], rows)
    lines += ["", "Why:", ""] + [f"- {d.explanations[f.label]}" for f in d.ranking] + [""]
    if result.posterior is not None:
        ident = result.identified()
        lines += ["## Update", "", f"{ident.attrs['method']}.", ""]
        rows = [[str(r["parameter"].values), f"{float(r.truth):.4g}", f"{float(r['map']):.4g}", f"{float(r['std']):.2g}",
                 f"{100 * float(r.relative_error):+.1f}", str(r["unit"].values)]
                for r in (ident.isel(parameter=k) for k in range(ident.sizes["parameter"]))]  # fmt: skip
        lines += _md_table(["parameter", "truth", "MAP", "std", "error [%]", "unit"], rows)
        lines += ["", "![errors after](after_errors.png)", "", "![spectra after](after_spectra.png)", ""]
    lines += ["## History", ""]
    rows = [[str(k), s.action, f"{100 * s.error:.3f}", f"{float(s.table.attrs['chi2']):.1f}"]
            for k, s in enumerate(tw.history)]  # fmt: skip
    lines += _md_table(["step", "action", "E [%]", "chi2"], rows)
    first, last = tw.history[0].error, tw.history[-1].error
    lines += ["", f"The error fell from {100 * first:.2f}% to {100 * last:.3f}% ({100 * (1 - last / first):.1f}% less).",
              "", "![history](history.png)", ""]  # fmt: skip
    path = result.out / "report.md"
    with atomic_output(path, ".md.part") as tmp:
        tmp.write_text("\n".join(lines))
    return path
