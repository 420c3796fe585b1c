"""The twin: a model, the measured modes, and the history of what was done to the model.

Each step (the start, an added effect, an update) records the model it left
and its error against the measured modes, so the history shows the error
falling step by step. :meth:`Twin.run` goes round the loop to the end:
diagnose, add every effect found missing, update jointly all the effects
added so far, diagnose again, until nothing new is missing.
"""

from __future__ import annotations

import json
import logging
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import xarray as xr

from twin.defaults import MAX_ROUNDS
from twin.errors import TwinError, TwinWarning, UpdateError
from twin.fem.effects import effect_label, free_names, holds, is_per_mode_name
from twin.fem.model import RotorModel
from twin.loop.candidates import add_effects
from twin.loop.compare import compare
from twin.loop.diagnose import Diagnosis, diagnose
from twin.loop.history import error_interval, history_dataset, plot_history
from twin.modes.measured import TOLERANCE, Measured, measured_modes
from twin.update.posterior import is_laplace

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Step:
    """One step of the history: what was done, the model after it, and its comparison."""

    action: str
    model: RotorModel
    table: xr.Dataset
    #: the 90% interval of E over the posterior of the update the step made (:func:`twin.loop.history.error_interval`)
    interval: tuple[float, float] | None = None

    @property
    def error(self) -> float:
        """The overall error ``E`` after the step (a fraction)."""
        return float(self.table.attrs["error"])


