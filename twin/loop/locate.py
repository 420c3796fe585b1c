"""Where a model fails when no library effect explains it: a scan of local changes.

The hypotheses are the local changes (:func:`twin.fem.effects.local_changes`): each shaft
element's bending stiffness, each disk's mass, each disk's moments of
inertia, one relative change ``δ`` each with the prior ``N(0, s²)``,
``s =`` :data:`twin.fem.effects.LOCAL_CHANGE_SCALE`. Two passes:

1. **Screening**, linearised at the hypothesis already fitted: each change
   weighed as a linear-Gaussian hypothesis on the residuals
   (:func:`twin.update.evidence.linear_fit`; with ``J`` the residuals'
   derivative in ``δ`` scaled by ``s`` and ``r`` the residuals, its log
   Bayes factor is ``½ (Jᵀr)² / (1 + JᵀJ) − ½ ln(1 + JᵀJ)``);
2. **Refit** of the best :data:`REFIT` of them with the fitted hypothesis's
   parameters (nonlinear, :func:`twin.update.laplace.fit`), whose log Bayes factor
   against that hypothesis is what the diagnosis compares with the library's.

A softened shaft element and a heavier disk move the modes differently (a
mass change weighs ``λ²``, a stiffness change does not), so the scan says
which and where, and how much of the residual χ² the change explains.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from twin.fem.effects import LOCAL_CHANGE_SCALE, effect_label, local_changes, parse_label
from twin.fem.model import RotorModel
from twin.modes.measured import Measured, channel_dofs, pair_with_measured
from twin.modes.sensitivity import footprint_jacobian, solve_modes
from twin.tasks import mapper, one_blas_thread
from twin.update.evidence import linear_fit
from twin.update.laplace import Fit, fit, residual, scaled_rows

#: How many of the best-screened local changes are refitted.
REFIT = 3


@dataclass(frozen=True)
class Location:
    """A local change that explains part of the residuals.

    Attributes
    ----------
    label : str
        ``shaft_stiffness:<element>``, ``disk_mass:<disk>`` or ``disk_inertia:<disk>``.
    where : str
        The place in words.
    relative_change, std : float
        Fitted relative change and its posterior std.
    explained : float
        Fraction of the residual χ² (of the hypothesis it was added to) it removes.
    log_bayes_factor : float
        Against the hypothesis it was added to.
    """

    label: str
    where: str
    relative_change: float
    std: float
    explained: float
    log_bayes_factor: float

    @property
    def element(self) -> int:
        """The shaft element of a stiffness change (-1 for a disk)."""
        key, where = parse_label(self.label)
        return int(where) if key == "shaft_stiffness" else -1

    def text(self) -> str:
        """One sentence."""
        return (
            f"a {100 * self.relative_change:+.0f}% (± {100 * self.std:.0f}%) change of {self.where} explains "
            f"{100 * self.explained:.0f}% of the residual chi2 (ln B = {self.log_bayes_factor:.1f})"
        )


@one_blas_thread
def screen(model: RotorModel, meas: Measured, values: Mapping[str, float] | None = None) -> list[tuple[object, float]]:
    """Every local change with its linearised log Bayes factor at ``values``, best first."""
    changes = local_changes(model)
    sol = solve_modes(model, values)
    _, cols = pair_with_measured(sol, meas, channel_dofs(model, meas.channels))
    r = -residual(sol.poles[cols], meas)
    terms = [list(c.parameters(model)[0].terms) for c in changes]
    J = scaled_rows(footprint_jacobian(sol, terms, cols), meas)
    scale = np.array([LOCAL_CHANGE_SCALE])
    ln_b = np.array([linear_fit(r, J[:, [k]], scale).log_bayes_factor for k in range(len(changes))])
    order = np.argsort(-ln_b)
    return [(changes[k], float(ln_b[k])) for k in order]


def locate(
    model: RotorModel,
    meas: Measured,
    hypothesis: Fit | None = None,
    *,
    reference: float,
    top: int = REFIT,
    tasks: Any = None,
) -> list[Location]:
    """The local changes that best explain what ``hypothesis`` (or the model as it is) leaves, best first.

    Parameters
    ----------
    model : RotorModel
        The model with the hypothesis's effects (zero-valued or not).
    meas : Measured
    hypothesis : Fit, optional
        The fitted hypothesis the change is added to (its parameters are
        refitted with the change); None for the model as it is.
    reference : float
        ``ln Z`` of that hypothesis.
    top : int
        How many screened changes are refitted.
    tasks : distributed.Client or mapper, optional
        Where the refits run (:func:`twin.tasks.mapper`).

    Examples
    --------
    >>> from twin.fem.effects import DiskMassChange
    >>> from twin.fem.truthfile import Truth
    >>> from twin.modes.measured import measured_modes
    >>> from twin.update.laplace import log_evidence_as_is
    >>> from twin.update import synthesize_modes
    >>> model = hydro_unit
    >>> data = synthesize_modes(model, Truth((DiskMassChange("generator", 0.1),)), n_modes=13, samples=50,
    ...                         seed=2, pole_variance=(0.01, 0.01))
    >>> meas = measured_modes(data)
    >>> best = locate(model, meas, reference=log_evidence_as_is(model, meas)[0])[0]
    >>> best.label, round(best.relative_change, 2)
    ('disk_mass:generator', 0.1)
    """
    names = list(hypothesis.names) if hypothesis is not None else []
    start = hypothesis.value_of() if hypothesis is not None else {}
    screened = screen(model, meas, start)[:top]
    fits = mapper(tasks, desc="local changes")(
        _refit, [c for c, _ in screened], model=model, meas=meas, names=names, start=start, reference=reference
    )
    base_chi2 = hypothesis.chi2_after if hypothesis is not None else None
    out = []
    for (change, _), f in zip(screened, fits):
        name = change.parameters(model)[0].name
        k = f.names.index(name)
        before = f.chi2_before if base_chi2 is None else base_chi2
        explained = 1.0 - f.chi2_after / before if before > 0 else 0.0
        out.append(
            Location(
                effect_label(change),
                change.where(model),
                float(f.values[k]),
                float(f.std[k]),
                float(explained),
                f.log_bayes_factor,
            )
        )
    return sorted(out, key=lambda loc: -loc.log_bayes_factor)


def _refit(
    change, model: RotorModel, meas: Measured, names: Sequence[str], start: Mapping[str, float], reference: float
) -> Fit:
    with_change = model.with_effects(change)
    name = change.parameters(with_change)[0].name
    return fit(with_change, meas, [*names, name], effect_label(change), reference=reference, start=start)
