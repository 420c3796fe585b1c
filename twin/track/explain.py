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
import scipy.special

from twin.fem.effects import exclusive, holds
from twin.fem.model import RotorModel
from twin.fem.operation import at_operating_point, with_change, with_parameters
from twin.loop.candidates import Candidate
from twin.loop.candidates import candidates as all_candidates
from twin.modes.sensitivity import pole_jacobian, solve_modes
from twin.track.physics import Tracked, parts, tracked_indices
from twin.update.evidence import LinearFit, linear_fit, log_evidence, simplest, truncation

#: Random walk of a followed change per square-root day, as a fraction of its plausible scale.
PROCESS_NOISE = 0.02
#: The evidence (natural log) a named change needs over no change at all.
MIN_LOG_EVIDENCE = 3.0
#: ... and the posterior odds (natural log) of the named change against all the others together, for the
#: name to stand (20 to 1); below them the records cannot yet tell it from the runner-up, and the tracker
#: weighs them again as records come (``twin.track.watch``).
MIN_MARGIN = 3.0


@dataclass(frozen=True)
class Linearised:
    """A candidate change (:class:`twin.loop.candidates.Candidate`) with its parameters, their plausible
    scales, the tracked pole parts' sensitivities to them at the reference point and the physical bounds
    of the change (``(k, 2)``; the parameter's bounds less its value in the model: a magnetic pull does not
    stiffen, added mass is not negative, a bearing keeps a non-negative stiffness)."""

    candidate: Candidate
    parameters: tuple[str, ...]
    scale: np.ndarray
    jacobian: np.ndarray  # (2m, k)
    where: str = ""
    bounds: np.ndarray | None = None

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
        given = [m.parameter(n) for n in names]
        bounds = in_service(
            np.array([[p.bounds[0] - p.nominal, p.bounds[1] - p.nominal] for p in given]), cand.effect.in_service
        )
        out.append(
            Linearised(
                cand, tuple(names), np.array([scales[n] for n in names]), parts(jac.T).T, cand.where(ref), bounds
            )
        )
    return out


def in_service(bounds: np.ndarray, way: int) -> np.ndarray:
    """A change's bounds ``(n, 2)`` (lower, upper, from the baseline's value) narrowed to the way its effect's
    parameters can move in service (:attr:`twin.fem.effects.base.Effect.in_service`: -1 down, +1 up, 0 either).

    Examples
    --------
    >>> in_service(np.array([[-1.0, np.inf]]), -1).tolist(), in_service(np.array([[-1.0, np.inf]]), 0).tolist()
    ([[-1.0, 0.0]], [[-1.0, inf]])
    """
    out = np.array(bounds, dtype=float)
    if way < 0:
        out[:, 1] = np.minimum(out[:, 1], 0.0)
    elif way > 0:
        out[:, 0] = np.maximum(out[:, 0], 0.0)
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
    #: Natural log of the posterior odds of the named change against all the others together (each weighed by
    #: its log evidence and :func:`log_prior`; the named one's richer or simpler forms left out): the name stands
    #: when it is :data:`MIN_MARGIN` or more.
    odds: float = np.inf

    @property
    def clear(self) -> bool:
        """Whether the name stands: the evidence over no change and the odds over every other change suffice."""
        return self.log_evidence >= MIN_LOG_EVIDENCE and self.odds >= MIN_MARGIN


@dataclass(frozen=True)
class Setting:
    """Where a pooled residual was measured, for the candidates' refit on the full model: the model, its tracked
    modes, the pooled records' mean operating point and the changes followed already (candidate, values)."""

    model: RotorModel
    tracked: Tracked
    point: dict[str, float]
    others: list


#: Candidates refitted on the full model (:func:`refit`): those whose linear evidence lies within this much of
#: the best's (natural log), at most :data:`REFIT_MAX` of them.
REFIT_WITHIN = 25.0
REFIT_MAX = 10