class Twin:
    """A model with measured modes and the history of its updates.

    Parameters
    ----------
    model : RotorModel
    modes : xarray.Dataset
        Measured modes (``modes.nc`` layout).
    tolerance : float
        Relative pole uncertainty accepted as model-form error.

    Examples
    --------
    >>> from twin.loop import Twin
    >>> from twin.fem.effects import MagneticPull
    >>> from twin.fem.truthfile import Truth
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> data = synthesize_modes(model, Truth((MagneticPull(-1e8),)), n_modes=13, samples=50, seed=3,
    ...                         pole_variance=(0.01, 0.01))
    >>> tw = Twin(model, data)
    >>> tw.diagnose(candidates=["magnetic_pull", "seal_cross_coupling"]).missing
    ('magnetic_pull',)
    >>> _ = tw.add_effect("magnetic_pull")
    >>> _ = tw.update(["MAG.stiffness"], draws=200, chains=1, seed=1, progress=False)
    >>> [round(100 * s.error, 2) for s in tw.history]
    [0.18, 0.18, 0.01]
    """

    def __init__(self, model: RotorModel, modes: xr.Dataset, tolerance: float = TOLERANCE) -> None:
        self.modes = modes
        self.tolerance = tolerance
        self.measured: Measured = measured_modes(modes, tolerance)
        self.history: list[Step] = []
        self.added: list[str] = []  # labels of the effects the loop added
        self.diagnoses: list[Diagnosis] = []
        self.posterior: xr.DataTree | None = None  # of the last update
        self._record("start", model)

    @property
    def model(self) -> RotorModel:
        """The model after the last step."""
        return self.history[-1].model

    def _record(self, action: str, model: RotorModel, posterior: xr.DataTree | None = None) -> Step:
        """Append a step; with the sampler's ``posterior`` (of the update from the last model), E's interval too."""
        interval = None if posterior is None else error_interval(self.model, posterior, self.measured)
        step = Step(action, model, compare(model, self.measured), interval)
        self.history.append(step)
        log.info(
            "%s: error %.3f%%%s",
            action,
            100 * step.error,
            "" if interval is None else f" (90% over the posterior: {100 * interval[0]:.3g}-{100 * interval[1]:.3g}%)",
        )
        return step

    def compare(self) -> xr.Dataset:
        """The comparison table of the current model (see :func:`twin.loop.compare.compare`)."""
        return self.history[-1].table

    def diagnose(self, candidates: Sequence[str] | None = None, **kwargs) -> Diagnosis:
        """Where the current model fails and which library effects are missing (the effects it has refitted)."""
        d = diagnose(self.model, self.measured, candidates=candidates, tolerance=self.tolerance, **kwargs)
        self.diagnoses.append(d)
        return d

    def add_effect(self, label: str) -> Step:
        """Add a library effect, zero-valued (the error is unchanged until an update).

        A per-mode effect (``fsi_per_mode``) takes one value per measured mode.
        """
        step = self._record(f"add {label} at zero", add_effects(self.model, [label], self.measured.mode))
        self.added.append(label)
        return step

    def _drop_replaced(self, label: str) -> None:
        """Before an effect comes in, the effects the loop added that it holds go (per-mode FSI holds the
        mode-independent FSI: :func:`twin.fem.effects.holds`)."""
        import dataclasses

        for old in [a for a in self.added if holds(label, a)]:
            gone = [e for e in self.model.effects if effect_label(e) == old]
            names = {p.name for e in gone for p in e.parameters(self.model)}
            model = dataclasses.replace(
                self.model,
                effects=tuple(e for e in self.model.effects if e not in gone),
                values={k: v for k, v in self.model.values.items() if k not in names},
            )
            self._record(f"drop {old} ({label} holds it)", model)
            self.added.remove(old)

    def added_parameters(self) -> list[str]:
        """The parameters of every effect the loop added (a per-mode effect's for the measured modes)."""
        labels = set(self.added)
        return [
            n
            for e in self.model.effects
            if effect_label(e) in labels
            for n in free_names(self.model, e, self.measured.mode)
        ]

    def run(
        self,
        *,
        method: str = "hmc",
        max_rounds: int = MAX_ROUNDS,
        candidates: Sequence[str] | None = None,
        tasks: Any = None,
        progress: bool = False,
        **kwargs,
    ) -> Diagnosis:
        """Go round the loop to the end; returns the last diagnosis.

        Each round diagnoses the current model; when it names effects the
        model does not have yet, they are added and every effect the loop
        has added is updated jointly (``method`` and ``kwargs`` as
        :meth:`update`); where the sampler cannot take them (the HMC's
        marginal model needs every parametrised DOF observed or condensable),
        they are fitted by the Laplace approximation instead, with a warning,
        so the round's diagnosis is not lost. The loop stops when a diagnosis names nothing new
        ("nothing missing", "unexplained", "not enough data", or the same
        effects again), or after ``max_rounds`` rounds. The last update's
        posterior is then calibrated on records simulated at its estimate, on
        ``tasks`` (:meth:`calibrate`): ``bootstrap=R`` (in ``kwargs``) records,
        by default :data:`twin.defaults.DEFAULT_RECORDS` when the modes
        were extracted from a record and the method is the sampler's
        (:func:`twin.loop.bootstrap.records_for`); ``bootstrap=0``: none.
        ``progress`` draws
        bars over the candidate fits (and the chains) on a terminal; each
        round's stages are logged on ``twin.progress`` (:mod:`twin.progress`).

        Examples
        --------
        >>> from twin.fem.effects import MagneticPull, SealCrossCoupling
        >>> from twin.fem.truthfile import Truth
        >>> from twin.update import synthesize_modes
        >>> model = hydro_unit
        >>> truth = Truth((MagneticPull(-1.5e8), SealCrossCoupling(4e7)))
        >>> tw = Twin(model, synthesize_modes(model, truth, n_modes=13, samples=50, seed=1, pole_variance=(0.01, 0.01)))
        >>> tw.run(candidates=["magnetic_pull", "seal_cross_coupling", "thrust_tilt:thrust"], draws=200, chains=2,
        ...        seed=1).verdict
        'nothing missing'
        >>> [s.action for s in tw.history]  # doctest: +NORMALIZE_WHITESPACE
        ['start', 'add seal_cross_coupling at zero', 'add magnetic_pull at zero', 'update SEAL.kxy, MAG.stiffness']
        >>> abs(tw.model.parameter("MAG.stiffness").nominal / -1.5e8 - 1) < 0.10
        True
        """
        from twin.loop.bootstrap import records_for
        from twin.progress import log as progress_log
        from twin.progress import stage

        bootstrap = records_for(kwargs.pop("bootstrap", None), self.modes, method)
        d = None
        for k in range(1, max_rounds + 1):
            with stage(f"round {k}: diagnose"):
                d = self.diagnose(candidates=candidates, tasks=tasks, progress=progress)
            new = [label for label in d.missing if label not in self.added]
            progress_log.info("round %d: %s%s", k, d.verdict, f" ({', '.join(d.missing)})" if d.missing else "")
            if not new:
                break
            for label in new:
                self._drop_replaced(label)
                self.add_effect(label)
            with stage(f"round {k}: update {', '.join(self.added)} ({method})"):
                extra = {"progress": progress} if method != "laplace" and "progress" not in kwargs else {}
                try:
                    self.update(self.added_parameters(), method=method, bootstrap=0, tasks=tasks, **kwargs, **extra)
                except UpdateError as exc:
                    if method == "laplace":
                        raise
                    # the round's diagnosis stands: its effects are fitted by the Laplace approximation instead
                    warnings.warn(
                        f"round {k}: the {method} update of {', '.join(self.added)} cannot run ({exc}); "
                        "updated by the Laplace approximation of the pole fit instead",
                        TwinWarning,
                        stacklevel=2,
                    )
                    self.update(self.added_parameters(), method="laplace", bootstrap=0)
            progress_log.info(
                "round %d: error E %.3g%% -> %.3g%%", k, 100 * self.history[0].error, 100 * self.history[-1].error
            )
        if (
            bootstrap
            and self.posterior is not None
            and not is_laplace(self.posterior)
            and self.history[-1].action.startswith("update")
        ):
            with stage(f"calibrate the posterior on {bootstrap} simulated records"):
                self._calibrate_or_keep(bootstrap, seed=kwargs.get("seed"), tasks=tasks, progress=progress)
        return d

    def _calibrate_or_keep(self, records: int, **kwargs: Any) -> None:
        """:meth:`calibrate`, or, where the calibration cannot run (its records could not be extracted or
        fitted), the sampler's own posterior kept with a warning saying why: the loop's work is not lost."""
        try:
            self.calibrate(records, **kwargs)
        except TwinError as exc:
            warnings.warn(
                f"the posterior could not be calibrated on simulated records ({exc}); it is the sampler's "
                "own, uncalibrated: its intervals may be too narrow",
                TwinWarning,
                stacklevel=3,
            )
            last = self.history[-1]
            if last.interval is None:  # recorded for a calibration that did not come: E's interval of its own
                self.history.pop()
                self._record(last.action + " (not calibrated)", last.model, self.posterior)

    def update(
        self,
        params: str | Sequence[str],
        *,
        method: str = "hmc",
        options: Any = None,
        estimate: str = "map",
        bootstrap: int | None = None,
        priors: Any = "plausible",
        tasks: Any = None,
        **fields: Any,
    ) -> xr.DataTree:
        """Bayesian update of ``params``, then the model at the posterior estimate.

        Parameters
        ----------
        params : str or sequence of str
            Parameter names, or a group such as ``"bearings"``.
        method : {"hmc", "gibbs", "paper", "laplace"}
            One of the samplers of :func:`twin.update.update` on pole and shape samples (``"hmc"``, the
            default; ``options``, ``priors`` and ``tasks`` go to it, and ``fields`` are fields of its
            options); or ``"laplace"``: the Gaussian posterior of the pole fit (:mod:`twin.update.laplace`,
            its exact MAP and std in the group ``constant_data``). Either way the posterior DataTree of
            :func:`twin.update.update` is returned.
        estimate : {"map", "mean"}
            Which estimate of a sampler's posterior the model takes.
        bootstrap : int, optional
            Records to simulate at the posterior's estimate to calibrate its spread
            (:meth:`calibrate`; about 11 s a 20-min record on one core, on ``tasks`` when given); 0: none.
            Default: :data:`twin.defaults.DEFAULT_RECORDS` for the HMC sampler on modes extracted
            from a record, none otherwise (:func:`twin.loop.bootstrap.records_for`).
        """
        from twin.update.problem import select_parameters

        per_mode = [] if isinstance(params, str) else [n for n in params if is_per_mode_name(n)]
        names = (
            select_parameters(
                self.model, [n for n in ([params] if isinstance(params, str) else params) if n not in per_mode]
            )
            + per_mode
        )
        label = (
            params
            if isinstance(params, str)
            else (", ".join(params) if len(params) <= 4 else f"{len(params)} parameters ({params[0]}, ...)")
        )
        from twin.loop.bootstrap import records_for

        bootstrap = records_for(bootstrap, self.modes, method)
        from twin.update import LaplaceOptions, apply_posterior, sampler, update

        if method == "laplace":
            if fields or options is not None:
                raise TypeError(f"method 'laplace' takes no sampler options, got {sorted(fields) or options}")
            opts = LaplaceOptions(tolerance=self.tolerance)
        else:
            opts = sampler(method).options(options, **fields)
        if per_mode:  # the update's per-mode FSI covers every mode of the data
            every = [f"FSI.{k}_{int(m)}" for m in self.modes["mode"].values for k in ("added_mass", "added_damping")]
            if sorted(per_mode) != sorted(every):
                raise ValueError(
                    f"the update fits the per-mode FSI of every measured mode at once: give all of {', '.join(every)}"
                )
        shared = [n for n in names if n not in per_mode]
        tree = update(
            self.model, self.modes, shared, fsi=bool(per_mode), method=method, options=opts, priors=priors, tasks=tasks
        )
        if method == "laplace":  # the fit's Gaussian, no spread of E over it in the history
            self._record(f"update {label} (Laplace)", apply_posterior(self.model, tree, "map"))
            self.posterior = tree
            return tree
        # a calibration replaces this step at once, with the interval of its own posterior
        self._record(f"update {label}", apply_posterior(self.model, tree, estimate), None if bootstrap else tree)
        self.posterior = tree
        if bootstrap:
            self._calibrate_or_keep(bootstrap, estimate=estimate, seed=opts.seed, tasks=tasks, progress=opts.progress)
        return self.posterior

    def calibrate(
        self, records: int, *, estimate: str = "map", seed: int | None = None, tasks: Any = None, progress: bool = False
    ) -> xr.DataTree:
        """Calibrate the last update's posterior on ``records`` records simulated at its estimate.

        The model after the update is simulated through its FMU ``records`` times, each record is extracted
        as the measured modes were and fitted with the update's density; every determined parameter's draws
        are stretched by its RMS error over them in the posterior's std, shrunk towards the determined parameters'
        common value (:mod:`twin.loop.bootstrap`; more records when a determined parameter's mode came out of
        too few). The last step
        of the history is replaced by the model at the calibrated posterior's estimate; the posterior (attrs
        ``bootstrap_calibration``, ``bootstrap_records``, group ``bootstrap``) is returned and kept in :attr:`posterior`.
        ``tasks``: where the records run (:func:`twin.tasks.mapper`).
        """
        from twin.loop.bootstrap import bootstrap_factors, calibrated, posterior_labels
        from twin.update import apply_posterior

        last = self.history[-1]
        if self.posterior is None or is_laplace(self.posterior) or not last.action.startswith("update"):
            raise ValueError("calibrate needs the HMC sampler's update (method='hmc') as the twin's last step")
        before, tree = self.history[-2].model, self.posterior
        labels = posterior_labels(tree)
        undetermined = set(json.loads(tree.attrs.get("undetermined", "[]")))
        determined = [p for p in labels if p not in undetermined]
        factors = bootstrap_factors(
            before,
            last.model,
            self.modes,
            tree,
            {p: last.model.parameter(p).nominal for p in labels},
            records=records,
            seed=seed,
            pooled=determined,
            tasks=tasks,
            progress=progress,
        )
        tree = calibrated(tree, factors, determined)
        self.history.pop()
        self._record(
            f"{last.action}, calibrated on {factors.sizes['record']} simulated records",
            apply_posterior(before, tree, estimate),
            tree,
        )
        self.posterior = tree
        return tree

    def posterior_tree(self) -> xr.DataTree:
        """The last update's posterior in the ``posterior.nc`` layout (:func:`twin.update.update`'s)."""
        if self.posterior is None:
            raise ValueError("the twin has no posterior yet: update it first")
        return self.posterior

    def history_table(self) -> xr.Dataset:
        """The error after each step: ``action``, ``error`` and ``chi2`` over dimension ``step``."""
        table = history_dataset(
            [s.action for s in self.history],
            [s.error for s in self.history],
            [float(s.table.attrs["chi2"]) for s in self.history],
            str(self.modes.attrs.get("title", "measured modes")),
            [s.interval for s in self.history],
        )
        table.attrs["error_definition"] = self.history[0].table.attrs["error_definition"]
        return table

    def plot_history(self, path: str | Path) -> Path:
        """Bar chart of the error after each step."""
        return plot_history(self.history_table(), path)
