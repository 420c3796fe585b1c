"""Slice sampling of independent parameter blocks side by side: the per-mode step of the marginal HMC.

Given the shared parameters ``t``, each mode's own parameters ``η_i`` enter
only that mode's term of the marginal posterior, so the ``η_i`` are
independent and each can be moved on its own. :func:`slice_blocks` moves
every block along each of its axes in turn with Neal's (2003) univariate
slice sampler (stepping out, then shrinkage), all blocks at once: one
vectorised evaluation of every block's log density per round.

The slice sampler needs no step size: the interval steps out as far as the
density stays above the slice and shrinks back where it does not. A
per-mode parameter that the data barely determine has a posterior with a
long tail (its mode's residual and residual covariance grow together along
it, so the likelihood flattens), and one HMC step size for all parameters
cannot follow both it and the well-determined ones: one chain's step size
or metric set in a tail excursion of the warm-up held every mode's
parameters back for the whole run.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Initial interval along an axis, in that axis's conditional std (:func:`block_axes`).
SLICE_WIDTH = 2.0
#: Most intervals stepped out along an axis, both ways together.
SLICE_STEPS = 50


def block_axes(
    precision: np.ndarray, n_global: int, n_blocks: int, block_size: int, width: float = SLICE_WIDTH
) -> tuple[np.ndarray, np.ndarray]:
    """Each block's principal axes in its conditional precision, and ``width`` conditional std along each.

    ``precision`` is over ``[t, η_1, ..., η_I]`` (``n_global`` then
    ``n_blocks`` blocks of ``block_size``); block ``i``'s conditional
    precision given everything else is its diagonal block. Returns the axes
    as columns ``(I, Km, Km)`` and the interval widths ``(I, Km)``.

    Examples
    --------
    >>> axes, widths = block_axes(np.diag([9.0, 4.0, 1.0]), n_global=1, n_blocks=1, block_size=2)
    >>> widths
    array([[2., 1.]])
    """
    Kg, Km = n_global, block_size
    idx = Kg + np.arange(n_blocks)[:, None] * Km + np.arange(Km)
    blocks = precision[idx[:, :, None], idx[:, None, :]]
    w, U = np.linalg.eigh(blocks)
    return U, width / np.sqrt(w)


def slice_blocks(
    log_f: Callable[[np.ndarray], np.ndarray],
    x: np.ndarray,
    axes: np.ndarray,
    widths: np.ndarray,
    rng: np.random.Generator,
    f0: np.ndarray | None = None,
    max_steps: int = SLICE_STEPS,
) -> tuple[np.ndarray, np.ndarray]:
    """One slice-sampling update of every independent block along each of its axes in turn.

    Parameters
    ----------
    log_f : callable
        ``(I, Km) -> (I,)``: each block's log density (up to a constant per
        block) at the given rows; ``-inf`` outside its support.
    x : (I, Km)
        The blocks' current values.
    axes, widths : (I, Km, A), (I, A)
        The A directions (columns) and initial interval widths (:func:`block_axes`: all Km principal axes).
    f0 : (I,), optional
        ``log_f(x)``, if known; it must be finite (the shrinkage closes in on ``x``).
    max_steps : int
        Most widths the interval steps out along an axis (split at random
        between the two ends, as Neal's procedure does to keep the update
        reversible).

    Returns
    -------
    The new values ``(I, Km)`` and ``log_f`` there.

    Examples
    --------
    Two independent Gaussian blocks, unit std and std 10, moved from zero:

    >>> rng = np.random.default_rng(0)
    >>> log_f = lambda x: -0.5 * np.sum(x**2, axis=1) / np.array([1.0, 100.0])
    >>> x, draws = np.zeros((2, 1)), []
    >>> for _ in range(4000):
    ...     x, _ = slice_blocks(log_f, x, np.ones((2, 1, 1)), np.ones((2, 1)), rng)
    ...     draws.append(x[:, 0])
    >>> np.round(np.std(draws, axis=0), 0)
    array([ 1., 10.])
    """
    I = x.shape[0]
    x = np.array(x, dtype=float)
    f0 = log_f(x) if f0 is None else np.array(f0, dtype=float)
    if not np.all(np.isfinite(f0)):
        raise ValueError(
            f"slice_blocks: block(s) {np.flatnonzero(~np.isfinite(f0)).tolist()} start where their "
            "log density is not finite"
        )
    for a in range(axes.shape[2]):
        step = axes[:, :, a] * widths[:, a, None]
        log_y = f0 - rng.exponential(size=I)
        lo = -rng.uniform(size=I)
        hi = lo + 1.0
        left = np.floor(max_steps * rng.uniform(size=I)).astype(int)
        right = max_steps - 1 - left
        phase = np.zeros(I, int)  # 0: stepping out to the left, 1: to the right, 2: shrinking, 3: done
        s, f_new = np.zeros(I), f0.copy()
        while np.any(phase < 3):
            s = np.where(phase == 0, lo, np.where(phase == 1, hi, np.where(phase == 2, rng.uniform(lo, hi), s)))
            f = log_f(x + s[:, None] * step)
            inside = f > log_y
            out_left = (phase == 0) & inside & (left > 0)
            out_right = (phase == 1) & inside & (right > 0)
            took = (phase == 2) & inside
            missed = (phase == 2) & ~inside
            lo, left = np.where(out_left, lo - 1.0, np.where(missed & (s < 0), s, lo)), left - out_left
            hi, right = np.where(out_right, hi + 1.0, np.where(missed & (s >= 0), s, hi)), right - out_right
            f_new = np.where(took, f, f_new)
            phase = phase + ((phase == 0) & ~out_left) + ((phase == 1) & ~out_right) + took
        x = x + s[:, None] * step
        f0 = f_new
    return x, f0