def refit(r: np.ndarray, cov: np.ndarray, ok: np.ndarray, cand: Linearised, setting: Setting, start) -> LinearFit:
    """The candidate fitted to the pooled residual ``r`` (the parts ``ok``) on the full model at the setting's
    point, from the linear fit ``start``: Gauss-Newton to the posterior mode inside the change's bounds, and
    Laplace's evidence there (:func:`twin.update.evidence.log_evidence`, the bounds' mass as in
    :func:`twin.update.evidence.linear_fit`).

    The sensitivities at the reference point and no change hold for small changes only: a guide bearing's
    stiffness 30% down moves the first modes a quarter as much as its slope says, and a linear screening then
    prefers a change of the wrong kind (measured on the tracker's detection campaigns).
    """
    base = changed_poles(setting.model, setting.tracked, setting.point, setting.others)[0]
    # the pooled residual as one observation at the setting's point, for the tracker's Gauss-Newton
    y = np.full(len(ok), np.nan)
    y[ok] = r + base[ok]
    full = np.eye(len(ok))
    full[np.ix_(ok, ok)] = cov
    start_values = start.values if cand.bounds is None else np.clip(start.values, *cand.bounds.T)
    theta, _ = update(
        setting.model, setting.tracked, cand, [(setting.point, y, full)], setting.others, start=start_values
    )
    g, H = changed_poles(setting.model, setting.tracked, setting.point, [*setting.others, (cand, theta)], cand)
    factor, s = np.linalg.cholesky(cov), cand.scale
    white = np.linalg.solve(factor, r)
    J = np.linalg.solve(factor, H[ok]) * s
    e, u = np.linalg.solve(factor, r - (g - base)[ok]), theta / s
    A = J.T @ J + np.eye(len(s))
    post = np.linalg.inv(A) * np.outer(s, s)
    log_b = log_evidence(e, u, A) + 0.5 * float(white @ white)
    if cand.bounds is not None:
        log_b += truncation(theta, post, s, cand.bounds)
    return LinearFit(theta, post, float(e @ e), log_b)


def diagnose(r: np.ndarray, cov: np.ndarray, cands: list[Linearised], setting: Setting | None = None) -> Verdict:
    """The candidate that best explains the pooled residual ``r`` (``2m``, covariance ``cov``): each weighed as
    a linear-Gaussian hypothesis against no change (:func:`twin.update.evidence.linear_fit`), and, given the
    ``setting``, the leading ones refitted on the full model (:func:`refit`). A richer form
    of a change is named only when it pays for itself against the simpler (:func:`twin.update.evidence.simplest`);
    the runner-up is the best other change, not the named one in a richer or simpler form.

    Only pole parts measured since the onset take part (NaN elsewhere).
    """
    ok = np.isfinite(r)
    r, cov = r[ok], cov[np.ix_(ok, ok)]
    fits = [(linear_fit(r, c.jacobian[ok], c.scale, cov, c.bounds), c) for c in cands]
    # residuals that no candidate brings down to their stated errors (a change that grew or varied with the
    # operating point over the pooled records, what the laws miss under it) scatter beyond them: the errors
    # are widened by the best candidate's reduced chi-square, so that the evidence between changes is not
    # inflated with it (Birge's ratio)
    spread = min(f.chi2 / max(int(ok.sum()) - len(c.scale), 1) for f, c in fits)
    if spread > 1.0:
        cov = cov * spread
        fits = [(linear_fit(r, c.jacobian[ok], c.scale, cov, c.bounds), c) for c in cands]
    if setting is not None:
        top = max(f.log_bayes_factor for f, _ in fits)
        lead = sorted(
            (i for i, (f, _) in enumerate(fits) if f.log_bayes_factor >= top - REFIT_WITHIN),
            key=lambda i: -fits[i][0].log_bayes_factor,
        )[:REFIT_MAX]
        for i in lead:
            f, c = fits[i]
            fits[i] = (refit(r, cov, ok, c, setting, f), c)
        # a candidate left out of the refit keeps its linear evidence only below every refitted one's
        floor = min(fits[i][0].log_bayes_factor for i in lead)
        fits = [
            (f if i in lead else dataclasses.replace(f, log_bayes_factor=min(f.log_bayes_factor, floor)), c)
            for i, (f, c) in enumerate(fits)
        ]
    prior = log_prior(cands)
    score = {c.label: f.log_bayes_factor + prior[c.label] for f, c in fits}
    scored = sorted(fits, key=lambda t: -score[t[1].label])
    evidence = {c.label: f.log_bayes_factor for f, c in fits}
    label = simplest(scored[0][1].label, evidence, MIN_MARGIN)
    best_fit, best = next(t for t in scored if t[1].label == label)
    # the runner-up is another change, not the best one in a richer or a simpler form (which fits as well)
    others = [t for t in scored if t[1].label != best.label and not exclusive(t[1].label, best.label)]
    second_fit, second = others[0] if others else next(t for t in scored if t[1].label != best.label)
    best_ev, second_ev = best_fit.log_bayes_factor, second_fit.log_bayes_factor
    rest = np.array([score[c.label] for _, c in others])
    odds = score[best.label] - float(scipy.special.logsumexp(rest)) if rest.size else np.inf
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
        _text(best, mean, post, best_ev, second.label, second_ev, odds),
        odds,
    )


