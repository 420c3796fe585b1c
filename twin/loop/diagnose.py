"""Diagnose a model against measured modes: where it fails, and which effects are missing.

1. **Where**: the comparison table (:func:`twin.loop.compare.compare`) gives
   the modes whose frequency or damping is off by more than :data:`Z_LIMIT`
   measurement sigmas, the sensors with the largest shape error, and the
   measured modes the model has no mode like. The model *fails* when the
   pole residuals are not consistent with the measurement uncertainty: their
   χ² exceeds the 99.9% quantile of the χ² law with as many degrees of
   freedom as data.
2. **Which effects**, by evidence (:mod:`twin.update.laplace`: Laplace
   approximation, priors at the effects' plausible scales inside their
   physical bounds). Stepwise, until nothing is missing: while the residuals
   are not consistent with the uncertainty, each round fits every remaining
   library candidate (:func:`twin.loop.candidates.candidates`) *jointly* with the
   effects already chosen and with those the model has, and adds the one of
   the largest log Bayes factor if it is strong (``ln B >`` :data:`STRONG_EVIDENCE`,
   odds above 20:1 on the Kass-Raftery scale). A second effect enters only
   when it pays for itself against a *richer form* of an effect already
   chosen (an effect that holds it as a special case: per-mode FSI for FSI,
   an anisotropic bearing change for a bearing change), fitted in its place:
   its evidence must exceed the richer form's by the same margin. Otherwise
   the richer form takes the first effect's place (when it is strongly
   supported itself): one change described more fully is named rather than
   a second change elsewhere that absorbs what the first form cannot fit.
   Likewise a richer form is chosen over the simpler one it holds only when
   its evidence exceeds the simpler's by that margin
   (:func:`twin.update.evidence.simplest`), and after each step a chosen
   richer form that no longer does, given the others, gives way to it. A model that agrees with the
   data gets no effect, however well one fits the noise (a candidate can
   reach a strong ln B on one record by taking up a few-sigma scatter of one
   mode). After each addition, an effect
   chosen earlier that the others now make unnecessary (its own ``ln B``
   below the threshold) is dropped. So two effects at once are named
   together, and a first choice that only mimicked them is undone. We chose
   the Bayes factor over an information criterion or LOO because it weighs
   each parameter by how sharply the data pin it relative to what is
   physically plausible (the Occam factor), which a count of parameters
   cannot do for a per-mode effect with 2 parameters per mode against a
   one-parameter stiffness.
3. **Outside the library**: a scan of local changes (each shaft element's
   stiffness, each disk's mass and inertia, :mod:`twin.loop.locate`), fitted
   alone and on top of the chosen effects.
4. **Verdict**: "unexplained" with the place when one local change explains
   the data far better (``ln B`` larger by :data:`STRONG_EVIDENCE`) than the
   chosen library effects; "missing effect" naming every chosen effect when
   they leave residuals within the uncertainty; "partly explained" when they
   do not; "nothing missing" when the model does not fail and no effect is
   supported; "not enough data" when the measured modes cover too little of
   the band or the record is too short (:mod:`twin.loop.coverage`), whatever
   the fits say.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.stats
import xarray as xr

from twin.fem.effects import describe, free_names, holds
from twin.fem.model import RotorModel
from twin.loop.candidates import Candidate, select, sized
from twin.loop.compare import compare
from twin.loop.coverage import Coverage, coverage
from twin.loop.locate import Location, locate
from twin.modes.measured import TOLERANCE, Measured, measured_modes
from twin.tasks import mapper, one_blas_thread
from twin.update.evidence import simplest
from twin.update.laplace import Fit, fit, log_evidence_as_is

log = logging.getLogger(__name__)

#: A mode fails in frequency or damping beyond this many measurement sigmas.
Z_LIMIT = 3.0
#: Log Bayes factor counted as strong evidence (Kass & Raftery: 2 ln B > 6).
STRONG_EVIDENCE = 3.0
#: What ``ln B`` means, in a sentence for the tables that show it.
LN_B_KEY = (
    "ln B: the log Bayes factor of the model with the candidate against the model without it (the evidence "
    "of the better fit less the Occam penalty of its parameters over their plausible scales); above "
    f"{STRONG_EVIDENCE:g} is strong evidence, below 0 the fit does not pay for its parameters; 'N ln-units "
    "below the best' is the best candidate's ln B less this one's"
)
#: Quantile of the χ² law above which residuals are not consistent with the uncertainty.
CONSISTENCY_QUANTILE = 0.999
#: Library effects named at most (the stepwise search stops there).
MAX_EFFECTS = 3
#: Verdicts of a diagnosis.
VERDICTS = ("missing effect", "partly explained", "unexplained", "nothing missing", "not enough data")


def consistent(chi2: float, dof: int) -> bool:
    """Whether a χ² with ``dof`` degrees of freedom is below the consistency quantile.

    Examples
    --------
    >>> consistent(20.0, 20), consistent(80.0, 20)
    (True, False)
    """
    return bool(chi2 <= scipy.stats.chi2.ppf(CONSISTENCY_QUANTILE, max(int(dof), 1)))


@dataclass(frozen=True)
class Diagnosis:
    """What :func:`diagnose` found; :meth:`to_dict` is the JSON layout.

    Attributes
    ----------
    verdict : str
        One of :data:`VERDICTS`.
    missing : tuple of str
        The library effects found missing (empty for none).
    fits : list of Fit
        The first round: every candidate fitted alone (jointly with the
        model's own effects), its ``log_bayes_factor`` against the model.
    final : Fit or None
        The joint fit of the model's own effects and the ones found missing.
    path : list of (str, str, float)
        The stepwise search: ``("add" | "drop", label, ln B)``.
    locations : list of Location
        Local changes outside the library, best first.
    coverage : Coverage or None
        What the measured modes cover of the band (None for synthetic modes).
    """

    verdict: str
    missing: tuple[str, ...]
    fits: list[Fit]
    explanations: dict[str, str]
    table: xr.Dataset
    chi2: float
    n_data: int
    failing_modes: dict[str, list[int]]
    sensors: list[str]
    locations: list[Location] = field(default_factory=list)
    summary: str = ""
    final: Fit | None = None
    path: list[tuple[str, str, float]] = field(default_factory=list)
    coverage: Coverage | None = None

    @property
    def ranking(self) -> list[Fit]:
        """First-round fits by log Bayes factor, best first."""
        return sorted(self.fits, key=lambda f: -f.log_bayes_factor)

    @property
    def named(self) -> str:
        """The missing effects joined by ``+`` (empty for none)."""
        return "+".join(self.missing)

    def to_dict(self, meas: Measured) -> dict:
        """``{"verdict", "missing", "summary", "error", "ranking": [...], "final", "path", "failing", "locations", ...}``."""
        ranking = [_fit_dict(f, meas, self.explanations.get(f.label, "")) for f in self.ranking]
        return {
            "verdict": self.verdict,
            "missing": list(self.missing),
            "summary": self.summary,
            "error": float(self.table.attrs["error"]),
            "chi2": self.chi2,
            "n_data": self.n_data,
            "failing": self.failing_modes,
            "poorly_paired": [int(m) for m in np.atleast_1d(self.table.attrs["poorly_paired"])],
            "sensors_by_shape_error": self.sensors,
            "coverage": None
            if self.coverage is None
            else {
                "band_hz": list(self.coverage.band_hz),
                "model_modes_in_band": len(self.coverage.in_band_hz),
                "measured": self.coverage.n_measured,
                "duration_s": self.coverage.duration_s,
                "enough": self.coverage.enough,
                "text": self.coverage.text(),
            },
            "ranking": ranking,
            "final": None if self.final is None else _fit_dict(self.final, meas, ""),
            "path": [{"action": a, "effect": lab, "score": s} for a, lab, s in self.path],
            "locations": [loc.__dict__ | {"element": loc.element} for loc in self.locations],
        }

    def to_json(self, meas: Measured) -> str:
        """The diagnosis as JSON text."""
        return json.dumps(self.to_dict(meas), indent=2)


def _fit_dict(f: Fit, meas: Measured, why: str) -> dict:
    return {
        "effect": f.label,
        "score": f.log_bayes_factor,
        "score_kind": "log Bayes factor (Laplace)",
        "error_before": f.error_before(meas),
        "error_after": f.error_after(meas),
        "chi2_after": f.chi2_after,
        "explains": consistent(f.chi2_after, f.residual_dof),
        "parameters": {
            n: {"value": float(v), "std": float(s), "unit": u} for n, v, s, u in zip(f.names, f.values, f.std, f.units)
        },
        "at_bound": f.at_bound,
        "converged": f.converged,
        "why": why,
    }


def _explain(f: Fit, candidate: Candidate, model: RotorModel, meas: Measured, best: float) -> str:
    e0, e1 = 100 * f.error_before(meas), 100 * f.error_after(meas)
    words = f"{describe(candidate.effect, model)} Error {e0:.2f}% -> {e1:.2f}%, ln B = {f.log_bayes_factor:.1f}"
    if f.log_bayes_factor < 0:
        words += "; the better fit does not pay for its parameters"
    elif f.log_bayes_factor < STRONG_EVIDENCE:
        words += "; weak evidence"
    if f.log_bayes_factor < best - 1:
        words += f"; {best - f.log_bayes_factor:.0f} ln-units below the best"
    if f.at_bound:
        words += f"; {', '.join(f.at_bound)} on its physical bound (the data push it beyond)"
    return words


def _fit_set(
    extra: Sequence[Candidate],
    model: RotorModel,
    meas: Measured,
    own: Sequence[str],
    start: dict,
    reference: float,
    label: str | None = None,
) -> Fit:
    """The joint fit of the model's own effects and the candidates ``extra``."""
    m = model.with_effects(*[c.effect for c in extra])
    names = list(own) + [n for c in extra for n in free_names(m, c.effect, meas.mode)]
    return fit(
        m,
        meas,
        names,
        label or "+".join(c.label for c in extra) or "the model's effects",
        reference=reference,
        start=start,
    )


def _fit_with(
    candidate: Candidate,
    model: RotorModel,
    meas: Measured,
    own: Sequence[str],
    included: tuple[Candidate, ...],
    start: dict,
    reference: float,
) -> Fit:
    """One candidate fitted jointly with the effects already chosen (less any it replaces); labelled by it."""
    rest = [c for c in included if not holds(candidate.label, c.label)]
    return _fit_set([*rest, candidate], model, meas, own, start, reference, label=candidate.label)


@one_blas_thread
def diagnose(
    model: RotorModel,
    modes: xr.Dataset | Measured,
    *,
    candidates: Sequence[str] | None = None,
    tolerance: float = TOLERANCE,
    max_effects: int = MAX_EFFECTS,
    tasks: Any = None,
    progress: bool = False,
) -> Diagnosis:
    """Where the model fails against the measured modes, and which library effects are missing.

    Parameters
    ----------
    model : RotorModel
        The model as it is; the effects it has are refitted with every
        candidate (the loop's earlier rounds).
    modes : xarray.Dataset or Measured
        Measured modes (``modes.nc`` layout).
    candidates : sequence of str, optional
        Candidate labels (default: the whole library, see :func:`twin.loop.candidates.candidates`).
    tolerance : float
        Relative pole uncertainty accepted as model-form error.
    max_effects : int
        Library effects named at most.
    tasks : distributed.Client or mapper, optional
        Where the candidate fits run, one task each (:func:`twin.tasks.mapper`):
        in this process by default.
    progress : bool
        A bar over each step's candidate fits (on a terminal).

    Returns
    -------
    Diagnosis

    Examples
    --------
    >>> from twin.loop import diagnose
    >>> from twin.fem.effects import MagneticPull, SealCrossCoupling
    >>> from twin.fem.truthfile import Truth
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> truth = Truth((MagneticPull(-1.5e8), SealCrossCoupling(4e7)))
    >>> data = synthesize_modes(model, truth, n_modes=13, samples=50, seed=1, pole_variance=(0.01, 0.01))
    >>> d = diagnose(model, data, candidates=["magnetic_pull", "seal_cross_coupling", "bearing_change:UGB"])
    >>> d.verdict, sorted(d.missing)
    ('missing effect', ['magnetic_pull', 'seal_cross_coupling'])
    """
    meas = modes if isinstance(modes, Measured) else measured_modes(modes, tolerance)
    table = compare(model, meas)
    chosen = [sized(c, meas.mode) for c in select(model, candidates)]
    run = mapper(tasks, progress=progress, desc="candidate fits")
    own = [n for e in model.effects for n in free_names(model, e, meas.mode)]
    lnz_as_is, _ = log_evidence_as_is(model, meas)
    base = _fit_set([], model, meas, own, {}, lnz_as_is) if own else None
    base_lnz = base.log_evidence if base is not None else lnz_as_is

    included: list[Candidate] = []
    current, current_lnz = base, base_lnz
    first: list[Fit] | None = None
    path: list[tuple[str, str, float]] = []
    remaining = list(chosen)
    while remaining:
        chi2_now = current.chi2_after if current is not None else float(table.attrs["chi2"])
        dof_now = current.residual_dof if current is not None else int(table.attrs["n_data"])
        start = current.value_of() if current is not None else {}
        shared = {
            "model": model,
            "meas": meas,
            "own": own,
            "included": tuple(included),
            "start": start,
            "reference": current_lnz,
        }
        # Effects with a few parameters first; a per-mode effect (two parameters per mode: it can fit every pole
        # alone) only when none of them is strongly supported any more, so it never stands in for simpler ones.
        # Once max_effects are chosen, only a candidate that replaces one of them may still come in.
        eligible = [
            c for c in remaining if len(included) < max_effects or any(holds(c.label, i.label) for i in included)
        ]
        tiers = [[c for c in eligible if not c.per_mode], [c for c in eligible if c.per_mode]]
        fitted: dict[str, Fit] = {}
        if first is None:  # every candidate alone, for the ranking
            first = run(_fit_with, remaining, **shared)
            fitted = {f.label: f for f in first}
        if consistent(chi2_now, dof_now) or not eligible:
            break  # nothing is missing (any more); the first round is fitted for its ranking all the same
        pick = None
        for tier in (t for t in tiers if t):
            unfitted = [c for c in tier if c.label not in fitted]
            if unfitted:
                fitted.update({f.label: f for f in run(_fit_with, unfitted, **shared)})
            best = max(tier, key=lambda c: fitted[c.label].log_bayes_factor)
            evidence = {c.label: fitted[c.label].log_bayes_factor for c in tier}
            label = simplest(best.label, evidence, STRONG_EVIDENCE)
            best = next(c for c in tier if c.label == label)
            if fitted[best.label].log_bayes_factor > STRONG_EVIDENCE:
                pick = best
                break
        if pick is not None and not any(holds(pick.label, c.label) for c in included):
            pick = _against_richer(pick, included, remaining, fitted, run, shared)
        if pick is None:
            break
        added, fit_added = pick, fitted[pick.label]
        for replaced in [c for c in included if holds(added.label, c.label)]:
            included.remove(replaced)
            path.append(("replace", replaced.label, fit_added.log_bayes_factor))
        included.append(added)
        path.append(("add", added.label, fit_added.log_bayes_factor))
        current, current_lnz = fit_added, fit_added.log_evidence
        # per-mode FSI stays a candidate after the mode-independent one (it may replace it), not the other way
        remaining = [c for c in remaining if c is not added and not holds(added.label, c.label)]
        current, current_lnz = _drop_unneeded(included, path, current, model, meas, own, run)
        current, current_lnz = _simplify(included, chosen, path, current, model, meas, own, run)
    first = first or []
    by_label = {c.label: c for c in chosen}
    best = max((f.log_bayes_factor for f in first), default=-np.inf)
    explanations = {
        f.label: _explain(f, by_label[f.label], model.with_effects(by_label[f.label].effect), meas, best) for f in first
    }

    chi2, n_data = float(table.attrs["chi2"]), int(table.attrs["n_data"])
    fails = not consistent(chi2, n_data)
    failing = {
        "frequency": table["mode"].values[np.abs(table["z_frequency"].values) > Z_LIMIT].tolist(),
        "damping": table["mode"].values[np.abs(table["z_damping"].values) > Z_LIMIT].tolist(),
    }
    sensors = [str(c) for c in table["channel"].values[np.argsort(-table["channel_shape_error"].values)]]
    alone = locate(model, meas, base, reference=base_lnz, tasks=tasks) if fails or included else []
    cover = coverage(model, meas)
    final = current if included else base
    lib_gain = current_lnz - base_lnz
    named = tuple(c.label for c in included)
    where = _where(failing, sensors, table)
    if alone and alone[0].log_bayes_factor > max(lib_gain, 0.0) + STRONG_EVIDENCE:
        verdict, missing, locations = "unexplained", (), alone
        loc = alone[0]
        summary = (
            f"The model fails (chi2 = {chi2:.1f} for {n_data} data) and no effect of the library explains it"
            + (f" as well ({'+'.join(named)}: ln B = {lib_gain:.1f})" if named else "")
            + f". Outside the library, {loc.text()}. {where}"
        )
    elif included:
        explains = consistent(final.chi2_after, final.residual_dof)
        locations = (
            []
            if explains
            else locate(
                model.with_effects(*[c.effect for c in included]), meas, final, reference=current_lnz, tasks=tasks
            )
        )
        verdict, missing = ("missing effect" if explains else "partly explained"), named
        steps = "; ".join(f"{a} {lab} (ln B = {s:.1f})" for a, lab, s in path)
        summary = (
            f"The model misses {' and '.join(named)}: "
            + "; ".join(by_label[n].explain(model) for n in named)
            + f". Fitted jointly, they bring the error from {100 * final.error_before(meas):.2f}% to "
            f"{100 * final.error_after(meas):.2f}% (ln B = {lib_gain:.1f} against the model as it is; "
            f"search: {steps})."
        )
        if explains:
            summary += " The residuals are within the measurement uncertainty."
        else:
            summary += (
                f" They leave residuals beyond the measurement uncertainty (chi2 = {final.chi2_after:.1f} "
                f"for {final.residual_dof} degrees of freedom): something else is missing too. {where}"
            )
            if locations and locations[0].log_bayes_factor > STRONG_EVIDENCE:
                summary += f" Outside the library, {locations[0].text()}."
    elif fails:
        verdict, missing, locations = "unexplained", (), alone
        top = max(first, key=lambda f: f.log_bayes_factor) if first else None
        summary = (
            f"The model fails (chi2 = {chi2:.1f} for {n_data} data) and no candidate effect of the library "
            f"explains it (best: {top.label if top else 'none'}, ln B = {best:.1f}). {where}"
        )
        if alone:
            summary += f" Outside the library, {alone[0].text()}."
    else:
        verdict, missing, locations = "nothing missing", (), []
        summary = (
            f"Nothing is missing: the model's poles agree with the measured ones within their uncertainty "
            f"(chi2 = {chi2:.1f} for {n_data} data) and no candidate effect is supported (best ln B = "
            f"{best:.1f})."
        )
    if cover is not None and not cover.enough:
        found = f" With these data the diagnosis would be: {verdict}" + (f" ({', '.join(missing)})" if missing else "")
        verdict, missing = "not enough data", ()
        summary = f"Not enough data to judge the model: {cover.text()}.{found}. Measure longer or add sensors."
    elif cover is not None:
        summary += f" ({cover.text()}.)"
    log.info("diagnosis: %s", summary)
    return Diagnosis(
        verdict,
        missing,
        first,
        explanations,
        table,
        chi2,
        n_data,
        failing,
        sensors,
        locations,
        summary,
        final,
        path,
        cover,
    )


def _against_richer(
    pick: Candidate,
    included: list[Candidate],
    remaining: list[Candidate],
    fitted: dict[str, Fit],
    run,
    shared: dict,
) -> Candidate | None:
    """The candidate to add in place of a second effect ``pick``: ``pick`` itself only when it pays for itself
    against the richer forms of the effects already chosen (those that hold one of them as a special case).

    Each richer form is fitted in place of the effect it holds. ``pick`` enters when its log evidence exceeds the
    best richer form's by :data:`STRONG_EVIDENCE`; otherwise that richer form takes the first effect's place when it
    is itself strongly supported, and nothing enters when it is not.
    """
    richer = [c for c in remaining if any(holds(c.label, i.label) for i in included)]
    if not richer:
        return pick
    unfitted = [c for c in richer if c.label not in fitted]
    if unfitted:
        fitted.update({f.label: f for f in run(_fit_with, unfitted, **shared)})
    best = max(richer, key=lambda c: fitted[c.label].log_bayes_factor)
    margin = fitted[pick.label].log_bayes_factor - fitted[best.label].log_bayes_factor
    if margin > STRONG_EVIDENCE:
        return pick
    log.info("%s does not pay for itself against %s (ln B %.1f); not added", pick.label, best.label, margin)
    return best if fitted[best.label].log_bayes_factor > STRONG_EVIDENCE else None


def _simplify(
    included: list[Candidate],
    chosen: Sequence[Candidate],
    path: list,
    current: Fit,
    model: RotorModel,
    meas: Measured,
    own: Sequence[str],
    run,
) -> tuple[Fit, float]:
    """Replace a chosen richer form by a simpler form it holds while the others now explain what it added: the
    richer form stays only when its log evidence exceeds the simpler's, fitted in its place with the other
    chosen effects, by :data:`STRONG_EVIDENCE` (a richer form chosen before a second effect came in may have
    taken up that effect's share of the misfit)."""
    changed = True
    while changed:
        changed = False
        for rich in list(included):
            simpler = [c for c in chosen if holds(rich.label, c.label)]
            if not simpler:
                continue
            rest = tuple(c for c in included if c is not rich)
            start = current.value_of()
            fits = run(_fit_with, simpler, model=model, meas=meas, own=own, included=rest, start=start, reference=0.0)
            best = max(fits, key=lambda f: f.log_evidence)
            margin = current.log_evidence - best.log_evidence
            if margin > STRONG_EVIDENCE:
                continue
            simple = next(c for c in simpler if c.label == best.label)
            included[included.index(rich)] = simple
            path.append(("simplify", rich.label, margin))
            current, changed = best, True
            break
    return current, current.log_evidence


def _drop_unneeded(
    included: list[Candidate], path: list, current: Fit, model: RotorModel, meas: Measured, own: Sequence[str], run
) -> tuple[Fit, float]:
    """Drop, one at a time, an earlier choice whose own log Bayes factor (given the others) is not strong."""
    while len(included) > 1:
        earlier = included[:-1]
        start = current.value_of()
        without = run(
            _fit_without, earlier, model=model, meas=meas, own=own, included=tuple(included), start=start, reference=0.0
        )
        gains = [current.log_evidence - f.log_evidence for f in without]
        k = int(np.argmin(gains))
        if gains[k] > STRONG_EVIDENCE:
            break
        dropped = earlier[k]
        included.remove(dropped)
        path.append(("drop", dropped.label, gains[k]))
        current = without[k]
    return current, current.log_evidence


def _fit_without(
    candidate: Candidate,
    model: RotorModel,
    meas: Measured,
    own: Sequence[str],
    included: tuple[Candidate, ...],
    start: dict,
    reference: float,
) -> Fit:
    rest = [c for c in included if c is not candidate]
    return _fit_set(rest, model, meas, own, start, reference)


def _where(failing: dict[str, list[int]], sensors: list[str], table: xr.Dataset) -> str:
    parts = []
    if failing["frequency"]:
        parts.append(f"frequency of mode(s) {', '.join(map(str, failing['frequency']))}")
    if failing["damping"]:
        parts.append(f"damping of mode(s) {', '.join(map(str, failing['damping']))}")
    text = f"It fails in the {' and the '.join(parts)}" if parts else "No single mode is off by more than 3 sigmas"
    poorly = [int(m) for m in np.atleast_1d(table.attrs["poorly_paired"])]
    if poorly:
        text += f"; the model has no mode like measured mode(s) {', '.join(map(str, poorly))} (MAC < {table.attrs['min_mac']:g})"
    return f"{text}; largest shape errors at sensor(s) {', '.join(sensors[:2])}."
