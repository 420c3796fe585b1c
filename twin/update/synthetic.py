"""Paper-style synthetic modal data (the reference paper's Figure 2).

A calibrated FEM is altered, for each mode ``i``, by that mode's own added
mass and damping ``(m_i, c_i)``; mode ``i`` is taken from its altered FEM
(:func:`twin.fmu.truth.truth_modes`). Its shape on the sensors is normalised
(unit norm, largest entry real positive), then J noisy samples are drawn:

* shapes: every real entry of ``[Re ψ; Im ψ]`` gets an independent Gaussian
  error of ``shape_cov`` (5%) times its own magnitude (coefficient of variation);
* poles: ``λ̂ = λ + N(0, 1.58) + i N(0, 1.1)`` [rad²/s² variances].

The result has the layout of ``modes.nc`` (:mod:`twin.modes.modesfile`),
with the truth in the attrs.
"""

from __future__ import annotations

import json
import numpy as np
import xarray as xr

from twin.defaults import SYNTHETIC_SAMPLES
from twin import __version__
from twin.fem.model import RotorModel
from twin.fem.truthfile import PAPER_POLE_VARIANCE, PAPER_SHAPE_COV, Truth, paper_truth
from twin.fmu.truth import truth_modes
from twin.modes.analysis import damping_ratio
from twin.modes.shapes import normalise_shapes
from twin.update.problem import UpdateError


def synthesize_modes(
    model: RotorModel,
    truth: Truth | None = None,
    *,
    samples: int = SYNTHETIC_SAMPLES,
    seed: int = 0,
    n_modes: int | None = None,
    shape_cov: float = PAPER_SHAPE_COV,
    pole_variance: tuple[float, float] = PAPER_POLE_VARIANCE,
    command: str = "",
) -> xr.Dataset:
    """Noisy pole and shape samples of a truth's modes on the model's sensors.

    Parameters
    ----------
    model : RotorModel
        The calibrated FEM (its sensors give the channels).
    truth : Truth, optional
        Hidden effects (default: the paper's Table 2 per-mode FSI).
    samples : int
        J, samples per mode.
    seed : int
        Seed of the noise.
    n_modes : int, optional
        Number of target modes when the truth has no per-mode effect.
    shape_cov : float
        Coefficient of variation of each real shape entry.
    pole_variance : (float, float)
        Variance of the real and imaginary parts of the pole samples [1/s²].

    Returns
    -------
    xarray.Dataset
        ``pole`` (mode, sample), ``shape`` (mode, sample, channel), complex;
        per mode the true ``frequency`` [Hz], ``damping_ratio`` and
        ``sensor_shape``; attrs ``truth`` (JSON) and the noise settings.

    Examples
    --------
    >>> from twin.update import synthesize_modes
    >>> ds = synthesize_modes(hydro_unit, samples=10, seed=1)
    >>> dict(ds.sizes)
    {'mode': 15, 'sample': 10, 'channel': 8}
    """
    if samples < 2:
        raise UpdateError(f"samples must be at least 2 (the data variance needs two), got {samples}")
    if not 0 <= shape_cov < 1:
        raise UpdateError(f"shape_cov must be in [0, 1), got {shape_cov}")
    if min(pole_variance) < 0:
        raise UpdateError(f"pole variances must be non-negative, got {pole_variance}")
    truth = truth or paper_truth()
    tm = truth_modes(model, truth, n_modes)
    shapes = normalise_shapes(tm.shapes[:, model.sensor_dofs])
    rng = np.random.default_rng(seed)
    n, J = len(tm.poles), samples
    noise = rng.standard_normal((2, n, J))
    pole_samples = tm.poles[:, None] + np.sqrt(pole_variance[0]) * noise[0] + 1j * np.sqrt(pole_variance[1]) * noise[1]
    e = shape_cov * rng.standard_normal((2, n, J, shapes.shape[1]))
    shape_samples = shapes.real[:, None] * (1 + e[0]) + 1j * shapes.imag[:, None] * (1 + e[1])
    truth_poles = [{"real": float(p.real), "imag": float(p.imag)} for p in tm.poles]
    attrs = {
        "title": f"synthetic modes of {model.name} (paper Figure 2 procedure)",
        "producer": f"twin {__version__}",
        "command": command,
        "model": model.name,
        "model_source": model.source,
        "truth": truth.to_json(),
        "truth_poles": json.dumps(truth_poles),
        "target_modes": json.dumps([int(k) + 1 for k in tm.targets]),
        "samples_method": f"Gaussian noise: shape CoV {shape_cov:g} per real entry, pole variance "
        f"{pole_variance[0]:g} (real) and {pole_variance[1]:g} (imag) rad^2/s^2",
        "seed": seed,
    }
    sensors = {s.name: s for s in model.sensors}
    return xr.Dataset(
        {
            "pole": (("mode", "sample"), pole_samples, {"units": "1/s", "long_name": "pole samples"}),
            "shape": (
                ("mode", "sample", "channel"),
                shape_samples,
                {"units": "1", "long_name": "mode shape samples (unit norm, largest entry real positive)"},
            ),
            "frequency": ("mode", tm.poles.imag / (2 * np.pi), {"units": "Hz", "long_name": "true damped frequency"}),
            "natural_frequency": (
                "mode",
                np.abs(tm.poles) / (2 * np.pi),
                {"units": "Hz", "long_name": "true undamped natural frequency"},
            ),
            "damping_ratio": ("mode", damping_ratio(tm.poles), {"units": "1", "long_name": "true damping ratio"}),
            "sensor_shape": (("mode", "channel"), shapes, {"units": "1", "long_name": "true mode shape"}),
        },
        coords={
            "mode": ("mode", np.arange(1, n + 1)),
            "sample": ("sample", np.arange(J)),
            "channel": ("channel", model.channels),
            "node": ("channel", [sensors[c].node for c in model.channels]),
            "direction": ("channel", [sensors[c].direction for c in model.channels]),
            "location": ("channel", [sensors[c].location for c in model.channels]),
        },
        attrs=attrs,
    )