def log_prior(cands: list[Linearised]) -> dict[str, float]:
    """Each candidate's prior log probability among the changes: half to the library's effects and half to the
    local changes, shared equally within each (all to the library when there is no local change).

    A local change is one place of dozens (every shaft element, every disk), so the best of them beats a
    library effect by chance more often than one effect beats another: with equal weights a tilt of the thrust
    block growing over days was named as a stiffer shaft element. The weights make the naming a posterior
    probability over every candidate.

    Examples
    --------
    >>> from twin.fem.effects import MagneticPull
    >>> from twin.loop.candidates import Candidate
    >>> one = Linearised(Candidate("magnetic_pull", MagneticPull()), ("MAG.stiffness",), np.ones(1), np.ones((2, 1)))
    >>> log_prior([one])
    {'magnetic_pull': 0.0}
    """
    n_library = sum(c.library for c in cands)
    n_local = len(cands) - n_library
    share = 0.5 if n_library and n_local else 1.0
    return {c.label: float(np.log(share / (n_library if c.library else n_local))) for c in cands}


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
    start: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The candidate's values after the records since the onset: the posterior mode and covariance under its
    prior (zero, its plausible scale), by Gauss-Newton on the full model at each record's operating point,
    from ``start`` (zero when None) and inside the change's bounds.

    ``observed`` holds ``(point, y, cov)`` per record: the measured pole parts less the baseline's offsets
    (NaN where not measured or not used) and their covariance; ``others`` the changes followed already.
    """
    k = len(cand.parameters)
    mean = np.zeros(k) if start is None else np.array(start, dtype=float)
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
        if cand.bounds is not None:  # projected onto the physical bounds of the change
            mean = np.clip(mean, cand.bounds[:, 0], cand.bounds[:, 1])
        if np.all(np.abs(step) < 1e-3 * cand.scale):
            break
    return mean, np.linalg.inv(A)


def named(verdict: Verdict, cand: Linearised, mean: np.ndarray, cov: np.ndarray, note: str = "") -> Verdict:
    """The verdict with the change's values updated (:func:`update`) in place of the screening's linear ones,
    and a ``note`` added to its text."""
    text = _text(cand, mean, cov, verdict.log_evidence, verdict.runner_up, verdict.runner_up_evidence, verdict.odds)
    return dataclasses.replace(verdict, mean=mean, covariance=cov, text=f"{text}; {note}" if note else text)


def _text(
    cand: Linearised, mean: np.ndarray, cov: np.ndarray, evidence: float, second: str, second_ev: float, odds: float
) -> str:
    values = ", ".join(f"{n} = {m:.3g} ± {np.sqrt(v):.2g}" for n, m, v in zip(cand.parameters, mean, cov.diagonal()))
    if evidence < MIN_LOG_EVIDENCE:
        return f"no change the model can name stands out (best: {cand.label}, log evidence {evidence:.1f})"
    if odds < MIN_MARGIN:
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
