"""The candidates of a diagnosis: the changes it can name for a model.

A candidate is an effect of :mod:`twin.fem.effects` with zero values, added to
the model: its parameters are what the diagnosis fits. The library offers,
for a model with the matching regions and elements:

* ``fsi``: mode-independent water added mass and damping at the runner;
* ``fsi_per_mode``: a different added mass and damping for each mode;
* ``magnetic_pull``: negative radial stiffness at the generator;
* ``seal_cross_coupling``: cross-coupled stiffness at the runner seals;
* ``bearing_change:<B>``: direct stiffness and damping change of each guide bearing;
* ``thrust_tilt:<T>``: tilt stiffness change of each thrust bearing;

and any other registered library effect (:func:`twin.fem.effects.effect_classes`).
Outside the library, the local changes (each shaft element's stiffness, each
disk's mass and inertia) say where a model fails that no effect explains.

:func:`candidates` lists them for the single-record diagnosis
(:mod:`twin.loop.diagnose`, :mod:`twin.loop.locate`) and for the tracker
(:mod:`twin.track.explain`). Effects the model already has are no library
candidates (the diagnosis refits them), nor effects that one the model has
holds as a special case (a model with per-mode FSI tries no mode-independent
FSI); the tracker, which asks what changed since its baseline, keeps them.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from twin.errors import ModelError
from twin.fem.effects import effect_classes, effect_fields, effect_label, holds, library_effects, local_changes
from twin.fem.excitation import machine_excitation
from twin.fem.model import RotorModel


@dataclass(frozen=True)
class Candidate:
    """One change to try: its label and the zero-valued effect (a library effect or a local change).

    Examples
    --------
    >>> c = candidates(hydro_unit, local=True)[-1]
    >>> c.label, c.library
    ('disk_inertia:runner', False)
    """

    label: str
    effect: object

    def explain(self, model) -> str:
        """One line of physics, in ``model``'s words (:meth:`twin.fem.effects.Effect.explain`)."""
        return self.effect.explain(model)

    @property
    def per_mode(self) -> bool:
        """Whether each mode has its own parameters."""
        return self.effect.per_mode

    @property
    def library(self) -> bool:
        """Whether the candidate is a library effect (not a local change)."""
        return not self.effect.local

    def where(self, model: RotorModel) -> str:
        """The place of a local change in words (empty for a library effect)."""
        return "" if self.library else self.effect.where(model)

    def with_values(self, values: Sequence[float]):
        """The effect with its number fields (in their order: its parameters' order) set to ``values``."""
        numbers = [name for name, kind in effect_fields(type(self.effect)).items() if kind is float]
        return dataclasses.replace(self.effect, **{k: float(v) for k, v in zip(numbers, np.ravel(values))})


def candidates(
    model: RotorModel, *, present: bool = False, per_mode: bool = True, local: bool = False
) -> list[Candidate]:
    """The changes a diagnosis of ``model`` can name: library effects first, in the library's order.

    Parameters
    ----------
    model : RotorModel
    present : bool
        Keep the effects the model has (a change of their values is a candidate) and those they hold;
        by default they are left out (a diagnosis refits them with every candidate).
    per_mode : bool
        Include effects with one value per mode.
    local : bool
        Add the local changes outside the library (:func:`twin.fem.effects.local_changes`).

    Examples
    --------
    >>> from twin.loop import candidates
    >>> [c.label for c in candidates(hydro_unit)][:5]
    ['fsi', 'fsi_per_mode', 'magnetic_pull', 'seal_cross_coupling', 'bearing_change:UGB']
    """
    have = [effect_label(e) for e in model.effects]
    out = []
    for e in library_effects(model):
        label = effect_label(e)
        if e.per_mode and not per_mode:
            continue
        known = (
            label in have or any(holds(p, label) for p in have) or (e.per_mode and model.per_mode_effect is not None)
        )
        if known and not present:
            continue
        out.append(Candidate(label, e))
    if local:
        out += [Candidate(effect_label(c), c) for c in local_changes(model)]
    return out


def select(model: RotorModel, labels: Sequence[str] | None) -> list[Candidate]:
    """The library candidates named by ``labels`` (all when None); unknown labels are an error.

    Labels of effects the model already has are no candidates (a diagnosis refits them) and are skipped.
    """
    available = candidates(model)
    if labels is None:
        return available
    by_label = {c.label: c for c in available}
    present = {effect_label(e) for e in model.effects}
    unknown = [lab for lab in labels if lab not in by_label and lab not in present]
    if unknown:
        raise ModelError(
            f"no candidate effect {unknown} for model '{model.name}'; available: "
            f"{', '.join(by_label) or 'none'} (library keys: {', '.join(effect_classes(local=False))})"
        )
    return [by_label[lab] for lab in labels if lab in by_label]


