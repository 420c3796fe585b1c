"""What changed at an alarm, and how it goes on: the candidates' evidence and the changed parameter followed.

At an alarm the residuals since the onset (what the operating conditions do not explain) are pooled and
set against every change the model can name (:func:`twin.loop.candidates.candidates`: the library's
effects and the local changes outside it). Each candidate moves the tracked poles along its
sensitivities at the reference point; with its plausible scale as a Gaussian prior, its evidence is that
of a linear Gaussian model, ``r ~ N(0, C + J D J')``, against the evidence of no change, ``r ~ N(0, C)``
(:func:`twin.update.evidence.linear_fit`, the formula the single-record diagnosis weighs effects with:
the Occam factor in the prior). The best library
effect is named when its evidence is the best of all; when a local change outside the library explains
the residual better, the verdict says so and where.

At the alarm the named change is updated on the records since the onset through the full model at each
record's operating point (:func:`update`: Gauss-Newton to the posterior mode under the plausible-scale
prior), then followed record by record: an extended Kalman filter whose state is the change, with a
random walk of :data:`PROCESS_NOISE` times the plausible scale per day (the change may still be
growing), and whose observations are the records' poles (:class:`Follower`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from twin.fem.effects import exclusive, holds
from twin.fem.model import RotorModel
from twin.fem.operation import at_operating_point, with_change, with_parameters
from twin.loop.candidates import Candidate
from twin.loop.candidates import candidates as all_candidates
from twin.modes.sensitivity import pole_jacobian, solve_modes
from twin.track.physics import Tracked, parts, tracked_indices
from twin.update.evidence import linear_fit, simplest

#: Random walk of a followed change per square-root day, as a fraction of its plausible scale.
PROCESS_NOISE = 0.02
#: The evidence (natural log) a named change needs over no change at all.
MIN_LOG_EVIDENCE = 3.0
#: ... and over the runner-up, for the name to stand (a Bayes factor of 20); below it the records cannot
#: yet tell the two apart, and the tracker weighs them again as records come (``twin.track.tracker``).
MIN_MARGIN = 3.0


@dataclass(frozen=True)
class Linearised:
    """A candidate change (:class:`twin.loop.candidates.Candidate`) with its parameters, their plausible
    scales and the tracked pole parts' sensitivities to them at the reference point."""

    candidate: Candidate
    parameters: tuple[str, ...]
    scale: np.ndarray
    jacobian: np.ndarray  # (2m, k)
    where: str = ""

    @property
    def label(self) -> str:
        return self.candidate.label

    @property
    def library(self) -> bool:
        return self.candidate.library

    def with_values(self, values: np.ndarray):
        """The candidate's effect at ``values`` (in its parameters' order)."""
        return self.candidate.with_values(values)


def candidates(model: RotorModel, tracked: Tracked) -> list[Linearised]:
    """Every library effect (one value for the whole machine) in its simplest form, and every local change, at
    the reference point (:func:`twin.loop.candidates.candidates`: a change of an effect the model has is one
    too).

    A richer form of a candidate (an anisotropic bearing change beside the change alike in x and y) is left
    to the single-record diagnosis: on residuals pooled over records at many operating points its extra
    parameters take up what the laws leave, and it out-scored the simple form for a change alike in x and y.
    """
    ref = at_operating_point(model, {})
    pool = all_candidates(ref, present=True, per_mode=False, local=True)
    out = []
    for cand in [c for c in pool if not any(holds(c.label, d.label) for d in pool)]:
        names = [p.name for p in cand.effect.parameters(ref)]
        m = with_parameters(ref, names) if cand.library else ref.with_effects(cand.effect)
        sol = solve_modes(m)
        jac = pole_jacobian(m, sol, names, modes=tracked_indices(m, sol, tracked))
        scales = cand.effect.plausible_scale(m)
        out.append(
            Linearised(cand, tuple(names), np.array([scales[n] for n in names]), parts(jac.T).T, cand.where(ref))
        )
    return out


