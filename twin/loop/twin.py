"""The twin: a model, the measured modes, and the history of what was done to the model.

Each step (the start, an added effect, an update) records the model it left
and its error against the measured modes, so the history shows the error
falling step by step.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import xarray as xr

from twin.fem.model import RotorModel
from twin.loop.candidates import add_effects
from twin.loop.compare import TOLERANCE, Measured, compare, measured_modes
from twin.loop.diagnose import Diagnosis, diagnose
from twin.loop.fit import laplace_update
from twin.loop.history import history_dataset, plot_history

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Step:
    """One step of the history: what was done, the model after it, and its comparison."""

    action: str
    model: RotorModel
    table: xr.Dataset

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
    >>> from twin import load_model
    >>> from twin.fem.effects import MagneticPull
    >>> from twin.fem.truthfile import Truth
    >>> from twin.update import synthesize_modes
    >>> model = load_model("models/hydro_unit.toml")
    >>> data = synthesize_modes(model, Truth((MagneticPull(-1e8),)), n_modes=13, samples=50, seed=3,
    ...                         pole_variance=(0.01, 0.01))
    >>> tw = Twin(model, data)
    >>> tw.diagnose(candidates=["magnetic_pull", "seal_cross_coupling"]).missing
    'magnetic_pull'
    >>> _ = tw.add_effect("magnetic_pull")
    >>> _ = tw.update(["MAG.stiffness"], draws=200, chains=1, seed=1, progress=False)
    >>> [round(100 * s.error, 2) for s in tw.history]
    [2.74, 2.74, 0.04]
    """

    def __init__(self, model: RotorModel, modes: xr.Dataset, tolerance: float = TOLERANCE) -> None:
        self.modes = modes
        self.tolerance = tolerance
        self.measured: Measured = measured_modes(modes, tolerance)
        self.history: list[Step] = []
        self._record("start", model)

    @property
    def model(self) -> RotorModel:
        """The model after the last step."""
        return self.history[-1].model

    def _record(self, action: str, model: RotorModel) -> Step:
        step = Step(action, model, compare(model, self.measured))
        self.history.append(step)
        log.info("%s: error %.3f%%", action, 100 * step.error)
        return step

    def compare(self) -> xr.Dataset:
        """The comparison table of the current model (see :func:`twin.loop.compare.compare`)."""
        return self.history[-1].table

    def diagnose(self, candidates: Sequence[str] | None = None, **kwargs) -> Diagnosis:
        """Where the current model fails and which library effect is missing."""
        return diagnose(self.model, self.measured, candidates=candidates, tolerance=self.tolerance, **kwargs)

    def add_effect(self, label: str) -> Step:
        """Add a library effect, zero-valued (the error is unchanged until an update)."""
        return self._record(f"add {label}", add_effects(self.model, [label]))

    def update(
        self, params: str | Sequence[str], *, method: str = "gibbs", estimate: str = "map", **kwargs
    ) -> xr.DataTree | xr.Dataset:
        """Bayesian update of ``params``, then the model at the posterior estimate.

        Parameters
        ----------
        params : str or sequence of str
            Parameter names, or a group such as ``"bearings"``.
        method : {"gibbs", "laplace"}
            ``"gibbs"``: the APerCEM sampler on pole and shape samples
            (:func:`twin.update.update`; ``kwargs`` go to it), returns its
            posterior DataTree. ``"laplace"``: the Gaussian posterior of the
            pole fit (:func:`twin.loop.fit.laplace_update`), returns a Dataset
            of MAP and std.
        estimate : {"map", "mean"}
            Which estimate of a Gibbs posterior the model takes.
        """
        from twin.update.problem import select_parameters

        names = select_parameters(self.model, params)
        label = params if isinstance(params, str) else ", ".join(params)
        if method == "laplace":
            if kwargs:
                raise TypeError(f"method 'laplace' takes no sampler settings, got {sorted(kwargs)}")
            model, post = laplace_update(self.model, self.measured, names)
            self._record(f"update {label} (Laplace)", model)
            return post
        if method != "gibbs":
            raise ValueError(f"method must be 'gibbs' or 'laplace', got {method!r}")
        from twin.update import apply_posterior, update

        tree = update(self.model, self.modes, names, **kwargs)
        self._record(f"update {label}", apply_posterior(self.model, tree, estimate))
        return tree

    def history_table(self) -> xr.Dataset:
        """The error after each step: ``action``, ``error`` and ``chi2`` over dimension ``step``."""
        table = history_dataset([s.action for s in self.history], [s.error for s in self.history],
                                [float(s.table.attrs["chi2"]) for s in self.history],
                                str(self.modes.attrs.get("title", "measured modes")))  # fmt: skip
        table.attrs["error_definition"] = self.history[0].table.attrs["error_definition"]
        return table

    def plot_history(self, path: str | Path) -> Path:
        """Bar chart of the error after each step."""
        return plot_history(self.history_table(), path)
