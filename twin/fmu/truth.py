"""Truth models: the model plus hidden effects, as a state space ready for export.

Mode-independent effects (FSI added mass, magnetic pull, seal cross-coupling)
simply alter the FEM. A per-mode FSI truth is not one FEM: by modal
synthesis, mode ``i`` is taken from the FEM altered by its own ``(m_i, c_i)``.
Each target mode is followed from the dry FEM to its altered FEM by
continuation (small steps in ``(m, c)``, matched by MAC of the full shape), so
a large added mass that reorders frequencies cannot swap modes.

*Target modes* are the lowest modes whose damping ratio is below
:data:`MAX_TARGET_DAMPING`: over-damped bearing modes (the hydro unit's UGB
mode at 75%) carry no per-mode value and are not identifiable from signals.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
import logging

import numpy as np
import scipy.linalg as sla

from twin.errors import ModelError
from twin.fem.effects import effect_label, with_shared_fsi
from twin.fem.model import RotorModel
from twin.fem.truthfile import Truth
from twin.fmu.statespace import StateSpace, full_state_space, modal_state_space, truncated_state_space
from twin.modes.analysis import damping_ratio, oscillating
from twin.modes.sensitivity import state_modes
from twin.modes.shapes import mac

log = logging.getLogger(__name__)

#: Modes damped more than this are not target modes.
MAX_TARGET_DAMPING = 0.10
#: Steps of the continuation from the dry FEM to a mode's altered FEM.
CONTINUATION_STEPS = 6


def target_mode_indices(poles: np.ndarray, n: int | None = None) -> np.ndarray:
    """Indices of the lowest ``n`` poles (sorted by frequency) with damping ratio below the limit (all of them
    when ``n`` is None).

    Examples
    --------
    >>> target_mode_indices(np.array([-0.1 + 7j, -9 + 10j, -0.2 + 20j]), 2)
    array([0, 2])
    """
    zeta = damping_ratio(poles)
    light = np.nonzero(zeta < MAX_TARGET_DAMPING)[0]
    if n is not None and len(light) < n:
        raise ModelError(
            f"{n} target modes asked for, but the model has only {len(light)} modes "
            f"damped less than {MAX_TARGET_DAMPING:.0%}"
        )
    return light if n is None else light[:n]


def hidden_effects(attrs: dict) -> dict[str, dict] | None:
    """The effects a truth system's ``attrs["truth"]`` (:func:`truth_state_space`) hides, by label with their
    fields; None for a system without a truth.

    Examples
    --------
    >>> hidden_effects({"truth": '{"source": "t.toml", "effects": {"magnetic_pull": {"stiffness": -5e7}}}'})
    {'magnetic_pull': {'stiffness': -50000000.0}}
    >>> hidden_effects({}) is None
    True
    """
    if "truth" not in attrs:
        return None
    return dict(json.loads(attrs["truth"]).get("effects", {}))


def truth_model(model: RotorModel, truth: Truth) -> RotorModel:
    """The model with the truth's mode-independent effects switched on (its per-mode one is not one FEM)."""
    present = {effect_label(e) for e in model.effects}
    clash = present & {effect_label(e) for e in truth.effects}
    if clash:
        raise ModelError(f"the model already has effect(s) {sorted(clash)} that the truth sets")
    return dataclasses.replace(model, effects=tuple(model.effects) + truth.mode_independent)


def truth_state_space(model: RotorModel, truth: Truth, basis: str = "full", fmax_hz: float | None = None) -> StateSpace:
    """State space of the truth: the altered FEM, or the per-mode modal synthesis.

    Parameters
    ----------
    model : RotorModel
    truth : Truth
    basis, fmax_hz
        For a truth without per-mode effect: full FEM or modes up to ``fmax_hz``.
        A per-mode truth is always modal (its target modes).

    Returns
    -------
    StateSpace
        With ``attrs["truth"]`` (JSON) and ``attrs["truth_modes"]`` (JSON list of
        the truth's frequency [Hz] and damping ratio per mode).

    Examples
    --------
    >>> from twin.fem.truthfile import paper_truth
    >>> ss = truth_state_space(hydro_unit, paper_truth())
    >>> ss.n_states, ss.basis
    (30, 'modal')
    """
    altered = truth_model(model, truth)
    per_mode = truth.per_mode
    if per_mode is None:
        ss = model_state_space(altered, basis, fmax_hz)  # the model's own per-mode FSI, if any, included
    else:
        ss = synthesize_per_mode_fsi(altered, per_mode.added_mass, per_mode.added_damping)
    poles = ss.poles[oscillating(ss.poles)]
    poles = poles[np.argsort(poles.imag)]
    modes = [{"frequency_hz": float(p.imag / (2 * np.pi)), "damping_ratio": float(damping_ratio(p))} for p in poles]
    attrs = {**ss.attrs, "model": model.name, "truth": truth.to_json(), "truth_modes": json.dumps(modes)}
    return dataclasses.replace(ss, attrs=attrs)