@dataclass(frozen=True)
class Verdict:
    """What an alarm names: the best candidate, its values, the runner-up and the text a user reads."""

    label: str
    library: bool
    parameters: tuple[str, ...]
    mean: np.ndarray
    covariance: np.ndarray
    log_evidence: float
    runner_up: str
    runner_up_evidence: float
    chi2: float
    dof: int
    text: str


def diagnose(r: np.ndarray, cov: np.ndarray, cands: list[Linearised]) -> Verdict:
    """The candidate that best explains the pooled residual ``r`` (``2m``, covariance ``cov``): each weighed as
    a linear-Gaussian hypothesis against no change (:func:`twin.update.evidence.linear_fit`). A richer form
    of a change is named only when it pays for itself against the simpler (:func:`twin.update.evidence.simplest`);
    the runner-up is the best other change, not the named one in a richer or simpler form.

    Only pole parts measured since the onset take part (NaN elsewhere).
    """
    ok = np.isfinite(r)
    r, cov = r[ok], cov[np.ix_(ok, ok)]
    fits = [(linear_fit(r, c.jacobian[ok], c.scale, cov), c) for c in cands]
    scored = sorted(fits, key=lambda t: -t[0].log_bayes_factor)
    evidence = {c.label: f.log_bayes_factor for f, c in fits}
    label = simplest(scored[0][1].label, evidence, MIN_MARGIN)
    best_fit, best = next(t for t in scored if t[1].label == label)
    # the runner-up is another change, not the best one in a richer or a simpler form (which fits as well)
    others = [t for t in scored if t[1].label != best.label and not exclusive(t[1].label, best.label)]
    second_fit, second = others[0] if others else next(t for t in scored if t[1].label != best.label)
    best_ev, second_ev = best_fit.log_bayes_factor, second_fit.log_bayes_factor
    mean, post = best_fit.values, best_fit.covariance
    return Verdict(
        best.label,
        best.library,
        best.parameters,
        mean,
        post,
        best_ev,
        second.label,
        second_ev,
        best_fit.chi2,
        int(ok.sum()),
        _text(best, mean, post, best_ev, second.label, second_ev),
    )


def changed_poles(
    model: RotorModel, tracked: Tracked, point: dict[str, float], changes: list, derive: Linearised | None = None
) -> tuple[np.ndarray, np.ndarray | None]:
    """The tracked poles at ``point`` with ``changes`` (candidate, values) on the model, and their derivatives
    by ``derive``'s parameters (pole parts, ``(2m, k)``) when it is given."""
    m = at_operating_point(model, point)
    for cand, values in changes:
        m = with_change(m, cand.with_values(values))
    sol = solve_modes(m)
    idx = tracked_indices(m, sol, tracked)
    if derive is None:
        return parts(sol.poles[idx]), None
    return parts(sol.poles[idx]), parts(pole_jacobian(m, sol, list(derive.parameters), modes=idx).T).T


#: Gauss-Newton steps of the update at an alarm.
UPDATE_STEPS = 5


def update(
    model: RotorModel,
    tracked: Tracked,
    cand: Linearised,
    observed: list[tuple[dict, np.ndarray, np.ndarray]],
    others: list,
) -> tuple[np.ndarray, np.ndarray]:
    """The candidate's values after the records since the onset: the posterior mode and covariance under its
    prior (zero, its plausible scale), by Gauss-Newton on the full model at each record's operating point.

    ``observed`` holds ``(point, y, cov)`` per record: the measured pole parts less the baseline's offsets
    (NaN where not measured or not used) and their covariance; ``others`` the changes followed already.
    """
    k = len(cand.parameters)
    mean = np.zeros(k)
    prior = np.diag(1.0 / cand.scale**2)
    for _ in range(UPDATE_STEPS):
        A, b = prior.copy(), -prior @ mean
        for point, y, cov in observed:
            g, H = changed_poles(model, tracked, point, [*others, (cand, mean)], derive=cand)
            ok = np.isfinite(y)
            ci = np.linalg.inv(cov[np.ix_(ok, ok)])
            A += H[ok].T @ ci @ H[ok]
            b += H[ok].T @ ci @ (y[ok] - g[ok])
        step = np.linalg.solve(A, b)
        mean = mean + step
        if np.all(np.abs(step) < 1e-3 * cand.scale):
            break
    return mean, np.linalg.inv(A)