def with_effect(model: RotorModel, effect) -> RotorModel:
    """The model with one more effect (zero-valued effects change nothing until their values are set)."""
    return dataclasses.replace(model, effects=(*model.effects, effect))


def sized(candidate: Candidate, labels: Sequence[int]) -> Candidate:
    """A per-mode candidate with one zero value per mode up to the largest measured mode label (others as they are).

    Examples
    --------
    >>> c = select(hydro_unit, ["fsi_per_mode"])[0]
    >>> sized(c, [1, 2, 4]).effect.n_modes
    4
    """
    if not candidate.per_mode:
        return candidate
    n = int(max(labels))
    return Candidate(candidate.label, candidate.effect.with_modes(n))


def add_effects(model: RotorModel, labels: Sequence[str], mode_labels: Sequence[int] | None = None) -> RotorModel:
    """The model with the library effects ``labels`` added, zero-valued (their values come from an update).

    A per-mode effect takes one value per mode up to the largest of ``mode_labels`` (the measured modes).

    Examples
    --------
    >>> from twin.loop import add_effects
    >>> m = add_effects(hydro_unit, ["magnetic_pull", "bearing_change:LGB"])
    >>> m.parameter_names[-3:]
    ['MAG.stiffness', 'LGB.stiffness_change', 'LGB.damping_change']
    """
    for c in select(model, list(labels)):
        if c.per_mode and mode_labels is None:
            raise ModelError(f"'{c.label}' has one value per mode: say which modes (mode_labels)")
        model = with_effect(model, (sized(c, mode_labels) if c.per_mode else c).effect)
    return model


def with_effects(model: RotorModel, labels: Sequence[str] = (), modes=None, posterior=None) -> RotorModel:
    """The model with the library effects ``labels`` and those ``posterior`` was made with (its ``effects`` attr).

    Effects the model has already are not added again. A per-mode effect takes one value per mode of
    ``modes`` (the measured modes). Used to read a posterior back onto the model file it came from.

    Examples
    --------
    >>> from twin.loop.candidates import with_effects
    >>> m = with_effects(hydro_unit, ["magnetic_pull", "magnetic_pull"])
    >>> [n for n in m.parameter_names if n.startswith("MAG.")]
    ['MAG.stiffness']
    """
    wanted = list(labels)
    if posterior is not None:
        wanted += json.loads(posterior.attrs.get("effects", "[]"))
    present = {effect_label(e) for e in model.effects}
    wanted = [w for i, w in enumerate(wanted) if w not in present and w not in wanted[:i]]
    if not wanted:
        return model
    mode_labels = None if modes is None else [int(m) for m in modes["mode"].values]
    return add_effects(model, wanted, mode_labels)


def posterior_model(
    model: RotorModel, posterior, estimate: str = "map", labels: Sequence[str] = (), modes=None
) -> RotorModel:
    """The model ``posterior`` stands for: the effects it needs added (:func:`with_effects`), its ``estimate``
    (``"map"`` or ``"mean"``) applied (:func:`twin.update.apply_posterior`)."""
    from twin.update import apply_posterior

    return apply_posterior(with_effects(model, labels, modes, posterior), posterior, estimate)


def parameters_json(model: RotorModel) -> dict:
    """The ``twin params --json`` layout: a model's parameters, its effects, the library effects it can take and
    the excitation that drives it (:func:`twin.fem.excitation.machine_excitation`).

    Each parameter with its nominal value (SI, ``unit``), its group for ``--params``, its physical bounds
    (``null`` for an open side: JSON has no infinity) and its description.

    Examples
    --------
    >>> out = parameters_json(hydro_unit)
    >>> out["groups"][:2], out["parameters"][0]["unit"], "magnetic_pull" in out["library"]
    (['bearings', 'thrust'], 'kg', True)
    """
    from twin.update.problem import PARAMETER_GROUPS

    groups = {n: g for g, f in PARAMETER_GROUPS.items() for n in f(model)}

    def finite(x: float) -> float | None:
        return float(x) if np.isfinite(x) else None

    rows = [
        {
            "name": p.name,
            "nominal": p.nominal,
            "unit": p.unit,
            "group": groups.get(p.name, "effects"),
            "low": finite(p.bounds[0]),
            "high": finite(p.bounds[1]),
            "bounds": p.bounds_text() or "either sign",
            "description": p.description,
        }
        for p in model.parameters
    ]
    return {
        "model": model.name,
        "n_dof": model.n_dof,
        "speed_rpm": model.speed_rpm,
        "channels": list(model.channels),
        "parameters": rows,
        "groups": list(PARAMETER_GROUPS),
        "effects": [effect_label(e) for e in model.effects],
        "library": [c.label for c in candidates(model)],
        "physics": model.physics,
        "excitation": {
            k: finite(v) if isinstance(v, float) else v
            for k, v in dataclasses.asdict(machine_excitation(model)).items()
        },
    }