@dataclass(frozen=True)
class TruthModes:
    """Target modes of a truth, each from its own (altered) FEM.

    Attributes
    ----------
    poles : (r,) complex
        Poles [1/s], Im > 0, in target-mode order.
    right, left : (r, 2 n_dof) complex
        Right and left *state* eigenvectors (``left_i right_i = 1``); the
        first ``n_dof`` entries of ``right`` are the mode shape on all DOFs.
    wb : (r, p) complex
        Input projection ``left_i B`` of each mode, ``B`` from its own FEM.
    targets : (r,) int
        Index of each mode among the dry FEM's modes (by frequency).
    ss : StateSpace
        The dry (no per-mode effect) full state space: ports, outputs, speed.
    """

    poles: np.ndarray
    right: np.ndarray
    left: np.ndarray
    wb: np.ndarray
    targets: np.ndarray
    ss: StateSpace

    @property
    def shapes(self) -> np.ndarray:
        """Mode shapes on all DOFs, ``(r, n_dof)`` complex (not normalised)."""
        return self.right[:, : self.right.shape[1] // 2]


def truth_modes(model: RotorModel, truth: Truth, n_modes: int | None = None) -> TruthModes:
    """The truth's target modes on all DOFs (the paper's Figure 2 for a per-mode truth).

    With a per-mode effect, mode ``i`` is taken from the FEM altered by that
    mode's ``(m_i, c_i)`` (and ``n_modes`` defaults to the effect's count);
    otherwise the lowest ``n_modes`` target modes of the altered FEM.

    Examples
    --------
    >>> from twin.fem.truthfile import paper_truth
    >>> tm = truth_modes(hydro_unit, paper_truth())
    >>> tm.shapes.shape
    (15, 116)
    """
    altered = truth_model(model, truth)
    per_mode = truth.per_mode
    if per_mode is None:
        ss = full_state_space(altered)
        lam, right, left = state_modes(ss.A)
        targets = target_mode_indices(lam, n_modes)
        return TruthModes(lam[targets], right[targets], left[targets], left[targets] @ ss.B, targets, ss)
    if n_modes not in (None, per_mode.n_modes):
        raise ModelError(f"the truth gives per-mode values for {per_mode.n_modes} modes, not {n_modes}")
    return per_mode_fsi_modes(altered, per_mode.added_mass, per_mode.added_damping)


def per_mode_fsi_modes(model: RotorModel, added_mass: tuple, added_damping: tuple) -> TruthModes:
    """Target mode ``i`` from the FEM altered by ``(added_mass[i], added_damping[i])``.

    The added mass and damping are shared over the immersed DOFs like the
    mode-independent FSI effect (on top of it if the model has one).

    Each mode is followed from the dry FEM in :data:`CONTINUATION_STEPS`
    full eigen-solves, about 6 s for the paper's 15 modes; the last
    :data:`CACHE_SIZE` results are kept (keyed by the model's full ``repr``
    and the values), with read-only arrays.
    """
    key = (repr(model), tuple(map(float, added_mass)), tuple(map(float, added_damping)))
    if key not in _CACHE:
        _CACHE[key] = _per_mode_fsi_modes(model, added_mass, added_damping)
        while len(_CACHE) > CACHE_SIZE:
            _CACHE.pop(next(iter(_CACHE)))
    return _CACHE[key]


#: Per-mode truths kept by :func:`per_mode_fsi_modes`.
CACHE_SIZE = 4
_CACHE: dict[tuple, TruthModes] = {}


def _per_mode_fsi_modes(model: RotorModel, added_mass: tuple, added_damping: tuple) -> TruthModes:
    fsi_model = with_shared_fsi(model)
    m0, c0 = fsi_model.parameter("FSI.added_mass").nominal, fsi_model.parameter("FSI.added_damping").nominal
    n_dof = model.n_dof

    def state(m: float, c: float) -> StateSpace:
        return full_state_space(fsi_model, values={"FSI.added_mass": m0 + m, "FSI.added_damping": c0 + c})

    dry = state(0.0, 0.0)
    lam0, right0, _ = state_modes(dry.A)
    targets = target_mode_indices(lam0, len(added_mass))
    poles, rights, lefts, wb = [], [], [], []
    for i, k in enumerate(targets):
        shape, lam = right0[k, :n_dof], lam0[k]
        for s in np.linspace(0.0, 1.0, CONTINUATION_STEPS + 1)[1:]:
            ss = state(s * added_mass[i], s * added_damping[i])
            if s < 1.0:
                cand, vecs = sla.eig(ss.A)
                left = None
            else:
                cand, right, left = state_modes(ss.A)
                vecs = right.T
            osc = oscillating(cand)
            cand, vecs = cand[osc], vecs[:, osc]
            similarity = mac(vecs[:n_dof].T, shape)[:, 0] - 1e-3 * np.abs(np.log(np.abs(cand / lam)))
            j = int(np.argmax(similarity))
            if similarity[j] < 0.5:
                log.warning("mode %d: continuation step s=%.2f matched with MAC %.2f only", i + 1, s, similarity[j])
            shape, lam = vecs[:n_dof, j], cand[j]
        poles.append(lam)
        rights.append(right[j])
        lefts.append(left[j])
        wb.append(left[j] @ ss.B)
    arrays = [np.array(a) for a in (poles, rights, lefts, wb, targets)]
    for a in arrays:
        a.setflags(write=False)
    return TruthModes(*arrays, dry)


def synthesize_per_mode_fsi(model: RotorModel, added_mass: tuple, added_damping: tuple) -> StateSpace:
    """Modal synthesis: target mode ``i`` from the FEM altered by ``(added_mass[i], added_damping[i])``."""
    tm = per_mode_fsi_modes(model, added_mass, added_damping)
    dry = tm.ss
    attrs = {"basis": "modal", "synthesis": "per-mode FSI", "target_modes": [int(k) + 1 for k in tm.targets]}
    return modal_state_space(tm.poles, dry.C @ tm.right.T, tm.wb, dry.ports, dry.outputs, dry.speed_rpm, attrs)


def model_state_space(model: RotorModel, basis: str = "full", fmax_hz: float | None = None) -> StateSpace:
    """The model's state space in the chosen basis: ``"full"`` FEM or ``"modal"`` up to ``fmax_hz``.

    A model with a per-mode FSI effect (an update's per-mode estimate, :func:`twin.update.apply_posterior`)
    is not one FEM: its state space is the modal synthesis of its target modes, mode ``i`` from the FEM
    altered by its own values (:func:`synthesize_per_mode_fsi`), whatever ``basis`` says.

    Examples
    --------
    >>> model_state_space(hydro_unit, "modal", 50.0).n_states  # modes 1-11
    22
    >>> from twin.fem.effects import FluidAddedMassPerMode
    >>> wet = hydro_unit.with_effects(FluidAddedMassPerMode((1e5, 1e5), (1e6, 1e6)))
    >>> model_state_space(wet).n_states  # its two target modes
    4
    """
    if basis not in ("full", "modal"):
        raise ModelError(f"basis must be 'full' or 'modal', got {basis!r}")
    if basis == "modal" and fmax_hz is None:
        raise ModelError("a modal basis needs fmax_hz, the highest frequency to keep")
    per_mode = model.per_mode_effect
    if per_mode is not None:
        return synthesize_per_mode_fsi(model.without_per_mode_effect(), per_mode.added_mass, per_mode.added_damping)
    ss = full_state_space(model)
    return ss if basis == "full" else truncated_state_space(ss, fmax_hz)