def named(verdict: Verdict, cand: Linearised, mean: np.ndarray, cov: np.ndarray, note: str = "") -> Verdict:
    """The verdict with the change's values updated (:func:`update`) in place of the screening's linear ones,
    and a ``note`` added to its text."""
    text = _text(cand, mean, cov, verdict.log_evidence, verdict.runner_up, verdict.runner_up_evidence)
    return dataclasses.replace(verdict, mean=mean, covariance=cov, text=f"{text}; {note}" if note else text)


def _text(cand: Linearised, mean: np.ndarray, cov: np.ndarray, evidence: float, second: str, second_ev: float) -> str:
    values = ", ".join(f"{n} = {m:.3g} ± {np.sqrt(v):.2g}" for n, m, v in zip(cand.parameters, mean, cov.diagonal()))
    if evidence < MIN_LOG_EVIDENCE:
        return f"no change the model can name stands out (best: {cand.label}, log evidence {evidence:.1f})"
    if evidence - second_ev < MIN_MARGIN:
        return (
            f"{cand.label} or {second}: the records cannot yet tell them apart (log evidence {evidence:.1f} "
            f"and {second_ev:.1f}); followed as {cand.label}: {values}"
        )
    if cand.library:
        return f"{cand.label} changed: {values} (log evidence {evidence:.1f}; next {second}, {second_ev:.1f})"
    return (
        f"a change outside the library: {cand.where} ({cand.label}: {values}; log evidence {evidence:.1f}; "
        f"next {second}, {second_ev:.1f})"
    )


class Follower:
    """An extended Kalman filter on a named change: its values after each record, with a random walk between.

    ``history`` holds, for each of ``n_records`` records, each parameter's value and its 5% and 95%
    quantiles as :meth:`keep` wrote them (NaN before the change was followed).
    """

    def __init__(
        self,
        model: RotorModel,
        tracked: Tracked,
        cand: Linearised,
        mean: np.ndarray,
        cov: np.ndarray,
        day: float,
        n_records: int = 0,
    ) -> None:
        self.model, self.tracked, self.cand = model, tracked, cand
        self.mean, self.cov, self.day = np.array(mean, float), np.array(cov, float), day
        self.walk = np.diag((PROCESS_NOISE * cand.scale) ** 2)
        self.history = np.full((n_records, len(self.mean), 3), np.nan)

    def keep(self, t: int) -> None:
        """Write the values and their 5-95% interval after record ``t`` into :attr:`history`."""
        half = 1.645 * np.sqrt(self.cov.diagonal())
        self.history[t] = np.stack([self.mean, self.mean - half, self.mean + half], axis=1)

    def update(self, point: dict[str, float], y: np.ndarray, cov: np.ndarray, day: float, others: list) -> None:
        """One record: its measured pole parts less the offsets ``y`` (NaN where not used), covariance ``cov``."""
        self.cov = self.cov + self.walk * max(day - self.day, 0.0)
        self.day = day
        ok = np.isfinite(y)
        if not ok.any():
            return
        g, H = changed_poles(self.model, self.tracked, point, [*others, (self.cand, self.mean)], derive=self.cand)
        S = H[ok] @ self.cov @ H[ok].T + cov[np.ix_(ok, ok)]
        gain = self.cov @ H[ok].T @ np.linalg.inv(S)
        self.mean = self.mean + gain @ (y[ok] - g[ok])
        self.cov = (np.eye(len(self.mean)) - gain @ H[ok]) @ self.cov
